"""The mekf's zero-rate update takes its noise from the rest itself (att_mekf.h, "Gyro bias").

At each rest the mean square of w - b (per axis, the bias before the step's update) is a running mean
from the rest's first zero-rate update until its gain is 1 / (rest_n + 1), then a low-pass of that gain,
restarted when the rest ends; the update's noise is that, at least rest_noise^2 / dt. These tests pin the
statistics against a float64 recomputation from the bias the filter held at each step, the floor, the
restart, C against the reference bit for bit (with a retune inside a rest), and what it is for: a still
gyro's bias pinned closer than with the former fixed noise (rest_noise 1e-3).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from attica import native
from attica.crosscheck import Stream, crosscheck
from attica.reference.filter import Filter as RefFilter
from attica.settings import FilterKind, Flag, make_settings

from helpers import assert_same_bits

RATE = 100.0
G = 9.80665
BIAS = np.array([0.01, -0.02, 0.005])
FIELD = np.array([0.0, 20.0, -40.0])
"""uT, sensor frame at the identity attitude (ENU: north along y, dipping down)."""


def _settings(**over: Any) -> Any:
    return make_settings(FilterKind.MEKF, dt=1.0 / RATE, **over)


def _still(seconds: float, sigma: float, seed: int, turn: float = 0.0) -> Stream:
    """A sensor at rest (or turning at ``turn`` rad/s about the vertical), gyro white noise ``sigma``
    rad/s per sample and axis on BIAS, accel and mag with small noise."""
    rng = np.random.default_rng(seed)
    n = int(seconds * RATE)
    gyr = BIAS + rng.normal(0.0, sigma, (n, 3))
    gyr[:, 2] += turn
    yaw = turn * np.arange(n) / RATE
    c, s = np.cos(yaw), np.sin(yaw)
    acc = np.array([0.0, 0.0, G]) + rng.normal(0.0, 0.01, (n, 3))
    # the earth field seen by a sensor turned by yaw about z: R(yaw)^T m
    mag = np.stack([c * FIELD[0] + s * FIELD[1], -s * FIELD[0] + c * FIELD[1], np.full(n, FIELD[2])], axis=1)
    mag = mag + rng.normal(0.0, 0.1, (n, 3))
    return Stream(gyr.astype(np.float32), acc.astype(np.float32), mag.astype(np.float32), f"still-{seed}")


def _moving(seconds: float, seed: int) -> Stream:
    """A turn at 1 rad/s about x (no rest), then back."""
    rng = np.random.default_rng(seed)
    n = int(seconds * RATE)
    w = np.where(np.arange(n) < n // 2, 1.0, -1.0)
    gyr = BIAS + np.stack([w, np.zeros(n), np.zeros(n)], axis=1) + rng.normal(0.0, 0.004, (n, 3))
    ang = np.cumsum(w) / RATE
    acc = np.stack([np.zeros(n), G * np.sin(ang), G * np.cos(ang)], axis=1)
    ca, sa = np.cos(ang), np.sin(ang)
    mag = np.stack(
        [np.full(n, FIELD[0]), ca * FIELD[1] + sa * FIELD[2], -sa * FIELD[1] + ca * FIELD[2]], axis=1
    )
    return Stream(gyr.astype(np.float32), acc.astype(np.float32), mag.astype(np.float32), f"moving-{seed}")


def _cat(*parts: Stream) -> Stream:
    return Stream(
        np.concatenate([p.gyr for p in parts]),
        np.concatenate([p.acc for p in parts]),
        np.concatenate([p.mag for p in parts if p.mag is not None]),
        "+".join(p.name for p in parts),
    )


def _st(f: native.Filter) -> Any:
    return f.state.u.mekf.st


def _step_all(f: native.Filter, s: Stream) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Step by step: the bias before each step, the flags, rest_e2 and rest_e2_n after it."""
    bias, flags, e2, n = [], [], [], []
    assert s.mag is not None
    for i in range(len(s.gyr)):
        st = _st(f)
        bias.append([st.bias.x, st.bias.y, st.bias.z])
        out = f.run(s.gyr[i : i + 1], s.acc[i : i + 1], s.mag[i : i + 1], check_units=False)
        flags.append(int(out["flags"][0]))
        st = _st(f)
        e2.append(float(st.rest_e2))
        n.append(int(st.rest_e2_n))
    return np.array(bias), np.array(flags), np.array(e2), np.array(n)


