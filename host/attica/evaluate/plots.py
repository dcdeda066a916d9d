"""PNG plots of an evaluation, readable at a glance (matplotlib, ``pip install '.[eval]'``).

- ``error_<trial>.png`` (:mod:`attica.evaluate.trialplot`): per trial, the Euler angles of each method
  against the truth, the inclination and heading errors, attica's status flags and the gyro-bias
  estimates over time, the movement phases shaded (the caption says when there are none to shade);
- ``groups.png`` / ``groups_seed.png``: per-group RMSE bars, 6-axis and 9-axis methods on separate
  charts.

Every figure is 1600 px wide with the legends outside the data; an axis is logarithmic only when its
values are positive and span more than two decades (one method far worse than the others), else linear
from 0 (:func:`attica.evaluate.plotting.set_scale`).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from attica.data import Recording
from attica.evaluate.core import Report
from attica.evaluate.plotting import DPI, WIDTH_PX, legend_right, pyplot, save, set_scale
from attica.evaluate.trialplot import plot_trial, trial_figure
from attica.kinds import KINDS

__all__ = ["PLOT_PEERS", "groups_figure", "plot_groups", "plot_trial", "trial_figure", "write_plots"]

PLOT_PEERS = ("vqf9", "vqf6", "basicvqf9", "fusion9", "madgwick9", "mahony9", "ekf9")
"""Peers drawn in the plots (when they were run; the tables and the JSON have every method)."""


def _pyplot() -> Any:
    """``matplotlib.pyplot`` (Agg); RuntimeError naming the extra when matplotlib is missing."""
    return pyplot()


def _split(report: Report, names: Sequence[str]) -> tuple[list[str], list[str]]:
    six = [n for n in names if not report.result(n).method.nine_axis]
    nine = [n for n in names if report.result(n).method.nine_axis]
    return six, nine


def groups_figure(report: Report, methods: Sequence[str] | None = None) -> Any:
    """The matplotlib figure of :func:`plot_groups` (None when no method is drawn); close it after use."""
    plt = pyplot()
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
        set_scale(ax, seen, seen)
        ax.set_xticks(x)
        ax.set_xticklabels(labels, rotation=20, ha="right", fontsize=8)
        ax.set_ylabel("RMSE (deg)")
        ax.set_title(title, fontsize=10, loc="left")
        ax.grid(True, axis="y", which="both", lw=0.3, color="0.8")
        legend_right(ax)
    fig.tight_layout(rect=(0, 0, 0.88, 1))
    return fig


def plot_groups(report: Report, path: Path, methods: Sequence[str] | None = None) -> None:
    """Per-group RMSE bars and the all-trial average: 6-axis inclination and 9-axis total charts (PNG)."""
    save(groups_figure(report, methods), path)


def _label(name: str) -> str:
    """A method's kind or variant label: its name without the setting changes (``mars[tau_mag=7.0]``)."""
    return name.split("[", 1)[0]


def _seed_name(name: str) -> str:
    """The seed preset's name of a default-setting method (``mars[x=1]`` -> ``mars@seed[x=1]``)."""
    label, sep, rest = name.partition("[")
    return f"{label}@seed{sep}{rest}"


def write_plots(report: Report, recs: Iterable[Recording], out: Path) -> list[Path]:
    """Write the PNGs; returns their paths.

    error_<trial>.png: attica's filters at their defaults (without the gyro-only and accel-only
    baselines) and VQF (vqf9, vqf6); groups.png: the same filters and the default-setting peers of
    :data:`PLOT_PEERS`; groups_seed.png: attica's tuned filters against their seed preset.
    """
    baselines = {k.label for k in KINDS if k.baseline}
    ran = [r.method for r in report.results]
    mine = [
        m.name
        for m in ran
        if m.family == "attica" and m.setting == "default" and _label(m.name) not in baselines
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
    pairs = [n for k in mine for n in (k, _seed_name(k)) if _seed_name(k) in seeds]
    if pairs:
        plot_groups(report, out / "groups_seed.png", pairs)
        written.append(out / "groups_seed.png")
    return [p for p in written if p.exists()]
