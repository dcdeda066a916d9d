"""Deterministic float32 math, mirroring firmware/src/math/att_math.c operation by operation.

Every function accepts ``np.float32`` scalars or float32 arrays (broadcast together) and returns
float32 values with exactly the bits the C code produces. Rules followed here (see DEVELOPERS.md):
one numpy operation per C operator, in the same order; constants built from hex floats; branches
as ``np.where`` (both sides are evaluated, the selected one is bit-identical to C); no Python
floats, no ``math``, no reductions.

Vectors are tuples ``(x, y, z)`` and quaternions tuples ``(w, x, y, z)`` of float32 values, so a
whole batch of independent instances runs in lockstep when the components are arrays.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

F32 = np.float32 | NDArray[np.float32]
"""A float32 scalar or array."""
Vec3 = tuple[Any, Any, Any]
"""(x, y, z), float32 components."""
Quat = tuple[Any, Any, Any, Any]
"""(w, x, y, z), float32 components."""


def c(hex_literal: str) -> np.float32:
    """A float32 constant from a C99 hex-float literal (``'0x1.8p+23'``)."""
    value = np.float32(float.fromhex(hex_literal))
    if float(value).hex() != float.fromhex(hex_literal).hex():
        raise ValueError(f"{hex_literal} is not exactly representable in float32")
    return value


def f32(x: Any) -> Any:
    """Convert input data (arrays, lists, numbers) to float32 without changing float32 bits."""
    return np.asarray(x, dtype=np.float32)


ZERO = c("0x0p+0")
ONE = c("0x1p+0")
TWO = c("0x1p+1")
HALF = c("0x1p-1")
NAN = np.float32(np.nan)
INF = np.float32(np.inf)

PIO2_P1 = c("0x1.92p+0")
PIO2_P2 = c("0x1.fb4p-12")
PIO2_P3 = c("0x1.4442d2p-24")
TWO_OVER_PI = c("0x1.45f306p-1")
INV_TWO_PI = c("0x1.45f306p-3")
PI_HI = c("0x1.921fb6p+1")
PI_LO = c("-0x1.777a5cp-24")
PIO2_HI = c("0x1.921fb6p+0")
PIO2_LO = c("-0x1.777a5cp-25")
PIO4_HI = c("0x1.921fb6p-1")
PIO4_LO = c("-0x1.777a5cp-26")
TWOPI_HI = c("0x1.921fb6p+2")
TWOPI_LO = c("-0x1.777a5cp-23")
TWOPI_P1 = c("0x1.92p+2")
TWOPI_P2 = c("0x1.fb4p-10")
TWOPI_P3 = c("0x1.4442d2p-22")
TAN_PIO8 = c("0x1.a8279ap-2")
ROUND_MAGIC = c("0x1.8p+23")
TRIG_MAX_ARG = c("0x1p+13")
NORM2_MIN = c("0x1p-100")

SIN_S0 = c("-0x1.55554p-3")
SIN_S1 = c("0x1.11059cp-7")
SIN_S2 = c("-0x1.98d306p-13")
COS_C0 = c("0x1.55554ap-5")
COS_C1 = c("-0x1.6c0c76p-10")
COS_C2 = c("0x1.99fc24p-16")
ATAN_A0 = c("-0x1.55554p-2")
ATAN_A1 = c("0x1.998e68p-3")
ATAN_A2 = c("-0x1.2383p-3")
ATAN_A3 = c("0x1.af6706p-4")
ATAN_A4 = c("-0x1.e682b8p-5")


def _quiet() -> Any:
    """Floating-point warnings are expected: both sides of every branch are evaluated."""
    return np.errstate(all="ignore")


def sqrtf(x: F32) -> Any:
    """Correctly rounded square root (att_sqrtf)."""
    with _quiet():
        return np.sqrt(f32(x))


def isfinitef(x: F32) -> Any:
    """att_isfinitef: ``(x - x) == 0``."""
    x = f32(x)
    with _quiet():
        return (x - x) == ZERO


def clampf(x: F32, lo: F32, hi: F32) -> Any:
    """att_clampf: x limited to [lo, hi]; NaN stays NaN."""
    x, lo, hi = f32(x), f32(lo), f32(hi)
    return np.where(x < lo, lo, np.where(x > hi, hi, x)).astype(np.float32)


def absf(x: F32) -> Any:
    """att_absf: IEEE abs, the sign bit cleared (``|-0| = +0``; NaN stays NaN)."""
    return np.abs(f32(x))


def _sin_poly(r: Any) -> Any:
    z = r * r
    return r + r * z * (SIN_S0 + z * (SIN_S1 + z * SIN_S2))


def _cos_poly(r: Any) -> Any:
    z = r * r
    return ONE - z * HALF + z * z * (COS_C0 + z * (COS_C1 + z * COS_C2))


def _trig_reduce(x: Any) -> tuple[Any, Any, Any]:
    """Return (ok, r, quadrant) as att_trig_reduce plus the domain check of the callers."""
    ok = absf(x) <= TRIG_MAX_ARG
    xs = np.where(ok, x, ZERO)  # keep the int conversion in range where C would not reach it
    kf = (xs * TWO_OVER_PI + ROUND_MAGIC) - ROUND_MAGIC
    k = np.asarray(kf).astype(np.int32)
    r = ((xs - kf * PIO2_P1) - kf * PIO2_P2) - kf * PIO2_P3
    return ok, r, k & np.int32(3)


def sinf(x: F32) -> Any:
    """att_sinf: sin(x), NaN outside |x| <= 8192."""
    x = f32(x)
    with _quiet():
        ok, r, q = _trig_reduce(x)
        s = _sin_poly(r)
        co = _cos_poly(r)
        out = np.select([q == 0, q == 1, q == 2], [s, co, -s], -co)
        return np.where(ok, out, NAN).astype(np.float32)


def cosf(x: F32) -> Any:
    """att_cosf: cos(x), NaN outside |x| <= 8192."""
    x = f32(x)
    with _quiet():
        ok, r, q = _trig_reduce(x)
        s = _sin_poly(r)
        co = _cos_poly(r)
        out = np.select([q == 0, q == 1, q == 2], [co, -s, -co], s)
        return np.where(ok, out, NAN).astype(np.float32)


def _atan_unit(t: Any) -> Any:
    big = t > TAN_PIO8
    u = np.where(big, (t - ONE) / (t + ONE), t)
    z = u * u
    p = u + u * z * (ATAN_A0 + z * (ATAN_A1 + z * (ATAN_A2 + z * (ATAN_A3 + z * ATAN_A4))))
    return np.where(big, PIO4_HI + (p + PIO4_LO), p)


def atan2f(y: F32, x: F32) -> Any:
    """att_atan2f: atan2(y, x) in [-pi, pi]; atan2(0, 0) = 0; signed zeros not distinguished."""
    y, x = f32(y), f32(x)
    with _quiet():
        nan_in = (x != x) | (y != y)
        ax = absf(x)
        ay = absf(y)
        both_inf = (ax == INF) & (ay == INF)
        ax = np.where(both_inf, ONE, ax)
        ay = np.where(both_inf, ONE, ay)
        swap = ay > ax
        num = np.where(swap, ax, ay)
        den = np.where(swap, ay, ax)
        r = np.where(den == ZERO, ZERO, _atan_unit(num / den))
        r = np.where(swap, (PIO2_HI - r) + PIO2_LO, r)
        r = np.where(x < ZERO, (PI_HI - r) + PI_LO, r)
        r = np.where(y < ZERO, -r, r)
        return np.where(nan_in, NAN, r).astype(np.float32)


def asinf(x: F32) -> Any:
    """att_asinf: asin(x) in [-pi/2, pi/2]; NaN outside [-1, 1]."""
    x = f32(x)
    with _quiet():
        ok = absf(x) <= ONE
        r = atan2f(x, sqrtf((ONE - x) * (ONE + x)))
        return np.where(ok, r, NAN).astype(np.float32)


def acosf(x: F32) -> Any:
    """att_acosf: acos(x) in [0, pi]; NaN outside [-1, 1]."""
    x = f32(x)
    with _quiet():
        ok = absf(x) <= ONE
        r = atan2f(sqrtf((ONE - x) * (ONE + x)), x)
        return np.where(ok, r, NAN).astype(np.float32)


def wrap_pi(a: F32) -> Any:
    """att_wrap_pi: a wrapped into (-pi, pi]; NaN for non-finite or |a| > 8192."""
    a = f32(a)
    with _quiet():
        ok = absf(a) <= TRIG_MAX_ARG
        kf = (a * INV_TWO_PI + ROUND_MAGIC) - ROUND_MAGIC
        r = ((a - kf * TWOPI_P1) - kf * TWOPI_P2) - kf * TWOPI_P3
        r = np.where(
            r <= -PI_HI, (r + TWOPI_HI) + TWOPI_LO, np.where(r > PI_HI, (r - TWOPI_HI) - TWOPI_LO, r)
        )
        return np.where(ok, r, NAN).astype(np.float32)


# --- 3-vectors ---------------------------------------------------------------------------------


def vec3(x: Any, y: Any, z: Any) -> Vec3:
    """A vector tuple with float32 components."""
    return (f32(x), f32(y), f32(z))


def vec3_add(a: Vec3, b: Vec3) -> Vec3:
    """att_vec3_add."""
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def vec3_sub(a: Vec3, b: Vec3) -> Vec3:
    """att_vec3_sub."""
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def vec3_scale(a: Vec3, s: Any) -> Vec3:
    """att_vec3_scale."""
    return (a[0] * s, a[1] * s, a[2] * s)


def vec3_dot(a: Vec3, b: Vec3) -> Any:
    """att_vec3_dot: (a.x*b.x + a.y*b.y) + a.z*b.z."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def vec3_cross(a: Vec3, b: Vec3) -> Vec3:
    """att_vec3_cross."""
    return (
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    )


