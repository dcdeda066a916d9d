/**
 * @file att_ars.c
 * @brief Quaternion complementary ARS (see att_ars.h). Mirrored by host/attica/reference/ars.py.
 */
#include <string.h>

#include "../../math/att_fp.h"

#include "../../core/att_core.h"
#include "../att_kinds.h"
#include "../att_yaw.h"
#include "att_ars_checks.h"
#include "attica/att_ars.h"
#include "attica/att_math.h"
#include "attica/att_sensor.h"

/* The covariance model's default densities (docs/filters.md "Covariance": how they were chosen). */
#define ATT_ARS_GYRO_NOISE 0.002f  /* rad/s/sqrt(Hz) */
#define ATT_ARS_ACCEL_NOISE 0.24f  /* m/s^2/sqrt(Hz) */

void att_ars_settings_default(att_ars_settings_t *settings, float dt)
{
    if (settings == NULL) {
        return;
    }
    settings->dt = dt;
    settings->gain = 1.0f;
    settings->tau = 0.0f;
    settings->gain_c = 0.0f;
    settings->gravity = 9.80665f;
    settings->accel_reject = 0.0f;
    settings->accel_range = 156.9064f; /* 16 g */
    settings->gyro_range = 34.906586f; /* 2000 deg/s */
    settings->bias_mode = ATT_BIAS_AT_REST;
    settings->bias_n_max = 1000u;
    settings->bias_init = att_i_vec3(0.0f, 0.0f, 0.0f);
    settings->rest_gyro = 0.05f;
    settings->rest_accel = 0.5f;
    settings->rest_time = 0.5f;
    settings->integration = ATT_INTEGRATE_ROTVEC;
    settings->init_from_accel = true;
    settings->q_init = att_i_quat_identity();
    settings->tau_acc_lp = 1.5f;
    settings->recovery_time = 2.0f;
    settings->gyro_noise = ATT_ARS_GYRO_NOISE;
    settings->accel_noise = ATT_ARS_ACCEL_NOISE;
}

att_status_t att_ars_settings_validate(const att_ars_settings_t *s)
{
    bool ok;
    if (s == NULL) {
        return ATT_ERR_NULL;
    }
    ok = true ATT_ARS_CHECKS(ATT_CHECK_AND);
    return ok ? ATT_OK : ATT_ERR_SETTINGS;
}

/* The coefficients of the recovery after a clipping gyro (att_ars.h); after k. */
static void att_ars_rec_coeffs(att_ars_coeffs_t *c, const att_ars_settings_t *s)
{
    const float k = att_i_recovery_params(s->recovery_time, s->gyro_range, s->dt, &c->rec_n, &c->clip);
    c->k_rec = (k > c->k) ? k : c->k;
}

/* att_i_cov_tilt out of line (init only: one copy for both calls), 0 gain: the tilt is not observed. */
static ATT_NOINLINE float att_ars_cov_tilt(float dt, float k_lp, float k, float s2, float a2)
{
    return (k > 0.0f) ? att_i_cov_tilt(dt, k_lp, k, s2, a2) : ATT_COV_TILT_MAX;
}

/* The covariance model's coefficients (att_ars.h, step 5); after the gains. */
static void att_ars_cov_coeffs(att_ars_coeffs_t *c, const att_ars_settings_t *s)
{
    const float s2 = s->gyro_noise * s->gyro_noise;
    const float an = s->accel_noise / s->gravity;
    const float a2 = an * an;
    c->var_step = s2 * s->dt;
    c->var_tilt = att_ars_cov_tilt(s->dt, c->k_lp, c->k, s2, a2);
    c->var_tilt_rec = att_ars_cov_tilt(s->dt, c->k_lp, c->k_rec, s2, a2);
}

static void att_ars_coeffs(att_ars_coeffs_t *c, const att_ars_settings_t *s)
{
    c->dt = s->dt;
    c->k = (s->tau > 0.0f) ? s->dt / (s->tau + s->dt) : s->gain;
    c->k_lp = (s->tau_acc_lp > 0.0f) ? s->dt / (s->tau_acc_lp + s->dt) : 0.0f;
    c->gain_c = s->gain_c;
    c->gravity = s->gravity;
    c->accel_reject = s->accel_reject;
    c->accel_range2 = s->accel_range * s->accel_range;
    c->gyro_range = s->gyro_range;
    att_i_bias_params(&c->bias, s->bias_mode, s->bias_n_max, s->rest_gyro, s->rest_accel,
                      att_sensor_samples(s->rest_time, s->dt), s->gravity);
    (void)att_i_quat_normalize(s->q_init, &c->q_init);
    c->bias_init = (s->bias_mode == ATT_BIAS_OFF) ? att_i_vec3(0.0f, 0.0f, 0.0f) : s->bias_init;
    c->integration = (uint8_t)s->integration;
    c->init_from_accel = s->init_from_accel;
    c->lp_on = c->k_lp > 0.0f;
    c->reject_on = s->accel_reject > 0.0f;
    c->full = (c->k == 1.0f && s->gain_c == 0.0f);
    att_ars_rec_coeffs(c, s);
    att_ars_cov_coeffs(c, s);
}

