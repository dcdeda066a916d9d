/**
 * @file att_fdcan_hal.h
 * @brief CAN HAL of the attica node for a Bosch M_CAN controller: STM32 FDCAN (G0/G4 fixed message RAM,
 * H7 configurable message RAM), classic CAN and CAN FD.
 *
 * Moves frames between the controller and an att_node_t: Rx FIFO 0 -> att_node_rx, att_node_poll,
 * att_node_tx -> the Tx buffers, used as a Tx FIFO (sent in the order queued). Same structure as the
 * bxCAN HAL (att_can_hal.h): every register and message RAM access goes through att_fdcan_hal_io_t
 * (32-bit read / write at a byte offset), so the driver runs unchanged on the peripheral
 * (att_fdcan_hal_mmio) and against the fake controller of tests/c/att_fdcan_hal_test.c; no heap, no
 * time source, every wait bounded (ATT_FDCAN_HAL_SPIN reads).
 *
 * @code
 * static att_node_t node;
 * static att_fdcan_hal_t can;
 * att_node_settings_t ns;
 * if (att_node_settings_default(ATT_FILTER_ARS, 285.714f, &ns) != ATT_OK) { ... }  // kind, rate in Hz
 * ns.fd = true;                                   // CAN FD outputs ...
 * ns.data_bitrate = 2000000u;                     // ... at 2 Mbit/s (classic: leave both)
 * if (att_node_init(&node, &ns) != ATT_OK) { ... }
 * // STM32G4 FDCAN1: registers at 0x40006400, its message RAM at 0x4000A400, kernel clock 160 MHz
 * if (att_fdcan_hal_init(&can, att_fdcan_hal_mmio((void *)0x40006400u), att_fdcan_hal_mmio((void *)0x4000A400u),
 *                        &att_fdcan_layout_g4, &node, 160000000u) != ATT_OK) { ... }
 * for (;;) { (void)att_fdcan_hal_service(&can); }   // or: on the FIFO 0 interrupt / a timer tick
 * @endcode
 *
 * Two register maps (att_fdcan_variant_t):
 * - ATT_FDCAN_G4 (STM32G4, G0B1/G0C1, and the parts with the same FDCAN: L5, U5, H5): the message RAM
 *   layout is fixed (RM0440 "Message RAM"): per instance 0x350 bytes, 28 standard filters at 0x000, 8
 *   extended filters at 0x070, Rx FIFO 0 (3 elements of 18 words) at 0x0B0, Rx FIFO 1 at 0x188, Tx
 *   event FIFO at 0x260, 3 Tx buffers of 18 words at 0x278; instance i's RAM at SRAMCAN + 0x350 i
 *   (SRAMCAN: G4 0x4000A400, G0 0x4000B400; see the part's reference manual). Global filter in RXGFC
 *   (with the list size LSS); FIFO status RXF0S 0x090, RXF0A 0x094; TXBAR 0x0CC. Pass
 *   att_fdcan_layout_g4.
 * - ATT_FDCAN_H7 (STM32H7, and the generic Bosch M_CAN register map): the 10 KB message RAM at
 *   0x4000AC00 is shared by the instances and configured by software: start addresses and sizes in
 *   SIDFC, RXF0C, TXBC, element data sizes in RXESC / TXESC (8 .. 64 bytes), filter GFC; FIFO status
 *   RXF0S 0x0A4, RXF0A 0x0A8; TXBAR 0x0D0. Describe the instance's share in an att_fdcan_layout_t
 *   (att_fdcan_layout_h7 packs one); the ram io's base is the start of the message RAM (the offsets
 *   are from there, as in the configuration registers).
 *
 * Acceptance filter: exactly the node's receive IDs (att_node_rx_ids: IMU_GYRO, IMU_ACC, IMU_MAG, IMU_FD
 * in builds with CAN FD, CMD; each + id_offset) as standard data frames into Rx FIFO 0, as dual-ID
 * standard filter elements (SFT 01, SFEC 001 "store in Rx FIFO 0", two IDs each, the last one repeated
 * when the count is odd); the global filter rejects every other standard frame (ANFS 10), every
 * extended frame (ANFE 10, no extended filter elements) and every remote frame (RRFS, RRFE).
 *
 * Controller faults (att_fdcan_hal_service, every call): at bus-off (PSR.BO) the controller sets
 * CCCR.INIT and stops; the driver counts the episode and waits h->backoff service calls
 * (ATT_FDCAN_HAL_BACKOFF_FIRST, doubled at each bus-off up to ATT_FDCAN_HAL_BACKOFF_MAX, back to FIRST
 * after ATT_FDCAN_HAL_BACKOFF_RESET calls in a row neither bus-off nor error-passive) before it clears
 * INIT, which starts the recovery the protocol prescribes (129 x 11 recessive bits, then PSR.BO clear:
 * counted in recoveries; INIT seen set again before that is a recovery and a new bus-off in between);
 * nothing is queued for sending meanwhile (the frames wait in the node). A node
 * whose transceiver or bit timing is wrong so rejoins at most once per ATT_FDCAN_HAL_BACKOFF_MAX calls
 * instead of flooding the bus with error frames. Error-passive (PSR.EP) and error warning (PSR.EW)
 * entries are counted on the edge seen by the service (bus-off holds until the driver recovers, so it
 * is never missed), Rx FIFO 0 / 1 message-lost flags (IR.RF0L, IR.RF1L) counted and cleared, the last
 * error code (PSR.LEC) kept. att_fdcan_hal_init registers att_fdcan_hal_bus_diag with the node
 * (att_node_set_bus_diag): every ATT_DIAG the node sends is followed by an ATT_DIAG_BUS with these
 * counters. Call the service at a steady rate (each sample, a timer tick) for the delays to be a time.
 *
 * att_fdcan_hal_service (= controller faults, receive, att_node_poll, transmit) must not run concurrently
 * with itself or with other calls on the same node: call it from one context. Not done here: the
 * kernel clock (RCC; on G0/G4 also FDCAN_CONFIG CKDIV, which divides it for every instance: leave it
 * at 1 or pass the divided clock), the pins, interrupts (none enabled: polled; enable RF0NE and route
 * it with ILS/ILE yourself to be woken by frames).
 */
