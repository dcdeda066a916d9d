/**
 * @file att_tilt_checks.h
 * @brief Private: the settings contract of tilt as one table, read by att_tilt_settings_validate
 * (att_tilt.c) and att_tilt_settings_check (att_tilt_check.c); the forms of its lines: att_core.h.
 */
#ifndef ATT_TILT_CHECKS_H
#define ATT_TILT_CHECKS_H

#include "../../core/att_core.h"
#include "attica/att_tilt.h"

/*
 * The settings contract (att_tilt.h), in the order of the tests: att_tilt_settings_validate accepts
 * exactly the settings that pass every line, att_tilt_settings_check names the first line that fails
 * (att_core.h: ATT_CHECK_AND, ATT_CHECK_WHY).
 */
#define ATT_TILT_CHECKS(C)                                                                                    \
    ATT_CK_IN(C, gravity, ATT_GRAVITY_MIN, ATT_GRAVITY_MAX, "[1, 100]", "m/s^2")                               \
    ATT_CK_OC(C, accel_range, s->gravity, ATT_ACCEL_RANGE_MAX, "(gravity, 1e4]", "m/s^2")                      \
    ATT_CK_BOOL(C, normalise)

#endif /* ATT_TILT_CHECKS_H */
