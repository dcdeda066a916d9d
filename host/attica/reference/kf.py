"""Mirror of firmware/src/att_kf.c: the linear quaternion Kalman filter, many instances in lockstep.

Matrices are 4x4 nested lists of per-instance float32 arrays of shape (n,); every product is the
same fixed-order scalar sequence as in C (the sum starts from the first product).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.reference import detmath as dm
from attica.reference import sensor
from attica.reference._common import StateSpec, carry_state, run_steps, setting, split3, stack
from attica.settings import Flag, KfSettings, KfYawMode

_U0 = np.uint32(0)
Mat = list[list[Any]]
"""A 4x4 matrix: rows of per-instance float32 arrays."""
Vec4 = list[Any]
"""A 4-vector of per-instance float32 arrays."""


def _u(flag: Flag) -> np.uint32:
    return np.uint32(flag.value)


def _mul(a: Mat, b: Mat) -> Mat:
    """att_kf_mul: a * b."""
    out: Mat = [[None] * 4 for _ in range(4)]
    for i in range(4):
        for j in range(4):
            s = a[i][0] * b[0][j]
            for k in range(1, 4):
                s = s + a[i][k] * b[k][j]
            out[i][j] = s
    return out


def _mul_bt(a: Mat, b: Mat) -> Mat:
    """att_kf_mul_bt: a * b^T."""
    out: Mat = [[None] * 4 for _ in range(4)]
    for i in range(4):
        for j in range(4):
            s = a[i][0] * b[j][0]
            for k in range(1, 4):
                s = s + a[i][k] * b[j][k]
            out[i][j] = s
    return out


def _symmetrise(m: Mat) -> Mat:
    """att_kf_symmetrise: (m + m^T) / 2 elementwise."""
    return [[(m[i][j] + m[j][i]) * dm.HALF for j in range(4)] for i in range(4)]


def _all_finite(x: Vec4, p: Mat) -> Any:
    """att_kf_all_finite."""
    ok = dm.isfinitef(x[0])
    for i in range(4):
        if i > 0:
            ok = ok & dm.isfinitef(x[i])
        for j in range(4):
            ok = ok & dm.isfinitef(p[i][j])
    return ok


def _where4(cond: Any, a: Vec4, b: Vec4) -> Vec4:
    return [np.where(cond, a[i], b[i]) for i in range(4)]


def _where44(cond: Any, a: Mat, b: Mat) -> Mat:
    return [[np.where(cond, a[i][j], b[i][j]) for j in range(4)] for i in range(4)]


class Kf:
    """Linear quaternion KF reference: ``n`` independent instances sharing one settings object.

    Settings fields may be scalars or length-``n`` sequences (one value per instance). Settings are
    not validated here (``att_kf_init`` does that in C).
    """

    STATE: StateSpec = {"q": "quat", "p": "f32x16", "initialised": "bool", "steps": "u32", "flags": "u32"}
    """C state fields mirrored by this class (see reference._common.load_c_state)."""

    def __init__(self, settings: KfSettings | None = None, n: int = 1) -> None:
        s = settings if settings is not None else KfSettings()
        self.settings = s
        self.n = n
        self.dt = setting(s.dt, n)
        # att_kf_init: per-step Q and R (q_step, r_step); with noise_rates the settings are rates
        rates = setting(s.noise_rates, n, np.bool_)
        q_noise = setting(s.q_noise, n)
        r_noise = setting(s.r_noise, n)
        with np.errstate(all="ignore"):
            self.q_noise = np.where(rates, q_noise * self.dt, q_noise).astype(np.float32)
            self.r_noise = np.where(rates, r_noise / self.dt, r_noise).astype(np.float32)
        self.p0 = setting(s.p0, n)
        self.gravity = setting(s.gravity, n)
        self.accel_reject = setting(s.accel_reject, n)
        self.accel_range = setting(s.accel_range, n)
        self.gyro_range = setting(s.gyro_range, n)
        self.yaw_mode = setting(s.yaw_mode, n, np.int32)
        self.init_from_accel = setting(s.init_from_accel, n, np.bool_)
        qi = np.broadcast_to(np.asarray(s.q_init, np.float32), (n, 4))  # (4,) or one per instance (n, 4)
        self.q_init = (qi[:, 0].copy(), qi[:, 1].copy(), qi[:, 2].copy(), qi[:, 3].copy())
        self.reset()

    def reset(self) -> None:
        """Back to the state after construction (att_kf_reset)."""
        n = self.n
        _, self.q = dm.quat_normalize(self.q_init)
        zero = np.zeros(n, np.float32)
        self.p: Mat = [[self.p0.copy() if i == j else zero.copy() for j in range(4)] for i in range(4)]
        self.initialised = ~self.init_from_accel
        self.steps = np.zeros(n, np.uint32)
        self.flags = np.zeros(n, np.uint32)

    def _predict(self, g: dm.Vec3, x: Vec4, p: Mat) -> tuple[Vec4, Mat]:
        h = self.dt * dm.HALF
        hp = h * g[0]
        hq = h * g[1]
        hr = h * g[2]
        one = dm.ONE
        a: Mat = [
            [one, -hp, -hq, -hr],
            [hp, one, hr, -hq],
            [hq, -hr, one, hp],
            [hr, hq, -hp, one],
        ]
        xn: Vec4 = []
        for i in range(4):
            s = a[i][0] * x[0]
            for k in range(1, 4):
                s = s + a[i][k] * x[k]
            xn.append(s)
        u = _mul_bt(_mul(a, p), a)
        for i in range(4):
            u[i][i] = u[i][i] + self.q_noise
        return xn, _symmetrise(u)

    def _measurement(self, a: dm.Vec3, x: Vec4) -> Vec4:
        _, xu = dm.quat_normalize((x[0], x[1], x[2], x[3]))
        psi_state = dm.quat_to_euler(xu)[2]
        psi = np.where(self.yaw_mode == KfYawMode.STATE, psi_state, dm.ZERO).astype(np.float32)
        t = sensor.tilt(a)
        zq = dm.quat_from_euler(t[0], t[1], psi)
        dot = zq[0] * x[0] + zq[1] * x[1] + zq[2] * x[2] + zq[3] * x[3]
        neg = dot < dm.ZERO
        return [np.where(neg, -zq[i], zq[i]) for i in range(4)]

    def _update(self, z: Vec4, x: Vec4, p: Mat) -> tuple[Any, Vec4, Mat]:
        r = self.r_noise
        ok = np.ones(self.n, np.bool_)
        lt: Mat = [[None] * 4 for _ in range(4)]
        for j in range(4):
            d = p[j][j] + r
            for m in range(j):
                d = d - lt[j][m] * lt[j][m]
            ok = ok & (d > dm.ZERO) & dm.isfinitef(d)
            lt[j][j] = dm.sqrtf(d)
            for i in range(j + 1, 4):
                v = p[i][j]
                for m in range(j):
                    v = v - lt[i][m] * lt[j][m]
                lt[i][j] = v / lt[j][j]

        k: Mat = [[None] * 4 for _ in range(4)]
        for c in range(4):
            y: Vec4 = [None] * 4
            w: Vec4 = [None] * 4
            for i in range(4):
                v = p[i][c]
                for m in range(i):
                    v = v - lt[i][m] * y[m]
                y[i] = v / lt[i][i]
            for i in range(3, -1, -1):
                v = y[i]
                for m in range(i + 1, 4):
                    v = v - lt[m][i] * w[m]
                w[i] = v / lt[i][i]
            for i in range(4):
                k[c][i] = w[i]

        e = [z[i] - x[i] for i in range(4)]
        xn: Vec4 = []
        for i in range(4):
            s = k[i][0] * e[0]
            for m in range(1, 4):
                s = s + k[i][m] * e[m]
            xn.append(x[i] + s)

        mm: Mat = [[dm.ONE - k[i][j] if i == j else -k[i][j] for j in range(4)] for i in range(4)]
        u = _mul_bt(_mul(mm, p), mm)
        kk = _mul_bt(k, k)
        u = [[u[i][j] + r * kk[i][j] for j in range(4)] for i in range(4)]
        pn = _symmetrise(u)
        ok = ok & _all_finite(xn, pn)
        return ok, xn, pn

    def step(self, gyr: Any, acc: Any) -> NDArray[np.uint32]:
        """One update of every instance; gyr, acc of shape (n, 3) or (3,). Returns flags (n,)."""
        n = self.n
        g = split3(gyr, n)
        a = split3(acc, n)
        with np.errstate(all="ignore"):
            flags = sensor.check_gyro(g, self.gyro_range)
            gyro_ok = flags == _U0
            accel_flags, norm = sensor.check_accel(a, self.accel_range)
            accel_ok = accel_flags == _U0
            flags = flags | accel_flags
            e = norm / self.gravity - dm.ONE
            rejected = accel_ok & (self.accel_reject > dm.ZERO) & (dm.absf(e) > self.accel_reject)
            flags = flags | np.where(rejected, _u(Flag.ACCEL_REJECTED), _U0)

            # not yet initialised: attitude from the first usable accel sample
            waiting = ~self.initialised
            init_now = waiting & accel_ok
            t = sensor.tilt(a)
            _, q_tilt = dm.quat_normalize(dm.quat_from_euler(t[0], t[1], np.zeros(n, np.float32)))
            flags = flags | np.where(
                waiting, np.where(accel_ok, _u(Flag.INITIALISED), _u(Flag.NOT_READY)), _U0
            )

            # prediction; an unusable gyro sample leaves x as it is but still adds Q
            x0: Vec4 = list(self.q)
            p0 = self.p
            xp, pp = self._predict(g, x0, p0)
            p_hold = [[p0[i][j] + self.q_noise if i == j else p0[i][j] for j in range(4)] for i in range(4)]
            x1 = _where4(gyro_ok, xp, x0)
            p1 = _where44(gyro_ok, pp, p_hold)

            # measurement update
            do_update = accel_ok & ~rejected
            z = self._measurement(a, x1)
            upd_ok, xu, pu = self._update(z, x1, p1)
            flags = flags | np.where(~waiting & do_update & ~upd_ok, _u(Flag.NUMERIC), _U0)
            use = do_update & upd_ok
            x2 = _where4(use, xu, x1)
            p2 = _where44(use, pu, p1)

            # normalisation x := x / |x|, P := P / |x|^2
            n2 = x2[0] * x2[0] + x2[1] * x2[1] + x2[2] * x2[2] + x2[3] * x2[3]
            ok, qn = dm.quat_normalize((x2[0], x2[1], x2[2], x2[3]))
            p3 = [[p2[i][j] / n2 for j in range(4)] for i in range(4)]
            ok = ok & _all_finite(list(qn), p3)
            flags = flags | np.where(~waiting & ~ok, _u(Flag.NUMERIC), _U0)
            q_run = dm.quat_where(ok, qn, self.q)
            p_run = _where44(ok, p3, p0)
            self.q = dm.quat_where(waiting, dm.quat_where(init_now, q_tilt, self.q), q_run)
            self.p = _where44(waiting, p0, p_run)
        self.q = tuple(np.asarray(c, np.float32) for c in self.q)  # type: ignore[assignment]
        self.p = [[np.asarray(v, np.float32) for v in row] for row in self.p]
        self.initialised = self.initialised | init_now
        self.steps = self.steps + np.uint32(1)
        self.flags = np.asarray(flags, np.uint32)
        return self.flags

    def retune(self, settings: KfSettings) -> None:
        """att_kf_retune: new settings (coefficients), the state kept."""
        new = Kf(settings, self.n)
        carry_state(self, new)
        self.__dict__.update(new.__dict__)

    @property
    def quat(self) -> NDArray[np.float32]:
        """Attitudes (n, 4), w,x,y,z, sensor-to-earth."""
        return stack(self.q)

    @property
    def covariance(self) -> NDArray[np.float32]:
        """Covariance matrices P (n, 4, 4) of (w, x, y, z)."""
        return np.stack([stack(tuple(row)) for row in self.p], axis=-2)

    @property
    def cov_diag(self) -> NDArray[np.float32]:
        """Covariance diagonals (n, 4): P_ww, P_xx, P_yy, P_zz."""
        return stack(tuple(self.p[i][i] for i in range(4)))

    def run(self, gyr: Any, acc: Any) -> tuple[NDArray[np.float32], NDArray[np.uint32]]:
        """Step through N samples: gyr, acc (N, 3) for n == 1 or (N, n, 3).

        Returns quats (N, 4) or (N, n, 4) and flags (N,) or (N, n).
        """
        return run_steps(self, gyr, acc)
