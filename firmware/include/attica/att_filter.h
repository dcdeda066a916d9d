/**
 * @file att_filter.h
 * @brief One interface for every attica filter: a tagged union, no heap.
 *
 * @code
 * static att_filter_t f;
 * att_filter_settings_t s;
 * att_output_t out;
 * att_sample_t in;
 * att_settings_error_t why;
 * att_filter_settings_default(ATT_FILTER_ARS, 0.0035f, &s);   // dt = 1 / 285.714 Hz
 * s.ars.tau = 1.0f;                                           // change what you need (tau > 0: gain unused)
 * if (att_filter_init(&f, ATT_FILTER_ARS, &s) != ATT_OK) {
 *     (void)att_filter_settings_check(ATT_FILTER_ARS, &s, &why);   // why.field: "ars.tau" ...
 *     return 1;
 * }
 * while (read_imu(&in)) {                         // your driver: rad/s, m/s^2, uT, sensor frame
 *     (void)att_filter_step(&f, &in, &out);       // q, gyro_bias, flags, steps (see out.valid)
 *     att_filter_output(&f, &out);                // when Euler angles are needed: the whole record
 *     if ((out.valid & ATT_OUT_EULER) != 0u && (out.flags & ATT_FLAGS_OUTPUT_INVALID) == 0u) {
 *         publish(out.q, out.euler, out.flags);
 *     }
 * }
 * @endcode
 *
 * att_filter_step writes euler only for the kinds whose state is Euler angles (ekf, gyro, tilt: the
 * ATT_OUT_EULER bit of out.valid); the other fields of out keep what they held.
 *
 * A sample carries gyro (rad/s), accel (m/s^2) and mag (uT), all sensor frame; a mag vector that is
 * exactly zero or has a NaN component means "no mag sample". Filters ignore inputs they do not use.
 */
#ifndef ATT_FILTER_H
#define ATT_FILTER_H

#include "attica/att_config.h"
#include "attica/att_ars.h"
#include "attica/att_calib.h"
#include "attica/att_ekf.h"
#include "attica/att_gyro.h"
#include "attica/att_kf.h"
#include "attica/att_mars.h"
#include "attica/att_mekf.h"
#include "attica/att_tilt.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/** Filter kinds (values are part of the CAN contract: do not renumber). */
typedef enum {
    ATT_FILTER_NONE = 0,
    ATT_FILTER_ARS = 1,  /**< quaternion complementary ARS, 6-axis (att_ars.h) */
    ATT_FILTER_MARS = 2, /**< 9-axis complementary filter with magnetometer */
    ATT_FILTER_KF = 3,   /**< linear quaternion Kalman filter, 6-axis */
    ATT_FILTER_EKF = 4,  /**< Euler-angle extended Kalman filter, 6-axis */
    ATT_FILTER_GYRO = 5, /**< gyro-only Euler-rate integration baseline (att_gyro.h) */
    ATT_FILTER_TILT = 6, /**< accel-only tilt baseline (att_tilt.h) */
    ATT_FILTER_MEKF = 7  /**< multiplicative (error-state) EKF with gyro bias, 6- or 9-axis (att_mekf.h) */
} att_filter_kind_t;

/** One IMU sample, sensor frame. */
typedef struct {
    att_vec3_t gyr; /**< angular rate, rad/s */
    att_vec3_t acc; /**< specific force, m/s^2 (+g up at rest) */
    att_vec3_t mag; /**< magnetic field, uT; zero vector or NaN = absent */
} att_sample_t;

/** Output fields (att_output_t.valid bits): which fields of a record hold values. */
enum {
    ATT_OUT_Q = 0x1u,     /**< q */
    ATT_OUT_EULER = 0x2u, /**< euler */
    ATT_OUT_BIAS = 0x4u,  /**< gyro_bias */
    ATT_OUT_COV = 0x8u,   /**< cov */
    ATT_OUT_ALL = 0xFu,   /**< every field (att_filter_output) */
    ATT_OUT_ACCEL = 0x10u /**< att_accel_t.valid: the acceleration outputs (att_filter_accel) */
};

