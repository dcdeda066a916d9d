/**
 * @file att_host_kf.c
 * @brief Host-only batch kernel for the linear quaternion KF (see att_host_kf.h).
 */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

#include "att_host_kf.h"

size_t att_host_kf_run(att_kf_t *f, size_t m, const float *gyr, const float *acc, size_t steps, float *quat,
                       float *p, uint32_t *flags)
{
    size_t t;
    size_t j;
    if (f == NULL || gyr == NULL || acc == NULL || quat == NULL || flags == NULL) {
        return 0u;
    }
    for (t = 0; t < steps; t++) {
        for (j = 0; j < m; j++) {
            const size_t k = t * m + j;
            att_kf_t *fj = f + j;
            att_vec3_t g;
            att_vec3_t a;
            g.x = gyr[3u * k];
            g.y = gyr[3u * k + 1u];
            g.z = gyr[3u * k + 2u];
            a.x = acc[3u * k];
            a.y = acc[3u * k + 1u];
            a.z = acc[3u * k + 2u];
            flags[k] = att_kf_step(fj, g, a);
            quat[4u * k] = fj->st.q.w;
            quat[4u * k + 1u] = fj->st.q.x;
            quat[4u * k + 2u] = fj->st.q.y;
            quat[4u * k + 3u] = fj->st.q.z;
            if (p != NULL) {
                p[k] = fj->st.p;
            }
        }
    }
    return steps * m;
}
