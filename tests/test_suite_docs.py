"""docs/accuracy.md's table of the whole generalisation suite is what ``attica eval --suite`` computes.

The table "The whole suite now" (every cell, the clip recovery counts) and the summary figures under it
(attica's best ahead of VQF in N of M comparisons, the worst ratio) are recomputed from a full run (10
seeds, every condition and method: about 20 s on one core).
"""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import pytest

from attica.evaluate import suite

from helpers import markdown_table, need

DOCS = Path(__file__).resolve().parents[1] / "docs" / "accuracy.md"
PEERS_INSTALLED = all(importlib.util.find_spec(m) is not None for m in ("vqf", "imufusion"))


def _table() -> tuple[list[str], dict[str, list[str]], str]:
    """The column names, the rows by condition and the text after the table."""
    after = "The whole suite now (`attica eval --suite"
    text = DOCS.read_text(encoding="utf-8")
    header, rows, end = markdown_table(text, after, "condition")
    lines = text[text.index(after) :].splitlines()
    return header, rows, "\n".join(lines[end : end + 12])


def _number(cell: str) -> str:
    """The first figure of a cell ("**1.18** (1.32)" -> "1.18"; "" when empty)."""
    m = re.search(r"\d+(\.\d+)?", cell)
    return m.group(0) if m else ""


@pytest.fixture(scope="module")
def result() -> suite.SuiteResult:
    need(PEERS_INSTALLED, "vqf and imufusion (pip install '.[peers]')")
    return suite.run_suite(jobs=2)


def test_every_cell_of_the_table(result: suite.SuiteResult) -> None:
    header, rows, _ = _table()
    names = {c.name for c in suite.CONDITIONS}
    assert names <= set(rows), f"conditions missing from the table: {names - set(rows)}"
    checked = 0
    for cond in suite.CONDITIONS:
        cells = rows[cond.name]
        for j, method in enumerate(header):
            if j == 0 or not method:
                continue
            info = next(m for m in result.methods if m.name == method)
            if cond.magnetic and not info.nine_axis:
                assert _number(cells[j]) == "", f"{cond.name} {method}: a 6-axis figure there"
                continue
            assert _number(cells[j]) == f"{result.mean(method, cond.name):.2f}", f"{cond.name} {method}"
            checked += 1
    assert checked >= 100
    counts = next(v for k, v in rows.items() if k.startswith("clipped: within 2 s"))
    for j, method in enumerate(header):
        if j == 0 or not method:
            continue
        within = sum(t <= 2.0 for t in result.recovery(method, "clipped"))
        assert _number(counts[j]) == str(within), f"clip recovery {method}"


def test_the_summary_under_it(result: suite.SuiteResult) -> None:
    _, _, after = _table()
    s = result.summary()
    assert f"ahead of VQF in {s['ahead']} of {s['of']} comparisons" in " ".join(after.split())
    assert f"**Worst ratio {s['worst_ratio']['ratio']:.2f}**" in after