def test_the_mean_square_is_the_rests_own() -> None:
    """rest_e2 is the running mean, then low-pass, of |w - b|^2 / 3 over the zero-rate updates (float64
    recomputation from the bias held before each step), restarted by the motion between two rests."""
    s = _settings()
    rest_n = int(native.Filter(FilterKind.MEKF, s).state.u.mekf.c.rest_n)
    stream = _cat(_still(6.0, 0.004, 1), _moving(2.0, 2), _still(4.0, 0.004, 3))
    f = native.Filter(FilterKind.MEKF, s)
    bias, flags, e2, n = _step_all(f, stream)
    at_rest = (flags & Flag.AT_REST) != 0
    assert at_rest[: int(6.0 * RATE)].sum() > 4.0 * RATE, "the first rest is found"
    assert not at_rest[int(6.0 * RATE) : int(8.0 * RATE)].any(), "no rest while turning"
    assert at_rest[int(8.0 * RATE) :].sum() > 2.0 * RATE, "the second rest is found"
    mean, count, rests = 0.0, 0, 0
    for i in range(len(flags)):
        if not at_rest[i]:
            if count:
                rests += 1
            count = 0 if n[i] == 0 else count
            assert n[i] == 0 or at_rest[i - 1], "the count restarts when a rest ends"
            assert n[i] > 0 or e2[i] == 0.0, "and the mean with it"
            continue
        w = stream.gyr[i].astype(np.float64) - bias[i]
        k = 1.0 / (min(count, rest_n) + 1)
        mean = (float(w @ w) / 3.0) if count == 0 else mean + (float(w @ w) / 3.0 - mean) * k
        count = min(count + 1, rest_n)
        assert n[i] == count
        assert e2[i] == pytest.approx(mean, rel=1e-4), f"step {i}"
    assert rests >= 1 and count == rest_n
    # the statistic measures the gyro's noise: sigma^2 per axis, the bias being known by then
    assert 0.6 * 0.004**2 < e2[-1] < 1.6 * 0.004**2


def test_the_noise_is_the_larger_of_the_measured_and_the_floor() -> None:
    """A floor below every measured value changes nothing; one above the gyro's noise is the noise used,
    and holds the bias estimate back."""
    stream = _still(8.0, 0.01, 4)
    assert stream.mag is not None
    runs = {
        rn: native.Filter(FilterKind.MEKF, _settings(rest_noise=rn)).run(stream.gyr, stream.acc, stream.mag)
        for rn in (1e-6, 1e-5, 0.05)
    }
    # floors of 1e-8 and 1e-6 (rad/s)^2 per sample at 100 Hz, against sigma^2 = 1e-4: the same bits
    assert_same_bits(runs[1e-6]["q"], runs[1e-5]["q"], "floors below the measured noise")
    assert_same_bits(runs[1e-6]["gyro_bias"], runs[1e-5]["gyro_bias"], "floors below the measured noise")
    b_measured = np.abs(runs[1e-5]["gyro_bias"][-1] - BIAS).max()
    b_floor = np.abs(runs[0.05]["gyro_bias"][-1] - BIAS).max()
    assert b_measured < 0.5 * b_floor, (b_measured, b_floor)


def test_a_still_gyros_bias_is_pinned_closer_than_with_the_former_fixed_noise() -> None:
    """At a true rest the measured noise is the gyro's own: the bias (and so the attitude) is pinned
    tighter than with the fixed rest_noise 1e-3 of before, which is 3 times the gyro's noise here."""
    errs: dict[str, list[float]] = {"measured": [], "fixed 1e-3": []}
    for seed in range(5, 10):
        stream = _cat(_moving(2.0, seed), _still(20.0, 0.003, seed + 100))
        assert stream.mag is not None
        for label, over in (("measured", {}), ("fixed 1e-3", {"rest_noise": 1e-3})):
            out = native.Filter(FilterKind.MEKF, _settings(**over)).run(stream.gyr, stream.acc, stream.mag)
            tail = out["gyro_bias"][-int(10 * RATE) :] - BIAS
            errs[label].append(float(np.sqrt(np.mean(tail**2))))
    assert np.mean(errs["measured"]) < 0.7 * np.mean(errs["fixed 1e-3"]), errs


def _bit_exact(stream: Stream, s: Any) -> None:
    res = crosscheck(FilterKind.MEKF, [stream], settings=s, segment=300)
    assert res.ok, res.first_mismatch or f"{res.state_mismatches} state mismatches"


@pytest.mark.parametrize("use_mag", [True, False])
@pytest.mark.parametrize(
    "over", [{}, {"rest_noise": 0.05}, {"rest_time": 0.0}, {"rest_time": 0.01}, {"gyro_scale_sd": 0.0}]
)
def test_c_and_reference_agree(use_mag: bool, over: dict[str, Any]) -> None:
    """Rests with noise, a slow turn the detector takes for rest, motion between; floors above and below,
    rest_n 0 and 1, with and without the magnetometer and the scale estimate."""
    stream = _cat(
        _still(3.0, 0.004, 11), _still(2.0, 0.002, 12, turn=0.02), _moving(1.0, 13), _still(2.0, 0.004, 14)
    )
    _bit_exact(stream, _settings(use_mag=use_mag, **over))


