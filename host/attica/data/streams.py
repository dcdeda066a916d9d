"""Sensor streams onto the gyro's clock: what every recording reader (bags, logs, phone exports) shares.

A reader collects each sensor as it was recorded, a :class:`Series` of raw times (the file's unit and
origin) and values in attica's units and sensor frame, and :func:`assemble` makes the
:class:`~attica.data.recording.Recording` by the rules of :mod:`attica.data.timing`:

- **Origin**: the earliest time of any stream is subtracted (exactly, in the file's integer type for
  integer stamps), so ``Recording.time`` starts near 0; the origin is stated in the notes.
- **Gyro**: its time column is read by :func:`attica.data.timing.clock` (unit, duplicates and
  out-of-order rows dropped, gaps counted); it is the recording's clock and its nominal rate the
  recording's rate.
- **Accelerometer**: paired with the gyro when both come in one message (a ``sensor_msgs/Imu``, PX4's
  ``sensor_combined``), else held (the latest sample at or before each gyro time); gyro rows before the
  first accel sample are dropped and reported.
- **Magnetometer**: each sample placed once, on the first gyro time at or after it; NaN elsewhere.
- **Reference attitude**: paired, or held for at most 1.5 of its own median intervals (NaN beyond, and
  before its first sample).

The reader also describes the file (:class:`Contents`: the streams with counts and rates, what was
chosen and converted, problems beyond the time column's), which ``attica info`` prints and
:func:`report` turns into :class:`~attica.data.timing.TimingWarning` s.
"""

from __future__ import annotations

import importlib
import struct
import warnings
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.data import timing
from attica.data.recording import Recording

EXTRA = "pip install 'attica[recordings]'"
"""How to install the optional packages of the bag and log readers."""


class RecordingError(ValueError):
    """A file that cannot be read as the recording it should be; the message names the file."""


def require(module: str, what: str) -> ModuleType:
    """Import an optional package, or raise an ImportError that says how to install it."""
    try:
        return importlib.import_module(module)
    except ImportError:
        top = module.split(".")[0]
        raise ImportError(f"reading {what} needs the {top} package: {EXTRA}") from None


@contextmanager
def reading(path: Path, what: str, errors: tuple[type[BaseException], ...] = ()) -> Iterator[None]:
    """Turn a library's error on a bad file into a :class:`RecordingError` naming the file.

    ``errors`` are the library's own exception types; malformed data that surfaces as ValueError,
    KeyError, IndexError, struct.error, EOFError, zipfile.BadZipFile or an OSError from a bad offset is
    caught too. A :class:`RecordingError`, a missing file, a folder or a permission error pass unchanged.
    """
    caught: tuple[type[BaseException], ...] = (
        *errors,
        ValueError,
        KeyError,
        IndexError,
        struct.error,
        EOFError,
        zipfile.BadZipFile,
        OSError,  # a library seeking to a corrupt offset
    )
    try:
        yield
    except (RecordingError, FileNotFoundError, PermissionError, IsADirectoryError):
        raise
    except caught as exc:
        detail = str(exc).strip() or type(exc).__name__
        raise RecordingError(f"{path}: not a readable {what}: {detail}") from None


@dataclass(frozen=True)
class Series:
    """One sensor stream as recorded.

    Attributes
    ----------
    time : ndarray, shape (N,)
        Times as in the file (integer or float; the file's unit and origin).
    values : ndarray, float64, shape (N, C)
        Samples in attica's units and the sensor frame (conversions are the reader's job).
    source : str
        What the stream is (a topic, a file), for the messages.

    """

    time: NDArray[Any]
    values: NDArray[np.float64]
    source: str

    def __post_init__(self) -> None:
        if self.time.ndim != 1 or self.values.ndim != 2 or self.values.shape[0] != self.time.shape[0]:
            raise RecordingError(
                f"{self.source}: {self.time.shape[0]} times but values of shape {self.values.shape}"
            )

    def __len__(self) -> int:
        return int(self.time.shape[0])


@dataclass(frozen=True)
class Stream:
    """One stream (topic, message, file) of a recording file, for ``attica info``.

    Attributes
    ----------
    name : str
        Topic, ULog message, or file name.
    kind : str
        Message type or sensor.
    count : int
        Samples or messages.
    rate : float or None
        Hz: from the median interval for the streams read, the mean over the file's span for the others.
    role : str
        What it became in the recording (``gyr``, ``acc``, ``mag``, ``quat_true``, comma-separated), or
        ``""`` when not used.

    """

    name: str
    kind: str
    count: int
    rate: float | None = None
    role: str = ""


