"""docs/accuracy.md's BROAD tables are what the code computes now.

- "Summary: mean over the 20 trials": every cell of attica's rows (total, heading, inclination, 2
  decimals) and of the peers' rows that run in C (VQF, BasicVQF, Fusion; ahrs' Madgwick and EKF, pure
  Python and minutes long, are not rerun here);
- "In sample and leave-one-trial-out": each filter's grid size, its defaults in sample, the grid's best
  point in sample and the leave-one-trial-out mean (3 decimals), from ``attica.tuning`` as ``attica eval
  --grid`` computes them (225 grid points x 20 trials: about a minute on one core);
- "Per group" and "Per trial": attica's columns and the C peers' (VQF, Fusion; the judged metric, 2
  decimals); until stop 48 no test read them, and the mekf's columns had gone stale.

Until session 9 no test read these tables and several figures elsewhere on the page had gone stale.
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path
from typing import Any

import pytest

from attica.data import load_recording
from attica.evaluate import (
    GRIDS,
    VARIANT_GRIDS,
    VARIANTS,
    attica_method,
    method_kind,
    peer_methods,
    run_methods,
)
from attica.tuning import grid_points, grid_scores, leave_one_out

from helpers import broad_trials, markdown_table, need

DOCS = Path(__file__).resolve().parents[1] / "docs" / "accuracy.md"
ATTICA_ROWS = ("ars", "kf", "ekf", "mekf6", "mars", "mekf", "gyro", "tilt")
PEER_ROWS = ("vqf9", "vqf6", "basicvqf9", "fusion9", "fusion9@tuned", "fusion6@tuned")
GRID_ROWS = ("ars", "kf", "ekf", "mekf6", "mars", "mekf")


def _rows(heading: str, first_col: str) -> dict[str, list[str]]:
    """The cells of the first table after ``heading``, by the first column."""
    return markdown_table(DOCS.read_text(encoding="utf-8"), heading, first_col)[1]


def _number(cell: str) -> str:
    """The first figure of a cell ("**1.90**" -> "1.90", "(4.31)" -> "4.31", "0.825 (0.8 ...)" -> "0.825")."""
    m = re.search(r"\d+(\.\d+)?", cell)
    assert m is not None, cell
    return m.group(0)


def _method(name: str) -> Any:
    return attica_method(method_kind(name), variant=name if name in VARIANTS else "")


@pytest.fixture(scope="module")
def broad() -> list[Any]:
    return [load_recording(p) for p in broad_trials()]


def test_the_summary_table(broad: list[Any]) -> None:
    rows = _rows("## Summary: mean over the 20 trials", "method")
    methods = [_method(n) for n in ATTICA_ROWS]
    peers = all(importlib.util.find_spec(m) is not None for m in ("vqf", "imufusion"))
    if peers:
        methods += [m for m in peer_methods(list(PEER_ROWS)) if m.name in PEER_ROWS]
        assert {m.name for m in methods} >= set(PEER_ROWS)
    rep = run_methods(methods, broad, progress=False)
    for m in methods:
        cells = rows[m.name]
        r = rep.result(m.name)
        for col, metric in ((2, "total"), (3, "heading"), (4, "inclination")):
            assert _number(cells[col]) == f"{r.mean(metric):.2f}", (m.name, metric, cells[col])
    need(peers, "vqf and imufusion (pip install '.[peers]'): their rows not checked")


@pytest.mark.parametrize("name", GRID_ROWS)
def test_the_in_sample_and_leave_one_out_table(broad: list[Any], name: str) -> None:
    rows = _rows("## In sample and leave-one-trial-out", "filter")
    cells = rows[name]
    variant = name if name in VARIANT_GRIDS else ""
    kind = method_kind(name)
    grid = VARIANT_GRIDS[name] if variant else GRIDS[kind]
    assert cells[2] == str(len(grid_points(grid)))
    res = grid_scores(kind, broad, grid, variant=variant, progress=False)
    loo = leave_one_out(res)
    defaults = run_methods([_method(name)], broad, progress=False).result(name).mean(res.metric)
    assert _number(cells[3]) == f"{defaults:.3f}", (name, cells[3])
    assert _number(cells[4]) == f"{loo.in_sample:.3f}", (name, cells[4])
    assert _number(cells[5]) == f"{loo.mean:.3f}", (name, cells[5])


GROUP_COLUMNS = ("ars", "kf", "ekf", "mekf6", "mars", "mekf", "vqf9", "vqf6", "fusion9")
"""The columns of the per-group and per-trial tables checked (madgwick9, from ahrs, is pure Python)."""


def test_the_per_group_and_per_trial_tables(broad: list[Any]) -> None:
    groups = markdown_table(DOCS.read_text(encoding="utf-8"), "## Per group", "group")
    trials = markdown_table(DOCS.read_text(encoding="utf-8"), "## Per trial", "trial")
    assert groups[0][1:] == trials[0][1:], "the two tables have the same columns"
    methods = [_method(n) for n in GROUP_COLUMNS[:6]]
    peers = all(importlib.util.find_spec(m) is not None for m in ("vqf", "imufusion"))
    if peers:
        methods += [m for m in peer_methods(list(GROUP_COLUMNS[6:])) if m.name in GROUP_COLUMNS]
    rep = run_methods(methods, broad, progress=False)
    assert sorted(trials[1]) == sorted(t.trial for t in rep.results[0].trials), "every trial, once"
    for m in methods:
        col = groups[0].index(m.name)
        r = rep.result(m.name)
        for t in r.trials:
            assert trials[1][t.trial][col] == f"{getattr(t.errors, m.score_metric):.2f}", (m.name, t.trial)
        for label, cells in groups[1].items():
            name = label.strip("*")
            want = r.score() if name.startswith("average") else r.score(name)
            assert cells[col] == f"{want:.2f}", (m.name, label)
    need(peers, "vqf and imufusion (pip install '.[peers]'): their columns not checked")
