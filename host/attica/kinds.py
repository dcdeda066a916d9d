"""The filter kinds: one registry of what each kind is, read by every per-kind list in Python.

The Python twin of the C kind table (``ATT_KINDS_EACH`` in firmware/src/filters/att_kinds.h);
``tests/test_kinds.py`` checks that the two agree, fact by fact, against the C library. Everything in
attica that depends on the kind (settings classes, the reference's dispatch, 6- or 9-axis scoring,
heading commands, the CAN gains, the tests' parametrisations) asks this module instead of listing
kinds, so that a new kind is one entry here (plus its settings dataclass, reference module and C
source).

Examples
--------
>>> from attica import kinds
>>> kinds.info("mekf").label, kinds.info(7).macro
('mekf', 'ATT_WITH_MEKF')
>>> [k.label for k in kinds.KINDS if k.covariance]
['kf', 'ekf', 'mekf']
>>> from attica.settings import MekfSettings
>>> kinds.uses_mag("mekf"), kinds.uses_mag("mekf", MekfSettings(use_mag=False))
(True, False)
>>> kinds.heading("mekf", MekfSettings(use_mag=False)).name
'UPDATE'

"""

from __future__ import annotations

import dataclasses
import enum
import importlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from attica.settings import (
    ArsSettings,
    EkfSettings,
    FilterKind,
    GyroSettings,
    KfSettings,
    MarsSettings,
    MekfSettings,
    TiltSettings,
)

if TYPE_CHECKING:
    from attica.can.layout import Gain

__all__ = [
    "KINDS",
    "SENSORS",
    "Heading",
    "KindInfo",
    "axes",
    "gains",
    "heading",
    "info",
    "inputs",
    "labels",
    "uses_mag",
]

SENSORS = ("gyr", "acc", "mag")
"""The inputs of a sample (``att_sample_t``), in the order of ``Filter.step(gyr, acc, mag)``."""


class Heading(enum.IntEnum):
    """What a kind does with a heading (``att_heading_t`` in att_kinds.h).

    ``NONE``: no heading (``set_heading`` and ``heading_update`` refused). ``SET``: the kind has its own
    heading reference (the magnetometer): ``set_heading`` only. ``UPDATE``: ``set_heading`` and external
    heading updates (GNSS course, compass) through ``heading_update``.
    """

    NONE = 0
    SET = 1
    UPDATE = 2


