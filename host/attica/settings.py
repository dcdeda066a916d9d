"""Filter settings shared by the C binding (:mod:`attica.native`) and the reference.

Each dataclass mirrors a C settings struct field by field (same names, same units). Defaults equal
the C ``att_*_settings_default`` functions; ``tests/test_settings.py`` checks that.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field, fields
from typing import Any


class Flag(enum.IntFlag):
    """Per-step status flags (``ATT_FLAG_*`` in att_types.h)."""

    GYRO_INVALID = 0x0001
    GYRO_RANGE = 0x0002
    ACCEL_INVALID = 0x0004
    ACCEL_RANGE = 0x0008
    ACCEL_REJECTED = 0x0010
    MAG_INVALID = 0x0020
    MAG_ABSENT = 0x0040
    MAG_REJECTED = 0x0080
    AT_REST = 0x0100
    BIAS_UPDATED = 0x0200
    INITIALISED = 0x0400
    GIMBAL = 0x0800
    CLAMPED = 0x1000
    NUMERIC = 0x2000
    NOT_READY = 0x4000
    BAD_ARG = 0x8000


def describe_flags(value: int) -> str:
    """Human-readable ``A|B`` names of a flags word (``-`` for none)."""
    names = [f.name for f in Flag if f.name is not None and value & f.value]
    return "|".join(names) if names else "-"


class BiasMode(enum.IntEnum):
    """``att_bias_mode_t``."""

    OFF = 0
    FROZEN = 1
    RUNNING = 2
    AT_REST = 3


class Integration(enum.IntEnum):
    """``att_integration_t``."""

    ROTVEC = 0
    EULER = 1


@dataclass
class ArsSettings:
    """Complementary ARS settings (``att_ars_settings_t``); see att_ars.h for meanings."""

    dt: float = 0.01
    gain: float = 0.1
    tau: float = 0.0
    gain_c: float = 100.0
    gravity: float = 9.80665
    accel_reject: float = 0.0
    accel_range: float = 156.9064
    gyro_range: float = 34.906586
    bias_mode: BiasMode = BiasMode.AT_REST
    bias_n_max: int = 1000
    bias_init: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rest_gyro: float = 0.05
    rest_accel: float = 0.5
    rest_time: float = 0.5
    integration: Integration = Integration.ROTVEC
    init_from_accel: bool = True
    q_init: tuple[float, float, float, float] = field(default=(1.0, 0.0, 0.0, 0.0))


@dataclass
class GyroSettings:
    """Gyro-only Euler-rate integration baseline (``att_gyro_settings_t``); see att_gyro.h."""

    dt: float = 0.01
    gyro_range: float = 34.906586
    cos_min: float = 0.001
    euler_init: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass
class TiltSettings:
    """Accel-only tilt baseline (``att_tilt_settings_t``); see att_tilt.h."""

    gravity: float = 9.80665
    accel_range: float = 156.9064
    normalise: bool = True


def to_dict(settings: Any) -> dict[str, Any]:
    """Field name to value of a settings dataclass."""
    return {f.name: getattr(settings, f.name) for f in fields(settings)}
