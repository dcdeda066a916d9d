"""Tests of the BROAD orientation error metrics (attica.metrics) with hand-computed cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from attica.metrics import Errors, error_angles, error_quat, evaluate, quat_mul, rmse_deg


def axis_angle(axis, deg: float) -> np.ndarray:
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    h = math.radians(deg) / 2
    return np.r_[math.cos(h), math.sin(h) * a]


def random_quats(n: int, seed: int = 0) -> np.ndarray:
    q = np.random.default_rng(seed).normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


@pytest.fixture
def truth() -> np.ndarray:
    return random_quats(200)


def earth_offset(q_true: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Estimate = offset (an earth-frame rotation) applied after the true orientation."""
    return quat_mul(offset, q_true)


def test_heading_offset_10deg(truth):
    est = earth_offset(truth, axis_angle([0, 0, 1], 10.0))
    err = evaluate(est, truth)
    assert err.heading == pytest.approx(10.0, abs=1e-9)
    assert err.inclination == pytest.approx(0.0, abs=1e-6)
    assert err.total == pytest.approx(10.0, abs=1e-9)
    assert err.n == 200


def test_inclination_offset_10deg(truth):
    est = earth_offset(truth, axis_angle([1, 0, 0], 10.0))
    err = evaluate(est, truth)
    assert err.heading == pytest.approx(0.0, abs=1e-6)
    assert err.inclination == pytest.approx(10.0, abs=1e-9)
    assert err.total == pytest.approx(10.0, abs=1e-9)


def test_inclination_about_any_horizontal_axis(truth):
    est = earth_offset(truth, axis_angle([1, -2, 0], 25.0))
    total, heading, incl = error_angles(est, truth)
    assert np.allclose(np.degrees(incl), 25.0) and np.allclose(np.degrees(total), 25.0)
    assert np.allclose(heading, 0.0, atol=1e-7)


def test_combined_offset_hand_computed():
    # heading 30 deg then tilt 40 deg: e = q_tilt * q_head; e_w = cos15 cos20, e_z = cos20 sin15
    e = quat_mul(axis_angle([1, 0, 0], 40.0), axis_angle([0, 0, 1], 30.0))
    total, heading, incl = error_angles(e, [1.0, 0.0, 0.0, 0.0])
    ew = math.cos(math.radians(15)) * math.cos(math.radians(20))
    assert math.degrees(total[0]) == pytest.approx(math.degrees(2 * math.acos(ew)))
    assert math.degrees(heading[0]) == pytest.approx(30.0)
    assert math.degrees(incl[0]) == pytest.approx(40.0)


def test_sensor_frame_offset_is_not_earth_frame():
    """A sensor-frame offset about z is a heading error only while the sensor z is vertical."""
    q_true = axis_angle([1, 0, 0], 90.0)  # sensor z now horizontal
    est = quat_mul(q_true, axis_angle([0, 0, 1], 10.0))  # rotate about the sensor's z
    total, heading, incl = error_angles(est, q_true)
    assert math.degrees(total[0]) == pytest.approx(10.0)
    assert math.degrees(incl[0]) == pytest.approx(10.0)
    assert heading[0] == pytest.approx(0.0, abs=1e-12)


def test_sign_ambiguity(truth):
    err = evaluate(-truth, truth)
    assert err.total == pytest.approx(0.0, abs=1e-5)
    assert err.heading == pytest.approx(0.0, abs=1e-5)
    assert err.inclination == pytest.approx(0.0, abs=1e-5)
    est = earth_offset(truth, axis_angle([0, 0, 1], 10.0))
    flipped = est * np.where(np.arange(200) % 2 == 0, 1.0, -1.0)[:, None]
    assert evaluate(flipped, truth).heading == pytest.approx(10.0)


def test_unnormalised_inputs_are_normalised(truth):
    est = earth_offset(truth, axis_angle([0, 1, 0], 10.0)) * 3.0
    assert evaluate(est, truth * 0.5).inclination == pytest.approx(10.0)


