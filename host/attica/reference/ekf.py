"""Mirror of firmware/src/filters/ekf/att_ekf.c: Euler-angle EKF with gyro bias states, instances in lockstep.

P is kept as the 21 elements of the packed upper triangle (att_ekf_state_t.p), each an (n,) array.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.reference import detmath as dm
from attica.reference import sensor
from attica.reference._common import (
    COV_UNKNOWN,
    StateSpec,
    carry_state,
    pd6,
    recovery_lp_gain2,
    recovery_params,
    recovery_q,
    recovery_step,
    run_steps,
    setting,
    split3,
    stack,
)
from attica.reference.ars import align_up
from attica.settings import EkfSettings, Flag

_U0 = np.uint32(0)
PI = dm.c("0x1.921fb6p+1")
PIO2 = dm.c("0x1.921fb6p+0")
TWOPI_HI = dm.c("0x1.921fb6p+2")
TWOPI_LO = dm.c("-0x1.777a5cp-23")
PIVOT_MIN = dm.c("0x1p-12")
COLLAPSE = dm.c("0x1p+12")  # ATT_EKF_COLLAPSE: a roll or pitch variance this far above its noise
SHRINK = dm.c("0x1.ff8p-1")
QUARTER = dm.c("0x1p-2")
THIRD = dm.c("0x1.555556p-2")
SETTLED = dm.c("0x1.47ae14p-7")
BIAS_SOFT = dm.c("0x1p-4")
COND_MASK = np.uint32(15)
INC_MAX = dm.c("0x1p-4")
INC_S3 = dm.c("-0x1.555556p-3")
INC_S5 = dm.c("0x1.111112p-7")
INC_C4 = dm.c("0x1.555556p-5")

_IX = [
    [0, 1, 2, 3, 4, 5],
    [1, 6, 7, 8, 9, 10],
    [2, 7, 11, 12, 13, 14],
    [3, 8, 12, 15, 16, 17],
    [4, 9, 13, 16, 18, 19],
    [5, 10, 14, 17, 19, 20],
]
"""att_ekf_ix: packed index of element (i, j) of the symmetric 6x6 P."""

_UPDATED = frozenset(
    [0, 1, 6]
    + [_IX[r][i] for r in (0, 1) for i in range(3, 6)]
    + [_IX[i][j] for i in range(3, 6) for j in range(i, 6)]
)
"""The elements of P the update writes (yaw's row is not carried)."""


def _u(flag: Flag) -> np.uint32:
    return np.uint32(flag.value)


def _wrap(a: Any) -> Any:
    """att_ekf_wrap: one 2 pi step for small excursions, att_wrap_pi beyond."""
    with np.errstate(all="ignore"):
        a = np.where(a > PI, (a - TWOPI_HI) - TWOPI_LO, np.where(a <= -PI, (a + TWOPI_HI) + TWOPI_LO, a))
        far = (a > PI) | (a <= -PI)
        return np.where(far, dm.wrap_pi(a), a).astype(np.float32)


def _sincos_small(d: Any) -> tuple[Any, Any]:
    """att_ekf_sincos_small: sin(d), cos(d) by their series (valid for |d| <= 1/16)."""
    with np.errstate(all="ignore"):
        z = d * d
        return d + (d * z) * (INC_S3 + z * INC_S5), dm.ONE - z * (dm.HALF - z * INC_C4)


def _sincos_step(a: Any, d: Any, s0: Any, c0: Any) -> tuple[Any, Any]:
    """att_ekf_sincos_step: sin/cos of a = a0 + d by angle addition for |d| <= 1/16, else directly."""
    with np.errstate(all="ignore"):
        sd, cd = _sincos_small(d)
        small = dm.absf(d) <= INC_MAX
        s = np.where(small, s0 * cd + c0 * sd, dm.sinf(a)).astype(np.float32)
        c = np.where(small, c0 * cd - s0 * sd, dm.cosf(a)).astype(np.float32)
        return s, c


def _sincos_mid(a: Any, d: Any, s0: Any, c0: Any) -> tuple[Any, Any]:
    """att_ekf_sincos_mid: sin/cos of the midpoint a = a0 + d to first order for |d| <= 1/16."""
    with np.errstate(all="ignore"):
        small = dm.absf(d) <= INC_MAX
        s = np.where(small, s0 + c0 * d, dm.sinf(a)).astype(np.float32)
        c = np.where(small, c0 - s0 * d, dm.cosf(a)).astype(np.float32)
        return s, c


def _turn(lp: dm.Vec3, d: Any) -> dm.Vec3:
    """att_ekf_turn: a heading-frame vector turned by the yaw change d (x := c x + s y, y := c y - s x)."""
    with np.errstate(all="ignore"):
        small = dm.absf(d) <= INC_MAX
        s1, c1 = _sincos_small(d)
        sd = np.where(small, s1, dm.sinf(d)).astype(np.float32)
        cd = np.where(small, c1, dm.cosf(d)).astype(np.float32)
        x, y, zz = lp
        return (cd * x + sd * y, cd * y - sd * x, zz)


def _canon(e: dm.Vec3, p: list[Any]) -> tuple[dm.Vec3, list[Any], Any]:
    """att_ekf_canon: theta into [-pi/2, pi/2] by the equivalent attitude, phi and psi wrapped.

    Returns (e, P, flipped).
    """
    ex, ey, ez = e
    ey = _wrap(ey)
    flip = (ey > PIO2) | (ey < -PIO2)
    ey = np.where(flip, np.where(ey > dm.ZERO, PI, -PI) - ey, ey)
    ex = np.where(flip, ex + PI, ex)
    ez = np.where(flip, ez + PI, ez)
    p = list(p)
    for k in (0, 3, 4, 5):  # yaw's correlation (1, 2) is not carried
        if k != 1:
            i = _IX[1][k]
            p[i] = np.where(flip, -p[i], p[i])
    ez = _wrap(ez)
    return (_wrap(ex), ey.astype(np.float32), ez), p, flip


def _usable(p: list[Any]) -> Any:
    """att_ekf_p_usable: the sum of the 21 elements finite and every variance > 0."""
    with np.errstate(all="ignore"):
        s = p[0]
        for i in (1, 3, 4, 5, 6, 8, 9, 10, 11, 15, 16, 17, 18, 19, 20):  # the carried elements
            s = s + p[i]
        return (
            dm.isfinitef(s)
            & (p[0] > dm.ZERO)
            & (p[6] > dm.ZERO)
            & (p[11] > dm.ZERO)
            & (p[15] > dm.ZERO)
            & (p[18] > dm.ZERO)
            & (p[20] > dm.ZERO)
        )


def _pd_ok(p: list[Any]) -> Any:
    """att_ekf_pd_ok: att_i_pd6 with the margin 2^-12."""
    return pd6(p, PIVOT_MIN)


def _near_singular(p: list[Any]) -> Any:
    """att_ekf_update's test of its prior (F12): det P2 = P00 P11 - P01^2 not above 2^-12 P00 P11."""
    with np.errstate(all="ignore"):
        pp = p[0] * p[6]
        dp = pp - p[1] * p[1]
        return ~(dp > PIVOT_MIN * pp)


def _condition(p: list[Any], p_max: Any, pb_max: Any) -> tuple[list[Any], Any]:
    """att_ekf_condition: (P, changed) with the caps (p_max, pb_max bias), PD test and repair."""
    with np.errstate(all="ignore"):
        dd = []
        capped = np.zeros(np.shape(p[0]), np.bool_)
        for i in range(6):
            v = p[_IX[i][i]]
            cap = p_max if i < 3 else pb_max
            over = v > cap
            dd.append(np.where(over, dm.sqrtf(cap / v), dm.ONE))
            capped = capped | over
        q = list(p)
        for i in range(6):
            for j in range(i, 6):
                k = _IX[i][j]
                q[k] = np.where(capped, (p[k] * dd[i]) * dd[j], p[k])
        ok = _pd_ok(q)
        shr = list(q)
        for i in range(6):
            for j in range(i + 1, 6):
                k = _IX[i][j]
                shr[k] = q[k] * SHRINK
        ok2 = _pd_ok(shr)
        out = []
        for idx in range(21):
            diag = idx in (0, 6, 11, 15, 18, 20)
            zero = np.zeros(np.shape(p[0]), np.float32)
            repaired = shr[idx] if diag else np.where(ok2, shr[idx], zero)
            out.append(np.where(ok, q[idx], repaired).astype(np.float32))
        return out, capped | ~ok


MEAN_N_MAX = np.uint32(0x1000000)
"""ATT_EKF_MEAN_N_MAX: the start's running mean ends at this count at the latest."""


class Ekf:
    """Euler EKF reference: ``n`` independent instances sharing one settings object.

    Settings fields may be scalars or length-``n`` sequences (one value per instance).
    """

    STATE: StateSpec = {
        "st.euler": "vec3",
        "st.bias": "vec3",
        "st.p": "f32x21",
        "st.lp1": "vec3",
        "st.lp2": "vec3",
        "st.lp_psi": "f32",
        "st.lp_ready": "bool",
        "st.converging": "bool",
        "st.lp_mean": "bool",
        "st.recover": "bool",
        "st.steps": "u32",
        "st.flags": "u32",
        "st.rec_left": "u32",
        "st.rec_lp_n": "u32",
        "st.initialised": "bool",
        "st.head_known": "bool",
    }
    """C state fields mirrored by this class (see reference._common.load_c_state)."""
    EARTH: tuple[str, ...] = ("lp1", "lp2")
    """Earth-frame state vectors, turned with the attitude by a heading change (reference.calib.yaw_to)."""

    COEFFS: StateSpec = {
        "c.dt": "f32",
        "c.q_step": "f32x4",
        "c.r_step": "f32x2",
        "c.r_accel": "f32",
        "c.gate": "f32",
        "c.soft": "f32",
        "c.p0": "f32",
        "c.p0_bias": "f32",
        "c.p_max": "f32",
        "c.gravity": "f32",
        "c.accel_reject": "f32",
        "c.accel_range2": "f32",
        "c.gyro_range": "f32",
        "c.cos_min": "f32",
        "c.k_lp": "f32",
        "c.euler_init": "vec3",
        "c.bias_init": "vec3",
        "c.init_from_accel": "bool",
        "c.lp_on": "bool",
        "c.need_norm": "bool",
        "c.clip": "f32",
        "c.q_rec": "f32x2",
        "c.rec_n": "u32",
    }
    """Every C coefficient of att_ekf_coeffs_t (set by att_ekf_init / retune), derived here alike
    from the settings; state_matches compares them after the state."""

    def __init__(self, settings: EkfSettings | None = None, n: int = 1) -> None:
        s = settings if settings is not None else EkfSettings()
        self.settings = s
        self.n = n
        self.dt = setting(s.dt, n)
        rates = setting(s.noise_rates, n, np.bool_)
        dq = np.where(rates, self.dt, dm.ONE).astype(np.float32)
        self.q_step = (
            setting(s.q_phi, n) * dq,
            setting(s.q_theta, n) * dq,
            setting(s.q_psi, n) * dq,
            setting(s.q_bias, n) * dq,
        )
        with np.errstate(all="ignore"):
            self.r_step = (setting(s.r_phi, n) / dq, setting(s.r_theta, n) / dq)
        self.r_accel = setting(s.r_accel, n)
        self.gate = setting(s.gate, n)
        self.soft = self.gate * QUARTER
        self.p0 = setting(s.p0, n)
        self.p0_bias = setting(s.p0_bias, n)
        self.p_max = setting(s.p_max, n)
        self.gravity = setting(s.gravity, n)
        self.accel_reject = setting(s.accel_reject, n)
        acc_range = setting(s.accel_range, n)
        self.accel_range2 = acc_range * acc_range
        self.gyro_range = setting(s.gyro_range, n)
        self.cos_min = setting(s.cos_min, n)
        tau_lp = setting(s.tau_acc_lp, n)
        with np.errstate(all="ignore"):
            self.k_lp = np.where(tau_lp > dm.ZERO, self.dt / (tau_lp + self.dt), dm.ZERO).astype(np.float32)
        ei = split3(s.euler_init, n)
        self.euler_init: dm.Vec3 = (dm.wrap_pi(ei[0]), ei[1], dm.wrap_pi(ei[2]))
        self.bias_init = split3(s.bias_init, n)
        self.init_from_accel = setting(s.init_from_accel, n, np.bool_)
        self.need_norm = (self.r_accel > dm.ZERO) | (self.accel_reject > dm.ZERO)
        self.lp_on = self.k_lp > dm.ZERO
        self._rec_coeffs(s)
        self._zeros = np.zeros(n, np.float32)
        self.reset()

    def _rec_coeffs(self, s: EkfSettings) -> None:
        """att_ekf_rec_coeffs: the recovery after a clipping gyro (k^2 r / (1 - k): steady-state gain k)."""
        self.rec_n, self.clip, k = recovery_params(setting(s.recovery_time, self.n), self.gyro_range, self.dt)
        on = self.rec_n > _U0
        self.q_rec = tuple(
            np.where(on, recovery_q(k, r, self.p_max), dm.ZERO).astype(np.float32) for r in self.r_step
        )

    def _p_start(self) -> list[Any]:
        """att_ekf_p_diag(p0, p0_bias): P at reset, and after a step whose P cannot be used."""
        z = self._zeros
        p = [z.copy() for _ in range(21)]
        for i in (0, 6, 11):
            p[i] = self.p0.copy()
        for i in (15, 18, 20):
            p[i] = self.p0_bias.copy()
        return p

    def reset(self) -> None:
        """att_ekf_reset."""
        z = self._zeros
        self.euler: dm.Vec3 = tuple(np.copy(v) for v in self.euler_init)  # type: ignore[assignment]
        self.bias: dm.Vec3 = tuple(np.copy(v) for v in self.bias_init)  # type: ignore[assignment]
        self.p: list[Any] = self._p_start()
        self.lp1: dm.Vec3 = (z.copy(), z.copy(), self.gravity.copy())
        self.lp2: dm.Vec3 = (z.copy(), z.copy(), self.gravity.copy())
        self.lp_psi = np.copy(self.euler[2])
        self.lp_ready = np.zeros(self.n, np.bool_)
        self.converging = np.zeros(self.n, np.bool_)
        self.lp_mean = np.zeros(self.n, np.bool_)
        self.recover = np.zeros(self.n, np.bool_)
        self.steps = np.zeros(self.n, np.uint32)
        self.flags = np.zeros(self.n, np.uint32)
        self.rec_left = np.zeros(self.n, np.uint32)
        self.rec_lp_n = np.zeros(self.n, np.uint32)
        self.initialised = ~self.init_from_accel
        self.head_known = np.zeros(self.n, np.bool_)

    def _guard(self, c: Any) -> tuple[Any, Any]:
        small = dm.absf(c) < self.cos_min
        return np.where(small, np.where(c < dm.ZERO, -self.cos_min, self.cos_min), c), small

    def _predict(
        self, w: dm.Vec3, gyro_ok: Any, rec: Any
    ) -> tuple[Any, Any, dm.Vec3, list[Any], Any, tuple[Any, ...], Any]:
        """att_ekf_predict: (usable, taken, angles, P, flags, sin/cos of roll and pitch, condition now).

        The prediction is taken unless its angles leave the wrap's range (then the angles are kept, P
        restarts and the stages restart: ``ok_e`` false); ``usable`` is att_ekf_check's test of it
        (made when no update is applied after it).
        """
        dt = self.dt
        p = self.p
        ex0, ey0, ez0 = self.euler
        wx, wy, wz = w
        with np.errstate(all="ignore"):
            sphi = dm.sinf(ex0)
            cphi = dm.cosf(ex0)
            sth = dm.sinf(ey0)
            cth0 = dm.cosf(ey0)
            cth, gim = self._guard(cth0)
            flags = np.where(gim & gyro_ok, _u(Flag.GIMBAL), _U0)
            tth = sth / cth
            sec = dm.ONE / cth
            hdt = dt * dm.HALF
            dxh = (wx + sphi * tth * wy + cphi * tth * wz) * hdt
            dyh = (cphi * wy - sphi * wz) * hdt
            # the midpoint's sin/cos to first order (its error, O(dt^2) in the rates, keeps the rule
            # second order)
            sm, cm = _sincos_mid(ex0 + dxh, dxh, sphi, cphi)
            stm, ctm0 = _sincos_mid(ey0 + dyh, dyh, sth, cth0)
            ctm, _ = self._guard(ctm0)
            ttm = stm / ctm
            secm = dm.ONE / ctm
            dx = (wx + sm * ttm * wy + cm * ttm * wz) * dt
            dy = (cm * wy - sm * wz) * dt
            e = (
                ex0 + dx,
                ey0 + dy,
                ez0 + (sm * secm * wy + cm * secm * wz) * dt,
            )
            u = sphi * wy + cphi * wz
            v = cphi * wy - sphi * wz
            a00 = dm.ONE + dt * (v * tth)
            a01 = dt * (u * sec * sec)
            a10 = -(dt * u)
            b00 = -dt
            b01 = -(dt * (sphi * tth))
            b02 = -(dt * (cphi * tth))
            b11 = -(dt * cphi)
            b12 = dt * sphi

            def pp(i: int, j: int) -> Any:
                return p[_IX[i][j]]

            # yaw's row of P is not carried (its correlations stay as they are: zero): F's yaw column is
            # zero in the rows of roll and pitch and H does not see yaw
            uu: list[list[Any]] = [[None] * 3 for _ in range(2)]
            vv: list[list[Any]] = [[None] * 3 for _ in range(2)]
            ww: list[list[Any]] = [[None] * 2 for _ in range(2)]
            for j in range(3):
                p0j, p1j = pp(0, 3 + j), pp(1, 3 + j)
                q0j, q1j, q2j = pp(3, 3 + j), pp(4, 3 + j), pp(5, 3 + j)
                uu[0][j] = a00 * p0j + a01 * p1j
                uu[1][j] = a10 * p0j + p1j
                vv[0][j] = (b00 * q0j + b01 * q1j) + b02 * q2j
                vv[1][j] = b11 * q1j + b12 * q2j
            for j in range(2):
                r0j, r1j = pp(0, j), pp(1, j)
                ww[0][j] = a00 * r0j + a01 * r1j
                ww[1][j] = a10 * r0j + r1j
            nn = [[uu[i][j] + vv[i][j] for j in range(3)] for i in range(2)]
            x = [
                [(nn[i][0] * b00 + nn[i][1] * b01) + nn[i][2] * b02, nn[i][1] * b11 + nn[i][2] * b12]
                for i in range(2)
            ]
            y = [
                [(uu[i][0] * b00 + uu[i][1] * b01) + uu[i][2] * b02, uu[i][1] * b11 + uu[i][2] * b12]
                for i in range(2)
            ]
            pn: list[Any] = list(p)
            for i in range(2):
                w0, w1 = ww[i]
                t = [w0 * a00 + w1 * a01, w0 * a10 + w1]
                for j in range(i, 2):
                    pn[_IX[i][j]] = (t[j] + x[i][j]) + y[j][i]
                for j in range(3):
                    pn[_IX[i][3 + j]] = nn[i][j]
            # without usable rates F = I and the angles are kept
            pn = [np.where(gyro_ok, pn[k], p[k]).astype(np.float32) for k in range(21)]
            e = dm.vec3_where(gyro_ok, e, self.euler)
            dx = np.where(gyro_ok, dx, dm.ZERO).astype(np.float32)
            dy = np.where(gyro_ok, dy, dm.ZERO).astype(np.float32)
            for i, qi in ((0, 0), (1, 1), (2, 2), (3, 3), (4, 3), (5, 3)):
                pn[_IX[i][i]] = pn[_IX[i][i]] + self.q_step[qi]
            for i in (0, 1):  # a recovery (step 3): roll and pitch follow the accelerometer with its gain
                pn[_IX[i][i]] = np.where(rec, pn[_IX[i][i]] + self.q_rec[i], pn[_IX[i][i]]).astype(np.float32)
            e, pn, flip = _canon(e, pn)
            # increments beyond the wrap's range (adversarial rates, dt, cos_min): the angles kept, P
            # restarted
            ok_e = dm.isfinitef((e[0] + e[1]) + e[2])
            e = dm.vec3_where(ok_e, e, self.euler)
            start = self._p_start()
            pn = [np.where(ok_e, pn[k], start[k]).astype(np.float32) for k in range(21)]
            flags = flags | np.where(ok_e, _U0, _u(Flag.NUMERIC))
            ok = dm.vec3_isfinite(e) & _usable(pn)
            # sin/cos of the predicted roll and pitch: by angle addition, directly after a flip
            s1, c1 = _sincos_step(e[0], dx, sphi, cphi)
            s2, c2 = _sincos_step(e[1], dy, sth, cth0)
            s1 = np.where(flip, dm.sinf(e[0]), s1)
            c1 = np.where(flip, dm.cosf(e[0]), c1)
            s2 = np.where(flip, dm.sinf(e[1]), s2)
            c2 = np.where(flip, dm.cosf(e[1]), c2)
            trig = (s1, c1, s2, c2)  # not used after a prediction not taken (no update follows)
            # a roll or pitch increment beyond 1/16 rad: P conditioned this step (ATT_EKF_COND_NOW)
            big = ok_e & ~((dm.absf(dx) <= INC_MAX) & (dm.absf(dy) <= INC_MAX))
        return ok, ok_e, e, pn, flags, trig, big

    def _update(
        self,
        a: dm.Vec3,
        e2: Any,
        lp_ready: Any,
        trig: tuple[Any, ...],
        rec: Any,
        k_lp: Any,
        k_lp2: Any,
    ) -> tuple[Any, Any, Any, Any, tuple[Any, ...]]:
        """att_ekf_update: (applied, discarded, flags, collapse, new state parts) of the update here.

        ``collapse``: P is conditioned after it when applied (a prior variance far above its noise, F18).

        ``discarded``: computed but not usable (C updates P in place: P restarts, att_ekf_p_restart).

        ``trig`` holds sin/cos of its roll and pitch (sphi, cphi, sth, cth), from the prediction;
        ``k_lp`` the low-pass gain of this update (the running mean's, att_i_recovery_lp_gain, in a
        recovery and after the start), ``k_lp2`` the second stage's (1 while that mean runs).
        """
        p = self.p
        ex0, ey0, ez0 = self.euler
        with np.errstate(all="ignore"):
            sphi, cphi, sth, cth = trig
            ax, ay, az = a
            # the specific force in the heading frame of the prediction: R_y(theta) R_x(phi) a
            va = (
                cth * ax + (sth * sphi) * ay + (sth * cphi) * az,
                cphi * ay - sphi * az,
                (-sth) * ax + (cth * sphi) * ay + (cth * cphi) * az,
            )
            lp_on = self.k_lp > dm.ZERO
            # the stages (heading frame of yaw lp_psi) turned into the predicted one (att_ekf_turn)
            d_psi = ez0 - self.lp_psi
            lp1t = _turn(self.lp1, d_psi)
            lp2t = _turn(self.lp2, d_psi)
            # not started: a sample within 0.1 rad of the estimate's gravity starts the stages, from
            # (0, 0, g) after a reset or an unusable gyro sample, from the sample at the end of the
            # convergence phase; otherwise the raw sample is the measurement
            h2 = va[0] * va[0] + va[1] * va[1]
            agrees = (va[2] > dm.ZERO) & (h2 < SETTLED * (h2 + va[2] * va[2]))
            ready = lp_ready | agrees
            up = (self._zeros, self._zeros, self.gravity)
            start = dm.vec3_where(agrees & ~self.converging, up, va)
            b1 = dm.vec3_where(lp_ready, lp1t, start)
            b2 = dm.vec3_where(lp_ready, lp2t, start)
            lp1 = dm.vec3_add(b1, dm.vec3_scale(dm.vec3_sub(va, b1), k_lp))
            lp2 = dm.vec3_add(b2, dm.vec3_scale(dm.vec3_sub(lp1, b2), k_lp2))
            lp1 = dm.vec3_where(lp_on, lp1, self.lp1)
            lp2 = dm.vec3_where(lp_on, lp2, self.lp2)
            vv = dm.vec3_where(lp_on, lp2, va)
            ok_a, (_, cx, cy), n = align_up(vv)
            exx = dm.TWO * cx
            eyy = dm.TWO * cy
            cg, _ = self._guard(cth)
            sec = dm.ONE / cg
            y0 = exx * sec
            y1 = eyy
            inn = dm.ONE / n
            bx = va[1] * inn
            by = -(va[0] * inn)
            yb0 = bx * sec
            yb1 = by
            fa = dm.ONE + self.r_accel * e2
            r1 = self.r_step[1] * fa
            r0 = (self.r_step[0] * fa) * (sec * sec)
            # a prior variance 2^12 times its noise collapses in this update: P conditioned after it (F18)
            collapse = (p[0] > COLLAPSE * r0) | (p[6] > COLLAPSE * r1)
            pp = p[0] * p[6]
            dp = pp - p[1] * p[1]
            dp = np.where(dp > dm.ZERO, dp, dm.ZERO).astype(np.float32)
            t0 = dp + r1 * p[0]
            t1 = dp + r0 * p[6]
            det = (t0 + r0 * p[6]) + r0 * r1
            ok_det = (det > dm.ZERO) & dm.isfinitef(det)
            inv = dm.ONE / det
            i00 = (p[6] + r1) * inv
            i01 = (-p[1]) * inv
            i11 = (p[0] + r0) * inv
            d2 = y0 * (i00 * y0 + i01 * y1) + y1 * (i01 * y0 + i11 * y1)
            gate_on = (self.gate > dm.ZERO) & ~rec  # off during a recovery
            gated = gate_on & (d2 > self.gate)
            fk = np.where(gate_on & (d2 > self.soft), self.soft / d2, dm.ONE).astype(np.float32)
            db = yb0 * (i00 * yb0 + i01 * yb1) + yb1 * (i01 * yb0 + i11 * yb1)
            fb = np.where(db > BIAS_SOFT, (BIAS_SOFT / db) * fk, fk).astype(np.float32)
            k0 = []
            k1 = []
            for i in range(6):
                pi0, pi1 = p[_IX[i][0]], p[_IX[i][1]]
                k0.append(pi0 * i00 + pi1 * i01)
                k1.append(pi0 * i01 + pi1 * i11)
            ex = ex0 + (k0[0] * y0 + k1[0] * y1) * fk
            ey = ey0 + (k0[1] * y0 + k1[1] * y1) * fk
            pn: list[Any] = list(p)
            pn[0] = (r0 * inv) * t0
            pn[1] = ((r0 * r1) * inv) * p[1]
            pn[6] = (r1 * inv) * t1
            for i in range(3, 6):
                pn[_IX[0][i]] = r0 * k0[i]
                pn[_IX[1][i]] = r1 * k1[i]
            for i in range(3, 6):
                for j in range(i, 6):
                    pn[_IX[i][j]] = p[_IX[i][j]] - (k0[i] * p[_IX[j][0]] + k1[i] * p[_IX[j][1]])
            soft = fk < dm.ONE
            pn = [
                np.where(soft, p[k] + fk * (pn[k] - p[k]), pn[k]).astype(np.float32)
                if k in _UPDATED
                else p[k]
                for k in range(21)
            ]
            # a pure tilt correction: yaw follows roll by sin(theta) dphi (no turn about the vertical);
            # the correction's rotation in the heading frame is (cos(theta) dphi, dtheta, 0)
            dphi = ex - ex0
            epx = dphi * cth
            epy = ey - ey0
            e, pn, _ = _canon((ex, ey, ez0 + sth * dphi), pn)
            ok_u = dm.vec3_isfinite(e) & _usable(pn)
            bias = (
                self.bias[0] + (k0[3] * yb0 + k1[3] * yb1) * fb,
                self.bias[1] + (k0[4] * yb0 + k1[4] * yb1) * fb,
                self.bias[2] + (k0[5] * yb0 + k1[5] * yb1) * fb,
            )
            # lp + eps x lp with eps_z = 0, in the predicted heading frame (lp_psi := its yaw)
            lp1n = (lp1[0] + epy * lp1[2], lp1[1] - epx * lp1[2], lp1[2] + (epx * lp1[1] - epy * lp1[0]))
            lp2n = (lp2[0] + epy * lp2[2], lp2[1] - epx * lp2[2], lp2[2] + (epx * lp2[1] - epy * lp2[0]))
        numeric = ok_a & (~ok_det | (~gated & ~ok_u))
        applied = ok_a & ok_det & ~gated & ok_u
        discarded = ok_a & ok_det & ~gated & ~ok_u
        flags = np.where(
            numeric, _u(Flag.NUMERIC), np.where(ok_a & ok_det & gated, _u(Flag.ACCEL_REJECTED), _U0)
        )
        lp_apply = applied & lp_on
        return (
            applied,
            discarded,
            flags,
            collapse,
            (
                e,
                bias,
                pn,
                dm.vec3_where(lp_apply, lp1n, self.lp1),
                dm.vec3_where(lp_apply, lp2n, self.lp2),
                np.where(lp_apply, ready, lp_ready),
                np.where(lp_apply, ~ready, self.converging),
            ),
        )

    def step(self, gyr: Any, acc: Any) -> NDArray[np.uint32]:
        """One update of every instance; gyr, acc (n, 3) or (3,). Returns flags (n,)."""
        g = split3(gyr, self.n)
        a = split3(acc, self.n)
        flags = sensor.check_gyro(g, self.gyro_range)
        gyro_ok = sensor.gyro_usable(g, self.gyro_range, flags)
        accel_flags, n2 = sensor.check_accel2(a, self.accel_range2)
        accel_ok = accel_flags == _U0
        flags = flags | accel_flags
        z = self._zeros
        with np.errstate(all="ignore"):
            er = dm.sqrtf(n2) / self.gravity - dm.ONE
            use_e = accel_ok & self.need_norm
            e2 = np.where(use_e, er * er, dm.ZERO).astype(np.float32)
            rejected = use_e & (self.accel_reject > dm.ZERO) & (dm.absf(er) > self.accel_reject)
            flags = flags | np.where(rejected, _u(Flag.ACCEL_REJECTED), _U0)
            waiting = ~self.initialised
            init_now = waiting & accel_ok
            t = sensor.tilt(a)
            # the first start: yaw 0; a re-initialisation after a step flagged NUMERIC: the yaw kept
            start = (dm.wrap_pi(t[0]), t[1], np.where(self.recover, self.euler[2], z).astype(np.float32))
            _, q_tilt = dm.quat_normalize_bounded(dm.quat_from_euler(start[0], start[1], z))
            lp_start = dm.quat_rotate(q_tilt, a)
            flags = flags | np.where(
                waiting, np.where(accel_ok, _u(Flag.INITIALISED), _u(Flag.NOT_READY)), _U0
            )
            run = ~waiting
            # the recovery after a clipping gyro (step 3)
            self.rec_left, _, self.rec_lp_n = recovery_step(
                g, self.clip, self.rec_n, self.rec_left, run, self.rec_lp_n
            )
            rec = run & (self.rec_left > _U0)
            flags = flags | np.where(rec, _u(Flag.INITIALISED), _U0)
            # a clipping sample: the yaw lost rotation too (the output's cov[2])
            self.head_known = self.head_known & ~(rec & (self.rec_left == self.rec_n))
            w = dm.vec3_where(gyro_ok, dm.vec3_sub(g, self.bias), (z, z, z))
            ok_p, taken_p, e_p, p_p, fl_p, trig, big_p = self._predict(w, gyro_ok, rec)
            flags = flags | np.where(run, fl_p, _U0)
            e_before = self.euler
            self.euler = dm.vec3_where(run, e_p, self.euler)
            self.p = [np.where(run, p_p[i], self.p[i]).astype(np.float32) for i in range(21)]
            restart = self._p_start()
            # an unmeasured rotation (no usable rates, or a prediction not taken): the low-pass stages
            # (estimate's heading frame) are stale
            self.lp_ready = self.lp_ready & ~(run & (~gyro_ok | ~taken_p))
            # a prediction not taken also restarts the bias (a bias run beyond any gyro's range could
            # keep every later prediction out of the wrap's range: docs/robustness.md F10): at bias_init,
            # or at zero when the prediction ran with bias_init (att_ekf_out_of_range)
            b, bi = self.bias, self.bias_init
            from_init = (b[0] == bi[0]) & (b[1] == bi[1]) & (b[2] == bi[2])
            self.bias = dm.vec3_where(run & ~taken_p, dm.vec3_where(from_init, (z, z, z), bi), self.bias)
            measure = run & accel_ok & ~rejected & taken_p  # no update after a prediction not taken
            # the stages' running mean (att_ekf_lowpass): in a recovery, and after the start until it falls
            # below k_lp / 4 or the stages restart (not ready: they start from a sample or the estimate)
            mean = rec | (self.lp_mean & self.lp_ready)
            k_mean, lp_n1, k_mean2 = recovery_lp_gain2(self.rec_lp_n, self.k_lp)
            k_lp = np.where(mean, k_mean, self.k_lp).astype(np.float32)
            k_lp2 = np.where(mean, k_mean2, self.k_lp).astype(np.float32)
            applied, discarded, fl_u, collapse_u, (e_u, b_u, p_u, lp1_u, lp2_u, rdy_u, cv_u) = self._update(
                a, e2, self.lp_ready, trig, rec, k_lp, k_lp2
            )
            # the low-pass count of the mean: up by one where the update ran the stages
            lp_ran = measure & (self.k_lp > dm.ZERO)
            self.rec_lp_n = np.where(lp_ran & mean, lp_n1, self.rec_lp_n).astype(np.uint32)
            keep_mean = self.lp_mean & self.lp_ready & (k_mean2 > self.k_lp) & (lp_n1 < MEAN_N_MAX)
            self.lp_mean = np.where(lp_ran, keep_mean, self.lp_mean)
            flags = flags | np.where(measure, fl_u, _U0)
            take_u = measure & applied
            # updated in place, then not usable: P restarted; a step without an applied update tests
            # the prediction (att_ekf_check)
            drop_u = (measure & discarded) | (run & ~(measure & (applied | discarded)) & ~ok_p)
            flags = flags | np.where(drop_u, _u(Flag.NUMERIC), _U0)
            self.euler = dm.vec3_where(take_u, e_u, self.euler)
            self.bias = dm.vec3_where(take_u, b_u, self.bias)
            self.p = [
                np.where(take_u, p_u[i], np.where(drop_u, restart[i], self.p[i])).astype(np.float32)
                for i in range(21)
            ]
            self.lp1 = dm.vec3_where(take_u, lp1_u, self.lp1)
            self.lp2 = dm.vec3_where(take_u, lp2_u, self.lp2)
            self.lp_psi = np.where(take_u & self.lp_on, e_p[2], self.lp_psi).astype(np.float32)
            # NUMERIC: the attitude from before the step (P restarted if it was unusable); the next usable
            # accel sample re-initialises roll and pitch (not ready until then)
            numeric = run & ((flags & _u(Flag.NUMERIC)) != _U0)
            self.euler = dm.vec3_where(numeric, e_before, self.euler)
            self.lp_ready = np.where(take_u, rdy_u, self.lp_ready)
            self.converging = np.where(take_u, cv_u, self.converging)
            gimbal = (flags & _u(Flag.GIMBAL)) != _U0
            # conditioned now: after an applied update whose prior (the predicted P) has a near singular
            # roll/pitch block (F12), and at every step without an applied update whose P is usable
            # (att_ekf_check, F15); not after a restart
            now = ~drop_u & (~take_u | _near_singular(p_p) | collapse_u)
            # and at every step of a recovery (F17: its process noise moves P fast)
            cond = run & (((self.steps & COND_MASK) == _U0) | gimbal | big_p | now | rec)
            r2 = self.gyro_range * self.gyro_range
            rb = np.where(r2 > self.p0_bias, r2, self.p0_bias)
            p_c, changed = _condition(self.p, self.p_max, np.where(rb < self.p_max, rb, self.p_max))
            self.p = [np.where(cond, p_c[i], self.p[i]).astype(np.float32) for i in range(21)]
            flags = flags | np.where(cond & changed, _u(Flag.CLAMPED), _U0)
            # with the conditioning, the bias limited to +-gyro_range (att_ekf_bias_limit; NaN: bias_init)
            rg = self.gyro_range
            b = self.bias
            inside = ((dm.absf(b[0]) + dm.absf(b[1])) + dm.absf(b[2])) <= rg
            lim = (dm.clampf(b[0], -rg, rg), dm.clampf(b[1], -rg, rg), dm.clampf(b[2], -rg, rg))
            lim = dm.vec3_where(dm.isfinitef((lim[0] + lim[1]) + lim[2]), lim, self.bias_init)
            moved = (lim[0] != b[0]) | (lim[1] != b[1]) | (lim[2] != b[2])
            limit = cond & ~inside
            self.bias = dm.vec3_where(limit, lim, b)
            flags = flags | np.where(limit & moved, _u(Flag.CLAMPED), _U0)
            # a re-initialisation also restarts P (att_ekf_start)
            reinit = init_now & self.recover
            self.p = [np.where(reinit, restart[i], self.p[i]).astype(np.float32) for i in range(21)]
            self.euler = dm.vec3_where(init_now, start, self.euler)
            self.lp1 = dm.vec3_where(init_now, lp_start, self.lp1)
            self.lp2 = dm.vec3_where(init_now, lp_start, self.lp2)
            self.lp_psi = np.where(init_now, start[2], self.lp_psi).astype(np.float32)
            self.lp_ready = self.lp_ready | init_now
            self.converging = self.converging & ~init_now
            # the stages take the running mean of the samples since the start (att_ekf_start)
            self.lp_mean = np.where(init_now, self.k_lp > dm.ZERO, self.lp_mean)
            self.rec_lp_n = np.where(init_now, np.uint32(1), self.rec_lp_n).astype(np.uint32)
        self.recover = (self.recover & ~init_now) | numeric
        self.initialised = (self.initialised | init_now) & ~numeric
        self.head_known = self.head_known & ~numeric  # the rotation of the restart is lost (cov[2])
        self.steps = self.steps + np.uint32(1)
        self.flags = flags.astype(np.uint32)
        return self.flags

    def retune(self, settings: EkfSettings) -> None:
        """att_ekf_retune: new settings (coefficients), the state kept."""
        new = Ekf(settings, self.n)
        carry_state(self, new)
        new.rec_left = np.minimum(new.rec_left, new.rec_n).astype(np.uint32)
        self.__dict__.update(new.__dict__)

    @property
    def quat(self) -> NDArray[np.float32]:
        """Attitudes (n, 4) from the angles (att_quat_from_euler)."""
        return stack(dm.quat_from_euler(*self.euler))

    @property
    def gyro_bias(self) -> NDArray[np.float32]:
        """Gyro bias estimates (n, 3), rad/s, sensor frame."""
        return stack(self.bias)

    @property
    def covariance(self) -> NDArray[np.float32]:
        """The packed upper triangles of P (n, 21)."""
        return stack(tuple(self.p))

    def heading_set(self) -> None:
        """att_ekf_yaw_to with gain 1: yaw's variance restarts at one step's noise; the output reports it."""
        self.p[11] = np.broadcast_to(self.q_step[2], (self.n,)).astype(np.float32)
        self.head_known = np.ones(self.n, np.bool_)

    def output_cov(self) -> tuple[Any, Any, Any, Any]:
        """The output record's ``cov`` (att_filter_output): phi, theta, psi, then the mean bias variance.

        Yaw, which nothing observes, is pi^2/3 (unknown) but from a set heading to the next clipping
        gyro sample, where it is p[11] (at most pi^2/3).
        """
        p = self.p
        yaw = np.where(self.head_known & (p[11] < COV_UNKNOWN), p[11], COV_UNKNOWN).astype(np.float32)
        return (p[0], p[6], yaw, ((p[15] + p[18]) + p[20]) * THIRD)

    def run(self, gyr: Any, acc: Any) -> tuple[NDArray[np.float32], NDArray[np.uint32]]:
        """Step through N samples: gyr, acc (N, 3) for n == 1 or (N, n, 3)."""
        return run_steps(self, gyr, acc)
