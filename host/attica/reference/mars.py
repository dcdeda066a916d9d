"""Mirror of firmware/src/filters/mars/att_mars.c: the 9-axis complementary filter, instances in lockstep."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.reference import detmath as dm
from attica.reference import hardiron as hiron
from attica.reference import magref as mr
from attica.reference import sensor
from attica.reference._common import (
    COV_TILT_MAX,
    COV_UNKNOWN,
    StateSpec,
    carry_state,
    cov_first,
    cov_grow,
    cov_tilt,
    cov_tilt_now,
    recovery_lp_gain2,
    recovery_params,
    recovery_start,
    recovery_step,
    run_steps,
    setting,
    split3,
    stack,
)
from attica.reference.ars import A_MIN, align_up
from attica.reference.bias import bias_params, bias_retune, bias_step
from attica.settings import BiasMode, Flag, Integration, MagMode, MarsSettings

_U0 = np.uint32(0)
_U1 = np.uint32(1)

_M0Parts = tuple[dm.Vec3, dm.Vec3, dm.Vec3, Any, Any, Any, Any, Any]
"""(m0, m0_ref, m0_perp, m0_ref_ok, m0_lo, m0_hi, dip_lo, dip_hi) as att_mars_set_m0 stores them."""

PIO2 = dm.c("0x1.921fb6p+0")
THREE = dm.c("0x1.8p+1")
SIX = dm.c("0x1.8p+2")


def _u(flag: Flag) -> np.uint32:
    return np.uint32(flag.value)


def _split4(x: Any, n: int) -> dm.Quat:
    a = np.broadcast_to(np.asarray(x, dtype=np.float32), (n, 4))
    return (a[:, 0].copy(), a[:, 1].copy(), a[:, 2].copy(), a[:, 3].copy())


def _dip(v: dm.Vec3) -> Any:
    """att_mars_dip: atan2(v.z, |v_xy|)."""
    with np.errstate(all="ignore"):
        return dm.atan2f(v[2], dm.sqrtf(v[0] * v[0] + v[1] * v[1]))


def _integrate(q: dm.Quat, w: dm.Vec3, dt: Any) -> dm.Quat:
    """att_mars_integrate: q + (0.5 q (x) (0, w)) dt."""
    o = (np.zeros(np.shape(w[0]), np.float32), w[0], w[1], w[2])
    p = dm.quat_mul(q, o)
    return (
        q[0] + p[0] * dm.HALF * dt,
        q[1] + p[1] * dm.HALF * dt,
        q[2] + p[2] * dm.HALF * dt,
        q[3] + p[3] * dm.HALF * dt,
    )


def _rotation_toward(v: dm.Vec3, r: dm.Vec3, fallback: dm.Vec3, gain: Any) -> dm.Quat:
    """att_mars_rotation_toward."""
    with np.errstate(all="ignore"):
        c = dm.vec3_cross(v, r)
        angle = dm.atan2f(dm.vec3_norm(c), dm.vec3_dot(v, r))
        ok, axis = dm.vec3_normalize(c)
        axis = dm.vec3_where(ok, axis, fallback)
        return dm.quat_from_axis_angle(axis, gain * angle)


GAP_MAX = np.uint32(255)
"""ATT_MARS_GAP_MAX: the steps without a mag sample counted (a longer gap counts 255: an outage)."""


def gap_steps(gap: Any, period: Any) -> Any:
    """att_mars_gap_close's count, min(gap, period) + 1.

    The steps a sample after ``gap`` absent ones stands for (``period``: the gap before, 0 when the gap
    did not follow a gap-ending sample).
    """
    return (np.minimum(period, gap) + _U1).astype(np.uint32)


def gap_gain(k: Any, n: Any) -> Any:
    """att_mars_gap_gain: 1 - (1 - k)^n for n = 1 .. 256 steps, by binary powers composed as a + b - a b."""
    acc = np.zeros(np.shape(k), np.float32)
    p = np.asarray(k, np.float32)
    n = np.asarray(n, np.uint32)
    with np.errstate(all="ignore"):
        for i in range(9):  # n <= 256: nine bits; C stops at the highest (the later p unused)
            bit = ((n >> np.uint32(i)) & _U1) != _U0
            acc = np.where(bit, (acc + p) - acc * p, acc).astype(np.float32)
            p = ((p + p) - p * p).astype(np.float32)
    return acc


class Mars:
    """9-axis complementary filter reference: ``n`` independent instances sharing one settings object.

    Settings fields may be scalars or length-``n`` sequences (one value per instance); vector fields
    may be given as (3,)/(4,) or (n, 3)/(n, 4).
    """

    hi_on: Any
    """Per instance: the hard-iron estimate is on (C's ``c.hi.on``; set by :func:`hardiron.params`)."""

    STATE: StateSpec = {
        "st.q": "quat",
        "st.bias": "vec3",
        "st.lp1": "vec3",
        "st.lp2": "vec3",
        "st.m0": "vec3",
        "st.m0_ref": "vec3",
        "st.m0_perp": "vec3",
        "st.m0_lo": "f32",
        "st.m0_hi": "f32",
        "st.dip_lo": "f32",
        "st.dip_hi": "f32",
        **mr.state_spec("st.ref"),
        **hiron.state_spec("st.hi"),
        "st.fast_left": "u32",
        "st.rec_left": "u32",
        "st.rec_lp_n": "u32",
        "st.acc_step": "u32",
        "st.mag_step": "u32",
        "st.mag_gap": "u32",
        "st.mag_period": "u32",
        "st.mag_gap_step": "u32",
        "st.bias_n": "u32",
        "st.rest_count": "u32",
        "st.rest_gate2": "f32",
        "st.steps": "u32",
        "st.flags": "u32",
        "st.m0_ref_ok": "bool",
        "st.m0_valid": "bool",
        "st.initialised": "bool",
        "st.rec_clip": "bool",
    }
    """C state fields mirrored by this class (see reference._common.load_c_state)."""
    EARTH: tuple[str, ...] = ("lp1", "lp2", "m0", "m0_ref", "m0_perp")
    """Earth-frame state vectors, turned with the attitude by a heading change (reference.calib.yaw_to)."""

    COEFFS: StateSpec = {
        "c.dt": "f32",
        "c.k_acc": "f32",
        "c.k_mag": "f32",
        "c.k_mag1": "f32",
        "c.k_lp": "f32",
        "c.gravity": "f32",
        "c.accel_reject": "f32",
        "c.accel_range2": "f32",
        "c.gyro_range": "f32",
        "c.mag_range": "f32",
        "c.mag_norm_reject": "f32",
        "c.mag_dip_reject": "f32",
        "c.bias.mode": "u32:bias_mode",
        "c.bias.n_max": "u32:bias_n_max",
        "c.bias.rest_n": "u32",
        "c.bias.rest_gyro2": "f32",
        "c.bias.acc2_lo": "f32",
        "c.bias.acc2_hi": "f32",
        "c.bias.rest_first2": "f32",
        "c.q_init": "quat",
        "c.m0_init": "vec3",
        "c.bias_init": "vec3",
        "c.integration": "u32",
        "c.mag_mode": "u32",
        "c.init_from_sensors": "bool",
        "c.lp_on": "bool",
        "c.reject_on": "bool",
        "c.full": "bool",
        **mr.coeff_spec("c.ref"),
        **hiron.coeff_spec("c.hi"),
        "c.k_fast": "f32",
        "c.k_fast1": "f32",
        "c.fast_n": "u32",
        "c.fast_start_n": "u32",
        "c.k_bias_mag": "f32",
        "c.bias_mag_on": "bool",
        "c.clip": "f32",
        "c.k_rec": "f32",
        "c.k_rec1": "f32",
        "c.rec_n": "u32",
        "c.decl": "f32",
        "c.decl_sin": "f32",
        "c.decl_cos": "f32",
        "c.var_step": "f32",
        "c.var_tilt": "f32",
        "c.gyro_noise2": "f32",
        "c.mag_noise2": "f32",
    }
    """Every C coefficient of att_mars_coeffs_t (set by att_mars_init / retune), derived here alike
    from the settings; state_matches compares them after the state."""

    def __init__(self, settings: MarsSettings | None = None, n: int = 1) -> None:
        s = settings if settings is not None else MarsSettings()
        self.settings = s
        self.n = n
        self.dt = setting(s.dt, n)
        alpha_acc = setting(s.alpha_acc, n)
        alpha_mag = setting(s.alpha_mag, n)
        tau_acc = setting(s.tau_acc, n)
        tau_mag = setting(s.tau_mag, n)
        self.mag_mode = setting(np.asarray(s.mag_mode, np.int32), n, np.int32)
        self.gravity = setting(s.gravity, n)
        self.accel_reject = setting(s.accel_reject, n)
        self.accel_range = setting(s.accel_range, n)
        self.accel_range2 = self.accel_range * self.accel_range
        self.gyro_range = setting(s.gyro_range, n)
        self.mag_range = setting(s.mag_range, n)
        self.mag_norm_reject = setting(s.mag_norm_reject, n)
        self.mag_dip_reject = setting(s.mag_dip_reject, n)
        self.bias_init = split3(s.bias_init, n)
        self.init_from_sensors = setting(s.init_from_sensors, n, np.bool_)
        self.q_init = _split4(s.q_init, n)
        _, self.q_init = dm.quat_normalize(self.q_init)  # as c.q_init: normalised once, at init
        zeros = np.zeros(n, np.float32)
        self.m0_init = dm.vec3_where(self.init_from_sensors, (zeros, zeros, zeros), split3(s.m0_init, n))
        with np.errstate(all="ignore"):
            k_acc = np.where(tau_acc > dm.ZERO, self.dt / (tau_acc + self.dt), alpha_acc)
            k_mag = np.where(tau_mag > dm.ZERO, self.dt / (tau_mag + self.dt), alpha_mag)
        self.k_acc = k_acc.astype(np.float32)
        self.k_mag = k_mag.astype(np.float32)
        self.k_mag1 = (dm.ONE - self.k_mag).astype(np.float32)
        self.full = self.k_acc == dm.ONE
        self.reject_on = self.accel_reject > dm.ZERO
        self.integration = setting(np.asarray(s.integration, np.int32), n, np.int32)
        tau_lp = setting(s.tau_acc_lp, n)
        with np.errstate(all="ignore"):
            self.k_lp = np.where(tau_lp > dm.ZERO, self.dt / (tau_lp + self.dt), dm.ZERO).astype(np.float32)
        self.lp_on = self.k_lp > dm.ZERO
        self.bias_mode = setting(np.asarray(s.bias_mode, np.int32), n, np.int32)
        self.bias_init = dm.vec3_where(  # as c.bias_init: zero when the bias is OFF
            self.bias_mode == BiasMode.OFF, (np.zeros(n, np.float32),) * 3, self.bias_init
        )
        self.bias_n_max = setting(s.bias_n_max, n, np.uint32)
        self.rest_gyro = setting(s.rest_gyro, n)
        self.rest_accel = setting(s.rest_accel, n)
        self.rest_gyro2, self.rest_first2, self.acc2_lo, self.acc2_hi = bias_params(
            self.bias_mode, self.rest_gyro, self.rest_accel, self.gravity
        )
        self.rest_time = setting(s.rest_time, n)
        self.rest_n = sensor.samples(self.rest_time, self.dt)
        self._ref_coeffs(s)
        hiron.params(
            self,
            self.dt,
            setting(s.hard_iron_tau, n),
            setting(s.hard_iron_rate, n),
            self.mag_norm_reject,
            self.mag_range,
        )
        self._rec_coeffs(s)
        self._cov_coeffs(s)
        self.decl = setting(s.declination, n)
        self.decl_sin = dm.sinf(self.decl)
        self.decl_cos = dm.cosf(self.decl)
        self._zeros = zeros
        self._ones = np.full(n, dm.ONE, np.float32)
        self._up = (self._zeros, self._zeros, self._ones)
        self._xaxis = (self._ones, self._zeros, self._zeros)
        self.reset()

    def _ref_coeffs(self, s: MarsSettings) -> None:
        """att_mars_ref_coeffs: the reference field's estimation and the fast phase."""
        n = self.n
        t = mr.params(
            self,
            self.dt,
            setting(s.mag_ref_tau, n),
            setting(s.mag_new_time, n),
            self.mag_norm_reject,
            self.mag_dip_reject,
        )
        with np.errstate(all="ignore"):
            tau_fast = setting(s.tau_mag_fast, n)
            k_fast = np.where(tau_fast > dm.ZERO, self.dt / (tau_fast + self.dt), self.k_mag)
        self.k_fast = k_fast.astype(np.float32)
        self.k_fast1 = (dm.ONE - self.k_fast).astype(np.float32)
        self.fast_n = sensor.samples(THREE * tau_fast, t)
        lp = setting(s.tau_acc_lp, n)
        start = sensor.samples(THREE * tau_fast + SIX * lp, t)
        self.fast_start_n = np.where((self.fast_n > _U0) & (lp > dm.ZERO), start, self.fast_n).astype(
            np.uint32
        )
        tau_b = setting(s.tau_bias_mag, n)
        self.bias_mag_on = (
            (tau_b > dm.ZERO)
            & (self.mag_mode == MagMode.HORIZONTAL)
            & ((self.bias_mode == BiasMode.AT_REST) | (self.bias_mode == BiasMode.RUNNING))
        )
        with np.errstate(all="ignore"):
            tau_k = np.where(tau_b > self.dt, tau_b, self.dt)  # 1 / max(tau_bias_mag, dt): finite (F14)
            self.k_bias_mag = np.where(self.bias_mag_on, dm.ONE / tau_k, dm.ZERO).astype(np.float32)

    def _rec_coeffs(self, s: MarsSettings) -> None:
        """att_mars_rec_coeffs: the recovery after a clipping gyro."""
        rt = setting(s.recovery_time, self.n)
        self.rec_n, self.clip, k = recovery_params(rt, self.gyro_range, self.dt)
        self.k_rec = np.where(k > self.k_mag, k, self.k_mag).astype(np.float32)
        self.k_rec1 = (dm.ONE - self.k_rec).astype(np.float32)

    def _cov_coeffs(self, s: MarsSettings) -> None:
        """att_mars_cov_coeffs: the covariance model's coefficients."""
        n = self.n
        an = setting(s.accel_noise, n) / self.gravity
        a2 = an * an
        on = self.k_acc > dm.ZERO
        gn = setting(s.gyro_noise, n)
        mn = setting(s.mag_noise, n)
        self.gyro_noise2 = (gn * gn).astype(np.float32)
        self.mag_noise2 = (mn * mn).astype(np.float32)
        self.var_step = (self.gyro_noise2 * self.dt).astype(np.float32)
        self.var_tilt = np.where(
            on, cov_tilt(self.dt, self.k_lp, self.k_acc, self.gyro_noise2, a2), COV_TILT_MAX
        ).astype(np.float32)

    def output_cov(self) -> tuple[Any, Any, Any, Any]:
        """att_mars_cov: the output record's cov (tilt about earth x, y; heading about z; 0), rad^2."""
        rec = self.rec_left > _U0
        tilt = cov_tilt_now(self, self.var_tilt)  # a recovery adds only its fading term
        with np.errstate(all="ignore"):
            mx, my, _ = self.m0
            h2 = mx * mx + my * my
            k = np.where(rec, self.k_rec, np.where(self.fast_left > _U0, self.k_fast, self.k_mag))
            v = cov_first(self.dt, k, self.gyro_noise2, self.mag_noise2 / h2)
            known = self.m0_valid & self.initialised & (k > dm.ZERO) & (h2 > dm.ZERO)
            grown = cov_grow(v, self.var_step, self.steps, self.mag_step, COV_UNKNOWN)
        yaw = np.where(known, grown, COV_UNKNOWN).astype(np.float32)
        return (tilt, tilt.copy(), yaw, np.zeros(self.n, np.float32))

    def reset(self) -> None:
        """Back to the state after construction (att_mars_reset)."""
        n = self.n
        qi = self.q_init
        self.q = (qi[0].copy(), qi[1].copy(), qi[2].copy(), qi[3].copy())
        z = self._zeros
        self.m0: dm.Vec3 = (z.copy(), z.copy(), z.copy())
        self.m0_ref: dm.Vec3 = (z.copy(), z.copy(), z.copy())
        self.m0_perp: dm.Vec3 = (z.copy(), z.copy(), z.copy())
        self.m0_lo: Any = z.copy()
        self.m0_hi: Any = z.copy()
        self.dip_lo: Any = z.copy()
        self.dip_hi: Any = z.copy()
        self.m0_ref_ok: Any = np.zeros(n, np.bool_)
        self.m0_valid: Any = np.zeros(n, np.bool_)
        self.fast_left = np.zeros(n, np.uint32)
        self.rec_left = np.zeros(n, np.uint32)
        self.rec_lp_n = np.zeros(n, np.uint32)
        self.rec_clip: Any = np.zeros(n, np.bool_)
        self.acc_step = np.zeros(n, np.uint32)
        self.mag_step = np.zeros(n, np.uint32)
        self.mag_gap = np.zeros(n, np.uint32)
        self.mag_period = np.zeros(n, np.uint32)
        self.mag_gap_step = np.zeros(n, np.uint32)
        mr.reset(self, n)
        hiron.reset(self, n)
        mi = self.m0_init
        nonzero = ~((mi[0] == dm.ZERO) & (mi[1] == dm.ZERO) & (mi[2] == dm.ZERO))
        ok, parts = self._derive_m0(mi)
        self._commit_m0(nonzero & ok, parts)
        self.initialised: Any = ~self.init_from_sensors
        off = self.bias_mode == BiasMode.OFF
        self.bias: dm.Vec3 = dm.vec3_where(off, (z.copy(), z.copy(), z.copy()), self.bias_init)
        self.bias_n = np.zeros(n, np.uint32)
        self.rest_count = np.zeros(n, np.uint32)
        self.rest_gate2 = self.rest_first2.copy()
        self.lp1: dm.Vec3 = (z.copy(), z.copy(), self.gravity.copy())
        self.lp2: dm.Vec3 = (z.copy(), z.copy(), self.gravity.copy())
        self.steps = np.zeros(n, np.uint32)
        self.flags = np.zeros(n, np.uint32)

    def _derive_m0(self, m0: dm.Vec3) -> tuple[Any, _M0Parts]:
        """att_mars_set_m0 / att_mars_m0_limits: whether it succeeds and what it stores."""
        with np.errstate(all="ignore"):
            ok, unit = dm.vec3_normalize(m0)
            norm = dm.vec3_norm(m0)
            ok_p, perp_full = dm.vec3_normalize(dm.vec3_cross(unit, self._up))
            perp_full = dm.vec3_where(ok_p, perp_full, self._xaxis)
            ok_h, ref_h = dm.vec3_normalize((m0[0], m0[1], self._zeros))
            full = self.mag_mode == MagMode.FULL
            ref = dm.vec3_where(full, unit, ref_h)
            perp = dm.vec3_where(full, perp_full, self._up)
            ref_ok = full | ok_h
            nr = self.mag_norm_reject
            on = nr > dm.ZERO
            lo = np.where(on, norm * (dm.ONE - nr), dm.ZERO)
            ref_ok = full | ok_h
            lo = np.where(ref_ok, lo, dm.INF)  # no usable direction: every sample rejected
            hi = np.where(on, norm * (dm.ONE + nr), self.mag_range)
            t = self.mag_dip_reject
            dip = _dip(m0)
            d_lo = dip - t
            d_hi = dip + t
            two = dm.TWO
            dip_lo = np.where((t > dm.ZERO) & (d_lo > -PIO2), dm.sinf(d_lo), -two)
            dip_hi = np.where((t > dm.ZERO) & (d_hi < PIO2), dm.sinf(d_hi), two)
        return ok, (m0, ref, perp, ref_ok, lo, hi, dip_lo, dip_hi)

    def _commit_m0(self, cond: Any, parts: _M0Parts, new_block: bool = True) -> None:
        """att_mars_set_m0's stores where ``cond`` (``new_block`` False: att_mars_m0_limits' only)."""
        m0, ref, perp, ref_ok, lo, hi, dip_lo, dip_hi = parts
        self.m0 = dm.vec3_where(cond, m0, self.m0)
        self.m0_ref = dm.vec3_where(cond, ref, self.m0_ref)
        self.m0_perp = dm.vec3_where(cond, perp, self.m0_perp)
        self.m0_ref_ok = np.where(cond, ref_ok, self.m0_ref_ok)
        self.m0_lo = np.where(cond, lo, self.m0_lo).astype(np.float32)
        self.m0_hi = np.where(cond, hi, self.m0_hi).astype(np.float32)
        self.dip_lo = np.where(cond, dip_lo, self.dip_lo).astype(np.float32)
        self.dip_hi = np.where(cond, dip_hi, self.dip_hi).astype(np.float32)
        self.m0_valid = self.m0_valid | cond
        if new_block:
            mr.clear(self, cond)

    def _align(self, q: dm.Quat, mag: dm.Vec3) -> tuple[Any, dm.Quat, dm.Vec3]:
        """att_mars_align: (ok, q turned about z so the field is at the declination's azimuth, m0)."""
        with np.errstate(all="ignore"):
            me = dm.quat_rotate(q, mag)
            ok1, _ = dm.vec3_normalize(me)
            qa = dm.quat_mul(dm.quat_from_axis_angle(self._up, dm.atan2f(me[0], me[1]) - self.decl), q)
            ok2, qa = dm.quat_normalize_bounded(qa)
            me = dm.quat_rotate(qa, mag)
            h = dm.sqrtf(me[0] * me[0] + me[1] * me[1])
            m0 = (h * self.decl_sin, h * self.decl_cos, me[2])
        return ok1 & ok2, qa, m0

    def _mag_correct(self, q: dm.Quat, me: dm.Vec3, mnorm: Any) -> tuple[Any, Any, dm.Quat, Any]:
        """att_mars_mag_correct: (gated by norm or dip, rejected, corrected q, heading angle 2 C'_z)."""
        fast = self.fast_left > _U0
        rec = self.rec_left > _U0
        k = np.where(rec, self.k_rec, np.where(fast, self.k_fast, self.k_mag))
        k1 = np.where(rec, self.k_rec1, np.where(fast, self.k_fast1, self.k_mag1))
        gap = self.mag_gap != _U0  # a slower magnetometer: the correction of its interval (att_mars_gap_gain)
        k_gap = gap_gain(k, gap_steps(self.mag_gap, self.mag_period))
        k = np.where(gap, k_gap, k).astype(np.float32)
        k1 = np.where(gap, dm.ONE - k_gap, k1).astype(np.float32)
        with np.errstate(all="ignore"):
            dip_off = (me[2] < self.dip_lo * mnorm) | (me[2] > self.dip_hi * mnorm)
            gated = (mnorm < self.m0_lo) | (mnorm > self.m0_hi) | dip_off
            # full mode: the 3-D rotation toward m0
            ok_u, unit = dm.vec3_normalize(me)
            q_full = dm.quat_mul(_rotation_toward(unit, self.m0_ref, self.m0_perp, k), q)
            # horizontal mode: the interpolation toward the shortest arc from h to r about z
            h2 = me[0] * me[0] + me[1] * me[1]
            ok_h = h2 >= dm.NORM2_MIN
            hn = dm.sqrtf(h2)
            rx, ry, _ = self.m0_ref
            a = hn + (me[0] * rx + me[1] * ry)
            b = me[0] * ry - me[1] * rx
            kn = k / dm.sqrtf((dm.TWO * hn) * a)
            arc = a > A_MIN * hn
            qw = np.where(arc, k1 + a * kn, k1)
            qz = np.where(arc, b * kn, k)
            q_hor = dm.quat_mul_z(qw, qz, q)
            full = self.mag_mode == MagMode.FULL
            reject = gated | np.where(full, ~ok_u, ~ok_h)
            qc = dm.quat_where(full, q_full, q_hor)
            theta = dm.TWO * qz
        return gated, reject, dm.quat_where(reject, q, qc), theta

    def _hard_iron(self, g: dm.Vec3, m: dm.Vec3) -> dm.Vec3:
        """att_mars_step_hi where hard_iron_tau > 0: the estimate's step, the sample the step then sees."""
        with np.errstate(all="ignore"):
            gyro_ok = hiron.gyro_ok(sensor.check_gyro(g, self.gyro_range), g, self.gyro_range)
            mag_ok = sensor.check_mag(m, self.mag_range)[0] == _U0
            hiron.step(self, self.hi_on, self.dt, dm.vec3_sub(g, self.bias), gyro_ok, m, mag_ok)
            return hiron.apply(self, self.hi_on & mag_ok, m)[0]

    def step(self, gyr: Any, acc: Any, mag: Any) -> NDArray[np.uint32]:
        """One update of every instance; gyr, acc, mag of shape (n, 3) or (3,). Returns flags (n,)."""
        g = split3(gyr, self.n)
        a = split3(acc, self.n)
        m = self._hard_iron(g, split3(mag, self.n))
        flags = sensor.check_gyro(g, self.gyro_range)
        gyro_ok = sensor.gyro_usable(g, self.gyro_range, flags)
        accel_flags, n2 = sensor.check_accel2(a, self.accel_range2)
        accel_ok = accel_flags == _U0
        flags = flags | accel_flags
        with np.errstate(all="ignore"):
            e = dm.sqrtf(n2) / self.gravity - dm.ONE
            rejected = accel_ok & (self.accel_reject > dm.ZERO) & (dm.absf(e) > self.accel_reject)
            flags = flags | np.where(rejected, _u(Flag.ACCEL_REJECTED), _U0)
            mag_flags, mnorm = sensor.check_mag(m, self.mag_range)
            mag_ok = mag_flags == _U0
            flags = flags | mag_flags

            # rest detection and gyro bias (att_bias.c)
            self.bias, self.bias_n, self.rest_count, self.rest_gate2, bias_flags, _ = bias_step(
                self.bias_mode,
                self.bias_n_max,
                self.rest_n,
                self.rest_gyro2,
                self.acc2_lo,
                self.acc2_hi,
                self.bias,
                self.bias_n,
                self.rest_count,
                self.rest_gate2,
                g,
                gyro_ok,
                accel_ok,
                n2,
            )
            flags = flags | bias_flags

            # not yet initialised: attitude from the first valid accel (+ mag) sample
            waiting = ~self.initialised
            init_now = waiting & accel_ok
            t = sensor.tilt(a)
            _, q_tilt = dm.quat_normalize_bounded(dm.quat_from_euler(t[0], t[1], self._zeros))
            ok_a0, q_a0, m0_a0 = self._align(q_tilt, m)
            ok_d0, parts0 = self._derive_m0(m0_a0)
            good0 = ok_a0 & ok_d0
            init_mag = init_now & mag_ok & good0
            q_start = dm.quat_where(init_mag, q_a0, q_tilt)
            flags = flags | np.where(
                waiting, np.where(accel_ok, _u(Flag.INITIALISED), _u(Flag.NOT_READY)), _U0
            )
            flags = flags | np.where(init_now & mag_ok & ~good0, _u(Flag.MAG_REJECTED), _U0)

            # running: the recovery counter (att_mars_recovery), then the step
            run = ~waiting
            self.rec_left, ended, self.rec_lp_n = recovery_step(
                g, self.clip, self.rec_n, self.rec_left, run, self.rec_lp_n
            )
            # the fast phase after a clip's recovery (the start's runs inside the alignment's)
            self.fast_left = np.where(ended & self.rec_clip, self.fast_start_n, self.fast_left).astype(
                np.uint32
            )
            rec = self.rec_left > _U0
            self.rec_clip = self.rec_clip | (run & rec & (self.rec_left == self.rec_n))
            flags = flags | np.where(run & rec, _u(Flag.INITIALISED), _U0)
            k_rec_lp, lp_n1, k_rec_lp2 = recovery_lp_gain2(self.rec_lp_n, self.k_lp)
            k_lp = np.where(rec, k_rec_lp, self.k_lp)
            k_lp2 = np.where(rec, k_rec_lp2, self.k_lp)
            q = self.q
            w = dm.vec3_sub(g, self.bias)
            q_rv = dm.quat_mul(q, dm.quat_from_rotvec_fast(dm.vec3_scale(w, self.dt)))
            ok_fo, q_fo = dm.quat_normalize_bounded(_integrate(q, w, self.dt))
            rotvec = self.integration == Integration.ROTVEC
            q1 = dm.quat_where(gyro_ok, dm.quat_where(rotvec, q_rv, dm.quat_where(ok_fo, q_fo, q)), q)
            numeric = gyro_ok & ~rotvec & ~ok_fo
            lp_on = self.k_lp > dm.ZERO
            use_acc = run & accel_ok & ~rejected
            self.rec_lp_n = np.where(use_acc & lp_on & rec, lp_n1, self.rec_lp_n).astype(np.uint32)
            me = dm.quat_rotate(q1, m)  # the mag in the earth frame of the predicted attitude
            v = dm.quat_rotate(q1, a)
            lp1n = dm.vec3_add(self.lp1, dm.vec3_scale(dm.vec3_sub(v, self.lp1), k_lp))
            lp2n = dm.vec3_add(self.lp2, dm.vec3_scale(dm.vec3_sub(lp1n, self.lp2), k_lp2))
            v = dm.vec3_where(lp_on, lp2n, v)
            # full alignment (k_acc == 1)
            ok_f, (fw, fx, fy), n_f = align_up(v)
            q_af = dm.quat_mul_hz(fw, fx, fy, q1)
            lp1_f = dm.quat_rotate_hz(fw, fx, fy, lp1n)
            lp2_f = (self._zeros, self._zeros, n_f)
            # partial correction (k_acc < 1)
            ok_u, unit = dm.vec3_normalize(v)
            qc = _rotation_toward(unit, self._up, self._xaxis, self.k_acc)
            q_ap = dm.quat_mul(qc, q1)
            lp1_p = dm.quat_rotate(qc, lp1n)
            lp2_p = dm.quat_rotate(qc, lp2n)
            full = self.full
            ok_c = np.where(full, ok_f, ok_u)
            q2 = dm.quat_where(use_acc & ok_c, dm.quat_where(full, q_af, q_ap), q1)
            lp1c = dm.vec3_where(ok_c, dm.vec3_where(full, lp1_f, lp1_p), lp1n)
            lp2c = dm.vec3_where(ok_c, dm.vec3_where(full, lp2_f, lp2_p), lp2n)
            lp_upd = use_acc & lp_on

            gated, rej_c, q_corr, theta = self._mag_correct(q2, me, mnorm)
            ok_al, q_al, m0_al = self._align(q2, m)
            ok_dl, parts_l = self._derive_m0(m0_al)
            good_l = ok_al & ok_dl
            ok_ds, parts_s = self._derive_m0(dm.quat_rotate(q2, m))
            m0_was = self.m0_valid.copy()  # the mag step's reference state (before this step's commit)
            use_corr = run & mag_ok & m0_was
            use_align = run & mag_ok & ~self.m0_valid & self.init_from_sensors
            use_set = run & mag_ok & ~self.m0_valid & ~self.init_from_sensors
            q3 = dm.quat_where(use_corr, q_corr, dm.quat_where(use_align & good_l, q_al, q2))
            bad_mag = (use_corr & rej_c) | (use_align & ~good_l) | (use_set & ~ok_ds)
            flags = flags | np.where(bad_mag, _u(Flag.MAG_REJECTED), _U0)
            flags = flags | np.where(use_align & good_l, _u(Flag.INITIALISED), _U0)
            ok_n, q_fin = dm.quat_normalize_bounded(q3)
            flags = flags | np.where(run & (numeric | ~ok_n), _u(Flag.NUMERIC), _U0)
            q_run = dm.quat_where(ok_n, q_fin, q)
            self.q = dm.quat_where(waiting, dm.quat_where(init_now, q_start, q), q_run)
            lp_init = dm.quat_rotate(q_start, a)
            upd = lp_upd & ok_n
            self.lp1 = dm.vec3_where(init_now, lp_init, dm.vec3_where(upd, lp1c, self.lp1))
            self.lp2 = dm.vec3_where(init_now, lp_init, dm.vec3_where(upd, lp2c, self.lp2))
        self._commit_m0(init_mag, parts0)
        self._commit_m0(use_align & good_l, parts_l)
        self._commit_m0(use_set & ok_ds, parts_s)
        self.fast_left = np.where(init_mag | (use_align & good_l), self.fast_start_n, self.fast_left)
        self.fast_left = self.fast_left.astype(np.uint32)
        count = run & ok_n & self.m0_valid
        learn = (
            count & self.bias_mag_on & use_corr & ~rej_c & (self.fast_left == _U0) & (self.rec_left == _U0)
        )
        self._bias_mag(learn, theta)
        flags = flags | np.where(learn, _u(Flag.BIAS_UPDATED), _U0)
        self._ref_count(count, use_corr & ~gated, use_corr & gated, mnorm, me[2])
        # the start is a recovery: the stages' running mean from its sample on, the strong correction
        self.rec_left, self.rec_lp_n = recovery_start(init_now, self.rec_n, self.rec_left, self.rec_lp_n)
        self.rec_clip = self.rec_clip & ~init_now
        self.initialised = self.initialised | init_now
        self.steps = self.steps + np.uint32(1)
        # the covariance's last accepted corrections (the start, an alignment, a sample used)
        acc_now = init_now | use_acc  # stamped before the commit, as in C
        mag_now = init_mag | (use_align & good_l) | (use_set & ok_ds) | (count & use_corr & ~gated)
        before = self.steps - _U1  # the stamps hold the steps before the step (as in C)
        self.acc_step = np.where(acc_now, before, self.acc_step).astype(np.uint32)
        self.mag_step = np.where(mag_now, before, self.mag_step).astype(np.uint32)
        # the gap of steps without a mag sample: a valid sample after one, the alignment's or the
        # reference's sample and an invalid one end it (att_mars_gap_close: period and stamp kept), a valid
        # one without a gap leaves it at 0, an absent step (MAG_ABSENT) counts it up (saturating)
        absent = (mag_flags & _u(Flag.MAG_ABSENT)) != _U0
        closes = run & ((mag_ok & m0_was & (self.mag_gap != _U0)) | (mag_ok & ~m0_was) | (~mag_ok & ~absent))
        # att_mars_gap_count: a gap's first step forgets the previous gap unless a gap-ending sample was
        # the step before
        forget = run & absent & (self.mag_gap == _U0) & ((before - _U1) != self.mag_gap_step)
        self.mag_period = np.where(forget, _U0, self.mag_period).astype(np.uint32)
        self.mag_period = np.where(closes, self.mag_gap, self.mag_period).astype(np.uint32)
        self.mag_gap_step = np.where(closes, before, self.mag_gap_step).astype(np.uint32)
        more = np.minimum(self.mag_gap + _U1, GAP_MAX)
        self.mag_gap = np.where(run & ~absent, _U0, np.where(run, more, self.mag_gap)).astype(np.uint32)
        self.flags = flags.astype(np.uint32)
        return self.flags

    def _bias_mag(self, cond: Any, theta: Any) -> None:
        """att_mars_bias_mag where cond: b -= (theta / tau_bias_mag) r3, r3 = R(q)^T z."""
        w, x, y, z = self.q
        with np.errstate(all="ignore"):
            k = theta * self.k_bias_mag
            rx = dm.TWO * (x * z - w * y)
            ry = dm.TWO * (y * z + w * x)
            rz = dm.ONE - dm.TWO * (x * x + y * y)
            r = self.gyro_range
            b = (
                dm.clampf(self.bias[0] - k * rx, -r, r),
                dm.clampf(self.bias[1] - k * ry, -r, r),
                dm.clampf(self.bias[2] - k * rz, -r, r),
            )
        self.bias = dm.vec3_where(cond, b, self.bias)

    def _ref_count(self, count: Any, accepted: Any, gated: Any, mnorm: Any, mz: Any) -> None:
        """att_mars_ref_count (and att_mars_ref_block at the end of a block) where count."""
        end = mr.count(self, count, accepted, gated, mnorm, mz)
        if not end.any():
            return
        dec = end & (self.fast_left > _U0)  # the fast phase is counted in blocks
        self.fast_left = np.where(dec, self.fast_left - _U1, self.fast_left).astype(np.uint32)
        follow, adopt, n, s = mr.block(self, end, self.m0)
        ok, parts = self._derive_m0(mr.m0_from(self.m0, n, s, self.decl_sin, self.decl_cos))
        self._commit_m0((follow | adopt) & ok, parts)
        longer = adopt & (self.fast_left < self.fast_n)  # a longer phase under way runs on
        self.fast_left = np.where(longer, self.fast_n, self.fast_left).astype(np.uint32)

    def retune(self, settings: MarsSettings) -> None:
        """att_mars_retune: new settings, the state kept (bias_init for OFF/FROZEN, counters limited)."""
        new = Mars(settings, self.n)
        carry_state(self, new)
        hiron.reset_where(new, new.hi_on != self.hi_on)  # turned on or off: the estimate starts again
        hiron.retune(new)
        bias_retune(new)
        ok, parts = new._derive_m0(new.m0)
        new._commit_m0(new.m0_valid & ok, parts, new_block=False)  # the limits only: the block is kept
        new.fast_left = np.minimum(new.fast_left, new.fast_start_n).astype(np.uint32)
        new.rec_left = np.minimum(new.rec_left, new.rec_n).astype(np.uint32)
        self.__dict__.update(new.__dict__)

    @property
    def quat(self) -> NDArray[np.float32]:
        """Attitudes (n, 4), w,x,y,z, sensor-to-earth."""
        return stack(self.q)

    @property
    def mag_ref(self) -> NDArray[np.float32]:
        """Reference fields m0 (n, 3), uT, earth frame (zero until known)."""
        return stack(self.m0)

    def run(self, gyr: Any, acc: Any, mag: Any = None) -> tuple[NDArray[np.float32], NDArray[np.uint32]]:
        """Step through N samples: gyr, acc, mag (N, 3) for n == 1 or (N, n, 3); mag None = absent.

        Returns quats (N, 4) or (N, n, 4) and flags (N,) or (N, n).
        """
        if mag is None:
            mag = np.zeros_like(np.asarray(gyr, np.float32))
        return run_steps(self, gyr, acc, mag)
