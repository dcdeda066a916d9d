"""Which reader a path needs (attica.data.detect, load_recording) and ``attica info``'s output; the
Readers section of docs/recordings.md runs as written."""

from __future__ import annotations

import re
import shlex
import shutil
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest
from recordings_support import (
    T0_NS,
    motion,
    need_package,
    px4_topics,
    ros_samples,
    typestore,
    write_bare_mcap,
    write_ros1_bag,
    write_ros2_bag,
    write_ulog,
)
from recordings_text import write_euroc, write_phyphox_zip, write_sensor_logger

from attica.cli import main
from attica.data import Recording, detect, load_recording

from helpers import ROOT


@pytest.fixture(scope="module")
def rec() -> Recording:
    return motion()


def _bag_with_extra_topic(path: Path, rec: Recording) -> Path:
    ts = typestore()
    text = ts.types["std_msgs/msg/String"]
    samples = ros_samples(rec) + [("/status", T0_NS + i * 100_000_000, text(data="ok")) for i in range(30)]
    return write_ros2_bag(path, sorted(samples, key=lambda s: s[1]))


def test_detect_by_suffix_and_content(tmp_path: Path, rec: Recording) -> None:
    rec.save(tmp_path / "a.npz")
    rec.save(tmp_path / "a.csv")
    euroc = write_euroc(tmp_path / "MH", rec)
    phone = write_sensor_logger(tmp_path / "phone", rec)
    phy = write_phyphox_zip(tmp_path / "phy.zip", rec)
    expected = {
        tmp_path / "a.npz": "npz",
        tmp_path / "a.csv": "csv",
        euroc: "euroc",
        euroc / "mav0" / "imu0": "euroc",
        euroc / "mav0" / "imu0" / "data.csv": "euroc",
        phone: "phone",
        phy: "phyphox",
    }
    for name, fmt in (("x.bag", "rosbag"), ("x.db3", "rosbag"), ("x.mcap", "mcap"), ("x.ulg", "ulog")):
        (tmp_path / name).write_bytes(b"\x00")
        expected[tmp_path / name] = fmt
    for path, fmt in expected.items():
        assert detect(path) == fmt, path
    with pytest.raises(ValueError, match=r"unknown suffix '\.txt'"):
        (tmp_path / "notes.txt").write_text("hello")
        detect(tmp_path / "notes.txt")
    with pytest.raises(ValueError, match="one sensor of a Sensor Logger export; give its folder"):
        detect(phone / "Gyroscope.csv")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="a folder attica does not read"):
        detect(tmp_path / "empty")
    (tmp_path / "zero.ulg").write_bytes(b"")
    with pytest.raises(ValueError, match="zero.ulg: empty file"):
        load_recording(tmp_path / "zero.ulg")
    with pytest.raises(FileNotFoundError):
        detect(tmp_path / "nothing.bag")


def test_attica_formats_load_as_before(tmp_path: Path, rec: Recording) -> None:
    rec.save(tmp_path / "a.npz")
    got = load_recording(tmp_path / "a.npz")
    np.testing.assert_array_equal(got.gyr, rec.gyr)
    with pytest.raises(TypeError, match="take no options"):
        load_recording(tmp_path / "a.npz", topic="/imu")
    euroc = write_euroc(tmp_path / "MH", rec)
    with pytest.raises(TypeError, match="takes no option 'topic'"):
        load_recording(euroc, topic="/imu")


