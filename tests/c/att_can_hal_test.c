/**
 * @file att_can_hal_test.c
 * @brief Host unit test of the bxCAN HAL (firmware/ports/cortex_m/att_can_hal.c) against a fake controller.
 *
 * The fake keeps a register file and models what the driver relies on: INRQ/SLEEP acknowledged in
 * MSR (or never, to test the timeout), the acceptance filter (bx_fifo0_accepts: the bxCAN filter
 * matching rules of RM0090 32.7.4 evaluated on the filter registers the driver wrote; a frame that
 * arrives from the bus reaches FIFO 0 only when they say so), a 3-deep receive FIFO behind
 * RF0R/RI0R.. with RFOM0 release and FOVR0 overrun, three transmit mailboxes whose TXRQ captures the
 * frame and stays busy until the test completes the transmission, RF1R's FOVR1, and a log of the MCR
 * writes. ESR (bus-off, error-passive, error warning, last error code) is set by the test as the
 * controller would. A real attica node runs behind the driver: IMU sample frames go in, output sets
 * come out and must equal (bit for bit) a filter stepped directly on the decoded samples.
 *
 * Controller faults (test_bus_faults): bus-off -> nothing written to a mailbox during the back-off, the
 * recovery writes exactly MCR = INRQ | TXFP then MCR = TXFP (ABOM never set), the back-off doubles from
 * ATT_CAN_HAL_BACKOFF_FIRST to ATT_CAN_HAL_BACKOFF_MAX and starts over after ATT_CAN_HAL_BACKOFF_RESET
 * good service calls (not before, not across an error-passive call), error-passive and warning counted
 * once per entry, FIFO 0 and 1 overruns counted and cleared, and the ATT_DIAG_BUS frame the node sends
 * after each ATT_DIAG carries them (printed as "diag_bus ..." lines that tests/test_cross.py decodes
 * with the host's codec).
 *
 * Prints "ok ..." / "FAIL ..." per check; exit status = number of failures.
 */
#include <stdio.h>
#include <string.h>

#define ATT_HAL_TEST_SEED 99u
#include "att_hal_test_common.h"

#include "att_can_hal.h"
#include "attica/att_can.h"
#include "attica/att_config.h"
#include "attica/att_filter.h"
#include "attica/att_node.h"

#define FAKE_FIFO 3u
#define FAKE_TX_LOG 4096u

typedef struct {
    uint32_t reg[0x400 / 4];
    uint32_t fifo[FAKE_FIFO][4]; /* RIR RDTR RDLR RDHR */
    uint32_t fifo_n;
    int ack_init;       /* 0: never acknowledge INRQ (broken controller) */
    int tx_busy[3];     /* mailbox holds a frame not yet on the bus */
    att_can_frame_t tx_log[FAKE_TX_LOG];
    uint32_t tx_n;
    uint32_t writes;
    uint32_t filtered; /* frames from the bus the acceptance filter kept out of FIFO 0 */
    uint32_t mcr_log[16]; /* the first MCR writes since the test last cleared mcr_n */
    uint32_t mcr_n;       /* MCR writes */
    uint32_t mbox_writes; /* writes to a transmit mailbox register */
    uint32_t aborted;     /* pending mailboxes emptied by TSR.ABRQx */
} fake_t;

/*
 * The controller's acceptance decision, from the filter registers alone (RM0090 32.7.4, "Identifier
 * filtering"): does a frame (11-bit id, or 29-bit id when ide; remote when rtr) go to FIFO 0?
 * - nothing is received while FMR.FINIT is set (filter initialisation mode);
 * - every bank with its FA1R bit set holds, by FS1R, one 32-bit filter per register or two 16-bit
 *   filters per register, and by FM1R identifier mask (register 1 / low half = identifier, register 2
 *   / high half = mask: the masked bits must be equal) or identifier list (every entry an identifier
 *   that must be equal in every bit);
 * - 32-bit layout: STID[10:0] bits 31:21 (or EXID[28:0] bits 31:3), IDE bit 2, RTR bit 1, bit 0 unused;
 *   16-bit layout: STID[10:0] bits 15:5, RTR bit 4, IDE bit 3, EXID[17:15] bits 2:0;
 * - of the filters that match, the one of highest priority decides the FIFO (FFA1R bit of its bank):
 *   32-bit before 16-bit, then list before mask, then the lower filter number (lower bank, earlier
 *   entry); no match: the frame is discarded.
 */
