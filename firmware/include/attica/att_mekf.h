/**
 * @file att_mekf.h
 * @brief Multiplicative (error-state) extended Kalman filter ("MEKF"), 6-axis or 9-axis, with gyro
 * bias states: the attitude filter of spacecraft and drones (Markley's MEKF), made robust to linear
 * acceleration and magnetic disturbances.
 *
 * Nominal state: the unit quaternion q (sensor-to-earth, ENU) and the gyro bias b (rad/s, sensor
 * frame). Error state dx = (dtheta, db): dtheta (rad) is a rotation vector in the EARTH frame,
 * multiplied on the left, q_true = exp(dtheta) (x) q; db = b_true - b. Its 6x6 covariance P is kept as
 * the 21 floats of its upper triangle (row-major: (0,0) (0,1) .. (0,5) (1,1) .. (5,5)); P = [[A, B],
 * [B^T, C]] with A the attitude block (rad^2), B attitude-bias, C the bias block ((rad/s)^2).
 * Derivation in docs/filters.md. Per step, once initialised:
 *
 *  1. prediction: q := q (x) exp((w - b) dt) (att_i_quat_from_rotvec_fast: the exact exponential map,
 *     small angles by its series); R = R(q) of the predicted attitude. With the earth-frame error the
 *     attitude block of the transition is the identity, F = [[I, -R dt], [0, I]], and Q = diag(qa I3,
 *     qb I3), qa = gyro_noise^2 dt, qb = bias_noise^2 dt (noise densities: rate-independent):
 *       A := A - dt (R H^T + H R^T) + qa I,  B := H - (dt / 2) R C,  C := C + qb I,
 *     with H = B - (dt / 2) R C (which is Phi P Phi^T + Q exactly, written out for the structure).
 *     An unusable gyro sample leaves q (the covariance is still predicted).
 *  2. accelerometer update (skipped for an unusable sample or ||a|/g - 1| > accel_reject): the specific
 *     force in the earth frame of the prediction, v = R a, low-passed by a second-order Butterworth
 *     section (natural frequency 1 / (sqrt(2) tau_acc_lp), damping 1 / sqrt(2); tau_acc_lp = 0: v
 *     itself) is the measured up direction u. In its two states, with k = dt / (sqrt(2) tau_acc_lp + dt):
 *       lp1 := lp1 + (k (v - lp2) - (sqrt(2) - 1) k (lp1 - lp2)),  lp2 := lp2 + k (lp1 - lp2),  u = lp2.
 *     Its lag at low frequencies is 2 tau_acc_lp, as two cascaded first-order stages of time constant
 *     tau_acc_lp (att_ars.h), and it attenuates faster linear accelerations twice as much: during
 *     motion the estimate's tilt follows u closely, so the lag (the gyro errors u cannot follow) and the
 *     linear acceleration left in u are the two errors traded. Until the first rest (step 0's zero-rate
 *     update) has measured the gyro bias, the section runs at tau_acc_lp_no_rest instead: a bias learnt
 *     from the accel alone drifts more within the lag, so a shorter one pays (docs/accuracy.md). The
 *     residual is the horizontal part of the shortest rotation taking u to z = (0, 0, 1) in half-angle
 *     form, y = 2 (c_x, c_y) with
 *     (c_w, c_x, c_y, 0) = att_i_align_up(u): to first order u = z - dtheta x z, so y = (dtheta_x,
 *     dtheta_y), H = [I2 0]; unlike the raw (u_x, u_y) it grows monotonically up to a half turn
 *     (|y| = 2 sin(angle / 2)).
 *     Noise r = r_acc (1 + r_accel (|a|/g - 1)^2) per axis, r_acc = accel_noise^2 / dt; S = A_xy + r I2.
 *     Chi-square gate on d^2 = y^T S^-1 y (2 degrees of freedom): d^2 > gate rejects the update
 *     (ATT_FLAG_ACCEL_REJECTED, nothing applied, the sample not entered into the low-pass); above gate / 4
 *     the innovation covariance is scaled by lambda = d^2 / (gate / 4), so that an applied update never
 *     has d^2 > gate / 4 (the measurement noise then is lambda S - A_xy >= lambda r: a Huber-like soft
 *     limit). After gate_recover s of consecutive gate rejections the tilt variances grow by
 *     |y|^2 / (gate / 4) (at most p_max), the error the innovation reveals, and the update is applied
 *     (a wrong start or an over-confident filter recovers; a PSD addition, P stays positive definite).
 *     Update K = P H^T (lambda S)^-1, dx = K y, P := P - K (lambda S) K^T (the optimal gain for that
 *     noise), q := exp(dtheta) (x) q, b := b + db; lp1 and lp2 are rotated by exp(dtheta) too, so they
 *     stay in the estimate's earth frame.
 *  3. magnetometer update (use_mag, a usable mag sample, the reference field m0 known): m' = q m q*
 *     with the corrected q; rejected (ATT_FLAG_MAG_REJECTED) for |m| outside |m0| (1 -+ mag_norm_reject)
 *     or a dip off that of m0 by more than mag_dip_reject (the bounds of att_mars.h), or no horizontal
 *     part. The innovation is the heading error: with h the horizontal part of m' and r the unit
 *     horizontal direction of m0, y = 2 sin(alpha / 2) for the angle alpha from h to r about z,
 *     y = 2 (h x r)_z / sqrt(2 |h| (|h| + h . r)) (no trigonometry; 2 when h points away from r).
 *     To first order y = dtheta_z - c (r_x dtheta_x + r_y dtheta_y), c = m0_z / |m0_xy| (a tilt error
 *     moves the horizontal projection), so H = [-c r_x, -c r_y, 1, 0, 0, 0]; noise r_mag =
 *     mag_noise^2 / dt; s = H P H^T + r_mag; its own gate and soft limit on y^2 / s (1 degree of freedom,
 *     mag_gate). The gain K = P H^T / s has its dtheta_x, dtheta_y entries set to zero, so the field
 *     can change only the heading (and the bias), never the tilt; P takes the Joseph form for that
 *     suboptimal gain, (I - K H) P (I - K H)^T + K r K^T (the tilt block is left unchanged).
 *     q := exp((0, 0, dtheta_z)) (x) q, b := b + db, and lp1, lp2 are turned about z by the same
 *     rotation: like every correction (accel, rest, the yaw alignment) it turns the estimate's earth
 *     frame, in which the low-pass stages live.
 *     Heading is relative to magnetic north (m0 = (0, |m_xy|, m_z) after the yaw alignment), or to true
 *     north with the setting declination D (the alignment of att_mars.h puts the field at the azimuth
 *     D: m0 = (|m_xy| sin D, |m_xy| cos D, m_z)).
 *     The reference is estimated, not frozen (att_magref.h, as in att_mars.h): after the mag phase every
 *     step with a known m0 counts its sample, accepted (it passed the norm and dip tests, whatever the
 *     chi-square gate then did) or rejected by them, with |m| and m'_z, in blocks of 1 s. At a block's
 *     end the norm and sin(dip) of m0 move toward the accepted samples' means (mag_ref_tau), its
 *     horizontal direction kept; or a rejected field that stays steady for mag_new_time becomes m0, and
 *     the heading is then unknown against it: its variance is set to p_max and its correlations to zero,
 *     so the next samples set the heading at the pace their noise allows (a few seconds at the defaults,
 *     where the steady heading variance is about p0_att). The heading is not tied to the field of the
 *     first samples. In 6-axis use (use_mag off) a set heading (att_filter_set_heading) resets the
 *     heading's row the same way, to one step's noise qa: the heading is then known (head_known).
 *  4. conditioning of P: a variance above its cap (p_max for the attitude, p0_bias for the bias) is
 *     brought to the cap by the congruence D P D (correlations kept; in 6-axis use it holds the
 *     unobservable yaw variance at p_max, a normal condition that is not flagged). P must then pass a
 *     positive definiteness test with margin (the pivots of P = L D L^T: d_0 > 0, d_j > 2^-16 (P_jj +
 *     sum_{i<j} m_ji^2 P_ii) with m = L^-1, a bound of the factorisation's own rounding; F16); if it
 *     does not, or a variance is not > 0, the variance is set to its cap and the correlations are
 *     multiplied by 1 - 2^-10 (dropped when that is not enough): ATT_FLAG_CLAMPED.
 *  5. q is normalised (ATT_FLAG_NUMERIC keeps the attitude of the step before; it cannot happen with
 *     the finite ranges of the settings contract).
 *  6. Recovery after a clipping gyro (recovery_time > 0): a gyro sample with any |w_i| >= 0.98 gyro_range
 *     (a sensor at its full scale reads a clipped value, not an overrange) or beyond gyro_range starts a
 *     recovery of recovery_time (a later one restarts it), flagged ATT_FLAG_INITIALISED: the rate the
 *     gyro could not measure has turned the attitude by an unknown angle. During it, with the gain
 *     k = dt / (recovery_time / 8 + dt), each prediction adds k^2 r / (1 - k) (at most p_max) to the attitude
 *     variances (r = r_acc for the two tilt axes, r_mag for the heading): the process noise whose steady-state
 *     Kalman gain is k, so the filter follows accel and mag with the time constant recovery_time / 8;
 *     each clipping sample restarts the accel low-pass (its stages hold samples turned by a wrong
 *     rotation: the next applied accel sample starts them, as at the start), which then takes the
 *     running mean of the samples since (att_i_recovery_lp_gain, att_ars.h; both states hold it) until
 *     its age is the section's lag, 1 / (n + 1) below k / (2 sqrt(2)) for the low-pass's gain of the
 *     moment k (k_lp, or k_lp_no_rest before the first rest; ATT_MEKF_REC_MEAN_END); in the start's
 *     recovery, where the bias is not known yet, only until it is below k_lp_rec / (2 sqrt(2)),
 *     k_lp_rec = max(k_lp_no_rest, k): a long mean would gather samples turned by that bias); an accel
 *     gate rejection is recovered at once
 *     (the gate_recover wait is skipped); the accel update takes the bias as a consider state (Schmidt:
 *     its gain rows zero, its rows of P and V kept); and the updates leave the scale-factor estimate
 *     alone (the innovations of a clipped turn or of the start are attitude errors of unknown origin,
 *     not evidence of a bias or a scale error). Once over, P has converged with the
 *     measurements and the usual noises take over. Fusion's angular rate recovery is the model; it is
 *     the recovery of att_ars.h and att_mars.h in the Kalman filter's own terms. The start from the
 *     sensors is a recovery too (flagged alike): its tilt comes from one accel sample, whatever linear
 *     acceleration that held, its heading from one mag sample turned by that tilt, and the low-pass
 *     stages start from that sample; followed by the normal gains, the settling of the low-pass reads
 *     as a gyro bias and the heading converges at the pace of mag_noise.
 *
 * Initialisation (init_from_sensors, default): at the first usable accel sample, roll and pitch from
 * att_sensor_tilt(a), yaw 0, lp1 = lp2 = q a q*. With use_mag, the first usable mag sample (at that
 * step or later) aligns the yaw with north as att_mars.h does (the field at the azimuth of the
 * declination D) and sets m0 = (|m_xy| sin D, |m_xy| cos D, m_z); the
 * heading variance and its correlations are then reset to p0_att, 0 (ATT_FLAG_INITIALISED), and
 * lp1, lp2 are turned with the alignment's rotation about z.
 * Without init_from_sensors the attitude is q_init from the start and m0 = m0_init, or when m0_init
 * is zero the first usable mag sample in the earth frame of q (its yaw is trusted). P starts as
 * diag(p0_att I3, p0_bias I3), b as bias_init. The low-pass states start from the first usable sample
 * (q a q*), never from a prior: a fictitious history would tell the filter its tilt is right.
 *
 * Hard-iron offset estimated on the device (hard_iron_tau > 0, opt-in; att_hardiron.h): from the rotation
 * the gyro measures between mag samples ((1 + s)(w - b)), independent of the attitude and of m0; the
 * applied offset (moving at most hard_iron_rate) is subtracted from every valid mag sample (after its
 * sample checks) before the start, the alignment and step 3; it stays 0 until the rotations have made it
 * observable. Without use_mag there is none (hard_iron_tau is ignored).
 * att_filter_mag_offset reports it.
 *
 * Gyro bias: estimated at all times through the correlations of P (the horizontal earth components
 * during any motion that tilts, the vertical one from the heading in 9-axis use), and at rest (step 0,
 * before the prediction: |w - b|^2 < rest_gyro^2 + min(9 tr(P_bb), ATT_BIAS_UNKNOWN2), the bias
 * estimate's error up to 3 sigma per axis and at most that of the running mean's first rest (att_bias.h;
 * rest_gyro 0: never), and ||a| - g| < rest_accel for rest_time) by the zero-rate
 * pseudo-measurement w = b + noise (three scalar updates; its attitude correction through the
 * correlations is applied as the accel update's; ATT_FLAG_AT_REST). Its noise per sample and axis is
 * measured: the mean square of w - b over the rest (the bias before the step's update, the mean of the
 * three axes; a running mean from the rest's first update until its gain is 1 / (rest_n + 1), then a
 * first-order low-pass of that gain (rest_time 0: the sample's own); restarted at each rest and by a
 * retune to another dt), at least r_rest = rest_noise^2 / dt. A true rest
 * shows the gyro's own noise and pins the bias; a slow turn the detector takes for rest shows its rate
 * in w - b and is believed no more than its size allows.
 * The attitude process noise grows with the rate: qa = (gyro_noise^2 + gyro_rate_noise^2 |w - b|^2) dt
 * (scale factor and misalignment errors, and the sampling of a rate that changes within a sample).
 * ATT_FLAG_BIAS_UPDATED when an update changed b.
 *
 * Gyro scale factor (gyro_scale_sd > 0): the integrated rate is (1 + s)(w - b), with s the estimate of
 * the gyro's scale-factor error (one for the three axes; a rate sampled against a clock that runs fast
 * or slow scales the same way). An error ds of it rotates the estimate by ds (w - b) dt per step, a
 * drift during motion that the low-passed accel measurement sees only with its lag. It is estimated by
 * a two-stage Kalman filter beside the 6-state one (Friedland's separate-bias form, so P stays 6x6):
 * the sensitivity V = d(dtheta, db)/ds (6 floats) is predicted as
 *   V_theta := V_theta + dt R ((w - b) - V_b)      (V_b unchanged),
 * and the accel and zero-rate updates of the 6-state filter (residual y, H, gain K, innovation
 * covariance S as the gain uses it) are also measurements of s with sensitivity a = H V:
 *   k_s = p_s a^T (S + p_s a a^T)^-1,  ds = k_s y,  p_s := p_s (1 - k_s a),
 *   V := V - K a,  dx := K y + V ds (with that V),  s := s + ds.
 * The heading update only takes V := V - K a: its gain has the tilt entries forced to zero, so the split
 * into the two stages is exact only with k_s = 0 there (docs/filters.md). The variance p_s starts at
 * gyro_scale_sd^2; s is kept within +-ATT_MEKF_SCALE_MAX (ATT_FLAG_CLAMPED when that limit acts) and
 * |V| within ATT_MEKF_SENS_MAX (V scaled down, not flagged: in 6-axis use nothing corrects the heading's
 * sensitivity while the sensor turns about the vertical). The scale is a constant: no process noise,
 * the estimate settles as the motion excites it (rotations that tilt; heading turns in 9-axis use).
 *
 * Units: rad/s, m/s^2, uT, s; variances rad^2 and (rad/s)^2. Frames: samples in the sensor frame,
 * q sensor-to-earth (ENU, z up), dtheta in the earth frame, b in the sensor frame. Mirrored bit for
 * bit by host/attica/reference/mekf.py.
 */
