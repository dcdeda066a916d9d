"""Mirror of firmware/src/att_mars.c: the 9-axis complementary filter, many instances in lockstep."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.reference import detmath as dm
from attica.reference import sensor
from attica.reference._common import StateSpec, run_steps, setting, split3, stack
from attica.reference.bias import bias_step
from attica.settings import BiasMode, Flag, Integration, MagMode, MarsSettings

_U0 = np.uint32(0)

_M0Parts = tuple[Any, Any, Any, dm.Vec3, dm.Vec3, Any]
"""(m0, |m0|, dip, m0_ref, m0_perp, m0_ref_ok) as computed by att_mars_set_m0."""


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


def _rotate_toward(q: dm.Quat, v: dm.Vec3, r: dm.Vec3, fallback: dm.Vec3, gain: Any) -> dm.Quat:
    """att_mars_rotate_toward."""
    with np.errstate(all="ignore"):
        return dm.quat_mul(_rotation_toward(v, r, fallback, gain), q)


class Mars:
    """9-axis complementary filter reference: ``n`` independent instances sharing one settings object.

    Settings fields may be scalars or length-``n`` sequences (one value per instance); vector fields
    may be given as (3,)/(4,) or (n, 3)/(n, 4).
    """

    STATE: StateSpec = {
        "q": "quat",
        "m0": "vec3",
        "m0_norm": "f32",
        "m0_dip": "f32",
        "m0_ref": "vec3",
        "m0_perp": "vec3",
        "m0_ref_ok": "bool",
        "m0_valid": "bool",
        "initialised": "bool",
        "bias": "vec3",
        "bias_n": "u32",
        "rest_count": "u32",
        "lp1": "vec3",
        "lp2": "vec3",
        "steps": "u32",
        "flags": "u32",
    }
    """C state fields mirrored by this class (see reference._common.load_c_state)."""

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
        self.gyro_range = setting(s.gyro_range, n)
        self.mag_range = setting(s.mag_range, n)
        self.mag_norm_reject = setting(s.mag_norm_reject, n)
        self.mag_dip_reject = setting(s.mag_dip_reject, n)
        self.bias_init = split3(s.bias_init, n)
        self.init_from_sensors = setting(s.init_from_sensors, n, np.bool_)
        self.q_init = _split4(s.q_init, n)
        self.m0_init = split3(s.m0_init, n)
        with np.errstate(all="ignore"):
            k_acc = np.where(tau_acc > dm.ZERO, self.dt / (tau_acc + self.dt), alpha_acc)
            k_mag = np.where(tau_mag > dm.ZERO, self.dt / (tau_mag + self.dt), alpha_mag)
        self.k_acc = k_acc.astype(np.float32)
        self.k_mag = k_mag.astype(np.float32)
        self.integration = setting(np.asarray(s.integration, np.int32), n, np.int32)
        tau_lp = setting(s.tau_acc_lp, n)
        with np.errstate(all="ignore"):
            self.k_lp = np.where(tau_lp > dm.ZERO, self.dt / (tau_lp + self.dt), dm.ZERO).astype(np.float32)
        self.bias_mode = setting(np.asarray(s.bias_mode, np.int32), n, np.int32)
        self.bias_n_max = setting(s.bias_n_max, n, np.uint32)
        self.rest_gyro = setting(s.rest_gyro, n)
        self.rest_accel = setting(s.rest_accel, n)
        self.rest_time = setting(s.rest_time, n)
        self.rest_n = sensor.samples(self.rest_time, self.dt)
        self._zeros = np.zeros(n, np.float32)
        self._ones = np.full(n, dm.ONE, np.float32)
        self._up = (self._zeros, self._zeros, self._ones)
        self._xaxis = (self._ones, self._zeros, self._zeros)
        self.reset()

    def reset(self) -> None:
        """Back to the state after construction (att_mars_reset)."""
        n = self.n
        _, self.q = dm.quat_normalize(self.q_init)
        z = self._zeros
        self.m0: dm.Vec3 = (z.copy(), z.copy(), z.copy())
        self.m0_norm: Any = z.copy()
        self.m0_dip: Any = z.copy()
        self.m0_ref: dm.Vec3 = (z.copy(), z.copy(), z.copy())
        self.m0_perp: dm.Vec3 = (z.copy(), z.copy(), z.copy())
        self.m0_ref_ok: Any = np.zeros(n, np.bool_)
        self.m0_valid: Any = np.zeros(n, np.bool_)
        mi = self.m0_init
        nonzero = ~((mi[0] == dm.ZERO) & (mi[1] == dm.ZERO) & (mi[2] == dm.ZERO))
        ok, parts = self._derive_m0(mi)
        self._commit_m0(~self.init_from_sensors & nonzero & ok, parts)
        self.initialised: Any = ~self.init_from_sensors
        off = self.bias_mode == BiasMode.OFF
        self.bias: dm.Vec3 = dm.vec3_where(off, (z.copy(), z.copy(), z.copy()), self.bias_init)
        self.bias_n = np.zeros(n, np.uint32)
        self.rest_count = np.zeros(n, np.uint32)
        self.lp1: dm.Vec3 = (z.copy(), z.copy(), self.gravity.copy())
        self.lp2: dm.Vec3 = (z.copy(), z.copy(), self.gravity.copy())
        self.steps = np.zeros(n, np.uint32)
        self.flags = np.zeros(n, np.uint32)

    def _derive_m0(self, m0: dm.Vec3) -> tuple[Any, _M0Parts]:
        """The quantities att_mars_set_m0 stores, and whether it succeeds."""
        with np.errstate(all="ignore"):
            ok, unit = dm.vec3_normalize(m0)
            norm = dm.vec3_norm(m0)
            dip = _dip(m0)
            ok_p, perp_full = dm.vec3_normalize(dm.vec3_cross(unit, self._up))
            perp_full = dm.vec3_where(ok_p, perp_full, self._xaxis)
            ok_h, ref_h = dm.vec3_normalize((m0[0], m0[1], self._zeros))
            full = self.mag_mode == MagMode.FULL
            ref = dm.vec3_where(full, unit, ref_h)
            perp = dm.vec3_where(full, perp_full, self._up)
            ref_ok = full | ok_h
        return ok, (m0, norm, dip, ref, perp, ref_ok)

    def _commit_m0(self, cond: Any, parts: _M0Parts) -> None:
        m0, norm, dip, ref, perp, ref_ok = parts
        self.m0 = dm.vec3_where(cond, m0, self.m0)
        self.m0_norm = np.where(cond, norm, self.m0_norm)
        self.m0_dip = np.where(cond, dip, self.m0_dip)
        self.m0_ref = dm.vec3_where(cond, ref, self.m0_ref)
        self.m0_perp = dm.vec3_where(cond, perp, self.m0_perp)
        self.m0_ref_ok = np.where(cond, ref_ok, self.m0_ref_ok)
        self.m0_valid = self.m0_valid | cond

    def _align(self, q: dm.Quat, mag: dm.Vec3) -> tuple[Any, dm.Quat, dm.Vec3]:
        """att_mars_align: (ok, yaw-aligned q, m0)."""
        with np.errstate(all="ignore"):
            me = dm.quat_rotate(q, mag)
            ok1, _ = dm.vec3_normalize(me)
            qa = dm.quat_mul(dm.quat_from_axis_angle(self._up, dm.atan2f(me[0], me[1])), q)
            ok2, qa = dm.quat_normalize(qa)
            me = dm.quat_rotate(qa, mag)
            m0 = (self._zeros, dm.sqrtf(me[0] * me[0] + me[1] * me[1]), me[2])
        return ok1 & ok2, qa, m0

    def _mag_correct(self, q: dm.Quat, mag: dm.Vec3, mnorm: Any) -> tuple[Any, dm.Quat]:
        """att_mars_mag_correct: (rejected, corrected q)."""
        with np.errstate(all="ignore"):
            me = dm.quat_rotate(q, mag)
            e = mnorm / self.m0_norm - dm.ONE
            ddip = _dip(me) - self.m0_dip
            reject = (
                ~self.m0_ref_ok
                | ((self.mag_norm_reject > dm.ZERO) & (dm.absf(e) > self.mag_norm_reject))
                | ((self.mag_dip_reject > dm.ZERO) & (dm.absf(ddip) > self.mag_dip_reject))
            )
            vz = np.where(self.mag_mode == MagMode.HORIZONTAL, dm.ZERO, me[2])
            ok, unit = dm.vec3_normalize((me[0], me[1], vz))
            reject = reject | ~ok
            qc = _rotate_toward(q, unit, self.m0_ref, self.m0_perp, self.k_mag)
        return reject, dm.quat_where(reject, q, qc)

    def step(self, gyr: Any, acc: Any, mag: Any) -> NDArray[np.uint32]:
        """One update of every instance; gyr, acc, mag of shape (n, 3) or (3,). Returns flags (n,)."""
        g = split3(gyr, self.n)
        a = split3(acc, self.n)
        m = split3(mag, self.n)
        flags = sensor.check_gyro(g, self.gyro_range)
        gyro_ok = flags == _U0
        accel_flags, norm = sensor.check_accel(a, self.accel_range)
        accel_ok = accel_flags == _U0
        flags = flags | accel_flags
        with np.errstate(all="ignore"):
            e = norm / self.gravity - dm.ONE
            rejected = accel_ok & (self.accel_reject > dm.ZERO) & (dm.absf(e) > self.accel_reject)
            flags = flags | np.where(rejected, _u(Flag.ACCEL_REJECTED), _U0)
            mag_flags, mnorm = sensor.check_mag(m, self.mag_range)
            mag_ok = mag_flags == _U0
            flags = flags | mag_flags

            # rest detection and gyro bias (att_bias.c)
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

            # not yet initialised: attitude from the first valid accel (+ mag) sample
            waiting = ~self.initialised
            init_now = waiting & accel_ok
            t = sensor.tilt(a)
            _, q_tilt = dm.quat_normalize(dm.quat_from_euler(t[0], t[1], self._zeros))
            ok_a0, q_a0, m0_a0 = self._align(q_tilt, m)
            ok_d0, parts0 = self._derive_m0(m0_a0)
            good0 = ok_a0 & ok_d0
            init_mag = init_now & mag_ok & good0
            q_start = dm.quat_where(init_mag, q_a0, q_tilt)
            flags = flags | np.where(
                waiting, np.where(accel_ok, _u(Flag.INITIALISED), _u(Flag.NOT_READY)), _U0
            )
            flags = flags | np.where(init_now & mag_ok & ~good0, _u(Flag.MAG_REJECTED), _U0)

            # running
            run = ~waiting
            q = self.q
            w = dm.vec3_sub(g, self.bias)
            q_rv = dm.quat_mul(q, dm.quat_from_rotvec(dm.vec3_scale(w, self.dt)))
            q_fo = _integrate(q, w, self.dt)
            rotvec = self.integration == Integration.ROTVEC
            ok_i, q_int = dm.quat_normalize(dm.quat_where(rotvec, q_rv, q_fo))
            q1 = dm.quat_where(gyro_ok & ok_i, q_int, q)
            numeric = gyro_ok & ~ok_i
            lp_on = self.k_lp > dm.ZERO
            ae = dm.quat_rotate(q1, a)
            lp1n = dm.vec3_add(self.lp1, dm.vec3_scale(dm.vec3_sub(ae, self.lp1), self.k_lp))
            lp2n = dm.vec3_add(self.lp2, dm.vec3_scale(dm.vec3_sub(lp1n, self.lp2), self.k_lp))
            ok_u, unit = dm.vec3_normalize(dm.vec3_where(lp_on, lp2n, ae))
            qc = _rotation_toward(unit, self._up, self._xaxis, self.k_acc)
            q_acc = dm.quat_mul(qc, q1)
            use_acc = run & accel_ok & ~rejected
            q2 = dm.quat_where(use_acc & ok_u, q_acc, q1)
            lp_upd = use_acc & lp_on
            lp1n = dm.vec3_where(ok_u, dm.quat_rotate(qc, lp1n), lp1n)
            lp2n = dm.vec3_where(ok_u, dm.quat_rotate(qc, lp2n), lp2n)

            rej_c, q_corr = self._mag_correct(q2, m, mnorm)
            ok_al, q_al, m0_al = self._align(q2, m)
            ok_dl, parts_l = self._derive_m0(m0_al)
            good_l = ok_al & ok_dl
            ok_ds, parts_s = self._derive_m0(dm.quat_rotate(q2, m))
            use_corr = run & mag_ok & self.m0_valid
            use_align = run & mag_ok & ~self.m0_valid & self.init_from_sensors
            use_set = run & mag_ok & ~self.m0_valid & ~self.init_from_sensors
            q3 = dm.quat_where(use_corr, q_corr, dm.quat_where(use_align & good_l, q_al, q2))
            bad_mag = (use_corr & rej_c) | (use_align & ~good_l) | (use_set & ~ok_ds)
            flags = flags | np.where(bad_mag, _u(Flag.MAG_REJECTED), _U0)
            flags = flags | np.where(use_align & good_l, _u(Flag.INITIALISED), _U0)
            ok_f, q_fin = dm.quat_normalize(q3)
            flags = flags | np.where(run & (numeric | ~ok_f), _u(Flag.NUMERIC), _U0)
            q_run = dm.quat_where(ok_f, q_fin, q)
            self.q = dm.quat_where(waiting, dm.quat_where(init_now, q_start, q), q_run)
            lp_init = dm.quat_rotate(q_start, a)
            self.lp1 = dm.vec3_where(init_now, lp_init, dm.vec3_where(lp_upd, lp1n, self.lp1))
            self.lp2 = dm.vec3_where(init_now, lp_init, dm.vec3_where(lp_upd, lp2n, self.lp2))
        self._commit_m0(init_mag, parts0)
        self._commit_m0(use_align & good_l, parts_l)
        self._commit_m0(use_set & ok_ds, parts_s)
        self.initialised = self.initialised | init_now
        self.steps = self.steps + np.uint32(1)
        self.flags = flags.astype(np.uint32)
        return self.flags

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
