/**
 * @file att_mekf.c
 * @brief Multiplicative (error-state) EKF (see att_mekf.h). Mirrored by host/attica/reference/mekf.py.
 *
 * The covariance P is the packed upper triangle of a symmetric 6x6 matrix: P(i, j) for i <= j is
 * p[ATT_MEKF_IX(i, j)]; every formula below computes the upper triangle only, so P is exactly
 * symmetric by construction.
 */
#include "../../math/att_fp.h"

#include "../../core/att_core.h"
#include "../att_kinds.h"
#include "../att_yaw.h"
#include "att_mekf_checks.h"
#include "attica/att_math.h"
#include "attica/att_mekf.h"
#include "attica/att_sensor.h"

#define ATT_MEKF_PIO2_F 0x1.921fb6p+0f
#define ATT_MEKF_PIVOT_MIN 0x1p-16f /* relative pivot margin of the positive definiteness test */
#define ATT_MEKF_SHRINK 0x1.ff8p-1f /* 1 - 2^-10: correlation shrink factor of the repair */
#define ATT_MEKF_GATED_MAX 0xFFFFFFFFu
#define ATT_MEKF_REST_SIGMA2 0x1.2p+3f /* 9 = 3^2: the rest gate takes the bias estimate's error up to 3 sigma */
#define ATT_MEKF_SQRT2 0x1.6a09e6p+0f /* sqrt(2): the Butterworth low-pass */
#define ATT_MEKF_BW_Q 0x1.a8279ap-2f  /* sqrt(2) - 1: its damping feedback (2 zeta - 1, zeta = 1 / sqrt(2)) */
/* Where a recovery's running mean hands over to the Butterworth section of gain k (att_i_recovery_lp_gain):
 * at k / (2 sqrt(2)), after n = 2 sqrt(2) / k updates, where the mean's age n / 2 is the section's lag,
 * 2 tau_acc_lp = sqrt(2) / k samples (ATT_I_REC_MEAN_END is the first-order cascade's, 1 / 4). */
#define ATT_MEKF_REC_MEAN_END 0x1.6a09e6p-2f

/* Full unrolling of the small fixed loops of the covariance algebra (the indices become constants), not
 * when optimising for size (-Os); no effect on results. */
#if defined(__GNUC__) && !defined(__OPTIMIZE_SIZE__)
#define ATT_MEKF_PRAGMA(x) _Pragma(#x)
#define ATT_MEKF_UNROLL ATT_MEKF_PRAGMA(GCC unroll 6)
#else
#define ATT_MEKF_UNROLL
#endif

/* Packed index of P(i, j), i <= j < 6; and of a symmetric access with any order. */
#define ATT_MEKF_IX(i, j) ((i) * (11u - (i)) / 2u + (j))
#define ATT_MEKF_S(i, j) (((i) <= (j)) ? ATT_MEKF_IX(i, j) : ATT_MEKF_IX(j, i))

void att_mekf_settings_default(att_mekf_settings_t *settings, float dt)
{
    if (settings == NULL) {
        return;
    }
    settings->dt = dt;
    settings->gyro_noise = 1e-4f;       /* rad/s/sqrt(Hz): a MEMS gyro's white noise (BROAD's: 9.5e-5 at rest) */
    settings->gyro_rate_noise = 0.01f;  /* sqrt(s): 1 % of the rate (scale factor, misalignment, sampling) */
    settings->bias_noise = 1e-4f;       /* rad/s/sqrt(s): bias instability with temperature */
    settings->accel_noise = 0.003f;     /* rad sqrt(s): the low-passed up direction (linear accelerations) */
    settings->r_accel = 0.0f;
    settings->gate = 16.0f;             /* chi-square, 2 dof: P(d^2 > 16) = 3e-4 for a consistent filter */
    settings->gate_recover = 2.0f;
    settings->mag_noise = 0.6f;         /* rad sqrt(s): the heading, indoor field disturbances */
    settings->mag_gate = 0.0f;
    settings->p0_att = 0.01f;  /* (0.1 rad)^2 */
    settings->p0_bias = 1e-4f; /* (0.01 rad/s)^2 */
    settings->p_max = 10.0f;   /* rad^2: beyond a turn a variance means "unknown" */
    settings->gravity = 9.80665f;
    settings->accel_reject = 0.0f;
    settings->accel_range = 156.9064f; /* 16 g */
    settings->gyro_range = 34.906586f; /* 2000 deg/s */
    settings->mag_range = 1000.0f;
    settings->mag_norm_reject = 0.2f;
    settings->mag_dip_reject = 0.5f; /* about 29 deg */
    settings->tau_acc_lp = 1.45f;         /* s: Butterworth low-pass, a lag of 2.9 s (docs/accuracy.md) */
    settings->tau_acc_lp_no_rest = 1.25f; /* s: a lag of 2.5 s until a rest has measured the bias */
    settings->rest_noise = 1e-4f; /* rad/s/sqrt(Hz): the floor of the measured noise at rest (gyro_noise's) */
    settings->rest_gyro = 0.05f;
    settings->rest_accel = 0.5f;
    settings->rest_time = 0.5f;
    settings->gyro_scale_sd = 0.003f; /* 0.3 %: a calibrated MEMS gyro's scale-factor error (docs/accuracy.md) */
    settings->gyro_scale_init = 0.0f;
    settings->recovery_time = 2.0f; /* s: Fusion's recovery trigger period at 100 Hz is 5 s; ars and mars use 2 s */
    settings->declination = 0.0f;
    settings->mag_ref_tau = 20.0f;  /* s: the learnt reference field, as mars (att_magref.h) */
    settings->mag_new_time = 20.0f; /* s */
    settings->hard_iron_tau = 0.0f;  /* s: the hard-iron estimate is opt-in (60 s: docs/filters.md) */
    settings->hard_iron_rate = 1.0f; /* uT/s */
    settings->use_mag = true;
    settings->init_from_sensors = true;
    settings->q_init = att_i_quat_identity();
    settings->m0_init = att_i_vec3(0.0f, 0.0f, 0.0f);
    settings->bias_init = att_i_vec3(0.0f, 0.0f, 0.0f);
}

att_status_t att_mekf_settings_validate(const att_mekf_settings_t *s)
{
    bool ok;
    if (s == NULL) {
        return ATT_ERR_NULL;
    }
    ok = true ATT_MEKF_CHECKS(ATT_CHECK_AND);
    return ok ? ATT_OK : ATT_ERR_SETTINGS;
}

/*
 * The coefficients of the recovery after a clipping gyro (att_mekf.h, step 6); after r_acc, r_mag, k_lp,
 * lp_on and p_max. The process noise k^2 r / (1 - k) is the one whose steady-state Kalman gain is k (at
 * most p_max, the variance of "unknown").
 */
static void att_mekf_rec_coeffs(att_mekf_coeffs_t *c, const att_mekf_settings_t *s)
{
    const float k = att_i_recovery_params(s->recovery_time, s->gyro_range, s->dt, &c->rec_n, &c->clip);
    c->k_lp_rec = (c->lp_on && k > c->k_lp_no_rest) ? k : c->k_lp_no_rest;
    c->q_rec_tilt = (c->rec_n > 0u) ? att_i_recovery_q(k, c->r_acc, c->p_max) : 0.0f;
    c->q_rec_head = (c->rec_n > 0u) ? att_i_recovery_q(k, c->r_mag, c->p_max) : 0.0f;
}

static void att_mekf_coeffs(att_mekf_coeffs_t *c, const att_mekf_settings_t *s)
{
    c->dt = s->dt;
    c->half_dt = s->dt * 0.5f;
    c->qa = (s->gyro_noise * s->gyro_noise) * s->dt;
    c->qw = (s->gyro_rate_noise * s->gyro_rate_noise) * s->dt;
    c->qb = (s->bias_noise * s->bias_noise) * s->dt;
    c->r_acc = (s->accel_noise * s->accel_noise) / s->dt;
    c->r_accel = s->r_accel;
    c->gate = s->gate;
    c->soft = s->gate * 0.25f;
    c->r_mag = (s->mag_noise * s->mag_noise) / s->dt;
    c->mag_gate = s->mag_gate;
    c->mag_soft = s->mag_gate * 0.25f;
    c->p0_att = s->p0_att;
    c->p0_bias = s->p0_bias;
    c->p_max = s->p_max;
    c->gravity = s->gravity;
    c->accel_reject = s->accel_reject;
    c->accel_range2 = s->accel_range * s->accel_range;
    c->gyro_range = s->gyro_range;
    c->mag_range = s->mag_range;
    c->mag_norm_reject = s->mag_norm_reject;
    c->mag_dip_reject = s->mag_dip_reject;
    c->k_lp = (s->tau_acc_lp > 0.0f) ? s->dt / (ATT_MEKF_SQRT2 * s->tau_acc_lp + s->dt) : 0.0f;
    c->k_lp_no_rest = (c->k_lp > 0.0f && s->tau_acc_lp_no_rest > 0.0f)
                          ? s->dt / (ATT_MEKF_SQRT2 * s->tau_acc_lp_no_rest + s->dt)
                          : c->k_lp;
    c->n_recover = att_sensor_samples(s->gate_recover, s->dt);
    c->r_rest = (s->rest_noise * s->rest_noise) / s->dt;
    c->rest_gyro2 = s->rest_gyro * s->rest_gyro;
    {
        const float lo = s->gravity - s->rest_accel;
        const float hi = s->gravity + s->rest_accel;
        c->acc2_lo = lo * lo;
        c->acc2_hi = hi * hi;
    }
    c->rest_n = att_sensor_samples(s->rest_time, s->dt);
    c->p0_scale = s->gyro_scale_sd * s->gyro_scale_sd;
    c->scale_init = s->gyro_scale_init;
    (void)att_i_quat_normalize(s->q_init, &c->q_init);
    c->m0_init = s->init_from_sensors ? att_i_vec3(0.0f, 0.0f, 0.0f) : s->m0_init;
    c->bias_init = s->bias_init;
    c->use_mag = s->use_mag;
    c->init_from_sensors = s->init_from_sensors;
    c->lp_on = c->k_lp > 0.0f;
    c->need_norm = s->r_accel > 0.0f || s->accel_reject > 0.0f;
    att_mekf_rec_coeffs(c, s);
    c->decl = s->declination;
    c->decl_sin = att_sinf(s->declination);
    c->decl_cos = att_cosf(s->declination);
    att_i_magref_params(&c->ref, s->dt, s->mag_ref_tau, s->mag_new_time, s->mag_norm_reject, s->mag_dip_reject);
    att_i_hi_params(&c->hi, s->dt, s->use_mag ? s->hard_iron_tau : 0.0f, s->hard_iron_rate, s->mag_norm_reject,
                    s->mag_range);
}

