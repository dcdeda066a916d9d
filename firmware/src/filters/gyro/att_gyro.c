/**
 * @file att_gyro.c
 * @brief Gyro-only Euler-rate integration (see att_gyro.h). Mirrored by reference/gyro.py.
 */
#include "../../math/att_fp.h"

#include "../../core/att_core.h"
#include "../att_kinds.h"
#include "../att_yaw.h"
#include "att_gyro_checks.h"
#include "attica/att_gyro.h"
#include "attica/att_math.h"

#define ATT_PI_F 0x1.921fb6p+1f

void att_gyro_settings_default(att_gyro_settings_t *settings, float dt)
{
    if (settings == NULL) {
        return;
    }
    settings->dt = dt;
    settings->gyro_range = 34.906586f;
    settings->cos_min = 0x1.0624dep-10f; /* 1e-3 */
    settings->euler_init = att_i_vec3(0.0f, 0.0f, 0.0f);
}

att_status_t att_gyro_settings_validate(const att_gyro_settings_t *s)
{
    if (s == NULL) {
        return ATT_ERR_NULL;
    }
    if (!(true ATT_GYRO_CHECKS(ATT_CHECK_AND))) {
        return ATT_ERR_SETTINGS;
    }
    return ATT_OK;
}

att_status_t att_gyro_init(att_gyro_t *f, const att_gyro_settings_t *settings)
{
    att_status_t st;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    st = att_gyro_settings_validate(settings);
    if (st != ATT_OK) {
        return st;
    }
    f->c = *settings;
    att_gyro_reset(f);
    return ATT_OK;
}

att_status_t att_gyro_retune(att_gyro_t *f, const att_gyro_settings_t *settings)
{
    att_status_t st;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    st = att_gyro_settings_validate(settings);
    if (st == ATT_OK) {
        f->c = *settings;
    }
    return st;
}

void att_gyro_reset(att_gyro_t *f)
{
    if (f == NULL) {
        return;
    }
    f->st.euler.x = att_wrap_pi(f->c.euler_init.x);
    f->st.euler.y = f->c.euler_init.y;
    f->st.euler.z = att_wrap_pi(f->c.euler_init.z);
    f->st.q = att_quat_from_euler(f->st.euler.x, f->st.euler.y, f->st.euler.z);
    f->st.steps = 0u;
    f->st.flags = 0u;
}

/*
 * D1 (issue 26): near pitch +-pi/2 with a small cos_min, sec(theta) * rate * dt gives a roll or yaw
 * increment that att_wrap_pi cannot take (|angle| > 8192 rad, or not finite). That step used to be
 * NUMERIC with the angles kept, and under a steady rotation the next sample repeated it for ever. The
 * Euler representation is singular there, not the motion: such a step instead turns the attitude by
 * the rotation vector w dt as a quaternion (exact for a constant rate over the period), q_new =
 * q * exp(w dt / 2), and reads consistent ZYX angles back from its rotation matrix m: psi =
 * atan2(m21, m11), then theta and phi from Rz(psi)^T m (rows 1 and 2), which stay accurate when
 * cos(theta) is at rounding level and psi itself is noise (phi and psi alone are not defined at the
 * pole; the attitude they give is). The step is flagged GIMBAL; NUMERIC (the state kept) only if
 * this fails too (it cannot for an accepted sample: |w dt| <= 1e3 sqrt(3) rad). Every step whose Euler
 * increments are representable is unchanged (the clamped, wrong rates of the GIMBAL zone included: the
 * baseline). Mirrored by reference/gyro.py rotated_euler.
 */
static uint32_t gyro_rotate(att_gyro_t *f, att_vec3_t gyr, float dt)
{
    att_quat_t q;
    att_vec3_t e;
    float m[9];
    float sps;
    float cps;
    const att_quat_t dq = att_i_quat_from_rotvec(att_i_vec3_scale(gyr, dt));
    const bool ok = att_i_quat_normalize_bounded(att_i_quat_mul(f->st.q, dq), &q);
    att_i_quat_to_matrix(q, m);
    e.z = att_atan2f(m[3], m[0]);
    att_i_sincosf(e.z, &sps, &cps);
    e.y = att_atan2f(-m[6], cps * m[0] + sps * m[3]);
    e.x = att_atan2f(sps * m[2] - cps * m[5], cps * m[4] - sps * m[1]);
    e.y = att_i_clampf(e.y, -ATT_PIO2_F, ATT_PIO2_F);
    e.x = att_wrap_pi(e.x);
    e.z = att_wrap_pi(e.z);
    if (!ok || !att_i_vec3_isfinite(e)) {
        return ATT_FLAG_NUMERIC;
    }
    f->st.euler = e;
    f->st.q = att_quat_from_euler(e.x, e.y, e.z);
    return ATT_FLAG_GIMBAL;
}