def _info(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(["info", *args])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_info_lists_topics_types_counts_rates_and_roles(
    tmp_path: Path, rec: Recording, capsys: pytest.CaptureFixture[str]
) -> None:
    need_package("rosbags")
    bag = _bag_with_extra_topic(tmp_path / "walk_bag", rec)
    code, out, _ = _info(capsys, str(bag))
    assert code == 0
    lines = out.splitlines()
    assert lines[0] == f"{bag}: ROS 2 bag (sqlite3)"
    assert lines[1] == "streams:"
    topics = {ln.split()[0]: ln for ln in lines[2:5]}
    assert re.search(r"sensor_msgs/msg/Imu\s+300\s+100 Hz\s+-> gyr, acc$", topics["/imu"])
    assert re.search(r"sensor_msgs/msg/MagneticField\s+75\s+25 Hz\s+-> mag$", topics["/mag"])
    assert re.search(r"std_msgs/msg/String\s+30\s+[\d.]+ Hz$", topics["/status"])
    assert "recording: 300 samples at 100 Hz, 2.99 s (0 lost in gaps)" in lines
    assert "sensors: gyr, acc, mag (75 samples)" in lines
    assert "ground truth: none" in lines
    assert any(ln.startswith("time: /imu: 300 samples at 100 Hz (time in ns)") for ln in lines)
    assert "warnings: none" in lines
    assert "  - time: header.stamp of each message" in lines
    code, out, _ = _info(capsys, str(bag), "--orientation", "--mag-topic", "")
    assert "ground truth: quat_true, known for 300 of 300 samples" in out and "(no magnetometer)" in out


def test_info_reports_gaps_truth_and_notes(
    tmp_path: Path, rec: Recording, capsys: pytest.CaptureFixture[str]
) -> None:
    euroc = write_euroc(tmp_path / "MH_01_easy", rec, skip=range(100, 104))
    code, out, _ = _info(capsys, str(euroc))
    assert code == 0
    assert f"{euroc}: EuRoC/ASL" in out
    assert "recording: 296 samples at 100 Hz, 2.99 s (4 lost in gaps)" in out
    assert "ground truth: quat_true, known for 246 of 296 samples" in out  # 4 rows with truth lost
    assert re.search(r"warnings:\n  - mav0/imu0/data.csv: 4 sample\(s\) lost in 1 gap\(s\)", out)
    assert "heading arbitrary" in out
    code, out, _ = _info(capsys, str(euroc), "--no-truth")
    assert "ground truth: none" in out


def test_info_ulog_lists_every_message(
    tmp_path: Path, rec: Recording, capsys: pytest.CaptureFixture[str]
) -> None:
    need_package("pyulog")
    from recordings_support import UlogTopic

    battery = UlogTopic("battery_status", [("uint64_t", "timestamp"), ("float", "voltage_v")])
    battery.rows = [(20_000_000 + i * 1_000_000, 12.3) for i in range(3)]
    path = write_ulog(tmp_path / "flight.ulg", [*px4_topics(rec), battery], dropouts=(20,))
    code, out, _ = _info(capsys, str(path), "--attitude")
    assert code == 0 and f"{path}: PX4 ULog" in out
    assert re.search(r"battery_status\s+ULog message\s+3\s+1 Hz\n", out)
    assert re.search(r"vehicle_attitude\s+ULog message\s+150\s+50 Hz\s+-> quat_true", out)
    assert "1 logger dropout(s), 20 ms" in out
    assert "PX4 software v1.14.0-test" in out


def test_info_of_attica_files_and_errors(
    tmp_path: Path, rec: Recording, capsys: pytest.CaptureFixture[str]
) -> None:
    rec.save(tmp_path / "sim.npz")
    code, out, _ = _info(capsys, str(tmp_path / "sim.npz"))
    assert code == 0 and "attica/BROAD .npz" in out and "time: none in the file, a sample every 0.01 s" in out
    code, _, err = _info(capsys, str(tmp_path / "missing.bag"))
    assert code == 2 and err.startswith("attica: error: ") and "missing.bag" in err
    code, _, err = _info(capsys, str(tmp_path / "sim.npz"), "--topic", "/imu")
    assert code == 2 and "take no options" in err
    need_package("rosbags")
    samples = ros_samples(rec) + ros_samples(rec, topics=("/imu2", "/mag2"))
    bag = write_ros2_bag(tmp_path / "two", sorted(samples, key=lambda s: s[1]))
    code, _, err = _info(capsys, str(bag))
    assert code == 2 and "2 sensor_msgs/msg/Imu topics: /imu (sensor_msgs/msg/Imu, 300 msgs)" in err
    assert "choose one with topic='<name>'" in err
    code, out, _ = _info(capsys, str(bag), "--topic", "/imu2", "--mag-topic", "/mag2")
    assert code == 0 and "-> gyr, acc" in out


def _readers_section() -> str:
    text = (ROOT / "docs" / "recordings.md").read_text()
    start = text.index("## Readers")
    nxt = re.search(r"^## ", text[start + 3 :], re.M)
    return text[start : start + 3 + nxt.start()] if nxt else text[start:]


def test_docs_readers_examples_run(
    tmp_path: Path, rec: Recording, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """docs/recordings.md, ## Readers: every Python block and command runs, in order, on its files."""
    for name in ("rosbags", "mcap", "pyulog"):
        need_package(name)
    write_ros2_bag(tmp_path / "walk_bag", ros_samples(rec, topics=("/imu/data", "/imu/mag")))
    write_ros1_bag(tmp_path / "walk.bag", ros_samples(rec, ros1=True))
    write_bare_mcap(tmp_path / "walk.mcap", ros_samples(rec))
    write_ulog(tmp_path / "flight.ulg", px4_topics(rec))
    write_euroc(tmp_path / "MH_01_easy", rec)
    write_sensor_logger(tmp_path / "sl", rec)
    shutil.make_archive(str(tmp_path / "sensorlogger"), "zip", tmp_path / "sl")
    write_phyphox_zip(tmp_path / "phyphox.zip", rec)
    section = _readers_section()
    blocks = re.findall(r"```(sh|python)\n(.*?)```", section, re.S)
    assert sum(lang == "python" for lang, _ in blocks) >= 6 and any(lang == "sh" for lang, _ in blocks)
    for fmt in (
        "### ROS bags and MCAP",
        "### PX4 ULog",
        "### EuRoC / ASL",
        "### Sensor Logger",
        "### phyphox",
    ):
        assert fmt in section
    monkeypatch.chdir(tmp_path)
    ns: dict[str, object] = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the example files have gyro rows before the first accel sample
        for lang, block in blocks:
            if lang == "python":
                exec(compile(textwrap.dedent(block), "docs/recordings.md", "exec"), ns)
                continue
            for line in block.splitlines():
                if line.strip().startswith("attica "):
                    assert main(shlex.split(line.split("  #")[0])[1:]) == 0, line
    assert "PX4 ULog" in capsys.readouterr().out
