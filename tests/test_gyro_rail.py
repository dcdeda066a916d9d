"""A gyro reading at its rail, a little beyond ``gyro_range``, is a saturated sample, not a lost one.

A MEMS gyro's last code is not exactly its nominal full scale (32767 LSB at 65.5 LSB/(deg/s) is
500.3 deg/s on a 500 deg/s range): with ``gyro_range`` set from the data sheet, its saturated samples
lie just beyond it. Every kind integrates a sample with a component beyond ``gyro_range`` and within
twice it as read, flagged ATT_FLAG_GYRO_RANGE (att_core.h att_i_gyro_usable); beyond twice the sample
is corrupt and not integrated. Before (until 2026-12-06) every such sample was skipped: on the suite's
clipped condition with the range 0.01 % below the rail kf 1.52 -> 6.64 deg, ekf 2.18 -> 13.17, mars
2.36 -> 10.24, mekf 2.45 -> 12.41 (the last test: now as with the range at the rail).
"""

from __future__ import annotations

import numpy as np
import pytest

from attica import native
from attica.crosscheck import Stream, crosscheck
from attica.evaluate.core import attica_method
from attica.evaluate.suite import score_method
from attica.settings import FilterKind, Flag, make_settings
from attica.sim import SimConfig, simulate
from attica.sim.conditions import condition

RATE = 200.0
RANGE = np.float32(8.0)
KINDS = [k for k in FilterKind if k != FilterKind.TILT]


def _rec(seed: int = 5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rec = simulate(SimConfig(duration=10.0, rate=RATE, seed=seed, rest_breaks=0))
    return rec.gyr.astype(np.float32).copy(), rec.acc.astype(np.float32), rec.mag.astype(np.float32)


def _run(
    kind: FilterKind, g: np.ndarray, a: np.ndarray, m: np.ndarray, rng: float = float(RANGE)
) -> np.ndarray:
    f = native.Filter(kind, 1.0 / RATE, gyro_range=rng)
    return np.asarray(
        f.run(g, a, m if kind in (FilterKind.MARS, FilterKind.MEKF) else None, check_units=False)
    )


@pytest.mark.parametrize("level", [1.004, 1.9, 2.0])
@pytest.mark.parametrize("kind", KINDS, ids=lambda k: k.label)
def test_a_reading_at_the_rail_is_integrated_as_read(kind: FilterKind, level: float) -> None:
    """Components in (range, 2 range] step the filter as they would with a range just above them (the
    clip recovery starts in both), only flagged GYRO_RANGE."""
    g, a, m = _rec()
    assert np.abs(g).max() < 0.9 * RANGE  # no other sample near either range's clip level
    value = RANGE * np.float32(level)
    g[300:340, 0] = value
    g[300:340, 2] = -value
    got = _run(kind, g, a, m)
    wide = _run(kind, g, a, m, float(value) * 1.001)  # the same samples within this range
    assert got["q"].tobytes() == wide["q"].tobytes()
    assert got["gyro_bias"].tobytes() == wide["gyro_bias"].tobytes()
    beyond = (np.abs(g) > RANGE).any(axis=1)
    np.testing.assert_array_equal(got["flags"] & ~np.uint32(Flag.GYRO_RANGE), wide["flags"])
    assert ((got["flags"] & Flag.GYRO_RANGE) != 0).tolist() == beyond.tolist()
    if kind != FilterKind.GYRO:
        assert (got["flags"][beyond] & Flag.INITIALISED).all()  # the recovery after a clipping gyro runs


@pytest.mark.parametrize("kind", KINDS, ids=lambda k: k.label)
def test_beyond_twice_the_range_the_sample_is_not_used(kind: FilterKind) -> None:
    """A component beyond 2 range (or not finite) is a corrupt sample, not integrated."""
    g, a, m = _rec()
    bad = g.copy()
    bad[400, 1] = RANGE * np.float32(2.0) * np.float32(1.0001)
    out = _run(kind, bad, a, m)
    assert out["flags"][400] & Flag.GYRO_RANGE
    if kind == FilterKind.GYRO:  # the integrator alone: its attitude stays
        assert out["q"][400].tobytes() == out["q"][399].tobytes()
    wide = _run(kind, bad, a, m, float(RANGE) * 2.1)  # integrated there
    assert wide["q"][400].tobytes() != out["q"][400].tobytes()


@pytest.mark.parametrize("kind", KINDS, ids=lambda k: k.label)
def test_reference_agrees_at_and_beyond_the_rail(kind: FilterKind) -> None:
    g, a, m = _rec(7)
    g[200:230, 0] = RANGE * np.float32(1.3)
    g[240:245, 1] = -RANGE * np.float32(2.0)
    g[250:252, 2] = RANGE * np.float32(2.5)
    g[260, 0] = np.nan
    g[261, 1] = np.inf
    s = make_settings(kind, None, dt=1.0 / RATE, gyro_range=float(RANGE))
    r = crosscheck(kind, [Stream(g, a, m, "rail")], s)
    assert r.ok, r.first_mismatch


@pytest.mark.parametrize("kind", ["kf", "ekf", "mars", "mekf"])
def test_a_range_just_below_the_rail_costs_nothing(kind: str) -> None:
    """The suite's clipped condition with gyro_range 0.01 % below the sensor's rail scores as at the rail."""
    c = condition("clipped")
    rec = simulate(c.config(2))
    at = score_method(
        attica_method(FilterKind.parse(kind), overrides={"gyro_range": c.gyro_range}), rec, c.score_from
    )
    below = score_method(
        attica_method(FilterKind.parse(kind), overrides={"gyro_range": c.gyro_range * 0.9999}),
        rec,
        c.score_from,
    )
    judged = (lambda e: e.total) if kind in ("mars", "mekf") else (lambda e: e.inclination)
    assert judged(below[0]) < 1.05 * judged(at[0]), (judged(below[0]), judged(at[0]))


@pytest.mark.parametrize("kind", KINDS, ids=lambda k: k.label)
def test_the_largest_rate_integrated_stays_finite(kind: FilterKind) -> None:
    """The largest rate a filter now integrates is twice the largest gyro_range (2e3 rad/s at 1e3), here at
    a period of 0.5 s (1e3 rad a step): every output finite and q a unit quaternion."""
    n = 200
    rng = np.random.default_rng(3)
    g = (rng.uniform(-1.0, 1.0, (n, 3)) * 2e3).astype(np.float32)
    g[::7] = np.float32(2e3)
    a = np.tile(np.float32([0.0, 0.0, 9.80665]), (n, 1))
    m = np.tile(np.float32([0.0, 20.0, -40.0]), (n, 1))
    f = native.Filter(kind, 0.5, gyro_range=1e3)
    out = np.asarray(
        f.run(g, a, m if kind in (FilterKind.MARS, FilterKind.MEKF) else None, check_units=False)
    )
    assert np.isfinite(out["q"]).all() and np.isfinite(out["euler"]).all() and np.isfinite(out["cov"]).all()
    np.testing.assert_allclose(np.linalg.norm(out["q"].astype(np.float64), axis=1), 1.0, atol=1e-5)
    assert not (out["flags"] & Flag.GYRO_INVALID).any()
    # integrated, not skipped: the same run with those samples beyond the rail (skipped) differs
    beyond = g.copy()
    beyond[::7] = np.float32(2.5e3)
    skipped = native.Filter(kind, 0.5, gyro_range=1e3)
    other = np.asarray(
        skipped.run(beyond, a, m if kind in (FilterKind.MARS, FilterKind.MEKF) else None, check_units=False)
    )
    assert other["q"].tobytes() != out["q"].tobytes()
