"""Filter settings shared by the C binding (:mod:`attica.native`) and the reference.

Each dataclass mirrors a C settings struct field by field (same names, same units). Defaults equal
the C ``att_*_settings_default`` functions; ``tests/test_settings.py`` checks that. The dataclasses are
frozen: change settings with :func:`dataclasses.replace`, :func:`make_settings` or a filter's ``retune``.
"""

from __future__ import annotations

import enum
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, fields, replace
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


OUTPUT_INVALID = int(Flag.NOT_READY | Flag.BAD_ARG)
"""``ATT_FLAGS_OUTPUT_INVALID``: with one of these flags q is not an attitude estimate (att_filter.h)."""


def flag_names(value: int) -> list[str]:
    """Names of the flags set in a flags word, in bit order (``[]`` for none)."""
    return [f.name for f in Flag if f.name is not None and int(value) & f.value]


def describe_flags(value: int) -> str:
    """Human-readable ``A|B`` names of a flags word (``-`` for none)."""
    names = flag_names(value)
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
    FIRST_ORDER = 2


@dataclass(frozen=True)
class ArsSettings:
    """Complementary ARS settings (``att_ars_settings_t``); see att_ars.h for meanings."""

    dt: float = 0.01
    gain: float = 1.0
    tau: float = 0.0
    gain_c: float = 0.0
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
    tau_acc_lp: float = 1.5
    recovery_time: float = 2.0
    gyro_noise: float = 0.002
    accel_noise: float = 0.24


@dataclass(frozen=True)
class GyroSettings:
    """Gyro-only Euler-rate integration baseline (``att_gyro_settings_t``); see att_gyro.h."""

    dt: float = 0.01
    gyro_range: float = 34.906586
    cos_min: float = 0.001
    euler_init: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class TiltSettings:
    """Accel-only tilt baseline (``att_tilt_settings_t``); see att_tilt.h."""

    gravity: float = 9.80665
    accel_range: float = 156.9064
    normalise: bool = True


def to_dict(settings: Any) -> dict[str, Any]:
    """Field name to value of a settings dataclass."""
    return {f.name: getattr(settings, f.name) for f in fields(settings)}


@dataclass(frozen=True)
class KfSettings:
    """Linear quaternion KF settings (``att_kf_settings_t``); see att_kf.h for meanings."""

    dt: float = 0.01
    q_noise: float = 1e-3
    r_noise: float = 1e-5
    r_accel: float = 0.0
    gate: float = 0.0
    p0: float = 1.0
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
    tau_acc_lp: float = 1.5
    recovery_time: float = 2.0
    init_from_accel: bool = True
    q_init: tuple[float, float, float, float] = field(default=(1.0, 0.0, 0.0, 0.0))
    noise_rates: bool = True


class MagMode(enum.IntEnum):
    """``att_mars_mag_mode_t``."""

    HORIZONTAL = 0
    FULL = 1


@dataclass(frozen=True)
class MarsSettings:
    """9-axis complementary filter settings (``att_mars_settings_t``); see att_mars.h for meanings."""

    dt: float = 0.01
    alpha_acc: float = 1.0
    alpha_mag: float = 0.0
    tau_acc: float = 0.0
    tau_mag: float = 20.0
    mag_mode: MagMode = MagMode.HORIZONTAL
    gravity: float = 9.80665
    accel_reject: float = 0.0
    accel_range: float = 156.9064
    gyro_range: float = 34.906586
    mag_range: float = 1000.0
    mag_norm_reject: float = 0.2
    mag_dip_reject: float = 0.3
    bias_init: tuple[float, float, float] = (0.0, 0.0, 0.0)
    init_from_sensors: bool = True
    q_init: tuple[float, float, float, float] = field(default=(1.0, 0.0, 0.0, 0.0))
    m0_init: tuple[float, float, float] = (0.0, 0.0, 0.0)
    integration: Integration = Integration.ROTVEC
    tau_acc_lp: float = 1.3
    bias_mode: BiasMode = BiasMode.AT_REST
    bias_n_max: int = 1000
    rest_gyro: float = 0.05
    rest_accel: float = 0.5
    rest_time: float = 0.5
    mag_ref_tau: float = 20.0
    mag_new_time: float = 20.0
    tau_mag_fast: float = 2.0
    tau_bias_mag: float = 0.0
    recovery_time: float = 2.0
    declination: float = 0.0
    gyro_noise: float = 0.002
    accel_noise: float = 0.24
    mag_noise: float = 3.5
    hard_iron_tau: float = 0.0
    hard_iron_rate: float = 1.0


