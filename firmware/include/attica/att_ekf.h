/**
 * @file att_ekf.h
 * @brief Euler-angle extended Kalman filter (EKF), after the Hanyang University lecture notes.
 *
 * State x = (phi, theta, psi), ZYX Euler angles in rad (roll, pitch, yaw; sensor-to-earth, ENU).
 * Per step, with the sensor-frame rate w = (p, q, r) in rad/s and the sample period dt:
 *
 *  1. prediction: x := x + dt E(phi, theta) w with the Euler kinematics
 *       phi'   = p + sin(phi) tan(theta) q + cos(phi) tan(theta) r
 *       theta' = cos(phi) q - sin(phi) r
 *       psi'   = sin(phi) / cos(theta) q + cos(phi) / cos(theta) r
 *     (the same expressions as att_gyro.c), and P := A P A^T + Q with the discretised Jacobian
 *     A = I + dt J evaluated at the state before the step. With u = sin(phi) q + cos(phi) r and
 *     v = cos(phi) q - sin(phi) r, tan = tan(theta), sec = 1 / cos(theta):
 *       J = [ v tan   u sec sec   0 ]
 *           [ -u      0           0 ]
 *           [ v sec   u sec tan   0 ]
 *     An unusable gyro sample is treated as w = 0 (state kept, P := P + Q).
 *     |cos(theta)| below cos_min is clamped to +-cos_min (ATT_FLAG_GIMBAL) in the kinematics and in
 *     J, so P stays finite there (it can grow by a factor of about (dt |w| / cos_min^2)^2 per step).
 *  2. update with the accelerometer (skipped when the sample is unusable or ||a|/g - 1| >
 *     accel_reject): z = (atan2(ay, az), atan2(-ax, sqrt(ay^2 + az^2))) (att_sensor_tilt),
 *     H = [I2 0], innovation y = z - H x wrapped to (-pi, pi] per component, S = H P H^T + R,
 *     K = P H^T S^-1 (explicit 2x2 inverse; det(S) not > 0 or not finite: ATT_FLAG_NUMERIC and no
 *     update), x := x + K y, and the Joseph form P := (I - K H) P (I - K H)^T + K R K^T.
 *  After each stage (prediction, update):
 *  - theta is wrapped to (-pi, pi] and, beyond +-pi/2, mapped to the equivalent attitude
 *    (phi + pi, +-pi - theta, psi + pi); P's theta row and column change sign with it. phi and psi are
 *    wrapped to (-pi, pi].
 *  - P is conditioned: a variance above p_max is brought down to p_max by the congruence D P D
 *    (D diagonal, correlations kept); if P then fails a positive definiteness test with margin (L D L^T
 *    pivots d_i > 2^-12 P_ii), its correlations are multiplied by 1 - 2^-10, or set to zero when that
 *    is not enough. Either sets ATT_FLAG_CLAMPED. In normal operation neither happens until the yaw
 *    variance reaches p_max (after about 1e7 steps with the defaults).
 *  - a stage whose angles or P are not finite, or that leaves a variance not > 0, is discarded
 *    (ATT_FLAG_NUMERIC): a failed prediction leaves the state as before the step (the update still
 *    runs), a failed update leaves the predicted state.
 *  P is stored exactly symmetric (upper triangle computed, mirrored).
 *
 * Noises: with noise_rates (default) the q_* are rates (rad^2/s, added as q dt per step) and the r_*
 * densities (rad^2 s, R = r / dt per sample), so the time constants do not depend on dt; without,
 * per step / per sample as in the notes. Defaults (tuned on BROAD, docs/accuracy.md): q_phi = q_theta
 * 0.03 rad^2/s, q_psi 1 rad^2/s, r_phi = r_theta 3 rad^2 s, P0 = I. The notes' Q = diag(1e-4, 1e-4, 0.1)
 * per step and R = 6 I2 are the seed preset (att_filter_settings_preset). Yaw is not observed: its
 * variance grows every step (up to p_max).
 *
 * Units: rad, rad/s, m/s^2, s, variances rad^2. Frames: gyro/accel in the sensor frame.
 */
