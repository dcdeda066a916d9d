/**
 * @file att_can_hal.h
 * @brief CAN HAL of the attica node for a bxCAN-style controller (STM32F1/F2/F4/F7 "bxCAN" register map).
 *
 * Moves frames between the controller and an att_node_t: receive FIFO 0 -> att_node_rx,
 * att_node_poll, att_node_tx -> transmit mailboxes. Classic CAN only (bxCAN has no CAN FD): the node
 * must run with fd = false. The acceptance filter passes exactly the node's receive IDs
 * (att_node_rx_ids: IMU_GYRO, IMU_ACC, IMU_MAG, IMU_FD in builds with CAN FD, CMD, each + id_offset)
 * as standard data frames into FIFO 0; the controller drops everything else (other nodes' traffic,
 * extended-ID and remote frames) without the CPU seeing it. Should such a frame reach FIFO 0 anyway
 * (a filter bank of your own), the driver drops it (counted in rx_ignored) or the node counts it in
 * unknown_ids.
 *
 * The filter banks belong to CAN1 (or the one bxCAN of the part): on a dual-CAN part, CAN2's banks
 * start at FMR.CAN2SB in CAN1's register block, which this driver does not program; use CAN1.
 *
 * Every register access goes through att_can_hal_io_t (read/write of a 32-bit register at a byte
 * offset), so the driver runs unchanged against the real peripheral (att_can_hal_mmio: ctx = the
 * peripheral base address, e.g. (void *)0x40006400 for CAN1 on an STM32F4) and against a fake
 * register block in a host unit test (tests/c/att_can_hal_test.c). No heap, no time source: waits
 * for the controller are bounded loops (ATT_CAN_HAL_SPIN), and the bus-off back-off counts service calls.
 *
 * Controller faults (att_can_hal_service, every call): automatic bus-off management (MCR.ABOM) is off.
 * When ESR.BOFF is seen the driver counts the episode, aborts the frames still pending in the mailboxes
 * (TSR.ABRQx; counted in tx_aborted: a frame left there would be retried after the recovery and could
 * take the controller bus-off again unseen, and with ABOM clear it would then wait for ever), stops
 * filling the mailboxes and waits
 * h->backoff service calls (ATT_CAN_HAL_BACKOFF_FIRST, doubled at each bus-off up to
 * ATT_CAN_HAL_BACKOFF_MAX, back to FIRST after ATT_CAN_HAL_BACKOFF_RESET calls in a row neither bus-off
 * nor error-passive); then it starts the recovery (MCR.INRQ set until MSR.INAK, then cleared: the
 * controller rejoins after 128 x 11 recessive bits, ESR.BOFF clear, counted in recoveries). A node
 * whose transceiver or bit timing is wrong so rejoins at most once per ATT_CAN_HAL_BACKOFF_MAX calls
 * instead of flooding the bus with error frames. Error-passive (ESR.EPVF) and error warning (ESR.EWGF)
 * entries are counted on the edge seen by the service (bus-off holds until the driver recovers, so it
 * is never missed), receive FIFO overruns (RF0R/RF1R.FOVR) counted and cleared, the last error code
 * (ESR.LEC) kept. att_can_hal_init registers att_can_hal_bus_diag with the node
 * (att_node_set_bus_diag): every ATT_DIAG the node sends is followed by an ATT_DIAG_BUS with these
 * counters. Call the service at a steady rate (each sample, a timer tick) for the delays to be a time.
 *
 * @code
 * static att_node_t node;
 * static att_can_hal_t can;
 * att_node_settings_t ns;
 * if (att_node_settings_default(ATT_FILTER_ARS, 285.714f, &ns) != ATT_OK) { ... }  // kind, rate in Hz
 * if (att_node_init(&node, &ns) != ATT_OK) { ... }
 * if (att_can_hal_init(&can, att_can_hal_mmio((void *)0x40006400u), &node, 42000000u) != ATT_OK) { ... }
 * for (;;) { (void)att_can_hal_service(&can); }   // or: on the RX interrupt / a timer tick
 * @endcode
 *
 * att_can_hal_service (= receive, att_node_poll, transmit) must not run concurrently with itself or
 * with other calls on the same node: call it from one context (main loop, or one interrupt).
 */
