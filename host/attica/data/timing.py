"""Time in recordings: the unit of a time column, the nominal period, gaps, and sensors on one clock.

A recording is stepped on the gyro's clock. Its time column is read as it is, and what it says is
reported (:class:`Timing`), never corrected in silence:

- **Unit** (s, ms, us, ns): from the column's name when it says (``t_ns``, ``time [ms]``,
  ``timestamp_us``), else from the intervals: the unit in which the median interval gives a rate in
  10 Hz .. 10 kHz (ties: the one nearest 200 Hz on a log scale). :attr:`Timing.unit_guessed` tells which.
- **Order**: a row whose time equals the previous kept row's is a duplicate, one before it is out of
  order; both are dropped (counted, first row given). A stream is never re-sorted.
- **Nominal period**: a given rate, else the span divided by the periods in it (each interval counted
  as ``round(interval / median interval)`` periods).
- **Steps**: each kept row advances the filter by ``max(1, round(interval / period))`` periods: jitter
  within half a period is one step, an interval of n periods is n steps (n - 1 samples lost; the
  filter integrates the sample it has over them, see :func:`attica.native.Filter.run`).
- **Other sensors** (:func:`hold_on`, :func:`place_on`): the accelerometer is held (the latest
  sample at or before each gyro time, zero-order hold), the magnetometer is placed once, on the first
  gyro sample at or after it, and absent (NaN) elsewhere. Nothing is interpolated into a sample that was
  never measured.
- **Resampling** (:func:`resample`), only when asked for, for logs that are not clocked at all: linear
  interpolation of gyro and accel onto a uniform grid, magnetometer placed as above.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

UNITS: dict[str, float] = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
"""Time units a column may have, and their length in s."""

_NAME_UNIT = re.compile(r"(?:^|[^a-z])(ns|us|µs|ms|s|sec|nsec|usec|msec)(?:[^a-z]|$)")
_ALIASES = {"sec": "s", "nsec": "ns", "usec": "us", "msec": "ms", "µs": "us"}


class TimingWarning(UserWarning):
    """A recording's time column has gaps, dropped rows, a guessed unit or large jitter."""


RATE_RANGE = (10.0, 10000.0)
"""The sampling rates (Hz) a guessed unit must give."""


def unit_from_name(name: str) -> str | None:
    """The time unit a column's name states (``t_ns`` -> ``ns``, ``time [ms]`` -> ``ms``), or None."""
    found = _NAME_UNIT.findall(name.strip().lower())
    if not found:
        return None
    unit = str(found[-1])
    return _ALIASES.get(unit, unit)


def guess_unit(raw: NDArray[np.float64]) -> str:
    """The unit in which the median positive interval of ``raw`` gives a plausible IMU rate.

    Raises
    ------
    ValueError
        Fewer than two distinct times, or no unit gives a rate in :data:`RATE_RANGE`.

    """
    d = np.diff(raw)
    d = d[np.isfinite(d) & (d > 0)]
    if d.size == 0:
        raise ValueError("the time column has fewer than two increasing values")
    med = float(np.median(d))
    best: tuple[float, str] | None = None
    for unit, scale in UNITS.items():
        rate = 1.0 / (med * scale)
        if RATE_RANGE[0] <= rate <= RATE_RANGE[1]:
            score = abs(math.log(rate / 200.0))
            if best is None or score < best[0]:
                best = (score, unit)
    if best is None:
        raise ValueError(
            f"cannot tell the time unit: the median interval {med:g} gives no rate in "
            f"{RATE_RANGE[0]:g}..{RATE_RANGE[1]:g} Hz in s, ms, us or ns; give the unit"
        )
    return best[1]


