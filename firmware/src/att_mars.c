/**
 * @file att_mars.c
 * @brief 9-axis complementary filter with magnetometer (see att_mars.h).
 * Mirrored by host/attica/reference/mars.py.
 */
#include "att_fp.h"

#include "attica/att_mars.h"
#include "attica/att_math.h"
#include "attica/att_sensor.h"

#define ATT_MARS_BIAS_N_MAX_LIMIT 16777216u /* 2^24: n converts to float exactly */

void att_mars_settings_default(att_mars_settings_t *settings, float dt)
{
    if (settings == NULL) {
        return;
    }
    settings->dt = dt;
    settings->alpha_acc = 0.02f;
    settings->alpha_mag = 0.01f;
    settings->tau_acc = 0.5f;
    settings->tau_mag = 20.0f;
    settings->mag_mode = ATT_MARS_MAG_HORIZONTAL;
    settings->gravity = 9.80665f;
    settings->accel_reject = 0.0f;
    settings->accel_range = 156.9064f; /* 16 g */
    settings->gyro_range = 34.906586f; /* 2000 deg/s */
    settings->mag_range = 1000.0f;
    settings->mag_norm_reject = 0.2f;
    settings->mag_dip_reject = 0.3f; /* about 17 deg */
    settings->bias_init.x = 0.0f;
    settings->bias_init.y = 0.0f;
    settings->bias_init.z = 0.0f;
    settings->init_from_sensors = true;
    settings->q_init = att_quat_identity();
    settings->m0_init.x = 0.0f;
    settings->m0_init.y = 0.0f;
    settings->m0_init.z = 0.0f;
    settings->integration = ATT_INTEGRATE_ROTVEC;
    settings->tau_acc_lp = 1.0f;
    settings->bias_mode = ATT_BIAS_AT_REST;
    settings->bias_n_max = 1000u;
    settings->rest_gyro = 0.05f;
    settings->rest_accel = 0.5f;
    settings->rest_time = 0.5f;
}

static bool att_mars_vec3_is_zero(att_vec3_t v)
{
    return v.x == 0.0f && v.y == 0.0f && v.z == 0.0f;
}

static bool att_mars_settings_valid(const att_mars_settings_t *s)
{
    att_quat_t qn;
    att_vec3_t vn;
    const bool finite = att_isfinitef(s->dt) && att_isfinitef(s->alpha_acc) && att_isfinitef(s->alpha_mag) &&
                        att_isfinitef(s->tau_acc) && att_isfinitef(s->tau_mag) && att_isfinitef(s->gravity) &&
                        att_isfinitef(s->accel_reject) && att_isfinitef(s->mag_norm_reject) &&
                        att_isfinitef(s->mag_dip_reject) && att_vec3_isfinite(s->bias_init) &&
                        att_quat_isfinite(s->q_init) && att_vec3_isfinite(s->m0_init) &&
                        att_isfinitef(s->tau_acc_lp) && att_isfinitef(s->rest_gyro) &&
                        att_isfinitef(s->rest_accel) && att_isfinitef(s->rest_time);
    if (!finite) {
        return false;
    }
    /* ranges may be +Inf (no limit) but not NaN */
    if (!(s->accel_range > 0.0f) || !(s->gyro_range > 0.0f) || !(s->mag_range > 0.0f)) {
        return false;
    }
    if (!(s->dt > 0.0f && s->dt <= 1.0f) || !(s->alpha_acc >= 0.0f && s->alpha_acc <= 1.0f) ||
        !(s->alpha_mag >= 0.0f && s->alpha_mag <= 1.0f) || !(s->tau_acc >= 0.0f) || !(s->tau_mag >= 0.0f) ||
        !(s->gravity > 0.0f) || !(s->accel_reject >= 0.0f) || !(s->mag_norm_reject >= 0.0f) ||
        !(s->mag_dip_reject >= 0.0f) || !(s->tau_acc_lp >= 0.0f) || !(s->rest_gyro >= 0.0f) ||
        !(s->rest_accel >= 0.0f) || !(s->rest_time >= 0.0f)) {
        return false;
    }
    if (s->integration != ATT_INTEGRATE_ROTVEC && s->integration != ATT_INTEGRATE_FIRST_ORDER) {
        return false;
    }
    if (s->bias_mode != ATT_BIAS_OFF && s->bias_mode != ATT_BIAS_FROZEN && s->bias_mode != ATT_BIAS_RUNNING &&
        s->bias_mode != ATT_BIAS_AT_REST) {
        return false;
    }
    if (s->bias_n_max < 1u || s->bias_n_max > ATT_MARS_BIAS_N_MAX_LIMIT) {
        return false;
    }
    if (s->mag_mode != ATT_MARS_MAG_HORIZONTAL && s->mag_mode != ATT_MARS_MAG_FULL) {
        return false;
    }
    if (!att_mars_vec3_is_zero(s->m0_init) && !att_vec3_normalize(s->m0_init, &vn)) {
        return false;
    }
    return att_quat_normalize(s->q_init, &qn);
}