@pytest.mark.parametrize(
    "over", [{"rest_time": 0.05}, {"rest_time": 2.0}, {"dt": 1.0 / 200.0}], ids=["rest-5", "rest-200", "dt"]
)
def test_a_retune_inside_a_rest_stays_bit_exact(over: dict[str, float]) -> None:
    """A retune 2 s into a rest: the same dt keeps the mean, its count limited to the new rest_n (0.05 s:
    5 samples); a new dt starts it again (per sample, the noise depends on dt); the rest goes on, C and
    reference alike. The same settings change no byte (tests/test_core.py checks every kind)."""
    stream = _still(5.0, 0.004, 21)
    assert stream.mag is not None
    s = _settings()
    half = int(2.0 * RATE)
    c = native.Filter(FilterKind.MEKF, s)
    c.run(stream.gyr[:half], stream.acc[:half], stream.mag[:half], check_units=False)
    n0, e0 = int(_st(c).rest_e2_n), float(_st(c).rest_e2)
    assert n0 > 5, "made inside a rest, the mean past the new rest_n"
    ref = RefFilter(FilterKind.MEKF, s)
    ref.load_c_states([c.state.copy()[0]])
    s2 = replace(s, **over)
    c.retune(s2)
    ref.retune(s2)
    assert ref.state_matches(0, c.state.copy()[0]), ref.state_diff(0, c.state.copy()[0])
    if "dt" in over:
        assert (_st(c).rest_e2_n, _st(c).rest_e2) == (0, 0.0), "a new dt starts the mean again"
    else:
        assert _st(c).rest_e2 == e0, "the mean is kept"
        assert _st(c).rest_e2_n == min(n0, int(c.state.u.mekf.c.rest_n))
    out = c.run(stream.gyr[half:], stream.acc[half:], stream.mag[half:], check_units=False)
    q_ref = np.array(
        [ref.step(stream.gyr[i], stream.acc[i], stream.mag[i])["q"][0] for i in range(half, len(stream.gyr))]
    )
    assert_same_bits(out["q"], q_ref, "after the retune")
    assert ref.state_matches(0, c.state.copy()[0]), ref.state_diff(0, c.state.copy()[0])


@pytest.mark.parametrize("bad", [np.nan, np.inf, 40.0])
def test_a_bad_gyro_sample_ends_the_rest_and_its_mean(bad: float) -> None:
    """A NaN, infinite or out-of-range (40 rad/s, beyond the 34.9 default range) gyro sample inside a
    rest: no rest update with it, the mean restarts (finite), and the next rest measures anew; C and
    reference bit for bit across it."""
    stream = _still(4.0, 0.004, 31)
    assert stream.mag is not None
    i = int(3.0 * RATE)
    stream.gyr[i, 1] = np.float32(bad)
    s = _settings()
    f = native.Filter(FilterKind.MEKF, s)
    f.run(stream.gyr[:i], stream.acc[:i], stream.mag[:i], check_units=False)
    assert _st(f).rest_e2_n > 0, "inside a rest"
    out = f.run(stream.gyr[i : i + 1], stream.acc[i : i + 1], stream.mag[i : i + 1], check_units=False)
    assert not out["flags"][0] & Flag.AT_REST
    assert (_st(f).rest_e2_n, _st(f).rest_e2) == (0, 0.0)
    f.run(stream.gyr[i + 1 :], stream.acc[i + 1 :], stream.mag[i + 1 :], check_units=False)
    assert 0.0 < _st(f).rest_e2 < 1e-3 and np.isfinite(_st(f).rest_e2), "the next rest measured anew"
    _bit_exact(stream, s)


def test_reset_is_a_fresh_filter() -> None:
    """att_mekf_reset clears the mean: after a run with rests the same stream gives the same bits."""
    stream = _cat(_still(3.0, 0.004, 41), _moving(1.0, 42), _still(3.0, 0.004, 43))
    assert stream.mag is not None
    f = native.Filter(FilterKind.MEKF, _settings())
    first = f.run(stream.gyr, stream.acc, stream.mag)
    assert _st(f).rest_e2_n > 0
    f.reset()
    assert (_st(f).rest_e2_n, _st(f).rest_e2) == (0, 0.0)
    again = f.run(stream.gyr, stream.acc, stream.mag)
    assert_same_bits(first["q"], again["q"], "after reset")
    assert_same_bits(first["gyro_bias"], again["gyro_bias"], "after reset")