@dataclass(frozen=True)
class KindInfo:
    """The facts of one filter kind.

    Attributes
    ----------
    kind : FilterKind
        The kind (its value is ``att_filter_kind_t``, part of the CAN contract).
    settings_class : type
        Its settings dataclass (:mod:`attica.settings`), mirror of ``att_<label>_settings_t``.
    reference : str
        ``module:Class`` of its numpy reference (imported on demand by :meth:`reference_class`).
    sensors : tuple of str
        The inputs it reads (of :data:`SENSORS`, in that order), the magnetometer included when the
        kind can use one (see ``mag_switch``). The reference's ``step`` takes them in this order.
    mag_switch : str or None
        The boolean setting that turns the magnetometer on (mekf: ``use_mag``); None when the kind
        always uses the sensors it reads.
    q_state : bool
        Its state holds a quaternion: a step writes ``q`` (``ATT_OUT_Q``).
    euler_state : bool
        Its state holds Euler angles: a step writes ``euler`` (``ATT_OUT_EULER``); the EKF, whose
        state is only the angles, derives ``q`` on request.
    gyro_bias : bool
        It estimates a gyro bias (the baselines report zeros).
    covariance : bool
        It has a covariance, reported in the output's ``cov``.
    heading_mode : Heading
        What it does with a heading (with its magnetometer on, when it has a ``mag_switch``).
    heading_no_mag : Heading or None
        What it does with a heading when its ``mag_switch`` setting is off (None without a switch).
    gain_names : tuple of str
        Names of the :class:`attica.can.layout.Gain` parameters the node's ``SET_GAIN`` takes for it.
    gain_time_constants : tuple of (str, str)
        (per-sample gain, time constant) setting pairs: a time constant > 0 is used and the gain beside
        it ignored (still range-checked); with the time constant 0 the gain is used.

    """

    kind: FilterKind
    settings_class: type[Any]
    reference: str
    sensors: tuple[str, ...]
    q_state: bool
    euler_state: bool
    gyro_bias: bool
    covariance: bool
    heading_mode: Heading
    mag_switch: str | None = None
    heading_no_mag: Heading | None = None
    gain_names: tuple[str, ...] = ()
    gain_time_constants: tuple[tuple[str, str], ...] = ()

    def __post_init__(self) -> None:
        if not set(self.sensors) <= set(SENSORS) or list(self.sensors) != [
            s for s in SENSORS if s in self.sensors
        ]:
            raise ValueError(f"{self.label}: sensors {self.sensors} must be some of {SENSORS}, in that order")
        if not (self.q_state or self.euler_state):
            raise ValueError(f"{self.label}: the state holds a quaternion, Euler angles or both")
        switched = self.mag_switch is not None
        if switched != (self.heading_no_mag is not None) or (switched and "mag" not in self.sensors):
            raise ValueError(f"{self.label}: mag_switch and heading_no_mag go together, with the mag read")
        names = {f.name for f in dataclasses.fields(self.settings_class)}
        used = [self.mag_switch] if self.mag_switch else []
        used += [name for pair in self.gain_time_constants for name in pair]
        missing = sorted(set(used) - names)
        if missing:
            raise ValueError(f"{self.label}: {self.settings_class.__name__} has no {', '.join(missing)}")

    @property
    def label(self) -> str:
        """Lower-case name: command line, ``att_filter_name``, ``att_<label>_*`` in C."""
        return self.kind.label

    @property
    def macro(self) -> str:
        """The C build option that compiles the kind in (att_config.h)."""
        return f"ATT_WITH_{self.kind.name}"

    @property
    def c_settings(self) -> str:
        """The C settings struct (``att_<label>_settings_t``)."""
        return f"att_{self.label}_settings_t"

    @property
    def has_period(self) -> bool:
        """Its settings carry a sample period ``dt`` (the tilt baseline's do not)."""
        return "dt" in {f.name for f in dataclasses.fields(self.settings_class)}

    @property
    def baseline(self) -> bool:
        """A single-sensor baseline (gyro-only integration, accel-only tilt), not a fusion filter."""
        return len(self.sensors) == 1

    @property
    def gains(self) -> tuple[Gain, ...]:
        """The :class:`attica.can.layout.Gain` parameters of ``SET_GAIN`` for this kind."""
        from attica.can.layout import Gain

        return tuple(Gain[name] for name in self.gain_names)

    def reference_class(self) -> type[Any]:
        """The numpy reference class of the kind (imported now)."""
        module, name = self.reference.split(":")
        cls: type[Any] = getattr(importlib.import_module(module), name)
        return cls

    def uses_mag(self, settings: Any = None) -> bool:
        """Whether it reads the magnetometer with ``settings`` (None: the defaults).

        With per-instance array settings (the reference's lockstep instances), True when any does.
        """
        if "mag" not in self.sensors:
            return False
        if self.mag_switch is None:
            return True
        s = settings if settings is not None else self.settings_class()
        return bool(np.any(getattr(s, self.mag_switch)))

    def inputs(self, settings: Any = None) -> tuple[str, ...]:
        """The sensors it uses with ``settings`` (None: the defaults), in :data:`SENSORS` order."""
        return tuple(s for s in self.sensors if s != "mag" or self.uses_mag(settings))

    def axes(self, settings: Any = None) -> int:
        """Sensor axes it fuses with ``settings``: 9 (gyro, accel, mag), 6 (gyro, accel), 3 (baselines)."""
        return 3 * len(self.inputs(settings))

    def heading(self, settings: Any = None) -> Heading:
        """What it does with a heading with ``settings`` (None: the defaults)."""
        if self.heading_no_mag is not None and not self.uses_mag(settings):
            return self.heading_no_mag
        return self.heading_mode


_REF = "attica.reference"

