/**
 * @file att_fdcan_hal_test.c
 * @brief Host unit test of the FDCAN / M_CAN HAL (firmware/ports/cortex_m/att_fdcan_hal.c) against a fake
 * controller: a register block and a message RAM, in both register maps (STM32G4 fixed RAM, STM32H7
 * configurable RAM).
 *
 * The fake models what the driver relies on, from the registers and the RAM the driver wrote:
 * - CCCR: INIT acknowledged (or never, to test the timeout), CCE only with INIT, the configuration
 *   bits and the protected registers (bit timing, filter and RAM configuration) writable only with
 *   INIT and CCE set (a write without them is ignored and counted); clock stop request / acknowledge;
 *   ENDN;
 * - acceptance filtering (mcan_fifo0_accepts: the M_CAN rules - remote frame rejection, the standard
 *   filter list in order up to the first matching enabled element, its SFT type and SFEC action, then
 *   the global filter for non-matching frames - evaluated on the filter elements in the message RAM);
 * - Rx FIFO 0 in the message RAM at the configured place and element size: fill level, get/put index,
 *   acknowledge, blocking mode (a frame arriving at a full FIFO is lost and sets RF0L), data beyond the
 *   element's data size not stored;
 * - the Tx buffers as a FIFO: free level, put index, TXBAR capturing the element (ID, XTD, RTR, FDF,
 *   BRS, DLC, data) until the test lets the bus take it;
 * - bus-off: PSR.BO with CCCR.INIT set, as the controller does; PSR.EP / EW / LEC set by the test, LEC
 *   set to 7 by every read of PSR (M_CAN "set on read"); a log of the CCCR writes.
 * A real attica node runs behind the driver: classic IMU frames or IMU_FD frames go in, output sets
 * (classic frames or ATT_OUT_FD) come out and must equal (bit for bit) a filter stepped directly on
 * the decoded samples.
 *
 * Controller faults (test_bus_faults, both maps): bus-off -> nothing queued during the back-off nor
 * during the recovery, the recovery is exactly one CCCR write clearing INIT and CCE (configuration
 * kept, no protected write refused), the back-off doubles from ATT_FDCAN_HAL_BACKOFF_FIRST to
 * ATT_FDCAN_HAL_BACKOFF_MAX and starts over after ATT_FDCAN_HAL_BACKOFF_RESET good service calls (not
 * before, not across an error-passive call), error-passive and warning counted once per entry, IR.RF0L
 * and IR.RF1L counted and cleared, and the ATT_DIAG_BUS frame after each ATT_DIAG carries them (printed
 * as "diag_bus ..." lines that tests/test_cross.py decodes with the host's codec).
 *
 * Prints "ok ..." / "FAIL ..." per check; exit status = number of failures.
 */
#include <stdio.h>
#include <string.h>

#define ATT_HAL_TEST_SEED 7u
#include "att_hal_test_common.h"

#include "att_fdcan_hal.h"
#include "attica/att_can.h"
#include "attica/att_config.h"
#include "attica/att_filter.h"
#include "attica/att_node.h"

#define FAKE_RAM_BYTES 0x2800u
#define FAKE_TX_LOG 4096u
#define FAKE_PATTERN 0xa5a5a5a5u
#define G4_RAM_BYTES 0x350u
#define KERNEL_HZ 160000000u

typedef struct {
    att_can_frame_t f;
    uint32_t dlc;
    int brs;
    int xtd;
    int rtr;
} tx_entry_t;

typedef struct {
    att_fdcan_variant_t variant;
    uint32_t reg[0x400 / 4];
    uint32_t ram[FAKE_RAM_BYTES / 4];
    int ack_init;       /* 0: INIT never changes (a controller without clock) */
    uint32_t endn;      /* what ENDN reads */
    uint32_t rx_gi;     /* Rx FIFO 0 get index */
    uint32_t rx_fill;   /* Rx FIFO 0 fill level */
    uint32_t tx_gi;     /* Tx FIFO get index (next element the bus takes) */
    uint32_t tx_pend;   /* Tx FIFO elements pending */
    tx_entry_t tx_log[FAKE_TX_LOG];
    uint32_t tx_n;
    uint32_t writes;           /* every register and RAM write */
    uint32_t denied;           /* protected writes without INIT and CCE */
    uint32_t bad_txbar;        /* TXBAR bits other than the put index, or into a full FIFO */
    uint32_t ram_outside;      /* RAM writes outside the instance's share */
    uint32_t filtered;         /* frames the acceptance filter kept out */
    uint32_t lost;             /* frames lost at a full FIFO */
    uint32_t not_running;      /* frames on the bus while INIT was set */
    uint32_t cccr_log[16];     /* the first CCCR writes since the test last cleared cccr_n */
    uint32_t cccr_n;           /* CCCR writes */
} fake_t;

static fake_t fake;
static att_fdcan_layout_t lay_h7;      /* FD elements, at 0x400 (another instance's share before it) */
static att_fdcan_layout_t lay_h7_cls;  /* classic elements of 8 bytes */
static uint32_t lay_h7_end;

/* ---- the fake's view of its configuration ------------------------------------------------------- */

static const uint8_t dlc_len_fd[16] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64};

static uint32_t size_of_code(uint32_t code) { return dlc_len_fd[8u + (code & 7u)]; }

static uint32_t r(const fake_t *f, uint32_t off) { return f->reg[off / 4u]; }

static uint32_t cfg_gfc(const fake_t *f)
{
    return r(f, f->variant == ATT_FDCAN_G4 ? ATT_FDCAN_G4_RXGFC : ATT_FDCAN_H7_GFC);
}

static uint32_t cfg_lss(const fake_t *f)
{
    return f->variant == ATT_FDCAN_G4 ? (r(f, ATT_FDCAN_G4_RXGFC) >> 16) & 0x1fu
                                      : (r(f, ATT_FDCAN_H7_SIDFC) >> 16) & 0xffu;
}

static uint32_t cfg_lse(const fake_t *f)
{
    return f->variant == ATT_FDCAN_G4 ? (r(f, ATT_FDCAN_G4_RXGFC) >> 24) & 0xfu
                                      : (r(f, ATT_FDCAN_H7_XIDFC) >> 16) & 0x7fu;
}

static uint32_t cfg_flssa(const fake_t *f)
{
    return f->variant == ATT_FDCAN_G4 ? 0u : r(f, ATT_FDCAN_H7_SIDFC) & 0xfffcu;
}

static uint32_t cfg_rx_start(const fake_t *f)
{
    return f->variant == ATT_FDCAN_G4 ? 0x0b0u : r(f, ATT_FDCAN_H7_RXF0C) & 0xfffcu;
}

static uint32_t cfg_rx_n(const fake_t *f)
{
    return f->variant == ATT_FDCAN_G4 ? 3u : (r(f, ATT_FDCAN_H7_RXF0C) >> 16) & 0x7fu;
}

static uint32_t cfg_rx_data(const fake_t *f)
{
    return f->variant == ATT_FDCAN_G4 ? 64u : size_of_code(r(f, ATT_FDCAN_H7_RXESC));
}

static uint32_t cfg_tx_start(const fake_t *f)
{
    return f->variant == ATT_FDCAN_G4 ? 0x278u : r(f, ATT_FDCAN_TXBC) & 0xfffcu;
}

static uint32_t cfg_tx_n(const fake_t *f)
{
    return f->variant == ATT_FDCAN_G4 ? 3u : (r(f, ATT_FDCAN_TXBC) >> 24) & 0x3fu;
}

static uint32_t cfg_tx_data(const fake_t *f)
{
    return f->variant == ATT_FDCAN_G4 ? 64u : size_of_code(r(f, ATT_FDCAN_H7_TXESC));
}

static uint32_t rf0l_bit(const fake_t *f)
{
    return f->variant == ATT_FDCAN_G4 ? ATT_FDCAN_G4_IR_RF0L : ATT_FDCAN_H7_IR_RF0L;
}


/*
 * M_CAN acceptance filtering (RM0440 "Acceptance filtering"; Bosch M_CAN user's manual): does a frame
 * (11-bit id, or 29-bit id when ext; remote when rtr) get stored in Rx FIFO 0?
 * - standard frames: a remote frame is rejected when RRFS is set; otherwise the LSS elements of the
 *   standard filter list at FLSSA are tried in order: an element with SFEC 000 or SFT 11 is disabled
 *   and skipped; SFT 00 matches SFID1 <= id <= SFID2, 01 id == SFID1 or id == SFID2, 10 (id & SFID2)
 *   == (SFID1 & SFID2); filtering stops at the first match and its SFEC decides: 001 / 101 store in
 *   FIFO 0, 010 / 110 FIFO 1, 011 reject, 100 priority only (not stored: not FIFO 0 here), 111 an Rx
 *   buffer / debug message (not FIFO 0). No match: ANFS 00 FIFO 0, 01 FIFO 1, 1x reject.
 * - extended frames: rejected when remote and RRFE is set; with an extended filter list (LSE > 0,
 *   which the driver never configures) the model answers "accepted" so that the test fails;
 *   otherwise ANFE decides like ANFS.
 */