@dataclass(frozen=True)
class Contents:
    """What a recording file holds and how it was read.

    Attributes
    ----------
    path : Path
        The file or folder.
    format : str
        Its format, in words (``ROS 2 bag (sqlite3)``, ``PX4 ULog`` ...).
    streams : tuple of Stream
        Every stream the file lists (bags: every topic with its type).
    notes : tuple of str
        What was chosen and converted (topics, time source, frames, units, origin).
    warnings : tuple of str
        Problems beyond the time column's (those are in ``Recording.timing``).

    """

    path: Path
    format: str
    streams: tuple[Stream, ...] = ()
    notes: tuple[str, ...] = ()
    warnings: tuple[str, ...] = field(default=())


def report(rec: Recording, contents: Contents, stacklevel: int = 3) -> None:
    """The recording's timing warnings and the reader's as :class:`~attica.data.timing.TimingWarning` s."""
    if rec.timing is not None:
        timing.report(rec.timing, stacklevel=stacklevel + 1)
    for msg in contents.warnings:
        warnings.warn(msg, timing.TimingWarning, stacklevel=stacklevel)


def median_rate(t: NDArray[np.float64]) -> float | None:
    """Hz from the median positive interval of times in s, None for fewer than two distinct times."""
    d = np.diff(np.asarray(t, np.float64))
    d = d[d > 0]
    return float(1.0 / np.median(d)) if d.size else None


def _relative(t: NDArray[Any], origin: Any) -> NDArray[np.float64]:
    """``t - origin`` as float64, exactly for integer stamps."""
    if t.dtype.kind in "iu":
        return (t.astype(np.int64) - np.int64(origin)).astype(np.float64)
    return np.asarray(t, np.float64) - float(origin)


