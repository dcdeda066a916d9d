/**
 * @file att_filter.c
 * @brief Dispatch of the unified filter interface (see att_filter.h). Mirrored by reference/filter.py.
 */
#include "att_fp.h"

#include "attica/att_filter.h"
#include "attica/att_math.h"

att_status_t att_filter_settings_default(att_filter_kind_t kind, float dt, att_filter_settings_t *settings)
{
    if (settings == NULL) {
        return ATT_ERR_NULL;
    }
    switch (kind) {
    case ATT_FILTER_ARS:
        att_ars_settings_default(&settings->ars, dt);
        return ATT_OK;
    case ATT_FILTER_MARS:
        att_mars_settings_default(&settings->mars, dt);
        return ATT_OK;
    case ATT_FILTER_KF:
        att_kf_settings_default(&settings->kf, dt);
        return ATT_OK;
    case ATT_FILTER_EKF:
        att_ekf_settings_default(&settings->ekf, dt);
        return ATT_OK;
    case ATT_FILTER_GYRO:
        att_gyro_settings_default(&settings->gyro, dt);
        return ATT_OK;
    case ATT_FILTER_TILT:
        att_tilt_settings_default(&settings->tilt);
        return ATT_OK;
    default:
        return ATT_ERR_KIND;
    }
}

att_status_t att_filter_settings_preset(att_filter_kind_t kind, att_preset_t preset, float dt,
                                        att_filter_settings_t *settings)
{
    att_status_t st;
    if (preset != ATT_PRESET_DEFAULT && preset != ATT_PRESET_SEED) {
        return ATT_ERR_KIND;
    }
    st = att_filter_settings_default(kind, dt, settings);
    if (st != ATT_OK || preset == ATT_PRESET_DEFAULT) {
        return st;
    }
    switch (kind) {
    case ATT_FILTER_ARS:
        settings->ars.gain = 0.1f;
        settings->ars.tau = 0.0f;
        settings->ars.gain_c = 100.0f;
        settings->ars.tau_acc_lp = 0.0f;
        break;
    case ATT_FILTER_MARS:
        settings->mars.alpha_acc = 0.02f;
        settings->mars.alpha_mag = 0.01f;
        settings->mars.tau_acc = 0.0f;
        settings->mars.tau_mag = 0.0f;
        settings->mars.accel_reject = 0.1f;
        settings->mars.mag_norm_reject = 0.2f;
        settings->mars.mag_dip_reject = 0.17f;
        settings->mars.integration = ATT_INTEGRATE_FIRST_ORDER;
        settings->mars.tau_acc_lp = 0.0f;
        settings->mars.bias_mode = ATT_BIAS_FROZEN;
        break;
    case ATT_FILTER_KF:
        settings->kf.q_noise = 1e-4f;
        settings->kf.r_noise = 10.0f;
        settings->kf.accel_reject = 0.1f;
        settings->kf.noise_rates = false;
        break;
    case ATT_FILTER_EKF:
        settings->ekf.q_phi = 0.0001f;
        settings->ekf.q_theta = 0.0001f;
        settings->ekf.q_psi = 0.1f;
        settings->ekf.r_phi = 6.0f;
        settings->ekf.r_theta = 6.0f;
        settings->ekf.accel_reject = 0.1f;
        settings->ekf.noise_rates = false;
        break;
    default:
        break; /* gyro, tilt: nothing was tuned */
    }
    return ATT_OK;
}

att_status_t att_filter_init(att_filter_t *f, att_filter_kind_t kind, const att_filter_settings_t *settings)
{
    att_filter_state_t u;
    att_status_t st;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    switch (kind) {
    case ATT_FILTER_ARS:
        st = att_ars_init(&u.ars, &settings->ars);
        break;
    case ATT_FILTER_MARS:
        st = att_mars_init(&u.mars, &settings->mars);
        break;
    case ATT_FILTER_KF:
        st = att_kf_init(&u.kf, &settings->kf);
        break;
    case ATT_FILTER_EKF:
        st = att_ekf_init(&u.ekf, &settings->ekf);
        break;
    case ATT_FILTER_GYRO:
        st = att_gyro_init(&u.gyro, &settings->gyro);
        break;
    case ATT_FILTER_TILT:
        st = att_tilt_init(&u.tilt, &settings->tilt);
        break;
    default:
        return ATT_ERR_KIND;
    }
    if (st == ATT_OK) {
        f->kind = kind;
        f->u = u;
    }
    return st;
}

void att_filter_reset(att_filter_t *f)
{
    if (f == NULL) {
        return;
    }
    switch (f->kind) {
    case ATT_FILTER_ARS:
        att_ars_reset(&f->u.ars);
        break;
    case ATT_FILTER_MARS:
        att_mars_reset(&f->u.mars);
        break;
    case ATT_FILTER_KF:
        att_kf_reset(&f->u.kf);
        break;
    case ATT_FILTER_EKF:
        att_ekf_reset(&f->u.ekf);
        break;
    case ATT_FILTER_GYRO:
        att_gyro_reset(&f->u.gyro);
        break;
    case ATT_FILTER_TILT:
        att_tilt_reset(&f->u.tilt);
        break;
    default:
        break;
    }
}

