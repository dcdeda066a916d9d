/**
 * @file att_mekf_checks.h
 * @brief Private: the settings contract of mekf as one table, read by att_mekf_settings_validate
 * (att_mekf.c) and att_mekf_settings_check (att_mekf_check.c); the forms of its lines: att_core.h.
 */
#ifndef ATT_MEKF_CHECKS_H
#define ATT_MEKF_CHECKS_H

#include "../../core/att_core.h"
#include "attica/att_mekf.h"

#define ATT_MEKF_PI_F 0x1.921fb6p+1f
#define ATT_MEKF_M0_MIN 0x1.0624dep-10f     /* 1e-3 uT: smallest |m0_init| */
#define ATT_MEKF_GYRO_NOISE_MIN 0x1.ad7f2ap-24f /* 1e-7 rad/s/sqrt(Hz) */
#define ATT_MEKF_BIAS_NOISE_MIN 0x1.12e0bep-30f /* 1e-9 rad/s/sqrt(s) */
#define ATT_MEKF_DENSITY_MIN 0x1.0c6f7ap-20f    /* 1e-6 rad sqrt(s) */
#define ATT_MEKF_DENSITY_MAX 1000.0f
#define ATT_MEKF_VAR_MIN 0x1.19799800p-40f      /* 1e-12 */
#define ATT_MEKF_PMAX_MIN 0x1.0c6f7ap-20f       /* 1e-6 rad^2 */
#define ATT_MEKF_PMAX_MAX 1000.0f
#define ATT_MEKF_PBIAS_MAX 100.0f

static inline bool att_mekf_vec3_is_zero(att_vec3_t v)
{
    return v.x == 0.0f && v.y == 0.0f && v.z == 0.0f;
}

/*
 * The settings contract (att_mekf.h), in the order of the tests: att_mekf_settings_validate accepts
 * exactly the settings that pass every line, att_mekf_settings_check names the first line that fails
 * (att_core.h: ATT_CHECK_AND, ATT_CHECK_WHY). m0_init: zero, or its norm (as the mag sample check
 * measures one) within [1e-3, mag_range].
 */
#define ATT_MEKF_CHECKS(C)                                                                                    \
    ATT_CK_IN(C, dt, ATT_DT_MIN, ATT_DT_MAX, "[1e-6, 1]", "s")                                                 \
    ATT_CK_IN(C, gyro_noise, ATT_MEKF_GYRO_NOISE_MIN, 1.0f, "[1e-7, 1]", "rad/s/sqrt(Hz)")                     \
    ATT_CK_IN(C, gyro_rate_noise, 0.0f, 1.0f, "[0, 1]", "sqrt(s)")                                             \
    ATT_CK_IN(C, bias_noise, ATT_MEKF_BIAS_NOISE_MIN, 1.0f, "[1e-9, 1]", "rad/s/sqrt(s)")                      \
    ATT_CK_IN(C, accel_noise, ATT_MEKF_DENSITY_MIN, ATT_MEKF_DENSITY_MAX, "[1e-6, 1e3]", "rad sqrt(s)")        \
    ATT_CK_IN(C, r_accel, 0.0f, ATT_GAIN_C_MAX, "[0, 1e6]", "")                                                \
    ATT_CK_IN(C, gate, 0.0f, ATT_GAIN_C_MAX, "[0, 1e6]", "")                                                   \
    ATT_CK_IN(C, gate_recover, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                             \
    ATT_CK_IN(C, mag_noise, ATT_MEKF_DENSITY_MIN, ATT_MEKF_DENSITY_MAX, "[1e-6, 1e3]", "rad sqrt(s)")          \
    ATT_CK_IN(C, mag_gate, 0.0f, ATT_GAIN_C_MAX, "[0, 1e6]", "")                                               \
    ATT_CK_IN(C, p_max, ATT_MEKF_PMAX_MIN, ATT_MEKF_PMAX_MAX, "[1e-6, 1000]", "rad^2")                         \
    ATT_CK_IN(C, p0_att, ATT_MEKF_VAR_MIN, s->p_max, "[1e-12, p_max]", "rad^2")                                \
    ATT_CK_IN(C, p0_bias, ATT_MEKF_VAR_MIN, ATT_MEKF_PBIAS_MAX, "[1e-12, 100]", "(rad/s)^2")                   \
    ATT_CK_INERTIAL(C)                                                                                    \
    ATT_CK_MAG(C, ATT_MEKF_PI_F)                                                                           \
    ATT_CK_IN(C, tau_acc_lp, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                               \
    ATT_CK_IN(C, tau_acc_lp_no_rest, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                       \
    ATT_CK_IN(C, rest_noise, ATT_MEKF_GYRO_NOISE_MIN, 1.0f, "[1e-7, 1]", "rad/s/sqrt(Hz)")                     \
    ATT_CK_IN(C, rest_gyro, 0.0f, s->gyro_range, "[0, gyro_range]", "rad/s")                                   \
    ATT_CK_IN(C, rest_accel, 0.0f, s->gravity, "[0, gravity]", "m/s^2")                                        \
    ATT_CK_IN(C, rest_time, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                                \
    ATT_CK_IN(C, gyro_scale_sd, 0.0f, ATT_MEKF_SCALE_MAX, "[0, 0.1]", "")                                      \
    ATT_CK_IN(C, gyro_scale_init, -ATT_MEKF_SCALE_MAX, ATT_MEKF_SCALE_MAX, "[-0.1, 0.1]", "")                  \
    ATT_CK_IN(C, recovery_time, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                            \
    ATT_CK_IN(C, declination, -ATT_MEKF_PI_F, ATT_MEKF_PI_F, "[-pi, pi]", "rad")                               \
    ATT_CK_IN(C, mag_ref_tau, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                              \
    ATT_CK_IN(C, mag_new_time, 0.0f, ATT_TAU_MAX, "[0, 1e4]", "s")                                             \
    ATT_CK_IN(C, hard_iron_tau, 0.0f, ATT_HI_TAU_MAX, ATT_HI_TAU_RULE, "s")                                            \
    ATT_CK_IN(C, hard_iron_rate, 1e-3f, 1000.0f, "[1e-3, 1e3]", "uT/s")                                        \
    ATT_CK_BOOL(C, use_mag)                                                                                    \
    ATT_CK_BOOL(C, init_from_sensors)                                                                          \
    ATT_CK_QUAT(C, q_init)                                                                                     \
    ATT_CK_NORM0(C, m0_init, ATT_MEKF_M0_MIN, s->mag_range, "zero, or |m0_init| in [1e-3, mag_range]",         \
                 "uT")                                                                                         \
    ATT_CK_VEC(C, bias_init, s->gyro_range, "each component in [-gyro_range, gyro_range]", "rad/s")

#endif /* ATT_MEKF_CHECKS_H */
