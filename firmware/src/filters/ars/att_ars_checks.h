/**
 * @file att_ars_checks.h
 * @brief Private: the settings contract of ars as one table, read by att_ars_settings_validate
 * (att_ars.c) and att_ars_settings_check (att_ars_check.c); the forms of its lines: att_core.h.
 */
#ifndef ATT_ARS_CHECKS_H
#define ATT_ARS_CHECKS_H

#include "../../core/att_core.h"
#include "attica/att_ars.h"

/*
 * The settings contract (att_ars.h), in the order of the tests: att_ars_settings_validate accepts
 * exactly the settings that pass every line, att_ars_settings_check names the first line that fails
 * (att_core.h: ATT_CHECK_AND, ATT_CHECK_WHY). gain is checked even when tau > 0 makes it unused.
 */
#define ATT_ARS_CHECKS(C)                                                                                     \
    ATT_CK_IN(C, dt, ATT_DT_MIN, ATT_DT_MAX, "[1e-6, 1]", "s")                                                 \
    ATT_CK_IN(C, gain, 0.0f, 1.0f, "[0, 1]", "")                                                               \
    ATT_CK_IN(C, tau, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                                      \
    ATT_CK_IN(C, gain_c, 0.0f, ATT_GAIN_C_MAX, "[0, 1e6]", "")                                                 \
    ATT_CK_IN(C, gravity, ATT_GRAVITY_MIN, ATT_GRAVITY_MAX, "[1, 100]", "m/s^2")                               \
    ATT_CK_IN(C, accel_reject, 0.0f, ATT_REJECT_MAX, "[0, 1e3]", "")                                           \
    ATT_CK_OC(C, accel_range, s->gravity, ATT_ACCEL_RANGE_MAX, "(gravity, 1e4]", "m/s^2")                      \
    ATT_CK_OC(C, gyro_range, 0.0f, ATT_GYRO_RANGE_MAX, "(0, 1e3]", "rad/s")                                    \
    ATT_CK_BIAS(C)                                                                                             \
    C("integration", s->integration == ATT_INTEGRATE_ROTVEC || s->integration == ATT_INTEGRATE_EULER, 0.0f,    \
      1.0f, "ROTVEC (0) or EULER (1)", "")                                                                     \
    ATT_CK_BOOL(C, init_from_accel)                                                                            \
    ATT_CK_QUAT(C, q_init)                                                                                     \
    ATT_CK_IN(C, tau_acc_lp, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")

#endif /* ATT_ARS_CHECKS_H */