/**
 * Flags that mean "the output is not an attitude estimate": no valid sample has initialised the
 * filter yet (q is the initial attitude), or the call itself was invalid. With every other flag q is
 * a finite unit quaternion estimating the attitude (ATT_FLAG_NUMERIC: the one of the step before).
 */
enum { ATT_FLAGS_OUTPUT_INVALID = 0xC000 /**< ATT_FLAG_NOT_READY | ATT_FLAG_BAD_ARG */ };

/**
 * What a filter reports. att_filter_step fills q, gyro_bias, flags and steps (and euler for the kinds
 * whose state is Euler angles: ekf, gyro, tilt) and says so in valid; it leaves the other fields as
 * they were. att_filter_output fills every field (valid = ATT_OUT_ALL): the Euler angles of the other
 * kinds and the covariance diagonal are computed there, on request, not in every step.
 */
typedef struct {
    att_quat_t q;         /**< attitude, unit, sensor-to-earth (ENU, or the calibration's convention) */
    att_vec3_t euler;     /**< ZYX (roll phi, pitch theta, yaw psi), rad */
    att_vec3_t gyro_bias; /**< gyro bias estimate, rad/s, sensor frame (0 if not estimated) */
    float cov[4];         /**< covariance diagonal: KF (w, x, y, z); EKF (phi, theta, psi rad^2; mean bias
                               variance, (rad/s)^2); MEKF (dtheta x, y, z (earth frame), rad^2; mean bias
                               variance, (rad/s)^2); ARS, MARS: the covariance model's (tilt about earth
                               x, y, heading about z, 0) rad^2 (att_ars.h, step 5); gyro, tilt: 0. About
                               the ENU axes whatever the calibration's convention (q, euler converted).
                               A heading nothing observes (ars, EKF, MEKF without mag) is pi^2/3 except
                               from att_filter_set_heading to the next clipping gyro sample */
    uint32_t flags;       /**< ATT_FLAG_* of the step */
    uint32_t steps;       /**< steps since init/reset (wraps) */
    uint32_t valid;       /**< ATT_OUT_* bits of the fields written by the call that filled the record */
} att_output_t;

/** Named settings presets (att_filter_settings_preset). */
typedef enum {
    ATT_PRESET_DEFAULT = 0, /**< att_filter_settings_default: tuned on BROAD, rate-independent */
    ATT_PRESET_SEED = 1     /**< the literal settings of the first implementation (per-sample gains) */
} att_preset_t;

/** Settings of any filter; the member named after the kind is used (the kinds compiled in: att_config.h). */
typedef union {
#if ATT_WITH_ARS
    att_ars_settings_t ars;
#endif
#if ATT_WITH_MARS
    att_mars_settings_t mars;
#endif
#if ATT_WITH_KF
    att_kf_settings_t kf;
#endif
#if ATT_WITH_EKF
    att_ekf_settings_t ekf;
#endif
#if ATT_WITH_GYRO
    att_gyro_settings_t gyro;
#endif
#if ATT_WITH_TILT
    att_tilt_settings_t tilt;
#endif
#if ATT_WITH_MEKF
    att_mekf_settings_t mekf;
#endif
} att_filter_settings_t;

/** State of any filter; the member named after the kind is used (the kinds compiled in). */
typedef union {
#if ATT_WITH_ARS
    att_ars_t ars;
#endif
#if ATT_WITH_MARS
    att_mars_t mars;
#endif
#if ATT_WITH_KF
    att_kf_t kf;
#endif
#if ATT_WITH_EKF
    att_ekf_t ekf;
#endif
#if ATT_WITH_GYRO
    att_gyro_t gyro;
#endif
#if ATT_WITH_TILT
    att_tilt_t tilt;
#endif
#if ATT_WITH_MEKF
    att_mekf_t mekf;
#endif
} att_filter_state_t;

