/**
 * @file att_node.c
 * @brief The attica CAN node (see att_node.h): rx ring -> checks -> sample assembly -> filter step ->
 * output set -> tx ring. No heap, no time source, no I/O.
 */
#include "../math/att_fp.h"

#include "../core/att_core.h"
#include "../filters/att_kinds.h"

#include <string.h>

#include "attica/att_math.h"
#include "attica/att_node.h"

#define ATT_NODE_RX_MASK ((uint32_t)ATT_NODE_RX_RING - 1u)
#define ATT_NODE_TX_MASK ((uint32_t)ATT_NODE_TX_RING - 1u)
#define ATT_NODE_PART_ALL 7u
#define ATT_NODE_MAX_RATE 100000.0f
#define ATT_NODE_MIN_BITRATE 1000u
#define ATT_NODE_MAX_BITRATE 1000000u
#define ATT_NODE_MAX_DATA_BITRATE 16000000u
#define ATT_NODE_MAX_DIVIDER 65535u
#define ATT_NODE_SET_FRAMES 6u

/* The kinds' gain hooks take the CAN contract's SET_GAIN parameters as they are. */
typedef char att_node_check_gains[((int)ATT_GAIN_TAU_ACC == (int)ATT_CAN_GAIN_TAU_ACC &&
                                   (int)ATT_GAIN_TAU_MAG == (int)ATT_CAN_GAIN_TAU_MAG &&
                                   (int)ATT_GAIN_KF_R == (int)ATT_CAN_GAIN_KF_R &&
                                   (int)ATT_GAIN_EKF_R == (int)ATT_CAN_GAIN_EKF_R &&
                                   (int)ATT_GAIN_DECLINATION == (int)ATT_CAN_GAIN_DECLINATION)
                                      ? 1
                                      : -1];

/* att_config.h checks the ring sizes; this is the same bound written with att_node.h's name. */
#if ATT_NODE_TX_RING < ATT_NODE_SET_MAX
#error "ATT_NODE_TX_RING must hold at least one output set (ATT_NODE_SET_MAX frames)"
#endif

/* --- bus load -------------------------------------------------------------------------------- */

uint32_t att_node_classic_bits(uint32_t len)
{
    uint32_t n = (len > 8u) ? 8u : len;
    /* SOF..CRC = 34 + 8n bits may be stuffed (worst case one bit per 4 after the first); + CRC delimiter,
       ACK slot and delimiter, EOF (10 bits) and the 3-bit intermission: 8n + 47 + floor((33 + 8n) / 4). */
    return 8u * n + 47u + (34u + 8u * n - 1u) / 4u;
}

float att_node_fd_frame_time(uint32_t len, uint32_t bitrate, uint32_t data_bitrate)
{
    uint32_t n = (len > 64u) ? 64u : len;
    uint32_t crc = (n > 16u) ? 21u : 17u;
    uint32_t stuffed = 22u + 8u * n;         /* SOF..BRS (17), ESI, DLC (4), data: dynamic stuffing */
    uint32_t stuff = (stuffed - 1u) / 4u;    /* worst-case dynamic stuff bits */
    uint32_t nominal = 17u + 4u + 1u + 2u + 7u + 3u; /* SOF..BRS + its 4 stuff bits, CRC delim, ACK, EOF, IFS */
    uint32_t data = 5u + 8u * n + (stuff - 4u) + 4u + crc + (1u + (3u + crc) / 4u);
    if (bitrate == 0u || data_bitrate == 0u) {
        return -1.0f;
    }
    return (float)nominal / (float)bitrate + (float)data / (float)data_bitrate;
}

/*
 * The node's own settings, one line per condition, in the form of the kinds' tables (att_core.h):
 * att_node_init accepts settings only when every line holds (att_node_rates_ok, ATT_CHECK_AND), and
 * att_node_settings_check reports the first line that fails (ATT_CHECK_WHY), so the two cannot
 * disagree. fd is checked as a bool first: reading a
 * bool that holds another byte value would be undefined.
 */
