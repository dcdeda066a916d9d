/**
 * @file att_ekf_checks.h
 * @brief Private: the settings contract of ekf as one table, read by att_ekf_settings_validate
 * (att_ekf.c) and att_ekf_settings_check (att_ekf_check.c); the forms of its lines: att_core.h.
 */
#ifndef ATT_EKF_CHECKS_H
#define ATT_EKF_CHECKS_H

#include "../../core/att_core.h"
#include "attica/att_ekf.h"

#define ATT_EKF_PIO2_F 0x1.921fb6p+0f
#define ATT_EKF_NOISE_MIN 0x1.79ca10p-67f /* 1e-20 */
#define ATT_EKF_VAR_MAX 1000000.0f           /* upper limit of every variance setting */
#define ATT_EKF_PMAX_MIN 0.000001f           /* lower limit of p_max and p0 */

static inline bool att_ekf_noise_ok(float v)
{
    return att_i_in(v, ATT_EKF_NOISE_MIN, ATT_EKF_VAR_MAX);
}

/*
 * The settings contract (att_ekf.h), in the order of the tests: att_ekf_settings_validate accepts
 * exactly the settings that pass every line, att_ekf_settings_check names the first line that fails
 * (att_core.h: ATT_CHECK_AND, ATT_CHECK_WHY). With noise_rates the per-step noises (q_* dt, r_* / dt)
 * are not checked: over these ranges they lie in [1e-26, 1e6] and [1e-20, 1e12], normal floats, and
 * the step is safe with them (docs/filters.md, tests/test_ekf.py).
 */
#define ATT_EKF_NOISE(C, f) C(#f, att_ekf_noise_ok(s->f), ATT_EKF_NOISE_MIN, ATT_EKF_VAR_MAX, "[1e-20, 1e6]", "")
#define ATT_EKF_CHECKS(C)                                                                                     \
    ATT_CK_IN(C, dt, ATT_DT_MIN, ATT_DT_MAX, "[1e-6, 1]", "s")                                                 \
    ATT_EKF_NOISE(C, q_phi)                                                                                    \
    ATT_EKF_NOISE(C, q_theta)                                                                                  \
    ATT_EKF_NOISE(C, q_psi)                                                                                    \
    ATT_EKF_NOISE(C, q_bias)                                                                                   \
    ATT_EKF_NOISE(C, r_phi)                                                                                    \
    ATT_EKF_NOISE(C, r_theta)                                                                                  \
    ATT_CK_IN(C, r_accel, 0.0f, ATT_GAIN_C_MAX, "[0, 1e6]", "")                                                \
    ATT_CK_IN(C, gate, 0.0f, ATT_GAIN_C_MAX, "[0, 1e6]", "")                                                   \
    ATT_CK_IN(C, p_max, ATT_EKF_PMAX_MIN, ATT_EKF_VAR_MAX, "[1e-6, 1e6]", "rad^2")                             \
    ATT_CK_IN(C, p0, ATT_EKF_PMAX_MIN, s->p_max, "[1e-6, p_max]", "rad^2")                                     \
    ATT_CK_IN(C, p0_bias, ATT_EKF_NOISE_MIN, s->p_max, "[1e-20, p_max]", "(rad/s)^2")                          \
    ATT_CK_INERTIAL(C)                                                                                    \
    ATT_CK_OO(C, cos_min, 0.0f, 1.0f, "(0, 1)", "")                                                            \
    ATT_CK_IN(C, tau_acc_lp, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                               \
    ATT_CK_BOOL(C, init_from_accel)                                                                            \
    ATT_CK_BOOL(C, noise_rates)                                                                                \
    ATT_CK_IN(C, euler_init.y, -ATT_EKF_PIO2_F, ATT_EKF_PIO2_F, "[-pi/2, pi/2]", "rad")                        \
    ATT_CK_IN(C, euler_init.x, -8192.0f, 8192.0f, "[-8192, 8192]", "rad")                                      \
    ATT_CK_IN(C, euler_init.z, -8192.0f, 8192.0f, "[-8192, 8192]", "rad")                                      \
    ATT_CK_VEC(C, bias_init, s->gyro_range, "each component in [-gyro_range, gyro_range]", "rad/s")      \
    ATT_CK_IN(C, recovery_time, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")

#endif /* ATT_EKF_CHECKS_H */
