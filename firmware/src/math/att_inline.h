/**
 * @file att_inline.h
 * @brief Private: the hot math of attica as static inline functions (compiled only with cflags.txt).
 *
 * Every function here computes exactly what its public, out-of-line twin in att_math.h computes,
 * operation for operation (att_math.c implements the public functions with these), so inlining
 * changes speed, never bits. The public headers keep the out-of-line entry points for applications
 * and for the Python binding: a user's compiler flags never reach the arithmetic inlined here, because
 * this header is included only by the library's own sources, which are always built with
 * firmware/cflags.txt (-ffp-contract=off, no fast-math: att_fp.h refuses it).
 *
 * Naming: att_i_<module>_<verb>, the twin of att_<module>_<verb>. A few helpers have no public twin
 * (the small-angle sine/cosine, products with a quaternion whose z part is zero); their contracts are
 * stated where they are defined and mirrored by host/attica/reference/detmath.py.
 */
#ifndef ATT_INLINE_H
#define ATT_INLINE_H

#include "att_fp.h"

#include "attica/att_types.h"

#include <math.h> /* NAN and INFINITY only: no libm function is called */

/* Inlining and outlining hints for the hot step functions (no effect on results). ATT_IN_LINE(cond):
 * a rare branch's body laid out in line (GCC and clang, which defines __GNUC__ too: the branch declared
 * likely, which it is not), where a short body skipped by one compare-and-branch costs the common path
 * an instruction less than a far jump out of line (on the Cortex-M, cbz needs a near forward target);
 * its value is cond, a bool. */
#if defined(__GNUC__)
#define ATT_ALWAYS_INLINE inline __attribute__((always_inline))
#define ATT_NOINLINE __attribute__((noinline))
#define ATT_IN_LINE(cond) (__builtin_expect((cond) ? 1L : 0L, 1L) != 0L)
#else
#define ATT_ALWAYS_INLINE inline
#define ATT_NOINLINE
#define ATT_IN_LINE(cond) (cond)
#endif

/* pi/2 in three parts: P1 and P2 have 11 significant bits so k*P1 and k*P2 are exact for
 * |k| < 2^13 (Cody-Waite range reduction). */
#define ATT_PIO2_P1 0x1.92p+0f
#define ATT_PIO2_P2 0x1.fb4p-12f
#define ATT_PIO2_P3 0x1.4442d2p-24f
#define ATT_TWO_OVER_PI 0x1.45f306p-1f
/* Adding and subtracting 1.5 * 2^23 rounds a float of magnitude < 2^22 to the nearest integer
 * (ties to even) in round-to-nearest mode. */
#define ATT_ROUND_MAGIC 0x1.8p+23f
#define ATT_TRIG_MAX_ARG_F 0x1p+13f
#define ATT_NORM2_MIN 0x1p-100f

/*
 * Largest |x| for which the reduction of att_sinf/att_cosf leaves x unchanged in quadrant 0:
 * x * 2/pi rounds to k = 0 for |x| < 0.785 (pi/4), and then r = ((x - 0 P1) - 0 P2) - 0 P3 = x
 * exactly, so att_i_sin_small(x) == att_sinf(x) and att_i_cos_small(x) == att_cosf(x) bit for bit
 * for |x| <= ATT_SMALL_ANGLE_MAX (tests/test_detmath.py checks the boundary).
 */
#define ATT_SMALL_ANGLE_MAX 0x1.8p-1f /* 3/4 rad */

/* sin(r) = r + r*z*(S0 + z*(S1 + z*S2)), |r| <= pi/4 */
#define ATT_SIN_S0 (-0x1.55554p-3f)
#define ATT_SIN_S1 0x1.11059cp-7f
#define ATT_SIN_S2 (-0x1.98d306p-13f)
/* cos(r) = 1 - z/2 + z*z*(C0 + z*(C1 + z*C2)) */
#define ATT_COS_C0 0x1.55554ap-5f
#define ATT_COS_C1 (-0x1.6c0c76p-10f)
#define ATT_COS_C2 0x1.99fc24p-16f

static inline float att_i_sqrtf(float x)
{
#if defined(__GNUC__)
    return __builtin_sqrtf(x); /* IEEE correctly rounded; one instruction with an FPU */
#else
    return sqrtf(x);
#endif
}

static inline bool att_i_isfinitef(float x)
{
    return (x - x) == 0.0f;
}

/* |x| with the sign bit cleared (IEEE abs: |-0| = +0, NaN stays NaN); one instruction with an FPU. */
static inline float att_i_absf(float x)
{
#if defined(__GNUC__)
    return __builtin_fabsf(x);
#else
    union {
        float f;
        uint32_t u;
    } v;
    v.f = x;
    v.u &= 0x7FFFFFFFu;
    return v.f;
#endif
}

static inline float att_i_clampf(float x, float lo, float hi)
{
    if (x < lo) {
        return lo;
    }
    if (x > hi) {
        return hi;
    }
    return x;
}

static inline float att_i_sin_poly(float r)
{
    const float z = r * r;
    return r + r * z * (ATT_SIN_S0 + z * (ATT_SIN_S1 + z * ATT_SIN_S2));
}

