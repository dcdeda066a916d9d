"""Still periods in a recording: where the gyro offset and the accelerometer positions are measured.

A sample is *still* when, over the window of ``window`` s centred on it, every gyro axis and every
accelerometer axis has a standard deviation below its threshold and the gyro mean is below
``max_rate`` (a sensor turning steadily about the vertical has quiet signals but is not still).
The thresholds adapt to the sensor: ``factor`` times the 5th percentile of the windowed standard
deviations (the noise of the quietest moments), capped at ``gyro_cap`` rad/s and ``accel_cap`` m/s^2 so
a recording without any still moment finds none. Still runs shorter than ``min_duration`` are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["RestPeriods", "find_rest"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class RestPeriods:
    """Still runs of a recording.

    Attributes
    ----------
    segments : tuple of (start, stop)
        Sample index ranges (stop exclusive), each at least ``min_duration`` long.
    gyro_threshold : float
        Gyro standard deviation threshold used, rad/s.
    accel_threshold : float
        Accelerometer standard deviation threshold used, m/s^2.
    rate : float
        Sampling rate in Hz.

    """

    segments: tuple[tuple[int, int], ...]
    gyro_threshold: float
    accel_threshold: float
    rate: float

    @property
    def samples(self) -> int:
        """Number of still samples."""
        return sum(b - a for a, b in self.segments)

    @property
    def seconds(self) -> float:
        """Still time in s."""
        return self.samples / self.rate

    def mask(self, n: int) -> NDArray[np.bool_]:
        """Boolean mask over ``n`` samples."""
        m = np.zeros(n, np.bool_)
        for a, b in self.segments:
            m[a:b] = True
        return m


def _moving(x: F64, w: int) -> tuple[F64, F64]:
    """Centred moving mean and standard deviation over windows of ``w`` samples (edges: NaN)."""
    n = x.shape[0]
    mean = np.full(x.shape, np.nan)
    std = np.full(x.shape, np.nan)
    if n < w:
        return mean, std
    xc = x - np.median(x, axis=0)  # cumulative sums of centred data: no cancellation
    c1 = np.concatenate([np.zeros((1, x.shape[1])), np.cumsum(xc, axis=0)])
    c2 = np.concatenate([np.zeros((1, x.shape[1])), np.cumsum(xc * xc, axis=0)])
    s1 = c1[w:] - c1[:-w]
    s2 = c2[w:] - c2[:-w]
    m = s1 / w
    var = np.maximum(s2 / w - m * m, 0.0)
    lo = w // 2
    mean[lo : lo + n - w + 1] = m + np.median(x, axis=0)
    std[lo : lo + n - w + 1] = np.sqrt(var)
    return mean, std


def find_rest(
    gyr: NDArray[np.floating[Any]],
    acc: NDArray[np.floating[Any]],
    rate: float,
    window: float = 0.5,
    min_duration: float = 1.0,
    factor: float = 3.0,
    gyro_cap: float = 0.05,
    accel_cap: float = 0.5,
    max_rate: float = 0.35,
) -> RestPeriods:
    """The still periods of a recording (see the module docstring).

    Parameters
    ----------
    gyr, acc : ndarray, shape (N, 3)
        rad/s and m/s^2 (raw: offsets and scale errors do not matter).
    rate : float
        Hz.
    window, min_duration : float
        Seconds.
    factor, gyro_cap, accel_cap, max_rate : float
        Threshold rule; caps in rad/s and m/s^2, ``max_rate`` in rad/s.

    Returns
    -------
    RestPeriods

    """
    g = np.asarray(gyr, np.float64)
    a = np.asarray(acc, np.float64)
    if g.shape != a.shape or g.ndim != 2 or g.shape[1] != 3:
        raise ValueError(f"gyr and acc must both have shape (N, 3), got {g.shape} and {a.shape}")
    if not (rate > 0.0 and window > 0.0 and min_duration >= 0.0):
        raise ValueError("rate and window must be > 0 and min_duration >= 0")
    w = max(5, int(round(window * rate)))
    bad: NDArray[np.bool_] = np.asarray(~(np.isfinite(g).all(axis=1) & np.isfinite(a).all(axis=1)))
    g = np.where(bad[:, None], 0.0, g)
    a = np.where(bad[:, None], 0.0, a)
    g_mean, g_std = _moving(g, w)
    _, a_std = _moving(a, w)
    gs = np.max(g_std, axis=1)
    as_ = np.max(a_std, axis=1)
    finite = np.isfinite(gs)
    if not finite.any():
        return RestPeriods((), gyro_cap, accel_cap, rate)
    g_thr = float(min(gyro_cap, factor * max(np.percentile(gs[finite], 5), 1e-6)))
    a_thr = float(min(accel_cap, factor * max(np.percentile(as_[finite], 5), 1e-5)))
    with np.errstate(invalid="ignore"):
        still = finite & (gs < g_thr) & (as_ < a_thr) & (np.linalg.norm(g_mean, axis=1) < max_rate)
    # a sample with a non-finite value breaks its whole window
    if bad.any():
        near = np.convolve(bad.astype(np.float64), np.ones(w), mode="same") > 0
        still &= ~near
    flags = np.concatenate([[0], np.asarray(still, np.int8), [0]])
    edges = np.flatnonzero(np.diff(flags))
    min_len = max(1, int(round(min_duration * rate)))
    segs = tuple((int(s), int(e)) for s, e in zip(edges[0::2], edges[1::2], strict=True) if e - s >= min_len)
    return RestPeriods(segs, g_thr, a_thr, rate)
