"""Mirror of firmware/src/filters/mekf/att_mekf.c: multiplicative (error-state) EKF, instances in lockstep.

The covariance algebra lives in :mod:`attica.reference.mekf_cov`; this module holds the coefficients,
the reference field, the initialisation and the step, with every C branch as ``np.where``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.reference import detmath as dm
from attica.reference import mekf_cov as cv
from attica.reference import mekf_scale as msc
from attica.reference import sensor
from attica.reference._common import StateSpec, carry_state, run_steps, setting, split3, stack
from attica.reference.ars import A_MIN, align_up
from attica.settings import Flag, MekfSettings

_U0 = np.uint32(0)
PIO2 = dm.c("0x1.921fb6p+0")
THREE = dm.c("0x1.8p+1")
QUARTER = dm.c("0x1p-2")
GATED_MAX = np.uint32(0xFFFFFFFF)
SQRT2 = dm.c("0x1.6a09e6p+0")
BW_Q = dm.c("0x1.a8279ap-2")
"""sqrt(2) and sqrt(2) - 1: the Butterworth accel low-pass (ATT_MEKF_SQRT2, ATT_MEKF_BW_Q)."""

_M0Parts = tuple[dm.Vec3, dm.Vec3, Any, Any, Any, Any, Any, Any]
"""(m0, m0_ref, mag_hx, mag_hy, m0_lo, m0_hi, dip_lo, dip_hi) as att_mekf_set_m0 stores them."""


def _u(flag: Flag) -> np.uint32:
    return np.uint32(flag.value)


def _split4(x: Any, n: int) -> dm.Quat:
    a = np.broadcast_to(np.asarray(x, dtype=np.float32), (n, 4))
    return (a[:, 0].copy(), a[:, 1].copy(), a[:, 2].copy(), a[:, 3].copy())


class Mekf:
    """MEKF reference: ``n`` independent instances sharing one settings object.

    Settings fields may be scalars or length-``n`` sequences (one value per instance); vector fields
    may be given as (3,)/(4,) or (n, 3)/(n, 4). Settings are not validated here (att_mekf_init does).
    """

    STATE: StateSpec = {
        "st.q": "quat",
        "st.bias": "vec3",
        "st.p": "f32x21",
        "st.scale": "f32",
        "st.p_scale": "f32",
        "st.scale_v": "f32x6",
        "st.lp1": "vec3",
        "st.lp2": "vec3",
        "st.m0": "vec3",
        "st.m0_ref": "vec3",
        "st.mag_hx": "f32",
        "st.mag_hy": "f32",
        "st.m0_lo": "f32",
        "st.m0_hi": "f32",
        "st.dip_lo": "f32",
        "st.dip_hi": "f32",
        "st.gated": "u32",
        "st.rest_count": "u32",
        "st.steps": "u32",
        "st.flags": "u32",
        "st.m0_valid": "bool",
        "st.lp_valid": "bool",
        "st.initialised": "bool",
    }
    """C state fields mirrored by this class (see reference._common.load_c_state)."""
    EARTH: tuple[str, ...] = ("lp1", "lp2", "m0", "m0_ref", "mag_h")
    """Earth-frame state vectors, turned with the attitude by a heading change (reference.calib.yaw_to)."""

    COEFFS: StateSpec = {
        "c.dt": "f32",
        "c.half_dt": "f32",
        "c.qa": "f32",
        "c.qw": "f32",
        "c.qb": "f32",
        "c.r_acc": "f32",
        "c.soft": "f32",
        "c.r_mag": "f32",
        "c.mag_soft": "f32",
        "c.k_lp": "f32",
        "c.n_recover": "u32",
        "c.r_rest": "f32",
        "c.rest_gyro2": "f32",
        "c.acc2_lo": "f32",
        "c.acc2_hi": "f32",
        "c.rest_n": "u32",
        "c.p0_scale": "f32",
        "c.scale_init": "f32",
        "c.q_init": "quat",
        "c.r_accel": "f32",
        "c.gate": "f32",
        "c.mag_gate": "f32",
        "c.p0_att": "f32",
        "c.p0_bias": "f32",
        "c.p_max": "f32",
        "c.gravity": "f32",
        "c.accel_reject": "f32",
        "c.accel_range2": "f32",
        "c.gyro_range": "f32",
        "c.mag_range": "f32",
        "c.mag_norm_reject": "f32",
        "c.mag_dip_reject": "f32",
        "c.m0_init": "vec3",
        "c.bias_init": "vec3",
        "c.use_mag": "bool",
        "c.init_from_sensors": "bool",
        "c.lp_on": "bool",
        "c.need_norm": "bool",
    }
    """Every C coefficient of att_mekf_coeffs_t (set by att_mekf_init / retune), derived here alike
    from the settings; state_matches compares them after the state."""

    def __init__(self, settings: MekfSettings | None = None, n: int = 1) -> None:
        s = settings if settings is not None else MekfSettings()
        self.settings = s
        self.n = n
        f = setting
        self.dt = f(s.dt, n)
        self.half_dt = self.dt * dm.HALF
        gn, wn, bn = f(s.gyro_noise, n), f(s.gyro_rate_noise, n), f(s.bias_noise, n)
        an, mn, rn = f(s.accel_noise, n), f(s.mag_noise, n), f(s.rest_noise, n)
        with np.errstate(all="ignore"):
            self.qa = (gn * gn) * self.dt
            self.qw = (wn * wn) * self.dt
            self.qb = (bn * bn) * self.dt
            self.r_acc = (an * an) / self.dt
            self.r_mag = (mn * mn) / self.dt
            self.r_rest = (rn * rn) / self.dt
            tau_lp = f(s.tau_acc_lp, n)
            k_lp = np.where(tau_lp > dm.ZERO, self.dt / (SQRT2 * tau_lp + self.dt), dm.ZERO)
            self.k_lp = k_lp.astype(np.float32)
        self.r_accel = f(s.r_accel, n)
        self.gate = f(s.gate, n)
        self.soft = self.gate * QUARTER
        self.mag_gate = f(s.mag_gate, n)
        self.mag_soft = self.mag_gate * QUARTER
        self.p0_att = f(s.p0_att, n)
        self.p0_bias = f(s.p0_bias, n)
        self.p_max = f(s.p_max, n)
        self.gravity = f(s.gravity, n)
        self.accel_reject = f(s.accel_reject, n)
        self.accel_range2 = f(s.accel_range, n) * f(s.accel_range, n)
        self.gyro_range = f(s.gyro_range, n)
        self.mag_range = f(s.mag_range, n)
        self.mag_norm_reject = f(s.mag_norm_reject, n)
        self.mag_dip_reject = f(s.mag_dip_reject, n)
        self.n_recover = sensor.samples(f(s.gate_recover, n), self.dt)
        rest_gyro = f(s.rest_gyro, n)
        rest_accel = f(s.rest_accel, n)
        self.rest_gyro2 = rest_gyro * rest_gyro
        lo = self.gravity - rest_accel
        hi = self.gravity + rest_accel
        self.acc2_lo = lo * lo
        self.acc2_hi = hi * hi
        self.rest_n = sensor.samples(f(s.rest_time, n), self.dt)
        scale_sd = f(s.gyro_scale_sd, n)
        self.p0_scale = scale_sd * scale_sd
        self.scale_init = f(s.gyro_scale_init, n)
        _, self.q_init = dm.quat_normalize(_split4(s.q_init, n))
        self.use_mag = f(s.use_mag, n, np.bool_)
        self.init_from_sensors = f(s.init_from_sensors, n, np.bool_)
        zeros = np.zeros(n, np.float32)
        self.m0_init = dm.vec3_where(self.init_from_sensors, (zeros, zeros, zeros), split3(s.m0_init, n))
        self.bias_init = split3(s.bias_init, n)
        self.lp_on = self.k_lp > dm.ZERO
        self.need_norm = (self.r_accel > dm.ZERO) | (self.accel_reject > dm.ZERO)
        self._zeros = zeros
        self._up = (zeros, zeros, np.full(n, dm.ONE, np.float32))
        self.reset()

    def reset(self) -> None:
        """Back to the state after construction (att_mekf_reset)."""
        n = self.n
        z = self._zeros
        self.q: dm.Quat = tuple(a.copy() for a in self.q_init)
        self.bias: dm.Vec3 = tuple(a.copy() for a in self.bias_init)
        self.p: cv.Cov = cv.diag(self.p0_att, self.p0_bias, n)
        self.scale: Any = self.scale_init.copy()
        self.p_scale: Any = self.p0_scale.copy()
        self.scale_v: msc.Sens = msc.zeros(n)
        self.lp1: dm.Vec3 = (z.copy(), z.copy(), self.gravity.copy())
        self.lp2: dm.Vec3 = (z.copy(), z.copy(), self.gravity.copy())
        self.m0: dm.Vec3 = (z.copy(), z.copy(), z.copy())
        self.m0_ref: dm.Vec3 = (z.copy(), z.copy(), z.copy())
        self.mag_hx: Any = z.copy()
        self.mag_hy: Any = z.copy()
        self.m0_lo: Any = z.copy()
        self.m0_hi: Any = z.copy()
        self.dip_lo: Any = z.copy()
        self.dip_hi: Any = z.copy()
        self.gated = np.zeros(n, np.uint32)
        self.rest_count = np.zeros(n, np.uint32)
        self.steps = np.zeros(n, np.uint32)
        self.flags = np.zeros(n, np.uint32)
        self.m0_valid: Any = np.zeros(n, np.bool_)
        self.lp_valid: Any = np.zeros(n, np.bool_)
        self.initialised: Any = ~self.init_from_sensors
        mi = self.m0_init
        nonzero = ~((mi[0] == dm.ZERO) & (mi[1] == dm.ZERO) & (mi[2] == dm.ZERO))
        ok, parts = self._derive_m0(mi)
        self._commit_m0(nonzero & ok, parts)

    # --- the reference field -------------------------------------------------------------------

    def _derive_m0(self, m0: dm.Vec3) -> tuple[Any, _M0Parts]:
        """att_mekf_set_m0 / att_mekf_m0_limits: whether it succeeds and what it stores."""
        with np.errstate(all="ignore"):
            ok, _ = dm.vec3_normalize(m0)
            norm = dm.vec3_norm(m0)
            ref_ok, ref = dm.vec3_normalize((m0[0], m0[1], self._zeros))
            cz = m0[2] / dm.sqrtf(m0[0] * m0[0] + m0[1] * m0[1])
            hx = np.where(ref_ok, -(cz * ref[0]), dm.ZERO).astype(np.float32)
            hy = np.where(ref_ok, -(cz * ref[1]), dm.ZERO).astype(np.float32)
            nr = self.mag_norm_reject
            on = nr > dm.ZERO
            lo = np.where(on, norm * (dm.ONE - nr), dm.ZERO)
            lo = np.where(ref_ok, lo, dm.INF)  # no horizontal reference: every sample rejected
            hi = np.where(on, norm * (dm.ONE + nr), self.mag_range)
            t = self.mag_dip_reject
            dip = dm.atan2f(m0[2], dm.sqrtf(m0[0] * m0[0] + m0[1] * m0[1]))
            d_lo = dip - t
            d_hi = dip + t
            dip_lo = np.where((t > dm.ZERO) & (d_lo > -PIO2), dm.sinf(d_lo), -dm.TWO)
            dip_hi = np.where((t > dm.ZERO) & (d_hi < PIO2), dm.sinf(d_hi), dm.TWO)
        return ok, (m0, ref, hx, hy, lo, hi, dip_lo, dip_hi)

    def _commit_m0(self, cond: Any, parts: _M0Parts) -> None:
        m0, ref, hx, hy, lo, hi, dip_lo, dip_hi = parts
        w = np.where
        self.m0 = dm.vec3_where(cond, m0, self.m0)
        self.m0_ref = dm.vec3_where(cond, ref, self.m0_ref)
        self.mag_hx = w(cond, hx, self.mag_hx).astype(np.float32)
        self.mag_hy = w(cond, hy, self.mag_hy).astype(np.float32)
        self.m0_lo = w(cond, lo, self.m0_lo).astype(np.float32)
        self.m0_hi = w(cond, hi, self.m0_hi).astype(np.float32)
        self.dip_lo = w(cond, dip_lo, self.dip_lo).astype(np.float32)
        self.dip_hi = w(cond, dip_hi, self.dip_hi).astype(np.float32)
        self.m0_valid = self.m0_valid | cond

    def _align(self, q: dm.Quat, mag: dm.Vec3) -> tuple[Any, dm.Quat, dm.Vec3]:
        """att_mekf_align: (ok, yaw-aligned q, m0)."""
        with np.errstate(all="ignore"):
            me = dm.quat_rotate(q, mag)
            ok1, _ = dm.vec3_normalize(me)
            qa = dm.quat_mul(dm.quat_from_axis_angle(self._up, dm.atan2f(me[0], me[1])), q)
            ok2, qa = dm.quat_normalize_bounded(qa)
            me = dm.quat_rotate(qa, mag)
            m0 = (self._zeros, dm.sqrtf(me[0] * me[0] + me[1] * me[1]), me[2])
        return ok1 & ok2, qa, m0

    def _heading(self, me: dm.Vec3, mnorm: Any) -> tuple[Any, Any]:
        """att_mekf_heading: (usable, y = 2 sin(alpha / 2))."""
        with np.errstate(all="ignore"):
            reject = (
                (mnorm < self.m0_lo)
                | (mnorm > self.m0_hi)
                | (me[2] < self.dip_lo * mnorm)
                | (me[2] > self.dip_hi * mnorm)
            )
            h2 = me[0] * me[0] + me[1] * me[1]
            ok_h = h2 >= dm.NORM2_MIN
            hn = dm.sqrtf(h2)
            rx, ry, _ = self.m0_ref
            a = hn + (me[0] * rx + me[1] * ry)
            b = me[0] * ry - me[1] * rx
            arc = (dm.TWO * b) / dm.sqrtf((dm.TWO * hn) * a)
            y = np.where(a > A_MIN * hn, arc, dm.TWO).astype(np.float32)
        return ~reject & ok_h, y

    # --- the step ------------------------------------------------------------------------------

    def step(self, gyr: Any, acc: Any, mag: Any) -> NDArray[np.uint32]:
        """One update of every instance; gyr, acc, mag of shape (n, 3) or (3,). Returns flags (n,)."""
        g = split3(gyr, self.n)
        a = split3(acc, self.n)
        m = split3(mag, self.n)
        w = np.where
        with np.errstate(all="ignore"):
            flags = sensor.check_gyro(g, self.gyro_range)
            gyro_ok = flags == _U0
            accel_flags, n2 = sensor.check_accel2(a, self.accel_range2)
            accel_ok = accel_flags == _U0
            flags = flags | accel_flags
            e = dm.sqrtf(n2) / self.gravity - dm.ONE
            use_e = accel_ok & self.need_norm
            e2 = w(use_e, e * e, dm.ZERO).astype(np.float32)
            rejected = use_e & (self.accel_reject > dm.ZERO) & (dm.absf(e) > self.accel_reject)
            flags = flags | w(rejected, _u(Flag.ACCEL_REJECTED), _U0)
            mag_flags, mnorm = sensor.check_mag(m, self.mag_range)
            flags = flags | w(self.use_mag, mag_flags, _U0)
            mag_ok = self.use_mag & (mag_flags == _U0)
            mnorm = w(self.use_mag, mnorm, dm.ZERO).astype(np.float32)

            # not yet initialised: the start (att_mekf_start)
            waiting = ~self.initialised
            run = self.initialised
            init_now = waiting & accel_ok
            t = sensor.tilt(a)
            _, q_tilt = dm.quat_normalize_bounded(dm.quat_from_euler(t[0], t[1], self._zeros))
            ok_a0, q_a0, m0_a0 = self._align(q_tilt, m)
            ok_d0, parts0 = self._derive_m0(m0_a0)
            good0 = ok_a0 & ok_d0
            init_mag = init_now & mag_ok & good0
            q_start = dm.quat_where(init_mag, q_a0, q_tilt)
            flags = flags | w(waiting, w(accel_ok, _u(Flag.INITIALISED), _u(Flag.NOT_READY)), _U0)
            flags = flags | w(init_now & mag_ok & ~good0, _u(Flag.MAG_REJECTED), _U0)

            # 0. rest
            d = dm.vec3_sub(g, self.bias)
            rest = gyro_ok & accel_ok & (dm.vec3_dot(d, d) < self.rest_gyro2) & (n2 > self.acc2_lo)
            rest = rest & (n2 < self.acc2_hi)
            inc = w(self.rest_count < self.rest_n, self.rest_count + np.uint32(1), self.rest_count)
            count = w(~rest, _U0, inc)
            rest_count = w(run, count, self.rest_count).astype(np.uint32)
            at_rest = run & rest & (rest_count >= self.rest_n)
            flags = flags | w(at_rest, _u(Flag.AT_REST) | _u(Flag.BIAS_UPDATED), _U0)
            p_r, dth_r, b_r, sv_r, ps_r, sc_r = cv.rest_apply(
                self.p, self.r_rest, g, self.bias, self.scale_v, self.p_scale, self.scale
            )
            dq_r = dm.quat_from_rotvec_fast((dth_r[0], dth_r[1], dth_r[2]))
            p = cv.where(at_rest, p_r, self.p)
            sv = msc.where(at_rest, sv_r, self.scale_v)
            ps = w(at_rest, ps_r, self.p_scale).astype(np.float32)
            scale = w(at_rest, sc_r, self.scale).astype(np.float32)
            bias = dm.vec3_where(at_rest, (b_r[0], b_r[1], b_r[2]), self.bias)
            q = dm.quat_where(at_rest, dm.quat_mul(dq_r, self.q), self.q)
            rot_r = at_rest & self.lp_on
            lp1 = dm.vec3_where(rot_r, dm.quat_rotate(dq_r, self.lp1), self.lp1)
            lp2 = dm.vec3_where(rot_r, dm.quat_rotate(dq_r, self.lp2), self.lp2)

            # 1. prediction
            wr = dm.vec3_sub(g, bias)
            ws = dm.vec3_scale(wr, dm.ONE + scale)
            q_int = dm.quat_mul(q, dm.quat_from_rotvec_fast(dm.vec3_scale(ws, self.dt)))
            q = dm.quat_where(gyro_ok, q_int, q)
            qa = w(gyro_ok, self.qa + self.qw * dm.vec3_dot(ws, ws), self.qa).astype(np.float32)
            r = _matrix(q)
            p = cv.where(run, cv.predict(p, r, self.half_dt, self.dt, qa, self.qb), p)
            sv = msc.where(run, msc.predict(sv, r, gyro_ok, wr, self.dt), sv)

            # 2. accelerometer update
            acc_try = run & accel_ok & ~rejected
            u = (
                r[0] * a[0] + r[1] * a[1] + r[2] * a[2],
                r[3] * a[0] + r[4] * a[1] + r[5] * a[2],
                r[6] * a[0] + r[7] * a[1] + r[8] * a[2],
            )
            start_lp = ~self.lp_valid
            l1 = dm.vec3_where(start_lp, u, lp1)
            l2 = dm.vec3_where(start_lp, u, lp2)
            l1, l2 = _lowpass(u, self.k_lp, l1, l2)
            u = dm.vec3_where(self.lp_on, l2, u)
            ok_u, (_, cx, cy), _ = align_up(u)
            y0 = dm.TWO * cx
            y1 = dm.TWO * cy
            rn = self.r_acc * (dm.ONE + self.r_accel * e2)
            v = cv.innov(p, rn, y0, y1)
            measure = acc_try & ok_u
            gate_on = self.gate > dm.ZERO
            hit = measure & gate_on & (v[4] > self.gate * v[3])
            gated = w(hit & (self.gated < GATED_MAX), self.gated + np.uint32(1), self.gated).astype(np.uint32)
            recover = hit & (self.n_recover > _U0) & (gated >= self.n_recover)
            p_rec = cv.recover(p, self.soft, y0, y1, self.p_max)
            v_rec = cv.innov(p_rec, rn, y0, y1)
            p = cv.where(recover, p_rec, p)
            v = tuple(w(recover, x1, x0).astype(np.float32) for x0, x1 in zip(v, v_rec, strict=True))
            flags = flags | w(hit & ~recover, _u(Flag.ACCEL_REJECTED), _U0)
            want = measure & (~hit | recover)
            det_ok = v[3] > dm.ZERO
            flags = flags | w(want & ~det_ok, _u(Flag.NUMERIC), _U0)
            apply = want & det_ok
            self.gated = w(apply, _U0, gated).astype(np.uint32)
            p_a, dx, sv_a, ds_a, ps_a = cv.accel_apply(p, v, y0, y1, gate_on, self.soft, sv, ps)
            p = cv.where(apply, p_a, p)
            sv = msc.where(apply, sv_a, sv)
            ps = w(apply, ps_a, ps).astype(np.float32)
            scale = w(apply, scale + ds_a, scale).astype(np.float32)
            dq = dm.quat_from_rotvec_fast((dx[0], dx[1], dx[2]))
            q = dm.quat_where(apply, dm.quat_mul(dq, q), q)
            bias = dm.vec3_where(apply, (bias[0] + dx[3], bias[1] + dx[4], bias[2] + dx[5]), bias)
            lp_commit = apply & self.lp_on
            lp1 = dm.vec3_where(lp_commit, dm.quat_rotate(dq, l1), lp1)
            lp2 = dm.vec3_where(lp_commit, dm.quat_rotate(dq, l2), lp2)
            lp_valid = self.lp_valid | lp_commit
            flags = flags | w(apply, _u(Flag.BIAS_UPDATED), _U0)

            # 3. magnetometer update
            use_corr = run & mag_ok & self.m0_valid
            me = dm.quat_rotate(q, m)
            ok_h, ym = self._heading(me, mnorm)
            ok_g, p_m, dz, db, sv_m = cv.mag_apply(
                p, self.mag_hx, self.mag_hy, self.r_mag, self.mag_gate, self.mag_soft, ym, sv
            )
            mag_apply = use_corr & ok_h & ok_g
            p = cv.where(mag_apply, p_m, p)
            sv = msc.where(mag_apply, sv_m, sv)
            dqz = dm.quat_from_rotvec_fast((self._zeros, self._zeros, dz))
            q = dm.quat_where(mag_apply, dm.quat_mul_z(dqz[0], dqz[3], q), q)
            bias = dm.vec3_where(mag_apply, dm.vec3_add(bias, (db[0], db[1], db[2])), bias)
            lp1, lp2 = _lp_turn(mag_apply & self.lp_on, dqz[0], dqz[3], lp1, lp2)
            flags = flags | w(mag_apply, _u(Flag.BIAS_UPDATED), _U0)
            flags = flags | w(use_corr & ~mag_apply, _u(Flag.MAG_REJECTED), _U0)
            # the first mag sample (att_mekf_mag_first)
            first = run & mag_ok & ~self.m0_valid
            ok_al, q_al, m0_al = self._align(q, m)
            ok_dl, parts_l = self._derive_m0(m0_al)
            use_align = first & self.init_from_sensors
            good_l = use_align & ok_al & ok_dl
            ok_ds, parts_s = self._derive_m0(dm.quat_rotate(q, m))
            use_set = first & ~self.init_from_sensors
            # the turn applied, q_al q* = (w, 0, 0, z) (its x, y are rounding: dropped)
            tw = q_al[0] * q[0] + q_al[1] * q[1] + q_al[2] * q[2] + q_al[3] * q[3]
            tz = q_al[3] * q[0] - q_al[0] * q[3] + q_al[2] * q[1] - q_al[1] * q[2]
            lp1, lp2 = _lp_turn(good_l & self.lp_on, tw, tz, lp1, lp2)
            q = dm.quat_where(good_l, q_al, q)
            p = cv.where(good_l, cv.yaw_reset(p, self.p0_att), p)
            sv[2] = w(good_l, dm.ZERO, sv[2]).astype(np.float32)
            flags = flags | w(good_l, _u(Flag.INITIALISED), _U0)
            flags = flags | w((use_align & ~good_l) | (use_set & ~ok_ds), _u(Flag.MAG_REJECTED), _U0)

            # 4. conditioning, 5. normalisation
            p_c, clamped = cv.condition(p, self.p_max, self.p0_bias)
            p = cv.where(run, p_c, p)
            flags = flags | w(run & clamped, _u(Flag.CLAMPED), _U0)
            scale, ps, sv, clamped_s = msc.bound(scale, ps, sv)
            flags = flags | w(run & clamped_s, _u(Flag.CLAMPED), _U0)
            ok_n, qn = dm.quat_normalize_bounded(q)
            flags = flags | w(run & ~ok_n, _u(Flag.NUMERIC), _U0)

            # commit (the start for the waiting instances)
            lp_init = dm.quat_rotate(q_start, a)
            q_wait = dm.quat_where(init_now, q_start, self.q)
            self.q = dm.quat_where(waiting, q_wait, dm.quat_where(ok_n, qn, self.q))
            p_start = cv.where(init_mag, cv.yaw_reset(self.p, self.p0_att), self.p)
            self.p = cv.where(waiting, p_start, p)
            self.bias = dm.vec3_where(run, bias, self.bias)
            self.scale = w(run, scale, self.scale).astype(np.float32)
            self.p_scale = w(run, ps, self.p_scale).astype(np.float32)
            sv_wait = list(self.scale_v)
            sv_wait[2] = w(init_mag, dm.ZERO, sv_wait[2]).astype(np.float32)
            self.scale_v = msc.where(waiting, sv_wait, msc.where(run, sv, self.scale_v))
            self.lp1 = dm.vec3_where(init_now, lp_init, dm.vec3_where(run, lp1, self.lp1))
            self.lp2 = dm.vec3_where(init_now, lp_init, dm.vec3_where(run, lp2, self.lp2))
            self.lp_valid = self.lp_valid | init_now | (run & lp_valid)
            self.rest_count = rest_count
        self._commit_m0(init_mag, parts0)
        self._commit_m0(good_l, parts_l)
        self._commit_m0(use_set & ok_ds, parts_s)
        self.initialised = self.initialised | init_now
        self.steps = self.steps + np.uint32(1)
        self.flags = flags.astype(np.uint32)
        return self.flags

    def retune(self, settings: MekfSettings) -> None:
        """att_mekf_retune: new settings, the state kept (reference limits recomputed, counter limited)."""
        new = Mekf(settings, self.n)
        carry_state(self, new)
        ok, parts = new._derive_m0(new.m0)
        new._commit_m0(new.m0_valid & ok, parts)
        new.rest_count = np.minimum(new.rest_count, new.rest_n).astype(np.uint32)
        off = ~(new.p0_scale > dm.ZERO)
        restart = ~off & ~(new.p_scale > dm.ZERO)
        new.p_scale = np.where(off, dm.ZERO, np.where(restart, new.p0_scale, new.p_scale)).astype(np.float32)
        new.scale_v = msc.where(off | restart, msc.zeros(new.n), new.scale_v)
        self.__dict__.update(new.__dict__)

    @property
    def quat(self) -> NDArray[np.float32]:
        """Attitudes (n, 4), w,x,y,z, sensor-to-earth."""
        return stack(self.q)

    @property
    def gyro_bias(self) -> NDArray[np.float32]:
        """Gyro bias estimates (n, 3), rad/s, sensor frame."""
        return stack(self.bias)

    @property
    def mag_h(self) -> dm.Vec3:
        """The heading measurement's tilt entries (mag_hx, mag_hy) as an earth-frame vector with z = 0."""
        return (self.mag_hx, self.mag_hy, dm.f32(np.zeros_like(self.mag_hx)))

    @mag_h.setter
    def mag_h(self, v: dm.Vec3) -> None:
        self.mag_hx, self.mag_hy = dm.f32(v[0]), dm.f32(v[1])

    @property
    def gyro_scale(self) -> NDArray[np.float32]:
        """Gyro scale-factor error estimates (n,): the rate integrated is (1 + s)(w - b)."""
        return np.asarray(self.scale, np.float32).copy()

    @property
    def covariance(self) -> NDArray[np.float32]:
        """The packed covariance (n, 21): upper triangle of the 6x6 P, row-major."""
        return stack(tuple(self.p))

    def output_cov(self) -> tuple[Any, Any, Any, Any]:
        """The output record's ``cov`` (att_filter_output): attitude error variances, mean bias variance.

        The attitude error variances x, y, z, then the mean of the three bias variances (the diagonal of
        the packed P is at 0, 6, 11, 15, 18, 20).
        """
        p = self.p
        return (p[0], p[6], p[11], (p[15] + p[18] + p[20]) / THREE)

    def run(self, gyr: Any, acc: Any, mag: Any = None) -> tuple[NDArray[np.float32], NDArray[np.uint32]]:
        """Step through N samples: gyr, acc, mag (N, 3) for n == 1 or (N, n, 3); mag None = absent.

        Returns quats (N, 4) or (N, n, 4) and flags (N,) or (N, n).
        """
        if mag is None:
            mag = np.zeros_like(np.asarray(gyr, np.float32))
        return run_steps(self, gyr, acc, mag)


