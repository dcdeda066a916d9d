"""The MEKF's reference field and magnetometer phases (firmware/src/filters/mekf/att_mekf.c), in lockstep.

att_mekf_set_m0 with att_mekf_m0_limits, att_mekf_align, att_mekf_heading, att_mekf_lp_turn,
att_mekf_yaw_reset, att_mekf_start, att_mekf_mag, att_mekf_mag_first and att_mekf_ref_block (the learnt
reference, :mod:`attica.reference.magref`) as functions of the filter ``f``
(C's coefficients ``c`` and state ``st``) and the step's work record ``wk``: every C branch an
``np.where``, every operation the C one in the same order. The driver is
:meth:`attica.reference.mekf.Mekf.step`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from attica.reference import detmath as dm
from attica.reference import magref as mr
from attica.reference import mekf_cov as cv
from attica.reference import mekf_scale as msc
from attica.reference import sensor
from attica.reference.ars import A_MIN
from attica.settings import Flag

if TYPE_CHECKING:
    from attica.reference.mekf import Mekf, Work

_U0 = np.uint32(0)
PIO2 = dm.c("0x1.921fb6p+0")

M0Parts = tuple[dm.Vec3, dm.Vec3, Any, Any, Any, Any, Any, Any]
"""(m0, m0_ref, mag_hx, mag_hy, m0_lo, m0_hi, dip_lo, dip_hi) as att_mekf_set_m0 stores them."""


def _u(flag: Flag) -> np.uint32:
    return np.uint32(flag.value)


# --- the reference field -----------------------------------------------------------------------


def derive_m0(f: Mekf, m0: dm.Vec3) -> tuple[Any, M0Parts]:
    """Mirror of att_mekf_set_m0 / att_mekf_m0_limits: whether it succeeds and what it stores."""
    with np.errstate(all="ignore"):
        ok, _ = dm.vec3_normalize(m0)
        norm = dm.vec3_norm(m0)
        ref_ok, ref = dm.vec3_normalize((m0[0], m0[1], f._zeros))
        cz = m0[2] / dm.sqrtf(m0[0] * m0[0] + m0[1] * m0[1])
        hx = np.where(ref_ok, -(cz * ref[0]), dm.ZERO).astype(np.float32)
        hy = np.where(ref_ok, -(cz * ref[1]), dm.ZERO).astype(np.float32)
        nr = f.mag_norm_reject
        on = nr > dm.ZERO
        lo = np.where(on, norm * (dm.ONE - nr), dm.ZERO)
        lo = np.where(ref_ok, lo, dm.INF)  # no horizontal reference: every sample rejected
        hi = np.where(on, norm * (dm.ONE + nr), f.mag_range)
        t = f.mag_dip_reject
        dip = dm.atan2f(m0[2], dm.sqrtf(m0[0] * m0[0] + m0[1] * m0[1]))
        d_lo = dip - t
        d_hi = dip + t
        dip_lo = np.where((t > dm.ZERO) & (d_lo > -PIO2), dm.sinf(d_lo), -dm.TWO)
        dip_hi = np.where((t > dm.ZERO) & (d_hi < PIO2), dm.sinf(d_hi), dm.TWO)
    return ok, (m0, ref, hx, hy, lo, hi, dip_lo, dip_hi)


def commit_m0(f: Mekf, cond: Any, parts: M0Parts, new_block: bool = True) -> None:
    """Mirror of att_mekf_set_m0's stores, where ``cond``: the parts of :func:`derive_m0` into ``f``.

    ``new_block`` False: only att_mekf_m0_limits' (a retune keeps the learnt reference's block).
    """
    m0, ref, hx, hy, lo, hi, dip_lo, dip_hi = parts
    w = np.where
    f.m0 = dm.vec3_where(cond, m0, f.m0)
    f.m0_ref = dm.vec3_where(cond, ref, f.m0_ref)
    f.mag_hx = w(cond, hx, f.mag_hx).astype(np.float32)
    f.mag_hy = w(cond, hy, f.mag_hy).astype(np.float32)
    f.m0_lo = w(cond, lo, f.m0_lo).astype(np.float32)
    f.m0_hi = w(cond, hi, f.m0_hi).astype(np.float32)
    f.dip_lo = w(cond, dip_lo, f.dip_lo).astype(np.float32)
    f.dip_hi = w(cond, dip_hi, f.dip_hi).astype(np.float32)
    f.m0_valid = f.m0_valid | cond
    if new_block:
        mr.clear(f, cond)


def align(f: Mekf, q: dm.Quat, mag: dm.Vec3) -> tuple[Any, dm.Quat, dm.Vec3]:
    """Mirror of att_mekf_align: (ok, q turned about z so the field is at the declination's azimuth, m0)."""
    with np.errstate(all="ignore"):
        me = dm.quat_rotate(q, mag)
        ok1, _ = dm.vec3_normalize(me)
        qa = dm.quat_mul(dm.quat_from_axis_angle(f._up, dm.atan2f(me[0], me[1]) - f.decl), q)
        ok2, qa = dm.quat_normalize_bounded(qa)
        me = dm.quat_rotate(qa, mag)
        h = dm.sqrtf(me[0] * me[0] + me[1] * me[1])
        m0 = (h * f.decl_sin, h * f.decl_cos, me[2])
    return ok1 & ok2, qa, m0


def heading(f: Mekf, me: dm.Vec3, mnorm: Any) -> tuple[Any, Any, Any]:
    """Mirror of att_mekf_heading: (usable, y = 2 sin(alpha / 2), rejected by norm or dip)."""
    with np.errstate(all="ignore"):
        reject = (
            (mnorm < f.m0_lo) | (mnorm > f.m0_hi) | (me[2] < f.dip_lo * mnorm) | (me[2] > f.dip_hi * mnorm)
        )
        h2 = me[0] * me[0] + me[1] * me[1]
        ok_h = h2 >= dm.NORM2_MIN
        hn = dm.sqrtf(h2)
        rx, ry, _ = f.m0_ref
        a = hn + (me[0] * rx + me[1] * ry)
        b = me[0] * ry - me[1] * rx
        arc = (dm.TWO * b) / dm.sqrtf((dm.TWO * hn) * a)
        y = np.where(a > A_MIN * hn, arc, dm.TWO).astype(np.float32)
    return ~reject & ok_h, y, reject


def lp_turn(cond: Any, qw: Any, qz: Any, lp1: dm.Vec3, lp2: dm.Vec3) -> tuple[dm.Vec3, dm.Vec3]:
    """Mirror of att_mekf_lp_turn where ``cond``: lp1, lp2 turned about the earth z axis by (qw, 0, 0, qz)."""
    cz = dm.ONE - dm.TWO * (qz * qz)
    sz = dm.TWO * (qw * qz)
    t1 = (cz * lp1[0] - sz * lp1[1], sz * lp1[0] + cz * lp1[1], lp1[2])
    t2 = (cz * lp2[0] - sz * lp2[1], sz * lp2[0] + cz * lp2[1], lp2[2])
    return dm.vec3_where(cond, t1, lp1), dm.vec3_where(cond, t2, lp2)


def yaw_reset(cond: Any, p: cv.Cov, sv: msc.Sens, var: Any) -> tuple[cv.Cov, msc.Sens]:
    """Mirror of att_mekf_yaw_reset where ``cond``: (P, V) with the heading's row reset (variance ``var``)."""
    v = list(sv)
    v[2] = np.where(cond, dm.ZERO, v[2]).astype(np.float32)
    return cv.where(cond, cv.yaw_reset(p, var), p), v


# --- the phases ----------------------------------------------------------------------------------


class Start(NamedTuple):
    """The start of att_mekf_start for every instance (stored for the waiting ones by Mekf._commit)."""

    init_now: Any
    """Waiting, with a usable accel sample: started by this step."""
    init_mag: Any
    """Started with the yaw from the mag sample (m0 set, the heading's variance reset)."""
    q: dm.Quat
    """The start attitude."""
    lp: dm.Vec3
    """The low-pass stages' start, R a."""
    parts: M0Parts
    """The reference field where ``init_mag`` (:func:`derive_m0`)."""
    flags: Any
    """INITIALISED, NOT_READY (no usable accel sample: C's driver) and MAG_REJECTED of the waiting."""


def start(f: Mekf, a: dm.Vec3, m: dm.Vec3, accel_ok: Any, mag_ok: Any) -> Start:
    """Mirror of att_mekf_start: roll and pitch from ``a``, the yaw from ``m`` when usable."""
    w = np.where
    waiting = ~f.initialised
    init_now = waiting & accel_ok
    t = sensor.tilt(a)
    _, q_tilt = dm.quat_normalize_bounded(dm.quat_from_euler(t[0], t[1], f._zeros))
    ok_a0, q_a0, m0_a0 = align(f, q_tilt, m)
    ok_d0, parts0 = derive_m0(f, m0_a0)
    good0 = ok_a0 & ok_d0
    init_mag = init_now & mag_ok & good0
    q_start = dm.quat_where(init_mag, q_a0, q_tilt)
    flags = w(waiting, w(accel_ok, _u(Flag.INITIALISED), _u(Flag.NOT_READY)), _U0)
    flags = flags | w(init_now & mag_ok & ~good0, _u(Flag.MAG_REJECTED), _U0)
    lp_init = dm.quat_rotate(q_start, a)
    return Start(init_now, init_mag, q_start, lp_init, parts0, flags)


def mag(f: Mekf, wk: Work, use_corr: Any, m: dm.Vec3) -> Any:
    """Mirror of att_mekf_mag: the heading update where ``use_corr``; returns its flags."""
    w = np.where
    me = dm.quat_rotate(wk.q, m)
    ok_h, ym, gated = heading(f, me, wk.mnorm)
    wk.mz = w(use_corr, me[2], wk.mz).astype(np.float32)
    wk.accepted = use_corr & ~gated
    wk.gated = use_corr & gated
    ok_g, p_m, dz, db, sv_m = cv.mag_apply(
        wk.p, f.mag_hx, f.mag_hy, f.r_mag, f.mag_gate, f.mag_soft, ym, wk.sv
    )
    mag_apply = use_corr & ok_h & ok_g
    wk.p = cv.where(mag_apply, p_m, wk.p)
    wk.sv = msc.where(mag_apply, sv_m, wk.sv)
    dqz = dm.quat_from_rotvec_fast((f._zeros, f._zeros, dz))
    wk.q = dm.quat_where(mag_apply, dm.quat_mul_z(dqz[0], dqz[3], wk.q), wk.q)
    wk.bias = dm.vec3_where(mag_apply, dm.vec3_add(wk.bias, (db[0], db[1], db[2])), wk.bias)
    wk.lp1, wk.lp2 = lp_turn(mag_apply & f.lp_on, dqz[0], dqz[3], wk.lp1, wk.lp2)
    flags = w(mag_apply, _u(Flag.BIAS_UPDATED), _U0)
    return flags | w(use_corr & ~mag_apply, _u(Flag.MAG_REJECTED), _U0)


def mag_first(f: Mekf, wk: Work, first: Any, m: dm.Vec3) -> Any:
    """Mirror of att_mekf_mag_first where ``first``: the yaw alignment, or m0 from the sample; its flags."""
    w = np.where
    q = wk.q
    ok_al, q_al, m0_al = align(f, q, m)
    ok_dl, parts_l = derive_m0(f, m0_al)
    use_align = first & f.init_from_sensors
    good_l = use_align & ok_al & ok_dl
    ok_ds, parts_s = derive_m0(f, dm.quat_rotate(q, m))
    use_set = first & ~f.init_from_sensors
    # the turn applied, q_al q* = (w, 0, 0, z) (its x, y are rounding: dropped)
    tw = q_al[0] * q[0] + q_al[1] * q[1] + q_al[2] * q[2] + q_al[3] * q[3]
    tz = q_al[3] * q[0] - q_al[0] * q[3] + q_al[2] * q[1] - q_al[1] * q[2]
    wk.lp1, wk.lp2 = lp_turn(good_l & f.lp_on, tw, tz, wk.lp1, wk.lp2)
    wk.q = dm.quat_where(good_l, q_al, q)
    wk.p, wk.sv = yaw_reset(good_l, wk.p, wk.sv, f.p0_att)
    commit_m0(f, good_l, parts_l)
    commit_m0(f, use_set & ok_ds, parts_s)
    flags = w(good_l, _u(Flag.INITIALISED), _U0)
    return flags | w((use_align & ~good_l) | (use_set & ~ok_ds), _u(Flag.MAG_REJECTED), _U0)


def ref_count(f: Mekf, wk: Work, cond: Any) -> None:
    """Mirror of the learnt reference's count where ``cond`` and att_mekf_ref_block at a block's end."""
    end = mr.count(f, cond, wk.accepted, wk.gated, wk.mnorm, wk.mz)
    if not end.any():
        return
    follow, adopt, n, s = mr.block(f, end, f.m0)
    ok, parts = derive_m0(f, mr.m0_from(f.m0, n, s, f.decl_sin, f.decl_cos))
    commit_m0(f, (follow | adopt) & ok, parts)
    wk.p, wk.sv = yaw_reset(adopt, wk.p, wk.sv, f.p_max)  # the heading is unknown against the new field