/**
 * A filter of any kind: as large as the largest kind compiled in, plus the kind and (ATT_WITH_CALIB)
 * the input/output stages.
 */
typedef struct {
    att_filter_kind_t kind; /**< which member of u is live; ATT_FILTER_NONE before init */
    att_filter_state_t u;   /**< the filter state */
#if ATT_WITH_CALIB
    att_calib_t cal;        /**< input and output stages (att_filter_calibrate; identity after init) */
#endif
} att_filter_t;

/**
 * Default settings of a kind for sample period dt (s). settings points to a whole att_filter_settings_t:
 * it is cleared first (the bytes past the kind's member and its padding are 0, so the same call gives the
 * same image byte for byte), then the kind's member written; untouched on an error. ATT_ERR_KIND for an
 * unknown kind, ATT_ERR_DISABLED for a kind compiled out (att_config.h).
 */
att_status_t att_filter_settings_default(att_filter_kind_t kind, float dt, att_filter_settings_t *settings);
/**
 * Settings of a named preset for sample period dt (s). ATT_PRESET_SEED restores the literal settings of
 * the first implementation: ARS k = 0.1 per sample, c = 100, no accel low-pass; MARS alpha_acc 0.02,
 * alpha_mag 0.01 per sample, accel_reject 0.1, first-order integration, fixed bias, no low-pass; KF
 * Q = 1e-4 I and R = 10 I per step; EKF Q = diag(1e-4, 1e-4, 0.1) and R = 6 I2 per step; MEKF: its
 * defaults (it has no earlier literal settings). MARS's is the first implementation's where a mag sample
 * comes every step (a slower one's gain now spans its interval, att_mars.h step 3). The union is cleared
 * first, as by att_filter_settings_default. ATT_ERR_KIND for an unknown kind or preset.
 */
att_status_t att_filter_settings_preset(att_filter_kind_t kind, att_preset_t preset, float dt,
                                        att_filter_settings_t *settings);
/**
 * ATT_OK when the kind's member of settings satisfies its settings contract (every field within the
 * range its header states), ATT_ERR_SETTINGS otherwise, ATT_ERR_KIND / ATT_ERR_NULL for a bad call.
 * att_filter_init and att_filter_retune accept exactly the settings this accepts.
 */
att_status_t att_filter_settings_validate(att_filter_kind_t kind, const att_filter_settings_t *settings);
/**
 * Which field makes att_filter_init refuse settings: the status att_filter_settings_validate returns
 * (ATT_OK exactly when init accepts them) and, for ATT_ERR_SETTINGS, in why (may be NULL) the first
 * refused field in the kind's order of checks, its bounds for these settings and the rule in words:
 *
 * @code
 * att_filter_settings_t s;
 * att_settings_error_t why;
 * att_filter_settings_default(ATT_FILTER_ARS, 0.01f, &s);
 * s.ars.tau_acc_lp = -1.0f;                       // out of range
 * if (att_filter_settings_check(ATT_FILTER_ARS, &s, &why) == ATT_ERR_SETTINGS) {
 *     log_refused(why.field, why.rule, why.unit);   // your log: "ars.tau_acc_lp", "[0, 1e4]", "s"
 * }
 * @endcode
 *
 * why->field is NULL unless a field was refused. The validator and this function are written from one
 * table per kind, so they cannot disagree. att_filter_init does not call it: an image that does not
 * carries none of its names (--gc-sections).
 */
att_status_t att_filter_settings_check(att_filter_kind_t kind, const att_filter_settings_t *settings,
                                       att_settings_error_t *why);
