/**
 * @file att_gyro.h
 * @brief Gyro-only baseline: ZYX Euler-rate integration.
 *
 * (phi, theta, psi) += E(phi, theta) w dt with the Euler kinematics matrix
 *   phi'   = p + sin(phi) tan(theta) q + cos(phi) tan(theta) r
 *   theta' = cos(phi) q - sin(phi) r
 *   psi'   = sin(phi) / cos(theta) q + cos(phi) / cos(theta) r
 * where (p, q, r) is the sensor-frame rate in rad/s. When |cos(theta)| < cos_min the value is
 * clamped to +-cos_min and ATT_FLAG_GIMBAL is set (the rates stay finite but are wrong there: that
 * is the singularity of the representation). phi, psi are wrapped to (-pi, pi]; a theta beyond
 * +-pi/2 is mapped to the equivalent (phi + pi, +-pi - theta, psi + pi).
 */
#ifndef ATT_GYRO_H
#define ATT_GYRO_H

#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/** Settings of the gyro-only baseline. */
typedef struct {
    float dt;              /**< sample period, s; 0 < dt <= 1 */
    float gyro_range;      /**< any |w_i| above this: step skipped, rad/s */
    float cos_min;         /**< guard on |cos(theta)|, (0, 1) */
    att_vec3_t euler_init; /**< initial (phi, theta, psi), rad */
} att_gyro_settings_t;

/** State of the gyro-only baseline. */
typedef struct {
    att_gyro_settings_t s; /**< validated copy of the settings */
    att_vec3_t euler;      /**< (phi, theta, psi), rad, ZYX sensor-to-earth */
    att_quat_t q;          /**< the same attitude as a quaternion */
    uint32_t steps;        /**< steps since init/reset (wraps) */
    uint32_t flags;        /**< flags of the last step */
} att_gyro_t;

/** Defaults for period dt: range 2000 deg/s, cos_min 1e-3, start level. */
void att_gyro_settings_default(att_gyro_settings_t *settings, float dt);
/** Validate settings and initialise; on error f is unchanged. */
att_status_t att_gyro_init(att_gyro_t *f, const att_gyro_settings_t *settings);
/** Back to the initial state. */
void att_gyro_reset(att_gyro_t *f);
/** One step with the gyro sample (rad/s, sensor frame); returns flags. */
uint32_t att_gyro_step(att_gyro_t *f, att_vec3_t gyr);
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_GYRO_H */
