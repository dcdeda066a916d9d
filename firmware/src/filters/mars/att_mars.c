/**
 * @file att_mars.c
 * @brief 9-axis complementary filter with magnetometer (see att_mars.h).
 * Mirrored by host/attica/reference/mars.py.
 */
#include "../../math/att_fp.h"

#include "../../core/att_core.h"
#include "../att_kinds.h"
#include "../att_yaw.h"
#include "att_mars_checks.h"
#include "attica/att_mars.h"
#include "attica/att_math.h"
#include "attica/att_sensor.h"

#define ATT_MARS_PIO2_F 0x1.921fb6p+0f
#define ATT_MARS_MAG_ACCEPTED ATT_MAGREF_ACCEPTED /* the sample passed the norm and dip tests */
#define ATT_MARS_MAG_GATED ATT_MAGREF_GATED       /* the sample failed them */
#define ATT_MARS_GAP_MAX 255u /* steps without a mag sample counted (a longer gap counts 255: an outage) */

/* The covariance model's default densities (docs/filters.md "Covariance": how they were chosen). */
#define ATT_MARS_GYRO_NOISE 0.002f /* rad/s/sqrt(Hz) */
#define ATT_MARS_ACCEL_NOISE 0.24f /* m/s^2/sqrt(Hz) */
#define ATT_MARS_MAG_NOISE 3.5f    /* uT/sqrt(Hz) */

void att_mars_settings_default(att_mars_settings_t *settings, float dt)
{
    if (settings == NULL) {
        return;
    }
    settings->dt = dt;
    settings->alpha_acc = 1.0f;
    settings->alpha_mag = 0.0f;
    settings->tau_acc = 0.0f;
    settings->tau_mag = 20.0f;
    settings->mag_mode = ATT_MARS_MAG_HORIZONTAL;
    settings->gravity = 9.80665f;
    settings->accel_reject = 0.0f;
    settings->accel_range = 156.9064f; /* 16 g */
    settings->gyro_range = 34.906586f; /* 2000 deg/s */
    settings->mag_range = 1000.0f;
    settings->mag_norm_reject = 0.2f;
    settings->mag_dip_reject = 0.3f; /* about 17 deg */
    settings->bias_init = att_i_vec3(0.0f, 0.0f, 0.0f);
    settings->init_from_sensors = true;
    settings->q_init = att_i_quat_identity();
    settings->m0_init = att_i_vec3(0.0f, 0.0f, 0.0f);
    settings->integration = ATT_INTEGRATE_ROTVEC;
    settings->tau_acc_lp = 1.3f;
    settings->bias_mode = ATT_BIAS_AT_REST;
    settings->bias_n_max = 1000u;
    settings->rest_gyro = 0.05f;
    settings->rest_accel = 0.5f;
    settings->rest_time = 0.5f;
    settings->mag_ref_tau = 20.0f;
    settings->mag_new_time = 20.0f;
    settings->tau_mag_fast = 2.0f;
    settings->tau_bias_mag = 0.0f; /* off: on BROAD it costs 0.07 deg (docs/filters.md) */
    settings->recovery_time = 2.0f;
    settings->declination = 0.0f;
    settings->gyro_noise = ATT_MARS_GYRO_NOISE;
    settings->accel_noise = ATT_MARS_ACCEL_NOISE;
    settings->mag_noise = ATT_MARS_MAG_NOISE;
    settings->hard_iron_tau = 0.0f;  /* s: the hard-iron estimate is opt-in (60 s: docs/filters.md) */
    settings->hard_iron_rate = 1.0f; /* uT/s */
}

att_status_t att_mars_settings_validate(const att_mars_settings_t *s)
{
    bool ok;
    if (s == NULL) {
        return ATT_ERR_NULL;
    }
    ok = true ATT_MARS_CHECKS(ATT_CHECK_AND);
    return ok ? ATT_OK : ATT_ERR_SETTINGS;
}

static float att_mars_gain(float tau, float alpha, float dt)
{
    return (tau > 0.0f) ? dt / (tau + dt) : alpha;
}

/* The coefficients of the reference field's estimation and of the fast phase (att_mars.h, step 3). */
static void att_mars_ref_coeffs(att_mars_coeffs_t *c, const att_mars_settings_t *s)
{
    float t;
    att_i_magref_params(&c->ref, s->dt, s->mag_ref_tau, s->mag_new_time, s->mag_norm_reject, s->mag_dip_reject);
    t = (float)c->ref.blk_n * s->dt;
    c->k_fast = (s->tau_mag_fast > 0.0f) ? s->dt / (s->tau_mag_fast + s->dt) : c->k_mag;
    c->k_fast1 = 1.0f - c->k_fast;
    c->fast_n = att_sensor_samples(3.0f * s->tau_mag_fast, t);
    c->fast_start_n = c->fast_n;
    if (c->fast_n > 0u && s->tau_acc_lp > 0.0f) {
        c->fast_start_n = att_sensor_samples(3.0f * s->tau_mag_fast + 6.0f * s->tau_acc_lp, t);
    }
    c->bias_mag_on = s->tau_bias_mag > 0.0f && s->mag_mode == ATT_MARS_MAG_HORIZONTAL &&
                     (s->bias_mode == ATT_BIAS_AT_REST || s->bias_mode == ATT_BIAS_RUNNING);
    /* a time constant below one sample period acts within the sample: 1 / max(tau_bias_mag, dt), finite
       for every accepted setting (1 / 1e-45 is Inf, and Inf times a zero correction NaN: F14) */
    c->k_bias_mag = c->bias_mag_on ? 1.0f / ((s->tau_bias_mag > s->dt) ? s->tau_bias_mag : s->dt) : 0.0f;
}

/* The coefficients of the recovery after a clipping gyro (att_mars.h); after k_lp and k_fast. */
static void att_mars_rec_coeffs(att_mars_coeffs_t *c, const att_mars_settings_t *s)
{
    const float k = att_i_recovery_params(s->recovery_time, s->gyro_range, s->dt, &c->rec_n, &c->clip);
    c->k_rec = (k > c->k_mag) ? k : c->k_mag;
    c->k_rec1 = 1.0f - c->k_rec;
}