#ifndef ATT_MEKF_H
#define ATT_MEKF_H

#include "attica/att_config.h"
#include "attica/att_hardiron.h"
#include "attica/att_magref.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Largest |gyro scale-factor error| estimated (and accepted as gyro_scale_init, gyro_scale_sd): 10 %. */
#define ATT_MEKF_SCALE_MAX 0.1f
/** Largest norm of the scale sensitivity V (rad per unit scale error, and rad/s for the bias rows). */
#define ATT_MEKF_SENS_MAX 16.0f

/* ATT_CDEF_BEGIN */
/** Entries of the packed upper triangle of the 6x6 covariance (the length of att_mekf_state_t.p). */
#define ATT_MEKF_P_LEN 21

/**
 * Settings of the MEKF. Fill with att_mekf_settings_default, then change fields. Each field's valid
 * range is given in brackets; init refuses anything else (NaN and Inf included;
 * att_filter_settings_check names the field).
 */
typedef struct {
    float dt;              /**< sample period, s; [1e-6, 1] */
    float gyro_noise;      /**< gyro white-noise density, rad/s/sqrt(Hz) (= rad/sqrt(s)); [1e-7, 1] */
    float gyro_rate_noise; /**< rate-proportional gyro error density (scale factor, misalignment), sqrt(s); [0, 1] */
    float bias_noise;      /**< gyro bias random walk, rad/s/sqrt(s); [1e-9, 1] */
    float accel_noise;     /**< noise density of the measured up direction (low-passed), rad sqrt(s); [1e-6, 1e3] */
    float r_accel;         /**< growth of the accel noise with (|a|/g - 1)^2; [0, 1e6] */
    float gate;            /**< chi-square gate on the accel d^2 (2 dof); [0, 1e6]; 0 = off */
    float gate_recover;    /**< after this long of consecutive gate rejections, recover, s; [0, 1e4]; 0 = never */
    float mag_noise;       /**< noise density of the heading innovation, rad sqrt(s); [1e-6, 1e3] */
    float mag_gate;        /**< chi-square gate on the heading innovation (1 dof); [0, 1e6]; 0 = off */
    float p0_att;          /**< initial attitude error variance per axis, rad^2; [1e-12, p_max] */
    float p0_bias;         /**< initial bias variance per axis and its cap, (rad/s)^2; [1e-12, 100] */
    float p_max;           /**< cap on each attitude error variance, rad^2; [1e-6, 1000] */
    float gravity;         /**< g, m/s^2; [1, 100] */
    float accel_reject;    /**< skip the accel update when ||a|/g - 1| > this, [0, 1e3]; 0 = never skip */
    float accel_range;     /**< |a| above this is saturation: update skipped, m/s^2; (gravity, 1e4] */
    float gyro_range;      /**< the gyro's full scale, rad/s, (0, 1e3]: a |w_i| beyond it, up to
                               twice it, is a reading at the rail, used as read
                               (ATT_FLAG_GYRO_RANGE); beyond, the sample is not used */
    float mag_range;       /**< |m| above this: sample invalid, uT; (0, 1e5] */
    float mag_norm_reject; /**< skip mag when ||m|/|m0| - 1| > this; [0, 1e3]; 0 = never skip */
    float mag_dip_reject;  /**< skip mag when |dip(q m q*) - dip(m0)| > this, rad, [0, pi]; 0 = never */
    float tau_acc_lp;      /**< earth-frame accel low-pass (Butterworth, lag 2 tau_acc_lp), s, [0, 1e4]; 0 = off */
    float tau_acc_lp_no_rest; /**< the low-pass's time constant until a rest (the zero-rate update) has
                                measured the gyro bias (a bias_init does not count), s, [0, 1e4];
                                0 = tau_acc_lp throughout; unused when tau_acc_lp is 0 */
    float rest_noise;      /**< least noise density of the zero-rate pseudo-measurement at rest (the measured
                                one is used when larger), rad/s/sqrt(Hz); [1e-7, 1] */
    float rest_gyro;       /**< at rest when |w - b| < rest_gyro (+ the bias's error), rad/s, [0, gyro_range]; 0 = none ... */
    float rest_accel;      /**< ... and ||a| - g| < rest_accel, m/s^2, [0, gravity] ... */
    float rest_time;       /**< ... for at least rest_time, s, [0, 1e4] */
    float gyro_scale_sd;   /**< prior standard deviation of the gyro scale-factor error, estimated online
                                (1 = 100 %); [0, 0.1] (ATT_MEKF_SCALE_MAX); 0 = not estimated */
    float gyro_scale_init; /**< initial gyro scale-factor error (rate = (1 + s)(w - b)); [-0.1, 0.1] */
    float recovery_time;   /**< after a gyro sample at 98 % of gyro_range or beyond (a clipping gyro),
                                this long the recovery of step 6, s; [0, 1e4]; 0 = none; at most 2^24 samples */
    float declination;     /**< magnetic declination, rad, [-pi, pi], east of true north positive: the yaw
                                alignment from the sensors (init_from_sensors, use_mag) puts the field at
                                this azimuth, so yaw is relative to true north; 0 = magnetic north
                                (default). Unused without use_mag; without init_from_sensors only where
                                a new reference has no horizontal part of its own to keep (it then
                                points at this azimuth) */
    float mag_ref_tau;     /**< time constant of the reference field's norm and dip, learnt from the
                                accepted samples (att_magref.h), s, [0, 1e4]; 0 = kept as first set */
    float mag_new_time;    /**< a rejected field that stays steady this long becomes the reference (its
                                heading variance reset, as at the alignment), s, [0, 1e4]; 0 = never */
    float hard_iron_tau;   /**< hard-iron offset estimated on the device from rotation (att_hardiron.h): the
                                memory of its estimate, s, [0, 1e4]; 0 = off (default); below a few pairs
                                (about 5 s) it keeps too little to become observable */
    float hard_iron_rate;  /**< the applied hard-iron offset moves by at most this per axis, uT/s, [1e-3, 1e3];
                                a step (rate dt) below the float resolution of the offset (2^-23 |h|)
                                rounds: it needs rate dt >= 2^-22 mag_range */
    bool use_mag;          /**< 9-axis: use the magnetometer (false: 6-axis, mag ignored, no mag flags) */
    bool init_from_sensors; /**< roll/pitch from the first usable accel sample, yaw from the first mag */
    att_quat_t q_init;     /**< initial attitude when init_from_sensors is false; finite, |q|^2 in [2^-20, 2^20] */
    att_vec3_t m0_init;    /**< reference field when init_from_sensors is false, uT, earth (ENU); zero, or
                                |m0_init| in [1e-3, mag_range] (zero: from the first usable mag sample) */
    att_vec3_t bias_init;  /**< initial gyro bias, rad/s, sensor frame; each component in [-gyro_range, gyro_range] */
} att_mekf_settings_t;

