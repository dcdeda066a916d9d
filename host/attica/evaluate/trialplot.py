"""The per-trial figure of ``attica eval --out`` (``error_<trial>.png``): what each method did over time.

Panels, top to bottom, on one time axis (each only when something is drawn in it):

- roll and pitch of every method against the truth (degrees, ZYX angles in ENU);
- yaw of the 9-axis methods against the truth (a 6-axis method's yaw is not observable: not drawn);
- the inclination error of every method and the heading error of the 9-axis methods (BROAD's
  definitions; linear scale unless the values span more than two decades, see
  :data:`~attica.evaluate.plotting.LOG_DECADES`);
- the status flags (``ATT_FLAG_*``) of attica's filters as timelines: one row per flag that is ever
  set, one lane per filter, marked where set;
- the gyro-bias estimate (deg/s) of the methods that estimate one (attica's filters, VQF).

The movement phases (the samples the metrics count) are shaded when the recording marks some and they
are not the whole recording; the x-axis label says which. Curves are the thinned traces
(:mod:`attica.evaluate.trace`): every ``n // 4000``-th sample, flags OR-ed over the samples in between.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.data import Recording
from attica.evaluate.core import Report
from attica.evaluate.plotting import (
    DPI,
    WIDTH_PX,
    colour,
    curve_levels,
    legend_right,
    pyplot,
    save,
    set_scale,
)
from attica.evaluate.trace import Trace, euler_deg, trace_index
from attica.settings import Flag

__all__ = ["TITLES", "movement_caption", "plot_trial", "trial_figure"]

PANEL_INCHES = 2.1
"""Height of one panel."""

TOP_INCHES, BOTTOM_INCHES, LEFT_INCHES, GAP_INCHES = 0.55, 0.55, 1.0, 0.45
"""Figure margins and the gap between panels (room for the title, tick labels and caption)."""

MARK_FRACTION = 0.002
"""The narrowest flag mark, as a fraction of the time axis (a flag set for one sample still shows)."""

TITLES = {
    "roll": "roll (deg): truth and every method",
    "pitch": "pitch (deg): truth and every method",
    "yaw": "yaw (deg): truth and the 9-axis methods (a 6-axis method's yaw is not observable)",
    "inclination": "inclination error (deg): every method",
    "heading": "heading error (deg): the 9-axis methods",
    "flags": "status flags (ATT_FLAG_*) of attica's filters: one lane per filter, marked where set",
    "bias": "gyro-bias estimate (deg/s): x solid, y dashed, z dotted",
}
"""Each panel's title (its left title in the figure)."""


def _phases(movement: NDArray[np.bool_]) -> list[tuple[int, int]]:
    m = np.concatenate([[False], movement, [False]]).astype(np.int8)
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))


def movement_caption(rec: Recording) -> tuple[list[tuple[int, int]], str]:
    """The movement phases to shade (``[start, stop)`` sample ranges) and the x-axis caption that says so."""
    if rec.movement is None:
        return [], "time (s); the recording marks no movement phases: every sample is scored"
    if not rec.movement.any():
        return [], "time (s); no sample is in a movement phase: none is scored"
    if rec.movement.all():
        return [], "time (s); every sample is in the movement phase (scored)"
    return _phases(rec.movement), "time (s); movement phases (the samples scored) shaded"


def _no_wrap(v: NDArray[Any]) -> NDArray[np.float64]:
    """An angle curve with a gap where it wraps around +-180 deg (no vertical line across the panel)."""
    out = np.array(v, np.float64)
    jump = np.abs(np.diff(out)) > 180.0
    out[1:][jump] = np.nan
    return out


