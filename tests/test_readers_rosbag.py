"""ROS 1 and ROS 2 bags (attica.data.rosbag): files written with rosbags' writers, read back."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from recordings_support import (
    IMU,
    T0_NS,
    imu_message,
    motion,
    need_package,
    ros_samples,
    typestore,
    write_ros1_bag,
    write_ros2_bag,
)

from attica.data import Recording, load_recording, read_recording
from attica.data.rosbag import read_rosbag
from attica.data.timing import TimingWarning


@pytest.fixture(autouse=True)
def _rosbags() -> None:
    need_package("rosbags")


@pytest.fixture(scope="module")
def rec() -> Recording:
    return motion()


def _check_same(got: Recording, rec: Recording, mag_every: int = 4) -> None:
    assert got.n == rec.n
    np.testing.assert_array_equal(got.gyr, rec.gyr)
    np.testing.assert_array_equal(got.acc, rec.acc)
    placed = np.isfinite(got.mag).all(axis=1)
    assert placed.sum() == (rec.n + mag_every - 1) // mag_every
    np.testing.assert_allclose(got.mag[placed], rec.mag[::mag_every], rtol=1e-6, atol=1e-4)  # tesla and back
    np.testing.assert_allclose(got.time, np.arange(rec.n) * 0.01, atol=1e-9)
    assert got.rate == pytest.approx(100.0)
    assert got.timing is not None and got.timing.unit == "ns" and got.lost == 0


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_ros2_bag_folder_reads_back(tmp_path: Path, rec: Recording, storage: str) -> None:
    bag = write_ros2_bag(tmp_path / "walk", ros_samples(rec), storage)
    got, contents = read_rosbag(bag, orientation=True)
    _check_same(got, rec)
    assert contents.format == f"ROS 2 bag ({storage})"
    roles = {s.name: s.role for s in contents.streams}
    assert roles == {"/imu": "gyr, acc, quat_true", "/mag": "mag"}
    assert {s.name: s.kind for s in contents.streams}["/mag"] == "sensor_msgs/msg/MagneticField"
    np.testing.assert_allclose(np.abs(np.sum(got.quat_true * rec.quat_true, axis=1)), 1.0, atol=1e-12)
    assert any("header.stamp" in n for n in contents.notes)
    assert got.name == "walk"


def test_ros1_bag_and_bare_db3(tmp_path: Path, rec: Recording) -> None:
    got, contents = read_rosbag(write_ros1_bag(tmp_path / "walk.bag", ros_samples(rec, ros1=True)))
    _check_same(got, rec)
    assert contents.format == "ROS 1 bag" and got.quat_true is None  # orientation only when asked
    bag = write_ros2_bag(tmp_path / "b", ros_samples(rec))
    got, contents = read_rosbag(bag / "b.db3")
    _check_same(got, rec)
    assert contents.format == "ROS 2 bag file (sqlite3)"


def test_at_rest_reads_plus_g_up(tmp_path: Path, rec: Recording) -> None:
    """REP-103/145: FLU, specific force; attica's frame: the start at rest reads +g along the truth's up."""
    got = load_recording(write_ros2_bag(tmp_path / "b", ros_samples(rec)))
    from attica.sim.rotations import quat_rotate

    up = quat_rotate(rec.quat_true[:20], got.acc[:20].astype(np.float64))  # sensor -> ENU
    np.testing.assert_allclose(up.mean(axis=0), [0.0, 0.0, 9.80665], atol=0.1)


def test_frd_option_converts_axes_and_orientation(tmp_path: Path, rec: Recording) -> None:
    from attica.data.frames import frd_to_flu, ned_frd_to_enu_flu

    got, contents = read_rosbag(write_ros2_bag(tmp_path / "b", ros_samples(rec)), frd=True, orientation=True)
    np.testing.assert_allclose(got.gyr, frd_to_flu(rec.gyr), atol=0)
    np.testing.assert_allclose(got.acc, frd_to_flu(rec.acc), atol=0)
    np.testing.assert_allclose(got.quat_true, ned_frd_to_enu_flu(rec.quat_true), atol=1e-12)
    assert any("frd=True" in n for n in contents.notes)


def test_zero_stamps_fall_back_to_log_time(tmp_path: Path, rec: Recording) -> None:
    got, contents = read_rosbag(write_ros2_bag(tmp_path / "b", ros_samples(rec, zero_stamps=True)))
    assert any("header.stamp is 0" in n for n in contents.notes)
    assert got.n == rec.n and got.rate == pytest.approx(100.0)
    got_log, contents = read_rosbag(write_ros2_bag(tmp_path / "c", ros_samples(rec)), stamp="log")
    assert any("stamp='log'" in n for n in contents.notes) and got_log.n == rec.n


def test_gaps_and_multi_rate_mag(tmp_path: Path, rec: Recording) -> None:
    samples = ros_samples(rec, mag_every=10)
    imu_rows = [i for i, s in enumerate(samples) if s[0] == "/imu"]
    drop = set(imu_rows[50:55])  # five IMU messages lost
    bag = write_ros2_bag(tmp_path / "b", [s for i, s in enumerate(samples) if i not in drop])
    with pytest.warns(TimingWarning, match="5 sample"):
        got = load_recording(bag)
    assert got.n == rec.n - 5 and got.lost == 5
    assert int(got.steps[50]) == 6
    assert np.isfinite(got.mag).all(axis=1).sum() == 30


def test_orientation_unknown_rows_are_nan(tmp_path: Path, rec: Recording) -> None:
    got, _ = read_rosbag(write_ros2_bag(tmp_path / "b", ros_samples(rec, quat=False)), orientation=True)
    assert got.quat_true is not None and np.isnan(got.quat_true).all()


def _two_imus(rec: Recording) -> list[tuple[str, int, Any]]:
    samples = ros_samples(rec, mag_every=0)
    ts = typestore()
    extra = [
        ("/imu2", T0_NS + i * 10_000_000, imu_message(ts, T0_NS + i * 10_000_000, [0, 0, 0], [0, 0, 9.8]))
        for i in range(20)
    ]
    return samples + extra


def test_topic_choice(tmp_path: Path, rec: Recording) -> None:
    bag = write_ros2_bag(tmp_path / "b", _two_imus(rec))
    with pytest.raises(
        ValueError, match=r"2 sensor_msgs/msg/Imu topics: /imu \(.*300 msgs\), /imu2 .*topic='<name>'"
    ):
        read_rosbag(bag)
    got, contents = read_rosbag(bag, topic="/imu2")
    assert got.n == 20 and got.mag is not None and not got.has_mag
    with pytest.raises(ValueError, match="no topic '/nope'.*/imu2"):
        read_rosbag(bag, topic="/nope")
    with pytest.raises(ValueError, match="no sensor_msgs/msg/Imu topic"):
        read_rosbag(write_ros2_bag(tmp_path / "m", [s for s in ros_samples(rec) if s[0] == "/mag"]))
    got, _ = read_rosbag(write_ros2_bag(tmp_path / "c", ros_samples(rec)), mag_topic="")
    assert not got.has_mag
    with pytest.raises(ValueError, match="is sensor_msgs/msg/MagneticField, not sensor_msgs/msg/Imu"):
        read_rosbag(tmp_path / "c", topic="/mag")


def test_ned_frame_id_warns(tmp_path: Path, rec: Recording) -> None:
    ts = typestore()
    samples = [
        (
            "/imu",
            T0_NS + i * 10_000_000,
            imu_message(ts, T0_NS + i * 10_000_000, rec.gyr[i], rec.acc[i], frame="base_link_frd"),
        )
        for i in range(30)
    ]
    _, contents = read_rosbag(write_ros2_bag(tmp_path / "b", samples))
    assert any("frd=True" in w for w in contents.warnings)


def test_bad_bags_name_the_file(tmp_path: Path) -> None:
    bad = tmp_path / "junk.bag"
    bad.write_bytes(b"#ROSBAG V2.0\n" + b"\x01" * 64)
    with pytest.raises(ValueError, match="junk.bag: not a readable ROS 1 bag"):
        load_recording(bad)
    empty = tmp_path / "empty.bag"
    empty.write_bytes(b"")
    with pytest.raises(ValueError, match="empty.bag: empty file"):
        load_recording(empty)
    folder = tmp_path / "broken"
    folder.mkdir()
    (folder / "metadata.yaml").write_text("rosbag2_bagfile_information: {version: 9}\n")
    with pytest.raises(ValueError, match="broken: not a readable ROS 2 bag"):
        load_recording(folder)
    with pytest.raises(FileNotFoundError):
        load_recording(tmp_path / "missing.bag")
    with pytest.raises(ValueError, match="stamp must be"):
        read_rosbag(bad, stamp="sensor")


def test_missing_package_names_the_extra(
    tmp_path: Path, rec: Recording, monkeypatch: pytest.MonkeyPatch
) -> None:
    bag = write_ros2_bag(tmp_path / "b", ros_samples(rec))
    monkeypatch.setitem(sys.modules, "rosbags.highlevel", None)
    with pytest.raises(ImportError, match=r"pip install 'attica\[recordings\]'"):
        read_recording(bag)


def test_no_warning_for_a_clean_bag(tmp_path: Path, rec: Recording) -> None:
    bag = write_ros2_bag(tmp_path / "b", ros_samples(rec))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = load_recording(bag)
    assert got.n == rec.n
    assert IMU in {s.kind for s in read_recording(bag)[1].streams}