#ifndef ATT_FDCAN_HAL_H
#define ATT_FDCAN_HAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "attica/att_can.h"
#include "attica/att_node.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Register offsets (bytes from the controller's base) common to both register maps. */
enum {
    ATT_FDCAN_CREL = 0x000,  /**< core release */
    ATT_FDCAN_ENDN = 0x004,  /**< endianness test value: reads ATT_FDCAN_ENDN_VALUE */
    ATT_FDCAN_DBTP = 0x00C,  /**< data bit timing and prescaler (protected) */
    ATT_FDCAN_TEST = 0x010,  /**< test */
    ATT_FDCAN_CCCR = 0x018,  /**< CC control */
    ATT_FDCAN_NBTP = 0x01C,  /**< nominal bit timing and prescaler (protected) */
    ATT_FDCAN_ECR = 0x040,   /**< error counters */
    ATT_FDCAN_PSR = 0x044,   /**< protocol status */
    ATT_FDCAN_TDCR = 0x048,  /**< transmitter delay compensation (protected) */
    ATT_FDCAN_IR = 0x050,    /**< interrupt flags (write 1 to clear) */
    ATT_FDCAN_IE = 0x054,    /**< interrupt enable */
    ATT_FDCAN_ILS = 0x058,   /**< interrupt line select */
    ATT_FDCAN_ILE = 0x05C,   /**< interrupt line enable */
    ATT_FDCAN_TXBC = 0x0C0,  /**< Tx buffer configuration (protected) */
    ATT_FDCAN_TXFQS = 0x0C4  /**< Tx FIFO/queue status */
};