/* att_i_cov_tilt out of line (init only: one copy for both calls), 0 gain: the tilt is not observed. */
static ATT_NOINLINE float att_mars_cov_tilt(float dt, float k_lp, float k, float s2, float a2)
{
    return (k > 0.0f) ? att_i_cov_tilt(dt, k_lp, k, s2, a2) : ATT_COV_TILT_MAX;
}

/* The covariance model's coefficients (att_mars.h, step 5); after the gains and the recovery's. */
static void att_mars_cov_coeffs(att_mars_coeffs_t *c, const att_mars_settings_t *s)
{
    const float an = s->accel_noise / s->gravity;
    const float a2 = an * an;
    c->gyro_noise2 = s->gyro_noise * s->gyro_noise;
    c->mag_noise2 = s->mag_noise * s->mag_noise;
    c->var_step = c->gyro_noise2 * s->dt;
    c->var_tilt = att_mars_cov_tilt(s->dt, c->k_lp, c->k_acc, c->gyro_noise2, a2);
}

static void att_mars_coeffs(att_mars_coeffs_t *c, const att_mars_settings_t *s)
{
    c->dt = s->dt;
    c->k_acc = att_mars_gain(s->tau_acc, s->alpha_acc, s->dt);
    c->k_mag = att_mars_gain(s->tau_mag, s->alpha_mag, s->dt);
    c->k_mag1 = 1.0f - c->k_mag;
    c->k_lp = (s->tau_acc_lp > 0.0f) ? s->dt / (s->tau_acc_lp + s->dt) : 0.0f;
    c->gravity = s->gravity;
    c->accel_reject = s->accel_reject;
    c->accel_range2 = s->accel_range * s->accel_range;
    c->gyro_range = s->gyro_range;
    c->mag_range = s->mag_range;
    c->mag_norm_reject = s->mag_norm_reject;
    c->mag_dip_reject = s->mag_dip_reject;
    att_i_bias_params(&c->bias, s->bias_mode, s->bias_n_max, s->rest_gyro, s->rest_accel,
                      att_sensor_samples(s->rest_time, s->dt), s->gravity);
    (void)att_i_quat_normalize(s->q_init, &c->q_init);
    c->m0_init = s->init_from_sensors ? att_i_vec3(0.0f, 0.0f, 0.0f) : s->m0_init;
    c->bias_init = (s->bias_mode == ATT_BIAS_OFF) ? att_i_vec3(0.0f, 0.0f, 0.0f) : s->bias_init;
    c->integration = (uint8_t)s->integration;
    c->mag_mode = (uint8_t)s->mag_mode;
    c->init_from_sensors = s->init_from_sensors;
    c->lp_on = c->k_lp > 0.0f;
    c->reject_on = s->accel_reject > 0.0f;
    c->full = (c->k_acc == 1.0f);
    att_mars_ref_coeffs(c, s);
    att_i_hi_params(&c->hi, s->dt, s->hard_iron_tau, s->hard_iron_rate, s->mag_norm_reject,
                    s->mag_range);
    att_mars_rec_coeffs(c, s);
    att_mars_cov_coeffs(c, s);
    c->decl = s->declination;
    c->decl_sin = att_sinf(s->declination);
    c->decl_cos = att_cosf(s->declination);
}

/* Dip angle of v: atan2(v.z, |v_xy|), rad. */
static float att_mars_dip(att_vec3_t v)
{
    return att_atan2f(v.z, att_i_sqrtf(v.x * v.x + v.y * v.y));
}

/*
 * Derived limits of the reference field m0 (state m0): mode-dependent unit direction and fallback
 * axis, the accepted |m| interval (norm rejection) and the accepted interval of sin(dip) (dip
 * rejection: dip in [dip0 - t, dip0 + t], limited to [-pi/2, pi/2] where sin is monotonic).
 */
static void att_mars_m0_limits(const att_mars_coeffs_t *c, att_mars_state_t *st)
{
    const att_vec3_t up = att_i_vec3(0.0f, 0.0f, 1.0f);
    const float norm = att_i_vec3_norm(st->m0);
    att_vec3_t unit;
    att_vec3_t perp;
    (void)att_i_vec3_normalize(st->m0, &unit);
    if (c->mag_mode == (uint8_t)ATT_MARS_MAG_FULL) {
        st->m0_ref = unit;
        st->m0_ref_ok = true;
        if (!att_i_vec3_normalize(att_i_vec3_cross(unit, up), &perp)) {
            perp = att_i_vec3(1.0f, 0.0f, 0.0f);
        }
        st->m0_perp = perp;
    } else {
        st->m0_ref_ok = att_i_vec3_normalize(att_i_vec3(st->m0.x, st->m0.y, 0.0f), &st->m0_ref);
        st->m0_perp = up;
    }
    st->m0_lo = 0.0f;
    st->m0_hi = c->mag_range;
    if (c->mag_norm_reject > 0.0f) {
        st->m0_lo = norm * (1.0f - c->mag_norm_reject);
        st->m0_hi = norm * (1.0f + c->mag_norm_reject);
    }
    if (!st->m0_ref_ok) {
        st->m0_lo = INFINITY; /* no usable reference direction: every sample is rejected */
    }
    st->dip_lo = -2.0f;
    st->dip_hi = 2.0f;
    if (c->mag_dip_reject > 0.0f) {
        const float dip = att_mars_dip(st->m0);
        const float lo = dip - c->mag_dip_reject;
        const float hi = dip + c->mag_dip_reject;
        float sn;
        float cs;
        if (lo > -ATT_MARS_PIO2_F) {
            att_i_sincosf(lo, &sn, &cs); /* att_sinf */
            st->dip_lo = sn;
        }
        if (hi < ATT_MARS_PIO2_F) {
            att_i_sincosf(hi, &sn, &cs);
            st->dip_hi = sn;
        }
    }
}