static int bx_fifo0_accepts(const fake_t *f, uint32_t id, int ide, int rtr)
{
    const uint32_t fmr = f->reg[ATT_BXCAN_FMR / 4];
    const uint32_t fa = f->reg[ATT_BXCAN_FA1R / 4];
    const uint32_t fm = f->reg[ATT_BXCAN_FM1R / 4];
    const uint32_t fs = f->reg[ATT_BXCAN_FS1R / 4];
    const uint32_t ffa = f->reg[ATT_BXCAN_FFA1R / 4];
    const uint32_t w32 = (ide ? ((id & 0x1fffffffu) << 3) | 4u : (id & 0x7ffu) << 21) | (rtr ? 2u : 0u);
    const uint32_t w16 = (ide ? (((id >> 18) & 0x7ffu) << 5) | 8u | ((id >> 15) & 7u) : (id & 0x7ffu) << 5) |
                         (rtr ? 16u : 0u);
    uint32_t best = 0xffffffffu; /* priority key of the best match: class * 1000 + bank * 4 + entry */
    int best_fifo = -1;
    uint32_t b;
    if ((fmr & ATT_BXCAN_FMR_FINIT) != 0u) {
        return 0;
    }
    for (b = 0u; b < ATT_BXCAN_BANKS; b++) {
        const uint32_t r1 = f->reg[(ATT_BXCAN_F0R1 + ATT_BXCAN_BANK_STRIDE * b) / 4];
        const uint32_t r2 = f->reg[(ATT_BXCAN_F0R2 + ATT_BXCAN_BANK_STRIDE * b) / 4];
        const int scale32 = (int)((fs >> b) & 1u);
        const int list = (int)((fm >> b) & 1u);
        const uint32_t cls = (scale32 ? 0u : 2u) + (list ? 0u : 1u);
        uint32_t entry = 99u;
        if (((fa >> b) & 1u) == 0u) {
            continue;
        }
        if (scale32 && list) {
            entry = (((w32 ^ r1) & ~1u) == 0u) ? 0u : (((w32 ^ r2) & ~1u) == 0u) ? 1u : 99u;
        } else if (scale32) {
            entry = (((w32 ^ r1) & r2 & ~1u) == 0u) ? 0u : 99u;
        } else if (list) {
            const uint32_t h[4] = {r1 & 0xffffu, r1 >> 16, r2 & 0xffffu, r2 >> 16};
            uint32_t k;
            for (k = 0u; k < 4u && entry == 99u; k++) {
                if (w16 == h[k]) {
                    entry = k;
                }
            }
        } else if (((w16 ^ (r1 & 0xffffu)) & (r1 >> 16)) == 0u) {
            entry = 0u;
        } else if (((w16 ^ (r2 & 0xffffu)) & (r2 >> 16)) == 0u) {
            entry = 1u;
        }
        if (entry != 99u && cls * 1000u + b * 4u + entry < best) {
            best = cls * 1000u + b * 4u + entry;
            best_fifo = (int)((ffa >> b) & 1u);
        }
    }
    return best_fifo == 0;
}

static void fake_update_status(fake_t *f)
{
    uint32_t tsr = 0u;
    uint32_t b;
    f->reg[ATT_BXCAN_RF0R / 4] = (f->reg[ATT_BXCAN_RF0R / 4] & ATT_BXCAN_RF0R_FOVR0) | f->fifo_n |
                                 (f->fifo_n == FAKE_FIFO ? ATT_BXCAN_RF0R_FULL0 : 0u);
    for (b = 0u; b < 3u; b++) {
        if (!f->tx_busy[b]) {
            tsr |= ATT_BXCAN_TSR_TME0 << b;
        }
    }
    f->reg[ATT_BXCAN_TSR / 4] = tsr;
    if (f->fifo_n > 0u) {
        memcpy(&f->reg[ATT_BXCAN_RI0R / 4], f->fifo[0], sizeof f->fifo[0]);
    }
}

static uint32_t fake_read(void *ctx, uint32_t offset)
{
    fake_t *f = (fake_t *)ctx;
    fake_update_status(f);
    return f->reg[offset / 4u];
}

static void fake_write(void *ctx, uint32_t offset, uint32_t value)
{
    fake_t *f = (fake_t *)ctx;
    f->writes++;
    if (offset >= ATT_BXCAN_TI0R && offset < ATT_BXCAN_TI0R + 0x30u) {
        f->mbox_writes++;
    }
    if (offset == ATT_BXCAN_MCR) {
        if (f->mcr_n < 16u) {
            f->mcr_log[f->mcr_n] = value;
        }
        f->mcr_n++;
        f->reg[offset / 4] = value;
        if (f->ack_init) {
            uint32_t msr = 0u;
            if (value & ATT_BXCAN_MCR_INRQ) {
                msr |= ATT_BXCAN_MSR_INAK;
            }
            if ((value & ATT_BXCAN_MCR_SLEEP) && !(value & ATT_BXCAN_MCR_INRQ)) {
                msr |= ATT_BXCAN_MSR_SLAK;
            }
            f->reg[ATT_BXCAN_MSR / 4] = msr;
        }
        return;
    }
    if (offset == ATT_BXCAN_RF0R) {
        if (value & ATT_BXCAN_RF0R_FOVR0) {
            f->reg[offset / 4] &= ~ATT_BXCAN_RF0R_FOVR0;
        }
        if ((value & ATT_BXCAN_RF0R_RFOM0) && f->fifo_n > 0u) {
            memmove(f->fifo[0], f->fifo[1], sizeof f->fifo[0] * (FAKE_FIFO - 1u));
            f->fifo_n--;
        }
        return;
    }
    if (offset == ATT_BXCAN_TSR) { /* ABRQx: a pending mailbox is emptied, its request aborted */
        uint32_t b;
        for (b = 0u; b < 3u; b++) {
            if ((value & (ATT_BXCAN_TSR_ABRQ0 << (8u * b))) != 0u && f->tx_busy[b]) {
                f->tx_busy[b] = 0;
                f->aborted++;
            }
        }
        return;
    }
    if (offset == ATT_BXCAN_RF1R) { /* FOVR1 rc_w1; FIFO 1 is never filled here */
        if (value & ATT_BXCAN_RF0R_FOVR0) {
            f->reg[offset / 4] &= ~ATT_BXCAN_RF0R_FOVR0;
        }
        return;
    }
    if (offset >= ATT_BXCAN_TI0R && offset < ATT_BXCAN_TI0R + 0x30u && (offset & 0xfu) == 0u &&
        (value & ATT_BXCAN_TIR_TXRQ)) {
        const uint32_t b = (offset - ATT_BXCAN_TI0R) / 0x10u;
        const uint32_t base = ATT_BXCAN_TI0R / 4 + 4u * b;
        att_can_frame_t fr;
        uint32_t i;
        f->reg[offset / 4] = value;
        memset(&fr, 0, sizeof fr);
        fr.id = value >> 21;
        fr.len = (uint8_t)(f->reg[base + 1] & 0xfu);
        for (i = 0u; i < 4u; i++) {
            fr.data[i] = (uint8_t)(f->reg[base + 2] >> (8u * i));
            fr.data[4u + i] = (uint8_t)(f->reg[base + 3] >> (8u * i));
        }
        if (f->tx_n < FAKE_TX_LOG) {
            f->tx_log[f->tx_n++] = fr;
        }
        f->tx_busy[b] = 1;
        return;
    }
    f->reg[offset / 4u] = value;
}

