"""Mirror of firmware/src/filters/tilt/att_tilt.c: accel-only tilt, instances in lockstep."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.reference import detmath as dm
from attica.reference import sensor
from attica.reference._common import StateSpec, carry_state, setting, split3, stack
from attica.settings import Flag, TiltSettings

_U0 = np.uint32(0)


class Tilt:
    """Accel-only tilt reference; ``n`` instances sharing one settings object."""

    STATE: StateSpec = {
        "st.euler": "vec3",
        "st.q": "quat",
        "st.valid": "bool",
        "st.steps": "u32",
        "st.flags": "u32",
    }
    """C state fields mirrored by this class (see reference._common.load_c_state)."""
    EARTH: tuple[str, ...] = ()
    """Earth-frame state vectors, turned with the attitude by a heading change (reference.calib.yaw_to)."""
    COEFFS: StateSpec = {
        "c.gravity": "f32",
        "c.accel_range": "f32",
        "c.normalise": "bool",
    }
    """Every C coefficient of att_tilt_coeffs_t (set by att_tilt_init / retune), derived here alike
    from the settings; state_matches compares them after the state."""

    def __init__(self, settings: TiltSettings | None = None, n: int = 1) -> None:
        s = settings if settings is not None else TiltSettings()
        self.settings = s
        self.n = n
        self.gravity = setting(s.gravity, n)
        self.accel_range = setting(s.accel_range, n)
        self.normalise = setting(s.normalise, n, np.bool_)
        self.reset()

    def reset(self) -> None:
        """att_tilt_reset."""
        z = np.zeros(self.n, np.float32)
        self.euler: dm.Vec3 = (z, z.copy(), z.copy())
        self.q = dm.quat_identity((self.n,))
        self.valid = np.zeros(self.n, np.bool_)
        self.steps = np.zeros(self.n, np.uint32)
        self.flags = np.zeros(self.n, np.uint32)

    def step(self, acc: Any) -> NDArray[np.uint32]:
        """One update with accel (n, 3) or (3,), m/s^2. Returns flags (n,)."""
        a = split3(acc, self.n)
        flags, norm = sensor.check_accel(a, self.accel_range)
        ok = flags == _U0
        with np.errstate(all="ignore"):
            s = -a[0] / np.where(self.normalise, norm, self.gravity)
            clamp = dm.absf(s) > dm.ONE
            s = np.where(clamp, np.where(s < dm.ZERO, -dm.ONE, dm.ONE), s)
            flags = flags | np.where(ok & clamp, np.uint32(Flag.CLAMPED), _U0)
            phi = dm.atan2f(a[1], a[2])
            theta = dm.asinf(s)
            zero = np.zeros(self.n, np.float32)
            self.euler = dm.vec3_where(ok, (phi, theta, zero), self.euler)
            self.q = dm.quat_where(ok, dm.quat_from_euler(phi, theta, zero), self.q)
        flags = flags | np.where(~ok & ~self.valid, np.uint32(Flag.NOT_READY), _U0)
        self.valid = self.valid | ok
        self.steps = self.steps + np.uint32(1)
        self.flags = flags.astype(np.uint32)
        return self.flags

    def retune(self, settings: TiltSettings) -> None:
        """att_tilt_retune: new settings (coefficients), the state kept."""
        new = Tilt(settings, self.n)
        carry_state(self, new)
        self.__dict__.update(new.__dict__)

    @property
    def quat(self) -> NDArray[np.float32]:
        """Attitudes (n, 4)."""
        return stack(self.q)