@dataclass(frozen=True)
class EkfSettings:
    """Euler-angle EKF with gyro bias states (``att_ekf_settings_t``); see att_ekf.h for meanings."""

    dt: float = 0.01
    q_phi: float = 1e-3
    q_theta: float = 1e-3
    q_psi: float = 1e-3
    q_bias: float = 1e-8
    r_phi: float = 1e-4
    r_theta: float = 1e-4
    r_accel: float = 0.0
    gate: float = 0.0
    p0: float = 1.0
    p0_bias: float = 1e-4
    p_max: float = 1000000.0
    gravity: float = 9.80665
    accel_reject: float = 0.0
    accel_range: float = 156.9064
    gyro_range: float = 34.906586
    cos_min: float = 0.001
    tau_acc_lp: float = 1.5
    init_from_accel: bool = True
    euler_init: tuple[float, float, float] = (0.0, 0.0, 0.0)
    bias_init: tuple[float, float, float] = (0.0, 0.0, 0.0)
    noise_rates: bool = True
    recovery_time: float = 2.0


@dataclass(frozen=True)
class MekfSettings:
    """Multiplicative EKF settings (``att_mekf_settings_t``); see att_mekf.h for meanings."""

    dt: float = 0.01
    gyro_noise: float = 1e-4
    gyro_rate_noise: float = 0.01
    bias_noise: float = 1e-4
    accel_noise: float = 0.003
    r_accel: float = 0.0
    gate: float = 16.0
    gate_recover: float = 2.0
    mag_noise: float = 0.6
    mag_gate: float = 0.0
    p0_att: float = 0.01
    p0_bias: float = 1e-4
    p_max: float = 10.0
    gravity: float = 9.80665
    accel_reject: float = 0.0
    accel_range: float = 156.9064
    gyro_range: float = 34.906586
    mag_range: float = 1000.0
    mag_norm_reject: float = 0.2
    mag_dip_reject: float = 0.5
    tau_acc_lp: float = 1.45
    tau_acc_lp_no_rest: float = 1.25
    rest_noise: float = 1e-4
    rest_gyro: float = 0.05
    rest_accel: float = 0.5
    rest_time: float = 0.5
    gyro_scale_sd: float = 0.003
    gyro_scale_init: float = 0.0
    recovery_time: float = 2.0
    declination: float = 0.0
    mag_ref_tau: float = 20.0
    mag_new_time: float = 20.0
    hard_iron_tau: float = 0.0
    hard_iron_rate: float = 1.0
    use_mag: bool = True
    init_from_sensors: bool = True
    q_init: tuple[float, float, float, float] = field(default=(1.0, 0.0, 0.0, 0.0))
    m0_init: tuple[float, float, float] = (0.0, 0.0, 0.0)
    bias_init: tuple[float, float, float] = (0.0, 0.0, 0.0)


class FilterKind(enum.IntEnum):
    """``att_filter_kind_t`` (values are part of the CAN contract); what each kind is: :mod:`attica.kinds`."""

    ARS = 1
    MARS = 2
    KF = 3
    EKF = 4
    GYRO = 5
    TILT = 6
    MEKF = 7

    @property
    def label(self) -> str:
        """Lower-case name used on the command line (``ars``, ``kf`` ...)."""
        return self.name.lower()

    @classmethod
    def parse(cls, value: str | int | FilterKind) -> FilterKind:
        """A kind from its name (any case) or number; ValueError listing the choices otherwise."""
        if isinstance(value, FilterKind):
            return value
        if isinstance(value, int):
            return cls(value)
        try:
            return cls[value.upper()]
        except KeyError:
            choices = ", ".join(k.label for k in cls)
            raise ValueError(f"unknown filter {value!r}; choose one of: {choices}") from None


class _SettingsClasses(Mapping[FilterKind, type[Any]]):
    """Read-only view of the registry (:mod:`attica.kinds`): kind -> settings dataclass.

    The registry imports this module (for the dataclasses), so it is read on use, not at import.
    """

    def __getitem__(self, kind: FilterKind) -> type[Any]:
        from attica.kinds import info

        try:
            return info(kind).settings_class
        except ValueError:
            raise KeyError(kind) from None

    def __iter__(self) -> Iterator[FilterKind]:
        from attica.kinds import KINDS

        return iter([k.kind for k in KINDS])

    def __len__(self) -> int:
        from attica.kinds import KINDS

        return len(KINDS)

    def __repr__(self) -> str:
        return repr(dict(self))


SETTINGS_CLASS: Mapping[FilterKind, type[Any]] = _SettingsClasses()
"""Settings dataclass of each implemented kind (a view of :data:`attica.kinds.KINDS`)."""


def implemented_kinds() -> list[FilterKind]:
    """The kinds with a C and reference implementation, in kind order (:data:`attica.kinds.KINDS`)."""
    from attica.kinds import KINDS

    return [k.kind for k in KINDS]


