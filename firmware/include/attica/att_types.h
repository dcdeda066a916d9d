/**
 * @file att_types.h
 * @brief Common types, status codes and status flags of attica.
 *
 * Conventions used everywhere in attica:
 * - float32 only; no double anywhere.
 * - Earth frame: ENU (x east, y north, z up). Sensor frame: the IMU's own axes.
 * - Quaternions are stored (w, x, y, z) and rotate sensor-frame vectors into the
 *   earth frame: v_earth = q * v_sensor * conj(q).
 * - Euler angles are ZYX (yaw psi about z, then pitch theta about y, then roll phi about x):
 *   q = Qz(psi) * Qy(theta) * Qx(phi), in rad.
 * - Angular rate in rad/s (sensor frame), specific force in m/s^2 (sensor frame; reads +g up at
 *   rest), magnetic field in uT (sensor frame), time in s.
 */
#ifndef ATT_TYPES_H
#define ATT_TYPES_H

#include "attica/att_config.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/** A 3-vector; units and frame are given where it is used. */
typedef struct {
    float x;
    float y;
    float z;
} att_vec3_t;

/** A quaternion (w, x, y, z); attitudes are unit quaternions, sensor-to-earth (ENU). */
typedef struct {
    float w;
    float x;
    float y;
    float z;
} att_quat_t;

/** Return codes of init/configuration functions. */
typedef enum {
    ATT_OK = 0,            /**< success */
    ATT_ERR_NULL = -1,     /**< a required pointer argument was NULL */
    ATT_ERR_SETTINGS = -2, /**< a setting is out of range or not finite; nothing was changed */
    ATT_ERR_KIND = -3,     /**< unknown filter kind, or a call the kind does not support */
    ATT_ERR_STATE = -4,    /**< the filter's state does not allow the call yet (not initialised) */
    ATT_ERR_DISABLED = -5  /**< the kind or feature is compiled out of this build (att_config.h) */
} att_status_t;

/**
 * Which settings field was refused, and its range (att_filter_settings_check). min and max are the
 * bounds of the rule for the settings checked, with the values of the other fields it names filled
 * in (accel_range "(gravity, 1e4]": min = gravity); the rule says whether they are included. For a
 * rule that is not a range of the field itself they bound what the rule names (|q|^2 of q_init,
 * q_noise * dt with noise_rates; bools and enums: the smallest and largest accepted value).
 */
typedef struct {
    const char *field; /**< "<kind>.<field>" ("ars.tau_acc_lp", "ekf.euler_init.y"); NULL if none refused */
    float min;         /**< lower bound of the rule, for these settings */
    float max;         /**< upper bound of the rule, for these settings (may be +Inf) */
    const char *rule;  /**< the accepted values in words: "[0, 1e4]", "(gravity, 1e4]", "0 or 1" */
    const char *unit;  /**< the field's unit: "s", "rad/s", "m/s^2", "uT", "rad"; "" when it has none */
} att_settings_error_t;

/**
 * Per-step status flags (bit set). Every filter step returns an OR of these.
 * A flag that names a skipped correction means the state was left as it was before that correction.
 */
enum {
    ATT_FLAG_GYRO_INVALID = 0x0001,    /**< gyro sample NaN/Inf: integration skipped */
    ATT_FLAG_GYRO_RANGE = 0x0002,      /**< |gyro component| > gyro_range: up to 2 gyro_range a reading at
                                            the rail, integrated as read; beyond, not used */
    ATT_FLAG_ACCEL_INVALID = 0x0004,   /**< accel NaN/Inf or zero vector: correction skipped */
    ATT_FLAG_ACCEL_RANGE = 0x0008,     /**< |accel| > accel_range (saturation): correction skipped */
    ATT_FLAG_ACCEL_REJECTED = 0x0010,  /**< ||accel| - g| > accel_reject: correction skipped */
    ATT_FLAG_MAG_INVALID = 0x0020,     /**< mag NaN/Inf or huge: correction skipped */
    ATT_FLAG_MAG_ABSENT = 0x0040,      /**< no mag sample (zero or NaN vector): correction skipped */
    ATT_FLAG_MAG_REJECTED = 0x0080,    /**< mag disturbed (norm/dip off): correction skipped */
    ATT_FLAG_AT_REST = 0x0100,         /**< the rest detector says the sensor is still */
    ATT_FLAG_BIAS_UPDATED = 0x0200,    /**< the gyro bias estimate changed this step */
    ATT_FLAG_INITIALISED = 0x0400,     /**< the attitude was (re)initialised from the sensors this step, or
                                            is being (a recovery: ars, mars, kf, ekf, mekf after a clipping
                                            gyro; ars, mars, kf, mekf after the start) */
    ATT_FLAG_GIMBAL = 0x0800,          /**< |cos(theta)| below the guard: value clamped */
    ATT_FLAG_CLAMPED = 0x1000,         /**< an argument was clamped into its domain (e.g. asin) */
    ATT_FLAG_NUMERIC = 0x2000,         /**< numeric failure; state kept from before the step */
    ATT_FLAG_NOT_READY = 0x4000,       /**< no valid attitude yet (waiting for a first valid sample) */
    ATT_FLAG_BAD_ARG = 0x8000          /**< NULL argument or uninitialised state: nothing done */
};
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_TYPES_H */
