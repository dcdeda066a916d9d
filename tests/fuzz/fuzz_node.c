/**
 * @file fuzz_node.c
 * @brief libFuzzer target: the CAN node's receive path (att_node_rx / att_node_poll / att_node_tx) with
 * sample frames in any order, corrupted frames, raw frames, commands (select, reset, set gain = retune)
 * and tx back-pressure, for every filter kind and both bus formats (docs/robustness.md).
 *
 * Frames are mostly built with the codec and sealed (else the fuzzer would rarely get past the CRC),
 * then optionally corrupted in a way the harness knows. Invariants:
 * - N1 every transmitted frame checks (att_can_check), output sets are complete (QUAT_A, QUAT_B, QUAT16,
 *   EULER, BIAS, STATUS with one counter and a set CRC that verifies; or one ATT_OUT_FD), the set counter
 *   counts mod 16, ATT_DIAG follows every diag_divider-th set.
 * - N2 a frame the independent model (fuzz_model.h) calls unknown / wrong length / bad CRC increments
 *   exactly that counter by one, runs no step and leaves the filter's output bit for bit as it was.
 * - N3 every command with a good CRC gets exactly one answer (STATUS, ack bit, its cmd and counter);
 *   unknown commands answer UNKNOWN_CMD; a select answered OK runs the asked kind from step 0.
 * - N4 a set-gain answered OK keeps the filter's state: att_filter_output is bit for bit unchanged but for
 *   cov (ars's and mars's covariance model follows the new gains at once); a refused one changes nothing.
 * - N5 a clean sample (the next counter, no partial pending) runs exactly one step.
 * - N6 samples <= steps <= 15 samples (a sample steps over 1 .. 15 periods), tx_overflows == 0,
 *   rx_frames + rx_overflows == frames pushed; a frame that completes a sample steps the filter over
 *   n = (its counter - the last stepped sample's) mod 16 periods, 1 for the first sample and for 0
 *   (stats.steps and the filter's step count both advance by n).
 * - N7 determinism: a second node, filled with other bytes before init, sends the same bytes.
 * The -msan build adds: no branch and no sent byte depends on uninitialised memory.
 */
#include <stdbool.h>

#include "attica/att_node.h"
#include "fuzz_common.h"
#include "fuzz_model.h"

#define FZ_MAX_OPS 400
#define FZ_LOG_MAX 8192

typedef struct {
    att_can_frame_t log[FZ_LOG_MAX]; /* every frame sent, in order */
    size_t n_log;
    uint32_t pushed;
    /* output set parser */
    att_can_frame_t set[6];
    size_t in_set;
    uint32_t sets;
    uint32_t answers;
} tracker_t;

static att_node_t g_a;
static att_node_t g_b;
static tracker_t g_ta;
static tracker_t g_tb;

static bool same_out(const att_output_t *x, const att_output_t *y)
{
    return memcmp(&x->q, &y->q, sizeof x->q) == 0 && memcmp(&x->euler, &y->euler, sizeof x->euler) == 0 &&
           memcmp(&x->gyro_bias, &y->gyro_bias, sizeof x->gyro_bias) == 0 &&
           memcmp(x->cov, y->cov, sizeof x->cov) == 0 && x->flags == y->flags && x->steps == y->steps;
}

/* same_out but the covariance: the estimate (ars's and mars's covariance model follows a new gain at once). */
static bool same_estimate(const att_output_t *x, const att_output_t *y)
{
    return memcmp(&x->q, &y->q, sizeof x->q) == 0 && memcmp(&x->euler, &y->euler, sizeof x->euler) == 0 &&
           memcmp(&x->gyro_bias, &y->gyro_bias, sizeof x->gyro_bias) == 0 && x->flags == y->flags &&
           x->steps == y->steps;
}

static void filter_out(const att_node_t *n, att_output_t *o)
{
    att_filter_output(&n->f, o);
}