/* Set the reference field m0 and start a new block; returns false (and changes nothing) when m0 has no
   direction. */
static bool att_mars_set_m0(const att_mars_coeffs_t *c, att_mars_state_t *st, const att_vec3_t *m0)
{
    att_vec3_t unit;
    if (!att_i_vec3_normalize(*m0, &unit)) {
        return false;
    }
    st->m0 = *m0;
    st->m0_valid = true;
    att_mars_m0_limits(c, st);
    att_i_magref_clear(&st->ref);
    return true;
}

att_status_t att_mars_init(att_mars_t *f, const att_mars_settings_t *settings)
{
    att_status_t st;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    st = att_mars_settings_validate(settings);
    if (st != ATT_OK) {
        return st;
    }
    att_mars_coeffs(&f->c, settings);
    att_mars_reset(f);
    return ATT_OK;
}

att_status_t att_mars_retune(att_mars_t *f, const att_mars_settings_t *settings)
{
    att_status_t st;
    bool hi_was_on;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    st = att_mars_settings_validate(settings);
    if (st != ATT_OK) {
        return st;
    }
    hi_was_on = f->c.hi.on;
    att_mars_coeffs(&f->c, settings);
    if (f->c.hi.on != hi_was_on) {
        att_i_hi_reset(&f->st.hi); /* turned on or off: the estimate starts again (off: no offset applied) */
    }
    att_i_hi_retune(&f->c.hi, &f->st.hi);
    att_i_bias_retune(&f->c.bias, f->c.bias_init, &f->st.bias, &f->st.bias_n, &f->st.rest_count,
                      &f->st.rest_gate2);
    if (f->st.m0_valid) {
        att_mars_m0_limits(&f->c, &f->st);
    }
    if (f->st.fast_left > f->c.fast_start_n) {
        f->st.fast_left = f->c.fast_start_n;
    }
    if (f->st.rec_left > f->c.rec_n) {
        f->st.rec_left = f->c.rec_n; /* a recovery no longer than the new recovery_time (0: ended) */
    }
    return ATT_OK;
}

void att_mars_reset(att_mars_t *f)
{
    const att_vec3_t zero = att_i_vec3(0.0f, 0.0f, 0.0f);
    att_mars_state_t *st;
    if (f == NULL) {
        return;
    }
    st = &f->st;
    st->q = f->c.q_init;
    st->bias = f->c.bias_init;
    st->lp1 = att_i_vec3(0.0f, 0.0f, f->c.gravity);
    st->lp2 = st->lp1;
    st->m0 = zero;
    st->m0_ref = zero;
    st->m0_perp = zero;
    st->m0_lo = 0.0f;
    st->m0_hi = 0.0f;
    st->dip_lo = 0.0f;
    st->dip_hi = 0.0f;
    st->bias_n = 0u;
    st->rest_count = 0u;
    st->rest_gate2 = f->c.bias.rest_first2;
    st->steps = 0u;
    st->flags = 0u;
    st->fast_left = 0u;
    st->acc_step = 0u;
    st->mag_step = 0u;
    st->mag_gap = 0u;
    st->mag_period = 0u;
    st->mag_gap_step = 0u;
    st->rec_left = 0u;
    st->rec_lp_n = 0u;
    st->rec_clip = false;
    att_i_magref_reset(&st->ref);
    att_i_hi_reset(&st->hi);
    st->m0_ref_ok = false;
    st->m0_valid = false;
    st->initialised = !f->c.init_from_sensors;
    if (!att_mars_vec3_is_zero(f->c.m0_init)) {
        (void)att_mars_set_m0(&f->c, st, &f->c.m0_init); /* succeeds: checked by the settings validation */
    }
}

/*
 * The out-of-line helpers of the step below take and return vectors and quaternions through pointers
 * (codegen note C1, docs/architecture.md); the values are the same.
 */

/* First-order quaternion integration q + (0.5 q (x) (0, w)) dt (not normalised). */
static inline att_quat_t att_mars_integrate(att_quat_t q, att_vec3_t w, float dt)
{
    const att_quat_t p = att_i_quat_mul(q, att_i_quat(0.0f, w.x, w.y, w.z));
    return att_i_quat(q.w + p.w * 0.5f * dt, q.x + p.x * 0.5f * dt, q.y + p.y * 0.5f * dt, q.z + p.z * 0.5f * dt);
}

/* att_quat_from_rotvec (the large angles of att_mars_rotvec), the vector as scalars. */
static ATT_NOINLINE void att_mars_rotvec_large(float x, float y, float z, att_quat_t *out)
{
    *out = att_i_quat_from_rotvec(att_i_vec3(x, y, z));
}

/*
 * att_i_quat_from_rotvec_fast (att_core.h: the same series, the same operations) with the large angles
 * through att_mars_rotvec_large (codegen note C1).
 */
static ATT_ALWAYS_INLINE att_quat_t att_mars_rotvec(att_vec3_t rv)
{
    const float z = att_i_vec3_dot(rv, rv);
    att_quat_t q;
    float k;
    if (z <= ATT_ROTVEC_Z_SMALL) {
        k = ATT_ROTVEC_S0 + z * (ATT_ROTVEC_S1 + z * ATT_ROTVEC_S2);
        return att_i_quat(1.0f + z * (ATT_ROTVEC_C1 + z * ATT_ROTVEC_C2), rv.x * k, rv.y * k, rv.z * k);
    }
    att_mars_rotvec_large(rv.x, rv.y, rv.z, &q);
    return q;
}

/* The earth z axis (up) and x axis (the fallback axis of the accel correction). */
static const att_vec3_t att_mars_up = {0.0f, 0.0f, 1.0f};
static const att_vec3_t att_mars_xaxis = {1.0f, 0.0f, 0.0f};