static int mcan_fifo0_accepts(const fake_t *f, uint32_t id, int ext, int rtr)
{
    const uint32_t gfc = cfg_gfc(f);
    uint32_t i;
    if (ext) {
        if (rtr && (gfc & 1u) != 0u) {
            return 0;
        }
        if (cfg_lse(f) != 0u) {
            return 1;
        }
        return ((gfc >> 2) & 3u) == 0u;
    }
    if (rtr && (gfc & 2u) != 0u) {
        return 0;
    }
    for (i = 0u; i < cfg_lss(f); i++) {
        const uint32_t e = f->ram[(cfg_flssa(f) + 4u * i) / 4u];
        const uint32_t sft = e >> 30;
        const uint32_t sfec = (e >> 27) & 7u;
        const uint32_t id1 = (e >> 16) & 0x7ffu;
        const uint32_t id2 = e & 0x7ffu;
        int match;
        if (sfec == 0u || sft == 3u) {
            continue;
        }
        match = (sft == 0u)   ? (id1 <= id && id <= id2)
                : (sft == 1u) ? (id == id1 || id == id2)
                              : ((id & id2) == (id1 & id2));
        if (match) {
            return sfec == 1u || sfec == 5u;
        }
    }
    return ((gfc >> 4) & 3u) == 0u;
}

/* ---- the fake's register and RAM behaviour -------------------------------------------------------- */

static int is_protected(const fake_t *f, uint32_t off)
{
    if (off == ATT_FDCAN_NBTP || off == ATT_FDCAN_DBTP || off == ATT_FDCAN_TDCR || off == ATT_FDCAN_TXBC ||
        off == ATT_FDCAN_TEST) {
        return 1;
    }
    if (f->variant == ATT_FDCAN_G4) {
        return off == ATT_FDCAN_G4_RXGFC;
    }
    return off == ATT_FDCAN_H7_GFC || off == ATT_FDCAN_H7_SIDFC || off == ATT_FDCAN_H7_XIDFC ||
           off == ATT_FDCAN_H7_RXF0C || off == ATT_FDCAN_H7_RXF1C || off == ATT_FDCAN_H7_RXBC ||
           off == ATT_FDCAN_H7_RXESC || off == ATT_FDCAN_H7_TXESC || off == ATT_FDCAN_H7_TXEFC;
}

static uint32_t rxf0s_off(const fake_t *f)
{
    return f->variant == ATT_FDCAN_G4 ? ATT_FDCAN_G4_RXF0S : ATT_FDCAN_H7_RXF0S;
}

static uint32_t rxf0a_off(const fake_t *f)
{
    return f->variant == ATT_FDCAN_G4 ? ATT_FDCAN_G4_RXF0A : ATT_FDCAN_H7_RXF0A;
}

static uint32_t txbar_off(const fake_t *f)
{
    return f->variant == ATT_FDCAN_G4 ? ATT_FDCAN_G4_TXBAR : ATT_FDCAN_H7_TXBAR;
}

static uint32_t fake_read(void *ctx, uint32_t off)
{
    fake_t *f = (fake_t *)ctx;
    if (off == ATT_FDCAN_ENDN) {
        return f->endn;
    }
    if (off == ATT_FDCAN_PSR) {
        const uint32_t v = f->reg[off / 4u];
        f->reg[off / 4u] |= ATT_FDCAN_PSR_LEC; /* LEC reads 7 ("no change") until the next bus event */
        return v;
    }
    if (off == rxf0s_off(f)) {
        const uint32_t n = cfg_rx_n(f);
        const uint32_t pi = n ? (f->rx_gi + f->rx_fill) % n : 0u;
        return f->rx_fill | (f->rx_gi << 8) | (pi << 16) | ((n != 0u && f->rx_fill == n) ? (1u << 24) : 0u) |
               ((r(f, ATT_FDCAN_IR) & rf0l_bit(f)) ? ATT_FDCAN_RXFS_RFL : 0u);
    }
    if (off == ATT_FDCAN_TXFQS) {
        const uint32_t n = cfg_tx_n(f);
        const uint32_t free_n = n - f->tx_pend;
        const uint32_t pi = n ? (f->tx_gi + f->tx_pend) % n : 0u;
        return free_n | (f->tx_gi << 8) | (pi << 16) | (free_n == 0u ? ATT_FDCAN_TXFQS_TFQF : 0u);
    }
    return f->reg[off / 4u];
}

static void fake_capture_tx(fake_t *f, uint32_t b)
{
    const uint32_t base = (cfg_tx_start(f) + b * (8u + cfg_tx_data(f))) / 4u;
    const uint32_t t0 = f->ram[base];
    const uint32_t t1 = f->ram[base + 1u];
    tx_entry_t e;
    uint32_t i;
    memset(&e, 0, sizeof e);
    e.xtd = (t0 & ATT_FDCAN_E0_XTD) != 0u;
    e.rtr = (t0 & ATT_FDCAN_E0_RTR) != 0u;
    e.f.id = e.xtd ? (t0 & 0x1fffffffu) : ((t0 >> 18) & 0x7ffu);
    e.f.fd = (uint8_t)((t1 & ATT_FDCAN_E1_FDF) != 0u);
    e.brs = (t1 & ATT_FDCAN_E1_BRS) != 0u;
    e.dlc = (t1 >> 16) & 0xfu;
    e.f.len = (uint8_t)(e.f.fd ? dlc_len_fd[e.dlc] : (e.dlc > 8u ? 8u : e.dlc));
    for (i = 0u; i < e.f.len && i < cfg_tx_data(f); i++) {
        e.f.data[i] = (uint8_t)(f->ram[base + 2u + i / 4u] >> (8u * (i % 4u)));
    }
    if (f->tx_n < FAKE_TX_LOG) {
        f->tx_log[f->tx_n++] = e;
    }
}

static void fake_write(void *ctx, uint32_t off, uint32_t value)
{
    fake_t *f = (fake_t *)ctx;
    const uint32_t cccr = f->reg[ATT_FDCAN_CCCR / 4];
    const int config = (cccr & ATT_FDCAN_CCCR_INIT) && (cccr & ATT_FDCAN_CCCR_CCE);
    f->writes++;
    if (off == ATT_FDCAN_CCCR) {
        const uint32_t keep = ATT_FDCAN_CCCR_INIT | ATT_FDCAN_CCCR_CCE | ATT_FDCAN_CCCR_CSA | ATT_FDCAN_CCCR_CSR;
        uint32_t v = config ? (value & ~keep) : (cccr & ~keep);
        uint32_t init = f->ack_init ? (value & ATT_FDCAN_CCCR_INIT) : (cccr & ATT_FDCAN_CCCR_INIT);
        if (!config && ((value ^ cccr) & ~keep) != 0u) {
            f->denied++;
        }
        v |= init;
        if (init && (cccr & ATT_FDCAN_CCCR_INIT)) {
            v |= value & ATT_FDCAN_CCCR_CCE; /* CCE only while INIT is set; cleared with INIT */
        }
        v |= value & ATT_FDCAN_CCCR_CSR;
        if (f->ack_init && (value & ATT_FDCAN_CCCR_CSR)) {
            v |= ATT_FDCAN_CCCR_CSA;
        }
        f->reg[off / 4u] = v;
        if (f->cccr_n < 16u) {
            f->cccr_log[f->cccr_n] = value;
        }
        f->cccr_n++;
        return;
    }
    if (is_protected(f, off)) {
        if (config) {
            f->reg[off / 4u] = value;
        } else {
            f->denied++;
        }
        return;
    }
    if (off == ATT_FDCAN_IR) {
        f->reg[off / 4u] &= ~value;
        return;
    }
    if (off == rxf0a_off(f)) {
        const uint32_t n = cfg_rx_n(f);
        if (n != 0u && f->rx_fill > 0u && value < n) {
            uint32_t count = (value + n - f->rx_gi) % n + 1u;
            count = count > f->rx_fill ? f->rx_fill : count;
            f->rx_fill -= count;
            f->rx_gi = (value + 1u) % n;
        }
        return;
    }
    if (off == txbar_off(f)) {
        const uint32_t n = cfg_tx_n(f);
        uint32_t b;
        for (b = 0u; b < 32u; b++) {
            if ((value >> b) & 1u) {
                if (n == 0u || f->tx_pend == n || b != (f->tx_gi + f->tx_pend) % n) {
                    f->bad_txbar++;
                } else {
                    fake_capture_tx(f, b);
                    f->tx_pend++;
                }
            }
        }
        return;
    }
    f->reg[off / 4u] = value;
}

static int ram_in_share(const fake_t *f, uint32_t off, const att_fdcan_layout_t *l)
{
    const uint32_t el = 8u + l->data_bytes;
    if (f->variant == ATT_FDCAN_G4) {
        return off < G4_RAM_BYTES;
    }
    return (off >= l->filters && off < l->filters + 4u * l->filters_max) ||
           (off >= l->rx_fifo0 && off < l->rx_fifo0 + l->rx_fifo0_n * el) ||
           (off >= l->tx_fifo && off < l->tx_fifo + l->tx_fifo_n * el);
}

static const att_fdcan_layout_t *fake_share;

static uint32_t fake_ram_read(void *ctx, uint32_t off)
{
    const fake_t *f = (const fake_t *)ctx;
    return off < FAKE_RAM_BYTES ? f->ram[off / 4u] : 0u;
}

static void fake_ram_write(void *ctx, uint32_t off, uint32_t value)
{
    fake_t *f = (fake_t *)ctx;
    f->writes++;
    if (off >= FAKE_RAM_BYTES || (off & 3u) != 0u || (fake_share != NULL && !ram_in_share(f, off, fake_share))) {
        f->ram_outside++;
        return;
    }
    f->ram[off / 4u] = value;
}

