"""Mirror of firmware/src/att_ekf.c: the Euler-angle extended Kalman filter, many instances in lockstep."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.reference import detmath as dm
from attica.reference import sensor
from attica.reference._common import StateSpec, carry_state, run_steps, setting, split3, stack
from attica.settings import EkfSettings, Flag

_U0 = np.uint32(0)
_PI = dm.c("0x1.921fb6p+1")
_PIO2 = dm.c("0x1.921fb6p+0")
_PIVOT_MIN = dm.c("0x1p-12")
_SHRINK = dm.c("0x1.ff8p-1")

Mat = list[list[Any]]
"""A 3x3 matrix as rows of float32 (n,) arrays."""


def _u(flag: Flag) -> np.uint32:
    return np.uint32(flag.value)


def _mul(a: Mat, b: Mat) -> Mat:
    """att_ekf_mul: a b, each element ((a_i0 b_0j + a_i1 b_1j) + a_i2 b_2j)."""
    return [[a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j] for j in range(3)] for i in range(3)]


def _mul_t_sym(t: Mat, m: Mat) -> Mat:
    """att_ekf_mul_t_sym: upper triangle of t m^T, mirrored to the lower triangle."""
    out: Mat = [[None, None, None] for _ in range(3)]
    for i in range(3):
        for j in range(i, 3):
            out[i][j] = t[i][0] * m[j][0] + t[i][1] * m[j][1] + t[i][2] * m[j][2]
            out[j][i] = out[i][j]
    return out


def _mat_where(cond: Any, a: Mat, b: Mat) -> Mat:
    return [[np.where(cond, a[i][j], b[i][j]) for j in range(3)] for i in range(3)]


def _mat_finite(p: Mat) -> Any:
    ok = dm.isfinitef(p[0][0])
    for i in range(3):
        for j in range(3):
            ok = ok & dm.isfinitef(p[i][j])
    return ok


def _canon(e: dm.Vec3, p: Mat) -> tuple[dm.Vec3, Mat]:
    """att_ekf_canon: theta wrapped and brought into [-pi/2, pi/2], phi and psi wrapped; P follows."""
    ey = dm.wrap_pi(e[1])
    over = ey > _PIO2
    under = ey < -_PIO2
    flip = over | under
    ey = np.where(over, _PI - ey, np.where(under, -_PI - ey, ey))
    ex = np.where(flip, e[0] + _PI, e[0])
    ez = np.where(flip, e[2] + _PI, e[2])
    out = [list(row) for row in p]
    for i, j in ((0, 1), (1, 0), (1, 2), (2, 1)):
        out[i][j] = np.where(flip, -p[i][j], p[i][j])
    return (dm.wrap_pi(ex), ey, dm.wrap_pi(ez)), out


def _cap(p: Mat, p_max: Any) -> tuple[Mat, Any]:
    """att_ekf_cap: (P, capped); the congruence D P D (d = 1 leaves the bits unchanged)."""
    over = [p[i][i] > p_max for i in range(3)]
    d = [np.where(over[i], dm.sqrtf(p_max / p[i][i]), dm.ONE) for i in range(3)]
    out: Mat = [[None, None, None] for _ in range(3)]
    for i in range(3):
        for j in range(i, 3):
            out[i][j] = p[i][j] * d[i] * d[j]
            out[j][i] = out[i][j]
    return out, over[0] | over[1] | over[2]


def _pd_ok(p: Mat) -> Any:
    """att_ekf_pd_ok: L D L^T pivots positive with a relative margin."""
    d0 = p[0][0]
    l10 = p[1][0] / d0
    d1 = p[1][1] - l10 * p[1][0]
    l20 = p[2][0] / d0
    e21 = p[2][1] - l20 * p[1][0]
    l21 = e21 / d1
    d2 = p[2][2] - l20 * p[2][0] - l21 * e21
    return (d0 > dm.ZERO) & (d1 > _PIVOT_MIN * p[1][1]) & (d2 > _PIVOT_MIN * p[2][2])


def _shrink(p: Mat, s: Any) -> Mat:
    """att_ekf_shrink: off-diagonal elements times s."""
    p01 = p[0][1] * s
    p02 = p[0][2] * s
    p12 = p[1][2] * s
    return [[p[0][0], p01, p02], [p01, p[1][1], p12], [p02, p12, p[2][2]]]


def _condition(p: Mat, p_max: Any) -> tuple[Mat, Any]:
    """att_ekf_condition: (P, flags); NUMERIC means the caller discards the stage."""
    numeric = ~_mat_finite(p) | ~(p[0][0] > dm.ZERO) | ~(p[1][1] > dm.ZERO) | ~(p[2][2] > dm.ZERO)
    pc, capped = _cap(p, p_max)
    ok1 = _pd_ok(pc)
    p1 = _shrink(pc, _SHRINK)
    ok2 = _pd_ok(p1)
    p2 = _shrink(p1, dm.ZERO)
    out = _mat_where(ok1, pc, _mat_where(ok2, p1, p2))
    clamped = capped | ~ok1
    flags = np.where(numeric, _u(Flag.NUMERIC), np.where(clamped, _u(Flag.CLAMPED), _U0))
    return out, flags


class Ekf:
    """Euler EKF reference: ``n`` independent instances sharing one settings object.

    Settings fields may be scalars or length-``n`` sequences (one value per instance).
    """

    STATE: StateSpec = {
        "euler": "vec3",
        "q": "quat",
        "p": "f32x9",
        "initialised": "bool",
        "steps": "u32",
        "flags": "u32",
    }
    """C state fields mirrored by this class (see reference._common.load_c_state)."""

    def __init__(self, settings: EkfSettings | None = None, n: int = 1) -> None:
        s = settings if settings is not None else EkfSettings()
        self.settings = s
        self.n = n
        self.dt = setting(s.dt, n)
        # att_ekf_init: per-step variances (q_step, r_step); with noise_rates the settings are rates
        rates = setting(s.noise_rates, n, np.bool_)
        with np.errstate(all="ignore"):
            q_phi = setting(s.q_phi, n)
            q_theta = setting(s.q_theta, n)
            q_psi = setting(s.q_psi, n)
            r_phi = setting(s.r_phi, n)
            r_theta = setting(s.r_theta, n)
            self.q_phi = np.where(rates, q_phi * self.dt, q_phi).astype(np.float32)
            self.q_theta = np.where(rates, q_theta * self.dt, q_theta).astype(np.float32)
            self.q_psi = np.where(rates, q_psi * self.dt, q_psi).astype(np.float32)
            self.r_phi = np.where(rates, r_phi / self.dt, r_phi).astype(np.float32)
            self.r_theta = np.where(rates, r_theta / self.dt, r_theta).astype(np.float32)
        self.p0 = setting(s.p0, n)
        self.p_max = setting(s.p_max, n)
        self.gravity = setting(s.gravity, n)
        self.accel_reject = setting(s.accel_reject, n)
        self.accel_range = setting(s.accel_range, n)
        self.gyro_range = setting(s.gyro_range, n)
        self.cos_min = setting(s.cos_min, n)
        self.init_from_accel = setting(s.init_from_accel, n, np.bool_)
        self.euler_init = split3(s.euler_init, n)
        self.reset()

    def reset(self) -> None:
        """Back to the state after construction (att_ekf_reset)."""
        n = self.n
        e0 = self.euler_init
        self.euler: dm.Vec3 = (dm.wrap_pi(e0[0]), e0[1].copy(), dm.wrap_pi(e0[2]))
        self.q = dm.quat_from_euler(*self.euler)
        zero = np.zeros(n, np.float32)
        self.p: Mat = [[self.p0.copy() if i == j else zero.copy() for j in range(3)] for i in range(3)]
        self.initialised = ~self.init_from_accel
        self.steps = np.zeros(n, np.uint32)
        self.flags = np.zeros(n, np.uint32)

    def _predict(self, w: dm.Vec3, gyro_ok: Any) -> tuple[dm.Vec3, Mat, Any]:
        """att_ekf_predict: (euler, P, flags) after the prediction (state kept on NUMERIC)."""
        dt = self.dt
        phi, theta, psi = self.euler
        p, q, r = w
        sphi = dm.sinf(phi)
        cphi = dm.cosf(phi)
        sth = dm.sinf(theta)
        cth = dm.cosf(theta)
        gimbal = dm.absf(cth) < self.cos_min
        cth = np.where(gimbal, np.where(cth < dm.ZERO, -self.cos_min, self.cos_min), cth)
        flags = np.where(gimbal & gyro_ok, _u(Flag.GIMBAL), _U0)
        tth = sth / cth
        sec = dm.ONE / cth
        ex = phi + (p + sphi * tth * q + cphi * tth * r) * dt
        ey = theta + (cphi * q - sphi * r) * dt
        ez = psi + (sphi / cth * q + cphi / cth * r) * dt
        u = sphi * q + cphi * r
        v = cphi * q - sphi * r
        zero = np.zeros(self.n, np.float32)
        one = np.full(self.n, dm.ONE, np.float32)
        a: Mat = [
            [dm.ONE + dt * (v * tth), dt * (u * sec * sec), zero],
            [-(dt * u), one, zero],
            [dt * (v * sec), dt * (u * sec * tth), one],
        ]
        pp = _mul_t_sym(_mul(a, self.p), a)
        pp[0][0] = pp[0][0] + self.q_phi
        pp[1][1] = pp[1][1] + self.q_theta
        pp[2][2] = pp[2][2] + self.q_psi
        e, pp = _canon((ex, ey, ez), pp)
        pp, cond = _condition(pp, self.p_max)
        ok = dm.vec3_isfinite(e) & (cond != _u(Flag.NUMERIC))
        flags = flags | np.where(ok, cond, _u(Flag.NUMERIC))
        return dm.vec3_where(ok, e, self.euler), _mat_where(ok, pp, self.p), flags

    def _update(self, e0: dm.Vec3, p: Mat, a: dm.Vec3) -> tuple[dm.Vec3, Mat, Any]:
        """att_ekf_update: (euler, P, flags) after the accel update (state kept on NUMERIC)."""
        z = sensor.tilt(a)
        y0 = dm.wrap_pi(z[0] - e0[0])
        y1 = dm.wrap_pi(z[1] - e0[1])
        s00 = p[0][0] + self.r_phi
        s01 = p[0][1]
        s11 = p[1][1] + self.r_theta
        det = s00 * s11 - s01 * s01
        det_ok = (det > dm.ZERO) & dm.isfinitef(det)
        i00 = s11 / det
        i01 = -s01 / det
        i11 = s00 / det
        k = [(p[i][0] * i00 + p[i][1] * i01, p[i][0] * i01 + p[i][1] * i11) for i in range(3)]
        e = (
            e0[0] + (k[0][0] * y0 + k[0][1] * y1),
            e0[1] + (k[1][0] * y0 + k[1][1] * y1),
            e0[2] + (k[2][0] * y0 + k[2][1] * y1),
        )
        zero = np.zeros(self.n, np.float32)
        one = np.full(self.n, dm.ONE, np.float32)
        m: Mat = [
            [dm.ONE - k[0][0], dm.ZERO - k[0][1], zero],
            [dm.ZERO - k[1][0], dm.ONE - k[1][1], zero],
            [dm.ZERO - k[2][0], dm.ZERO - k[2][1], one],
        ]
        pn = _mul_t_sym(_mul(m, p), m)
        for i in range(3):
            for j in range(i, 3):
                pn[i][j] = pn[i][j] + (k[i][0] * self.r_phi * k[j][0] + k[i][1] * self.r_theta * k[j][1])
                pn[j][i] = pn[i][j]
        e, pn = _canon(e, pn)
        pn, cond = _condition(pn, self.p_max)
        take = det_ok & dm.vec3_isfinite(e) & (cond != _u(Flag.NUMERIC))
        flags = np.where(take, cond, _u(Flag.NUMERIC))
        return dm.vec3_where(take, e, e0), _mat_where(take, pn, p), flags

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
            err = norm / self.gravity - dm.ONE
            rejected = accel_ok & (self.accel_reject > dm.ZERO) & (dm.absf(err) > self.accel_reject)
            flags = flags | np.where(rejected, _u(Flag.ACCEL_REJECTED), _U0)

            # not yet initialised: roll and pitch from the first valid accel sample, yaw 0
            waiting = ~self.initialised
            init_now = waiting & accel_ok
            t = sensor.tilt(a)
            e_init = (dm.wrap_pi(t[0]), t[1], np.zeros(self.n, np.float32))
            flags = flags | np.where(
                waiting, np.where(accel_ok, _u(Flag.INITIALISED), _u(Flag.NOT_READY)), _U0
            )

            zero = np.zeros(self.n, np.float32)
            w = dm.vec3_where(gyro_ok, g, (zero, zero, zero))
            e1, p1, pred_flags = self._predict(w, gyro_ok)
            upd = accel_ok & ~rejected
            e2, p2, upd_flags = self._update(e1, p1, a)
            e2 = dm.vec3_where(upd, e2, e1)
            p2 = _mat_where(upd, p2, p1)
            run_flags = pred_flags | np.where(upd, upd_flags, _U0)
            flags = flags | np.where(waiting, _U0, run_flags)

            self.euler = dm.vec3_where(waiting, dm.vec3_where(init_now, e_init, self.euler), e2)
            self.p = _mat_where(waiting, self.p, p2)
            self.q = dm.quat_from_euler(*self.euler)
        self.initialised = self.initialised | init_now
        self.steps = self.steps + np.uint32(1)
        self.flags = flags.astype(np.uint32)
        return self.flags

    def retune(self, settings: EkfSettings) -> None:
        """att_ekf_retune: new settings (coefficients), the state kept."""
        new = Ekf(settings, self.n)
        carry_state(self, new)
        self.__dict__.update(new.__dict__)

    @property
    def quat(self) -> NDArray[np.float32]:
        """Attitudes (n, 4), w,x,y,z, sensor-to-earth."""
        return stack(self.q)

    @property
    def euler_angles(self) -> NDArray[np.float32]:
        """ZYX Euler angles (n, 3): roll phi, pitch theta, yaw psi, rad."""
        return stack(self.euler)

    @property
    def covariance(self) -> NDArray[np.float32]:
        """Error covariance P (n, 3, 3) of (phi, theta, psi), rad^2."""
        return np.stack([stack(tuple(row)) for row in self.p], axis=1)

    @property
    def cov_diag(self) -> NDArray[np.float32]:
        """Variances (n, 3): P_phi, P_theta, P_psi, rad^2."""
        return stack((self.p[0][0], self.p[1][1], self.p[2][2]))

    def run(self, gyr: Any, acc: Any) -> tuple[NDArray[np.float32], NDArray[np.uint32]]:
        """Step through N samples: gyr, acc (N, 3) for n == 1 or (N, n, 3).

        Returns quats (N, 4) or (N, n, 4) and flags (N,) or (N, n).
        """
        return run_steps(self, gyr, acc)
