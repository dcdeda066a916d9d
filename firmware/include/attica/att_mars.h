/**
 * @file att_mars.h
 * @brief 9-axis quaternion complementary filter with magnetometer ("MARS"), after a Qiita article.
 *
 * Per step (after the attitude has been initialised):
 *  0. gyro bias b (bias_mode, as att_ars.h): running mean of the samples taken at rest (AT_REST,
 *     default: |w - b| < rest_gyro, wider until the first rest (att_bias.h), and ||a| - g| < rest_accel
 *     for rest_time), of every sample (RUNNING),
 *     fixed at bias_init (FROZEN, the article) or zero (OFF);
 *  1. gyro integration of w - b: exponential map q := q * Q((w - b) dt) (ATT_INTEGRATE_ROTVEC,
 *     default, exact for a constant rate; small angles by its series, see att_ars.h) or the article's
 *     first-order quaternion derivative q := q + (0.5 q (x) (0, w - b)) dt, normalised
 *     (ATT_INTEGRATE_FIRST_ORDER). The magnetometer sample is rotated into the earth frame of this
 *     predicted attitude, m' = q m q*, for step 3 (both corrections are computed from the prediction);
 *  2. accel correction, toward z = (0, 0, 1) of the earth-frame specific force a' = q a q*, or with
 *     tau_acc_lp > 0 (default) of the output of two cascaded first-order low-passes of it (gain
 *     dt / (tau_acc_lp + dt) each), so translational accelerations average out before they tilt q:
 *     with k_acc = 1 (default: alpha_acc 1, tau_acc 0) the full alignment without trigonometry as in
 *     att_ars.h (lp2 becomes (0, 0, |lp2|), lp1 is rotated with it); otherwise the rotation by the
 *     fraction k_acc of the angle atan2(|a' x z|, a' . z) about a' x z / |a' x z| (the article's
 *     acos(a' . z), accurate for small angles), both stages rotated with it; q := Q * q (left
 *     multiplication: a rotation in the earth frame);
 *  3. magnetometer correction against the earth-frame reference field m0:
 *     ATT_MARS_MAG_HORIZONTAL (default) uses the horizontal parts h of m' and r of m0 only, so the
 *     magnetometer can only change yaw, never roll/pitch: with C = (|h| + h . r, 0, 0, (h x r)_z) /
 *     sqrt(2 |h| (|h| + h . r)), the shortest-arc rotation about z from h to r, q := ((1 - k_mag) +
 *     k_mag C_w, 0, 0, k_mag C_z) * q (the normalised interpolation from the identity toward C, no
 *     trigonometry: for the small heading errors of tracking the fraction k_mag of the angle; a half turn
 *     toward C when h points away from r). ATT_MARS_MAG_FULL uses the full vectors (the article):
 *     rotation toward m0 by the fraction k_mag of the angle about m' x m0.
 *     A sample is rejected (ATT_FLAG_MAG_REJECTED, no correction) when ||m|/|m0| - 1| > mag_norm_reject
 *     (tested as |m| outside |m0| (1 -+ mag_norm_reject)), when the dip of m' differs from that of m0
 *     by more than mag_dip_reject (tested as m'_z outside |m| sin(dip0 -+ mag_dip_reject), the interval
 *     limited to +-pi/2 where sin is monotonic), or when the direction is degenerate (horizontal mode:
 *     |h| == 0 or no horizontal m0).
 *     A magnetometer slower than the gyro gives no sample (MAG_ABSENT: zero or NaN) on the steps between
 *     its samples. A valid sample after g such steps corrects with the gain of n steps, 1 - (1 - k)^n
 *     (k of the phase at the sample's step: k_mag, k_fast or k_rec), n = g + 1 when the sample before
 *     also ended a gap, at most that gap + 1 (a regular period is made up, an outage beyond it is not;
 *     g counted up to 255), else 1 (after samples on every step): tau_mag stays a time constant in
 *     seconds. An invalid sample (MAG_INVALID) or a rejected one ends its gap with nothing applied.
 *     The reference is estimated, not frozen: the steps count the accepted samples and those rejected by
 *     norm or dip (summing their |m| and earth-frame vertical field m'_z) in blocks of 1 s (at least one
 *     sample). At the end of a block with more accepted than rejected samples, the norm and sin(dip) of
 *     m0 move toward the block's means (sum m'_z / sum |m|) by k_ref = T / (mag_ref_tau + T), T the
 *     block length, its horizontal direction kept: a slowly changing field stays accepted. A block with
 *     at least as many rejected samples is a candidate field; when the following blocks stay within half
 *     the rejection bounds of the candidate's running mean (norm within mag_norm_reject / 2 of it,
 *     sin(dip) within mag_dip_reject / 2) for mag_new_time, the candidate becomes m0: the heading is
 *     never tied to whatever field the first samples saw. After the heading alignment and after a new
 *     reference, the correction uses tau_mag_fast instead of tau_mag for 3 tau_mag_fast, in whole blocks
 *     (fast convergence). Blocks without mag samples change nothing.
 *     Gyro bias in motion (tau_bias_mag > 0, bias modes AT_REST and RUNNING, HORIZONTAL mode): a bias
 *     left in the integration turns the heading at a steady rate, which the heading correction keeps
 *     undoing; each accepted correction by the angle theta = 2 C'_z (C' the applied correction, toward
 *     the fraction k of the angle) moves the bias by -theta / max(tau_bias_mag, dt) along the earth's vertical
 *     seen in the sensor frame, r3 = R(q)^T z (a PI loop: critically damped for tau_bias_mag = 4 tau_mag),
 *     each component kept within +-gyro_range.
 *     Not during the fast phase or a recovery (their corrections are a heading error, not a rate). Off by default: it
 *     helps on long runs without rest in the simulator but costs accuracy on BROAD, where the heading
 *     corrections come from the field more than from the bias (docs/filters.md).
 *  Recovery after a clipping gyro (recovery_time > 0): a gyro sample with any |w_i| >= 0.98 gyro_range
 *     (a sensor at its full scale reads a clipped value, not an overrange) or beyond gyro_range starts a
 *     recovery of recovery_time: the integration has lost rotation it cannot know, so the first applied
 *     accel sample after a clipping sample restarts the accel low-pass, which then takes the running mean
 *     of the samples since (att_i_recovery_lp_gain, as in att_ars.h), and the heading correction runs with the
 *     time constant recovery_time / 8 (instead of tau_mag); every step of it
 *     reports ATT_FLAG_INITIALISED (the attitude is being re-initialised from the sensors), and its end
 *     starts the fast heading phase of an alignment (the tilt is still settling). The start from the
 *     first usable accel sample is a recovery too (one sample gives the tilt, whatever linear
 *     acceleration it holds): the stages start from that sample, the running mean's first update; its
 *     end does not start the fast phase again (the alignment's is running: rec_clip).
 *  4. q is normalised; ATT_FLAG_NUMERIC keeps the attitude and the low-pass states from before the step.
 *  5. Covariance (att_filter_output's cov, on request; docs/filters.md): the model of att_ars.h (step 5)
 *     for the tilt (accel gain k_acc and its low-pass, which a recovery leaves as they are: only the
 *     recovery's fading term is added), cov[0] and cov[1]; for the
 *     heading, cov[2], the first-order model of the mag correction's gain (k_mag; k_fast in the fast
 *     phase, k_rec in a recovery) with the heading noise density mag_noise / |m0_xy| (a weak horizontal
 *     field gives a noisy heading), plus gyro_noise^2 dt per step since the last accepted mag sample or
 *     the alignment, at most pi^2/3; pi^2/3 (unknown) before the reference field is known or without a
 *     mag gain or a horizontal field. Accepted: an accel sample that passed its tests, a mag sample that
 *     passed the norm and dip tests. Before the first usable sample the caps (pi^2/12, pi^2/3). The
 *     model treats the full mag mode's correction as a heading correction. cov[3] = 0. Units rad^2.
 *  When the direction to correct is exactly opposite to the reference (cross product too small to
 *  normalise), a fixed axis perpendicular to the reference is used: accel: x = (1, 0, 0); full mag:
 *  the horizontal unit vector perpendicular to m0 (x when m0 is vertical).
 *
 * Initialisation (init_from_sensors, default): at the first step with a valid accel sample, roll and
 * pitch come from att_sensor_tilt(acc). If that step also has a valid mag sample, yaw is chosen so
 * that the earth-frame horizontal field points north (+y): with m_e = q m q* for the yaw-0 attitude,
 * q := Qz(atan2(m_e.x, m_e.y)) q, and m0 = (0, |m_e,xy|, m_e,z) for m_e of the aligned attitude.
 * Heading is thus relative to magnetic north; with a declination D (setting declination, east of
 * true north positive) the field is put at the azimuth D instead, q := Qz(atan2(m_e.x, m_e.y) - D) q
 * and m0 = (|m_e,xy| sin D, |m_e,xy| cos D, m_e,z), so that yaw is relative to true north (D = 0
 * gives the same bits as magnetic north). Without a mag sample at that step the attitude starts
 * with yaw 0 (6-axis operation) and the first later valid mag sample aligns the yaw the same way and
 * sets m0 (the step reports ATT_FLAG_INITIALISED again). With init_from_sensors false the attitude is
 * q_init from the start and m0 = m0_init; when m0_init is zero, m0 = q m q* of the first valid mag
 * sample (the yaw of q_init is trusted, no alignment).
 *
 * Hard-iron offset estimated on the device (hard_iron_tau > 0, opt-in; att_hardiron.h): from the rotation
 * the gyro measures between mag samples, independent of the attitude and of m0; the applied offset
 * (moving at most hard_iron_rate) is subtracted from every valid mag sample before step 3 and the
 * alignment; it stays 0 until the rotations have made it observable. att_filter_mag_offset reports it.
 *
 * Flags: the sensor checks of att_sensor.h (mag: zero or NaN vector = ATT_FLAG_MAG_ABSENT, Inf or
 * |m| > mag_range = ATT_FLAG_MAG_INVALID); ATT_FLAG_ACCEL_REJECTED when ||a|/g - 1| > accel_reject;
 * ATT_FLAG_MAG_REJECTED when a valid mag sample was not used (norm/dip rejection, degenerate
 * direction, or a failed alignment); ATT_FLAG_NUMERIC when the first-order integration or the final
 * normalisation failed (the state is kept from before); with the finite ranges of the settings
 * contract neither can happen. The state stays finite and unit in every case.
 *
 * Units: rad/s, m/s^2, uT, s. Frames: samples in the sensor frame; q sensor-to-earth (ENU, z up).
 */