static att_fdcan_hal_io_t regs_io(void)
{
    att_fdcan_hal_io_t io;
    io.ctx = &fake;
    io.read = fake_read;
    io.write = fake_write;
    return io;
}

static att_fdcan_hal_io_t ram_io(void)
{
    att_fdcan_hal_io_t io;
    io.ctx = &fake;
    io.read = fake_ram_read;
    io.write = fake_ram_write;
    return io;
}

/* A controller after reset (INIT set, RAM holding another instance's pattern), one register map. */
static void fake_reset(att_fdcan_variant_t v, const att_fdcan_layout_t *share)
{
    uint32_t i;
    memset(&fake, 0, sizeof fake);
    fake.variant = v;
    fake.ack_init = 1;
    fake.endn = ATT_FDCAN_ENDN_VALUE;
    fake.reg[ATT_FDCAN_CCCR / 4] = ATT_FDCAN_CCCR_INIT;
    for (i = 0u; i < FAKE_RAM_BYTES / 4u; i++) {
        fake.ram[i] = FAKE_PATTERN;
    }
    fake_share = share;
}

static uint32_t len_to_dlc(uint32_t len)
{
    uint32_t d;
    for (d = 0u; d < 15u; d++) {
        if (dlc_len_fd[d] >= len) {
            return d;
        }
    }
    return 15u;
}

/* A frame arrives from the bus (ext: 29-bit id; rtr: remote); 1 when it was stored in Rx FIFO 0. */
static int fake_bus_rx(fake_t *f, const att_can_frame_t *fr, int ext, int rtr, int brs)
{
    const uint32_t n = cfg_rx_n(f);
    const uint32_t dsize = cfg_rx_data(f);
    uint32_t base;
    uint32_t dlc;
    uint32_t i;
    if (r(f, ATT_FDCAN_CCCR) & ATT_FDCAN_CCCR_INIT) {
        f->not_running++;
        return 0;
    }
    if (fr->fd && !(r(f, ATT_FDCAN_CCCR) & ATT_FDCAN_CCCR_FDOE)) {
        f->not_running++; /* a classic controller sees an FD frame as a protocol error */
        return 0;
    }
    if (!mcan_fifo0_accepts(f, fr->id, ext, rtr)) {
        f->filtered++;
        return 0;
    }
    if (f->rx_fill == n) {
        f->reg[ATT_FDCAN_IR / 4] |= rf0l_bit(f);
        f->lost++;
        return 0;
    }
    base = (cfg_rx_start(f) + ((f->rx_gi + f->rx_fill) % n) * (8u + dsize)) / 4u;
    dlc = fr->fd ? len_to_dlc(fr->len) : fr->len;
    f->ram[base] = (ext ? ((fr->id & 0x1fffffffu) | ATT_FDCAN_E0_XTD) : (fr->id << 18)) | (rtr ? ATT_FDCAN_E0_RTR : 0u);
    f->ram[base + 1u] = (dlc << 16) | (fr->fd ? ATT_FDCAN_E1_FDF : 0u) | (brs ? ATT_FDCAN_E1_BRS : 0u);
    for (i = 0u; i < dsize / 4u; i++) {
        f->ram[base + 2u + i] = FAKE_PATTERN; /* stale bytes beyond the frame's data */
    }
    for (i = 0u; i < dlc_len_fd[dlc] && i < dsize; i++) {
        const uint32_t w = base + 2u + i / 4u;
        const uint32_t sh = 8u * (i % 4u);
        const uint8_t byte = (i < fr->len) ? fr->data[i] : 0u;
        f->ram[w] = (f->ram[w] & ~(0xffu << sh)) | ((uint32_t)byte << sh);
    }
    f->rx_fill++;
    return 1;
}

/* The bus takes every frame waiting in the Tx FIFO. */
static void fake_complete_tx(fake_t *f)
{
    const uint32_t n = cfg_tx_n(f);
    if (n != 0u) {
        f->tx_gi = (f->tx_gi + f->tx_pend) % n;
    }
    f->tx_pend = 0u;
}

/* ---- helpers ------------------------------------------------------------------------------------ */

static att_node_t node;
static att_fdcan_hal_t can;

static const char *vname(att_fdcan_variant_t v) { return v == ATT_FDCAN_G4 ? "G4" : "H7"; }

static const att_fdcan_layout_t *layout_for(att_fdcan_variant_t v, int fd)
{
    if (v == ATT_FDCAN_G4) {
        return &att_fdcan_layout_g4;
    }
    return fd ? &lay_h7 : &lay_h7_cls;
}

static att_status_t node_setup(att_node_t *n, int fd, int32_t offset)
{
    att_node_settings_t s;
    att_status_t st = att_node_settings_default(ATT_FILTER_ARS, 100.0f, &s);
    if (st != ATT_OK) {
        return st;
    }
    s.id_offset = offset;
    if (fd) {
        s.fd = true;
        s.data_bitrate = 2000000u;
    }
    return att_node_init(n, &s);
}

static att_status_t hal_setup(att_fdcan_variant_t v, int fd)
{
    const att_fdcan_layout_t *l = layout_for(v, fd);
    fake_reset(v, l);
    return att_fdcan_hal_init(&can, regs_io(), ram_io(), l, &node, KERNEL_HZ);
}

static uint32_t nbtp(uint32_t sjw, uint32_t brp, uint32_t t1, uint32_t t2)
{
    return ((sjw - 1u) << 25) | ((brp - 1u) << 16) | ((t1 - 1u) << 8) | (t2 - 1u);
}

static uint32_t dbtp(uint32_t tdc, uint32_t brp, uint32_t t1, uint32_t t2, uint32_t sjw)
{
    return (tdc << 23) | ((brp - 1u) << 16) | ((t1 - 1u) << 8) | ((t2 - 1u) << 4) | (sjw - 1u);
}

/* ---- tests -------------------------------------------------------------------------------------- */

static void test_timing(void)
{
    att_fdcan_timing_t t;
    char what[160];
    check(att_fdcan_hal_timing(160000000u, 500000u, 2000000u, &t) == ATT_OK && t.nbtp == nbtp(20u, 2u, 139u, 20u) &&
              t.dbtp == dbtp(1u, 2u, 29u, 10u, 10u) && t.tdcr == (60u << 8),
          "160 MHz, 500 kbit/s + 2 Mbit/s: prescaler 2 both phases, 160 tq (SP 87.5 %), 40 tq (SP 75 %), TDC at 60");
    check(att_fdcan_hal_timing(170000000u, 500000u, 0u, &t) == ATT_OK && t.nbtp == nbtp(21u, 2u, 148u, 21u) &&
              t.dbtp == 0u && t.tdcr == 0u,
          "170 MHz, 500 kbit/s classic: prescaler 2 (prescaler 1 needs TSEG1 297 > 256), 170 tq");
    check(att_fdcan_hal_timing(80000000u, 1000000u, 1000000u, &t) == ATT_OK && t.nbtp == nbtp(5u, 2u, 34u, 5u) &&
              t.dbtp == dbtp(0u, 2u, 29u, 10u, 10u) && t.tdcr == 0u,
          "80 MHz, 1 + 1 Mbit/s: no TDC at 1 Mbit/s, prescaler 2 both phases");
    check(att_fdcan_hal_timing(80000000u, 500000u, 8000000u, &t) == ATT_OK && t.dbtp == dbtp(1u, 1u, 7u, 2u, 2u) &&
              t.tdcr == (8u << 8) && t.nbtp == nbtp(20u, 1u, 139u, 20u),
          "80 MHz, 500 kbit/s + 8 Mbit/s: 10 tq data bit, TDCO 8, nominal 160 tq with the same prescaler");
    check(att_fdcan_hal_timing(40000000u, 125000u, 5000000u, &t) == ATT_OK && t.dbtp == dbtp(1u, 1u, 5u, 2u, 2u) &&
              t.tdcr == (6u << 8) && t.nbtp == nbtp(20u, 2u, 139u, 20u),
          "40 MHz, 125 kbit/s + 5 Mbit/s: no common prescaler (nominal 320 tq at 1, data 4 tq at 2): "
          "data 1, nominal 2");
    check(att_fdcan_hal_timing(170000000u, 500000u, 2000000u, &t) == ATT_ERR_SETTINGS && t.nbtp == 0u && t.dbtp == 0u,
          "refused: 170 MHz cannot make 2 Mbit/s with a TDC prescaler of 1 or 2 (85 tq, 42.5 tq)");
    check(att_fdcan_hal_timing(160000000u, 500000u, 250000u, &t) == ATT_ERR_SETTINGS,
          "refused: data bitrate below the nominal one");
    check(att_fdcan_hal_timing(160000000u, 0u, 0u, &t) == ATT_ERR_SETTINGS, "refused: bitrate 0");
    check(att_fdcan_hal_timing(160000001u, 500000u, 0u, &t) == ATT_ERR_SETTINGS, "refused: inexact bitrate");
    check(att_fdcan_hal_timing(200000000u, 1000u, 0u, &t) == ATT_ERR_SETTINGS,
          "refused: 200 MHz / 1 kbit/s needs more than 512 x 385 kernel clocks per bit");
    check(att_fdcan_hal_timing(160000000u, 500000u, 0u, NULL) == ATT_ERR_NULL, "timing NULL");
    snprintf(what, sizeof what, "every reachable pair keeps the field ranges (checked on 36 clocks x 4 bitrates)");
    {
        static const uint32_t clocks[] = {8000000u,  16000000u, 20000000u,  24000000u,  32000000u,  36000000u,
                                          40000000u, 42000000u, 48000000u,  50000000u,  56000000u,  60000000u,
                                          64000000u, 72000000u, 75000000u,  80000000u,  84000000u,  90000000u,
                                          96000000u, 100000000u, 108000000u, 120000000u, 128000000u, 144000000u,
                                          150000000u, 160000000u, 168000000u, 170000000u, 180000000u, 192000000u,
                                          200000000u, 216000000u, 240000000u, 250000000u, 275000000u, 280000000u};
        static const uint32_t rates[4][2] = {{125000u, 0u}, {500000u, 0u}, {500000u, 2000000u}, {1000000u, 5000000u}};
        uint32_t i;
        uint32_t j;
        uint32_t bad = 0u;
        for (i = 0u; i < sizeof clocks / sizeof clocks[0]; i++) {
            for (j = 0u; j < 4u; j++) {
                if (att_fdcan_hal_timing(clocks[i], rates[j][0], rates[j][1], &t) == ATT_OK) {
                    const uint32_t brp = ((t.nbtp >> 16) & 0x1ffu) + 1u;
                    const uint32_t tq = 1u + ((t.nbtp >> 8) & 0xffu) + 1u + (t.nbtp & 0x7fu) + 1u;
                    if (((t.nbtp >> 8) & 0xffu) == 0u || brp * tq * rates[j][0] != clocks[i]) {
                        bad++;
                    }
                    if (rates[j][1] != 0u) {
                        const uint32_t dbrp = ((t.dbtp >> 16) & 0x1fu) + 1u;
                        const uint32_t dtq = 1u + ((t.dbtp >> 8) & 0x1fu) + 1u + ((t.dbtp >> 4) & 0xfu) + 1u;
                        if (dbrp * dtq * rates[j][1] != clocks[i] || ((t.dbtp & ATT_FDCAN_DBTP_TDC) && dbrp > 2u)) {
                            bad++;
                        }
                    }
                }
            }
        }
        check(bad == 0u, what);
    }
}