/**
 * The kind's settings contract, line by line: line index of the table att_filter_settings_validate and
 * att_filter_settings_check are written from, in their order, in *rule (field, the bounds for these
 * settings, rule in words, unit); ATT_OK when the line holds for settings, ATT_ERR_SETTINGS when not.
 * Past the last line rule->field is NULL (ATT_OK). ATT_ERR_NULL / ATT_ERR_KIND / ATT_ERR_DISABLED for a
 * bad call. The host's settings tables, the command line's help and docs/settings.md are made from it.
 *
 * @code
 * att_filter_settings_t s;
 * att_settings_error_t r;
 * att_filter_settings_default(ATT_FILTER_ARS, 0.01f, &s);
 * for (uint32_t i = 0u;; i++) {
 *     const att_status_t st = att_filter_settings_rule(ATT_FILTER_ARS, &s, i, &r);
 *     if (r.field == NULL) {
 *         break;                                          // past the last line (or a bad call)
 *     }
 *     print_rule(r.field, r.rule, r.unit, st == ATT_OK);  // your print: "ars.dt", "[1e-6, 1]", "s" ...
 * }
 * @endcode
 */
att_status_t att_filter_settings_rule(att_filter_kind_t kind, const att_filter_settings_t *settings, uint32_t index,
                                      att_settings_error_t *rule);
/**
 * Initialise f as the given kind, with identity input/output stages (ENU); on error f is unchanged.
 * ATT_ERR_DISABLED for a kind compiled out of this build (att_config.h).
 */
att_status_t att_filter_init(att_filter_t *f, att_filter_kind_t kind, const att_filter_settings_t *settings);
/**
 * New settings for a running filter of the same kind, keeping its state (attitude, bias, filter
 * memories and counters; see att_<kind>_retune for what a setting resets). ATT_ERR_KIND when f is not
 * initialised; on any error f is unchanged.
 */
att_status_t att_filter_retune(att_filter_t *f, const att_filter_settings_t *settings);
/** Reset to the state right after init. */
void att_filter_reset(att_filter_t *f);
/**
 * One step; fills the per-step fields of out (may be NULL; see att_output_t) and returns the flags
 * (ATT_FLAG_BAD_ARG for NULL/uninitialised).
 */
uint32_t att_filter_step(att_filter_t *f, const att_sample_t *in, att_output_t *out);
/** The largest n of att_filter_step_n; a larger n is clamped to it (ATT_FLAG_CLAMPED). */
enum { ATT_FILTER_STEP_N_MAX = 65535 };
/**
 * A step after n sample periods (n - 1 samples lost, e.g. an E2E counter gap or a timestamp gap): the
 * sample is held over the n periods, so the kind's fixed-period step runs n times on it (the gyro is
 * integrated over the whole gap, the corrections act for as long as they would have). Returns the OR
 * of the n steps' flags; out (may be NULL) gets the last step's fields with those flags. n = 1 is
 * att_filter_step; n = 0 does nothing and returns ATT_FLAG_BAD_ARG (out cleared); n above
 * ATT_FILTER_STEP_N_MAX is clamped and flagged ATT_FLAG_CLAMPED. Costs n steps.
 */
uint32_t att_filter_step_n(att_filter_t *f, const att_sample_t *in, uint32_t n, att_output_t *out);
/** The whole output record of the current state (flags and steps of the last step), valid = ATT_OUT_ALL. */
void att_filter_output(const att_filter_t *f, att_output_t *out);
/**
 * Apply calibration, mounting and output convention (att_calib.h) to a running filter: from the next
 * step on, att_filter_step feeds the kind's step the calibrated body-frame sample and reports q (and
 * euler) in the convention's earth frame; att_filter_output likewise. The filter state is kept (it is
 * the attitude of the body frame in ENU), except that a mars or mekf hard-iron estimate starts again
 * when the magnetometer's stage changed (mag model or mounting: att_hardiron.h, its samples are in
 * another frame or scale; the same stage keeps it). ATT_ERR_KIND when f is not initialised;
 * ATT_ERR_SETTINGS (att_calib_settings_check says why) / ATT_ERR_NULL leave f unchanged. Survives reset
 * and retune.
 */