/* Dip angle of v: atan2(v.z, |v_xy|), rad. */
static float att_mars_dip(att_vec3_t v)
{
    return att_atan2f(v.z, att_sqrtf(v.x * v.x + v.y * v.y));
}

/* Set m0 and its derived quantities; returns false (and changes nothing) when m0 has no direction. */
static bool att_mars_set_m0(att_mars_t *f, att_vec3_t m0)
{
    att_vec3_t unit;
    att_vec3_t h;
    att_vec3_t up;
    att_vec3_t perp;
    if (!att_vec3_normalize(m0, &unit)) {
        return false;
    }
    f->m0 = m0;
    f->m0_norm = att_vec3_norm(m0);
    f->m0_dip = att_mars_dip(m0);
    up.x = 0.0f;
    up.y = 0.0f;
    up.z = 1.0f;
    if (f->s.mag_mode == ATT_MARS_MAG_FULL) {
        f->m0_ref = unit;
        f->m0_ref_ok = true;
        if (!att_vec3_normalize(att_vec3_cross(unit, up), &perp)) {
            perp.x = 1.0f;
            perp.y = 0.0f;
            perp.z = 0.0f;
        }
        f->m0_perp = perp;
    } else {
        h.x = m0.x;
        h.y = m0.y;
        h.z = 0.0f;
        f->m0_ref_ok = att_vec3_normalize(h, &f->m0_ref);
        f->m0_perp = up;
    }
    f->m0_valid = true;
    return true;
}

att_status_t att_mars_init(att_mars_t *f, const att_mars_settings_t *settings)
{
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    if (!att_mars_settings_valid(settings)) {
        return ATT_ERR_SETTINGS;
    }
    f->s = *settings;
    f->k_acc = (settings->tau_acc > 0.0f) ? settings->dt / (settings->tau_acc + settings->dt) : settings->alpha_acc;
    f->k_mag = (settings->tau_mag > 0.0f) ? settings->dt / (settings->tau_mag + settings->dt) : settings->alpha_mag;
    f->k_lp = (settings->tau_acc_lp > 0.0f) ? settings->dt / (settings->tau_acc_lp + settings->dt) : 0.0f;
    f->rest_n = att_sensor_samples(settings->rest_time, settings->dt);
    att_mars_reset(f);
    return ATT_OK;
}

void att_mars_reset(att_mars_t *f)
{
    att_vec3_t zero;
    if (f == NULL) {
        return;
    }
    zero.x = 0.0f;
    zero.y = 0.0f;
    zero.z = 0.0f;
    (void)att_quat_normalize(f->s.q_init, &f->q);
    f->m0 = zero;
    f->m0_norm = 0.0f;
    f->m0_dip = 0.0f;
    f->m0_ref = zero;
    f->m0_perp = zero;
    f->m0_ref_ok = false;
    f->m0_valid = false;
    if (!f->s.init_from_sensors && !att_mars_vec3_is_zero(f->s.m0_init)) {
        (void)att_mars_set_m0(f, f->s.m0_init); /* succeeds: checked by the settings validation */
    }
    f->initialised = !f->s.init_from_sensors;
    f->bias = (f->s.bias_mode == ATT_BIAS_OFF) ? zero : f->s.bias_init;
    f->bias_n = 0u;
    f->rest_count = 0u;
    f->lp1 = zero;
    f->lp1.z = f->s.gravity;
    f->lp2 = f->lp1;
    f->steps = 0u;
    f->flags = 0u;
}