att_status_t att_ars_init(att_ars_t *f, const att_ars_settings_t *settings)
{
    att_status_t st;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    st = att_ars_settings_validate(settings);
    if (st != ATT_OK) {
        return st;
    }
    att_ars_coeffs(&f->c, settings);
    att_ars_reset(f);
    return ATT_OK;
}

att_status_t att_ars_retune(att_ars_t *f, const att_ars_settings_t *settings)
{
    att_status_t st;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    st = att_ars_settings_validate(settings);
    if (st != ATT_OK) {
        return st;
    }
    att_ars_coeffs(&f->c, settings);
    att_i_bias_retune(&f->c.bias, f->c.bias_init, &f->st.bias, &f->st.bias_n, &f->st.rest_count,
                      &f->st.rest_gate2);
    if (f->st.rec_left > f->c.rec_n) {
        f->st.rec_left = f->c.rec_n; /* a recovery no longer than the new recovery_time (0: ended) */
    }
    return ATT_OK;
}

void att_ars_reset(att_ars_t *f)
{
    if (f == NULL) {
        return;
    }
    memset(&f->st, 0, sizeof f->st); /* the counts, steps, flags and stamps; head_known false */
    f->st.q = f->c.q_init;
    f->st.bias = f->c.bias_init;
    f->st.lp1 = att_i_vec3(0.0f, 0.0f, f->c.gravity);
    f->st.lp2 = f->st.lp1;
    f->st.rest_gate2 = f->c.bias.rest_first2;
    f->st.initialised = !f->c.init_from_accel;
}

/*
 * *q = att_quat_from_euler(phi, theta, psi) (the same operations), the result through a pointer
 * (codegen note C1, docs/architecture.md). Shared by the start and the Euler increments.
 */
static ATT_NOINLINE void att_ars_quat_from_euler(float phi, float theta, float psi, att_quat_t *q)
{
    *q = att_i_quat_from_euler(phi, theta, psi);
}

/* The attitude increment of the rotation (w - w_m) dt. */
static ATT_ALWAYS_INLINE att_quat_t att_ars_increment(const att_ars_coeffs_t *c, att_vec3_t rate)
{
    const att_vec3_t rv = att_i_vec3_scale(rate, c->dt);
    if (c->integration == (uint8_t)ATT_INTEGRATE_EULER) {
        att_quat_t q; /* the ZYX Euler quaternion of the increments (KITECH literal; out of the hot path) */
        att_ars_quat_from_euler(rv.x, rv.y, rv.z, &q);
        return q;
    }
    return att_i_quat_from_rotvec_fast(rv);
}

/*
 * The rotation *qc of the general correction (K_a < 1) for the earth-frame specific force v (or its
 * low-passed value; as scalars, the result through a pointer: codegen note C1): the fraction K_a of the
 * angle between v and z about their common horizontal axis, K_a = k / (1 + c (|a|/g - 1)^2) with
 * norm = |a| (k: c->k, or c->k_rec during a recovery).
 */
static ATT_NOINLINE void att_ars_tilt_rotation(const att_ars_coeffs_t *c, float k, float vx, float vy, float vz,
                                               float norm, att_quat_t *qc)
{
    const float axy = att_i_sqrtf(vx * vx + vy * vy);
    const float angle = att_atan2f(axy, vz);
    const float e = norm / c->gravity - 1.0f;
    const float ka = k / (1.0f + c->gain_c * e * e);
    att_vec3_t axis;
    if (axy > 0.0f) {
        axis.x = vy / axy;
        axis.y = -vx / axy;
    } else {
        axis.x = 1.0f;
        axis.y = 0.0f;
    }
    axis.z = 0.0f;
    *qc = att_i_quat_from_axis_angle(axis, ka * angle);
}

/*
 * First valid accel sample: roll and pitch from it (att_sensor_tilt: the same operations inline), yaw 0;
 * the low-pass stages start from it, and a recovery starts: the stages' running mean (the sample is its
 * first update) and the strong correction, as after a clipping gyro.
 */