#define ATT_NODE_CHECKS(C)                                                                                    \
    C("sample_rate", att_isfinitef(s->sample_rate) && s->sample_rate > 0.0f && s->sample_rate <= ATT_NODE_MAX_RATE, \
      0.0f, ATT_NODE_MAX_RATE, "(0, 100000]", "Hz")                                                           \
    C("bitrate", s->bitrate >= ATT_NODE_MIN_BITRATE && s->bitrate <= ATT_NODE_MAX_BITRATE,                    \
      (float)ATT_NODE_MIN_BITRATE, (float)ATT_NODE_MAX_BITRATE, "[1000, 1000000]", "bit/s")                   \
    C("data_bitrate",                                                                                         \
      s->data_bitrate == 0u || (s->data_bitrate >= s->bitrate && s->data_bitrate <= ATT_NODE_MAX_DATA_BITRATE), \
      (float)s->bitrate, (float)ATT_NODE_MAX_DATA_BITRATE, "0 (classic only) or [bitrate, 16000000]", "bit/s") \
    C("fd", att_i_bool_ok(&s->fd), 0.0f, 1.0f, "0 or 1 (bool)", "")                                          \
    C("fd", !s->fd || (s->data_bitrate != 0u && ATT_NODE_WITH_FD != 0), 0.0f, (float)ATT_NODE_WITH_FD,        \
      ATT_NODE_WITH_FD ? "true needs data_bitrate > 0" : "false (this build has no CAN FD: ATT_NODE_WITH_FD 0)", \
      "")                                                                                                     \
    C("id_offset", s->id_offset >= ATT_NODE_ID_OFFSET_MIN && s->id_offset <= ATT_NODE_ID_OFFSET_MAX,          \
      (float)ATT_NODE_ID_OFFSET_MIN, (float)ATT_NODE_ID_OFFSET_MAX, "[-256, 1279] (every ID stays 11-bit)", "") \
    C("output_divider", s->output_divider >= 1u && s->output_divider <= ATT_NODE_MAX_DIVIDER, 1.0f,           \
      (float)ATT_NODE_MAX_DIVIDER, "[1, 65535]", "")                                                          \
    C("diag_divider", true, 0.0f, 4294967295.0f, "any (0: never)", "")                                        \
    C("accel_out", att_i_bool_ok(&s->accel_out), 0.0f, 1.0f, "0 or 1 (bool)", "")                            \
    C("accel_out", ATT_WITH_CALIB || !s->accel_out, 0.0f, (float)ATT_WITH_CALIB,                              \
      ATT_WITH_CALIB ? "0 or 1 (bool)" : "false (this build has no stages: ATT_WITH_CALIB 0)", "")

static bool att_node_rates_ok(const att_node_settings_t *s)
{
    return true ATT_NODE_CHECKS(ATT_CHECK_AND);
}

/* The bus load of the periodic outputs with diag_frames classic frames every diag_divider-th set. */
static float att_node_outputs_load(const att_node_settings_t *s, uint32_t diag_frames)
{
    float sets_per_s;
    float t_set;
    float t_classic;
    uint32_t classic_bits = att_node_classic_bits(8u);
    if (s == NULL || !att_node_rates_ok(s)) {
        return -1.0f;
    }
    sets_per_s = s->sample_rate / (float)s->output_divider;
    t_classic = (float)classic_bits / (float)s->bitrate;
    if (s->fd) {
        t_set = att_node_fd_frame_time(64u, s->bitrate, s->data_bitrate);
        if (s->accel_out) {
            t_set += att_node_fd_frame_time(64u, s->bitrate, s->data_bitrate);
        }
    } else {
        t_set = (float)ATT_NODE_SET_FRAMES * t_classic;
        if (s->accel_out) {
            t_set += 2.0f * t_classic;
        }
    }
    if (s->diag_divider != 0u) {
        t_set += (float)diag_frames * t_classic / (float)s->diag_divider;
    }
    return sets_per_s * t_set;
}

/* 1 when the init filter estimates a hard-iron offset (ATT_MAG_OFFSET after each ATT_DIAG), else 0. A
   filter selected later starts from its defaults, where the estimate is off. */
static uint32_t att_node_mag_offset_frames(const att_node_settings_t *s)
{
    uint32_t n = 0u;
    (void)s;
#if ATT_WITH_MARS
    if (s->kind == ATT_FILTER_MARS && s->filter.mars.hard_iron_tau > 0.0f) {
        n = 1u;
    }
#endif
#if ATT_WITH_MEKF
    if (s->kind == ATT_FILTER_MEKF && s->filter.mekf.use_mag && s->filter.mekf.hard_iron_tau > 0.0f) {
        n = 1u;
    }
#endif
    return n;
}

float att_node_bus_load(const att_node_settings_t *s)
{
    return (s == NULL) ? -1.0f : att_node_outputs_load(s, 1u + att_node_mag_offset_frames(s));
}

/** The filter's dt agrees with sample_rate (relative 1e-3), or the kind has no dt. */
static bool att_node_dt_matches(const att_node_settings_t *s)
{
    float dt = att_filter_settings_period(s->kind, &s->filter);
    float r;
    if (dt == 0.0f) {
        return true;
    }
    r = dt * s->sample_rate;
    return r > 0.999f && r < 1.001f;
}

/* --- init ------------------------------------------------------------------------------------ */

