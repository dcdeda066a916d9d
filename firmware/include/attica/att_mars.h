/**
 * @file att_mars.h
 * @brief 9-axis quaternion complementary filter with magnetometer ("MARS"), after a Qiita article.
 *
 * Per step (after the attitude has been initialised):
 *  0. gyro bias b (bias_mode, as att_ars.h): running mean of the samples taken at rest (AT_REST,
 *     default: |w - b| < rest_gyro and ||a| - g| < rest_accel for rest_time), of every sample (RUNNING),
 *     fixed at bias_init (FROZEN, the article) or zero (OFF);
 *  1. gyro integration of w - b: exponential map q := q * Q((w - b) dt) (ATT_INTEGRATE_ROTVEC,
 *     default, exact for a constant rate) or the article's first-order quaternion derivative
 *     q := q + (0.5 q (x) (0, w - b)) dt (ATT_INTEGRATE_FIRST_ORDER); then normalise;
 *  2. accel correction: a' = q a q* / |a| (earth frame); the rotation taking a' to z = (0, 0, 1) has
 *     the axis a' x z / |a' x z| and the angle atan2(|a' x z|, a' . z) (equal to the article's
 *     acos(a' . z) for unit vectors, but accurate for small angles where acos loses ~3e-4 rad);
 *     q := Q(k_acc * angle, axis) * q (left multiplication: a rotation in the earth frame);
 *     with tau_acc_lp > 0 (default) a' is taken from two cascaded first-order low-passes of the
 *     earth-frame specific force q a q* (gain dt / (tau_acc_lp + dt) each; both stages rotated by the
 *     correction, see att_ars.h), so translational accelerations average out before they tilt q;
 *  3. magnetometer correction the same way against the earth-frame reference field m0:
 *     ATT_MARS_MAG_HORIZONTAL (default) projects m' = q m q* and m0 onto the horizontal plane first,
 *     so the axis is vertical and the magnetometer can only change yaw, never roll/pitch;
 *     ATT_MARS_MAG_FULL uses the full vectors (the article), axis m' x m0.
 *     A sample is rejected (ATT_FLAG_MAG_REJECTED, no correction) when ||m|/|m0| - 1| > mag_norm_reject,
 *     when the dip atan2(m'_z, |m'_xy|) differs from that of m0 by more than mag_dip_reject, or when
 *     the direction is degenerate (horizontal mode: |m'_xy| == 0).
 *  When the direction to correct is exactly opposite to the reference (cross product too small to
 *  normalise), a fixed axis perpendicular to the reference is used with the same atan2 angle (~pi):
 *  accel: x = (1, 0, 0); horizontal mag: z = (0, 0, 1); full mag: the horizontal unit vector
 *  perpendicular to m0 (x when m0 is vertical). When the vectors are already aligned the angle is ~0.
 *
 * Initialisation (init_from_sensors, default): at the first step with a valid accel sample, roll and
 * pitch come from att_sensor_tilt(acc). If that step also has a valid mag sample, yaw is chosen so
 * that the earth-frame horizontal field points north (+y): with m_e = q m q* for the yaw-0 attitude,
 * q := Qz(atan2(m_e.x, m_e.y)) q, and m0 = (0, |m_e,xy|, m_e,z) for m_e of the aligned attitude.
 * Heading is thus relative to magnetic north. Without a mag sample at that step the attitude starts
 * with yaw 0 (6-axis operation) and the first later valid mag sample aligns the yaw the same way and
 * sets m0 (the step reports ATT_FLAG_INITIALISED again). With init_from_sensors false the attitude is
 * q_init from the start and m0 = m0_init; when m0_init is zero, m0 = q m q* of the first valid mag
 * sample (the yaw of q_init is trusted, no alignment).
 *
 * Flags: the sensor checks of att_sensor.h (mag: zero or NaN vector = ATT_FLAG_MAG_ABSENT, Inf or
 * |m| > mag_range = ATT_FLAG_MAG_INVALID); ATT_FLAG_ACCEL_REJECTED when ||a|/g - 1| > accel_reject;
 * ATT_FLAG_MAG_REJECTED when a valid mag sample was not used (norm/dip rejection, degenerate
 * direction, or a failed alignment); ATT_FLAG_NUMERIC when the first-order integration overflowed
 * (the integration is then skipped, like an unusable gyro sample) or the final normalisation failed
 * (the attitude is kept from before the step). A corrected vector that cannot be normalised (only
 * possible with +Inf ranges and huge samples) skips that correction silently. The state stays
 * finite and unit in every case.
 *
 * Units: rad/s, m/s^2, uT, s. Frames: samples in the sensor frame; q sensor-to-earth (ENU, z up).
 */
#ifndef ATT_MARS_H
#define ATT_MARS_H

#include "attica/att_ars.h"
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

