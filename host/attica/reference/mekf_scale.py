"""The MEKF's gyro scale-factor estimate (firmware/src/filters/mekf/att_mekf.c), operation for operation.

The two-stage filter beside the 6-state one (att_mekf.h, "Gyro scale factor"): the scale error's
variance ``p_scale`` and the sensitivity ``V`` (six float32 arrays, one value per instance) of the error
state (dtheta, db) to it. The functions return new values (the inputs are not changed) and compute
what the C functions of the same name compute, in the same order.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from attica.reference import detmath as dm

SCALE_MAX = dm.c("0x1.99999ap-4")
"""ATT_MEKF_SCALE_MAX (0.1f): the largest |scale-factor error| estimated."""
SENS_MAX = dm.c("0x1p+4")
"""ATT_MEKF_SENS_MAX (16): the largest |V|."""
SENS_MAX2 = dm.c("0x1p+8")
"""ATT_MEKF_SENS_MAX^2 (256, exact)."""

Sens = list[Any]
"""Six float32 arrays: the sensitivity V of (dtheta, db) to the scale error."""


def zeros(n: int) -> Sens:
    """att_mekf_scale_v_zero: V = 0."""
    return [np.zeros(n, np.float32) for _ in range(6)]


def where(cond: Any, a: Sens, b: Sens) -> Sens:
    """Entry-wise ``cond ? a : b``."""
    return [np.where(cond, x, y).astype(np.float32) for x, y in zip(a, b, strict=True)]


def gain1(ps: Any, a: Any, s0: Any, y: Any) -> tuple[Any, Any]:
    """att_mekf_scale_gain1: (ds, p_scale after) of a scalar update with sensitivity a."""
    k = (ps * a) / (s0 + ps * (a * a))
    return k * y, ps * (dm.ONE - k * a)


def predict(sv: Sens, r: list[Any], gyro_ok: Any, wr: dm.Vec3, dt: Any) -> Sens:
    """att_mekf_propagate's part: V_theta := V_theta + dt R (u - V_b).

    u = w - b (``wr``) where the gyro sample is usable, else no rotation (-V_b itself, as C negates it).
    """
    w = np.where
    ux = w(gyro_ok, wr[0] - sv[3], -sv[3]).astype(np.float32)
    uy = w(gyro_ok, wr[1] - sv[4], -sv[4]).astype(np.float32)
    uz = w(gyro_ok, wr[2] - sv[5], -sv[5]).astype(np.float32)
    out = list(sv)
    for i in range(3):
        out[i] = sv[i] + dt * (r[3 * i] * ux + r[3 * i + 1] * uy + r[3 * i + 2] * uz)
    return out


def bound(scale: Any, ps: Any, sv: Sens) -> tuple[Any, Any, Sens, Any]:
    """att_mekf_scale_bound with att_mekf_scale_limit: (scale, p_scale, V, ATT_FLAG_CLAMPED raised).

    The slow part is the identity where the fast test passes, so it is computed for every instance.
    """
    with np.errstate(all="ignore"):
        n = ((sv[0] * sv[0] + sv[1] * sv[1]) + (sv[2] * sv[2] + sv[3] * sv[3])) + (
            sv[4] * sv[4] + sv[5] * sv[5]
        )
        hi = scale > SCALE_MAX
        lo = scale < -SCALE_MAX
        nan_s = ~hi & ~lo & ~(scale == scale)
        s = np.where(hi, SCALE_MAX, np.where(lo, -SCALE_MAX, np.where(nan_s, dm.ZERO, scale)))
        bad_p = ~(ps >= dm.ZERO)
        p = np.where(bad_p, dm.ZERO, ps)
        nan_n = ~(n == n)
        k = np.where(nan_n, dm.ZERO, np.where(n > SENS_MAX2, SENS_MAX / dm.sqrtf(n), dm.ONE))
        v = [np.where(k == dm.ZERO, dm.ZERO, x * k).astype(np.float32) for x in sv]
    clamped = hi | lo | nan_s | bad_p | nan_n
    return s.astype(np.float32), p.astype(np.float32), v, clamped