def test_mask_handling(truth):
    big = earth_offset(truth, axis_angle([0, 0, 1], 20.0))
    small = earth_offset(truth, axis_angle([0, 0, 1], 5.0))
    mask = np.arange(200) < 50
    est = np.where(mask[:, None], small, big)
    assert evaluate(est, truth, mask).heading == pytest.approx(5.0)
    assert evaluate(est, truth, ~mask).heading == pytest.approx(20.0)
    expect = math.sqrt((50 * 5.0**2 + 150 * 20.0**2) / 200)
    assert evaluate(est, truth).heading == pytest.approx(expect)
    assert evaluate(est, truth, mask).n == 50
    none = evaluate(est, truth, np.zeros(200, dtype=bool))
    assert math.isnan(none.total) and none.n == 0


def test_nan_truth_rows_ignored(truth):
    est = earth_offset(truth, axis_angle([1, 0, 0], 10.0))
    est[:20] = earth_offset(truth[:20], axis_angle([1, 0, 0], 90.0))  # large errors where truth is lost
    lost = truth.copy()
    lost[:20] = np.nan
    err = evaluate(est, lost)
    assert err.inclination == pytest.approx(10.0)
    assert err.n == 180
    total, _, _ = error_angles(est, lost)
    assert np.isnan(total[:20]).all() and np.isfinite(total[20:]).all()
    assert rmse_deg(total) == pytest.approx(10.0)


def test_nan_estimate_is_not_silently_skipped(truth):
    est = truth.copy()
    est[5] = np.nan
    assert math.isnan(evaluate(est, truth).total)
    mask = np.ones(200, dtype=bool)
    mask[5] = False
    assert evaluate(est, truth, mask).total == pytest.approx(0.0, abs=1e-5)
    est[5] = 0.0
    assert math.isnan(evaluate(est, truth).total)


def test_rmse_deg():
    a = np.radians([3.0, 4.0, np.nan, 100.0])
    assert rmse_deg(a[:2]) == pytest.approx(math.sqrt(12.5))
    assert rmse_deg(a, np.array([True, True, True, False])) == pytest.approx(math.sqrt(12.5))
    assert math.isnan(rmse_deg(np.array([])))
    with pytest.raises(ValueError):
        rmse_deg(a, np.array([1, 1, 0, 0]))
    with pytest.raises(ValueError):
        rmse_deg(a, np.array([True, False]))


def test_error_quat_is_earth_frame(truth):
    off = axis_angle([0.3, -0.2, 0.9], 33.0)
    e = error_quat(earth_offset(truth, off), truth)
    e *= np.sign(e[:, :1])
    assert np.allclose(e, off, atol=1e-12)


def test_large_and_180_deg_errors():
    total, heading, incl = error_angles(axis_angle([0, 0, 1], 180.0), [1.0, 0, 0, 0])
    assert math.degrees(total[0]) == pytest.approx(180.0)
    assert math.degrees(heading[0]) == pytest.approx(180.0)
    assert incl[0] == pytest.approx(0.0, abs=1e-7)
    total, heading, incl = error_angles(axis_angle([1, 0, 0], 180.0), [1.0, 0, 0, 0])
    assert math.degrees(incl[0]) == pytest.approx(180.0) and heading[0] == 0.0


def test_bad_shapes(truth):
    with pytest.raises(ValueError):
        evaluate(truth[:, :3], truth[:, :3])
    with pytest.raises(ValueError):
        evaluate(truth[:10], truth)
    with pytest.raises(ValueError):
        evaluate(truth, truth, np.ones(10, dtype=bool))
    with pytest.raises(ValueError):
        evaluate(truth, truth, np.ones(200))


def test_errors_dict():
    d = Errors(1.0, 2.0, 3.0, 4).as_dict()
    assert d == {"total_rmse_deg": 1.0, "heading_rmse_deg": 2.0, "inclination_rmse_deg": 3.0, "n": 4}
