"""Grid search with per-trial scores and leave-one-trial-out validation (``attica eval --grid``).

:func:`grid_scores` runs every point of a grid (setting overrides applied to a kind's defaults, or to a
named variant of :data:`attica.evaluate.VARIANTS`) on every trial and keeps each trial's BROAD errors.
:func:`leave_one_out` then asks how well the tuning generalises: for each trial it picks the grid point
with the best mean score on the *other* trials and scores that point on the held-out one. The mean of
those held-out scores is the leave-one-out figure reported beside the in-sample one (the best point's
mean over all trials, which has seen every trial it is judged on).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from attica.data import Recording
from attica.metrics import Errors
from attica.settings import FilterKind, Preset

if TYPE_CHECKING:
    from attica.evaluate.parallel import TrialPool

__all__ = ["GridResult", "LeaveOneOut", "grid_points", "grid_scores", "grid_search", "leave_one_out"]

METRICS = ("total", "heading", "inclination")


def grid_points(grid: dict[str, list[Any]]) -> list[dict[str, Any]]:
    """Every combination of ``grid`` as a dict of setting overrides (``"a,b"`` keys set both fields)."""
    keys = list(grid)
    points = []
    for vals in itertools.product(*grid.values()):
        over: dict[str, Any] = {}
        for k, v in zip(keys, vals, strict=True):
            for name in k.split(","):
                over[name] = v
        points.append(over)
    return points


@dataclass
class GridResult:
    """Per-trial errors of every grid point.

    Attributes
    ----------
    points : list of dict
        The setting overrides of each point, in grid order.
    trials : list of str
        Trial names.
    errors : ndarray, shape (points, trials, 3)
        Total, heading and inclination RMSE in degrees.
    metric : str
        The score metric (``total`` for 9-axis methods, else ``inclination``).

    """

    points: list[dict[str, Any]]
    trials: list[str]
    errors: NDArray[np.float64]
    metric: str

    def scores(self) -> NDArray[np.float64]:
        """(points, trials) values of the score metric."""
        return self.errors[:, :, METRICS.index(self.metric)]

    def means(self) -> NDArray[np.float64]:
        """(points, 3) mean errors over the trials (NaN when a trial is NaN)."""
        out: NDArray[np.float64] = np.mean(self.errors, axis=1)
        return out

    def ranked(self) -> list[tuple[dict[str, Any], Errors]]:
        """``(overrides, mean errors)`` best first (non-finite scores last)."""
        m = self.means()
        s = m[:, METRICS.index(self.metric)]
        order = sorted(range(len(self.points)), key=lambda i: (not np.isfinite(s[i]), s[i]))
        return [(self.points[i], Errors(float(m[i, 0]), float(m[i, 1]), float(m[i, 2]))) for i in order]


@dataclass
class LeaveOneOut:
    """Held-out scores of :func:`leave_one_out`.

    Attributes
    ----------
    held_out : ndarray, shape (trials,)
        The score metric on each trial of the point chosen on the other trials.
    chosen : list of int
        Index (into :attr:`GridResult.points`) of the point chosen without each trial.
    in_sample : float
        Mean over all trials of the best point on all trials.

    """

    held_out: NDArray[np.float64]
    chosen: list[int]
    in_sample: float

    @property
    def mean(self) -> float:
        """Mean of the held-out scores: the leave-one-out figure."""
        return float(np.mean(self.held_out))


def _best(scores: NDArray[np.float64]) -> int:
    """Index of the smallest finite row mean (the first on ties)."""
    means = np.mean(scores, axis=1)
    means = np.where(np.isfinite(means), means, np.inf)
    return int(np.argmin(means))


def leave_one_out(result: GridResult) -> LeaveOneOut:
    """For each trial: the best point on the other trials, scored on that trial."""
    s = result.scores()
    n = s.shape[1]
    if n < 2:
        raise ValueError("leave-one-out needs at least two trials")
    held = np.empty(n)
    chosen = []
    for t in range(n):
        rest = np.delete(s, t, axis=1)
        i = _best(rest)
        chosen.append(i)
        held[t] = s[i, t]
    best = _best(s)
    return LeaveOneOut(held, chosen, float(np.mean(s[best])))


def grid_scores(
    kind: FilterKind,
    recs: Sequence[Recording],
    grid: dict[str, list[Any]],
    variant: str = "",
    progress: bool = True,
    pool: TrialPool | None = None,
) -> GridResult:
    """Run every point of ``grid`` (overrides on the defaults of ``kind`` or of ``variant``) on ``recs``.

    ``pool`` (:class:`~attica.evaluate.parallel.TrialPool`) runs the points' trials in parallel; the
    errors are the serial run's bit for bit. The progress bar counts trials (points x recordings).
    """
    from attica.evaluate.core import VARIANTS, attica_method, run_methods
    from attica.kinds import uses_mag

    nine = VARIANTS[variant][2] if variant else uses_mag(kind)
    if variant:
        kind = VARIANTS[variant][0]
    points = grid_points(grid)
    methods = [attica_method(kind, Preset.DEFAULT, over, variant=variant) for over in points]
    report = run_methods(methods, recs, progress=progress, pool=pool, desc=f"grid {variant or kind.label}")
    errors = np.full((len(points), len(recs), 3), np.nan)
    for i, res in enumerate(report.results):
        for j, t in enumerate(res.trials):
            errors[i, j] = (t.errors.total, t.errors.heading, t.errors.inclination)
    return GridResult(points, [r.name for r in recs], errors, "total" if nine else "inclination")


def grid_search(
    kind: FilterKind,
    recs: Sequence[Recording],
    grid: dict[str, list[Any]] | None = None,
    progress: bool = True,
    jobs: int = 1,
) -> list[tuple[dict[str, Any], Errors]]:
    """Score every point of ``grid`` (default :data:`GRIDS`), applied to the default settings.

    Returns ``(overrides, mean errors over trials)`` sorted best first (9-axis kinds by total error, the
    others by inclination error): one parameter set for all trials, as BROAD's authors tune. ``jobs``:
    worker processes, as for :func:`run_methods`.
    """
    from attica.evaluate.core import GRIDS
    from attica.evaluate.parallel import TrialPool

    g = grid if grid is not None else GRIDS[kind]
    with TrialPool(jobs) as pool:
        return grid_scores(kind, recs, g, progress=progress, pool=pool).ranked()
