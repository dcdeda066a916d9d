"""PX4 ULog (attica.data.ulog): minimal ULog files written from the format spec, read back."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from recordings_support import (
    SENSOR_COMBINED,
    T0_US,
    G,
    UlogTopic,
    motion,
    need_package,
    px4_topics,
    write_ulog,
)

from attica.data import Recording, detect, load_recording
from attica.data.frames import ned_frd_to_enu_flu
from attica.data.timing import TimingWarning
from attica.data.ulog import read_ulog
from attica.sim.rotations import quat_rotate


@pytest.fixture(autouse=True)
def _pyulog() -> None:
    need_package("pyulog")


@pytest.fixture(scope="module")
def rec() -> Recording:
    return motion()


def test_values_units_frames_and_time(tmp_path: Path, rec: Recording) -> None:
    path = write_ulog(tmp_path / "flight.ulg", px4_topics(rec))
    assert detect(path) == "ulog"
    got, contents = read_ulog(path, attitude=True)
    assert got.n == rec.n and got.rate == pytest.approx(100.0)
    assert got.timing is not None and got.timing.unit == "us" and got.lost == 0
    np.testing.assert_array_equal(got.gyr, rec.gyr)  # FRD -> FLU undoes the writer's flip exactly
    np.testing.assert_array_equal(got.acc, rec.acc)
    placed = np.flatnonzero(np.isfinite(got.mag).all(axis=1))
    np.testing.assert_array_equal(placed, np.arange(1, rec.n, 4))  # sampled 300 us after row i: on row i + 1
    np.testing.assert_allclose(
        got.mag[placed], rec.mag[::4][: placed.size], rtol=1e-6, atol=1e-4
    )  # gauss -> uT
    roles = {s.name: s.role for s in contents.streams}
    assert roles == {
        "sensor_combined": "gyr, acc",
        "vehicle_attitude": "quat_true",
        "vehicle_magnetometer": "mag",
    }
    assert any("gauss -> uT" in n for n in contents.notes)


def test_attitude_ned_frd_to_enu_flu_numerically(tmp_path: Path, rec: Recording) -> None:
    """The attitude written in PX4's convention (built with matrices) reads back as the simulation's
    sensor-to-ENU quaternion, and it rotates the converted accelerometer at rest to +g up."""
    got, _ = read_ulog(write_ulog(tmp_path / "a.ulg", px4_topics(rec)), attitude=True)
    q = got.quat_true
    assert q is not None
    on = np.arange(0, rec.n, 2)  # rows with an attitude sample at their time
    np.testing.assert_allclose(np.abs(np.sum(q[on] * rec.quat_true[on], axis=1)), 1.0, atol=1e-6)
    held = np.arange(1, rec.n, 2)
    np.testing.assert_array_equal(q[held], q[held - 1])  # held 10 ms, within 1.5 intervals
    up = quat_rotate(q[:40], got.acc[:40].astype(np.float64))
    np.testing.assert_allclose(up.mean(axis=0), [0.0, 0.0, G], atol=0.1)
    # the module's formula on a few hand-made cases: level and north: FLU x north -> ENU yaw +90 deg
    np.testing.assert_allclose(np.abs(ned_frd_to_enu_flu([1.0, 0, 0, 0])), [np.sqrt(0.5), 0, 0, np.sqrt(0.5)])
    yaw_east = [np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)]  # FRD x east in NED
    np.testing.assert_allclose(np.abs(ned_frd_to_enu_flu(yaw_east)), [1.0, 0, 0, 0], atol=1e-12)


def test_level_vehicle_at_rest_reads_plus_g(tmp_path: Path) -> None:
    rows = [
        (T0_US + i * 4000, [0.0, 0.0, 0.0], 4000, 0, [0.0, 0.0, -G], 4000, 0, 0, [0, 0]) for i in range(100)
    ]
    got, contents = read_ulog(
        write_ulog(tmp_path / "rest.ulg", [UlogTopic("sensor_combined", SENSOR_COMBINED, rows)])
    )
    np.testing.assert_allclose(got.acc, np.tile([0.0, 0.0, G], (100, 1)), rtol=1e-6)
    assert got.rate == pytest.approx(250.0) and not got.has_mag
    assert any("magnetometer: none" in n for n in contents.notes)


def test_gaps_and_dropouts_are_reported(tmp_path: Path, rec: Recording) -> None:
    path = write_ulog(tmp_path / "gap.ulg", px4_topics(rec, skip=range(100, 105)), dropouts=(50,))
    with pytest.warns(TimingWarning) as caught:
        got = load_recording(path)
    text = " ".join(str(w.message) for w in caught)
    assert "5 sample(s) lost" in text and "1 logger dropout(s), 50 ms" in text
    assert got.n == rec.n - 5 and got.lost == 5 and int(got.steps[100]) == 6


def test_sensor_mag_and_choices(tmp_path: Path, rec: Recording) -> None:
    path = write_ulog(tmp_path / "raw.ulg", px4_topics(rec, mag_name="sensor_mag"))
    got, contents = read_ulog(path)
    assert np.isfinite(got.mag).all(axis=1).sum() == len(range(0, rec.n, 4))
    np.testing.assert_allclose(np.nanmax(np.abs(got.mag)), np.abs(rec.mag[::4]).max(), rtol=1e-6)
    assert any("sensor_mag instance 0 (raw, uncalibrated" in n for n in contents.notes)
    assert not read_ulog(path, mag="none")[0].has_mag
    with pytest.raises(ValueError, match="no vehicle_magnetometer instance 0"):
        read_ulog(path, mag="vehicle_magnetometer")
    with pytest.raises(ValueError, match="mag must be one of"):
        read_ulog(path, mag="compass")


def test_bad_files(tmp_path: Path, rec: Recording) -> None:
    topics = px4_topics(rec)
    path = write_ulog(tmp_path / "nosc.ulg", topics[1:2])
    with pytest.raises(
        ValueError, match=r"nosc.ulg: no sensor_combined message \(messages: vehicle_magnetometer\)"
    ):
        read_ulog(path, everything=True)
    with pytest.raises(ValueError, match="attitude=True, but the log has no vehicle_attitude"):
        read_ulog(write_ulog(tmp_path / "noatt.ulg", topics[:2]), attitude=True)
    junk = tmp_path / "junk.ulg"
    junk.write_bytes(b"this is not a ULog file")
    with pytest.raises(ValueError, match="junk.ulg: not a readable PX4 ULog file"):
        load_recording(junk)
    cut = tmp_path / "cut.ulg"
    cut.write_bytes(b"ULog\x01\x12\x35\x01" + bytes(range(60)))
    with pytest.raises(ValueError, match="cut.ulg: "):
        load_recording(cut)