att_status_t att_node_settings_default(att_filter_kind_t kind, float sample_rate, att_node_settings_t *s)
{
    att_status_t st;
    if (s == NULL) {
        return ATT_ERR_NULL;
    }
    if (!att_isfinitef(sample_rate) || !(sample_rate > 0.0f)) {
        return ATT_ERR_SETTINGS;
    }
    memset(s, 0, sizeof *s);
    st = att_filter_settings_default(kind, 1.0f / sample_rate, &s->filter);
    if (st != ATT_OK) {
        return st;
    }
    s->kind = kind;
    s->sample_rate = sample_rate;
    s->bitrate = 500000u;
    s->data_bitrate = 0u;
    s->fd = false;
    s->output_divider = 1u;
    s->diag_divider = 16u;
#if ATT_WITH_CALIB
    att_calib_settings_default(&s->calib);
#endif
    s->accel_out = false;
    s->id_offset = 0;
    return ATT_OK;
}

att_status_t att_node_init(att_node_t *n, const att_node_settings_t *s)
{
    att_status_t st;
    float load;
    if (n == NULL || s == NULL) {
        return ATT_ERR_NULL;
    }
    if (!att_node_rates_ok(s)) {
        return ATT_ERR_SETTINGS;
    }
    /* everything is validated before n is touched; the filter is then set up in place (no filter-sized
       copy on the stack: the kinds' state is most of att_filter_t) */
    st = att_filter_settings_validate(s->kind, &s->filter);
    if (st != ATT_OK) {
        return st;
    }
#if ATT_WITH_CALIB
    if (att_calib_settings_validate(&s->calib) != ATT_OK) {
        return ATT_ERR_SETTINGS;
    }
#endif
    if (!att_node_dt_matches(s)) {
        return ATT_ERR_SETTINGS; /* the filter would integrate with another period than the samples have */
    }
    load = att_node_bus_load(s);
    if (!(load >= 0.0f) || load > 1.0f) {
        return ATT_ERR_SETTINGS; /* the outputs would need more than the whole bus */
    }
    memset(n, 0, sizeof *n);
    n->s = *s;
    n->kind = s->kind;
    n->fs = s->filter;
    (void)att_filter_init(&n->f, s->kind, &s->filter); /* validated above */
#if ATT_WITH_CALIB
    n->cal = s->calib;
    n->cal.accel_outputs = n->cal.accel_outputs || s->accel_out;
    (void)att_filter_calibrate(&n->f, &n->cal); /* validated above: only accel_outputs may differ */
    n->cal = s->calib;
#endif
    att_filter_output(&n->f, &n->out);
    return ATT_OK;
}

att_status_t att_node_settings_rule(const att_node_settings_t *s, uint32_t index, att_settings_error_t *out)
{
    uint32_t line = 0u;
    (void)att_i_settings_end(out);
    if (s == NULL || out == NULL) {
        return ATT_ERR_NULL;
    }
    ATT_NODE_CHECKS(ATT_CHECK_RULE)
    return att_i_settings_end(out);
}

att_status_t att_node_settings_check(const att_node_settings_t *s, att_settings_error_t *why)
{
    att_status_t st;
    float load;
    (void)att_i_settings_refused(why, NULL, 0.0f, 0.0f, "", "");
    if (s == NULL) {
        return ATT_ERR_NULL;
    }
    ATT_NODE_CHECKS(ATT_CHECK_WHY)
    st = att_filter_settings_check(s->kind, &s->filter, why);
    if (st != ATT_OK) {
        return st;
    }
#if ATT_WITH_CALIB
    {
        att_settings_error_t r; /* the stages' first line that fails ("calib.gyro.sensitivity" ...) */
        uint32_t i = 0u;
        while (att_calib_settings_rule(&s->calib, i, &r) == ATT_OK && r.field != NULL) {
            i++;
        }
        if (r.field != NULL) {
            return att_i_settings_refused(why, r.field, r.min, r.max, r.rule, r.unit);
        }
    }
#endif
    if (!att_node_dt_matches(s)) {
        return att_i_settings_refused(why, "filter.dt", 0.999f / s->sample_rate, 1.001f / s->sample_rate,
                                "1 / sample_rate within 1e-3 (relative)", "s");
    }
    load = att_node_bus_load(s);
    if (!(load >= 0.0f) || load > 1.0f) {
        return att_i_settings_refused(why, "bus load", 0.0f, 1.0f,
                                "the periodic outputs need at most the whole bus (raise output_divider or "
                                "bitrate, or use fd)",
                                "");
    }
    return ATT_OK;
}

void att_node_set_persist(att_node_t *n, att_node_persist_fn fn, void *ctx)
{
    if (n == NULL) {
        return;
    }
    n->persist = fn;
    n->persist_ctx = ctx;
}