def vec3_norm(a: Vec3) -> Any:
    """att_vec3_norm."""
    return sqrtf(vec3_dot(a, a))


def vec3_isfinite(a: Vec3) -> Any:
    """att_vec3_isfinite."""
    return isfinitef(a[0]) & isfinitef(a[1]) & isfinitef(a[2])


def vec3_normalize(a: Vec3) -> tuple[Any, Vec3]:
    """att_vec3_normalize: (ok, unit vector or zeros)."""
    with _quiet():
        n2 = vec3_dot(a, a)
        ok = (n2 >= NORM2_MIN) & (n2 < INF)
        inv = ONE / sqrtf(n2)
        s = vec3_scale(a, inv)
        return ok, (np.where(ok, s[0], ZERO), np.where(ok, s[1], ZERO), np.where(ok, s[2], ZERO))


def vec3_where(cond: Any, a: Vec3, b: Vec3) -> Vec3:
    """Component-wise ``cond ? a : b`` (a C branch on a whole vector)."""
    return (np.where(cond, a[0], b[0]), np.where(cond, a[1], b[1]), np.where(cond, a[2], b[2]))


# --- quaternions -------------------------------------------------------------------------------


def quat(w: Any, x: Any, y: Any, z: Any) -> Quat:
    """A quaternion tuple with float32 components."""
    return (f32(w), f32(x), f32(y), f32(z))


