/**
 * @file att_tilt.h
 * @brief Accel-only baseline: roll and pitch from the specific force, yaw 0.
 *
 * theta = asin(-ax / d) and phi = atan2(ay, az), where d = |a| (normalise, default) or d = g
 * (the textbook form asin(fx / g); the minus sign is ours: with ZYX angles and a sensor-to-earth
 * quaternion, at rest a = g (-sin(theta), sin(phi) cos(theta), cos(phi) cos(theta))). When
 * |ax| > d the argument is clamped to +-1 and ATT_FLAG_CLAMPED is set. Invalid or saturated
 * samples keep the previous attitude.
 */
#ifndef ATT_TILT_H
#define ATT_TILT_H

#include "attica/att_config.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/** Settings of the tilt baseline (valid ranges in brackets; anything else is refused). */
typedef struct {
    float gravity;     /**< g, m/s^2, [1, 100] (used when normalise is false) */
    float accel_range; /**< |a| above this is saturation: sample skipped, m/s^2; (gravity, 1e4] */
    bool normalise;    /**< divide by |a| (true) or by g (false) */
} att_tilt_settings_t;

/** Dynamic state of the tilt baseline. */
typedef struct {
    att_vec3_t euler; /**< (phi, theta, 0), rad */
    att_quat_t q;     /**< the same attitude as a quaternion */
    uint32_t steps;   /**< steps since init/reset (wraps) */
    uint32_t flags;   /**< flags of the last step */
    bool valid;       /**< a valid sample has been seen */
} att_tilt_state_t;

/** One tilt baseline instance: its coefficients are the validated settings. */
typedef struct {
    att_tilt_settings_t c; /**< validated copy of the settings */
    att_tilt_state_t st;   /**< changes every step */
} att_tilt_t;

/** Defaults: g = 9.80665, range 16 g, normalise. */
void att_tilt_settings_default(att_tilt_settings_t *settings);
/** ATT_OK when every field is within its range, else ATT_ERR_SETTINGS (ATT_ERR_NULL for NULL). */
att_status_t att_tilt_settings_validate(const att_tilt_settings_t *settings);
/** Validate settings and initialise; on error f is unchanged. */
att_status_t att_tilt_init(att_tilt_t *f, const att_tilt_settings_t *settings);
/** New settings, the state kept; on error f is unchanged. */
att_status_t att_tilt_retune(att_tilt_t *f, const att_tilt_settings_t *settings);
/** Back to the initial state (level, not valid). */
void att_tilt_reset(att_tilt_t *f);
/** One step with the accel sample (m/s^2, sensor frame); returns flags. */
uint32_t att_tilt_step(att_tilt_t *f, att_vec3_t acc);
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_TILT_H */
