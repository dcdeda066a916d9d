/**
 * @file att_ars.h
 * @brief Quaternion complementary attitude reference system (ARS), after the KITECH design.
 *
 * Per step:
 *  1. gyro bias w_m as a running mean w_m := (n w_m + w) / (n + 1) with n capped at bias_n_max
 *     (mode ATT_BIAS_RUNNING), or only while the sensor is at rest (ATT_BIAS_AT_REST, default),
 *     or frozen at bias_init (ATT_BIAS_FROZEN), or zero (ATT_BIAS_OFF);
 *  2. integration q := q * dq with the rotation (w - w_m) dt, either as the exponential map of the
 *     rotation vector (ATT_INTEGRATE_ROTVEC, default, exact for constant rate) or as the ZYX Euler
 *     quaternion Q(dphi, dtheta, dpsi) of the increments (ATT_INTEGRATE_EULER, the KITECH literal);
 *  3. accel correction: rotate the specific force a (sensor frame) into the earth frame, a_e = q a q*,
 *     take the axis n = a_e x z / |a_e x z| and the angle phi_e between a_e and z = (0, 0, 1) (up),
 *     the gain K_a = k / (1 + c (|a|/g - 1)^2), and q := Q(K_a phi_e, n) * q. The axis is horizontal,
 *     so yaw is never changed by the accelerometer.
 *     With tau_acc_lp > 0 (default) the correction uses, instead of a_e, the output of two cascaded
 *     first-order low-passes (gain k_lp = dt / (tau_acc_lp + dt) each) fed with a_e; both stages are
 *     rotated by each correction, so they stay in the corrected earth frame. Linear accelerations that
 *     average out over a few seconds (translation back and forth, vibration, taps) are thus filtered
 *     before they can tilt the estimate (the idea of VQF's inclination correction). Samples rejected by
 *     accel_reject do not enter the low-pass.
 *     With K_a = 1 (k = 1 and c = 0, the default) the correction is the full alignment of the vector
 *     with z, computed without trigonometry: with u = v / |v| (v = lp2, or a_e without the low-pass),
 *     w = sqrt((1 + u_z) / 2) and Q = (w, u_y / (2 w), -u_x / (2 w), 0), the half-angle form of
 *     Q(phi_e, n); for w <= 2^-10 (upside down) Q = (0, 1, 0, 0), a half turn about x. After it lp2 is
 *     (0, 0, |lp2|) exactly (that is what the rotation makes of it) and lp1 is rotated by Q. Otherwise
 *     (K_a < 1) the angle is phi_e = atan2(|a_xy|, a_z) and Q = Q(K_a phi_e, n) as above.
 *     Recovery after a clipping gyro (recovery_time > 0): a gyro sample with any |w_i| >= 0.98 gyro_range
 *     (a sensor at its full scale reads a clipped value, not an overrange) or beyond gyro_range starts a
 *     recovery of recovery_time (counted only once initialised): the integration has lost rotation it
 *     cannot know. The first applied accel sample after a clipping sample (the clipping sample itself
 *     when its accel is usable) restarts the low-pass stages (the history they hold was turned into the
 *     earth frame by a rotation the gyro did not measure), which then take the running mean of the
 *     samples since, gain 1 / (n + 1) after n earlier updates, until the mean is as good as their own
 *     window, 1 / (n + 1) below k_lp / 4 (att_i_recovery_lp_gain, ATT_I_REC_MEAN_END: with the gyro
 *     right again every such sample is an equally good measurement of gravity, and their mean is what an
 *     unknown attitude calls for; the second stage is held at the first meanwhile, its gain 1, so that
 *     the correction follows the plain mean, not the mean of the first stage's means, which would weight
 *     the first samples after the clip most; then the cascade runs again at k_lp from that mean; every
 *     kind's recovery does the same); the correction runs
 *     with the time constant recovery_time / 8 when that is faster than its own (k_rec instead of k).
 *     Every step of it reports ATT_FLAG_INITIALISED (the attitude is being re-initialised from the
 *     sensors). The start from the first usable accel sample (init_from_accel) is a recovery too, for
 *     the same reason (one sample with whatever linear acceleration it holds gives the tilt): the stages
 *     start from that sample, the running mean's first update, and the recovery's correction follows.
 *  4. q is normalised. ATT_FLAG_NUMERIC when that fails or the low-passed vector cannot be normalised
 *     (the attitude and low-pass states are then kept from before the step): no state can become
 *     NaN or Inf, since samples are bounded by the (finite) ranges.
 *  5. Covariance (att_filter_output's cov, on request; docs/filters.md): a documented model of the
 *     fixed-gain correction with white gyro noise (gyro_noise) and a white disturbance of the specific
 *     force (accel_noise: the sensor's noise and the motion's linear acceleration). cov[0], cov[1]: the
 *     tilt error variance about the earth's x and y axes, the steady state of the correction's gains
 *     plus gyro_noise^2 dt per step since the last accepted correction (rejected or missing samples
 *     raise it); during a recovery the gains of the recovery plus pi^2/48 (a +-45 deg error) fading
 *     over it; at most pi^2/12. cov[2]: the heading variance about the earth's z, pi^2/3 (unknown: the
 *     yaw starts at 0) until att_filter_set_heading (or a heading update of gain 1), then gyro_noise^2
 *     dt per step since, at most pi^2/3 (a heading update of gain < 1 leaves it), and pi^2/3 again from
 *     a clipping gyro sample (one that starts a recovery: recovery_time > 0). Before the first
 *     usable sample pi^2/12 and pi^2/3. cov[3] = 0. Units rad^2.
 *
 * Units: rad/s, m/s^2, s. Frames: gyro/accel in the sensor frame; q sensor-to-earth (ENU, z up).
 */
