/**
 * @file att_gyro_checks.h
 * @brief Private: the settings contract of gyro as one table, read by att_gyro_settings_validate
 * (att_gyro.c) and att_gyro_settings_check (att_gyro_check.c); the forms of its lines: att_core.h.
 */
#ifndef ATT_GYRO_CHECKS_H
#define ATT_GYRO_CHECKS_H

#include "../../core/att_core.h"
#include "attica/att_gyro.h"

#define ATT_PIO2_F 0x1.921fb6p+0f

/*
 * The settings contract (att_gyro.h), in the order of the tests: att_gyro_settings_validate accepts
 * exactly the settings that pass every line, att_gyro_settings_check names the first line that fails
 * (att_core.h: ATT_CHECK_AND, ATT_CHECK_WHY).
 */
#define ATT_GYRO_CHECKS(C)                                                                                    \
    ATT_CK_IN(C, dt, ATT_DT_MIN, ATT_DT_MAX, "[1e-6, 1]", "s")                                                 \
    ATT_CK_OC(C, gyro_range, 0.0f, ATT_GYRO_RANGE_MAX, "(0, 1e3]", "rad/s")                                    \
    ATT_CK_OO(C, cos_min, 0.0f, 1.0f, "(0, 1)", "")                                                            \
    ATT_CK_IN(C, euler_init.y, -ATT_PIO2_F, ATT_PIO2_F, "[-pi/2, pi/2]", "rad")                                \
    ATT_CK_IN(C, euler_init.x, -8192.0f, 8192.0f, "[-8192, 8192]", "rad")                                      \
    ATT_CK_IN(C, euler_init.z, -8192.0f, 8192.0f, "[-8192, 8192]", "rad")

#endif /* ATT_GYRO_CHECKS_H */
