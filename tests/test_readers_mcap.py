"""Bare MCAP files (attica.data.mcapfile): written with the mcap package and by attica's own writer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from recordings_support import motion, need_package, ros_samples, write_bare_mcap

from attica.data import Recording, detect, load_recording, read_recording
from attica.data.mcapfile import read_mcap


@pytest.fixture(autouse=True)
def _packages() -> None:
    need_package("mcap")
    need_package("rosbags")


@pytest.fixture(scope="module")
def rec() -> Recording:
    return motion()


def test_bare_mcap_skips_json_and_protobuf_channels(tmp_path: Path, rec: Recording) -> None:
    path = write_bare_mcap(tmp_path / "walk.mcap", ros_samples(rec))
    assert detect(path) == "mcap"
    got, contents = read_mcap(path, orientation=True)
    assert got.n == rec.n
    np.testing.assert_array_equal(got.gyr, rec.gyr)
    np.testing.assert_array_equal(got.acc, rec.acc)
    placed = np.isfinite(got.mag).all(axis=1)
    np.testing.assert_allclose(got.mag[placed], rec.mag[::4], rtol=1e-6, atol=1e-4)
    np.testing.assert_allclose(np.abs(np.sum(got.quat_true * rec.quat_true, axis=1)), 1.0, atol=1e-12)
    kinds = {s.name: s.kind for s in contents.streams}
    assert kinds["/tf_json"].startswith("foxglove.FrameTransform (json") and "skipped" in kinds["/tf_json"]
    assert "protobuf" in kinds["/imu_pb"] and "skipped" in kinds["/imu_pb"]
    assert {s.name: s.role for s in contents.streams}["/imu"] == "gyr, acc, quat_true"
    assert any("profile ''" in n for n in contents.notes)


def test_unfinished_mcap_reads_what_is_there(tmp_path: Path, rec: Recording) -> None:
    path = write_bare_mcap(tmp_path / "cut.mcap", ros_samples(rec), finish=False)
    got, contents = read_mcap(path)
    assert got.n == rec.n
    assert any("no summary" in n for n in contents.notes)


def test_attica_run_output_reads_back(tmp_path: Path, rec: Recording) -> None:
    """The file `attica run -o out.mcap` writes (attica.data.export.write_mcap) is a recording again."""
    import attica
    from attica.data.export import write_mcap
    from attica.outputs import MAG_OFFSET_DTYPE

    mo = np.zeros(rec.n, MAG_OFFSET_DTYPE)  # the hard-iron estimate: a second MagneticField topic
    out = attica.Filter("mars", rec.dt, hard_iron_tau=60.0).run(rec.gyr, rec.acc, rec.mag, mag_offset=mo)
    path = tmp_path / "out.mcap"
    write_mcap(path, out, rec, "mars", mag_offset=mo)
    got, contents = read_recording(path, orientation=True)
    np.testing.assert_array_equal(got.gyr, rec.gyr)
    np.testing.assert_array_equal(got.acc, rec.acc)
    np.testing.assert_allclose(got.mag, rec.mag, rtol=1e-6)
    q = np.asarray(out["q"], np.float64)
    np.testing.assert_allclose(np.abs(np.sum(got.quat_true * q, axis=1)), 1.0, atol=1e-6)
    np.testing.assert_allclose(got.t, rec.t, atol=1e-9)
    assert {s.name: s.role for s in contents.streams} == {
        "/attica/imu": "gyr, acc, quat_true",
        "/attica/mag": "mag",
        "/attica/mag_offset": "",
        "/attica/flags": "",
        "/tf": "",
    }
    assert load_recording(path).quat_true is None  # the estimate is truth only when asked


def test_topic_errors(tmp_path: Path, rec: Recording) -> None:
    path = write_bare_mcap(tmp_path / "walk.mcap", ros_samples(rec))
    with pytest.raises(ValueError, match=r"topic '/imu_pb' is foxglove.Imu \(protobuf"):
        read_mcap(path, topic="/imu_pb")
    only_json = write_bare_mcap(tmp_path / "json.mcap", [s for s in ros_samples(rec) if s[0] == "/mag"])
    with pytest.raises(ValueError, match="json.mcap: no sensor_msgs/msg/Imu topic; the topics are: /imu_pb"):
        read_mcap(only_json)


def test_corrupt_and_empty_files(tmp_path: Path) -> None:
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"\x89MCAP0\r\n" + bytes(range(200)))
    with pytest.raises(ValueError, match="junk.mcap: not a readable MCAP file"):
        load_recording(junk)
    noise = tmp_path / "noise.mcap"
    noise.write_bytes(b"not an mcap file at all")
    with pytest.raises(ValueError, match="noise.mcap: not a readable MCAP file"):
        load_recording(noise)
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    with pytest.raises(ValueError, match="empty.mcap: empty file"):
        load_recording(empty)