/** Register offsets of the STM32G0/G4 FDCAN (fixed message RAM). */
enum {
    ATT_FDCAN_G4_RXGFC = 0x080, /**< global filter: LSS 20:16, LSE 27:24, F0OM 9, ANFS 5:4, ANFE 3:2, RRFS 1, RRFE 0 */
    ATT_FDCAN_G4_RXF0S = 0x090, /**< Rx FIFO 0 status */
    ATT_FDCAN_G4_RXF0A = 0x094, /**< Rx FIFO 0 acknowledge */
    ATT_FDCAN_G4_TXBRP = 0x0C8, /**< Tx buffer request pending */
    ATT_FDCAN_G4_TXBAR = 0x0CC  /**< Tx buffer add request */
};

/** Register offsets of the STM32H7 FDCAN / Bosch M_CAN (configurable message RAM). */
enum {
    ATT_FDCAN_H7_GFC = 0x080,   /**< global filter: ANFS 5:4, ANFE 3:2, RRFS 1, RRFE 0 */
    ATT_FDCAN_H7_SIDFC = 0x084, /**< standard ID filter list: FLSSA 15:2 (byte offset), LSS 23:16 */
    ATT_FDCAN_H7_XIDFC = 0x088, /**< extended ID filter list: FLESA 15:2, LSE 22:16 */
    ATT_FDCAN_H7_RXF0C = 0x0A0, /**< Rx FIFO 0: F0SA 15:2, F0S 22:16, F0WM 30:24, F0OM 31 */
    ATT_FDCAN_H7_RXF0S = 0x0A4, /**< Rx FIFO 0 status */
    ATT_FDCAN_H7_RXF0A = 0x0A8, /**< Rx FIFO 0 acknowledge */
    ATT_FDCAN_H7_RXBC = 0x0AC,  /**< Rx buffers: RBSA 15:2 */
    ATT_FDCAN_H7_RXF1C = 0x0B0, /**< Rx FIFO 1 configuration */
    ATT_FDCAN_H7_RXESC = 0x0BC, /**< Rx element data sizes: F0DS 2:0, F1DS 6:4, RBDS 10:8 */
    ATT_FDCAN_H7_TXESC = 0x0C8, /**< Tx element data size: TBDS 2:0 */
    ATT_FDCAN_H7_TXBRP = 0x0CC, /**< Tx buffer request pending */
    ATT_FDCAN_H7_TXBAR = 0x0D0, /**< Tx buffer add request */
    ATT_FDCAN_H7_TXEFC = 0x0F0, /**< Tx event FIFO configuration */
    ATT_FDCAN_H7_RAM_BYTES = 0x2800 /**< the message RAM shared by the instances (10 KB) */
};

#define ATT_FDCAN_ENDN_VALUE 0x87654321u /**< what ENDN reads on every M_CAN */

#define ATT_FDCAN_CCCR_INIT ((uint32_t)1u << 0)  /**< initialisation (set by the controller at bus-off) */
#define ATT_FDCAN_CCCR_CCE ((uint32_t)1u << 1)   /**< configuration change enable (with INIT) */
#define ATT_FDCAN_CCCR_CSA ((uint32_t)1u << 3)   /**< clock stop acknowledge */
#define ATT_FDCAN_CCCR_CSR ((uint32_t)1u << 4)   /**< clock stop request */
#define ATT_FDCAN_CCCR_FDOE ((uint32_t)1u << 8)  /**< CAN FD operation enable */
#define ATT_FDCAN_CCCR_BRSE ((uint32_t)1u << 9)  /**< bit rate switching enable */
/* PSR (RM0440 "FDCAN protocol status register", M_CAN PSR at 0x44; both maps): LEC 2:0 (set to 7 on
   read), ACT 4:3, EP 5, EW 6, BO 7. */
