"""The covariance model of the complementary filters (ars, mars; issue 23, docs/filters.md "Covariance").

- C and the reference bit for bit, the covariance included, on streams with rejected and missing accel
  samples, a clipping gyro, a disturbed field, with the defaults, the seed preset (no low-pass, a
  partial correction), a time constant after the low-pass, no accel correction at all;
- the model against Monte Carlo: a still sensor with white gyro and accel noise of the densities the
  settings state; the tilt error's measured variance against cov[0], within 10 %;
- what moves it: missing or rejected accel samples add gyro_noise^2 dt per step; a recovery raises
  it; the heading is unknown (pi^2/3) until set (ars) or aligned (mars), then small and growing without
  mag samples; a weak horizontal field gives a larger heading variance;
- the settings contract of the three densities;
- docs/accuracy.md's tables of every kind's covariance against BROAD and the simulator are what
  ``attica_dev.cov_check`` computes.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from attica import native
from attica.crosscheck import Stream, crosscheck
from attica.evaluate import load_trials
from attica.settings import ArsSettings, BiasMode, FilterKind, MarsSettings, Preset, preset_settings
from attica.sim import SimConfig, simulate
from attica_dev import cov_check

from helpers import BROAD, broad_trials

RATE = 100.0
DT = float(np.float32(1.0 / RATE))
G = 9.80665
UNKNOWN = float(np.float32(math.pi**2 / 3.0))
KINDS = {FilterKind.ARS: ArsSettings, FilterKind.MARS: MarsSettings}


def _settings(kind: FilterKind, **over: Any) -> Any:
    return replace(KINDS[kind](dt=DT), **over)


def _streams(seed: int) -> list[Stream]:
    """A simulated run with gaps, rejected-looking samples, a clipping gyro and a disturbed field."""
    r = simulate(
        SimConfig(duration=40.0, rate=RATE, seed=seed, mag_disturbances=((5.0, 15.0, (8.0, -6.0, 4.0)),))
    )
    gyr, acc, mag = r.gyr.copy(), r.acc.copy(), r.mag.copy()
    acc[500:700] = np.nan  # accel missing for 2 s
    acc[1200:1300] *= 1.6  # far from g: rejected where accel_reject is set
    mag[2000:2400] = np.nan  # mag missing for 4 s
    gyr[2600:2605, 0] = 40.0  # beyond the 2000 deg/s range: a recovery
    return [Stream(gyr, acc, mag, name=f"seed {seed}")]


SETTINGS = {
    "defaults": {},
    "mars: full mag mode": {"mag_mode": 1},
    "not from the sensors": {"init_from_sensors": False},
    "not from the sensors, m0 given": {"init_from_sensors": False, "m0_init": (0.0, 20.0, -40.0)},
    "ars: not from the accel": {"init_from_accel": False},
    "reject": {"accel_reject": 0.2},
    "tau after the low-pass": {"tau_acc_lp": 0.8},
    "no low-pass": {"tau_acc_lp": 0.0},
    "zero noise": {"gyro_noise": 0.0, "accel_noise": 0.0},
}


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
@pytest.mark.parametrize("name", list(SETTINGS))
def test_bit_exact_with_the_covariance(kind: FilterKind, name: str) -> None:
    over = dict(SETTINGS[name])
    fields = {f for f in KINDS[kind].__dataclass_fields__}
    if not set(over) <= fields:
        over = {"init_from_accel": False} if "from the sensors" in name else {}  # ars's form of the case
    if name == "tau after the low-pass":
        over.update({"tau": 0.5} if kind == FilterKind.ARS else {"tau_acc": 0.5, "alpha_acc": 0.0})
    res = crosscheck(kind, _streams(3), settings=_settings(kind, **over), segment=700)
    assert res.ok, res.first_mismatch or f"{res.state_mismatches} state mismatches"
    cov = res.c_outputs[0]["cov"]
    assert np.isfinite(cov).all() and (cov >= 0.0).all()


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
def test_bit_exact_seed_preset_and_no_accel_correction(kind: FilterKind) -> None:
    seed = preset_settings(kind, Preset.SEED, dt=DT)
    # no accel correction; gyro_noise 0, so that only the rule (not the cap) can give pi^2/12
    off = _settings(kind, gyro_noise=0.0, **({"gain": 0.0} if kind == FilterKind.ARS else {"alpha_acc": 0.0}))
    for s in (seed, off):
        res = crosscheck(kind, _streams(4), settings=s, segment=900)
        assert res.ok, res.first_mismatch or f"{res.state_mismatches} state mismatches"
    out = native.Filter(kind, off).run(*(_streams(4)[0].gyr, _streams(4)[0].acc), check_units=False)
    # no accel correction: the tilt is not observed, before the recovery after the clipping sample at
    # 2600; ars's recoveries correct with their own gain, the start's (recovery_time 2 s) too
    unknown = np.float32(math.pi**2 / 12.0)
    start = round(2.0 / DT) if kind == FilterKind.ARS else 5
    assert (out["cov"][start:2600, 0] == unknown).all(), "no accel correction: unknown"
    if kind == FilterKind.ARS:
        assert (out["cov"][:start, 0] < unknown).all(), "the start's recovery corrects the tilt"


def _still(seed: int, seconds: float, gyro_noise: float, accel_noise: float) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    n = int(seconds * RATE)
    gyr = rng.standard_normal((n, 3)) * (gyro_noise / math.sqrt(DT))
    acc = np.array([0.0, 0.0, G]) + rng.standard_normal((n, 3)) * (accel_noise / math.sqrt(DT))
    return gyr.astype(np.float32), acc.astype(np.float32)


MONTE_CARLO = {
    # name: (settings, gyro_noise, accel_noise, bounds of measured / model)
    "defaults (two low-pass stages, full alignment)": ({}, 0.002, 0.3, (0.9, 1.1)),
    "short low-pass": ({"tau_acc_lp": 0.3}, 0.002, 0.3, (0.9, 1.1)),
    "long low-pass": ({"tau_acc_lp": 5.0}, 0.002, 0.3, (0.9, 1.1)),
    "no low-pass, partial gain (exact)": ({"gain": 0.1, "tau_acc_lp": 0.0}, 0.002, 0.05, (0.9, 1.1)),
    "no low-pass, full alignment (exact)": ({"tau_acc_lp": 0.0}, 0.002, 0.05, (0.9, 1.1)),
    # the gyro term dominates (about 2000 times the accel term): its tc^3 .. tl^3 coefficients
    "gyro-dominated, partial gain after the low-pass": (
        {"tau": 2.0, "tau_acc_lp": 1.0},
        0.01,
        0.01,
        (0.9, 1.1),
    ),
    "partial gain after the low-pass": ({"tau": 0.5}, 0.002, 0.3, (0.9, 1.1)),
}


@pytest.mark.parametrize("name", list(MONTE_CARLO))
def test_tilt_variance_against_monte_carlo(name: str) -> None:
    """A still ars with white noise of the stated densities (bias off, no recovery): the measured variance
    of the tilt error about x and y over an hour, against cov[0] (the model's steady state)."""
    over, gyro_noise, accel_noise, (lo, hi) = MONTE_CARLO[name]
    s = _settings(
        FilterKind.ARS,
        bias_mode=BiasMode.OFF,
        recovery_time=0.0,
        gyro_noise=gyro_noise,
        accel_noise=accel_noise,
        **over,
    )
    gyr, acc = _still(11, 3600.0, gyro_noise, accel_noise)
    out = native.Filter(FilterKind.ARS, s).run(gyr, acc, check_units=False)
    q = out["q"][len(out) // 10 :].astype(np.float64)
    sign = np.sign(q[:, 0])
    measured = (np.var(2.0 * q[:, 1] * sign) + np.var(2.0 * q[:, 2] * sign)) / 2.0
    model = float(out["cov"][-1, 0])
    assert out["cov"][-1, 1] == out["cov"][-1, 0]
    assert lo < measured / model < hi, f"{name}: measured {measured:.3e} rad^2, model {model:.3e}"


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
def test_what_moves_the_tilt_variance(kind: FilterKind) -> None:
    """Missing accel samples add gyro_noise^2 dt per step (float32 of it, to rounding); the next accepted
    sample brings the steady state back; a clipping gyro raises it by up to pi^2/48 over the recovery."""
    r = simulate(SimConfig(duration=20.0, rate=RATE, seed=5))
    gyr, acc, mag = r.gyr.copy(), r.acc.copy(), r.mag.copy()
    acc[600:800] = np.nan
    gyr[1200, 2] = 40.0
    s = _settings(kind)
    out = native.Filter(kind, s).run(gyr, acc, mag, check_units=False)
    tilt = out["cov"][:, 0].astype(np.float64)
    steady = tilt[590]
    step = np.float32(np.float32(s.gyro_noise) * np.float32(s.gyro_noise)) * np.float32(DT)
    n = np.arange(1, 201).astype(np.float32)
    expected = np.float32(steady) + step * n  # att_i_cov_grow's operations in float32
    assert out["cov"][600:800, 0].tobytes() == expected.astype(np.float32).tobytes()
    assert tilt[800] == steady, "the first accepted sample after the gap"
    rec = tilt[1200:1300]
    assert rec[0] > steady + 0.2 and np.all(np.diff(rec) < 0), "the recovery's term fades"
    assert tilt[1200 + int(s.recovery_time * RATE) + 5] == steady


@pytest.mark.parametrize("how", ["set_heading", "heading update of gain 1", "heading update of gain 0.5"])
def test_ars_heading_unknown_until_set(how: str) -> None:
    """pi^2/3 until a heading is set (att_filter_set_heading, or an update of gain 1: the same call), then
    gyro_noise^2 dt per step; an update of gain < 1 leaves it unknown. C and reference bit for bit."""
    from attica.reference.filter import Filter as RefFilter

    r = simulate(SimConfig(duration=10.0, rate=RATE, seed=6))
    s = _settings(FilterKind.ARS)
    f = native.Filter(FilterKind.ARS, s)
    ref = RefFilter(FilterKind.ARS, s)
    out = f.run(r.gyr[:300], r.acc[:300], check_units=False)
    ref.run(r.gyr[:300], r.acc[:300], check_units=False)
    assert (out["cov"][1:, 2] == np.float32(UNKNOWN)).all()
    for obj in (f, ref):
        if how == "set_heading":
            obj.set_heading(0.5)
        else:
            obj.heading_update(0.5, 1.0 if "gain 1" in how else 0.5)
    out = f.run(r.gyr[300:], r.acc[300:], check_units=False)
    ref.run(r.gyr[300:], r.acc[300:], check_units=False)
    assert f.output()["cov"].tobytes() == ref.output()["cov"][0].tobytes(), "C vs reference"
    if how.endswith("0.5"):
        assert (out["cov"][:, 2] == np.float32(UNKNOWN)).all()
        return
    step = np.float32(np.float32(0.002) * np.float32(0.002)) * np.float32(DT)
    expected = np.float32(0.0) + step * np.arange(1, len(out) + 1).astype(np.float32)
    assert out["cov"][:, 2].tobytes() == expected.astype(np.float32).tobytes()


def test_ars_heading_unknown_again_after_a_clip() -> None:
    """A clipping gyro sample (one that starts a recovery) makes a set heading unknown again: the rotation
    it lost turns the heading too (before, the variance went on growing from the set heading's, 0.4 deg
    against a 70 deg error). C and reference bit for bit."""
    from attica.reference.filter import Filter as RefFilter

    r = simulate(SimConfig(duration=10.0, rate=RATE, seed=6))
    s = _settings(FilterKind.ARS)
    f = native.Filter(FilterKind.ARS, s)
    ref = RefFilter(FilterKind.ARS, s)
    for obj in (f, ref):
        obj.run(r.gyr[:300], r.acc[:300], check_units=False)
        obj.set_heading(0.5)
        obj.run(r.gyr[300:400], r.acc[300:400], check_units=False)
    assert f.output()["cov"][2] < 1e-5
    gyr = r.gyr[400:600].copy()
    gyr[50:60, 2] = 0.985 * float(s.gyro_range)  # ten clipping samples
    out = f.run(gyr, r.acc[400:600], check_units=False)
    ref.run(gyr, r.acc[400:600], check_units=False)
    assert (out["cov"][:50, 2] < 1e-5).all()
    assert (out["cov"][50:, 2] == np.float32(UNKNOWN)).all()
    assert f.output()["cov"].tobytes() == ref.output()["cov"][0].tobytes(), "C vs reference"


def test_mars_heading_variance() -> None:
    """Unknown before the alignment, the model's steady state after it (larger in a weaker horizontal
    field: up to the ratio of the fields' squares, the gyro term being the same), growing while the mag
    is missing and back at the next accepted sample."""
    outs = {}
    for h in (20.0, 5.0):  # the horizontal field, uT, of a 49 uT field
        r = simulate(SimConfig(duration=40.0, rate=RATE, seed=7, mag_dip=math.acos(h / 49.0)))
        mag = r.mag.copy()
        mag[:100] = np.nan
        mag[2500:2700] = np.nan  # after the fast phase of the alignment (15 s)
        outs[h] = native.Filter(FilterKind.MARS, _settings(FilterKind.MARS)).run(r.gyr, r.acc, mag)
    yaw = outs[20.0]["cov"][:, 2].astype(np.float64)
    # the alignment at 100 is inside the start's recovery (2 s): its gain k_rec until step 200
    rec = round(2.0 / DT)
    assert (yaw[:100] == np.float32(UNKNOWN)).all() and (yaw[100:rec] < 0.1).all() and yaw[rec + 1] < 1e-2
    assert yaw[rec + 1] < yaw[rec - 1] / 4.0  # the recovery's fast gain lets more noise through
    base = yaw[2490]
    assert (
        np.all(np.diff(yaw[2500:2700]) > 0) and yaw[2700] <= base * 1.01
    )  # the learnt reference moves h a little
    ratio = outs[5.0]["cov"][2490, 2] / outs[20.0]["cov"][2490, 2]
    assert 4.0 < ratio <= 16.0, ratio  # 16: the mag term alone, (20 / 5)^2; the gyro term is in both


DENSITIES = [
    (kind, field)
    for kind in KINDS
    for field in ("gyro_noise", "accel_noise", "mag_noise")
    if not (kind == FilterKind.ARS and field == "mag_noise")
]


@pytest.mark.parametrize(("kind", "field"), DENSITIES, ids=lambda x: getattr(x, "label", x))
@pytest.mark.parametrize("bad", [-1e-3, math.nan, math.inf, 2e3])
def test_densities_out_of_range_are_refused(kind: FilterKind, field: str, bad: float) -> None:
    with pytest.raises(native.NativeError, match=field):
        native.Filter(kind, _settings(kind, **{field: bad}))


def _doc_rows(marker: str) -> list[list[str]]:
    text = (Path(__file__).resolve().parent.parent / "docs" / "accuracy.md").read_text(encoding="utf-8")
    rows = []
    for line in text[text.index(f"<!-- {marker}") :].splitlines()[1:]:
        if not line.startswith("|"):
            if len(rows) > 2:
                break
            continue
        rows.append([c.strip() for c in line.strip().strip("|").split("|")])
    return rows[2:]


def _doc_header(marker: str) -> list[str]:
    text = (Path(__file__).resolve().parent.parent / "docs" / "accuracy.md").read_text(encoding="utf-8")
    line = next(x for x in text[text.index(f"<!-- {marker}") :].splitlines()[1:] if x.startswith("|"))
    return [c.strip() for c in line.strip().strip("|").split("|")]


def test_docs_cov_check_table() -> None:
    """docs/accuracy.md's BROAD table of every kind's covariance is what attica_dev.cov_check computes."""
    broad_trials()
    recs = load_trials(BROAD)
    got = {}
    for method in cov_check.METHODS:
        for angle, c in cov_check.measure(recs, method).items():
            r = c.per_trial
            held = float(np.mean(c.held_out() * c.var) / np.mean(c.var))
            got[f"{method} {angle}"] = [
                f"{np.degrees(np.sqrt(c.mse.mean())):.2f}",
                f"{np.degrees(np.sqrt(c.var.mean())):.2f}",
                f"{c.pooled:.2f}",
                f"{held:.2f}",
                f"{r.min():.2f}, {np.median(r):.2f}, {r.max():.2f}",
            ]
    rows = _doc_rows("cov-check")
    assert [row[0] for row in rows] == [f"{m} {a}" for m, a in cov_check.columns()]
    assert {row[0]: row[1:] for row in rows} == got


def test_docs_cov_check_simulator_table() -> None:
    """docs/accuracy.md's simulator table of every kind's covariance (the rows it shows) is cov_check's."""
    sims = {method: cov_check.simulated(method) for method in cov_check.METHODS}
    header = _doc_header("cov-check-sim")
    assert header == ["condition"] + [f"{m} {a}" for m, a in cov_check.columns()]
    rows = _doc_rows("cov-check-sim")
    assert len(rows) >= 8
    for name, *cells in rows:
        got = [sims[m][name][a].pooled for m, a in cov_check.columns()]
        assert cells == [f"{x:.2f}" for x in got], name


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
def test_not_initialised_reports_unknown(kind: FilterKind) -> None:
    """Before the first accel sample there is no attitude: the caps (pi^2/12 tilt, pi^2/3 heading)."""
    f = native.Filter(kind, _settings(kind))
    nan = np.full((20, 3), np.nan, np.float32)
    out = f.run(np.zeros((20, 3), np.float32), nan, nan, check_units=False)
    assert (out["cov"][:, 0] == np.float32(math.pi**2 / 12.0)).all()
    assert (out["cov"][:, 2] == np.float32(UNKNOWN)).all()


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
def test_a_retune_limits_the_recovery(kind: FilterKind) -> None:
    """A retune to recovery_time 0 inside a recovery ends it (as kf, ekf and mekf): C and reference bit
    for bit, the covariance back at its steady state after the next accepted sample."""
    from attica.reference.filter import Filter as RefFilter

    r = simulate(SimConfig(duration=10.0, rate=RATE, seed=8))
    gyr = r.gyr.copy()
    gyr[300, 1] = 40.0
    s = _settings(kind)
    f = native.Filter(kind, s)
    ref = RefFilter(kind, s)
    f.run(gyr[:320], r.acc[:320], r.mag[:320], check_units=False)
    ref.run(gyr[:320], r.acc[:320], r.mag[:320], check_units=False)
    assert int(f.output()["flags"]) & 0x0400, "in the recovery"
    s0 = replace(s, recovery_time=0.0)
    f.retune(s0)
    ref.retune(s0)
    out = f.run(gyr[320:], r.acc[320:], r.mag[320:], check_units=False)
    ref.run(gyr[320:], r.acc[320:], r.mag[320:], check_units=False)
    assert ref.state_matches(0, f.state.copy()[0]), ref.state_diff(0, f.state.copy()[0])
    assert not (out["flags"] & 0x0400).any(), "the recovery ended with the retune"
    steady = native.Filter(kind, s0).run(r.gyr, r.acc, r.mag, check_units=False)["cov"][-1, 0]
    assert out["cov"][5, 0] == steady