/*
 * The rotation *qc in the earth frame that moves the unit vector v toward the unit reference r by the
 * fraction gain of the angle between them: Q(gain * angle, axis) with axis = v x r / |v x r| and
 * angle = atan2(|v x r|, v . r) (q := *qc * q). When v x r cannot be normalised, the axis is fallback.
 */
static ATT_NOINLINE void att_mars_rotation_toward(float vx, float vy, float vz, const att_vec3_t *rp,
                                                  const att_vec3_t *fallback, float gain, att_quat_t *qc)
{
    const att_vec3_t v = att_i_vec3(vx, vy, vz);
    const att_vec3_t r = *rp;
    const att_vec3_t c = att_i_vec3_cross(v, r);
    const float angle = att_atan2f(att_i_vec3_norm(c), att_i_vec3_dot(v, r));
    att_vec3_t axis;
    if (!att_i_vec3_normalize(c, &axis)) {
        axis = *fallback;
    }
    *qc = att_i_quat_from_axis_angle(axis, gain * angle);
}

/*
 * Yaw alignment: rotate q about the earth z axis so that the horizontal part of q mag q* points at the
 * azimuth D (the declination, east of north; D = 0: north, +y); *m0 = (|m_e,xy| sin D, |m_e,xy| cos D,
 * m_e,z) for the aligned attitude. Returns false when mag has no direction.
 */
static ATT_NOINLINE bool att_mars_align(const att_mars_coeffs_t *c, float qw, float qx, float qy, float qz,
                                        const att_vec3_t *mag, att_quat_t *q_out, att_vec3_t *m0)
{
    const att_quat_t q = att_i_quat(qw, qx, qy, qz);
    att_vec3_t me = att_i_quat_rotate(q, *mag);
    att_vec3_t unit;
    att_quat_t qa;
    float h;
    if (!att_i_vec3_normalize(me, &unit)) {
        return false;
    }
    qa = att_i_quat_mul(att_i_quat_from_axis_angle(att_mars_up, att_atan2f(me.x, me.y) - c->decl), q);
    if (!att_i_quat_normalize_bounded(qa, &qa)) {
        return false;
    }
    me = att_i_quat_rotate(qa, *mag);
    h = att_i_sqrtf(me.x * me.x + me.y * me.y);
    *m0 = att_i_vec3(h * c->decl_sin, h * c->decl_cos, me.z);
    *q_out = qa;
    return true;
}

/*
 * A step without a mag sample (MAG_ABSENT): the gap grows (up to 255). Its first step forgets the
 * previous gap (mag_period 0) unless the sample just before it ended one: only a gap that follows a gap
 * has a regular period to make up.
 */
static ATT_NOINLINE void att_mars_gap_count(att_mars_state_t *st)
{
    if (st->mag_gap == 0u && st->steps - 1u != st->mag_gap_step) {
        st->mag_period = 0u;
    }
    if (st->mag_gap < ATT_MARS_GAP_MAX) {
        st->mag_gap = st->mag_gap + 1u;
    }
}

/*
 * A mag sample, valid or not, ends the gap of steps without one (mag_gap, reset; mag_period and
 * mag_gap_step then hold it and this step). Returns the steps it stands for, min(gap, mag_period) + 1:
 * a magnetometer that samples every n steps stands for n; the sample after an outage for one regular
 * period, not the outage (mag_period: the gap before it); after samples on every step, 1.
 */
static uint32_t att_mars_gap_close(att_mars_state_t *st)
{
    const uint32_t gap = st->mag_gap;
    const uint32_t n = ((st->mag_period < gap) ? st->mag_period : gap) + 1u;
    st->mag_period = gap;
    st->mag_gap_step = st->steps;
    st->mag_gap = 0u;
    return n;
}

/*
 * The gain of the n steps a sample after a gap stands for (att_mars_gap_close), each of gain k,
 * 1 - (1 - k)^n, by binary powers composed as a + b - a b (exact for small gains, where 1 - (1 - k)^n
 * would cancel): a magnetometer that samples every n steps corrects per sample what one sampling every
 * step would over those n steps, so that tau_mag (and the fast phase's and the recovery's, the phase of
 * the sample's step) stays a time constant in seconds.
 */
static ATT_NOINLINE float att_mars_gap_gain(att_mars_state_t *st, float k)
{
    uint32_t n = att_mars_gap_close(st);
    float acc = 0.0f;
    float p = k;
    while (n != 0u) {
        if ((n & 1u) != 0u) {
            acc = (acc + p) - acc * p;
        }
        p = (p + p) - p * p;
        n = n >> 1;
    }
    return acc;
}

/*
 * Magnetometer correction of q with a usable sample of norm mnorm (the reference field is known);
 * sets ATT_FLAG_MAG_REJECTED when the sample is not used. Horizontal mode: with h the horizontal part of
 * q mag q* and r that of m0 (unit), the rotation about z that takes h to r is the shortest-arc
 * quaternion C = (|h| + h . r, 0, 0, (h x r)_z) / sqrt(2 |h| (|h| + h . r)) (a half turn about z when h
 * points away from r); the correction is the normalised interpolation (1 - k_mag) I + k_mag C, applied
 * as q := ((1 - k_mag) + k_mag C_w, 0, 0, k_mag C_z) * q (the final normalisation of the step makes it
 * a rotation). No trigonometry; for small gains it turns by k_mag times 2 sin(angle / 2), i.e. k_mag
 * times the angle for the small heading errors of tracking. Full mode: att_mars_rotation_toward.
 * The gain is k_rec during a recovery, k_fast during the fast phase, each that of the steps the sample
 * stands for after steps without one (att_mars_gap_gain; a rejected sample drops them all). *use: ATT_MARS_MAG_ACCEPTED when the sample passed the norm
 * and dip tests, ATT_MARS_MAG_GATED when it failed them (the reference statistics count both). *theta:
 * the heading correction's angle 2 C'_z (horizontal mode; 0 when none), rad.
 */