att_status_t att_node_set_bus_diag(att_node_t *n, att_node_bus_diag_fn fn, void *ctx)
{
    if (n == NULL) {
        return ATT_ERR_NULL;
    }
    if (fn != NULL) {
        /* ATT_DIAG, ATT_DIAG_BUS (and ATT_MAG_OFFSET) */
        const float load = att_node_outputs_load(&n->s, 2u + att_node_mag_offset_frames(&n->s));
        if (!(load >= 0.0f) || load > 1.0f) {
            return ATT_ERR_SETTINGS;
        }
    }
    n->bus_diag = fn;
    n->bus_diag_ctx = (fn != NULL) ? ctx : NULL;
    return ATT_OK;
}

/* --- rings ----------------------------------------------------------------------------------- */

/* A ring entry from a frame: the first ATT_NODE_FRAME_LEN data bytes (a longer classic-only frame is
   refused by its length before any byte past them is read). */
static void att_node_store(att_node_frame_t *e, const att_can_frame_t *f, uint32_t id)
{
#if ATT_NODE_WITH_FD
    *e = *f;
#else
    e->len = f->len;
    e->fd = f->fd;
    memcpy(e->data, f->data, sizeof e->data);
#endif
    e->id = id;
}

/* A frame from a ring entry at CAN ID id, the bytes a ring entry does not hold zero. */
static void att_node_load(att_can_frame_t *f, const att_node_frame_t *e, uint32_t id)
{
#if ATT_NODE_WITH_FD
    *f = *e;
#else
    f->len = e->len;
    f->fd = e->fd;
    memcpy(f->data, e->data, sizeof e->data);
    memset(&f->data[ATT_NODE_FRAME_LEN], 0, sizeof f->data - (size_t)ATT_NODE_FRAME_LEN);
#endif
    f->id = id;
}

bool att_node_rx(att_node_t *n, const att_can_frame_t *f)
{
    if (n == NULL || f == NULL) {
        return false;
    }
    if (n->rx_head - n->rx_tail >= (uint32_t)ATT_NODE_RX_RING) {
        n->stats.rx_overflows++;
        return false;
    }
    att_node_store(&n->rx[n->rx_head & ATT_NODE_RX_MASK], f, f->id);
    n->rx_head++;
    n->stats.rx_frames++;
    return true;
}

bool att_node_tx(att_node_t *n, att_can_frame_t *f)
{
    const att_node_frame_t *e;
    if (n == NULL || f == NULL || n->tx_head == n->tx_tail) {
        return false;
    }
    e = &n->tx[n->tx_tail & ATT_NODE_TX_MASK];
    att_node_load(f, e, e->id + (uint32_t)n->s.id_offset); /* the tx ring holds the DBC's IDs */
    n->tx_tail++;
    n->stats.tx_frames++;
    return true;
}

size_t att_node_rx_ids(const att_node_t *n, uint32_t ids[ATT_NODE_RX_IDS_MAX])
{
    static const uint32_t base[] = {
        (uint32_t)ATT_CAN_ID_IMU_GYRO, (uint32_t)ATT_CAN_ID_IMU_ACC, (uint32_t)ATT_CAN_ID_IMU_MAG,
#if ATT_NODE_WITH_FD
        (uint32_t)ATT_CAN_ID_IMU_FD,
#endif
        (uint32_t)ATT_CAN_ID_CMD};
    size_t i;
    if (n == NULL || ids == NULL) {
        return 0u;
    }
    for (i = 0u; i < sizeof base / sizeof base[0]; i++) {
        ids[i] = base[i] + (uint32_t)n->s.id_offset;
    }
    return i;
}

size_t att_node_tx_pending(const att_node_t *n)
{
    return (n == NULL) ? 0u : (size_t)(n->tx_head - n->tx_tail);
}

static uint32_t att_node_tx_free(const att_node_t *n)
{
    return (uint32_t)ATT_NODE_TX_RING - (n->tx_head - n->tx_tail);
}

static void att_node_queue(att_node_t *n, const att_can_frame_t *f, uint32_t count)
{
    uint32_t i;
    if (att_node_tx_free(n) < count) {
        n->stats.tx_overflows += count; /* not reached: poll keeps room for ATT_NODE_SET_MAX frames */
        return;
    }
    for (i = 0u; i < count; ++i) {
        att_node_store(&n->tx[n->tx_head & ATT_NODE_TX_MASK], &f[i], f[i].id);
        n->tx_head++;
    }
}

/* --- counters -------------------------------------------------------------------------------- */

void att_node_diag(const att_node_t *n, att_can_diag_t *d)
{
    if (n == NULL || d == NULL) {
        return;
    }
    d->crc_errors = n->stats.crc_errors;
    d->counter_gaps = n->stats.counter_gaps;
    d->dlc_errors = n->stats.dlc_errors;
    d->unknown_ids = n->stats.unknown_ids;
    d->duplicates = n->stats.duplicates;
    d->stale_partials = n->stats.stale_partials;
}

