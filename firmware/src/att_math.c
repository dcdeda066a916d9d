/**
 * @file att_math.c
 * @brief Deterministic float32 math (see att_math.h). Mirrored by host/attica/reference/detmath.py.
 *
 * Rules: + - * / and sqrtf only, hex-float constants, one fixed evaluation order (C evaluates
 * a + b + c as (a + b) + c, and so does the reference), no contraction into fused multiply-add.
 * Coefficients come from docs/tools/fit_trig.py.
 */
#include "att_fp.h"

#include "attica/att_math.h"

#include <math.h>

/* pi/2 in three parts: P1 and P2 have 11 significant bits so k*P1 and k*P2 are exact for
 * |k| < 2^13 (Cody-Waite range reduction). */
#define ATT_PIO2_P1 0x1.92p+0f
#define ATT_PIO2_P2 0x1.fb4p-12f
#define ATT_PIO2_P3 0x1.4442d2p-24f
#define ATT_TWO_OVER_PI 0x1.45f306p-1f
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
/* Adding and subtracting 1.5 * 2^23 rounds a float of magnitude < 2^22 to the nearest integer
 * (ties to even) in round-to-nearest mode. */
#define ATT_ROUND_MAGIC 0x1.8p+23f
#define ATT_TRIG_MAX_ARG_F 0x1p+13f
#define ATT_NORM2_MIN 0x1p-100f

/* sin(r) = r + r*z*(S0 + z*(S1 + z*S2)), |r| <= pi/4 */
#define ATT_SIN_S0 (-0x1.55554p-3f)
#define ATT_SIN_S1 0x1.11059cp-7f
#define ATT_SIN_S2 (-0x1.98d306p-13f)
/* cos(r) = 1 - z/2 + z*z*(C0 + z*(C1 + z*C2)) */
#define ATT_COS_C0 0x1.55554ap-5f
#define ATT_COS_C1 (-0x1.6c0c76p-10f)
#define ATT_COS_C2 0x1.99fc24p-16f
/* atan(u) = u + u*z*(A0 + z*(A1 + z*(A2 + z*(A3 + z*A4)))), |u| <= tan(pi/8) */
#define ATT_ATAN_A0 (-0x1.55554p-2f)
#define ATT_ATAN_A1 0x1.998e68p-3f
#define ATT_ATAN_A2 (-0x1.2383p-3f)
#define ATT_ATAN_A3 0x1.af6706p-4f
#define ATT_ATAN_A4 (-0x1.e682b8p-5f)

float att_sqrtf(float x)
{
#if defined(__GNUC__)
    return __builtin_sqrtf(x); /* IEEE correctly rounded; inlined as one instruction */
#else
    return sqrtf(x);
#endif
}

bool att_isfinitef(float x)
{
    return (x - x) == 0.0f;
}

float att_clampf(float x, float lo, float hi)
{
    if (x < lo) {
        return lo;
    }
    if (x > hi) {
        return hi;
    }
    return x;
}

float att_absf(float x)
{
    return (x < 0.0f) ? -x : x;
}

static float att_sin_poly(float r)
{
    const float z = r * r;
    return r + r * z * (ATT_SIN_S0 + z * (ATT_SIN_S1 + z * ATT_SIN_S2));
}

static float att_cos_poly(float r)
{
    const float z = r * r;
    return 1.0f - z * 0.5f + z * z * (ATT_COS_C0 + z * (ATT_COS_C1 + z * ATT_COS_C2));
}

/* Reduce x to r in about [-pi/4, pi/4] with x = k*pi/2 + r; returns the quadrant k mod 4.
 * Requires |x| <= ATT_TRIG_MAX_ARG_F (checked by the callers). */
static uint32_t att_trig_reduce(float x, float *r)
{
    const float kf = (x * ATT_TWO_OVER_PI + ATT_ROUND_MAGIC) - ATT_ROUND_MAGIC;
    /* |kf| <= 5216 here, so the conversion is in range. */
    const int32_t k = (int32_t)kf;
    *r = ((x - kf * ATT_PIO2_P1) - kf * ATT_PIO2_P2) - kf * ATT_PIO2_P3;
    return (uint32_t)k & 3u;
}

float att_sinf(float x)
{
    float r;
    uint32_t quadrant;
    if (!(att_absf(x) <= ATT_TRIG_MAX_ARG_F)) {
        return NAN;
    }
    quadrant = att_trig_reduce(x, &r);
    switch (quadrant) {
    case 0u:
        return att_sin_poly(r);
    case 1u:
        return att_cos_poly(r);
    case 2u:
        return -att_sin_poly(r);
    default:
        return -att_cos_poly(r);
    }
}

float att_cosf(float x)
{
    float r;
    uint32_t quadrant;
    if (!(att_absf(x) <= ATT_TRIG_MAX_ARG_F)) {
        return NAN;
    }
    quadrant = att_trig_reduce(x, &r);
    switch (quadrant) {
    case 0u:
        return att_cos_poly(r);
    case 1u:
        return -att_sin_poly(r);
    case 2u:
        return -att_cos_poly(r);
    default:
        return att_sin_poly(r);
    }
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
    att_vec3_t r;
    r.x = a.x + b.x;
    r.y = a.y + b.y;
    r.z = a.z + b.z;
    return r;
}

att_vec3_t att_vec3_sub(att_vec3_t a, att_vec3_t b)
{
    att_vec3_t r;
    r.x = a.x - b.x;
    r.y = a.y - b.y;
    r.z = a.z - b.z;
    return r;
}

att_vec3_t att_vec3_scale(att_vec3_t a, float s)
{
    att_vec3_t r;
    r.x = a.x * s;
    r.y = a.y * s;
    r.z = a.z * s;
    return r;
}