#define ATT_FDCAN_PSR_LEC ((uint32_t)7u)         /**< last error code: 0 none, 1..6 error, 7 no change since read */
#define ATT_FDCAN_PSR_EP ((uint32_t)1u << 5)     /**< error passive */
#define ATT_FDCAN_PSR_EW ((uint32_t)1u << 6)     /**< warning status: TEC or REC >= 96 */
#define ATT_FDCAN_PSR_BO ((uint32_t)1u << 7)     /**< bus-off */
#define ATT_FDCAN_DBTP_TDC ((uint32_t)1u << 23)  /**< transmitter delay compensation enable */
#define ATT_FDCAN_G4_IR_RF0L ((uint32_t)1u << 2) /**< Rx FIFO 0 message lost (G0/G4, RM0440 FDCAN_IR) */
#define ATT_FDCAN_G4_IR_RF1L ((uint32_t)1u << 5) /**< Rx FIFO 1 message lost (G0/G4) */
#define ATT_FDCAN_H7_IR_RF0L ((uint32_t)1u << 3) /**< Rx FIFO 0 message lost (H7 / M_CAN, RM0433 FDCAN_IR) */
#define ATT_FDCAN_H7_IR_RF1L ((uint32_t)1u << 7) /**< Rx FIFO 1 message lost (H7 / M_CAN) */
#define ATT_FDCAN_RXFS_RFL ((uint32_t)1u << 25)  /**< RXF0S: message lost (copy of IR.RF0L) */
#define ATT_FDCAN_TXFQS_TFQF ((uint32_t)1u << 21) /**< TXFQS: Tx FIFO full */
/** Global filter of both maps: reject non-matching standard and extended frames, reject remote frames. */
#define ATT_FDCAN_GFC_REJECT_ALL_OTHERS (((uint32_t)2u << 4) | ((uint32_t)2u << 2) | 3u)

/** Message RAM elements: word 0 and 1 of an Rx / Tx element, a standard filter element. */
#define ATT_FDCAN_E0_XTD ((uint32_t)1u << 30)  /**< extended identifier */
#define ATT_FDCAN_E0_RTR ((uint32_t)1u << 29)  /**< remote frame */
#define ATT_FDCAN_E0_STD_SHIFT 18u             /**< a standard ID sits in bits 28:18 */
#define ATT_FDCAN_E1_FDF ((uint32_t)1u << 21)  /**< CAN FD format */
#define ATT_FDCAN_E1_BRS ((uint32_t)1u << 20)  /**< bit rate switch */
#define ATT_FDCAN_E1_DLC_SHIFT 16u             /**< DLC in bits 19:16 */
#define ATT_FDCAN_SFT_DUAL ((uint32_t)1u << 30) /**< standard filter type 01: SFID1 or SFID2 */
#define ATT_FDCAN_SFEC_FIFO0 ((uint32_t)1u << 27) /**< standard filter element config 001: store in Rx FIFO 0 */

/** Busy-wait bound for the controller's acknowledgements (loop iterations). */
#define ATT_FDCAN_HAL_SPIN 100000u
#ifndef ATT_FDCAN_HAL_BACKOFF_FIRST
/** Service calls from the first bus-off to its recovery (then 2, 4 ... times this). */
#define ATT_FDCAN_HAL_BACKOFF_FIRST 1u
#endif
#ifndef ATT_FDCAN_HAL_BACKOFF_MAX
/** Longest back-off, service calls (the doubling stops here). */
#define ATT_FDCAN_HAL_BACKOFF_MAX 1024u
#endif
#ifndef ATT_FDCAN_HAL_BACKOFF_RESET
/** Service calls in a row neither bus-off nor error-passive that bring the back-off back to FIRST. */
#define ATT_FDCAN_HAL_BACKOFF_RESET 1024u
#endif
/** Standard filter elements the driver writes at most: two IDs each. */
#define ATT_FDCAN_HAL_FILTERS ((ATT_NODE_RX_IDS_MAX + 1) / 2)

/** Register access: 32-bit read and write at a byte offset from a base (registers or message RAM). */
typedef struct {
    void *ctx;                                                  /**< base address or fake state */
    uint32_t (*read)(void *ctx, uint32_t offset);              /**< read the word at offset */
    void (*write)(void *ctx, uint32_t offset, uint32_t value); /**< write the word at offset */
} att_fdcan_hal_io_t;

