/**
 * @file att_ekf.h
 * @brief Euler-angle extended Kalman filter with gyro bias states (6-state EKF), after the Hanyang
 * University lecture notes, made robust like att_kf.h.
 *
 * State x = (phi, theta, psi, b_x, b_y, b_z): ZYX Euler angles in rad (roll, pitch, yaw;
 * sensor-to-earth, ENU) and the gyro bias in rad/s (sensor frame); covariance P (6x6, symmetric,
 * stored as its upper triangle) with yaw's row not carried: its correlations stay zero and its variance
 * is a random walk (q_psi). Yaw enters neither the roll/pitch kinematics nor the measurement, so that row
 * never reaches roll, pitch or the bias; the yaw share of a tilt correction comes from geometry
 * instead (yaw follows roll, below; docs/filters.md). Per step, with w = (p, q, r) - b (rad/s, sensor frame), dt:
 *
 *  1. prediction: angles := angles + dt E(phi, theta) w with the Euler kinematics
 *       phi'   = p + sin(phi) tan(theta) q + cos(phi) tan(theta) r
 *       theta' = cos(phi) q - sin(phi) r
 *       psi'   = sin(phi) / cos(theta) q + cos(phi) / cos(theta) r
 *     (as att_gyro.c), bias := bias (random walk), and P := F P F^T + Q (the rows of roll, pitch and the
 *     bias; yaw's variance + q_psi) with the discretised Jacobian
 *       F = [ I + dt J   -dt E ]      J = [ v tan   u sec sec   0 ]   u = sin(phi) q + cos(phi) r
 *           [ 0           I    ]          [ -u      0           0 ]   v = cos(phi) q - sin(phi) r
 *                                         [ v sec   u sec tan   0 ]   tan = tan(theta), sec = 1/cos(theta)
 *     evaluated at the state before the step, written out block by block for the sparsity of F.
 *     sin/cos of phi and theta are evaluated once per step, at its start; the midpoint's follow to
 *     first order from the half increments (s + c d, c - s d), the predicted angles' (for the update) by
 *     angle addition from the increments d of the step (series of sin d, cos d to d^5, d^4), both for
 *     |d| <= 1/16 rad (a larger d, or a flip to the equivalent attitude, evaluates them directly);
 *     psi's never (the update works in the heading frame; the stages' turn by psi - lp_psi takes the
 *     same series).
 *     |cos(theta)| below cos_min is clamped to +-cos_min (ATT_FLAG_GIMBAL) in the kinematics and the
 *     Jacobians: the singularity of the representation, where the estimate is unreliable but finite.
 *     An unusable gyro sample gives w = 0: the state is kept, P := P + Q.
 *  2. update (skipped when the accel sample is unusable or ||a|/g - 1| > accel_reject): the measured
 *     roll and pitch, H = [I2 0]. The measurement is taken from the specific force in the heading frame
 *     of the prediction (the earth frame turned about z by its yaw: R_y(theta) R_x(phi) a), low-passed by
 *     two cascaded first-order stages (tau_acc_lp): C = (c_w, c_x, c_y, 0), the trig-free alignment of
 *     the low-passed vector with z (att_ars.h), is the tilt error of the prediction as a heading-frame
 *     rotation e = 2 (c_x, c_y, 0); the roll and pitch that remove it are, to first order (e = M d for
 *     roll/pitch differences d, M d = (cos(theta) d_phi, d_theta, -sin(theta) d_phi)), y = (e_x /
 *     cos(theta), e_y): the innovation. S = P[0:2,0:2] + R, R = diag(r_phi / cos^2(theta), r_theta) (1 + r_accel
 *     (|a|/g - 1)^2): the tilt error has the same noise about both horizontal axes, so roll (e / cos(theta)) is
 *     not observable at +-90 deg pitch (cos guarded as in the prediction); det S = det P2 + ... > 0 by construction;
 *     with the chi-square gate d^2 = y^T S^-1 y > gate the update is rejected (ATT_FLAG_ACCEL_REJECTED)
 *     and above gate / 4 the measurement noise is scaled so that d^2 = gate / 4 (a soft limit);
 *     K = P H^T S^-1, x := x + K y, P := P - K S K^T written without cancellation: the roll/pitch
 *     rows are R S^-1 P (their 2x2 block [r0 (det P2 + r1 P00), r0 r1 P01; ., r1 (det P2 + r0 P11)] /
 *     det S, positive definite), the rest P - K H P. The correction is a pure tilt rotation (the
 *     measurement carries no heading): yaw follows roll, psi += sin(theta) d_phi, so that it turns the
 *     estimate by (cos(theta) d_phi, d_theta, 0) in the heading frame, about no vertical axis. The bias states measure against the raw sample
 *     (first order, e = (v_y, -v_x) / |v|; their gain averages over minutes, while the lag of the stages
 *     would hide a bias), weighted by min(1, (1/16) / d_raw^2). The stages restart after reset or an
 *     unusable gyro sample (an unmeasured rotation makes them stale): a sample within 0.1 rad of the
 *     estimate's gravity (sin^2 of its tilt error < 0.01) starts them from that gravity (0, 0, g), so a
 *     right estimate is kept; otherwise the raw sample is the measurement (the convergence phase, state
 *     converging) until one is within 0.1 rad, which then starts them from itself. The stages are kept in
 *     the heading frame of yaw lp_psi: each update first turns them about z into the predicted one
 *     (by psi - lp_psi: the yaw's change since, flips to the equivalent attitude included); an applied
 *     update rotates them by its correction (to first order) and sets lp_psi to the predicted yaw.
 *     From the start (or a re-initialisation) from a sample, the stages take the running mean of the
 *     samples since (att_i_recovery_lp_gain, the sample its first update; state lp_mean) until it is as
 *     good as their own window (1 / (n + 1) below k_lp / 4, ATT_I_REC_MEAN_END) or they restart: one sample gives the tilt, whatever linear acceleration it held. (The
 *     start is not a recovery here, unlike in ars, kf, mars and mekf: the recovery's process noise let
 *     the bias states take the start's innovations.)
 *  3. recovery after a clipping gyro (recovery_time > 0, as att_kf.h step 5): a gyro sample with any
 *     |w_i| >= 0.98 gyro_range (or beyond) starts a recovery of recovery_time (a later one restarts it),
 *     flagged ATT_FLAG_INITIALISED: the integration has lost rotation it cannot know. With k = dt /
 *     (recovery_time / 8 + dt) each prediction adds k^2 r / (1 - k) (at most p_max; r = r_phi, r_theta
 *     per sample) to the roll and pitch variances, the process noise whose steady-state Kalman gain is
 *     k; the first applied accel sample after a clipping sample restarts the low-pass stages, which
 *     then take the running mean of the samples since (att_i_recovery_lp_gain, as in att_ars.h), and
 *     the gate is off. So the filter follows that mean with the time constant recovery_time / 8 until
 *     the recovery ends (the bias
 *     states keep their gain: holding them, as att_mekf.h does, changed nothing measurable here).
 *  After each stage: theta is wrapped to (-pi, pi] and, beyond +-pi/2, mapped to the equivalent attitude
 *  (phi + pi, +-pi - theta, psi + pi) (P's theta row and column change sign); phi and psi are wrapped to
 *  (-pi, pi]. One test per step, on the state it leaves (the update tests its result; a step without
 *  an applied update tests the prediction, which is taken unless its angles leave the range of the
 *  wrap, |angle| > 8192 rad, from adversarial rates, dt and cos_min: then the angles are kept): angles
 *  or P not finite, or a variance not > 0, give ATT_FLAG_NUMERIC and P (predicted
 *  and updated in place, so that no copy of it is on the stack) restarts at its start values p0,
 *  p0_bias; a step flagged NUMERIC keeps the angles and bias from before it, except after a prediction
 *  not taken, which restarts the bias too (bias_init: a bias estimate run beyond any gyro's range would
 *  keep every later prediction out of the wrap's range; zero when the prediction ran with bias_init, so
 *  that a start value that is no gyro's bias cannot do so either). After a step flagged NUMERIC the
 *  filter is not ready (ATT_FLAG_NOT_READY, initialised false) until the next usable accel sample
 *  re-initialises roll and pitch from it, the yaw kept, P restarted and the stages started from it
 *  (ATT_FLAG_INITIALISED, no prediction that step): the failed step left the state as it was, which
 *  with a constant sample would fail again at every step; with every conditioning of P (below) the bias
 *  is limited to +-gyro_range per axis (ATT_FLAG_CLAMPED when that acts). Every 16 steps, at every
 *  step of a recovery (step 3; F17: its process noise moves P fast), at every step flagged GIMBAL, at
 *  every step without an applied accel update (nothing else bounds P then), after an update whose prior
 *  roll or pitch variance exceeds 2^12 times its measurement noise (F18: the rounding of the bias rows
 *  of a collapse that large can leave P indefinite), after a roll or pitch increment beyond 1/16 rad, and at a step whose roll/pitch block of P is
 *  within the margin below of singular (det P2 <= 2^-12 P00 P11: float32 cannot carry a correlation
 *  that close to +-1), P is conditioned: variances
 *  above p_max (the bias variances above min(p_max, max(gyro_range^2, p0_bias)): a bias beyond the
 *  range is no estimate) are brought down by the congruence D P D (correlations kept); if P then fails a positive
 *  definiteness test with margin (L D L^T pivots d_0 > 0, d_j > 2^-12 (P_jj + sum_{i<j} m_ji^2 P_ii),
 *  m = L^-1: the margin covers the test's own rounding) its correlations are multiplied by
 *  1 - 2^-10, or set to zero when that is not enough (ATT_FLAG_CLAMPED). Yaw is not observed: its variance grows (up to p_max).
 *
 * Noises: with noise_rates (default) the q_* are rates (added as q dt per step) and r_* densities
 * (R = r / dt per sample), so the time constants do not depend on dt (the per-step values, in
 * [1e-26, 1e6] and [1e-20, 1e12] over the ranges below, are not range-checked themselves); without,
 * per step / per sample as in the notes (the seed preset). The quaternion of the output is derived from the angles on request
 * (att_filter_output); att_filter_step fills the Euler angles and the bias.
 *
 * Units: rad, rad/s, m/s^2, s, variances rad^2 and (rad/s)^2. Frames: gyro/accel in the sensor frame.
 * Mirrored bit for bit by host/attica/reference/ekf.py.
 */
