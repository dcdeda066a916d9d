"""attica: deterministic attitude estimation firmware, its bit-exact numpy reference and tools.

The user API at the top level::

    import attica
    rec = attica.simulate(attica.SimConfig(duration=60, rate=100.0))
    out = attica.Filter("ars", 1 / rec.rate).run(rec.gyr, rec.acc)   # the C filter (cffi)
    q = attica.Filter("ars", 1 / rec.rate).run_q(rec.gyr, rec.acc)   # quaternions only (throughput)
    print(out)                                                       # labelled table
    attica.describe_flags(int(out["flags"][-1]))                     # "AT_REST|BIAS_UPDATED"

- :class:`Filter` (= :class:`attica.native.Filter`): the C firmware through cffi.
- :mod:`attica.reference`: the numpy float32 mirror, bit for bit (``attica.reference.Filter``).
- :func:`simulate`, :class:`SimConfig`: deterministic IMU simulator with ground truth.
- :func:`load_recording`, :class:`Recording`: .npz / .csv / BROAD files.
- :mod:`attica.kinds`: the filter kinds and what each one is (inputs, heading, outputs, CAN gains).
- :class:`Flag`, :func:`describe_flags`, :func:`flag_names`: the per-step status flags by name.
- :class:`UnitWarning`: raised as a warning when inputs look like deg/s, g, gauss or nT.
- :class:`SettingsError` (= :class:`attica.native.SettingsError`): settings the C library refuses,
  naming the field, its value and its range.
- ``attica`` on the command line (:mod:`attica.cli`); ``attica paths`` prints where the firmware
  sources, headers, flags and DBC of this installation are (:mod:`attica.resources`).

The version (``__version__``) is the one of the C headers (``ATT_VERSION_*`` in att_version.h).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from attica._version import parse_version_header as _parse_version
from attica.checks import SettingsConflictError, UnitWarning
from attica.resources import version_header as _version_header
from attica.settings import (
    ArsSettings,
    BiasMode,
    EkfSettings,
    FilterKind,
    Flag,
    GyroSettings,
    Integration,
    KfSettings,
    MagMode,
    MarsSettings,
    MekfSettings,
    Preset,
    TiltSettings,
    describe_flags,
    flag_names,
)

if TYPE_CHECKING:
    from attica.data import Recording, load_recording
    from attica.native import Filter, SettingsError
    from attica.sim import SimConfig, simulate, simulate_with_truth

VERSION_INFO: tuple[int, int, int] = _parse_version(_version_header().read_text())
"""(major, minor, patch) of att_version.h."""

__version__ = "{}.{}.{}".format(*VERSION_INFO)

_LAZY = {
    "Filter": ("attica.native", "Filter"),
    "SettingsError": ("attica.native", "SettingsError"),
    "simulate": ("attica.sim", "simulate"),
    "simulate_with_truth": ("attica.sim", "simulate_with_truth"),
    "SimConfig": ("attica.sim", "SimConfig"),
    "Recording": ("attica.data", "Recording"),
    "load_recording": ("attica.data", "load_recording"),
}
"""Names imported on first use (the C extension loads only when ``attica.Filter`` is used)."""

__all__ = [
    "VERSION_INFO",
    "ArsSettings",
    "BiasMode",
    "EkfSettings",
    "Filter",
    "FilterKind",
    "Flag",
    "GyroSettings",
    "Integration",
    "KfSettings",
    "MagMode",
    "MarsSettings",
    "MekfSettings",
    "Preset",
    "Recording",
    "SettingsConflictError",
    "SettingsError",
    "SimConfig",
    "TiltSettings",
    "UnitWarning",
    "__version__",
    "describe_flags",
    "flag_names",
    "load_recording",
    "simulate",
    "simulate_with_truth",
]


def __getattr__(name: str) -> Any:
    if name in ("native", "reference", "kinds"):
        import importlib

        return importlib.import_module(f"attica.{name}")
    if name in _LAZY:
        import importlib

        module, attr = _LAZY[name]
        value = getattr(importlib.import_module(module), attr)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'attica' has no attribute {name!r}")
