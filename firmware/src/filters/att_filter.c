/**
 * @file att_filter.c
 * @brief The unified filter interface (see att_filter.h): calls through the kind table (att_kinds.h),
 * the input/output stages and the heading. Reads no field of any filter: each kind's hooks do.
 * Mirrored by reference/filter.py.
 */
#include <string.h>

#include "../math/att_fp.h"

#include "../calib/att_calib_i.h"
#include "../core/att_core.h"
#include "../math/att_inline.h"
#include "att_kinds.h"
#include "attica/att_filter.h"
#include "attica/att_math.h"

/* --- the kind table -------------------------------------------------------------------------- */

#define ATT_FILTER_OR_IS(NAME, name, num) || (kind == ATT_FILTER_##NAME)

bool att_filter_kind_enabled(att_filter_kind_t kind)
{
    return false ATT_KINDS(ATT_FILTER_OR_IS);
}

/* Why kind cannot be used: ATT_ERR_DISABLED for a kind compiled out, ATT_ERR_KIND for an unknown one. */
static att_status_t att_filter_absent(att_filter_kind_t kind)
{
    return (false ATT_KINDS_ALL(ATT_FILTER_OR_IS)) ? ATT_ERR_DISABLED : ATT_ERR_KIND;
}

#define ATT_FILTER_CASE_PERIOD(NAME, name, num)                                                            \
    case ATT_FILTER_##NAME:                                                                                  \
        return att_##name##_period(&settings->name);

float att_filter_settings_period(att_filter_kind_t kind, const att_filter_settings_t *settings)
{
    switch (kind) {
        ATT_KINDS(ATT_FILTER_CASE_PERIOD)
    default:
        return 0.0f;
    }
}

#define ATT_FILTER_CASE_GAIN(NAME, name, num)                                                              \
    case ATT_FILTER_##NAME:                                                                                  \
        return att_##name##_set_gain(&settings->name, gain, value);

bool att_filter_settings_gain(att_filter_kind_t kind, att_filter_settings_t *settings, att_gain_t gain,
                              float value)
{
    switch (kind) {
        ATT_KINDS(ATT_FILTER_CASE_GAIN)
    default:
        return false;
    }
}

/* --- settings, init, retune, reset ----------------------------------------------------------- */

/* The whole union is cleared first: the bytes past the kind's member are 0, not what the caller's memory
   held, so a settings image compared or saved byte by byte (the node's persisted configuration) is the
   same every time. */
#define ATT_FILTER_CASE_PRESET(NAME, name, num)                                                            \
    case ATT_FILTER_##NAME:                                                                                  \
        (void)memset(settings, 0, sizeof *settings);                                                         \
        att_##name##_preset(&settings->name, preset, dt);                                                    \
        return ATT_OK;

att_status_t att_filter_settings_preset(att_filter_kind_t kind, att_preset_t preset, float dt,
                                        att_filter_settings_t *settings)
{
    if (preset != ATT_PRESET_DEFAULT && preset != ATT_PRESET_SEED) {
        return ATT_ERR_KIND;
    }
    if (settings == NULL) {
        return ATT_ERR_NULL;
    }
    switch (kind) {
        ATT_KINDS(ATT_FILTER_CASE_PRESET)
    default:
        return att_filter_absent(kind);
    }
}

att_status_t att_filter_settings_default(att_filter_kind_t kind, float dt, att_filter_settings_t *settings)
{
    return att_filter_settings_preset(kind, ATT_PRESET_DEFAULT, dt, settings);
}

#define ATT_FILTER_CASE_VALIDATE(NAME, name, num)                                                          \
    case ATT_FILTER_##NAME:                                                                                  \
        return att_##name##_settings_validate(&settings->name);

att_status_t att_filter_settings_validate(att_filter_kind_t kind, const att_filter_settings_t *settings)
{
    if (settings == NULL) {
        return ATT_ERR_NULL;
    }
    switch (kind) {
        ATT_KINDS(ATT_FILTER_CASE_VALIDATE)
    default:
        return att_filter_absent(kind);
    }
}

#define ATT_FILTER_CASE_CHECK(NAME, name, num)                                                             \
    case ATT_FILTER_##NAME:                                                                                  \
        return att_##name##_settings_check(&settings->name, why);