static ATT_ALWAYS_INLINE att_quat_t att_mars_mag_correct(const att_mars_coeffs_t *c, att_mars_state_t *st,
                                                         att_quat_t q, att_vec3_t me, float mnorm, uint32_t *flags,
                                                         uint32_t *use, float *theta)
{
    float k = c->k_mag;
    float k1 = c->k_mag1;
    if (st->rec_left > 0u) {
        k = c->k_rec;
        k1 = c->k_rec1;
    } else if (st->fast_left > 0u) {
        k = c->k_fast;
        k1 = c->k_fast1;
    }
    if (ATT_IN_LINE(st->mag_gap != 0u)) { /* rare (a slower magnetometer), in line: one instruction less */
        k = att_mars_gap_gain(st, k); /* a slower magnetometer: the correction of its interval */
        k1 = 1.0f - k;
    }
    att_vec3_t unit;
    att_quat_t qc;
    float h2;
    float hn;
    float a;
    float b;
    float qw;
    float qz;
    if (mnorm < st->m0_lo || mnorm > st->m0_hi || me.z < st->dip_lo * mnorm || me.z > st->dip_hi * mnorm) {
        *flags |= ATT_FLAG_MAG_REJECTED;
        *use = ATT_MARS_MAG_GATED;
        return q;
    }
    *use = ATT_MARS_MAG_ACCEPTED;
    if (c->mag_mode == (uint8_t)ATT_MARS_MAG_FULL) {
        if (!att_i_vec3_normalize(me, &unit)) {
            *flags |= ATT_FLAG_MAG_REJECTED;
            return q;
        }
        att_mars_rotation_toward(unit.x, unit.y, unit.z, &st->m0_ref, &st->m0_perp, k, &qc);
        return att_i_quat_mul(qc, q);
    }
    h2 = me.x * me.x + me.y * me.y;
    if (!(h2 >= ATT_NORM2_MIN)) {
        *flags |= ATT_FLAG_MAG_REJECTED; /* vertical field: no heading information */
        return q;
    }
    hn = att_i_sqrtf(h2);
    a = hn + (me.x * st->m0_ref.x + me.y * st->m0_ref.y);
    b = me.x * st->m0_ref.y - me.y * st->m0_ref.x;
    if (a > ATT_ALIGN_A_MIN * hn) {
        const float kn = k / att_i_sqrtf((2.0f * hn) * a);
        qw = k1 + a * kn;
        qz = b * kn;
    } else {
        qw = k1; /* h opposite to r: toward the half turn about z */
        qz = k;
    }
    *theta = 2.0f * qz;
    return att_i_quat_mul_z(qw, qz, q);
}

/*
 * A usable mag sample before the reference field is known: yaw alignment of q (returns true with the
 * aligned attitude in *qa), or m0 from it (returns false: q stays). The flags of the sample are added
 * to st->flags (which holds the step's flags so far: the step writes its final flags there).
 */
static ATT_NOINLINE bool att_mars_mag_first(const att_mars_coeffs_t *c, att_mars_state_t *st, float qw, float qx,
                                            float qy, float qz, const att_vec3_t *mag, att_quat_t *qa)
{
    att_vec3_t m0;
    if (c->init_from_sensors) {
        if (att_mars_align(c, qw, qx, qy, qz, mag, qa, &m0) && att_mars_set_m0(c, st, &m0)) {
            st->flags |= ATT_FLAG_INITIALISED;
            st->fast_left = c->fast_start_n;
            st->mag_step = st->steps; /* the covariance's heading: aligned at this step */
            return true;
        }
        st->flags |= ATT_FLAG_MAG_REJECTED;
        return false;
    }
    m0 = att_i_quat_rotate(att_i_quat(qw, qx, qy, qz), *mag);
    if (att_mars_set_m0(c, st, &m0)) {
        st->mag_step = st->steps;
    } else {
        st->flags |= ATT_FLAG_MAG_REJECTED;
    }
    return false;
}

/*
 * The rest of the first step with a valid accel sample, the tail of att_mars_update (which left the sample's
 * flags in st->flags): roll and pitch from the sample (att_sensor_tilt, att_quat_from_euler: the same
 * operations inline), yaw from the mag sample when usable. Returns the step's flags.
 */
static ATT_NOINLINE uint32_t att_mars_start(att_mars_t *f, const att_vec3_t *acc, const att_vec3_t *mag)
{
    const float roll = att_atan2f(acc->y, acc->z);
    const float pitch = att_atan2f(-acc->x, att_i_sqrtf(acc->y * acc->y + acc->z * acc->z));
    att_mars_state_t *st = &f->st;
    uint32_t flags = st->flags | ATT_FLAG_INITIALISED;
    const bool mag_ok = (flags & (ATT_FLAG_MAG_INVALID | ATT_FLAG_MAG_ABSENT)) == 0u;
    att_quat_t qa;
    att_vec3_t m0;
    (void)att_i_quat_normalize_bounded(att_i_quat_from_euler(roll, pitch, 0.0f), &st->q);
    if (mag_ok) {
        if (att_mars_align(&f->c, st->q.w, st->q.x, st->q.y, st->q.z, mag, &qa, &m0) &&
            att_mars_set_m0(&f->c, st, &m0)) {
            st->q = qa;
            st->fast_left = f->c.fast_start_n;
            st->mag_step = st->steps;
        } else {
            flags |= ATT_FLAG_MAG_REJECTED;
        }
    }
    st->lp1 = att_i_quat_rotate(st->q, *acc);
    st->lp2 = st->lp1;
    att_i_recovery_start(f->c.rec_n, &st->rec_left, &st->rec_lp_n);
    st->rec_clip = false;
    st->initialised = true;
    st->acc_step = st->steps;
    st->steps = st->steps + 1u;
    st->flags = flags;
    return flags;
}

/*
 * The recovery counter (att_i_recovery_step); the fast phase starts when a clip's recovery ends (the
 * start's runs inside the alignment's fast phase). Returns ATT_FLAG_INITIALISED while a recovery runs.
 */