static uint32_t att_node_sat_add(uint32_t a, uint32_t b)
{
    return (a > 255u || b > 255u - a) ? 255u : a + b;
}

uint8_t att_node_error_count(const att_node_t *n)
{
    uint32_t e = 0u;
    if (n == NULL) {
        return 0u;
    }
    e = att_node_sat_add(e, n->stats.crc_errors);
    e = att_node_sat_add(e, n->stats.counter_gaps);
    e = att_node_sat_add(e, n->stats.dlc_errors);
    e = att_node_sat_add(e, n->stats.unknown_ids);
    e = att_node_sat_add(e, n->stats.duplicates);
    e = att_node_sat_add(e, n->stats.stale_partials);
    e = att_node_sat_add(e, n->stats.rx_overflows);
    return (uint8_t)e;
}

/* --- outputs --------------------------------------------------------------------------------- */

/* ATT_MAG_OFFSET after ATT_DIAG while the filter estimates a hard-iron offset (mars, mekf). */
static void att_node_emit_mag_offset(att_node_t *n, uint8_t counter)
{
#if ATT_NODE_WITH_MAG_OFFSET
    att_mag_offset_t h;
    att_can_frame_t fr;
    if (att_filter_mag_offset(&n->f, &h) == ATT_OK && h.on) {
        att_can_encode_mag_offset(&h, counter, &fr);
        att_node_queue(n, &fr, 1u);
    }
#else
    (void)n;
    (void)counter;
#endif
}

static void att_node_emit(att_node_t *n)
{
    att_can_frame_t set[ATT_NODE_SET_FRAMES];
    uint8_t counter = (uint8_t)(n->stats.sets & 0x0Fu);
#if ATT_NODE_WITH_FD
    if (n->s.fd) {
        att_can_encode_output_fd(&n->out, n->kind, counter, &set[0]);
        att_node_queue(n, set, 1u);
    } else
#endif
    {
        (void)att_can_encode_output_set(&n->out, n->kind, counter, att_node_error_count(n), set);
        att_node_queue(n, set, ATT_NODE_SET_FRAMES);
    }
#if ATT_WITH_CALIB
    if (n->s.accel_out) {
        att_accel_t a;
        att_filter_accel(&n->f, &a);
#if ATT_NODE_WITH_FD
        if (n->s.fd) {
            att_can_encode_accel_fd(&a, counter, &set[0]);
            att_node_queue(n, set, 1u);
        } else
#endif
        {
            att_can_encode_accel(&a, counter, set);
            att_node_queue(n, set, 2u);
        }
    }
#endif
    n->stats.sets++;
    if (n->s.diag_divider != 0u && (n->stats.sets % n->s.diag_divider) == 0u) {
        att_can_diag_t d;
        att_node_diag(n, &d);
        att_can_encode_diag(&d, counter, &set[0]);
        att_node_queue(n, set, 1u);
        if (n->bus_diag != NULL) {
            att_can_bus_diag_t b;
            memset(&b, 0, sizeof b);
            n->bus_diag(n->bus_diag_ctx, &b);
            att_can_encode_diag_bus(&b, counter, &set[0]);
            att_node_queue(n, set, 1u);
        }
        att_node_emit_mag_offset(n, counter);
    }
}

/*
 * One sample held over `periods` sample periods (att_filter_step_n: the filter steps that many times;
 * 1 unless samples were lost). The output record is att_filter_output's (the frames carry Euler angles
 * and covariance too) with the flags ORed over the periods, as att_filter_step_n reports them. A set is
 * queued when the step count reaches or passes a multiple of output_divider (div_count: the steps past
 * the last multiple; at most one set per sample, the sets stay on the step grid). The set's flags are
 * ORed over every step since the previous set (div_flags), so that a clipped gyro or a rejected field
 * between two sets still reaches the bus, but for NOT_READY and BAD_ARG, which say whether the set's q is
 * an estimate: those are its own sample's. Returns the filter steps run.
 */
static size_t att_node_step(att_node_t *n, const att_sample_t *in, uint32_t periods)
{
    const uint32_t flags = att_filter_step_n(&n->f, in, periods, &n->out);
    const uint32_t invalid = (uint32_t)ATT_FLAGS_OUTPUT_INVALID;
    att_filter_output(&n->f, &n->out);
    n->out.flags = flags;
    n->div_flags |= flags;
    n->stats.samples++;
    n->stats.steps += periods;
    n->div_count += periods;
    if (n->div_count >= n->s.output_divider) {
        n->div_count %= n->s.output_divider;
        n->out.flags = (n->div_flags & ~invalid) | (flags & invalid);
        n->div_flags = 0u;
        att_node_emit(n);
        n->out.flags = flags; /* a command's answer: the last sample's */
    }
    return (size_t)periods;
}