/* Not called by att_filter_init (nor by anything on its path): the names and rules of the fields stay
 * out of the images that do not call it. */
att_status_t att_filter_settings_check(att_filter_kind_t kind, const att_filter_settings_t *settings,
                                       att_settings_error_t *why)
{
    if (why != NULL) {
        why->field = NULL;
        why->min = 0.0f;
        why->max = 0.0f;
        why->rule = NULL;
        why->unit = NULL;
    }
    if (settings == NULL) {
        return ATT_ERR_NULL;
    }
    switch (kind) {
        ATT_KINDS(ATT_FILTER_CASE_CHECK)
    default:
        return att_filter_absent(kind);
    }
}

#define ATT_FILTER_CASE_RULE(NAME, name, num)                                                              \
    case ATT_FILTER_##NAME:                                                                                  \
        return att_##name##_settings_rule(&settings->name, index, rule);

/* Not on att_filter_init's path either (the names and rules stay out of images that do not call it). */
att_status_t att_filter_settings_rule(att_filter_kind_t kind, const att_filter_settings_t *settings, uint32_t index,
                                      att_settings_error_t *rule)
{
    (void)att_i_settings_end(rule);
    if (settings == NULL || rule == NULL) {
        return ATT_ERR_NULL;
    }
    switch (kind) {
        ATT_KINDS(ATT_FILTER_CASE_RULE)
    default:
        return att_filter_absent(kind);
    }
}

#define ATT_FILTER_CASE_INIT(NAME, name, num)                                                              \
    case ATT_FILTER_##NAME:                                                                                  \
        st = att_##name##_init(&f->u.name, &settings->name);                                                 \
        break;

att_status_t att_filter_init(att_filter_t *f, att_filter_kind_t kind, const att_filter_settings_t *settings)
{
    att_status_t st;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    /* validate first, so that f is untouched on error; the kind's init then cannot fail */
    st = att_filter_settings_validate(kind, settings);
    if (st != ATT_OK) {
        return st;
    }
    switch (kind) {
        ATT_KINDS(ATT_FILTER_CASE_INIT)
    default:
        return ATT_ERR_KIND; /* not reached: validated */
    }
    if (st == ATT_OK) {
#if ATT_WITH_CALIB
        att_calib_settings_t cs;
        att_calib_settings_default(&cs);
        (void)att_calib_init(&f->cal, &cs); /* the defaults are valid */
#endif
        f->kind = kind;
    }
    return st;
}

#define ATT_FILTER_CASE_RETUNE(NAME, name, num)                                                            \
    case ATT_FILTER_##NAME:                                                                                  \
        return att_##name##_retune(&f->u.name, &settings->name);

att_status_t att_filter_retune(att_filter_t *f, const att_filter_settings_t *settings)
{
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    switch (f->kind) {
        ATT_KINDS(ATT_FILTER_CASE_RETUNE)
    default:
        return ATT_ERR_KIND;
    }
}

#define ATT_FILTER_CASE_RESET(NAME, name, num)                                                             \
    case ATT_FILTER_##NAME:                                                                                  \
        att_##name##_reset(&f->u.name);                                                                      \
        break;

void att_filter_reset(att_filter_t *f)
{
    if (f == NULL) {
        return;
    }
#if ATT_WITH_CALIB
    f->cal.have_acc = false;
    f->cal.acc_body = att_i_vec3(0.0f, 0.0f, 0.0f);
#endif
    switch (f->kind) {
        ATT_KINDS(ATT_FILTER_CASE_RESET)
    default:
        break;
    }
}

/* --- outputs --------------------------------------------------------------------------------- */

static void att_filter_clear(att_output_t *out)
{
    const att_vec3_t zero = att_i_vec3(0.0f, 0.0f, 0.0f);
    out->q = att_i_quat_identity();
    out->euler = zero;
    out->gyro_bias = zero;
    out->cov[0] = 0.0f;
    out->cov[1] = 0.0f;
    out->cov[2] = 0.0f;
    out->cov[3] = 0.0f;
    out->flags = 0u;
    out->steps = 0u;
    out->valid = ATT_OUT_ALL;
}

#define ATT_FILTER_CASE_OUTPUT(NAME, name, num)                                                            \
    case ATT_FILTER_##NAME:                                                                                  \
        att_##name##_output(&f->u.name, out);                                                                \
        return true;