#ifndef ATT_ARS_H
#define ATT_ARS_H

#include "attica/att_config.h"
#include "attica/att_bias.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/** How the gyro rate is turned into an attitude increment. */
typedef enum {
    ATT_INTEGRATE_ROTVEC = 0, /**< exponential map of (w - w_m) dt */
    ATT_INTEGRATE_EULER = 1,  /**< Q(dphi, dtheta, dpsi), ZYX Euler increments (KITECH literal) */
    ATT_INTEGRATE_FIRST_ORDER = 2 /**< q + q (0, w) dt / 2, normalised (MARS only: the article) */
} att_integration_t;

/**
 * Settings of the complementary ARS. Fill with att_ars_settings_default, then change fields.
 * Each field's valid range is given in brackets; att_ars_init (and att_ars_settings_validate) refuse
 * anything else with ATT_ERR_SETTINGS (att_filter_settings_check names the field). NaN and Inf are
 * outside every range.
 */
typedef struct {
    float dt;                      /**< sample period, s; [1e-6, 1] */
    float gain;                    /**< k: per-sample accel gain at |a| = g, [0, 1]; unused when tau > 0 */
    float tau;                     /**< accel correction time constant, s, [0, 1e4]; > 0 sets k = dt/(tau+dt)
                                        (gain is then ignored); 0 = k is gain */
    float gain_c;                  /**< c in K_a = k / (1 + c (|a|/g - 1)^2); [0, 1e6] */
    float gravity;                 /**< g, m/s^2; [1, 100] */
    float accel_reject;            /**< skip correction when ||a|/g - 1| > this; [0, 1e3]; 0 = never skip */
    float accel_range;             /**< |a| above this is saturation: correction skipped, m/s^2; (gravity, 1e4] */
    float gyro_range;              /**< the gyro's full scale, rad/s, (0, 1e3]: a |w_i| beyond it, up to
                                       twice it, is a reading at the rail, used as read
                                       (ATT_FLAG_GYRO_RANGE); beyond, the sample is not used */
    att_bias_mode_t bias_mode;     /**< gyro bias estimation: OFF (0), FROZEN (1), RUNNING (2) or AT_REST (3) */
    uint32_t bias_n_max;           /**< cap on n in the running mean; [1, 2^24] */
    att_vec3_t bias_init;          /**< initial gyro bias w_m, rad/s, sensor frame; each component in [-gyro_range, gyro_range] */
    float rest_gyro;               /**< at rest when |w - w_m| < rest_gyro (+ att_bias.h's widening), rad/s, [0, gyro_range] ... */
    float rest_accel;              /**< ... and ||a| - g| < rest_accel, m/s^2, [0, gravity] ... */
    float rest_time;               /**< ... for at least rest_time, s, [0, 1e4] */
    att_integration_t integration; /**< ROTVEC (0) or EULER (1) */
    bool init_from_accel;          /**< take roll/pitch from the first valid accel sample (yaw 0) */
    att_quat_t q_init;             /**< initial attitude when init_from_accel is false, sensor-to-earth;
                                        finite, |q|^2 in [2^-20, 2^20] (normalised by init) */
    float tau_acc_lp;              /**< low-pass time constant of the earth-frame accel, s, [0, 1e4]; 0 = off */
    float recovery_time;           /**< after a gyro sample at 98 % of gyro_range or beyond (a clipping gyro),
                                        the accel is trusted strongly for this long, s, [0, 1e4]; 0 = off;
                                        at most 2^24 samples */
    float gyro_noise;              /**< covariance model: gyro white noise density, rad/s/sqrt(Hz), [0, 1] */
    float accel_noise;             /**< covariance model: density of the specific force's disturbance (noise
                                        and linear acceleration), m/s^2/sqrt(Hz), [0, 1e3] */
} att_ars_settings_t;

