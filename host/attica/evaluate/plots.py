"""PNG plots of an evaluation, readable at a glance (matplotlib, ``pip install '.[eval]'``).

- ``error_<trial>.png``: error over time, 6-axis inclination and 9-axis total on separate charts,
  movement phases shaded;
- ``groups.png`` / ``groups_seed.png``: per-group RMSE bars, 6-axis and 9-axis methods on separate
  charts.

Every figure is 1600 px wide with the legend outside the data; an axis whose values span more than a
factor of 10 (one method far worse than the others) is logarithmic.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.data import Recording
from attica.evaluate.core import Report
from attica.kinds import KINDS

__all__ = ["PLOT_PEERS", "groups_figure", "plot_groups", "plot_trial", "trial_figure", "write_plots"]

WIDTH_PX = 1600
DPI = 100
LOG_RATIO = 10.0
"""An axis is logarithmic when its largest value exceeds its smallest positive one by this factor."""

PLOT_PEERS = ("vqf9", "vqf6", "basicvqf9", "fusion9", "madgwick9", "mahony9", "ekf9")
"""Peers drawn in the plots (when they were run; the tables and the JSON have every method)."""


def _pyplot() -> Any:
    try:
        import matplotlib
    except ImportError:
        raise RuntimeError("plots need matplotlib: pip install '.[eval]' (or use --no-plots)") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _phases(movement: NDArray[np.bool_]) -> list[tuple[int, int]]:
    m = np.concatenate([[False], movement, [False]]).astype(np.int8)
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _scale(ax: Any, values: Iterable[float]) -> None:
    """Log scale when the values span more than :data:`LOG_RATIO`."""
    v = np.array([x for x in values if np.isfinite(x) and x > 0], np.float64)
    if v.size and v.max() / v.min() > LOG_RATIO:
        ax.set_yscale("log")
    else:
        ax.set_ylim(bottom=0)


def _split(report: Report, names: Sequence[str]) -> tuple[list[str], list[str]]:
    six = [n for n in names if not report.result(n).method.nine_axis]
    nine = [n for n in names if report.result(n).method.nine_axis]
    return six, nine


def trial_figure(report: Report, rec: Recording, methods: Sequence[str] | None = None) -> Any:
    """The matplotlib figure of :func:`plot_trial` (None when no method is drawn); close it after use.

    One chart per kind of method (6-axis: inclination error, 9-axis: total error), each with its own
    scale and its legend right of the data.
    """
    plt = _pyplot()
    names = [r.method.name for r in report.results if methods is None or r.method.name in methods]
    six, nine = _split(report, names)
    panels = [(t, n) for t, n in (("6-axis: inclination error", six), ("9-axis: total error", nine)) if n]
    if not panels:
        return None
    fig, axes = plt.subplots(
        len(panels), 1, figsize=(WIDTH_PX / DPI, 3.2 * len(panels) + 0.6), dpi=DPI, sharex=True, squeeze=False
    )
    t = rec.t
    step = max(1, len(t) // 4000)
    colours = plt.get_cmap("tab10").colors
    for ax, (title, group) in zip(axes[:, 0], panels):
        if rec.movement is not None:
            for a, b in _phases(rec.movement):
                ax.axvspan(t[a], t[min(b, len(t) - 1)], color="0.92", lw=0)
        seen: list[float] = []
        for i, name in enumerate(group):
            score, _ = report.curves[(name, rec.name)]
            ax.plot(t[::step], score[::step], lw=0.9, label=name, color=colours[i % 10])
            finite = score[np.isfinite(score)]
            if finite.size:
                seen += [float(np.percentile(finite, 5)), float(np.percentile(finite, 99.5))]
        _scale(ax, seen)
        ax.set_ylabel("error (deg)")
        ax.set_title(title, fontsize=10, loc="left")
        ax.grid(True, which="both", lw=0.3, color="0.8")
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.005, 1.0), borderaxespad=0.0)
    axes[-1, 0].set_xlabel("time (s); movement phases shaded")
    fig.suptitle(rec.name, fontsize=11)
    fig.tight_layout(rect=(0, 0, 0.88, 1))
    return fig


def _save(fig: Any, path: Path) -> None:
    if fig is None:
        return
    try:
        fig.savefig(path)
    finally:
        _pyplot().close(fig)


def plot_trial(report: Report, rec: Recording, path: Path, methods: Sequence[str] | None = None) -> None:
    """Error over time on one trial: 6-axis methods' inclination and 9-axis methods' total error (PNG)."""
    _save(trial_figure(report, rec, methods), path)


def groups_figure(report: Report, methods: Sequence[str] | None = None) -> Any:
    """The matplotlib figure of :func:`plot_groups` (None when no method is drawn); close it after use."""
    plt = _pyplot()
    names = [r.method.name for r in report.results if methods is None or r.method.name in methods]
    six, nine = _split(report, names)
    panels = [(t, n) for t, n in (("6-axis: inclination RMSE", six), ("9-axis: total RMSE", nine)) if n]
    if not panels:
        return None
    labels = [*report.groups, "average"]
    fig, axes = plt.subplots(
        len(panels), 1, figsize=(WIDTH_PX / DPI, 3.6 * len(panels) + 0.8), dpi=DPI, squeeze=False
    )
    colours = plt.get_cmap("tab20").colors
    x = np.arange(len(labels))
    for ax, (title, group) in zip(axes[:, 0], panels):
        width = 0.8 / max(1, len(group))
        seen: list[float] = []
        for i, name in enumerate(group):
            r = report.result(name)
            vals = [r.score(g) for g in report.groups] + [r.score()]
            seen += vals
            pos = x + (i - (len(group) - 1) / 2) * width
            ax.bar(pos, vals, width, label=name, color=colours[(2 * i) % 20 if i < 10 else (2 * i) % 20 + 1])
        _scale(ax, seen)
        ax.set_xticks(x)
        ax.set_xticklabels(labels, rotation=20, ha="right", fontsize=8)
        ax.set_ylabel("RMSE (deg)")
        ax.set_title(title, fontsize=10, loc="left")
        ax.grid(True, axis="y", which="both", lw=0.3, color="0.8")
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.005, 1.0), borderaxespad=0.0)
    fig.tight_layout(rect=(0, 0, 0.88, 1))
    return fig


def plot_groups(report: Report, path: Path, methods: Sequence[str] | None = None) -> None:
    """Per-group RMSE bars and the all-trial average: 6-axis inclination and 9-axis total charts (PNG)."""
    _save(groups_figure(report, methods), path)


def write_plots(report: Report, recs: Iterable[Recording], out: Path) -> list[Path]:
    """Write the PNGs; returns their paths.

    error_<trial>.png: attica's filters at their defaults (without the gyro-only and accel-only
    baselines) and VQF; groups.png: the same filters and the default-setting peers of
    :data:`PLOT_PEERS`; groups_seed.png: attica's tuned filters against their seed preset.
    """
    baselines = {k.label for k in KINDS if k.baseline}
    ran = [r.method for r in report.results]
    mine = [
        m.name for m in ran if m.family == "attica" and m.setting == "default" and m.name not in baselines
    ]
    peers = [m.name for m in ran if m.family != "attica" and m.name in PLOT_PEERS]
    written = []
    for rec in recs:
        path = out / f"error_{rec.name}.png"
        plot_trial(report, rec, path, mine + [n for n in peers if n.startswith("vqf")])
        written.append(path)
    plot_groups(report, out / "groups.png", mine + peers)
    written.append(out / "groups.png")
    seeds = {m.name for m in ran if m.setting == "seed"}
    pairs = [n for k in mine for n in (k, f"{k}@seed") if f"{k}@seed" in seeds]
    if pairs:
        plot_groups(report, out / "groups_seed.png", pairs)
        written.append(out / "groups_seed.png")
    return [p for p in written if p.exists()]