#ifndef ATT_MARS_H
#define ATT_MARS_H

#include "attica/att_config.h"
#include "attica/att_ars.h"
#include "attica/att_hardiron.h"
#include "attica/att_magref.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/** How the magnetometer correction uses the field vectors. */
typedef enum {
    ATT_MARS_MAG_HORIZONTAL = 0, /**< horizontal projections only: corrects yaw alone (default) */
    ATT_MARS_MAG_FULL = 1        /**< full vectors, axis m' x m0 (the article): may also tilt */
} att_mars_mag_mode_t;

/**
 * Settings of the 9-axis complementary filter. Fill with att_mars_settings_default, then change.
 * Each field's valid range is given in brackets; att_mars_init (and att_mars_settings_validate) refuse
 * anything else with ATT_ERR_SETTINGS (att_filter_settings_check names the field). NaN and Inf are
 * outside every range.
 */
typedef struct {
    float dt;                     /**< sample period, s; [1e-6, 1] */
    float alpha_acc;              /**< per-sample accel correction gain, [0, 1]; unused when tau_acc > 0 */
    float alpha_mag;              /**< mag correction gain per step (per sample when a mag sample comes every
                                       step; step 3: a slower mag's), [0, 1]; unused when tau_mag > 0 */
    float tau_acc;                /**< accel time constant, s, [0, 1e4]; > 0 sets k_acc = dt/(tau_acc+dt)
                                       (alpha_acc is then ignored); 0 = k_acc is alpha_acc */
    float tau_mag;                /**< mag time constant, s, [0, 1e4]; > 0 sets k_mag = dt/(tau_mag+dt)
                                       (alpha_mag is then ignored); 0 = k_mag is alpha_mag */
    att_mars_mag_mode_t mag_mode; /**< HORIZONTAL (0) or FULL (1): yaw-only or full-vector mag correction */
    float gravity;                /**< g, m/s^2; [1, 100] */
    float accel_reject;           /**< skip accel correction when ||a|/g - 1| > this; [0, 1e3]; 0 = never */
    float accel_range;            /**< |a| above this is saturation: correction skipped, m/s^2; (gravity, 1e4] */
    float gyro_range;             /**< the gyro's full scale, rad/s, (0, 1e3]: a |w_i| beyond it, up to
                                      twice it, is a reading at the rail, used as read
                                      (ATT_FLAG_GYRO_RANGE); beyond, the sample is not used */
    float mag_range;              /**< |m| above this: sample invalid, uT; (0, 1e5] */
    float mag_norm_reject;        /**< skip mag when ||m|/|m0| - 1| > this; [0, 1e3]; 0 = never skip */
    float mag_dip_reject;         /**< skip mag when |dip(q m q*) - dip(m0)| > this, rad, [0, pi]; 0 = never */
    att_vec3_t bias_init;         /**< initial gyro bias b, rad/s, sensor frame; each component in [-gyro_range, gyro_range] */
    bool init_from_sensors;       /**< attitude and m0 from the first valid accel (+ mag) samples */
    att_quat_t q_init;            /**< initial attitude when init_from_sensors is false, sensor-to-earth;
                                       finite, |q|^2 in [2^-20, 2^20] (normalised by init) */
    att_vec3_t m0_init;           /**< reference field when init_from_sensors is false, uT, earth (ENU);
                                       zero, or |m0_init| in [1e-3, mag_range] (zero: take it from the
                                       first valid mag sample) */
    att_integration_t integration; /**< ROTVEC (0) or FIRST_ORDER (2): exponential map (default) or the article's */
    float tau_acc_lp;             /**< low-pass time constant of the earth-frame accel, s, [0, 1e4]; 0 = off */
    att_bias_mode_t bias_mode;    /**< gyro bias (default AT_REST; FROZEN: bias_init): OFF (0), FROZEN (1), RUNNING (2) or AT_REST (3) */
    uint32_t bias_n_max;          /**< cap on n in the running mean of the bias; [1, 2^24] */
    float rest_gyro;              /**< at rest when |w - b| < rest_gyro (+ att_bias.h's widening), rad/s, [0, gyro_range] ... */
    float rest_accel;             /**< ... and ||a| - g| < rest_accel, m/s^2, [0, gravity] ... */
    float rest_time;              /**< ... for at least rest_time, s, [0, 1e4] */
    float mag_ref_tau;            /**< time constant of the reference field's norm and dip, learnt from the
                                       accepted samples, s, [0, 1e4]; 0 = kept as first set */
    float mag_new_time;           /**< a rejected field that stays steady this long becomes the reference,
                                       s, [0, 1e4]; 0 = never */
    float tau_mag_fast;           /**< mag time constant for 3 tau_mag_fast after the heading was aligned or
                                       a new reference adopted, s, [0, 1e4]; 0 = off */
    float tau_bias_mag;           /**< time constant of the gyro bias learnt in motion from the heading
                                       corrections (bias modes AT_REST and RUNNING, HORIZONTAL mag mode), s,
                                       [0, 1e4]; 0 = off */
    float recovery_time;          /**< after a gyro sample at 98 % of gyro_range or beyond (a clipping gyro),
                                       accel and mag are trusted strongly for this long, s, [0, 1e4]; 0 = off;
                                       at most 2^24 samples */
    float declination;            /**< magnetic declination, rad, [-pi, pi], east of true north positive: the
                                       heading alignment from the sensors (init_from_sensors) puts the field
                                       at this azimuth, so yaw is relative to true north; 0 = magnetic north
                                       (default). Without init_from_sensors (q_init and m0_init are the
                                       caller's frame) only where a new reference has no horizontal part of
                                       its own to keep: it then points at this azimuth */
    float gyro_noise;             /**< covariance model: gyro white noise density, rad/s/sqrt(Hz), [0, 1] */
    float accel_noise;            /**< covariance model: density of the specific force's disturbance (noise
                                       and linear acceleration), m/s^2/sqrt(Hz), [0, 1e3] */
    float mag_noise;              /**< covariance model: density of the field's disturbance, uT/sqrt(Hz),
                                       [0, 1e3] */
    float hard_iron_tau;          /**< hard-iron offset estimated on the device from rotation (att_hardiron.h):
                                       the memory of its estimate, s, [0, 1e4]; 0 = off (default); below
                                       a few pairs (about 5 s) it keeps too little to become observable */
    float hard_iron_rate;         /**< the applied hard-iron offset moves by at most this per axis, uT/s,
                                       [1e-3, 1e3]; a step (rate dt) below the float resolution of the
                                       offset (2^-23 |h|) rounds: it needs rate dt >= 2^-22 mag_range */
} att_mars_settings_t;

