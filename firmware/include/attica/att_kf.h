/**
 * @file att_kf.h
 * @brief Linear quaternion Kalman filter (6-axis), after the Hanyang University lecture notes, made
 * robust: gyro bias from the rest detector, the measurement from the low-passed gravity direction,
 * measurement noise that grows with the accel magnitude error and with the innovation, and a
 * chi-square gate.
 *
 * State x = q = (w, x, y, z), sensor-to-earth (ENU), with covariance P (4x4). Model: x' = A x with
 * A = I + dt/2 Omega(w - b) (q_dot = q (x) (0, w - b) / 2; Omega skew-symmetric, so A A^T =
 * (1 + (dt/2)^2 |w - b|^2) I), process noise Q = q_step I, measurement z = x + v with H = I and
 * R = r I. With P0 = p0 I the covariance stays isotropic for ever: if P = p I, then A P A^T + Q =
 * (p (1 + (dt/2)^2 |w - b|^2) + q_step) I, and the update K = P (P + R)^-1 = p / (p + r) I,
 * P := (I - K) P = p r / (p + r) I; the normalisation x := x / |x| scales P by 1 / |x|^2. The filter
 * therefore carries P as the scalar p (P = p I exactly; docs/filters.md), which is the same Kalman
 * filter without the rounding noise a 4x4 matrix would add to its zeros. Per step:
 *  1. gyro bias b (bias_mode, as att_ars.h) from the rest detector, subtracted from the rate;
 *  2. prediction x := x + x (x) (0, (w - b) dt / 2), p := p (1 + |(w - b) dt / 2|^2) + q_step;
 *     an unusable gyro sample leaves x and adds q_step;
 *  3. measurement: the specific force in the earth frame of the prediction, low-passed by two cascaded
 *     first-order stages (tau_acc_lp, as att_ars.h), gives the measured attitude z = C (x) x, C the
 *     trig-free full alignment of the low-passed vector with z (att_ars.h): the prediction with its
 *     tilt corrected, its yaw kept (the accelerometer cannot observe yaw);
 *     noise r = r_step (1 + r_accel (|a|/g - 1)^2) (a sample far from |a| = g is trusted less);
 *     innovation y = z - x with |y|^2 = 2 (1 - C_w) |x|^2 and d^2 = |y|^2 / (p + r) (chi-square with the
 *     filter's own variance): d^2 > gate rejects the update (ATT_FLAG_ACCEL_REJECTED, nothing applied,
 *     the low-pass stages kept); above gate / 4 the noise grows to r = |y|^2 / (gate / 4) - p, so that
 *     d^2 never exceeds gate / 4 in an applied update (a Huber-like soft limit: large innovations
 *     pull less);
 *     update k = p / (p + r): x := x + k y = ((1 - k) I + k C) (x) x, p := r k, and the low-pass stages
 *     are rotated by the same rotation (1 - k) I + k C (normalised), so they stay in the estimate's
 *     earth frame;
 *  4. normalisation x := x / |x|, p := p / |x|^2; p is limited to ATT_KF_P_MAX (ATT_FLAG_CLAMPED), which
 *     only long runs without usable accel samples reach (p then grows by q_step a step).
 *  5. recovery after a clipping gyro (recovery_time > 0): a gyro sample with any |w_i| >= 0.98 gyro_range
 *     (or beyond) starts a recovery of recovery_time (a later one restarts it), flagged
 *     ATT_FLAG_INITIALISED; with k = dt / (recovery_time / 8 + dt) each prediction adds
 *     k^2 r_step / (1 - k) to p (the process noise whose steady-state gain is k; at most ATT_KF_P_MAX),
 *     the first applied accel sample after a clipping sample restarts the low-pass stages, which then
 *     take the running mean of the samples since (att_i_recovery_lp_gain, as in att_ars.h), and the gate
 *     and its soft limit are off: the filter follows that mean with the time constant recovery_time / 8
 *     (att_ars.h, att_mekf.h).
 * With ATT_FLAG_NUMERIC (x cannot be normalised) the state is kept from before the step.
 * Before a valid attitude exists (init_from_accel) the filter waits for the first usable accel
 * sample (ATT_FLAG_NOT_READY), takes roll/pitch from it with yaw 0 (ATT_FLAG_INITIALISED) and starts
 * the recovery of step 5 from it: the stages start from that sample, the running mean's first update.
 *
 * Units: rad/s, m/s^2, s; variances in (unit quaternion)^2. Frames: gyro/accel in the sensor frame;
 * q sensor-to-earth (ENU, z up). Mirrored bit for bit by host/attica/reference/kf.py.
 */