static ATT_NOINLINE void att_ars_start(const att_ars_coeffs_t *c, att_ars_state_t *st, const att_vec3_t *acc)
{
    const float roll = att_atan2f(acc->y, acc->z);
    const float pitch = att_atan2f(-acc->x, att_i_sqrtf(acc->y * acc->y + acc->z * acc->z));
    att_quat_t q;
    att_ars_quat_from_euler(roll, pitch, 0.0f, &q);
    (void)att_i_quat_normalize_bounded(q, &st->q);
    st->lp1 = att_i_quat_rotate(st->q, *acc);
    st->lp2 = st->lp1;
    att_i_recovery_start(c->rec_n, &st->rec_left, &st->rec_lp_n);
    st->initialised = true;
}

/*
 * One step (att_ars_step, f not NULL; att_ars_step_out adds the output fields). The general correction
 * (K_a < 1) shares the low-pass update with the full alignment and takes only its rotation out of line.
 */
static ATT_NOINLINE uint32_t att_ars_update(att_ars_t *f, const att_vec3_t *gyr_in, const att_vec3_t *acc_in)
{
    const att_vec3_t gyr = att_i_vec3(gyr_in->x, gyr_in->y, gyr_in->z);
    const att_vec3_t acc = att_i_vec3(acc_in->x, acc_in->y, acc_in->z);
    const att_ars_coeffs_t *c;
    att_ars_state_t *st;
    uint32_t flags;
    uint32_t accel_flags;
    float n2;
    float norm = 0.0f;
    bool gyro_ok;
    bool accel_ok;
    float k;
    att_quat_t q;
    att_quat_t qn = att_i_quat_identity(); /* set by every arm that commits it (clang cannot see it) */
    att_vec3_t d;
    c = &f->c;
    st = &f->st;
    flags = att_i_sensor_check_gyro(gyr, c->gyro_range);
    gyro_ok = att_i_gyro_usable(gyr, c->gyro_range, flags);
    accel_flags = att_i_sensor_check_accel2(acc, c->accel_range2, &n2);
    accel_ok = (accel_flags == 0u);
    flags |= accel_flags;
    if (accel_ok && (!c->full || c->reject_on)) {
        norm = att_i_sqrtf(n2); /* |a| for the adaptive gain and the rejection test */
        if (c->reject_on && att_i_absf(norm / c->gravity - 1.0f) > c->accel_reject) {
            flags |= ATT_FLAG_ACCEL_REJECTED;
        }
    }

    /* rest detection and gyro bias */
    flags |= att_i_bias_step(&c->bias, &st->bias, &st->bias_n, &st->rest_count, &st->rest_gate2, gyr, gyro_ok,
                             accel_ok, n2, &d);

    if (!st->initialised) {
        if (accel_ok) {
            att_ars_start(c, st, acc_in);
            st->acc_step = st->steps;
            flags |= ATT_FLAG_INITIALISED;
        } else {
            flags |= ATT_FLAG_NOT_READY;
        }
        st->steps = st->steps + 1u;
        st->flags = flags;
        return flags;
    }

    /* the recovery after a clipping gyro */
    (void)att_i_recovery_step(gyr, c->clip, c->rec_n, &st->rec_left, &st->rec_lp_n);
    k = c->k;
    if (st->rec_left > 0u) {
        flags |= ATT_FLAG_INITIALISED;
        k = c->k_rec;
        if (st->rec_left == c->rec_n) {
            st->head_known = false; /* a clipping sample: the heading lost rotation too (covariance, step 5) */
        }
    }

    q = st->q;
    if (gyro_ok) {
        if ((flags & ATT_FLAG_BIAS_UPDATED) != 0u) {
            d = att_i_vec3_sub(gyr, st->bias);
        }
        q = att_i_quat_mul(q, att_ars_increment(c, d));
    }
    if (accel_ok && (flags & ATT_FLAG_ACCEL_REJECTED) == 0u) {
        const att_vec3_t v = att_i_quat_rotate(q, acc);
        att_vec3_t lp1 = st->lp1;
        att_vec3_t lp2 = st->lp2;
        att_vec3_t u = v;
        if (c->lp_on) {
            float k2 = c->k_lp;
            const float k1 = (st->rec_left > 0u) ? att_i_recovery_lp_gain2(&st->rec_lp_n, k2, &k2) : k2;
            att_i_lowpass2(v, k1, k2, &lp1, &lp2);
            u = lp2;
        }
        bool ok;
        if (c->full) {
            float qw;
            float qx;
            float qy;
            float n;
            /* full alignment of u with z; lp2 becomes (0, 0, |lp2|), lp1 is rotated with q */
            ok = att_i_align_up(u, &qw, &qx, &qy, &n) &&
                 att_i_quat_normalize_bounded(att_i_quat_mul_hz(qw, qx, qy, q), &qn);
            if (ok && c->lp_on) {
                lp1 = att_i_quat_rotate_hz(qw, qx, qy, lp1);
                lp2 = att_i_vec3(0.0f, 0.0f, n);
            }
        } else {
            att_quat_t qc;
            att_ars_tilt_rotation(c, k, u.x, u.y, u.z, norm, &qc);
            if (c->lp_on) {
                lp1 = att_i_quat_rotate(qc, lp1);
                lp2 = att_i_quat_rotate(qc, lp2);
            }
            ok = att_i_quat_normalize_bounded(att_i_quat_mul(qc, q), &qn);
        }
        if (ok) {
            st->q = qn;
            st->acc_step = st->steps;
            st->lp1 = lp1;
            st->lp2 = lp2;
        } else {
            flags |= ATT_FLAG_NUMERIC; /* keep the attitude and the low-pass states from before */
        }
    } else if (att_i_quat_normalize_bounded(q, &qn)) {
        st->q = qn;
    } else {
        flags |= ATT_FLAG_NUMERIC; /* keep the attitude from before the step */
    }
    st->steps = st->steps + 1u;
    st->flags = flags;
    return flags;
}