/** Coefficients derived from the settings by att_mars_init: what a step needs, and the reset values. */
typedef struct {
    float dt;                /**< sample period, s */
    float k_acc;             /**< per-sample accel correction gain, [0, 1] */
    float k_mag;             /**< per-sample mag correction gain, [0, 1] */
    float k_mag1;            /**< 1 - k_mag */
    float k_lp;              /**< per-sample gain of each accel low-pass stage, [0, 1) (0 = off) */
    float gravity;           /**< g, m/s^2 */
    float accel_reject;      /**< ||a|/g - 1| limit (0 = never) */
    float accel_range2;      /**< saturation limit of |a|^2, (m/s^2)^2 */
    float gyro_range;        /**< saturation limit of |w_i|, rad/s */
    float mag_range;         /**< validity limit of |m|, uT */
    float mag_norm_reject;   /**< ||m|/|m0| - 1| limit (0 = never) */
    float mag_dip_reject;    /**< dip deviation limit, rad (0 = never) */
    att_bias_params_t bias;  /**< rest detector and running-mean parameters */
    att_quat_t q_init;       /**< attitude after reset (unit, sensor-to-earth) without init_from_sensors */
    att_vec3_t m0_init;      /**< reference field after reset, uT, earth frame (zero: none) */
    att_vec3_t bias_init;    /**< bias after reset, rad/s, sensor frame */
    uint8_t integration;     /**< att_integration_t */
    uint8_t mag_mode;        /**< att_mars_mag_mode_t */
    bool init_from_sensors;  /**< wait for the first usable accel sample, align yaw with the first mag */
    bool lp_on;               /**< k_lp > 0: the accel low-pass is used */
    bool reject_on;           /**< accel_reject > 0: the rejection test is made */
    bool full;               /**< k_acc == 1: full alignment with the low-passed gravity, no trig */
    att_magref_params_t ref; /**< the learnt reference field (att_magref.h) */
    float k_fast;            /**< per-sample mag gain of the fast phase (k_mag when tau_mag_fast is 0) */
    float k_fast1;           /**< 1 - k_fast */
    uint32_t fast_n;         /**< blocks of the fast phase after a new reference (0 = none) */
    uint32_t fast_start_n;   /**< blocks of the fast phase after the heading alignment: also the accel
                                  low-pass's settling time 6 tau_acc_lp (the tilt of a first sample can be off) */
    float k_bias_mag;        /**< 1 / max(tau_bias_mag, dt), 1/s (0: the bias is not learnt from the heading corrections) */
    bool bias_mag_on;        /**< k_bias_mag > 0 (tau_bias_mag > 0, bias mode AT_REST or RUNNING, HORIZONTAL) */
    float clip;              /**< |w_i| at or above this is clipping: 0.98 gyro_range, rad/s (Inf: no recovery) */
    float k_rec;             /**< per-sample mag gain during a recovery */
    float k_rec1;            /**< 1 - k_rec */
    uint32_t rec_n;          /**< samples of a recovery (0 = none) */
    float decl;              /**< declination D, rad (east of true north positive) */
    float decl_sin;          /**< sin D: the east part of the reference's horizontal unit direction */
    float decl_cos;          /**< cos D: its north part */
    float var_step;          /**< covariance: gyro_noise^2 dt, the variance a step adds, rad^2 */
    float var_tilt;          /**< covariance: steady-state tilt variance of the accel correction, rad^2 */
    float gyro_noise2;       /**< covariance: gyro_noise^2, (rad/s)^2/Hz */
    float mag_noise2;        /**< covariance: mag_noise^2, uT^2/Hz */
    att_hardiron_params_t hi; /**< the hard-iron estimate (att_hardiron.h) */
} att_mars_coeffs_t;