/* The bus takes every frame waiting in the mailboxes. */
static void fake_complete_tx(fake_t *f) { memset(f->tx_busy, 0, sizeof f->tx_busy); }

/* A frame enters FIFO 0 (whatever the filter says); false (and FOVR0) when the FIFO is full. */
static int fake_inject(fake_t *f, const att_can_frame_t *fr, int extended)
{
    uint32_t lo = 0u;
    uint32_t hi = 0u;
    uint32_t i;
    if (f->fifo_n == FAKE_FIFO) {
        f->reg[ATT_BXCAN_RF0R / 4] |= ATT_BXCAN_RF0R_FOVR0;
        return 0;
    }
    for (i = 0u; i < 4u; i++) {
        lo |= (uint32_t)fr->data[i] << (8u * i);
        hi |= (uint32_t)fr->data[4u + i] << (8u * i);
    }
    f->fifo[f->fifo_n][0] = extended ? ((fr->id << 3) | ATT_BXCAN_RIR_IDE) : (fr->id << 21);
    f->fifo[f->fifo_n][1] = fr->len;
    f->fifo[f->fifo_n][2] = lo;
    f->fifo[f->fifo_n][3] = hi;
    f->fifo_n++;
    return 1;
}

/* A frame arrives from the bus: the acceptance filter decides whether it enters FIFO 0. */
static int fake_receive(fake_t *f, const att_can_frame_t *fr, int extended)
{
    if (!bx_fifo0_accepts(f, fr->id, extended, 0)) {
        f->filtered++;
        return 0;
    }
    return fake_inject(f, fr, extended);
}

static fake_t fake;
static att_node_t node;
static att_can_hal_t can;

static att_can_hal_io_t fake_io(void)
{
    att_can_hal_io_t io;
    io.ctx = &fake;
    io.read = fake_read;
    io.write = fake_write;
    return io;
}

static void test_btr(void)
{
    char what[80];
    check(att_can_hal_btr(42000000u, 500000u) == 0x001a0005u, "BTR 500 kbit/s at 42 MHz: BRP 6, TS1 11, TS2 2");
    check(att_can_hal_btr(36000000u, 1000000u) == 0x001e0001u, "BTR 1 Mbit/s at 36 MHz: BRP 2, TS1 15, TS2 2");
    check(att_can_hal_btr(42000000u, 333333u) == 0u, "BTR 0 for an unreachable bitrate");
    check(att_can_hal_btr(42000000u, 0u) == 0u, "BTR 0 for bitrate 0");
    snprintf(what, sizeof what, "BTR 125 kbit/s at 8 MHz = 0x%08lx", (unsigned long)att_can_hal_btr(8000000u, 125000u));
    check(att_can_hal_btr(8000000u, 125000u) != 0u, what);
}

static void test_init(void)
{
    att_node_settings_t s;
    att_can_hal_t h2;
    check(att_node_settings_default(ATT_FILTER_ARS, 100.0f, &s) == ATT_OK && att_node_init(&node, &s) == ATT_OK,
          "node init (ARS, 100 Hz, 500 kbit/s)");
    memset(&fake, 0, sizeof fake);
    fake.ack_init = 0;
    check(att_can_hal_init(&h2, fake_io(), &node, 42000000u) == ATT_ERR_SETTINGS && node.bus_diag == NULL &&
              node.bus_diag_ctx == NULL,
          "init times out when the controller never acknowledges INRQ, and leaves no hook to its handle");
    fake.ack_init = 1;
    check(att_can_hal_init(&h2, fake_io(), &node, 42000001u) == ATT_ERR_SETTINGS,
          "init refuses a clock that cannot make the bitrate");
    check(att_can_hal_init(NULL, fake_io(), &node, 42000000u) == ATT_ERR_NULL, "init NULL");
    memset(&fake, 0, sizeof fake);
    fake.ack_init = 1;
    check(att_can_hal_init(&can, fake_io(), &node, 42000000u) == ATT_OK, "init");
    check(fake.reg[ATT_BXCAN_BTR / 4] == 0x001a0005u, "BTR written");
    check((fake.reg[ATT_BXCAN_MCR / 4] & ATT_BXCAN_MCR_INRQ) == 0u, "normal mode after init");
    check((fake.reg[ATT_BXCAN_MCR / 4] & (ATT_BXCAN_MCR_ABOM | ATT_BXCAN_MCR_TXFP)) == ATT_BXCAN_MCR_TXFP,
          "automatic bus-off management off (the driver recovers), transmit in request order");
    check(node.bus_diag == att_can_hal_bus_diag && node.bus_diag_ctx == (void *)&can,
          "init registers the port's ATT_DIAG_BUS hook with the node");
    check((fake.reg[ATT_BXCAN_FA1R / 4] & 3u) == (ATT_NODE_WITH_FD ? 3u : 1u) &&
              (fake.reg[ATT_BXCAN_FM1R / 4] & 3u) == 3u && (fake.reg[ATT_BXCAN_FS1R / 4] & 3u) == 0u &&
              (fake.reg[ATT_BXCAN_FFA1R / 4] & 3u) == 0u && (fake.reg[ATT_BXCAN_FMR / 4] & ATT_BXCAN_FMR_FINIT) == 0u,
          "filter banks active as needed (5 IDs: 0 and 1; 4 IDs without CAN FD: 0), 16-bit identifier list, FIFO 0, "
          "filters out of init");
}