def quat_identity(shape: tuple[int, ...] = ()) -> Quat:
    """(1, 0, 0, 0), optionally as arrays of the given shape."""
    return (
        np.full(shape, ONE, np.float32),
        np.zeros(shape, np.float32),
        np.zeros(shape, np.float32),
        np.zeros(shape, np.float32),
    )


def quat_where(cond: Any, a: Quat, b: Quat) -> Quat:
    """Component-wise ``cond ? a : b``."""
    return (
        np.where(cond, a[0], b[0]),
        np.where(cond, a[1], b[1]),
        np.where(cond, a[2], b[2]),
        np.where(cond, a[3], b[3]),
    )


def quat_mul(a: Quat, b: Quat) -> Quat:
    """att_quat_mul: Hamilton product a * b."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


def quat_mul_hz(aw: Any, ax: Any, ay: Any, b: Quat) -> Quat:
    """att_i_quat_mul_hz: (aw, ax, ay, 0) * b, the terms of quat_mul with a.z dropped."""
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by,
        aw * bx + ax * bw + ay * bz,
        aw * by - ax * bz + ay * bw,
        aw * bz + ax * by - ay * bx,
    )


def quat_mul_z(aw: Any, az: Any, b: Quat) -> Quat:
    """att_i_quat_mul_z: (aw, 0, 0, az) * b, the terms of quat_mul with a.x and a.y dropped."""
    bw, bx, by, bz = b
    return (aw * bw - az * bz, aw * bx - az * by, aw * by + az * bx, aw * bz + az * bw)


def quat_conj(q: Quat) -> Quat:
    """att_quat_conj."""
    return (q[0], -q[1], -q[2], -q[3])


def quat_isfinite(q: Quat) -> Any:
    """att_quat_isfinite."""
    return isfinitef(q[0]) & isfinitef(q[1]) & isfinitef(q[2]) & isfinitef(q[3])


def quat_normalize(q: Quat) -> tuple[Any, Quat]:
    """att_quat_normalize: (ok, unit quaternion or identity)."""
    w, x, y, z = q
    with _quiet():
        n2 = w * w + x * x + y * y + z * z
        ok = (n2 >= NORM2_MIN) & (n2 < INF)
        inv = ONE / sqrtf(n2)
        return ok, (
            np.where(ok, w * inv, ONE),
            np.where(ok, x * inv, ZERO),
            np.where(ok, y * inv, ZERO),
            np.where(ok, z * inv, ZERO),
        )


def quat_normalize_bounded(q: Quat) -> tuple[Any, Quat]:
    """att_i_quat_normalize_bounded: (ok, unit quaternion or identity), one test |q|^2 >= 2^-100."""
    w, x, y, z = q
    with _quiet():
        n2 = w * w + x * x + y * y + z * z
        ok = n2 >= NORM2_MIN
        inv = ONE / sqrtf(n2)
        return ok, (
            np.where(ok, w * inv, ONE),
            np.where(ok, x * inv, ZERO),
            np.where(ok, y * inv, ZERO),
            np.where(ok, z * inv, ZERO),
        )


def quat_rotate(q: Quat, v: Vec3) -> Vec3:
    """att_quat_rotate: q * (0, v) * conj(q) for unit q."""
    u = (q[1], q[2], q[3])
    t = vec3_scale(vec3_cross(u, v), TWO)
    return vec3_add(vec3_add(v, vec3_scale(t, q[0])), vec3_cross(u, t))


def quat_rotate_hz(w: Any, x: Any, y: Any, v: Vec3) -> Vec3:
    """att_i_quat_rotate_hz: quat_rotate for (w, x, y, 0), the products by the zero z part dropped."""
    vx, vy, vz = v
    tx = (y * vz) * TWO
    ty = (-(x * vz)) * TWO
    tz = (x * vy - y * vx) * TWO
    return ((vx + tx * w) + y * tz, (vy + ty * w) - x * tz, (vz + tz * w) + (x * ty - y * tx))


def quat_rotate_inv(q: Quat, v: Vec3) -> Vec3:
    """att_quat_rotate_inv: rotate by conj(q) (earth to sensor)."""
    return quat_rotate(quat_conj(q), v)


def quat_from_axis_angle(axis: Vec3, angle: Any) -> Quat:
    """att_quat_from_axis_angle: unit axis, angle in rad."""
    h = f32(angle) * HALF
    s = sinf(h)
    return (cosf(h), axis[0] * s, axis[1] * s, axis[2] * s)


def quat_from_rotvec(rv: Vec3) -> Quat:
    """att_quat_from_rotvec: exponential map; identity for a zero vector."""
    with _quiet():
        angle = vec3_norm(rv)
        ok = angle > ZERO
        h = angle * HALF
        k = sinf(h) / angle
        q = (cosf(h), rv[0] * k, rv[1] * k, rv[2] * k)
        return quat_where(ok, q, quat_identity(np.shape(angle)))


ROTVEC_Z_SMALL = c("0x1p-4")
ROTVEC_C1 = c("-0x1p-3")
ROTVEC_C2 = c("0x1.555556p-9")
ROTVEC_S0 = c("0x1p-1")
ROTVEC_S1 = c("-0x1.555556p-6")
ROTVEC_S2 = c("0x1.111112p-12")


def quat_from_rotvec_fast(rv: Vec3) -> Quat:
    """att_i_quat_from_rotvec_fast: the z^2 series of the exponential map for |rv|^2 <= 1/16, else exact."""
    with _quiet():
        z = vec3_dot(rv, rv)
        k = ROTVEC_S0 + z * (ROTVEC_S1 + z * ROTVEC_S2)
        small = (ONE + z * (ROTVEC_C1 + z * ROTVEC_C2), rv[0] * k, rv[1] * k, rv[2] * k)
        return quat_where(z <= ROTVEC_Z_SMALL, small, quat_from_rotvec(rv))


def quat_from_euler(phi: Any, theta: Any, psi: Any) -> Quat:
    """att_quat_from_euler: ZYX Euler (rad) to q = Qz(psi) Qy(theta) Qx(phi)."""
    hr = f32(phi) * HALF
    hp = f32(theta) * HALF
    hy = f32(psi) * HALF
    cr = cosf(hr)
    sr = sinf(hr)
    cp = cosf(hp)
    sp = sinf(hp)
    cy = cosf(hy)
    sy = sinf(hy)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


def quat_to_euler(q: Quat) -> Vec3:
    """att_quat_to_euler: (roll phi, pitch theta, yaw psi) in rad."""
    w, x, y, z = q
    s = TWO * (w * y - z * x)
    return (
        atan2f(TWO * (w * x + y * z), ONE - TWO * (x * x + y * y)),
        asinf(clampf(s, -ONE, ONE)),
        atan2f(TWO * (w * z + x * y), ONE - TWO * (y * y + z * z)),
    )


def quat_to_matrix(q: Quat) -> list[Any]:
    """att_quat_to_matrix: row-major 3x3 (9 values), v_earth = m v_sensor."""
    w, x, y, z = q
    xx = x * x
    yy = y * y
    zz = z * z
    xy = x * y
    xz = x * z
    yz = y * z
    wx = w * x
    wy = w * y
    wz = w * z
    return [
        ONE - TWO * (yy + zz),
        TWO * (xy - wz),
        TWO * (xz + wy),
        TWO * (xy + wz),
        ONE - TWO * (xx + zz),
        TWO * (yz - wx),
        TWO * (xz - wy),
        TWO * (yz + wx),
        ONE - TWO * (xx + yy),
    ]
