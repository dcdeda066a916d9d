"""``attica run -o``: .npz, .csv and .mcap written from the command line and read back.

The CSV and the MCAP must hold what the .npz holds (the filter's own float32 outputs), on the
recording's clock; the MCAP must open with the mcap package's reader and with rosbags' AnyReader and
decode, message for message, with rosbags' ROS 2 typestore.
"""

from __future__ import annotations

import dataclasses
import errno
import importlib.util
import re
import shlex
import sys
import textwrap
from decimal import Decimal
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from attica import native
from attica.cli import main
from attica.data import export, load_recording
from attica.kinds import info
from attica.outputs import OUTPUT_DTYPE
from attica.settings import FilterKind, Flag
from attica.sim import SimConfig, simulate

from helpers import ROOT, need

RUN_KINDS = ("ars", "kf", "ekf", "mekf", "gyro")
"""One kind per covariance layout: none, quaternion, Euler angles, earth-frame rotation vector."""

T0 = 1_700_000_000.25
"""Start of the timed recording's clock (Unix time, s)."""


def _need_recordings() -> None:
    have = all(importlib.util.find_spec(m) is not None for m in ("mcap", "rosbags"))
    need(have, "mcap and rosbags are not installed (pip install 'attica[recordings]')")


@pytest.fixture(scope="module")
def timed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 4 s simulation on a Unix-time clock; no accel in the first 3 samples, one gyro sample lost."""
    rec = simulate(SimConfig(duration=4.0, seed=4))
    acc, gyr = rec.acc.copy(), rec.gyr.copy()
    acc[:3] = np.nan  # the filters wait: NOT_READY, no orientation estimate
    gyr[10] = np.nan  # GYRO_INVALID: angular velocity without a value
    rec = dataclasses.replace(rec, acc=acc, gyr=gyr, time=T0 + rec.t)
    path = tmp_path_factory.mktemp("timed") / "timed.npz"
    rec.save(path)
    return path


@pytest.fixture(scope="module")
def written(timed: Path) -> dict[str, Path]:
    """``attica run`` over the timed recording with -o .npz, .csv and .mcap (one file per kind)."""
    _need_recordings()
    out = {}
    for suffix in ("npz", "csv", "mcap"):
        out[suffix] = timed.with_name(f"out.{suffix}")
        argv = ["run", "--data", str(timed), "--filter", ",".join(RUN_KINDS), "-q", "--no-unit-check"]
        assert main([*argv, "-o", str(out[suffix])]) == 0
    return out


def _per_kind(path: Path, kind: str) -> Path:
    return path.with_name(f"{path.stem}_{kind}{path.suffix}")


def _read_csv(path: Path) -> tuple[list[str], list[str], np.ndarray]:
    lines = path.read_text().splitlines()
    comments = [x for x in lines if x.startswith("#")]
    body = [x for x in lines if not x.startswith("#")]
    return comments, body[0].split(","), np.loadtxt(body[1:], delimiter=",", ndmin=2)


def _exact_ns(seconds: np.ndarray) -> np.ndarray:
    """Nanoseconds nearest to each float64 time, in exact decimal arithmetic."""
    return np.array([int((Decimal(float(s)) * 10**9).to_integral_value()) for s in seconds], np.int64)


@pytest.mark.parametrize("kind", RUN_KINDS)
def test_csv_holds_the_npz_outputs(written: dict[str, Path], timed: Path, kind: str) -> None:
    rec = load_recording(timed)
    ref = np.load(_per_kind(written["npz"], kind))
    comments, columns, table = _read_csv(_per_kind(written["csv"], kind))
    assert columns == export.csv_columns(kind)
    col = {name: table[:, i] for i, name in enumerate(columns)}
    assert rec.time is not None
    np.testing.assert_array_equal(col["time"], rec.time)  # 9 decimals give the float64 back
    assert any("recording's own clock" in c for c in comments)
    for i, name in enumerate(("q_w", "q_x", "q_y", "q_z")):
        np.testing.assert_array_equal(col[name].astype(np.float32), ref["q"][:, i])
    for i, name in enumerate(("roll", "pitch", "yaw")):
        np.testing.assert_array_equal(col[name].astype(np.float32), ref["euler"][:, i])
    for i, axis in enumerate("xyz"):
        np.testing.assert_array_equal(col[f"gyro_bias_{axis}"].astype(np.float32), ref["gyro_bias"][:, i])
    cov = export.COVARIANCE.get(info(kind).kind)
    cov_names = cov.columns if cov is not None else ()
    assert [c for c in columns if c.startswith("var_")] == list(cov_names)
    for i, name in enumerate(cov_names):
        np.testing.assert_array_equal(col[name].astype(np.float32), ref["cov"][:, i])
    np.testing.assert_array_equal(col["flags"].astype(np.uint32), ref["flags"])
    np.testing.assert_array_equal(col["steps"].astype(np.uint32), ref["steps"])
    header = "\n".join(comments)
    assert all(f"0x{f.value:04X} {f.name}" in header for f in Flag)  # every bit named
    assert "rad" in header and "ENU" in header


def _mcap_messages(path: Path) -> dict[str, list[tuple[int, Any]]]:
    """topic -> [(log_time, decoded message)] through the mcap package's reader and rosbags' typestore."""
    from mcap.reader import make_reader
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    found: dict[str, list[tuple[int, Any]]] = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            assert schema is not None and schema.encoding == "ros2msg" and channel.message_encoding == "cdr"
            msg = ts.deserialize_cdr(message.data, schema.name)
            found.setdefault(channel.topic, []).append((message.log_time, msg))
    return found


@pytest.mark.parametrize("kind", RUN_KINDS)
def test_mcap_holds_the_npz_outputs(written: dict[str, Path], timed: Path, kind: str) -> None:
    rec = load_recording(timed)
    ref = np.load(_per_kind(written["npz"], kind))
    msgs = _mcap_messages(_per_kind(written["mcap"], kind))
    assert set(msgs) == {export.IMU_TOPIC, export.TF_TOPIC, export.MAG_TOPIC, export.FLAGS_TOPIC}
    imu = [m for _, m in msgs[export.IMU_TOPIC]]
    n = len(rec.gyr)
    assert len(imu) == n and len(msgs[export.TF_TOPIC]) == n
    flags = [(t, m.data) for t, m in msgs[export.FLAGS_TOPIC]]
    np.testing.assert_array_equal([f for _, f in flags], ref["flags"])  # a recovery is visible in a file
    assert (ref["flags"] & Flag.GYRO_INVALID).any()  # the recording's lost gyro sample
    q = np.array([[m.orientation.w, m.orientation.x, m.orientation.y, m.orientation.z] for m in imu])
    np.testing.assert_array_equal(q, ref["q"].astype(np.float64))  # float32 -> float64 is exact
    assert rec.time is not None
    ns = _exact_ns(rec.time)
    stamps = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in imu], np.int64)
    np.testing.assert_array_equal(stamps, ns)
    np.testing.assert_array_equal([t for t, _ in msgs[export.IMU_TOPIC]], ns)  # log time = stamp
    assert {m.header.frame_id for m in imu} == {"imu"}
    gyr = np.array([[m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z] for m in imu])
    np.testing.assert_array_equal(gyr, rec.gyr.astype(np.float64))
    acc = np.array([[m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z] for m in imu])
    np.testing.assert_array_equal(acc, rec.acc.astype(np.float64))

    # covariance layout: 3x3 row-major rad^2, the kind's diagonal; -1 = no estimate / no value
    cov = np.array([m.orientation_covariance for m in imu])
    no_estimate = (ref["flags"] & export.OUTPUT_INVALID) != 0
    waits = 3 if kind != "gyro" else 0  # the gyro baseline needs no accel sample to start
    assert no_estimate[:waits].all() and not no_estimate[waits:].any()
    np.testing.assert_array_equal(cov[no_estimate], np.tile([-1.0] + [0.0] * 8, (waits, 1)))
    est = cov[~no_estimate].reshape(-1, 3, 3)
    off = ~np.eye(3, dtype=bool)
    np.testing.assert_array_equal(est, np.transpose(est, (0, 2, 1)))  # symmetric
    if kind != "ekf":
        assert (est[:, off] == 0.0).all()
    c = ref["cov"][~no_estimate].astype(np.float64)
    diag = np.diagonal(est, axis1=1, axis2=2)
    unknown = np.full(len(c), export.UNKNOWN_YAW)
    if kind == "ekf":  # the Euler angles' variances turned onto the earth's axes; the yaw's own (pi^2/3)
        e = ref["euler"][~no_estimate].astype(np.float64)
        s_th, c_th = np.sin(e[:, 1]), np.cos(e[:, 1])
        s_ps, c_ps = np.sin(e[:, 2]), np.cos(e[:, 2])
        ekf_x = c[:, 0] * (c_ps * c_th) ** 2 + c[:, 1] * s_ps**2
        ekf_y = c[:, 0] * (s_ps * c_th) ** 2 + c[:, 1] * c_ps**2
        ekf_z = c[:, 0] * s_th**2 + c[:, 2]
    expected = {
        "ars": c[:, :3],  # the model's tilt, tilt, heading
        "gyro": np.zeros((len(c), 3)),  # no covariance: all zeros, "unknown"
        "kf": np.stack([4.0 * c.mean(axis=1)] * 2 + [unknown], axis=1),  # P = p I on q: 4 p rad^2; yaw
        "ekf": np.stack([ekf_x, ekf_y, ekf_z], axis=1) if kind == "ekf" else None,
        "mekf": c[:, :3],  # earth-frame rotation vector
    }[kind]
    np.testing.assert_allclose(diag, expected, rtol=1e-12)
    if kind != "gyro":
        assert (diag > 0.0).all()
    gyr_cov = np.array([m.angular_velocity_covariance for m in imu])
    assert gyr_cov[10, 0] == -1.0 and not gyr_cov[np.arange(n) != 10].any()
    assert not np.array([m.linear_acceleration_covariance for m in imu])[3:].any()

    # the transform for Foxglove's 3D panel: enu -> imu, rotation q, no translation
    tfs = [m.transforms for _, m in msgs[export.TF_TOPIC]]
    assert all(len(t) == 1 for t in tfs)
    tf = [t[0] for t in tfs]
    assert {(t.header.frame_id, t.child_frame_id) for t in tf} == {("enu", "imu")}
    rot = np.array(
        [
            [t.transform.rotation.w, t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z]
            for t in tf
        ]
    )
    np.testing.assert_array_equal(rot, q)
    assert all(
        t.transform.translation.x == t.transform.translation.y == t.transform.translation.z == 0.0 for t in tf
    )

    # the magnetometer samples, in T, make the file a recording again
    field = np.array(
        [[m.magnetic_field.x, m.magnetic_field.y, m.magnetic_field.z] for _, m in msgs[export.MAG_TOPIC]]
    )
    np.testing.assert_allclose(field * 1e6, rec.mag.astype(np.float64), rtol=1e-12)


def test_mcap_opens_with_rosbags_anyreader(written: dict[str, Path]) -> None:
    from rosbags.highlevel import AnyReader

    path = _per_kind(written["mcap"], "mekf")
    with AnyReader([path]) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        assert types == {
            export.IMU_TOPIC: "sensor_msgs/msg/Imu",
            export.TF_TOPIC: "tf2_msgs/msg/TFMessage",
            export.MAG_TOPIC: "sensor_msgs/msg/MagneticField",
            export.FLAGS_TOPIC: "std_msgs/msg/UInt32",
        }
        decoded = sum(1 for c, _, raw in reader.messages() if reader.deserialize(raw, c.msgtype) is not None)
        assert decoded == sum(c.msgcount for c in reader.connections) > 0


def test_mcap_reads_back_as_the_recording(tmp_path: Path) -> None:
    """attica's own MCAP reader gets the input samples back from the Imu and MagneticField topics."""
    _need_recordings()
    mcapfile = pytest.importorskip("attica.data.mcapfile")
    rec = simulate(SimConfig(duration=2.0, seed=5))
    rec.save(tmp_path / "rec.npz")
    assert main(["run", "--data", str(tmp_path / "rec.npz"), "-q", "-o", str(tmp_path / "out.mcap")]) == 0
    back = mcapfile.load_mcap(tmp_path / "out.mcap")
    np.testing.assert_array_equal(back.gyr, rec.gyr)
    np.testing.assert_array_equal(back.acc, rec.acc)
    np.testing.assert_array_equal(back.mag, rec.mag)
    np.testing.assert_allclose(back.t, rec.t, atol=1e-9, rtol=0)