#ifndef ATT_EKF_H
#define ATT_EKF_H

#include "attica/att_config.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/**
 * Settings of the Euler EKF. Fill with att_ekf_settings_default, then change fields. Each field's valid
 * range is given in brackets; init refuses anything else (NaN and Inf included;
 * att_filter_settings_check names the field).
 */
typedef struct {
    float dt;              /**< sample period, s; [1e-6, 1] */
    float q_phi;           /**< process noise of roll (rate or per step, see noise_rates), rad^2; [1e-20, 1e6] */
    float q_theta;         /**< process noise of pitch, rad^2; [1e-20, 1e6] */
    float q_psi;           /**< process noise of yaw, rad^2; [1e-20, 1e6] */
    float q_bias;          /**< process noise of each bias component, (rad/s)^2; [1e-20, 1e6] */
    float r_phi;           /**< measurement noise of roll (density or per sample), rad^2; [1e-20, 1e6] */
    float r_theta;         /**< measurement noise of pitch, rad^2; [1e-20, 1e6] */
    float r_accel;         /**< growth of the measurement noise with (|a|/g - 1)^2; [0, 1e6] */
    float gate;            /**< chi-square gate on the normalised innovation (2 dof); [0, 1e6]; 0 = off */
    float p0;              /**< initial variance of each angle, rad^2; [1e-6, p_max] */
    float p0_bias;         /**< initial variance of each bias component, (rad/s)^2; [1e-20, p_max] */
    float p_max;           /**< cap on each variance (numeric guard), rad^2; [1e-6, 1e6] */
    float gravity;         /**< g, m/s^2; [1, 100] */
    float accel_reject;    /**< skip the update when ||a|/g - 1| > this, [0, 1e3]; 0 = never skip */
    float accel_range;     /**< |a| above this is saturation: update skipped, m/s^2; (gravity, 1e4] */
    float gyro_range;      /**< the gyro's full scale, rad/s, (0, 1e3]: a |w_i| beyond it, up to
                               twice it, is a reading at the rail, used as read
                               (ATT_FLAG_GYRO_RANGE); beyond, the sample is not used */
    float cos_min;         /**< guard on |cos(theta)|; (0, 1) */
    float tau_acc_lp;      /**< low-pass time constant of the heading-frame accel, s, [0, 1e4]; 0 = off */
    bool init_from_accel;  /**< take roll/pitch from the first usable accel sample (yaw 0) */
    att_vec3_t euler_init; /**< start angles without init_from_accel, rad; x (phi), z (psi) in [-8192, 8192], y (theta) in [-pi/2, pi/2] */
    att_vec3_t bias_init;  /**< initial gyro bias, rad/s, sensor frame; each component in [-gyro_range, gyro_range] */
    bool noise_rates;      /**< true: q_* rates (Q = q dt), r_* densities (R = r / dt); false: per step */
    float recovery_time;   /**< after a gyro sample at 98 % of gyro_range or beyond (a clipping gyro),
                                this long the recovery of step 3, s; [0, 1e4]; 0 = none; at most 2^24 samples */
} att_ekf_settings_t;

