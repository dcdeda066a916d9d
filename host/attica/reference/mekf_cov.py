"""The covariance algebra of the MEKF (firmware/src/filters/mekf/att_mekf.c), operation for operation.

P is the packed upper triangle of a symmetric 6x6 matrix: a list of 21 float32 arrays (one value per
instance), ``p[ix(i, j)]`` for ``i <= j``. Every function returns new lists (the inputs are not changed)
and computes what the C function of the same name computes, in the same order.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from attica.reference import detmath as dm
from attica.reference import mekf_scale as msc
from attica.reference._common import pd6

P_LEN = 21
PIVOT_MIN = dm.c("0x1p-16")
"""ATT_MEKF_PIVOT_MIN: relative pivot margin of the positive definiteness test."""
SHRINK = dm.c("0x1.ff8p-1")
"""ATT_MEKF_SHRINK = 1 - 2^-10."""

Cov = list[Any]
"""21 float32 arrays: the packed upper triangle."""


def ix(i: int, j: int) -> int:
    """ATT_MEKF_IX: packed index of (i, j), i <= j < 6."""
    return i * (11 - i) // 2 + j


def sx(i: int, j: int) -> int:
    """ATT_MEKF_S: packed index of (i, j) in either order."""
    return ix(i, j) if i <= j else ix(j, i)


def where(cond: Any, a: Cov, b: Cov) -> Cov:
    """Entry-wise ``cond ? a : b``."""
    return [np.where(cond, x, y).astype(np.float32) for x, y in zip(a, b, strict=True)]


def diag(a: Any, b: Any, n: int) -> Cov:
    """The packed covariance with a on the attitude and b on the bias diagonal (att_mekf_p_reset)."""
    p = [np.zeros(n, np.float32) for _ in range(P_LEN)]
    for i in range(3):
        p[ix(i, i)] = np.broadcast_to(np.asarray(a, np.float32), (n,)).copy()
        p[ix(3 + i, 3 + i)] = np.broadcast_to(np.asarray(b, np.float32), (n,)).copy()
    return p


def predict(p: Cov, r: list[Any], hdt: Any, dt: Any, qa: Any, qb: Any) -> Cov:
    """att_mekf_predict: Phi P Phi^T + Q written out (r: R row-major)."""
    out = list(p)
    h = [None] * 9
    for i in range(3):
        for j in range(3):
            m = r[3 * i] * p[sx(3, 3 + j)] + r[3 * i + 1] * p[sx(4, 3 + j)] + r[3 * i + 2] * p[sx(5, 3 + j)]
            hh = p[ix(i, 3 + j)] - hdt * m
            h[3 * i + j] = hh
            out[ix(i, 3 + j)] = hh - hdt * m
    for i in range(3):
        for j in range(i, 3):
            nij = r[3 * i] * h[3 * j] + r[3 * i + 1] * h[3 * j + 1] + r[3 * i + 2] * h[3 * j + 2]
            nji = r[3 * j] * h[3 * i] + r[3 * j + 1] * h[3 * i + 1] + r[3 * j + 2] * h[3 * i + 2]
            a = p[ix(i, j)] - dt * (nij + nji)
            if i == j:
                a = a + qa
            out[ix(i, j)] = a
    for k in (3, 4, 5):
        out[ix(k, k)] = p[ix(k, k)] + qb
    return out


def innov(p: Cov, r: Any, y0: Any, y1: Any) -> tuple[Any, Any, Any, Any, Any]:
    """att_mekf_innov: (s00, s01, s11, det, dn) of S = A_xy + r I2, dn = y^T adj(S) y."""
    s00 = p[ix(0, 0)] + r
    s01 = p[ix(0, 1)]
    s11 = p[ix(1, 1)] + r
    det = s00 * s11 - s01 * s01
    dn = y0 * y0 * s11 - dm.TWO * y0 * y1 * s01 + y1 * y1 * s00
    return s00, s01, s11, det, dn


def recover(p: Cov, soft: Any, y0: Any, y1: Any, p_max: Any) -> Cov:
    """att_mekf_recover: the tilt variances grow by |y|^2 / soft, by at most p_max (NaN: p_max)."""
    out = list(p)
    with np.errstate(all="ignore"):
        add = (y0 * y0 + y1 * y1) / soft
    add = np.where(add <= p_max, add, p_max).astype(np.float32)
    out[ix(0, 0)] = p[ix(0, 0)] + add
    out[ix(1, 1)] = p[ix(1, 1)] + add
    return out


def accel_apply(
    p: Cov,
    v: tuple[Any, Any, Any, Any, Any],
    y0: Any,
    y1: Any,
    gate_on: Any,
    soft: Any,
    sv: list[Any],
    ps: Any,
    upd_bias: Any = True,
) -> tuple[Cov, list[Any], list[Any], Any, Any]:
    """att_mekf_accel_apply: (P - K (lambda S) K^T, dx = K y + V' ds, V' = V - K H V, ds, p_scale).

    Where ``upd_bias`` is false (n_upd 3, a recovery) the bias is a consider state (Schmidt): its rows of
    P and V are kept and its dx is 0.
    """
    s00, s01, s11, det, dn = v
    g0 = [p[ix(0, i)] for i in range(6)]
    g1 = [p[sx(1, i)] for i in range(6)]
    ks = np.where(gate_on & (dn > soft * det), soft / dn, dm.ONE / det)
    a0 = s11 * ks
    a1 = -(s01 * ks)
    a2 = s00 * ks
    sa0, sa1 = sv[0], sv[1]
    m0 = a0 * sa0 + a1 * sa1
    m1 = a1 * sa0 + a2 * sa1
    r = ps / (dm.ONE + ps * (sa0 * m0 + sa1 * m1))
    ds = r * (m0 * y0 + m1 * y1)
    out = list(p)
    dx = []
    v_out = []
    for i in range(6):
        k0 = g0[i] * a0 + g1[i] * a1
        k1 = g0[i] * a1 + g1[i] * a2
        upd = True if i < 3 else upd_bias
        v_out.append(np.where(upd, sv[i] - (k0 * sa0 + k1 * sa1), sv[i]).astype(np.float32))
        dx.append(np.where(upd, (k0 * y0 + k1 * y1) + v_out[i] * ds, dm.ZERO).astype(np.float32))
        for j in range(i, 6):
            out[ix(i, j)] = np.where(upd, p[ix(i, j)] - (k0 * g0[j] + k1 * g1[j]), p[ix(i, j)]).astype(
                np.float32
            )
    return out, dx, v_out, ds, r


def mag_apply(
    p: Cov, hx: Any, hy: Any, r_mag: Any, gate: Any, soft: Any, y: Any, sv: list[Any]
) -> tuple[Any, Cov, Any, list[Any], list[Any]]:
    """att_mekf_mag_apply: (accepted, Joseph-form P, dz, db, V) of the heading update."""
    g = [p[sx(i, 2)] + hx * p[sx(i, 0)] + hy * p[sx(i, 1)] for i in range(6)]
    s = g[2] + hx * g[0] + hy * g[1] + r_mag
    y2 = y * y
    gate_on = gate > dm.ZERO
    ok = ~(gate_on & (y2 > gate * s))
    k = np.where(gate_on & (y2 > soft * s), soft / y2, dm.ONE / s)
    kg = [k * gi for gi in g]
    out = list(p)
    for i in range(6):
        for j in range(2 if i < 2 else i, 6):
            out[ix(i, j)] = p[ix(i, j)] - kg[i] * g[j]
    sa = (sv[2] + hx * sv[0]) + hy * sv[1]
    v_out = list(sv[:2]) + [sv[i] - kg[i] * sa for i in range(2, 6)]
    return ok, out, kg[2] * y, [kg[3] * y, kg[4] * y, kg[5] * y], v_out


def rest_apply(
    p: Cov, r_rest: Any, gyr: dm.Vec3, bias: dm.Vec3, sv: list[Any], ps: Any, scale: Any
) -> tuple[Cov, list[Any], list[Any], list[Any], Any, Any]:
    """att_mekf_rest_update's algebra: (P, dtheta, bias, V, p_scale, scale) after three scalar updates."""
    zero = np.zeros(np.shape(p[0]), np.float32)
    dth = [zero, zero, zero]
    b = list(bias)
    v = list(sv)
    out = list(p)
    for k in range(3):
        sa = v[3 + k]
        g = [out[sx(i, 3 + k)] for i in range(6)]
        sk = g[3 + k] + r_rest
        ks = dm.ONE / sk
        y = gyr[k] - b[k]
        ds, ps = msc.gain1(ps, sa, sk, y)
        scale = scale + ds
        nxt = list(out)
        for i in range(6):
            gk = g[i] * ks
            v[i] = v[i] - gk * sa
            if i < 3:
                dth[i] = dth[i] + (gk * y + v[i] * ds)
            else:
                b[i - 3] = b[i - 3] + (gk * y + v[i] * ds)
            for j in range(i, 6):
                nxt[ix(i, j)] = out[ix(i, j)] - gk * g[j]
        out = nxt
    return out, dth, b, v, ps, scale


