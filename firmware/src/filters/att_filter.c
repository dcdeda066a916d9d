/**
 * @file att_filter.c
 * @brief Dispatch of the unified filter interface (see att_filter.h). Mirrored by reference/filter.py.
 */
#include "../math/att_fp.h"

#include "../calib/att_calib_i.h"
#include "../core/att_core.h"
#include "../math/att_inline.h"
#include "att_step.h"
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
    case ATT_FILTER_MEKF:
        att_mekf_settings_default(&settings->mekf, dt);
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
        settings->kf.r_accel = 0.0f;
        settings->kf.gate = 0.0f;
        settings->kf.accel_reject = 0.1f;
        settings->kf.noise_rates = false;
        settings->kf.tau_acc_lp = 0.0f;
        settings->kf.bias_mode = ATT_BIAS_OFF;
        break;
    case ATT_FILTER_EKF:
        settings->ekf.q_phi = 0.0001f;
        settings->ekf.q_theta = 0.0001f;
        settings->ekf.q_psi = 0.1f;
        settings->ekf.q_bias = 1e-12f; /* the notes' filter had no bias states: they stay at 0 */
        settings->ekf.p0_bias = 1e-12f;
        settings->ekf.r_phi = 6.0f;
        settings->ekf.r_theta = 6.0f;
        settings->ekf.r_accel = 0.0f;
        settings->ekf.gate = 0.0f;
        settings->ekf.accel_reject = 0.1f;
        settings->ekf.tau_acc_lp = 0.0f;
        settings->ekf.noise_rates = false;
        break;
    default:
        break; /* gyro, tilt: nothing was tuned; mekf: the defaults are its first settings */
    }
    return ATT_OK;
}

att_status_t att_filter_settings_validate(att_filter_kind_t kind, const att_filter_settings_t *settings)
{
    if (settings == NULL) {
        return ATT_ERR_NULL;
    }
    switch (kind) {
    case ATT_FILTER_ARS:
        return att_ars_settings_validate(&settings->ars);
    case ATT_FILTER_MARS:
        return att_mars_settings_validate(&settings->mars);
    case ATT_FILTER_KF:
        return att_kf_settings_validate(&settings->kf);
    case ATT_FILTER_EKF:
        return att_ekf_settings_validate(&settings->ekf);
    case ATT_FILTER_GYRO:
        return att_gyro_settings_validate(&settings->gyro);
    case ATT_FILTER_TILT:
        return att_tilt_settings_validate(&settings->tilt);
    case ATT_FILTER_MEKF:
        return att_mekf_settings_validate(&settings->mekf);
    default:
        return ATT_ERR_KIND;
    }
}

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
    case ATT_FILTER_ARS:
        st = att_ars_init(&f->u.ars, &settings->ars);
        break;
    case ATT_FILTER_MARS:
        st = att_mars_init(&f->u.mars, &settings->mars);
        break;
    case ATT_FILTER_KF:
        st = att_kf_init(&f->u.kf, &settings->kf);
        break;
    case ATT_FILTER_EKF:
        st = att_ekf_init(&f->u.ekf, &settings->ekf);
        break;
    case ATT_FILTER_GYRO:
        st = att_gyro_init(&f->u.gyro, &settings->gyro);
        break;
    case ATT_FILTER_MEKF:
        st = att_mekf_init(&f->u.mekf, &settings->mekf);
        break;
    default:
        st = att_tilt_init(&f->u.tilt, &settings->tilt);
        break;
    }
    if (st == ATT_OK) {
        att_calib_settings_t cs;
        att_calib_settings_default(&cs);
        (void)att_calib_init(&f->cal, &cs); /* the defaults are valid */
        f->kind = kind;
    }
    return st;
}