@dataclass(frozen=True)
class Timing:
    """What a stream's time column says: unit, nominal period, jitter, gaps and dropped rows.

    Attributes
    ----------
    unit : str
        Unit of the raw column (``s``, ``ms``, ``us``, ``ns``).
    unit_guessed : bool
        True when the unit came from the intervals, not from the name or the caller.
    period : float
        Nominal sample period in s.
    rows : int
        Rows read.
    kept : int
        Rows kept (``rows - duplicates - backwards``).
    jitter : float
        RMS deviation of the one-step intervals from the period, s.
    max_jitter : float
        Largest deviation of a one-step interval from the period, s.
    gaps : tuple of (int, int)
        ``(kept row, samples lost before it)`` for every interval of two or more periods.
    lost : int
        Samples lost in all gaps.
    duplicates, backwards : int
        Rows dropped for a time equal to, or before, the previous kept row's.
    first_dropped : int
        Index (in the rows read) of the first dropped row; -1 if none.
    source : str
        What the stream is (``gyr``, a file and topic ...), for the messages.

    """

    unit: str
    unit_guessed: bool
    period: float
    rows: int
    kept: int
    jitter: float
    max_jitter: float
    gaps: tuple[tuple[int, int], ...] = field(default=())
    lost: int = 0
    duplicates: int = 0
    backwards: int = 0
    first_dropped: int = -1
    source: str = ""

    @property
    def rate(self) -> float:
        """Nominal rate in Hz."""
        return 1.0 / self.period

    def summary(self) -> str:
        """One line: rate, unit, rows, jitter, gaps and dropped rows."""
        unit = f"{self.unit} (guessed)" if self.unit_guessed else self.unit
        text = (
            f"{self.source or 'time'}: {self.kept} samples at {self.rate:.6g} Hz (time in {unit}), "
            f"jitter {self.jitter * 1e6:.3g} us RMS / {self.max_jitter * 1e6:.3g} us max, "
            f"{len(self.gaps)} gap(s) with {self.lost} sample(s) lost"
        )
        if self.duplicates or self.backwards:
            text += f", {self.duplicates} duplicate and {self.backwards} out-of-order row(s) dropped"
        return text

    def warnings(self) -> list[str]:
        """The problems, one message each (empty for a clean stream)."""
        out: list[str] = []
        src = self.source or "time"
        if self.gaps:
            where = ", ".join(f"row {i} ({n})" for i, n in self.gaps[:5])
            more = f" and {len(self.gaps) - 5} more" if len(self.gaps) > 5 else ""
            longest = max(n for _, n in self.gaps)
            out.append(
                f"{src}: {self.lost} sample(s) lost in {len(self.gaps)} gap(s), the longest "
                f"{longest} ({longest * self.period:.3g} s), at {where}{more}; each gap is integrated "
                "as that many periods"
            )
        if self.duplicates:
            first = self.first_dropped
            out.append(f"{src}: {self.duplicates} row(s) with a repeated time dropped (first: row {first})")
        if self.backwards:
            out.append(f"{src}: {self.backwards} row(s) with a time before the previous row's dropped")
        if self.unit_guessed:
            out.append(f"{src}: time unit not stated, read as {self.unit} from the intervals")
        if self.max_jitter > 0.5 * self.period:
            out.append(f"{src}: jitter up to {self.max_jitter * 1e3:.3g} ms, over half the period")
        return out


@dataclass(frozen=True)
class Clock:
    """A stream's times after :func:`clock`: seconds, the rows kept and the steps between them.

    Attributes
    ----------
    time : ndarray, float64, shape (K,)
        Kept times in s (as recorded, not shifted to 0).
    keep : ndarray, bool, shape (N,)
        Which of the N rows read were kept.
    steps : ndarray, uint32, shape (K,)
        Periods each kept row advances the filter (1 for the first row).
    timing : Timing
        The report.

    """

    time: NDArray[np.float64]
    keep: NDArray[np.bool_]
    steps: NDArray[np.uint32]
    timing: Timing


def _monotonic(t: NDArray[np.float64]) -> tuple[NDArray[np.bool_], int, int]:
    """Rows kept when each must come after the last kept one; (keep, duplicates, backwards)."""
    keep = np.ones(t.shape[0], np.bool_)
    if t.size == 0:
        return keep, 0, 0
    # fast path: strictly increasing already
    d = np.diff(t)
    if np.all(d > 0):
        return keep, 0, 0
    dup = back = 0
    last = t[0]
    for i in range(1, t.shape[0]):
        if t[i] > last:
            last = t[i]
        else:
            keep[i] = False
            if t[i] == last:
                dup += 1
            else:
                back += 1
    return keep, dup, back


def steps_for(time: NDArray[np.float64], period: float) -> NDArray[np.uint32]:
    """Periods each sample advances: 1 first, then ``max(1, round(interval / period))``."""
    steps = np.ones(time.shape[0], np.uint32)
    if time.shape[0] > 1:
        k = np.rint(np.diff(time) / period)
        steps[1:] = np.maximum(k, 1.0).astype(np.uint32)
    return steps