/** Settings of the 9-axis complementary filter. Fill with att_mars_settings_default, then change. */
typedef struct {
    float dt;                     /**< sample period, s; 0 < dt <= 1 */
    float alpha_acc;              /**< per-sample accel correction gain, [0, 1]; used when tau_acc == 0 */
    float alpha_mag;              /**< per-sample mag correction gain, [0, 1]; used when tau_mag == 0 */
    float tau_acc;                /**< accel time constant, s (>= 0); > 0 sets alpha = dt/(tau+dt) */
    float tau_mag;                /**< mag time constant, s (>= 0); > 0 sets alpha = dt/(tau+dt) */
    att_mars_mag_mode_t mag_mode; /**< horizontal (yaw only) or full-vector mag correction */
    float gravity;                /**< g, m/s^2; > 0 */
    float accel_reject;           /**< skip accel correction when ||a|/g - 1| > this; 0 = never skip */
    float accel_range;            /**< |a| above this is saturation: correction skipped, m/s^2 (> 0) */
    float gyro_range;             /**< any |w_i| above this: integration skipped, rad/s (> 0) */
    float mag_range;              /**< |m| above this: sample invalid, uT (> 0) */
    float mag_norm_reject;        /**< skip mag when ||m|/|m0| - 1| > this; 0 = never skip */
    float mag_dip_reject;         /**< skip mag when |dip(q m q*) - dip(m0)| > this, rad; 0 = never */
    att_vec3_t bias_init;         /**< fixed gyro bias b subtracted from every sample, rad/s, sensor frame */
    bool init_from_sensors;       /**< attitude and m0 from the first valid accel (+ mag) samples */
    att_quat_t q_init;            /**< initial attitude when init_from_sensors is false, sensor-to-earth */
    att_vec3_t m0_init;           /**< reference field when init_from_sensors is false, uT, earth (ENU);
                                       zero = take it from the first valid mag sample */
    att_integration_t integration; /**< ROTVEC (exponential map, default) or FIRST_ORDER (the article) */
    float tau_acc_lp;             /**< low-pass time constant of the earth-frame accel, s (>= 0); 0 = off */
    att_bias_mode_t bias_mode;    /**< gyro bias: AT_REST (default), FROZEN (= bias_init), RUNNING, OFF */
    uint32_t bias_n_max;          /**< cap on n in the running mean of the bias; 1 .. 2^24 */
    float rest_gyro;              /**< at rest when |w - b| < rest_gyro, rad/s ... */
    float rest_accel;             /**< ... and ||a| - g| < rest_accel, m/s^2 ... */
    float rest_time;              /**< ... for at least rest_time, s (>= 0) */
} att_mars_settings_t;

/** State of one 9-axis complementary filter instance (no heap; copy freely). */
typedef struct {
    att_mars_settings_t s; /**< validated copy of the settings */
    float k_acc;           /**< effective per-sample accel gain */
    float k_mag;           /**< effective per-sample mag gain */
    float k_lp;            /**< per-sample gain of each accel low-pass stage (0 = off) */
    uint32_t rest_n;       /**< samples at rest needed before the bias is updated */
    att_quat_t q;          /**< attitude, unit, sensor-to-earth (ENU) */
    att_vec3_t m0;         /**< reference magnetic field, uT, earth frame (ENU); valid when m0_valid */
    float m0_norm;         /**< |m0|, uT */
    float m0_dip;          /**< dip of m0: atan2(m0.z, |m0_xy|), rad (negative = pointing down) */
    att_vec3_t m0_ref;     /**< unit reference direction of the mag correction (mode dependent), earth */
    att_vec3_t m0_perp;    /**< unit fallback axis for a field opposite to m0_ref, earth */
    bool m0_ref_ok;        /**< m0_ref is defined (horizontal mode: m0 has a horizontal component) */
    bool m0_valid;         /**< m0 holds a reference field */
    bool initialised;      /**< q holds a valid attitude */
    att_vec3_t bias;       /**< gyro bias estimate b, rad/s, sensor frame */
    uint32_t bias_n;       /**< n of the running mean, <= bias_n_max */
    uint32_t rest_count;   /**< consecutive samples at rest (saturates at rest_n) */
    att_vec3_t lp1;        /**< first accel low-pass stage, m/s^2, earth frame */
    att_vec3_t lp2;        /**< second accel low-pass stage (used by the correction), m/s^2, earth */
    uint32_t steps;        /**< steps taken since init/reset (wraps) */
    uint32_t flags;        /**< flags of the last step */
} att_mars_t;

/**
 * Default settings for sample period dt (s), tuned on BROAD (docs/accuracy.md), rate-independent:
 * rotvec integration, gyro bias learnt at rest, accel low-pass tau_acc_lp 1 s, tau_acc 0.5 s,
 * tau_mag 20 s, horizontal mag mode, no accel rejection, mag_norm_reject 0.2, mag_dip_reject 0.3 rad,
 * initialisation from the sensors. The article's literal settings (alpha_acc 0.02, alpha_mag 0.01 per
 * sample, accel_reject 0.1, first-order integration, fixed bias, no low-pass) are the seed preset
 * (att_filter_settings_preset).
 */
void att_mars_settings_default(att_mars_settings_t *settings, float dt);
/** Validate settings and initialise f. On error f is left unchanged. */
att_status_t att_mars_init(att_mars_t *f, const att_mars_settings_t *settings);
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