/** Coefficients derived from the settings by att_mekf_init: what a step needs, and the reset values. */
typedef struct {
    float dt;              /**< sample period, s */
    float half_dt;         /**< dt / 2, s */
    float qa;              /**< attitude process noise per step, gyro_noise^2 dt, rad^2 */
    float qw;              /**< growth of qa with |w - b|^2, gyro_rate_noise^2 dt, s^2 */
    float qb;              /**< bias process noise per step, bias_noise^2 dt, (rad/s)^2 */
    float r_acc;           /**< accel noise per sample and axis, accel_noise^2 / dt, rad^2 */
    float r_accel;         /**< growth of r with (|a|/g - 1)^2 */
    float gate;            /**< accel chi-square gate (0 = off) */
    float soft;            /**< gate / 4: the soft limit of d^2 */
    float r_mag;           /**< heading noise per sample, mag_noise^2 / dt, rad^2 */
    float mag_gate;        /**< heading chi-square gate (0 = off) */
    float mag_soft;        /**< mag_gate / 4 */
    float p0_att;          /**< initial attitude variance, rad^2 */
    float p0_bias;         /**< initial bias variance and its cap, (rad/s)^2 */
    float p_max;           /**< cap on the attitude variances, rad^2 */
    float gravity;         /**< g, m/s^2 */
    float accel_reject;    /**< ||a|/g - 1| limit (0 = never) */
    float accel_range2;    /**< saturation limit of |a|^2, (m/s^2)^2 */
    float gyro_range;      /**< saturation limit of |w_i|, rad/s */
    float mag_range;       /**< validity limit of |m|, uT */
    float mag_norm_reject; /**< ||m|/|m0| - 1| limit (0 = never) */
    float mag_dip_reject;  /**< dip deviation limit, rad (0 = never) */
    float k_lp;            /**< per-sample gain of the accel low-pass, dt / (sqrt(2) tau_acc_lp + dt) (0 = off) */
    float k_lp_no_rest;    /**< its gain until the first rest, from tau_acc_lp_no_rest (k_lp when 0 or off) */
    uint32_t n_recover;    /**< consecutive gate rejections before the recovery (0 = never) */
    float r_rest;          /**< least zero-rate noise per sample and axis, rest_noise^2 / dt, (rad/s)^2 */
    float rest_gyro2;      /**< rest_gyro^2, (rad/s)^2 */
    float acc2_lo;         /**< (g - rest_accel)^2, (m/s^2)^2 */
    float acc2_hi;         /**< (g + rest_accel)^2, (m/s^2)^2 */
    uint32_t rest_n;       /**< rest_time in samples */
    float p0_scale;        /**< initial variance of the scale-factor error, gyro_scale_sd^2 (0 = off) */
    float scale_init;      /**< scale-factor error after reset */
    float clip;            /**< |w_i| at or above this is clipping: 0.98 gyro_range, rad/s (Inf: no recovery) */
    float k_lp_rec;        /**< the low-pass gain in the start's recovery once its mean is below it: max(k_lp_no_rest, dt / (recovery_time / 8 + dt)) */
    float q_rec_tilt;      /**< tilt process noise per step of a recovery, min(k^2 r_acc / (1 - k), p_max), rad^2 */
    float q_rec_head;      /**< heading process noise per step of a recovery, min(k^2 r_mag / (1 - k), p_max), rad^2 */
    uint32_t rec_n;        /**< samples of a recovery (0 = none) */
    float decl;            /**< declination D, rad (east of true north positive) */
    float decl_sin;        /**< sin D: the east part of the reference's horizontal unit direction */
    float decl_cos;        /**< cos D: its north part */
    att_magref_params_t ref; /**< the learnt reference field (att_magref.h) */
    att_hardiron_params_t hi; /**< the hard-iron estimate (att_hardiron.h) */
    att_quat_t q_init;     /**< attitude after reset without init_from_sensors (unit) */
    att_vec3_t m0_init;    /**< reference field after reset, uT, earth (zero: none) */
    att_vec3_t bias_init;  /**< bias after reset, rad/s, sensor frame */
    bool use_mag;          /**< the magnetometer is used */
    bool init_from_sensors; /**< wait for the first usable accel sample, align yaw with the first mag */
    bool lp_on;            /**< k_lp > 0 */
    bool need_norm;        /**< |a| is needed (r_accel or accel_reject set) */
} att_mekf_coeffs_t;