def _lowpass(u: dm.Vec3, k: Any, lp1: dm.Vec3, lp2: dm.Vec3) -> tuple[dm.Vec3, dm.Vec3]:
    """att_mekf_lowpass: the second-order Butterworth section, (lp1, lp2) after the sample u."""
    kq = BW_Q * k
    d = dm.vec3_sub(lp1, lp2)
    e = dm.vec3_sub(u, lp2)
    lp1 = dm.vec3_add(lp1, dm.vec3_sub(dm.vec3_scale(e, k), dm.vec3_scale(d, kq)))
    lp2 = dm.vec3_add(lp2, dm.vec3_scale(dm.vec3_sub(lp1, lp2), k))
    return lp1, lp2


def _lp_turn(cond: Any, qw: Any, qz: Any, lp1: dm.Vec3, lp2: dm.Vec3) -> tuple[dm.Vec3, dm.Vec3]:
    """att_mekf_lp_turn where ``cond``: lp1, lp2 turned about the earth z axis by (qw, 0, 0, qz)."""
    cz = dm.ONE - dm.TWO * (qz * qz)
    sz = dm.TWO * (qw * qz)
    t1 = (cz * lp1[0] - sz * lp1[1], sz * lp1[0] + cz * lp1[1], lp1[2])
    t2 = (cz * lp2[0] - sz * lp2[1], sz * lp2[0] + cz * lp2[1], lp2[2])
    return dm.vec3_where(cond, t1, lp1), dm.vec3_where(cond, t2, lp2)


def _matrix(q: dm.Quat) -> list[Any]:
    """The rotation matrix of the predicted attitude as att_mekf_update writes it (row-major)."""
    qw, qx, qy, qz = q
    xx = qx * qx
    yy = qy * qy
    zz = qz * qz
    xy = qx * qy
    xz = qx * qz
    yz = qy * qz
    wx = qw * qx
    wy = qw * qy
    wz = qw * qz
    one, two = dm.ONE, dm.TWO
    return [
        one - two * (yy + zz),
        two * (xy - wz),
        two * (xz + wy),
        two * (xy + wz),
        one - two * (xx + zz),
        two * (yz - wx),
        two * (xz - wy),
        two * (yz + wx),
        one - two * (xx + yy),
    ]