#ifndef ATT_KF_H
#define ATT_KF_H

#include "attica/att_config.h"
#include "attica/att_bias.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/** Largest variance p (the cap of step 4), (unit quaternion)^2. */
#define ATT_KF_P_MAX 1000000

/**
 * Settings of the linear quaternion KF. Fill with att_kf_settings_default, then change fields. Each
 * field's valid range is given in brackets; init refuses anything else (NaN and Inf included;
 * att_filter_settings_check names the field).
 */
typedef struct {
    float dt;                  /**< sample period, s; [1e-6, 1] */
    float q_noise;             /**< process noise: rate (noise_rates) or per step, (unit quaternion)^2; [1e-12, 1e6] */
    float r_noise;             /**< measurement noise: density (noise_rates) or per sample; [1e-12, 1e6] */
    float r_accel;             /**< growth of r with (|a|/g - 1)^2; [0, 1e6] */
    float gate;                /**< chi-square gate on the normalised innovation d^2; [0, 1e6]; 0 = off */
    float p0;                  /**< initial variance (P0 = p0 I), (unit quaternion)^2; [1e-12, 1e6] */
    float gravity;             /**< g, m/s^2; [1, 100] */
    float accel_reject;        /**< skip the update when ||a|/g - 1| > this, [0, 1e3]; 0 = never skip */
    float accel_range;         /**< |a| above this is saturation: update skipped, m/s^2; (gravity, 1e4] */
    float gyro_range;          /**< the gyro's full scale, rad/s, (0, 1e3]: a |w_i| beyond it, up to
                                   twice it, is a reading at the rail, used as read
                                   (ATT_FLAG_GYRO_RANGE); beyond, the sample is not used */
    att_bias_mode_t bias_mode; /**< gyro bias as att_ars.h: OFF (0), FROZEN (1), RUNNING (2) or AT_REST (3) */
    uint32_t bias_n_max;       /**< cap on n in the running mean of the bias; [1, 2^24] */
    att_vec3_t bias_init;      /**< initial gyro bias, rad/s, sensor frame; each component in [-gyro_range, gyro_range] */
    float rest_gyro;           /**< at rest when |w - b| < rest_gyro (+ att_bias.h's widening), rad/s, [0, gyro_range] ... */
    float rest_accel;          /**< ... and ||a| - g| < rest_accel, m/s^2, [0, gravity] ... */
    float rest_time;           /**< ... for at least rest_time, s, [0, 1e4] */
    float tau_acc_lp;          /**< low-pass time constant of the earth-frame accel, s, [0, 1e4]; 0 = off */
    float recovery_time;       /**< after a gyro sample at 98 % of gyro_range or beyond (a clipping gyro),
                                    this long the recovery of step 5, s; [0, 1e4]; 0 = none; at most 2^24 samples */
    bool init_from_accel;      /**< take roll/pitch from the first usable accel sample (yaw 0) */
    att_quat_t q_init;         /**< initial attitude when init_from_accel is false; finite, |q|^2 in [2^-20, 2^20] */
    bool noise_rates;          /**< true: Q = q_noise dt, R = r_noise / dt (rate-independent; these per-step values
                                    are not range-checked themselves: docs/filters.md); false: per step */
} att_kf_settings_t;

