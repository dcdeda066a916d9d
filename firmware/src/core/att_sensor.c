/**
 * @file att_sensor.c
 * @brief Sensor sample checks (see att_sensor.h). Mirrored by host/attica/reference/sensor.py.
 */
#include "../math/att_fp.h"

#include "attica/att_math.h"
#include "attica/att_sensor.h"

#define ATT_NORM2_MIN 0x1p-100f
#define ATT_SAMPLES_MAX 0x1p+24f

uint32_t att_sensor_check_gyro(att_vec3_t gyr, float range)
{
    if (!att_vec3_isfinite(gyr)) {
        return ATT_FLAG_GYRO_INVALID;
    }
    if (att_absf(gyr.x) > range || att_absf(gyr.y) > range || att_absf(gyr.z) > range) {
        return ATT_FLAG_GYRO_RANGE;
    }
    return 0u;
}

uint32_t att_sensor_check_accel(att_vec3_t acc, float range, float *norm)
{
    float n2;
    float n = 0.0f;
    uint32_t flags = 0u;
    if (!att_vec3_isfinite(acc)) {
        flags = ATT_FLAG_ACCEL_INVALID;
    } else {
        n2 = att_vec3_dot(acc, acc);
        if (!(n2 >= ATT_NORM2_MIN)) {
            flags = ATT_FLAG_ACCEL_INVALID;
        } else {
            n = att_sqrtf(n2); /* n2 may be +Inf for huge input: then n = Inf > range */
            if (n > range) {
                flags = ATT_FLAG_ACCEL_RANGE;
            }
        }
    }
    if (norm != NULL) {
        *norm = n;
    }
    return flags;
}

uint32_t att_sensor_check_mag(att_vec3_t mag, float range, float *norm)
{
    float n2;
    float n = 0.0f;
    uint32_t flags = 0u;
    if (mag.x != mag.x || mag.y != mag.y || mag.z != mag.z ||
        (mag.x == 0.0f && mag.y == 0.0f && mag.z == 0.0f)) {
        flags = ATT_FLAG_MAG_ABSENT;
    } else if (!att_vec3_isfinite(mag)) {
        flags = ATT_FLAG_MAG_INVALID;
    } else {
        n2 = att_vec3_dot(mag, mag);
        n = att_sqrtf(n2);
        if (!(n2 >= ATT_NORM2_MIN) || n > range) {
            flags = ATT_FLAG_MAG_INVALID;
            n = 0.0f;
        }
    }
    if (norm != NULL) {
        *norm = n;
    }
    return flags;
}

att_vec3_t att_sensor_tilt(att_vec3_t acc)
{
    att_vec3_t e;
    e.x = att_atan2f(acc.y, acc.z);
    e.y = att_atan2f(-acc.x, att_sqrtf(acc.y * acc.y + acc.z * acc.z));
    e.z = 0.0f;
    return e;
}

uint32_t att_sensor_samples(float seconds, float dt)
{
    float ratio = seconds / dt;
    uint32_t n;
    if (!(ratio > 0.0f)) {
        return 0u;
    }
    if (ratio > ATT_SAMPLES_MAX) {
        ratio = ATT_SAMPLES_MAX;
    }
    n = (uint32_t)ratio; /* in range: 0 < ratio <= 2^24 */
    if ((float)n < ratio) {
        n = n + 1u;
    }
    return n;
}
