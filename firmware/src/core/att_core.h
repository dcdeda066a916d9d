/**
 * @file att_core.h
 * @brief Private: filter building blocks shared by several filters, as static inline functions.
 *
 * The sample checks of att_sensor.h and the rest detector / running-mean bias of att_bias.h, in the
 * form the filters inline into their step functions. att_sensor.c and att_bias.c implement the public
 * functions with these, so both give the same results. Compiled only with firmware/cflags.txt.
 */
#ifndef ATT_CORE_H
#define ATT_CORE_H

#include "../math/att_inline.h"

#include "attica/att_bias.h"
#include "attica/att_hardiron.h"
#include "attica/att_magref.h"
#include "attica/att_math.h"
#include "attica/att_sensor.h"
#include "attica/att_types.h"

/**
 * att_sensor_check_gyro for a finite range (every filter's settings contract guarantees one; the
 * public att_sensor_check_gyro also accepts +Inf). The common case costs three comparisons: NaN and
 * Inf fail |w_i| <= range and take the slow path.
 */
static inline uint32_t att_i_sensor_check_gyro(att_vec3_t gyr, float range)
{
    if (att_i_absf(gyr.x) <= range && att_i_absf(gyr.y) <= range && att_i_absf(gyr.z) <= range) {
        return 0u;
    }
    /* a finite sample that is not within the (finite) range has a component beyond it */
    return att_i_vec3_isfinite(gyr) ? (uint32_t)ATT_FLAG_GYRO_RANGE : (uint32_t)ATT_FLAG_GYRO_INVALID;
}

/**
 * A gyro component beyond gyro_range but within this many times it is a reading at the sensor's rail, not
 * a corrupt sample: a MEMS gyro's last code is not exactly its nominal full scale (32767 LSB at 65.5
 * LSB/(deg/s) is 500.3 deg/s on a 500 deg/s range) and its sensitivity has a tolerance of a few percent,
 * so a saturated axis can read a little beyond the range a user sets from the data sheet. No rail is twice
 * its full scale.
 */
#define ATT_GYRO_RAIL 0x1p+1f /* 2 */

/**
 * Whether a filter integrates the gyro sample gyr, given att_i_sensor_check_gyro's flags: yes for 0; for
 * ATT_FLAG_GYRO_RANGE with every component within ATT_GYRO_RAIL * range yes, as read (a saturated
 * reading: the rail's value is the best there is, the true rate at least that; skipping the sample would
 * lose all of its rotation instead of the excess); no for a sample that is not finite or beyond the rail
 * (corrupt). The flag stays set, and the recovery after a clipping gyro starts as for any sample at 0.98
 * of the range.
 */
static ATT_ALWAYS_INLINE bool att_i_gyro_usable(att_vec3_t gyr, float range, uint32_t flags)
{
    const float rail = ATT_GYRO_RAIL * range;
    return flags == 0u || (flags == (uint32_t)ATT_FLAG_GYRO_RANGE && att_i_absf(gyr.x) <= rail &&
                           att_i_absf(gyr.y) <= rail && att_i_absf(gyr.z) <= rail);
}

/**
 * att_sensor_check_accel with *norm = |a| (0 when invalid), for a finite range. The usable case needs
 * no finiteness test: a NaN or Inf component makes |a|^2 NaN or Inf, which fails the range test.
 */
static inline uint32_t att_i_sensor_check_accel(att_vec3_t acc, float range, float *norm)
{
    const float n2 = att_i_vec3_dot(acc, acc);
    const float n = att_i_sqrtf(n2);
    if (n2 >= ATT_NORM2_MIN && n <= range) {
        *norm = n;
        return 0u;
    }
    if (!att_i_vec3_isfinite(acc) || !(n2 >= ATT_NORM2_MIN)) {
        *norm = 0.0f;
        return ATT_FLAG_ACCEL_INVALID;
    }
    *norm = n; /* n2 may be +Inf for huge input: then n = Inf > range */
    return (n > range) ? ATT_FLAG_ACCEL_RANGE : 0u;
}

/**
 * att_sensor_check_mag with *norm = |m| (0 when not usable), for a finite range: ATT_FLAG_MAG_ABSENT
 * for a NaN component or the zero vector, ATT_FLAG_MAG_INVALID for +-Inf, |m| > range or
 * |m|^2 < 2^-100.
 */
static inline uint32_t att_i_sensor_check_mag(att_vec3_t mag, float range, float *norm)
{
    const float n2 = att_i_vec3_dot(mag, mag);
    const float n = att_i_sqrtf(n2);
    *norm = 0.0f;
    if (n2 >= ATT_NORM2_MIN && n <= range) {
        *norm = n;
        return 0u;
    }
    if (mag.x != mag.x || mag.y != mag.y || mag.z != mag.z ||
        (mag.x == 0.0f && mag.y == 0.0f && mag.z == 0.0f)) {
        return ATT_FLAG_MAG_ABSENT;
    }
    return ATT_FLAG_MAG_INVALID; /* +-Inf, |m| > range or |m|^2 < 2^-100 */
}

/** Settings checks: lo <= v <= hi (false for NaN). */
static inline bool att_i_in(float v, float lo, float hi)
{
    return v >= lo && v <= hi;
}

/** A bool field holds 0 or 1 (read as bytes: another value would make reading it undefined). */
static inline bool att_i_bool_ok(const bool *b)
{
    const unsigned char *p = (const unsigned char *)b;
    size_t i;
    for (i = 1u; i < sizeof *b; i++) {
        if (p[i] != 0u) {
            return false;
        }
    }
    return p[0] <= 1u;
}

/** Every component within [-lim, lim] (false for NaN). */
static inline bool att_i_vec3_within(att_vec3_t v, float lim)
{
    return att_i_in(v.x, -lim, lim) && att_i_in(v.y, -lim, lim) && att_i_in(v.z, -lim, lim);
}

/**
 * A vector setting zero, or with |v| in [lo, hi]: |v| = sqrtf(v.v) compared as att_i_sensor_check_mag
 * compares a sample's (a reference field accepted with hi = mag_range is a sample the filter takes as
 * within range); false for NaN and +-Inf (and a v.v that overflows: |v| = +Inf).
 */
static inline bool att_i_vec3_zero_or_norm_in(att_vec3_t v, float lo, float hi)
{
    return (v.x == 0.0f && v.y == 0.0f && v.z == 0.0f) || att_i_in(att_i_vec3_norm(v), lo, hi);
}

/** An initial quaternion: finite with |q|^2 in [2^-20, 2^20] (it is normalised by the filter). */
static inline bool att_i_quat_init_ok(att_quat_t q)
{
    const float n2 = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z;
    return att_i_quat_isfinite(q) && att_i_in(n2, 0x1p-20f, 0x1p+20f);
}