/** Coefficients derived from the settings by att_kf_init: what a step needs, and the reset values. */
typedef struct {
    float dt;               /**< sample period, s */
    float half_dt;          /**< dt / 2, s */
    float q_step;           /**< process noise added per step */
    float r_step;           /**< measurement noise of one sample (before the adaptive factors) */
    float r_accel;          /**< growth of r with (|a|/g - 1)^2 */
    float gate;             /**< chi-square gate (0 = off) */
    float soft;             /**< gate / 4: above it r grows with d^2 */
    float p0;               /**< variance after reset */
    float gravity;          /**< g, m/s^2 */
    float accel_reject;     /**< ||a|/g - 1| limit (0 = never) */
    float accel_range2;     /**< saturation limit of |a|^2, (m/s^2)^2 */
    float gyro_range;       /**< saturation limit of |w_i|, rad/s */
    float k_lp;             /**< per-sample gain of each accel low-pass stage (0 = off) */
    att_bias_params_t bias; /**< rest detector and running-mean parameters */
    att_quat_t q_init;      /**< attitude after reset without init_from_accel */
    att_vec3_t bias_init;   /**< bias after reset, rad/s */
    bool init_from_accel;   /**< wait for the first usable accel sample */
    float clip;             /**< |w_i| at or above this is clipping: 0.98 gyro_range, rad/s (Inf: no recovery) */
    float q_rec;            /**< process noise added per step of a recovery, min(k^2 r_step / (1 - k), P_MAX) */
    uint32_t rec_n;         /**< samples of a recovery (0 = none) */
    bool lp_on;             /**< k_lp > 0 */
    bool need_norm;         /**< |a| is needed (r_accel or accel_reject set) */
} att_kf_coeffs_t;

/** Dynamic state of a KF instance. */
typedef struct {
    att_quat_t q;         /**< state x: attitude, unit, sensor-to-earth (ENU) */
    float p;              /**< covariance P = p I of x, (unit quaternion)^2 */
    att_vec3_t bias;      /**< gyro bias estimate, rad/s, sensor frame */
    att_vec3_t lp1;       /**< first accel low-pass stage, m/s^2, earth frame */
    att_vec3_t lp2;       /**< second accel low-pass stage (the measurement), m/s^2, earth frame */
    uint32_t bias_n;      /**< n of the running mean of the bias */
    uint32_t rest_count;  /**< consecutive samples at rest */
    float rest_gate2;     /**< the rest detector's gyro gate, (rad/s)^2: bias.rest_first2 until the first
                               bias update, then bias.rest_gyro2 (att_bias.h) */
    uint32_t steps;       /**< steps taken since init/reset (wraps) */
    uint32_t flags;       /**< flags of the last step */
    uint32_t rec_left;    /**< steps left of the recovery after a clipping gyro or the start (0 = none) */
    uint32_t rec_lp_n;    /**< accel low-pass updates since the last clipping gyro sample or the start (att_i_recovery_lp_gain) */
    bool initialised;     /**< q holds a valid attitude */
} att_kf_state_t;

/** One linear quaternion KF instance (no heap; copy freely). */
typedef struct {
    att_kf_coeffs_t c; /**< derived from the settings at init / retune */
    att_kf_state_t st; /**< changes every step */
} att_kf_t;

/**
 * Default settings for sample period dt (s), tuned on BROAD (docs/accuracy.md), rate-independent
 * (noise_rates): see att_kf.c for the values. The notes' literal Q = 1e-4 I and R = 10 I per step are
 * the seed preset (att_filter_settings_preset).
 */
void att_kf_settings_default(att_kf_settings_t *settings, float dt);
/** ATT_OK when every field is within its range, else ATT_ERR_SETTINGS (ATT_ERR_NULL for NULL). */
att_status_t att_kf_settings_validate(const att_kf_settings_t *settings);
/** Validate settings and initialise f. ATT_ERR_NULL / ATT_ERR_SETTINGS leave f unchanged. */
att_status_t att_kf_init(att_kf_t *f, const att_kf_settings_t *settings);
/**
 * New settings, the state kept (attitude, variance, bias, low-pass stages; the bias to bias_init for
 * OFF / FROZEN, counters limited, the rest gate from the new settings and the kept n as in att_bias.h);
 * on error f is unchanged.
 */
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
