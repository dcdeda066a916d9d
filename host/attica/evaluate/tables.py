"""Plain-text tables of an evaluation that fit a terminal.

6-axis methods (judged by the inclination error) and 9-axis methods (judged by the total error) get
separate tables; a table wider than ``width`` columns (110 by default) is split into column groups,
each repeating the trial names, unless ``wide`` is asked for.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence

import numpy as np

from attica.evaluate.core import MethodResult, Report

__all__ = ["TABLE_WIDTH", "format_notes", "format_stated", "format_summary", "format_tables"]

TABLE_WIDTH = 110
"""Columns a table may use unless ``wide``."""


def _fmt(x: float) -> str:
    return f"{x:7.2f}" if np.isfinite(x) else "    nan"


def _column_groups(names: Sequence[str], label_width: int, width: int | None) -> list[list[int]]:
    """Indices of the columns of each printed table (all in one when ``width`` is None)."""
    if width is None:
        return [list(range(len(names)))]
    groups: list[list[int]] = [[]]
    used = label_width
    for i, n in enumerate(names):
        w = max(7, len(n)) + 1
        if groups[-1] and used + w > width:
            groups.append([])
            used = label_width
        groups[-1].append(i)
        used += w
    return groups


def _table(
    report: Report, title: str, metric: str, results: list[MethodResult], width: int | None
) -> list[str]:
    label_width = max(
        [len("average"), *(len(t) for t in report.trials), *(len(g) + 2 for g in report.groups)]
    )
    if width is not None:
        label_width = min(label_width, max(24, width // 3))
    names = [r.method.name for r in results]
    groups = _column_groups(names, label_width, width)
    lines: list[str] = []
    for part, cols in enumerate(groups):
        head_title = title if len(groups) == 1 else f"{title}, part {part + 1} of {len(groups)}"
        colw = [max(7, len(names[i])) for i in cols]
        head = head_title.ljust(label_width) + " " + " ".join(names[i].rjust(w) for i, w in zip(cols, colw))
        if len(head_title) > label_width:
            lines.append(head_title)
            head = "".ljust(label_width) + " " + " ".join(names[i].rjust(w) for i, w in zip(cols, colw))
        rule = "-" * len(head)
        lines += [head, rule]

        def row(label: str, vals: list[float], colw: list[int] = colw) -> str:
            # too long: keep the start (trial number) and the end (variant), "~" between
            half = (label_width - 1) // 2
            text = (
                label
                if len(label) <= label_width
                else label[:half] + "~" + label[-(label_width - 1 - half) :]
            )
            return text.ljust(label_width) + " " + " ".join(_fmt(v).rjust(w) for v, w in zip(vals, colw))

        for k, t in enumerate(report.trials):
            lines.append(row(t, [getattr(results[i].trials[k].errors, metric) for i in cols]))
        lines.append(rule)
        for g in report.groups:
            lines.append(row(f"[{g}]", [results[i].mean(metric, g) for i in cols]))
        lines.append(row("average", [results[i].mean(metric) for i in cols]))
        lines.append("")
    return lines


def format_tables(report: Report, width: int | None = TABLE_WIDTH, wide: bool = False) -> str:
    """The RMSE in degrees per trial, per group and averaged over trials, one table per kind of method.

    Parameters
    ----------
    report
        The evaluation.
    width
        Most columns per line; wider tables are split into column groups.
    wide
        One table per kind of method however wide (``attica eval --wide``).

    """
    w = None if wide else width
    six = [r for r in report.results if not r.method.nine_axis]
    nine = [r for r in report.results if r.method.nine_axis]
    lines: list[str] = []
    if six:
        lines += _table(report, "6-axis: inclination RMSE (deg)", "inclination", six, w)
    if nine:
        lines += _table(report, "9-axis: total RMSE (deg)", "total", nine, w)
    notes = format_notes(report, width or TABLE_WIDTH)
    if notes:
        lines += [notes, ""]
    return "\n".join(lines)


def format_stated(report: Report) -> str:
    """Each method's stated orientation covariance against its errors; empty when no method states one.

    Per method the mean squared error over the mean stated variance, pooled over the trials
    (:meth:`MethodResult.stated_ratio`): the inclination for every method, the heading for 9-axis ones
    (a 6-axis method states its heading as unknown: ``-``). Methods that state none (the peers) are not
    listed.
    """
    rows = [r for r in report.results if any(t.stated is not None for t in r.trials)]
    if not rows:
        return ""
    width = max([24, *(len(r.method.name) for r in rows)])
    head = f"{'stated covariance':<{width}} {'incl':>7} {'heading':>7}"
    out = [
        "orientation covariance stated (sensor_msgs/Imu's) against the errors: mean squared error over",
        "mean stated variance, pooled over the trials; 1 consistent, above 1 optimistic, below 1",
        "conservative (attica's kinds; the peers state none; -: a 6-axis heading, stated as unknown)",
        head,
        "-" * len(head),
    ]
    for r in rows:
        heading = _fmt(r.stated_ratio("heading")) if r.method.nine_axis else "      -"
        out.append(f"{r.method.name:<{width}} {_fmt(r.stated_ratio('inclination'))} {heading}")
    return "\n".join(out)


def format_notes(report: Report, width: int = TABLE_WIDTH) -> str:
    """What methods did to a trial's input or scoring (``TrialScore.notes``); empty when there is none.

    One entry per trial and note, naming the methods it concerns, wrapped to ``width`` columns.
    """
    entries: dict[tuple[str, str], list[str]] = {}
    for r in report.results:
        for t in r.trials:
            for note in t.notes:
                entries.setdefault((t.trial, note), []).append(r.method.name)
    if not entries:
        return ""
    lines = ["notes (the input the methods got, and what was scored):"]
    for (trial, note), names in entries.items():
        text = f"{', '.join(names)} on {trial}: {note}"
        lines += textwrap.wrap(text, width, initial_indent="- ", subsequent_indent="  ")
    return "\n".join(lines)


def format_summary(report: Report) -> str:
    """One line per method: mean total, heading and inclination RMSE and the score metric."""
    width = max([24, *(len(r.method.name) for r in report.results)])
    out = [f"{'method':<{width}} {'total':>7} {'heading':>7} {'incl':>7}  judged by"]
    for r in report.results:
        m = r.method
        means = " ".join(_fmt(r.mean(k)) for k in ("total", "heading", "inclination"))
        out.append(f"{m.name:<{width}} {means}  {m.score_metric}{'' if m.nine_axis else ' (6-axis)'}")
    return "\n".join(out)