static void test_dlc(void)
{
    uint32_t d;
    uint32_t len;
    uint32_t bad = 0u;
    for (d = 0u; d < 16u; d++) {
        bad += (uint32_t)(att_fdcan_dlc_to_len(d, true) != dlc_len_fd[d]);
        bad += (uint32_t)(att_fdcan_dlc_to_len(d, false) != (d > 8u ? 8u : d));
    }
    check(bad == 0u, "DLC -> length: 0..8, then FD 12 16 20 24 32 48 64, classic 8");
    bad = 0u;
    for (len = 0u; len <= 64u; len++) {
        d = att_fdcan_len_to_dlc(len);
        bad += (uint32_t)(dlc_len_fd[d] < len || (d > 0u && dlc_len_fd[d - 1u] >= len));
    }
    check(bad == 0u && att_fdcan_len_to_dlc(13u) == 10u && att_fdcan_len_to_dlc(64u) == 15u,
          "length -> the smallest DLC that holds it (13 -> DLC 10 = 16 bytes)");
}

static void test_layouts(void)
{
    att_fdcan_layout_t l;
    uint32_t end;
    check(att_fdcan_hal_layout_check(&att_fdcan_layout_g4) == ATT_OK, "layout: the G4 layout");
    l = att_fdcan_layout_g4;
    l.rx_fifo0 = 0x188u;
    check(att_fdcan_hal_layout_check(&l) == ATT_ERR_SETTINGS,
          "layout: G4 with another Rx FIFO 0 place refused (fixed RAM)");
    check(lay_h7_end != 0u && att_fdcan_hal_layout_check(&lay_h7) == ATT_OK &&
              att_fdcan_hal_layout_check(&lay_h7_cls) == ATT_OK,
          "layout: H7 packed from 0x400 (FD elements) and from its end (classic elements)");
    check(lay_h7.rx_fifo0 == 0x400u + 4u * ATT_FDCAN_HAL_FILTERS && lay_h7.tx_fifo == lay_h7.rx_fifo0 + 8u * 72u &&
              lay_h7_end == lay_h7.tx_fifo + 4u * 72u,
          "layout: H7 sections back to back (filters, 8 Rx elements, 4 Tx elements of 72 bytes)");
    l = lay_h7;
    l.tx_fifo = l.rx_fifo0 + 72u;
    check(att_fdcan_hal_layout_check(&l) == ATT_ERR_SETTINGS, "layout: overlapping sections refused");
    l = lay_h7;
    l.data_bytes = 10u;
    check(att_fdcan_hal_layout_check(&l) == ATT_ERR_SETTINGS, "layout: element data size 10 refused");
    l = lay_h7;
    l.rx_fifo0 += 2u;
    check(att_fdcan_hal_layout_check(&l) == ATT_ERR_SETTINGS, "layout: unaligned section refused");
    l = lay_h7;
    l.tx_fifo_n = 33u;
    check(att_fdcan_hal_layout_check(&l) == ATT_ERR_SETTINGS, "layout: 33 Tx buffers refused");
    l = lay_h7;
    l.rx_fifo0_n = 0u;
    check(att_fdcan_hal_layout_check(&l) == ATT_ERR_SETTINGS, "layout: empty Rx FIFO refused");
    l = lay_h7;
    l.filters_max = ATT_FDCAN_HAL_FILTERS - 1u;
    check(att_fdcan_hal_layout_check(&l) == ATT_ERR_SETTINGS, "layout: too few filter elements refused");
    end = att_fdcan_layout_h7(ATT_FDCAN_H7_RAM_BYTES - 64u, 3u, 3u, 64u, &l);
    check(end == 0u && att_fdcan_hal_layout_check(&l) == ATT_ERR_SETTINGS, "layout: past the 10 KB RAM refused");
    check(att_fdcan_layout_h7(0u, 65u, 3u, 64u, &l) == 0u && att_fdcan_layout_h7(0u, 3u, 3u, 7u, &l) == 0u &&
              att_fdcan_layout_h7(0u, 3u, 3u, 64u, NULL) == 0u,
          "layout: att_fdcan_layout_h7 refuses 65 Rx elements, data size 7, NULL");
    check(att_fdcan_hal_layout_check(NULL) == ATT_ERR_NULL, "layout: NULL");
}

static void test_init(att_fdcan_variant_t v)
{
    char what[160];
    att_fdcan_hal_t h2;
    uint32_t ids[8];
    const uint32_t n_el = (expected_ids(0, ids) + 1u) / 2u;
    const att_fdcan_layout_t *l = layout_for(v, 1);
    check(node_setup(&node, 0, 0) == ATT_OK, "node init (ARS, 100 Hz, 500 kbit/s classic)");
    fake_reset(v, l);
    snprintf(what, sizeof what, "%s: init NULL", vname(v));
    check(att_fdcan_hal_init(NULL, regs_io(), ram_io(), l, &node, KERNEL_HZ) == ATT_ERR_NULL &&
              att_fdcan_hal_init(&h2, regs_io(), ram_io(), l, NULL, KERNEL_HZ) == ATT_ERR_NULL,
          what);
    snprintf(what, sizeof what, "%s: init refuses a kernel clock that cannot make the bitrate, before writing anything",
             vname(v));
    check(att_fdcan_hal_init(&h2, regs_io(), ram_io(), l, &node, KERNEL_HZ + 1u) == ATT_ERR_SETTINGS &&
              fake.writes == 0u,
          what);
    fake.endn = 0u;
    snprintf(what, sizeof what, "%s: init refuses a controller whose ENDN is not 0x87654321 (clock off, wrong base)",
             vname(v));
    check(att_fdcan_hal_init(&h2, regs_io(), ram_io(), l, &node, KERNEL_HZ) == ATT_ERR_SETTINGS && fake.writes == 0u,
          what);
    fake_reset(v, l);
    fake.ack_init = 0;
    fake.reg[ATT_FDCAN_CCCR / 4] = 0u;
    snprintf(what, sizeof what, "%s: init times out when INIT is never acknowledged", vname(v));
    check(att_fdcan_hal_init(&h2, regs_io(), ram_io(), l, &node, KERNEL_HZ) == ATT_ERR_SETTINGS, what);
    fake_reset(v, l);
    fake.reg[ATT_FDCAN_CCCR / 4] = ATT_FDCAN_CCCR_CSR | ATT_FDCAN_CCCR_CSA; /* in clock stop */
    fake.reg[ATT_FDCAN_IR / 4] = rf0l_bit(&fake) | 1u;                       /* stale flags */
    snprintf(what, sizeof what, "%s: init (from clock stop)", vname(v));
    check(att_fdcan_hal_init(&can, regs_io(), ram_io(), l, &node, KERNEL_HZ) == ATT_OK, what);
    {
        const uint32_t cccr = r(&fake, ATT_FDCAN_CCCR);
        att_fdcan_timing_t t;
        (void)att_fdcan_hal_timing(KERNEL_HZ, 500000u, 0u, &t);
        snprintf(what, sizeof what, "%s: normal operation: INIT, CCE, CSR clear; classic: FDOE and BRSE clear",
                 vname(v));
        check((cccr & (ATT_FDCAN_CCCR_INIT | ATT_FDCAN_CCCR_CCE | ATT_FDCAN_CCCR_CSR | ATT_FDCAN_CCCR_FDOE |
                       ATT_FDCAN_CCCR_BRSE)) == 0u,
              what);
        snprintf(what, sizeof what,
                 "%s: NBTP written under INIT + CCE (no protected write refused, no stray RAM write), IR flags cleared",
                 vname(v));
        check(r(&fake, ATT_FDCAN_NBTP) == t.nbtp && fake.denied == 0u && fake.ram_outside == 0u &&
                  r(&fake, ATT_FDCAN_IR) == 0u,
              what);
    }
    if (v == ATT_FDCAN_G4) {
        check(r(&fake, ATT_FDCAN_G4_RXGFC) == ((n_el << 16) | 0x2bu) && r(&fake, ATT_FDCAN_TXBC) == 0u,
              "G4: RXGFC LSS = the filter elements, LSE 0, blocking FIFO 0, reject non-matching and remote frames; "
              "Tx FIFO mode");
        {
            uint32_t i;
            uint32_t stale = 0u;
            for (i = n_el; i < G4_RAM_BYTES / 4u; i++) {
                stale += (uint32_t)(fake.ram[i] != 0u);
            }
            for (i = G4_RAM_BYTES / 4u; i < FAKE_RAM_BYTES / 4u; i++) {
                stale += (uint32_t)(fake.ram[i] != FAKE_PATTERN);
            }
            check(stale == 0u, "G4: the instance's 0x350 bytes of RAM cleared, the next instance's untouched");
        }
    } else {
        snprintf(what, sizeof what, "H7: SIDFC, RXF0C, TXBC, RXESC, TXESC, GFC from the layout (%lu-byte elements)",
                 (unsigned long)l->data_bytes);
        check(r(&fake, ATT_FDCAN_H7_SIDFC) == ((n_el << 16) | l->filters) &&
                  r(&fake, ATT_FDCAN_H7_RXF0C) == ((l->rx_fifo0_n << 16) | l->rx_fifo0) &&
                  r(&fake, ATT_FDCAN_TXBC) == ((l->tx_fifo_n << 24) | l->tx_fifo) &&
                  (r(&fake, ATT_FDCAN_H7_RXESC) & 7u) == 7u && r(&fake, ATT_FDCAN_H7_TXESC) == 7u &&
                  r(&fake, ATT_FDCAN_H7_GFC) == 0x2bu && r(&fake, ATT_FDCAN_H7_XIDFC) == 0u,
              what);
    }
}