/** The shared limits of the settings contracts. */
#define ATT_DT_MIN 0x1.0c6f7ap-20f  /* 1e-6 s */
#define ATT_DT_MAX 1.0f             /* s */
#define ATT_TAU_MAX 10000.0f        /* s */
#define ATT_GRAVITY_MIN 1.0f        /* m/s^2 */
#define ATT_GRAVITY_MAX 100.0f      /* m/s^2 */
#define ATT_ACCEL_RANGE_MAX 10000.0f /* m/s^2 (about 1000 g) */
#define ATT_GYRO_RANGE_MAX 1000.0f  /* rad/s (about 57 000 deg/s) */
#define ATT_MAG_RANGE_MAX 100000.0f /* uT */
#define ATT_REJECT_MAX 1000.0f      /* relative deviations (dimensionless) */
#define ATT_GAIN_C_MAX 1000000.0f
#define ATT_BIAS_N_MAX_LIMIT 16777216u /* 2^24: n converts to float exactly */

/*
 * The settings contract of a kind, written once: ATT_<KIND>_CHECKS(C) in filters/<kind>/att_<kind>.c
 * lists the conditions on its settings s in the order they are tested, each as
 *     C(name, ok, lo, hi, rule, unit)
 *   name    the field, a string literal ("dt", "euler_init.y")
 *   ok      the condition on s (true: accepted; NaN fails every range)
 *   lo, hi  the bounds of the rule for these settings (float; may read other fields: s->gravity)
 *   rule    the accepted values in words, a string literal ("[0, 1e4]", "(gravity, 1e4]")
 *   unit    the field's unit, a string literal ("" for none)
 * att_<kind>_settings_validate is the conjunction of the conditions (ATT_CHECK_AND, the expression it
 * always was), att_<kind>_settings_check names the first that fails (ATT_CHECK_WHY), and
 * att_<kind>_settings_rule lists the lines (ATT_CHECK_RULE: the host's tables, help and docs are made
 * from it): one list, so they cannot disagree. Only the checks use name, rule and unit: an image that does not call
 * att_filter_settings_check carries none of the text (--gc-sections drops it with the function).
 * The forms below (ATT_CK_*) write the usual conditions; a line may also call C directly.
 */
#define ATT_CHECK_AND(name, ok, lo, hi, rule, unit) &&(ok)
/* ATT_CHECK_RULE: line `index` of the table (att_<kind>_settings_rule), counted in `line`: the rule in *out,
 * ATT_OK when it holds for s, ATT_ERR_SETTINGS when not. The caller ends with att_i_settings_end. */
#define ATT_CHECK_RULE(name, ok, lo, hi, rule, unit)                                                          \
    if (index == line) {                                                                                      \
        (void)att_i_settings_refused(out, name, lo, hi, rule, unit);                                          \
        return (ok) ? ATT_OK : ATT_ERR_SETTINGS;                                                              \
    }                                                                                                         \
    line++;
#define ATT_CHECK_WHY(name, ok, lo, hi, rule, unit)                                                           \
    if (!(ok)) {                                                                                              \
        return att_i_settings_refused(why, name, lo, hi, rule, unit);                                         \
    }

/** field in [lo, hi] */
#define ATT_CK_IN(C, f, lo, hi, rule, unit) C(#f, att_i_in(s->f, lo, hi), lo, hi, rule, unit)
/** field in (lo, hi] */
#define ATT_CK_OC(C, f, lo, hi, rule, unit) C(#f, s->f > (lo) && s->f <= (hi), lo, hi, rule, unit)
/** field in (lo, hi) */
#define ATT_CK_OO(C, f, lo, hi, rule, unit) C(#f, s->f > (lo) && s->f < (hi), lo, hi, rule, unit)
/** every component of a vector field in [-lim, lim] */
#define ATT_CK_VEC(C, f, lim, rule, unit) C(#f, att_i_vec3_within(s->f, lim), -(lim), lim, rule, unit)
/** a vector field zero, or with its norm in [lo, hi] (att_i_vec3_zero_or_norm_in) */
#define ATT_CK_NORM0(C, f, lo, hi, rule, unit) C(#f, att_i_vec3_zero_or_norm_in(s->f, lo, hi), lo, hi, rule, unit)
/** a bool field holds 0 or 1 */
#define ATT_CK_BOOL(C, f) C(#f, att_i_bool_ok(&s->f), 0.0f, 1.0f, "0 or 1 (bool)", "")
/** an initial quaternion (att_i_quat_init_ok) */
#define ATT_CK_QUAT(C, f) C(#f, att_i_quat_init_ok(s->f), 0x1p-20f, 0x1p+20f, "finite, |q|^2 in [2^-20, 2^20]", "")