static inline float att_i_cos_poly(float r)
{
    const float z = r * r;
    return 1.0f - z * 0.5f + z * z * (ATT_COS_C0 + z * (ATT_COS_C1 + z * ATT_COS_C2));
}

/* Reduce x to r in about [-pi/4, pi/4] with x = k*pi/2 + r; returns the quadrant k mod 4.
 * Requires |x| <= ATT_TRIG_MAX_ARG_F (checked by the callers). */
static inline uint32_t att_i_trig_reduce(float x, float *r)
{
    const float kf = (x * ATT_TWO_OVER_PI + ATT_ROUND_MAGIC) - ATT_ROUND_MAGIC;
    /* |kf| <= 5216 here, so the conversion is in range. */
    const int32_t k = (int32_t)kf;
    *r = ((x - kf * ATT_PIO2_P1) - kf * ATT_PIO2_P2) - kf * ATT_PIO2_P3;
    return (uint32_t)k & 3u;
}

/**
 * sin(x) and cos(x) of any x with one range reduction (defined in att_math.c): *s == att_sinf(x),
 * *c == att_cosf(x) bit for bit; NaN for |x| > ATT_TRIG_MAX_ARG or non-finite x.
 */
void att_sincosf_reduced(float x, float *s, float *c);

/**
 * sin(x) and cos(x): *s == att_sinf(x), *c == att_cosf(x) bit for bit. Arguments within
 * ATT_SMALL_ANGLE_MAX skip the range reduction, which there is the identity (inline); others call
 * att_sincosf_reduced.
 */
static inline void att_i_sincosf(float x, float *s, float *c)
{
#if defined(__OPTIMIZE_SIZE__)
    /* -Os: the one shared copy (the reduction is the identity up to ATT_SMALL_ANGLE_MAX: the same bits) */
    att_sincosf_reduced(x, s, c);
#else
    if (att_i_absf(x) <= ATT_SMALL_ANGLE_MAX) {
        *s = att_i_sin_poly(x);
        *c = att_i_cos_poly(x);
        return;
    }
    att_sincosf_reduced(x, s, c);
#endif
}

static inline att_vec3_t att_i_vec3(float x, float y, float z)
{
    att_vec3_t r;
    r.x = x;
    r.y = y;
    r.z = z;
    return r;
}

static inline att_vec3_t att_i_vec3_add(att_vec3_t a, att_vec3_t b)
{
    return att_i_vec3(a.x + b.x, a.y + b.y, a.z + b.z);
}

static inline att_vec3_t att_i_vec3_sub(att_vec3_t a, att_vec3_t b)
{
    return att_i_vec3(a.x - b.x, a.y - b.y, a.z - b.z);
}

static inline att_vec3_t att_i_vec3_scale(att_vec3_t a, float s)
{
    return att_i_vec3(a.x * s, a.y * s, a.z * s);
}