#if ATT_NODE_WITH_FD
static void test_init_fd(att_fdcan_variant_t v)
{
    static att_node_t fd_node;
    att_fdcan_hal_t h2;
    att_fdcan_timing_t t;
    char what[160];
    check(node_setup(&fd_node, 1, 0) == ATT_OK, "FD node init (500 kbit/s + 2 Mbit/s)");
    if (v == ATT_FDCAN_H7) {
        fake_reset(v, &lay_h7_cls);
        check(att_fdcan_hal_init(&h2, regs_io(), ram_io(), &lay_h7_cls, &fd_node, KERNEL_HZ) == ATT_ERR_SETTINGS &&
                  fake.writes == 0u,
              "H7: init refuses a CAN FD node on 8-byte elements");
    }
    fake_reset(v, layout_for(v, 1));
    snprintf(what, sizeof what, "%s: init refuses 170 MHz for 2 Mbit/s (no TDC prescaler)", vname(v));
    check(att_fdcan_hal_init(&h2, regs_io(), ram_io(), layout_for(v, 1), &fd_node, 170000000u) == ATT_ERR_SETTINGS,
          what);
    fake_reset(v, layout_for(v, 1));
    (void)att_fdcan_hal_timing(KERNEL_HZ, 500000u, 2000000u, &t);
    snprintf(what, sizeof what, "%s: FD init: FDOE, BRSE, NBTP, DBTP (TDC), TDCR written", vname(v));
    check(att_fdcan_hal_init(&h2, regs_io(), ram_io(), layout_for(v, 1), &fd_node, KERNEL_HZ) == ATT_OK &&
              (r(&fake, ATT_FDCAN_CCCR) & (ATT_FDCAN_CCCR_FDOE | ATT_FDCAN_CCCR_BRSE)) ==
                  (ATT_FDCAN_CCCR_FDOE | ATT_FDCAN_CCCR_BRSE) &&
              r(&fake, ATT_FDCAN_NBTP) == t.nbtp && r(&fake, ATT_FDCAN_DBTP) == t.dbtp &&
              r(&fake, ATT_FDCAN_TDCR) == t.tdcr && (t.dbtp & ATT_FDCAN_DBTP_TDC) != 0u && fake.denied == 0u &&
              h2.fd && h2.brs,
          what);
}
#endif

/*
 * The acceptance filter, decided by mcan_fifo0_accepts from the filter list and the global filter the
 * driver wrote: every 11-bit data frame ID is stored in Rx FIFO 0 iff it is one of the node's IDs;
 * none of them as a remote frame, none as an extended frame.
 */
static int mcan_accepts(uint32_t id, int ext, int rtr) { return mcan_fifo0_accepts(&fake, id, ext, rtr); }

static void test_acceptance_filter(att_fdcan_variant_t v)
{
    static const int32_t offsets[] = {0, 0x23, -0x100, 0x4ff};
    static att_node_t fnode;
    size_t o;
    for (o = 0u; o < sizeof offsets / sizeof offsets[0]; o++) {
        const att_fdcan_layout_t *l = layout_for(v, 0);
        att_fdcan_hal_t h2;
        char what[200];
        fake_reset(v, l);
        snprintf(what, sizeof what, "%s id_offset %ld: node and HAL init", vname(v), (long)offsets[o]);
        check(node_setup(&fnode, 0, offsets[o]) == ATT_OK &&
                  att_fdcan_hal_init(&h2, regs_io(), ram_io(), l, &fnode, KERNEL_HZ) == ATT_OK,
              what);
        snprintf(what, sizeof what, "%s Rx FIFO 0:", vname(v));
        check_acceptance(what, offsets[o], mcan_accepts);
    }
}

/* Drain: the bus takes the Tx FIFO, the driver refills it, until the node has nothing left. */
static void drain(void)
{
    uint32_t k;
    for (k = 0u; k < 64u && att_node_tx_pending(&node) > 0u; k++) {
        fake_complete_tx(&fake);
        (void)att_fdcan_hal_transmit(&can);
    }
    fake_complete_tx(&fake);
}

/* Classic or FD samples in, output sets out, equal to a filter stepped on the decoded samples. */
static void test_traffic(att_fdcan_variant_t v, int fd)
{
    att_filter_settings_t fs;
    att_filter_t ref;
    const uint32_t n = 150u;
    uint32_t i;
    uint32_t steps = 0u;
    uint32_t sets = 0u;
    uint32_t mismatches = 0u;
    uint32_t format_errors = 0u;
    char what[200];
    const char *mode = fd ? "FD" : "classic";
    snprintf(what, sizeof what, "%s %s: node and HAL init", vname(v), mode);
    check(node_setup(&node, fd, 0) == ATT_OK && hal_setup(v, fd) == ATT_OK, what);
    att_filter_settings_default(ATT_FILTER_ARS, 0.01f, &fs);
    att_filter_init(&ref, ATT_FILTER_ARS, &fs);
    for (i = 0u; i < n; i++) {
        att_sample_t s;
        att_sample_t q;
        att_output_t want;
        att_output_t got;
        att_can_frame_t fr[3];
        const uint32_t tx_before = fake.tx_n;
        uint32_t j;
        int have_set = 0;
        make_sample(&s);
        if (fd) {
            att_can_encode_imu_fd(&s, (uint8_t)(i & 15u), &fr[0]);
            (void)att_can_decode_imu_fd(&fr[0], &q);
            (void)fake_bus_rx(&fake, &fr[0], 0, 0, 1);
        } else {
            att_can_encode_imu(&s, (uint8_t)(i & 15u), fr);
            att_can_decode_imu_part(&fr[0], &q.gyr);
            att_can_decode_imu_part(&fr[1], &q.acc);
            att_can_decode_imu_part(&fr[2], &q.mag);
            for (j = 0u; j < 3u; j++) {
                (void)fake_bus_rx(&fake, &fr[j], 0, 0, 0);
            }
        }
        (void)att_filter_step(&ref, &q, &want);
        steps += (uint32_t)att_fdcan_hal_service(&can);
        drain();
        memset(&got, 0, sizeof got);
        for (j = tx_before; j < fake.tx_n; j++) {
            const tx_entry_t *e = &fake.tx_log[j];
            const int is_fd_id = e->f.id == (uint32_t)ATT_CAN_ID_OUT_FD || e->f.id == (uint32_t)ATT_CAN_ID_ACCEL_FD;
            if (e->xtd || e->rtr || e->f.fd != (uint8_t)is_fd_id || e->brs != is_fd_id ||
                e->dlc != (is_fd_id ? 15u : 8u) || e->f.len != (is_fd_id ? 64u : 8u)) {
                format_errors++;
            }
            if (att_can_check(&e->f) != ATT_CAN_OK && e->f.id != (uint32_t)ATT_CAN_ID_QUAT_A &&
                e->f.id != (uint32_t)ATT_CAN_ID_QUAT_B && e->f.id != (uint32_t)ATT_CAN_ID_QUAT16) {
                format_errors++;
            }
            if (e->f.id == (uint32_t)ATT_CAN_ID_OUT_FD || e->f.id == (uint32_t)ATT_CAN_ID_STATUS) {
                have_set = 1;
            }
            (void)att_can_decode_output(&e->f, &got);
        }
        if (have_set) {
            sets++;
            if (bits(got.q.w) != bits(want.q.w) || bits(got.q.x) != bits(want.q.x) || bits(got.q.y) != bits(want.q.y) ||
                bits(got.q.z) != bits(want.q.z) || got.steps % 65536u != want.steps % 65536u) {
                mismatches++;
            }
        }
    }
    snprintf(what, sizeof what, "%s %s: %lu samples through the fake FDCAN: %lu steps", vname(v), mode,
             (unsigned long)n, (unsigned long)steps);
    check(steps == n && node.stats.steps == n, what);
    snprintf(what, sizeof what, "%s %s: %lu output sets, quaternion and step count bit-identical to a direct filter",
             vname(v), mode, (unsigned long)sets);
    check(sets == n && mismatches == 0u, what);
    snprintf(what, sizeof what,
             "%s %s: every frame sent standard-ID data, valid E2E; ATT_OUT_FD as FD + BRS, DLC 15; classic "
             "frames DLC 8",
             vname(v), mode);
    check(format_errors == 0u && fake.bad_txbar == 0u, what);
    snprintf(what, sizeof what, "%s %s: every input frame moved to the node (%lu, %lu FD), none refused by it",
             vname(v), mode, (unsigned long)can.stats.rx_frames, (unsigned long)can.stats.rx_fd_frames);
    check(can.stats.rx_frames == (fd ? n : 3u * n) && can.stats.rx_fd_frames == (fd ? n : 0u) &&
              node.stats.crc_errors == 0u && node.stats.dlc_errors == 0u && node.stats.unknown_ids == 0u,
          what);
    snprintf(what, sizeof what, "%s %s: tx counters (%lu frames, %lu FD) = frames on the bus", vname(v), mode,
             (unsigned long)can.stats.tx_frames, (unsigned long)can.stats.tx_fd_frames);
    check(can.stats.tx_frames == fake.tx_n && can.stats.tx_unsupported == 0u &&
              (fd ? can.stats.tx_fd_frames >= n : can.stats.tx_fd_frames == 0u),
          what);
}

