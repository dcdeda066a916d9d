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
    ATT_CK_INERTIAL(C)                                                                                    \
    ATT_CK_BIAS(C)                                                                                             \
    C("integration", s->integration == ATT_INTEGRATE_ROTVEC || s->integration == ATT_INTEGRATE_EULER, 0.0f,    \
      1.0f, "ROTVEC (0) or EULER (1)", "")                                                                     \
    ATT_CK_BOOL(C, init_from_accel)                                                                            \
    ATT_CK_QUAT(C, q_init)                                                                                     \
    ATT_CK_IN(C, tau_acc_lp, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                             \
    ATT_CK_IN(C, recovery_time, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                          \
    ATT_CK_IN(C, gyro_noise, 0.0f, 1.0f, "[0, 1]", "rad/s/sqrt(Hz)")                                        \
    ATT_CK_IN(C, accel_noise, 0.0f, 1000.0f, "[0, 1e3]", "m/s^2/sqrt(Hz)")

#endif /* ATT_ARS_CHECKS_H */
