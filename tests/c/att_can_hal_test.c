/**
 * @file att_can_hal_test.c
 * @brief Host unit test of the bxCAN HAL (firmware/ports/cortex_m/att_can_hal.c) against a fake controller.
 *
 * The fake keeps a register file and models what the driver relies on: INRQ/SLEEP acknowledged in
 * MSR (or never, to test the timeout), the acceptance filter (bx_fifo0_accepts: the bxCAN filter
 * matching rules of RM0090 32.7.4 evaluated on the filter registers the driver wrote; a frame that
 * arrives from the bus reaches FIFO 0 only when they say so), a 3-deep receive FIFO behind
 * RF0R/RI0R.. with RFOM0 release and FOVR0 overrun, three transmit mailboxes whose TXRQ captures the
 * frame and stays busy until the test completes the transmission. A real attica node runs behind the
 * driver: IMU sample frames go in, output sets come out and must equal (bit for bit) a filter stepped
 * directly on the decoded samples.
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
    if (offset == ATT_BXCAN_MCR) {
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
    check(att_can_hal_init(&h2, fake_io(), &node, 42000000u) == ATT_ERR_SETTINGS,
          "init times out when the controller never acknowledges INRQ");
    fake.ack_init = 1;
    check(att_can_hal_init(&h2, fake_io(), &node, 42000001u) == ATT_ERR_SETTINGS,
          "init refuses a clock that cannot make the bitrate");
    check(att_can_hal_init(NULL, fake_io(), &node, 42000000u) == ATT_ERR_NULL, "init NULL");
    memset(&fake, 0, sizeof fake);
    fake.ack_init = 1;
    check(att_can_hal_init(&can, fake_io(), &node, 42000000u) == ATT_OK, "init");
    check(fake.reg[ATT_BXCAN_BTR / 4] == 0x001a0005u, "BTR written");
    check((fake.reg[ATT_BXCAN_MCR / 4] & ATT_BXCAN_MCR_INRQ) == 0u, "normal mode after init");
    check((fake.reg[ATT_BXCAN_MCR / 4] & ATT_BXCAN_MCR_ABOM) != 0u, "automatic bus-off recovery");
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
    check(can.stats.bus_off == 1u, "bus-off counted once per episode");
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

int main(void)
{
    test_btr();
    test_fd_refused();
    test_acceptance_filter();
    test_init();
    test_traffic();
    test_other_traffic();
    test_errors();
    printf("%d failure(s)\n", failures);
    return failures;
}
