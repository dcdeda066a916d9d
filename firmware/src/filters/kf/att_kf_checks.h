/**
 * @file att_kf_checks.h
 * @brief Private: the settings contract of kf as one table, read by att_kf_settings_validate
 * (att_kf.c) and att_kf_settings_check (att_kf_check.c); the forms of its lines: att_core.h.
 */
#ifndef ATT_KF_CHECKS_H
#define ATT_KF_CHECKS_H

#include "../../core/att_core.h"
#include "attica/att_kf.h"

#define ATT_KF_NOISE_MIN 0x1.19799800p-40f /* 1e-12 */
#define ATT_KF_NOISE_MAX 1000000.0f

static inline bool att_kf_noise_valid(float v)
{
    return att_i_in(v, ATT_KF_NOISE_MIN, ATT_KF_NOISE_MAX);
}

/*
 * The settings contract (att_kf.h), in the order of the tests: att_kf_settings_validate accepts
 * exactly the settings that pass every line, att_kf_settings_check names the first line that fails
 * (att_core.h: ATT_CHECK_AND, ATT_CHECK_WHY). With noise_rates the per-step noises q_noise dt and
 * r_noise / dt are not checked: over these ranges they lie in [1e-18, 1e6] and [1e-12, 1e12], normal
 * floats, and the step is safe with them (docs/filters.md, tests/test_kf.py).
 */
#define ATT_KF_NOISE(C, f) C(#f, att_kf_noise_valid(s->f), ATT_KF_NOISE_MIN, ATT_KF_NOISE_MAX, "[1e-12, 1e6]", "")
#define ATT_KF_CHECKS(C)                                                                                      \
    ATT_CK_IN(C, dt, ATT_DT_MIN, ATT_DT_MAX, "[1e-6, 1]", "s")                                                 \
    ATT_KF_NOISE(C, q_noise)                                                                                   \
    ATT_KF_NOISE(C, r_noise)                                                                                   \
    ATT_CK_IN(C, r_accel, 0.0f, ATT_GAIN_C_MAX, "[0, 1e6]", "")                                                \
    ATT_CK_IN(C, gate, 0.0f, ATT_GAIN_C_MAX, "[0, 1e6]", "")                                                   \
    ATT_KF_NOISE(C, p0)                                                                                        \
    ATT_CK_INERTIAL(C)                                                                                    \
    ATT_CK_BIAS(C)                                                                                             \
    ATT_CK_IN(C, tau_acc_lp, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                               \
    ATT_CK_IN(C, recovery_time, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                            \
    ATT_CK_BOOL(C, init_from_accel)                                                                            \
    ATT_CK_BOOL(C, noise_rates)                                                                                \
    ATT_CK_QUAT(C, q_init)

#endif /* ATT_KF_CHECKS_H */