static void att_filter_clear(att_output_t *out)
{
    out->q = att_quat_identity();
    out->euler.x = 0.0f;
    out->euler.y = 0.0f;
    out->euler.z = 0.0f;
    out->gyro_bias = out->euler;
    out->cov[0] = 0.0f;
    out->cov[1] = 0.0f;
    out->cov[2] = 0.0f;
    out->cov[3] = 0.0f;
    out->flags = 0u;
    out->steps = 0u;
}

void att_filter_output(const att_filter_t *f, att_output_t *out)
{
    if (out == NULL) {
        return;
    }
    att_filter_clear(out);
    if (f == NULL) {
        out->flags = ATT_FLAG_BAD_ARG;
        return;
    }
    switch (f->kind) {
    case ATT_FILTER_ARS:
        out->q = f->u.ars.q;
        out->euler = att_quat_to_euler(f->u.ars.q);
        out->gyro_bias = f->u.ars.bias;
        out->flags = f->u.ars.flags;
        out->steps = f->u.ars.steps;
        break;
    case ATT_FILTER_MARS:
        out->q = f->u.mars.q;
        out->euler = att_quat_to_euler(f->u.mars.q);
        out->gyro_bias = f->u.mars.bias;
        out->flags = f->u.mars.flags;
        out->steps = f->u.mars.steps;
        break;
    case ATT_FILTER_KF:
        out->q = f->u.kf.q;
        out->euler = att_quat_to_euler(f->u.kf.q);
        out->cov[0] = f->u.kf.p[0][0];
        out->cov[1] = f->u.kf.p[1][1];
        out->cov[2] = f->u.kf.p[2][2];
        out->cov[3] = f->u.kf.p[3][3];
        out->flags = f->u.kf.flags;
        out->steps = f->u.kf.steps;
        break;
    case ATT_FILTER_EKF:
        out->q = f->u.ekf.q;
        out->euler = f->u.ekf.euler;
        out->cov[0] = f->u.ekf.p[0][0];
        out->cov[1] = f->u.ekf.p[1][1];
        out->cov[2] = f->u.ekf.p[2][2];
        out->flags = f->u.ekf.flags;
        out->steps = f->u.ekf.steps;
        break;
    case ATT_FILTER_GYRO:
        out->q = f->u.gyro.q;
        out->euler = f->u.gyro.euler;
        out->flags = f->u.gyro.flags;
        out->steps = f->u.gyro.steps;
        break;
    case ATT_FILTER_TILT:
        out->q = f->u.tilt.q;
        out->euler = f->u.tilt.euler;
        out->flags = f->u.tilt.flags;
        out->steps = f->u.tilt.steps;
        break;
    default:
        out->flags = ATT_FLAG_BAD_ARG;
        break;
    }
}

uint32_t att_filter_step(att_filter_t *f, const att_sample_t *in, att_output_t *out)
{
    uint32_t flags;
    if (f == NULL || in == NULL) {
        if (out != NULL) {
            att_filter_clear(out);
            out->flags = ATT_FLAG_BAD_ARG;
        }
        return ATT_FLAG_BAD_ARG;
    }
    switch (f->kind) {
    case ATT_FILTER_ARS:
        flags = att_ars_step(&f->u.ars, in->gyr, in->acc);
        break;
    case ATT_FILTER_MARS:
        flags = att_mars_step(&f->u.mars, in->gyr, in->acc, in->mag);
        break;
    case ATT_FILTER_KF:
        flags = att_kf_step(&f->u.kf, in->gyr, in->acc);
        break;
    case ATT_FILTER_EKF:
        flags = att_ekf_step(&f->u.ekf, in->gyr, in->acc);
        break;
    case ATT_FILTER_GYRO:
        flags = att_gyro_step(&f->u.gyro, in->gyr);
        break;
    case ATT_FILTER_TILT:
        flags = att_tilt_step(&f->u.tilt, in->acc);
        break;
    default:
        flags = ATT_FLAG_BAD_ARG;
        break;
    }
    if (out != NULL) {
        att_filter_output(f, out);
        out->flags = flags;
    }
    return flags;
}

const char *att_filter_name(att_filter_kind_t kind)
{
    switch (kind) {
    case ATT_FILTER_ARS:
        return "ars";
    case ATT_FILTER_MARS:
        return "mars";
    case ATT_FILTER_KF:
        return "kf";
    case ATT_FILTER_EKF:
        return "ekf";
    case ATT_FILTER_GYRO:
        return "gyro";
    case ATT_FILTER_TILT:
        return "tilt";
    default:
        return "?";
    }
}