def _increasing(t: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Rows later than every row before them (the rule of :func:`attica.data.timing.clock`)."""
    if t.size == 0:
        return np.ones(0, np.bool_)
    before = np.maximum.accumulate(np.concatenate([[-np.inf], t[:-1]]))
    keep: NDArray[np.bool_] = t > before
    return keep


def _finite(values: NDArray[np.float64]) -> NDArray[np.bool_]:
    return np.asarray(np.isfinite(values).all(axis=1), np.bool_)


def truth_on(
    t_base: NDArray[np.float64], t: NDArray[np.float64], q: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Reference quaternions held on the base times for at most 1.5 of their median intervals."""
    held, _ = timing.hold_on(t_base, t, q)
    if t.size >= 2:
        period = float(np.median(np.diff(t)))
        idx = np.searchsorted(t, t_base, side="right") - 1
        age = t_base - t[np.clip(idx, 0, None)]
        held[(idx < 0) | (age > 1.5 * period)] = np.nan
    return held


@dataclass
class _Ordered:
    """A stream in s with its out-of-order and non-finite rows removed."""

    t: NDArray[np.float64]
    v: NDArray[np.float64]
    dropped: int


def _order(series: Series, origin: Any, scale: float) -> _Ordered:
    t = _relative(series.time, origin) * scale
    ok = _finite(series.values) & np.isfinite(t)
    t, v = t[ok], series.values[ok]
    keep = _increasing(t)
    return _Ordered(t[keep], v[keep], int(len(series) - int(np.count_nonzero(keep))))


def assemble(
    gyr: Series,
    acc: Series | NDArray[np.float64],
    *,
    mag: Series | None = None,
    quat: Series | NDArray[np.float64] | None = None,
    unit: str | None = None,
    time_name: str = "",
    rate: float | None = None,
    name: str = "",
    where: object = "",
) -> tuple[Recording, list[str], list[str]]:
    """The recording of the streams, on the gyro's clock (the rules of the module docstring).

    Parameters
    ----------
    gyr : Series
        Angular rate, rad/s, shape (N, 3).
    acc : Series or ndarray
        Specific force, m/s^2: a stream of its own, or an (N, 3) array paired with the gyro rows.
    mag : Series, optional
        Magnetic field, uT.
    quat : Series or ndarray, optional
        Reference ``w, x, y, z`` sensor-to-ENU: a stream, or (N, 4) paired with the gyro rows (NaN rows:
        unknown).
    unit : str, optional
        Unit of every stream's times (``s``, ``ms``, ``us``, ``ns``); None: from ``time_name``, else
        guessed from the gyro intervals (and reported as guessed).
    time_name : str
        The time column's name, for its unit.
    rate : float, optional
        Nominal gyro rate in Hz when the file states it.
    name : str
        The recording's name.
    where : str or Path
        The file, named first in the errors.

    Returns
    -------
    recording : Recording
    notes, warnings : list of str
        What was done, and the problems beyond the gyro's time column.

    Raises
    ------
    RecordingError
        A bad time column, or no gyro sample at or after the first accel sample.

    """
    try:
        return _assemble(gyr, acc, mag, quat, unit, time_name, rate, name)
    except RecordingError as exc:
        if where and not str(exc).startswith(str(where)):
            raise RecordingError(f"{where}: {exc}") from None
        raise


def _assemble(
    gyr: Series,
    acc: Series | NDArray[np.float64],
    mag: Series | None,
    quat: Series | NDArray[np.float64] | None,
    unit: str | None,
    time_name: str,
    rate: float | None,
    name: str,
) -> tuple[Recording, list[str], list[str]]:
    notes: list[str] = []
    warns: list[str] = []
    paired_acc = not isinstance(acc, Series)
    streams: list[Series] = [s for s in (gyr, acc, mag, quat) if isinstance(s, Series) and len(s)]
    if len(gyr) < 2:
        raise RecordingError(f"{gyr.source}: {len(gyr)} gyro sample(s); need at least 2")
    origin = min(s.time.min() for s in streams)
    g_rel = _relative(gyr.time, origin)
    g_val = gyr.values
    a_val = np.asarray(acc, np.float64) if paired_acc else None
    q_val = np.asarray(quat, np.float64) if quat is not None and not isinstance(quat, Series) else None
    ok = _finite(g_val) & (_finite(a_val) if a_val is not None else True)
    if not ok.all():
        warns.append(
            f"{gyr.source}: {int(np.count_nonzero(~ok))} row(s) with an empty or non-finite value dropped"
        )

    def cut(rows: NDArray[np.bool_]) -> None:
        nonlocal g_rel, g_val, a_val, q_val
        g_rel, g_val = g_rel[rows], g_val[rows]
        a_val = a_val[rows] if a_val is not None else None
        q_val = q_val[rows] if q_val is not None else None

    cut(ok)
    try:
        clk = timing.clock(g_rel, unit=unit, rate=rate, name=time_name, source=gyr.source)
        scale = timing.UNITS[clk.timing.unit]
        notes.append(f"time 0 s is {origin} {clk.timing.unit} of the file's clock (the earliest sample)")
        if isinstance(acc, Series):
            a = _order(acc, origin, scale)
            if a.t.size == 0:
                raise RecordingError(f"{acc.source}: no accelerometer sample")
            if a.dropped:
                warns.append(f"{acc.source}: {a.dropped} row(s) empty, repeated or out of order, dropped")
            early = g_rel * scale < a.t[0]
            if early.all():
                raise RecordingError(f"{gyr.source}: no gyro sample at or after the first accel sample")
            if early.any():
                n_early = int(np.count_nonzero(early))
                warns.append(
                    f"{gyr.source}: {n_early} gyro row(s) before the first accelerometer sample dropped "
                    f"({a.t[0] - float(np.min(g_rel)) * scale:.3g} s)"
                )
                cut(~early)
                clk = timing.clock(g_rel, unit=unit, rate=rate, name=time_name, source=gyr.source)
    except ValueError as exc:
        if isinstance(exc, RecordingError):
            raise
        raise RecordingError(str(exc)) from None
    t = clk.time
    cut(clk.keep)
    if isinstance(acc, Series):
        acc_out, _ = timing.hold_on(t, a.t, a.v)
        notes.append(f"{acc.source}: {a.t.size} samples held on the gyro clock (latest at or before)")
    else:
        assert a_val is not None
        acc_out = a_val
    size = float(np.median(np.linalg.norm(acc_out, axis=1))) if acc_out.size else 0.0
    if size < 5.0:
        warns.append(
            f"the accelerometer reads {size:.3g} m/s^2 in the median (g is 9.81): "
            + ("in g instead of m/s^2?" if 0.5 < size < 1.5 else "acceleration without gravity?")
            + " attica needs the specific force in m/s^2"
        )
    mag_out: NDArray[np.float64] | None = None
    if mag is not None and len(mag):
        m = _order(mag, origin, scale)
        if m.dropped:
            warns.append(f"{mag.source}: {m.dropped} row(s) empty, repeated or out of order, dropped")
        mag_out, superseded = timing.place_on(t, m.t, m.v)
        text = f"{mag.source}: {m.t.size} samples placed on the first gyro time at or after each"
        if superseded:
            text += f" ({superseded} replaced by a later one on the same gyro row, or after the last)"
        notes.append(text)
    q_out: NDArray[np.float64] | None = None
    if isinstance(quat, Series) and len(quat):
        q = _order(quat, origin, scale)
        q_out = truth_on(t, q.t, q.v)
        notes.append(f"{quat.source}: {q.t.size} reference attitudes held for up to 1.5 intervals")
    elif q_val is not None:
        q_out = q_val
    try:
        rec = Recording(
            gyr=g_val.astype(np.float32),
            acc=acc_out.astype(np.float32),
            mag=mag_out.astype(np.float32) if mag_out is not None else None,  # type: ignore[arg-type]
            rate=clk.timing.rate,
            quat_true=q_out,
            name=name,
            time=t,
            timing=clk.timing,
        )
    except ValueError as exc:
        raise RecordingError(f"{gyr.source}: {exc}") from None
    return rec, notes, warns
