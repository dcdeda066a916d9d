"""Mirror of firmware/src/att_ars.c: the quaternion complementary ARS, many instances in lockstep."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.reference import detmath as dm
from attica.reference import sensor
from attica.reference._common import StateSpec, run_steps, setting, split3, stack
from attica.reference.bias import bias_step
from attica.settings import ArsSettings, BiasMode, Flag, Integration

_U0 = np.uint32(0)


def _u(flag: Flag) -> np.uint32:
    return np.uint32(flag.value)


class Ars:
    """Complementary ARS reference: ``n`` independent instances sharing one settings object.

    Settings fields may be scalars or length-``n`` sequences (one value per instance).
    """

    STATE: StateSpec = {
        "q": "quat",
        "bias": "vec3",
        "bias_n": "u32",
        "rest_count": "u32",
        "initialised": "bool",
        "lp1": "vec3",
        "lp2": "vec3",
        "steps": "u32",
        "flags": "u32",
    }
    """C state fields mirrored by this class (see reference._common.load_c_state)."""

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
        self.gyro_range = setting(s.gyro_range, n)
        self.bias_mode = setting(int(s.bias_mode), n, np.int32)
        self.bias_n_max = setting(s.bias_n_max, n, np.uint32)
        self.bias_init = split3(s.bias_init, n)
        self.rest_gyro = setting(s.rest_gyro, n)
        self.rest_accel = setting(s.rest_accel, n)
        self.rest_time = setting(s.rest_time, n)
        self.integration = setting(int(s.integration), n, np.int32)
        self.init_from_accel = setting(s.init_from_accel, n, np.bool_)
        self.q_init: dm.Quat = (
            setting(s.q_init[0], n),
            setting(s.q_init[1], n),
            setting(s.q_init[2], n),
            setting(s.q_init[3], n),
        )
        with np.errstate(all="ignore"):
            self.k = np.where(tau > dm.ZERO, self.dt / (tau + self.dt), gain).astype(np.float32)
        self.rest_n = sensor.samples(self.rest_time, self.dt)
        tau_lp = setting(s.tau_acc_lp, n)
        with np.errstate(all="ignore"):
            self.k_lp = np.where(tau_lp > dm.ZERO, self.dt / (tau_lp + self.dt), dm.ZERO).astype(np.float32)
        self.reset()

    def reset(self) -> None:
        """Back to the state after construction (att_ars_reset)."""
        n = self.n
        _, self.q = dm.quat_normalize(self.q_init)
        off = self.bias_mode == BiasMode.OFF
        self.bias = dm.vec3_where(off, dm.vec3(np.zeros(n), np.zeros(n), np.zeros(n)), self.bias_init)
        self.bias_n = np.zeros(n, np.uint32)
        self.rest_count = np.zeros(n, np.uint32)
        self.initialised = ~self.init_from_accel
        zero = np.zeros(n, np.float32)
        self.lp1: dm.Vec3 = (zero.copy(), zero.copy(), self.gravity.copy())
        self.lp2: dm.Vec3 = (zero.copy(), zero.copy(), self.gravity.copy())
        self.steps = np.zeros(n, np.uint32)
        self.flags = np.zeros(n, np.uint32)

    def _increment(self, rate: dm.Vec3) -> dm.Quat:
        rv = dm.vec3_scale(rate, self.dt)
        q_euler = dm.quat_from_euler(rv[0], rv[1], rv[2])
        q_rotvec = dm.quat_from_rotvec(rv)
        return dm.quat_where(self.integration == Integration.EULER, q_euler, q_rotvec)

    def _correct(self, q: dm.Quat, acc: dm.Vec3, norm: Any) -> tuple[dm.Quat, dm.Vec3, dm.Vec3]:
        """att_ars_correct: (corrected q, new lp1, new lp2); the low-pass parts apply where k_lp > 0."""
        lp_on = self.k_lp > dm.ZERO
        with np.errstate(all="ignore"):
            ae = dm.quat_rotate(q, acc)
            lp1 = dm.vec3_add(self.lp1, dm.vec3_scale(dm.vec3_sub(ae, self.lp1), self.k_lp))
            lp2 = dm.vec3_add(self.lp2, dm.vec3_scale(dm.vec3_sub(lp1, self.lp2), self.k_lp))
            v = dm.vec3_where(lp_on, lp2, ae)
            axy = dm.sqrtf(v[0] * v[0] + v[1] * v[1])
            angle = dm.atan2f(axy, v[2])
            e = norm / self.gravity - dm.ONE
            ka = self.k / (dm.ONE + self.gain_c * e * e)
            pos = axy > dm.ZERO
            axis = (
                np.where(pos, v[1] / axy, dm.ONE),
                np.where(pos, -v[0] / axy, dm.ZERO),
                np.zeros(self.n, np.float32),
            )
            qc = dm.quat_from_axis_angle(axis, ka * angle)
            lp1 = dm.vec3_where(lp_on, dm.quat_rotate(qc, lp1), self.lp1)
            lp2 = dm.vec3_where(lp_on, dm.quat_rotate(qc, lp2), self.lp2)
        return dm.quat_mul(qc, q), lp1, lp2

    def step(self, gyr: Any, acc: Any) -> NDArray[np.uint32]:
        """One update of every instance; gyr, acc of shape (n, 3) or (3,). Returns flags (n,)."""
        g = split3(gyr, self.n)
        a = split3(acc, self.n)
        flags = sensor.check_gyro(g, self.gyro_range)
        gyro_ok = flags == _U0
        accel_flags, norm = sensor.check_accel(a, self.accel_range)
        accel_ok = accel_flags == _U0
        flags = flags | accel_flags
        with np.errstate(all="ignore"):
            e = norm / self.gravity - dm.ONE
            rejected = accel_ok & (self.accel_reject > dm.ZERO) & (dm.absf(e) > self.accel_reject)
            flags = flags | np.where(rejected, _u(Flag.ACCEL_REJECTED), _U0)

            self.bias, self.bias_n, self.rest_count, bias_flags = bias_step(
                self.bias_mode,
                self.bias_n_max,
                self.rest_n,
                self.rest_gyro,
                self.rest_accel,
                self.gravity,
                self.bias,
                self.bias_n,
                self.rest_count,
                g,
                gyro_ok,
                accel_ok,
                norm,
            )
            flags = flags | bias_flags

            # not yet initialised: attitude from the first valid accel sample
            waiting = ~self.initialised
            init_now = waiting & accel_ok
            t = sensor.tilt(a)
            _, q_tilt = dm.quat_normalize(dm.quat_from_euler(t[0], t[1], np.zeros(self.n, np.float32)))
            flags = flags | np.where(
                waiting, np.where(accel_ok, _u(Flag.INITIALISED), _u(Flag.NOT_READY)), _U0
            )

            q = self.q
            q1 = dm.quat_where(gyro_ok, dm.quat_mul(q, self._increment(dm.vec3_sub(g, self.bias))), q)
            correct = accel_ok & ~rejected
            q_corr, lp1c, lp2c = self._correct(q1, a, norm)
            q2 = dm.quat_where(correct, q_corr, q1)
            ok, qn = dm.quat_normalize(q2)
            flags = flags | np.where(~waiting & ~ok, _u(Flag.NUMERIC), _U0)
            q_run = dm.quat_where(ok, qn, q)
            self.q = dm.quat_where(waiting, dm.quat_where(init_now, q_tilt, q), q_run)
            # the low-pass states: from the first sample at initialisation, else after a correction
            lp_init = dm.quat_rotate(q_tilt, a)
            upd = ~waiting & correct
            self.lp1 = dm.vec3_where(init_now, lp_init, dm.vec3_where(upd, lp1c, self.lp1))
            self.lp2 = dm.vec3_where(init_now, lp_init, dm.vec3_where(upd, lp2c, self.lp2))
        self.initialised = self.initialised | init_now
        self.steps = self.steps + np.uint32(1)
        self.flags = flags.astype(np.uint32)
        return self.flags

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