/* Dip angle of v: atan2(v.z, |v_xy|), rad. */
static float att_mekf_dip(att_vec3_t v)
{
    return att_atan2f(v.z, att_i_sqrtf(v.x * v.x + v.y * v.y));
}

/*
 * Derived quantities of the reference field m0 (state m0): the unit horizontal direction, the H entries
 * of the tilt in the heading innovation, the accepted |m| interval and sin(dip) interval (as att_mars.c).
 */
static ATT_ALWAYS_INLINE void att_mekf_m0_limits(const att_mekf_coeffs_t *c, att_mekf_state_t *st)
{
    const float norm = att_i_vec3_norm(st->m0);
    const bool ref_ok = att_i_vec3_normalize(att_i_vec3(st->m0.x, st->m0.y, 0.0f), &st->m0_ref);
    st->mag_hx = 0.0f;
    st->mag_hy = 0.0f;
    if (ref_ok) {
        const float cz = st->m0.z / att_i_sqrtf(st->m0.x * st->m0.x + st->m0.y * st->m0.y);
        st->mag_hx = -(cz * st->m0_ref.x);
        st->mag_hy = -(cz * st->m0_ref.y);
    }
    st->m0_lo = 0.0f;
    st->m0_hi = c->mag_range;
    if (c->mag_norm_reject > 0.0f) {
        st->m0_lo = norm * (1.0f - c->mag_norm_reject);
        st->m0_hi = norm * (1.0f + c->mag_norm_reject);
    }
    if (!ref_ok) {
        st->m0_lo = INFINITY; /* no horizontal reference: every sample is rejected */
    }
    st->dip_lo = -2.0f;
    st->dip_hi = 2.0f;
    if (c->mag_dip_reject > 0.0f) {
        const float dip = att_mekf_dip(st->m0);
        const float lo = dip - c->mag_dip_reject;
        const float hi = dip + c->mag_dip_reject;
        if (lo > -ATT_MEKF_PIO2_F) {
            st->dip_lo = att_sinf(lo);
        }
        if (hi < ATT_MEKF_PIO2_F) {
            st->dip_hi = att_sinf(hi);
        }
    }
}

/* Set the reference field m0; returns false (and changes nothing) when m0 has no direction. */
static ATT_NOINLINE bool att_mekf_set_m0(const att_mekf_coeffs_t *c, att_mekf_state_t *st, att_vec3_t m0)
{
    att_vec3_t unit;
    if (!att_i_vec3_normalize(m0, &unit)) {
        return false;
    }
    st->m0 = m0;
    st->m0_valid = true;
    att_mekf_m0_limits(c, st);
    att_i_magref_clear(&st->ref);
    return true;
}

/* The scale sensitivity V := 0 (nothing is correlated with the scale error yet). */
static void att_mekf_scale_v_zero(att_mekf_state_t *st)
{
    uint32_t i;
    for (i = 0u; i < 6u; i++) {
        st->scale_v[i] = 0.0f;
    }
}

/* P := diag(p0_att I3, p0_bias I3). */
static void att_mekf_p_reset(const att_mekf_coeffs_t *c, float *p)
{
    uint32_t i;
    for (i = 0u; i < ATT_MEKF_P_LEN; i++) {
        p[i] = 0.0f;
    }
    p[ATT_MEKF_IX(0u, 0u)] = c->p0_att;
    p[ATT_MEKF_IX(1u, 1u)] = c->p0_att;
    p[ATT_MEKF_IX(2u, 2u)] = c->p0_att;
    p[ATT_MEKF_IX(3u, 3u)] = c->p0_bias;
    p[ATT_MEKF_IX(4u, 4u)] = c->p0_bias;
    p[ATT_MEKF_IX(5u, 5u)] = c->p0_bias;
}

att_status_t att_mekf_init(att_mekf_t *f, const att_mekf_settings_t *settings)
{
    att_status_t st;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    st = att_mekf_settings_validate(settings);
    if (st != ATT_OK) {
        return st;
    }
    att_mekf_coeffs(&f->c, settings);
    att_mekf_reset(f);
    return ATT_OK;
}

att_status_t att_mekf_retune(att_mekf_t *f, const att_mekf_settings_t *settings)
{
    att_status_t st;
    bool hi_was_on;
    bool mag_was;
    float dt_was;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    st = att_mekf_settings_validate(settings);
    if (st != ATT_OK) {
        return st;
    }
    hi_was_on = f->c.hi.on;
    dt_was = f->c.dt;
    mag_was = f->c.use_mag;
    att_mekf_coeffs(&f->c, settings);
    if (mag_was && !f->c.use_mag) {
        f->st.head_known = f->st.m0_valid; /* 9 -> 6 axes: the heading is known if the field tracked it */
    }
    if (f->c.hi.on != hi_was_on) {
        att_i_hi_reset(&f->st.hi); /* turned on or off: the estimate starts again (off: no offset applied) */
    }
    att_i_hi_retune(&f->c.hi, &f->st.hi);
    f->st.k_lp = f->st.rested ? f->c.k_lp : f->c.k_lp_no_rest;
    if (!(f->c.p0_scale > 0.0f)) {
        f->st.p_scale = 0.0f; /* no longer estimated: the estimate is kept, fixed */
        att_mekf_scale_v_zero(&f->st);
    } else if (!(f->st.p_scale > 0.0f)) {
        f->st.p_scale = f->c.p0_scale; /* estimated from now on, from the estimate kept */
        att_mekf_scale_v_zero(&f->st);
    }
    if (f->st.m0_valid) {
        att_mekf_m0_limits(&f->c, &f->st);
    }
    if (f->st.rest_count > f->c.rest_n) {
        f->st.rest_count = f->c.rest_n;
    }
    if (!(f->c.dt == dt_was)) {
        f->st.rest_e2 = 0.0f; /* the zero-rate noise is per sample: with a new dt its mean starts again */
        f->st.rest_e2_n = 0u;
    } else if (f->st.rest_e2_n > f->c.rest_n) {
        f->st.rest_e2_n = f->c.rest_n; /* the mean's gain at least the new floor 1 / (rest_n + 1) */
    }
    if (f->st.rec_left > f->c.rec_n) {
        f->st.rec_left = f->c.rec_n; /* a recovery no longer than the new recovery_time (0: ended) */
    }
    return ATT_OK;
}

void att_mekf_reset(att_mekf_t *f)
{
    const att_vec3_t zero = att_i_vec3(0.0f, 0.0f, 0.0f);
    att_mekf_state_t *st;
    if (f == NULL) {
        return;
    }
    st = &f->st;
    st->q = f->c.q_init;
    st->bias = f->c.bias_init;
    att_mekf_p_reset(&f->c, st->p);
    st->scale = f->c.scale_init;
    st->p_scale = f->c.p0_scale;
    att_mekf_scale_v_zero(st);
    st->lp1 = att_i_vec3(0.0f, 0.0f, f->c.gravity);
    st->lp2 = st->lp1;
    st->m0 = zero;
    st->m0_ref = zero;
    st->mag_hx = 0.0f;
    st->mag_hy = 0.0f;
    st->m0_lo = 0.0f;
    st->m0_hi = 0.0f;
    st->dip_lo = 0.0f;
    st->dip_hi = 0.0f;
    st->gated = 0u;
    st->rest_count = 0u;
    st->rest_e2 = 0.0f;
    st->rest_e2_n = 0u;
    st->steps = 0u;
    st->flags = 0u;
    st->rec_left = 0u;
    st->rec_lp_n = 0u;
    att_i_magref_reset(&st->ref);
    att_i_hi_reset(&st->hi);
    st->m0_valid = false;
    st->lp_valid = false;
    st->rec_clip = false;
    st->initialised = !f->c.init_from_sensors;
    st->head_known = false;
    st->rested = false;
    st->k_lp = f->c.k_lp_no_rest;
    if (!att_mekf_vec3_is_zero(f->c.m0_init)) {
        (void)att_mekf_set_m0(&f->c, st, f->c.m0_init); /* succeeds: checked by the settings validation */
    }
}