static inline float att_i_vec3_dot(att_vec3_t a, att_vec3_t b)
{
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

static inline att_vec3_t att_i_vec3_cross(att_vec3_t a, att_vec3_t b)
{
    return att_i_vec3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}

static inline float att_i_vec3_norm(att_vec3_t a)
{
    return att_i_sqrtf(att_i_vec3_dot(a, a));
}

static inline bool att_i_vec3_isfinite(att_vec3_t a)
{
    return att_i_isfinitef(a.x) && att_i_isfinitef(a.y) && att_i_isfinitef(a.z);
}

static inline bool att_i_vec3_normalize(att_vec3_t a, att_vec3_t *out)
{
    const float n2 = att_i_vec3_dot(a, a);
    float inv;
    if (!(n2 >= ATT_NORM2_MIN && n2 < INFINITY)) {
        *out = att_i_vec3(0.0f, 0.0f, 0.0f);
        return false;
    }
    inv = 1.0f / att_i_sqrtf(n2);
    *out = att_i_vec3_scale(a, inv);
    return true;
}

static inline att_quat_t att_i_quat(float w, float x, float y, float z)
{
    att_quat_t q;
    q.w = w;
    q.x = x;
    q.y = y;
    q.z = z;
    return q;
}

static inline att_quat_t att_i_quat_identity(void)
{
    return att_i_quat(1.0f, 0.0f, 0.0f, 0.0f);
}

static inline att_quat_t att_i_quat_mul(att_quat_t a, att_quat_t b)
{
    att_quat_t r;
    r.w = a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z;
    r.x = a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y;
    r.y = a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x;
    r.z = a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w;
    return r;
}

/**
 * a * b for a quaternion a whose z part is zero (a rotation about a horizontal axis): the terms of
 * att_i_quat_mul with a.z dropped. Mirrored by detmath.quat_mul_hz.
 */
static inline att_quat_t att_i_quat_mul_hz(float aw, float ax, float ay, att_quat_t b)
{
    att_quat_t r;
    r.w = aw * b.w - ax * b.x - ay * b.y;
    r.x = aw * b.x + ax * b.w + ay * b.z;
    r.y = aw * b.y - ax * b.z + ay * b.w;
    r.z = aw * b.z + ax * b.y - ay * b.x;
    return r;
}

/**
 * a * b for a = (aw, 0, 0, az), a rotation about the vertical: the terms of att_i_quat_mul with a.x,
 * a.y dropped. Mirrored by detmath.quat_mul_z.
 */
static inline att_quat_t att_i_quat_mul_z(float aw, float az, att_quat_t b)
{
    att_quat_t r;
    r.w = aw * b.w - az * b.z;
    r.x = aw * b.x - az * b.y;
    r.y = aw * b.y + az * b.x;
    r.z = aw * b.z + az * b.w;
    return r;
}

static inline att_quat_t att_i_quat_conj(att_quat_t q)
{
    return att_i_quat(q.w, -q.x, -q.y, -q.z);
}

static inline bool att_i_quat_isfinite(att_quat_t q)
{
    return att_i_isfinitef(q.w) && att_i_isfinitef(q.x) && att_i_isfinitef(q.y) && att_i_isfinitef(q.z);
}

/* q scaled by 1 / sqrt(n2) when n2 passes the test ok, else the identity; returns ok. */
static inline bool att_i_quat_scale_unit(att_quat_t q, float n2, bool ok, att_quat_t *out)
{
    float inv;
    if (!ok) {
        *out = att_i_quat_identity();
        return false;
    }
    inv = 1.0f / att_i_sqrtf(n2);
    out->w = q.w * inv;
    out->x = q.x * inv;
    out->y = q.y * inv;
    out->z = q.z * inv;
    return true;
}

static inline bool att_i_quat_normalize(att_quat_t q, att_quat_t *out)
{
    const float n2 = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z;
    return att_i_quat_scale_unit(q, n2, n2 >= ATT_NORM2_MIN && n2 < INFINITY, out);
}

/**
 * att_i_quat_normalize for a q that cannot overflow (every filter's attitude: products of unit
 * quaternions and of corrections bounded by 1): one test, |q|^2 >= 2^-100, which also fails for NaN.
 * Mirrored by detmath.quat_normalize_bounded.
 */
static inline bool att_i_quat_normalize_bounded(att_quat_t q, att_quat_t *out)
{
    const float n2 = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z;
    return att_i_quat_scale_unit(q, n2, n2 >= ATT_NORM2_MIN, out);
}

/* v' = v + w*t + u x t with t = 2 (u x v), u = (q.x, q.y, q.z). */
static inline att_vec3_t att_i_quat_rotate(att_quat_t q, att_vec3_t v)
{
    const att_vec3_t u = att_i_vec3(q.x, q.y, q.z);
    const att_vec3_t t = att_i_vec3_scale(att_i_vec3_cross(u, v), 2.0f);
    return att_i_vec3_add(att_i_vec3_add(v, att_i_vec3_scale(t, q.w)), att_i_vec3_cross(u, t));
}

/**
 * att_i_quat_rotate for a quaternion (w, x, y, 0) whose z part is zero: the same formula with the
 * products by u.z dropped. Mirrored by detmath.quat_rotate_hz.
 */
static inline att_vec3_t att_i_quat_rotate_hz(float w, float x, float y, att_vec3_t v)
{
    att_vec3_t t;
    att_vec3_t r;
    t.x = (y * v.z) * 2.0f;
    t.y = (-(x * v.z)) * 2.0f;
    t.z = (x * v.y - y * v.x) * 2.0f;
    r.x = (v.x + t.x * w) + y * t.z;
    r.y = (v.y + t.y * w) - x * t.z;
    r.z = (v.z + t.z * w) + (x * t.y - y * t.x);
    return r;
}

static inline att_quat_t att_i_quat_from_axis_angle(att_vec3_t axis, float angle)
{
    float s;
    float c;
    att_i_sincosf(angle * 0.5f, &s, &c);
    return att_i_quat(c, axis.x * s, axis.y * s, axis.z * s);
}

static inline att_quat_t att_i_quat_from_rotvec(att_vec3_t rv)
{
    const float angle = att_i_vec3_norm(rv);
    float s;
    float c;
    float k;
    if (!(angle > 0.0f)) {
        return att_i_quat_identity();
    }
    att_i_sincosf(angle * 0.5f, &s, &c);
    k = s / angle;
    return att_i_quat(c, rv.x * k, rv.y * k, rv.z * k);
}

static inline att_quat_t att_i_quat_from_euler(float phi, float theta, float psi)
{
    float cr;
    float sr;
    float cp;
    float sp;
    float cy;
    float sy;
    att_i_sincosf(phi * 0.5f, &sr, &cr);
    att_i_sincosf(theta * 0.5f, &sp, &cp);
    att_i_sincosf(psi * 0.5f, &sy, &cy);
    return att_i_quat(cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
                      cr * cp * sy - sr * sp * cy);
}

/* The rotation matrix of q (row-major, m = R(q): earth = m * sensor); q assumed unit. */
static ATT_ALWAYS_INLINE void att_i_quat_to_matrix(att_quat_t q, float m[9])
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

#endif /* ATT_INLINE_H */