/*
 * The sample periods since the last sample stepped from frames, from the E2E counter c of the sample
 * now complete: (c - last) mod 16, i.e. 1 for the next sample and k + 1 after k lost samples (whole
 * samples missing or partial samples discarded), at most 15. 1 for the first sample, and 1 when the
 * distance is 0 (a re-sent sample accepted after a stale partial: no time to integrate; 16 periods
 * cannot be told from 0). c becomes the last counter.
 */
static uint32_t att_node_periods(att_node_t *n, uint8_t c)
{
    uint32_t periods = 1u;
    if (n->have_last) {
        periods = ((uint32_t)c - (uint32_t)n->last_counter) & 0x0Fu;
        if (periods == 0u) {
            periods = 1u;
        }
    }
    n->have_last = true;
    n->last_counter = c;
    return periods;
}

/* --- sample assembly ------------------------------------------------------------------------- */

/**
 * A frame with counter c starts a new sample. False: it belongs to the sample just completed. The
 * sample started before it is the partial one when there is one (discarded here), else the last stepped.
 */
static bool att_node_begin(att_node_t *n, uint8_t c)
{
    const bool replaced = n->part_mask != 0u;
    const bool have_prev = replaced || n->have_last;
    const uint8_t prev = replaced ? n->part_counter : n->last_counter;
    if (replaced) {
        n->stats.stale_partials++;
        n->part_mask = 0u;
    } else if (n->have_last && c == n->last_counter) {
        n->stats.duplicates++;
        return false;
    }
    if (have_prev && c != (uint8_t)((prev + 1u) & 0x0Fu) && !(replaced && c == prev)) {
        n->stats.counter_gaps++;
    }
    return true;
}

static size_t att_node_part(att_node_t *n, const att_can_frame_t *f)
{
    uint8_t c = att_can_counter(f);
    uint8_t bit;
    att_vec3_t v;
    if (!att_can_decode_imu_part(f, &v)) {
        return 0u;
    }
    bit = (uint8_t)((f->id == ATT_CAN_ID_IMU_GYRO) ? 1u : ((f->id == ATT_CAN_ID_IMU_ACC) ? 2u : 4u));
    if (n->part_mask != 0u && c == n->part_counter) {
        if ((n->part_mask & bit) != 0u) {
            n->stats.duplicates++;
            return 0u;
        }
    } else {
        if (!att_node_begin(n, c)) {
            return 0u;
        }
        n->part_counter = c;
    }
    if (bit == 1u) {
        n->part.gyr = v;
    } else if (bit == 2u) {
        n->part.acc = v;
    } else {
        n->part.mag = v;
    }
    n->part_mask = (uint8_t)(n->part_mask | bit);
    if (n->part_mask != ATT_NODE_PART_ALL) {
        return 0u;
    }
    n->part_mask = 0u;
    return att_node_step(n, &n->part, att_node_periods(n, c));
}

#if ATT_NODE_WITH_FD
static size_t att_node_fd_sample(att_node_t *n, const att_can_frame_t *f)
{
    att_sample_t in;
    const uint8_t c = att_can_counter(f);
    if (!att_can_decode_imu_fd(f, &in) || !att_node_begin(n, c)) {
        return 0u;
    }
    return att_node_step(n, &in, att_node_periods(n, c));
}
#endif

/* --- commands -------------------------------------------------------------------------------- */

static uint8_t att_node_select(att_node_t *n, uint8_t arg)
{
    att_filter_kind_t kind = (att_filter_kind_t)arg;
    att_filter_settings_t fs;
    if (kind == n->s.kind) {
        fs = n->s.filter;
    } else {
        const att_status_t st = att_filter_settings_default(kind, 1.0f / n->s.sample_rate, &fs);
        if (st == ATT_ERR_DISABLED) {
            return (uint8_t)ATT_CAN_ACK_REFUSED; /* a kind this build does not have (att_config.h) */
        }
        if (st != ATT_OK) {
            return (uint8_t)ATT_CAN_ACK_BAD_ARG;
        }
    }
    if (att_filter_settings_validate(kind, &fs) != ATT_OK) {
        return (uint8_t)ATT_CAN_ACK_REFUSED;
    }
#if ATT_WITH_CALIB
    {
        const att_calib_t cal = n->f.cal; /* the calibration stays (it is not part of the filter's state) */
        (void)att_filter_init(&n->f, kind, &fs); /* validated above; set up in place (no copy on the stack) */
        n->f.cal = cal;
        n->f.cal.have_acc = false;
    }
#else
    (void)att_filter_init(&n->f, kind, &fs); /* validated above */
#endif
    n->kind = kind;
    n->fs = fs;
    n->div_count = 0u; /* the sets restart on the new filter's step grid */
    n->div_flags = 0u;
    att_filter_output(&n->f, &n->out);
    return (uint8_t)ATT_CAN_ACK_OK;
}