/* --- the step -------------------------------------------------------------------------------- */

/*
 * att_i_quat_from_rotvec_fast with its large-angle case inlined too (att_i_quat_from_rotvec, the twin of
 * the att_quat_from_rotvec it calls: the same bits), so that no extra frame is stacked under a phase.
 */
static ATT_ALWAYS_INLINE att_quat_t att_mekf_exp(att_vec3_t rv)
{
    const float z = att_i_vec3_dot(rv, rv);
    float k;
    if (z <= ATT_ROTVEC_Z_SMALL) {
        k = ATT_ROTVEC_S0 + z * (ATT_ROTVEC_S1 + z * ATT_ROTVEC_S2);
        return att_i_quat(1.0f + z * (ATT_ROTVEC_C1 + z * ATT_ROTVEC_C2), rv.x * k, rv.y * k, rv.z * k);
    }
    return att_i_quat_from_rotvec(rv);
}

/*
 * Yaw alignment: rotate q about the earth z axis so that the horizontal part of q mag q* points at the
 * azimuth D (the declination, east of north; D = 0: north, +y); *m0 = (|m_e,xy| sin D, |m_e,xy| cos D,
 * m_e,z) for the aligned attitude. Returns false when mag has no direction.
 */
static ATT_ALWAYS_INLINE bool att_mekf_align(const att_mekf_coeffs_t *c, att_quat_t q, att_vec3_t mag,
                                             att_quat_t *q_out, att_vec3_t *m0)
{
    att_vec3_t me = att_i_quat_rotate(q, mag);
    att_vec3_t unit;
    att_quat_t qa;
    float h;
    if (!att_i_vec3_normalize(me, &unit)) {
        return false;
    }
    qa = att_i_quat_mul(
        att_i_quat_from_axis_angle(att_i_vec3(0.0f, 0.0f, 1.0f), att_atan2f(me.x, me.y) - c->decl), q);
    if (!att_i_quat_normalize_bounded(qa, &qa)) {
        return false;
    }
    me = att_i_quat_rotate(qa, mag);
    h = att_i_sqrtf(me.x * me.x + me.y * me.y);
    *m0 = att_i_vec3(h * c->decl_sin, h * c->decl_cos, me.z);
    *q_out = qa;
    return true;
}

/*
 * The estimate's earth frame was turned about z by the unit quaternion (w, 0, 0, z) (a heading correction
 * or the yaw alignment): the low-pass stages, which live in that frame, are turned with it, as the accel
 * and rest corrections turn them. cz = 1 - 2 z^2 and sz = 2 w z are the cosine and sine of the angle.
 */
static ATT_ALWAYS_INLINE void att_mekf_lp_turn(att_mekf_state_t *st, float w, float z)
{
    const float cz = 1.0f - 2.0f * (z * z);
    const float sz = 2.0f * (w * z);
    const att_vec3_t l1 = st->lp1;
    const att_vec3_t l2 = st->lp2;
    st->lp1 = att_i_vec3(cz * l1.x - sz * l1.y, sz * l1.x + cz * l1.y, l1.z);
    st->lp2 = att_i_vec3(cz * l2.x - sz * l2.y, sz * l2.x + cz * l2.y, l2.z);
}

/*
 * The heading was aligned (var = p0_att) or a new reference field adopted (var = p_max: the heading is
 * unknown against it): its variance to var, its correlations to zero (P stays PD), and its sensitivity to
 * the scale error to zero.
 */
static void att_mekf_yaw_reset(att_mekf_state_t *st, float var)
{
    float *p = st->p;
    st->scale_v[2] = 0.0f;
    p[ATT_MEKF_IX(0u, 2u)] = 0.0f;
    p[ATT_MEKF_IX(1u, 2u)] = 0.0f;
    p[ATT_MEKF_IX(2u, 2u)] = var;
    p[ATT_MEKF_IX(2u, 3u)] = 0.0f;
    p[ATT_MEKF_IX(2u, 4u)] = 0.0f;
    p[ATT_MEKF_IX(2u, 5u)] = 0.0f;
}

/* First usable accel sample: roll and pitch from it, yaw from the mag sample when used and usable. */
static ATT_NOINLINE uint32_t att_mekf_start(const att_mekf_coeffs_t *c, att_mekf_state_t *st, const att_vec3_t *acc,
                                            const att_vec3_t *mag, bool mag_ok)
{
    /* att_sensor_tilt(*acc), written here to keep its frame off the stack */
    const float phi = att_atan2f(acc->y, acc->z);
    const float theta = att_atan2f(-acc->x, att_i_sqrtf(acc->y * acc->y + acc->z * acc->z));
    uint32_t flags = ATT_FLAG_INITIALISED;
    att_quat_t q;
    att_quat_t qa;
    att_vec3_t m0;
    (void)att_i_quat_normalize_bounded(att_i_quat_from_euler(phi, theta, 0.0f), &q);
    if (mag_ok) {
        if (att_mekf_align(c, q, *mag, &qa, &m0) && att_mekf_set_m0(c, st, m0)) {
            q = qa;
            att_mekf_yaw_reset(st, c->p0_att);
        } else {
            flags |= ATT_FLAG_MAG_REJECTED;
        }
    }
    st->q = q;
    st->lp1 = att_i_quat_rotate(q, *acc);
    st->lp2 = st->lp1;
    st->lp_valid = true;
    st->initialised = true;
    att_i_recovery_start(c->rec_n, &st->rec_left, &st->rec_lp_n); /* att_mekf.h, step 6 */
    st->rec_clip = false;
    return flags;
}

/*
 * A usable mag sample before the reference field is known: yaw alignment of *q (the low-pass stages turned
 * with it), or m0 from it; flags.
 */
static ATT_NOINLINE uint32_t att_mekf_mag_first(const att_mekf_coeffs_t *c, att_mekf_state_t *st, att_quat_t *q,
                                                const att_vec3_t *mag)
{
    att_quat_t qa;
    att_vec3_t m0;
    if (c->init_from_sensors) {
        if (att_mekf_align(c, *q, *mag, &qa, &m0) && att_mekf_set_m0(c, st, m0)) {
            if (c->lp_on) {
                /* the turn applied, qa q* = (w, 0, 0, z) (its x, y are rounding: dropped) */
                const att_quat_t q0 = *q;
                const float tw = qa.w * q0.w + qa.x * q0.x + qa.y * q0.y + qa.z * q0.z;
                const float tz = qa.z * q0.w - qa.w * q0.z + qa.y * q0.x - qa.x * q0.y;
                att_mekf_lp_turn(st, tw, tz);
            }
            *q = qa;
            att_mekf_yaw_reset(st, c->p0_att);
            return ATT_FLAG_INITIALISED;
        }
        return ATT_FLAG_MAG_REJECTED;
    }
    if (!att_mekf_set_m0(c, st, att_i_quat_rotate(*q, *mag))) {
        return ATT_FLAG_MAG_REJECTED;
    }
    return 0u;
}

/*
 * Covariance prediction P := Phi P Phi^T + Q with Phi = [[I, -R dt], [0, I]], written out (see
 * att_mekf.h): M = R C, H = B - (dt/2) M, A := A - dt (N + N^T) + qa I with N = R H^T, B := H - (dt/2) M,
 * C := C + qb I. r is R row-major. H is kept in the B entries of P between the two passes (M is
 * computed again, the same operations on the same values), so no 3x3 scratch is needed on the stack.
 */
static ATT_ALWAYS_INLINE float att_mekf_rc(const float *p, const float *r, uint32_t i, uint32_t j)
{
    return r[(size_t)3u * i] * p[ATT_MEKF_S(3u, 3u + j)] + r[3u * i + 1u] * p[ATT_MEKF_S(4u, 3u + j)] +
           r[3u * i + 2u] * p[ATT_MEKF_S(5u, 3u + j)];
}