uint32_t att_gyro_step(att_gyro_t *f, att_vec3_t gyr)
{
    uint32_t flags;
    float sphi;
    float cphi;
    float sth;
    float cth;
    float tth;
    float dt;
    att_vec3_t e;
    if (f == NULL) {
        return ATT_FLAG_BAD_ARG;
    }
    flags = att_i_sensor_check_gyro(gyr, f->c.gyro_range);
    if (att_i_gyro_usable(gyr, f->c.gyro_range, flags)) {
        dt = f->c.dt;
        att_i_sincosf(f->st.euler.x, &sphi, &cphi);
        att_i_sincosf(f->st.euler.y, &sth, &cth);
        if (att_i_absf(cth) < f->c.cos_min) {
            cth = (cth < 0.0f) ? -f->c.cos_min : f->c.cos_min;
            flags |= ATT_FLAG_GIMBAL;
        }
        tth = sth / cth;
        e.x = f->st.euler.x + (gyr.x + sphi * tth * gyr.y + cphi * tth * gyr.z) * dt;
        e.y = f->st.euler.y + (cphi * gyr.y - sphi * gyr.z) * dt;
        e.z = f->st.euler.z + (sphi / cth * gyr.y + cphi / cth * gyr.z) * dt;
        /* theta into (-pi, pi], then beyond +-pi/2 to the equivalent attitude */
        e.y = att_wrap_pi(e.y);
        if (e.y > ATT_PIO2_F) {
            e.y = ATT_PI_F - e.y;
            e.x = e.x + ATT_PI_F;
            e.z = e.z + ATT_PI_F;
        } else if (e.y < -ATT_PIO2_F) {
            e.y = -ATT_PI_F - e.y;
            e.x = e.x + ATT_PI_F;
            e.z = e.z + ATT_PI_F;
        }
        e.x = att_wrap_pi(e.x);
        e.z = att_wrap_pi(e.z);
        if (att_i_vec3_isfinite(e)) {
            f->st.euler = e;
            f->st.q = att_quat_from_euler(e.x, e.y, e.z);
        } else {
            /* D1: not representable as an Euler step: the rotation as a quaternion (gyro_rotate) */
            flags |= gyro_rotate(f, gyr, dt);
        }
    }
    f->st.steps = f->st.steps + 1u;
    f->st.flags = flags;
    return flags;
}

/* --- hooks of the kind table (att_kinds.h) ------------------------------------------------- */

void att_gyro_preset(att_gyro_settings_t *s, att_preset_t preset, float dt)
{
    (void)preset;
    att_gyro_settings_default(s, dt); /* nothing was tuned: the seed preset is the defaults */
}

float att_gyro_period(const att_gyro_settings_t *s)
{
    return s->dt;
}

ATT_NOINLINE void att_gyro_output(const att_gyro_t *f, att_output_t *out)
{
    out->q = f->st.q;
    out->euler = f->st.euler;
    out->gyro_bias = att_i_vec3(0.0f, 0.0f, 0.0f);
    out->flags = f->st.flags;
    out->steps = f->st.steps;
    out->valid = ATT_OUT_Q | ATT_OUT_BIAS | ATT_OUT_EULER;
}

uint32_t att_gyro_step_out(att_gyro_t *restrict f, const att_sample_t *restrict in, att_output_t *restrict out)
{
    const uint32_t flags = att_gyro_step(f, in->gyr);
    if (out != NULL) {
        att_gyro_output(f, out);
    }
    return flags;
}

att_heading_t att_gyro_heading_kind(const att_gyro_t *f)
{
    (void)f;
    return ATT_HEADING_UPDATE;
}

att_status_t att_gyro_yaw_to(att_gyro_t *f, float target, float gain)
{
    float d;
    float s;
    float c;
    const float yaw = f->st.euler.z;
    if (!att_yaw_turn(yaw, target, gain, &d, &s, &c)) {
        return ATT_ERR_STATE; /* a yaw outside the wrap domain */
    }
    f->st.euler.z = (gain == 1.0f) ? target : att_wrap_pi(yaw + d);
    f->st.q = att_quat_from_euler(f->st.euler.x, f->st.euler.y, f->st.euler.z);
    return ATT_OK;
}

bool att_gyro_set_gain(att_gyro_settings_t *s, att_gain_t gain, float value)
{
    (void)s;
    (void)gain;
    (void)value;
    return false;
}