/*
 * The acceptance filter, decided by bx_fifo0_accepts from the registers the driver wrote: every
 * 11-bit data frame ID reaches FIFO 0 iff it is one of the node's receive IDs; none of them as a
 * remote frame, none as an extended frame (same top 11 bits, or the same value as a 29-bit ID).
 * The fake starts with bank 0 left open by earlier code (32-bit mask 0: every frame) and bank 1 in
 * 32-bit mask mode: the driver must rewrite mode, scale and FIFO, not rely on reset values.
 */
static int bx_accepts(uint32_t id, int ext, int rtr) { return bx_fifo0_accepts(&fake, id, ext, rtr); }

static void test_acceptance_filter(void)
{
    static const int32_t offsets[] = {0, 0x23, -0x100, 0x4ff};
    static att_node_t fnode;
    size_t o;
    for (o = 0u; o < sizeof offsets / sizeof offsets[0]; o++) {
        att_node_settings_t s;
        att_can_hal_t h2;
        uint32_t want[8];
        uint32_t got[ATT_NODE_RX_IDS_MAX];
        const uint32_t n_want = expected_ids(offsets[o], want);
        uint32_t found = 0u;
        uint32_t k;
        size_t g;
        size_t n_got;
        char what[160];
        att_node_settings_default(ATT_FILTER_ARS, 100.0f, &s);
        s.id_offset = offsets[o];
        memset(&fake, 0, sizeof fake);
        fake.ack_init = 1;
        fake.reg[ATT_BXCAN_FA1R / 4] = 3u;
        fake.reg[ATT_BXCAN_FS1R / 4] = 3u;
        fake.reg[ATT_BXCAN_FFA1R / 4] = 0u;
        snprintf(what, sizeof what, "id_offset %ld: node and HAL init", (long)offsets[o]);
        check(att_node_init(&fnode, &s) == ATT_OK && att_can_hal_init(&h2, fake_io(), &fnode, 42000000u) == ATT_OK,
              what);
        n_got = att_node_rx_ids(&fnode, got);
        for (g = 0u; g < n_got; g++) {
            for (k = 0u; k < n_want; k++) {
                found += (uint32_t)(got[g] == want[k]);
            }
        }
        snprintf(what, sizeof what, "id_offset %ld: att_node_rx_ids gives the %lu IDs of the DBC + offset",
                 (long)offsets[o], (unsigned long)n_want);
        check(n_got == n_want && found == n_want, what);
        check_acceptance("bxCAN FIFO 0:", offsets[o], bx_accepts);
    }
}

/* Other nodes' traffic never reaches this node: no unknown IDs, no error count. */
static void test_other_traffic(void)
{
    att_can_frame_t fr;
    const uint32_t unknown = node.stats.unknown_ids;
    const uint32_t before = can.stats.rx_frames;
    uint32_t i;
    uint32_t kept_out = 0u;
    memset(&fr, 0, sizeof fr);
    fr.len = 8u;
    for (i = 0u; i < 300u; i++) {
        fr.id = (0x080u + 7u * i) & 0x7ffu;
        if (fr.id >= 0x100u && fr.id <= 0x300u) {
            fr.id = 0x400u + i; /* not an attica ID of this node */
        }
        fr.data[1] = (uint8_t)i;
        kept_out += (uint32_t)(fake_receive(&fake, &fr, 0) == 0);
        kept_out += (uint32_t)(fake_receive(&fake, &fr, 1) == 0);
        (void)att_can_hal_service(&can);
    }
    check(kept_out == 600u && can.stats.rx_frames == before && node.stats.unknown_ids == unknown &&
              att_node_error_count(&node) == 0u,
          "300 standard + 300 extended frames of other nodes: none reached the node, its error count stays 0");
}

static void test_fd_refused(void)
{
#if ATT_NODE_WITH_FD
    att_node_settings_t s;
    static att_node_t fd_node;
    att_can_hal_t h2;
    att_node_settings_default(ATT_FILTER_ARS, 100.0f, &s);
    s.fd = true;
    s.data_bitrate = 2000000u;
    memset(&fake, 0, sizeof fake);
    fake.ack_init = 1;
    check(att_node_init(&fd_node, &s) == ATT_OK && att_can_hal_init(&h2, fake_io(), &fd_node, 42000000u) == ATT_ERR_SETTINGS,
          "init refuses a CAN FD node (bxCAN is classic only)");
#endif
}