static ATT_ALWAYS_INLINE void att_mekf_predict(float *p, const float *r, float hdt, float dt, float qa, float qb)
{
    uint32_t i;
    uint32_t j;
    ATT_MEKF_UNROLL
    for (i = 0u; i < 3u; i++) {
        ATT_MEKF_UNROLL
        for (j = 0u; j < 3u; j++) {
            p[ATT_MEKF_IX(i, 3u + j)] = p[ATT_MEKF_IX(i, 3u + j)] - hdt * att_mekf_rc(p, r, i, j); /* H */
        }
    }
    ATT_MEKF_UNROLL
    for (i = 0u; i < 3u; i++) {
        ATT_MEKF_UNROLL
        for (j = i; j < 3u; j++) {
            const float *hi = &p[ATT_MEKF_IX(i, 3u)];
            const float *hj = &p[ATT_MEKF_IX(j, 3u)];
            const float nij = r[(size_t)3u * i] * hj[0] + r[3u * i + 1u] * hj[1] + r[3u * i + 2u] * hj[2];
            const float nji = r[(size_t)3u * j] * hi[0] + r[3u * j + 1u] * hi[1] + r[3u * j + 2u] * hi[2];
            float a = p[ATT_MEKF_IX(i, j)] - dt * (nij + nji);
            if (i == j) {
                a = a + qa;
            }
            p[ATT_MEKF_IX(i, j)] = a;
        }
    }
    ATT_MEKF_UNROLL
    for (i = 0u; i < 3u; i++) {
        ATT_MEKF_UNROLL
        for (j = 0u; j < 3u; j++) {
            p[ATT_MEKF_IX(i, 3u + j)] = p[ATT_MEKF_IX(i, 3u + j)] - hdt * att_mekf_rc(p, r, i, j); /* B */
        }
    }
    p[ATT_MEKF_IX(3u, 3u)] = p[ATT_MEKF_IX(3u, 3u)] + qb;
    p[ATT_MEKF_IX(4u, 4u)] = p[ATT_MEKF_IX(4u, 4u)] + qb;
    p[ATT_MEKF_IX(5u, 5u)] = p[ATT_MEKF_IX(5u, 5u)] + qb;
}

/* The innovation covariance of the accel update and the quantities derived from it. */
typedef struct {
    float s00; /**< S = A_xy + r I2 */
    float s01;
    float s11;
    float det; /**< det S */
    float dn;  /**< y^T adj(S) y = d^2 det S */
} att_mekf_innov_t;

static ATT_ALWAYS_INLINE att_mekf_innov_t att_mekf_innov(const float *p, float r, float y0, float y1)
{
    att_mekf_innov_t v;
    v.s00 = p[ATT_MEKF_IX(0u, 0u)] + r;
    v.s01 = p[ATT_MEKF_IX(0u, 1u)];
    v.s11 = p[ATT_MEKF_IX(1u, 1u)] + r;
    v.det = v.s00 * v.s11 - v.s01 * v.s01;
    v.dn = y0 * y0 * v.s11 - 2.0f * y0 * y1 * v.s01 + y1 * y1 * v.s00;
    return v;
}

/*
 * The gate recovery: the tilt variances grow by |y|^2 / (gate / 4) (then d^2 <= gate / 4), by at most
 * p_max (a gate so small that the growth overflows, or NaN: p_max, "unknown"); returns the new
 * innovation covariance.
 */
static ATT_ALWAYS_INLINE att_mekf_innov_t att_mekf_recover(const att_mekf_coeffs_t *c, float *p, float r, float y0, float y1)
{
    float add = (y0 * y0 + y1 * y1) / c->soft;
    if (!(add <= c->p_max)) {
        add = c->p_max;
    }
    p[ATT_MEKF_IX(0u, 0u)] = p[ATT_MEKF_IX(0u, 0u)] + add;
    p[ATT_MEKF_IX(1u, 1u)] = p[ATT_MEKF_IX(1u, 1u)] + add;
    return att_mekf_innov(p, r, y0, y1);
}

/*
 * The scale-factor error as measured by a scalar update with sensitivity a = H V, innovation variance
 * s0 (of the 6-state filter) and residual y: k_s = p_s a / (s0 + p_s a^2); *ps := p_s (1 - k_s a);
 * returns ds = k_s y. With p_s = 0 (not estimated) ds = 0.
 */
static ATT_ALWAYS_INLINE float att_mekf_scale_gain1(float *ps, float a, float s0, float y)
{
    const float p = *ps;
    const float k = (p * a) / (s0 + p * (a * a));
    *ps = p * (1.0f - k * a);
    return k * y;
}

/*
 * Accel update with the residual y (H = [I2 0]) and the innovation v: P := P - K (lambda S) K^T with
 * K = G (lambda S)^-1, G = P H^T (the first two columns of P). The scale: with a = H V (before the
 * update) and M = (lambda S)^-1 (the noise as the 6-state gain uses it: the split into two stages is
 * exact only with the same), k_s = p_s a^T (lambda S + p_s a a^T)^-1 = p_s (M a)^T / (1 + p_s a^T M a)
 * (Sherman-Morrison), so ds = r (M a)^T y and p_s := r with r = p_s / (1 + p_s a^T M a); then
 * V := V - K a and the error estimate dx = K y + V ds with the updated V. Returns ds. Only the first n_upd
 * states are updated (6; 3 during a recovery: the bias a consider state, its dx 0 and its rows of P and V
 * kept, which is the Joseph form for that gain: the attitude rows are the optimal ones either way).
 */
static ATT_ALWAYS_INLINE float att_mekf_accel_apply(const att_mekf_coeffs_t *c, float *p, att_mekf_innov_t v, float y0,
                                                    float y1, float *dx, float *sv, float *ps, uint32_t n_upd)
{
    const float sa0 = sv[0];
    const float sa1 = sv[1];
    float g0[6];
    float g1[6];
    float ks;
    float a0;
    float a1;
    float a2;
    float m0;
    float m1;
    float r;
    float ds;
    uint32_t i;
    uint32_t j;
    ATT_MEKF_UNROLL
    for (i = 0u; i < 6u; i++) {
        g0[i] = p[ATT_MEKF_IX(0u, i)];
        g1[i] = p[ATT_MEKF_S(1u, i)];
    }
    ks = 1.0f / v.det;
    if (c->gate > 0.0f && v.dn > c->soft * v.det) {
        ks = c->soft / v.dn; /* the soft limit: (lambda S)^-1 = adj(S) (gate / 4) / (y^T adj(S) y) */
    }
    a0 = v.s11 * ks;
    a1 = -(v.s01 * ks);
    a2 = v.s00 * ks;
    m0 = a0 * sa0 + a1 * sa1;
    m1 = a1 * sa0 + a2 * sa1;
    r = *ps / (1.0f + *ps * (sa0 * m0 + sa1 * m1));
    ds = r * (m0 * y0 + m1 * y1);
    *ps = r;
    ATT_MEKF_UNROLL
    for (i = 0u; i < 6u; i++) {
        const float k0 = g0[i] * a0 + g1[i] * a1;
        const float k1 = g0[i] * a1 + g1[i] * a2;
        if (i >= n_upd) {
            dx[i] = 0.0f; /* a consider state (Schmidt): not updated, its row of P and of V kept */
            continue;
        }
        sv[i] = sv[i] - (k0 * sa0 + k1 * sa1);
        dx[i] = (k0 * y0 + k1 * y1) + sv[i] * ds;
        ATT_MEKF_UNROLL
        for (j = i; j < 6u; j++) {
            p[ATT_MEKF_IX(i, j)] = p[ATT_MEKF_IX(i, j)] - (k0 * g0[j] + k1 * g1[j]);
        }
    }
    return ds;
}

/*
 * Heading update with innovation y and noise r: H = [hx, hy, 1, 0, 0, 0], g = P H^T, s = H g + r, the
 * gain K = g / (lambda s) with K_0 = K_1 = 0 and the Joseph form, which for that gain subtracts
 * k g_i g_j from every entry outside the tilt block (k = 1 / (lambda s)). Returns false (nothing
 * changed) when the gate rejects y; else dz (the heading correction) and db. The scale sensitivity
 * V := V - K a (a = H V; outside the tilt entries, as K). The heading update is not a measurement of
 * the scale: with the tilt entries of K forced to zero the 6-state errors it leaves are correlated with
 * the scale error unless the scale gain is zero (the two-stage split stays exact with ds = 0).
 */
static ATT_ALWAYS_INLINE bool att_mekf_mag_apply(const att_mekf_coeffs_t *c, att_mekf_state_t *st, float *p, float y,
                                                 float *dz, att_vec3_t *db)
{
    float *sv = st->scale_v;
    float sa;
    const float hx = st->mag_hx;
    const float hy = st->mag_hy;
    float g[6];
    float kg[6];
    float s;
    float y2;
    float k;
    uint32_t i;
    uint32_t j;
    ATT_MEKF_UNROLL
    for (i = 0u; i < 6u; i++) {
        g[i] = p[ATT_MEKF_S(i, 2u)] + hx * p[ATT_MEKF_S(i, 0u)] + hy * p[ATT_MEKF_S(i, 1u)];
    }
    s = g[2] + hx * g[0] + hy * g[1] + c->r_mag;
    y2 = y * y;
    if (c->mag_gate > 0.0f && y2 > c->mag_gate * s) {
        return false;
    }
    k = 1.0f / s;
    if (c->mag_gate > 0.0f && y2 > c->mag_soft * s) {
        k = c->mag_soft / y2;
    }
    ATT_MEKF_UNROLL
    for (i = 0u; i < 6u; i++) {
        kg[i] = k * g[i];
    }
    ATT_MEKF_UNROLL
    for (i = 0u; i < 6u; i++) {
        ATT_MEKF_UNROLL
        for (j = (i < 2u) ? 2u : i; j < 6u; j++) {
            p[ATT_MEKF_IX(i, j)] = p[ATT_MEKF_IX(i, j)] - kg[i] * g[j];
        }
    }
    sa = (sv[2] + hx * sv[0]) + hy * sv[1];
    ATT_MEKF_UNROLL
    for (i = 2u; i < 6u; i++) {
        sv[i] = sv[i] - kg[i] * sa;
    }
    *dz = kg[2] * y;
    *db = att_i_vec3(kg[3] * y, kg[4] * y, kg[5] * y);
    return true;
}