/* First-order quaternion integration q + (0.5 q (x) (0, w)) dt (not normalised). */
static att_quat_t att_mars_integrate(att_quat_t q, att_vec3_t w, float dt)
{
    att_quat_t o;
    att_quat_t p;
    att_quat_t r;
    o.w = 0.0f;
    o.x = w.x;
    o.y = w.y;
    o.z = w.z;
    p = att_quat_mul(q, o);
    r.w = q.w + p.w * 0.5f * dt;
    r.x = q.x + p.x * 0.5f * dt;
    r.y = q.y + p.y * 0.5f * dt;
    r.z = q.z + p.z * 0.5f * dt;
    return r;
}

/* Gyro integration (not normalised): exponential map q * Q(w dt), or first order. */
static att_quat_t att_mars_propagate(const att_mars_t *f, att_quat_t q, att_vec3_t w)
{
    if (f->s.integration == ATT_INTEGRATE_ROTVEC) {
        return att_quat_mul(q, att_quat_from_rotvec(att_vec3_scale(w, f->s.dt)));
    }
    return att_mars_integrate(q, w, f->s.dt);
}

/*
 * Rotate q in the earth frame so that the unit vector v moves toward the unit reference r by the
 * fraction gain of the angle between them: q := Q(gain * angle, axis) * q with axis = v x r / |v x r|
 * and angle = atan2(|v x r|, v . r). When v x r cannot be normalised, the axis is fallback.
 */
static att_quat_t att_mars_rotation_toward(att_vec3_t v, att_vec3_t r, att_vec3_t fallback, float gain)
{
    const att_vec3_t c = att_vec3_cross(v, r);
    const float angle = att_atan2f(att_vec3_norm(c), att_vec3_dot(v, r));
    att_vec3_t axis;
    if (!att_vec3_normalize(c, &axis)) {
        axis = fallback;
    }
    return att_quat_from_axis_angle(axis, gain * angle);
}

static att_quat_t att_mars_rotate_toward(att_quat_t q, att_vec3_t v, att_vec3_t r, att_vec3_t fallback,
                                         float gain)
{
    return att_quat_mul(att_mars_rotation_toward(v, r, fallback, gain), q);
}

/*
 * Yaw alignment: rotate q about the earth z axis so that the horizontal part of q mag q* points north
 * (+y); *m0 = (0, |m_e,xy|, m_e,z) for the aligned attitude. Returns false when mag has no direction.
 */
static bool att_mars_align(att_quat_t q, att_vec3_t mag, att_quat_t *q_out, att_vec3_t *m0)
{
    att_vec3_t me = att_quat_rotate(q, mag);
    att_vec3_t unit;
    att_vec3_t up;
    att_quat_t qa;
    if (!att_vec3_normalize(me, &unit)) {
        return false;
    }
    up.x = 0.0f;
    up.y = 0.0f;
    up.z = 1.0f;
    qa = att_quat_mul(att_quat_from_axis_angle(up, att_atan2f(me.x, me.y)), q);
    if (!att_quat_normalize(qa, &qa)) {
        return false;
    }
    me = att_quat_rotate(qa, mag);
    m0->x = 0.0f;
    m0->y = att_sqrtf(me.x * me.x + me.y * me.y);
    m0->z = me.z;
    *q_out = qa;
    return true;
}

