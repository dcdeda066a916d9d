"""The ideal clip recoveries of tools/attica_dev/clip_bound.py: their geometry, the figures in the docs."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from attica_dev.clip_bound import (
    IDEALS,
    KINDS,
    field_exact_error,
    horizontal_error,
    ideal_errors,
    measure,
    tilt_error,
    within,
)

DIP = math.radians(60.0)
FIELD = np.array([[0.0, 20.0 * math.cos(DIP), -20.0 * math.sin(DIP)]])  # ENU: north (y) and down
DOCS = Path(__file__).resolve().parents[1] / "docs" / "accuracy.md"


def _up(about: str, delta: float) -> np.ndarray:
    """The up direction seen by an estimate tilted by ``delta`` rad about the east (x) or north (y) axis."""
    if about == "east":
        return np.array([[0.0, -math.sin(delta), math.cos(delta)]])
    return np.array([[math.sin(delta), 0.0, math.cos(delta)]])


@pytest.mark.parametrize("delta", [0.01, 0.05, 0.2])
def test_a_tilt_about_the_fields_horizontal_direction_turns_the_heading_by_tan_dip(delta: float) -> None:
    """Tilted about north, the field's vertical part leans east: tan h = tan(dip) sin(delta) for heading h."""
    up = _up("north", delta)
    assert tilt_error(up)[0] == pytest.approx(delta, rel=1e-12)
    h = math.atan(math.tan(DIP) * math.sin(delta))
    total = 2.0 * math.acos(math.cos(h / 2.0) * math.cos(delta / 2.0))  # perpendicular axes: w multiplies
    assert horizontal_error(up, FIELD)[0] == pytest.approx(total, rel=1e-9)
    assert total > 1.8 * delta  # about twice the tilt at a dip of 60 deg


@pytest.mark.parametrize("delta", [0.01, 0.05, 0.2])
def test_a_tilt_about_east_leaves_the_heading_and_the_field_exact_ideal_removes_it(delta: float) -> None:
    up = _up("east", delta)
    assert horizontal_error(up, FIELD)[0] == pytest.approx(delta, rel=1e-9)
    assert field_exact_error(up, FIELD)[0] == pytest.approx(0.0, abs=1e-12)


def test_the_field_exact_ideal_turns_about_the_field_to_take_out_a_tilt_about_north() -> None:
    """A small tilt d about north is a turn of about d / cos(dip) about the field (60 deg below north)."""
    d = 1e-4
    assert field_exact_error(_up("north", d), FIELD)[0] == pytest.approx(d / math.cos(DIP), rel=1e-3)


def test_without_translation_the_ideals_are_exact_and_the_running_mean_averages_it_out() -> None:
    n = 400
    field = np.repeat(FIELD, n, axis=0)
    still = ideal_errors(np.zeros((n, 3)), field, 9.80665)
    for name in IDEALS:
        assert np.max(still[name]) < 1e-6
    acc = np.zeros((n, 3))
    acc[:100, 0] = 2.0  # a push east in the first 100 samples, then none: the mean's tilt falls as 100 / i
    err = ideal_errors(acc, field, 9.80665)
    first = math.degrees(math.atan2(2.0, 9.80665))
    assert err["tilt"][0] == pytest.approx(first, rel=1e-9)
    assert err["tilt"][399] == pytest.approx(math.degrees(math.atan2(2.0 * 100 / 400, 9.80665)), rel=1e-9)
    assert err["horizontal"][0] > 1.8 * err["tilt"][0]  # tilted about north: the heading follows
    assert err["field exact"][0] < err["horizontal"][0]


def test_within_counts_nan_as_never() -> None:
    assert within([0.5, 2.0, 2.01, math.nan]) == 2


def _doc_counts() -> dict[str, int]:
    """The counts in docs/accuracy.md's sentence on the ideal recoveries."""
    text = DOCS.read_text(encoding="utf-8")
    m = re.search(r"python -m attica_dev\.clip_bound`.*?\n#", text, flags=re.S)
    assert m, "docs/accuracy.md does not quote attica_dev.clip_bound"
    names = {"ideal tilt": "tilt", "ideal horizontal": "horizontal", "ideal field exact": "field exact"}
    names.update({k: k for k in KINDS})
    out = {}
    for label, key in names.items():
        hit = re.search(rf"\| {re.escape(label)} \| (\d+) of 40 \|", m.group(0))
        assert hit, f"no row for {label}"
        out[key] = int(hit.group(1))
    return out


def test_the_docs_counts_are_the_tools() -> None:
    """The table in docs/accuracy.md is what the tool prints (the suite's clipped condition, seeds 1-10)."""
    res = measure(range(1, 11))
    assert {k: within(v) for k, v in res.items()} == _doc_counts()
