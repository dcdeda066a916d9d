/**
 * @file att_tilt.c
 * @brief Accel-only tilt baseline (see att_tilt.h). Mirrored by reference/tilt.py.
 */
#include "att_fp.h"

#include "attica/att_math.h"
#include "attica/att_sensor.h"
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

att_status_t att_tilt_init(att_tilt_t *f, const att_tilt_settings_t *settings)
{
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    if (!(settings->gravity > 0.0f && settings->gravity < 1000.0f) || !(settings->accel_range > 0.0f)) {
        return ATT_ERR_SETTINGS;
    }
    f->s = *settings;
    att_tilt_reset(f);
    return ATT_OK;
}

void att_tilt_reset(att_tilt_t *f)
{
    if (f == NULL) {
        return;
    }
    f->euler.x = 0.0f;
    f->euler.y = 0.0f;
    f->euler.z = 0.0f;
    f->q = att_quat_identity();
    f->valid = false;
    f->steps = 0u;
    f->flags = 0u;
}

uint32_t att_tilt_step(att_tilt_t *f, att_vec3_t acc)
{
    uint32_t flags;
    float norm;
    float s;
    if (f == NULL) {
        return ATT_FLAG_BAD_ARG;
    }
    flags = att_sensor_check_accel(acc, f->s.accel_range, &norm);
    if (flags == 0u) {
        s = -acc.x / (f->s.normalise ? norm : f->s.gravity);
        if (att_absf(s) > 1.0f) {
            s = (s < 0.0f) ? -1.0f : 1.0f;
            flags |= ATT_FLAG_CLAMPED;
        }
        f->euler.x = att_atan2f(acc.y, acc.z);
        f->euler.y = att_asinf(s);
        f->euler.z = 0.0f;
        f->q = att_quat_from_euler(f->euler.x, f->euler.y, 0.0f);
        f->valid = true;
    } else if (!f->valid) {
        flags |= ATT_FLAG_NOT_READY;
    }
    f->steps = f->steps + 1u;
    f->flags = flags;
    return flags;
}