uint32_t att_ars_step(att_ars_t *f, att_vec3_t gyr, att_vec3_t acc)
{
    if (f == NULL) {
        return ATT_FLAG_BAD_ARG;
    }
    return att_ars_update(f, &gyr, &acc);
}

uint32_t att_ars_step_out(att_ars_t *restrict f, const att_sample_t *restrict in, att_output_t *restrict out)
{
    const uint32_t flags = att_ars_update(f, &in->gyr, &in->acc);
    if (out != NULL) {
        out->q = f->st.q;
        out->gyro_bias = f->st.bias;
        out->flags = flags;
        out->steps = f->st.steps;
        out->valid = ATT_OUT_Q | ATT_OUT_BIAS;
    }
    return flags;
}

/* --- hooks of the kind table (att_kinds.h) ------------------------------------------------- */

void att_ars_preset(att_ars_settings_t *s, att_preset_t preset, float dt)
{
    att_ars_settings_default(s, dt);
    if (preset == ATT_PRESET_SEED) {
        s->gain = 0.1f;
        s->tau = 0.0f;
        s->gain_c = 100.0f;
        s->tau_acc_lp = 0.0f;
        s->recovery_time = 0.0f;
    }
}

float att_ars_period(const att_ars_settings_t *s)
{
    return s->dt;
}

/* The covariance (att_ars.h, step 5): tilt about earth x and y, heading about z, rad^2. */
static void att_ars_cov(const att_ars_t *f, float cov[4])
{
    const att_ars_coeffs_t *c = &f->c;
    const att_ars_state_t *st = &f->st;
    const float tilt = att_i_cov_tilt_now(c->var_tilt, c->var_tilt_rec, c->var_step, st->rec_left, c->rec_n,
                                          st->steps, st->acc_step, st->initialised);
    float yaw = ATT_COV_UNKNOWN;
    if (st->head_known) {
        yaw = att_i_cov_grow(0.0f, c->var_step, st->steps + 1u, st->head_step, ATT_COV_UNKNOWN);
    }
    cov[0] = tilt;
    cov[1] = tilt;
    cov[2] = yaw;
    cov[3] = 0.0f;
}

void att_ars_output(const att_ars_t *f, att_output_t *out)
{
    out->q = f->st.q;
    out->gyro_bias = f->st.bias;
    out->flags = f->st.flags;
    out->steps = f->st.steps;
    out->valid = ATT_OUT_Q | ATT_OUT_BIAS;
    att_ars_cov(f, out->cov);
}

att_heading_t att_ars_heading_kind(const att_ars_t *f)
{
    (void)f;
    return ATT_HEADING_UPDATE;
}

att_status_t att_ars_yaw_to(att_ars_t *f, float target, float gain)
{
    float s;
    float c;
    const att_status_t st = att_yaw_q(&f->st.q, &f->st.lp1, &f->st.lp2, f->st.initialised, target, gain, &s, &c);
    if (st == ATT_OK && gain == 1.0f) {
        f->st.head_known = true; /* the covariance's heading: known from here (att_ars.h, step 5) */
        f->st.head_step = f->st.steps;
    }
    return st;
}

bool att_ars_set_gain(att_ars_settings_t *s, att_gain_t gain, float value)
{
    if (gain != ATT_GAIN_TAU_ACC) {
        return false;
    }
    s->tau = value;
    s->gain = att_i_gain_for_tau(value);
    return true;
}
