"""Mirror of firmware/src/filters/mekf/att_mekf.c: multiplicative (error-state) EKF, instances in lockstep.

The covariance algebra lives in :mod:`attica.reference.mekf_cov`, the gyro scale estimate in
:mod:`attica.reference.mekf_scale`, the reference field and the magnetometer phases (att_mekf_start,
att_mekf_mag, att_mekf_mag_first) in :mod:`attica.reference.mekf_mag`. This module holds the coefficients,
the state, :meth:`Mekf.step` (att_mekf_update: a sequence of phase calls) and the other phases, each
named after its C twin, with every C branch as ``np.where``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from attica.reference import detmath as dm
from attica.reference import hardiron as hiron
from attica.reference import magref as mr
from attica.reference import mekf_cov as cv
from attica.reference import mekf_mag as mg
from attica.reference import mekf_scale as msc
from attica.reference import sensor
from attica.reference._common import (
    COV_UNKNOWN,
    StateSpec,
    carry_state,
    recovery_lp_gain,
    recovery_params,
    recovery_q,
    recovery_start,
    recovery_step,
    run_steps,
    setting,
    split3,
    stack,
)
from attica.reference.ars import align_up
from attica.reference.bias import UNKNOWN2
from attica.settings import Flag, MekfSettings

_U0 = np.uint32(0)
THREE = dm.c("0x1.8p+1")
QUARTER = dm.c("0x1p-2")
GATED_MAX = np.uint32(0xFFFFFFFF)
REST_SIGMA2 = dm.c("0x1.2p+3")
"""ATT_MEKF_REST_SIGMA2 = 9: the rest gate takes the bias estimate's error up to 3 sigma."""
SQRT2 = dm.c("0x1.6a09e6p+0")
BW_Q = dm.c("0x1.a8279ap-2")
"""sqrt(2) and sqrt(2) - 1: the Butterworth accel low-pass (ATT_MEKF_SQRT2, ATT_MEKF_BW_Q)."""
REC_MEAN_END = dm.c("0x1.6a09e6p-2")
"""ATT_MEKF_REC_MEAN_END: 1 / (2 sqrt(2)), where a recovery's mean hands over to the Butterworth section."""


def _u(flag: Flag) -> np.uint32:
    return np.uint32(flag.value)


def _split4(x: Any, n: int) -> dm.Quat:
    a = np.broadcast_to(np.asarray(x, dtype=np.float32), (n, 4))
    return (a[:, 0].copy(), a[:, 1].copy(), a[:, 2].copy(), a[:, 3].copy())


class _Sample(NamedTuple):
    """att_mekf_update's sample checks, one value per instance (:meth:`Mekf._check`)."""

    flags: Any
    """The flags of the checks."""
    gyro_ok: Any
    accel_ok: Any
    rejected: Any
    """ACCEL_REJECTED by the norm test (no accel update)."""
    mag_ok: Any
    rest: Any
    """The rest test of the sample (before the counter)."""
    e2: Any
    """(|a|/g - 1)^2 (:attr:`Work.e2`)."""
    mnorm: Any
    """|m| (:attr:`Work.mnorm`)."""


@dataclass
class Work:
    """Mirror of att_mekf_work_t, with the state a run phase changes (C: in ``st``, here kept apart).

    The phases of :meth:`Mekf.step` read and write it; :meth:`Mekf._commit` stores it where initialised.
    """

    q: dm.Quat
    """The attitude (not normalised until the end of the step)."""
    v: dm.Vec3
    """R a of the predicted attitude, earth frame."""
    e2: Any
    """(|a|/g - 1)^2 of a usable accel sample (0 when not needed)."""
    mnorm: Any
    """|m| of a usable mag sample."""
    mz: Any
    """The vertical (earth z) field of a sample tested against m0 (the learnt reference)."""
    accepted: Any
    """The sample passed the norm and dip tests (wk.use == ATT_MAGREF_ACCEPTED)."""
    gated: Any
    """The sample failed them (ATT_MAGREF_GATED)."""
    p: cv.Cov
    """P (st->p)."""
    sv: msc.Sens
    """The scale sensitivity V (st->scale_v)."""
    ps: Any
    """The scale error's variance (st->p_scale)."""
    scale: Any
    """The scale error estimate (st->scale)."""
    bias: dm.Vec3
    """The gyro bias estimate (st->bias)."""
    lp1: dm.Vec3
    """The accel low-pass stages (st->lp1, st->lp2) and whether they have started (st->lp_valid)."""
    lp2: dm.Vec3
    lp_valid: Any