/* Samples in, output sets out, equal to a filter stepped on the decoded samples. */
static void test_traffic(void)
{
    att_filter_settings_t fs;
    att_filter_t ref;
    att_output_t want;
    att_output_t got;
    uint32_t i;
    uint32_t j;
    uint32_t k;
    uint32_t steps = 0u;
    uint32_t mismatches = 0u;
    uint32_t sets = 0u;
    const uint32_t n = 200u;
    char what[120];
    att_filter_settings_default(ATT_FILTER_ARS, 0.01f, &fs);
    att_filter_init(&ref, ATT_FILTER_ARS, &fs);
    for (i = 0u; i < n; i++) {
        att_sample_t s;
        att_sample_t q;
        att_can_frame_t fr[3];
        uint32_t tx_before = fake.tx_n;
        make_sample(&s);
        att_can_encode_imu(&s, (uint8_t)(i & 15u), fr);
        /* what the node will see: the dequantised frames */
        att_can_decode_imu_part(&fr[0], &q.gyr);
        att_can_decode_imu_part(&fr[1], &q.acc);
        att_can_decode_imu_part(&fr[2], &q.mag);
        (void)att_filter_step(&ref, &q, &want);
        for (j = 0u; j < 3u; j++) {
            fake_receive(&fake, &fr[j], 0);
        }
        steps += (uint32_t)att_can_hal_service(&can);
        /* the bus drains the mailboxes; the driver refills them */
        for (k = 0u; k < 8u && att_node_tx_pending(&node) + 3u > 0u; k++) {
            fake_complete_tx(&fake);
            (void)att_can_hal_transmit(&can);
        }
        fake_complete_tx(&fake);
        memset(&got, 0, sizeof got);
        for (j = tx_before; j < fake.tx_n; j++) {
            (void)att_can_decode_output(&fake.tx_log[j], &got);
        }
        if (fake.tx_n - tx_before >= 6u) {
            sets++;
            if (bits(got.q.w) != bits(want.q.w) || bits(got.q.x) != bits(want.q.x) ||
                bits(got.q.y) != bits(want.q.y) || bits(got.q.z) != bits(want.q.z) ||
                got.steps % 65536u != want.steps % 65536u) {
                mismatches++;
            }
        }
    }
    snprintf(what, sizeof what, "%lu samples through the fake bxCAN: %lu steps", (unsigned long)n,
             (unsigned long)steps);
    check(steps == n && node.stats.steps == n, what);
    snprintf(what, sizeof what, "%lu output sets, quaternion and step count bit-identical to a direct filter",
             (unsigned long)sets);
    check(sets == n && mismatches == 0u, what);
    check(can.stats.rx_frames == 3u * n && can.stats.rx_ignored == 0u, "every IMU frame moved to the node");
    check(node.stats.crc_errors == 0u && node.stats.dlc_errors == 0u, "no CRC or DLC errors at the node");
    check(can.stats.tx_frames == fake.tx_n, "every frame written to a mailbox reached the bus");
}

static void test_errors(void)
{
    att_can_frame_t fr;
    uint32_t ign = can.stats.rx_ignored;
    uint32_t ovr = can.stats.rx_overruns;
    uint32_t i;
    memset(&fr, 0, sizeof fr);
    fr.id = 0x100u;
    fr.len = 8u;
    fake_inject(&fake, &fr, 1); /* past the filter, e.g. a bank of the application's own */
    (void)att_can_hal_receive(&can);
    check(can.stats.rx_ignored == ign + 1u && fake.fifo_n == 0u, "extended-ID frame dropped and released");
    for (i = 0u; i < 4u; i++) {
        fake_receive(&fake, &fr, 0);
    }
    (void)att_can_hal_receive(&can);
    check(can.stats.rx_overruns == ovr + 1u && (fake.reg[ATT_BXCAN_RF0R / 4] & ATT_BXCAN_RF0R_FOVR0) == 0u,
          "FIFO overrun counted and cleared");
    check(fake.fifo_n == 0u, "FIFO drained");
    fake.reg[ATT_BXCAN_ESR / 4] = ATT_BXCAN_ESR_BOFF;
    (void)att_can_hal_service(&can);
    (void)att_can_hal_service(&can);
    fake.reg[ATT_BXCAN_ESR / 4] = 0u;
    (void)att_can_hal_service(&can);
    check(can.stats.bus_off == 1u && can.stats.recoveries == 1u && can.phase == ATT_CAN_HAL_ON,
          "bus-off counted once per episode, recovered");
    /* mailboxes full: frames stay in the node until a mailbox frees up */
    {
        att_can_cmd_t c;
        att_can_frame_t cmd;
        size_t pending;
        memset(&c, 0, sizeof c);
        c.cmd = ATT_CAN_CMD_RESET;
        att_can_encode_cmd(&c, &cmd);
        fake.tx_busy[0] = fake.tx_busy[1] = fake.tx_busy[2] = 1;
        fake_receive(&fake, &cmd, 0);
        (void)att_can_hal_service(&can);
        pending = att_node_tx_pending(&node);
        check(pending == 1u, "answer held in the node while every mailbox is busy");
        fake_complete_tx(&fake);
        check(att_can_hal_transmit(&can) == 1u && att_node_tx_pending(&node) == 0u,
              "answer sent once a mailbox is free");
    }
    check(att_can_hal_receive(NULL) == 0u && att_can_hal_transmit(NULL) == 0u && att_can_hal_service(NULL) == 0u,
          "NULL handles");
}

/* ---- controller faults ----------------------------------------------------------------------- */

static att_node_t bnode; /* DIAG (and DIAG_BUS) after every set */

static void bus_setup(void)
{
    att_node_settings_t s;
    (void)att_node_settings_default(ATT_FILTER_ARS, 100.0f, &s);
    s.diag_divider = 1u;
    memset(&fake, 0, sizeof fake);
    fake.ack_init = 1;
    check(att_node_init(&bnode, &s) == ATT_OK && att_can_hal_init(&can, fake_io(), &bnode, 42000000u) == ATT_OK,
          "faults: node (DIAG after every set) and HAL init");
}

/* One IMU sample (three frames) arrives from the bus. */
static void bus_sample(uint32_t i)
{
    att_sample_t s;
    att_can_frame_t fr[3];
    uint32_t j;
    make_sample(&s);
    att_can_encode_imu(&s, (uint8_t)(i & 15u), fr);
    for (j = 0u; j < 3u; j++) {
        (void)fake_receive(&fake, &fr[j], 0);
    }
}

