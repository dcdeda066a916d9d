"""Checks that stop silent misuse of the filters: the sample period, the gains, input units.

- :func:`filter_settings`: the settings of a new filter from ``(kind, dt, settings, **overrides)``,
  with the sample period required (a positional float after the kind is ``dt``, as in VQF); setting
  only a time constant sets its per-sample gain to 0, the value that says "unused" (:func:`implied_gains`).
- :func:`imu_arrays`: batch inputs as float32 C-contiguous (N, 3) arrays, with a clear error for a
  wrong shape or a dtype that is not a real number.
- :func:`unit_problems` / :func:`warn_units`: median magnitudes of the inputs that look like deg/s, g,
  milli-g, gauss or nT instead of rad/s, m/s^2 and uT, reported as a :class:`UnitWarning`.

A per-sample gain and its time constant (:data:`GAIN_TIME_CONSTANTS`) follow the rule of the C library
(att_ars.h, att_mars.h): a time constant > 0 is used and the gain beside it is ignored (it must still
lie in [0, 1]); with the time constant 0 the gain is used. Every range of the settings is the C
library's (``att_filter_settings_check`` names the refused field: :class:`attica.native.SettingsError`).

Silence the unit warnings with ``warnings.simplefilter("ignore", attica.UnitWarning)`` (or
``check_units=False`` in ``Filter.run``, ``--no-unit-check`` on the command line).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import warnings
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from attica.kinds import KINDS
from attica.settings import SETTINGS_CLASS, FilterKind, make_settings

__all__ = [
    "GAIN_TIME_CONSTANTS",
    "SettingsConflictError",
    "UnitWarning",
    "filter_settings",
    "implied_gains",
    "imu_arrays",
    "unit_problems",
    "warn_units",
]


class UnitWarning(UserWarning):
    """The inputs (or ``dt``) look like other units than attica's (rad/s, m/s^2, uT, s)."""


class SettingsConflictError(ValueError):
    """Two settings contradict each other.

    No longer raised for a per-sample gain beside the time constant that replaces it (since issue 22
    the time constant is used and the gain ignored, in C, Python and on CAN alike); kept so that
    ``except SettingsConflictError`` in existing code still works.
    """


GAIN_TIME_CONSTANTS: dict[FilterKind, tuple[tuple[str, str], ...]] = {
    k.kind: k.gain_time_constants for k in KINDS if k.gain_time_constants
}
"""Per kind that has some: (per-sample gain, time constant) pairs (``gain_time_constants`` of
:data:`attica.kinds.KINDS`). A time constant > 0 sets the per-sample gain of a step to
``dt / (tau + dt)``; the gain field is then ignored (still range-checked by the C library)."""


def implied_gains(kind: FilterKind, base: Any, overrides: dict[str, Any]) -> dict[str, Any]:
    """``overrides`` with each per-sample gain set to 0 where its time constant is in use (> 0).

    A per-sample gain left at its default (not in ``overrides``, default value in ``base``) yields to a
    time constant > 0, given in ``overrides`` or set in ``base`` (e.g. ``ArsSettings(tau=0.5)``): it is
    set to 0, the value that says "unused" (as the CAN node's SET_GAIN does). A gain given with a value
    of its own is kept as given: the time constant is used and the gain ignored (same outputs).
    """
    out = dict(overrides)
    cls = SETTINGS_CLASS[kind]
    defaults = cls()
    current = base if base is not None else defaults
    for gain, tau in GAIN_TIME_CONSTANTS.get(kind, ()):
        if gain in out:
            continue
        t = np.asarray(out.get(tau, getattr(current, tau)), np.float64)
        g = getattr(current, gain)
        unused = (t > 0) & (np.asarray(g, np.float64) == float(getattr(defaults, gain)))
        if unused.ndim == 0:
            if unused:
                out[gain] = 0.0
        elif unused.any():  # per-instance arrays (the reference): 0 where that instance's tau is in use
            garr = np.broadcast_to(np.asarray(g), unused.shape)
            out[gain] = np.where(unused, np.zeros_like(garr), garr)
    return out


def _is_real(x: Any) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, bool)


