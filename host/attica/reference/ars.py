"""Mirror of firmware/src/filters/ars/att_ars.c: the quaternion complementary ARS, instances in lockstep."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.reference import detmath as dm
from attica.reference import sensor
from attica.reference._common import (
    COV_TILT_MAX,
    COV_UNKNOWN,
    StateSpec,
    carry_state,
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
from attica.reference.bias import bias_params, bias_retune, bias_step
from attica.settings import ArsSettings, BiasMode, Flag, Integration

_U0 = np.uint32(0)
A_MIN = dm.c("0x1p-19")
"""Below this (|v| + v_z) / |v| the aligned vector points down: half turn about x (ATT_ALIGN_A_MIN)."""


def _u(flag: Flag) -> np.uint32:
    return np.uint32(flag.value)


def align_up(v: dm.Vec3) -> tuple[Any, tuple[Any, Any, Any], Any]:
    """att_i_align_up: (ok, (w, x, y) of the full alignment of v with z, |v|)."""
    with np.errstate(all="ignore"):
        n2 = dm.vec3_dot(v, v)
        ok = n2 >= dm.NORM2_MIN
        n = dm.sqrtf(n2)
        a = n + v[2]
        up = a > A_MIN * n
        inv = dm.ONE / dm.sqrtf((dm.TWO * n) * a)
        qw = np.where(up, a * inv, dm.ZERO)
        qx = np.where(up, v[1] * inv, dm.ONE)
        qy = np.where(up, -(v[0] * inv), dm.ZERO)
    return ok, (qw, qx, qy), n


class Ars:
    """Complementary ARS reference: ``n`` independent instances sharing one settings object.

    Settings fields may be scalars or length-``n`` sequences (one value per instance).
    """

    STATE: StateSpec = {
        "st.q": "quat",
        "st.bias": "vec3",
        "st.lp1": "vec3",
        "st.lp2": "vec3",
        "st.bias_n": "u32",
        "st.rest_count": "u32",
        "st.rest_gate2": "f32",
        "st.steps": "u32",
        "st.flags": "u32",
        "st.rec_left": "u32",
        "st.rec_lp_n": "u32",
        "st.acc_step": "u32",
        "st.head_step": "u32",
        "st.initialised": "bool",
        "st.head_known": "bool",
    }
    """C state fields mirrored by this class (see reference._common.load_c_state)."""
    EARTH: tuple[str, ...] = ("lp1", "lp2")
    """Earth-frame state vectors, turned with the attitude by a heading change (reference.calib.yaw_to)."""

    COEFFS: StateSpec = {
        "c.dt": "f32",
        "c.k": "f32",
        "c.k_lp": "f32",
        "c.gain_c": "f32",
        "c.gravity": "f32",
        "c.accel_reject": "f32",
        "c.accel_range2": "f32",
        "c.gyro_range": "f32",
        "c.bias.mode": "u32:bias_mode",
        "c.bias.n_max": "u32:bias_n_max",
        "c.bias.rest_n": "u32",
        "c.bias.rest_gyro2": "f32",
        "c.bias.acc2_lo": "f32",
        "c.bias.acc2_hi": "f32",
        "c.bias.rest_first2": "f32",
        "c.q_init": "quat",
        "c.bias_init": "vec3",
        "c.integration": "u32",
        "c.init_from_accel": "bool",
        "c.lp_on": "bool",
        "c.reject_on": "bool",
        "c.full": "bool",
        "c.clip": "f32",
        "c.k_rec": "f32",
        "c.rec_n": "u32",
        "c.var_step": "f32",
        "c.var_tilt": "f32",
        "c.var_tilt_rec": "f32",
    }
    """Every C coefficient of att_ars_coeffs_t (set by att_ars_init / retune), derived here alike
    from the settings; state_matches compares them after the state."""

    def __init__(self, settings: ArsSettings | None = None, n: int = 1) -> None:
        s = settings if settings is not None else ArsSettings()
        self.settings = s
        self.n = n
        self.dt = setting(s.dt, n)
        gain = setting(s.gain, n)
        tau = setting(s.tau, n)
        self.gain_c = setting(s.gain_c, n)
        self.gravity = setting(s.gravity, n)
        self.accel_reject = setting(s.accel_reject, n)
        self.accel_range = setting(s.accel_range, n)
        self.accel_range2 = self.accel_range * self.accel_range
        self.gyro_range = setting(s.gyro_range, n)
        self.bias_mode = setting(np.asarray(s.bias_mode, np.int32), n, np.int32)
        self.bias_n_max = setting(s.bias_n_max, n, np.uint32)
        self.bias_init = split3(s.bias_init, n)
        self.bias_init = dm.vec3_where(  # as c.bias_init: zero when the bias is OFF
            self.bias_mode == BiasMode.OFF, (np.zeros(n, np.float32),) * 3, self.bias_init
        )
        self.rest_gyro = setting(s.rest_gyro, n)
        self.rest_accel = setting(s.rest_accel, n)
        self.rest_gyro2, self.rest_first2, self.acc2_lo, self.acc2_hi = bias_params(
            self.bias_mode, self.rest_gyro, self.rest_accel, self.gravity
        )
        self.rest_time = setting(s.rest_time, n)
        self.integration = setting(int(s.integration), n, np.int32)
        self.init_from_accel = setting(s.init_from_accel, n, np.bool_)
        self.q_init: dm.Quat = (
            setting(s.q_init[0], n),
            setting(s.q_init[1], n),
            setting(s.q_init[2], n),
            setting(s.q_init[3], n),
        )
        _, self.q_init = dm.quat_normalize(self.q_init)  # as c.q_init: normalised once, at init
        with np.errstate(all="ignore"):
            self.k = np.where(tau > dm.ZERO, self.dt / (tau + self.dt), gain).astype(np.float32)
        self.rest_n = sensor.samples(self.rest_time, self.dt)
        tau_lp = setting(s.tau_acc_lp, n)
        with np.errstate(all="ignore"):
            self.k_lp = np.where(tau_lp > dm.ZERO, self.dt / (tau_lp + self.dt), dm.ZERO).astype(np.float32)
        self.full = (self.k == dm.ONE) & (self.gain_c == dm.ZERO)
        self.lp_on = self.k_lp > dm.ZERO
        self.reject_on = self.accel_reject > dm.ZERO
        self._rec_coeffs(s)
        self._cov_coeffs(s)
        self.reset()

    def _cov_coeffs(self, s: ArsSettings) -> None:
        """att_ars_cov_coeffs: the covariance model's coefficients."""
        gn = setting(s.gyro_noise, self.n)
        s2 = gn * gn
        an = setting(s.accel_noise, self.n) / self.gravity
        a2 = an * an
        self.var_step = (s2 * self.dt).astype(np.float32)
        # no accel correction (k = 0): the tilt is not observed
        self.var_tilt = np.where(self.k > dm.ZERO, cov_tilt(self.dt, self.k_lp, self.k, s2, a2), COV_TILT_MAX)
        self.var_tilt_rec = np.where(
            self.k_rec > dm.ZERO, cov_tilt(self.dt, self.k_lp, self.k_rec, s2, a2), COV_TILT_MAX
        ).astype(np.float32)
        self.var_tilt = self.var_tilt.astype(np.float32)

    def heading_set(self) -> None:
        """att_ars_yaw_to with gain 1: the covariance's heading is known from this step."""
        self.head_known = np.ones(self.n, np.bool_)
        self.head_step = self.steps.copy()

    def output_cov(self) -> tuple[Any, Any, Any, Any]:
        """att_ars_cov: the output record's cov (tilt about earth x, y; heading about z; 0), rad^2."""
        tilt = cov_tilt_now(self, self.var_tilt_rec)
        zero = np.zeros(self.n, np.float32)
        known = cov_grow(zero, self.var_step, self.steps + np.uint32(1), self.head_step, COV_UNKNOWN)
        yaw = np.where(self.head_known, known, COV_UNKNOWN).astype(np.float32)
        return (tilt, tilt.copy(), yaw, np.zeros(self.n, np.float32))

    def _rec_coeffs(self, s: ArsSettings) -> None:
        """att_ars_rec_coeffs: the recovery after a clipping gyro."""
        rt = setting(s.recovery_time, self.n)
        self.rec_n, self.clip, k = recovery_params(rt, self.gyro_range, self.dt)
        self.k_rec = np.where(k > self.k, k, self.k).astype(np.float32)

    def reset(self) -> None:
        """Back to the state after construction (att_ars_reset)."""
        n = self.n
        qi = self.q_init
        self.q = (qi[0].copy(), qi[1].copy(), qi[2].copy(), qi[3].copy())
        off = self.bias_mode == BiasMode.OFF
        self.bias = dm.vec3_where(off, dm.vec3(np.zeros(n), np.zeros(n), np.zeros(n)), self.bias_init)
        self.bias_n = np.zeros(n, np.uint32)
        self.rest_count = np.zeros(n, np.uint32)
        self.rest_gate2 = self.rest_first2.copy()
        self.initialised = ~self.init_from_accel
        zero = np.zeros(n, np.float32)
        self.lp1: dm.Vec3 = (zero.copy(), zero.copy(), self.gravity.copy())
        self.lp2: dm.Vec3 = (zero.copy(), zero.copy(), self.gravity.copy())
        self.steps = np.zeros(n, np.uint32)
        self.flags = np.zeros(n, np.uint32)
        self.rec_left = np.zeros(n, np.uint32)
        self.rec_lp_n = np.zeros(n, np.uint32)
        self.acc_step = np.zeros(n, np.uint32)
        self.head_step = np.zeros(n, np.uint32)
        self.head_known = np.zeros(n, np.bool_)

    def _increment(self, rate: dm.Vec3) -> dm.Quat:
        rv = dm.vec3_scale(rate, self.dt)
        q_euler = dm.quat_from_euler(rv[0], rv[1], rv[2])
        q_rotvec = dm.quat_from_rotvec_fast(rv)
        return dm.quat_where(self.integration == Integration.EULER, q_euler, q_rotvec)

    def _correct_partial(
        self, q: dm.Quat, v: dm.Vec3, norm: Any, lp1: dm.Vec3, lp2: dm.Vec3, k: Any
    ) -> tuple[dm.Quat, dm.Vec3, dm.Vec3]:
        """att_ars_correct_partial: (q, lp1, lp2) after a correction by the fraction K_a of the angle."""
        with np.errstate(all="ignore"):
            axy = dm.sqrtf(v[0] * v[0] + v[1] * v[1])
            angle = dm.atan2f(axy, v[2])
            e = norm / self.gravity - dm.ONE
            ka = k / (dm.ONE + self.gain_c * e * e)
            pos = axy > dm.ZERO
            axis = (
                np.where(pos, v[1] / axy, dm.ONE),
                np.where(pos, -v[0] / axy, dm.ZERO),
                np.zeros(self.n, np.float32),
            )
            qc = dm.quat_from_axis_angle(axis, ka * angle)
            lp_on = self.k_lp > dm.ZERO
            lp1 = dm.vec3_where(lp_on, dm.quat_rotate(qc, lp1), lp1)
            lp2 = dm.vec3_where(lp_on, dm.quat_rotate(qc, lp2), lp2)
        return dm.quat_mul(qc, q), lp1, lp2

    def _correct_full(
        self, q: dm.Quat, v: dm.Vec3, lp1: dm.Vec3, lp2: dm.Vec3
    ) -> tuple[Any, dm.Quat, dm.Vec3, dm.Vec3]:
        """att_ars_correct_full: (ok, q, lp1, lp2) after the full alignment of v with z."""
        ok, (qw, qx, qy), n = align_up(v)
        qf = dm.quat_mul_hz(qw, qx, qy, q)
        lp_on = ok & (self.k_lp > dm.ZERO)
        zero = np.zeros(self.n, np.float32)
        lp1 = dm.vec3_where(lp_on, dm.quat_rotate_hz(qw, qx, qy, lp1), lp1)
        lp2 = dm.vec3_where(lp_on, (zero, zero, n), lp2)
        return ok, dm.quat_where(ok, qf, q), lp1, lp2

    def step(self, gyr: Any, acc: Any) -> NDArray[np.uint32]:
        """One update of every instance; gyr, acc of shape (n, 3) or (3,). Returns flags (n,)."""
        g = split3(gyr, self.n)
        a = split3(acc, self.n)
        flags = sensor.check_gyro(g, self.gyro_range)
        gyro_ok = sensor.gyro_usable(g, self.gyro_range, flags)
        accel_flags, n2 = sensor.check_accel2(a, self.accel_range2)
        accel_ok = accel_flags == _U0
        flags = flags | accel_flags
        with np.errstate(all="ignore"):
            norm = dm.sqrtf(n2)
            e = norm / self.gravity - dm.ONE
            rejected = accel_ok & (self.accel_reject > dm.ZERO) & (dm.absf(e) > self.accel_reject)
            flags = flags | np.where(rejected, _u(Flag.ACCEL_REJECTED), _U0)

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

            # not yet initialised: attitude from the first valid accel sample
            waiting = ~self.initialised
            init_now = waiting & accel_ok
            t = sensor.tilt(a)
            _, q_tilt = dm.quat_normalize_bounded(
                dm.quat_from_euler(t[0], t[1], np.zeros(self.n, np.float32))
            )
            flags = flags | np.where(
                waiting, np.where(accel_ok, _u(Flag.INITIALISED), _u(Flag.NOT_READY)), _U0
            )

            # the recovery after a clipping gyro (only once initialised)
            run = ~waiting
            self.rec_left, _, self.rec_lp_n = recovery_step(
                g, self.clip, self.rec_n, self.rec_left, run, self.rec_lp_n
            )
            rec = self.rec_left > _U0
            flags = flags | np.where(run & rec, _u(Flag.INITIALISED), _U0)
            # a clipping sample: the heading lost rotation too, the covariance's heading is unknown again
            self.head_known = self.head_known & ~(run & rec & (self.rec_left == self.rec_n))
            k_rec_lp, lp_n1, k_rec_lp2 = recovery_lp_gain2(self.rec_lp_n, self.k_lp)
            k_lp = np.where(rec, k_rec_lp, self.k_lp)
            k_lp2 = np.where(rec, k_rec_lp2, self.k_lp)
            k = np.where(rec, self.k_rec, self.k)

            q = self.q
            q1 = dm.quat_where(gyro_ok, dm.quat_mul(q, self._increment(dm.vec3_sub(g, self.bias))), q)
            correct = ~waiting & accel_ok & ~rejected
            v = dm.quat_rotate(q1, a)
            lp_on = self.k_lp > dm.ZERO
            self.rec_lp_n = np.where(correct & lp_on & rec, lp_n1, self.rec_lp_n).astype(np.uint32)
            lp1 = dm.vec3_add(self.lp1, dm.vec3_scale(dm.vec3_sub(v, self.lp1), k_lp))
            lp2 = dm.vec3_add(self.lp2, dm.vec3_scale(dm.vec3_sub(lp1, self.lp2), k_lp2))
            lp1 = dm.vec3_where(lp_on, lp1, self.lp1)
            lp2 = dm.vec3_where(lp_on, lp2, self.lp2)
            v = dm.vec3_where(lp_on, lp2, v)
            q_p, lp1_p, lp2_p = self._correct_partial(q1, v, norm, lp1, lp2, k)
            ok_f, q_f, lp1_f, lp2_f = self._correct_full(q1, v, lp1, lp2)
            full = self.full
            q2 = dm.quat_where(correct, dm.quat_where(full, q_f, q_p), q1)
            numeric = correct & full & ~ok_f
            ok, qn = dm.quat_normalize_bounded(q2)
            numeric = ~waiting & (numeric | ~ok)
            flags = flags | np.where(numeric, _u(Flag.NUMERIC), _U0)
            self.q = dm.quat_where(waiting, dm.quat_where(init_now, q_tilt, q), dm.quat_where(numeric, q, qn))
            # the low-pass states: from the first sample at initialisation, else after a correction
            lp_init = dm.quat_rotate(q_tilt, a)
            keep = ~correct | numeric
            lp1_c = dm.vec3_where(full, lp1_f, lp1_p)
            lp2_c = dm.vec3_where(full, lp2_f, lp2_p)
            self.lp1 = dm.vec3_where(init_now, lp_init, dm.vec3_where(keep, self.lp1, lp1_c))
            self.lp2 = dm.vec3_where(init_now, lp_init, dm.vec3_where(keep, self.lp2, lp2_c))
        # the start is a recovery: the stages' running mean from its sample on, the strong correction
        self.rec_left, self.rec_lp_n = recovery_start(init_now, self.rec_n, self.rec_left, self.rec_lp_n)
        self.initialised = self.initialised | init_now
        self.steps = self.steps + np.uint32(1)
        # the covariance's last accepted correction: the start, or a correction that was applied
        before = self.steps - np.uint32(1)  # the stamp holds the steps before the step (as in C)
        self.acc_step = np.where(init_now | (correct & ~numeric), before, self.acc_step).astype(np.uint32)
        self.flags = flags.astype(np.uint32)
        return self.flags

    def retune(self, settings: ArsSettings) -> None:
        """att_ars_retune: new settings, the state kept (bias_init for OFF/FROZEN, counters limited)."""
        new = Ars(settings, self.n)
        carry_state(self, new)
        bias_retune(new)
        new.rec_left = np.minimum(new.rec_left, new.rec_n).astype(np.uint32)
        self.__dict__.update(new.__dict__)

    @property
    def quat(self) -> NDArray[np.float32]:
        """Attitudes (n, 4), w,x,y,z, sensor-to-earth."""
        return stack(self.q)

    @property
    def gyro_bias(self) -> NDArray[np.float32]:
        """Gyro bias estimates (n, 3), rad/s, sensor frame."""
        return stack(self.bias)

    def run(self, gyr: Any, acc: Any) -> tuple[NDArray[np.float32], NDArray[np.uint32]]:
        """Step through N samples: gyr, acc (N, 3) for n == 1 or (N, n, 3).

        Returns quats (N, 4) or (N, n, 4) and flags (N,) or (N, n).
        """
        return run_steps(self, gyr, acc)
