/**
 * @file att_mars_checks.h
 * @brief Private: the settings contract of mars as one table, read by att_mars_settings_validate
 * (att_mars.c) and att_mars_settings_check (att_mars_check.c); the forms of its lines: att_core.h.
 */
#ifndef ATT_MARS_CHECKS_H
#define ATT_MARS_CHECKS_H

#include "../../core/att_core.h"
#include "attica/att_mars.h"

#define ATT_MARS_PI_F 0x1.921fb6p+1f
#define ATT_MARS_M0_MIN 0x1.0624dep-10f /* 1e-3 uT: smallest |m0_init| */

static inline bool att_mars_vec3_is_zero(att_vec3_t v)
{
    return v.x == 0.0f && v.y == 0.0f && v.z == 0.0f;
}

/*
 * The settings contract (att_mars.h), in the order of the tests: att_mars_settings_validate accepts
 * exactly the settings that pass every line, att_mars_settings_check names the first line that fails
 * (att_core.h: ATT_CHECK_AND, ATT_CHECK_WHY). alpha_acc / alpha_mag are checked even when tau_acc /
 * tau_mag > 0 makes them unused. m0_init: zero, or its norm (as the mag sample check measures one)
 * within [1e-3, mag_range].
 */
#define ATT_MARS_CHECKS(C)                                                                                    \
    ATT_CK_IN(C, dt, ATT_DT_MIN, ATT_DT_MAX, "[1e-6, 1]", "s")                                                 \
    ATT_CK_IN(C, alpha_acc, 0.0f, 1.0f, "[0, 1]", "")                                                          \
    ATT_CK_IN(C, alpha_mag, 0.0f, 1.0f, "[0, 1]", "")                                                          \
    ATT_CK_IN(C, tau_acc, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                                  \
    ATT_CK_IN(C, tau_mag, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                                  \
    C("mag_mode", s->mag_mode == ATT_MARS_MAG_HORIZONTAL || s->mag_mode == ATT_MARS_MAG_FULL, 0.0f, 1.0f,      \
      "HORIZONTAL (0) or FULL (1)", "")                                                                        \
    ATT_CK_INERTIAL(C)                                                                                    \
    ATT_CK_MAG(C, ATT_MARS_PI_F)                                                                           \
    ATT_CK_BIAS(C)                                                                                             \
    ATT_CK_BOOL(C, init_from_sensors)                                                                          \
    ATT_CK_QUAT(C, q_init)                                                                                     \
    ATT_CK_NORM0(C, m0_init, ATT_MARS_M0_MIN, s->mag_range, "zero, or |m0_init| in [1e-3, mag_range]",         \
                 "uT")                                                                                         \
    C("integration", s->integration == ATT_INTEGRATE_ROTVEC || s->integration == ATT_INTEGRATE_FIRST_ORDER,    \
      0.0f, 2.0f, "ROTVEC (0) or FIRST_ORDER (2)", "")                                                         \
    ATT_CK_IN(C, tau_acc_lp, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                          \
    ATT_CK_IN(C, mag_ref_tau, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                         \
    ATT_CK_IN(C, mag_new_time, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                        \
    ATT_CK_IN(C, tau_mag_fast, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                        \
    ATT_CK_IN(C, tau_bias_mag, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                        \
    ATT_CK_IN(C, recovery_time, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                       \
    ATT_CK_IN(C, declination, -ATT_MARS_PI_F, ATT_MARS_PI_F, "[-pi, pi]", "rad")                         \
    ATT_CK_IN(C, gyro_noise, 0.0f, 1.0f, "[0, 1]", "rad/s/sqrt(Hz)")                                        \
    ATT_CK_IN(C, accel_noise, 0.0f, 1000.0f, "[0, 1e3]", "m/s^2/sqrt(Hz)")                                  \
    ATT_CK_IN(C, mag_noise, 0.0f, 1000.0f, "[0, 1e3]", "uT/sqrt(Hz)")                                      \
    ATT_CK_IN(C, hard_iron_tau, 0.0f, ATT_HI_TAU_MAX, ATT_HI_TAU_RULE, "s")                                       \
    ATT_CK_IN(C, hard_iron_rate, 1e-3f, 1000.0f, "[1e-3, 1e3]", "uT/s")

#endif /* ATT_MARS_CHECKS_H */