def filter_settings(
    kind: str | int | FilterKind,
    dt: Any,
    settings: Any,
    overrides: dict[str, Any],
    who: str = "Filter",
) -> tuple[FilterKind, Any]:
    """The kind and settings of a new filter, checked.

    Parameters
    ----------
    kind
        Filter kind (name, number or :class:`FilterKind`).
    dt
        Sample period in s. A settings dataclass here is taken as ``settings`` (the positional form
        ``Filter(kind, settings)``).
    settings
        A settings dataclass of the kind (its ``dt`` is used when ``dt`` is None), or None.
    overrides
        Settings fields to change.
    who
        Name used in error messages (``native.Filter``, ``reference.Filter``).

    Raises
    ------
    TypeError
        No sample period for a kind that has one, ``dt`` not a number, unknown fields.
    ValueError
        ``dt`` not finite and > 0, or an unknown kind.

    """
    k = FilterKind.parse(kind)
    if "dt" in overrides:  # retune(dt=...) and Filter(kind, settings=s, dt=...) name the period as a field
        overrides = dict(overrides)
        field_dt = overrides.pop("dt")
        if dt is not None and field_dt is not None and field_dt != dt:
            raise TypeError(f"{who}: dt given twice ({dt!r} and dt={field_dt!r})")
        dt = field_dt if field_dt is not None else dt
    if dt is not None and not _is_real(dt):
        if dataclasses.is_dataclass(dt) and not isinstance(dt, type):
            if settings is not None:
                raise TypeError(f"{who}: settings given twice (positionally and as settings=)")
            settings, dt = dt, None
        else:
            raise TypeError(
                f"{who}: dt is the sample period in s (a number, e.g. {who}({k.label!r}, 0.01) for 100 Hz); "
                f"got {type(dt).__name__}"
            )
    cls = SETTINGS_CLASS.get(k)
    has_dt = cls is not None and "dt" in {f.name for f in dataclasses.fields(cls)}
    if has_dt and dt is None and settings is None:
        raise TypeError(
            f"{who}({k.label!r}) needs the sample period: {who}({k.label!r}, dt) with dt in s, e.g. "
            f"{who}({k.label!r}, 0.01) for 100 Hz, or settings=... that carry dt"
        )
    if dt is not None:
        value = float(dt)
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{who}: dt must be a finite sample period > 0 s, got {dt!r}")
        if value >= 1.0:
            warnings.warn(
                f"{who}: dt = {value:g} s (a sample rate of {1 / value:g} Hz): dt is the sample period in "
                f"seconds, not a rate in Hz (for {value:g} Hz pass dt = {1 / value:g})",
                UnitWarning,
                stacklevel=4,
            )
    s = make_settings(k, settings, None if dt is None else float(dt), **implied_gains(k, settings, overrides))
    return k, s


# --- batch inputs ---------------------------------------------------------------------------------

_REAL_KINDS = "fiu"
"""numpy dtype kinds taken as samples (float, signed and unsigned integer); converted to float32."""


def imu_arrays(
    gyr: ArrayLike, acc: ArrayLike, mag: ArrayLike | None, who: str
) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32] | None]:
    """The inputs of a batch run as float32 C-contiguous (N, 3) arrays (no copy when they already are).

    Parameters
    ----------
    gyr, acc
        (N, 3) rad/s and m/s^2: arrays or nested sequences of real numbers.
    mag
        (N, 3) uT, or None (no magnetometer).
    who
        The caller, for the messages (``"ars Filter.run"``).

    Returns
    -------
    tuple
        ``(gyr, acc, mag)``; ``mag`` None when not given.

    Raises
    ------
    TypeError
        An input whose dtype is not a real number (bool, complex, object, text, ...): converting it
        would drop the imaginary part or guess at a meaning.
    ValueError
        Shapes other than (N, 3), or different N.

    """
    arrays: list[NDArray[np.float32] | None] = []
    for name, x in (("gyr", gyr), ("acc", acc), ("mag", mag)):
        if x is None:
            if name != "mag":
                raise TypeError(f"{who}: {name} is required, got None")
            arrays.append(None)
            continue
        raw = np.asarray(x)
        if raw.dtype.kind not in _REAL_KINDS:
            raise TypeError(f"{who}: {name} must hold real numbers (float or integer), got dtype {raw.dtype}")
        arrays.append(np.ascontiguousarray(raw, dtype=np.float32))
    g, a, m = arrays
    assert g is not None and a is not None
    if g.ndim != 2 or g.shape[1] != 3 or a.shape != g.shape or (m is not None and m.shape != g.shape):
        shapes = ", ".join(f"{n} {x.shape}" for n, x in zip(("gyr", "acc", "mag"), arrays) if x is not None)
        raise ValueError(f"{who}: gyr, acc (and mag) must all have shape (N, 3), the same N; got {shapes}")
    return g, a, m


# --- units ------------------------------------------------------------------------------------------

_SAMPLE_ROWS = 8192
"""Rows looked at (evenly spread) when computing the median magnitudes of a long recording: enough
for the median and the 99th percentile, and few enough that the float64 temporaries (64 KiB) come from
the heap without page faults (20 000 rows cost about 2 ms per call, most of it first-touch faults)."""