att_status_t att_filter_retune(att_filter_t *f, const att_filter_settings_t *settings)
{
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    switch (f->kind) {
    case ATT_FILTER_ARS:
        return att_ars_retune(&f->u.ars, &settings->ars);
    case ATT_FILTER_MARS:
        return att_mars_retune(&f->u.mars, &settings->mars);
    case ATT_FILTER_KF:
        return att_kf_retune(&f->u.kf, &settings->kf);
    case ATT_FILTER_EKF:
        return att_ekf_retune(&f->u.ekf, &settings->ekf);
    case ATT_FILTER_GYRO:
        return att_gyro_retune(&f->u.gyro, &settings->gyro);
    case ATT_FILTER_TILT:
        return att_tilt_retune(&f->u.tilt, &settings->tilt);
    case ATT_FILTER_MEKF:
        return att_mekf_retune(&f->u.mekf, &settings->mekf);
    default:
        return ATT_ERR_KIND;
    }
}

void att_filter_reset(att_filter_t *f)
{
    if (f == NULL) {
        return;
    }
    f->cal.have_acc = false;
    f->cal.acc_body = att_i_vec3(0.0f, 0.0f, 0.0f);
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
    case ATT_FILTER_MEKF:
        att_mekf_reset(&f->u.mekf);
        break;
    default:
        break;
    }
}

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