def test_csv_of_a_simulation_counts_from_zero(tmp_path: Path) -> None:
    path = tmp_path / "sim.csv"
    assert main(["run", "--filter", "mars", "--duration", "2", "-q", "-o", str(path)]) == 0
    comments, columns, table = _read_csv(path)
    assert "var_att_e" in columns and any("from the first sample" in c for c in comments)  # mars's model
    rate = SimConfig().rate
    np.testing.assert_allclose(table[:, 0], np.arange(len(table)) / rate, atol=5e-10, rtol=0)


def test_outputs_in_another_convention_say_so(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A calibration with the NED convention: the CSV's header names NED for q (and says the covariance
    stays ENU); an .mcap, whose sensor_msgs/Imu is ENU (REP-145), is refused before the filters run."""
    from attica.calibration import Calibration

    cal = tmp_path / "ned.json"
    Calibration(convention="ned").save(cal)
    path = tmp_path / "ned.csv"
    args = ["run", "--filter", "mekf", "--duration", "2", "-q", "--calibration", str(cal)]
    assert main([*args, "-o", str(path)]) == 0
    comments, _, _ = _read_csv(path)
    text = " ".join(comments)
    assert "sensor-to-earth (NED: x north, y east, z down)" in text and "ENU: x east" not in text
    assert "about the ENU axes whatever the output convention" in text
    capsys.readouterr()
    assert main([*args, "-o", str(tmp_path / "ned.mcap")]) == 2
    err = capsys.readouterr()
    assert "REP-145" in err.err and "ned" in err.err and "RMSE" not in err.out
    with pytest.raises(ValueError, match="REP-145"):
        export.write_outputs(
            tmp_path / "x.mcap",
            np.zeros(0, OUTPUT_DTYPE),
            simulate(SimConfig(duration=0.1)),
            "ars",
            convention="ned",
        )


@pytest.mark.parametrize(
    "name,message",
    [
        ("out.txt", "unknown suffix '.txt'; use .npz, .csv or .mcap"),
        ("out.tar.gz", "unknown suffix '.gz'"),
        ("missing/out.csv", "directory"),
        ("file.bin/out.mcap", "does not exist"),
    ],
)
def test_run_refuses_an_output_it_cannot_write(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, message: str
) -> None:
    (tmp_path / "file.bin").write_bytes(b"")
    assert main(["run", "--duration", "1", "-q", "-o", str(tmp_path / name)]) == 2
    err = capsys.readouterr()
    assert message in err.err and "RMSE" not in err.out  # refused before the filters ran


def test_run_reports_a_failed_write(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    def full(*_: Any, **__: Any) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(export, "write_csv", full)
    assert main(["run", "--duration", "1", "-q", "-o", str(tmp_path / "out.csv")]) == 2
    assert "cannot write" in capsys.readouterr().err


def test_mcap_without_its_packages_names_the_extra(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "mcap.writer", None)  # as if mcap were not installed
    assert main(["run", "--duration", "1", "-q", "-o", str(tmp_path / "out.mcap")]) == 2
    err = capsys.readouterr()
    assert "attica[recordings]" in err.err and "RMSE" not in err.out
    with pytest.raises(ImportError, match=r"attica\[recordings\]"):
        export.write_mcap(
            tmp_path / "x.mcap", np.zeros(0, OUTPUT_DTYPE), simulate(SimConfig(duration=0.1)), "ars"
        )


def test_mcap_refuses_times_that_are_no_stamps(tmp_path: Path) -> None:
    _need_recordings()
    rec = simulate(SimConfig(duration=0.1))
    early = dataclasses.replace(rec, time=rec.t - 1.0)
    with pytest.raises(ValueError, match="0 <= t < 2"):
        export.check_output(tmp_path / "x.mcap", early)
    export.check_output(tmp_path / "x.csv", early)  # a CSV holds any time


def test_stamps_round_to_the_nearest_nanosecond() -> None:
    t = np.array([0.0, 0.9999999996, 1.5, T0, 2.0**31 - 1e-3])
    sec, nsec = export.ros_stamps(t)
    assert ((nsec >= 0) & (nsec < 10**9)).all()
    np.testing.assert_array_equal(sec * 10**9 + nsec, _exact_ns(t))


def test_orientation_covariance_marks_no_estimate() -> None:
    out = np.zeros(2, OUTPUT_DTYPE)
    out["cov"] = [[1.0, 2.0, 3.0, 4.0], [1.0, 2.0, 3.0, 4.0]]
    out["flags"] = [int(Flag.NOT_READY), 0]
    u = export.UNKNOWN_YAW
    for kind, diag in (
        ("mekf", [1.0, 2.0, 3.0]),
        ("ekf", [1.0, 2.0, 3.0]),  # level, yaw 0: roll about east, pitch about north; the yaw's own
        ("kf", [10.0, 10.0, u]),
        ("tilt", [0.0] * 3),
    ):
        c = export.orientation_covariance(kind, out)
        assert list(c[0]) == [-1.0] + [0.0] * 8
        np.testing.assert_array_equal(c[1], np.diag(diag).ravel())


def test_the_6_axis_mekf_writes_its_yaw_as_unknown() -> None:
    """With use_mag off the mekf's yaw is observed by nothing: its output says pi^2/3 (until a heading is
    set: tests/test_heading_cov.py), and the Imu message takes that; a 9-axis mekf's is P's."""
    from attica.settings import MekfSettings

    r = simulate(SimConfig(duration=10.0, rate=100.0, seed=2))
    dt = float(np.float32(0.01))
    six = native.Filter(FilterKind.MEKF, MekfSettings(dt=dt, use_mag=False)).run(r.gyr, r.acc)
    nine = native.Filter(FilterKind.MEKF, MekfSettings(dt=dt)).run(r.gyr, r.acc, r.mag)
    c6 = export.orientation_covariance("mekf", six[1:])
    c9 = export.orientation_covariance("mekf", nine[1:])
    np.testing.assert_array_equal(c6[:, 8], np.full(len(c6), export.UNKNOWN_YAW))
    np.testing.assert_array_equal(c9[:, 8], nine["cov"][1:, 2].astype(np.float64))
    assert (c9[:, 8] < export.UNKNOWN_YAW).all() and len(np.unique(c9[:, 8])) > 10


def test_mcap_metadata_names_the_filter_and_its_axes(tmp_path: Path) -> None:
    """The metadata's ``filter`` entry says the run's axes (a mekf with use_mag off is 6-axis)."""
    _need_recordings()
    from mcap.reader import make_reader

    from attica.settings import MekfSettings

    rec = simulate(SimConfig(duration=0.5, rate=100.0, seed=1))
    out = np.zeros(len(rec), OUTPUT_DTYPE)
    out["q"] = (1.0, 0.0, 0.0, 0.0)
    cases = ((MekfSettings(dt=0.01), "9-axis"), (MekfSettings(dt=0.01, use_mag=False), "6-axis"))
    for settings, axes in cases:
        path = tmp_path / f"{axes}.mcap"
        export.write_mcap(path, out, rec, "mekf", settings=settings)
        with open(path, "rb") as f:
            meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
        assert meta["attica"]["kind"] == "mekf" and meta["attica"]["filter"].startswith(f"mekf ({axes}")


def test_ekf_covariance_turns_with_the_yaw() -> None:
    """The EKF's roll and pitch variances are about axes that turn with the yaw: at a yaw of 90 deg the
    roll's is about the earth's north (y), the pitch's about west-east (x); at a pitch of 90 deg the
    roll's is about the vertical."""
    out = np.zeros(3, OUTPUT_DTYPE)
    out["cov"] = [[1.0, 2.0, 3.0, 0.0]] * 3
    out["euler"] = [[0.0, 0.0, np.pi / 2], [0.0, np.pi / 2, 0.0], [0.3, 0.2, 0.1]]
    c = export.orientation_covariance("ekf", out).reshape(3, 3, 3)
    u = 3.0  # the yaw's, about up
    np.testing.assert_allclose(c[0], np.diag([2.0, 1.0, u]), atol=1e-7)  # float32 angles
    np.testing.assert_allclose(c[1], np.diag([0.0, 2.0, 1.0 + u]), atol=1e-7)
    # the general case: unit axes, so the trace is the sum of the variances; positive definite
    assert np.trace(c[2]) == pytest.approx(1.0 + 2.0 + u)
    assert np.linalg.eigvalsh(c[2]).min() > 0.0


