"""The clipping streams of the recovery tests (tests/test_{ars,kf,ekf,mekf}_recovery.py): 100 Hz, a gyro of
500 deg/s full scale, three turns to 14 rad/s that clip it."""

from __future__ import annotations

from typing import Any

import numpy as np

from attica.sim import SimConfig, simulate

RATE = 100.0
CLIP = float(np.radians(500.0))  # rad/s: a gyro of 500 deg/s full scale
SPINS = tuple((t, 1.0, 14.0, (0.3, 0.4, 0.866)) for t in (10.0, 22.0, 34.0))  # turns to 14 rad/s: clipped
INITIALISED = 0x400


def clipping(seed: int, duration: float = 40.0) -> Any:
    """A simulated recording whose gyro clips in each of the three turns."""
    return simulate(SimConfig(duration=duration, rate=RATE, seed=seed, gyro_clip=CLIP, spins=SPINS))


def clipped_rows(gyr: Any) -> Any:
    """Rows with any |w_i| at 98 % of the range or beyond (the filters' clipping test)."""
    return (np.abs(gyr) >= 0.98 * np.float32(CLIP)).any(axis=1)