/** Where the driver stands with the bus (att_fdcan_hal_t.phase). */
typedef enum {
    ATT_FDCAN_HAL_ON = 0,        /**< on the bus: the Tx FIFO is filled from the node */
    ATT_FDCAN_HAL_BACKOFF = 1,   /**< bus-off seen (CCCR.INIT set by the controller): waiting h->wait service calls */
    ATT_FDCAN_HAL_RECOVERING = 2 /**< INIT cleared: waiting for PSR.BO to clear (129 x 11 recessive bits) */
} att_fdcan_hal_phase_t;

/** Register map of the controller. */
typedef enum {
    ATT_FDCAN_G4 = 0, /**< STM32G0/G4 FDCAN: fixed message RAM layout (att_fdcan_layout_g4) */
    ATT_FDCAN_H7 = 1  /**< STM32H7 FDCAN / Bosch M_CAN: message RAM configured from the layout */
} att_fdcan_variant_t;

/**
 * Where the driver's message RAM sections are (byte offsets from the ram io's base, multiples of 4)
 * and how large. For ATT_FDCAN_G4 only att_fdcan_layout_g4 is accepted (the hardware's fixed layout).
 */
typedef struct {
    att_fdcan_variant_t variant; /**< register map */
    uint32_t filters;            /**< standard ID filter list (1 word per element) */
    uint32_t filters_max;        /**< elements the list has room for (>= ATT_FDCAN_HAL_FILTERS is enough) */
    uint32_t rx_fifo0;           /**< Rx FIFO 0 */
    uint32_t rx_fifo0_n;         /**< its elements: 1 .. 64 (G4: 3) */
    uint32_t tx_fifo;            /**< the Tx buffers, used as Tx FIFO */
    uint32_t tx_fifo_n;          /**< Tx buffers: 1 .. 32 (G4: 3) */
    uint32_t data_bytes;         /**< data bytes of an Rx FIFO 0 / Tx element: 8, 12, 16, 20, 24, 32, 48, 64 (G4: 64) */
} att_fdcan_layout_t;

/** The fixed message RAM layout of the STM32G0/G4 FDCAN (one instance; RM0440 "Message RAM"). */
extern const att_fdcan_layout_t att_fdcan_layout_g4;

/** Bit timing register values (att_fdcan_hal_timing). */
typedef struct {
    uint32_t nbtp;  /**< NBTP: NSJW 31:25, NBRP 24:16, NTSEG1 15:8, NTSEG2 6:0 (each value - 1) */
    uint32_t dbtp;  /**< DBTP: TDC 23, DBRP 20:16, DTSEG1 12:8, DTSEG2 7:4, DSJW 3:0; 0 = no data phase */
    uint32_t tdcr;  /**< TDCR: TDCO 14:8, TDCF 6:0; 0 without transmitter delay compensation */
} att_fdcan_timing_t;

/** Driver counters. */
typedef struct {
    uint32_t rx_frames;      /**< frames moved from Rx FIFO 0 to the node */
    uint32_t rx_fd_frames;   /**< ... of them CAN FD frames */
    uint32_t rx_ignored;     /**< extended-ID or remote frames, or longer than data_bytes (dropped) */
    uint32_t rx_overruns;    /**< Rx FIFO 0 / 1 message-lost events seen (frames lost in the controller) */
    uint32_t rx_node_full;   /**< frames att_node_rx refused (node rx ring full) */
    uint32_t tx_frames;      /**< frames written to the Tx FIFO */
    uint32_t tx_fd_frames;   /**< ... of them CAN FD frames */
    uint32_t tx_unsupported; /**< frames the controller as configured cannot send (dropped, see att_fdcan_hal_send) */
    uint32_t bus_off;        /**< bus-off episodes (PSR.BO seen set while on the bus) */
    uint32_t recoveries;     /**< bus-off episodes ended: PSR.BO clear again after the driver cleared INIT */
    uint32_t error_passive;  /**< entries into error-passive (PSR.EP seen set after clear) */
    uint32_t error_warning;  /**< entries into error warning (PSR.EW seen set after clear) */
    uint32_t lec;            /**< the last error code PSR.LEC reported (1 .. 6), 0 none yet */
} att_fdcan_hal_stats_t;