#ifndef ATT_EKF_H
#define ATT_EKF_H

#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/** Settings of the Euler EKF. Fill with att_ekf_settings_default, then change fields. */
typedef struct {
    float dt;              /**< sample period, s; 0 < dt <= 1 */
    float q_phi;           /**< process noise variance of roll per step, rad^2; [0, 1e6] */
    float q_theta;         /**< process noise variance of pitch per step, rad^2; [0, 1e6] */
    float q_psi;           /**< process noise variance of yaw per step, rad^2; [0, 1e6] */
    float r_phi;           /**< measurement noise variance of accel roll, rad^2; (0, 1e6] */
    float r_theta;         /**< measurement noise variance of accel pitch, rad^2; (0, 1e6] */
    float p0;              /**< initial variance of each angle (P0 = p0 I), rad^2; (0, p_max] */
    float p_max;           /**< cap on each variance (numeric guard), rad^2; [1e-6, 1e6] */
    float gravity;         /**< g, m/s^2; > 0 */
    float accel_reject;    /**< skip the update when ||a|/g - 1| > this; 0 = never skip */
    float accel_range;     /**< |a| above this is saturation: update skipped, m/s^2; > 0 */
    float gyro_range;      /**< any |w_i| above this: prediction with w = 0, rad/s; > 0 */
    float cos_min;         /**< guard on |cos(theta)|, (0, 1) */
    bool init_from_accel;  /**< take roll/pitch from the first valid accel sample (yaw 0) */
    att_vec3_t euler_init; /**< start (phi, theta, psi) when init_from_accel is false, rad; |theta| <= pi/2 */
    bool noise_rates;      /**< true: q_* in rad^2/s (Q = q dt), r_* in rad^2 s (R = r / dt) */
} att_ekf_settings_t;

/** State of one Euler EKF instance (no heap; copy freely). */
typedef struct {
    att_ekf_settings_t s; /**< validated copy of the settings */
    float q_step[3];      /**< process noise variances added per step (phi, theta, psi), rad^2 */
    float r_step[2];      /**< measurement noise variances of one sample (phi, theta), rad^2 */
    att_vec3_t euler;     /**< (phi, theta, psi), rad, ZYX sensor-to-earth (ENU) */
    att_quat_t q;         /**< att_quat_from_euler(euler), sensor-to-earth */
    float p[3][3];        /**< error covariance of (phi, theta, psi), rad^2, symmetric */
    bool initialised;     /**< euler holds a valid attitude */
    uint32_t steps;       /**< steps taken since init/reset (wraps) */
    uint32_t flags;       /**< flags of the last step */
} att_ekf_t;

/** Default settings for sample period dt (s): rate noises (above), P0 = I, accel_reject 0.1. */
void att_ekf_settings_default(att_ekf_settings_t *settings, float dt);
/** ATT_OK when every field is within its range, else ATT_ERR_SETTINGS (ATT_ERR_NULL for NULL). */
att_status_t att_ekf_settings_validate(const att_ekf_settings_t *settings);
/** Validate settings and initialise f. On error f is left unchanged. */
att_status_t att_ekf_init(att_ekf_t *f, const att_ekf_settings_t *settings);
/** New settings (noises, limits), the angles and covariance kept; on error f is unchanged. */
att_status_t att_ekf_retune(att_ekf_t *f, const att_ekf_settings_t *settings);
/** Back to the state right after att_ekf_init, keeping the settings. */
void att_ekf_reset(att_ekf_t *f);
/** One update with gyro (rad/s) and accel (m/s^2), sensor frame; returns ATT_FLAG_* bits. */
uint32_t att_ekf_step(att_ekf_t *f, att_vec3_t gyr, att_vec3_t acc);
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_EKF_H */