att_status_t att_filter_calibrate(att_filter_t *f, const att_calib_settings_t *s);
/**
 * The acceleration outputs of the last step (calibration accel_outputs must be on): gravity and
 * linear acceleration in the body frame, earth-frame acceleration without gravity in the convention's
 * frame, m/s^2. out->valid = ATT_OUT_ACCEL, or 0 with zero fields when accel_outputs is off, no step
 * was taken since init/reset/calibrate, or f is NULL / not initialised.
 */
void att_filter_accel(const att_filter_t *f, att_accel_t *out);
/** The hard-iron estimate of a mars or mekf filter (att_filter_mag_offset; att_hardiron.h). */
typedef struct {
    att_vec3_t offset; /**< the offset subtracted from the mag samples, uT, in the frame of the samples the
                            kind sees (the body frame after the calibration stage's hard- and soft-iron
                            correction); 0 until estimated */
    bool on;           /**< the estimate runs (settings hard_iron_tau > 0) */
    bool estimated;    /**< the rotations have made the offset observable (it moves toward its estimate) */
} att_mag_offset_t;

/**
 * The hard-iron offset a mars or mekf filter estimates on the device and subtracts from its mag samples
 * (settings hard_iron_tau > 0; att_hardiron.h), into *out. ATT_ERR_KIND for the other kinds or an
 * uninitialised f, ATT_ERR_DISABLED in a build without it (att_config.h ATT_WITH_HARD_IRON 0),
 * ATT_ERR_NULL for a NULL argument.
 */
att_status_t att_filter_mag_offset(const att_filter_t *f, att_mag_offset_t *out);
/**
 * Set the heading: keep the tilt, replace the yaw by heading (rad, the yaw of the output convention:
 * ENU counter-clockwise from east, NED / NWU from north, NED clockwise), |heading| <= 8192. The
 * earth-frame memories (accel low-passes, the 9-axis filter's reference field) turn with the attitude.
 * A 6-axis heading (ars, ekf, mekf without mag) is known from here: the output's cov[2] is the heading's
 * variance from ~0 (the ekf's yaw variance and the mekf's heading row restart at one step's noise)
 * instead of pi^2/3, until a clipping gyro sample; a 9-axis filter's covariance is unchanged.
 * ATT_ERR_KIND for the tilt baseline (no heading) or an uninitialised f, ATT_ERR_STATE before the
 * filter's first valid sample (ATT_FLAG_NOT_READY: the attitude is not set yet), ATT_ERR_SETTINGS for
 * a non-finite or too large heading; on error f is unchanged.
 */
att_status_t att_filter_set_heading(att_filter_t *f, float heading);
/**
 * External heading update (GNSS course, compass) for the filters without a magnetometer (ars, kf,
 * ekf, gyro, and mekf with use_mag false): with valid true, turn the yaw by gain * wrap(heading - yaw), gain in [0, 1] per update
 * (1 = set heading), heading as for att_filter_set_heading; valid false does nothing (ATT_OK). Gain 1 is
 * att_filter_set_heading, covariance included; a smaller gain leaves the covariance as it is. ATT_ERR_KIND for mars, a 9-axis mekf, tilt or an uninitialised f, ATT_ERR_STATE before
 * the first valid sample, ATT_ERR_SETTINGS for a bad heading or gain; on error f is unchanged.
 */
att_status_t att_filter_heading_update(att_filter_t *f, float heading, float gain, bool valid);
/** Short lower-case name of a kind ("ars", "mars", "kf", "ekf", "gyro", "tilt", "mekf"; "?" if unknown). */
const char *att_filter_name(att_filter_kind_t kind);
/** Upper-case name of one ATT_FLAG_* bit ("GYRO_INVALID", ...); NULL when flag is not exactly one known bit. */
const char *att_flag_name(uint32_t flag);
/**
 * The names of the bits of flags joined by '|' ("-" for none, "0x...." for unknown bits) into buf,
 * always NUL-terminated when size > 0 (truncated if it does not fit). Returns the length the full text
 * needs (without the NUL), like snprintf.
 */
size_t att_flags_format(uint32_t flags, char *buf, size_t size);
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_FILTER_H */