/** Bias mode and rest-detector settings shared by the ARS, the 9-axis filter and the KF (lines of a table). */
#define ATT_CK_BIAS(C)                                                                                        \
    C("bias_mode",                                                                                            \
      s->bias_mode == ATT_BIAS_OFF || s->bias_mode == ATT_BIAS_FROZEN || s->bias_mode == ATT_BIAS_RUNNING ||  \
          s->bias_mode == ATT_BIAS_AT_REST,                                                                   \
      0.0f, 3.0f, "OFF (0), FROZEN (1), RUNNING (2) or AT_REST (3)", "")                                      \
    C("bias_n_max", s->bias_n_max >= 1u && s->bias_n_max <= ATT_BIAS_N_MAX_LIMIT, 1.0f, 16777216.0f, "[1, 2^24]", \
      "")                                                                                                     \
    ATT_CK_VEC(C, bias_init, s->gyro_range, "each component in [-gyro_range, gyro_range]", "rad/s")          \
    ATT_CK_IN(C, rest_gyro, 0.0f, s->gyro_range, "[0, gyro_range]", "rad/s")                                  \
    ATT_CK_IN(C, rest_accel, 0.0f, s->gravity, "[0, gravity]", "m/s^2")                                       \
    ATT_CK_IN(C, rest_time, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")

/** The sensor limits of every fusion filter: gravity, accel rejection and saturation, gyro range (lines). */
#define ATT_CK_INERTIAL(C)                                                                                    \
    ATT_CK_IN(C, gravity, ATT_GRAVITY_MIN, ATT_GRAVITY_MAX, "[1, 100]", "m/s^2")                               \
    ATT_CK_IN(C, accel_reject, 0.0f, ATT_REJECT_MAX, "[0, 1e3]", "")                                           \
    ATT_CK_OC(C, accel_range, s->gravity, ATT_ACCEL_RANGE_MAX, "(gravity, 1e4]", "m/s^2")                      \
    ATT_CK_OC(C, gyro_range, 0.0f, ATT_GYRO_RANGE_MAX, "(0, 1e3]", "rad/s")

/** The magnetometer limits of the 9-axis filters (lines; pi: the kind's float pi). */
#define ATT_CK_MAG(C, pi)                                                                                     \
    ATT_CK_OC(C, mag_range, 0.0f, ATT_MAG_RANGE_MAX, "(0, 1e5]", "uT")                                         \
    ATT_CK_IN(C, mag_norm_reject, 0.0f, ATT_REJECT_MAX, "[0, 1e3]", "")                                        \
    ATT_CK_IN(C, mag_dip_reject, 0.0f, pi, "[0, pi]", "rad")

/** why (may be NULL) names field, its bounds and rule; returns ATT_ERR_SETTINGS (the checks' one exit). */
static inline att_status_t att_i_settings_refused(att_settings_error_t *why, const char *field, float lo, float hi,
                                                 const char *rule, const char *unit)
{
    if (why != NULL) {
        why->field = field;
        why->min = lo;
        why->max = hi;
        why->rule = rule;
        why->unit = unit;
    }
    return ATT_ERR_SETTINGS;
}

/** Past a table's last line: out (may be NULL) gets field NULL; ATT_OK. */
static inline att_status_t att_i_settings_end(att_settings_error_t *out)
{
    (void)att_i_settings_refused(out, NULL, 0.0f, 0.0f, NULL, NULL);
    return ATT_OK;
}

#define ATT_ALIGN_A_MIN 0x1p-19f /* full alignment: below this (|v| + v_z) / |v| the vector points down */

/**
 * The full alignment of v (earth frame) with z = (0, 0, 1) as the quaternion (w, x, y, 0) of a rotation
 * about a horizontal axis, without trigonometry: with n = |v| and a = n + v_z, the shortest-arc
 * quaternion (a, v_y, -v_x, 0) / sqrt(2 n a) (the half-angle form of the rotation by the angle between
 * v and z about v x z); when a <= 2^-19 n (v points down) a half turn about x, (0, 1, 0, 0). *n = |v|.
 * Returns false (outputs unset) when |v|^2 < 2^-100 or NaN (v is a low-passed specific force, bounded
 * by the accel range: it cannot overflow). Mirrored by reference/ars.align_up.
 */
static inline bool att_i_align_up(att_vec3_t v, float *qw, float *qx, float *qy, float *n)
{
    const float n2 = att_i_vec3_dot(v, v);
    float a;
    float inv;
    if (!(n2 >= ATT_NORM2_MIN)) {
        return false;
    }
    *n = att_i_sqrtf(n2);
    a = *n + v.z;
    if (a > ATT_ALIGN_A_MIN * *n) {
        inv = 1.0f / att_i_sqrtf((2.0f * *n) * a);
        *qw = a * inv;
        *qx = v.y * inv;
        *qy = -(v.x * inv);
    } else {
        *qw = 0.0f;
        *qx = 1.0f;
        *qy = 0.0f;
    }
    return true;
}

/**
 * One update of the two cascaded first-order low-passes of the specific force v (earth or heading frame):
 * lp1 += (v - lp1) k, lp2 += (lp1 - lp2) k2, with k2 = k except during a recovery's running mean, where
 * it is 1 (att_i_recovery_lp_gain).
 */
static inline void att_i_lowpass2(att_vec3_t v, float k, float k2, att_vec3_t *lp1, att_vec3_t *lp2)
{
    *lp1 = att_i_vec3_add(*lp1, att_i_vec3_scale(att_i_vec3_sub(v, *lp1), k));
    *lp2 = att_i_vec3_add(*lp2, att_i_vec3_scale(att_i_vec3_sub(*lp1, *lp2), k2));
}

/** The rest detector's gyro gate for a running mean of n samples: rest_first2 while n = 0, else rest_gyro2. */
static inline float att_i_bias_gate(const att_bias_params_t *p, uint32_t n)
{
    float gate = p->rest_gyro2;
    if (n == 0u) {
        gate = p->rest_first2;
    }
    return gate;
}

/**
 * The bias state after new parameters (a retune): the fixed value for OFF / FROZEN (init: 0 or
 * bias_init), the counters limited to the new rest_n and n_max, the gate from the new parameters.
 */
static inline void att_i_bias_retune(const att_bias_params_t *p, att_vec3_t init, att_vec3_t *bias, uint32_t *n,
                                     uint32_t *rest_count, float *gate2)
{
    if (p->mode == ATT_BIAS_OFF || p->mode == ATT_BIAS_FROZEN) {
        *bias = init;
    }
    if (*rest_count > p->rest_n) {
        *rest_count = p->rest_n;
    }
    if (*n > p->n_max) {
        *n = p->n_max;
    }
    *gate2 = att_i_bias_gate(p, *n);
}

/** att_bias_params_set with rest_n already in samples. */
static inline void att_i_bias_params(att_bias_params_t *p, att_bias_mode_t mode, uint32_t n_max, float rest_gyro,
                                     float rest_accel, uint32_t rest_n, float gravity)
{
    const float lo = gravity - rest_accel;
    const float hi = gravity + rest_accel;
    p->mode = mode;
    p->n_max = n_max;
    p->rest_n = rest_n;
    p->rest_gyro2 = rest_gyro * rest_gyro;
    p->rest_first2 = (mode == ATT_BIAS_AT_REST && p->rest_gyro2 > 0.0f) ? p->rest_gyro2 + ATT_BIAS_UNKNOWN2 : p->rest_gyro2;
    p->acc2_lo = lo * lo;
    p->acc2_hi = hi * hi;
}

/**
 * att_bias_step (see att_bias.h); the pointers are never NULL here. *gate2 is the owner's copy of
 * att_i_bias_gate(p, *n) (kept in its state, so that the step loads one float as before), narrowed to
 * rest_gyro2 when the bias is updated. *d = gyr - b with the bias from before the step (the caller
 * reuses it when the bias did not change).
 */
static inline uint32_t att_i_bias_step(const att_bias_params_t *p, att_vec3_t *bias, uint32_t *n,
                                       uint32_t *rest_count, float *gate2, att_vec3_t gyr, bool gyro_ok,
                                       bool accel_ok, float acc_norm2, att_vec3_t *d)
{
    uint32_t flags = 0u;
    bool rest;
    float nf;
    float den;
    *d = att_i_vec3_sub(gyr, *bias);
    rest = gyro_ok && accel_ok && att_i_vec3_dot(*d, *d) < *gate2 && acc_norm2 > p->acc2_lo &&
           acc_norm2 < p->acc2_hi;
    if (!rest) {
        *rest_count = 0u;
    } else if (*rest_count < p->rest_n) {
        *rest_count = *rest_count + 1u;
    }
    if (rest && *rest_count >= p->rest_n) {
        flags |= ATT_FLAG_AT_REST;
    }
    if (gyro_ok && (p->mode == ATT_BIAS_RUNNING || (p->mode == ATT_BIAS_AT_REST && (flags & ATT_FLAG_AT_REST) != 0u))) {
        nf = (float)*n; /* exact: n <= 2^24 */
        den = nf + 1.0f;
        bias->x = (nf * bias->x + gyr.x) / den;
        bias->y = (nf * bias->y + gyr.y) / den;
        bias->z = (nf * bias->z + gyr.z) / den;
        if (*n == 0u) {
            *gate2 = p->rest_gyro2; /* the first sample of the mean: the bias is known from now on */
        }
        if (*n < p->n_max) {
            *n = *n + 1u;
        }
        flags |= ATT_FLAG_BIAS_UPDATED;
    }
    return flags;
}

/**
 * att_sensor_check_accel on |a|^2 for a finite range: *n2 = |a|^2 ((m/s^2)^2; 0 when invalid).
 * ATT_FLAG_ACCEL_INVALID when non-finite or |a|^2 < 2^-100, ATT_FLAG_ACCEL_RANGE when |a|^2 >
 * range2 (range^2), else 0. NaN/Inf components make |a|^2 NaN/Inf and take the slow path.
 */
static inline uint32_t att_i_sensor_check_accel2(att_vec3_t acc, float range2, float *n2)
{
    const float m2 = att_i_vec3_dot(acc, acc);
    if (m2 >= ATT_NORM2_MIN && m2 <= range2) {
        *n2 = m2;
        return 0u;
    }
    if (!att_i_vec3_isfinite(acc) || !(m2 >= ATT_NORM2_MIN)) {
        *n2 = 0.0f;
        return ATT_FLAG_ACCEL_INVALID;
    }
    *n2 = m2;
    return ATT_FLAG_ACCEL_RANGE;
}

#define ATT_ROTVEC_Z_SMALL 0x1p-4f /* |rv|^2 up to which the series of att_i_quat_from_rotvec_fast hold */
#define ATT_ROTVEC_C1 (-0x1p-3f)         /* -1/8 */
#define ATT_ROTVEC_C2 0x1.555556p-9f     /* 1/384 */
#define ATT_ROTVEC_S0 0x1p-1f            /* 1/2 */
#define ATT_ROTVEC_S1 (-0x1.555556p-6f)  /* -1/48 */
#define ATT_ROTVEC_S2 0x1.111112p-12f    /* 1/3840 */

/**
 * The exponential map of a rotation vector rv (rad), att_quat_from_rotvec, with the small angles of
 * a sensor loop done without square root, division or trigonometry: for z = |rv|^2 <= 1/16
 * (|rv| <= 0.25 rad per sample) q = (1 + z (-1/8 + z / 384), rv (1/2 + z (-1/48 + z / 3840))), the
 * series of cos(|rv|/2) and sin(|rv|/2)/|rv| to the z^2 term (the next terms are below 6e-9 there,
 * under half an ulp of 1); larger angles take att_quat_from_rotvec. Mirrored by
 * reference/detmath.quat_from_rotvec_fast.
 */
static inline att_quat_t att_i_quat_from_rotvec_fast(att_vec3_t rv)
{
    const float z = att_i_vec3_dot(rv, rv);
    float k;
    if (z <= ATT_ROTVEC_Z_SMALL) {
        k = ATT_ROTVEC_S0 + z * (ATT_ROTVEC_S1 + z * ATT_ROTVEC_S2);
        return att_i_quat(1.0f + z * (ATT_ROTVEC_C1 + z * ATT_ROTVEC_C2), rv.x * k, rv.y * k, rv.z * k);
    }
    return att_quat_from_rotvec(rv);
}

/* The recovery after a clipping gyro (att_ars.h, att_mars.h: recovery_time). */
#define ATT_REC_CLIP_F 0x1.f5c29p-1f /* 0.98: |w_i| at this fraction of gyro_range is clipping */
#define ATT_REC_TAU 0x1p-3f          /* the time constant of a recovery: recovery_time / 8 */

/**
 * The recovery's coefficients: *rec_n its samples (0: none), *clip the |w_i| at and above which a gyro
 * sample is clipping (0.98 gyro_range, rad/s; Inf when rec_n is 0: no recovery). Returns the gain of a
 * first-order low-pass with the recovery's time constant, dt / (recovery_time / 8 + dt).
 */
static inline float att_i_recovery_params(float recovery_time, float gyro_range, float dt, uint32_t *rec_n,
                                          float *clip)
{
    const float tau = recovery_time * ATT_REC_TAU;
    const float k = dt / (tau + dt);
    *rec_n = att_sensor_samples(recovery_time, dt);
    *clip = (*rec_n > 0u) ? ATT_REC_CLIP_F * gyro_range : INFINITY;
    return k;
}

/**
 * The process noise whose steady-state Kalman gain is k for a measurement of noise r (a random walk: the
 * prior k r / (1 - k), its step k^2 r / (1 - k)), at most cap; k = 1 (Inf) gives cap. The Kalman filters'
 * recoveries (att_kf.h, att_ekf.h, att_mekf.h) add it per prediction.
 */
static inline float att_i_recovery_q(float k, float r, float cap)
{
    const float q = ((k * k) / (1.0f - k)) * r;
    return (q < cap) ? q : cap;
}

/*
 * The orientation covariance of the complementary filters (ars, mars; docs/filters.md "Covariance"),
 * a documented model, computed when the output is asked for. With s2 = gyro_noise^2 ((rad/s)^2/Hz), dt
 * the sample period and a2 the noise density^2 of the corrected angle (rad^2/Hz: (accel_noise / g)^2
 * for the tilt, (mag_noise / |m0_xy|)^2 for the heading), a correction of per-sample gain k alone (no
 * low-pass) is a first-order filter of the angle error: its steady-state variance is exactly
 * ((1 - k)^2 s2 dt + k^2 a2 / dt) / (k (2 - k)). Two low-pass stages of time constant tl followed by a
 * correction of time constant tc (0: the full alignment) are, in continuous time, the error e and the
 * stages l1, l2 (their angles in the filter's earth frame, turned by every correction):
 * de = -l2 / tc dt + dW_gyro, dl1 = ((e - l1) / tl - l2 / tc) dt + dW_acc / tl, dl2 = ((l1 - l2) / tl -
 * l2 / tc) dt. The steady state of that Lyapunov equation gives var(e) = (a2 (2 tc + tl) + s2 (2 tc^3 +
 * 12 tc^2 tl + 14 tc tl^2 + 5 tl^3)) / (4 (tc + tl)^2) (tc = 0: 5/4 s2 tl + a2 / (4 tl)), with tl =
 * dt (1 - k_lp) / k_lp and tc = dt (1 - k) / k. Since the last accepted correction each step adds s2 dt
 * (the gyro's random walk).
 */
#define ATT_COV_UNKNOWN 0x1.a51a66p+1f  /* pi^2 / 3, rad^2: an angle uniform on the circle (heading unknown) */
#define ATT_COV_TILT_MAX 0x1.a51a66p-1f /* pi^2 / 12, rad^2: a tilt uniform within +-90 deg */
#define ATT_COV_CLIP 0x1.a51a66p-3f     /* pi^2 / 48, rad^2: uniform within +-45 deg, after a clipping gyro */

/* The steady-state variance of a first-order correction of per-sample gain k in (0, 1] (above), rad^2. */
static inline float att_i_cov_first(float dt, float k, float s2, float a2)
{
    const float k1 = 1.0f - k;
    return (k1 * k1 * (s2 * dt) + k * k * (a2 / dt)) / (k * (2.0f - k));
}

/*
 * The steady-state tilt variance of the accel correction (above), rad^2: low-pass stages of per-sample
 * gain k_lp in (0, 1) (0: none), then the correction of per-sample gain k in (0, 1]. tc is at most
 * ATT_COV_TC_MAX (a gain of 1e-30 would overflow the cubes; the variance is then capped anyway).
 */
#define ATT_COV_TC_MAX 1000000.0f /* s */
static inline float att_i_cov_tilt(float dt, float k_lp, float k, float s2, float a2)
{
    float tl;
    float tc = 0.0f;
    float t;
    float g;
    if (!(k_lp > 0.0f && k_lp < 1.0f)) {
        return att_i_cov_first(dt, k, s2, a2);
    }
    tl = dt * (1.0f - k_lp) / k_lp;
    if (k < 1.0f) {
        tc = dt * (1.0f - k) / k;
        tc = (tc < ATT_COV_TC_MAX) ? tc : ATT_COV_TC_MAX;
    }
    t = tc + tl;
    g = ((2.0f * tc + 12.0f * tl) * tc + 14.0f * (tl * tl)) * tc + 5.0f * ((tl * tl) * tl);
    return (a2 * (2.0f * tc + tl) + s2 * g) / (4.0f * (t * t));
}

/*
 * A variance v (rad^2) grown by s2dt = s2 dt per step over the steps after the one whose count (before
 * it) was stamp, at most cap: steps - stamp - 1 of them (0 when stamp == steps, before any step).
 */
static inline float att_i_cov_grow(float v, float s2dt, uint32_t steps, uint32_t stamp, float cap)
{
    const uint32_t d = steps - stamp;
    const float g = v + s2dt * (float)((d > 0u) ? d - 1u : 0u);
    return (g < cap) ? g : cap;
}

/*
 * The tilt variance of ars's and mars's covariance (att_ars.h, step 5), rad^2: pi^2/12 before the first
 * usable sample; else the steady state var_tilt (during a recovery var_tilt_rec plus pi^2/48 fading over
 * its rec_n steps) grown by var_step per step since the last accepted accel sample (stamp acc_step).
 */
static inline float att_i_cov_tilt_now(float var_tilt, float var_tilt_rec, float var_step, uint32_t rec_left,
                                       uint32_t rec_n, uint32_t steps, uint32_t acc_step, bool initialised)
{
    float tilt = var_tilt;
    if (!initialised) {
        return ATT_COV_TILT_MAX; /* no attitude yet */
    }
    if (rec_left > 0u) {
        tilt = var_tilt_rec + ATT_COV_CLIP * ((float)rec_left / (float)rec_n);
    }
    return att_i_cov_grow(tilt, var_step, steps, acc_step, ATT_COV_TILT_MAX);
}

/*
 * The learnt reference field (att_magref.h), shared by mars and mekf. A step's mag sample is counted as
 * ATT_MAGREF_ACCEPTED (it passed the norm and dip tests), ATT_MAGREF_GATED (it failed them) or neither.
 */
#define ATT_MAGREF_BLOCK_S 1.0f    /* s: the length of a block of the statistics */
#define ATT_MAGREF_M0_MIN 0x1.0624dep-10f /* 1e-3 uT: a horizontal field below this has no direction */
#define ATT_MAGREF_ACCEPTED 1u
#define ATT_MAGREF_GATED 2u
#define ATT_MAGREF_KEEP 0u   /* the end of a block: the reference stays */
#define ATT_MAGREF_FOLLOW 1u /* its norm and sin(dip) move toward the accepted samples' */
#define ATT_MAGREF_ADOPT 2u  /* a steady new field becomes the reference */

/* The coefficients from the owner's settings (s, rad; the rejection bounds 0 = none). */
static inline void att_i_magref_params(att_magref_params_t *p, float dt, float ref_tau, float new_time,
                                       float norm_reject, float dip_reject)
{
    const uint32_t blk_n = att_sensor_samples(ATT_MAGREF_BLOCK_S, dt);
    float t;
    p->blk_n = (blk_n > 0u) ? blk_n : 1u;
    t = (float)p->blk_n * dt;
    p->ref_on = ref_tau > 0.0f;
    p->k_ref = p->ref_on ? t / (ref_tau + t) : 0.0f;
    p->new_n = att_sensor_samples(new_time, t);
    p->cand_tol_n = (norm_reject > 0.0f) ? 0.5f * norm_reject : INFINITY;
    p->cand_tol_s = (dip_reject > 0.0f) ? 0.5f * dip_reject : INFINITY;
}

/* A new block of the statistics. */
static inline void att_i_magref_clear(att_magref_t *r)
{
    r->acc_norm = 0.0f;
    r->acc_z = 0.0f;
    r->rej_norm = 0.0f;
    r->rej_z = 0.0f;
    r->blk = 0u;
    r->acc_n = 0u;
    r->rej_n = 0u;
}

/* No candidate, a new block (reset). */
static inline void att_i_magref_reset(att_magref_t *r)
{
    r->cand_norm = 0.0f;
    r->cand_sin = 0.0f;
    r->cand_n = 0u;
    att_i_magref_clear(r);
}

/* Count a step with a known reference: use (ATT_MAGREF_*), |m| (uT), the vertical field (uT). True at
   the end of a block (then call att_i_magref_block). */
static ATT_ALWAYS_INLINE bool att_i_magref_count(const att_magref_params_t *p, att_magref_t *r, uint32_t use,
                                                 float mnorm, float mz)
{
    if (use == ATT_MAGREF_ACCEPTED) {
        r->acc_norm = r->acc_norm + mnorm;
        r->acc_z = r->acc_z + mz;
        r->acc_n = r->acc_n + 1u;
    } else if (use == ATT_MAGREF_GATED) {
        r->rej_norm = r->rej_norm + mnorm;
        r->rej_z = r->rej_z + mz;
        r->rej_n = r->rej_n + 1u;
    }
    r->blk = r->blk + 1u;
    return r->blk >= p->blk_n;
}

/*
 * The end of a block (att_magref.h) with the reference m0 (uT, earth): ATT_MAGREF_FOLLOW or
 * ATT_MAGREF_ADOPT with the new reference's norm *n (uT) and sin(dip) *s, or ATT_MAGREF_KEEP; the
 * candidate updated, a new block.
 */
static inline uint32_t att_i_magref_block(const att_magref_params_t *p, att_magref_t *r, att_vec3_t m0, float *n,
                                          float *s)
{
    uint32_t out = ATT_MAGREF_KEEP;
    if (r->acc_n > r->rej_n) {
        if (p->ref_on && r->acc_norm > 0.0f) {
            const float n0 = att_i_vec3_norm(m0);
            const float s0 = m0.z / n0;
            const float nb = r->acc_norm / (float)r->acc_n;
            const float sb = r->acc_z / r->acc_norm;
            *n = n0 + p->k_ref * (nb - n0);
            *s = s0 + p->k_ref * (sb - s0);
            out = ATT_MAGREF_FOLLOW;
        }
        r->cand_n = 0u;
    } else if (r->rej_n > 0u && p->new_n > 0u && r->rej_norm > 0.0f) {
        const float nb = r->rej_norm / (float)r->rej_n;
        const float sb = r->rej_z / r->rej_norm;
        if (r->cand_n > 0u && att_i_absf(nb - r->cand_norm) <= p->cand_tol_n * r->cand_norm &&
            att_i_absf(sb - r->cand_sin) <= p->cand_tol_s) {
            const float w = 1.0f / (float)(r->cand_n + 1u);
            r->cand_norm = r->cand_norm + (nb - r->cand_norm) * w;
            r->cand_sin = r->cand_sin + (sb - r->cand_sin) * w;
            r->cand_n = r->cand_n + 1u;
        } else {
            r->cand_norm = nb;
            r->cand_sin = sb;
            r->cand_n = 1u;
        }
        if (r->cand_n >= p->new_n) {
            *n = r->cand_norm;
            *s = r->cand_sin;
            r->cand_n = 0u;
            out = ATT_MAGREF_ADOPT;
        }
    }
    att_i_magref_clear(r);
    return out;
}

/*
 * The reference field of norm n (uT) and sin(dip) s with the horizontal direction of m0 (uT, earth), or
 * the declination's azimuth (sin, cos) when m0 has none; |s| slightly above 1 (rounding of the sums) gives
 * a vertical field.
 */
static inline att_vec3_t att_i_magref_m0(att_vec3_t m0, float n, float s, float decl_sin, float decl_cos)
{
    const float s2 = s * s;
    const float h = (s2 < 1.0f) ? n * att_i_sqrtf(1.0f - s2) : 0.0f;
    const float h0 = att_i_sqrtf(m0.x * m0.x + m0.y * m0.y);
    if (h0 >= ATT_MAGREF_M0_MIN) {
        const float r = h / h0;
        return att_i_vec3(m0.x * r, m0.y * r, n * s);
    }
    return att_i_vec3(h * decl_sin, h * decl_cos, n * s);
}

/*
 * The hard-iron offset estimated on the device (att_hardiron.h), shared by mars and mekf.
 */
#define ATT_HI_KEY_S 1.0f               /* s: the longest keyframe pair */
#define ATT_HI_KEY_N_MAX 1024u          /* steps: the longest keyframe pair (its rotation's rounding) */
#define ATT_HI_KEY_V2 0x1.f56bfcp-5f    /* sin^2(0.25): a pair closes after a rotation of 0.5 rad */
#if ATT_WITH_HARD_IRON
#define ATT_HI_TAU_MAX ATT_TAU_MAX /* s: the largest hard_iron_tau */
#define ATT_HI_TAU_RULE "[0, 1e4]"
#else
#define ATT_HI_TAU_MAX 0.0f /* left out of the build (att_config.h): only 0 */
#define ATT_HI_TAU_RULE "0 (ATT_WITH_HARD_IRON is 0)"
#endif
#define ATT_HI_OBS 1.0f                 /* the smallest eigenvalue of the information that makes it observable */

/* The coefficients from the owner's settings: dt (s), hard_iron_tau (s, 0 = off), hard_iron_rate (uT/s),
   the norm gate (mag_norm_reject), the target's bound per axis (mag_range, uT). */
static inline void att_i_hi_params(att_hardiron_params_t *p, float dt, float tau, float rate, float gate,
                                   float limit)
{
    const uint32_t n = att_sensor_samples(ATT_HI_KEY_S, dt);
    p->on = tau > 0.0f;
    p->limit = limit;
    p->k_forget = p->on ? dt / tau : 0.0f;
    p->step_max = rate * dt;
    p->gate = gate;
    p->key_n = (n < 1u) ? 1u : ((n > ATT_HI_KEY_N_MAX) ? ATT_HI_KEY_N_MAX : n);
}

/* A retune's bound (p->limit, mag_range): the target and the applied offset kept within it per axis, as
   the solve keeps the target (a smaller mag_range would otherwise leave them outside). */
static inline void att_i_hi_retune(const att_hardiron_params_t *p, att_hardiron_t *s)
{
    const float l = p->limit;
    s->target = att_i_vec3(att_i_clampf(s->target.x, -l, l), att_i_clampf(s->target.y, -l, l),
                           att_i_clampf(s->target.z, -l, l));
    s->offset = att_i_vec3(att_i_clampf(s->offset.x, -l, l), att_i_clampf(s->offset.y, -l, l),
                           att_i_clampf(s->offset.z, -l, l));
}

/* Nothing estimated: offset 0, no information, no keyframe. */
static inline void att_i_hi_reset(att_hardiron_t *s)
{
    const att_vec3_t zero = att_i_vec3(0.0f, 0.0f, 0.0f);
    uint32_t i;
    s->offset = zero;
    s->target = zero;
    s->d = att_i_quat_identity();
    s->m_key = zero;
    s->w_key = zero;
    for (i = 0u; i < 10u; i++) {
        s->info[i] = 0.0f;
    }
    for (i = 0u; i < 4u; i++) {
        s->z[i] = 0.0f;
    }
    s->lag = 0.0f;
    s->key_steps = 0u;
    s->observable = false;
}

/*
 * The target from the information when observable (att_hardiron.h): the lag L eliminated (Schur
 * complement of its entry ll when ll > 0), the 3x3 system's smallest eigenvalue >= ATT_HI_OBS by the
 * bound det / (trace / 2)^2 <= it, solved by the adjugate over the determinant, each axis within +-limit.
 */
static inline void att_i_hi_solve(const att_hardiron_params_t *p, att_hardiron_t *s)
{
    const float *i = s->info;
    float a[6] = {i[0], i[1], i[2], i[4], i[5], i[7]};
    float z0 = s->z[0];
    float z1 = s->z[1];
    float z2 = s->z[2];
    float c00;
    float c01;
    float c02;
    float c11;
    float c12;
    float c22;
    float det;
    float tr;
    if (i[9] > 0.0f) {
        const float u0 = i[3] / i[9];
        const float u1 = i[6] / i[9];
        const float u2 = i[8] / i[9];
        a[0] = a[0] - u0 * i[3];
        a[1] = a[1] - u0 * i[6];
        a[2] = a[2] - u0 * i[8];
        a[3] = a[3] - u1 * i[6];
        a[4] = a[4] - u1 * i[8];
        a[5] = a[5] - u2 * i[8];
        z0 = z0 - u0 * s->z[3];
        z1 = z1 - u1 * s->z[3];
        z2 = z2 - u2 * s->z[3];
    }
    c00 = a[3] * a[5] - a[4] * a[4];
    c01 = a[2] * a[4] - a[1] * a[5];
    c02 = a[1] * a[4] - a[2] * a[3];
    c11 = a[0] * a[5] - a[2] * a[2];
    c12 = a[1] * a[2] - a[0] * a[4];
    c22 = a[0] * a[3] - a[1] * a[1];
    det = a[0] * c00 + a[1] * c01 + a[2] * c02;
    tr = a[0] + a[3] + a[5];
    if (det >= ATT_HI_OBS * (0.25f * (tr * tr)) && det > 0.0f) {
        const float l = p->limit;
        const att_vec3_t h = att_i_vec3(att_i_clampf((c00 * z0 + c01 * z1 + c02 * z2) / det, -l, l),
                                        att_i_clampf((c01 * z0 + c11 * z1 + c12 * z2) / det, -l, l),
                                        att_i_clampf((c02 * z0 + c12 * z1 + c22 * z2) / det, -l, l));
        s->target = h;
        s->lag = 0.0f;
        if (i[9] > 0.0f) {
            s->lag = (s->z[3] - (i[3] * h.x + i[6] * h.y + i[8] * h.z)) / i[9];
        }
        s->observable = true;
    }
}

/* A keyframe pair ends at the raw sample m with the rate w (rad/s): its information, unless the field
   changed between the two samples. */
static inline void att_i_hi_pair(const att_hardiron_params_t *p, att_hardiron_t *s, att_vec3_t m, att_vec3_t w)
{
    const att_quat_t d = s->d;
    const att_quat_t dc = att_i_quat_conj(d);
    const att_vec3_t y = att_i_vec3_sub(m, att_i_quat_rotate(dc, s->m_key));
    const att_vec3_t r = att_i_vec3_sub(y, att_i_quat_rotate(d, y));
    const att_vec3_t b = att_i_vec3_sub(att_i_vec3_cross(w, m),
                                        att_i_quat_rotate(dc, att_i_vec3_cross(s->w_key, s->m_key)));
    const att_vec3_t ab = att_i_vec3_sub(b, att_i_quat_rotate(d, b));
    const float v2 = d.x * d.x + d.y * d.y + d.z * d.z;
    float f = 1.0f - (float)(s->key_steps - 1u) * p->k_forget;
    float *a = s->info;
    float *z = s->z;
    if (s->observable && p->gate > 0.0f) {
        const float na = att_i_vec3_norm(att_i_vec3_sub(m, s->target));
        const float nb = att_i_vec3_norm(att_i_vec3_sub(s->m_key, s->target));
        if (att_i_absf(na - nb) > p->gate * nb) {
            return; /* the field changed between the two samples */
        }
    }
    f = (f > 0.0f) ? f : 0.0f;
    a[0] = f * a[0] + 4.0f * (v2 - d.x * d.x);
    a[1] = f * a[1] - 4.0f * (d.x * d.y);
    a[2] = f * a[2] - 4.0f * (d.x * d.z);
    a[3] = f * a[3] + ab.x;
    a[4] = f * a[4] + 4.0f * (v2 - d.y * d.y);
    a[5] = f * a[5] - 4.0f * (d.y * d.z);
    a[6] = f * a[6] + ab.y;
    a[7] = f * a[7] + 4.0f * (v2 - d.z * d.z);
    a[8] = f * a[8] + ab.z;
    a[9] = f * a[9] + att_i_vec3_dot(b, b);
    z[0] = f * z[0] + r.x;
    z[1] = f * z[1] + r.y;
    z[2] = f * z[2] + r.z;
    z[3] = f * z[3] + att_i_vec3_dot(b, y);
    att_i_hi_solve(p, s);
}

/*
 * One step of the estimate (att_hardiron.h): w the bias-corrected rate (rad/s) of a usable gyro sample
 * (gyro_ok: valid and not clipping), m the raw mag sample (uT) when valid (mag_ok), dt (s). A keyframe
 * without a mag sample for 2 key_n steps is dropped. The applied offset then moves toward the target by
 * at most step_max per axis.
 */
static inline void att_i_hi_step(const att_hardiron_params_t *p, att_hardiron_t *s, float dt, att_vec3_t w,
                                 bool gyro_ok, att_vec3_t m, bool mag_ok)
{
    if (s->key_steps > 0u) {
        if (gyro_ok && s->key_steps <= 2u * p->key_n) {
            s->d = att_i_quat_mul(s->d, att_i_quat_from_rotvec_fast(att_i_vec3_scale(w, dt)));
            s->key_steps = s->key_steps + 1u;
        } else {
            s->key_steps = 0u; /* the rotation since the keyframe is unknown, or no mag sample for 2 key_n */
        }
    }
    if (mag_ok) {
        const att_quat_t d = s->d;
        const bool close = s->key_steps > 0u &&
                           (d.x * d.x + d.y * d.y + d.z * d.z >= ATT_HI_KEY_V2 || s->key_steps > p->key_n);
        if (close) {
            att_i_hi_pair(p, s, m, w);
        }
        if (close || (s->key_steps == 0u && gyro_ok)) {
            s->m_key = m;
            s->w_key = w;
            s->d = att_i_quat_identity();
            s->key_steps = 1u;
        }
    }
    if (s->observable) {
        const float h = p->step_max;
        s->offset = att_i_vec3(s->offset.x + att_i_clampf(s->target.x - s->offset.x, -h, h),
                               s->offset.y + att_i_clampf(s->target.y - s->offset.y, -h, h),
                               s->offset.z + att_i_clampf(s->target.z - s->offset.z, -h, h));
    }
}

/* A usable gyro sample for the hard-iron estimate: valid (check_flags 0) and no |w_i| at the recovery's
   clip level ATT_REC_CLIP_F gyro_range (rad/s), also with recovery_time 0: the rotation of a clipping
   gyro is not what it measured. */
static inline bool att_i_hi_gyro_ok(uint32_t check_flags, att_vec3_t w, float gyro_range)
{
    const float clip = ATT_REC_CLIP_F * gyro_range;
    return check_flags == 0u && att_i_absf(w.x) < clip && att_i_absf(w.y) < clip && att_i_absf(w.z) < clip;
}

/* The sample the filter uses: the raw valid sample m minus the applied offset (uT). */
static inline att_vec3_t att_i_hi_correct(const att_hardiron_t *s, att_vec3_t m)
{
    return att_i_vec3_sub(m, s->offset);
}

/**
 * The recovery counter *left (steps, 0 = no recovery): restarted to rec_n by a clipping gyro sample g
 * (any |w_i| >= clip, rad/s; a sample beyond gyro_range is beyond clip too), which also sets *lp_n, the
 * accel low-pass stages' count of updates since (att_i_recovery_lp_gain), to 0; else counted down.
 * Returns true on the step that ends a recovery (the counter reaches 0 without a new clipping sample).
 */
static ATT_ALWAYS_INLINE bool att_i_recovery_step(att_vec3_t g, float clip, uint32_t rec_n, uint32_t *left,
                                                  uint32_t *lp_n)
{
    if (att_i_absf(g.x) >= clip || att_i_absf(g.y) >= clip || att_i_absf(g.z) >= clip) {
        *left = rec_n;
        *lp_n = 0u;
        return false;
    }
    if (*left > 0u) {
        *left = *left - 1u;
        return *left == 0u;
    }
    return false;
}

/**
 * The start from the sensors as a recovery (ars, kf, mars, mekf): rec_n steps of it, counted down from
 * the next step, and the stages' running mean with the start's sample, from which they start, as its
 * first update (*lp_n = 1, att_i_recovery_lp_gain).
 */
static ATT_ALWAYS_INLINE void att_i_recovery_start(uint32_t rec_n, uint32_t *left, uint32_t *lp_n)
{
    *left = rec_n;
    *lp_n = 1u;
}

/**
 * Where a recovery's running mean hands over to two cascaded first-order stages of gain k (ars, kf, ekf,
 * mars): at k_end = ATT_I_REC_MEAN_END k, i.e. after n = 4 / k updates, where the mean is as good as the
 * stages' own window by either measure: the variance of a mean of n samples of white noise (1 / n of
 * theirs) is the cascade's (about k / 4), and its mean age (n / 2 samples) is the cascade's lag (2 / k).
 * The mekf's Butterworth section has its own (att_mekf.c).
 */
#define ATT_I_REC_MEAN_END 0.25f

/**
 * The accel low-pass stages' gain for an update during a recovery: 1 / (n + 1) after n earlier updates
 * since the last clipping gyro sample or the start (n = *n, the state's rec_lp_n: 0 after a clipping
 * sample, 1 after the start, whose sample the stages start from; counted up here), while that is at least
 * k_end (the mean's end, below the stages' own gain k_lp: ATT_I_REC_MEAN_END), then k_lp (in the mekf's
 * start its fast window). After a clipping sample the first is 1: the stages restart from that sample,
 * since the history they hold was turned into the earth frame by a rotation the gyro did not measure (a
 * clipping sample whose accel is not applied leaves the restart to the next one).
 * After it, with the gyro right again, every sample is an equally good measurement of gravity in the
 * frame the gyro carries, so their running mean is the estimate an unknown attitude calls for (a Kalman
 * filter's gain without a prior), where a fast exponential window would keep forgetting the early ones;
 * it runs until it is as good as the stages' own window (k_end), not merely until its gain is theirs.
 * The second stage must hold that mean too: *k2, its gain, is set to 1 while the mean runs (lp2 := lp1
 * after the update, to its rounding) and left as the caller set it, to k_lp, after it, when the cascade
 * runs again from the mean. At the first stage's gain the second would be the mean of the first's
 * running means, which weights the j-th of n samples by about ln(n / j): the samples right after the
 * clip would count most, and the motion's linear acceleration in them would stay in the attitude for
 * seconds. With lp1 = lp2 the next update of either cascade, this one or the mekf's Butterworth section,
 * is the running mean's. On the suite's clipped condition, ars back within 2 deg in 2 s after 29 of 40
 * episodes with the mean of means down to k_lp, 34 with the plain mean, 37 with the plain mean down to
 * k_end (docs/accuracy.md).
 * *n counts only updates within one recovery, so it stays at most the rec_n of the settings it began
 * with (<= 2^24: its float is exact), or within the ekf's mean after its start, which ends at 2^24.
 */
static ATT_ALWAYS_INLINE float att_i_recovery_lp_gain(uint32_t *n, float k_lp, float k_end, float *k2)
{
    float m = 1.0f / (float)(*n + 1u);
    *n = *n + 1u;
    if (m < k_end) {
        m = k_lp;
    } else {
        *k2 = 1.0f;
    }
    return m;
}

/** att_i_recovery_lp_gain for two cascaded first-order stages of gain k_lp (ars, kf, ekf, mars): the mean
 * ends at ATT_I_REC_MEAN_END k_lp. */
static ATT_ALWAYS_INLINE float att_i_recovery_lp_gain2(uint32_t *n, float k_lp, float *k2)
{
    return att_i_recovery_lp_gain(n, k_lp, ATT_I_REC_MEAN_END * k_lp, k2);
}

/** Index of P_ij (i <= j) in a symmetric 6x6 matrix stored as its upper triangle row by row (21 floats). */
#define ATT_I_P6(i, j) ((uint32_t)(i) * (11u - (uint32_t)(i)) / 2u + (uint32_t)(j))

/* Full unrolling of the loops over a 6x6 matrix (the indices fold into constants), not when optimising
 * for size (-Os); no effect on results. */
#if defined(__GNUC__) && !defined(__OPTIMIZE_SIZE__)
#define ATT_I_PRAGMA(x) _Pragma(#x)
#define ATT_I_UNROLL6 ATT_I_PRAGMA(GCC unroll 6)
#else
#define ATT_I_UNROLL6
#endif

/**
 * Positive definite with margin, a test float32 rounding cannot fool (the ekf's and the mekf's P, 6x6
 * packed as ATT_I_P6): the pivots of P = L D L^T satisfy d_0 > 0 and d_j > margin (P_jj + sum_{i<j}
 * m_ji^2 P_ii), m = L^-1 (unit diagonal); NaN fails. The sum is the pivot's sensitivity to the rounding
 * of the factorisation: the computed factors are exact for P + E with |E_ik| <= ~7 u sqrt(P_ii P_kk)
 * (u = 2^-24, the backward error), and the pivot d_j = min x^T P x over x with x_j = 1, x_i = 0 for
 * i > j, attained at x = row j of L^-1, so P's own pivot is at least the computed one less about
 * 6 * 7 u sum_i m_ji^2 P_ii. The margins (ekf 2^-12, mekf 2^-16) leave a factor of 100 and of six to
 * seven above that. A margin on P_jj alone is not sound: after a small earlier pivot float32 rounding
 * passed an indefinite P (F15: pivots 5e-3 and 1.05e-3 in float32, the last one -3.8e-4 exact; F16 in the
 * mekf). Mirrored by reference/_common.pd6.
 */
static ATT_ALWAYS_INLINE bool att_i_pd6(const float *p, float margin)
{
    float l[6][6];
    float m[6][6];
    float d[6];
    int i;
    int j;
    int k;
    ATT_I_UNROLL6
    for (j = 0; j < 6; j++) {
        float dj = p[ATT_I_P6(j, j)];
        float sj = dj;
        ATT_I_UNROLL6
        for (k = 0; k < j; k++) {
            /* d[k] and l[j][k] (k < j) were written by the earlier passes of the j loop */
            /* cppcheck-suppress uninitvar */
            dj = dj - (l[j][k] * l[j][k]) * d[k];
        }
        /* row j of L^-1: m_ji = -(l_ji + sum_{i<k<j} l_jk m_ki), i from j - 1 down */
        ATT_I_UNROLL6
        for (i = j - 1; i >= 0; i--) {
            float v = l[j][i];
            ATT_I_UNROLL6
            for (k = i + 1; k < j; k++) {
                /* cppcheck-suppress uninitvar */
                v = v + l[j][k] * m[k][i];
            }
            m[j][i] = -v;
            sj = sj + (m[j][i] * m[j][i]) * p[ATT_I_P6(i, i)];
        }
        if (!(dj > ((j == 0) ? 0.0f : margin * sj))) {
            return false;
        }
        d[j] = dj;
        ATT_I_UNROLL6
        for (i = j + 1; i < 6; i++) {
            float v = p[ATT_I_P6(j, i)];
            ATT_I_UNROLL6
            for (k = 0; k < j; k++) {
                v = v - (l[i][k] * l[j][k]) * d[k];
            }
            l[i][j] = v / dj;
        }
    }
    return true;
}

#endif /* ATT_CORE_H */
