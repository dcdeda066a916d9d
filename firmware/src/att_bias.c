/**
 * @file att_bias.c
 * @brief Rest detector and capped running-mean gyro bias (see att_bias.h). Mirrored by reference/bias.py.
 */
#include "att_fp.h"

#include "attica/att_bias.h"
#include "attica/att_math.h"

uint32_t att_bias_step(const att_bias_params_t *p, att_vec3_t *bias, uint32_t *n, uint32_t *rest_count,
                       att_vec3_t gyr, bool gyro_ok, bool accel_ok, float norm)
{
    uint32_t flags = 0u;
    bool rest;
    float nf;
    float den;
    if (p == NULL || bias == NULL || n == NULL || rest_count == NULL) {
        return 0u;
    }
    rest = gyro_ok && accel_ok && att_vec3_norm(att_vec3_sub(gyr, *bias)) < p->rest_gyro &&
           att_absf(norm - p->gravity) < p->rest_accel;
    if (!rest) {
        *rest_count = 0u;
    } else if (*rest_count < p->rest_n) {
        *rest_count = *rest_count + 1u;
    }
    if (rest && *rest_count >= p->rest_n) {
        flags |= ATT_FLAG_AT_REST;
    }
    if (gyro_ok && (p->mode == ATT_BIAS_RUNNING || (p->mode == ATT_BIAS_AT_REST && (flags & ATT_FLAG_AT_REST) != 0u))) {
        nf = (float)*n; /* exact: n <= 2^24 */
        den = nf + 1.0f;
        bias->x = (nf * bias->x + gyr.x) / den;
        bias->y = (nf * bias->y + gyr.y) / den;
        bias->z = (nf * bias->z + gyr.z) / den;
        if (*n < p->n_max) {
            *n = *n + 1u;
        }
        flags |= ATT_FLAG_BIAS_UPDATED;
    }
    return flags;
}
