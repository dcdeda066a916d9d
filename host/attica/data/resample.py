"""A recording on a uniform clock, for logs that are not clocked at all (``attica run --resample HZ``).

The method, stated in the result's ``timing.source`` and in docs/recordings.md:

- gyro and accel: linear interpolation between the two samples around each grid time;
- magnetometer: each sample placed once, on the first grid time at or after it (never interpolated);
- ground truth: the sample nearest each grid time (quaternions are not averaged); movement likewise.

A gap in the log is bridged by the straight line between its ends instead of being stepped over, so
resample only what has no usable clock: a clocked log with gaps is better stepped as it is
(:attr:`attica.data.Recording.steps`).
"""

from __future__ import annotations

import math

import numpy as np

from attica.data import timing as tm
from attica.data.recording import Recording

METHOD = "gyro/accel linear interpolation, mag placed once, truth nearest"
"""The method in words (printed by the CLI)."""


def resample(rec: Recording, rate: float) -> Recording:
    """``rec`` on a uniform grid at ``rate`` Hz from its first time (see the module docstring).

    Raises
    ------
    ValueError
        A rate that is not finite and > 0, or fewer than two samples.

    """
    if not (math.isfinite(rate) and rate > 0.0):
        raise ValueError(f"resample: the rate must be finite and > 0 Hz, got {rate}")
    if rec.n < 2:
        raise ValueError("resample: needs at least two samples")
    t = rec.time if rec.time is not None else rec.t
    grid, gyr, acc = tm.resample(t, rate, rec.gyr, rec.acc)
    has = np.isfinite(rec.mag).all(axis=1)
    mag, _ = tm.place_on(grid, t[has], rec.mag[has])
    near = np.clip(np.searchsorted(t, grid), 0, rec.n - 1)
    prev = np.clip(near - 1, 0, rec.n - 1)
    near = np.where(np.abs(t[prev] - grid) < np.abs(t[near] - grid), prev, near)
    timing = tm.Timing(
        unit="s",
        unit_guessed=False,
        period=1.0 / rate,
        rows=rec.n,
        kept=int(grid.shape[0]),
        jitter=0.0,
        max_jitter=0.0,
        source=f"{rec.name or 'recording'} resampled to {rate:g} Hz ({METHOD})",
    )
    return Recording(
        gyr=gyr.astype(np.float32),
        acc=acc.astype(np.float32),
        mag=mag.astype(np.float32),
        rate=rate,
        quat_true=rec.quat_true[near] if rec.quat_true is not None else None,
        movement=rec.movement[near] if rec.movement is not None else None,
        name=rec.name,
        groups=rec.groups,
        time=grid,
        timing=timing,
    )
