/**
 * @file att_ars.c
 * @brief Quaternion complementary ARS (see att_ars.h). Mirrored by host/attica/reference/ars.py.
 */
#include "att_fp.h"

#include "attica/att_ars.h"
#include "attica/att_math.h"
#include "attica/att_sensor.h"

#define ATT_BIAS_N_MAX_LIMIT 16777216u /* 2^24: n converts to float exactly */

void att_ars_settings_default(att_ars_settings_t *settings, float dt)
{
    if (settings == NULL) {
        return;
    }
    settings->dt = dt;
    settings->gain = 0.1f;
    settings->tau = 0.02f;
    settings->gain_c = 0.0f;
    settings->gravity = 9.80665f;
    settings->accel_reject = 0.0f;
    settings->accel_range = 156.9064f; /* 16 g */
    settings->gyro_range = 34.906586f; /* 2000 deg/s */
    settings->bias_mode = ATT_BIAS_AT_REST;
    settings->bias_n_max = 1000u;
    settings->bias_init.x = 0.0f;
    settings->bias_init.y = 0.0f;
    settings->bias_init.z = 0.0f;
    settings->rest_gyro = 0.05f;
    settings->rest_accel = 0.5f;
    settings->rest_time = 0.5f;
    settings->integration = ATT_INTEGRATE_ROTVEC;
    settings->init_from_accel = true;
    settings->q_init = att_quat_identity();
    settings->tau_acc_lp = 1.5f;
}

static bool att_ars_settings_valid(const att_ars_settings_t *s)
{
    att_quat_t qn;
    const bool finite = att_isfinitef(s->dt) && att_isfinitef(s->gain) && att_isfinitef(s->tau) &&
                        att_isfinitef(s->gain_c) && att_isfinitef(s->gravity) &&
                        att_isfinitef(s->accel_reject) && att_isfinitef(s->rest_gyro) &&
                        att_isfinitef(s->rest_accel) && att_isfinitef(s->rest_time) &&
                        att_isfinitef(s->tau_acc_lp) &&
                        att_vec3_isfinite(s->bias_init) && att_quat_isfinite(s->q_init);
    if (!finite) {
        return false;
    }
    /* ranges may be +Inf (no limit) but not NaN */
    if (!(s->accel_range > 0.0f) || !(s->gyro_range > 0.0f)) {
        return false;
    }
    if (!(s->dt > 0.0f && s->dt <= 1.0f) || !(s->gain >= 0.0f && s->gain <= 1.0f) || !(s->tau >= 0.0f) ||
        !(s->gain_c >= 0.0f) || !(s->gravity > 0.0f) || !(s->accel_reject >= 0.0f) ||
        !(s->rest_gyro >= 0.0f) || !(s->rest_accel >= 0.0f) || !(s->rest_time >= 0.0f) ||
        !(s->tau_acc_lp >= 0.0f)) {
        return false;
    }
    if (s->bias_n_max < 1u || s->bias_n_max > ATT_BIAS_N_MAX_LIMIT) {
        return false;
    }
    if (s->bias_mode != ATT_BIAS_OFF && s->bias_mode != ATT_BIAS_FROZEN && s->bias_mode != ATT_BIAS_RUNNING &&
        s->bias_mode != ATT_BIAS_AT_REST) {
        return false;
    }
    if (s->integration != ATT_INTEGRATE_ROTVEC && s->integration != ATT_INTEGRATE_EULER) {
        return false;
    }
    return att_quat_normalize(s->q_init, &qn);
}

att_status_t att_ars_init(att_ars_t *f, const att_ars_settings_t *settings)
{
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    if (!att_ars_settings_valid(settings)) {
        return ATT_ERR_SETTINGS;
    }
    f->s = *settings;
    f->k = (settings->tau > 0.0f) ? settings->dt / (settings->tau + settings->dt) : settings->gain;
    f->rest_n = att_sensor_samples(settings->rest_time, settings->dt);
    f->k_lp = (settings->tau_acc_lp > 0.0f) ? settings->dt / (settings->tau_acc_lp + settings->dt) : 0.0f;
    att_ars_reset(f);
    return ATT_OK;
}

void att_ars_reset(att_ars_t *f)
{
    if (f == NULL) {
        return;
    }
    (void)att_quat_normalize(f->s.q_init, &f->q);
    if (f->s.bias_mode == ATT_BIAS_OFF) {
        f->bias.x = 0.0f;
        f->bias.y = 0.0f;
        f->bias.z = 0.0f;
    } else {
        f->bias = f->s.bias_init;
    }
    f->bias_n = 0u;
    f->rest_count = 0u;
    f->initialised = !f->s.init_from_accel;
    f->lp1.x = 0.0f;
    f->lp1.y = 0.0f;
    f->lp1.z = f->s.gravity;
    f->lp2 = f->lp1;
    f->steps = 0u;
    f->flags = 0u;
}

