/**
 * @file att_math.h
 * @brief Deterministic float32 math: trigonometry, 3-vectors and quaternions.
 *
 * Every function is built from IEEE-754 + - * / and sqrtf only, with a fixed operation order and
 * hex-float constants, so the same inputs give the same bits on every conforming CPU and compiler
 * (with -ffp-contract=off). host/attica/reference/detmath.py mirrors each function operation by
 * operation.
 *
 * Accuracy (max abs error against float64 libm of the same float32 input, measured by
 * tests/test_detmath.py): sin/cos/atan2/asin/acos below 1e-6 (rad for the inverse functions).
 *
 * Domain: att_sinf/att_cosf accept |x| <= ATT_TRIG_MAX_ARG (8192 rad) and return NaN beyond it or
 * for NaN/Inf. att_asinf/att_acosf return NaN outside [-1, 1]. att_atan2f(0, 0) = 0 and signed
 * zeros are not distinguished (atan2(+-0, x<0) = +pi).
 */
#ifndef ATT_MATH_H
#define ATT_MATH_H

#include "attica/att_config.h"
#include "attica/att_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ATT_CDEF_BEGIN */
/** Largest |x| accepted by att_sinf / att_cosf, rad. */
#define ATT_TRIG_MAX_ARG 8192

/** Correctly rounded square root (IEEE-754); NaN for x < 0. */
float att_sqrtf(float x);
/** true when x is neither NaN nor +-Inf. */
bool att_isfinitef(float x);
/** x limited to [lo, hi]; NaN stays NaN. */
float att_clampf(float x, float lo, float hi);
/** |x| without libm: the sign bit cleared (IEEE abs: |-0| = +0, NaN stays NaN). */
float att_absf(float x);

/** sin(x), x in rad, |x| <= ATT_TRIG_MAX_ARG. */
float att_sinf(float x);
/** cos(x), x in rad, |x| <= ATT_TRIG_MAX_ARG. */
float att_cosf(float x);
/** atan2(y, x) in [-pi, pi], rad. */
float att_atan2f(float y, float x);
/** asin(x) in [-pi/2, pi/2], rad; NaN outside [-1, 1]. */
float att_asinf(float x);
/** acos(x) in [0, pi], rad; NaN outside [-1, 1]. */
float att_acosf(float x);
/** a wrapped into (-pi, pi], rad; NaN for non-finite a or |a| > ATT_TRIG_MAX_ARG. */
float att_wrap_pi(float a);

/** a + b */
att_vec3_t att_vec3_add(att_vec3_t a, att_vec3_t b);
/** a - b */
att_vec3_t att_vec3_sub(att_vec3_t a, att_vec3_t b);
/** s * a */
att_vec3_t att_vec3_scale(att_vec3_t a, float s);
/** a . b = (a.x*b.x + a.y*b.y) + a.z*b.z */
float att_vec3_dot(att_vec3_t a, att_vec3_t b);
/** a x b */
att_vec3_t att_vec3_cross(att_vec3_t a, att_vec3_t b);
/** |a| */
float att_vec3_norm(att_vec3_t a);
/** true when every component is finite. */
bool att_vec3_isfinite(att_vec3_t a);
/**
 * Unit vector of a. Returns false (and *out = (0,0,0)) when |a|^2 is zero, subnormal-small
 * (< 2^-100), overflows or is not finite.
 */
bool att_vec3_normalize(att_vec3_t a, att_vec3_t *out);

/** (1, 0, 0, 0) */
att_quat_t att_quat_identity(void);
/** Hamilton product a * b (apply b first, then a). */
att_quat_t att_quat_mul(att_quat_t a, att_quat_t b);
/** Conjugate (inverse of a unit quaternion). */
att_quat_t att_quat_conj(att_quat_t q);
/** true when every component is finite. */
bool att_quat_isfinite(att_quat_t q);
/**
 * Unit quaternion of q. Returns false (and *out = identity) when |q|^2 is zero, below 2^-100,
 * overflows or is not finite.
 */
bool att_quat_normalize(att_quat_t q, att_quat_t *out);
/** Rotate v by unit q: q * (0, v) * conj(q) (sensor frame to earth frame for an attitude q). */
att_vec3_t att_quat_rotate(att_quat_t q, att_vec3_t v);
/** Rotate v by conj(q): earth frame to sensor frame for an attitude q. */
att_vec3_t att_quat_rotate_inv(att_quat_t q, att_vec3_t v);
/** Rotation by angle (rad) about a unit axis: (cos(angle/2), axis * sin(angle/2)). */
att_quat_t att_quat_from_axis_angle(att_vec3_t axis, float angle);
/** Exponential map of a rotation vector rv (rad): angle |rv| about rv/|rv|; identity for rv = 0. */
att_quat_t att_quat_from_rotvec(att_vec3_t rv);
/** ZYX Euler (roll phi, pitch theta, yaw psi; rad) to q = Qz(psi) * Qy(theta) * Qx(phi). */
att_quat_t att_quat_from_euler(float phi, float theta, float psi);
/** Unit q to ZYX Euler: x = roll phi in (-pi, pi], y = pitch theta in [-pi/2, pi/2], z = yaw psi. */
att_vec3_t att_quat_to_euler(att_quat_t q);
/** Unit q to the 3x3 rotation matrix m (row-major) with v_earth = m * v_sensor. */
void att_quat_to_matrix(att_quat_t q, float m[9]);
/* ATT_CDEF_END */

#ifdef __cplusplus
}
#endif

#endif /* ATT_MATH_H */