/* The state's fields of the kind (att_<kind>_output); false for an uninitialised filter. */
static bool att_filter_fill(const att_filter_t *f, att_output_t *out)
{
    switch (f->kind) {
        ATT_KINDS(ATT_FILTER_CASE_OUTPUT)
    default:
        return false;
    }
}

void att_filter_output(const att_filter_t *f, att_output_t *out)
{
    if (out == NULL) {
        return;
    }
    att_filter_clear(out);
    if (f == NULL || !att_filter_fill(f, out)) {
        out->flags = ATT_FLAG_BAD_ARG;
        out->valid = ATT_OUT_ALL;
        return;
    }
    if ((out->valid & ATT_OUT_Q) == 0u) {
        out->q = att_quat_from_euler(out->euler.x, out->euler.y, out->euler.z);
    }
#if ATT_WITH_CALIB
    if ((f->cal.active & ATT_CALIB_ACTIVE_CONV) != 0u) {
        out->q = att_calib_quat_to(out->q, f->cal.convention);
        out->euler = att_quat_to_euler(out->q);
        out->valid = ATT_OUT_ALL;
        return;
    }
#endif
    if ((out->valid & ATT_OUT_EULER) == 0u) {
        out->euler = att_quat_to_euler(out->q);
    }
    out->valid = ATT_OUT_ALL;
}

/* --- the step -------------------------------------------------------------------------------- */

/* The result of a step that was refused (f or in NULL, unknown kind): BAD_ARG, out cleared. */
static uint32_t att_filter_bad_arg(att_output_t *out)
{
    if (out != NULL) {
        att_filter_clear(out);
        out->flags = ATT_FLAG_BAD_ARG;
    }
    return ATT_FLAG_BAD_ARG;
}

/* The kinds' steps: a tail call each (no function pointers, so the static stack bound holds). */
#define ATT_FILTER_CASE_STEP(NAME, name, num)                                                              \
    case ATT_FILTER_##NAME:                                                                                  \
        return att_##name##_step_out(&f->u.name, in, out);

#if ATT_WITH_CALIB
/* The kind's step on in (the sample after the input stage). */
static uint32_t att_filter_dispatch(att_filter_t *f, const att_sample_t *in, att_output_t *out)
{
    switch (f->kind) {
        ATT_KINDS(ATT_FILTER_CASE_STEP)
    default:
        return att_filter_bad_arg(out);
    }
}

/*
 * att_filter_step with some stage active: the input stage on a copy of the sample, the kind's step,
 * then the per-step fields in the convention's frame (q, and euler when the kind reports it; the
 * Euler-state kinds also get q). An uninitialised filter (kind NONE) is refused before any stage.
 */
static uint32_t att_filter_step_cal(att_filter_t *f, const att_sample_t *in, att_output_t *out)
{
    att_sample_t s;
    const att_sample_t *src = in;
    uint32_t flags;
    const uint32_t active = f->cal.active;
    if (f->kind == ATT_FILTER_NONE) {
        return att_filter_bad_arg(out);
    }
    if ((active & ATT_CALIB_ACTIVE_INPUT) != 0u) {
        att_i_calib_apply(&f->cal, &in->gyr, &in->acc, &in->mag, &s.gyr, &s.acc, &s.mag);
        src = &s;
    }
    if ((active & ATT_CALIB_ACTIVE_ACC) != 0u) {
        f->cal.acc_body = src->acc;
        f->cal.have_acc = true;
    }
    flags = att_filter_dispatch(f, src, out);
    if (out != NULL && (active & ATT_CALIB_ACTIVE_CONV) != 0u) {
        if ((out->valid & ATT_OUT_Q) == 0u) {
            out->q = att_quat_from_euler(out->euler.x, out->euler.y, out->euler.z);
            out->valid |= ATT_OUT_Q;
        }
        out->q = att_calib_quat_to(out->q, f->cal.convention);
        if ((out->valid & ATT_OUT_EULER) != 0u) {
            out->euler = att_quat_to_euler(out->q);
        }
    }
    return flags;
}
#endif

/*
 * Everything but the fast path of att_filter_step: NULL arguments, an active stage, unknown kinds. The
 * same arguments as att_filter_step, so that its calls here are tail calls that leave the registers as
 * they are.
 */