class Preset(enum.IntEnum):
    """``att_preset_t``: named settings sets (see :data:`SEED_OVERRIDES`)."""

    DEFAULT = 0
    SEED = 1

    @property
    def label(self) -> str:
        """Lower-case name (``default``, ``seed``)."""
        return self.name.lower()

    @classmethod
    def parse(cls, value: str | int | Preset) -> Preset:
        """A preset from its name (any case) or number; ValueError listing the choices otherwise."""
        if isinstance(value, Preset):
            return value
        if isinstance(value, int):
            return cls(value)
        try:
            return cls[value.upper()]
        except KeyError:
            choices = ", ".join(p.label for p in cls)
            raise ValueError(f"unknown preset {value!r}; choose one of: {choices}") from None


SEED_OVERRIDES: dict[FilterKind, dict[str, Any]] = {
    FilterKind.ARS: {"gain": 0.1, "tau": 0.0, "gain_c": 100.0, "tau_acc_lp": 0.0, "recovery_time": 0.0},
    FilterKind.MARS: {
        "alpha_acc": 0.02,
        "alpha_mag": 0.01,
        "tau_acc": 0.0,
        "tau_mag": 0.0,
        "accel_reject": 0.1,
        "mag_norm_reject": 0.2,
        "mag_dip_reject": 0.17,
        "integration": Integration.FIRST_ORDER,
        "tau_acc_lp": 0.0,
        "bias_mode": BiasMode.FROZEN,
        "mag_ref_tau": 0.0,
        "mag_new_time": 0.0,
        "tau_mag_fast": 0.0,
        "tau_bias_mag": 0.0,
        "recovery_time": 0.0,
    },
    FilterKind.KF: {
        "q_noise": 1e-4,
        "r_noise": 10.0,
        "r_accel": 0.0,
        "gate": 0.0,
        "accel_reject": 0.1,
        "noise_rates": False,
        "tau_acc_lp": 0.0,
        "bias_mode": BiasMode.OFF,
        "recovery_time": 0.0,
    },
    FilterKind.EKF: {
        "q_phi": 0.0001,
        "q_theta": 0.0001,
        "q_psi": 0.1,
        "q_bias": 1e-12,
        "p0_bias": 1e-12,
        "r_phi": 6.0,
        "r_theta": 6.0,
        "r_accel": 0.0,
        "gate": 0.0,
        "accel_reject": 0.1,
        "tau_acc_lp": 0.0,
        "noise_rates": False,
        "recovery_time": 0.0,
    },
    FilterKind.GYRO: {},
    FilterKind.TILT: {},
    FilterKind.MEKF: {},
}
"""The seed preset: the literal settings each filter had before it was tuned on BROAD (per-sample gains,
per-step noises; no accel low-pass, no bias estimation in MARS); the MEKF has none (its seed = its
defaults). The C twin is ``att_filter_settings_preset(kind, ATT_PRESET_SEED, dt, &s)``. Every kind has an
entry (tests/test_kinds.py checks it)."""


def preset_settings(
    kind: FilterKind, preset: str | int | Preset = Preset.DEFAULT, dt: float | None = None
) -> Any:
    """Settings of a named preset for ``kind`` (``default`` or ``seed``), with ``dt`` when given."""
    p = Preset.parse(preset)
    base = make_settings(kind, dt=dt)
    if p == Preset.SEED:
        return replace(base, **SEED_OVERRIDES[kind])
    return base


def presets(kind: FilterKind, dt: float | None = None) -> dict[str, Any]:
    """Every preset of ``kind`` by name: ``{"default": ..., "seed": ...}``."""
    return {p.label: preset_settings(kind, p, dt) for p in Preset}


def make_settings(kind: FilterKind, settings: Any = None, dt: float | None = None, **overrides: Any) -> Any:
    """Settings for ``kind``: the given object (or defaults), with ``dt`` and field overrides.

    ``dt`` is ignored by kinds without a sample period (tilt). Unknown fields raise TypeError.
    """
    cls = SETTINGS_CLASS.get(kind)
    if cls is None:
        raise ValueError(f"filter {kind.label!r} is not implemented yet")
    base = settings if settings is not None else cls()
    if not isinstance(base, cls):
        raise TypeError(f"settings for {kind.label} must be {cls.__name__}, got {type(base).__name__}")
    names = {f.name for f in fields(cls)}
    if dt is not None and "dt" in names:
        overrides = {"dt": dt, **overrides}
    unknown = sorted(set(overrides) - names)
    if unknown:
        raise TypeError(
            f"{cls.__name__} has no field(s) {', '.join(unknown)}; fields: {', '.join(sorted(names))}"
        )
    return replace(base, **overrides)