def clock(
    raw: NDArray[np.float64] | list[float],
    unit: str | None = None,
    rate: float | None = None,
    name: str = "",
    source: str = "",
    default_unit: str | None = None,
) -> Clock:
    """Read a time column: its unit, the rows kept, the steps between them and a :class:`Timing`.

    Parameters
    ----------
    raw
        The column as recorded (any unit, any origin).
    unit
        ``s``, ``ms``, ``us`` or ``ns``; None: from ``name``, else guessed from the intervals.
    rate
        The nominal rate in Hz when known (a ``# rate=`` line, a bag's metadata); None: the median
        positive interval.
    name
        The column's name, for the unit.
    source
        What the stream is, for the messages.
    default_unit
        The unit a format documents for an unnamed column (``t`` of attica's CSV: s); a guess that
        agrees with it is not reported as a guess.

    Raises
    ------
    ValueError
        Non-finite times, an unknown unit, a bad rate, fewer than two distinct times, or a unit that
        cannot be told.

    """
    t_raw = np.asarray(raw, dtype=np.float64)
    if t_raw.ndim != 1:
        raise ValueError(f"{source or 'time'}: expected a 1-D time column, got shape {t_raw.shape}")
    if not np.all(np.isfinite(t_raw)):
        r = int(np.flatnonzero(~np.isfinite(t_raw))[0])
        raise ValueError(f"{source or 'time'}: row {r}: time is empty or not finite")
    guessed = False
    if unit is None:
        unit = unit_from_name(name)
    if unit is None and t_raw.shape[0] < 2 and default_unit is not None:
        unit = default_unit
    if unit is None:
        unit = guess_unit(t_raw)
        guessed = unit != default_unit
    if unit not in UNITS:
        raise ValueError(f"{source or 'time'}: unknown time unit {unit!r}; use one of {', '.join(UNITS)}")
    t = t_raw * UNITS[unit]
    keep, dup, back = _monotonic(t)
    kept = t[keep]
    if rate is not None:
        if not (math.isfinite(rate) and rate > 0.0):
            raise ValueError(f"{source or 'time'}: rate must be finite and > 0, got {rate}")
        period = 1.0 / rate
    else:
        d = np.diff(kept)
        if d.size == 0:
            raise ValueError(f"{source or 'time'}: need at least two distinct times for a rate")
        period = float(np.median(d))
        # the mean period over the whole span, gaps counted in periods: finer than one interval's median
        span = float(kept[-1] - kept[0])
        total = int(np.sum(steps_for(kept, period)[1:], dtype=np.int64))
        if total > 0 and span > 0:
            period = span / total
    steps = steps_for(kept, period)
    one = np.flatnonzero(steps[1:] == 1) + 1
    dev = np.diff(kept)[one - 1] - period if one.size else np.zeros(0)
    gap_rows = np.flatnonzero(steps > 1)
    gaps = tuple((int(i), int(steps[i]) - 1) for i in gap_rows)
    dropped = np.flatnonzero(~keep)
    timing = Timing(
        unit=unit,
        unit_guessed=guessed,
        period=period,
        rows=int(t.shape[0]),
        kept=int(kept.shape[0]),
        jitter=float(np.sqrt(np.mean(dev * dev))) if dev.size else 0.0,
        max_jitter=float(np.max(np.abs(dev))) if dev.size else 0.0,
        gaps=gaps,
        lost=int(sum(n for _, n in gaps)),
        duplicates=dup,
        backwards=back,
        first_dropped=int(dropped[0]) if dropped.size else -1,
        source=source,
    )
    return Clock(time=kept, keep=keep, steps=steps, timing=timing)


def report(timing: Timing, stacklevel: int = 3) -> None:
    """Each of ``timing.warnings()`` as a :class:`TimingWarning`."""
    import warnings

    for msg in timing.warnings():
        warnings.warn(msg, TimingWarning, stacklevel=stacklevel)


def hold_on(
    t_base: NDArray[np.float64], t: NDArray[np.float64], values: NDArray[np.floating]
) -> tuple[NDArray[np.float64], int]:
    """Zero-order hold: for each base time, the latest sample at or before it.

    Returns ``(held, first)``: held (K, C) float64, NaN before the first sample, and the index of the
    first base time that has a sample (K when none has).
    """
    v = np.asarray(values, dtype=np.float64)
    idx = np.searchsorted(t, t_base, side="right") - 1
    held = np.full((t_base.shape[0], v.shape[1]), np.nan)
    ok = idx >= 0
    held[ok] = v[idx[ok]]
    first = int(np.argmax(ok)) if ok.any() else int(t_base.shape[0])
    return held, first


def place_on(
    t_base: NDArray[np.float64], t: NDArray[np.float64], values: NDArray[np.floating]
) -> tuple[NDArray[np.float64], int]:
    """Each sample once, on the first base time at or after it; NaN rows elsewhere.

    Returns ``(placed, superseded)``: placed (K, C) float64, and how many samples were replaced by a
    later one that fell on the same base time (the latest wins). Samples after the last base time are
    not placed (they count as superseded).
    """
    v = np.asarray(values, dtype=np.float64)
    placed = np.full((t_base.shape[0], v.shape[1]), np.nan)
    pos = np.searchsorted(t_base, t, side="left")
    inside = pos < t_base.shape[0]
    pos_in = pos[inside]
    v_in = v[inside]
    # t is increasing, so pos_in is non-decreasing: the last sample of each run of one base row wins
    last = np.ones(pos_in.shape[0], np.bool_)
    last[:-1] = pos_in[1:] != pos_in[:-1]
    placed[pos_in[last]] = v_in[last]
    return placed, int(v.shape[0] - int(np.count_nonzero(last)))


def resample(
    t: NDArray[np.float64], rate: float, gyr: NDArray[np.floating], acc: NDArray[np.floating]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Gyro and accel linearly interpolated onto a uniform grid at ``rate`` Hz from ``t[0]``.

    For logs that are not clocked at all (phone apps): the method is stated in the result's report
    by the caller. Returns ``(grid, gyr, acc)``.
    """
    if not (math.isfinite(rate) and rate > 0.0):
        raise ValueError(f"resample: rate must be finite and > 0, got {rate}")
    n = int(math.floor((t[-1] - t[0]) * rate + 1e-9)) + 1
    grid = t[0] + np.arange(n, dtype=np.float64) / rate
    g = np.column_stack([np.interp(grid, t, np.asarray(gyr, np.float64)[:, k]) for k in range(3)])
    a = np.column_stack([np.interp(grid, t, np.asarray(acc, np.float64)[:, k]) for k in range(3)])
    return grid, g, a
