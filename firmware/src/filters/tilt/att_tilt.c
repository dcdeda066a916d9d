/**
 * @file att_tilt.c
 * @brief Accel-only tilt baseline (see att_tilt.h). Mirrored by reference/tilt.py.
 */
#include "../../math/att_fp.h"

#include "../../core/att_core.h"
#include "../att_kinds.h"
#include "../att_yaw.h"
#include "att_tilt_checks.h"
#include "attica/att_math.h"
#include "attica/att_tilt.h"

void att_tilt_settings_default(att_tilt_settings_t *settings)
{
    if (settings == NULL) {
        return;
    }
    settings->gravity = 9.80665f;
    settings->accel_range = 156.9064f;
    settings->normalise = true;
}

att_status_t att_tilt_settings_validate(const att_tilt_settings_t *s)
{
    if (s == NULL) {
        return ATT_ERR_NULL;
    }
    if (!(true ATT_TILT_CHECKS(ATT_CHECK_AND))) {
        return ATT_ERR_SETTINGS;
    }
    return ATT_OK;
}

att_status_t att_tilt_init(att_tilt_t *f, const att_tilt_settings_t *settings)
{
    att_status_t st;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    st = att_tilt_settings_validate(settings);
    if (st != ATT_OK) {
        return st;
    }
    f->c = *settings;
    att_tilt_reset(f);
    return ATT_OK;
}

att_status_t att_tilt_retune(att_tilt_t *f, const att_tilt_settings_t *settings)
{
    att_status_t st;
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    st = att_tilt_settings_validate(settings);
    if (st == ATT_OK) {
        f->c = *settings;
    }
    return st;
}

void att_tilt_reset(att_tilt_t *f)
{
    if (f == NULL) {
        return;
    }
    f->st.euler = att_i_vec3(0.0f, 0.0f, 0.0f);
    f->st.q = att_i_quat_identity();
    f->st.valid = false;
    f->st.steps = 0u;
    f->st.flags = 0u;
}

uint32_t att_tilt_step(att_tilt_t *f, att_vec3_t acc)
{
    uint32_t flags;
    float norm;
    float s;
    if (f == NULL) {
        return ATT_FLAG_BAD_ARG;
    }
    flags = att_i_sensor_check_accel(acc, f->c.accel_range, &norm);
    if (flags == 0u) {
        s = -acc.x / (f->c.normalise ? norm : f->c.gravity);
        if (att_i_absf(s) > 1.0f) {
            s = (s < 0.0f) ? -1.0f : 1.0f;
            flags |= ATT_FLAG_CLAMPED;
        }
        f->st.euler.x = att_atan2f(acc.y, acc.z);
        f->st.euler.y = att_asinf(s);
        f->st.euler.z = 0.0f;
        f->st.q = att_quat_from_euler(f->st.euler.x, f->st.euler.y, 0.0f);
        f->st.valid = true;
    } else if (!f->st.valid) {
        flags |= ATT_FLAG_NOT_READY;
    }
    f->st.steps = f->st.steps + 1u;
    f->st.flags = flags;
    return flags;
}

/* --- hooks of the kind table (att_kinds.h) ------------------------------------------------- */

void att_tilt_preset(att_tilt_settings_t *s, att_preset_t preset, float dt)
{
    (void)preset;
    (void)dt; /* no sample period: each sample stands alone */
    att_tilt_settings_default(s);
}

float att_tilt_period(const att_tilt_settings_t *s)
{
    (void)s;
    return 0.0f;
}

ATT_NOINLINE void att_tilt_output(const att_tilt_t *f, att_output_t *out)
{
    out->q = f->st.q;
    out->euler = f->st.euler;
    out->gyro_bias = att_i_vec3(0.0f, 0.0f, 0.0f);
    out->flags = f->st.flags;
    out->steps = f->st.steps;
    out->valid = ATT_OUT_Q | ATT_OUT_BIAS | ATT_OUT_EULER;
}

uint32_t att_tilt_step_out(att_tilt_t *restrict f, const att_sample_t *restrict in, att_output_t *restrict out)
{
    const uint32_t flags = att_tilt_step(f, in->acc);
    if (out != NULL) {
        att_tilt_output(f, out);
    }
    return flags;
}

att_heading_t att_tilt_heading_kind(const att_tilt_t *f)
{
    (void)f;
    return ATT_HEADING_NONE; /* no heading: accel alone does not observe it */
}

att_status_t att_tilt_yaw_to(att_tilt_t *f, float target, float gain)
{
    (void)f;
    (void)target;
    (void)gain;
    return ATT_ERR_KIND;
}

bool att_tilt_set_gain(att_tilt_settings_t *s, att_gain_t gain, float value)
{
    (void)s;
    (void)gain;
    (void)value;
    return false;
}