/** Dynamic state of an MEKF instance. */
typedef struct {
    att_quat_t q;          /**< nominal attitude, unit, sensor-to-earth (ENU) */
    att_vec3_t bias;       /**< gyro bias estimate b, rad/s, sensor frame */
    float p[21];           /**< covariance of (dtheta (earth, rad), db (rad/s)), packed upper triangle */
    float scale;           /**< gyro scale-factor error estimate s: the rate integrated is (1 + s)(w - b) */
    float p_scale;         /**< variance of s (0: not estimated) */
    float scale_v[6];      /**< sensitivity of (dtheta, db) to s: rad (earth frame), then rad/s (sensor) */
    att_vec3_t lp1;        /**< inner state of the accel low-pass, m/s^2, earth frame */
    att_vec3_t lp2;        /**< output of the accel low-pass (the measured up direction), m/s^2, earth */
    float k_lp;            /**< the low-pass's gain now: k_lp_no_rest until the first rest, then k_lp */
    att_vec3_t m0;         /**< reference magnetic field, uT, earth frame (ENU); valid when m0_valid */
    att_vec3_t m0_ref;     /**< unit horizontal direction of m0 (z = 0), earth */
    float mag_hx;          /**< H entry of dtheta_x in the heading innovation, -c r_x (c = m0_z / |m0_xy|) */
    float mag_hy;          /**< H entry of dtheta_y, -c r_y */
    float m0_lo;           /**< smallest accepted |m|, uT (norm rejection; INF: no usable reference) */
    float m0_hi;           /**< largest accepted |m|, uT */
    float dip_lo;          /**< smallest accepted sin(dip) of q m q* (-2 = none) */
    float dip_hi;          /**< largest accepted sin(dip) (2 = none) */
    uint32_t gated;        /**< consecutive accel gate rejections */
    uint32_t rest_count;   /**< consecutive samples that pass the rest test (saturates at rest_n) */
    float rest_e2;         /**< measured noise of the zero-rate update: mean square of w - b per axis over
                                the rest, (rad/s)^2, sensor frame; valid when rest_e2_n > 0 */
    uint32_t rest_e2_n;    /**< zero-rate updates in rest_e2 (0: none since the rest began; saturates at rest_n) */
    uint32_t steps;        /**< steps taken since init/reset (wraps) */
    uint32_t flags;        /**< flags of the last step */
    uint32_t rec_left;     /**< steps left of the recovery after a clipping gyro or the start (0 = none) */
    uint32_t rec_lp_n;     /**< accel low-pass updates since the last clipping gyro sample or the start (att_i_recovery_lp_gain) */
    att_magref_t ref;      /**< statistics of the learnt reference field (att_magref.h) */
    att_hardiron_t hi;     /**< the hard-iron estimate and the offset applied (att_hardiron.h) */
    bool m0_valid;         /**< m0 holds the reference field (m0_ref .. dip_hi derived from it) */
    bool lp_valid;         /**< lp1, lp2 hold samples (else the next usable sample starts them) */
    bool rec_clip;         /**< the last recovery began at a clipping gyro sample (false: the start's); read only during one */
    bool initialised;      /**< q holds a valid attitude */
    bool head_known;       /**< a heading was set (att_filter_set_heading; or the field tracked it before a
                                retune to 6 axes) and no clipping gyro sample has turned it since. With use_mag
                                off the output's cov[2] is P's when true, pi^2/3 when false; unused with it on */
    bool rested;           /**< a rest (the zero-rate update) has measured the gyro bias since the reset:
                                the accel low-pass runs at k_lp, before at k_lp_no_rest */
} att_mekf_state_t;