def _percentiles(n: NDArray[np.float64], qs: tuple[float, ...]) -> list[float]:
    """``np.percentile(n, qs)`` (linear interpolation) from one ``np.partition``: a fraction of its cost."""
    last = n.size - 1
    pos = [q / 100.0 * last for q in qs]
    lo = [min(int(math.floor(p)), last) for p in pos]
    hi = [min(k + 1, last) for k in lo]
    part = np.partition(n, sorted(set(lo + hi)))
    return [float(part[a] + (part[b] - part[a]) * (p - a)) for p, a, b in zip(pos, lo, hi, strict=True)]


def _norm_percentiles(x: ArrayLike | None, qs: tuple[float, ...] = (50.0,)) -> list[float]:
    """Percentiles ``qs`` of the row magnitudes of (..., 3) samples (NaN when there are none).

    Zero and non-finite rows are left out (no sample). A long recording is thinned to about
    ``_SAMPLE_ROWS`` evenly spread rows before anything is converted, column by column (a strided 1-D
    cast is one fast loop; casting the (N, 3) block is not), so the check costs little beside a batch run.
    """
    nan = [math.nan] * len(qs)
    if x is None:
        return nan
    with np.errstate(all="ignore"):
        a = np.asarray(x)
        if a.ndim == 0 or a.shape[-1] != 3 or a.size == 0:
            return nan
        a = a.reshape(-1, 3)
        if a.shape[0] > _SAMPLE_ROWS:
            a = a[:: -(-a.shape[0] // _SAMPLE_ROWS)]  # at most _SAMPLE_ROWS rows
        # (x*x + y*y) + z*z in place: few temporaries (fresh large arrays cost page faults)
        n: NDArray[np.float64] = a[:, 0].astype(np.float64)
        n *= n
        for k in (1, 2):
            c = a[:, k].astype(np.float64)
            c *= c
            n += c
        np.sqrt(n, out=n)
        n = n[np.isfinite(n) & (n > 0)]  # zero or NaN rows: no sample
        return _percentiles(n, qs) if n.size else nan


def unit_problems(gyr: ArrayLike | None, acc: ArrayLike | None, mag: ArrayLike | None = None) -> list[str]:
    """What looks wrong with the units of the inputs, judged by median magnitudes (empty: nothing).

    attica takes gyro in rad/s, accel in m/s^2 (|a| about 9.81 at rest) and mag in uT (the earth's
    field is 25..65 uT). Looks like deg/s: median |gyr| > 8 rad/s, or more than 1 % of the samples above
    35 rad/s (2000 deg/s, the full scale of common MEMS gyros and the default ``gyro_range``; a recording
    mostly at rest has a small median in any unit, and the fastest BROAD trial's 99th percentile is
    19 rad/s); g: median |acc| in 0.3..3; milli-g: 300..3000; gauss: median |mag| in 0.05..2; nT:
    2000..200000.
    """
    out = []
    g, g99 = _norm_percentiles(gyr, (50.0, 99.0))
    if g > 8.0 or g99 > 35.0:
        out.append(
            f"|gyr| (median {g:.3g}, 99th percentile {g99:.3g}) looks like deg/s "
            "(attica takes rad/s: multiply by pi/180)"
        )
    (a,) = _norm_percentiles(acc)
    if 0.3 <= a <= 3.0:
        out.append(f"median |acc| = {a:.3g} looks like g (attica takes m/s^2: multiply by 9.80665)")
    elif 300.0 <= a <= 3000.0:
        out.append(f"median |acc| = {a:.3g} looks like milli-g (attica takes m/s^2: multiply by 0.00980665)")
    (m,) = _norm_percentiles(mag)
    if 0.05 <= m <= 2.0:
        out.append(f"median |mag| = {m:.3g} looks like gauss (attica takes uT: multiply by 100)")
    elif 2000.0 <= m <= 200000.0:
        out.append(f"median |mag| = {m:.3g} looks like nT (attica takes uT: divide by 1000)")
    return out


def warn_units(
    gyr: ArrayLike | None,
    acc: ArrayLike | None,
    mag: ArrayLike | None = None,
    where: str = "",
    stacklevel: int = 3,
) -> list[str]:
    """Issue one :class:`UnitWarning` listing :func:`unit_problems` (if any); returns the problems."""
    problems = unit_problems(gyr, acc, mag)
    if problems:
        prefix = f"{where}: " if where else ""
        warnings.warn(
            prefix
            + "; ".join(problems)
            + " (silence: warnings.simplefilter('ignore', attica.UnitWarning), or check_units=False)",
            UnitWarning,
            stacklevel=stacklevel,
        )
    return problems
