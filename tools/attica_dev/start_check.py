"""The first seconds after the start, which the suite does not score (issue 23).

``python -m attica_dev.start_check`` runs the suite's conditions ``baseline``, ``consumer`` and
``vibration`` (10 seeds each, every method on its defaults as in ``attica eval --suite``) and prints
per method the RMSE over the first second and over 1-5 s after the first sample (inclination for the
6-axis methods, total for the 9-axis ones, deg). The suite scores from 5 s
(:data:`attica.evaluate.suite.CONVERGENCE`); a user sees the start too, and under the suite's 40 Hz
vibration the first accel sample alone is up to 18 deg off. docs/filters.md ("The start is a
recovery") quotes its output. It takes a few seconds.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Sequence

import numpy as np

from attica.evaluate.estimate import as_estimate
from attica.evaluate.suite import condition, suite_methods
from attica.metrics import error_angles
from attica.sim import simulate_with_truth

CONDITIONS = ("baseline", "consumer", "vibration")
KINDS = ("ars", "kf", "ekf", "mekf6", "mars", "mekf")
PEERS = ("vqf6", "vqf9", "fusion6", "fusion9")
WINDOWS = ((0.0, 1.0), (1.0, 5.0))
"""The windows scored, s after the first sample."""


def measure(cond_name: str, seeds: Sequence[int]) -> dict[str, list[float]]:
    """Per method the RMSE (deg) in each of :data:`WINDOWS`, mean over ``seeds``."""
    cond = condition(cond_name)
    acc: dict[str, list[list[float]]] = {}
    for seed in seeds:
        rec, _ = simulate_with_truth(cond.config(seed, None))
        assert rec.quat_true is not None
        t = rec.t - rec.t[0]
        for m in suite_methods(KINDS, PEERS, cond.gyro_range):
            est = as_estimate(m.outcome(rec), len(rec), m.name)
            total, _, incl = error_angles(est.q, rec.quat_true)
            err = np.degrees(total if m.nine_axis else incl)
            row = [math.sqrt(float(np.mean(err[(t >= a) & (t < b)] ** 2))) for a, b in WINDOWS]
            acc.setdefault(m.name, []).append(row)
    return {name: np.mean(np.asarray(rows), axis=0).tolist() for name, rows in acc.items()}


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: one table per condition."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("--seeds", type=int, default=10, help="seeds 1 .. N")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    seeds = range(1, args.seeds + 1)
    names = [*KINDS, *PEERS]
    print("RMSE after the first sample, deg (6-axis: inclination, 9-axis: total): 0-1 s / 1-5 s")
    print(f"{'condition':12s}" + "".join(f"{n:>13s}" for n in names))
    for c in CONDITIONS:
        r = measure(c, seeds)
        print(f"{c:12s}" + "".join(f"{r[n][0]:6.2f}/{r[n][1]:<6.2f}" for n in names))
    print(f"{args.seeds} seeds in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