/* Other nodes' traffic (standard and extended) never reaches the node. */
static void test_other_traffic(att_fdcan_variant_t v)
{
    att_can_frame_t fr;
    uint32_t i;
    uint32_t stored = 0u;
    const uint32_t unknown = node.stats.unknown_ids;
    const uint32_t before = can.stats.rx_frames;
    char what[160];
    memset(&fr, 0, sizeof fr);
    fr.len = 8u;
    for (i = 0u; i < 300u; i++) {
        fr.id = (0x080u + 7u * i) & 0x7ffu;
        if (fr.id >= 0x100u && fr.id <= 0x300u) {
            fr.id = 0x400u + i;
        }
        stored += (uint32_t)fake_bus_rx(&fake, &fr, 0, 0, 0);
        stored += (uint32_t)fake_bus_rx(&fake, &fr, 1, 0, 0);
        (void)att_fdcan_hal_service(&can);
    }
    snprintf(what, sizeof what, "%s: 300 standard + 300 extended frames of other nodes: none stored, error count 0",
             vname(v));
    check(stored == 0u && can.stats.rx_frames == before && node.stats.unknown_ids == unknown &&
              att_node_error_count(&node) == 0u,
          what);
}

/* FD frames of every length in both directions (FD node), and frames the controller cannot send. */
#if ATT_NODE_WITH_FD
static void test_fd_lengths(att_fdcan_variant_t v)
{
    att_can_frame_t fr;
    uint32_t len;
    uint32_t bad = 0u;
    uint32_t dlc_before;
    uint32_t rx_before;
    char what[200];
    check(node_setup(&node, 1, 0) == ATT_OK && hal_setup(v, 1) == ATT_OK, "FD node and HAL for the length tests");
    for (len = 0u; len <= 64u; len++) {
        const uint32_t before = fake.tx_n;
        uint32_t i;
        memset(&fr, 0, sizeof fr);
        fr.id = 0x555u;
        fr.fd = 1u;
        fr.len = (uint8_t)len;
        for (i = 0u; i < len; i++) {
            fr.data[i] = (uint8_t)(i * 7u + len);
        }
        if (att_fdcan_hal_send(&can, &fr) != ATT_OK || fake.tx_n != before + 1u) {
            bad++;
        } else {
            const tx_entry_t *e = &fake.tx_log[before];
            bad += (uint32_t)(e->dlc != len_to_dlc(len) || !e->f.fd || !e->brs || e->f.id != 0x555u);
            for (i = 0u; i < dlc_len_fd[e->dlc]; i++) {
                bad += (uint32_t)(e->f.data[i] != (i < len ? fr.data[i] : 0u));
            }
        }
        fake_complete_tx(&fake);
    }
    snprintf(what, sizeof what, "%s: FD frames of 0..64 bytes sent with the smallest DLC, BRS, zero padding (%lu bad)",
             vname(v), (unsigned long)bad);
    check(bad == 0u, what);
    memset(&fr, 0, sizeof fr);
    fr.id = 0x555u;
    fr.len = 9u;
    check(att_fdcan_hal_send(&can, &fr) == ATT_ERR_SETTINGS, "a classic frame of 9 bytes is refused");
    fr.len = 8u;
    fr.id = 0x800u;
    check(att_fdcan_hal_send(&can, &fr) == ATT_ERR_SETTINGS && can.stats.tx_unsupported == 2u,
          "an ID above 11 bits is refused; both counted in tx_unsupported");
    check(att_fdcan_hal_send(&can, NULL) == ATT_ERR_NULL && att_fdcan_hal_send(NULL, &fr) == ATT_ERR_NULL, "send NULL");
    /* receive: FD frames with DLC 9..14 (12..48 bytes) at CMD: the node gets them at their length */
    dlc_before = node.stats.dlc_errors;
    rx_before = can.stats.rx_fd_frames;
    for (len = 12u; len <= 48u; len = dlc_len_fd[len_to_dlc(len) + 1u]) {
        memset(&fr, 0, sizeof fr);
        fr.id = (uint32_t)ATT_CAN_ID_CMD;
        fr.fd = 1u;
        fr.len = (uint8_t)len;
        (void)fake_bus_rx(&fake, &fr, 0, 0, 1);
        (void)att_fdcan_hal_service(&can);
    }
    snprintf(what, sizeof what, "%s: FD frames of 12..48 bytes received as such (the node counts 6 DLC errors at CMD)",
             vname(v));
    check(can.stats.rx_fd_frames == rx_before + 6u && node.stats.dlc_errors == dlc_before + 6u, what);
    /* a classic frame with DLC 8 but 64 stale bytes in the element: only 8 reach the node */
    {
        att_can_cmd_t c;
        att_can_frame_t cmd;
        const uint32_t cmds = node.stats.commands;
        memset(&c, 0, sizeof c);
        c.cmd = ATT_CAN_CMD_RESET;
        att_can_encode_cmd(&c, &cmd);
        (void)fake_bus_rx(&fake, &cmd, 0, 0, 0);
        (void)att_fdcan_hal_service(&can);
        snprintf(what, sizeof what, "%s: a classic command among FD traffic is executed", vname(v));
        check(node.stats.commands == cmds + 1u, what);
    }
}
#endif

static void test_classic_refuses_fd_send(att_fdcan_variant_t v)
{
    att_can_frame_t fr;
    char what[160];
    memset(&fr, 0, sizeof fr);
    fr.id = 0x123u;
    fr.fd = 1u;
    fr.len = 12u;
    snprintf(what, sizeof what, "%s classic: an FD frame is refused (the controller runs without FDOE)", vname(v));
    check(node_setup(&node, 0, 0) == ATT_OK && hal_setup(v, 0) == ATT_OK &&
              att_fdcan_hal_send(&can, &fr) == ATT_ERR_SETTINGS && can.stats.tx_unsupported == 1u,
          what);
}

