"""Whether compensating the magnetometer's lag would help the 9-axis filters out of sample (issue 23).

``python -m attica_dev.mag_lag [BROAD_DIR]`` runs mars and mekf (defaults) on the BROAD trials with the
magnetometer advanced by L = 0 .. 6 samples (row t gets the sample recorded at row t + L, the last L rows
none), which is what a filter compensating a lag of L samples would see. Everything else is ``attica
eval``'s path: :func:`attica.evaluate.load_trials`, :func:`attica.evaluate.attica_method` (the default
preset) and :func:`attica.evaluate.parallel.score_trial` (the BROAD metric). It prints, per filter:

- the mean total and heading RMSE (deg) per L, in sample;
- leave-one-trial-out: each trial scored with the L best on the other trials;
- leave-one-condition-out: the trials of each disturbance condition (undisturbed, stationary magnet,
  attached magnet, office, mixed...) scored with the L best on the other conditions, since the trials
  of one condition share their field and a lag can trade against a condition's heading offset.

docs/accuracy.md quotes its output (tests/test_mag_lag.py recomputes the table). It takes about 7 s.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from attica.data.recording import Recording
from attica.evaluate import attica_method, load_trials
from attica.evaluate.parallel import score_trial
from attica.settings import FilterKind, Preset

LAGS = (0, 1, 2, 3, 4, 5, 6)
"""The lags tried, samples (BROAD's magnetometer lags its gyro by about 3 samples)."""

FILTERS = {"mars": FilterKind.MARS, "mekf": FilterKind.MEKF}

CONDITIONS = ("stationary_magnet", "attached_magnet", "office", "mixed")
"""BROAD's disturbance conditions; a trial in none of them is ``undisturbed``."""


def advanced(rec: Recording, lag: int) -> Recording:
    """``rec`` with its magnetometer advanced by ``lag`` rows (the last ``lag`` rows: no sample)."""
    if lag == 0:
        return rec
    mag = np.full_like(rec.mag, np.nan)
    mag[:-lag] = rec.mag[lag:]
    return dataclasses.replace(rec, mag=mag)


def condition(rec: Recording) -> str:
    """The trial's disturbance condition (one of :data:`CONDITIONS`, else ``undisturbed``)."""
    return next((c for c in CONDITIONS if c in rec.groups), "undisturbed")


def held_out(scores: NDArray[np.float64], units: Sequence[str]) -> tuple[NDArray[np.float64], list[int]]:
    """Each unit's trials scored with the lag best (lowest mean) on the trials of the other units.

    Parameters
    ----------
    scores : ndarray, shape (lags, trials)
        RMSE, deg.
    units : sequence of str
        The unit held out with each trial (its own name for leave-one-trial-out).

    Returns
    -------
    ndarray, list of int
        The held-out score of every trial, and the index of the lag chosen for it.

    """
    out = np.empty(scores.shape[1])
    chosen = [0] * scores.shape[1]
    for u in dict.fromkeys(units):
        mask = np.array([x == u for x in units])
        i = int(np.argmin(scores[:, ~mask].mean(axis=1)))
        out[mask] = scores[i, mask]
        for t in np.nonzero(mask)[0]:
            chosen[int(t)] = i
    return out, chosen


@dataclass(frozen=True)
class LagResult:
    """One filter's errors per lag and the out-of-sample choices of the lag.

    Attributes
    ----------
    total, heading, inclination : ndarray, shape (lags, trials)
        RMSE, deg, per lag of :data:`LAGS` and trial.
    by_trial, by_condition : float
        Mean over the trials of the held-out scores, leaving out one trial / one condition at a time.
    lags_trial, lags_condition : tuple of int
        The lags chosen in those folds.

    """

    total: NDArray[np.float64]
    heading: NDArray[np.float64]
    inclination: NDArray[np.float64]
    by_trial: float
    by_condition: float
    lags_trial: tuple[int, ...]
    lags_condition: tuple[int, ...]


def measure(recs: Sequence[Recording], kind: FilterKind) -> LagResult:
    """Run ``kind`` (defaults) on ``recs`` at every lag of :data:`LAGS` and choose the lag out of sample."""
    err = np.empty((3, len(LAGS), len(recs)))
    for j, rec in enumerate(recs):
        for i, lag in enumerate(LAGS):
            e = score_trial(attica_method(kind, Preset.DEFAULT), advanced(rec, lag)).errors
            err[:, i, j] = (e.total, e.heading, e.inclination)
    by_trial, c_trial = held_out(err[0], [r.name for r in recs])
    by_cond, c_cond = held_out(err[0], [condition(r) for r in recs])
    return LagResult(
        err[0],
        err[1],
        err[2],
        float(by_trial.mean()),
        float(by_cond.mean()),
        tuple(sorted({LAGS[c] for c in c_trial})),
        tuple(sorted({LAGS[c] for c in c_cond})),
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: print the figures of every filter of :data:`FILTERS`."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("data", nargs="?", default="../shared/data/broad", help="BROAD trials folder")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    recs = load_trials(args.data)
    for name, kind in FILTERS.items():
        r = measure(recs, kind)
        print(f"{name}: mean RMSE (deg) per lag L, in sample")
        print("   L  " + " ".join(f"{lag:>6}" for lag in LAGS))
        print("total " + " ".join(f"{x:6.3f}" for x in r.total.mean(axis=1)))
        print("head. " + " ".join(f"{x:6.3f}" for x in r.heading.mean(axis=1)))
        base = r.total[0].mean()
        print(f"  leave-one-trial-out: {r.by_trial:.3f} (L = 0: {base:.3f}; L chosen {list(r.lags_trial)})")
        print(f"  leave-one-condition-out: {r.by_condition:.3f} (L chosen {list(r.lags_condition)})")
        best = int(np.argmin(r.total.mean(axis=1)))
        gain = r.total[0] - r.total[best]
        top = np.argsort(-gain)[:2]
        share = 100.0 * gain[top].sum() / max(gain.sum(), 1e-12)
        rest = np.ones(len(recs), np.bool_)
        rest[top] = False
        inc = r.inclination.mean(axis=1)
        print(
            f"  best L = {LAGS[best]}: better than L = 0 in {int(np.sum(gain > 0))} of {len(recs)} trials; "
            f"the two largest gains ({', '.join(recs[t].name[:2] for t in top)}) are {share:.0f} % of it; "
            f"without them the mean gain is {gain[rest].mean():.3f} deg\n"
            f"  inclination over the lags: {inc.min():.3f} .. {inc.max():.3f} deg\n"
        )
    print(f"{len(recs)} trials in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
