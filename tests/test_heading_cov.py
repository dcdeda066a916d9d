"""The heading variance of the Kalman kinds once a heading is set (ekf, 6-axis mekf; issue 23, stop 46).

A 6-axis filter's yaw is observed by nothing, so its output reports pi^2/3 (unknown) about up, as ars
does. After ``att_filter_set_heading`` (or a heading update of gain 1, the same call) the heading is
known: the ekf's yaw variance and the mekf's heading row restart at one step's process noise (the mekf's
correlations zero, as at the start's mag alignment); the output then reports that variance, growing,
until a clipping gyro sample (one that starts a recovery), whose lost rotation turns the heading too.
An update of gain < 1 leaves the heading unknown (the filter does not know the source's noise). The
MCAP's orientation covariance takes it from the output. C and reference bit for bit throughout. (The
ekf's restart after a step flagged NUMERIC makes it unknown too: tests/test_ekf.py,
test_prediction_beyond_the_wrap_range_keeps_the_angles.)
Before stop 46 the ekf reported its grown yaw variance and the mekf its P's from the start, and the
MCAP wrote pi^2/3 for both whatever was set.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from attica import native
from attica.data.covariance import orientation_covariance
from attica.reference.filter import Filter as RefFilter
from attica.settings import FilterKind, make_settings
from attica.sim import SimConfig, simulate

RATE = 100.0
DT = float(np.float32(1.0 / RATE))
UNKNOWN = np.float32(math.pi**2 / 3.0)
CASES = {
    "ekf": (FilterKind.EKF, {}),
    "mekf6": (FilterKind.MEKF, {"use_mag": False}),
}


def _settings(name: str) -> Any:
    kind, over = CASES[name]
    return kind, make_settings(kind, dt=DT, **over)


def _pair(name: str) -> tuple[native.Filter, RefFilter, Any]:
    kind, s = _settings(name)
    return native.Filter(kind, s), RefFilter(kind, s), s


def _run(f: native.Filter, ref: RefFilter, gyr: Any, acc: Any) -> np.ndarray:
    out = f.run(gyr, acc, check_units=False)
    ref.run(gyr, acc, check_units=False)
    assert f.output().tobytes() == ref.output()[0].tobytes(), "C vs reference (the whole output record)"
    return out


def _set_after(f: native.Filter, ref: RefFilter, gyr: Any, acc: Any, heading: float) -> None:
    """Both filters run ``gyr, acc`` and then have ``heading`` set (rad)."""
    for obj in (f, ref):
        obj.run(gyr, acc, check_units=False)
        obj.set_heading(heading)


def _step_noise(name: str, s: Any) -> np.float32:
    """One step's heading process noise, where a set heading's variance restarts: the ekf's q_psi dt
    (noise_rates), the mekf's gyro_noise^2 dt."""
    dt = np.float32(s.dt)
    if name == "ekf":
        return np.float32(np.float32(s.q_psi) * dt)
    return np.float32(np.float32(np.float32(s.gyro_noise) * np.float32(s.gyro_noise)) * dt)


@pytest.mark.parametrize("name", list(CASES))
@pytest.mark.parametrize("how", ["set_heading", "heading update of gain 1", "heading update of gain 0.5"])
def test_heading_unknown_until_set(name: str, how: str) -> None:
    r = simulate(SimConfig(duration=10.0, rate=RATE, seed=6))
    f, ref, s = _pair(name)
    out = _run(f, ref, r.gyr[:300], r.acc[:300])
    assert (out["cov"][1:, 2] == UNKNOWN).all(), "a 6-axis filter's yaw is unknown from the start"
    for obj in (f, ref):
        if how == "set_heading":
            obj.set_heading(0.5)
        else:
            obj.heading_update(0.5, 1.0 if "gain 1" in how else 0.5)
    assert f.output()["cov"].tobytes() == ref.output()["cov"][0].tobytes(), "C vs reference at the set"
    out = _run(f, ref, r.gyr[300:], r.acc[300:])
    yaw = out["cov"][:, 2]
    if how.endswith("0.5"):
        assert (yaw == UNKNOWN).all(), "an update of gain < 1 does not make the heading known"
        return
    q = _step_noise(name, s)
    assert q <= yaw[0] < 1e-3, "exact at the set: one step's noise (with the rate's, mekf) after it"
    assert yaw[-1] > 100.0 * yaw[0], "then it grows with the gyro's noise"
    assert (yaw < 0.01).all()


@pytest.mark.parametrize("name", list(CASES))
def test_heading_unknown_again_after_a_clip(name: str) -> None:
    r = simulate(SimConfig(duration=10.0, rate=RATE, seed=6))
    f, ref, s = _pair(name)
    _set_after(f, ref, r.gyr[:300], r.acc[:300], 0.5)
    _run(f, ref, r.gyr[300:400], r.acc[300:400])
    assert f.output()["cov"][2] < 0.01
    gyr = r.gyr[400:800].copy()
    gyr[50:60, 2] = 0.985 * float(s.gyro_range)  # ten clipping samples; the recovery ends 2 s later
    out = _run(f, ref, gyr, r.acc[400:800])
    assert (out["cov"][:50, 2] < 0.01).all()
    assert (out["cov"][50:, 2] == UNKNOWN).all(), "the clip's lost rotation turns the heading"
    for obj in (f, ref):
        obj.set_heading(-1.0)
    out = _run(f, ref, r.gyr[800:900], r.acc[800:900])
    assert (out["cov"][:, 2] < 0.01).all(), "known again from the next set heading"


