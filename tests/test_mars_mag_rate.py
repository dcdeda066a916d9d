"""mars with a magnetometer slower than the gyro (issue 23, stop 46): ``tau_mag`` is a time constant in s.

A magnetometer often samples at a tenth of the IMU's rate (100 Hz beside 1 kHz); attica's loaders place
each sample once and leave the rows between absent (docs/recordings.md). mars corrected by its per-step
gain at each sample, so its heading correction ran as many times slower as the samples were rarer (a
mag every 10 steps: a 200 s time constant for the default 20 s). Now a valid sample after ``g`` absent
steps corrects by the gain of ``n`` steps, ``1 - (1 - k)^n`` (att_mars_gap_gain), ``n = g + 1`` when
the sample before also ended a gap, at most that gap + 1 (a regular period is made up, an outage is
not), else 1; invalid and rejected samples end their gap with nothing applied.

- the steady heading error under a constant gyro bias is ``bias * tau_mag`` whatever the mag's rate
  (before: 9.4 times that with a mag every 10 steps after 60 s, not yet settled);
- a simulated 1 kHz IMU with a 100 Hz mag is as accurate as with a mag every step (before: 33 % worse);
- an outage is not made up: the sample after it corrects as one step (or one regular period) would;
- C equals the reference bit for bit with gaps of 1 to 400 steps, outages, invalid and rejected
  samples, zero and NaN absent rows, a retune, and in each mode;
- the gain of n steps against 1 - (1 - k)^n.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest

from attica import native
from attica.evaluate.core import attica_method, method_kind
from attica.evaluate.suite import score_method
from attica.evaluate.trace import euler_deg
from attica.reference.filter import Filter as RefFilter
from attica.reference.mars import gap_gain
from attica.settings import BiasMode, FilterKind, MagMode, make_settings
from attica.sim import SimConfig, simulate
from attica_dev import mag_rate

DT = float(np.float32(0.01))


def _every(mag: np.ndarray, every: int, offset: int = 0) -> np.ndarray:
    """mag with only every ``every``-th row kept, the others absent (NaN)."""
    out = mag.copy()
    out[(np.arange(len(mag)) + offset) % every != 0] = np.nan
    return out


@pytest.mark.parametrize("every", [1, 10, 50])
def test_steady_heading_error_is_bias_times_tau(every: int) -> None:
    """A still sensor with a constant gyro bias the filter does not estimate: the complementary heading
    correction settles at an error of bias * tau_mag, whatever the mag's rate (attica_dev.mag_rate)."""
    assert mag_rate.steady_ratio(every) == pytest.approx(1.0, abs=0.01)


def test_a_slower_magnetometer_costs_no_accuracy() -> None:
    """1 kHz IMU, 100 Hz mag (absent between its samples): mars's RMSE within 5 % of a mag every step."""
    rec = simulate(SimConfig(duration=40.0, rate=1000.0, seed=2))
    slow = dataclasses.replace(rec, mag=_every(rec.mag, 10))
    m = attica_method(method_kind("mars"))
    every = score_method(m, rec, 5.0)[0].total
    tenth = score_method(m, slow, 5.0)[0].total
    assert tenth < 1.05 * every, (every, tenth)


CASES: dict[str, dict[str, Any]] = {
    "defaults": {},
    "hard iron": {"hard_iron_tau": 20.0},
    "per-sample gain": {"tau_mag": 0.0, "alpha_mag": 0.02},
    "full mag mode": {"mag_mode": MagMode.FULL},
    "no fast phase": {"tau_mag_fast": 0.0},
    "m0 given": {"init_from_sensors": False, "m0_init": (0.0, 20.0, -40.0)},
    "bias from the heading": {"tau_bias_mag": 80.0},
}
PATTERNS = ("absent", "outage", "invalid", "zero")


def _pattern(mag: np.ndarray, every: int, pattern: str) -> np.ndarray:
    """mag every ``every`` steps (NaN between, or zero), with a 4 s outage or invalid rows."""
    out = _every(mag, every, offset=1)
    if pattern == "zero":
        out[np.isnan(out).any(axis=1)] = 0.0
    if pattern == "outage":
        out[1500:1900] = np.nan
    if pattern == "invalid":
        out[1500:1510] = 5000.0  # beyond mag_range
        out[2000] = np.inf
    return out