/* The bus takes every frame the node has (the driver refills the mailboxes). */
static void bus_drain(void)
{
    uint32_t k;
    for (k = 0u; k < 64u && att_node_tx_pending(&bnode) > 0u; k++) {
        fake_complete_tx(&fake);
        (void)att_can_hal_transmit(&can);
    }
    fake_complete_tx(&fake);
}

/*
 * A bus-off episode: ESR.BOFF from the next service call on; service calls until the driver writes MCR
 * (the recovery), then BOFF clears (the controller back on the bus) and one more call sees it. Returns
 * the calls after the one that saw the bus-off until the recovery (0: none within 5000); *mbox: mailbox
 * writes meanwhile.
 */
static uint32_t bus_off_episode(uint32_t *mbox)
{
    uint32_t calls = 0u;
    const uint32_t mb0 = fake.mbox_writes;
    fake.mcr_n = 0u;
    fake.reg[ATT_BXCAN_ESR / 4] = ATT_BXCAN_ESR_BOFF | ATT_BXCAN_ESR_EPVF | ATT_BXCAN_ESR_EWGF;
    (void)att_can_hal_service(&can);
    while (fake.mcr_n == 0u && calls < 5000u) {
        (void)att_can_hal_service(&can);
        calls++;
    }
    *mbox = fake.mbox_writes - mb0;
    fake.reg[ATT_BXCAN_ESR / 4] = 0u;
    (void)att_can_hal_service(&can);
    return fake.mcr_n == 0u ? 0u : calls;
}

/* n service calls on a quiet bus in state esr. */
static void bus_calls(uint32_t n, uint32_t esr)
{
    uint32_t k;
    fake.reg[ATT_BXCAN_ESR / 4] = esr;
    for (k = 0u; k < n; k++) {
        (void)att_can_hal_service(&can);
    }
    fake.reg[ATT_BXCAN_ESR / 4] = 0u;
}

/* The ATT_DIAG_BUS frames sent since log index from: each right after its ATT_DIAG, checked, with want. */
static uint32_t bus_diag_frames(uint32_t from, const att_can_bus_diag_t *want, const char *label)
{
    uint32_t j;
    uint32_t seen = 0u;
    uint32_t bad = 0u;
    char what[200];
    for (j = from; j < fake.tx_n; j++) {
        if (fake.tx_log[j].id == (uint32_t)ATT_CAN_ID_DIAG_BUS) {
            seen++;
            bad += diag_bus_frame_check("bxcan", label, j > 0u ? &fake.tx_log[j - 1u] : NULL, &fake.tx_log[j], want);
        }
    }
    snprintf(what, sizeof what, "faults: %s: %lu ATT_DIAG_BUS after its ATT_DIAG, E2E good, the driver's counters",
             label, (unsigned long)seen);
    check(seen > 0u && bad == 0u, what);
    return seen;
}