float att_vec3_dot(att_vec3_t a, att_vec3_t b)
{
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

att_vec3_t att_vec3_cross(att_vec3_t a, att_vec3_t b)
{
    att_vec3_t r;
    r.x = a.y * b.z - a.z * b.y;
    r.y = a.z * b.x - a.x * b.z;
    r.z = a.x * b.y - a.y * b.x;
    return r;
}

float att_vec3_norm(att_vec3_t a)
{
    return att_sqrtf(att_vec3_dot(a, a));
}

bool att_vec3_isfinite(att_vec3_t a)
{
    return att_isfinitef(a.x) && att_isfinitef(a.y) && att_isfinitef(a.z);
}

bool att_vec3_normalize(att_vec3_t a, att_vec3_t *out)
{
    const float n2 = att_vec3_dot(a, a);
    float inv;
    if (!(n2 >= ATT_NORM2_MIN && n2 < INFINITY)) {
        out->x = 0.0f;
        out->y = 0.0f;
        out->z = 0.0f;
        return false;
    }
    inv = 1.0f / att_sqrtf(n2);
    *out = att_vec3_scale(a, inv);
    return true;
}

att_quat_t att_quat_identity(void)
{
    att_quat_t q;
    q.w = 1.0f;
    q.x = 0.0f;
    q.y = 0.0f;
    q.z = 0.0f;
    return q;
}

att_quat_t att_quat_mul(att_quat_t a, att_quat_t b)
{
    att_quat_t r;
    r.w = a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z;
    r.x = a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y;
    r.y = a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x;
    r.z = a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w;
    return r;
}

att_quat_t att_quat_conj(att_quat_t q)
{
    att_quat_t r;
    r.w = q.w;
    r.x = -q.x;
    r.y = -q.y;
    r.z = -q.z;
    return r;
}

bool att_quat_isfinite(att_quat_t q)
{
    return att_isfinitef(q.w) && att_isfinitef(q.x) && att_isfinitef(q.y) && att_isfinitef(q.z);
}

bool att_quat_normalize(att_quat_t q, att_quat_t *out)
{
    const float n2 = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z;
    float inv;
    if (!(n2 >= ATT_NORM2_MIN && n2 < INFINITY)) {
        *out = att_quat_identity();
        return false;
    }
    inv = 1.0f / att_sqrtf(n2);
    out->w = q.w * inv;
    out->x = q.x * inv;
    out->y = q.y * inv;
    out->z = q.z * inv;
    return true;
}

/* v' = v + w*t + u x t with t = 2 (u x v), u = (q.x, q.y, q.z). */
att_vec3_t att_quat_rotate(att_quat_t q, att_vec3_t v)
{
    att_vec3_t u;
    att_vec3_t t;
    att_vec3_t r;
    u.x = q.x;
    u.y = q.y;
    u.z = q.z;
    t = att_vec3_scale(att_vec3_cross(u, v), 2.0f);
    r = att_vec3_add(att_vec3_add(v, att_vec3_scale(t, q.w)), att_vec3_cross(u, t));
    return r;
}

att_vec3_t att_quat_rotate_inv(att_quat_t q, att_vec3_t v)
{
    return att_quat_rotate(att_quat_conj(q), v);
}

att_quat_t att_quat_from_axis_angle(att_vec3_t axis, float angle)
{
    const float h = angle * 0.5f;
    const float s = att_sinf(h);
    att_quat_t q;
    q.w = att_cosf(h);
    q.x = axis.x * s;
    q.y = axis.y * s;
    q.z = axis.z * s;
    return q;
}

att_quat_t att_quat_from_rotvec(att_vec3_t rv)
{
    const float angle = att_vec3_norm(rv);
    float h;
    float k;
    att_quat_t q;
    if (!(angle > 0.0f)) {
        return att_quat_identity();
    }
    h = angle * 0.5f;
    k = att_sinf(h) / angle;
    q.w = att_cosf(h);
    q.x = rv.x * k;
    q.y = rv.y * k;
    q.z = rv.z * k;
    return q;
}

att_quat_t att_quat_from_euler(float phi, float theta, float psi)
{
    const float hr = phi * 0.5f;
    const float hp = theta * 0.5f;
    const float hy = psi * 0.5f;
    const float cr = att_cosf(hr);
    const float sr = att_sinf(hr);
    const float cp = att_cosf(hp);
    const float sp = att_sinf(hp);
    const float cy = att_cosf(hy);
    const float sy = att_sinf(hy);
    att_quat_t q;
    q.w = cr * cp * cy + sr * sp * sy;
    q.x = sr * cp * cy - cr * sp * sy;
    q.y = cr * sp * cy + sr * cp * sy;
    q.z = cr * cp * sy - sr * sp * cy;
    return q;
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
    const float xx = q.x * q.x;
    const float yy = q.y * q.y;
    const float zz = q.z * q.z;
    const float xy = q.x * q.y;
    const float xz = q.x * q.z;
    const float yz = q.y * q.z;
    const float wx = q.w * q.x;
    const float wy = q.w * q.y;
    const float wz = q.w * q.z;
    m[0] = 1.0f - 2.0f * (yy + zz);
    m[1] = 2.0f * (xy - wz);
    m[2] = 2.0f * (xz + wy);
    m[3] = 2.0f * (xy + wz);
    m[4] = 1.0f - 2.0f * (xx + zz);
    m[5] = 2.0f * (yz - wx);
    m[6] = 2.0f * (xz - wy);
    m[7] = 2.0f * (yz + wx);
    m[8] = 1.0f - 2.0f * (xx + yy);
}