/** N1: one transmitted frame, in order. */
static void track_tx(const att_node_t *n, tracker_t *t, const att_can_frame_t *f)
{
    if (t->n_log < FZ_LOG_MAX) t->log[t->n_log++] = *f;
    if (f->id == ATT_CAN_ID_STATUS && (f->data[7] & ATT_CAN_ACK_ANSWER) != 0u) {
        FZ_CHECK(t->in_set == 0u, "command answer inside an output set");
        FZ_CHECK(att_can_check(f) == ATT_CAN_OK, "answer STATUS does not check");
        t->answers++;
        return;
    }
    if (f->id == ATT_CAN_ID_CAL_ACK) {
        FZ_CHECK(t->in_set == 0u, "calibration answer inside an output set");
        FZ_CHECK(att_can_check(f) == ATT_CAN_OK, "ATT_CAL_ACK does not check");
        t->answers++;
        return;
    }
    if (f->id == ATT_CAN_ID_LIN_ACC || f->id == ATT_CAN_ID_EARTH_ACC || f->id == ATT_CAN_ID_ACCEL_FD) {
        FZ_CHECK(n->s.accel_out && t->in_set == 0u && t->sets > 0u, "acceleration frame %03x unasked or inside a set",
                 (unsigned)f->id);
        FZ_CHECK((f->id == ATT_CAN_ID_ACCEL_FD) == n->s.fd, "acceleration frame %03x in the wrong mode", (unsigned)f->id);
        FZ_CHECK(att_can_check(f) == ATT_CAN_OK, "acceleration frame %03x does not check", (unsigned)f->id);
        FZ_CHECK(att_can_counter(f) == ((t->sets - 1u) & 15u), "acceleration frame counter");
        return;
    }
    if (f->id == ATT_CAN_ID_DIAG) {
        FZ_CHECK(t->in_set == 0u, "DIAG inside an output set");
        FZ_CHECK(att_can_check(f) == ATT_CAN_OK, "DIAG does not check");
        FZ_CHECK(n->s.diag_divider != 0u && t->sets % n->s.diag_divider == 0u, "DIAG after set %u (divider %u)",
                 t->sets, n->s.diag_divider);
        FZ_CHECK(att_can_counter(f) == ((t->sets - 1u) & 15u), "DIAG counter");
        return;
    }
    if (f->id == ATT_CAN_ID_OUT_FD) {
        FZ_CHECK(n->s.fd && t->in_set == 0u, "ATT_OUT_FD in classic mode or inside a set");
        FZ_CHECK(att_can_check(f) == ATT_CAN_OK, "ATT_OUT_FD does not check");
        FZ_CHECK(att_can_counter(f) == (t->sets & 15u), "OUT_FD counter %u, set %u", att_can_counter(f), t->sets);
        t->sets++;
        return;
    }
    {
        static const uint32_t order[6] = {ATT_CAN_ID_QUAT_A, ATT_CAN_ID_QUAT_B, ATT_CAN_ID_QUAT16,
                                          ATT_CAN_ID_EULER, ATT_CAN_ID_BIAS, ATT_CAN_ID_STATUS};
        FZ_CHECK(!n->s.fd, "classic output frame %03x in FD mode", (unsigned)f->id);
        FZ_CHECK(f->id == order[t->in_set], "output set frame %zu is %03x, want %03x", t->in_set, (unsigned)f->id,
                 (unsigned)order[t->in_set]);
        FZ_CHECK(att_can_check(f) == ATT_CAN_OK, "output frame %03x does not check", (unsigned)f->id);
        t->set[t->in_set++] = *f;
        if (t->in_set == 6u) {
            t->in_set = 0u;
            FZ_CHECK(att_can_status_crc(&t->set[5], &t->set[0], &t->set[1], &t->set[2]) == t->set[5].data[0],
                     "set CRC does not verify");
            FZ_CHECK(att_can_counter(&t->set[3]) == (t->sets & 15u) && att_can_counter(&t->set[4]) == (t->sets & 15u) &&
                         att_can_counter(&t->set[5]) == (t->sets & 15u),
                     "set counters differ from the set index %u", t->sets);
            t->sets++;
        }
    }
}

