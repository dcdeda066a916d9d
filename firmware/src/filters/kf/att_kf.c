/**
 * @file att_kf.c
 * @brief Linear quaternion Kalman filter (see att_kf.h). Mirrored by host/attica/reference/kf.py.
 */
#include "../../math/att_fp.h"

#include "../../core/att_core.h"
#include "../att_kinds.h"
#include "../att_yaw.h"
#include "att_kf_checks.h"
#include "attica/att_kf.h"
#include "attica/att_math.h"
#include "attica/att_sensor.h"

#define ATT_KF_P_MAX_F 1000000.0f

void att_kf_settings_default(att_kf_settings_t *settings, float dt)
{
    if (settings == NULL) {
        return;
    }
    settings->dt = dt;
    settings->q_noise = 1e-3f; /* with r_noise: a 0.1 s time constant after the 1.5 s low-pass */
    settings->r_noise = 1e-5f;
    settings->r_accel = 0.0f;
    settings->gate = 0.0f;
    settings->p0 = 1.0f;
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
    settings->tau_acc_lp = 1.5f;
    settings->recovery_time = 2.0f;
    settings->init_from_accel = true;
    settings->q_init = att_i_quat_identity();
    settings->noise_rates = true;
}

att_status_t att_kf_settings_validate(const att_kf_settings_t *s)
{
    bool ok;
    if (s == NULL) {
        return ATT_ERR_NULL;
    }
    ok = true ATT_KF_CHECKS(ATT_CHECK_AND);
    return ok ? ATT_OK : ATT_ERR_SETTINGS;
}

/*
 * The coefficients of the recovery after a clipping gyro (att_kf.h, step 5); after r_step.
 * k^2 r / (1 - k) is the process noise whose steady-state Kalman gain is k (at most ATT_KF_P_MAX).
 */
static void att_kf_rec_coeffs(att_kf_coeffs_t *c, const att_kf_settings_t *s)
{
    const float k = att_i_recovery_params(s->recovery_time, s->gyro_range, s->dt, &c->rec_n, &c->clip);
    c->q_rec = (c->rec_n > 0u) ? att_i_recovery_q(k, c->r_step, ATT_KF_P_MAX_F) : 0.0f;
}

static void att_kf_coeffs(att_kf_coeffs_t *c, const att_kf_settings_t *s)
{
    c->dt = s->dt;
    c->half_dt = s->dt * 0.5f;
    c->q_step = s->noise_rates ? s->q_noise * s->dt : s->q_noise;
    c->r_step = s->noise_rates ? s->r_noise / s->dt : s->r_noise;
    c->r_accel = s->r_accel;
    c->gate = s->gate;
    c->soft = s->gate * 0.25f;
    c->p0 = s->p0;
    c->gravity = s->gravity;
    c->accel_reject = s->accel_reject;
    c->accel_range2 = s->accel_range * s->accel_range;
    c->gyro_range = s->gyro_range;
    c->k_lp = (s->tau_acc_lp > 0.0f) ? s->dt / (s->tau_acc_lp + s->dt) : 0.0f;
    att_i_bias_params(&c->bias, s->bias_mode, s->bias_n_max, s->rest_gyro, s->rest_accel,
                      att_sensor_samples(s->rest_time, s->dt), s->gravity);
    (void)att_i_quat_normalize(s->q_init, &c->q_init);
    c->bias_init = (s->bias_mode == ATT_BIAS_OFF) ? att_i_vec3(0.0f, 0.0f, 0.0f) : s->bias_init;
    c->init_from_accel = s->init_from_accel;
    c->lp_on = c->k_lp > 0.0f;
    c->need_norm = s->r_accel > 0.0f || s->accel_reject > 0.0f;
    att_kf_rec_coeffs(c, s);
}

att_status_t att_kf_init(att_kf_t *f, const att_kf_settings_t *settings)
{
    att_status_t st;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    st = att_kf_settings_validate(settings);
    if (st != ATT_OK) {
        return st;
    }
    att_kf_coeffs(&f->c, settings);
    att_kf_reset(f);
    return ATT_OK;
}

att_status_t att_kf_retune(att_kf_t *f, const att_kf_settings_t *settings)
{
    att_status_t st;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    st = att_kf_settings_validate(settings);
    if (st != ATT_OK) {
        return st;
    }
    att_kf_coeffs(&f->c, settings);
    att_i_bias_retune(&f->c.bias, f->c.bias_init, &f->st.bias, &f->st.bias_n, &f->st.rest_count,
                      &f->st.rest_gate2);
    if (f->st.rec_left > f->c.rec_n) {
        f->st.rec_left = f->c.rec_n; /* a recovery no longer than the new recovery_time (0: ended) */
    }
    return ATT_OK;
}