/** One MEKF instance (no heap; copy freely). */
typedef struct {
    att_mekf_coeffs_t c;  /**< derived from the settings at init / retune */
    att_mekf_state_t st;  /**< changes every step */
} att_mekf_t;

/**
 * Default settings for sample period dt (s): noise densities of a MEMS IMU, tuned on BROAD with one
 * parameter set for all trials (docs/accuracy.md), 9-axis (use_mag). See att_mekf.c for the values.
 * They are also the seed preset (att_filter_settings_preset): the MEKF has no earlier literal settings.
 */
void att_mekf_settings_default(att_mekf_settings_t *settings, float dt);
/** ATT_OK when every field is within its range, else ATT_ERR_SETTINGS (ATT_ERR_NULL for NULL). */
att_status_t att_mekf_settings_validate(const att_mekf_settings_t *settings);
/** Validate settings and initialise f. ATT_ERR_NULL / ATT_ERR_SETTINGS leave f unchanged. */
att_status_t att_mekf_init(att_mekf_t *f, const att_mekf_settings_t *settings);
/**
 * New settings, the state kept (attitude, bias, covariance, low-pass stages, reference field and its
 * derived limits recomputed, counters); the new caps apply from the next step; turning the hard-iron
 * estimate on or off (hard_iron_tau, use_mag) starts it again (off: no offset applied), and a new dt
 * the zero-rate noise's mean (rest_e2: per sample, it depends on dt). A new declination applies
 * from the next yaw alignment (reset): to apply it at once, set the heading to the current one turned by
 * the change: ENU yaw (counter-clockwise) minus (D_new - D_old), NED yaw plus it (att_filter_set_heading). On error f is unchanged.
 */
att_status_t att_mekf_retune(att_mekf_t *f, const att_mekf_settings_t *settings);
/** Back to the state right after att_mekf_init, keeping the settings. */
void att_mekf_reset(att_mekf_t *f);
/**
 * One update with gyro (rad/s), accel (m/s^2) and mag (uT; zero or NaN vector = no sample; ignored
 * without use_mag), sensor frame; returns ATT_FLAG_* bits.
 */
uint32_t att_mekf_step(att_mekf_t *f, att_vec3_t gyr, att_vec3_t acc, att_vec3_t mag);
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_MEKF_H */
