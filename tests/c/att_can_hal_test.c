/**
 * @file att_can_hal_test.c
 * @brief Host unit test of the bxCAN HAL (firmware/ports/cortex_m/att_can_hal.c) against a fake controller.
 *
 * The fake keeps a register file and models what the driver relies on: INRQ/SLEEP acknowledged in
 * MSR (or never, to test the timeout), a 3-deep receive FIFO behind RF0R/RI0R.. with RFOM0 release and
 * FOVR0 overrun, three transmit mailboxes whose TXRQ captures the frame and stays busy until the test
 * completes the transmission. A real attica node runs behind the driver: IMU sample frames go in,
 * output sets come out and must equal (bit for bit) a filter stepped directly on the decoded samples.
 *
 * Prints "ok ..." / "FAIL ..." per check; exit status = number of failures.
 */
#include <stdio.h>
#include <string.h>

#include "att_can_hal.h"
#include "attica/att_can.h"
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
} fake_t;

static int failures;

static void check(int ok, const char *what)
{
    printf("%s %s\n", ok ? "ok" : "FAIL", what);
    if (!ok) {
        failures++;
    }
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

/* A frame arrives; false (and FOVR0) when the FIFO is full. */
static int fake_receive(fake_t *f, const att_can_frame_t *fr, int extended)
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

static uint32_t lcg = 99u;
static float uniform(void)
{
    lcg = lcg * 1664525u + 1013904223u;
    return (float)(lcg >> 8) * 0x1p-23f - 1.0f;
}

static uint32_t bits(float x)
{
    uint32_t w;
    memcpy(&w, &x, sizeof w);
    return w;
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
    check((fake.reg[ATT_BXCAN_FA1R / 4] & 1u) == 1u && fake.reg[ATT_BXCAN_F0R2 / 4] == 0u &&
              (fake.reg[ATT_BXCAN_FMR / 4] & ATT_BXCAN_FMR_FINIT) == 0u,
          "filter bank 0 active, accepts all, filters out of init");
}

static void test_fd_refused(void)
{
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
        s.gyr.x = 0.5f * uniform();
        s.gyr.y = 0.5f * uniform();
        s.gyr.z = 0.5f * uniform();
        s.acc.x = 0.3f * uniform();
        s.acc.y = 0.3f * uniform();
        s.acc.z = 9.8f + 0.1f * uniform();
        s.mag.x = 20.0f;
        s.mag.y = 5.0f;
        s.mag.z = -40.0f;
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
    fake_receive(&fake, &fr, 1);
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
    test_init();
    test_fd_refused();
    test_traffic();
    test_errors();
    printf("%d failure(s)\n", failures);
    return failures;
}