static void drain(att_node_t *n, tracker_t *t)
{
    att_can_frame_t f;
    while (att_node_tx(n, &f)) {
        track_tx(n, t, &f);
    }
}

static void push(att_node_t *n, tracker_t *t, const att_can_frame_t *f)
{
    t->pushed++;
    (void)att_node_rx(n, f);
}

static void check_stats(const att_node_t *n, const tracker_t *t)
{
    FZ_CHECK(n->stats.steps >= n->stats.samples && n->stats.steps - n->stats.samples <= 14u * n->stats.samples,
             "steps %u for %u samples", n->stats.steps, n->stats.samples);
    FZ_CHECK(n->stats.tx_overflows == 0u, "tx_overflows %u", n->stats.tx_overflows);
    FZ_CHECK(n->stats.rx_frames + n->stats.rx_overflows == t->pushed, "rx_frames %u + overflows %u != pushed %u",
             n->stats.rx_frames, n->stats.rx_overflows, t->pushed);
}

/** Corrupt f as the input says; returns what the model expects the node to make of it. */
static att_can_check_t corrupt(att_can_frame_t *f, fz_reader_t *r)
{
    uint8_t how = fz_u8(r);
    switch (how & 7u) {
    case 1: { /* flip one bit of the payload */
        uint8_t b = fz_u8(r);
        size_t bit = (size_t)b % (8u * (f->len ? f->len : 1u));
        f->data[bit / 8u] ^= (uint8_t)(1u << (bit % 8u));
        break;
    }
    case 2: /* wrong length */
        f->len = (uint8_t)(fz_u8(r) % 65u);
        break;
    case 3: /* classic/FD format toggled */
        f->fd = (uint8_t)(f->fd ^ 1u);
        break;
    case 4: /* another ID */
        f->id = (uint32_t)(fz_u16(r) & 0x7FFu);
        break;
    case 5: /* a byte replaced */
        f->data[fz_u8(r) % 64u] = fz_u8(r);
        break;
    default:
        break; /* clean */
    }
    return model_check(f);
}

static bool is_rx_id(uint32_t id)
{
    return id == ATT_CAN_ID_IMU_GYRO || id == ATT_CAN_ID_IMU_ACC || id == ATT_CAN_ID_IMU_MAG ||
           id == ATT_CAN_ID_IMU_FD || id == ATT_CAN_ID_CMD;
}

