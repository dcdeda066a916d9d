/**
 * @file att_bias.c
 * @brief Rest detector and capped running-mean gyro bias (see att_bias.h). Mirrored by reference/bias.py.
 */
#include "../math/att_fp.h"

#include "att_core.h"
#include "attica/att_bias.h"
#include "attica/att_sensor.h"

void att_bias_params_set(att_bias_params_t *p, att_bias_mode_t mode, uint32_t n_max, float rest_gyro,
                         float rest_accel, float rest_time, float gravity, float dt)
{
    if (p == NULL) {
        return;
    }
    att_i_bias_params(p, mode, n_max, rest_gyro, rest_accel, att_sensor_samples(rest_time, dt), gravity);
}

uint32_t att_bias_step(const att_bias_params_t *p, att_vec3_t *bias, uint32_t *n, uint32_t *rest_count,
                       att_vec3_t gyr, bool gyro_ok, bool accel_ok, float acc_norm2)
{
    att_vec3_t d;
    float gate2;
    if (p == NULL || bias == NULL || n == NULL || rest_count == NULL) {
        return 0u;
    }
    gate2 = att_i_bias_gate(p, *n);
    return att_i_bias_step(p, bias, n, rest_count, &gate2, gyr, gyro_ok, accel_ok, acc_norm2, &d);
}