static ATT_NOINLINE uint32_t att_filter_step_slow(att_filter_t *f, const att_sample_t *in, att_output_t *out)
{
    if (f == NULL || in == NULL) {
        return att_filter_bad_arg(out);
    }
#if ATT_WITH_CALIB
    if (f->cal.active != 0u) {
        return att_filter_step_cal(f, in, out);
    }
    return att_filter_dispatch(f, in, out);
#else
    return att_filter_bad_arg(out); /* the fast path took every known kind */
#endif
}

#if ATT_WITH_CALIB
#define ATT_FILTER_NO_STAGE(f) ((f)->cal.active == 0u)
#else
#define ATT_FILTER_NO_STAGE(f) true
#endif

uint32_t att_filter_step(att_filter_t *f, const att_sample_t *in, att_output_t *out)
{
    /* the fast path: no stage active (one test), a known kind: a tail call */
    if (f != NULL && in != NULL && ATT_FILTER_NO_STAGE(f)) {
        switch (f->kind) {
            ATT_KINDS(ATT_FILTER_CASE_STEP)
        default:
            break;
        }
    }
    return att_filter_step_slow(f, in, out);
}

uint32_t att_filter_step_n(att_filter_t *f, const att_sample_t *in, uint32_t n, att_output_t *out)
{
    uint32_t flags = 0u;
    uint32_t k;
    if (n == 0u) {
        return att_filter_bad_arg(out);
    }
    if (n > (uint32_t)ATT_FILTER_STEP_N_MAX) {
        n = (uint32_t)ATT_FILTER_STEP_N_MAX;
        flags = (uint32_t)ATT_FLAG_CLAMPED;
    }
    for (k = 1u; k < n; k++) {
        flags |= att_filter_step(f, in, NULL);
    }
    flags |= att_filter_step(f, in, out);
    if (out != NULL) {
        out->flags = flags;
    }
    return flags;
}

/* --- input and output stages ----------------------------------------------------------------- */

#if ATT_WITH_CALIB
/* The hard-iron estimate of mars and mekf starts again (offset 0, no information, no keyframe). */
static void att_filter_hard_iron_restart(att_filter_t *f)
{
#if ATT_WITH_MARS
    if (f->kind == ATT_FILTER_MARS) {
        att_i_hi_reset(&f->u.mars.st.hi);
    }
#endif
#if ATT_WITH_MEKF
    if (f->kind == ATT_FILTER_MEKF) {
        att_i_hi_reset(&f->u.mekf.st.hi);
    }
#endif
    (void)f;
}
#endif

#if ATT_WITH_CALIB
/* The same folded stage (every field att_calib_init sets; the floats by value: they are finite). */
static bool att_filter_stage_same(const att_calib_stage_t *a, const att_calib_stage_t *b)
{
    uint32_t i;
    bool same = a->mode == b->mode && a->perm == b->perm && a->o.x == b->o.x && a->o.y == b->o.y &&
                a->o.z == b->o.z;
    for (i = 0u; i < 9u; i++) {
        same = same && a->a[i] == b->a[i];
    }
    for (i = 0u; i < 3u; i++) {
        same = same && a->axis[i] == b->axis[i] && a->sign[i] == b->sign[i];
    }
    return same;
}
#endif

att_status_t att_filter_calibrate(att_filter_t *f, const att_calib_settings_t *s)
{
#if ATT_WITH_CALIB
    att_calib_t c;
    att_status_t st;
    if (f == NULL || s == NULL) {
        return ATT_ERR_NULL;
    }
    if (!att_filter_kind_enabled(f->kind)) {
        return ATT_ERR_KIND;
    }
    st = att_calib_init(&c, s);
    if (st == ATT_OK) {
        const bool mag_same = att_filter_stage_same(&f->cal.mag, &c.mag);
        f->cal = c;
        if (!mag_same) {
            att_filter_hard_iron_restart(f); /* its samples are in another frame or scale now */
        }
    }
    return st;
#else
    if (f == NULL || s == NULL) {
        return ATT_ERR_NULL;
    }
    return ATT_ERR_DISABLED;
#endif
}