def _writers_section() -> str:
    text = (ROOT / "docs" / "recordings.md").read_text()
    start = text.index("## Writers")
    nxt = re.search(r"^## ", text[start + 3 :], re.M)
    return text[start : start + 3 + nxt.start()] if nxt else text[start:]


def test_docs_writers_examples_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """docs/recordings.md, ## Writers: every command and Python block runs, in order."""
    _need_recordings()
    section = _writers_section()
    blocks = re.findall(r"```(sh|python)\n(.*?)```", section, re.S)
    assert any(lang == "sh" for lang, _ in blocks) and any(lang == "python" for lang, _ in blocks)
    monkeypatch.chdir(tmp_path)
    ns: dict[str, object] = {}
    for lang, block in blocks:
        if lang == "python":
            exec(compile(textwrap.dedent(block), "docs/recordings.md", "exec"), ns)
            continue
        for line in block.splitlines():
            line = line.split("  #")[0].strip()
            if line.startswith("attica "):
                assert main(shlex.split(line)[1:]) == 0, line


def test_outputs_hold_the_hard_iron_estimate(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A mars with hard_iron_tau writes the offset of every step in each format, as Filter.run(mag_offset)
    gives it; a kind without the estimate (or with it off) writes no such column, array or topic."""
    _need_recordings()
    from attica import native
    from attica.outputs import MAG_OFFSET_DTYPE
    from attica.sim.errors import mag_only

    hard = mag_only(hard_iron=20.0, soft_iron_scale=0.0, soft_iron_coupling=0.0)
    rec = simulate(SimConfig(duration=40.0, seed=6, sensor_errors=hard))
    data = tmp_path / "hi.npz"
    rec.save(data)
    base = ["run", "--data", str(data), "-q", "--no-unit-check", "--set", "hard_iron_tau=60"]
    for suffix in ("npz", "csv", "mcap"):
        assert main([*base, "--filter", "mars,ars", "-o", str(tmp_path / f"o.{suffix}")]) == 0
    capsys.readouterr()
    f = native.Filter("mars", 1.0 / rec.rate, hard_iron_tau=60.0)
    mo = np.zeros(len(rec.gyr), MAG_OFFSET_DTYPE)
    f.run(rec.gyr, rec.acc, rec.mag, check_units=False, mag_offset=mo)
    assert mo["estimated"][-1] and not mo["estimated"][0] and np.abs(mo["offset"][-1]).max() > 3.0

    npz = np.load(tmp_path / "o_mars.npz")
    assert npz["mag_offset"].tobytes() == mo["offset"].tobytes()
    np.testing.assert_array_equal(npz["mag_offset_estimated"], mo["estimated"])
    assert "mag_offset" not in np.load(tmp_path / "o_ars.npz")

    comments, columns, table = _read_csv(tmp_path / "o_mars.csv")
    assert columns == export.csv_columns("mars", mag_offset=True) and columns[-4:] == list(
        export.MAG_OFFSET_COLUMNS
    )
    col = {name: table[:, i] for i, name in enumerate(columns)}
    for i, axis in enumerate("xyz"):
        np.testing.assert_array_equal(col[f"mag_offset_{axis}"].astype(np.float32), mo["offset"][:, i])
    np.testing.assert_array_equal(col["mag_offset_estimated"].astype(bool), mo["estimated"])
    assert any("mag_offset_x" in c and "uT" in c for c in comments)
    assert _read_csv(tmp_path / "o_ars.csv")[1] == export.csv_columns("ars")

    msgs = _mcap_messages(tmp_path / "o_mars.mcap")
    fields = [m for _, m in msgs[export.MAG_OFFSET_TOPIC]]
    h = np.array([[m.magnetic_field.x, m.magnetic_field.y, m.magnetic_field.z] for m in fields])
    np.testing.assert_allclose(h * 1e6, mo["offset"].astype(np.float64), rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal([m.magnetic_field_covariance[0] == -1.0 for m in fields], ~mo["estimated"])
    assert export.MAG_OFFSET_TOPIC not in _mcap_messages(tmp_path / "o_ars.mcap")