/* Positive definite with margin 2^-16 (att_core.h, att_i_pd6: the test float32 rounding cannot fool). */
static ATT_NOINLINE bool att_mekf_pd(const float *p)
{
    return att_i_pd6(p, ATT_MEKF_PIVOT_MIN);
}

/* Multiply every correlation (off-diagonal entry) of P by s. */
static void att_mekf_shrink(float *p, float s)
{
    uint32_t i;
    uint32_t j;
    for (i = 0u; i < 6u; i++) {
        for (j = i + 1u; j < 6u; j++) {
            p[ATT_MEKF_IX(i, j)] = p[ATT_MEKF_IX(i, j)] * s;
        }
    }
}

/*
 * The conditioning of step 4 (see att_mekf.h), slow part: variances above their cap brought to it by
 * D P D; a variance not > 0 (or NaN) set to its cap (ATT_FLAG_CLAMPED); then the positive definiteness
 * test and the repair (ATT_FLAG_CLAMPED).
 */
static ATT_NOINLINE uint32_t att_mekf_repair(const att_mekf_coeffs_t *c, float *p, bool diag_ok)
{
    uint32_t flags = 0u;
    uint32_t i;
    uint32_t j;
    if (!diag_ok) {
        float d[6];
        for (i = 0u; i < 6u; i++) {
            const float cap = (i < 3u) ? c->p_max : c->p0_bias;
            const float v = p[ATT_MEKF_IX(i, i)];
            d[i] = 1.0f;
            if (v > cap) {
                d[i] = att_i_sqrtf(cap / v); /* D P D: the correlations kept */
                p[ATT_MEKF_IX(i, i)] = cap;
            } else if (!(v > 0.0f)) {
                p[ATT_MEKF_IX(i, i)] = cap; /* not > 0 or NaN: unknown */
                flags |= ATT_FLAG_CLAMPED;
            }
        }
        for (i = 0u; i < 6u; i++) {
            for (j = i + 1u; j < 6u; j++) {
                p[ATT_MEKF_IX(i, j)] = (p[ATT_MEKF_IX(i, j)] * d[i]) * d[j];
            }
        }
        if (att_mekf_pd(p)) {
            return flags;
        }
    }
    att_mekf_shrink(p, ATT_MEKF_SHRINK);
    if (!att_mekf_pd(p)) {
        att_mekf_shrink(p, 0.0f);
    }
    return flags | ATT_FLAG_CLAMPED;
}

/*
 * Step 4b, slow part: the scale estimate within +-ATT_MEKF_SCALE_MAX (ATT_FLAG_CLAMPED; NaN: 0), p_scale
 * >= 0 (NaN or negative: 0, the estimation stops; ATT_FLAG_CLAMPED), and |V| <= ATT_MEKF_SENS_MAX (V
 * scaled down: a normal condition in 6-axis use, where nothing corrects the heading's sensitivity while
 * the sensor turns about the vertical, so not flagged; a NaN entry sets V to 0, flagged). n = |V|^2.
 */
static ATT_NOINLINE uint32_t att_mekf_scale_limit(att_mekf_state_t *st, float n)
{
    uint32_t flags = 0u;
    uint32_t i;
    float k = 1.0f;
    if (st->scale > ATT_MEKF_SCALE_MAX) {
        st->scale = ATT_MEKF_SCALE_MAX;
        flags = ATT_FLAG_CLAMPED;
    } else if (st->scale < -ATT_MEKF_SCALE_MAX) {
        st->scale = -ATT_MEKF_SCALE_MAX;
        flags = ATT_FLAG_CLAMPED;
    } else if (!(st->scale == st->scale)) {
        st->scale = 0.0f;
        flags = ATT_FLAG_CLAMPED;
    }
    if (!(st->p_scale >= 0.0f)) {
        st->p_scale = 0.0f;
        flags = ATT_FLAG_CLAMPED;
    }
    if (!(n == n)) {
        k = 0.0f;
        flags = ATT_FLAG_CLAMPED;
    } else if (n > ATT_MEKF_SENS_MAX * ATT_MEKF_SENS_MAX) {
        k = ATT_MEKF_SENS_MAX / att_i_sqrtf(n);
    }
    for (i = 0u; i < 6u; i++) {
        st->scale_v[i] = (k == 0.0f) ? 0.0f : st->scale_v[i] * k;
    }
    return flags;
}

/* Step 4b: the scale limits (att_mekf_scale_limit) when s, p_scale or |V| leave their range. */
static ATT_ALWAYS_INLINE uint32_t att_mekf_scale_bound(att_mekf_state_t *st)
{
    const float *v = st->scale_v;
    const float n = ((v[0] * v[0] + v[1] * v[1]) + (v[2] * v[2] + v[3] * v[3])) + (v[4] * v[4] + v[5] * v[5]);
    if (n <= ATT_MEKF_SENS_MAX * ATT_MEKF_SENS_MAX && st->p_scale >= 0.0f && st->scale <= ATT_MEKF_SCALE_MAX &&
        st->scale >= -ATT_MEKF_SCALE_MAX) {
        return 0u;
    }
    return att_mekf_scale_limit(st, n);
}

/* Step 4: every variance in (0, cap] and P positive definite with margin, else the repair. */
static ATT_ALWAYS_INLINE uint32_t att_mekf_condition(const att_mekf_coeffs_t *c, float *p)
{
    const float pa = c->p_max;
    const float pb = c->p0_bias;
    const bool diag_ok = p[ATT_MEKF_IX(0u, 0u)] <= pa && p[ATT_MEKF_IX(1u, 1u)] <= pa &&
                         p[ATT_MEKF_IX(2u, 2u)] <= pa && p[ATT_MEKF_IX(3u, 3u)] <= pb &&
                         p[ATT_MEKF_IX(4u, 4u)] <= pb && p[ATT_MEKF_IX(5u, 5u)] <= pb &&
                         p[ATT_MEKF_IX(0u, 0u)] > 0.0f && p[ATT_MEKF_IX(1u, 1u)] > 0.0f &&
                         p[ATT_MEKF_IX(2u, 2u)] > 0.0f && p[ATT_MEKF_IX(3u, 3u)] > 0.0f &&
                         p[ATT_MEKF_IX(4u, 4u)] > 0.0f && p[ATT_MEKF_IX(5u, 5u)] > 0.0f;
    if (diag_ok && att_mekf_pd(p)) {
        return 0u;
    }
    return att_mekf_repair(c, p, diag_ok);
}

/*
 * The heading innovation of the earth-frame field me (reference known, sample of norm mnorm): false
 * when the sample is rejected (norm, dip, no horizontal part), else *y = 2 sin(alpha / 2); *use tells the
 * learnt reference whether it passed the norm and dip tests (att_magref.h).
 */
static ATT_ALWAYS_INLINE bool att_mekf_heading(const att_mekf_state_t *st, att_vec3_t me, float mnorm, float *y,
                                               uint32_t *use)
{
    float h2;
    float hn;
    float a;
    float b;
    if (mnorm < st->m0_lo || mnorm > st->m0_hi || me.z < st->dip_lo * mnorm || me.z > st->dip_hi * mnorm) {
        *use = ATT_MAGREF_GATED;
        return false;
    }
    *use = ATT_MAGREF_ACCEPTED;
    h2 = me.x * me.x + me.y * me.y;
    if (!(h2 >= ATT_NORM2_MIN)) {
        return false; /* vertical field: no heading information */
    }
    hn = att_i_sqrtf(h2);
    a = hn + (me.x * st->m0_ref.x + me.y * st->m0_ref.y);
    b = me.x * st->m0_ref.y - me.y * st->m0_ref.x;
    *y = 2.0f;
    if (a > ATT_ALIGN_A_MIN * hn) {
        *y = (2.0f * b) / att_i_sqrtf((2.0f * hn) * a);
    }
    return true;
}

/* The attitude correction of the rest update (rotation vector dth, rad) applied to *q and the low-pass stages. */
static ATT_NOINLINE void att_mekf_rest_apply(const att_mekf_coeffs_t *c, att_mekf_state_t *st, att_quat_t *q, float dth0,
                                             float dth1, float dth2)
{
    const att_quat_t dq = att_mekf_exp(att_i_vec3(dth0, dth1, dth2));
    *q = att_i_quat_mul(dq, *q);
    if (c->lp_on) {
        st->lp1 = att_i_quat_rotate(dq, st->lp1);
        st->lp2 = att_i_quat_rotate(dq, st->lp2);
    }
}

