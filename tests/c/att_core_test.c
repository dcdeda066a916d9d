/**
 * @file att_core_test.c
 * @brief Checks of the private fast paths of firmware/src (att_inline.h, att_core.h) against their
 * general twins: the bounds they rely on, tested at and around the boundary.
 *
 * Usage: att_core_test [STRIDE]   (every STRIDE-th float of the ranges below; 1 = every float)
 *
 * - att_i_sincosf for |x| <= ATT_SMALL_ANGLE_MAX skips the range reduction: its results must equal
 *   att_sincosf_reduced bit for bit (every STRIDE-th float of [0, 0.75] and both signs, plus every
 *   float within 2^16 ulps below the bound).
 * - att_i_quat_from_rotvec_fast (series for |rv|^2 <= 1/16) agrees with att_quat_from_rotvec within
 *   2 ulps per component (random and boundary rotation vectors), and equals it bit for bit above the
 *   bound (the general path).
 * - att_i_align_up gives a unit quaternion that rotates v onto +z: within 4e-7 rad plus the
 *   cancellation of |v| + v_z near "upside down" (2^-22 |v| / (|v| + v_z)), and the fallback half turn
 *   for the last 2^-19.
 * Prints one line per check; exit status 0 when all pass. Test harness: C99 + stdio.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "att_core.h"
#include "attica/att_math.h"

static uint32_t bits(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
}

static float from_bits(uint32_t u)
{
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

static int ulps(float a, float b)
{
    const int32_t ia = (int32_t)bits(a);
    const int32_t ib = (int32_t)bits(b);
    int32_t d;
    if ((ia < 0) != (ib < 0)) {
        return (a == b) ? 0 : 1000000; /* +0 vs -0 are equal */
    }
    d = ia - ib;
    return d < 0 ? -d : d;
}

static uint32_t lcg_state = 20261201u;

static float uniform(void) /* [-1, 1) */
{
    lcg_state = lcg_state * 1664525u + 1013904223u;
    return (float)(lcg_state >> 8) * 0x1p-23f - 1.0f;
}

static int check_sincos(uint32_t stride)
{
    const uint32_t top = bits(ATT_SMALL_ANGLE_MAX);
    unsigned long checked = 0ul;
    unsigned long bad = 0ul;
    uint32_t u;
    int sign;
    for (sign = 0; sign < 2; sign++) {
        for (u = 0u; u <= top; u += (u + 65536u > top) ? 1u : stride) {
            const float x = sign ? -from_bits(u) : from_bits(u);
            float s1;
            float c1;
            float s2;
            float c2;
            att_i_sincosf(x, &s1, &c1);
            att_sincosf_reduced(x, &s2, &c2);
            checked++;
            if (bits(s1) != bits(s2) || bits(c1) != bits(c2)) {
                if (bad < 5ul) {
                    printf("  sincos differs at %a: %a %a vs %a %a\n", (double)x, (double)s1, (double)c1,
                           (double)s2, (double)c2);
                }
                bad++;
            }
        }
    }
    printf("sincos small == reduced: %lu arguments with |x| <= %a, %lu differ\n", checked,
           (double)ATT_SMALL_ANGLE_MAX, bad);
    return bad == 0ul;
}

static int check_rotvec(void)
{
    unsigned long i;
    unsigned long bad = 0ul;
    int worst = 0;
    const float bound = att_sqrtf(ATT_ROTVEC_Z_SMALL);
    for (i = 0ul; i < 2000000ul; i++) {
        att_vec3_t rv;
        att_quat_t a;
        att_quat_t b;
        float scale;
        int d;
        /* half the vectors near the bound |rv| = 0.25, the others spread over [0, 0.3] */
        scale = (i % 2ul == 0ul) ? bound * (1.0f + 0.01f * uniform()) : 0.3f * (0.5f + 0.5f * uniform());
        rv = att_i_vec3(uniform(), uniform(), uniform());
        if (!att_vec3_normalize(rv, &rv)) {
            continue;
        }
        rv = att_vec3_scale(rv, scale * ((i % 7ul == 0ul) ? 1e-3f : 1.0f));
        a = att_i_quat_from_rotvec_fast(rv);
        b = att_quat_from_rotvec(rv);
        if (att_vec3_dot(rv, rv) > ATT_ROTVEC_Z_SMALL) {
            if (bits(a.w) != bits(b.w) || bits(a.x) != bits(b.x) || bits(a.y) != bits(b.y) || bits(a.z) != bits(b.z)) {
                bad++;
            }
            continue;
        }
        d = ulps(a.w, b.w);
        d = ulps(a.x, b.x) > d ? ulps(a.x, b.x) : d;
        d = ulps(a.y, b.y) > d ? ulps(a.y, b.y) : d;
        d = ulps(a.z, b.z) > d ? ulps(a.z, b.z) : d;
        worst = d > worst ? d : worst;
        if (d > 2) {
            bad++;
        }
    }
    printf("rotvec fast vs exact: worst %d ulp below the bound, %lu failures\n", worst, bad);
    return bad == 0ul;
}

static int check_align(void)
{
    unsigned long i;
    unsigned long bad = 0ul;
    float worst = 0.0f;
    for (i = 0ul; i < 1000000ul; i++) {
        att_vec3_t v = att_i_vec3(uniform(), uniform(), uniform());
        float qw;
        float qx;
        float qy;
        float n;
        att_quat_t q;
        att_vec3_t r;
        float err;
        if (i % 5ul == 0ul) {
            v.z = -1.0f; /* near upside down, down to the fallback */
            v.x = v.x * 1e-3f;
            v.y = v.y * 1e-3f;
        }
        v = att_vec3_scale(v, 9.8f);
        if (!att_i_align_up(v, &qw, &qx, &qy, &n)) {
            bad++;
            continue;
        }
        q = att_i_quat(qw, qx, qy, 0.0f);
        r = att_quat_rotate(q, att_vec3_scale(v, 1.0f / n));
        err = att_atan2f(att_sqrtf(r.x * r.x + r.y * r.y), r.z);
        if (qw > 0.0f) {
            /* a = |v| + v_z cancels toward "upside down": the error grows like 2^-22 |v| / a */
            const float tol = 4e-7f + 0x1p-22f * (n / (n + v.z));
            worst = err > worst ? err : worst;
            if (!(err < tol) || !(att_absf(qw * qw + qx * qx + qy * qy - 1.0f) < tol)) {
                if (bad < 3ul) {
                    printf("  align v = (%a, %a, %a): residual %a rad (tolerance %a), |q|^2 - 1 = %a\n", (double)v.x,
                           (double)v.y, (double)v.z, (double)err, (double)tol,
                           (double)(qw * qw + qx * qx + qy * qy - 1.0f));
                }
                bad++;
            }
        } else if (!(err < 4e-3f)) { /* the fallback is a half turn about x: exact only for v = -z */
            bad++;
        }
    }
    printf("align up: worst residual angle %a rad, %lu failures\n", (double)worst, bad);
    return bad == 0ul;
}

int main(int argc, char **argv)
{
    uint32_t stride = 1u;
    int ok = 1;
    if (argc > 1) {
        stride = (uint32_t)strtoul(argv[1], NULL, 10);
        if (stride == 0u) {
            stride = 1u;
        }
    }
    ok &= check_sincos(stride);
    ok &= check_rotvec();
    ok &= check_align();
    printf("%s\n", ok ? "PASS" : "FAIL");
    return ok ? 0 : 1;
}