/** An FDCAN controller serving one attica node. */
typedef struct {
    att_fdcan_hal_io_t regs;     /**< register access */
    att_fdcan_hal_io_t ram;      /**< message RAM access */
    att_fdcan_layout_t layout;   /**< message RAM layout in use */
    att_node_t *node;            /**< the node */
    att_fdcan_timing_t timing;   /**< bit timing in use */
    uint32_t filter_elements;    /**< standard filter elements written */
    bool fd;                     /**< CAN FD operation (the node has a data bitrate): FDOE, BRSE */
    bool brs;                    /**< FD frames are sent with bit rate switch (data bitrate > nominal) */
    att_fdcan_hal_phase_t phase; /**< on the bus, in back-off, recovering */
    uint32_t backoff;            /**< service calls the next bus-off waits (FIRST .. MAX) */
    uint32_t wait;               /**< ATT_FDCAN_HAL_BACKOFF: service calls left before INIT is cleared */
    uint32_t good;               /**< service calls in a row on the bus, not error-passive (up to RESET) */
    bool passive;                /**< PSR.EP at the last service */
    bool warning;                /**< PSR.EW at the last service */
    att_fdcan_hal_stats_t stats; /**< counters */
} att_fdcan_hal_t;

/** Access to memory-mapped registers or message RAM at base (volatile 32-bit loads and stores). */
att_fdcan_hal_io_t att_fdcan_hal_mmio(void *base);

/**
 * Pack an H7 / M_CAN layout from byte offset start of the message RAM: ATT_FDCAN_HAL_FILTERS standard
 * filters, rx_n Rx FIFO 0 elements, tx_n Tx buffers, data_bytes each; returns the offset of the first
 * byte after it (where the next instance's share can start), 0 when the arguments are out of range
 * (the layout then fails att_fdcan_hal_layout_check). E.g. FDCAN1 from 0, FDCAN2 from the result.
 */
uint32_t att_fdcan_layout_h7(uint32_t start, uint32_t rx_n, uint32_t tx_n, uint32_t data_bytes,
                             att_fdcan_layout_t *l);

/**
 * ATT_OK when the driver can use layout l: G4 = exactly att_fdcan_layout_g4; H7: offsets multiples of 4,
 * sections inside the 10 KB message RAM and not overlapping, 1 .. 64 Rx and 1 .. 32 Tx elements, a data
 * size the element size registers know, room for ATT_FDCAN_HAL_FILTERS filters. ATT_ERR_NULL,
 * ATT_ERR_SETTINGS otherwise.
 */
att_status_t att_fdcan_hal_layout_check(const att_fdcan_layout_t *l);

/**
 * Bit timing for a nominal bitrate and (data_bitrate > 0) a CAN FD data phase from the kernel clock
 * kernel_hz (all in Hz). Nominal: prescaler 1 .. 512, 8 .. 385 time quanta per bit, sample point
 * 87.5 % (rounded to the nearest quantum), SJW = phase segment 2. Data: prescaler 1 .. 32, 5 .. 49
 * quanta, sample point 75 %, SJW = phase segment 2; the same prescaler for both phases when one fits
 * (CiA 601-3), else the smallest of each. Above 1 Mbit/s the data phase uses transmitter delay
 * compensation (TDC; the secondary sample point at TDCO = the sample point in kernel clock periods),
 * which M_CAN allows for a data prescaler of 1 or 2 only. Every bitrate must come out exactly.
 * ATT_OK, ATT_ERR_NULL, ATT_ERR_SETTINGS (bitrate 0, data_bitrate below bitrate, or not reachable:
 * then t is zeroed).
 */
att_status_t att_fdcan_hal_timing(uint32_t kernel_hz, uint32_t bitrate, uint32_t data_bitrate,
                                  att_fdcan_timing_t *t);

/** Data bytes of a frame with data length code dlc (0 .. 15): 0 .. 8, then 12 16 20 24 32 48 64 (FD) or 8 (classic). */
uint32_t att_fdcan_dlc_to_len(uint32_t dlc, bool fd);
/** The smallest data length code whose length holds len bytes (len 0 .. 64; 15 above). */
uint32_t att_fdcan_len_to_dlc(uint32_t len);