/** N2/N3/N4: push one frame, poll, and check what it did. */
static void one_frame(att_node_t *n, tracker_t *t, const att_can_frame_t *f, bool drain_now)
{
    att_node_stats_t s0 = n->stats;
    att_output_t o0;
    att_output_t o1;
    att_can_check_t want = model_check(f);
    uint32_t answers0 = t->answers;
    att_filter_kind_t kind0 = n->kind;
    bool queued_empty = n->rx_head == n->rx_tail && att_node_tx_pending(n) + ATT_NODE_SET_MAX <= ATT_NODE_TX_RING;
    att_can_cmd_t cmd;
    const bool have_last0 = n->have_last;
    const uint8_t last0 = n->last_counter;
    filter_out(n, &o0);
    push(n, t, f);
    (void)att_node_poll(n);
    if (drain_now) drain(n, t);
    check_stats(n, t);
    if (!queued_empty || !drain_now) {
        return; /* the frame may still wait in the ring: nothing to attribute */
    }
    filter_out(n, &o1);
    if (!is_rx_id(f->id) || want == ATT_CAN_ERR_UNKNOWN_ID) {
        FZ_CHECK(n->stats.unknown_ids == s0.unknown_ids + 1u, "unknown ID %03x not counted", (unsigned)f->id);
    } else if (want == ATT_CAN_ERR_DLC) {
        FZ_CHECK(n->stats.dlc_errors == s0.dlc_errors + 1u, "bad length %u/fd %u of %03x not counted", f->len, f->fd,
                 (unsigned)f->id);
    } else if (want == ATT_CAN_ERR_CRC) {
        FZ_CHECK(n->stats.crc_errors == s0.crc_errors + 1u, "bad CRC of %03x not counted", (unsigned)f->id);
    }
    if (want != ATT_CAN_OK || !is_rx_id(f->id)) {
        FZ_CHECK(n->stats.steps == s0.steps && same_out(&o0, &o1) && t->answers == answers0,
                 "a rejected frame (%03x, %d) touched the filter", (unsigned)f->id, (int)want);
        FZ_CHECK(n->stats.unknown_ids + n->stats.dlc_errors + n->stats.crc_errors ==
                     s0.unknown_ids + s0.dlc_errors + s0.crc_errors + 1u,
                 "a rejected frame was counted more than once");
        return;
    }
    if (f->id == ATT_CAN_ID_CMD) {
        const att_can_frame_t *a = &t->log[t->n_log - 1u];
        uint8_t result;
        FZ_CHECK(att_can_decode_cmd(f, &cmd), "decode_cmd");
        FZ_CHECK(t->answers == answers0 + 1u && n->stats.commands == s0.commands + 1u, "command not answered once");
        if (cmd.cmd >= ATT_CAN_CMD_CAL_BEGIN && cmd.cmd <= ATT_CAN_CMD_SET_REMAP) {
            att_can_cal_ack_t ack;
            FZ_CHECK(a->id == ATT_CAN_ID_CAL_ACK && att_can_decode_cal_ack(a, &ack) && ack.cmd == cmd.cmd &&
                         ack.counter == cmd.counter,
                     "calibration answer does not name the command");
            FZ_CHECK(ack.result <= ATT_CAN_ACK_REFUSED && ack.session == (n->shadow_open ? 1u : 0u),
                     "calibration answer fields");
            FZ_CHECK((ack.result == ATT_CAN_ACK_REFUSED) == (ack.reason != 0u), "refusal without a reason");
            if (ack.result != ATT_CAN_ACK_OK || cmd.cmd == ATT_CAN_CMD_CAL_BEGIN || cmd.cmd == ATT_CAN_CMD_CAL_SET ||
                cmd.cmd == ATT_CAN_CMD_CAL_ABORT) {
                FZ_CHECK(same_out(&o0, &o1), "calibration command %u (result %u) changed the filter's output",
                         cmd.cmd, ack.result);
            }
            FZ_CHECK(att_calib_settings_check(&n->cal) == ATT_CALIB_OK, "the applied calibration is invalid");
            return;
        }
        FZ_CHECK(a->id == ATT_CAN_ID_STATUS && (a->data[7] & 0x8Fu) == (0x80u | (cmd.cmd & 15u)) &&
                     att_can_counter(a) == cmd.counter,
                 "answer does not name the command");
        result = (uint8_t)((a->data[7] >> 4) & 7u);
        if (cmd.cmd < 1u || cmd.cmd > 3u) {
            FZ_CHECK(result == ATT_CAN_ACK_UNKNOWN_CMD, "unknown command %u answered %u", cmd.cmd, result);
        }
        if (cmd.cmd == ATT_CAN_CMD_SELECT && result == ATT_CAN_ACK_OK) {
            FZ_CHECK((uint32_t)n->kind == cmd.arg && o1.steps == 0u, "select %u gave kind %d", cmd.arg, (int)n->kind);
        }
        if (cmd.cmd == ATT_CAN_CMD_SELECT && result != ATT_CAN_ACK_OK) {
            FZ_CHECK(n->kind == kind0 && same_out(&o0, &o1), "a refused select changed the filter");
        }
        if (cmd.cmd == ATT_CAN_CMD_SET_GAIN) {
            /* a gain taken changes no estimate (the complementary filters' covariance model follows it at
               once); a gain refused changes nothing at all */
            FZ_CHECK(result == ATT_CAN_ACK_OK ? same_estimate(&o0, &o1) : same_out(&o0, &o1),
                     "set gain (%u, %a) answered %u changed the filter's output", cmd.arg, (double)cmd.value,
                     result);
        }
        if (cmd.cmd == ATT_CAN_CMD_RESET) {
            FZ_CHECK(result == ATT_CAN_ACK_OK && o1.steps == 0u, "reset");
        }
        return;
    }
    if (n->stats.samples != s0.samples) { /* this frame completed a sample: N6, its periods */
        uint32_t want = have_last0 ? ((uint32_t)att_can_counter(f) - (uint32_t)last0) & 15u : 1u;
        if (want == 0u) want = 1u;
        FZ_CHECK(n->stats.samples == s0.samples + 1u && n->stats.steps == s0.steps + want &&
                     o1.steps == o0.steps + want,
                 "a sample with counter %u after %u stepped %u periods (filter %u), want %u", (unsigned)att_can_counter(f),
                 (unsigned)last0, n->stats.steps - s0.steps, o1.steps - o0.steps, want);
    }
}

