/**
 * @file att_gyro.c
 * @brief Gyro-only Euler-rate integration (see att_gyro.h). Mirrored by reference/gyro.py.
 */
#include "att_fp.h"

#include "attica/att_gyro.h"
#include "attica/att_math.h"
#include "attica/att_sensor.h"

#define ATT_PI_F 0x1.921fb6p+1f
#define ATT_PIO2_F 0x1.921fb6p+0f

void att_gyro_settings_default(att_gyro_settings_t *settings, float dt)
{
    if (settings == NULL) {
        return;
    }
    settings->dt = dt;
    settings->gyro_range = 34.906586f;
    settings->cos_min = 0x1.0624dep-10f; /* 1e-3 */
    settings->euler_init.x = 0.0f;
    settings->euler_init.y = 0.0f;
    settings->euler_init.z = 0.0f;
}

att_status_t att_gyro_init(att_gyro_t *f, const att_gyro_settings_t *settings)
{
    if (f == NULL || settings == NULL) {
        return ATT_ERR_NULL;
    }
    if (!(settings->dt > 0.0f && settings->dt <= 1.0f) || !(settings->gyro_range > 0.0f) ||
        !(settings->cos_min > 0.0f && settings->cos_min < 1.0f) || !att_vec3_isfinite(settings->euler_init) ||
        !(att_absf(settings->euler_init.y) <= ATT_PIO2_F) || !(att_absf(settings->euler_init.x) <= 8192.0f) ||
        !(att_absf(settings->euler_init.z) <= 8192.0f)) {
        return ATT_ERR_SETTINGS;
    }
    f->s = *settings;
    att_gyro_reset(f);
    return ATT_OK;
}

void att_gyro_reset(att_gyro_t *f)
{
    if (f == NULL) {
        return;
    }
    f->euler.x = att_wrap_pi(f->s.euler_init.x);
    f->euler.y = f->s.euler_init.y;
    f->euler.z = att_wrap_pi(f->s.euler_init.z);
    f->q = att_quat_from_euler(f->euler.x, f->euler.y, f->euler.z);
    f->steps = 0u;
    f->flags = 0u;
}

uint32_t att_gyro_step(att_gyro_t *f, att_vec3_t gyr)
{
    uint32_t flags;
    float sphi;
    float cphi;
    float sth;
    float cth;
    float tth;
    att_vec3_t e;
    if (f == NULL) {
        return ATT_FLAG_BAD_ARG;
    }
    flags = att_sensor_check_gyro(gyr, f->s.gyro_range);
    if (flags == 0u) {
        sphi = att_sinf(f->euler.x);
        cphi = att_cosf(f->euler.x);
        sth = att_sinf(f->euler.y);
        cth = att_cosf(f->euler.y);
        if (att_absf(cth) < f->s.cos_min) {
            cth = (cth < 0.0f) ? -f->s.cos_min : f->s.cos_min;
            flags |= ATT_FLAG_GIMBAL;
        }
        tth = sth / cth;
        e.x = f->euler.x + (gyr.x + sphi * tth * gyr.y + cphi * tth * gyr.z) * f->s.dt;
        e.y = f->euler.y + (cphi * gyr.y - sphi * gyr.z) * f->s.dt;
        e.z = f->euler.z + (sphi / cth * gyr.y + cphi / cth * gyr.z) * f->s.dt;
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
        if (att_vec3_isfinite(e)) {
            f->euler = e;
            f->q = att_quat_from_euler(e.x, e.y, e.z);
        } else {
            flags |= ATT_FLAG_NUMERIC;
        }
    }
    f->steps = f->steps + 1u;
    f->flags = flags;
    return flags;
}