/**
 * Configure the controller for the node (att_node_init done): leave clock stop, enter initialisation
 * mode with configuration change enabled, CAN FD operation and bit rate switching when the node has a
 * data bitrate, the bit timing of att_fdcan_hal_timing for the node's bitrate(s), the message RAM (G4:
 * the instance's RAM cleared; H7: the sections of the layout cleared and configured), the acceptance
 * filter, Rx FIFO 0 blocking (a full FIFO loses new frames: counted in rx_overruns), Tx FIFO mode,
 * interrupts off, then normal operation; registers att_fdcan_hal_bus_diag with the node
 * (att_node_set_bus_diag: ATT_ERR_SETTINGS when the node's outputs with ATT_DIAG_BUS do not fit the
 * bus; a later failure removes the hook again). layout NULL means att_fdcan_layout_g4.
 * ATT_ERR_NULL (h, node, an io function), ATT_ERR_SETTINGS: the layout (att_fdcan_hal_layout_check);
 * a bitrate the kernel clock cannot make; a CAN FD bus (data_bitrate > 0) with elements under 64 data
 * bytes; a receive ID that is not 11 bits or more filter elements than the layout holds; ENDN does
 * not read ATT_FDCAN_ENDN_VALUE (wrong base, peripheral clock off); the controller did not
 * acknowledge clock stop exit, init or normal mode within ATT_FDCAN_HAL_SPIN reads. Nothing is
 * written to the controller before the settings are validated.
 */
att_status_t att_fdcan_hal_init(att_fdcan_hal_t *h, att_fdcan_hal_io_t regs, att_fdcan_hal_io_t ram,
                                const att_fdcan_layout_t *layout, att_node_t *node, uint32_t kernel_hz);

/** Move the frames in Rx FIFO 0 (at most its size per call) into the node (att_node_rx); returns the frames moved. */
size_t att_fdcan_hal_receive(att_fdcan_hal_t *h);

/**
 * Queue one frame of your own in the Tx FIFO (the node's frames go through att_fdcan_hal_transmit).
 * Standard IDs only; classic frames 0 .. 8 bytes; CAN FD frames (f->fd) up to 64 bytes on a CAN FD
 * controller, a length between two DLC lengths padded with zeros to the next one (e.g. 13 -> 16),
 * with bit rate switch when the data bitrate is above the nominal one. ATT_OK; ATT_ERR_NULL;
 * ATT_ERR_SETTINGS when the frame cannot be sent as configured (counted in tx_unsupported);
 * ATT_ERR_STATE when the Tx FIFO is full, the controller is in initialisation, or bus-off (back-off,
 * recovery).
 */
att_status_t att_fdcan_hal_send(att_fdcan_hal_t *h, const att_can_frame_t *f);

/**
 * Fill the free Tx FIFO elements from the node's tx ring (att_node_tx); returns the frames written.
 * Nothing while the controller is bus-off (phase not ATT_FDCAN_HAL_ON): the frames wait in the node.
 */
size_t att_fdcan_hal_transmit(att_fdcan_hal_t *h);

/**
 * Controller faults (bus-off back-off and recovery, error-passive, error warning, last error code;
 * see the file comment), receive, att_node_poll, transmit; returns the filter steps run.
 */
size_t att_fdcan_hal_service(att_fdcan_hal_t *h);

/**
 * The node's hook of ATT_DIAG_BUS (att_node_bus_diag_fn; ctx = the att_fdcan_hal_t): the state (bus-off
 * while not ATT_FDCAN_HAL_ON, else error-passive / warning / active by PSR) and the counters of
 * h->stats. att_fdcan_hal_init registers it; register it again after an att_node_init of the same node.
 */
void att_fdcan_hal_bus_diag(void *ctx, att_can_bus_diag_t *d);

#ifdef __cplusplus
}
#endif

#endif /* ATT_FDCAN_HAL_H */
