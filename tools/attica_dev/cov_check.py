"""How well each kind's stated orientation covariance matches its errors on BROAD (issue 23).

``python -m attica_dev.cov_check [BROAD_DIR]`` runs every kind that reports a covariance (ars, kf, ekf,
the mekf with and without the magnetometer, mars) with its defaults on the BROAD trials (as ``attica
eval`` does: one period per row, lost rows stepped over) and compares, over each trial's scored rows,
the mean squared error with the mean variance the output states, as the ROS ``sensor_msgs/Imu`` of
the MCAP output carries it (:func:`attica.data.covariance.orientation_covariance`: the kind's
variances about the earth's axes):

- tilt: the inclination error squared against the sum of the two horizontal axes' variances;
- heading (the 9-axis methods, mars and mekf): the heading error squared against the vertical axis's.

The comparison per recording is ``attica eval``'s (:func:`attica.metrics.stated`, which its
``stated_ratio`` pools); this tool adds the leave-one-out, the per-trial spread and the simulator.

ars and mars state a documented model of their fixed-gain corrections (docs/filters.md, "Covariance
of the complementary filters"), whose default densities were chosen from the pooled in-sample ratios
here; the Kalman kinds (kf, ekf, mekf) state their own P, which follows from the settings chosen for
the attitude. It does the same on the simulator, for every condition of ``attica eval --suite``
(seeds 1-3, scored from 5 s or the condition's start; the sensor's gyro range given where the
condition sets one).

A ratio of 1 is a consistent model; above 1 it is optimistic, below 1 conservative. It prints the
ratio pooled over the trials (the mean squared error of all trials over their mean variance), its
leave-one-trial-out form (each trial's ratio after scaling the model by the pooled ratio of the other
19, the way a default density chosen on the other trials would), and the spread of the per-trial
ratios. docs/accuracy.md quotes this output (tests/test_cov_model.py recomputes it).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica import metrics
from attica.data.recording import Recording
from attica.evaluate import VARIANTS, attica_method, load_trials, method_kind

F64 = NDArray[np.float64]

METHODS = ("ars", "kf", "ekf", "mekf6", "mars", "mekf")
"""The methods measured, as ``attica eval`` names them (mekf6: the mekf with ``use_mag`` off)."""

NINE_AXIS = ("mars", "mekf")
"""The methods whose heading is measured (the others' is not observed: pi^2/3, unknown)."""


@dataclass(frozen=True)
class Consistency:
    """Per trial: mean squared error and mean stated variance (rad^2) of one angle.

    Attributes
    ----------
    mse, var : ndarray, shape (trials,)
        Over the trial's scored rows.

    """

    mse: F64
    var: F64

    @property
    def pooled(self) -> float:
        """Mean squared error of all trials over their mean variance."""
        return float(self.mse.mean() / self.var.mean())

    @property
    def per_trial(self) -> F64:
        """Each trial's ratio."""
        return self.mse / self.var

    def held_out(self) -> F64:
        """Each trial's ratio with the model scaled by the pooled ratio of the other trials."""
        out = np.empty(len(self.mse))
        for t in range(len(self.mse)):
            rest = np.arange(len(self.mse)) != t
            scale = self.mse[rest].mean() / self.var[rest].mean()
            out[t] = self.mse[t] / (self.var[t] * scale)
        return out


def measure(recs: Sequence[Recording], name: str) -> dict[str, Consistency]:
    """Run method ``name`` (:data:`METHODS`) on ``recs``: its tilt's and (9-axis) heading's consistency."""
    return _result(name, [_stated(name, rec, rec.movement) for rec in recs])


def _stated(name: str, rec: Recording, scored: Any, **over: Any) -> metrics.Stated:
    """``name`` (defaults and ``over``) on ``rec``: its stated covariance against its errors over ``scored``.

    As ``attica eval`` computes it (:func:`attica.metrics.stated` of the estimate's covariance).
    """
    variant = name if name in VARIANTS else ""
    m = attica_method(method_kind(name), overrides=over, variant=variant, covariance=True)
    assert m.estimate is not None and rec.quat_true is not None, rec.name
    est = m.estimate(rec)
    assert est.cov is not None, name
    return metrics.stated(est.q, rec.quat_true, est.cov, scored)


def _result(name: str, rows: Sequence[metrics.Stated]) -> dict[str, Consistency]:
    out = {
        "tilt": Consistency(
            np.array([r.inclination_mse for r in rows]), np.array([r.inclination_var for r in rows])
        )
    }
    if name in NINE_AXIS:
        out["heading"] = Consistency(
            np.array([r.heading_mse for r in rows]), np.array([r.heading_var for r in rows])
        )
    return out


def simulated(name: str, seeds: Sequence[int] = (1, 2, 3)) -> dict[str, dict[str, Consistency]]:
    """Per condition of the suite: the consistency of method ``name`` over ``seeds`` (one entry per seed)."""
    from attica.evaluate.suite import CONDITIONS, CONVERGENCE
    from attica.sim import simulate_with_truth

    out = {}
    for cond in CONDITIONS:
        over = {"gyro_range": cond.gyro_range} if cond.gyro_range > 0 else {}
        rows = []
        for seed in seeds:
            rec, _ = simulate_with_truth(cond.config(seed))
            rows.append(_stated(name, rec, rec.t >= max(CONVERGENCE, cond.score_from), **over))
        out[cond.name] = _result(name, rows)
    return out


def columns() -> list[tuple[str, str]]:
    """The (method, angle) pairs measured, in the order of the tables: every tilt, then the headings."""
    return [(m, "tilt") for m in METHODS] + [(m, "heading") for m in NINE_AXIS]


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: print the consistency of every kind's covariance on BROAD and the simulator."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("data", nargs="?", default="../shared/data/broad", help="BROAD trials folder")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    recs = load_trials(args.data)
    print("method angle    RMS error stated RMS pooled  held out (pooled)  per trial min-median-max")
    for name in METHODS:
        for angle, c in measure(recs, name).items():
            held = c.held_out()
            r = c.per_trial
            print(
                f"{name:<6} {angle:<8} {np.degrees(np.sqrt(c.mse.mean())):6.2f} deg "
                f"{np.degrees(np.sqrt(c.var.mean())):6.2f} deg  {c.pooled:6.2f}  "
                f"{float(np.mean(held * c.var) / np.mean(c.var)):6.2f}             "
                f"{r.min():.2f} - {np.median(r):.2f} - {r.max():.2f}"
            )
    print(f"{len(recs)} trials in {time.perf_counter() - t0:.1f} s\n")
    cols = columns()
    print("simulator, pooled ratio per condition (seeds 1-3): " + ", ".join(f"{m} {a}" for m, a in cols))
    sims = {name: simulated(name) for name in METHODS}
    for cond in sims["ars"]:
        print(f"{cond:<14} " + " ".join(f"{sims[m][cond][a].pooled:7.2f}" for m, a in cols))
    print(f"in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