class Mekf:
    """MEKF reference: ``n`` independent instances sharing one settings object.

    Settings fields may be scalars or length-``n`` sequences (one value per instance); vector fields
    may be given as (3,)/(4,) or (n, 3)/(n, 4). Settings are not validated here (att_mekf_init does).
    """

    hi_on: Any
    """Per instance: the hard-iron estimate is on (C's ``c.hi.on``; set by :func:`hardiron.params`)."""

    STATE: StateSpec = {
        "st.q": "quat",
        "st.bias": "vec3",
        "st.p": "f32x21",
        "st.scale": "f32",
        "st.p_scale": "f32",
        "st.scale_v": "f32x6",
        "st.lp1": "vec3",
        "st.lp2": "vec3",
        "st.k_lp": "f32:k_lp_now",
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
        "st.rest_e2": "f32",
        "st.rest_e2_n": "u32",
        "st.steps": "u32",
        "st.flags": "u32",
        "st.rec_left": "u32",
        "st.rec_lp_n": "u32",
        **mr.state_spec("st.ref"),
        **hiron.state_spec("st.hi"),
        "st.m0_valid": "bool",
        "st.lp_valid": "bool",
        "st.rec_clip": "bool",
        "st.initialised": "bool",
        "st.head_known": "bool",
        "st.rested": "bool",
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
        "c.k_lp_no_rest": "f32",
        "c.n_recover": "u32",
        "c.r_rest": "f32",
        "c.rest_gyro2": "f32",
        "c.acc2_lo": "f32",
        "c.acc2_hi": "f32",
        "c.rest_n": "u32",
        "c.p0_scale": "f32",
        "c.scale_init": "f32",
        "c.clip": "f32",
        "c.k_lp_rec": "f32",
        "c.q_rec_tilt": "f32",
        "c.q_rec_head": "f32",
        "c.rec_n": "u32",
        "c.decl": "f32",
        "c.decl_sin": "f32",
        "c.decl_cos": "f32",
        **mr.coeff_spec("c.ref"),
        **hiron.coeff_spec("c.hi"),
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
            tau_nr = f(s.tau_acc_lp_no_rest, n)
            k_nr = np.where(
                (self.k_lp > dm.ZERO) & (tau_nr > dm.ZERO), self.dt / (SQRT2 * tau_nr + self.dt), self.k_lp
            )
            self.k_lp_no_rest = k_nr.astype(np.float32)
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
        self._rec_coeffs(s)
        self.decl = setting(s.declination, n)
        self.decl_sin = dm.sinf(self.decl)
        self.decl_cos = dm.cosf(self.decl)
        mr.params(
            self,
            self.dt,
            setting(s.mag_ref_tau, n),
            setting(s.mag_new_time, n),
            self.mag_norm_reject,
            self.mag_dip_reject,
        )
        hiron.params(
            self,
            self.dt,
            np.where(self.use_mag, setting(s.hard_iron_tau, n), dm.ZERO).astype(np.float32),
            setting(s.hard_iron_rate, n),
            self.mag_norm_reject,
            self.mag_range,
        )
        self.reset()

    def _rec_coeffs(self, s: MekfSettings) -> None:
        """att_mekf_rec_coeffs: the recovery after a clipping gyro (k^2 r / (1 - k): steady-state gain k)."""
        self.rec_n, self.clip, k = recovery_params(setting(s.recovery_time, self.n), self.gyro_range, self.dt)
        k_nr = self.k_lp_no_rest
        self.k_lp_rec = np.where(self.lp_on & (k > k_nr), k, k_nr).astype(np.float32)
        on = self.rec_n > _U0
        self.q_rec_tilt = np.where(on, recovery_q(k, self.r_acc, self.p_max), dm.ZERO).astype(np.float32)
        self.q_rec_head = np.where(on, recovery_q(k, self.r_mag, self.p_max), dm.ZERO).astype(np.float32)

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
        self.rest_e2: Any = z.copy()
        self.rest_e2_n = np.zeros(n, np.uint32)
        self.steps = np.zeros(n, np.uint32)
        self.flags = np.zeros(n, np.uint32)
        self.rec_left = np.zeros(n, np.uint32)
        self.rec_lp_n = np.zeros(n, np.uint32)
        mr.reset(self, n)
        hiron.reset(self, n)
        self.m0_valid: Any = np.zeros(n, np.bool_)
        self.lp_valid: Any = np.zeros(n, np.bool_)
        self.rec_clip: Any = np.zeros(n, np.bool_)
        self.initialised: Any = ~self.init_from_sensors
        self.head_known: Any = np.zeros(n, np.bool_)
        self.rested: Any = np.zeros(n, np.bool_)
        self.k_lp_now: Any = self.k_lp_no_rest.copy()
        mi = self.m0_init
        nonzero = ~((mi[0] == dm.ZERO) & (mi[1] == dm.ZERO) & (mi[2] == dm.ZERO))
        ok, parts = mg.derive_m0(self, mi)
        mg.commit_m0(self, nonzero & ok, parts)

    # --- the step ------------------------------------------------------------------------------

    def step(self, gyr: Any, acc: Any, mag: Any) -> NDArray[np.uint32]:
        """One update of every instance: the mirror of att_mekf_update, phase for phase.

        Every instance goes through every phase: the start (att_mekf_start) is computed for all and kept
        where not yet initialised, the run phases act where initialised (``run``), each C branch an
        ``np.where``; :meth:`_commit` stores the result.

        Parameters
        ----------
        gyr, acc, mag
            The sample, each of shape (n, 3) or (3,): rad/s, m/s^2, uT.

        Returns
        -------
        NDArray[np.uint32]
            The flags of the step, shape (n,).

        """
        g = split3(gyr, self.n)
        a = split3(acc, self.n)
        m = split3(mag, self.n)
        run = self.initialised
        with np.errstate(all="ignore"):
            ck = self._check(g, a, m)
            # the hard-iron estimate (att_mekf_hard_iron), then its offset off a valid mag sample
            on = self.use_mag & self.hi_on
            w_hi = dm.vec3_scale(dm.vec3_sub(g, self.bias), dm.ONE + self.scale)
            g_ok = ck.gyro_ok & hiron.gyro_ok(_U0, g, self.gyro_range)
            hiron.step(self, on, self.dt, w_hi, g_ok, m, ck.mag_ok)
            m, mnorm_hi = hiron.apply(self, on & ck.mag_ok, m)
            ck = ck._replace(mnorm=np.where(on & ck.mag_ok, mnorm_hi, ck.mnorm).astype(np.float32))
            start = mg.start(self, a, m, ck.accel_ok, ck.mag_ok)
            flags = ck.flags | start.flags
            # 6. the recovery after a clipping gyro: its counter where initialised
            self.rec_left, _, self.rec_lp_n = recovery_step(
                g, self.clip, self.rec_n, self.rec_left, run, self.rec_lp_n
            )
            clipping = run & (self.rec_n > _U0) & (self.rec_left == self.rec_n)
            self.lp_valid = self.lp_valid & ~clipping  # the low-pass restarts after a clipping sample
            self.rec_clip = self.rec_clip | clipping
            self.head_known = self.head_known & ~clipping  # the heading lost rotation (6-axis cov[2])
            rec = run & (self.rec_left > _U0)
            flags = flags | np.where(rec, _u(Flag.INITIALISED), _U0)
            # 0. rest: the zero-rate pseudo-measurement
            wk = self._work(ck)
            flags = flags | self._rest_update(wk, self._rest_count(run, ck.rest), g, rec)
            # 1. prediction, 2. accel update, 3. mag update
            qa, wr = self._integrate(wk, ck.gyro_ok, g)
            self._propagate(wk, run, ck.gyro_ok, a, wr, qa)
            self._rec_noise(wk, rec)
            flags = flags | self._accel(wk, run & ck.accel_ok & ~ck.rejected, rec)
            flags = flags | mg.mag(self, wk, run & ck.mag_ok & self.m0_valid, m)
            flags = flags | mg.mag_first(self, wk, run & ck.mag_ok & ~self.m0_valid, m)
            mg.ref_count(self, wk, run & self.m0_valid)
            # 4. conditioning of P and the scale estimate, 5. normalisation
            flags = flags | self._condition(wk, run)
            flags = flags | self._scale_bound(wk, run)
            ok_n, qn = dm.quat_normalize_bounded(wk.q)
            flags = flags | np.where(run & ~ok_n, _u(Flag.NUMERIC), _U0)
            self._commit(wk, run, start, ok_n, qn)
        self.steps = self.steps + np.uint32(1)
        self.flags = flags.astype(np.uint32)
        return self.flags

    def _check(self, g: dm.Vec3, a: dm.Vec3, m: dm.Vec3) -> _Sample:
        """Mirror of att_mekf_update's sample checks, the accel norm's error and the rest test."""
        w = np.where
        flags = sensor.check_gyro(g, self.gyro_range)
        gyro_ok = sensor.gyro_usable(g, self.gyro_range, flags)
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
        d = dm.vec3_sub(g, self.bias)
        pb = (self.p[cv.ix(3, 3)] + self.p[cv.ix(4, 4)]) + self.p[cv.ix(5, 5)]
        wid = REST_SIGMA2 * pb
        wid = np.where(wid > UNKNOWN2, UNKNOWN2, wid)  # at most ATT_BIAS_UNKNOWN2 (NaN stays NaN)
        gate = np.where(self.rest_gyro2 > dm.ZERO, self.rest_gyro2 + wid, dm.ZERO)
        rest = gyro_ok & accel_ok & (dm.vec3_dot(d, d) < gate) & (n2 > self.acc2_lo)
        rest = rest & (n2 < self.acc2_hi)
        return _Sample(flags, gyro_ok, accel_ok, rejected, mag_ok, rest, e2, mnorm)

    def _work(self, ck: _Sample) -> Work:
        """Mirror of att_mekf_update's ``wk`` (``wk.q = st->q``): the work record from the state."""
        z = self._zeros
        return Work(
            self.q,
            (z, z, z),
            ck.e2,
            ck.mnorm,
            z,
            np.zeros(self.n, np.bool_),
            np.zeros(self.n, np.bool_),
            list(self.p),
            list(self.scale_v),
            self.p_scale,
            self.scale,
            self.bias,
            self.lp1,
            self.lp2,
            self.lp_valid,
        )

    def _rest_count(self, run: Any, rest: Any) -> Any:
        """Mirror of att_mekf_update's rest counter (step 0); returns where att_mekf_rest_update runs."""
        w = np.where
        inc = w(self.rest_count < self.rest_n, self.rest_count + np.uint32(1), self.rest_count)
        count = w(~rest, _U0, inc)
        self.rest_count = w(run, count, self.rest_count).astype(np.uint32)
        ended = run & ~rest  # the next rest measures its own noise
        self.rest_e2 = w(ended, dm.ZERO, self.rest_e2).astype(np.float32)
        self.rest_e2_n = w(ended, _U0, self.rest_e2_n).astype(np.uint32)
        at_rest = run & rest & (self.rest_count >= self.rest_n)
        self.rested = self.rested | at_rest  # the bias measured: the low-pass's longer lag pays from now on
        self.k_lp_now = np.where(at_rest, self.k_lp, self.k_lp_now).astype(np.float32)
        return at_rest

    def _rest_noise(self, at_rest: Any, g: dm.Vec3, bias: dm.Vec3) -> Any:
        """Mirror of att_mekf_rest_noise where ``at_rest``: the zero-rate noise per sample and axis."""
        w = np.where
        e = dm.vec3_sub(g, bias)
        e2 = dm.vec3_dot(e, e) / THREE
        k = dm.ONE / (self.rest_e2_n.astype(np.float32) + dm.ONE)
        mean = self.rest_e2 + (e2 - self.rest_e2) * k
        self.rest_e2 = w(at_rest, mean, self.rest_e2).astype(np.float32)
        inc = at_rest & (self.rest_e2_n < self.rest_n)
        self.rest_e2_n = w(inc, self.rest_e2_n + np.uint32(1), self.rest_e2_n).astype(np.uint32)
        return w(self.rest_e2 > self.r_rest, self.rest_e2, self.r_rest).astype(np.float32)

    def _rest_update(self, wk: Work, at_rest: Any, g: dm.Vec3, rec: Any) -> Any:
        """Mirror of att_mekf_rest_update (with att_mekf_rest_axis) where ``at_rest``; returns the flags.

        ``rec``: a recovery runs (p_s 0 for the updates, p_scale kept).
        """
        w = np.where
        flags = w(at_rest, _u(Flag.AT_REST) | _u(Flag.BIAS_UPDATED), _U0)
        r = self._rest_noise(at_rest, g, wk.bias)
        ps_in = w(rec, dm.ZERO, wk.ps).astype(np.float32)
        p_r, dth_r, b_r, sv_r, ps_r, sc_r = cv.rest_apply(wk.p, r, g, wk.bias, wk.sv, ps_in, wk.scale)
        wk.p = cv.where(at_rest, p_r, wk.p)
        wk.sv = msc.where(at_rest, sv_r, wk.sv)
        wk.ps = w(at_rest & ~rec, ps_r, wk.ps).astype(np.float32)
        wk.scale = w(at_rest, sc_r, wk.scale).astype(np.float32)
        wk.bias = dm.vec3_where(at_rest, (b_r[0], b_r[1], b_r[2]), wk.bias)
        self._rest_apply(wk, at_rest, dth_r)
        return flags

    def _rest_apply(self, wk: Work, at_rest: Any, dth: list[Any]) -> None:
        """Mirror of att_mekf_rest_apply where ``at_rest``: the rotation dth applied to q and the low-pass."""
        dq_r = dm.quat_from_rotvec_fast((dth[0], dth[1], dth[2]))
        wk.q = dm.quat_where(at_rest, dm.quat_mul(dq_r, wk.q), wk.q)
        rot_r = at_rest & self.lp_on
        wk.lp1 = dm.vec3_where(rot_r, dm.quat_rotate(dq_r, wk.lp1), wk.lp1)
        wk.lp2 = dm.vec3_where(rot_r, dm.quat_rotate(dq_r, wk.lp2), wk.lp2)

    def _integrate(self, wk: Work, gyro_ok: Any, g: dm.Vec3) -> tuple[Any, dm.Vec3]:
        """Mirror of att_mekf_integrate where ``gyro_ok``: (qa, else c->qa; w - b, for the propagation)."""
        wr = dm.vec3_sub(g, wk.bias)
        ws = dm.vec3_scale(wr, dm.ONE + wk.scale)
        q_int = dm.quat_mul(wk.q, dm.quat_from_rotvec_fast(dm.vec3_scale(ws, self.dt)))
        wk.q = dm.quat_where(gyro_ok, q_int, wk.q)
        qa = np.where(gyro_ok, self.qa + self.qw * dm.vec3_dot(ws, ws), self.qa).astype(np.float32)
        return qa, wr

    def _propagate(self, wk: Work, run: Any, gyro_ok: Any, a: dm.Vec3, wr: dm.Vec3, qa: Any) -> None:
        """Mirror of att_mekf_propagate (with att_mekf_predict): P and V predicted where ``run``, v = R a."""
        r = dm.quat_to_matrix(wk.q)
        wk.p = cv.where(run, cv.predict(wk.p, r, self.half_dt, self.dt, qa, self.qb), wk.p)
        wk.sv = msc.where(run, msc.predict(wk.sv, r, gyro_ok, wr, self.dt), wk.sv)
        wk.v = (
            r[0] * a[0] + r[1] * a[1] + r[2] * a[2],
            r[3] * a[0] + r[4] * a[1] + r[5] * a[2],
            r[6] * a[0] + r[7] * a[1] + r[8] * a[2],
        )

    def _rec_noise(self, wk: Work, rec: Any) -> None:
        """Mirror of att_mekf_rec_noise where ``rec``: the recovery's process noise on the attitude."""
        p = list(wk.p)
        for i, qn in (
            (cv.ix(0, 0), self.q_rec_tilt),
            (cv.ix(1, 1), self.q_rec_tilt),
            (cv.ix(2, 2), self.q_rec_head),
        ):
            p[i] = np.where(rec, p[i] + qn, p[i]).astype(np.float32)
        wk.p = p

    def _accel(self, wk: Work, acc_try: Any, rec: Any) -> Any:
        """Mirror of att_mekf_accel where ``acc_try`` (a usable sample, initialised); returns its flags.

        ``rec``: a recovery runs (the low-pass: the running mean of recovery_lp_gain in both states until
        it is below its floor over 2 sqrt(2), the floor the gain of the moment (k_lp_now) after a clipping
        sample and k_lp_rec in the start's recovery; a gate rejection recovered at once, the scale
        estimate left alone).
        """
        w = np.where
        u = wk.v
        start_lp = ~wk.lp_valid
        l1 = dm.vec3_where(start_lp, u, wk.lp1)
        l2 = dm.vec3_where(start_lp, u, wk.lp2)
        k = self.k_lp_now
        floor = w(self.rec_clip, k, self.k_lp_rec).astype(np.float32)
        k_end = (REC_MEAN_END * floor).astype(np.float32)
        k_mean, lp_n1, k_mean2 = recovery_lp_gain(self.rec_lp_n, floor, k_end)
        l1, l2 = _lowpass(u, w(rec, k_mean, k), w(rec, k_mean2, k), l1, l2)
        self.rec_lp_n = w(acc_try & self.lp_on & rec, lp_n1, self.rec_lp_n).astype(np.uint32)
        u = dm.vec3_where(self.lp_on, l2, u)
        ok_u, (_, cx, cy), _ = align_up(u)
        y0 = dm.TWO * cx
        y1 = dm.TWO * cy
        rn = self.r_acc * (dm.ONE + self.r_accel * wk.e2)
        v = cv.innov(wk.p, rn, y0, y1)
        measure = acc_try & ok_u
        gate_on = self.gate > dm.ZERO
        hit = measure & gate_on & (v[4] > self.gate * v[3])
        gated = w(hit & (self.gated < GATED_MAX), self.gated + np.uint32(1), self.gated).astype(np.uint32)
        recover = hit & (rec | ((self.n_recover > _U0) & (gated >= self.n_recover)))
        p_rec = cv.recover(wk.p, self.soft, y0, y1, self.p_max)
        v_rec = cv.innov(p_rec, rn, y0, y1)
        p = cv.where(recover, p_rec, wk.p)
        v = tuple(w(recover, x1, x0).astype(np.float32) for x0, x1 in zip(v, v_rec, strict=True))
        flags = w(hit & ~recover, _u(Flag.ACCEL_REJECTED), _U0)
        want = measure & (~hit | recover)
        det_ok = v[3] > dm.ZERO
        flags = flags | w(want & ~det_ok, _u(Flag.NUMERIC), _U0)
        apply = want & det_ok
        self.gated = w(apply, _U0, gated).astype(np.uint32)
        ps_in = w(rec, dm.ZERO, wk.ps).astype(np.float32)  # a recovery: p_s 0 for the update, ds = 0
        p_a, dx, sv_a, ds_a, ps_a = cv.accel_apply(p, v, y0, y1, gate_on, self.soft, wk.sv, ps_in, ~rec)
        wk.p = cv.where(apply, p_a, p)
        wk.sv = msc.where(apply, sv_a, wk.sv)
        wk.ps = w(apply & ~rec, ps_a, wk.ps).astype(np.float32)
        wk.scale = w(apply, wk.scale + ds_a, wk.scale).astype(np.float32)
        dq = dm.quat_from_rotvec_fast((dx[0], dx[1], dx[2]))
        wk.q = dm.quat_where(apply, dm.quat_mul(dq, wk.q), wk.q)
        wk.bias = dm.vec3_where(apply, (wk.bias[0] + dx[3], wk.bias[1] + dx[4], wk.bias[2] + dx[5]), wk.bias)
        lp_commit = apply & self.lp_on
        wk.lp1 = dm.vec3_where(lp_commit, dm.quat_rotate(dq, l1), wk.lp1)
        wk.lp2 = dm.vec3_where(lp_commit, dm.quat_rotate(dq, l2), wk.lp2)
        wk.lp_valid = wk.lp_valid | lp_commit
        return flags | w(apply, _u(Flag.BIAS_UPDATED), _U0)

    def _condition(self, wk: Work, run: Any) -> Any:
        """Mirror of att_mekf_condition (with att_mekf_repair) where ``run``; returns the flags."""
        p_c, clamped = cv.condition(wk.p, self.p_max, self.p0_bias)
        wk.p = cv.where(run, p_c, wk.p)
        return np.where(run & clamped, _u(Flag.CLAMPED), _U0)

    def _scale_bound(self, wk: Work, run: Any) -> Any:
        """Mirror of att_mekf_scale_bound (with att_mekf_scale_limit); returns the flags where ``run``."""
        wk.scale, wk.ps, wk.sv, clamped_s = msc.bound(wk.scale, wk.ps, wk.sv)
        return np.where(run & clamped_s, _u(Flag.CLAMPED), _U0)

    def _commit(self, wk: Work, run: Any, start: mg.Start, ok_n: Any, qn: dm.Quat) -> None:
        """Mirror of att_mekf_update's stores (att_mekf_start's for the instances not yet initialised)."""
        w = np.where
        waiting = ~run
        init_now, init_mag = start.init_now, start.init_mag
        q_wait = dm.quat_where(init_now, start.q, self.q)
        self.q = dm.quat_where(waiting, q_wait, dm.quat_where(ok_n, qn, self.q))
        p_start, sv_wait = mg.yaw_reset(init_mag, self.p, self.scale_v, self.p0_att)
        self.p = cv.where(waiting, p_start, wk.p)
        self.bias = dm.vec3_where(run, wk.bias, self.bias)
        self.scale = w(run, wk.scale, self.scale).astype(np.float32)
        self.p_scale = w(run, wk.ps, self.p_scale).astype(np.float32)
        self.scale_v = msc.where(waiting, sv_wait, msc.where(run, wk.sv, self.scale_v))
        self.lp1 = dm.vec3_where(init_now, start.lp, dm.vec3_where(run, wk.lp1, self.lp1))
        self.lp2 = dm.vec3_where(init_now, start.lp, dm.vec3_where(run, wk.lp2, self.lp2))
        self.lp_valid = self.lp_valid | init_now | (run & wk.lp_valid)
        mg.commit_m0(self, init_mag, start.parts)
        # the start is a recovery too (att_mekf_start)
        self.rec_left, self.rec_lp_n = recovery_start(init_now, self.rec_n, self.rec_left, self.rec_lp_n)
        self.rec_clip = self.rec_clip & ~init_now
        self.initialised = self.initialised | init_now

    def retune(self, settings: MekfSettings) -> None:
        """att_mekf_retune: new settings, the state kept (reference limits recomputed, counter limited)."""
        new = Mekf(settings, self.n)
        carry_state(self, new)
        # 9 -> 6 axes: the heading is known if the field tracked it
        to_six = self.use_mag & ~new.use_mag
        new.head_known = np.where(to_six, new.m0_valid, new.head_known)
        hiron.reset_where(new, new.hi_on != self.hi_on)  # turned on or off: the estimate starts again
        hiron.retune(new)
        new.k_lp_now = np.where(new.rested, new.k_lp, new.k_lp_no_rest).astype(np.float32)
        ok, parts = mg.derive_m0(new, new.m0)
        mg.commit_m0(new, new.m0_valid & ok, parts, new_block=False)
        new.rest_count = np.minimum(new.rest_count, new.rest_n).astype(np.uint32)
        new_dt = np.broadcast_to(~(new.dt == self.dt), (new.n,))  # the zero-rate noise is per sample
        new.rest_e2 = np.where(new_dt, dm.ZERO, new.rest_e2).astype(np.float32)
        new.rest_e2_n = np.where(new_dt, _U0, np.minimum(new.rest_e2_n, new.rest_n)).astype(np.uint32)
        new.rec_left = np.minimum(new.rec_left, new.rec_n).astype(np.uint32)
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

    def _get_mag_h(self) -> dm.Vec3:
        return (self.mag_hx, self.mag_hy, dm.f32(np.zeros_like(self.mag_hx)))

    def _set_mag_h(self, v: dm.Vec3) -> None:
        self.mag_hx, self.mag_hy = dm.f32(v[0]), dm.f32(v[1])

    mag_h = property(_get_mag_h, _set_mag_h)
    """The heading measurement's tilt entries (mag_hx, mag_hy) as an earth-frame vector with z = 0: one of
    the EARTH memories a heading turn rotates (att_mekf_yaw_to turns them with m0_ref)."""

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
        return (p[0], p[6], self._cov_heading(), (p[15] + p[18] + p[20]) / THREE)

    def _cov_heading(self) -> Any:
        """att_mekf_cov_heading: P's heading variance, but pi^2/3 for a 6-axis filter's unknown heading.

        Known from a set heading to the next clipping gyro sample (then at most pi^2/3).
        """
        v = self.p[11]
        own = self.use_mag | (self.head_known & (v < COV_UNKNOWN))
        return np.where(own, v, COV_UNKNOWN).astype(np.float32)

    def heading_set(self) -> None:
        """att_mekf_yaw_to with gain 1: the heading is known from here.

        Without the magnetometer the set heading is exact: the heading's row reset to one step's noise qa
        (its correlations zero). With it north is relabelled (the reference field turns with the
        attitude): P is unchanged.
        """
        six = ~np.broadcast_to(self.use_mag, (self.n,))
        self.p, self.scale_v = mg.yaw_reset(six, self.p, self.scale_v, self.qa)
        self.head_known = np.ones(self.n, np.bool_)

    def run(self, gyr: Any, acc: Any, mag: Any = None) -> tuple[NDArray[np.float32], NDArray[np.uint32]]:
        """Step through N samples: gyr, acc, mag (N, 3) for n == 1 or (N, n, 3); mag None = absent.

        Returns quats (N, 4) or (N, n, 4) and flags (N,) or (N, n).
        """
        if mag is None:
            mag = np.zeros_like(np.asarray(gyr, np.float32))
        return run_steps(self, gyr, acc, mag)


def _lowpass(u: dm.Vec3, k: Any, k2: Any, lp1: dm.Vec3, lp2: dm.Vec3) -> tuple[dm.Vec3, dm.Vec3]:
    """Mirror of att_mekf_lowpass: the second-order Butterworth section, (lp1, lp2) after the sample u.

    ``k2`` is the second stage's gain: 1 during a recovery's running mean, else ``k``.
    """
    kq = BW_Q * k
    d = dm.vec3_sub(lp1, lp2)
    e = dm.vec3_sub(u, lp2)
    lp1 = dm.vec3_add(lp1, dm.vec3_sub(dm.vec3_scale(e, k), dm.vec3_scale(d, kq)))
    lp2 = dm.vec3_add(lp2, dm.vec3_scale(dm.vec3_sub(lp1, lp2), k2))
    return lp1, lp2