static ATT_ALWAYS_INLINE uint32_t att_mars_recovery(const att_mars_coeffs_t *c, att_mars_state_t *st, att_vec3_t g)
{
    if (att_i_recovery_step(g, c->clip, c->rec_n, &st->rec_left, &st->rec_lp_n) && st->rec_clip) {
        st->fast_left = c->fast_start_n; /* the heading follows the settling tilt, as after the alignment */
    }
    if (st->rec_left == 0u) {
        return 0u;
    }
    if (st->rec_left == c->rec_n) {
        st->rec_clip = true; /* a clipping sample (the start's recovery is counted down from the next step) */
    }
    return ATT_FLAG_INITIALISED;
}

/* The prediction: q turned by the bias-corrected rate d over dt; NUMERIC when the first-order step overflowed. */
static ATT_ALWAYS_INLINE uint32_t att_mars_predict(const att_mars_coeffs_t *c, att_vec3_t d, att_quat_t *q)
{
    att_quat_t qn;
    if (c->integration == (uint8_t)ATT_INTEGRATE_ROTVEC) {
        *q = att_i_quat_mul(*q, att_mars_rotvec(att_i_vec3_scale(d, c->dt)));
        return 0u;
    }
    if (att_i_quat_normalize_bounded(att_mars_integrate(*q, d, c->dt), &qn)) {
        *q = qn;
        return 0u;
    }
    return ATT_FLAG_NUMERIC; /* first-order step overflowed: integration skipped */
}

/* The accel correction of q toward the earth-frame specific force (low-passed when on), the stages with it. */
static ATT_ALWAYS_INLINE void att_mars_accel_correct(const att_mars_coeffs_t *c, att_vec3_t acc, float k_lp,
                                                     float k_lp2, att_quat_t *q, att_vec3_t *lp1, att_vec3_t *lp2)
{
    const att_vec3_t v = att_i_quat_rotate(*q, acc);
    att_vec3_t u = v;
    if (c->lp_on) {
        att_i_lowpass2(v, k_lp, k_lp2, lp1, lp2);
        u = *lp2;
    }
    if (c->full) {
        float qw;
        float qx;
        float qy;
        float n;
        if (att_i_align_up(u, &qw, &qx, &qy, &n)) {
            *q = att_i_quat_mul_hz(qw, qx, qy, *q);
            if (c->lp_on) {
                *lp1 = att_i_quat_rotate_hz(qw, qx, qy, *lp1);
                *lp2 = att_i_vec3(0.0f, 0.0f, n);
            }
        }
    } else {
        /* general correction: q rotated toward z by the fraction k_acc of the angle, the stages with it */
        att_vec3_t unit;
        att_quat_t qc;
        if (att_i_vec3_normalize(u, &unit)) {
            att_mars_rotation_toward(unit.x, unit.y, unit.z, &att_mars_up, &att_mars_xaxis, c->k_acc, &qc);
            *q = att_i_quat_mul(qc, *q);
            if (c->lp_on) {
                /* keep the low-pass states in the corrected earth frame */
                *lp1 = att_i_quat_rotate(qc, *lp1);
                *lp2 = att_i_quat_rotate(qc, *lp2);
            }
        }
    }
}

/*
 * The end of a block of the reference statistics (att_mars.h, step 3, att_magref.h): the reference
 * follows the accepted samples, or a steady new field becomes the reference (then the fast phase
 * starts); its horizontal direction is kept.
 */
static ATT_NOINLINE void att_mars_ref_block(const att_mars_coeffs_t *c, att_mars_state_t *st)
{
    float n;
    float s;
    uint32_t out;
    if (st->fast_left > 0u) {
        st->fast_left = st->fast_left - 1u; /* the fast phase is counted in blocks */
    }
    out = att_i_magref_block(&c->ref, &st->ref, st->m0, &n, &s);
    if (out != ATT_MAGREF_KEEP) {
        const att_vec3_t m0 = att_i_magref_m0(st->m0, n, s, c->decl_sin, c->decl_cos);
        (void)att_mars_set_m0(c, st, &m0); /* n > 0: the mean of valid norms */
        if (out == ATT_MAGREF_ADOPT && st->fast_left < c->fast_n) {
            st->fast_left = c->fast_n; /* a longer phase under way (after the alignment) runs on */
        }
    }
}

/*
 * The gyro bias learnt from an accepted heading correction by theta (rad): b -= (theta / tau_bias_mag) r3,
 * r3 = R(q)^T z, the earth's vertical in the sensor frame (the third row of R(q)); each component kept in
 * [-gyro_range, gyro_range], the range of bias_init (a tiny tau_bias_mag cannot run the bias away).
 */
static ATT_ALWAYS_INLINE void att_mars_bias_mag(const att_mars_coeffs_t *c, att_mars_state_t *st, float theta)
{
    const att_quat_t q = st->q;
    const float k = theta * c->k_bias_mag;
    const float rx = 2.0f * (q.x * q.z - q.w * q.y);
    const float ry = 2.0f * (q.y * q.z + q.w * q.x);
    const float rz = 1.0f - 2.0f * (q.x * q.x + q.y * q.y);
    const float r = c->gyro_range;
    st->bias = att_i_vec3(att_i_clampf(st->bias.x - k * rx, -r, r), att_i_clampf(st->bias.y - k * ry, -r, r),
                          att_i_clampf(st->bias.z - k * rz, -r, r));
}

/* Count a committed step with a known reference: the sample's use, the block. */
static ATT_ALWAYS_INLINE void att_mars_ref_count(const att_mars_coeffs_t *c, att_mars_state_t *st, uint32_t use,
                                                 float mnorm, float mz)
{
    if (use == ATT_MARS_MAG_ACCEPTED) {
        st->mag_step = st->steps; /* the covariance's last mag sample that passed the norm and dip tests */
    }
    if (att_i_magref_count(&c->ref, &st->ref, use, mnorm, mz)) {
        att_mars_ref_block(c, st);
    }
}