/*
 * A new gain for the running filter, keeping its state (att_filter_retune). A time constant set here
 * replaces the kind's per-sample gain (set to 0 for tau > 0, to 1, the full correction, for tau = 0),
 * since a filter accepts only one of the two. A declination, like a retune's, applies from the next
 * heading alignment: the heading is kept until a RESET (docs/can.md).
 */
static uint8_t att_node_set_gain(att_node_t *n, uint8_t param, float value)
{
    att_filter_settings_t fs = n->fs;
    if (!att_filter_settings_gain(n->kind, &fs, (att_gain_t)param, value)) {
        return (uint8_t)ATT_CAN_ACK_BAD_ARG; /* no such gain for the running kind */
    }
    if (att_filter_retune(&n->f, &fs) != ATT_OK) {
        return (uint8_t)ATT_CAN_ACK_REFUSED; /* out of range (NaN included): nothing changed */
    }
    n->fs = fs;
    return (uint8_t)ATT_CAN_ACK_OK;
}

#if ATT_WITH_CALIB
/* Apply calibration cs to the running filter (state kept); REFUSED with *reason when invalid. */
static uint8_t att_node_apply_cal(att_node_t *n, const att_calib_settings_t *cs, uint8_t *reason,
                                  uint8_t *persisted)
{
    att_calib_settings_t t = *cs;
    const att_calib_error_t e = att_calib_settings_check(&t);
    if (e != ATT_CALIB_OK) {
        *reason = (uint8_t)e;
        return (uint8_t)ATT_CAN_ACK_REFUSED;
    }
    if (n->s.accel_out) {
        t.accel_outputs = true;
    }
    (void)att_filter_calibrate(&n->f, &t); /* valid: checked above; one struct assignment */
    n->cal = *cs;
    att_filter_output(&n->f, &n->out);
    if (n->persist != NULL) {
        *persisted = n->persist(n->persist_ctx, &n->cal) ? (uint8_t)ATT_CAN_PERSIST_OK : (uint8_t)ATT_CAN_PERSIST_FAILED;
    }
    return (uint8_t)ATT_CAN_ACK_OK;
}
#endif

static void att_node_cal_command(att_node_t *n, const att_can_cmd_t *c)
{
    att_can_cal_ack_t a;
    att_can_frame_t answer;
    att_calib_settings_t t;
    a.counter = c->counter;
    a.cmd = c->cmd;
    a.result = (uint8_t)ATT_CAN_ACK_OK;
    a.reason = 0u;
    a.index = c->arg;
    a.persisted = (uint8_t)ATT_CAN_PERSIST_NONE;
#if !ATT_WITH_CALIB
    (void)t;
    a.result = (uint8_t)ATT_CAN_ACK_REFUSED; /* no input/output stages in this build (ATT_WITH_CALIB 0) */
    a.session = 0u;
    att_can_encode_cal_ack(&a, &answer);
    att_node_queue(n, &answer, 1u);
    return;
#else
    switch (c->cmd) {
    case ATT_CAN_CMD_CAL_BEGIN:
        if (c->arg > 1u) {
            a.result = (uint8_t)ATT_CAN_ACK_BAD_ARG;
            break;
        }
        if (c->arg == 1u) {
            att_calib_settings_default(&n->shadow);
        } else {
            n->shadow = n->cal;
        }
        n->shadow_open = true;
        n->shadow_count = 0u;
        break;
    case ATT_CAN_CMD_CAL_SET:
        if (!n->shadow_open || !att_calib_field_set(&n->shadow, c->arg, c->value)) {
            a.result = (uint8_t)ATT_CAN_ACK_BAD_ARG;
            break;
        }
        if (n->shadow_count < 255u) {
            n->shadow_count++;
        }
        break;
    case ATT_CAN_CMD_CAL_COMMIT:
        a.index = n->shadow_count;
        if (!n->shadow_open) {
            a.result = (uint8_t)ATT_CAN_ACK_BAD_ARG;
            break;
        }
        a.result = att_node_apply_cal(n, &n->shadow, &a.reason, &a.persisted);
        if (a.result == (uint8_t)ATT_CAN_ACK_OK) {
            n->shadow_open = false;
        }
        break;
    case ATT_CAN_CMD_CAL_ABORT:
        n->shadow_open = false;
        break;
    case ATT_CAN_CMD_SET_CONVENTION:
    case ATT_CAN_CMD_SET_REMAP:
        t = n->cal;
        if (c->cmd == ATT_CAN_CMD_SET_CONVENTION) {
            t.convention = (att_convention_t)c->arg;
        } else {
            t.remap = c->arg;
            if (c->arg == 0u) {
                t.mounting = att_quat_identity();
            }
        }
        a.result = att_node_apply_cal(n, &t, &a.reason, &a.persisted);
        break;
    default:
        a.result = (uint8_t)ATT_CAN_ACK_UNKNOWN_CMD;
        break;
    }
    a.session = n->shadow_open ? 1u : 0u;
    att_can_encode_cal_ack(&a, &answer);
    att_node_queue(n, &answer, 1u);
#endif
}

