/**
 * @file att_tilt.c
 * @brief Accel-only tilt baseline (see att_tilt.h). Mirrored by reference/tilt.py.
 */
#include "../../math/att_fp.h"

#include "../../core/att_core.h"
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
    if (!att_i_in(s->gravity, ATT_GRAVITY_MIN, ATT_GRAVITY_MAX) || !(s->accel_range > s->gravity) ||
        !(s->accel_range <= ATT_ACCEL_RANGE_MAX) || !att_i_bool_ok(&s->normalise)) {
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
