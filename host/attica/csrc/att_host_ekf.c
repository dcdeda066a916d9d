/**
 * @file att_host_ekf.c
 * @brief Host-only batch kernel for the Euler EKF (see att_host_ekf.h).
 */
#include "att_host_ekf.h"

size_t att_host_ekf_run(att_ekf_t *f, size_t m, const float *gyr, const float *acc, size_t steps,
                        float *euler, float *bias, float *cov, uint32_t *flags)
{
    size_t k;
    size_t i;
    size_t r;
    size_t a;
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
                euler[3u * r] = f[i].st.euler.x;
                euler[3u * r + 1u] = f[i].st.euler.y;
                euler[3u * r + 2u] = f[i].st.euler.z;
            }
            if (bias != NULL) {
                bias[3u * r] = f[i].st.bias.x;
                bias[3u * r + 1u] = f[i].st.bias.y;
                bias[3u * r + 2u] = f[i].st.bias.z;
            }
            if (cov != NULL) {
                for (a = 0u; a < 21u; a++) {
                    cov[21u * r + a] = f[i].st.p[a];
                }
            }
        }
    }
    return steps * m;
}
