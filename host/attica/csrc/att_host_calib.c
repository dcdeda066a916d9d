/**
 * @file att_host_calib.c
 * @brief Host-only batch kernels of the input/output stages (see att_host_calib.h).
 */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

#include "att_host_calib.h"

#include <string.h>

static att_vec3_t att_host_calib_v3(const float *p)
{
    att_vec3_t v;
    v.x = p[0];
    v.y = p[1];
    v.z = p[2];
    return v;
}

static void att_host_calib_put(float *p, att_vec3_t v)
{
    p[0] = v.x;
    p[1] = v.y;
    p[2] = v.z;
}

void att_host_calib_apply(const att_calib_t *c, float *gyr, float *acc, float *mag, size_t n)
{
    size_t i;
    if (c == NULL || gyr == NULL || acc == NULL || mag == NULL) {
        return;
    }
    for (i = 0u; i < n; i++) {
        att_vec3_t g = att_host_calib_v3(gyr + 3u * i);
        att_vec3_t a = att_host_calib_v3(acc + 3u * i);
        att_vec3_t m = att_host_calib_v3(mag + 3u * i);
        att_calib_apply(c, &g, &a, &m);
        att_host_calib_put(gyr + 3u * i, g);
        att_host_calib_put(acc + 3u * i, a);
        att_host_calib_put(mag + 3u * i, m);
    }
}

size_t att_host_filter_run_accel(att_filter_t *f, const float *gyr, const float *acc, const float *mag, size_t n,
                                 att_output_t *out, float *accel)
{
    size_t i;
    if (f == NULL || gyr == NULL || acc == NULL || out == NULL || accel == NULL) {
        return 0u;
    }
    for (i = 0u; i < n; i++) {
        att_sample_t s;
        att_accel_t a;
        s.gyr = att_host_calib_v3(gyr + 3u * i);
        s.acc = att_host_calib_v3(acc + 3u * i);
        s.mag = (mag != NULL) ? att_host_calib_v3(mag + 3u * i) : att_host_calib_v3((const float[3]){0.0f, 0.0f, 0.0f});
        (void)att_filter_step(f, &s, NULL);
        att_filter_output(f, &out[i]);
        att_filter_accel(f, &a);
        att_host_calib_put(accel + 10u * i, a.gravity);
        att_host_calib_put(accel + 10u * i + 3u, a.linear);
        att_host_calib_put(accel + 10u * i + 6u, a.earth);
        memcpy(accel + 10u * i + 9u, &a.valid, sizeof a.valid);
    }
    return n;
}
