/**
 * @file att_ars.c
 * @brief Quaternion complementary ARS (see att_ars.h). Mirrored by host/attica/reference/ars.py.
 */
#include "att_fp.h"

#include "att_core.h"
#include "att_step.h"
#include "attica/att_ars.h"
#include "attica/att_math.h"
#include "attica/att_sensor.h"

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
}

att_status_t att_ars_settings_validate(const att_ars_settings_t *s)
{
    bool ok;
    if (s == NULL) {
        return ATT_ERR_NULL;
    }
    ok = att_i_in(s->dt, ATT_DT_MIN, ATT_DT_MAX) && att_i_in(s->gain, 0.0f, 1.0f) &&
         att_i_in(s->tau, 0.0f, ATT_TAU_MAX) && !(s->tau > 0.0f && s->gain != 0.0f) &&
         att_i_in(s->gain_c, 0.0f, ATT_GAIN_C_MAX) && att_i_in(s->gravity, ATT_GRAVITY_MIN, ATT_GRAVITY_MAX) &&
         att_i_in(s->accel_reject, 0.0f, ATT_REJECT_MAX) && s->accel_range > s->gravity &&
         s->accel_range <= ATT_ACCEL_RANGE_MAX && s->gyro_range > 0.0f && s->gyro_range <= ATT_GYRO_RANGE_MAX &&
         att_i_bias_settings_ok(s->bias_mode, s->bias_n_max, s->bias_init, s->gyro_range, s->rest_gyro,
                                s->rest_accel, s->rest_time, s->gravity) &&
         (s->integration == ATT_INTEGRATE_ROTVEC || s->integration == ATT_INTEGRATE_EULER) &&
         att_i_bool_ok(&s->init_from_accel) && att_i_quat_init_ok(s->q_init) &&
         att_i_in(s->tau_acc_lp, 0.0f, ATT_TAU_MAX);
    return ok ? ATT_OK : ATT_ERR_SETTINGS;
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
    att_i_bias_retune(&f->c.bias, f->c.bias_init, &f->st.bias, &f->st.bias_n, &f->st.rest_count);
    return ATT_OK;
}

void att_ars_reset(att_ars_t *f)
{
    if (f == NULL) {
        return;
    }
    f->st.q = f->c.q_init;
    f->st.bias = f->c.bias_init;
    f->st.lp1 = att_i_vec3(0.0f, 0.0f, f->c.gravity);
    f->st.lp2 = f->st.lp1;
    f->st.bias_n = 0u;
    f->st.rest_count = 0u;
    f->st.steps = 0u;
    f->st.flags = 0u;
    f->st.initialised = !f->c.init_from_accel;
}

/* The ZYX Euler quaternion of the increments (KITECH literal; out of the hot path). */
static ATT_NOINLINE att_quat_t att_ars_increment_euler(att_vec3_t rv)
{
    return att_quat_from_euler(rv.x, rv.y, rv.z);
}

/* The attitude increment of the rotation (w - w_m) dt. */
static ATT_ALWAYS_INLINE att_quat_t att_ars_increment(const att_ars_coeffs_t *c, att_vec3_t rate)
{
    const att_vec3_t rv = att_i_vec3_scale(rate, c->dt);
    if (c->integration == (uint8_t)ATT_INTEGRATE_EULER) {
        return att_ars_increment_euler(rv);
    }
    return att_i_quat_from_rotvec_fast(rv);
}

/* The corrected attitude and low-pass stages (the general correction returns them by value). */
typedef struct {
    att_quat_t q;
    att_vec3_t lp1;
    att_vec3_t lp2;
} att_ars_corr_t;

/*
 * General correction (K_a < 1) of q with the earth-frame specific force v: the low-pass stages of st
 * are updated with v (when on), then q is rotated by the fraction K_a of the angle between the
 * low-passed vector (or v) and z about their common horizontal axis, and the stages with it. st is
 * not changed: the caller commits the result.
 */
