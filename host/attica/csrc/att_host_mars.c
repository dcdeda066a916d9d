/**
 * @file att_host_mars.c
 * @brief Host-only batch kernel for the 9-axis complementary filter (see att_host_mars.h).
 */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif

#include "att_host_mars.h"

#include "attica/att_math.h"

static att_vec3_t att_host_mars_v3(const float *p)
{
    att_vec3_t v;
    v.x = p[0];
    v.y = p[1];
    v.z = p[2];
    return v;
}

size_t att_host_mars_run(att_mars_t *f, const float *gyr, const float *acc, const float *mag, size_t n,
                         float *quat, float *m0, uint32_t *flags)
{
    size_t i;
    att_vec3_t m;
    if (f == NULL || gyr == NULL || acc == NULL || quat == NULL || flags == NULL) {
        return 0u;
    }
    m.x = 0.0f;
    m.y = 0.0f;
    m.z = 0.0f;
    for (i = 0; i < n; i++) {
        if (mag != NULL) {
            m = att_host_mars_v3(mag + 3u * i);
        }
        flags[i] = att_mars_step(f, att_host_mars_v3(gyr + 3u * i), att_host_mars_v3(acc + 3u * i), m);
        quat[4u * i] = f->st.q.w;
        quat[4u * i + 1u] = f->st.q.x;
        quat[4u * i + 2u] = f->st.q.y;
        quat[4u * i + 3u] = f->st.q.z;
        if (m0 != NULL) {
            m0[3u * i] = f->st.m0.x;
            m0[3u * i + 1u] = f->st.m0.y;
            m0[3u * i + 2u] = f->st.m0.z;
        }
    }
    return n;
}