def yaw_reset(p: Cov, var: Any) -> Cov:
    """att_mekf_yaw_reset: the heading row and column to (0, .., var, .., 0).

    ``var`` is p0_att at the alignment, p_max when a new reference field is adopted.
    """
    out = list(p)
    zero = np.zeros(np.shape(p[0]), np.float32)
    for i, j in ((0, 2), (1, 2), (2, 3), (2, 4), (2, 5)):
        out[ix(i, j)] = zero
    out[ix(2, 2)] = np.broadcast_to(np.asarray(var, np.float32), np.shape(p[0])).copy()
    return out


def pd(p: Cov) -> Any:
    """att_mekf_pd: att_i_pd6 with the margin 2^-16."""
    return pd6(p, PIVOT_MIN)


def shrink(p: Cov, s: Any) -> Cov:
    """att_mekf_shrink: every off-diagonal entry times s."""
    out = list(p)
    for i in range(6):
        for j in range(i + 1, 6):
            out[ix(i, j)] = p[ix(i, j)] * s
    return out


def condition(p: Cov, p_max: Any, p0_bias: Any) -> tuple[Cov, Any]:
    """att_mekf_condition with att_mekf_repair: (P, ATT_FLAG_CLAMPED raised)."""
    with np.errstate(all="ignore"):
        caps = [p_max, p_max, p_max, p0_bias, p0_bias, p0_bias]
        dv = [p[ix(i, i)] for i in range(6)]
        diag_ok = np.ones(np.shape(p[0]), np.bool_)
        for i in range(6):
            diag_ok = diag_ok & (dv[i] <= caps[i]) & (dv[i] > dm.ZERO)
        ok0 = diag_ok & pd(p)
        # the diagonal repair (only used where diag_ok is false)
        fixed = list(p)
        d = []
        bad = np.zeros(np.shape(p[0]), np.bool_)
        for i in range(6):
            over = dv[i] > caps[i]
            nonpos = ~over & ~(dv[i] > dm.ZERO)
            d.append(np.where(over, dm.sqrtf(caps[i] / dv[i]), dm.ONE).astype(np.float32))
            fixed[ix(i, i)] = np.where(over | nonpos, caps[i], dv[i]).astype(np.float32)
            bad = bad | nonpos
        for i in range(6):
            for j in range(i + 1, 6):
                fixed[ix(i, j)] = (p[ix(i, j)] * d[i]) * d[j]
        base = where(diag_ok, p, fixed)
        ok1 = ~diag_ok & pd(fixed)
        shrunk = shrink(base, SHRINK)
        ok2 = pd(shrunk)
        dropped = shrink(base, dm.ZERO)
    repaired = where(ok2, shrunk, dropped)
    out = where(ok0, p, where(ok1, fixed, repaired))
    clamped = (~diag_ok & bad) | (~ok0 & ~ok1)
    return out, clamped
