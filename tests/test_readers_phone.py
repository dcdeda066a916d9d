"""Sensor Logger exports and Android-style folders (attica.data.phone): CSVs written from a known motion."""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
from recordings_support import G, motion
from recordings_text import android_file, gravity, write_sensor_logger

from attica.data import Recording, detect, load_recording, read_recording
from attica.data.phone import read_phone
from attica.data.timing import TimingWarning
from attica.sim.rotations import quat_rotate


@pytest.fixture(scope="module")
def rec() -> Recording:
    return motion()


def _check(got: Recording, rec: Recording) -> None:
    # the first gyro row comes before the first accel sample: dropped; then each accel is held one row
    assert got.n == rec.n - 1
    np.testing.assert_array_equal(got.gyr, rec.gyr[1:])
    np.testing.assert_allclose(got.acc, rec.acc[:-1], rtol=1e-5, atol=1e-5)
    placed = np.flatnonzero(np.isfinite(got.mag).all(axis=1))
    np.testing.assert_array_equal(placed + 1, np.arange(1, rec.n, 4))  # 1 ms after gyro row i: on row i + 1
    np.testing.assert_allclose(got.mag[placed], rec.mag[::4], rtol=1e-6)
    assert got.timing is not None and got.timing.unit == "ns" and got.rate == pytest.approx(100.0)


def test_sensor_logger_android(tmp_path: Path, rec: Recording) -> None:
    root = write_sensor_logger(tmp_path / "walk", rec)
    assert detect(root) == "phone"
    with pytest.warns(TimingWarning, match="1 gyro row.*before the first accelerometer sample"):
        got = load_recording(root)
    _check(got, rec)
    _, contents = read_phone(root)
    assert contents.format.startswith("Sensor Logger (Android")
    assert any("TotalAcceleration.csv (gravity included" in n for n in contents.notes)
    assert any("not used: GyroscopeUncalibrated.csv" in n for n in contents.notes)
    assert [(s.name, s.role) for s in contents.streams] == [
        ("Gyroscope.csv", "gyr"),
        ("TotalAcceleration.csv", "acc"),
        ("Magnetometer.csv", "mag"),
    ]


@pytest.mark.parametrize("standard", [False, True])
def test_sensor_logger_ios_sums_and_negates(tmp_path: Path, rec: Recording, standard: bool) -> None:
    root = write_sensor_logger(tmp_path / "walk", rec, platform="iOS", standard=standard)
    got, contents = read_phone(root)
    _check(got, rec)
    assert any("Accelerometer.csv + Gravity.csv" in n for n in contents.notes)
    # at rest at the start: +g along the truth's up axis, as attica wants
    up = quat_rotate(rec.quat_true[:19], got.acc[:19].astype(np.float64)).mean(axis=0)
    np.testing.assert_allclose(up, [0.0, 0.0, G], atol=0.1)


def test_sensor_logger_zip_without_metadata_is_taken_as_ios(tmp_path: Path, rec: Recording) -> None:
    write_sensor_logger(tmp_path / "walk", rec, platform="iOS", metadata=False)
    archive = Path(shutil.make_archive(str(tmp_path / "walk_export"), "zip", tmp_path, "walk"))
    assert detect(archive) == "phone"
    got, contents = read_recording(archive)
    _check(got, rec)
    assert any("taken as iOS" in n for n in contents.notes)


def test_sensor_logger_without_gravity_is_refused(tmp_path: Path, rec: Recording) -> None:
    root = write_sensor_logger(tmp_path / "walk", rec, platform="iOS")
    (root / "Gravity.csv").unlink()
    with pytest.raises(ValueError, match="Accelerometer.csv is acceleration without gravity"):
        read_phone(root)


def test_android_style_folder(tmp_path: Path, rec: Recording) -> None:
    root = tmp_path / "android"
    root.mkdir()
    boot = 5_123_456_789 + np.arange(rec.n, dtype=np.int64) * 10_000_000  # ns since boot, unit not stated
    android_file(root / "gyroscope.csv", boot, rec.gyr)
    android_file(root / "accelerometer.csv", boot - 1_000_000, rec.acc)
    android_file(root / "magnetic_field.csv", boot[::5] + 2_000_000, rec.mag[::5])
    android_file(root / "linear_acceleration.csv", boot, rec.acc * 0.0)
    android_file(root / "gravity.csv", boot, rec.acc)
    with pytest.warns(TimingWarning, match="time unit not stated, read as ns"):
        got = load_recording(root)
    assert got.n == rec.n
    np.testing.assert_array_equal(got.gyr, rec.gyr)
    np.testing.assert_array_equal(got.acc, rec.acc)  # 1 ms before each gyro sample: held on its row
    assert np.isfinite(got.mag).all(axis=1).sum() == len(range(0, rec.n, 5))
    _, contents = read_phone(root)
    assert contents.format == "Android-style CSV files"
    for name in ("timestamp_ns", "time [ns]"):
        for f in ("gyroscope", "accelerometer", "magnetic_field"):
            text = (root / f"{f}.csv").read_text().split("\n", 1)
            (root / f"{f}.csv").write_text(name + text[0][text[0].index(",") :] + "\n" + text[1])
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert load_recording(root).timing.unit_guessed is False  # type: ignore[union-attr]


def test_android_style_needs_gravity(tmp_path: Path, rec: Recording) -> None:
    root = tmp_path / "android"
    root.mkdir()
    t = np.arange(rec.n, dtype=np.int64) * 10_000_000
    android_file(root / "gyroscope.csv", t, rec.gyr, "timestamp_ns")
    android_file(root / "linear_acceleration.csv", t, rec.acc, "timestamp_ns")
    with pytest.raises(
        ValueError, match=r"need a gyroscope and an accelerometer .*not used: linear_acceleration"
    ):
        read_phone(root)
    android_file(root / "accelerometer.csv", t, rec.acc - gravity(rec), "timestamp_ns")
    with pytest.warns(TimingWarning, match="acceleration without gravity"):
        load_recording(root)
