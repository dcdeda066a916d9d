/**
 * @file att_kinds.h
 * @brief Private: the table of filter kinds and the hooks every kind implements.
 *
 * The one list of kinds in C. att_filter.c (the unified interface) and att_node.c dispatch through
 * it and read no field of any filter: what a kind does with its state is behind its hooks, in its
 * own source (filters/<kind>/att_<kind>.c). Adding a kind: its header and source, one line below,
 * its value in att_filter_kind_t and its member in the two unions of att_filter.h, its ATT_WITH_
 * option in att_config.h (docs/architecture.md lists the rest: reference module, Python registry).
 * host/attica/kinds.py is the Python table; tests/test_kinds.py checks that the two agree.
 *
 * ATT_KINDS_EACH(S, X) applies S(X, NAME, name, num) to every kind, in kind order: NAME as in
 * ATT_FILTER_<NAME> and ATT_WITH_<NAME>, name as in att_<name>_* and the union members, num the
 * att_filter_kind_t value (part of the CAN contract). ATT_KINDS(X) expands X(NAME, name, num) for
 * the kinds compiled in (att_config.h), ATT_KINDS_ALL(X) for every kind.
 */
#ifndef ATT_KINDS_H
#define ATT_KINDS_H

#include "attica/att_filter.h"

/* clang-format off */
#define ATT_KINDS_EACH(S, X) \
    S(X, ARS, ars, 1)        \
    S(X, MARS, mars, 2)      \
    S(X, KF, kf, 3)          \
    S(X, EKF, ekf, 4)        \
    S(X, GYRO, gyro, 5)      \
    S(X, TILT, tilt, 6)      \
    S(X, MEKF, mekf, 7)
/* clang-format on */

/* x when flag (0 or 1, after expansion) is 1. */
#define ATT_KIND_IF_1(x) x
#define ATT_KIND_IF_0(x)
#define ATT_KIND_IF_(flag, x) ATT_KIND_IF_##flag(x)
#define ATT_KIND_IF(flag, x) ATT_KIND_IF_(flag, x)
#define ATT_KIND_SELECT(X, NAME, name, num) ATT_KIND_IF(ATT_WITH_##NAME, X(NAME, name, num))
#define ATT_KIND_EVERY(X, NAME, name, num) X(NAME, name, num)

/** X(NAME, name, num) for every kind compiled in. */
#define ATT_KINDS(X) ATT_KINDS_EACH(ATT_KIND_SELECT, X)
/** X(NAME, name, num) for every kind, compiled in or not. */
#define ATT_KINDS_ALL(X) ATT_KINDS_EACH(ATT_KIND_EVERY, X)

/** What a kind does with a heading (att_filter_set_heading, att_filter_heading_update). */
typedef enum {
    ATT_HEADING_NONE = 0,   /**< no heading (tilt): both refused */
    ATT_HEADING_SET = 1,    /**< it has its own heading reference (magnetometer): set only */
    ATT_HEADING_UPDATE = 2  /**< set, and external heading updates (GNSS course, compass) */
} att_heading_t;

/** Gains a running filter takes through the node's SET_GAIN command (values of ATT_CAN_GAIN_*). */
typedef enum {
    ATT_GAIN_TAU_ACC = 1, /**< accel correction time constant, s (the per-sample gain follows) */
    ATT_GAIN_TAU_MAG = 2, /**< mag correction time constant, s */
    ATT_GAIN_KF_R = 3,    /**< KF measurement noise */
    ATT_GAIN_EKF_R = 4,   /**< EKF measurement noise of roll and pitch */
    ATT_GAIN_DECLINATION = 5 /**< magnetic declination, rad, east of true north positive (mars, mekf) */
} att_gain_t;

/**
 * The per-sample gain that goes with a time constant set over CAN: 0 when tau > 0 (the gain is then
 * unused: 0 says so when the settings are read back), else 1 (tau 0: the full correction).
 */
static inline float att_i_gain_for_tau(float tau)
{
    return (tau > 0.0f) ? 0.0f : 1.0f;
}

/*
 * The hooks of kind `name` beside its public att_<name>_init, _retune, _reset and
 * _settings_validate (same meaning for every kind):
 *   att_<name>_preset     the settings of a named preset (default or seed; checked by the caller)
 *                         for sample period dt (s)
 *   att_<name>_period     the sample period of settings, s (0 for kinds without one: tilt)
 *   att_<name>_step_out   one step on the sample; fills the per-step fields of out (may be NULL) as
 *                         att_filter_step documents; returns the flags
 *   att_<name>_output     the state's fields of an output record: q or euler (as valid says),
 *                         gyro_bias, flags, steps, cov (where the kind has one), valid
 *   att_<name>_heading_kind  what the kind does with a heading (may depend on its settings)
 *   att_<name>_yaw_to     turn the attitude about the earth vertical so that its yaw (rad, ENU)
 *                         moves to target by the fraction gain of the wrapped difference, with the
 *                         earth-frame memories; ATT_ERR_STATE before the first valid sample or when
 *                         the difference is not finite; ATT_ERR_KIND for a kind without heading
 *   att_<name>_set_gain   a gain set in settings (state not touched): false when the kind has no
 *                         such gain
 *   att_<name>_settings_check  att_<name>_settings_validate's verdict on settings (not NULL), and on
 *                         ATT_ERR_SETTINGS the first refused field in why (may be NULL; untouched
 *                         when accepted): both are written from the kind's one table of checks
 *                         (ATT_<NAME>_CHECKS, att_core.h); called only by att_filter_settings_check
 *   att_<name>_settings_rule  line index of that table for settings s in out (field NULL past the
 *                         last); ATT_OK when it holds, ATT_ERR_SETTINGS when not; called only by
 *                         att_filter_settings_rule
 */
#define ATT_KIND_HOOKS(NAME, name, num)                                                                    \
    void att_##name##_preset(att_##name##_settings_t *s, att_preset_t preset, float dt);                      \
    float att_##name##_period(const att_##name##_settings_t *s);                                              \
    uint32_t att_##name##_step_out(att_##name##_t *restrict f, const att_sample_t *restrict in,               \
                                   att_output_t *restrict out);                                               \
    void att_##name##_output(const att_##name##_t *f, att_output_t *out);                                     \
    att_heading_t att_##name##_heading_kind(const att_##name##_t *f);                                         \
    att_status_t att_##name##_yaw_to(att_##name##_t *f, float target, float gain);                            \
    bool att_##name##_set_gain(att_##name##_settings_t *s, att_gain_t gain, float value);                      \
    att_status_t att_##name##_settings_check(const att_##name##_settings_t *s, att_settings_error_t *why);    \
    att_status_t att_##name##_settings_rule(const att_##name##_settings_t *s, uint32_t index,                \
                                            att_settings_error_t *out);

ATT_KINDS_ALL(ATT_KIND_HOOKS)

/** The period of settings of kind (s; 0 for kinds without one or not compiled in). */
float att_filter_settings_period(att_filter_kind_t kind, const att_filter_settings_t *settings);
/** A gain of the kind's settings set to value (att_<kind>_set_gain); false when it has no such gain. */
bool att_filter_settings_gain(att_filter_kind_t kind, att_filter_settings_t *settings, att_gain_t gain,
                              float value);
/** The kind is compiled in (att_config.h). */
bool att_filter_kind_enabled(att_filter_kind_t kind);

#endif /* ATT_KINDS_H */