/* Magnetometer correction of q with a valid sample of norm mnorm; sets ATT_FLAG_MAG_REJECTED. */
static att_quat_t att_mars_mag_correct(const att_mars_t *f, att_quat_t q, att_vec3_t mag, float mnorm,
                                       uint32_t *flags)
{
    const att_vec3_t me = att_quat_rotate(q, mag);
    const float e = mnorm / f->m0_norm - 1.0f;
    const float ddip = att_mars_dip(me) - f->m0_dip;
    att_vec3_t v;
    att_vec3_t unit;
    bool reject = !f->m0_ref_ok;
    if (f->s.mag_norm_reject > 0.0f && att_absf(e) > f->s.mag_norm_reject) {
        reject = true;
    }
    if (f->s.mag_dip_reject > 0.0f && att_absf(ddip) > f->s.mag_dip_reject) {
        reject = true;
    }
    v = me;
    if (f->s.mag_mode == ATT_MARS_MAG_HORIZONTAL) {
        v.z = 0.0f;
    }
    if (!att_vec3_normalize(v, &unit)) {
        reject = true;
    }
    if (reject) {
        *flags |= ATT_FLAG_MAG_REJECTED;
        return q;
    }
    return att_mars_rotate_toward(q, unit, f->m0_ref, f->m0_perp, f->k_mag);
}

uint32_t att_mars_step(att_mars_t *f, att_vec3_t gyr, att_vec3_t acc, att_vec3_t mag)
{
    uint32_t flags;
    uint32_t accel_flags;
    uint32_t mag_flags;
    float norm;
    float mnorm;
    float e;
    bool gyro_ok;
    bool accel_ok;
    bool mag_ok;
    att_quat_t q;
    att_quat_t qn;
    att_quat_t qa;
    att_vec3_t m0;
    att_vec3_t up;
    att_vec3_t xaxis;
    att_vec3_t unit;
    att_vec3_t ae;
    att_quat_t qc;
    att_bias_params_t bias_params;
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
    mag_flags = att_sensor_check_mag(mag, f->s.mag_range, &mnorm);
    mag_ok = (mag_flags == 0u);
    flags |= mag_flags;

    /* rest detection and gyro bias (att_bias.c) */
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
            (void)att_quat_normalize(att_quat_from_euler(t.x, t.y, 0.0f), &q);
            if (mag_ok) {
                if (att_mars_align(q, mag, &qa, &m0) && att_mars_set_m0(f, m0)) {
                    q = qa;
                } else {
                    flags |= ATT_FLAG_MAG_REJECTED;
                }
            }
            f->q = q;
            f->lp1 = att_quat_rotate(q, acc);
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
        if (att_quat_normalize(att_mars_propagate(f, q, att_vec3_sub(gyr, f->bias)), &qn)) {
            q = qn;
        } else {
            flags |= ATT_FLAG_NUMERIC;
        }
    }
    if (accel_ok && (flags & ATT_FLAG_ACCEL_REJECTED) == 0u) {
        ae = att_quat_rotate(q, acc);
        if (f->k_lp > 0.0f) {
            /* two cascaded first-order low-passes of the earth-frame specific force */
            f->lp1 = att_vec3_add(f->lp1, att_vec3_scale(att_vec3_sub(ae, f->lp1), f->k_lp));
            f->lp2 = att_vec3_add(f->lp2, att_vec3_scale(att_vec3_sub(f->lp1, f->lp2), f->k_lp));
            ae = f->lp2;
        }
        if (att_vec3_normalize(ae, &unit)) {
            up.x = 0.0f;
            up.y = 0.0f;
            up.z = 1.0f;
            xaxis.x = 1.0f; /* fallback axis for an upside-down attitude */
            xaxis.y = 0.0f;
            xaxis.z = 0.0f;
            qc = att_mars_rotation_toward(unit, up, xaxis, f->k_acc);
            q = att_quat_mul(qc, q);
            if (f->k_lp > 0.0f) {
                /* keep the low-pass states in the corrected earth frame */
                f->lp1 = att_quat_rotate(qc, f->lp1);
                f->lp2 = att_quat_rotate(qc, f->lp2);
            }
        }
    }
    if (mag_ok) {
        if (f->m0_valid) {
            q = att_mars_mag_correct(f, q, mag, mnorm, &flags);
        } else if (f->s.init_from_sensors) {
            if (att_mars_align(q, mag, &qa, &m0) && att_mars_set_m0(f, m0)) {
                q = qa;
                flags |= ATT_FLAG_INITIALISED;
            } else {
                flags |= ATT_FLAG_MAG_REJECTED;
            }
        } else if (!att_mars_set_m0(f, att_quat_rotate(q, mag))) {
            flags |= ATT_FLAG_MAG_REJECTED;
        }
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