/*
 * The zero-rate update's noise per sample and axis, (rad/s)^2: the mean square of w - b over the rest
 * (e2 = |w - b|^2 / 3 with the bias before this step's update; st->rest_e2 its running mean, gain
 * 1 / (n + 1) after n earlier updates, n counted up to rest_n: then a low-pass of gain 1 / (rest_n + 1);
 * rest_e2 and n are 0 at a rest's first update, so it takes e2 exactly; rest_n 0: e2 alone), at least
 * r_rest.
 */
static ATT_ALWAYS_INLINE float att_mekf_rest_noise(const att_mekf_coeffs_t *c, att_mekf_state_t *st,
                                                   const att_vec3_t *gyr)
{
    const att_vec3_t e = att_i_vec3_sub(*gyr, st->bias);
    const float e2 = att_i_vec3_dot(e, e) / 3.0f;
    const float k = 1.0f / ((float)st->rest_e2_n + 1.0f); /* n <= rest_n <= 2^24: exact but at 2^24 + 1 */
    st->rest_e2 = st->rest_e2 + (e2 - st->rest_e2) * k;
    if (st->rest_e2_n < c->rest_n) {
        st->rest_e2_n = st->rest_e2_n + 1u;
    }
    return (st->rest_e2 > c->r_rest) ? st->rest_e2 : c->r_rest;
}

/* One of the three scalar updates of att_mekf_rest_update (axis k, rate w_k, noise r): b, dth, P and the scale. */
static ATT_NOINLINE void att_mekf_rest_axis(att_mekf_state_t *st, float r, uint32_t k, float w_k, float *dth)
{
    float *p = st->p;
    float *sv = st->scale_v;
    const float sa = sv[3u + k];
    float b[3];
    float g[6];
    float sk;
    float ks;
    float ds;
    float y;
    uint32_t i;
    uint32_t j;
    b[0] = st->bias.x;
    b[1] = st->bias.y;
    b[2] = st->bias.z;
    ATT_MEKF_UNROLL
    for (i = 0u; i < 6u; i++) {
        g[i] = p[ATT_MEKF_S(i, 3u + k)];
    }
    sk = g[3u + k] + r;
    ks = 1.0f / sk;
    y = w_k - b[k];
    ds = att_mekf_scale_gain1(&st->p_scale, sa, sk, y);
    st->scale = st->scale + ds;
    ATT_MEKF_UNROLL
    for (i = 0u; i < 6u; i++) {
        const float gk = g[i] * ks;
        sv[i] = sv[i] - gk * sa;
        if (i < 3u) {
            dth[i] = dth[i] + (gk * y + sv[i] * ds);
        } else {
            b[i - 3u] = b[i - 3u] + (gk * y + sv[i] * ds);
        }
        ATT_MEKF_UNROLL
        for (j = i; j < 6u; j++) {
            p[ATT_MEKF_IX(i, j)] = p[ATT_MEKF_IX(i, j)] - gk * g[j];
        }
    }
    st->bias = att_i_vec3(b[0], b[1], b[2]);
}

/*
 * The zero-rate pseudo-measurement at rest: w_k = b_k + noise (r_rest) for k = 0, 1, 2, H = [0 e_k], as
 * three sequential scalar updates (exact for the diagonal noise): g = P e_(3+k), s = g_(3+k) + r_rest,
 * a = V_(3+k) (the scale's sensitivity: the measurement itself does not depend on the scale, w = b at
 * rest), ds from att_mekf_scale_gain1, V := V - g a / s, dx = g (w_k - b_k) / s + V ds, P := P - g g^T / s.
 * One call per axis keeps the frame small (the phase is rare). The attitude correction (through the
 * correlations) is applied to *q and the low-pass stages as in the accel update. During a recovery (rec,
 * step 6) the updates run with p_s = 0 (ds = 0) and p_scale is kept: the scale estimate is left alone.
 */
static ATT_NOINLINE void att_mekf_rest_update(const att_mekf_coeffs_t *c, att_mekf_state_t *st, const att_vec3_t *gyr,
                                              att_quat_t *q, bool rec)
{
    float dth[3] = {0.0f, 0.0f, 0.0f};
    const float ps = st->p_scale;
    const float r = att_mekf_rest_noise(c, st, gyr);
    if (rec) {
        st->p_scale = 0.0f;
    }
    att_mekf_rest_axis(st, r, 0u, gyr->x, dth);
    att_mekf_rest_axis(st, r, 1u, gyr->y, dth);
    att_mekf_rest_axis(st, r, 2u, gyr->z, dth);
    if (rec) {
        st->p_scale = ps;
    }
    att_mekf_rest_apply(c, st, q, dth[0], dth[1], dth[2]); /* a tail call: its frame replaces this one */
}

/* What the phases of a step pass on (in memory: nothing float stays in registers across the calls). */
typedef struct {
    att_quat_t q; /**< the attitude (not normalised until the end of the step) */
    att_vec3_t v; /**< R a of the predicted attitude, m/s^2, earth frame */
    float e2;     /**< (|a|/g - 1)^2 of a usable accel sample (0 when not needed) */
    float mnorm;  /**< |m| of a usable mag sample, uT */
    float mz;     /**< the vertical (earth z) field of a usable mag sample, uT (the learnt reference) */
    uint32_t use; /**< ATT_MAGREF_ACCEPTED / ATT_MAGREF_GATED for a sample tested against m0, else 0 */
    att_vec3_t m; /**< the mag sample minus the hard-iron offset, uT (hard_iron_tau > 0) */
} att_mekf_work_t;

/* Step 1a: integration of (1 + s)(w - b); returns qa, the attitude process noise of the step. */
static ATT_NOINLINE float att_mekf_integrate(const att_mekf_coeffs_t *c, const att_mekf_state_t *st,
                                             const att_vec3_t *gyr, att_mekf_work_t *wk)
{
    const att_vec3_t w = att_i_vec3_scale(att_i_vec3_sub(*gyr, st->bias), 1.0f + st->scale);
    wk->q = att_i_quat_mul(wk->q, att_mekf_exp(att_i_vec3_scale(w, c->dt)));
    return c->qa + c->qw * att_i_vec3_dot(w, w);
}

/*
 * Step 1b: the rotation matrix R of the prediction, P := Phi P Phi^T + Q, the scale sensitivity
 * V_theta := V_theta + dt R (u - V_b) (u = w - b of a usable gyro sample, else 0: no rotation was
 * integrated), v = R a.
 */
static ATT_NOINLINE void att_mekf_propagate(const att_mekf_coeffs_t *c, att_mekf_state_t *st, const att_vec3_t *acc,
                                            const att_vec3_t *gyr, float qa, att_mekf_work_t *wk)
{
    const att_quat_t q = wk->q;
    float *sv = st->scale_v;
    float r[9];
    float ux = -sv[3];
    float uy = -sv[4];
    float uz = -sv[5];
    att_i_quat_to_matrix(q, r);
    att_mekf_predict(st->p, r, c->half_dt, c->dt, qa, c->qb);
    if (gyr != NULL) {
        ux = (gyr->x - st->bias.x) - sv[3];
        uy = (gyr->y - st->bias.y) - sv[4];
        uz = (gyr->z - st->bias.z) - sv[5];
    }
    sv[0] = sv[0] + c->dt * (r[0] * ux + r[1] * uy + r[2] * uz);
    sv[1] = sv[1] + c->dt * (r[3] * ux + r[4] * uy + r[5] * uz);
    sv[2] = sv[2] + c->dt * (r[6] * ux + r[7] * uy + r[8] * uz);
    wk->v = att_i_vec3(r[0] * acc->x + r[1] * acc->y + r[2] * acc->z, r[3] * acc->x + r[4] * acc->y + r[5] * acc->z,
                       r[6] * acc->x + r[7] * acc->y + r[8] * acc->z);
}

/*
 * The accel low-pass (see att_mekf.h): a second-order Butterworth section on the earth-frame specific
 * force u, natural frequency 1 / (sqrt(2) tau_acc_lp) and damping 1 / sqrt(2), in two states with lp2 the
 * output: lp1 := lp1 + (k (u - lp2) - kq (lp1 - lp2)), lp2 := lp2 + k2 (lp1 - lp2), kq = (sqrt(2) - 1) k,
 * k2 = k except during a recovery's running mean, where it is 1 (att_i_recovery_lp_gain: with lp1 = lp2
 * the section's next update is the running mean's).
 * Its lag at low frequencies (2 tau_acc_lp) is that of two cascaded first-order stages of time constant
 * tau_acc_lp, its attenuation of faster linear accelerations twice theirs. Stable for every k in (0, 1].
 */
static ATT_ALWAYS_INLINE void att_mekf_lowpass(att_vec3_t u, float k, float k2, att_vec3_t *lp1, att_vec3_t *lp2)
{
    const float kq = ATT_MEKF_BW_Q * k;
    const att_vec3_t d = att_i_vec3_sub(*lp1, *lp2);
    const att_vec3_t e = att_i_vec3_sub(u, *lp2);
    *lp1 = att_i_vec3_add(*lp1, att_i_vec3_sub(att_i_vec3_scale(e, k), att_i_vec3_scale(d, kq)));
    *lp2 = att_i_vec3_add(*lp2, att_i_vec3_scale(att_i_vec3_sub(*lp1, *lp2), k2));
}

