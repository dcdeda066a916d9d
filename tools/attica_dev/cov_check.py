"""How well the complementary filters' covariance model matches their errors on BROAD (issue 23).

``python -m attica_dev.cov_check [BROAD_DIR]`` runs ars and mars with their defaults on the BROAD trials
(as ``attica eval`` does: one period per row, lost rows stepped over) and compares, over each trial's
scored rows, the mean squared error with the mean variance the output's ``cov`` states:

- tilt: the inclination error squared against cov[0] + cov[1] (the tilt's two axes);
- heading (mars): the heading error squared against cov[2].

It does the same on the simulator, for every condition of ``attica eval --suite`` (seeds 1-3, scored
from 5 s or the condition's start; the sensor's gyro range given where the condition sets one).

A ratio of 1 is a consistent model; above 1 it is optimistic. It prints the ratio pooled over the
trials (the mean squared error of all trials over their mean variance), its leave-one-trial-out form
(each trial's ratio after scaling the model by the pooled ratio of the other 19, the way a default
density chosen on the other trials would), and the spread of the per-trial ratios. The default
densities of att_ars.h and att_mars.h were chosen from the pooled in-sample ratios (docs/filters.md
"Covariance"); docs/accuracy.md quotes this output (tests/test_cov_model.py recomputes it).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica import metrics, native
from attica.data.recording import Recording
from attica.evaluate import load_trials
from attica.settings import FilterKind, Preset, preset_settings

F64 = NDArray[np.float64]


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


def measure(recs: Sequence[Recording], kind: FilterKind) -> dict[str, Consistency]:
    """Run ``kind`` (defaults) on ``recs``: the tilt's and (mars) the heading's consistency."""
    rows: dict[str, list[tuple[float, float]]] = {"tilt": [], "heading": []}
    for rec in recs:
        incl, head, cov = _run(kind, rec)
        scored = np.ones(len(rec), np.bool_) if rec.movement is None else rec.movement.copy()
        _add(rows, incl, head, cov, scored)
    return _result(kind, rows)


def _run(kind: FilterKind, rec: Recording, **over: Any) -> tuple[F64, F64, F64]:
    """(inclination, heading errors (rad), cov) of ``kind`` (defaults and ``over``) on ``rec``."""
    s = dataclasses.replace(preset_settings(kind, Preset.DEFAULT, dt=1.0 / rec.rate), **over)
    out = native.Filter(kind, settings=s).run(
        rec.gyr, rec.acc, rec.mag, check_units=False, steps=rec.steps if rec.lost else None
    )
    assert rec.quat_true is not None, rec.name
    _, heading, inclination = metrics.error_angles(out["q"].astype(np.float64), rec.quat_true)
    return inclination, heading, out["cov"].astype(np.float64)


def _add(rows: dict[str, list[tuple[float, float]]], incl: F64, head: F64, cov: F64, scored: Any) -> None:
    scored = scored & np.isfinite(incl)
    rows["tilt"].append((float(np.mean(incl[scored] ** 2)), float(np.mean(cov[scored, 0] + cov[scored, 1]))))
    rows["heading"].append((float(np.mean(head[scored] ** 2)), float(np.mean(cov[scored, 2]))))


def _result(kind: FilterKind, rows: dict[str, list[tuple[float, float]]]) -> dict[str, Consistency]:
    names = ("tilt", "heading") if kind == FilterKind.MARS else ("tilt",)
    return {
        n: Consistency(np.array([r[0] for r in rows[n]]), np.array([r[1] for r in rows[n]])) for n in names
    }


def simulated(kind: FilterKind, seeds: Sequence[int] = (1, 2, 3)) -> dict[str, dict[str, Consistency]]:
    """Per condition of the suite: the consistency of ``kind`` over ``seeds`` (one entry per seed)."""
    from attica.evaluate.suite import CONDITIONS, CONVERGENCE
    from attica.sim import simulate_with_truth

    out = {}
    for cond in CONDITIONS:
        rows: dict[str, list[tuple[float, float]]] = {"tilt": [], "heading": []}
        over = {"gyro_range": cond.gyro_range} if cond.gyro_range > 0 else {}
        for seed in seeds:
            rec, _ = simulate_with_truth(cond.config(seed))
            incl, head, cov = _run(kind, rec, **over)
            _add(rows, incl, head, cov, rec.t >= max(CONVERGENCE, cond.score_from))
        out[cond.name] = _result(kind, rows)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: print the consistency of ars and mars on the BROAD trials."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("data", nargs="?", default="../shared/data/broad", help="BROAD trials folder")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    recs = load_trials(args.data)
    print("kind  angle    RMS error  model RMS  pooled  held out (pooled)  per trial min-median-max")
    for kind in (FilterKind.ARS, FilterKind.MARS):
        for name, c in measure(recs, kind).items():
            held = c.held_out()
            r = c.per_trial
            print(
                f"{kind.label:<5} {name:<8} {np.degrees(np.sqrt(c.mse.mean())):7.2f} deg "
                f"{np.degrees(np.sqrt(c.var.mean())):6.2f} deg  {c.pooled:6.2f}  "
                f"{float(np.mean(held * c.var) / np.mean(c.var)):6.2f}             "
                f"{r.min():.2f} - {np.median(r):.2f} - {r.max():.2f}"
            )
    print(f"{len(recs)} trials in {time.perf_counter() - t0:.1f} s\n")
    print("simulator, pooled ratio per condition (seeds 1-3): ars tilt, mars tilt, mars heading")
    sims = {kind: simulated(kind) for kind in (FilterKind.ARS, FilterKind.MARS)}
    for cond in sims[FilterKind.ARS]:
        a = sims[FilterKind.ARS][cond]["tilt"].pooled
        m = sims[FilterKind.MARS][cond]
        print(f"{cond:<14} {a:6.2f} {m['tilt'].pooled:6.2f} {m['heading'].pooled:6.2f}")
    print(f"in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