static att_quat_t att_ars_increment(const att_ars_t *f, att_vec3_t rate)
{
    const att_vec3_t rv = att_vec3_scale(rate, f->s.dt);
    if (f->s.integration == ATT_INTEGRATE_EULER) {
        return att_quat_from_euler(rv.x, rv.y, rv.z);
    }
    return att_quat_from_rotvec(rv);
}

/*
 * Rotate q so that the earth-frame specific force moves toward +z by the adaptive gain. With the
 * low-pass on (k_lp > 0), the earth-frame sample first feeds two cascaded first-order low-passes
 * lp1, lp2 and the correction uses lp2; both stages are then rotated by the correction, so they stay
 * expressed in the (corrected) earth frame.
 */
static att_quat_t att_ars_correct(att_ars_t *f, att_quat_t q, att_vec3_t acc, float norm)
{
    att_vec3_t ae = att_quat_rotate(q, acc);
    float axy;
    float angle;
    float e;
    float ka;
    att_vec3_t axis;
    att_quat_t qc;
    if (f->k_lp > 0.0f) {
        f->lp1 = att_vec3_add(f->lp1, att_vec3_scale(att_vec3_sub(ae, f->lp1), f->k_lp));
        f->lp2 = att_vec3_add(f->lp2, att_vec3_scale(att_vec3_sub(f->lp1, f->lp2), f->k_lp));
        ae = f->lp2;
    }
    axy = att_sqrtf(ae.x * ae.x + ae.y * ae.y);
    angle = att_atan2f(axy, ae.z);
    e = norm / f->s.gravity - 1.0f;
    ka = f->k / (1.0f + f->s.gain_c * e * e);
    if (axy > 0.0f) {
        axis.x = ae.y / axy;
        axis.y = -ae.x / axy;
    } else {
        axis.x = 1.0f;
        axis.y = 0.0f;
    }
    axis.z = 0.0f;
    qc = att_quat_from_axis_angle(axis, ka * angle);
    if (f->k_lp > 0.0f) {
        f->lp1 = att_quat_rotate(qc, f->lp1);
        f->lp2 = att_quat_rotate(qc, f->lp2);
    }
    return att_quat_mul(qc, q);
}

uint32_t att_ars_step(att_ars_t *f, att_vec3_t gyr, att_vec3_t acc)
{
    uint32_t flags;
    uint32_t accel_flags;
    float norm;
    float e;
    bool gyro_ok;
    bool accel_ok;
    att_bias_params_t bias_params;
    att_quat_t q;
    att_quat_t qn;
    if (f == NULL) {
        return ATT_FLAG_BAD_ARG;
    }
    flags = att_sensor_check_gyro(gyr, f->s.gyro_range);
    gyro_ok = (flags == 0u);
    accel_flags = att_sensor_check_accel(acc, f->s.accel_range, &norm);
    accel_ok = (accel_flags == 0u);
    flags |= accel_flags;
    e = norm / f->s.gravity - 1.0f;
    if (accel_ok && f->s.accel_reject > 0.0f && att_absf(e) > f->s.accel_reject) {
        flags |= ATT_FLAG_ACCEL_REJECTED;
    }

    /* rest detection and gyro bias */
    bias_params.mode = f->s.bias_mode;
    bias_params.n_max = f->s.bias_n_max;
    bias_params.rest_n = f->rest_n;
    bias_params.rest_gyro = f->s.rest_gyro;
    bias_params.rest_accel = f->s.rest_accel;
    bias_params.gravity = f->s.gravity;
    flags |= att_bias_step(&bias_params, &f->bias, &f->bias_n, &f->rest_count, gyr, gyro_ok, accel_ok, norm);

    if (!f->initialised) {
        if (accel_ok) {
            const att_vec3_t t = att_sensor_tilt(acc);
            f->q = att_quat_from_euler(t.x, t.y, 0.0f);
            (void)att_quat_normalize(f->q, &f->q);
            f->lp1 = att_quat_rotate(f->q, acc);
            f->lp2 = f->lp1;
            f->initialised = true;
            flags |= ATT_FLAG_INITIALISED;
        } else {
            flags |= ATT_FLAG_NOT_READY;
        }
        f->steps = f->steps + 1u;
        f->flags = flags;
        return flags;
    }

    q = f->q;
    if (gyro_ok) {
        q = att_quat_mul(q, att_ars_increment(f, att_vec3_sub(gyr, f->bias)));
    }
    if (accel_ok && (flags & ATT_FLAG_ACCEL_REJECTED) == 0u) {
        q = att_ars_correct(f, q, acc, norm);
    }
    if (att_quat_normalize(q, &qn)) {
        f->q = qn;
    } else {
        flags |= ATT_FLAG_NUMERIC; /* keep the previous attitude */
    }
    f->steps = f->steps + 1u;
    f->flags = flags;
    return flags;
}