/** Coefficients derived from the settings by att_ekf_init: what a step needs, and the reset values. */
typedef struct {
    float dt;               /**< sample period, s */
    float q_step[4];        /**< process noise added per step: phi, theta, psi, each bias component */
    float r_step[2];        /**< measurement noise of one sample (roll, pitch), before the adaptive factor */
    float r_accel;          /**< growth of R with (|a|/g - 1)^2 */
    float gate;             /**< chi-square gate (0 = off) */
    float soft;             /**< gate / 4 */
    float p0;               /**< angle variance after reset, rad^2 */
    float p0_bias;          /**< bias variance after reset, (rad/s)^2 */
    float p_max;            /**< cap on each variance */
    float gravity;          /**< g, m/s^2 */
    float accel_reject;     /**< ||a|/g - 1| limit (0 = never) */
    float accel_range2;     /**< saturation limit of |a|^2, (m/s^2)^2 */
    float gyro_range;       /**< saturation limit of |w_i|, rad/s */
    float cos_min;          /**< guard on |cos(theta)| */
    float k_lp;             /**< per-sample gain of each accel low-pass stage (0 = off) */
    att_vec3_t euler_init;  /**< angles after reset without init_from_accel, rad (wrapped) */
    att_vec3_t bias_init;   /**< bias after reset, rad/s */
    bool init_from_accel;   /**< wait for the first usable accel sample */
    bool lp_on;             /**< k_lp > 0 */
    bool need_norm;         /**< |a| is needed (r_accel or accel_reject set) */
    float clip;             /**< |w_i| at or above this is clipping: 0.98 gyro_range, rad/s (Inf: no recovery) */
    float q_rec[2];         /**< roll, pitch process noise per step of a recovery, min(k^2 r_step / (1 - k), p_max) */
    uint32_t rec_n;         /**< samples of a recovery (0 = none) */
} att_ekf_coeffs_t;

