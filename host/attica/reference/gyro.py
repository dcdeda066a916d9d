"""Mirror of firmware/src/filters/gyro/att_gyro.c: gyro-only ZYX Euler-rate integration, in lockstep."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.reference import detmath as dm
from attica.reference import sensor
from attica.reference._common import StateSpec, carry_state, setting, split3, stack
from attica.settings import Flag, GyroSettings

_U0 = np.uint32(0)
_PI = dm.c("0x1.921fb6p+1")
_PIO2 = dm.c("0x1.921fb6p+0")


def rotated_euler(q0: dm.Quat, w: dm.Vec3, dt: Any) -> tuple[Any, dm.Vec3]:
    """gyro_rotate of att_gyro.c (D1): the attitude q0 turned by the body rotation vector w dt.

    The turn as a quaternion, then consistent ZYX Euler angles of it, accurate also at pitch +-pi/2.
    Returns (ok, (phi, theta, psi)).
    """
    ok, qu = dm.quat_normalize_bounded(dm.quat_mul(q0, dm.quat_from_rotvec(dm.vec3_scale(w, dt))))
    m = dm.quat_to_matrix(qu)
    psi = dm.atan2f(m[3], m[0])
    sps = dm.sinf(psi)
    cps = dm.cosf(psi)
    theta = dm.atan2f(-m[6], cps * m[0] + sps * m[3])
    phi = dm.atan2f(sps * m[2] - cps * m[5], cps * m[4] - sps * m[1])
    theta = dm.clampf(theta, -_PIO2, _PIO2)
    return ok, (dm.wrap_pi(phi), theta, dm.wrap_pi(psi))


class Gyro:
    """Gyro-only baseline reference; ``n`` instances sharing one settings object."""

    STATE: StateSpec = {"st.euler": "vec3", "st.q": "quat", "st.steps": "u32", "st.flags": "u32"}
    """C state fields mirrored by this class (see reference._common.load_c_state)."""
    EARTH: tuple[str, ...] = ()
    """Earth-frame state vectors, turned with the attitude by a heading change (reference.calib.yaw_to)."""
    COEFFS: StateSpec = {
        "c.dt": "f32",
        "c.gyro_range": "f32",
        "c.cos_min": "f32",
        "c.euler_init": "vec3",
    }
    """Every C coefficient of att_gyro_coeffs_t (set by att_gyro_init / retune), derived here alike
    from the settings; state_matches compares them after the state."""

    def __init__(self, settings: GyroSettings | None = None, n: int = 1) -> None:
        s = settings if settings is not None else GyroSettings()
        self.settings = s
        self.n = n
        self.dt = setting(s.dt, n)
        self.gyro_range = setting(s.gyro_range, n)
        self.cos_min = setting(s.cos_min, n)
        self.euler_init = split3(s.euler_init, n)
        self.reset()

    def reset(self) -> None:
        """att_gyro_reset."""
        e0 = self.euler_init
        self.euler: dm.Vec3 = (dm.wrap_pi(e0[0]), e0[1].copy(), dm.wrap_pi(e0[2]))
        self.q = dm.quat_from_euler(*self.euler)
        self.steps = np.zeros(self.n, np.uint32)
        self.flags = np.zeros(self.n, np.uint32)

    def step(self, gyr: Any) -> NDArray[np.uint32]:
        """One update with gyro (n, 3) or (3,), rad/s. Returns flags (n,)."""
        p, q, r = split3(gyr, self.n)
        flags = sensor.check_gyro((p, q, r), self.gyro_range)
        ok = sensor.gyro_usable((p, q, r), self.gyro_range, flags)
        phi, theta, psi = self.euler
        dt = self.dt
        with np.errstate(all="ignore"):
            sphi = dm.sinf(phi)
            cphi = dm.cosf(phi)
            sth = dm.sinf(theta)
            cth = dm.cosf(theta)
            gimbal = dm.absf(cth) < self.cos_min
            cth = np.where(gimbal, np.where(cth < dm.ZERO, -self.cos_min, self.cos_min), cth)
            flags = flags | np.where(ok & gimbal, np.uint32(Flag.GIMBAL), _U0)
            tth = sth / cth
            ex = phi + (p + sphi * tth * q + cphi * tth * r) * dt
            ey = theta + (cphi * q - sphi * r) * dt
            ez = psi + (sphi / cth * q + cphi / cth * r) * dt
            ey = dm.wrap_pi(ey)
            over = ey > _PIO2
            under = ey < -_PIO2
            flip = over | under
            ey = np.where(over, _PI - ey, np.where(under, -_PI - ey, ey))
            ex = np.where(flip, ex + _PI, ex)
            ez = np.where(flip, ez + _PI, ez)
            ex = dm.wrap_pi(ex)
            ez = dm.wrap_pi(ez)
            e = (ex, ey, ez)
            finite = dm.vec3_isfinite(e)
            # D1: an Euler step that is not representable turns the quaternion instead (GIMBAL)
            rot = ok & ~finite
            r_ok, er = rotated_euler(self.q, (p, q, r), dt)
            r_ok = r_ok & dm.vec3_isfinite(er)
            e = dm.vec3_where(finite, e, er)
            flags = flags | np.where(rot & r_ok, np.uint32(Flag.GIMBAL), _U0)
            flags = flags | np.where(rot & ~r_ok, np.uint32(Flag.NUMERIC), _U0)
            take = ok & (finite | r_ok)
            ex, ey, ez = e
            self.euler = dm.vec3_where(take, e, self.euler)
            self.q = dm.quat_where(take, dm.quat_from_euler(ex, ey, ez), self.q)
        self.steps = self.steps + np.uint32(1)
        self.flags = flags.astype(np.uint32)
        return self.flags

    def retune(self, settings: GyroSettings) -> None:
        """att_gyro_retune: new settings (coefficients), the state kept."""
        new = Gyro(settings, self.n)
        carry_state(self, new)
        self.__dict__.update(new.__dict__)

    @property
    def quat(self) -> NDArray[np.float32]:
        """Attitudes (n, 4)."""
        return stack(self.q)
