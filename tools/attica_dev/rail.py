"""A gyro that saturates a little beyond the ``gyro_range`` it was given (issue 23, session 10).

``python -m attica_dev.rail`` runs the suite's ``clipped`` condition (seeds 1-10, the gyro clipped at
500 deg/s) with each kind's ``gyro_range`` set to a fraction of the sensor's rail: 1 (the suite), 0.9999
(the data sheet's range just below the part's last code) and 0.8. It prints each kind's mean RMSE as
the suite scores it (inclination for 6-axis kinds, total for 9-axis ones) and its clip recovery count.
A component beyond ``gyro_range`` and within twice it is integrated as read (att_core.h
``att_i_gyro_usable``), so the first two rows are equal. docs/accuracy.md quotes the output. About 20 s.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

import numpy as np

from attica.evaluate.core import VARIANTS, attica_method, method_kind
from attica.evaluate.suite import SEEDS, _episodes, condition, recovery_times, score_method
from attica.metrics import error_angles
from attica.sim import simulate_with_truth

KINDS = ("ars", "kf", "ekf", "mekf6", "mars", "mekf")
FRACTIONS = (1.0, 0.9999, 0.8)


def measure(
    kinds: Sequence[str] = KINDS, fractions: Sequence[float] = FRACTIONS, seeds: Sequence[int] = SEEDS
) -> dict[tuple[str, float], tuple[float, int, int]]:
    """(kind, fraction) -> (mean RMSE in deg, episodes back within 2 s, episodes)."""
    c = condition("clipped")
    acc: dict[tuple[str, float], tuple[list[float], int, int]] = {}
    for seed in seeds:
        rec, truth = simulate_with_truth(c.config(seed))
        assert rec.quat_true is not None
        eps = _episodes(np.asarray(truth.gyr_clipped.any(axis=1)), rec.rate)
        for name in kinds:
            for frac in fractions:
                over = {"gyro_range": c.gyro_range * frac}
                m = attica_method(method_kind(name), overrides=over, variant=name if name in VARIANTS else "")
                e, est = score_method(m, rec, c.score_from)
                total, _, incl = error_angles(est.q, rec.quat_true)
                times = recovery_times(np.degrees(total if m.nine_axis else incl), eps, rec.rate)
                errs, ok, n = acc.get((name, frac), ([], 0, 0))
                errs.append(e.total if m.nine_axis else e.inclination)
                acc[(name, frac)] = (errs, ok + sum(1 for t in times if t <= 2.0), n + len(times))
    return {k: (float(np.mean(v[0])), v[1], v[2]) for k, v in acc.items()}


def table(res: dict[tuple[str, float], tuple[float, int, int]], kinds: Sequence[str] = KINDS) -> str:
    """The Markdown table of docs/accuracy.md."""
    fracs = sorted({f for _, f in res}, reverse=True)
    lines = ["| `gyro_range` / rail | " + " | ".join(kinds) + " |", "|---|" + "---:|" * len(kinds)]
    for f in fracs:
        cells = [f"{res[(k, f)][0]:.2f} ({res[(k, f)][1]}/{res[(k, f)][2]})" for k in kinds]
        lines.append(f"| {f:g} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """Print the table."""
    p = argparse.ArgumentParser(prog="python -m attica_dev.rail", description=__doc__.split("\n")[0])
    p.parse_args(argv)
    print(table(measure()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