#if ATT_WITH_CALIB
/* The current attitude, sensor(body)-to-ENU; false for an unknown kind. */
static bool att_filter_q_enu(const att_filter_t *f, att_quat_t *q)
{
    att_output_t o;
    att_filter_clear(&o); /* the hook writes what the kind has; the rest is defined too */
    if (!att_filter_fill(f, &o)) {
        return false;
    }
    *q = ((o.valid & ATT_OUT_Q) != 0u) ? o.q : att_quat_from_euler(o.euler.x, o.euler.y, o.euler.z);
    return true;
}
#endif

void att_filter_accel(const att_filter_t *f, att_accel_t *out)
{
    const att_vec3_t zero = att_i_vec3(0.0f, 0.0f, 0.0f);
#if ATT_WITH_CALIB
    att_quat_t q;
    att_vec3_t a;
    att_vec3_t e;
    float m[9];
    float g;
#endif
    if (out == NULL) {
        return;
    }
    out->gravity = zero;
    out->linear = zero;
    out->earth = zero;
    out->valid = 0u;
#if ATT_WITH_CALIB
    if (f == NULL || (f->cal.active & ATT_CALIB_ACTIVE_ACC) == 0u || !f->cal.have_acc || !att_filter_q_enu(f, &q)) {
        return;
    }
    g = f->cal.gravity;
    a = f->cal.acc_body;
    att_quat_to_matrix(q, m);
    out->gravity = att_i_vec3(m[6] * g, m[7] * g, m[8] * g); /* R^T (0, 0, g): the up direction, body */
    out->linear = att_i_vec3_sub(a, out->gravity);
    e.x = (m[0] * a.x + m[1] * a.y) + m[2] * a.z;
    e.y = (m[3] * a.x + m[4] * a.y) + m[5] * a.z;
    e.z = ((m[6] * a.x + m[7] * a.y) + m[8] * a.z) - g;
    out->earth = att_calib_vec_to(e, f->cal.convention);
    out->valid = ATT_OUT_ACCEL;
#else
    (void)f;
#endif
}

/* --- heading --------------------------------------------------------------------------------- */

#define ATT_FILTER_PIO2 0x1.921fb6p+0f
#define ATT_FILTER_HEADING_MAX 8192.0f

/* The ENU yaw (rad) that heading (rad, in the convention of f) means. */
static float att_filter_heading_enu(const att_filter_t *f, float heading)
{
#if ATT_WITH_CALIB
    if (f->cal.convention == ATT_CONV_NED) {
        return att_wrap_pi(ATT_FILTER_PIO2 - heading);
    }
    if (f->cal.convention == ATT_CONV_NWU) {
        return att_wrap_pi(heading + ATT_FILTER_PIO2);
    }
#else
    (void)f;
#endif
    return att_wrap_pi(heading);
}

#define ATT_FILTER_CASE_HEADING(NAME, name, num)                                                           \
    case ATT_FILTER_##NAME:                                                                                  \
        return att_##name##_heading_kind(&f->u.name);

/* What the kind of f does with a heading (NONE for an uninitialised filter). */
static att_heading_t att_filter_heading_kind(const att_filter_t *f)
{
    switch (f->kind) {
        ATT_KINDS(ATT_FILTER_CASE_HEADING)
    default:
        return ATT_HEADING_NONE;
    }
}

#define ATT_FILTER_CASE_YAW(NAME, name, num)                                                               \
    case ATT_FILTER_##NAME:                                                                                  \
        return att_##name##_yaw_to(&f->u.name, target, gain);

/* The kind's yaw hook: turn the attitude toward yaw target (rad, ENU) by the fraction gain. */
static att_status_t att_filter_yaw_to(att_filter_t *f, float target, float gain)
{
    switch (f->kind) {
        ATT_KINDS(ATT_FILTER_CASE_YAW)
    default:
        return ATT_ERR_KIND;
    }
}

static bool att_filter_heading_ok(float heading)
{
    return att_i_in(heading, -ATT_FILTER_HEADING_MAX, ATT_FILTER_HEADING_MAX);
}

att_status_t att_filter_mag_offset(const att_filter_t *f, att_mag_offset_t *out)
{
    const att_hardiron_t *hi = NULL;
    bool on = false;
    if (f == NULL || out == NULL) {
        return ATT_ERR_NULL;
    }
#if ATT_WITH_MARS
    if (f->kind == ATT_FILTER_MARS) {
        hi = &f->u.mars.st.hi;
        on = f->u.mars.c.hi.on;
    }
#endif
#if ATT_WITH_MEKF
    if (f->kind == ATT_FILTER_MEKF) {
        hi = &f->u.mekf.st.hi;
        on = f->u.mekf.c.hi.on;
    }
#endif
    if (hi == NULL) {
        return ATT_ERR_KIND;
    }
    if (!ATT_WITH_HARD_IRON) {
        return ATT_ERR_DISABLED; /* left out of the build (att_config.h) */
    }
    out->offset = hi->offset;
    out->on = on;
    out->estimated = hi->observable;
    return ATT_OK;
}