/* The per-step fields (see att_output_t); returns false for an uninitialised filter. */
static bool att_filter_basic(const att_filter_t *f, att_output_t *out)
{
    const att_vec3_t zero = att_i_vec3(0.0f, 0.0f, 0.0f);
    out->valid = ATT_OUT_Q | ATT_OUT_BIAS;
    switch (f->kind) {
    case ATT_FILTER_ARS:
        out->q = f->u.ars.st.q;
        out->gyro_bias = f->u.ars.st.bias;
        out->flags = f->u.ars.st.flags;
        out->steps = f->u.ars.st.steps;
        return true;
    case ATT_FILTER_MARS:
        out->q = f->u.mars.st.q;
        out->gyro_bias = f->u.mars.st.bias;
        out->flags = f->u.mars.st.flags;
        out->steps = f->u.mars.st.steps;
        return true;
    case ATT_FILTER_KF:
        out->q = f->u.kf.st.q;
        out->gyro_bias = f->u.kf.st.bias;
        out->flags = f->u.kf.st.flags;
        out->steps = f->u.kf.st.steps;
        return true;
    case ATT_FILTER_EKF:
        out->euler = f->u.ekf.st.euler; /* the state: q is derived on request */
        out->gyro_bias = f->u.ekf.st.bias;
        out->flags = f->u.ekf.st.flags;
        out->steps = f->u.ekf.st.steps;
        out->valid = ATT_OUT_EULER | ATT_OUT_BIAS;
        return true;
    case ATT_FILTER_GYRO:
        out->q = f->u.gyro.st.q;
        out->euler = f->u.gyro.st.euler;
        out->gyro_bias = zero;
        out->flags = f->u.gyro.st.flags;
        out->steps = f->u.gyro.st.steps;
        out->valid |= ATT_OUT_EULER;
        return true;
    case ATT_FILTER_TILT:
        out->q = f->u.tilt.st.q;
        out->euler = f->u.tilt.st.euler;
        out->gyro_bias = zero;
        out->flags = f->u.tilt.st.flags;
        out->steps = f->u.tilt.st.steps;
        out->valid |= ATT_OUT_EULER;
        return true;
    case ATT_FILTER_MEKF:
        out->q = f->u.mekf.st.q;
        out->gyro_bias = f->u.mekf.st.bias;
        out->flags = f->u.mekf.st.flags;
        out->steps = f->u.mekf.st.steps;
        return true;
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
    if (f == NULL || !att_filter_basic(f, out)) {
        out->flags = ATT_FLAG_BAD_ARG;
        out->valid = ATT_OUT_ALL;
        return;
    }
    if ((out->valid & ATT_OUT_Q) == 0u) {
        out->q = att_quat_from_euler(out->euler.x, out->euler.y, out->euler.z);
    }
    if ((f->cal.active & ATT_CALIB_ACTIVE_CONV) != 0u) {
        out->q = att_calib_quat_to(out->q, f->cal.convention);
        out->euler = att_quat_to_euler(out->q);
    } else if ((out->valid & ATT_OUT_EULER) == 0u) {
        out->euler = att_quat_to_euler(out->q);
    }
    if (f->kind == ATT_FILTER_KF) {
        out->cov[0] = f->u.kf.st.p; /* P = p I */
        out->cov[1] = f->u.kf.st.p;
        out->cov[2] = f->u.kf.st.p;
        out->cov[3] = f->u.kf.st.p;
    } else if (f->kind == ATT_FILTER_EKF) {
        out->cov[0] = f->u.ekf.st.p[0]; /* phi, theta, psi; then the mean bias variance */
        out->cov[1] = f->u.ekf.st.p[6];
        out->cov[2] = f->u.ekf.st.p[11];
        out->cov[3] = ((f->u.ekf.st.p[15] + f->u.ekf.st.p[18]) + f->u.ekf.st.p[20]) * 0x1.555556p-2f;
    } else if (f->kind == ATT_FILTER_MEKF) {
        const float *p = f->u.mekf.st.p; /* packed upper triangle: the diagonal at 0, 6, 11, 15, 18, 20 */
        out->cov[0] = p[0];
        out->cov[1] = p[6];
        out->cov[2] = p[11];
        out->cov[3] = (p[15] + p[18] + p[20]) / 3.0f;
    }
    out->valid = ATT_OUT_ALL;
}

/* The result of a step that was refused (f or in NULL, unknown kind): BAD_ARG, out cleared. */
static uint32_t att_filter_bad_arg(att_output_t *out)
{
    if (out != NULL) {
        att_filter_clear(out);
        out->flags = ATT_FLAG_BAD_ARG;
    }
    return ATT_FLAG_BAD_ARG;
}

/* The kinds with a step_out entry (att_step.h): a tail call each. */
#define ATT_FILTER_STEP_OUT_CASES(f, in, out)                                                                 \
    case ATT_FILTER_ARS:                                                                                     \
        return att_ars_step_out(&(f)->u.ars, (in), (out));                                                   \
    case ATT_FILTER_MARS:                                                                                    \
        return att_mars_step_out(&(f)->u.mars, (in), (out));                                                 \
    case ATT_FILTER_KF:                                                                                      \
        return att_kf_step_out(&(f)->u.kf, (in), (out));                                                     \
    case ATT_FILTER_MEKF:                                                                                    \
        return att_mekf_step_out(&(f)->u.mekf, (in), (out));                                                 \
    case ATT_FILTER_EKF:                                                                                     \
        return att_ekf_step_out(&(f)->u.ekf, (in), (out))

/* The baseline kinds (gyro, tilt): their step, then the per-step fields from the state. */
static ATT_NOINLINE uint32_t att_filter_step_basic(att_filter_t *f, const att_sample_t *in, att_output_t *out)
{
    const uint32_t flags =
        (f->kind == ATT_FILTER_GYRO) ? att_gyro_step(&f->u.gyro, in->gyr) : att_tilt_step(&f->u.tilt, in->acc);
    if (out != NULL) {
        (void)att_filter_basic(f, out);
    }
    return flags;
}

/* The kind's step on in (the sample after the input stage). */
static uint32_t att_filter_dispatch(att_filter_t *f, const att_sample_t *in, att_output_t *out)
{
    switch (f->kind) {
        ATT_FILTER_STEP_OUT_CASES(f, in, out);
    case ATT_FILTER_GYRO:
    case ATT_FILTER_TILT:
        return att_filter_step_basic(f, in, out);
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

/*
 * Everything but the fast path of att_filter_step: NULL arguments, an active stage, unknown kinds. The same arguments as att_filter_step, so that its calls here
 * are tail calls that leave the registers as they are.
 */
static ATT_NOINLINE uint32_t att_filter_step_slow(att_filter_t *f, const att_sample_t *in, att_output_t *out)
{
    if (f == NULL || in == NULL) {
        return att_filter_bad_arg(out);
    }
    if (f->cal.active != 0u) {
        return att_filter_step_cal(f, in, out);
    }
    return att_filter_dispatch(f, in, out);
}

uint32_t att_filter_step(att_filter_t *f, const att_sample_t *in, att_output_t *out)
{
    /* the fast path: no stage active (one test), a known kind: a tail call */
    if (f != NULL && in != NULL && f->cal.active == 0u) {
        switch (f->kind) {
            ATT_FILTER_STEP_OUT_CASES(f, in, out);
        case ATT_FILTER_GYRO:
        case ATT_FILTER_TILT:
            return att_filter_step_basic(f, in, out);
        default:
            break;
        }
    }
    return att_filter_step_slow(f, in, out);
}

att_status_t att_filter_calibrate(att_filter_t *f, const att_calib_settings_t *s)
{
    att_calib_t c;
    att_status_t st;
    if (f == NULL || s == NULL) {
        return ATT_ERR_NULL;
    }
    if (att_filter_name(f->kind)[0] == '?') {
        return ATT_ERR_KIND;
    }
    st = att_calib_init(&c, s);
    if (st == ATT_OK) {
        f->cal = c;
    }
    return st;
}

/* The current attitude, sensor(body)-to-ENU; false for an unknown kind. */
static bool att_filter_q_enu(const att_filter_t *f, att_quat_t *q)
{
    att_output_t o;
    if (!att_filter_basic(f, &o)) {
        return false;
    }
    *q = ((o.valid & ATT_OUT_Q) != 0u) ? o.q : att_quat_from_euler(o.euler.x, o.euler.y, o.euler.z);
    return true;
}

void att_filter_accel(const att_filter_t *f, att_accel_t *out)
{
    const att_vec3_t zero = att_i_vec3(0.0f, 0.0f, 0.0f);
    att_quat_t q;
    att_vec3_t a;
    att_vec3_t e;
    float m[9];
    float g;
    if (out == NULL) {
        return;
    }
    out->gravity = zero;
    out->linear = zero;
    out->earth = zero;
    out->valid = 0u;
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
}

#define ATT_FILTER_PIO2 0x1.921fb6p+0f
#define ATT_FILTER_HEADING_MAX 8192.0f

/* The ENU yaw (rad) that heading (rad, in the convention of f) means. */
static float att_filter_heading_enu(const att_filter_t *f, float heading)
{
    if (f->cal.convention == ATT_CONV_NED) {
        return att_wrap_pi(ATT_FILTER_PIO2 - heading);
    }
    if (f->cal.convention == ATT_CONV_NWU) {
        return att_wrap_pi(heading + ATT_FILTER_PIO2);
    }
    return att_wrap_pi(heading);
}

/* v turned by the angle with cosine c and sine s about the earth z axis. */
static att_vec3_t att_filter_turn(att_vec3_t v, float c, float s)
{
    return att_i_vec3(c * v.x - s * v.y, s * v.x + c * v.y, v.z);
}

/*
 * Turn the attitude of f about the earth vertical so that its yaw becomes target (rad, ENU), by the
 * fraction gain of the wrapped difference; the earth-frame memories turn with it. Returns the status.
 */
static att_status_t att_filter_yaw_to(att_filter_t *f, float target, float gain)
{
    att_quat_t q;
    att_vec3_t *lp1 = NULL;
    att_vec3_t *lp2 = NULL;
    att_vec3_t *euler = NULL;
    bool ready = true;
    float yaw;
    float delta;
    float hs;
    float hc;
    float s;
    float c;
    switch (f->kind) {
    case ATT_FILTER_ARS:
        lp1 = &f->u.ars.st.lp1;
        lp2 = &f->u.ars.st.lp2;
        ready = f->u.ars.st.initialised;
        break;
    case ATT_FILTER_MARS:
        lp1 = &f->u.mars.st.lp1;
        lp2 = &f->u.mars.st.lp2;
        ready = f->u.mars.st.initialised;
        break;
    case ATT_FILTER_KF:
        lp1 = &f->u.kf.st.lp1;
        lp2 = &f->u.kf.st.lp2;
        ready = f->u.kf.st.initialised;
        break;
    case ATT_FILTER_EKF:
        lp1 = &f->u.ekf.st.lp1;
        lp2 = &f->u.ekf.st.lp2;
        euler = &f->u.ekf.st.euler;
        ready = f->u.ekf.st.initialised;
        break;
    case ATT_FILTER_GYRO:
        euler = &f->u.gyro.st.euler;
        break;
    case ATT_FILTER_MEKF:
        lp1 = &f->u.mekf.st.lp1;
        lp2 = &f->u.mekf.st.lp2;
        ready = f->u.mekf.st.initialised;
        break;
    default:
        return ATT_ERR_KIND;
    }
    if (!ready) {
        return ATT_ERR_STATE;
    }
    (void)att_filter_q_enu(f, &q);
    yaw = (euler != NULL) ? euler->z
                          : att_atan2f(2.0f * (q.w * q.z + q.x * q.y), 1.0f - 2.0f * (q.y * q.y + q.z * q.z));
    delta = att_wrap_pi(target - yaw) * gain;
    if (!att_i_isfinitef(delta)) {
        return ATT_ERR_STATE; /* an Euler-state yaw outside the wrap domain */
    }
    att_i_sincosf(delta, &s, &c);
    if (lp1 != NULL) {
        *lp1 = att_filter_turn(*lp1, c, s);
        *lp2 = att_filter_turn(*lp2, c, s);
    }
    if (f->kind == ATT_FILTER_MARS) {
        f->u.mars.st.m0 = att_filter_turn(f->u.mars.st.m0, c, s);
        f->u.mars.st.m0_ref = att_filter_turn(f->u.mars.st.m0_ref, c, s);
        f->u.mars.st.m0_perp = att_filter_turn(f->u.mars.st.m0_perp, c, s);
    }
    if (f->kind == ATT_FILTER_MEKF) {
        /* the heading measurement's tilt entries (-c r_x, -c r_y) are linear in m0_ref: they turn with it */
        att_vec3_t h = att_filter_turn(att_i_vec3(f->u.mekf.st.mag_hx, f->u.mekf.st.mag_hy, 0.0f), c, s);
        f->u.mekf.st.m0 = att_filter_turn(f->u.mekf.st.m0, c, s);
        f->u.mekf.st.m0_ref = att_filter_turn(f->u.mekf.st.m0_ref, c, s);
        f->u.mekf.st.mag_hx = h.x;
        f->u.mekf.st.mag_hy = h.y;
    }
    if (euler != NULL) {
        euler->z = (gain == 1.0f) ? target : att_wrap_pi(yaw + delta);
        if (f->kind == ATT_FILTER_GYRO) {
            f->u.gyro.st.q = att_quat_from_euler(euler->x, euler->y, euler->z);
        }
        return ATT_OK;
    }
    att_i_sincosf(delta * 0.5f, &hs, &hc);
    (void)att_i_quat_normalize_bounded(att_i_quat_mul_z(hc, hs, q), &q);
    switch (f->kind) {
    case ATT_FILTER_ARS:
        f->u.ars.st.q = q;
        break;
    case ATT_FILTER_MARS:
        f->u.mars.st.q = q;
        break;
    case ATT_FILTER_MEKF:
        f->u.mekf.st.q = q;
        break;
    default:
        f->u.kf.st.q = q;
        break;
    }
    return ATT_OK;
}

static bool att_filter_heading_ok(float heading)
{
    return att_i_in(heading, -ATT_FILTER_HEADING_MAX, ATT_FILTER_HEADING_MAX);
}

att_status_t att_filter_set_heading(att_filter_t *f, float heading)
{
    if (f == NULL) {
        return ATT_ERR_NULL;
    }
    if (f->kind == ATT_FILTER_TILT || att_filter_name(f->kind)[0] == '?') {
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
    if (f->kind != ATT_FILTER_ARS && f->kind != ATT_FILTER_KF && f->kind != ATT_FILTER_EKF &&
        f->kind != ATT_FILTER_GYRO && !(f->kind == ATT_FILTER_MEKF && !f->u.mekf.c.use_mag)) {
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
    case ATT_FILTER_MEKF:
        return "mekf";
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