/** Dynamic state of a 9-axis filter instance. */
typedef struct {
    att_quat_t q;          /**< attitude, unit, sensor-to-earth (ENU) */
    att_vec3_t bias;       /**< gyro bias estimate b, rad/s, sensor frame */
    att_vec3_t lp1;        /**< first accel low-pass stage, m/s^2, earth frame */
    att_vec3_t lp2;        /**< second accel low-pass stage (used by the correction), m/s^2, earth */
    att_vec3_t m0;         /**< reference magnetic field, uT, earth frame (ENU); valid when m0_valid */
    att_vec3_t m0_ref;     /**< unit reference direction of the mag correction (mode dependent), earth */
    att_vec3_t m0_perp;    /**< unit fallback axis for a field opposite to m0_ref, earth */
    float m0_lo;           /**< smallest accepted |m|, uT (norm rejection; 0 = none) */
    float m0_hi;           /**< largest accepted |m|, uT (norm rejection; mag_range = none) */
    float dip_lo;          /**< smallest accepted sin(dip) of q m q* (dip rejection; -1 = none) */
    float dip_hi;          /**< largest accepted sin(dip) (dip rejection; 1 = none) */
    uint32_t bias_n;       /**< n of the running mean, <= bias_n_max */
    uint32_t rest_count;   /**< consecutive samples at rest (saturates at rest_n) */
    float rest_gate2;      /**< the rest detector's gyro gate, (rad/s)^2: bias.rest_first2 until the first
                                bias update, then bias.rest_gyro2 (att_bias.h) */
    uint32_t steps;        /**< steps taken since init/reset (wraps) */
    uint32_t flags;        /**< flags of the last step */
    att_magref_t ref;      /**< statistics of the learnt reference field (att_magref.h) */
    att_hardiron_t hi;     /**< the hard-iron estimate and the offset applied (att_hardiron.h) */
    uint32_t fast_left;    /**< blocks left of the fast phase (k_fast instead of k_mag) */
    uint32_t rec_left;     /**< steps left of the recovery after a clipping gyro or the start (0 = none) */
    uint32_t rec_lp_n;     /**< accel low-pass updates since the last clipping gyro sample or the start (att_i_recovery_lp_gain) */
    uint32_t acc_step;     /**< steps before the step of the last accepted accel sample (or the start): covariance */
    uint32_t mag_step;     /**< steps before the step of the last accepted mag sample or alignment: covariance */
    uint32_t mag_gap;      /**< running steps with no mag sample (MAG_ABSENT) since the last sample, valid or
                                not (saturates at 255) */
    uint32_t mag_period;   /**< the gap that the last gap-ending sample ended, 0 from the first step of a gap
                                that does not follow such a sample: the most a sample makes up (att_mars.c) */
    uint32_t mag_gap_step; /**< steps at that sample */
    bool m0_ref_ok;        /**< m0_ref is defined (horizontal mode: m0 has a horizontal component) */
    bool m0_valid;         /**< m0 holds the reference field (and m0_ref .. dip_hi are derived from it) */
    bool initialised;      /**< q holds a valid attitude */
    bool rec_clip;         /**< a clipping gyro sample started a recovery since the start (the start's own
                                recovery does not start the fast phase at its end) */
} att_mars_state_t;