static void sample_frames(fz_reader_t *r, att_can_frame_t out[3], uint8_t counter)
{
    att_sample_t s;
    float *v = &s.gyr.x;
    int i;
    for (i = 0; i < 9; ++i) v[i] = ((fz_u8(r) & 3u) == 0u) ? fz_float(r) : (float)(int8_t)fz_u8(r) / 8.0f;
    s.acc.z += 9.80665f;
    att_can_encode_imu(&s, counter, out);
}

static void fd_frame(fz_reader_t *r, att_can_frame_t *out, uint8_t counter)
{
    att_sample_t s;
    float *v = &s.gyr.x;
    int i;
    for (i = 0; i < 9; ++i) v[i] = ((fz_u8(r) & 3u) == 0u) ? fz_float(r) : (float)(int8_t)fz_u8(r) / 8.0f;
    s.acc.z += 9.80665f;
    att_can_encode_imu_fd(&s, counter, out);
}

static const uint8_t perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
static const float rates[4] = {285.714f, 100.0f, 1000.0f, 50.0f};
static const uint32_t out_div[4] = {1u, 2u, 3u, 7u};
static const uint32_t diag_div[4] = {16u, 0u, 1u, 3u};

/** Run the whole input on one node; returns false if the settings were refused. */
static bool run(att_node_t *n, tracker_t *t, const uint8_t *data, size_t size, uint8_t fill)
{
    fz_reader_t r;
    att_node_settings_t s;
    att_filter_kind_t kind;
    uint8_t b1;
    bool drain_mode = true;
    size_t op;
    fz_init(&r, data, size);
    memset(t, 0, sizeof *t);
    kind = (att_filter_kind_t)(1 + fz_u8(&r) % 7u);
    b1 = fz_u8(&r);
    if (att_node_settings_default(kind, rates[(b1 >> 6) & 3u], &s) != ATT_OK) {
        FZ_FAIL("node defaults refused for kind %d", (int)kind);
    }
    s.fd = (b1 & 1u) != 0u;
    s.data_bitrate = s.fd ? 2000000u : 0u;
    s.output_divider = out_div[(b1 >> 1) & 3u];
    s.diag_divider = diag_div[(b1 >> 3) & 3u];
    s.accel_out = (b1 & 0x20u) != 0u;
    memset(n, fill, sizeof *n);
    if (att_node_init(n, &s) != ATT_OK) {
        return false;
    }
    for (op = 0; op < FZ_MAX_OPS && fz_left(&r) > 0u; ++op) {
        uint8_t code = fz_u8(&r);
        uint8_t counter = (uint8_t)(fz_u8(&r) & 15u);
        switch (code % 8u) {
        case 0: { /* a classic sample, frames in any order, each maybe corrupted */
            att_can_frame_t fr[3];
            const uint8_t *p = perms[fz_u8(&r) % 6u];
            int i;
            sample_frames(&r, fr, counter);
            for (i = 0; i < 3; ++i) {
                (void)corrupt(&fr[p[i]], &r);
                one_frame(n, t, &fr[p[i]], drain_mode);
            }
            break;
        }
        case 1: { /* an FD sample, maybe corrupted */
            att_can_frame_t fr;
            fd_frame(&r, &fr, counter);
            (void)corrupt(&fr, &r);
            one_frame(n, t, &fr, drain_mode);
            break;
        }
        case 2: { /* a command */
            att_can_cmd_t c;
            att_can_frame_t fr;
            uint8_t sel = fz_u8(&r);
            c.counter = counter;
            c.cmd = (sel & 0x80u) ? fz_u8(&r) : (uint8_t)(1u + sel % 9u);
            c.arg = (sel & 0x40u) ? fz_u8(&r) : (uint8_t)(fz_u8(&r) % 8u);
            c.value = ((sel & 0x30u) == 0u) ? fz_float(&r) : (float)fz_u8(&r) / 16.0f;
            att_can_encode_cmd(&c, &fr);
            (void)corrupt(&fr, &r);
            one_frame(n, t, &fr, drain_mode);
            break;
        }
        case 3: { /* a raw frame */
            att_can_frame_t fr;
            size_t i;
            uint16_t id = fz_u16(&r);
            memset(&fr, 0, sizeof fr);
            fr.id = (id & 0x8000u) ? (uint32_t)(id & 0x7FFu) : (uint32_t)(0x100u + (id & 0x3FFu) % 0x211u);
            fr.len = (uint8_t)(fz_u8(&r) % 65u);
            fr.fd = (uint8_t)(fz_u8(&r) & 1u);
            for (i = 0; i < fr.len; ++i) fr.data[i] = fz_u8(&r);
            if (fz_u8(&r) & 1u) att_can_seal(&fr);
            one_frame(n, t, &fr, drain_mode);
            break;
        }
        case 4: /* stop draining: the tx ring fills, then the rx ring, then rx_overflows */
            drain_mode = false;
            break;
        case 5:
            drain_mode = true;
            drain(n, t);
            break;
        case 6: { /* a clean classic sample: the next counter, nothing pending: exactly one step */
            att_can_frame_t fr[3];
            uint32_t steps0 = n->stats.steps;
            bool clean = drain_mode && n->part_mask == 0u && n->rx_head == n->rx_tail;
            uint8_t c = (uint8_t)((n->last_counter + 1u) & 15u);
            int i;
            drain(n, t);
            sample_frames(&r, fr, c);
            for (i = 0; i < 3; ++i) one_frame(n, t, &fr[i], true);
            if (clean) FZ_CHECK(n->stats.steps == steps0 + 1u, "a clean sample ran %u steps", n->stats.steps - steps0);
            break;
        }
        default: { /* a clean FD sample */
            att_can_frame_t fr;
            uint32_t steps0 = n->stats.steps;
            bool clean = drain_mode && n->rx_head == n->rx_tail;
            uint8_t c = (uint8_t)((n->last_counter + 1u) & 15u);
            drain(n, t);
            clean = clean && n->part_mask == 0u;
            fd_frame(&r, &fr, c);
            one_frame(n, t, &fr, true);
            if (clean) FZ_CHECK(n->stats.steps == steps0 + 1u, "a clean FD sample ran %u steps", n->stats.steps - steps0);
            break;
        }
        }
    }
    (void)att_node_poll(n);
    drain(n, t);
    check_stats(n, t);
    return true;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    bool a;
    bool b;
    if (size > 8192u) return -1;
    crc_table_init();
    a = run(&g_a, &g_ta, data, size, 0x00u);
    b = run(&g_b, &g_tb, data, size, 0xFFu);
    FZ_CHECK(a == b, "init result depends on the node's previous contents");
    if (a) {
        FZ_CHECK(g_ta.n_log == g_tb.n_log, "two runs sent %zu and %zu frames", g_ta.n_log, g_tb.n_log);
        FZ_CHECK(memcmp(g_ta.log, g_tb.log, g_ta.n_log * sizeof g_ta.log[0]) == 0,
                 "two runs from differently filled memory sent different bytes");
        FZ_CHECK(memcmp(&g_a.stats, &g_b.stats, sizeof g_a.stats) == 0, "two runs counted differently");
    }
    return 0;
}
