"""Mirror of firmware/src/filters/kf/att_kf.c: the linear quaternion Kalman filter, instances in lockstep.

The covariance is isotropic (P = p I, see att_kf.h), so the filter carries the scalar p.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.reference import detmath as dm
from attica.reference import sensor
from attica.reference._common import (
    StateSpec,
    carry_state,
    recovery_lp_gain2,
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
from attica.reference.bias import bias_params, bias_retune, bias_step
from attica.settings import BiasMode, Flag, KfSettings

_U0 = np.uint32(0)
P_MAX = dm.c("0x1.e848p+19")
"""ATT_KF_P_MAX = 1e6: the cap on the variance."""
QUARTER = dm.c("0x1p-2")


def _u(flag: Flag) -> np.uint32:
    return np.uint32(flag.value)


class Kf:
    """Linear quaternion KF reference: ``n`` independent instances sharing one settings object.

    Settings fields may be scalars or length-``n`` sequences (one value per instance). Settings are
    not validated here (``att_kf_init`` does that in C).
    """

    STATE: StateSpec = {
        "st.q": "quat",
        "st.p": "f32",
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
        "st.initialised": "bool",
    }
    """C state fields mirrored by this class (see reference._common.load_c_state)."""
    EARTH: tuple[str, ...] = ("lp1", "lp2")
    """Earth-frame state vectors, turned with the attitude by a heading change (reference.calib.yaw_to)."""

    COEFFS: StateSpec = {
        "c.dt": "f32",
        "c.half_dt": "f32",
        "c.q_step": "f32",
        "c.r_step": "f32",
        "c.r_accel": "f32",
        "c.gate": "f32",
        "c.soft": "f32",
        "c.p0": "f32",
        "c.gravity": "f32",
        "c.accel_reject": "f32",
        "c.accel_range2": "f32",
        "c.gyro_range": "f32",
        "c.k_lp": "f32",
        "c.clip": "f32",
        "c.q_rec": "f32",
        "c.rec_n": "u32",
        "c.bias.mode": "u32:bias_mode",
        "c.bias.n_max": "u32:bias_n_max",
        "c.bias.rest_n": "u32",
        "c.bias.rest_gyro2": "f32",
        "c.bias.acc2_lo": "f32",
        "c.bias.acc2_hi": "f32",
        "c.bias.rest_first2": "f32",
        "c.q_init": "quat",
        "c.bias_init": "vec3",
        "c.init_from_accel": "bool",
        "c.lp_on": "bool",
        "c.need_norm": "bool",
    }
    """Every C coefficient of att_kf_coeffs_t (set by att_kf_init / retune), derived here alike
    from the settings; state_matches compares them after the state."""

    def __init__(self, settings: KfSettings | None = None, n: int = 1) -> None:
        s = settings if settings is not None else KfSettings()
        self.settings = s
        self.n = n
        self.dt = setting(s.dt, n)
        self.half_dt = self.dt * dm.HALF
        rates = setting(s.noise_rates, n, np.bool_)
        q_noise = setting(s.q_noise, n)
        r_noise = setting(s.r_noise, n)
        with np.errstate(all="ignore"):
            self.q_step = np.where(rates, q_noise * self.dt, q_noise).astype(np.float32)
            self.r_step = np.where(rates, r_noise / self.dt, r_noise).astype(np.float32)
        self.r_accel = setting(s.r_accel, n)
        self.gate = setting(s.gate, n)
        self.soft = self.gate * QUARTER
        self.p0 = setting(s.p0, n)
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
        self.rest_time = setting(s.rest_time, n)
        self.rest_n = sensor.samples(self.rest_time, self.dt)
        self.rest_gyro2, self.rest_first2, self.acc2_lo, self.acc2_hi = bias_params(
            self.bias_mode, self.rest_gyro, self.rest_accel, self.gravity
        )
        tau_lp = setting(s.tau_acc_lp, n)
        with np.errstate(all="ignore"):
            self.k_lp = np.where(tau_lp > dm.ZERO, self.dt / (tau_lp + self.dt), dm.ZERO).astype(np.float32)
        self.init_from_accel = setting(s.init_from_accel, n, np.bool_)
        qi = np.broadcast_to(np.asarray(s.q_init, np.float32), (n, 4))  # (4,) or one per instance (n, 4)
        self.q_init: dm.Quat = (qi[:, 0].copy(), qi[:, 1].copy(), qi[:, 2].copy(), qi[:, 3].copy())
        _, self.q_init = dm.quat_normalize(self.q_init)  # as c.q_init: normalised once, at init
        self.need_norm = (self.r_accel > dm.ZERO) | (self.accel_reject > dm.ZERO)
        self.lp_on = self.k_lp > dm.ZERO
        self._rec_coeffs(s)
        self.reset()

    def _rec_coeffs(self, s: KfSettings) -> None:
        """att_kf_rec_coeffs: the recovery after a clipping gyro (k^2 r / (1 - k): steady-state gain k)."""
        self.rec_n, self.clip, k = recovery_params(setting(s.recovery_time, self.n), self.gyro_range, self.dt)
        q = recovery_q(k, self.r_step, P_MAX)
        self.q_rec = np.where(self.rec_n > _U0, q, dm.ZERO).astype(np.float32)

    def reset(self) -> None:
        """Back to the state after construction (att_kf_reset)."""
        n = self.n
        qi = self.q_init
        self.q = (qi[0].copy(), qi[1].copy(), qi[2].copy(), qi[3].copy())
        self.p = self.p0.copy()
        zero = np.zeros(n, np.float32)
        off = self.bias_mode == BiasMode.OFF
        self.bias: dm.Vec3 = dm.vec3_where(off, (zero, zero, zero), self.bias_init)
        self.lp1: dm.Vec3 = (zero.copy(), zero.copy(), self.gravity.copy())
        self.lp2: dm.Vec3 = (zero.copy(), zero.copy(), self.gravity.copy())
        self.bias_n = np.zeros(n, np.uint32)
        self.rest_count = np.zeros(n, np.uint32)
        self.rest_gate2 = self.rest_first2.copy()
        self.initialised = ~self.init_from_accel
        self.steps = np.zeros(n, np.uint32)
        self.flags = np.zeros(n, np.uint32)
        self.rec_left = np.zeros(n, np.uint32)
        self.rec_lp_n = np.zeros(n, np.uint32)

    def step(self, gyr: Any, acc: Any) -> NDArray[np.uint32]:
        """One update of every instance; gyr, acc of shape (n, 3) or (3,). Returns flags (n,)."""
        g = split3(gyr, self.n)
        a = split3(acc, self.n)
        flags = sensor.check_gyro(g, self.gyro_range)
        gyro_ok = sensor.gyro_usable(g, self.gyro_range, flags)
        accel_flags, n2 = sensor.check_accel2(a, self.accel_range2)
        accel_ok = accel_flags == _U0
        flags = flags | accel_flags
        zero = np.zeros(self.n, np.float32)
        with np.errstate(all="ignore"):
            e = dm.sqrtf(n2) / self.gravity - dm.ONE
            use_e = accel_ok & self.need_norm
            e2 = np.where(use_e, e * e, dm.ZERO)
            rejected = use_e & (self.accel_reject > dm.ZERO) & (dm.absf(e) > self.accel_reject)
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
            _, q_tilt = dm.quat_normalize_bounded(dm.quat_from_euler(t[0], t[1], zero))
            flags = flags | np.where(
                waiting, np.where(accel_ok, _u(Flag.INITIALISED), _u(Flag.NOT_READY)), _U0
            )

            # the recovery after a clipping gyro (step 5), where initialised
            self.rec_left, _, self.rec_lp_n = recovery_step(
                g, self.clip, self.rec_n, self.rec_left, ~waiting, self.rec_lp_n
            )
            rec = ~waiting & (self.rec_left > _U0)
            flags = flags | np.where(rec, _u(Flag.INITIALISED), _U0)

            # prediction
            x0 = self.q
            h = dm.vec3_scale(dm.vec3_sub(g, self.bias), self.half_dt)
            dx = dm.quat_mul(x0, (zero, h[0], h[1], h[2]))
            x_pred = (x0[0] + dx[0], x0[1] + dx[1], x0[2] + dx[2], x0[3] + dx[3])
            x = dm.quat_where(gyro_ok, x_pred, x0)
            p = np.where(
                gyro_ok, self.p * (dm.ONE + dm.vec3_dot(h, h)) + self.q_step, self.p + self.q_step
            ).astype(np.float32)
            p = np.where(rec, p + self.q_rec, p).astype(np.float32)

            # measurement and update
            u = dm.quat_rotate(x, a)
            lp_on = self.k_lp > dm.ZERO
            k_rec_lp, lp_n1, k_rec_lp2 = recovery_lp_gain2(self.rec_lp_n, self.k_lp)
            k_lp = np.where(rec, k_rec_lp, self.k_lp)
            k_lp2 = np.where(rec, k_rec_lp2, self.k_lp)
            lp_counted = ~waiting & accel_ok & ~rejected & lp_on & rec
            self.rec_lp_n = np.where(lp_counted, lp_n1, self.rec_lp_n).astype(np.uint32)
            lp1 = dm.vec3_add(self.lp1, dm.vec3_scale(dm.vec3_sub(u, self.lp1), k_lp))
            lp2 = dm.vec3_add(self.lp2, dm.vec3_scale(dm.vec3_sub(lp1, self.lp2), k_lp2))
            u = dm.vec3_where(lp_on, lp2, u)
            ok_a, (cw, cx, cy), _ = align_up(u)
            x2 = x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + x[3] * x[3]
            y2 = (dm.TWO * (dm.ONE - cw)) * x2
            r = self.r_step * (dm.ONE + self.r_accel * e2)
            s = p + r
            gate_on = (self.gate > dm.ZERO) & ~rec  # off during a recovery
            measure = ~waiting & accel_ok & ~rejected & ok_a
            gated = measure & gate_on & (y2 > self.gate * s)
            flags = flags | np.where(gated, _u(Flag.ACCEL_REJECTED), _U0)
            soft = gate_on & (y2 > self.soft * s)
            r = np.where(soft, y2 / self.soft - p, r)
            s = np.where(soft, p + r, s)
            k = p / s
            kw = (dm.ONE - k) + k * cw
            kx = k * cx
            ky = k * cy
            apply = measure & ~gated
            x = dm.quat_where(apply, dm.quat_mul_hz(kw, kx, ky, x), x)
            p = np.where(apply, r * k, p).astype(np.float32)
            ok_k, qk = dm.quat_normalize_bounded((kw, kx, ky, zero))
            lp_upd = apply & lp_on & ok_k
            lp1n = dm.quat_rotate_hz(qk[0], qk[1], qk[2], lp1)
            lp2n = dm.quat_rotate_hz(qk[0], qk[1], qk[2], lp2)

            # normalisation
            ok_n, xn = dm.quat_normalize_bounded(x)
            pn = p / (x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + x[3] * x[3])
            capped = pn > P_MAX
            pn = np.where(capped, P_MAX, pn)
            run = ~waiting
            flags = flags | np.where(run & ok_n & capped, _u(Flag.CLAMPED), _U0)
            flags = flags | np.where(run & ~ok_n, _u(Flag.NUMERIC), _U0)
            take = run & ok_n
            self.q = dm.quat_where(init_now, q_tilt, dm.quat_where(take, xn, self.q))
            self.p = np.where(take, pn, self.p).astype(np.float32)
            lp_init = dm.quat_rotate(q_tilt, a)
            self.lp1 = dm.vec3_where(init_now, lp_init, dm.vec3_where(lp_upd, lp1n, self.lp1))
            self.lp2 = dm.vec3_where(init_now, lp_init, dm.vec3_where(lp_upd, lp2n, self.lp2))
        # the start is a recovery: the stages' running mean from its sample on, the recovery noise
        self.rec_left, self.rec_lp_n = recovery_start(init_now, self.rec_n, self.rec_left, self.rec_lp_n)
        self.initialised = self.initialised | init_now
        self.steps = self.steps + np.uint32(1)
        self.flags = flags.astype(np.uint32)
        return self.flags

    def retune(self, settings: KfSettings) -> None:
        """att_kf_retune: new settings, the state kept (bias_init for OFF/FROZEN, counters limited)."""
        new = Kf(settings, self.n)
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

    @property
    def variance(self) -> NDArray[np.float32]:
        """The variance p of each instance (P = p I), (unit quaternion)^2."""
        return np.asarray(self.p, np.float32)

    def output_cov(self) -> tuple[Any, Any, Any, Any]:
        """The output record's ``cov`` (att_filter_output): p four times (P = p I)."""
        return (self.p, self.p, self.p, self.p)

    def run(self, gyr: Any, acc: Any) -> tuple[NDArray[np.float32], NDArray[np.uint32]]:
        """Step through N samples: gyr, acc (N, 3) for n == 1 or (N, n, 3).

        Returns quats (N, 4) or (N, n, 4) and flags (N,) or (N, n).
        """
        return run_steps(self, gyr, acc)