/** One 9-axis complementary filter instance (no heap; copy freely): coefficients and state. */
typedef struct {
    att_mars_coeffs_t c;  /**< derived from the settings at init / retune */
    att_mars_state_t st;  /**< changes every step */
} att_mars_t;

/**
 * Default settings for sample period dt (s), tuned on BROAD (docs/accuracy.md), rate-independent:
 * rotvec integration, gyro bias learnt at rest, accel low-pass tau_acc_lp 1.3 s with the full
 * alignment (alpha_acc 1, tau_acc 0: the same lag as the earlier 1 s low-pass followed by a 0.5 s
 * correction), tau_mag 20 s, horizontal mag mode, no accel rejection, mag_norm_reject 0.2,
 * mag_dip_reject 0.3 rad, initialisation from the sensors, the reference field learnt (mag_ref_tau 20 s,
 * the same time scale as the heading correction; mag_new_time 20 s; tau_mag_fast 2 s), no bias learnt in
 * motion (tau_bias_mag 0), a recovery of 2 s after a clipping gyro (recovery_time), declination 0
 * (magnetic north). The article's literal
 * settings (alpha_acc 0.02, alpha_mag 0.01 per sample, accel_reject 0.1, first-order integration, fixed
 * bias, no low-pass, the reference frozen: mag_ref_tau, mag_new_time, tau_mag_fast and recovery_time 0) are the seed
 * preset (att_filter_settings_preset).
 */