/* The mag correction (or, for the first usable sample, the heading alignment) of q; me = R(q) m. */
static ATT_ALWAYS_INLINE att_quat_t att_mars_mag_step(const att_mars_coeffs_t *c, att_mars_state_t *st,
                                                      att_quat_t q, att_vec3_t me, float mnorm,
                                                      const att_vec3_t *mag_in, uint32_t *flags, uint32_t *use,
                                                      float *theta)
{
    att_quat_t qa;
    if (st->m0_valid) {
        return att_mars_mag_correct(c, st, q, me, mnorm, flags, use, theta);
    }
    (void)att_mars_gap_close(st); /* the alignment or the reference from this sample: its gap ends */
    st->flags = *flags;
    if (att_mars_mag_first(c, st, q.w, q.x, q.y, q.z, mag_in, &qa)) {
        q = qa;
    }
    *flags = st->flags;
    return q;
}

/*
 * One step (att_mars_step, f not NULL; att_mars_step_out adds the output fields): the sample checks, the
 * bias, the prediction, the accel correction, the mag correction, the commit. The general accel correction
 * (k_acc < 1) shares the low-pass update with the full alignment and takes only the rotation toward z
 * out of line.
 */
static ATT_NOINLINE uint32_t att_mars_update(att_mars_t *f, const att_vec3_t *gyr_in, const att_vec3_t *acc_in,
                                             const att_vec3_t *mag_in)
{
    const att_vec3_t gyr = att_i_vec3(gyr_in->x, gyr_in->y, gyr_in->z);
    const att_vec3_t acc = att_i_vec3(acc_in->x, acc_in->y, acc_in->z);
    const att_vec3_t mag = att_i_vec3(mag_in->x, mag_in->y, mag_in->z);
    const att_mars_coeffs_t *c = &f->c;
    att_mars_state_t *st = &f->st;
    float n2;
    float mnorm;
    att_vec3_t d;
    att_quat_t q;
    att_quat_t qn;
    att_vec3_t lp1;
    att_vec3_t lp2;
    att_vec3_t me;
    uint32_t flags;
    uint32_t accel_flags;
    uint32_t mag_flags;
    uint32_t use = 0u;
    float theta = 0.0f;
    bool gyro_ok;
    bool accel_ok;
    bool mag_ok;
    /* the sample checks */
    flags = att_i_sensor_check_gyro(gyr, c->gyro_range);
    gyro_ok = att_i_gyro_usable(gyr, c->gyro_range, flags);
    accel_flags = att_i_sensor_check_accel2(acc, c->accel_range2, &n2);
    accel_ok = (accel_flags == 0u);
    flags |= accel_flags;
    if (accel_ok && c->reject_on && att_i_absf(att_i_sqrtf(n2) / c->gravity - 1.0f) > c->accel_reject) {
        flags |= ATT_FLAG_ACCEL_REJECTED;
    }
    mag_flags = att_i_sensor_check_mag(mag, c->mag_range, &mnorm);
    mag_ok = (mag_flags == 0u);
    flags |= mag_flags;
    /* rest detection and gyro bias */
    flags |= att_i_bias_step(&c->bias, &st->bias, &st->bias_n, &st->rest_count, &st->rest_gate2, gyr, gyro_ok,
                             accel_ok, n2, &d);
    if (!st->initialised) {
        st->flags = flags;
        if (accel_ok) {
            return att_mars_start(f, acc_in, mag_in); /* a tail call: its frame replaces this one */
        }
        st->steps = st->steps + 1u;
        st->flags = flags | ATT_FLAG_NOT_READY;
        return st->flags;
    }
    flags |= att_mars_recovery(c, st, gyr);
    q = st->q;
    lp1 = st->lp1;
    lp2 = st->lp2;
    if (gyro_ok) {
        if ((flags & ATT_FLAG_BIAS_UPDATED) != 0u) {
            d = att_i_vec3_sub(gyr, st->bias);
        }
        flags |= att_mars_predict(c, d, &q);
    }
    me = att_i_quat_rotate(q, mag); /* the mag in the earth frame of the predicted attitude */
    if (accel_ok && (flags & ATT_FLAG_ACCEL_REJECTED) == 0u) {
        float k2 = c->k_lp;
        const float k1 =
            (st->rec_left > 0u && c->lp_on) ? att_i_recovery_lp_gain2(&st->rec_lp_n, c->k_lp, &k2) : c->k_lp;
        att_mars_accel_correct(c, acc, k1, k2, &q, &lp1, &lp2);
        st->acc_step = st->steps; /* the covariance's last accepted accel sample */
    }
    if (mag_ok) {
        q = att_mars_mag_step(c, st, q, me, mnorm, mag_in, &flags, &use, &theta);
    } else if ((mag_flags & ATT_FLAG_MAG_ABSENT) == 0u) {
        (void)att_mars_gap_close(st); /* an invalid sample (saturated, Inf) ends the gap: its steps are lost */
    } else {
        att_mars_gap_count(st);
    }
    if (att_i_quat_normalize_bounded(q, &qn)) {
        st->q = qn;
        st->lp1 = lp1;
        st->lp2 = lp2;
        if (st->m0_valid) {
            if (c->bias_mag_on && use == ATT_MARS_MAG_ACCEPTED && (flags & ATT_FLAG_MAG_REJECTED) == 0u &&
                st->fast_left == 0u && st->rec_left == 0u) {
                att_mars_bias_mag(c, st, theta);
                flags |= ATT_FLAG_BIAS_UPDATED;
            }
            att_mars_ref_count(c, st, use, mnorm, me.z);
        }
    } else {
        flags |= ATT_FLAG_NUMERIC; /* keep the attitude and the low-pass states from before the step */
    }
    st->steps = st->steps + 1u;
    st->flags = flags;
    return flags;
}

#if ATT_WITH_HARD_IRON
/*
 * A step with the hard-iron estimate on (hard_iron_tau > 0; att_hardiron.h): its step from the raw samples
 * (the rate minus the bias of the step before), then the filter's step with a valid mag sample minus the
 * applied offset (the filter's own checks see that sample).
 */
