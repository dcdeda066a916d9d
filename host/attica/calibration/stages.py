"""The firmware's view of a calibration: ``att_calib_settings_t`` field by field, in float32.

:class:`StageSettings` is what the C input/output stages (firmware/src/calib/att_calib.c) and their numpy
mirror (:mod:`attica.reference.calib`) are given; :func:`from_calibration` makes it from a
:class:`~attica.calibration.model.Calibration` (a calibration file), :func:`fill_c` copies it into a
cffi ``att_calib_settings_t``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from attica.calibration.model import CONVENTIONS, REMAPS, Calibration

REMAP_NAMES: tuple[str, ...] = (
    "+x+y+z", "+x-y-z", "-x+y-z", "-x-y+z", "+x+z-y", "+x-z+y", "-x+z+y", "-x-z-y",
    "+y+x-z", "+y-x+z", "-y+x+z", "-y-x-z", "+y+z+x", "+y-z-x", "-y+z-x", "-y-z+x",
    "+z+x+y", "+z-x-y", "-z+x-y", "-z-x+y", "+z+y-x", "+z-y+x", "-z+y+x", "-z-y-x",
)  # fmt: skip
"""The firmware's remap numbers: ``REMAP_NAMES[r - 1]`` is remap r (att_calib_remap_name)."""

CONVENTION_CODES = {name: i for i, name in enumerate(CONVENTIONS)}
"""``att_convention_t`` of each convention name (enu 0, ned 1, nwu 2)."""

GRAVITY = 9.80665
"""Default g of the acceleration outputs, m/s^2."""

_EYE9 = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
_ONES = (1.0, 1.0, 1.0)
_ZERO = (0.0, 0.0, 0.0)

if set(REMAP_NAMES) != set(REMAPS):  # pragma: no cover - a contract between two tables
    raise RuntimeError("REMAP_NAMES and calibration.model.REMAPS disagree")


def _f32s(values: Any, count: int) -> tuple[float, ...]:
    a = np.asarray(values, np.float32).reshape(-1)
    if a.size != count:
        raise ValueError(f"expected {count} values, got {a.size}")
    return tuple(float(v) for v in a)


@dataclass(frozen=True)
class StageSettings:
    """``att_calib_settings_t``: every value a float32 (as Python floats), matrices row-major."""

    gyro_misalignment: tuple[float, ...] = _EYE9
    gyro_sensitivity: tuple[float, ...] = _ONES
    gyro_offset: tuple[float, ...] = _ZERO
    accel_misalignment: tuple[float, ...] = _EYE9
    accel_sensitivity: tuple[float, ...] = _ONES
    accel_offset: tuple[float, ...] = _ZERO
    soft_iron: tuple[float, ...] = _EYE9
    hard_iron: tuple[float, ...] = _ZERO
    remap: int = 0
    mounting: tuple[float, ...] = (1.0, 0.0, 0.0, 0.0)
    convention: int = 0
    gravity: float = float(np.float32(GRAVITY))
    accel_outputs: bool = False

    def __post_init__(self) -> None:
        for name, count in (
            ("gyro_misalignment", 9),
            ("gyro_sensitivity", 3),
            ("gyro_offset", 3),
            ("accel_misalignment", 9),
            ("accel_sensitivity", 3),
            ("accel_offset", 3),
            ("soft_iron", 9),
            ("hard_iron", 3),
            ("mounting", 4),
        ):
            object.__setattr__(self, name, _f32s(getattr(self, name), count))
        object.__setattr__(self, "gravity", float(np.float32(self.gravity)))

    @property
    def remap_name(self) -> str | None:
        """The remap's name, None when the mounting is the quaternion."""
        return REMAP_NAMES[self.remap - 1] if 1 <= self.remap <= len(REMAP_NAMES) else None


def _flat(m: Any) -> tuple[float, ...]:
    return tuple(float(v) for row in m for v in row)


def from_calibration(
    cal: Calibration | None, gravity: float = GRAVITY, accel_outputs: bool = False
) -> StageSettings:
    """The firmware settings of a calibration (None: identity, ENU) with the acceleration outputs' g."""
    if cal is None:
        return StageSettings(gravity=gravity, accel_outputs=accel_outputs)
    m = cal.mounting
    return StageSettings(
        gyro_misalignment=_flat(cal.gyro.misalignment),
        gyro_sensitivity=cal.gyro.sensitivity,
        gyro_offset=cal.gyro.offset,
        accel_misalignment=_flat(cal.accel.misalignment),
        accel_sensitivity=cal.accel.sensitivity,
        accel_offset=cal.accel.offset,
        soft_iron=_flat(cal.mag.soft_iron),
        hard_iron=cal.mag.hard_iron,
        remap=REMAP_NAMES.index(m.remap) + 1 if m.remap is not None else 0,
        mounting=m.quaternion if m.quaternion is not None else (1.0, 0.0, 0.0, 0.0),
        convention=CONVENTION_CODES[cal.convention],
        gravity=gravity,
        accel_outputs=accel_outputs,
    )


def fill_c(struct: Any, s: StageSettings) -> None:
    """Copy s into a cffi ``att_calib_settings_t`` (``struct`` is the pointed-to struct or pointer)."""

    def vec(dst: Any, v: tuple[float, ...]) -> None:
        dst.x, dst.y, dst.z = v

    for i in range(9):
        struct.gyro.misalignment[i] = s.gyro_misalignment[i]
        struct.accel.misalignment[i] = s.accel_misalignment[i]
        struct.mag.soft_iron[i] = s.soft_iron[i]
    vec(struct.gyro.sensitivity, s.gyro_sensitivity)
    vec(struct.gyro.offset, s.gyro_offset)
    vec(struct.accel.sensitivity, s.accel_sensitivity)
    vec(struct.accel.offset, s.accel_offset)
    vec(struct.mag.hard_iron, s.hard_iron)
    struct.remap = s.remap
    struct.mounting.w, struct.mounting.x, struct.mounting.y, struct.mounting.z = s.mounting
    struct.convention = s.convention
    struct.gravity = s.gravity
    struct.accel_outputs = bool(s.accel_outputs)


def fields(s: StageSettings) -> list[float]:
    """The settings as the 50 floats of att_calib_field_get (the CAN CAL_SET and persisted order)."""
    out: list[float] = [*s.gyro_misalignment, *s.gyro_sensitivity, *s.gyro_offset]
    out += [*s.accel_misalignment, *s.accel_sensitivity, *s.accel_offset]
    out += [*s.soft_iron, *s.hard_iron, *s.mounting]
    out += [float(s.remap), float(s.convention), s.gravity, 1.0 if s.accel_outputs else 0.0]
    return out