/* Rx FIFO 0 full: the next frames are lost (RF0L), the driver counts it once, clears it and drains. */
static void test_full_fifo(att_fdcan_variant_t v)
{
    const att_fdcan_layout_t *l = layout_for(v, 0);
    att_can_frame_t fr[3];
    att_sample_t s;
    uint32_t stored = 0u;
    uint32_t i;
    uint32_t moved;
    char what[200];
    check(node_setup(&node, 0, 0) == ATT_OK && hal_setup(v, 0) == ATT_OK, "classic node and HAL for the FIFO test");
    make_sample(&s);
    att_can_encode_imu(&s, 0u, fr);
    for (i = 0u; i < l->rx_fifo0_n + 2u; i++) {
        stored += (uint32_t)fake_bus_rx(&fake, &fr[i % 3u], 0, 0, 0);
    }
    snprintf(what, sizeof what, "%s: Rx FIFO 0 of %lu holds %lu frames, 2 lost, RF0L set", vname(v),
             (unsigned long)l->rx_fifo0_n, (unsigned long)stored);
    check(stored == l->rx_fifo0_n && fake.lost == 2u && (r(&fake, ATT_FDCAN_IR) & rf0l_bit(&fake)) != 0u, what);
    moved = (uint32_t)att_fdcan_hal_receive(&can);
    snprintf(what, sizeof what, "%s: receive moves the %lu stored frames, counts one overrun, clears RF0L", vname(v),
             (unsigned long)moved);
    check(moved == l->rx_fifo0_n && can.stats.rx_overruns == 1u && (r(&fake, ATT_FDCAN_IR) & rf0l_bit(&fake)) == 0u &&
              fake.rx_fill == 0u,
          what);
    check(att_fdcan_hal_receive(&can) == 0u && can.stats.rx_overruns == 1u, "nothing more: no frame, no overrun");
    /* Tx FIFO full: frames wait in the node (first the outputs of the sample just received go out) */
    (void)att_fdcan_hal_service(&can);
    drain();
    {
        att_can_cmd_t c;
        att_can_frame_t cmd;
        size_t k;
        const uint32_t before = fake.tx_n;
        memset(&c, 0, sizeof c);
        c.cmd = ATT_CAN_CMD_RESET;
        for (k = 0u; k < l->tx_fifo_n + 1u; k++) {
            c.counter = (uint8_t)(k & 15u);
            att_can_encode_cmd(&c, &cmd);
            (void)fake_bus_rx(&fake, &cmd, 0, 0, 0);
            (void)att_fdcan_hal_service(&can); /* the bus never takes them */
        }
        snprintf(what, sizeof what, "%s: Tx FIFO of %lu full: %lu answers in it, 1 held in the node, send says full",
                 vname(v), (unsigned long)l->tx_fifo_n, (unsigned long)(fake.tx_n - before));
        check(fake.tx_n - before == l->tx_fifo_n && att_node_tx_pending(&node) == 1u && fake.bad_txbar == 0u &&
                  att_fdcan_hal_send(&can, &cmd) == ATT_ERR_STATE,
              what);
        fake_complete_tx(&fake);
        check(att_fdcan_hal_transmit(&can) == 1u && att_node_tx_pending(&node) == 0u,
              "the held answer is sent once the bus took the FIFO");
        fake_complete_tx(&fake);
    }
}

/* ---- controller faults ----------------------------------------------------------------------- */

/* A node with ATT_DIAG (and ATT_DIAG_BUS) after every set, classic, and its HAL. */
static void bus_setup(att_fdcan_variant_t v)
{
    att_node_settings_t s;
    char what[120];
    (void)att_node_settings_default(ATT_FILTER_ARS, 100.0f, &s);
    s.diag_divider = 1u;
    snprintf(what, sizeof what, "%s faults: node (DIAG after every set) and HAL init, the hook registered", vname(v));
    check(att_node_init(&node, &s) == ATT_OK && hal_setup(v, 0) == ATT_OK && node.bus_diag == att_fdcan_hal_bus_diag &&
              node.bus_diag_ctx == (void *)&can,
          what);
}

/* One classic IMU sample arrives from the bus (stored while the controller runs). */
static void bus_sample(uint32_t i)
{
    att_sample_t s;
    att_can_frame_t fr[3];
    uint32_t j;
    make_sample(&s);
    att_can_encode_imu(&s, (uint8_t)(i & 15u), fr);
    for (j = 0u; j < 3u; j++) {
        (void)fake_bus_rx(&fake, &fr[j], 0, 0, 0);
    }
}

/* The controller goes bus-off: PSR.BO (with esr_extra: EP, EW, LEC) and CCCR.INIT. */
static void bus_off_now(uint32_t extra)
{
    fake.reg[ATT_FDCAN_PSR / 4] = ATT_FDCAN_PSR_BO | extra;
    fake.reg[ATT_FDCAN_CCCR / 4] |= ATT_FDCAN_CCCR_INIT;
}

/* n service calls with PSR = psr (LEC 7 unless given). */
static void bus_calls(uint32_t n, uint32_t psr)
{
    uint32_t k;
    fake.reg[ATT_FDCAN_PSR / 4] = psr;
    for (k = 0u; k < n; k++) {
        (void)att_fdcan_hal_service(&can);
    }
    fake.reg[ATT_FDCAN_PSR / 4] = ATT_FDCAN_PSR_LEC;
}

/*
 * A bus-off episode: service calls from the one that sees it until the driver writes CCCR (clearing
 * INIT: the recovery), then PSR.BO clears and one more call sees it. Returns the calls after the one
 * that saw the bus-off (0: no recovery within 5000); *queued: frames put in the Tx FIFO meanwhile.
 */
static uint32_t bus_off_episode(uint32_t *queued)
{
    uint32_t calls = 0u;
    const uint32_t tx0 = fake.tx_n + fake.bad_txbar;
    fake.cccr_n = 0u;
    bus_off_now(ATT_FDCAN_PSR_EP | ATT_FDCAN_PSR_EW);
    (void)att_fdcan_hal_service(&can);
    while (fake.cccr_n == 0u && calls < 5000u) {
        (void)att_fdcan_hal_service(&can);
        calls++;
    }
    *queued = fake.tx_n + fake.bad_txbar - tx0;
    bus_calls(1u, 0u);
    return fake.cccr_n == 0u ? 0u : calls;
}

/* The ATT_DIAG_BUS frames sent since log index from: each right after its ATT_DIAG, checked, with want. */
static void bus_diag_frames(att_fdcan_variant_t v, uint32_t from, const att_can_bus_diag_t *want, const char *label)
{
    uint32_t j;
    uint32_t seen = 0u;
    uint32_t bad = 0u;
    char what[200];
    char hal[16];
    snprintf(hal, sizeof hal, "fdcan-%s", vname(v));
    for (j = from; j < fake.tx_n; j++) {
        if (fake.tx_log[j].f.id == (uint32_t)ATT_CAN_ID_DIAG_BUS) {
            seen++;
            bad += diag_bus_frame_check(hal, label, j > 0u ? &fake.tx_log[j - 1u].f : NULL, &fake.tx_log[j].f, want);
        }
    }
    snprintf(what, sizeof what, "%s faults: %s: %lu ATT_DIAG_BUS after its ATT_DIAG, E2E good, the driver's counters",
             vname(v), label, (unsigned long)seen);
    check(seen > 0u && bad == 0u, what);
}