KINDS: tuple[KindInfo, ...] = (
    KindInfo(
        FilterKind.ARS,
        ArsSettings,
        f"{_REF}.ars:Ars",
        sensors=("gyr", "acc"),
        q_state=True,
        euler_state=False,
        gyro_bias=True,
        covariance=True,
        heading_mode=Heading.UPDATE,
        gain_names=("TAU_ACC",),
        gain_time_constants=(("gain", "tau"),),
    ),
    KindInfo(
        FilterKind.MARS,
        MarsSettings,
        f"{_REF}.mars:Mars",
        sensors=("gyr", "acc", "mag"),
        q_state=True,
        euler_state=False,
        gyro_bias=True,
        covariance=True,
        heading_mode=Heading.SET,
        gain_names=("TAU_ACC", "TAU_MAG", "DECLINATION"),
        gain_time_constants=(("alpha_acc", "tau_acc"), ("alpha_mag", "tau_mag")),
    ),
    KindInfo(
        FilterKind.KF,
        KfSettings,
        f"{_REF}.kf:Kf",
        sensors=("gyr", "acc"),
        q_state=True,
        euler_state=False,
        gyro_bias=True,
        covariance=True,
        heading_mode=Heading.UPDATE,
        gain_names=("KF_R",),
    ),
    KindInfo(
        FilterKind.EKF,
        EkfSettings,
        f"{_REF}.ekf:Ekf",
        sensors=("gyr", "acc"),
        q_state=False,
        euler_state=True,
        gyro_bias=True,
        covariance=True,
        heading_mode=Heading.UPDATE,
        gain_names=("EKF_R",),
    ),
    KindInfo(
        FilterKind.GYRO,
        GyroSettings,
        f"{_REF}.gyro:Gyro",
        sensors=("gyr",),
        q_state=True,
        euler_state=True,
        gyro_bias=False,
        covariance=False,
        heading_mode=Heading.UPDATE,
    ),
    KindInfo(
        FilterKind.TILT,
        TiltSettings,
        f"{_REF}.tilt:Tilt",
        sensors=("acc",),
        q_state=True,
        euler_state=True,
        gyro_bias=False,
        covariance=False,
        heading_mode=Heading.NONE,
    ),
    KindInfo(
        FilterKind.MEKF,
        MekfSettings,
        f"{_REF}.mekf:Mekf",
        sensors=("gyr", "acc", "mag"),
        q_state=True,
        euler_state=False,
        gyro_bias=True,
        covariance=True,
        heading_mode=Heading.SET,
        mag_switch="use_mag",
        heading_no_mag=Heading.UPDATE,
        gain_names=("DECLINATION",),
    ),
)
"""Every kind, in the order of their values (the order of the C table)."""

if [k.kind for k in KINDS] != list(FilterKind):  # pragma: no cover - a registry edit gone wrong
    raise RuntimeError("attica.kinds.KINDS must list every FilterKind once, in value order")

_BY_KIND = {k.kind: k for k in KINDS}


def info(kind: str | int | FilterKind | KindInfo) -> KindInfo:
    """The facts of a kind given by name (any case), number, :class:`FilterKind` or its :class:`KindInfo`.

    Raises
    ------
    ValueError
        For an unknown kind (the message lists the choices).

    """
    if isinstance(kind, KindInfo):
        return kind
    return _BY_KIND[FilterKind.parse(kind)]


def labels() -> list[str]:
    """The names of every kind, in value order (``["ars", "mars", ...]``)."""
    return [k.label for k in KINDS]


def uses_mag(kind: str | int | FilterKind | KindInfo, settings: Any = None) -> bool:
    """Whether ``kind`` reads the magnetometer with ``settings`` (None: its defaults)."""
    return info(kind).uses_mag(settings)


def inputs(kind: str | int | FilterKind | KindInfo, settings: Any = None) -> tuple[str, ...]:
    """The sensors ``kind`` uses with ``settings`` (None: its defaults), e.g. ``("gyr", "acc")``."""
    return info(kind).inputs(settings)


def axes(kind: str | int | FilterKind | KindInfo, settings: Any = None) -> int:
    """9, 6 or 3: the sensor axes ``kind`` fuses with ``settings`` (None: its defaults)."""
    return info(kind).axes(settings)


def heading(kind: str | int | FilterKind | KindInfo, settings: Any = None) -> Heading:
    """What ``kind`` does with a heading with ``settings`` (None: its defaults)."""
    return info(kind).heading(settings)


def gains(kind: str | int | FilterKind | KindInfo) -> tuple[Gain, ...]:
    """The ``SET_GAIN`` parameters the node takes for ``kind`` (empty: none)."""
    return info(kind).gains
