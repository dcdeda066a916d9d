"""Tests of the IMU simulator (attica.sim): determinism, conventions, sensor models, ground truth."""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
import pytest

from attica.data import load_recording
from attica.sim import (
    SimConfig,
    mag_field_earth,
    quat_exp,
    quat_rotate,
    quat_rotate_inv,
    sim_to_npz,
    simulate,
    simulate_with_truth,
)

G = 9.80665


# Independent helpers (written out here so that a convention error in attica.sim cannot cancel out).
def rotmat(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of unit quaternions w,x,y,z: v_earth = R @ v_sensor."""
    w, x, y, z = (q[..., i] for i in range(4))
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ]
    )


def to_sensor(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """R^T v per row."""
    return np.einsum("nji,nj->ni", rotmat(q), v)


def quat_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation angle between unit quaternions (rad), q and -q equal."""
    d = np.clip(np.abs(np.sum(a * b, axis=-1)), 0.0, 1.0)
    return 2.0 * np.arccos(d)


@pytest.fixture(scope="module")
def default_run():
    return simulate_with_truth(SimConfig())


def test_determinism():
    cfg = SimConfig(duration=20.0, taps=3, mag_disturbances=((5.0, 8.0, (10.0, 0.0, 0.0)),))
    a, b = simulate(cfg), simulate(dataclasses.replace(cfg))
    for name in ("gyr", "acc", "mag", "quat_true", "movement"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    c = simulate(dataclasses.replace(cfg, seed=1))
    for name in ("gyr", "acc", "mag", "quat_true"):
        assert not np.allclose(getattr(a, name), getattr(c, name)), name


def test_shapes_dtypes(default_run):
    rec, truth = default_run
    n = round(60.0 * 285.714)
    assert rec.n == len(rec) == n
    assert rec.rate == 285.714
    for name in ("gyr", "acc", "mag"):
        arr = getattr(rec, name)
        assert arr.shape == (n, 3) and arr.dtype == np.float32, name
        assert np.all(np.isfinite(arr)), name
    assert rec.quat_true is not None and rec.quat_true.shape == (n, 4) and rec.quat_true.dtype == np.float64
    assert np.allclose(np.linalg.norm(rec.quat_true, axis=1), 1.0, atol=1e-12)
    assert rec.movement is not None and rec.movement.shape == (n,) and rec.movement.dtype == np.bool_
    for name in ("gyr", "gyr_bias", "acc_lin", "mag_earth"):
        arr = getattr(truth, name)
        assert arr.shape == (n, 3) and arr.dtype == np.float64, name
    assert rec.t[-1] == pytest.approx((n - 1) / 285.714)


def test_identity_at_rest_sign_conventions():
    """Identity attitude, still: acc ~ (0, 0, +g), mag ~ (0, B cos dip, -B sin dip), quat stays identity."""
    cfg = SimConfig(initial_attitude=(1.0, 0.0, 0.0, 0.0), duration=20.0, rest_start=5.0)
    rec, truth = simulate_with_truth(cfg)
    rest = rec.t < 4.9
    assert not rec.movement[rest].any()
    assert np.array_equal(truth.gyr[rest], np.zeros_like(truth.gyr[rest]))
    assert np.abs(rec.quat_true[rest] - [1.0, 0.0, 0.0, 0.0]).max() < 1e-15
    m = int(rest.sum())
    tol_acc = 5 * cfg.accel_noise / math.sqrt(m)
    assert np.allclose(rec.acc[rest].mean(axis=0), [0.0, 0.0, G], atol=tol_acc)
    expect_mag = [0.0, 49.0 * math.cos(1.1), -49.0 * math.sin(1.1)]
    assert expect_mag[1] > 0 > expect_mag[2]
    assert np.allclose(rec.mag[rest].mean(axis=0), expect_mag, atol=5 * cfg.mag_noise / math.sqrt(m))
    # at rest the gyro reads only bias + noise
    assert np.allclose(rec.gyr[rest].mean(axis=0), truth.gyr_bias[rest].mean(axis=0), atol=1e-3)


def test_random_attitude_at_rest_accel_is_rotated_gravity(default_run):
    rec, truth = default_run
    assert abs(rec.quat_true[0, 0]) < 0.999  # not identity: the check below is meaningful
    for still in (~rec.movement[: rec.n // 2], ~rec.movement):  # start rest, then every still sample
        idx = np.flatnonzero(still)
        expect = to_sensor(rec.quat_true[idx], np.tile([0.0, 0.0, G], (idx.size, 1)))
        resid = rec.acc[idx] - expect
        assert np.abs(resid.mean(axis=0)).max() < 5 * 0.05 / math.sqrt(idx.size)
        assert resid.std() == pytest.approx(0.05, rel=0.05)
        norm = np.linalg.norm(rec.acc[idx], axis=1)
        assert norm.mean() == pytest.approx(G, abs=0.01)
    # same for the magnetometer: R^T m_earth
    idx = np.flatnonzero(~rec.movement)
    m_earth = np.tile(mag_field_earth(SimConfig()), (idx.size, 1))
    resid = rec.mag[idx] - to_sensor(rec.quat_true[idx], m_earth)
    assert np.abs(resid.mean(axis=0)).max() < 5 * 0.3 / math.sqrt(idx.size)


def test_accel_during_motion_includes_linear_acceleration(default_run):
    rec, truth = default_run
    expect = to_sensor(rec.quat_true, truth.acc_lin + [0.0, 0.0, G])
    resid = rec.acc - expect
    assert resid.std() == pytest.approx(0.05, rel=0.05)
    assert np.abs(resid).max() < 8 * 0.05
    moving = rec.movement
    assert np.sqrt(np.mean(truth.acc_lin[moving] ** 2)) > 0.2  # translation is really there


def test_gyro_integration_recovers_truth(default_run):
    """Integrating the noise-free rate with q <- q * exp(w dt / 2) (own code) tracks quat_true."""
    rec, truth = default_run
    w = truth.gyr
    dt = rec.dt
    q = rec.quat_true[0].copy()
    err = 0.0
    for k in range(1, rec.n):
        wm = 0.5 * (w[k - 1] + w[k]) * dt
        angle = np.linalg.norm(wm)
        inc = (
            np.array([1.0, 0.0, 0.0, 0.0])
            if angle == 0
            else np.r_[np.cos(angle / 2), np.sin(angle / 2) * wm / angle]
        )
        q = qmul(q, inc)
        if k % 100 == 0:
            err = max(err, float(quat_angle(q / np.linalg.norm(q), rec.quat_true[k])))
    assert math.degrees(err) < 0.05
    # the motion is substantial: the attitude changes a lot, so the check above is not trivial
    assert math.degrees(quat_angle(rec.quat_true[0], rec.quat_true).max()) > 90


def test_left_multiplication_would_not_match(default_run):
    """The body-rate convention matters: the earth-frame (left) product drifts far from the truth."""
    rec, truth = default_run
    w, dt = truth.gyr, rec.dt
    q = rec.quat_true[0].copy()
    for k in range(1, rec.n // 3):
        q = qmul(quat_exp(0.5 * (w[k - 1] + w[k]) * dt), q)
    assert math.degrees(float(quat_angle(q / np.linalg.norm(q), rec.quat_true[rec.n // 3 - 1]))) > 5


def test_integrator_converges():
    cfg = SimConfig(duration=15.0, rate=100.0, rotation_rms=2.0, rotation_bandwidth=2.0)
    fine = simulate(dataclasses.replace(cfg, substeps=64)).quat_true
    coarse = simulate(dataclasses.replace(cfg, substeps=1)).quat_true
    auto = simulate(cfg).quat_true
    assert quat_angle(fine, coarse).max() < 1e-5
    assert quat_angle(fine, auto).max() < 1e-7


def test_gyro_bias_present_and_drifting():
    cfg = SimConfig(duration=120.0, gyro_bias=0.02, gyro_bias_drift=0.002)
    rec, truth = simulate_with_truth(cfg)
    bias = truth.gyr_bias
    assert np.all(np.abs(bias[0]) <= 0.02)
    assert np.abs(bias[0]).max() > 1e-3
    steps = np.diff(bias, axis=0)
    assert steps.std() == pytest.approx(0.002 * math.sqrt(rec.dt), rel=0.05)
    assert np.abs(bias[-1] - bias[0]).max() > 0.002  # it moved (about 0.02 expected per axis)
    noise = rec.gyr.astype(np.float64) - truth.gyr - bias
    assert noise.std() == pytest.approx(0.005, rel=0.05)
    assert np.abs(noise.mean(axis=0)).max() < 5 * 0.005 / math.sqrt(rec.n)
    no_drift = simulate_with_truth(dataclasses.replace(cfg, gyro_bias_drift=0.0))[1].gyr_bias
    assert np.array_equal(no_drift, np.broadcast_to(no_drift[0], no_drift.shape))


def test_taps_visible_as_spikes():
    cfg = SimConfig(duration=30.0, taps=4)
    with_taps, truth = simulate_with_truth(cfg)
    without = simulate(dataclasses.replace(cfg, taps=0))
    assert truth.tap_times.shape == (4,)
    # independent random streams: only the accelerometer changes, and only at the taps
    assert np.array_equal(with_taps.gyr, without.gyr)
    assert np.array_equal(with_taps.quat_true, without.quat_true)
    diff = np.linalg.norm(with_taps.acc.astype(np.float64) - without.acc, axis=1)
    spikes = diff > 1e-3
    assert spikes.sum() <= 4 * math.ceil(0.01 * cfg.rate + 1)
    for t0 in truth.tap_times:
        near = np.abs(with_taps.t - (t0 + 0.005)) <= 0.006
        assert diff[near].max() > 0.5 * cfg.tap_amplitude
        assert with_taps.movement[near].all()
    in_tap = np.zeros(with_taps.n, dtype=bool)
    for t0 in truth.tap_times:
        in_tap |= (with_taps.t >= t0) & (with_taps.t < t0 + cfg.tap_duration)
    assert np.array_equal(spikes, in_tap)
    assert np.all(np.isclose(np.linalg.norm(truth.tap_dirs, axis=1), 1.0))


def test_mag_dip_in_earth_frame(default_run):
    rec, truth = default_run
    m = mag_field_earth(SimConfig())
    assert m[0] == 0.0
    assert math.atan2(-m[2], m[1]) == pytest.approx(1.1)
    assert np.linalg.norm(m) == pytest.approx(49.0)
    # recover the earth-frame field from the sensor data with the truth (own rotation code)
    earth = np.einsum("nij,nj->ni", rotmat(rec.quat_true), rec.mag.astype(np.float64))
    mean = earth.mean(axis=0)
    assert math.atan2(-mean[2], math.hypot(mean[0], mean[1])) == pytest.approx(1.1, abs=2e-3)
    assert abs(mean[0]) < 0.05 and mean[1] > 0
    # at rest, the angle between measured gravity (up) and the field is 90 deg + dip in any attitude
    first_move = np.flatnonzero(rec.movement)[0]
    up = rec.acc[:first_move].mean(axis=0)
    mag = rec.mag[:first_move].mean(axis=0)
    ang = math.acos(float(np.dot(up, mag) / np.linalg.norm(up) / np.linalg.norm(mag)))
    assert ang == pytest.approx(math.pi / 2 + 1.1, abs=5e-3)


def test_mag_disturbance_window():
    dist = (10.0, 14.0, (0.0, 0.0, 30.0))
    cfg = SimConfig(duration=25.0, mag_disturbances=(dist,))
    rec, truth = simulate_with_truth(cfg)
    clean = simulate(dataclasses.replace(cfg, mag_disturbances=()))
    assert np.array_equal(rec.acc, clean.acc) and np.array_equal(rec.gyr, clean.gyr)
    diff_earth = np.einsum("nij,nj->ni", rotmat(rec.quat_true), rec.mag.astype(np.float64) - clean.mag)
    inside = (rec.t >= 10.0) & (rec.t < 14.0)
    assert np.allclose(diff_earth[inside], [0.0, 0.0, 30.0], atol=1e-4)
    assert np.abs(diff_earth[~inside]).max() < 1e-4
    assert np.allclose(truth.mag_earth[inside] - mag_field_earth(cfg), [0.0, 0.0, 30.0])
    assert "magnet" in rec.groups


def test_movement_mask_and_still_periods():
    cfg = SimConfig(duration=40.0, rest_start=3.0, rest_end=2.0, rest_breaks=2)
    rec, truth = simulate_with_truth(cfg)
    mov = rec.movement
    assert not mov[rec.t < 3.0].any()
    assert not mov[rec.t > 38.0].any()
    assert not mov[0] and not mov[-1]
    # two breaks of ~2 s inside the motion, i.e. three motion segments
    edges = np.flatnonzero(np.diff(mov.astype(np.int8)))
    assert edges.size == 6
    pauses = (edges[2::2] - edges[1:-1:2]) / cfg.rate
    assert np.allclose(pauses, 2.0, atol=2.0 / cfg.rate)
    # still means exactly still in the truth
    assert np.all(truth.gyr[~mov] == 0.0) and np.all(truth.acc_lin[~mov] == 0.0)
    # and the envelope ramps in smoothly: no jumps in the rate
    assert np.abs(np.diff(truth.gyr, axis=0)).max() < 20.0 * rec.dt
    # moving means moving, RMS close to the configured value
    assert np.sqrt(np.mean(truth.gyr[mov] ** 2)) == pytest.approx(0.8, rel=0.35)
    no_breaks = simulate(dataclasses.replace(cfg, rest_breaks=0))
    assert np.flatnonzero(np.diff(no_breaks.movement.astype(np.int8))).size == 2


def test_linear_velocity_stays_bounded():
    rec, truth = simulate_with_truth(SimConfig(duration=120.0, translation_rms=1.0))
    vel = np.cumsum(truth.acc_lin, axis=0) * rec.dt
    assert np.abs(vel).max() < 2.0
    assert np.abs(vel[-1]).max() < 0.05  # back to rest at the end


def test_quat_helpers():
    q = quat_exp([0.0, 0.0, math.pi / 2])  # +90 deg about up
    assert np.allclose(q, [math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)])
    # sensor x (east at identity) turns to north; counter-clockwise seen from above
    assert np.allclose(quat_rotate(q, [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0])
    assert np.allclose(quat_rotate_inv(q, [0.0, 1.0, 0.0]), [1.0, 0.0, 0.0])
    assert np.allclose(quat_exp(np.zeros(3)), [1.0, 0.0, 0.0, 0.0])
    rng = np.random.default_rng(3)
    qs = rng.normal(size=(50, 4))
    qs /= np.linalg.norm(qs, axis=1, keepdims=True)
    v = rng.normal(size=(50, 3))
    assert np.allclose(quat_rotate(qs, v), np.einsum("nij,nj->ni", rotmat(qs), v))


def test_initial_attitude_is_normalised_and_kept():
    rec = simulate(SimConfig(duration=5.0, initial_attitude=(0.0, 0.0, 0.0, 2.0)))
    assert np.allclose(rec.quat_true[0], [0.0, 0.0, 0.0, 1.0])
    # upside-down about z only: still reads +g on z
    assert rec.acc[:100].mean(axis=0) == pytest.approx([0.0, 0.0, G], abs=0.05)
    assert rec.mag[:100, 1].mean() < 0  # north is behind the sensor's y axis


@pytest.mark.parametrize(
    "change",
    [
        {"rate": 0.0},
        {"duration": -1.0},
        {"rate": float("nan")},
        {"gyro_noise": -0.1},
        {"rest_breaks": 40},
        {"initial_attitude": (0.0, 0.0, 0.0, 0.0)},
        {"components": 0},
    ],
)
def test_invalid_config(change):
    with pytest.raises(ValueError):
        simulate(dataclasses.replace(SimConfig(), **change))


def test_no_motion_and_short_recordings():
    rec = simulate(SimConfig(duration=4.0, rest_start=3.0, rest_end=2.0))
    assert not rec.movement.any()
    assert np.allclose(rec.quat_true, rec.quat_true[0], atol=1e-15)
    one = simulate(SimConfig(duration=1.0 / 285.714))
    assert one.n == 1 and one.quat_true.shape == (1, 4)


def test_save_round_trip(tmp_path, default_run):
    rec, _ = default_run
    path = tmp_path / "sim.npz"
    sim_to_npz(rec, path)
    back = load_recording(path)
    for name in ("gyr", "acc", "mag", "quat_true", "movement"):
        assert np.array_equal(getattr(back, name), getattr(rec, name)), name
    assert back.rate == rec.rate and back.name == rec.name and back.groups == rec.groups


def test_speed():
    simulate(SimConfig(duration=1.0))  # warm up
    t0 = time.perf_counter()
    simulate(SimConfig(duration=60.0, rate=1000.0))
    assert time.perf_counter() - t0 < 3.0