att_status_t att_filter_set_heading(att_filter_t *f, float heading)
{
    if (f == NULL) {
        return ATT_ERR_NULL;
    }
    if (att_filter_heading_kind(f) == ATT_HEADING_NONE) {
        return ATT_ERR_KIND;
    }
    if (!att_filter_heading_ok(heading)) {
        return ATT_ERR_SETTINGS;
    }
    return att_filter_yaw_to(f, att_filter_heading_enu(f, heading), 1.0f);
}

att_status_t att_filter_heading_update(att_filter_t *f, float heading, float gain, bool valid)
{
    if (f == NULL) {
        return ATT_ERR_NULL;
    }
    if (att_filter_heading_kind(f) != ATT_HEADING_UPDATE) {
        return ATT_ERR_KIND;
    }
    if (!att_filter_heading_ok(heading) || !att_i_in(gain, 0.0f, 1.0f)) {
        return ATT_ERR_SETTINGS;
    }
    if (!valid) {
        return ATT_OK;
    }
    return att_filter_yaw_to(f, att_filter_heading_enu(f, heading), gain);
}

/* --- names ----------------------------------------------------------------------------------- */

#define ATT_FILTER_CASE_NAME(NAME, name, num)                                                              \
    case ATT_FILTER_##NAME:                                                                                  \
        return #name;

const char *att_filter_name(att_filter_kind_t kind)
{
    switch (kind) {
        ATT_KINDS_ALL(ATT_FILTER_CASE_NAME)
    default:
        return "?";
    }
}

static const char *const att_flag_names[16] = {
    "GYRO_INVALID", "GYRO_RANGE", "ACCEL_INVALID", "ACCEL_RANGE", "ACCEL_REJECTED", "MAG_INVALID",
    "MAG_ABSENT",   "MAG_REJECTED", "AT_REST",     "BIAS_UPDATED", "INITIALISED",   "GIMBAL",
    "CLAMPED",      "NUMERIC",      "NOT_READY",   "BAD_ARG"};

const char *att_flag_name(uint32_t flag)
{
    uint32_t i;
    for (i = 0u; i < 16u; i++) {
        if (flag == (1u << i)) {
            return att_flag_names[i];
        }
    }
    return NULL;
}

/* Append text at *len of buf (size bytes), keeping buf NUL-terminated; *len counts the full text. */
static void att_flags_append(char *buf, size_t size, size_t *len, const char *text)
{
    size_t i;
    for (i = 0u; text[i] != '\0'; i++) {
        if (buf != NULL && *len + 1u < size) {
            buf[*len] = text[i];
            buf[*len + 1u] = '\0';
        }
        *len = *len + 1u;
    }
}

size_t att_flags_format(uint32_t flags, char *buf, size_t size)
{
    static const char hex[] = "0123456789abcdef";
    size_t len = 0u;
    uint32_t i;
    uint32_t unknown = flags & ~0xFFFFu;
    if (buf != NULL && size > 0u) {
        buf[0] = '\0';
    }
    if (flags == 0u) {
        att_flags_append(buf, size, &len, "-");
        return len;
    }
    for (i = 0u; i < 16u; i++) {
        if ((flags & (1u << i)) != 0u) {
            if (len > 0u) {
                att_flags_append(buf, size, &len, "|");
            }
            att_flags_append(buf, size, &len, att_flag_names[i]);
        }
    }
    if (unknown != 0u) {
        char text[11];
        int d;
        text[0] = '0';
        text[1] = 'x';
        for (d = 0; d < 8; d++) {
            text[2 + d] = hex[(unknown >> (28 - 4 * d)) & 0xFu];
        }
        text[10] = '\0';
        if (len > 0u) {
            att_flags_append(buf, size, &len, "|");
        }
        att_flags_append(buf, size, &len, text);
    }
    return len;
}