static ATT_NOINLINE att_ars_corr_t att_ars_correct_partial(const att_ars_coeffs_t *c, const att_ars_state_t *st,
                                                           const att_quat_t *qp, att_vec3_t v, float norm)
{
    const att_quat_t q = *qp;
    float axy;
    float angle;
    float e;
    float ka;
    att_vec3_t axis;
    att_quat_t qc;
    att_ars_corr_t r;
    r.lp1 = st->lp1;
    r.lp2 = st->lp2;
    if (c->lp_on) {
        att_i_lowpass2(v, c->k_lp, &r.lp1, &r.lp2);
        v = r.lp2;
    }
    axy = att_i_sqrtf(v.x * v.x + v.y * v.y);
    angle = att_atan2f(axy, v.z);
    e = norm / c->gravity - 1.0f;
    ka = c->k / (1.0f + c->gain_c * e * e);
    if (axy > 0.0f) {
        axis.x = v.y / axy;
        axis.y = -v.x / axy;
    } else {
        axis.x = 1.0f;
        axis.y = 0.0f;
    }
    axis.z = 0.0f;
    qc = att_quat_from_axis_angle(axis, ka * angle);
    if (c->lp_on) {
        r.lp1 = att_i_quat_rotate(qc, r.lp1);
        r.lp2 = att_i_quat_rotate(qc, r.lp2);
    }
    r.q = att_i_quat_mul(qc, q);
    return r;
}

/* First valid accel sample: roll and pitch from it, yaw 0; the low-pass stages start from it. */
static ATT_NOINLINE void att_ars_start(att_ars_state_t *st, const att_vec3_t *acc)
{
    const att_vec3_t t = att_sensor_tilt(*acc);
    (void)att_i_quat_normalize_bounded(att_quat_from_euler(t.x, t.y, 0.0f), &st->q);
    st->lp1 = att_i_quat_rotate(st->q, *acc);
    st->lp2 = st->lp1;
    st->initialised = true;
}

static ATT_ALWAYS_INLINE uint32_t att_ars_update(att_ars_t *f, const att_vec3_t *gyr_in, const att_vec3_t *acc_in)
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
    att_quat_t q;
    att_quat_t qn;
    att_vec3_t d;
    if (f == NULL) {
        return ATT_FLAG_BAD_ARG;
    }
    c = &f->c;
    st = &f->st;
    flags = att_i_sensor_check_gyro(gyr, c->gyro_range);
    gyro_ok = (flags == 0u);
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
    flags |= att_i_bias_step(&c->bias, &st->bias, &st->bias_n, &st->rest_count, gyr, gyro_ok, accel_ok, n2, &d);

    if (!st->initialised) {
        if (accel_ok) {
            att_ars_start(st, acc_in);
            flags |= ATT_FLAG_INITIALISED;
        } else {
            flags |= ATT_FLAG_NOT_READY;
        }
        st->steps = st->steps + 1u;
        st->flags = flags;
        return flags;
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
        if (c->full) {
            att_vec3_t lp1 = st->lp1;
            att_vec3_t lp2 = st->lp2;
            att_vec3_t u = v;
            float qw;
            float qx;
            float qy;
            float n;
            if (c->lp_on) {
                att_i_lowpass2(v, c->k_lp, &lp1, &lp2);
                u = lp2;
            }
            /* full alignment of u with z; lp2 becomes (0, 0, |lp2|), lp1 is rotated with q */
            if (att_i_align_up(u, &qw, &qx, &qy, &n) &&
                att_i_quat_normalize_bounded(att_i_quat_mul_hz(qw, qx, qy, q), &qn)) {
                st->q = qn;
                if (c->lp_on) {
                    st->lp1 = att_i_quat_rotate_hz(qw, qx, qy, lp1);
                    st->lp2 = att_i_vec3(0.0f, 0.0f, n);
                }
            } else {
                flags |= ATT_FLAG_NUMERIC; /* keep the attitude and the low-pass states from before */
            }
        } else {
            const att_ars_corr_t r = att_ars_correct_partial(c, st, &q, v, norm);
            if (att_i_quat_normalize_bounded(r.q, &qn)) {
                st->q = qn;
                st->lp1 = r.lp1;
                st->lp2 = r.lp2;
            } else {
                flags |= ATT_FLAG_NUMERIC; /* keep the attitude and the low-pass states from before */
            }
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
    att_sample_t in;
    in.gyr = gyr;
    in.acc = acc;
    in.mag = att_i_vec3(0.0f, 0.0f, 0.0f);
    return att_ars_step_out(f, &in, NULL);
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