#ifndef ATT_CAN_HAL_H
#define ATT_CAN_HAL_H

#include <stddef.h>
#include <stdint.h>

#include "attica/att_node.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/**
 * Register offsets (bytes from the base) and bits of the bxCAN controller (RM0090 section 32.9, "CAN
 * registers"; the same in RM0008 / RM0033 / RM0390 bxCAN chapters).
 */
enum {
    ATT_BXCAN_MCR = 0x000,  /**< master control */
    ATT_BXCAN_MSR = 0x004,  /**< master status */
    ATT_BXCAN_TSR = 0x008,  /**< transmit status */
    ATT_BXCAN_RF0R = 0x00C, /**< receive FIFO 0 */
    ATT_BXCAN_RF1R = 0x010, /**< receive FIFO 1 (the driver's filter sends nothing there; a bank of yours could) */
    ATT_BXCAN_IER = 0x014,  /**< interrupt enable */
    ATT_BXCAN_ESR = 0x018,  /**< error status */
    ATT_BXCAN_BTR = 0x01C,  /**< bit timing */
    ATT_BXCAN_TI0R = 0x180, /**< transmit mailbox 0 identifier; mailbox n at + 0x10 n */
    ATT_BXCAN_TDT0R = 0x184,
    ATT_BXCAN_TDL0R = 0x188,
    ATT_BXCAN_TDH0R = 0x18C,
    ATT_BXCAN_RI0R = 0x1B0, /**< receive FIFO 0 output mailbox identifier */
    ATT_BXCAN_RDT0R = 0x1B4,
    ATT_BXCAN_RDL0R = 0x1B8,
    ATT_BXCAN_RDH0R = 0x1BC,
    ATT_BXCAN_FMR = 0x200,  /**< filter master (FINIT; CAN2SB on dual-CAN parts) */
    ATT_BXCAN_FM1R = 0x204, /**< filter mode, bit per bank (0 = identifier mask, 1 = identifier list) */
    ATT_BXCAN_FS1R = 0x20C, /**< filter scale, bit per bank (0 = two 16-bit filters per register, 1 = 32 bit) */
    ATT_BXCAN_FFA1R = 0x214, /**< filter FIFO assignment, bit per bank (0 = FIFO 0) */
    ATT_BXCAN_FA1R = 0x21C, /**< filter activation, bit per bank */
    ATT_BXCAN_F0R1 = 0x240, /**< filter bank 0 register 1; bank n at + ATT_BXCAN_BANK_STRIDE n */
    ATT_BXCAN_F0R2 = 0x244, /**< filter bank 0 register 2 */
    ATT_BXCAN_BANK_STRIDE = 0x8, /**< bytes between the registers of two filter banks */
    ATT_BXCAN_BANKS = 28    /**< filter banks of a dual-CAN part (STM32F4: 28, shared with CAN2; single CAN: 14) */
};

#define ATT_BXCAN_MCR_INRQ ((uint32_t)1u << 0)
#define ATT_BXCAN_MCR_SLEEP ((uint32_t)1u << 1)
#define ATT_BXCAN_MCR_TXFP ((uint32_t)1u << 2)  /**< transmit in request order (not by ID) */
#define ATT_BXCAN_MCR_ABOM ((uint32_t)1u << 6)  /**< automatic bus-off management (left clear: the driver recovers) */
#define ATT_BXCAN_MSR_INAK ((uint32_t)1u << 0)
#define ATT_BXCAN_MSR_SLAK ((uint32_t)1u << 1)
#define ATT_BXCAN_TSR_TME0 ((uint32_t)1u << 26) /**< mailbox 0 empty; TME1, TME2 follow */
#define ATT_BXCAN_TSR_ABRQ0 ((uint32_t)1u << 7) /**< abort request of mailbox 0; mailbox n at bit 7 + 8 n */
#define ATT_BXCAN_RF0R_FMP0 ((uint32_t)3u << 0) /**< messages pending in FIFO 0 */
#define ATT_BXCAN_RF0R_FULL0 ((uint32_t)1u << 3)
#define ATT_BXCAN_RF0R_FOVR0 ((uint32_t)1u << 4) /**< FIFO 0 overrun (write 1 to clear); RF1R.FOVR1 the same bit */
#define ATT_BXCAN_RF0R_RFOM0 ((uint32_t)1u << 5) /**< release the FIFO 0 output mailbox */
#define ATT_BXCAN_ESR_EWGF ((uint32_t)1u << 0) /**< error warning: TEC or REC >= 96 (read only) */
#define ATT_BXCAN_ESR_EPVF ((uint32_t)1u << 1) /**< error passive: TEC or REC > 127 (read only) */
#define ATT_BXCAN_ESR_BOFF ((uint32_t)1u << 2) /**< bus-off: TEC > 255 (read only) */
#define ATT_BXCAN_ESR_LEC_SHIFT 4u             /**< LEC[2:0] at bits 6:4: 0 none, 1..6 error, 7 set by software */
#define ATT_BXCAN_TIR_TXRQ ((uint32_t)1u << 0)
#define ATT_BXCAN_RIR_RTR ((uint32_t)1u << 1)
#define ATT_BXCAN_RIR_IDE ((uint32_t)1u << 2)
#define ATT_BXCAN_FMR_FINIT ((uint32_t)1u << 0)

/** Busy-wait bound for the controller's acknowledgements (loop iterations). */
#define ATT_CAN_HAL_SPIN 100000u
#ifndef ATT_CAN_HAL_BACKOFF_FIRST
/** Service calls from the first bus-off to its recovery (then 2, 4 ... times this). */
#define ATT_CAN_HAL_BACKOFF_FIRST 1u
#endif
#ifndef ATT_CAN_HAL_BACKOFF_MAX
/** Longest back-off, service calls (the doubling stops here). */
#define ATT_CAN_HAL_BACKOFF_MAX 1024u
#endif
#ifndef ATT_CAN_HAL_BACKOFF_RESET
/** Service calls in a row neither bus-off nor error-passive that bring the back-off back to FIRST. */
#define ATT_CAN_HAL_BACKOFF_RESET 1024u
#endif

/** Where the driver stands with the bus (att_can_hal_t.phase). */
typedef enum {
    ATT_CAN_HAL_ON = 0,        /**< on the bus: the mailboxes are filled from the node */
    ATT_CAN_HAL_BACKOFF = 1,   /**< bus-off seen: waiting h->wait service calls, nothing written to the mailboxes */
    ATT_CAN_HAL_RECOVERING = 2 /**< recovery started (INRQ set and cleared): waiting for ESR.BOFF to clear */
} att_can_hal_phase_t;
/**
 * Filter banks the driver owns: 0 .. ATT_CAN_HAL_FILTER_BANKS - 1, four of the node's IDs each (16-bit
 * identifier list mode), enough for ATT_NODE_RX_IDS_MAX. Other banks are left as they are (inactive
 * after reset): code of yours that activates one routes more frames into FIFO 0.
 */
#define ATT_CAN_HAL_FILTER_BANKS 2u

/** Register access: 32-bit read and write at a byte offset from the controller's base. */
typedef struct {
    void *ctx;                                                  /**< base address or fake state */
    uint32_t (*read)(void *ctx, uint32_t offset);              /**< read register at offset */
    void (*write)(void *ctx, uint32_t offset, uint32_t value); /**< write register at offset */
} att_can_hal_io_t;

/** Driver counters. */
typedef struct {
    uint32_t rx_frames;      /**< frames moved from FIFO 0 to the node */
    uint32_t rx_ignored;     /**< extended-ID or remote frames dropped (the filter keeps them out of FIFO 0) */
    uint32_t rx_overruns;    /**< FIFO 0 overruns seen (frames lost in the controller) */
    uint32_t rx_node_full;   /**< frames att_node_rx refused (node rx ring full) */
    uint32_t tx_frames;      /**< frames written to a transmit mailbox */
    uint32_t tx_unsupported; /**< CAN FD / long frames from the node that bxCAN cannot send (dropped) */
    uint32_t tx_aborted;     /**< frames aborted in the mailboxes at a bus-off (lost: the host sees a set cut) */
    uint32_t bus_off;        /**< bus-off episodes (ESR.BOFF seen set while on the bus) */
    uint32_t recoveries;     /**< bus-off episodes ended: ESR.BOFF clear again after the driver's recovery */
    uint32_t recovery_timeouts; /**< recoveries not started: MSR.INAK never came (retried after the next back-off) */
    uint32_t error_passive;  /**< entries into error-passive (ESR.EPVF seen set after clear) */
    uint32_t error_warning;  /**< entries into error warning (ESR.EWGF seen set after clear) */
    uint32_t lec;            /**< the last error code ESR.LEC reported (1 .. 6), 0 none yet */
} att_can_hal_stats_t;

/** A bxCAN controller serving one attica node. */
typedef struct {
    att_can_hal_io_t io;       /**< register access */
    att_node_t *node;          /**< the node */
    uint32_t btr;              /**< bit timing register value in use */
    att_can_hal_phase_t phase; /**< on the bus, in back-off, recovering */
    uint32_t backoff;          /**< service calls the next bus-off waits (FIRST .. MAX) */
    uint32_t wait;             /**< ATT_CAN_HAL_BACKOFF: service calls left before the recovery */
    uint32_t good;             /**< service calls in a row on the bus, not error-passive (up to RESET) */
    bool passive;              /**< ESR.EPVF at the last service */
    bool warning;              /**< ESR.EWGF at the last service */
    att_can_hal_stats_t stats; /**< counters */
} att_can_hal_t;

/** Register access to a memory-mapped controller at base (volatile 32-bit loads and stores). */
att_can_hal_io_t att_can_hal_mmio(void *base);

/**
 * Bit timing register value for bitrate with the CAN kernel clock pclk_hz: 8..25 time quanta per bit,
 * sample point at 87.5 % (rounded), SJW 1 tq. 0 when no prescaler 1..1024 gives the exact bitrate.
 */
uint32_t att_can_hal_btr(uint32_t pclk_hz, uint32_t bitrate);

/**
 * Configure the controller for the node (att_node_init done, classic CAN): init mode, bit timing for
 * the node's bitrate from the CAN kernel clock pclk_hz (Hz; APB1 on STM32F4), automatic bus-off
 * management off (the driver recovers with a back-off), transmit in request order, the acceptance
 * filter for the node's receive IDs (banks 0 and 1 in 16-bit identifier list mode into FIFO 0, see
 * ATT_CAN_HAL_FILTER_BANKS), then normal mode; registers att_can_hal_bus_diag with the node. Polled:
 * no interrupt is enabled. ATT_ERR_NULL (h, io functions or node NULL), ATT_ERR_SETTINGS (fd node,
 * bitrate not reachable from pclk_hz, a receive ID that is not an 11-bit ID, the node's outputs with
 * ATT_DIAG_BUS over the bus (att_node_set_bus_diag), or the controller did not acknowledge init /
 * normal mode within ATT_CAN_HAL_SPIN reads: then the node has no bus diagnostics hook).
 */
att_status_t att_can_hal_init(att_can_hal_t *h, att_can_hal_io_t io, att_node_t *node, uint32_t pclk_hz);

/** Move every pending FIFO 0 frame into the node (att_node_rx); returns the frames moved. */
size_t att_can_hal_receive(att_can_hal_t *h);

/**
 * Fill the free transmit mailboxes from the node's tx ring (att_node_tx); returns the frames written.
 * Nothing while the controller is bus-off (phase not ATT_CAN_HAL_ON): the frames wait in the node.
 */
size_t att_can_hal_transmit(att_can_hal_t *h);

/**
 * Controller faults (bus-off back-off and recovery, error-passive, error warning, last error code;
 * see the file comment), receive, att_node_poll, transmit; returns the filter steps run.
 */
size_t att_can_hal_service(att_can_hal_t *h);

/**
 * The node's hook of ATT_DIAG_BUS (att_node_bus_diag_fn; ctx = the att_can_hal_t): the state (bus-off
 * while not ATT_CAN_HAL_ON, else error-passive / warning / active by ESR) and the counters of h->stats.
 * att_can_hal_init registers it; register it again after an att_node_init of the same node.
 */
void att_can_hal_bus_diag(void *ctx, att_can_bus_diag_t *d);

#ifdef __cplusplus
}
#endif

#endif /* ATT_CAN_HAL_H */