void att_kf_reset(att_kf_t *f)
{
    if (f == NULL) {
        return;
    }
    f->st.q = f->c.q_init;
    f->st.p = f->c.p0;
    f->st.bias = f->c.bias_init;
    f->st.lp1 = att_i_vec3(0.0f, 0.0f, f->c.gravity);
    f->st.lp2 = f->st.lp1;
    f->st.bias_n = 0u;
    f->st.rest_count = 0u;
    f->st.rest_gate2 = f->c.bias.rest_first2;
    f->st.steps = 0u;
    f->st.flags = 0u;
    f->st.rec_left = 0u;
    f->st.rec_lp_n = 0u;
    f->st.initialised = !f->c.init_from_accel;
}

/*
 * First valid accel sample: roll and pitch from it, yaw 0; the low-pass stages start from it, and a
 * recovery starts: the stages' running mean (the sample is its first update) and the recovery noise.
 */
static ATT_NOINLINE void att_kf_start(const att_kf_coeffs_t *c, att_kf_state_t *st, const att_vec3_t *acc)
{
    const att_vec3_t t = att_sensor_tilt(*acc);
    (void)att_i_quat_normalize_bounded(att_quat_from_euler(t.x, t.y, 0.0f), &st->q);
    st->lp1 = att_i_quat_rotate(st->q, *acc);
    st->lp2 = st->lp1;
    att_i_recovery_start(c->rec_n, &st->rec_left, &st->rec_lp_n);
    st->initialised = true;
}

static ATT_NOINLINE uint32_t att_kf_update(att_kf_t *f, const att_vec3_t *gyr_in, const att_vec3_t *acc_in)
{
    const att_vec3_t gyr = att_i_vec3(gyr_in->x, gyr_in->y, gyr_in->z);
    const att_vec3_t acc = att_i_vec3(acc_in->x, acc_in->y, acc_in->z);
    const att_kf_coeffs_t *c;
    att_kf_state_t *st;
    uint32_t flags;
    uint32_t accel_flags;
    float n2;
    float e2 = 0.0f;
    float p;
    bool gyro_ok;
    bool accel_ok;
    bool rec;
    att_quat_t x;
    att_quat_t xn;
    att_vec3_t d;
    if (f == NULL) {
        return ATT_FLAG_BAD_ARG;
    }
    c = &f->c;
    st = &f->st;
    flags = att_i_sensor_check_gyro(gyr, c->gyro_range);
    gyro_ok = att_i_gyro_usable(gyr, c->gyro_range, flags);
    accel_flags = att_i_sensor_check_accel2(acc, c->accel_range2, &n2);
    accel_ok = (accel_flags == 0u);
    flags |= accel_flags;
    if (accel_ok && c->need_norm) {
        const float e = att_i_sqrtf(n2) / c->gravity - 1.0f;
        e2 = e * e;
        if (c->accel_reject > 0.0f && att_i_absf(e) > c->accel_reject) {
            flags |= ATT_FLAG_ACCEL_REJECTED;
        }
    }
    flags |= att_i_bias_step(&c->bias, &st->bias, &st->bias_n, &st->rest_count, &st->rest_gate2, gyr, gyro_ok,
                             accel_ok, n2, &d);

    if (!st->initialised) {
        if (accel_ok) {
            att_kf_start(c, st, acc_in);
            flags |= ATT_FLAG_INITIALISED;
        } else {
            flags |= ATT_FLAG_NOT_READY;
        }
        st->steps = st->steps + 1u;
        st->flags = flags;
        return flags;
    }

    /* the recovery after a clipping gyro (step 5) */
    (void)att_i_recovery_step(gyr, c->clip, c->rec_n, &st->rec_left, &st->rec_lp_n);
    rec = st->rec_left > 0u;
    if (rec) {
        flags |= ATT_FLAG_INITIALISED;
    }

    /* prediction x := A x, p := p |A|^2 + q with A = I + dt/2 Omega(w - b) */
    x = st->q;
    p = st->p + c->q_step;
    if (gyro_ok) {
        att_vec3_t h;
        att_quat_t dx;
        if ((flags & ATT_FLAG_BIAS_UPDATED) != 0u) {
            d = att_i_vec3_sub(gyr, st->bias);
        }
        h = att_i_vec3_scale(d, c->half_dt);
        dx = att_i_quat_mul(x, att_i_quat(0.0f, h.x, h.y, h.z));
        x = att_i_quat(x.w + dx.w, x.x + dx.x, x.y + dx.y, x.z + dx.z);
        p = st->p * (1.0f + att_i_vec3_dot(h, h)) + c->q_step;
    }
    if (rec) {
        p = p + c->q_rec;
    }

    /* measurement: the prediction with its tilt aligned to the low-passed gravity */
    if (accel_ok && (flags & ATT_FLAG_ACCEL_REJECTED) == 0u) {
        att_vec3_t lp1 = st->lp1;
        att_vec3_t lp2 = st->lp2;
        att_vec3_t u = att_i_quat_rotate(x, acc);
        float cw;
        float cx;
        float cy;
        float n;
        if (c->lp_on) {
            float k2 = c->k_lp;
            const float k1 = rec ? att_i_recovery_lp_gain2(&st->rec_lp_n, c->k_lp, &k2) : c->k_lp;
            att_i_lowpass2(u, k1, k2, &lp1, &lp2);
            u = lp2;
        }
        if (att_i_align_up(u, &cw, &cx, &cy, &n)) {
            const float x2 = x.w * x.w + x.x * x.x + x.y * x.y + x.z * x.z;
            const float y2 = (2.0f * (1.0f - cw)) * x2; /* |z - x|^2 */
            float r = c->r_step * (1.0f + c->r_accel * e2);
            float s = p + r;
            const bool gate_on = c->gate > 0.0f && !rec; /* off during a recovery */
            if (gate_on && y2 > c->gate * s) {
                flags |= ATT_FLAG_ACCEL_REJECTED; /* outside the chi-square gate: not applied */
            } else {
                float k;
                float kw;
                float kx;
                float ky;
                att_quat_t qk;
                if (gate_on && y2 > c->soft * s) {
                    r = y2 / c->soft - p; /* the soft limit: d^2 = gate / 4 */
                    s = p + r;
                }
                k = p / s;
                kw = (1.0f - k) + k * cw;
                kx = k * cx;
                ky = k * cy;
                x = att_i_quat_mul_hz(kw, kx, ky, x);
                p = r * k;
                if (c->lp_on && att_i_quat_normalize_bounded(att_i_quat(kw, kx, ky, 0.0f), &qk)) {
                    st->lp1 = att_i_quat_rotate_hz(qk.w, qk.x, qk.y, lp1);
                    st->lp2 = att_i_quat_rotate_hz(qk.w, qk.x, qk.y, lp2);
                }
            }
        }
    }

    /* normalisation x := x / |x|, p := p / |x|^2 */
    if (att_i_quat_normalize_bounded(x, &xn)) {
        p = p / (x.w * x.w + x.x * x.x + x.y * x.y + x.z * x.z);
        if (p > ATT_KF_P_MAX_F) {
            p = ATT_KF_P_MAX_F;
            flags |= ATT_FLAG_CLAMPED;
        }
        st->q = xn;
        st->p = p;
    } else {
        flags |= ATT_FLAG_NUMERIC; /* keep the state from before the step */
    }
    st->steps = st->steps + 1u;
    st->flags = flags;
    return flags;
}