/*
 * The low-pass gain during a recovery (step 6): the running mean of att_i_recovery_lp_gain (att_core.h)
 * until it is below the floor over 2 sqrt(2) (ATT_MEKF_REC_MEAN_END), then the floor: after a clipping
 * gyro sample the low-pass's gain of the moment st->k_lp (k_lp, or k_lp_no_rest before the first rest);
 * in the recovery of the start k_lp_rec, the fast exponential window, since there the gyro bias is not
 * known yet and the samples of a long mean would be turned by it. *k2: the second stage's gain (1 while
 * the mean runs, then the floor).
 */
static ATT_ALWAYS_INLINE float att_mekf_rec_lp_gain(const att_mekf_coeffs_t *c, att_mekf_state_t *st, float *k2)
{
    const float floor = st->rec_clip ? st->k_lp : c->k_lp_rec;
    *k2 = floor;
    return att_i_recovery_lp_gain(&st->rec_lp_n, floor, ATT_MEKF_REC_MEAN_END * floor, k2);
}

/*
 * Step 2: the accelerometer update with a usable sample (e2 = (|a|/g - 1)^2); returns its flags. During a
 * recovery (rec, step 6) the low-pass runs at att_mekf_rec_lp_gain, a gate rejection is recovered at once, the bias is
 * a consider state and the scale-factor estimate is left alone.
 */
static ATT_NOINLINE uint32_t att_mekf_accel(const att_mekf_coeffs_t *c, att_mekf_state_t *st, att_mekf_work_t *wk,
                                            bool rec)
{
    uint32_t flags = 0u;
    att_vec3_t lp1 = st->lp1;
    att_vec3_t lp2 = st->lp2;
    att_vec3_t u = wk->v;
    float cw;
    float cx;
    float cy;
    float n;
    float y0;
    float y1;
    float rn;
    att_mekf_innov_t v;
    if (c->lp_on) {
        if (!st->lp_valid) {
            lp1 = u; /* the first sample starts the low-pass */
            lp2 = u;
        }
        float k2 = st->k_lp;
        const float k1 = rec ? att_mekf_rec_lp_gain(c, st, &k2) : st->k_lp;
        att_mekf_lowpass(u, k1, k2, &lp1, &lp2);
        u = lp2;
    }
    if (!att_i_align_up(u, &cw, &cx, &cy, &n)) {
        return 0u;
    }
    y0 = 2.0f * cx;
    y1 = 2.0f * cy;
    rn = c->r_acc * (1.0f + c->r_accel * wk->e2);
    v = att_mekf_innov(st->p, rn, y0, y1);
    if (c->gate > 0.0f && v.dn > c->gate * v.det) {
        if (st->gated < ATT_MEKF_GATED_MAX) {
            st->gated = st->gated + 1u;
        }
        if (!(rec || (c->n_recover > 0u && st->gated >= c->n_recover))) {
            return ATT_FLAG_ACCEL_REJECTED; /* outside the chi-square gate: not applied */
        }
        v = att_mekf_recover(c, st->p, rn, y0, y1);
    }
    if (!(v.det > 0.0f)) {
        return ATT_FLAG_NUMERIC; /* cannot happen with a conditioned P */
    }
    {
        float dx[6];
        att_quat_t dq;
        float ds;
        float ps_off = 0.0f; /* during a recovery: p_s 0 for this update, ds = 0, st->p_scale kept */
        st->gated = 0u;
        ds = att_mekf_accel_apply(c, st->p, v, y0, y1, dx, st->scale_v, rec ? &ps_off : &st->p_scale,
                                  rec ? 3u : 6u);
        st->scale = st->scale + ds;
        dq = att_mekf_exp(att_i_vec3(dx[0], dx[1], dx[2]));
        wk->q = att_i_quat_mul(dq, wk->q);
        st->bias = att_i_vec3(st->bias.x + dx[3], st->bias.y + dx[4], st->bias.z + dx[5]);
        if (c->lp_on) {
            st->lp1 = att_i_quat_rotate(dq, lp1);
            st->lp2 = att_i_quat_rotate(dq, lp2);
            st->lp_valid = true;
        }
        flags |= ATT_FLAG_BIAS_UPDATED;
    }
    return flags;
}

/* Step 6: the recovery's process noise, added to the attitude variances after the prediction. */
static ATT_ALWAYS_INLINE void att_mekf_rec_noise(const att_mekf_coeffs_t *c, float *p)
{
    p[ATT_MEKF_IX(0u, 0u)] = p[ATT_MEKF_IX(0u, 0u)] + c->q_rec_tilt;
    p[ATT_MEKF_IX(1u, 1u)] = p[ATT_MEKF_IX(1u, 1u)] + c->q_rec_tilt;
    p[ATT_MEKF_IX(2u, 2u)] = p[ATT_MEKF_IX(2u, 2u)] + c->q_rec_head;
}

/*
 * Step 3: the heading update with a usable mag sample of norm mnorm (m0 known); returns its flags. The
 * heading correction turns the estimate's earth frame about z, so the low-pass stages are turned with it
 * (att_mekf_lp_turn).
 */
static ATT_NOINLINE uint32_t att_mekf_mag(const att_mekf_coeffs_t *c, att_mekf_state_t *st, att_quat_t *q,
                                          const att_vec3_t *mag, att_mekf_work_t *wk)
{
    const att_vec3_t me = att_i_quat_rotate(*q, *mag);
    float y;
    float dz;
    att_vec3_t db;
    att_quat_t dq;
    wk->mz = me.z;
    if (!att_mekf_heading(st, me, wk->mnorm, &y, &wk->use) || !att_mekf_mag_apply(c, st, st->p, y, &dz, &db)) {
        return ATT_FLAG_MAG_REJECTED;
    }
    dq = att_mekf_exp(att_i_vec3(0.0f, 0.0f, dz));
    *q = att_i_quat_mul_z(dq.w, dq.z, *q);
    st->bias = att_i_vec3_add(st->bias, db);
    if (c->lp_on) {
        att_mekf_lp_turn(st, dq.w, dq.z);
    }
    return ATT_FLAG_BIAS_UPDATED;
}

/*
 * The end of a block of the learnt reference's statistics (att_magref.h): the reference's norm and dip
 * follow the accepted samples, or a steady new field becomes the reference, its horizontal direction
 * kept; the heading is then unknown against the new field: its variance p_max, its correlations zero
 * (att_mekf_yaw_reset), so the next samples set it at the pace their noise allows (fast convergence).
 */
static ATT_NOINLINE void att_mekf_ref_block(const att_mekf_coeffs_t *c, att_mekf_state_t *st)
{
    float n;
    float s;
    const uint32_t out = att_i_magref_block(&c->ref, &st->ref, st->m0, &n, &s);
    if (out != ATT_MAGREF_KEEP) {
        (void)att_mekf_set_m0(c, st, att_i_magref_m0(st->m0, n, s, c->decl_sin, c->decl_cos)); /* n > 0 */
        if (out == ATT_MAGREF_ADOPT) {
            att_mekf_yaw_reset(st, c->p_max);
        }
    }
}

#if ATT_WITH_HARD_IRON
/*
 * The hard-iron estimate's step (hard_iron_tau > 0; att_hardiron.h) from the gyro sample (the rate the
 * integration uses, (1 + s)(w - b)) and the raw mag sample; returns the sample the filter uses: with a
 * valid one, the raw sample minus the applied offset (in wk->m, its norm in wk->mnorm).
 */
static ATT_NOINLINE const att_vec3_t *att_mekf_hard_iron(const att_mekf_coeffs_t *c, att_mekf_state_t *st,
                                                        const att_vec3_t *gyr, bool gyro_ok, const att_vec3_t *mag,
                                                        bool mag_ok, att_mekf_work_t *wk)
{
    const att_vec3_t w = att_i_vec3_scale(att_i_vec3_sub(*gyr, st->bias), 1.0f + st->scale);
    att_i_hi_step(&c->hi, &st->hi, c->dt, w, gyro_ok && att_i_hi_gyro_ok(0u, *gyr, c->gyro_range), *mag, mag_ok);
    if (!mag_ok) {
        return mag;
    }
    wk->m = att_i_hi_correct(&st->hi, *mag);
    wk->mnorm = att_i_vec3_norm(wk->m);
    return &wk->m;
}
#endif

/*
 * One step: the sample checks, then the phases (each its own leaf function, so that the stack holds one
 * phase's frame at a time): rest update, propagation, accel update, mag update, conditioning.
 */