/** Dynamic state of an Euler EKF instance. */
typedef struct {
    att_vec3_t euler;     /**< (phi, theta, psi), rad, ZYX sensor-to-earth (ENU) */
    att_vec3_t bias;      /**< gyro bias estimate, rad/s, sensor frame */
    float p[21];          /**< covariance of (phi, theta, psi, b_x, b_y, b_z): upper triangle row by row
                               (yaw's correlations, p[2], p[7], p[12..14], not carried: zero) */
    att_vec3_t lp1;       /**< first accel low-pass stage, m/s^2, heading frame (earth turned by psi) */
    att_vec3_t lp2;       /**< second accel low-pass stage (the measurement), m/s^2, heading frame */
    float lp_psi;         /**< yaw of the stages' heading frame, rad (they are turned to the estimate's at
                               each update) */
    bool lp_ready;        /**< the stages hold a sample (else the next usable one starts them) */
    bool converging;      /**< the convergence phase: the raw sample was the measurement of the last update */
    bool lp_mean;         /**< the stages take the running mean of the samples since the start
                               (att_i_recovery_lp_gain), until it falls below k_lp / 4, they restart or the
                               count reaches 2^24 */
    bool recover;         /**< a step flagged NUMERIC set initialised false: the next usable accel sample
                               re-initialises roll and pitch, the yaw kept, P restarted */
    uint32_t steps;       /**< steps taken since init/reset (wraps) */
    uint32_t flags;       /**< flags of the last step */
    uint32_t rec_left;    /**< steps left of the recovery after a clipping gyro (0 = none) */
    uint32_t rec_lp_n;    /**< accel low-pass updates computed since the last clipping gyro sample or the
                               start or re-initialisation, counted in a recovery and while lp_mean
                               (att_i_recovery_lp_gain) */
    bool initialised;     /**< euler holds a valid attitude */
    bool head_known;      /**< a heading was set (att_filter_set_heading) and no clipping gyro sample nor a
                               NUMERIC restart has turned it since: the output's yaw variance is p[11], else
                               pi^2/3 */
} att_ekf_state_t;

/** One Euler EKF instance (no heap; copy freely). */
typedef struct {
    att_ekf_coeffs_t c; /**< derived from the settings at init / retune */
    att_ekf_state_t st; /**< changes every step */
} att_ekf_t;

/** Default settings for sample period dt (s), tuned on BROAD (docs/accuracy.md), rate-independent. */
void att_ekf_settings_default(att_ekf_settings_t *settings, float dt);
/** ATT_OK when every field is within its range, else ATT_ERR_SETTINGS (ATT_ERR_NULL for NULL). */
att_status_t att_ekf_settings_validate(const att_ekf_settings_t *settings);
/** Validate settings and initialise f. On error f is left unchanged. */
att_status_t att_ekf_init(att_ekf_t *f, const att_ekf_settings_t *settings);
/**
 * New settings (noises, limits), the angles, bias and covariance kept (a recovery under way no longer
 * than the new recovery_time); on error f is unchanged.
 */
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