/* Bus-off back-off and recovery, error-passive and warning, FIFO overruns, and ATT_DIAG_BUS. */
static void test_bus_faults(att_fdcan_variant_t v)
{
    att_can_frame_t fr;
    att_can_bus_diag_t want;
    uint32_t from;
    uint32_t queued;
    uint32_t writes;
    uint32_t cccr;
    uint32_t delays[12];
    uint32_t bad = 0u;
    uint32_t k;
    char what[260];
    const char *vn = vname(v);
    memset(&fr, 0, sizeof fr);
    fr.id = 0x321u;
    fr.len = 8u;
    bus_setup(v);
    bus_sample(0u);
    (void)att_fdcan_hal_service(&can);
    drain();
    memset(&want, 0, sizeof want);
    bus_diag_frames(v, 0u, &want, "quiet bus");

    /* a sample stored, then bus-off: its outputs are held in the node */
    from = fake.tx_n;
    bus_sample(1u);
    fake.cccr_n = 0u;
    bus_off_now(ATT_FDCAN_PSR_EP | ATT_FDCAN_PSR_EW | 3u);
    (void)att_fdcan_hal_service(&can);
    snprintf(what, sizeof what,
             "%s faults: bus-off seen: counted, the set + DIAG + DIAG_BUS held in the node, nothing queued, INIT "
             "left set for the back-off",
             vn);
    check(can.stats.bus_off == 1u && can.phase == ATT_FDCAN_HAL_BACKOFF && att_node_tx_pending(&node) == 8u &&
              fake.tx_n == from && fake.cccr_n == 0u && (r(&fake, ATT_FDCAN_CCCR) & ATT_FDCAN_CCCR_INIT) != 0u,
          what);
    snprintf(what, sizeof what, "%s faults: error-passive and warning entries counted, last error code 3 kept "
             "though PSR.LEC now reads 7", vn);
    check(can.stats.error_passive == 1u && can.stats.error_warning == 1u && can.stats.lec == 3u &&
              (r(&fake, ATT_FDCAN_PSR) & ATT_FDCAN_PSR_LEC) == 7u,
          what);
    cccr = r(&fake, ATT_FDCAN_CCCR);
    writes = fake.writes;
    (void)att_fdcan_hal_service(&can); /* ATT_FDCAN_HAL_BACKOFF_FIRST = 1 call later: the recovery */
    snprintf(what, sizeof what,
             "%s faults: recovery after %u call: one write, CCCR = 0x%lx (INIT and CCE clear, the rest kept), no "
             "protected write refused",
             vn, (unsigned)ATT_FDCAN_HAL_BACKOFF_FIRST, (unsigned long)fake.cccr_log[0]);
    check(ATT_FDCAN_HAL_BACKOFF_FIRST == 1u && fake.cccr_n == 1u && fake.writes == writes + 1u &&
              fake.cccr_log[0] == (cccr & ~(ATT_FDCAN_CCCR_INIT | ATT_FDCAN_CCCR_CCE)) && fake.denied == 0u &&
              can.phase == ATT_FDCAN_HAL_RECOVERING && fake.tx_n == from,
          what);
    fake.reg[ATT_FDCAN_PSR / 4] = ATT_FDCAN_PSR_BO | ATT_FDCAN_PSR_EP;
    snprintf(what, sizeof what, "%s faults: recovering (INIT clear, BO still set): send refused, nothing queued, no "
             "second write", vn);
    check(att_fdcan_hal_send(&can, &fr) == ATT_ERR_STATE && att_fdcan_hal_transmit(&can) == 0u, what);
    bus_calls(3u, ATT_FDCAN_PSR_BO | ATT_FDCAN_PSR_EP);
    check(fake.cccr_n == 1u && fake.tx_n == from && can.stats.recoveries == 0u && can.stats.error_passive == 1u,
          "faults: still recovering after 3 calls: nothing queued, no new entry counted");
    bus_calls(1u, 0u); /* 129 x 11 recessive bits later: PSR.BO clear */
    drain();
    snprintf(what, sizeof what, "%s faults: PSR.BO clear: recovery counted, the 8 held frames sent", vn);
    check(can.stats.recoveries == 1u && can.phase == ATT_FDCAN_HAL_ON && att_node_tx_pending(&node) == 0u &&
              fake.tx_n == from + 8u && fake.bad_txbar == 0u,
          what);
    want.state = (uint8_t)ATT_CAN_BUS_OFF;
    want.lec = 3u;
    want.bus_off = 1u;
    want.error_passive = 1u;
    want.error_warning = 1u;
    bus_diag_frames(v, from, &want, "queued during the back-off");

    /* the back-off doubles up to the cap */
    for (k = 0u; k < 12u; k++) {
        delays[k] = bus_off_episode(&queued);
        bad += (uint32_t)(queued != 0u || (fake.cccr_log[0] & (ATT_FDCAN_CCCR_INIT | ATT_FDCAN_CCCR_CCE)) != 0u);
        bad += (uint32_t)(delays[k] != ((k < 10u) ? (2u << k) : ATT_FDCAN_HAL_BACKOFF_MAX));
    }
    snprintf(what, sizeof what,
             "%s faults: back-off of 12 more episodes: %lu %lu %lu ... %lu %lu %lu calls (2, 4, 8 ... capped at %u), "
             "INIT cleared once each, nothing queued",
             vn, (unsigned long)delays[0], (unsigned long)delays[1], (unsigned long)delays[2],
             (unsigned long)delays[9], (unsigned long)delays[10], (unsigned long)delays[11],
             (unsigned)ATT_FDCAN_HAL_BACKOFF_MAX);
    check(ATT_FDCAN_HAL_BACKOFF_MAX == 1024u && bad == 0u && can.stats.bus_off == 13u && can.stats.recoveries == 13u &&
              fake.denied == 0u,
          what);
    bus_calls(ATT_FDCAN_HAL_BACKOFF_RESET - 1u, 0u);
    check(bus_off_episode(&queued) == ATT_FDCAN_HAL_BACKOFF_MAX,
          "faults: RESET - 1 good calls: the back-off stays at the cap");
    bus_calls(ATT_FDCAN_HAL_BACKOFF_RESET, ATT_FDCAN_PSR_EW);
    check(bus_off_episode(&queued) == ATT_FDCAN_HAL_BACKOFF_FIRST,
          "faults: RESET good calls (warning counts as good): back to FIRST");
    bus_calls(ATT_FDCAN_HAL_BACKOFF_RESET - 1u, 0u);
    bus_calls(1u, ATT_FDCAN_PSR_EP);
    bus_calls(ATT_FDCAN_HAL_BACKOFF_RESET - 1u, 0u);
    check(bus_off_episode(&queued) == 2u * ATT_FDCAN_HAL_BACKOFF_FIRST,
          "faults: an error-passive call breaks the good run: the back-off doubles instead of starting over");

    /* error-passive and warning: once per entry */
    {
        const uint32_t p0 = can.stats.error_passive;
        const uint32_t w0 = can.stats.error_warning;
        bus_calls(5u, ATT_FDCAN_PSR_EP | ATT_FDCAN_PSR_EW);
        bus_calls(2u, ATT_FDCAN_PSR_EW);
        bus_calls(3u, ATT_FDCAN_PSR_EP | ATT_FDCAN_PSR_EW | 6u);
        bus_calls(2u, 0u);
        bus_calls(4u, ATT_FDCAN_PSR_EW | 5u);
        snprintf(what, sizeof what,
                 "%s faults: error-passive entered twice (%lu), warning twice (%lu); LEC 5 (bit0) kept over the 7s "
                 "of later reads", vn, (unsigned long)(can.stats.error_passive - p0),
                 (unsigned long)(can.stats.error_warning - w0));
        check(can.stats.error_passive == p0 + 2u && can.stats.error_warning == w0 + 2u && can.stats.lec == 5u, what);
    }

    /* Rx FIFO 0 and 1 message lost: counted once each, cleared */
    {
        const uint32_t o0 = can.stats.rx_overruns;
        const uint32_t rf1l = (v == ATT_FDCAN_G4) ? ATT_FDCAN_G4_IR_RF1L : ATT_FDCAN_H7_IR_RF1L;
        fake.reg[ATT_FDCAN_IR / 4] |= rf0l_bit(&fake) | rf1l | 1u; /* + RF0N, not ours to clear */
        (void)att_fdcan_hal_receive(&can);
        snprintf(what, sizeof what, "%s faults: IR.RF0L and IR.RF1L counted once each and cleared (write 1), RF0N "
                 "left", vn);
        check(can.stats.rx_overruns == o0 + 2u && r(&fake, ATT_FDCAN_IR) == 1u, what);
        fake.reg[ATT_FDCAN_IR / 4] = 0u;
    }

    /* what the host sees now */
    from = fake.tx_n;
    bus_sample(2u);
    fake.reg[ATT_FDCAN_PSR / 4] = ATT_FDCAN_PSR_EP | ATT_FDCAN_PSR_EW;
    (void)att_fdcan_hal_service(&can);
    drain();
    att_fdcan_hal_bus_diag(&can, &want);
    check(want.state == (uint8_t)ATT_CAN_BUS_PASSIVE && want.bus_off == 16u && want.recoveries == 16u &&
              want.lec == 5u && want.rx_overruns == 2u,
          "faults: the hook reports error-passive, 16 bus-off episodes and recoveries, 2 overruns, LEC 5");
    bus_diag_frames(v, from, &want, "after the faults");
    fake.reg[ATT_FDCAN_PSR / 4] = 0u;

    /* back on the bus and bus-off again between two calls: INIT set again while recovering */
    {
        const uint32_t off0 = can.stats.bus_off;
        const uint32_t rec0 = can.stats.recoveries;
        fake.cccr_n = 0u;
        bus_off_now(0u);
        (void)att_fdcan_hal_service(&can);
        for (k = 0u; k < 5000u && fake.cccr_n == 0u; k++) {
            (void)att_fdcan_hal_service(&can);
        }
        fake.reg[ATT_FDCAN_CCCR / 4] |= ATT_FDCAN_CCCR_INIT; /* PSR.BO still reads 1 */
        (void)att_fdcan_hal_service(&can);
        snprintf(what, sizeof what, "%s faults: INIT set again while recovering: a recovery and a new bus-off "
                 "counted, back-off again (INIT left set)", vn);
        check(can.phase == ATT_FDCAN_HAL_BACKOFF && can.stats.bus_off == off0 + 2u && can.stats.recoveries == rec0 + 1u &&
                  fake.cccr_n == 1u && (r(&fake, ATT_FDCAN_CCCR) & ATT_FDCAN_CCCR_INIT) != 0u,
              what);
        for (k = 0u; k < 5000u && fake.cccr_n == 1u; k++) {
            (void)att_fdcan_hal_service(&can);
        }
        bus_calls(1u, 0u);
        check(can.phase == ATT_FDCAN_HAL_ON && can.stats.recoveries == rec0 + 2u && fake.cccr_n == 2u,
              "faults: and recovers after its back-off");
    }
}

int main(void)
{
    static const att_fdcan_variant_t variants[2] = {ATT_FDCAN_G4, ATT_FDCAN_H7};
    size_t k;
    lay_h7_end = att_fdcan_layout_h7(0x400u, 8u, 4u, 64u, &lay_h7);
    (void)att_fdcan_layout_h7(lay_h7_end, 4u, 2u, 8u, &lay_h7_cls);
    test_timing();
    test_dlc();
    test_layouts();
    for (k = 0u; k < 2u; k++) {
        test_init(variants[k]);
        test_acceptance_filter(variants[k]);
        test_traffic(variants[k], 0);
        test_other_traffic(variants[k]);
#if ATT_NODE_WITH_FD
        test_init_fd(variants[k]);
        test_traffic(variants[k], 1);
        test_fd_lengths(variants[k]);
#endif
        test_classic_refuses_fd_send(variants[k]);
        test_full_fifo(variants[k]);
        test_bus_faults(variants[k]);
    }
    check(att_fdcan_hal_receive(NULL) == 0u && att_fdcan_hal_transmit(NULL) == 0u && att_fdcan_hal_service(NULL) == 0u,
          "NULL handles");
    printf("%d failure(s)\n", failures);
    return failures;
}
