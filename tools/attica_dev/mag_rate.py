"""mars and mekf with a magnetometer slower than the gyro (issue 23, stop 46).

``python -m attica_dev.mag_rate`` prints two tables that docs/accuracy.md quotes:

- the steady heading error of mars under a constant gyro bias it does not estimate (0.01 rad/s, still
  sensor, ``tau_mag`` 2 s, no fast phase), over ``bias * tau_mag``: 1 for a complementary correction whose
  time constant is ``tau_mag`` in seconds, with a mag sample every 1, 10 and 50 steps;
- mars's and mekf's total RMSE (deg, the suite's scoring from 5 s) on simulated 1 kHz recordings (60 s,
  seeds 1-3) with the magnetometer every 1, 4, 10 and 20 steps, absent (NaN) between its samples as
  attica's loaders place it, and 10 held (the last sample repeated on every step).

About 3 s.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
from collections.abc import Sequence

import numpy as np

from attica import native
from attica.data import Recording
from attica.evaluate.core import attica_method, method_kind
from attica.evaluate.suite import score_method
from attica.evaluate.trace import euler_deg
from attica.settings import BiasMode, FilterKind, make_settings
from attica.sim import SimConfig, simulate

EVERY = (1, 4, 10, 20)
SEEDS = (1, 2, 3)


def steady_ratio(every: int, bias: float = 0.01, tau: float = 2.0) -> float:
    """Mars's mean yaw error over the last 10 s of 60 s, over bias * tau_mag (mag every ``every`` steps)."""
    n, dt = 6000, float(np.float32(0.01))
    gyr = np.tile(np.array([0.0, 0.0, bias], np.float32), (n, 1))
    acc = np.tile(np.array([0.0, 0.0, 9.80665], np.float32), (n, 1))
    mag = np.tile(np.array([0.0, 20.0, -40.0], np.float32), (n, 1))
    mag[np.arange(n) % every != 0] = np.nan
    s = make_settings(FilterKind.MARS, dt=dt, tau_mag=tau, tau_mag_fast=0.0, bias_mode=BiasMode.OFF)
    q = native.Filter(FilterKind.MARS, s).run(gyr, acc, mag, check_units=False)["q"].astype(np.float64)
    yaw = np.radians(euler_deg(q)[:, 2])
    return float(yaw[-1000:].mean() / (bias * tau))


@functools.cache
def _recording(seed: int) -> Recording:
    return simulate(SimConfig(duration=60.0, rate=1000.0, seed=seed))


def rmse(kind: str, every: int, held: bool = False, seeds: Sequence[int] = SEEDS) -> float:
    """Mean total RMSE (deg) over ``seeds`` of 60 s at 1 kHz, the mag every ``every`` steps."""
    m = attica_method(method_kind(kind))
    out = []
    for seed in seeds:
        rec = _recording(seed)
        idx = np.arange(len(rec))
        new = idx % every == 0
        if held:
            mag = rec.mag[np.maximum.accumulate(np.where(new, idx, 0))]
        else:
            mag = rec.mag.copy()
            mag[~new] = np.nan
        out.append(score_method(m, dataclasses.replace(rec, mag=mag.astype(np.float32)), 5.0)[0].total)
    return float(np.mean(out))


def tables() -> str:
    """Both tables as Markdown."""
    lines = ["| mag every | 1 step | 10 steps | 50 steps |", "|---|---:|---:|---:|"]
    lines.append(
        "| mars: heading error / (bias tau_mag) | "
        + " | ".join(f"{steady_ratio(e):.3f}" for e in (1, 10, 50))
        + " |"
    )
    lines += [
        "",
        "| 1 kHz IMU, mag every | " + " | ".join(f"{e}" for e in EVERY) + " | 10, held |",
        "|---|" + "---:|" * (len(EVERY) + 1),
    ]
    for kind in ("mars", "mekf"):
        cells = [f"{rmse(kind, e):.3f}" for e in EVERY] + [f"{rmse(kind, 10, held=True):.3f}"]
        lines.append(f"| {kind} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Print the tables."""
    p = argparse.ArgumentParser(prog="python -m attica_dev.mag_rate", description=__doc__.split("\n")[0])
    p.parse_args(argv)
    print(tables())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