static void test_bus_faults(void)
{
    att_can_bus_diag_t want;
    uint32_t from;
    uint32_t mbox;
    uint32_t writes;
    uint32_t k;
    uint32_t delays[16];
    uint32_t bad = 0u;
    char what[240];
    {
        /* 125 Hz sets of 7 classic frames (DIAG after every set) fill 94.5 % of 125 kbit/s; 8 would not fit */
        att_node_settings_t s;
        att_can_hal_t h2;
        (void)att_node_settings_default(ATT_FILTER_ARS, 125.0f, &s);
        s.diag_divider = 1u;
        s.bitrate = 125000u;
        memset(&fake, 0, sizeof fake);
        fake.ack_init = 1;
        check(att_node_init(&bnode, &s) == ATT_OK && att_node_set_bus_diag(&bnode, att_can_hal_bus_diag, &can) ==
                                                          ATT_ERR_SETTINGS &&
                  bnode.bus_diag == NULL && att_can_hal_init(&h2, fake_io(), &bnode, 42000000u) == ATT_ERR_SETTINGS &&
                  fake.writes == 0u,
              "faults: a node whose outputs fit the bus only without ATT_DIAG_BUS: the hook and init refused, nothing "
              "written");
        s.diag_divider = 2u;
        check(att_node_init(&bnode, &s) == ATT_OK && att_can_hal_init(&h2, fake_io(), &bnode, 42000000u) == ATT_OK &&
                  bnode.bus_diag == att_can_hal_bus_diag && att_node_set_bus_diag(&bnode, NULL, &h2) == ATT_OK &&
                  bnode.bus_diag == NULL && bnode.bus_diag_ctx == NULL &&
                  att_node_set_bus_diag(NULL, att_can_hal_bus_diag, &h2) == ATT_ERR_NULL,
              "faults: with DIAG every 2nd set it fits; a NULL hook removes it; NULL node refused");
    }
    bus_setup();
    bus_sample(0u);
    (void)att_can_hal_service(&can);
    bus_drain();
    memset(&want, 0, sizeof want);
    (void)bus_diag_frames(0u, &want, "quiet bus");

    /* bus-off with two frames still in the mailboxes and a sample arriving at the same service */
    fake.tx_busy[0] = fake.tx_busy[2] = 1;
    fake.mcr_n = 0u;
    from = fake.tx_n;
    mbox = fake.mbox_writes;
    bus_sample(1u);
    fake.reg[ATT_BXCAN_ESR / 4] = ATT_BXCAN_ESR_BOFF | ATT_BXCAN_ESR_EPVF | ATT_BXCAN_ESR_EWGF |
                                  (3u << ATT_BXCAN_ESR_LEC_SHIFT) | (0xf8u << 16);
    (void)att_can_hal_service(&can);
    check(can.stats.bus_off == 1u && can.phase == ATT_CAN_HAL_BACKOFF && att_node_tx_pending(&bnode) == 8u &&
              fake.mbox_writes == mbox && fake.mcr_n == 0u,
          "faults: bus-off seen: counted, the set + DIAG + DIAG_BUS held in the node, no mailbox written, no MCR "
          "write yet");
    check(can.stats.tx_aborted == 2u && fake.aborted == 2u && !fake.tx_busy[0] && !fake.tx_busy[1] && !fake.tx_busy[2],
          "faults: the 2 frames pending in the mailboxes aborted (TSR.ABRQ0, ABRQ2): nothing left to retry after the "
          "recovery");
    check(can.stats.error_passive == 1u && can.stats.error_warning == 1u && can.stats.lec == 3u,
          "faults: error-passive and warning entries counted, last error code 3 (acknowledgment) kept");
    check(att_can_hal_transmit(&can) == 0u && fake.mbox_writes == mbox,
          "faults: att_can_hal_transmit writes nothing while bus-off");
    writes = fake.writes;
    (void)att_can_hal_service(&can); /* ATT_CAN_HAL_BACKOFF_FIRST = 1 call later: the recovery */
    snprintf(what, sizeof what,
             "faults: recovery after %u call: MCR = INRQ|TXFP (0x%lx), then MCR = TXFP (0x%lx), nothing else written",
             (unsigned)ATT_CAN_HAL_BACKOFF_FIRST, (unsigned long)fake.mcr_log[0], (unsigned long)fake.mcr_log[1]);
    check(ATT_CAN_HAL_BACKOFF_FIRST == 1u && fake.mcr_n == 2u &&
              fake.mcr_log[0] == (ATT_BXCAN_MCR_INRQ | ATT_BXCAN_MCR_TXFP) && fake.mcr_log[1] == ATT_BXCAN_MCR_TXFP &&
              fake.writes == writes + 2u && can.phase == ATT_CAN_HAL_RECOVERING && fake.mbox_writes == mbox,
          what);
    bus_calls(3u, ATT_BXCAN_ESR_BOFF | ATT_BXCAN_ESR_EPVF); /* 128 x 11 recessive bits take a while */
    check(fake.mcr_n == 2u && fake.mbox_writes == mbox && can.stats.recoveries == 0u &&
              can.stats.error_passive == 1u && can.stats.error_warning == 1u,
          "faults: recovering (BOFF still set): no second request, still nothing sent, no new entries counted");
    (void)att_can_hal_service(&can); /* BOFF clear: back on the bus */
    bus_drain();
    check(can.stats.recoveries == 1u && can.phase == ATT_CAN_HAL_ON && att_node_tx_pending(&bnode) == 0u &&
              fake.tx_n == from + 8u,
          "faults: BOFF clear: recovery counted, the held frames sent");
    want.state = (uint8_t)ATT_CAN_BUS_OFF;
    want.lec = 3u;
    want.bus_off = 1u;
    want.error_passive = 1u;
    want.error_warning = 1u;
    (void)bus_diag_frames(from, &want, "queued during the back-off");

    /* the back-off doubles up to the cap (no good period between the episodes) */
    for (k = 0u; k < 12u; k++) {
        delays[k] = bus_off_episode(&mbox);
        bad += (uint32_t)(mbox != 0u);
        bad += (uint32_t)(fake.mcr_log[0] != (ATT_BXCAN_MCR_INRQ | ATT_BXCAN_MCR_TXFP) ||
                          fake.mcr_log[1] != ATT_BXCAN_MCR_TXFP);
    }
    for (k = 0u; k < 12u; k++) {
        const uint32_t expect = (k < 10u) ? (2u << k) : ATT_CAN_HAL_BACKOFF_MAX;
        bad += (uint32_t)(delays[k] != expect);
    }
    snprintf(what, sizeof what,
             "faults: back-off of 12 more episodes: %lu %lu %lu ... %lu %lu %lu calls (2, 4, 8 ... capped at %u), "
             "the same recovery writes, no mailbox written",
             (unsigned long)delays[0], (unsigned long)delays[1], (unsigned long)delays[2], (unsigned long)delays[9],
             (unsigned long)delays[10], (unsigned long)delays[11], (unsigned)ATT_CAN_HAL_BACKOFF_MAX);
    check(ATT_CAN_HAL_BACKOFF_MAX == 1024u && bad == 0u && can.stats.bus_off == 13u && can.stats.recoveries == 13u,
          what);

    /* it starts over after ATT_CAN_HAL_BACKOFF_RESET good calls, not before, not across error-passive */
    bus_calls(ATT_CAN_HAL_BACKOFF_RESET - 1u, 0u);
    k = bus_off_episode(&mbox);
    check(k == ATT_CAN_HAL_BACKOFF_MAX, "faults: RESET - 1 good calls: the back-off stays at the cap");
    bus_calls(ATT_CAN_HAL_BACKOFF_RESET, ATT_BXCAN_ESR_EWGF); /* error warning is still good */
    k = bus_off_episode(&mbox);
    check(k == ATT_CAN_HAL_BACKOFF_FIRST, "faults: RESET good calls (error warning counts as good): back to FIRST");
    bus_calls(ATT_CAN_HAL_BACKOFF_RESET - 1u, 0u);
    bus_calls(1u, ATT_BXCAN_ESR_EPVF);
    bus_calls(ATT_CAN_HAL_BACKOFF_RESET - 1u, 0u);
    k = bus_off_episode(&mbox);
    check(k == 2u * ATT_CAN_HAL_BACKOFF_FIRST,
          "faults: an error-passive call breaks the good run: the back-off doubles instead of starting over");

    /* a controller that does not acknowledge INRQ: counted, retried after the next (doubled) back-off */
    {
        const uint32_t off0 = can.stats.bus_off;
        fake.mcr_n = 0u;
        fake.ack_init = 0;
        fake.reg[ATT_BXCAN_MSR / 4] = 0u;
        bus_calls(1u + 4u, ATT_BXCAN_ESR_BOFF); /* edge, then the back-off of 4 calls */
        check(can.stats.recovery_timeouts == 1u && can.phase == ATT_CAN_HAL_BACKOFF && can.wait == 8u &&
                  fake.mcr_n == 1u && can.stats.bus_off == off0 + 1u,
              "faults: INAK never came: one INRQ write, counted, back-off again (8 calls)");
        fake.ack_init = 1;
        bus_calls(8u, ATT_BXCAN_ESR_BOFF);
        (void)att_can_hal_service(&can);
        check(fake.mcr_n == 3u && fake.mcr_log[1] == (ATT_BXCAN_MCR_INRQ | ATT_BXCAN_MCR_TXFP) &&
                  fake.mcr_log[2] == ATT_BXCAN_MCR_TXFP && can.phase == ATT_CAN_HAL_ON,
              "faults: the retry recovers");
    }

    /* error-passive and warning: once per entry, however long they last */
    {
        const uint32_t p0 = can.stats.error_passive;
        const uint32_t w0 = can.stats.error_warning;
        bus_calls(5u, ATT_BXCAN_ESR_EPVF | ATT_BXCAN_ESR_EWGF);
        bus_calls(2u, ATT_BXCAN_ESR_EWGF);
        bus_calls(3u, ATT_BXCAN_ESR_EPVF | ATT_BXCAN_ESR_EWGF);
        bus_calls(2u, 0u);
        bus_calls(4u, ATT_BXCAN_ESR_EWGF | (5u << ATT_BXCAN_ESR_LEC_SHIFT));
        bus_calls(1u, 7u << ATT_BXCAN_ESR_LEC_SHIFT); /* 7: written by software, not an error */
        snprintf(what, sizeof what,
                 "faults: error-passive entered twice (%lu), warning twice (%lu) over 17 calls; LEC 5 kept, 7 ignored",
                 (unsigned long)(can.stats.error_passive - p0), (unsigned long)(can.stats.error_warning - w0));
        check(can.stats.error_passive == p0 + 2u && can.stats.error_warning == w0 + 2u && can.stats.lec == 5u, what);
    }

    /* overruns of FIFO 0 and FIFO 1: counted, flags cleared */
    {
        att_can_frame_t fr;
        const uint32_t o0 = can.stats.rx_overruns;
        memset(&fr, 0, sizeof fr);
        fr.id = 0x100u;
        fr.len = 8u;
        for (k = 0u; k < 4u; k++) {
            (void)fake_inject(&fake, &fr, 0);
        }
        fake.reg[ATT_BXCAN_RF1R / 4] |= ATT_BXCAN_RF0R_FOVR0;
        (void)att_can_hal_receive(&can);
        check(can.stats.rx_overruns == o0 + 2u && (fake.reg[ATT_BXCAN_RF0R / 4] & ATT_BXCAN_RF0R_FOVR0) == 0u &&
                  (fake.reg[ATT_BXCAN_RF1R / 4] & ATT_BXCAN_RF0R_FOVR0) == 0u,
              "faults: FOVR0 and FOVR1 counted once each and cleared (write 1)");
        (void)att_can_hal_receive(&can);
        check(can.stats.rx_overruns == o0 + 2u, "faults: cleared flags are not counted again");
    }

    /* what the host sees now: the DIAG_BUS of the next set */
    fake.reg[ATT_BXCAN_ESR / 4] = ATT_BXCAN_ESR_EWGF;
    from = fake.tx_n;
    bus_sample(2u);
    (void)att_can_hal_service(&can);
    bus_drain();
    fake.reg[ATT_BXCAN_ESR / 4] = 0u;
    att_can_hal_bus_diag(&can, &want);
    want.state = (uint8_t)ATT_CAN_BUS_WARNING;
    (void)bus_diag_frames(from, &want, "after the faults");
    check(want.bus_off == 17u && want.recoveries == 17u && want.lec == 5u && want.rx_overruns >= 2u,
          "faults: 17 bus-off episodes, 17 recoveries, overruns, last error code 5 reported");
    /* saturation at 255 on the bus */
    {
        att_can_frame_t f;
        att_can_bus_diag_t d;
        att_can_bus_diag_t back;
        memset(&d, 0, sizeof d);
        d.state = 7u;
        d.lec = 15u;
        d.bus_off = 256u;
        d.recoveries = 255u;
        d.error_passive = 100000u;
        d.rx_overruns = 1u;
        att_can_encode_diag_bus(&d, 19u, &f);
        check(att_can_check(&f) == ATT_CAN_OK && att_can_decode_diag_bus(&f, &back) && back.state == 3u &&
                  back.lec == 7u && back.bus_off == 255u && back.recoveries == 255u && back.error_passive == 255u &&
                  back.error_warning == 0u && back.rx_overruns == 1u && att_can_counter(&f) == 3u,
              "faults: ATT_DIAG_BUS saturates the counters at 255, masks state (2 bits), lec (3 bits), counter");
    }
}

int main(void)
{
    test_btr();
    test_fd_refused();
    test_acceptance_filter();
    test_init();
    test_traffic();
    test_other_traffic();
    test_errors();
    test_bus_faults();
    printf("%d failure(s)\n", failures);
    return failures;
}
