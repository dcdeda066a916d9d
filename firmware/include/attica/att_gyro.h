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
 * is the singularity of the representation). theta is wrapped to (-pi, pi] and, beyond +-pi/2, mapped
 * to the equivalent (phi + pi, +-pi - theta, psi + pi), so it always lies in [-pi/2, pi/2]; phi and
 * psi are wrapped to (-pi, pi]. A step whose Euler increments are not representable (a roll or yaw
 * angle not finite or beyond the range of att_wrap_pi, 8192 rad: sec(theta) rate dt near +-pi/2 with
 * cos_min below |cos(theta)|) instead turns the attitude by w dt as a quaternion, q exp(w dt / 2), and
 * reads consistent ZYX angles back from it (ATT_FLAG_GIMBAL); ATT_FLAG_NUMERIC (state kept) only if
 * that fails too.
 */
#ifndef ATT_GYRO_H
#define ATT_GYRO_H

#include "attica/att_config.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/** Settings of the gyro-only baseline (valid ranges in brackets; anything else is refused). */
typedef struct {
    float dt;              /**< sample period, s; [1e-6, 1] */
    float gyro_range;      /**< the gyro's full scale, rad/s, (0, 1e3]: a |w_i| beyond it, up to
                               twice it, is a reading at the rail, used as read
                               (ATT_FLAG_GYRO_RANGE); beyond, the sample is not used */
    float cos_min;         /**< guard on |cos(theta)|, (0, 1) */
    att_vec3_t euler_init; /**< initial (phi, theta, psi), rad; x (phi), z (psi) in [-8192, 8192], y (theta) in [-pi/2, pi/2] */
} att_gyro_settings_t;

/** Dynamic state of the gyro-only baseline. */
typedef struct {
    att_vec3_t euler; /**< (phi, theta, psi), rad, ZYX sensor-to-earth; theta in [-pi/2, pi/2] */
    att_quat_t q;     /**< the same attitude as a quaternion */
    uint32_t steps;   /**< steps since init/reset (wraps) */
    uint32_t flags;   /**< flags of the last step */
} att_gyro_state_t;

/** One gyro-only baseline instance: its coefficients are the validated settings. */
typedef struct {
    att_gyro_settings_t c; /**< validated copy of the settings */
    att_gyro_state_t st;   /**< changes every step */
} att_gyro_t;

/** Defaults for period dt: range 2000 deg/s, cos_min 1e-3, start level. */
void att_gyro_settings_default(att_gyro_settings_t *settings, float dt);
/** ATT_OK when every field is within its range, else ATT_ERR_SETTINGS (ATT_ERR_NULL for NULL). */
att_status_t att_gyro_settings_validate(const att_gyro_settings_t *settings);
/** Validate settings and initialise; on error f is unchanged. */
att_status_t att_gyro_init(att_gyro_t *f, const att_gyro_settings_t *settings);
/** New settings, the attitude kept (euler_init only matters at reset); on error f is unchanged. */
att_status_t att_gyro_retune(att_gyro_t *f, const att_gyro_settings_t *settings);
/** Back to the initial state. */
void att_gyro_reset(att_gyro_t *f);
/** One step with the gyro sample (rad/s, sensor frame); returns flags. */
uint32_t att_gyro_step(att_gyro_t *f, att_vec3_t gyr);
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_GYRO_H */