uint32_t att_kf_step_out(att_kf_t *restrict f, const att_sample_t *restrict in, att_output_t *restrict out)
{
    const uint32_t flags = att_kf_update(f, &in->gyr, &in->acc);
    if (out != NULL) {
        out->q = f->st.q;
        out->gyro_bias = f->st.bias;
        out->flags = flags;
        out->steps = f->st.steps;
        out->valid = ATT_OUT_Q | ATT_OUT_BIAS;
    }
    return flags;
}

uint32_t att_kf_step(att_kf_t *f, att_vec3_t gyr, att_vec3_t acc)
{
    return att_kf_update(f, &gyr, &acc);
}

/* --- hooks of the kind table (att_kinds.h) ------------------------------------------------- */

void att_kf_preset(att_kf_settings_t *s, att_preset_t preset, float dt)
{
    att_kf_settings_default(s, dt);
    if (preset == ATT_PRESET_SEED) {
        s->q_noise = 1e-4f;
        s->r_noise = 10.0f;
        s->r_accel = 0.0f;
        s->gate = 0.0f;
        s->accel_reject = 0.1f;
        s->noise_rates = false;
        s->tau_acc_lp = 0.0f;
        s->bias_mode = ATT_BIAS_OFF;
        s->recovery_time = 0.0f;
    }
}

float att_kf_period(const att_kf_settings_t *s)
{
    return s->dt;
}

void att_kf_output(const att_kf_t *f, att_output_t *out)
{
    out->q = f->st.q;
    out->gyro_bias = f->st.bias;
    out->flags = f->st.flags;
    out->steps = f->st.steps;
    out->valid = ATT_OUT_Q | ATT_OUT_BIAS;
    out->cov[0] = f->st.p; /* P = p I */
    out->cov[1] = f->st.p;
    out->cov[2] = f->st.p;
    out->cov[3] = f->st.p;
}

att_heading_t att_kf_heading_kind(const att_kf_t *f)
{
    (void)f;
    return ATT_HEADING_UPDATE;
}

att_status_t att_kf_yaw_to(att_kf_t *f, float target, float gain)
{
    float s;
    float c;
    return att_yaw_q(&f->st.q, &f->st.lp1, &f->st.lp2, f->st.initialised, target, gain, &s, &c);
}

bool att_kf_set_gain(att_kf_settings_t *s, att_gain_t gain, float value)
{
    if (gain != ATT_GAIN_KF_R) {
        return false;
    }
    s->r_noise = value;
    return true;
}
