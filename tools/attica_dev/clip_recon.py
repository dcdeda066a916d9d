"""Whether the rotation a clipping gyro loses can be put back from the rate around the clip (issue 23).

``python -m attica_dev.clip_recon`` runs the suite's ``clipped`` condition (10 seeds, its scoring)
with the gyro as recorded, the same recording without the clip, and the gyro repaired two ways, each
filter on its defaults:

- ``shipped``: the clipped gyro, the filters told the range (their recovery after a clipping gyro);
- ``unclipped``: the same recording simulated without the clip (same seed, same noise): the bound;
- ``replaced``: on every axis each clipped run replaced by a parabola fitted (least squares) to the
  :data:`FIT` samples before and after it, where that is above the clipped value: an offline repair,
  since the run's samples are rewritten after its end;
- ``at end``: the same parabola's lost rotation (its area above the clipped value) added on that axis to
  the sample :data:`FIT` after the run, the first one at which a filter running in real time could make
  the fit.

The repaired streams go to the filters with ``gyro_range`` at its maximum (1000 rad/s), so that no
recovery starts. It prints the RMSE after 5 s (inclination for 6-axis, total for 9-axis, deg) and
the episodes back within 2 deg within 2 s, per filter and stream. docs/accuracy.md quotes its output
(the clip section of issue 23). It takes a few seconds.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from attica.evaluate.estimate import as_estimate
from attica.evaluate.suite import _episodes, condition, recovery_times, suite_methods
from attica.metrics import error_angles
from attica.sim import simulate_with_truth

FIT = 4
"""Samples on each side of a clipped run used for the parabola."""

KINDS = ("ars", "mekf6", "mars", "mekf")
STREAMS = ("shipped", "unclipped", "replaced", "at end")
NO_RANGE = 1000.0
"""``gyro_range`` for the repaired streams (its maximum): no sample counts as clipped."""

F32 = NDArray[np.float32]


def _runs(clipped: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """(first, one past the last) sample of each run of True."""
    d = np.diff(np.concatenate([[0], clipped.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def reconstruct(gyr: F32, clip: float, fit: int = FIT) -> tuple[F32, F32]:
    """The gyro with each clipped run replaced by the fitted parabola, and with its area added at the end.

    Parameters
    ----------
    gyr : ndarray, float32, shape (N, 3)
        Gyro samples in rad/s, clipped at ``clip``.
    clip : float
        The clipping level in rad/s (a sample with ``|w| >= clip`` on an axis is clipped there).
    fit : int
        Samples before and after each run fitted; runs with fewer around them are left alone.

    Returns
    -------
    replaced, at_end : ndarray, float32, shape (N, 3)
        The repaired streams (see the module's description).

    """
    g = gyr.astype(np.float64)
    replaced = gyr.copy()
    at_end = gyr.copy()
    for ax in range(3):
        for s, e in _runs(np.abs(g[:, ax]) >= clip):
            if s < fit or e + fit > len(g):
                continue
            sign = math.copysign(1.0, g[s, ax])
            t = np.concatenate([np.arange(s - fit, s), np.arange(e, e + fit)]).astype(np.float64)
            y = np.concatenate([g[s - fit : s, ax], g[e : e + fit, ax]]) * sign
            coef = np.linalg.lstsq(np.stack([np.ones_like(t), t, t * t], axis=1), y, rcond=None)[0]
            tt = np.arange(s, e, dtype=np.float64)
            peak = np.maximum(coef[0] + coef[1] * tt + coef[2] * tt * tt, g[s:e, ax] * sign)
            replaced[s:e, ax] = (peak * sign).astype(np.float32)
            at_end[e + fit - 1, ax] += np.float32(np.sum(peak - g[s:e, ax] * sign) * sign)
    return replaced, at_end


def measure(
    seeds: Sequence[int], kinds: Sequence[str] = KINDS
) -> dict[tuple[str, str], tuple[float, int, int]]:
    """Per (kind, stream): the mean RMSE over ``seeds`` (deg), episodes within 2 s and episodes in all."""
    cond = condition("clipped")
    rmse: dict[tuple[str, str], list[float]] = {}
    times: dict[tuple[str, str], list[float]] = {}
    for seed in seeds:
        cfg = cond.config(seed, None)
        rec, truth = simulate_with_truth(cfg)
        assert rec.quat_true is not None
        episodes = _episodes(np.asarray(truth.gyr_clipped.any(axis=1), np.bool_), rec.rate)
        scored = rec.t >= cond.score_from
        unclipped, _ = simulate_with_truth(dataclasses.replace(cfg, gyro_clip=0.0))
        replaced, at_end = reconstruct(rec.gyr, cond.gyro_range * 0.98)
        streams = {
            "shipped": (rec, cond.gyro_range),
            "unclipped": (unclipped, NO_RANGE),
            "replaced": (dataclasses.replace(rec, gyr=replaced), NO_RANGE),
            "at end": (dataclasses.replace(rec, gyr=at_end), NO_RANGE),
        }
        for stream, (r, rng) in streams.items():
            for m in suite_methods(kinds, [], rng):
                est = as_estimate(m.outcome(r), len(r), m.name)
                total, _, incl = error_angles(est.q, rec.quat_true)
                err = np.degrees(total if m.nine_axis else incl)
                rmse.setdefault((m.name, stream), []).append(math.sqrt(float(np.mean(err[scored] ** 2))))
                times.setdefault((m.name, stream), []).extend(recovery_times(err, episodes, rec.rate))
    out = {}
    for key, errs in rmse.items():
        t = np.asarray(times[key])
        out[key] = (float(np.mean(errs)), int(np.sum(t <= 2.0)), int(t.size))
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: print the table of :func:`measure`."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("--seeds", type=int, default=10, help="seeds 1 .. N of the suite's clipped condition")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    res = measure(range(1, args.seeds + 1))
    print("RMSE after 5 s, deg (episodes back within 2 deg in 2 s)")
    print(f"{'':8s}" + "".join(f"{s:>18s}" for s in STREAMS))
    for kind in KINDS:
        cells = [res[(kind, s)] for s in STREAMS]
        print(f"{kind:8s}" + "".join(f"{r:8.2f} ({n:2d}/{m:2d})".rjust(18) for r, n, m in cells))
    print(f"{args.seeds} seeds in {time.perf_counter() - t0:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