@pytest.mark.parametrize("name", list(CASES))
def test_a_reset_forgets_the_set_heading(name: str) -> None:
    r = simulate(SimConfig(duration=10.0, rate=RATE, seed=3))
    f, ref, _ = _pair(name)
    _set_after(f, ref, r.gyr[:100], r.acc[:100], 0.2)
    for obj in (f, ref):
        obj.reset()
    out = _run(f, ref, r.gyr[100:200], r.acc[100:200])
    assert (out["cov"][1:, 2] == UNKNOWN).all()


def test_nine_axis_mekf_set_heading_keeps_its_covariance() -> None:
    """With the magnetometer the heading is the filter's own: its variance is P's before and after a set
    heading, which relabels north (the reference field turns with the attitude) and leaves P as it is.
    A retune to 6 axes then keeps the heading known (the field tracked it), with P's variance."""
    r = simulate(SimConfig(duration=10.0, rate=RATE, seed=4))
    kind = FilterKind.MEKF
    s = make_settings(kind, dt=DT)
    f, ref = native.Filter(kind, s), RefFilter(kind, s)
    for obj in (f, ref):
        obj.run(r.gyr[:300], r.acc[:300], r.mag[:300], check_units=False)
    before = f.output()
    assert before["cov"][2] < UNKNOWN  # P's own (the start's fast phase: large still)
    for obj in (f, ref):
        obj.set_heading(1.0)
    after = f.output()
    assert after["cov"].tobytes() == before["cov"].tobytes(), "P unchanged"
    assert after.tobytes() == ref.output()[0].tobytes()
    _run(f, ref, r.gyr[300:600], r.acc[300:600])  # mag absent: the heading's variance grows
    six = replace(s, use_mag=False)
    for obj in (f, ref):
        obj.retune(six)
    out = _run(f, ref, r.gyr[600:700], r.acc[600:700])
    assert (out["cov"][:, 2] < UNKNOWN).all(), "9 -> 6 axes: known, the field tracked it"


def test_retune_to_six_axes_without_a_field_leaves_the_heading_unknown() -> None:
    r = simulate(SimConfig(duration=10.0, rate=RATE, seed=4))
    kind = FilterKind.MEKF
    s = make_settings(kind, dt=DT)
    f, ref = native.Filter(kind, s), RefFilter(kind, s)
    for obj in (f, ref):
        obj.run(r.gyr[:300], r.acc[:300], check_units=False)  # no mag sample: no reference field
        obj.retune(replace(s, use_mag=False))
    out = _run(f, ref, r.gyr[300:400], r.acc[300:400])
    assert (out["cov"][:, 2] == UNKNOWN).all()


@pytest.mark.parametrize("name", list(CASES))
def test_without_a_recovery_a_clip_keeps_the_heading_known(name: str) -> None:
    """recovery_time 0 (no recovery: the ekf's seed preset) has no clipping test, so a clip does not make
    the heading unknown (as in ars): documented in docs/filters.md."""
    r = simulate(SimConfig(duration=10.0, rate=RATE, seed=6))
    kind, s = _settings(name)
    s = replace(s, recovery_time=0.0)
    f, ref = native.Filter(kind, s), RefFilter(kind, s)
    _set_after(f, ref, r.gyr[:300], r.acc[:300], 0.5)
    gyr = r.gyr[300:400].copy()
    gyr[50:60, 2] = 1.5 * float(s.gyro_range)
    out = _run(f, ref, gyr, r.acc[300:400])
    assert (out["cov"][:, 2] < 0.1).all()


@pytest.mark.parametrize("name", list(CASES))
def test_mcap_orientation_covariance_takes_the_set_heading(name: str) -> None:
    """The Imu message's covariance about up: pi^2/3 before the set heading, the output's after it."""
    r = simulate(SimConfig(duration=10.0, rate=RATE, seed=5))
    kind, s = _settings(name)
    f = native.Filter(kind, s)
    before = f.run(r.gyr[:200], r.acc[:200], check_units=False)
    f.set_heading(0.3)
    after = f.run(r.gyr[200:], r.acc[200:], check_units=False)
    m0 = orientation_covariance(kind, before[1:])
    m1 = orientation_covariance(kind, after)
    # about up: the heading's variance, plus (ekf) the roll's share through the pitch (sin^2 theta)
    assert (m0[:, 8] >= float(UNKNOWN)).all() and (m0[:, 8] < float(UNKNOWN) + 0.01).all()
    assert (m1[:, 8] >= after["cov"][:, 2]).all() and (m1[:, 8] < 0.01).all()
    if kind == FilterKind.MEKF:
        assert np.array_equal(m1[:, 8], after["cov"][:, 2].astype(np.float64))
