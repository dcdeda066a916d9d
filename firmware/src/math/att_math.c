/**
 * @file att_math.c
 * @brief Deterministic float32 math (see att_math.h). Mirrored by host/attica/reference/detmath.py.
 *
 * Rules: + - * / and sqrtf only, hex-float constants, one fixed evaluation order (C evaluates
 * a + b + c as (a + b) + c, and so does the reference), no contraction into fused multiply-add.
 * Coefficients come from docs/tools/fit_trig.py. The small and hot functions are the inline twins
 * of att_inline.h (the same operations), which the filters use directly.
 */
#include "att_fp.h"

#include "att_inline.h"
#include "attica/att_math.h"

#include <math.h>

#define ATT_INV_TWO_PI 0x1.45f306p-3f
#define ATT_PI_HI 0x1.921fb6p+1f
#define ATT_PI_LO (-0x1.777a5cp-24f)
#define ATT_PIO2_HI 0x1.921fb6p+0f
#define ATT_PIO2_LO (-0x1.777a5cp-25f)
#define ATT_PIO4_HI 0x1.921fb6p-1f
#define ATT_PIO4_LO (-0x1.777a5cp-26f)
#define ATT_TWOPI_HI 0x1.921fb6p+2f
/* 2 pi = 4 (P1 + P2 + P3): the same exact split as pi/2, scaled by 4 */
#define ATT_TWOPI_P1 0x1.92p+2f
#define ATT_TWOPI_P2 0x1.fb4p-10f
#define ATT_TWOPI_P3 0x1.4442d2p-22f
#define ATT_TWOPI_LO (-0x1.777a5cp-23f)
#define ATT_TAN_PIO8 0x1.a8279ap-2f

/* atan(u) = u + u*z*(A0 + z*(A1 + z*(A2 + z*(A3 + z*A4)))), |u| <= tan(pi/8) */
#define ATT_ATAN_A0 (-0x1.55554p-2f)
#define ATT_ATAN_A1 0x1.998e68p-3f
#define ATT_ATAN_A2 (-0x1.2383p-3f)
#define ATT_ATAN_A3 0x1.af6706p-4f
#define ATT_ATAN_A4 (-0x1.e682b8p-5f)

float att_sqrtf(float x)
{
    return att_i_sqrtf(x);
}

bool att_isfinitef(float x)
{
    return att_i_isfinitef(x);
}

float att_clampf(float x, float lo, float hi)
{
    return att_i_clampf(x, lo, hi);
}

float att_absf(float x)
{
    return att_i_absf(x);
}

void att_sincosf_reduced(float x, float *s, float *c)
{
    float r;
    float sp;
    float cp;
    uint32_t quadrant;
    if (!(att_i_absf(x) <= ATT_TRIG_MAX_ARG_F)) {
        *s = NAN;
        *c = NAN;
        return;
    }
    quadrant = att_i_trig_reduce(x, &r);
    sp = att_i_sin_poly(r);
    cp = att_i_cos_poly(r);
    switch (quadrant) {
    case 0u:
        *s = sp;
        *c = cp;
        break;
    case 1u:
        *s = cp;
        *c = -sp;
        break;
    case 2u:
        *s = -sp;
        *c = -cp;
        break;
    default:
        *s = -cp;
        *c = sp;
        break;
    }
}

float att_sinf(float x)
{
    float s;
    float c;
    att_i_sincosf(x, &s, &c);
    return s;
}

float att_cosf(float x)
{
    float s;
    float c;
    att_i_sincosf(x, &s, &c);
    return c;
}

/* atan(t) for t in [0, 1]. */
static float att_atan_unit(float t)
{
    const bool big = t > ATT_TAN_PIO8;
    const float u = big ? (t - 1.0f) / (t + 1.0f) : t;
    const float z = u * u;
    const float p =
        u + u * z * (ATT_ATAN_A0 + z * (ATT_ATAN_A1 + z * (ATT_ATAN_A2 + z * (ATT_ATAN_A3 + z * ATT_ATAN_A4))));
    return big ? ATT_PIO4_HI + (p + ATT_PIO4_LO) : p;
}

float att_atan2f(float y, float x)
{
    float ax;
    float ay;
    float num;
    float den;
    float r;
    bool swap;
    if (x != x || y != y) {
        return NAN;
    }
    ax = att_absf(x);
    ay = att_absf(y);
    if (ax == INFINITY && ay == INFINITY) {
        ax = 1.0f;
        ay = 1.0f;
    }
    swap = ay > ax;
    num = swap ? ax : ay;
    den = swap ? ay : ax;
    r = (den == 0.0f) ? 0.0f : att_atan_unit(num / den);
    if (swap) {
        r = (ATT_PIO2_HI - r) + ATT_PIO2_LO;
    }
    if (x < 0.0f) {
        r = (ATT_PI_HI - r) + ATT_PI_LO;
    }
    return (y < 0.0f) ? -r : r;
}