def trial_figure(report: Report, rec: Recording, methods: Sequence[str] | None = None) -> Any:
    """The matplotlib figure of :func:`plot_trial` (None when no method is drawn); close it after use.

    Needs the report's traces (``run_methods(..., curves=True)``) and the recording's truth.
    """
    plt = pyplot()
    names = [
        r.method.name
        for r in report.results
        if (methods is None or r.method.name in methods) and (r.method.name, rec.name) in report.traces
    ]
    if not names or rec.quat_true is None:
        return None
    tr = {n: report.traces[(n, rec.name)] for n in names}
    col = {n: colour(i) for i, n in enumerate(names)}
    nine = [n for n in names if report.result(n).method.nine_axis]
    idx = trace_index(len(rec))
    t = rec.t[idx]
    truth = euler_deg(rec.quat_true[idx])
    flagged = [n for n in names if _flags(tr[n]) is not None]
    flags = [f for f in Flag if any(np.any(_bit(tr[n], f)) for n in flagged)]
    biased = [n for n in names if tr[n].gyro_bias is not None]

    def angle(k: int, group: list[str]) -> Callable[[Any], None]:
        def draw(ax: Any) -> None:
            ax.plot(t, _no_wrap(truth[:, k]), lw=2.2, color="0.1", alpha=0.45, label="truth", zorder=1)
            for n in group:
                ax.plot(t, _no_wrap(tr[n].euler[:, k]), lw=0.9, color=col[n], label=n, zorder=2)
            legend_right(ax)

        return draw

    def error(what: str, group: list[str]) -> Callable[[Any], None]:
        def draw(ax: Any) -> None:
            levels = []
            for n in group:
                v = getattr(tr[n], what)
                ax.plot(t, v, lw=0.9, color=col[n], label=n)
                lv = curve_levels(v)
                if lv is not None:
                    levels.append(lv)
            set_scale(ax, [lo for lo, _ in levels], [hi for _, hi in levels])
            ax.set_ylabel("deg")
            legend_right(ax)

        return draw

    def flag_lanes(ax: Any) -> None:
        from matplotlib.patches import Patch

        lane = 0.8 / len(flagged)
        step = t[1] - t[0] if len(t) > 1 else 1.0 / rec.rate
        least = MARK_FRACTION * max(float(t[-1] - t[0]), step)  # a one-sample flag stays visible
        for row, f in enumerate(flags):
            for k, n in enumerate(flagged):
                on = _bit(tr[n], f)
                spans = [
                    (t[a], max(least, (t[b] if b < len(t) else t[-1] + step) - t[a])) for a, b in _phases(on)
                ]
                if spans:
                    ax.broken_barh(spans, (row + 0.1 + k * lane, 0.9 * lane), facecolors=col[n])
        ax.set_yticks(np.arange(len(flags)) + 0.5)
        ax.set_yticklabels([str(f.name).lower().replace("_", " ") for f in flags], fontsize=8)
        ax.set_ylim(0, len(flags))
        handles = [Patch(color=col[n], label=n) for n in flagged]
        ax.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.005, 1.0), borderaxespad=0)

    def bias(ax: Any) -> None:
        for n in biased:
            b = tr[n].gyro_bias
            assert b is not None
            for axis, style in enumerate(("-", "--", ":")):
                ax.plot(t, b[:, axis], ls=style, lw=0.9, color=col[n], label=n if axis == 0 else "_nolegend_")
        ax.axhline(0.0, lw=0.5, color="0.5")
        legend_right(ax)

    panels: list[tuple[str, Callable[[Any], None]]] = [("roll", angle(0, names)), ("pitch", angle(1, names))]
    if nine:
        panels.append(("yaw", angle(2, nine)))
    panels.append(("inclination", error("inclination", names)))
    if nine:
        panels.append(("heading", error("heading", nine)))
    if flags:
        panels.append(("flags", flag_lanes))
    if biased:
        panels.append(("bias", bias))

    fig, axes = plt.subplots(
        len(panels),
        1,
        figsize=(WIDTH_PX / DPI, PANEL_INCHES * len(panels) + TOP_INCHES + BOTTOM_INCHES),
        dpi=DPI,
        sharex=True,
        squeeze=False,
    )
    phases, caption = movement_caption(rec)
    full_t = rec.t
    for ax, (key, draw) in zip(axes[:, 0], panels, strict=True):
        for a, b in phases:
            ax.axvspan(full_t[a], full_t[b - 1], color="0.9", lw=0, zorder=0)
        draw(ax)
        ax.set_title(TITLES[key], fontsize=10, loc="left")
        ax.grid(True, which="both", lw=0.3, color="0.8")
    axes[-1, 0].set_xlabel(caption)
    fig.suptitle(rec.name, fontsize=11)
    # fixed margins (tight_layout would cost a second per figure): tick labels left, legends right
    height = fig.get_size_inches()[1]
    fig.subplots_adjust(
        left=LEFT_INCHES / (WIDTH_PX / DPI),
        right=0.87,
        top=1.0 - TOP_INCHES / height,
        bottom=BOTTOM_INCHES / height,
        hspace=GAP_INCHES / (PANEL_INCHES - GAP_INCHES),
    )
    return fig


def _flags(trace: Trace) -> NDArray[np.uint32] | None:
    """A trace's flags when any is ever set (else None)."""
    if trace.flags is None or not np.any(trace.flags):
        return None
    return trace.flags


def _bit(trace: Trace, flag: Flag) -> NDArray[np.bool_]:
    """Where a trace has ``flag`` set (all False without flags)."""
    if trace.flags is None:
        return np.zeros(len(trace.index), np.bool_)
    on: NDArray[np.bool_] = (trace.flags & np.uint32(flag.value)) != 0
    return on


def plot_trial(report: Report, rec: Recording, path: Path, methods: Sequence[str] | None = None) -> None:
    """The per-trial figure (:func:`trial_figure`) as a PNG."""
    save(trial_figure(report, rec, methods), path)
