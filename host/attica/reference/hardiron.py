"""Mirror of the on-device hard-iron estimate (firmware att_hardiron.h, att_core.h's att_i_hi_*), in lockstep.

Shared by :mod:`attica.reference.mars` and :mod:`attica.reference.mekf`: the functions work on the owner
``f``, which holds the coefficients (C's ``c.hi``) and the state (C's ``st.hi``) as attributes named
``hi_<field>``, one array element per instance. Every C branch an ``np.where``, every operation the C one
in the same order.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from attica.reference import detmath as dm
from attica.reference import sensor
from attica.reference._common import REC_CLIP

_U0 = np.uint32(0)
_U1 = np.uint32(1)

KEY_S = dm.ONE  # ATT_HI_KEY_S, s
KEY_N_MAX = np.uint32(1024)  # ATT_HI_KEY_N_MAX
KEY_V2 = dm.c("0x1.f56bfcp-5")  # ATT_HI_KEY_V2: sin^2(0.25)
OBS = dm.ONE  # ATT_HI_OBS
FOUR = dm.c("0x1p+2")
QUARTER = dm.c("0x1p-2")


def state_spec(prefix: str) -> dict[str, str]:
    """StateSpec entries of att_hardiron_t under the C path ``prefix`` (e.g. ``st.hi``)."""
    layouts = (
        ("offset", "vec3"),
        ("target", "vec3"),
        ("d", "quat"),
        ("m_key", "vec3"),
        ("w_key", "vec3"),
        ("info", "f32x10"),
        ("z", "f32x4"),
        ("lag", "f32"),
        ("key_steps", "u32"),
        ("observable", "bool"),
    )
    return {f"{prefix}.{name}": f"{layout}:hi_{name}" for name, layout in layouts}


def coeff_spec(prefix: str) -> dict[str, str]:
    """StateSpec entries of att_hardiron_params_t under the C path ``prefix`` (e.g. ``c.hi``)."""
    layouts = (
        ("k_forget", "f32"),
        ("step_max", "f32"),
        ("gate", "f32"),
        ("limit", "f32"),
        ("key_n", "u32"),
        ("on", "bool"),
    )
    return {f"{prefix}.{name}": f"{layout}:hi_{name}" for name, layout in layouts}


def params(f: Any, dt: Any, tau: Any, rate: Any, gate: Any, limit: Any) -> None:
    """att_i_hi_params: the coefficients into ``f`` (s, uT/s, the norm gate, the target's bound in uT)."""
    n = sensor.samples(KEY_S, dt)
    f.hi_on = tau > dm.ZERO
    f.hi_limit = np.asarray(limit, np.float32).copy()
    with np.errstate(all="ignore"):
        f.hi_k_forget = np.where(f.hi_on, dt / tau, dm.ZERO).astype(np.float32)
    f.hi_step_max = (rate * dt).astype(np.float32)
    f.hi_gate = np.asarray(gate, np.float32).copy()
    f.hi_key_n = np.where(n < _U1, _U1, np.where(n > KEY_N_MAX, KEY_N_MAX, n)).astype(np.uint32)


def reset(f: Any, n: int) -> None:
    """att_i_hi_reset: offset 0, no information, no keyframe (every instance)."""
    z = np.zeros(n, np.float32)
    f.hi_offset = (z.copy(), z.copy(), z.copy())
    f.hi_target = (z.copy(), z.copy(), z.copy())
    f.hi_d = (np.ones(n, np.float32), z.copy(), z.copy(), z.copy())
    f.hi_m_key = (z.copy(), z.copy(), z.copy())
    f.hi_w_key = (z.copy(), z.copy(), z.copy())
    f.hi_info = [z.copy() for _ in range(10)]
    f.hi_z = [z.copy() for _ in range(4)]
    f.hi_lag = z.copy()
    f.hi_key_steps = np.zeros(n, np.uint32)
    f.hi_observable = np.zeros(n, np.bool_)


def retune(f: Any) -> None:
    """att_i_hi_retune: the target and the applied offset within the new bound (mag_range) per axis."""
    lim = f.hi_limit
    f.hi_target = tuple(dm.clampf(v, -lim, lim) for v in f.hi_target)
    f.hi_offset = tuple(dm.clampf(v, -lim, lim) for v in f.hi_offset)


def reset_where(f: Any, cond: Any) -> None:
    """att_i_hi_reset where ``cond`` (a retune that turns the estimate on or off, a new calibration)."""
    fresh = type("Fresh", (), {})()
    reset(fresh, np.shape(cond)[0])
    for name in ("hi_offset", "hi_target", "hi_d", "hi_m_key", "hi_w_key", "hi_info", "hi_z"):
        old, new = getattr(f, name), getattr(fresh, name)
        setattr(f, name, type(old)(np.where(cond, b, a).astype(np.float32) for a, b in zip(old, new)))
    f.hi_lag = np.where(cond, dm.ZERO, f.hi_lag).astype(np.float32)
    f.hi_key_steps = np.where(cond, _U0, f.hi_key_steps).astype(np.uint32)
    f.hi_observable = f.hi_observable & ~cond


def gyro_ok(check_flags: Any, g: dm.Vec3, gyro_range: Any) -> Any:
    """att_i_hi_gyro_ok: a valid gyro sample with no component at the clip level REC_CLIP gyro_range."""
    clip = (REC_CLIP * np.asarray(gyro_range, np.float32)).astype(np.float32)
    return (check_flags == _U0) & (dm.absf(g[0]) < clip) & (dm.absf(g[1]) < clip) & (dm.absf(g[2]) < clip)


def _solve(f: Any, cond: Any) -> None:
    """att_i_hi_solve where ``cond``: the lag eliminated, the 3x3 system solved when observable."""
    i = f.hi_info
    zz = f.hi_z
    with np.errstate(all="ignore"):
        schur = i[9] > dm.ZERO
        u0 = i[3] / i[9]
        u1 = i[6] / i[9]
        u2 = i[8] / i[9]
        w = np.where
        a = [
            w(schur, i[0] - u0 * i[3], i[0]),
            w(schur, i[1] - u0 * i[6], i[1]),
            w(schur, i[2] - u0 * i[8], i[2]),
            w(schur, i[4] - u1 * i[6], i[4]),
            w(schur, i[5] - u1 * i[8], i[5]),
            w(schur, i[7] - u2 * i[8], i[7]),
        ]
        a = [x.astype(np.float32) for x in a]
        z0 = w(schur, zz[0] - u0 * zz[3], zz[0]).astype(np.float32)
        z1 = w(schur, zz[1] - u1 * zz[3], zz[1]).astype(np.float32)
        z2 = w(schur, zz[2] - u2 * zz[3], zz[2]).astype(np.float32)
        c00 = a[3] * a[5] - a[4] * a[4]
        c01 = a[2] * a[4] - a[1] * a[5]
        c02 = a[1] * a[4] - a[2] * a[3]
        c11 = a[0] * a[5] - a[2] * a[2]
        c12 = a[1] * a[2] - a[0] * a[4]
        c22 = a[0] * a[3] - a[1] * a[1]
        det = a[0] * c00 + a[1] * c01 + a[2] * c02
        tr = a[0] + a[3] + a[5]
        ok = cond & (det >= OBS * (QUARTER * (tr * tr))) & (det > dm.ZERO)
        lim = f.hi_limit
        h = (
            dm.clampf((c00 * z0 + c01 * z1 + c02 * z2) / det, -lim, lim),
            dm.clampf((c01 * z0 + c11 * z1 + c12 * z2) / det, -lim, lim),
            dm.clampf((c02 * z0 + c12 * z1 + c22 * z2) / det, -lim, lim),
        )
        lag = w(schur, (zz[3] - (i[3] * h[0] + i[6] * h[1] + i[8] * h[2])) / i[9], dm.ZERO)
    f.hi_target = dm.vec3_where(ok, h, f.hi_target)
    f.hi_lag = np.where(ok, lag, f.hi_lag).astype(np.float32)
    f.hi_observable = f.hi_observable | ok


def _pair(f: Any, cond: Any, m: dm.Vec3, w: dm.Vec3) -> None:
    """att_i_hi_pair where ``cond``: the keyframe pair ending at the raw sample ``m`` with the rate ``w``."""
    d = f.hi_d
    with np.errstate(all="ignore"):
        dc = dm.quat_conj(d)
        y = dm.vec3_sub(m, dm.quat_rotate(dc, f.hi_m_key))
        r = dm.vec3_sub(y, dm.quat_rotate(d, y))
        b = dm.vec3_sub(dm.vec3_cross(w, m), dm.quat_rotate(dc, dm.vec3_cross(f.hi_w_key, f.hi_m_key)))
        ab = dm.vec3_sub(b, dm.quat_rotate(d, b))
        v2 = d[1] * d[1] + d[2] * d[2] + d[3] * d[3]
        fk = dm.ONE - (f.hi_key_steps - _U1).astype(np.float32) * f.hi_k_forget
        na = dm.vec3_norm(dm.vec3_sub(m, f.hi_target))
        nb = dm.vec3_norm(dm.vec3_sub(f.hi_m_key, f.hi_target))
        changed = f.hi_observable & (f.hi_gate > dm.ZERO) & (dm.absf(na - nb) > f.hi_gate * nb)
        use = cond & ~changed
        fk = np.where(fk > dm.ZERO, fk, dm.ZERO).astype(np.float32)
        a = f.hi_info
        new = (
            fk * a[0] + FOUR * (v2 - d[1] * d[1]),
            fk * a[1] - FOUR * (d[1] * d[2]),
            fk * a[2] - FOUR * (d[1] * d[3]),
            fk * a[3] + ab[0],
            fk * a[4] + FOUR * (v2 - d[2] * d[2]),
            fk * a[5] - FOUR * (d[2] * d[3]),
            fk * a[6] + ab[1],
            fk * a[7] + FOUR * (v2 - d[3] * d[3]),
            fk * a[8] + ab[2],
            fk * a[9] + dm.vec3_dot(b, b),
        )
        zz = f.hi_z
        zn = (fk * zz[0] + r[0], fk * zz[1] + r[1], fk * zz[2] + r[2], fk * zz[3] + dm.vec3_dot(b, y))
    f.hi_info = [np.where(use, x, o).astype(np.float32) for x, o in zip(new, a)]
    f.hi_z = [np.where(use, x, o).astype(np.float32) for x, o in zip(zn, zz)]
    _solve(f, use)


def step(f: Any, cond: Any, dt: Any, w: dm.Vec3, gyro_ok: Any, m: dm.Vec3, mag_ok: Any) -> None:
    """att_i_hi_step where ``cond``: w the bias-corrected rate, m the raw mag sample."""
    keyed = cond & (f.hi_key_steps > _U0)
    with np.errstate(all="ignore"):
        dn = dm.quat_mul(f.hi_d, dm.quat_from_rotvec_fast(dm.vec3_scale(w, dt)))
    integ = keyed & gyro_ok & (f.hi_key_steps <= np.uint32(2) * f.hi_key_n)
    f.hi_d = dm.quat_where(integ, dn, f.hi_d)
    ks = np.where(integ, f.hi_key_steps + _U1, np.where(keyed, _U0, f.hi_key_steps))
    f.hi_key_steps = ks.astype(np.uint32)
    d = f.hi_d
    v2 = d[1] * d[1] + d[2] * d[2] + d[3] * d[3]
    at = cond & mag_ok
    close = at & (f.hi_key_steps > _U0) & ((v2 >= KEY_V2) | (f.hi_key_steps > f.hi_key_n))
    _pair(f, close, m, w)
    start = close | (at & (f.hi_key_steps == _U0) & gyro_ok)
    f.hi_m_key = dm.vec3_where(start, m, f.hi_m_key)
    f.hi_w_key = dm.vec3_where(start, w, f.hi_w_key)
    ident = dm.quat_identity(np.shape(f.hi_key_steps))
    f.hi_d = dm.quat_where(start, ident, f.hi_d)
    f.hi_key_steps = np.where(start, _U1, f.hi_key_steps).astype(np.uint32)
    move = cond & f.hi_observable
    h = f.hi_step_max
    o, t = f.hi_offset, f.hi_target
    with np.errstate(all="ignore"):
        moved = (
            o[0] + dm.clampf(t[0] - o[0], -h, h),
            o[1] + dm.clampf(t[1] - o[1], -h, h),
            o[2] + dm.clampf(t[2] - o[2], -h, h),
        )
    f.hi_offset = dm.vec3_where(move, moved, f.hi_offset)


def apply(f: Any, cond: Any, m: dm.Vec3) -> tuple[dm.Vec3, Any]:
    """att_i_hi_correct where ``cond`` (else ``m``), and the corrected sample's norm (0 where not)."""
    with np.errstate(all="ignore"):
        mc = dm.vec3_sub(m, f.hi_offset)
        n = dm.vec3_norm(mc)
    return dm.vec3_where(cond, mc, m), np.where(cond, n, dm.ZERO).astype(np.float32)