float att_asinf(float x)
{
    if (!(att_absf(x) <= 1.0f)) {
        return NAN;
    }
    return att_atan2f(x, att_sqrtf((1.0f - x) * (1.0f + x)));
}

float att_acosf(float x)
{
    if (!(att_absf(x) <= 1.0f)) {
        return NAN;
    }
    return att_atan2f(att_sqrtf((1.0f - x) * (1.0f + x)), x);
}

float att_wrap_pi(float a)
{
    float kf;
    float r;
    if (!(att_absf(a) <= ATT_TRIG_MAX_ARG_F)) {
        return NAN;
    }
    kf = (a * ATT_INV_TWO_PI + ATT_ROUND_MAGIC) - ATT_ROUND_MAGIC;
    r = ((a - kf * ATT_TWOPI_P1) - kf * ATT_TWOPI_P2) - kf * ATT_TWOPI_P3;
    if (r <= -ATT_PI_HI) {
        r = (r + ATT_TWOPI_HI) + ATT_TWOPI_LO;
    } else if (r > ATT_PI_HI) {
        r = (r - ATT_TWOPI_HI) - ATT_TWOPI_LO;
    }
    return r;
}

att_vec3_t att_vec3_add(att_vec3_t a, att_vec3_t b)
{
    return att_i_vec3_add(a, b);
}

att_vec3_t att_vec3_sub(att_vec3_t a, att_vec3_t b)
{
    return att_i_vec3_sub(a, b);
}

att_vec3_t att_vec3_scale(att_vec3_t a, float s)
{
    return att_i_vec3_scale(a, s);
}

float att_vec3_dot(att_vec3_t a, att_vec3_t b)
{
    return att_i_vec3_dot(a, b);
}

att_vec3_t att_vec3_cross(att_vec3_t a, att_vec3_t b)
{
    return att_i_vec3_cross(a, b);
}

float att_vec3_norm(att_vec3_t a)
{
    return att_i_vec3_norm(a);
}

bool att_vec3_isfinite(att_vec3_t a)
{
    return att_i_vec3_isfinite(a);
}

bool att_vec3_normalize(att_vec3_t a, att_vec3_t *out)
{
    return att_i_vec3_normalize(a, out);
}

att_quat_t att_quat_identity(void)
{
    return att_i_quat_identity();
}

att_quat_t att_quat_mul(att_quat_t a, att_quat_t b)
{
    return att_i_quat_mul(a, b);
}

att_quat_t att_quat_conj(att_quat_t q)
{
    return att_i_quat_conj(q);
}

bool att_quat_isfinite(att_quat_t q)
{
    return att_i_quat_isfinite(q);
}

bool att_quat_normalize(att_quat_t q, att_quat_t *out)
{
    return att_i_quat_normalize(q, out);
}

att_vec3_t att_quat_rotate(att_quat_t q, att_vec3_t v)
{
    return att_i_quat_rotate(q, v);
}

att_vec3_t att_quat_rotate_inv(att_quat_t q, att_vec3_t v)
{
    return att_i_quat_rotate(att_i_quat_conj(q), v);
}

att_quat_t att_quat_from_axis_angle(att_vec3_t axis, float angle)
{
    return att_i_quat_from_axis_angle(axis, angle);
}

att_quat_t att_quat_from_rotvec(att_vec3_t rv)
{
    return att_i_quat_from_rotvec(rv);
}

att_quat_t att_quat_from_euler(float phi, float theta, float psi)
{
    return att_i_quat_from_euler(phi, theta, psi);
}

att_vec3_t att_quat_to_euler(att_quat_t q)
{
    att_vec3_t e;
    const float s = 2.0f * (q.w * q.y - q.z * q.x);
    e.x = att_atan2f(2.0f * (q.w * q.x + q.y * q.z), 1.0f - 2.0f * (q.x * q.x + q.y * q.y));
    e.y = att_asinf(att_clampf(s, -1.0f, 1.0f));
    e.z = att_atan2f(2.0f * (q.w * q.z + q.x * q.y), 1.0f - 2.0f * (q.y * q.y + q.z * q.z));
    return e;
}

void att_quat_to_matrix(att_quat_t q, float m[9])
{
    att_i_quat_to_matrix(q, m);
}
