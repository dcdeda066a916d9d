"""Calibration fits against the simulator's truth: magnetometer, gyro, accelerometer; coverage; refusals.

The recordings and the tolerances (measured errors are printed; run with ``-s`` to see them):

- magnetometer: :func:`attica.sim.calib_motion.mag_sweep`, 60 s at 100 Hz, full sweep (coverage about
  95 %), noise 0.3 uT, hard iron up to 25 uT, soft iron diagonal 1 +- 0.15 and coupling +- 0.08:
  ``|h - h_true| <= 0.05 uT`` and ``|S - S_true| <= 0.002`` per entry, with ``B`` = 49 uT given;
- gyro: :func:`attica.sim.calib_motion.static_poses` with 6 positions (22 s, 6 still periods of 4 s),
  noise 0.005 rad/s: ``|o - o_true| <= 5e-4 rad/s``;
- accelerometer, same recording: ``|o - o_true| <= 0.01 m/s^2``, ``|s - s_true| <= 2e-3``; with 12
  positions the misalignment too: ``|A - P_true| <= 2e-3`` per entry (``P_true`` the symmetric polar
  factor of ``M diag(s)``: gravity cannot see a rotation of the axes).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from attica.calibration import Calibration, InertialModel, MagModel, Mounting
from attica.calibration.coverage import CELLS, cell_counts, coverage
from attica.calibration.errors import CalibrationError
from attica.calibration.inertial import fit_accel, fit_gyro
from attica.calibration.magfit import MIN_COVERAGE, fit_mag
from attica.calibration.rest import RestPeriods, find_rest
from attica.sim import SimConfig, simulate
from attica.sim.calib_motion import mag_sweep, static_poses
from attica.sim.errors import ErrorSizes, apply_errors, draw_errors

SWEEP = SimConfig(duration=60.0, rate=100.0, seed=2)
STATIC = SimConfig(rate=100.0, seed=4)


def _polar(a: np.ndarray) -> np.ndarray:
    """The symmetric positive factor P of A = U P."""
    ev, vec = np.linalg.eigh(a.T @ a)
    return (vec * np.sqrt(ev)) @ vec.T


def _inertial_matrix(m: InertialModel) -> np.ndarray:
    return np.array(m.misalignment) * np.array(m.sensitivity)


# --- simulator errors -------------------------------------------------------------------------------


def test_errors_are_seeded_and_undone_by_their_truth() -> None:
    truth = draw_errors(7, ErrorSizes(mounting=True))
    assert truth == draw_errors(7, ErrorSizes(mounting=True))
    assert truth != draw_errors(8, ErrorSizes(mounting=True))
    assert not truth.mounting.identity
    rec = simulate(SimConfig(duration=5.0, seed=1))
    raw = apply_errors(rec, truth)
    r = truth.mounting.matrix()
    for got, want, tol in (
        (truth.gyro.apply(raw.gyr) @ r.T, rec.gyr, 1e-5),
        (truth.accel.apply(raw.acc) @ r.T, rec.acc, 1e-4),
        (truth.mag.apply(raw.mag) @ r.T, rec.mag, 1e-3),
    ):
        err = float(np.max(np.abs(got - want)))
        assert err < tol, err
    assert float(np.max(np.abs(raw.mag - rec.mag))) > 5.0  # the distortion is there


def test_drawn_soft_iron_is_symmetric_positive_definite() -> None:
    for seed in range(20):
        s = np.array(draw_errors(seed).mag.soft_iron)
        assert np.array_equal(s, s.T)
        assert np.linalg.eigvalsh(s)[0] > 0.5


# --- coverage ----------------------------------------------------------------------------------------


def test_coverage_cells_have_equal_area() -> None:
    rng = np.random.default_rng(0)
    d = rng.normal(size=(400_000, 3))
    counts = cell_counts(d)
    rel = counts / counts.mean()
    print(f"cell area relative to the mean: {rel.min():.3f} .. {rel.max():.3f}")
    assert 0.9 < rel.min() and rel.max() < 1.1
    assert coverage(d) == 1.0


def test_coverage_of_a_circle_and_a_hemisphere() -> None:
    a = np.linspace(0, 2 * np.pi, 5000)
    circle = np.stack([np.cos(a), np.sin(a), 0.1 * np.ones_like(a)], axis=1)
    hemi = np.random.default_rng(1).normal(size=(50_000, 3))
    hemi[:, 2] = np.abs(hemi[:, 2])
    c, h = coverage(circle), coverage(hemi)
    print(f"coverage: circle {c:.2f}, hemisphere {h:.2f} ({CELLS} cells)")
    assert 0.1 <= c <= 0.25
    assert 0.55 <= h <= 0.65  # the cells along its edge count
    assert coverage(np.zeros((10, 3))) == 0.0  # zero rows are left out


# --- magnetometer ------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_mag_fit_recovers_the_truth(seed: int) -> None:
    truth = draw_errors(seed)
    rec = mag_sweep(dataclasses.replace(SWEEP, seed=seed + 10), truth)
    f = fit_mag(rec.mag, field_strength=49.0)
    dh = float(np.max(np.abs(np.array(f.model.hard_iron) - truth.mag.hard_iron)))
    ds = float(np.max(np.abs(np.array(f.model.soft_iron) - np.array(truth.mag.soft_iron))))
    print(
        f"seed {seed}: 60 s sweep, coverage {f.coverage:.0%}: |dh| {dh:.4f} uT, |dS| {ds:.5f}; "
        f"residual {f.before_rms:.2f} -> {f.after_rms:.3f} uT"
    )
    assert f.coverage > 0.9
    assert dh <= 0.05 and ds <= 0.002
    assert f.after_rms < 0.4 < 3.0 < f.before_rms  # noise 0.3 uT left
    assert f.inliers == f.samples


def test_mag_fit_without_field_has_unit_determinant() -> None:
    truth = draw_errors(1)
    f = fit_mag(mag_sweep(SWEEP, truth).mag)
    assert abs(np.linalg.det(np.array(f.model.soft_iron)) - 1.0) < 1e-5
    # the shape is the true one up to scale
    s_true = np.array(truth.mag.soft_iron)
    assert np.allclose(np.array(f.model.soft_iron) * 49.0 / f.field, s_true, atol=0.002)


def test_mag_fit_refuses_low_coverage() -> None:
    truth = draw_errors(1)
    measured = []
    for extent in (1.0, 0.6, 0.4, 0.3, 0.2, 0.0):
        rec = mag_sweep(SWEEP, truth, extent=extent)
        try:
            f = fit_mag(rec.mag, 49.0, min_coverage=0.0)
        except CalibrationError as exc:
            assert "do not determine an ellipsoid" in str(exc) and "figure eight" in str(exc)
            measured.append(f"extent {extent}: refused (no ellipsoid)")
            continue
        dh = float(np.max(np.abs(np.array(f.model.hard_iron) - truth.mag.hard_iron)))
        measured.append(f"extent {extent}: coverage {f.coverage:.0%} |dh| {dh:.3f} uT")
        if f.coverage < MIN_COVERAGE:
            with pytest.raises(CalibrationError, match=r"covers \d+% of the sphere, .* needs 50%"):
                fit_mag(rec.mag, 49.0)
        else:
            assert dh < 0.5  # what the default threshold promises
    print("; ".join(measured))
    assert any("refused" in m for m in measured)
    with pytest.raises(CalibrationError, match="needs at least"):
        fit_mag(np.full((1000, 3), np.nan))


def test_mag_fit_is_robust_to_outliers() -> None:
    truth = draw_errors(2)
    rec = mag_sweep(SWEEP, truth)
    mag = rec.mag.astype(np.float64)
    rng = np.random.default_rng(5)
    bad = rng.choice(len(mag), size=len(mag) // 20, replace=False)  # 5 %: spikes and a magnet
    mag[bad[: len(bad) // 2]] += rng.normal(scale=60.0, size=(len(bad) // 2, 3))
    mag[bad[len(bad) // 2 :]] *= 1.5
    mag[:50] = np.nan  # missing samples are skipped
    f = fit_mag(mag, 49.0)
    dh = float(np.max(np.abs(np.array(f.model.hard_iron) - truth.mag.hard_iron)))
    ds = float(np.max(np.abs(np.array(f.model.soft_iron) - np.array(truth.mag.soft_iron))))
    rejected = f.samples - f.inliers
    print(f"5 % outliers: |dh| {dh:.4f} uT, |dS| {ds:.5f}, {rejected} rejected of {len(bad)} injected")
    assert dh <= 0.1 and ds <= 0.004
    assert rejected >= 0.8 * len(bad)
    assert not f.inlier_mask[:50].any()


# --- gyro and accelerometer ------------------------------------------------------------------------


def test_rest_detection_matches_the_still_periods() -> None:
    rec = static_poses(STATIC, draw_errors(3), poses=6)
    rest = find_rest(rec.gyr, rec.acc, rec.rate)
    assert len(rest.segments) == 6
    assert rec.movement is not None and not (rest.mask(rec.n) & rec.movement).any()
    assert rest.seconds > 6 * 3.0  # 4 s still each, half a window lost at each end
    sweep = mag_sweep(SWEEP)
    assert find_rest(sweep.gyr, sweep.acc, sweep.rate).segments == ()


def test_gyro_offset() -> None:
    truth = draw_errors(3)
    rec = static_poses(STATIC, truth, poses=6)
    base = InertialModel(sensitivity=(1.01, 1.0, 0.99))
    f = fit_gyro(rec.gyr, rec.acc, rec.rate, base=base)
    err = float(np.max(np.abs(np.array(f.model.offset) - truth.gyro.offset)))
    print(f"gyro offset from {f.rest.seconds:.1f} s still: |do| {err:.2e} rad/s")
    assert err <= 5e-4
    assert f.model.sensitivity == base.sensitivity  # kept
    assert f.after_rms < f.before_rms
    with pytest.raises(CalibrationError, match=r"0.0 s of the recording is still"):
        sweep = mag_sweep(SWEEP)
        fit_gyro(sweep.gyr, sweep.acc, sweep.rate)


def test_accel_six_positions() -> None:
    truth = draw_errors(3)
    rec = static_poses(STATIC, truth, poses=6)
    f = fit_accel(rec.acc, rec.gyr, rec.rate)
    p = _polar(_inertial_matrix(truth.accel))
    do = float(np.max(np.abs(np.array(f.model.offset) - truth.accel.offset)))
    ds = float(np.max(np.abs(np.array(f.model.sensitivity) - np.diag(p))))
    print(f"accel, 6 positions: |do| {do:.4f} m/s^2, |ds| {ds:.5f}, condition {f.condition:.2f}")
    assert not f.misalignment and f.distinct == 6
    assert do <= 0.01 and ds <= 2e-3
    assert f.after_rms < 0.01 < 0.1 < f.before_rms


def test_accel_misalignment_from_twelve_positions() -> None:
    truth = draw_errors(3)
    rec = static_poses(STATIC, truth, poses=12)
    f = fit_accel(rec.acc, rec.gyr, rec.rate)
    p = _polar(_inertial_matrix(truth.accel))
    da = float(np.max(np.abs(_inertial_matrix(f.model) - p)))
    do = float(np.max(np.abs(np.array(f.model.offset) - truth.accel.offset)))
    print(f"accel, 12 positions: |dA| {da:.5f}, |do| {do:.4f} m/s^2, condition {f.condition:.2f}")
    assert f.misalignment and f.distinct == 12
    assert da <= 2e-3 and do <= 0.01
    off = fit_accel(rec.acc, rec.gyr, rec.rate, misalignment="off")
    assert not off.misalignment and off.model.misalignment == ((1, 0, 0), (0, 1, 0), (0, 0, 1))


def test_accel_refusals() -> None:
    truth = draw_errors(3)
    rec = static_poses(STATIC, truth, poses=5)
    with pytest.raises(CalibrationError, match="5 distinct still position.*needs 6"):
        fit_accel(rec.acc, rec.gyr, rec.rate)
    six = static_poses(STATIC, truth, poses=6)
    with pytest.raises(CalibrationError, match="misalignment needs at least 9"):
        fit_accel(six.acc, six.gyr, six.rate, misalignment="on")
    # nine positions all on the upper side of the sphere: the z offset and scale are not separable
    many = static_poses(STATIC, truth, poses=30)
    rest = find_rest(many.gyr, many.acc, many.rate)
    up = [(a, b) for a, b in rest.segments if many.acc[a:b, 2].mean() > 4.0]
    assert len(up) >= 6
    cap = RestPeriods(tuple(up), rest.gyro_threshold, rest.accel_threshold, rest.rate)
    with pytest.raises(CalibrationError, match="do not determine the accelerometer model"):
        fit_accel(many.acc, many.gyr, many.rate, rest=cap)


# --- the calibration file ------------------------------------------------------------------------------


def test_fitted_calibration_round_trips(tmp_path: object) -> None:
    from pathlib import Path

    truth = draw_errors(4, ErrorSizes(mounting=True))
    mag = fit_mag(mag_sweep(SWEEP, truth).mag, 49.0)
    cal = dataclasses.replace(truth, mag=mag.model, fit={"mag": mag.record()})
    path = Path(str(tmp_path)) / "cal.json"
    cal.save(path)
    back = Calibration.load(path)
    assert back == cal
    assert back.fit["mag"]["coverage"] == pytest.approx(mag.coverage)
    for a, b in ((back.mag.soft_iron, cal.mag.soft_iron), (back.gyro.offset, cal.gyro.offset)):
        assert np.array_equal(np.float32(a), np.float32(b))  # the same float32 bits
    assert back.mounting == cal.mounting and isinstance(back.mounting, Mounting)
    path.write_text(path.read_text().replace('"hard_iron"', '"hard_irn"'))
    with pytest.raises(ValueError, match="unknown field"):
        Calibration.load(path)
    assert MagModel().identity
