/**
 * @file att_sensor.h
 * @brief Checks of raw sensor samples and attitude from gravity, shared by all filters.
 */
#ifndef ATT_SENSOR_H
#define ATT_SENSOR_H

#include "attica/att_config.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/**
 * Check a gyro sample (rad/s, sensor frame): ATT_FLAG_GYRO_INVALID when a component is NaN/Inf,
 * else ATT_FLAG_GYRO_RANGE when a component's magnitude exceeds range; 0 when within range. (The filters
 * still integrate a GYRO_RANGE sample within twice the range, as read: a reading at the rail.)
 */
uint32_t att_sensor_check_gyro(att_vec3_t gyr, float range);
/**
 * Check an accel sample (m/s^2, sensor frame): ATT_FLAG_ACCEL_INVALID when non-finite or with
 * |a|^2 < 2^-100, else ATT_FLAG_ACCEL_RANGE when |a| > range; 0 when usable. *norm = |a| (0 when
 * invalid). norm may be NULL.
 */
uint32_t att_sensor_check_accel(att_vec3_t acc, float range, float *norm);
/**
 * Check a magnetometer sample (uT, sensor frame): ATT_FLAG_MAG_ABSENT when a component is NaN or the
 * vector is exactly zero (the "no sample" encodings), else ATT_FLAG_MAG_INVALID when a component is
 * +-Inf or |m| > range (or |m|^2 < 2^-100); 0 when usable. *norm = |m| (0 when not usable); may be NULL.
 */
uint32_t att_sensor_check_mag(att_vec3_t mag, float range, float *norm);
/**
 * Roll and pitch (rad) of the sensor from the specific force acc (sensor frame, +g up at rest),
 * ZYX convention: phi = atan2(ay, az), theta = atan2(-ax, sqrt(ay^2 + az^2)); returned as
 * (phi, theta, 0). Well defined for any non-zero vector; caller checks validity first.
 */
att_vec3_t att_sensor_tilt(att_vec3_t acc);
/**
 * Number of samples covering seconds at period dt: ceil(seconds / dt), limited to [0, 2^24].
 * NaN or negative gives 0.
 */
uint32_t att_sensor_samples(float seconds, float dt);
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_SENSOR_H */