static ATT_NOINLINE uint32_t att_mars_step_hi(att_mars_t *f, const att_vec3_t *gyr, const att_vec3_t *acc,
                                              const att_vec3_t *mag)
{
    float mnorm;
    const bool gyro_ok = att_i_hi_gyro_ok(att_i_sensor_check_gyro(*gyr, f->c.gyro_range), *gyr, f->c.gyro_range);
    const bool mag_ok = att_i_sensor_check_mag(*mag, f->c.mag_range, &mnorm) == 0u;
    att_vec3_t m = *mag;
    att_i_hi_step(&f->c.hi, &f->st.hi, f->c.dt, att_i_vec3_sub(*gyr, f->st.bias), gyro_ok, m, mag_ok);
    if (mag_ok) {
        m = att_i_hi_correct(&f->st.hi, m);
    }
    return att_mars_update(f, gyr, acc, &m);
}
#endif

/* One step: att_mars_update (which ends in att_mars_start for the first usable sample), with the
   hard-iron estimate's step around it when it is on. */
static ATT_ALWAYS_INLINE uint32_t att_mars_step_in(att_mars_t *f, const att_vec3_t *gyr, const att_vec3_t *acc,
                                                   const att_vec3_t *mag)
{
#if ATT_WITH_HARD_IRON
    if (f->c.hi.on) {
        return att_mars_step_hi(f, gyr, acc, mag);
    }
#endif
    return att_mars_update(f, gyr, acc, mag);
}

uint32_t att_mars_step(att_mars_t *f, att_vec3_t gyr, att_vec3_t acc, att_vec3_t mag)
{
    if (f == NULL) {
        return ATT_FLAG_BAD_ARG;
    }
    return att_mars_step_in(f, &gyr, &acc, &mag);
}

uint32_t att_mars_step_out(att_mars_t *restrict f, const att_sample_t *restrict in, att_output_t *restrict out)
{
    const uint32_t flags = att_mars_step_in(f, &in->gyr, &in->acc, &in->mag);
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

void att_mars_preset(att_mars_settings_t *s, att_preset_t preset, float dt)
{
    att_mars_settings_default(s, dt);
    if (preset == ATT_PRESET_SEED) {
        s->alpha_acc = 0.02f;
        s->alpha_mag = 0.01f;
        s->tau_acc = 0.0f;
        s->tau_mag = 0.0f;
        s->accel_reject = 0.1f;
        s->mag_norm_reject = 0.2f;
        s->mag_dip_reject = 0.17f;
        s->integration = ATT_INTEGRATE_FIRST_ORDER;
        s->tau_acc_lp = 0.0f;
        s->bias_mode = ATT_BIAS_FROZEN;
        s->mag_ref_tau = 0.0f;
        s->mag_new_time = 0.0f;
        s->tau_mag_fast = 0.0f;
        s->tau_bias_mag = 0.0f;
        s->recovery_time = 0.0f;
    }
}

float att_mars_period(const att_mars_settings_t *s)
{
    return s->dt;
}

/* The covariance (att_mars.h, step 5): tilt about earth x and y, heading about z, rad^2. */
static void att_mars_cov(const att_mars_t *f, float cov[4])
{
    const att_mars_coeffs_t *c = &f->c;
    const att_mars_state_t *st = &f->st;
    const float tilt = att_i_cov_tilt_now(c->var_tilt, c->var_tilt, c->var_step, st->rec_left, c->rec_n,
                                          st->steps, st->acc_step, st->initialised);
    float yaw = ATT_COV_UNKNOWN;
    if (st->m0_valid && st->initialised) {
        const float h2 = st->m0.x * st->m0.x + st->m0.y * st->m0.y;
        float k = c->k_mag;
        if (st->rec_left > 0u) {
            k = c->k_rec;
        } else if (st->fast_left > 0u) {
            k = c->k_fast;
        }
        if (k > 0.0f && h2 > 0.0f) { /* else no heading correction (or no horizontal field): unknown */
            const float v = att_i_cov_first(c->dt, k, c->gyro_noise2, c->mag_noise2 / h2);
            yaw = att_i_cov_grow(v, c->var_step, st->steps, st->mag_step, ATT_COV_UNKNOWN);
        }
    }
    cov[0] = tilt;
    cov[1] = tilt;
    cov[2] = yaw;
    cov[3] = 0.0f;
}

void att_mars_output(const att_mars_t *f, att_output_t *out)
{
    out->q = f->st.q;
    out->gyro_bias = f->st.bias;
    out->flags = f->st.flags;
    out->steps = f->st.steps;
    out->valid = ATT_OUT_Q | ATT_OUT_BIAS;
    att_mars_cov(f, out->cov);
}

att_heading_t att_mars_heading_kind(const att_mars_t *f)
{
    (void)f;
    return ATT_HEADING_SET; /* its heading reference is the magnetometer */
}

att_status_t att_mars_yaw_to(att_mars_t *f, float target, float gain)
{
    float s;
    float c;
    const att_status_t st = att_yaw_q(&f->st.q, &f->st.lp1, &f->st.lp2, f->st.initialised, target, gain, &s, &c);
    if (st == ATT_OK) {
        f->st.m0 = att_i_yaw_vec(f->st.m0, c, s);
        f->st.m0_ref = att_i_yaw_vec(f->st.m0_ref, c, s);
        f->st.m0_perp = att_i_yaw_vec(f->st.m0_perp, c, s);
    }
    return st;
}

bool att_mars_set_gain(att_mars_settings_t *s, att_gain_t gain, float value)
{
    if (gain == ATT_GAIN_TAU_ACC) {
        s->tau_acc = value;
        s->alpha_acc = att_i_gain_for_tau(value);
        return true;
    }
    if (gain == ATT_GAIN_TAU_MAG) {
        s->tau_mag = value;
        s->alpha_mag = att_i_gain_for_tau(value);
        return true;
    }
    if (gain == ATT_GAIN_DECLINATION) {
        s->declination = value;
        return true;
    }
    return false;
}