void att_mars_settings_default(att_mars_settings_t *settings, float dt);
/** ATT_OK when every field is within its range (above), else ATT_ERR_SETTINGS (ATT_ERR_NULL for NULL). */
att_status_t att_mars_settings_validate(const att_mars_settings_t *settings);
/** Validate settings and initialise f. On error f is left unchanged. */
att_status_t att_mars_init(att_mars_t *f, const att_mars_settings_t *settings);
/**
 * New settings for a running instance: coefficients replaced, state kept (attitude, bias, low-pass
 * states, reference field and its statistics, counters), except that the bias becomes 0 (mode OFF) or bias_init
 * (FROZEN), the counters are limited to the new rest_n / bias_n_max (the rest gate follows the new
 * settings and the kept n, att_bias.h), and the reference field's
 * derived limits (direction for the mag mode, norm and dip bounds) are recomputed and the fast phase
 * is limited to the new one's length after an alignment (fast_start_n); a recovery under way is
 * limited to the new recovery_time (0: ended); a change of hard_iron_tau between 0 and > 0 starts the
 * hard-iron estimate again (off: no offset applied). A new declination applies from the next heading alignment (reset): the heading and the reference are kept;
 * to apply it at once, set the heading to the current one turned by the change: ENU yaw (counter-clockwise)
 * minus (D_new - D_old), NED yaw plus it (att_filter_set_heading). On error f is left
 * unchanged.
 */
att_status_t att_mars_retune(att_mars_t *f, const att_mars_settings_t *settings);
/** Back to the state right after att_mars_init, keeping the settings. */
void att_mars_reset(att_mars_t *f);
/**
 * One update with gyro (rad/s), accel (m/s^2) and mag (uT; zero or NaN vector = no sample), all in the
 * sensor frame; returns ATT_FLAG_* bits.
 */
uint32_t att_mars_step(att_mars_t *f, att_vec3_t gyr, att_vec3_t acc, att_vec3_t mag);
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_MARS_H */
