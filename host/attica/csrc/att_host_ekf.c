/**
 * @file att_host_ekf.c
 * @brief Host-only batch kernel for the Euler EKF (see att_host_ekf.h).
 */
#include "att_host_ekf.h"

size_t att_host_ekf_run(att_ekf_t *f, size_t m, const float *gyr, const float *acc, size_t steps,
                        float *euler, float *quat, float *cov, uint32_t *flags)
{
    size_t k;
    size_t i;
    size_t r;
    size_t a;
    size_t b;
    att_vec3_t g;
    att_vec3_t s;
    uint32_t fl;
    if (f == NULL || gyr == NULL || acc == NULL) {
        return 0u;
    }
    for (k = 0u; k < steps; k++) {
        for (i = 0u; i < m; i++) {
            r = k * m + i;
            g.x = gyr[3u * r];
            g.y = gyr[3u * r + 1u];
            g.z = gyr[3u * r + 2u];
            s.x = acc[3u * r];
            s.y = acc[3u * r + 1u];
            s.z = acc[3u * r + 2u];
            fl = att_ekf_step(&f[i], g, s);
            if (flags != NULL) {
                flags[r] = fl;
            }
            if (euler != NULL) {
                euler[3u * r] = f[i].euler.x;
                euler[3u * r + 1u] = f[i].euler.y;
                euler[3u * r + 2u] = f[i].euler.z;
            }
            if (quat != NULL) {
                quat[4u * r] = f[i].q.w;
                quat[4u * r + 1u] = f[i].q.x;
                quat[4u * r + 2u] = f[i].q.y;
                quat[4u * r + 3u] = f[i].q.z;
            }
            if (cov != NULL) {
                for (a = 0u; a < 3u; a++) {
                    for (b = 0u; b < 3u; b++) {
                        cov[9u * r + 3u * a + b] = f[i].p[a][b];
                    }
                }
            }
        }
    }
    return steps * m;
}
