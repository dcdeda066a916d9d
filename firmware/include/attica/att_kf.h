/**
 * @file att_kf.h
 * @brief Linear quaternion Kalman filter (6-axis), after the Hanyang University lecture notes.
 *
 * State x = q = (w, x, y, z), sensor-to-earth (ENU), with covariance P (4x4). Per step:
 *  1. prediction with the gyro rate w = (p, q, r) (rad/s, sensor frame):
 *     A = I + dt/2 * Omega(w),  Omega = [[0,-p,-q,-r],[p,0,r,-q],[q,-r,0,p],[r,q,-p,0]]
 *     (q_dot = q * (0, w) / 2; the notes print the (4,3) entry as -q, it is -p),
 *     x := A x,  P := A P A^T + Q,  Q = q_step * I, then P symmetrised. With noise_rates (default)
 *     q_step = q_noise * dt and r_step = r_noise / dt (a white-noise rate and a noise density), so the
 *     steady-state gain per second, hence the filter's time constant, does not depend on dt; without,
 *     q_step = q_noise and r_step = r_noise per step (the notes).
 *     When the gyro sample is unusable (ATT_FLAG_GYRO_INVALID / ATT_FLAG_GYRO_RANGE) the state is
 *     not propagated (A = I: x unchanged) but time still passes: P := P + Q.
 *  2. measurement z = att_quat_from_euler(phi, theta, psi) with roll phi and pitch theta from the
 *     accelerometer (att_sensor_tilt) and yaw psi = yaw of the predicted state (ATT_KF_YAW_STATE,
 *     default) or 0 (ATT_KF_YAW_ZERO, the notes' literal choice). z is negated when z . x < 0 (the
 *     sign nearest x). H = I.
 *     S = P + R (R = r_step * I), Cholesky S = L L^T in a fixed order; K = P S^-1 by forward and
 *     back substitution (fixed order); x := x + K (z - x);
 *     P := (I - K) P (I - K)^T + r_noise * K K^T (Joseph form), then symmetrised:
 *     P_ij := (P_ij + P_ji) * 0.5, which makes P bitwise symmetric.
 *     The update is skipped when the accel sample is unusable (ATT_FLAG_ACCEL_INVALID /
 *     ATT_FLAG_ACCEL_RANGE), when ||a|/g - 1| > accel_reject (ATT_FLAG_ACCEL_REJECTED), or with
 *     ATT_FLAG_NUMERIC (predicted x and P kept) when a Cholesky pivot is not > 0 / not finite or
 *     the updated x or P is not finite.
 *  3. normalisation x := x / |x| and, as the same linear scaling, P := P / |x|^2. (Not in the notes:
 *     A is not orthogonal, |A x| = sqrt(1 + (dt/2)^2 |w|^2) |x|, so without this P would grow
 *     geometrically whenever the update is skipped during fast rotation and overflow within seconds;
 *     with it the prediction of P is a pure rotation. Effect on normal operation: below 1e-3
 *     relative per step.) If x cannot be normalised or P is not finite, the whole state from before
 *     the step is kept and ATT_FLAG_NUMERIC is set.
 *
 * Before a valid attitude exists (init_from_accel) the filter waits for the first usable accel
 * sample (ATT_FLAG_NOT_READY), takes roll/pitch from it with yaw 0 (ATT_FLAG_INITIALISED), and
 * starts predicting on the next step. P starts as p0 * I.
 *
 * Note: yaw is unobservable; with ATT_KF_YAW_STATE the yaw of z equals the state's yaw, so the
 * accelerometer never moves the yaw (apart from the Euler coupling near pitch +-90 deg, where roll
 * from the accelerometer is ill-defined and the notes' Euler construction of z is unreliable),
 * but P still shrinks in the yaw direction as if it were measured.
 *
 * Units: rad/s, m/s^2, s. Frames: gyro/accel in the sensor frame; q sensor-to-earth (ENU, z up).
 * Mirrored bit for bit by host/attica/reference/kf.py.
 */