/** Coefficients derived from the settings by att_ars_init: what a step needs, and the reset values. */
typedef struct {
    float dt;                 /**< sample period, s */
    float k;                  /**< per-sample accel correction gain at |a| = g, [0, 1] */
    float k_lp;               /**< per-sample gain of each accel low-pass stage, [0, 1) (0 = off) */
    float gain_c;             /**< c of the adaptive gain */
    float gravity;            /**< g, m/s^2 */
    float accel_reject;       /**< ||a|/g - 1| limit (0 = never) */
    float accel_range2;       /**< saturation limit of |a|^2, (m/s^2)^2 */
    float gyro_range;         /**< saturation limit of |w_i|, rad/s */
    att_bias_params_t bias;   /**< rest detector and running-mean parameters */
    att_quat_t q_init;        /**< attitude after reset (unit, sensor-to-earth) without init_from_accel */
    att_vec3_t bias_init;     /**< bias after reset, rad/s, sensor frame */
    uint8_t integration;      /**< att_integration_t */
    bool init_from_accel;     /**< wait for the first usable accel sample */
    bool lp_on;               /**< k_lp > 0: the accel low-pass is used */
    bool reject_on;           /**< accel_reject > 0: the rejection test is made */
    bool full;                /**< k == 1 and c == 0: full alignment with the low-passed gravity, no
                                   trigonometry (and no |a| unless accel_reject is set) */
    float clip;               /**< |w_i| at or above this is clipping: 0.98 gyro_range, rad/s (Inf: no recovery) */
    float k_rec;              /**< per-sample accel correction gain during a recovery */
    uint32_t rec_n;           /**< samples of a recovery (0 = none) */
    float var_step;           /**< covariance: gyro_noise^2 dt, the variance a step adds, rad^2 */
    float var_tilt;           /**< covariance: steady-state tilt variance of the correction, rad^2 */
    float var_tilt_rec;       /**< covariance: the same with the recovery's gains, rad^2 */
} att_ars_coeffs_t;

/** Dynamic state of an ARS instance. */
typedef struct {
    att_quat_t q;          /**< attitude, unit, sensor-to-earth (ENU) */
    att_vec3_t bias;       /**< gyro bias estimate w_m, rad/s, sensor frame */
    att_vec3_t lp1;        /**< first accel low-pass stage, m/s^2, earth frame */
    att_vec3_t lp2;        /**< second accel low-pass stage (used by the correction), m/s^2, earth */
    uint32_t bias_n;       /**< n of the running mean, <= bias_n_max */
    uint32_t rest_count;   /**< consecutive samples at rest (saturates at rest_n) */
    float rest_gate2;      /**< the rest detector's gyro gate, (rad/s)^2: bias.rest_first2 until the first
                                bias update, then bias.rest_gyro2 (att_bias.h) */
    uint32_t steps;        /**< steps taken since init/reset (wraps) */
    uint32_t flags;        /**< flags of the last step */
    uint32_t rec_left;     /**< steps left of the recovery after a clipping gyro or the start (0 = none) */
    uint32_t rec_lp_n;     /**< accel low-pass updates since the last clipping gyro sample or the start (att_i_recovery_lp_gain) */
    uint32_t acc_step;     /**< steps before the step of the last accepted accel correction (or the start): covariance */
    uint32_t head_step;    /**< steps at the last att_filter_set_heading: covariance */
    bool initialised;      /**< q holds a valid attitude */
    bool head_known;       /**< a heading was set (att_filter_set_heading): covariance */
} att_ars_state_t;

/** One complementary ARS instance (no heap; copy freely): coefficients and state, no settings copy. */
typedef struct {
    att_ars_coeffs_t c;  /**< derived from the settings at init / retune */
    att_ars_state_t st;  /**< changes every step */
} att_ars_t;

/**
 * Default settings for sample period dt (s), tuned on BROAD (docs/accuracy.md) and rate-independent:
 * accel low-pass tau_acc_lp 1.5 s, full correction (gain 1, tau 0: the attitude follows the low-passed
 * gravity, so tau_acc_lp is the filter's time constant), c = 0, bias at rest, rotvec integration, a
 * recovery of 2 s after a clipping gyro (recovery_time). The first implementation's literal settings
 * (k = 0.1 per sample, c = 100, no low-pass, no recovery: recovery_time 0) are
 * att_filter_settings_preset(ATT_FILTER_ARS, ATT_PRESET_SEED, ...).
 */
void att_ars_settings_default(att_ars_settings_t *settings, float dt);
/** ATT_OK when every field is within its range (above), else ATT_ERR_SETTINGS (ATT_ERR_NULL for NULL). */
att_status_t att_ars_settings_validate(const att_ars_settings_t *settings);
/** Validate settings and initialise f. On error f is left unchanged. */
att_status_t att_ars_init(att_ars_t *f, const att_ars_settings_t *settings);
/**
 * New settings for a running instance: the coefficients are replaced and the state is kept (attitude,
 * bias, low-pass states, counters), except that the bias becomes 0 (mode OFF) or bias_init (mode
 * FROZEN), the counters are limited to the new rest_n / bias_n_max and the rest gate follows the new
 * settings and the kept n (wide while n = 0, att_bias.h); a recovery under way is limited
 * to the new recovery_time (0: ended). On error f is left unchanged.
 */
att_status_t att_ars_retune(att_ars_t *f, const att_ars_settings_t *settings);
/** Back to the state right after att_ars_init, keeping the settings. */
void att_ars_reset(att_ars_t *f);
/** One update with gyro (rad/s) and accel (m/s^2), sensor frame; returns ATT_FLAG_* bits. */
uint32_t att_ars_step(att_ars_t *f, att_vec3_t gyr, att_vec3_t acc);
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_ARS_H */