static ATT_NOINLINE uint32_t att_mekf_update(att_mekf_t *f, const att_vec3_t *gyr_in, const att_vec3_t *acc_in,
                                                  const att_vec3_t *mag_in)
{
    const att_vec3_t gyr = att_i_vec3(gyr_in->x, gyr_in->y, gyr_in->z);
    const att_vec3_t acc = att_i_vec3(acc_in->x, acc_in->y, acc_in->z);
    const att_mekf_coeffs_t *c;
    att_mekf_state_t *st;
    uint32_t flags;
    uint32_t accel_flags;
    float n2;
    bool gyro_ok;
    bool accel_ok;
    bool mag_ok = false;
    bool rest;
    bool rec;
    att_mekf_work_t wk;
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
    wk.e2 = 0.0f;
    wk.mnorm = 0.0f;
    wk.mz = 0.0f;
    wk.use = 0u;
    if (accel_ok && c->need_norm) {
        const float e = att_i_sqrtf(n2) / c->gravity - 1.0f;
        wk.e2 = e * e;
        if (c->accel_reject > 0.0f && att_i_absf(e) > c->accel_reject) {
            flags |= ATT_FLAG_ACCEL_REJECTED;
        }
    }
    if (c->use_mag) {
        const uint32_t mag_flags = att_i_sensor_check_mag(*mag_in, c->mag_range, &wk.mnorm);
        mag_ok = (mag_flags == 0u);
        flags |= mag_flags;
#if ATT_WITH_HARD_IRON
        if (c->hi.on) {
            mag_in = att_mekf_hard_iron(c, st, gyr_in, gyro_ok, mag_in, mag_ok, &wk);
        }
#endif
    }
    {
        const att_vec3_t d = att_i_vec3_sub(gyr, st->bias);
        const float pb = (st->p[ATT_MEKF_IX(3u, 3u)] + st->p[ATT_MEKF_IX(4u, 4u)]) + st->p[ATT_MEKF_IX(5u, 5u)];
        const float w = ATT_MEKF_REST_SIGMA2 * pb; /* at most ATT_BIAS_UNKNOWN2 (its value at the defaults) */
        const float gate = (c->rest_gyro2 > 0.0f) ? c->rest_gyro2 + ((w > ATT_BIAS_UNKNOWN2) ? ATT_BIAS_UNKNOWN2 : w) : 0.0f;
        rest = gyro_ok && accel_ok && att_i_vec3_dot(d, d) < gate && n2 > c->acc2_lo && n2 < c->acc2_hi;
    }

    if (!st->initialised) {
        flags |= accel_ok ? att_mekf_start(c, st, acc_in, mag_in, mag_ok) : ATT_FLAG_NOT_READY;
        st->steps = st->steps + 1u;
        st->flags = flags;
        return flags;
    }

    /* 6. the recovery after a clipping gyro: its counter, then the phases below */
    (void)att_i_recovery_step(gyr, c->clip, c->rec_n, &st->rec_left, &st->rec_lp_n);
    if (c->rec_n > 0u && st->rec_left == c->rec_n) {
        st->lp_valid = false; /* a clipping sample: the low-pass holds samples turned by a wrong rotation */
        st->rec_clip = true;
        st->head_known = false; /* and the heading lost rotation (a 6-axis output's cov[2]) */
    }
    rec = st->rec_left > 0u;
    if (rec) {
        flags |= ATT_FLAG_INITIALISED;
    }

    /* 0. rest: the zero-rate pseudo-measurement */
    wk.q = st->q;
    {
        if (!rest) {
            st->rest_count = 0u;
            st->rest_e2 = 0.0f; /* the next rest measures its own noise */
            st->rest_e2_n = 0u;
        } else if (st->rest_count < c->rest_n) {
            st->rest_count = st->rest_count + 1u;
        }
        if (rest && st->rest_count >= c->rest_n) {
            att_mekf_rest_update(c, st, gyr_in, &wk.q, rec);
            st->rested = true; /* the bias measured: the accel low-pass's longer lag pays from now on */
            st->k_lp = c->k_lp;
            flags |= ATT_FLAG_AT_REST | ATT_FLAG_BIAS_UPDATED;
        }
    }
    /* 1. prediction, 2. accel update, 3. mag update */
    att_mekf_propagate(c, st, acc_in, gyro_ok ? gyr_in : NULL,
                       gyro_ok ? att_mekf_integrate(c, st, gyr_in, &wk) : c->qa, &wk);
    if (rec) {
        att_mekf_rec_noise(c, st->p);
    }
    if (accel_ok && (flags & ATT_FLAG_ACCEL_REJECTED) == 0u) {
        flags |= att_mekf_accel(c, st, &wk, rec);
    }
    if (mag_ok) {
        flags |= st->m0_valid ? att_mekf_mag(c, st, &wk.q, mag_in, &wk) : att_mekf_mag_first(c, st, &wk.q, mag_in);
    }
    if (st->m0_valid && att_i_magref_count(&c->ref, &st->ref, wk.use, wk.mnorm, wk.mz)) {
        att_mekf_ref_block(c, st);
    }
    /* 4. conditioning of P and the scale estimate, 5. normalisation */
    flags |= att_mekf_condition(c, st->p);
    flags |= att_mekf_scale_bound(st);
    if (att_i_quat_normalize_bounded(wk.q, &wk.q)) {
        st->q = wk.q;
    } else {
        flags |= ATT_FLAG_NUMERIC; /* keep the attitude from before the step */
    }
    st->steps = st->steps + 1u;
    st->flags = flags;
    return flags;
}

uint32_t att_mekf_step_out(att_mekf_t *restrict f, const att_sample_t *restrict in, att_output_t *restrict out)
{
    const uint32_t flags = att_mekf_update(f, &in->gyr, &in->acc, &in->mag);
    if (out != NULL) {
        out->q = f->st.q;
        out->gyro_bias = f->st.bias;
        out->flags = flags;
        out->steps = f->st.steps;
        out->valid = ATT_OUT_Q | ATT_OUT_BIAS;
    }
    return flags;
}

uint32_t att_mekf_step(att_mekf_t *f, att_vec3_t gyr, att_vec3_t acc, att_vec3_t mag)
{
    return att_mekf_update(f, &gyr, &acc, &mag);
}

/* --- hooks of the kind table (att_kinds.h) ------------------------------------------------- */

void att_mekf_preset(att_mekf_settings_t *s, att_preset_t preset, float dt)
{
    (void)preset;
    att_mekf_settings_default(s, dt); /* the seed preset is the defaults: mekf has no earlier settings */
}

float att_mekf_period(const att_mekf_settings_t *s)
{
    return s->dt;
}

/*
 * The output's heading variance (cov[2]), rad^2: P's with the magnetometer; without it (use_mag off, a
 * 6-axis filter, whose heading nothing observes) P's only from a set heading on (att_mekf_yaw_to, gain 1)
 * to the next clipping gyro sample, at most pi^2/3, and pi^2/3 (unknown) otherwise.
 */
static float att_mekf_cov_heading(const att_mekf_t *f)
{
    const float v = f->st.p[ATT_MEKF_IX(2u, 2u)];
    if (f->c.use_mag || (f->st.head_known && v < ATT_COV_UNKNOWN)) {
        return v;
    }
    return ATT_COV_UNKNOWN;
}

void att_mekf_output(const att_mekf_t *f, att_output_t *out)
{
    out->q = f->st.q;
    out->gyro_bias = f->st.bias;
    out->flags = f->st.flags;
    out->steps = f->st.steps;
    out->valid = ATT_OUT_Q | ATT_OUT_BIAS;
    out->cov[0] = f->st.p[0]; /* packed upper triangle: the diagonal at 0, 6, 11, 15, 18, 20 */
    out->cov[1] = f->st.p[6];
    out->cov[2] = att_mekf_cov_heading(f);
    out->cov[3] = (f->st.p[15] + f->st.p[18] + f->st.p[20]) / 3.0f;
}

att_heading_t att_mekf_heading_kind(const att_mekf_t *f)
{
    return f->c.use_mag ? ATT_HEADING_SET : ATT_HEADING_UPDATE;
}

att_status_t att_mekf_yaw_to(att_mekf_t *f, float target, float gain)
{
    float s;
    float c;
    att_vec3_t h;
    const att_status_t st = att_yaw_q(&f->st.q, &f->st.lp1, &f->st.lp2, f->st.initialised, target, gain, &s, &c);
    if (st == ATT_OK && gain == 1.0f) {
        if (!f->c.use_mag) {
            att_mekf_yaw_reset(&f->st, f->c.qa); /* a set heading is exact: one step's noise (cov[2]) */
        }
        /* with the mag the reference field turns with the attitude below: north is relabelled, the
         * heading's uncertainty against the field (P) is unchanged */
        f->st.head_known = true;
    }
    if (st == ATT_OK) {
        /* the heading measurement's tilt entries (-c r_x, -c r_y) are linear in m0_ref: they turn with it */
        h = att_i_yaw_vec(att_i_vec3(f->st.mag_hx, f->st.mag_hy, 0.0f), c, s);
        f->st.m0 = att_i_yaw_vec(f->st.m0, c, s);
        f->st.m0_ref = att_i_yaw_vec(f->st.m0_ref, c, s);
        f->st.mag_hx = h.x;
        f->st.mag_hy = h.y;
    }
    return st;
}

bool att_mekf_set_gain(att_mekf_settings_t *s, att_gain_t gain, float value)
{
    if (gain == ATT_GAIN_DECLINATION) {
        s->declination = value; /* the only SET_GAIN parameter of mekf (docs/can.md) */
        return true;
    }
    return false;
}