#ifndef ATT_KF_H
#define ATT_KF_H

#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/** Yaw of the accelerometer measurement quaternion z. */
typedef enum {
    ATT_KF_YAW_STATE = 0, /**< psi = yaw of the predicted state (yaw does not jump; default) */
    ATT_KF_YAW_ZERO = 1   /**< psi = 0, as in the lecture notes (pulls the yaw toward 0) */
} att_kf_yaw_mode_t;

/** Settings of the linear quaternion KF. Fill with att_kf_settings_default, then change fields. */
typedef struct {
    float dt;                   /**< sample period, s; [1e-6, 1] */
    float q_noise;              /**< process noise Q = q_noise * I per step, (unit quaternion)^2; 1e-12..1e12 */
    float r_noise;              /**< measurement noise R = r_noise * I, (unit quaternion)^2; 1e-12..1e12 */
    float p0;                   /**< initial covariance P0 = p0 * I, (unit quaternion)^2; 1e-12..1e12 */
    float gravity;              /**< g, m/s^2; [1, 100] */
    float accel_reject;         /**< skip the update when ||a|/g - 1| > this, [0, 1e3]; 0 = never skip */
    float accel_range;          /**< |a| above this is saturation: update skipped, m/s^2; (gravity, 1e4] */
    float gyro_range;           /**< any |w_i| above this: propagation skipped, rad/s; (0, 1e3] */
    att_kf_yaw_mode_t yaw_mode; /**< yaw of the measurement quaternion */
    bool init_from_accel;       /**< take roll/pitch from the first usable accel sample (yaw 0) */
    att_quat_t q_init;          /**< initial attitude when init_from_accel is false, sensor-to-earth */
    bool noise_rates;           /**< true: q_noise per s (Q = q_noise dt), r_noise in unit^2 s (R = r_noise / dt) */
} att_kf_settings_t;

/** State of one linear quaternion KF instance (no heap; copy freely). */
typedef struct {
    att_kf_settings_t s; /**< validated copy of the settings */
    float q_step;        /**< process noise added per step (Q = q_step I) */
    float r_step;        /**< measurement noise of one sample (R = r_step I) */
    att_quat_t q;        /**< state x: attitude, unit, sensor-to-earth (ENU) */
    float p[4][4];       /**< covariance P of (w, x, y, z), (unit quaternion)^2; bitwise symmetric */
    bool initialised;    /**< q holds a valid attitude */
    uint32_t steps;      /**< steps taken since init/reset (wraps) */
    uint32_t flags;      /**< flags of the last step */
} att_kf_t;

/**
 * Default settings for sample period dt (s), tuned on BROAD and rate-independent (noise_rates):
 * q_noise 1e-3 /s (Q = 1e-3 dt I), r_noise 0.1 s (R = 0.1 / dt I), P0 = I, accel_reject 0.1. The notes'
 * literal Q = 1e-4 I, R = 10 I per step are the seed preset (att_filter_settings_preset).
 */
void att_kf_settings_default(att_kf_settings_t *settings, float dt);
/** ATT_OK when every field is within its range, else ATT_ERR_SETTINGS (ATT_ERR_NULL for NULL). */
att_status_t att_kf_settings_validate(const att_kf_settings_t *settings);
/** Validate settings and initialise f. ATT_ERR_NULL / ATT_ERR_SETTINGS leave f unchanged. */
att_status_t att_kf_init(att_kf_t *f, const att_kf_settings_t *settings);
/** New settings (noises, limits), the attitude and covariance kept; on error f is unchanged. */
att_status_t att_kf_retune(att_kf_t *f, const att_kf_settings_t *settings);
/** Back to the state right after att_kf_init, keeping the settings. */
void att_kf_reset(att_kf_t *f);
/** One update with gyro (rad/s) and accel (m/s^2), sensor frame; returns ATT_FLAG_* bits. */
uint32_t att_kf_step(att_kf_t *f, att_vec3_t gyr, att_vec3_t acc);
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_KF_H */