@pytest.mark.parametrize("case", list(CASES))
def test_c_equals_reference(case: str) -> None:
    """A mag every 1, 3, 10 and 37 steps in each pattern (the reference runs them as 16 instances at
    once), across a field disturbed for 2 s (rejected samples), a clip (the recovery's gain) and a retune
    (tau_mag 5 s) half way."""
    rec = simulate(
        SimConfig(duration=30.0, rate=100.0, seed=3, mag_disturbances=((12.0, 14.0, (30.0, -20.0, 10.0)),))
    )
    gyr = rec.gyr.copy()
    gyr[900:905, 2] = 40.0
    s = make_settings(FilterKind.MARS, dt=DT, **CASES[case])
    mags = np.stack([_pattern(rec.mag, e, p) for e in (1, 3, 10, 37) for p in PATTERNS], axis=1)
    n = mags.shape[1]
    ref = RefFilter(FilterKind.MARS, s, n=n)
    tiles = [np.repeat(x[:, None, :], n, axis=1) for x in (gyr, rec.acc)]
    halves = (slice(0, 1200), slice(1200, None))
    want = []
    for i, part in enumerate(halves):
        if i:
            ref.retune(dataclasses.replace(s, tau_mag=5.0))
        want.append(ref.run(tiles[0][part], tiles[1][part], mags[part], check_units=False))
    for j in range(n):
        f = native.Filter(FilterKind.MARS, s)
        for i, part in enumerate(halves):
            if i:
                f.retune(dataclasses.replace(s, tau_mag=5.0))
            got = f.run(gyr[part], rec.acc[part], mags[part, j], check_units=False)
            assert got.tobytes() == np.ascontiguousarray(want[i][:, j]).tobytes(), (j, i)


def _yaw(q: np.ndarray) -> np.ndarray:
    return euler_deg(q.astype(np.float64))[:, 2]


@pytest.mark.parametrize("every", [1, 10])
@pytest.mark.parametrize("outage", ["absent", "invalid"])
def test_an_outage_is_not_made_up(every: int, outage: str) -> None:
    """A still sensor, its mag every ``every`` steps; 3 s without a usable sample (absent rows, or its
    samples invalid), after which the field has turned by 30 deg (a turned reference is accepted: norm and
    dip unchanged). The first sample after the outage corrects as one regular period would (``every``
    steps' gain), not as the 300 steps of the outage; the next ones as their period again."""
    n, dt = 6000, DT
    gyr = np.zeros((n, 3), np.float32)
    acc = np.tile(np.array([0.0, 0.0, 9.80665], np.float32), (n, 1))
    turned = 30.0
    c, s_ = math.cos(math.radians(turned)), math.sin(math.radians(turned))
    field = np.tile(np.array([0.0, 20.0, -40.0], np.float32), (n, 1))
    field[4300:] = np.array([-20.0 * s_, 20.0 * c, -40.0], np.float32)
    mag = _every(field, every)
    if outage == "absent":
        mag[4000:4300] = np.nan
    else:  # the magnetometer's own samples invalid (saturated near a magnet), at its rate
        rows = np.arange(4000, 4300)
        mag[rows[rows % every == 0]] = 5000.0
    s = make_settings(FilterKind.MARS, dt=dt, tau_mag_fast=0.0, bias_mode=BiasMode.OFF)
    yaw = _yaw(native.Filter(FilterKind.MARS, s).run(gyr, acc, mag, check_units=False)["q"])
    k = dt / (float(s.tau_mag) + dt)
    step = 1.0 - (1.0 - k) ** every  # the gain of one regular period
    first = abs(yaw[4300] - yaw[4299])
    assert first == pytest.approx(step * turned, rel=0.02), (first, step * turned)
    second = abs(yaw[4300 + every] - yaw[4300 + every - 1])
    assert second == pytest.approx(step * (turned - first), rel=0.02)


@pytest.mark.parametrize("k", [1e-6, 5e-5, 0.01, 0.3, 1.0])
def test_gain_of_n_steps(k: float) -> None:
    n = np.arange(1, 257, dtype=np.uint32)
    got = gap_gain(np.full(len(n), k, np.float32), n).astype(np.float64)
    k32 = float(np.float32(k))
    want = np.array([-math.expm1(int(m) * math.log1p(-k32)) if k32 < 1.0 else 1.0 for m in n])
    np.testing.assert_allclose(got, want, rtol=2e-6 * 9, atol=0.0)
    assert got[0] == np.float32(k)  # one step: the gain itself


def test_docs_table_is_what_the_tool_computes() -> None:
    """docs/accuracy.md quotes ``python -m attica_dev.mag_rate`` as it is now."""
    from helpers import ROOT

    text = (ROOT / "docs" / "accuracy.md").read_text()
    assert mag_rate.tables() in text