static void att_node_command(att_node_t *n, const att_can_frame_t *f)
{
    att_can_cmd_t c;
    att_can_status_t st;
    att_can_frame_t answer;
    uint8_t result;
    if (!att_can_decode_cmd(f, &c)) {
        return;
    }
    n->stats.commands++;
    if (c.cmd >= (uint8_t)ATT_CAN_CMD_CAL_BEGIN && c.cmd <= (uint8_t)ATT_CAN_CMD_SET_REMAP) {
        att_node_cal_command(n, &c);
        return;
    }
    switch (c.cmd) {
    case ATT_CAN_CMD_SELECT:
        result = att_node_select(n, c.arg);
        break;
    case ATT_CAN_CMD_RESET:
        att_filter_reset(&n->f);
        n->div_count = 0u; /* steps restart at 0: so do the sets' steps grid */
        n->div_flags = 0u;
        att_filter_output(&n->f, &n->out);
        result = (uint8_t)ATT_CAN_ACK_OK;
        break;
    case ATT_CAN_CMD_SET_GAIN:
        result = att_node_set_gain(n, c.arg, c.value);
        break;
    default:
        result = (uint8_t)ATT_CAN_ACK_UNKNOWN_CMD;
        break;
    }
    st.counter = c.counter;
    st.kind = (uint8_t)((uint32_t)n->kind & 0x0Fu);
    st.flags = (uint16_t)(n->out.flags & 0xFFFFu);
    st.steps = (uint16_t)(n->out.steps & 0xFFFFu);
    st.error_count = att_node_error_count(n);
    st.ack = (uint8_t)((uint32_t)ATT_CAN_ACK_ANSWER | ((uint32_t)result << 4) | ((uint32_t)c.cmd & 0x0Fu));
    att_can_encode_status(&st, &answer);
    att_node_queue(n, &answer, 1u);
}

/* --- poll ------------------------------------------------------------------------------------ */

static size_t att_node_handle(att_node_t *n, const att_can_frame_t *f)
{
    switch (f->id) {
    case ATT_CAN_ID_IMU_GYRO:
    case ATT_CAN_ID_IMU_ACC:
    case ATT_CAN_ID_IMU_MAG:
#if ATT_NODE_WITH_FD
    case ATT_CAN_ID_IMU_FD:
#endif
    case ATT_CAN_ID_CMD:
        break;
    default:
        n->stats.unknown_ids++; /* not for the node (incl. attica output IDs; IMU_FD without CAN FD) */
        return 0u;
    }
    switch (att_can_check(f)) {
    case ATT_CAN_OK:
        break;
    case ATT_CAN_ERR_DLC:
        n->stats.dlc_errors++;
        return 0u;
    case ATT_CAN_ERR_CRC:
        n->stats.crc_errors++;
        return 0u;
    default:
        n->stats.unknown_ids++;
        return 0u;
    }
    if (f->id == ATT_CAN_ID_CMD) {
        att_node_command(n, f);
        return 0u;
    }
#if ATT_NODE_WITH_FD
    if (f->id == ATT_CAN_ID_IMU_FD) {
        return att_node_fd_sample(n, f);
    }
#endif
    return att_node_part(n, f);
}

size_t att_node_poll(att_node_t *n)
{
    size_t steps = 0u;
    if (n == NULL) {
        return 0u;
    }
    while (n->rx_tail != n->rx_head && att_node_tx_free(n) >= (uint32_t)ATT_NODE_SET_MAX) {
        const att_node_frame_t *e = &n->rx[n->rx_tail & ATT_NODE_RX_MASK];
        att_can_frame_t f;
        att_node_load(&f, e, e->id - (uint32_t)n->s.id_offset); /* the DBC's ID (another node's: unknown) */
        steps += att_node_handle(n, &f);
        n->rx_tail++;
    }
    return steps;
}

bool att_node_push_sample(att_node_t *n, const att_sample_t *in)
{
    if (n == NULL || in == NULL) {
        return false;
    }
    (void)att_node_poll(n); /* frames that arrived before this sample go first */
    if (n->rx_tail != n->rx_head || att_node_tx_free(n) < (uint32_t)ATT_NODE_SET_MAX) {
        n->stats.rx_overflows++; /* tx not drained: no room for the outputs of this sample */
        return false;
    }
    (void)att_node_step(n, in, 1u); /* no counter: one sample period */
    return true;
}
