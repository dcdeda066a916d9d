"""attica view without a browser: the state fed frame by frame, the sources (log playback, a bus that
fails), against the real C node and python-can's own buses and log writers."""

from __future__ import annotations

import json
import math
import threading
import time
import uuid
from pathlib import Path

import can
import numpy as np
import pytest

from attica.can import codec
from attica.can.bus import resolve_config, to_messages
from attica.can.logs import open_writer
from attica.can.node import Node
from attica.can.runner import NodeRunner
from attica.settings import Flag
from attica.view.playback import LogSource
from attica.view.sources import BusSource, SourceError
from attica.view.state import ViewState

G = 9.80665
YAW90_MAG = (20.0, 0.0, -40.0)  # the field (north, down) seen by a level sensor whose x points north


def still(
    n: int, mag: tuple[float, float, float] | None = YAW90_MAG, acc: float = G
) -> tuple[np.ndarray, ...]:
    """n still samples of a level sensor, yaw 90 deg (x north) by its magnetometer."""
    gyr = np.zeros((n, 3), np.float32)
    a = np.tile(np.float32([0.0, 0.0, acc]), (n, 1))
    m = np.full((n, 3), np.nan, np.float32) if mag is None else np.tile(np.float32(mag), (n, 1))
    return gyr, a, m


def session(
    kind: str = "mars", n: int = 200, rate: float = 200.0, fd: bool = False, mag=YAW90_MAG, t0: float = 1000.0
) -> tuple[list[can.Message], Node]:
    """The bus of a node fed n samples: each sample's IMU frames, then the node's answer, time-stamped."""
    node = Node(kind, sample_rate=rate, fd=fd, data_bitrate=2_000_000 if fd else 0)
    gyr, acc, m = still(n, mag)
    out: list[can.Message] = []
    per = 1 if fd else 3
    imu = to_messages(codec.encode_imu(gyr, acc, m, fd=fd))
    for k in range(n):
        ts = t0 + k / rate
        frames = imu[k * per : (k + 1) * per]
        answer, _ = node.run(
            codec.encode_imu(gyr[k : k + 1], acc[k : k + 1], m[k : k + 1], counter0=k, fd=fd)
        )
        for j, msg in enumerate(frames + to_messages(answer)):
            msg.timestamp = ts + 1e-5 * j
            out.append(msg)
    return out, node


@pytest.mark.parametrize("fd", [False, True])
def test_state_shows_the_node_outputs(fd: bool) -> None:
    msgs, node = session(fd=fd)
    st = ViewState(data_bitrate=2_000_000)
    st.feed_many(msgs)
    snap = st.snapshot()
    json.dumps(snap, allow_nan=False)  # the page's JSON: no NaN anywhere
    att = snap["att"]
    assert att["kind"] == "mars" and att["fd"] is fd
    roll, pitch, yaw = (math.degrees(v) for v in att["euler"])
    assert abs(yaw - 90.0) < 0.05 and abs(roll) < 0.05 and abs(pitch) < 0.05, att["euler"]
    assert att["steps"] == node.stats()["steps"] & 0xFFFF
    assert att["flag_names"] == [f.name for f in Flag if f.value & att["flags"]]
    assert "AT_REST" in att["flag_names"]  # a second at rest
    h = snap["health"]
    assert h["frames"] == len(msgs)
    assert h["crc_errors"] == h["counter_gaps"] == h["dlc_errors"] == h["missing_sets"] == h["dropped"] == 0
    assert h["frames_per_s"] == pytest.approx(len(msgs) / (msgs[-1].timestamp - msgs[0].timestamp), rel=0.05)
    assert 0 < h["latency_ms"] < 1.0  # IMU sample to output set, in bus time
    assert h["bus_load"] > 0
    imu = snap["imu"]
    assert imu["acc_norm"] == pytest.approx(G, abs=0.01)
    assert imu["mag_norm"] == pytest.approx(math.hypot(*YAW90_MAG), abs=0.05)
    if not fd:
        assert snap["diag"] is not None and snap["diag"]["crc_errors"] == 0
    assert snap["history_seq"] == 1 and len(st.history_since(0)) == 1


@pytest.mark.parametrize("kind", ["mars", "mekf", "kf", "gyro"])
def test_state_shows_the_orientation_covariance_of_fd_sets(kind: str) -> None:
    """An FD set's covariance reaches the page and Foxglove's /imu as the Imu message's 3x3 (the file
    export's, attica.data.export.orientation_covariance), turned onto the view's convention's axes; a
    classic set has none (None: zeros on /imu), nor have gyro and tilt."""
    from attica.data.export import orientation_covariance
    from attica.settings import FilterKind

    msgs, node = session(kind, fd=True)
    st = ViewState(data_bitrate=2_000_000)
    st.feed_many(msgs)
    att = st.snapshot()["att"]
    out, _ = Node(kind, sample_rate=200.0, fd=True, data_bitrate=2_000_000).run(
        codec.encode_imu(*still(200), fd=True)
    )
    last = codec.decode_outputs(out).sets[-1:]
    if kind == "gyro":
        assert att["cov"] is None
        return
    want = orientation_covariance(FilterKind.parse(kind), last)[0]
    assert want[0] > 0 and att["cov"] == pytest.approx(want.tolist(), rel=1e-12)
    st.convention = "NED"  # east <-> north, up -> down: the diagonal's first two swap
    ned = st.snapshot()["att"]["cov"]
    assert (
        ned[0] == pytest.approx(want[4])
        and ned[4] == pytest.approx(want[0])
        and ned[8] == pytest.approx(want[8])
    )
    classic, _ = session(kind, fd=False)
    st = ViewState()
    st.feed_many(classic)
    assert st.snapshot()["att"]["cov"] is None


@pytest.mark.parametrize("convention", ["NED", "NWU"])
def test_the_ekf_covariance_in_another_convention(convention: str) -> None:
    """The EKF's covariance turns its Euler angles' variances onto the earth's axes through the angles,
    which the model takes about ENU: in another convention the view takes them from the set's q turned
    back to ENU (the set's own angles are the convention's), then turns the matrix onto its axes."""
    from attica.can.frames import SET_DTYPE
    from attica.data.export import orientation_covariance
    from attica.settings import FilterKind
    from attica.view.state import _FROM_ENU, orientation_cov

    roll, pitch, yaw = 0.1, 0.05, 0.3
    cr, sr, cp, sp, cy, sy = (f(a / 2) for a in (roll, pitch, yaw) for f in (math.cos, math.sin))
    q_enu = np.array(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ]
    )
    enu = np.zeros(1, SET_DTYPE)
    enu["q"][0], enu["euler"][0], enu["cov"][0] = q_enu, (roll, pitch, yaw), (1e-3, 4e-3, 0.2, 1e-8)
    r = _FROM_ENU[convention]
    want = r @ orientation_covariance(FilterKind.EKF, enu)[0].reshape(3, 3) @ r.T
    # the same attitude in the convention: R_conv = r R_enu, as a quaternion (w from the trace: w > 0 here)
    m = r @ np.array(
        [
            [
                1 - 2 * (q_enu[2] ** 2 + q_enu[3] ** 2),
                2 * (q_enu[1] * q_enu[2] - q_enu[0] * q_enu[3]),
                2 * (q_enu[1] * q_enu[3] + q_enu[0] * q_enu[2]),
            ],
            [
                2 * (q_enu[1] * q_enu[2] + q_enu[0] * q_enu[3]),
                1 - 2 * (q_enu[1] ** 2 + q_enu[3] ** 2),
                2 * (q_enu[2] * q_enu[3] - q_enu[0] * q_enu[1]),
            ],
            [
                2 * (q_enu[1] * q_enu[3] - q_enu[0] * q_enu[2]),
                2 * (q_enu[2] * q_enu[3] + q_enu[0] * q_enu[1]),
                1 - 2 * (q_enu[1] ** 2 + q_enu[2] ** 2),
            ],
        ]
    )
    w = math.sqrt(max(0.0, 1 + np.trace(m))) / 2
    q_conv = np.array(
        [w, (m[2, 1] - m[1, 2]) / (4 * w), (m[0, 2] - m[2, 0]) / (4 * w), (m[1, 0] - m[0, 1]) / (4 * w)]
    )
    conv = enu.copy()
    conv["q"][0] = q_conv
    conv["euler"][0] = (9.0, 9.0, 9.0)  # the convention's own angles: not used
    got = np.array(orientation_cov(FilterKind.EKF, conv, convention), np.float64).reshape(3, 3)
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-9)


def test_state_shows_the_hard_iron_offset() -> None:
    """The last ATT_MAG_OFFSET (a mars estimating its hard-iron offset sends one after each ATT_DIAG) is in
    the snapshot, for the page and Foxglove's /attica/status; None from a node that sends none."""
    gyr, acc, mag = still(64)
    out, _ = Node("mars", sample_rate=200.0, hard_iron_tau=60.0).run(codec.encode_imu(gyr, acc, mag))
    sent = codec.decode_outputs(out).mag_offset
    assert len(sent) == 64 // 16
    st = ViewState()
    st.feed_many(to_messages(codec.encode_imu(gyr, acc, mag)) + to_messages(out))
    mo = st.snapshot()["mag_offset"]
    assert mo is not None and mo["estimated"] == bool(sent["estimated"][-1])
    assert mo["offset"] == [float(v) for v in sent["offset"][-1]]
    msgs, _ = session("mars", n=64)
    plain = ViewState()
    plain.feed_many(msgs)
    assert plain.snapshot()["mag_offset"] is None


def test_state_and_monitor_show_the_can_controller() -> None:
    """ATT_DIAG_BUS (a node on a Cortex-M port reports its CAN controller): the page's ``diag_bus`` and the
    monitor's summary line; its counter follows the sets like ATT_DIAG's and is no gap. A node without
    a port sends none: ``diag_bus`` is None."""
    msgs, _ = session(kind="ars", n=40)
    plain = ViewState()
    plain.feed_many(msgs)
    assert plain.snapshot()["diag_bus"] is None
    assert not any("ATT_DIAG_BUS" in line for line in plain.monitor.summary())
    m = codec.database().get_message_by_name("ATT_DIAG_BUS")
    extra = []
    for k in range(3):
        fields = {"crc": 0, "counter": (5 * k) % 16, "state": 3, "bus_off": 2 + k, "recoveries": 1 + k}
        fields.update({"error_passive": 4, "error_warning": 5, "rx_overruns": 0, "lec": 3})
        data = bytearray(m.encode(fields))
        data[0] = codec.e2e_crc(codec.data_id(codec.ID_DIAG_BUS), bytes(data[1:]))
        ts = msgs[-1].timestamp + 0.001 * (k + 1)
        extra.append(
            can.Message(
                arbitration_id=codec.ID_DIAG_BUS, data=bytes(data), is_extended_id=False, timestamp=ts
            )
        )
    st = ViewState()
    st.feed_many(msgs + extra)
    snap = st.snapshot()
    json.dumps(snap, allow_nan=False)
    assert snap["diag_bus"] == {
        "state": "BUS_OFF",
        "bus_off": 4,
        "recoveries": 3,
        "error_passive": 4,
        "error_warning": 5,
        "rx_overruns": 0,
        "lec": "ACK",
    }
    h = snap["health"]
    assert h["counter_gaps"] == h["crc_errors"] == h["unknown_ids"] == 0
    want = "node CAN controller (ATT_DIAG_BUS): state BUS_OFF, bus-off 4, recoveries 3, error-passive 4"
    assert any(line.startswith(want) for line in st.monitor.summary()), st.monitor.summary()


def test_state_without_mag_is_json_safe() -> None:
    msgs, _ = session(kind="ars", n=40, mag=None)
    st = ViewState()
    st.feed_many(msgs)
    snap = st.snapshot()
    text = json.dumps(snap, allow_nan=False)
    assert snap["imu"]["mag_norm"] is None and snap["imu"]["mag"] == [None, None, None]
    assert "NaN" not in text


def test_bad_frames_are_counted_shown_and_never_raised() -> None:
    msgs, _ = session(n=120)
    st = ViewState()
    st.feed_many(msgs[:300])
    good = st.snapshot()["att"]
    bad = list(msgs[300:330])
    # a bad E2E CRC on an ATT_EULER, a gap (the next sample's IMU frames missing), a short frame, an
    # unknown ID, an extended ID, an error frame, a remote frame, junk on ATT_OUT_FD
    euler = next(m for m in bad if m.arbitration_id == codec.ID_EULER)
    corrupt = can.Message(
        arbitration_id=codec.ID_EULER,
        data=bytes([euler.data[0] ^ 0x5A]) + bytes(euler.data[1:]),
        is_extended_id=False,
        timestamp=euler.timestamp,
    )
    bad[bad.index(euler)] = corrupt
    imu_ids = (codec.ID_IMU_GYRO, codec.ID_IMU_ACC, codec.ID_IMU_MAG)
    lost = [i for i, m in enumerate(bad) if m.arbitration_id in imu_ids][:3]  # one sample's frames
    bad = [m for i, m in enumerate(bad) if i not in lost]
    ts = bad[-1].timestamp
    extra = [
        can.Message(arbitration_id=codec.ID_STATUS, data=b"\x01\x02", is_extended_id=False, timestamp=ts),
        can.Message(arbitration_id=0x7AB, data=bytes(8), is_extended_id=False, timestamp=ts),
        can.Message(arbitration_id=0x1234567, data=bytes(8), is_extended_id=True, timestamp=ts),
        can.Message(is_error_frame=True, timestamp=ts),
        can.Message(arbitration_id=codec.ID_EULER, is_remote_frame=True, is_extended_id=False, timestamp=ts),
        can.Message(
            arbitration_id=codec.ID_OUT_FD,
            data=bytes(range(64)),
            is_fd=True,
            is_extended_id=False,
            timestamp=ts,
        ),
    ]
    st.feed_many(bad + extra)
    snap = st.snapshot()
    h = snap["health"]
    assert st.view_errors == 0
    assert h["crc_errors"] >= 2  # the EULER frame and the OUT_FD junk
    assert h["counter_gaps"] >= 1 and h["dlc_errors"] >= 1 and h["unknown_ids"] >= 1 and h["other"] >= 2
    assert {"crc_errors", "counter_gaps", "dlc_errors", "unknown_ids"} <= set(h["recent"])
    texts = " ".join(e["text"] for e in snap["events"])
    for p in ("!CRC", "!GAP", "!DLC", "!UNKNOWN", "!OTHER"):
        assert p in texts, (p, texts)
    # the attitude is the last good set's (the set with the bad EULER frame is not taken)
    assert snap["att"]["euler"] == pytest.approx(good["euler"])
    json.dumps(snap, allow_nan=False)


def test_repeated_problems_are_summed_up_not_listed_one_by_one() -> None:
    st = ViewState()
    msgs = [
        can.Message(arbitration_id=0x7AB, data=bytes(8), is_extended_id=False, timestamp=float(i))
        for i in range(500)
    ]
    st.feed_many(msgs)
    events = st.snapshot()["events"]
    assert len([e for e in events if "!UNKNOWN" in e["text"]]) == 1
    for p in st._problems.values():  # the summary comes EVENT_SUMMARY s later
        p.last_report -= 10
    events = st.snapshot()["events"]
    assert any("499 more !UNKNOWN on ID 7AB" in e["text"] for e in events), events


def test_history_is_bounded_and_a_reset_starts_a_new_epoch() -> None:
    msgs, _ = session(n=60)
    st = ViewState(history=10)
    sets = [i for i, m in enumerate(msgs) if m.arbitration_id == codec.ID_STATUS]
    for i in sets[:30]:
        st.feed_many(msgs[: i + 1] if i == sets[0] else msgs[sets[sets.index(i) - 1] + 1 : i + 1])
        st.snapshot()
    assert len(st.history_since(0)) == 10
    assert st.history_since(0)[-1][0] == 30
    epoch = st.epoch
    st.reset("seek")
    assert st.epoch == epoch + 1 and st.history_since(0) == []
    assert st.snapshot()["att"] is None


def test_commands_are_answered_by_the_c_node() -> None:
    node = Node("mars", sample_rate=200.0)
    st = ViewState()
    gyr, acc, mag = still(20)
    st.feed_many(to_messages(node.run(codec.encode_imu(gyr, acc, mag))[0]))

    def send(name: str, arg: object = 0) -> str:
        rec, msg = st.command(name, arg)  # type: ignore[arg-type]
        out, _ = node.run(codec.from_message(msg))
        st.feed_many(to_messages(out))
        st.snapshot()
        return rec.status

    assert send("reset") == "ok"
    assert send("select", "ekf") == "ok" and node.running_kind.label == "ekf"
    assert send("convention", "NED") == "ok" and st.convention == "NED"
    assert send("convention", 0) == "ok" and st.convention == "ENU"
    with pytest.raises(ValueError):
        st.command("select", "nope")
    with pytest.raises(ValueError):
        st.command("convention", 7)
    with pytest.raises(ValueError):
        st.command("format", 0)
    rec, _ = st.command("reset")  # never delivered
    rec.sent -= 10
    snap = st.snapshot()
    assert snap["commands"][-1]["status"] == "no answer"
    assert [c["status"] for c in snap["commands"][:4]] == ["ok"] * 4


# --- sources ------------------------------------------------------------------------------------------


def _write_log(path: Path, msgs: list[can.Message]) -> None:
    w = open_writer(path)
    for m in msgs:
        w.on_message_received(m)
    w.stop()


def _wait(cond, timeout: float = 10.0) -> None:  # type: ignore[no-untyped-def]
    t0 = time.monotonic()
    while not cond():
        assert time.monotonic() - t0 < timeout, "timed out"
        time.sleep(0.02)


def test_log_playback_pause_seek_speed(tmp_path: Path) -> None:
    msgs, _ = session(n=400, rate=200.0)  # 2 s of bus time
    log = tmp_path / "node.log"
    _write_log(log, msgs)
    st = ViewState()
    src = LogSource(log, speed=4.0)
    src.start(st)
    try:
        _wait(lambda: st.source["state"] == "ended", 5.0)
        assert src.played == len(msgs)
        h = st.snapshot()["health"]
        assert h["frames"] == len(msgs) and h["crc_errors"] == h["counter_gaps"] == 0
        assert st.playback is not None and st.playback["ended"]
        with pytest.raises(SourceError):
            src.send(msgs[0])
        # seek to the middle, paused: the counters start anew there
        epoch = st.epoch
        src.control("pause")
        src.control("seek", 1.0)
        _wait(lambda: st.epoch == epoch + 1)
        _wait(lambda: abs(st.playback["position"] - 1.0) < 0.02)  # type: ignore[index]
        time.sleep(0.2)
        assert st.snapshot()["health"]["frames"] == 0  # paused
        src.control("speed", 2.0)
        src.control("play")
        _wait(lambda: st.snapshot()["health"]["frames"] > 0)
        t0 = time.monotonic()
        _wait(lambda: st.source["state"] == "ended", 5.0)
        assert 0.3 < time.monotonic() - t0 < 1.5  # 1 s of log at 2x
        assert st.snapshot()["health"]["counter_gaps"] == 0
        with pytest.raises(SourceError):
            src.control("speed", 0)
        with pytest.raises(SourceError):
            src.control("rewind")
    finally:
        src.stop()


def test_a_bad_log_line_is_shown_and_what_came_before_plays(tmp_path: Path) -> None:
    msgs, _ = session(n=50)
    log = tmp_path / "cut.log"
    _write_log(log, msgs)
    lines = log.read_text().splitlines()
    lines.insert(100, "(1000.5) can0 2O3#zz")
    log.write_text("\n".join(lines) + "\n")
    st = ViewState()
    src = LogSource(log, speed=50.0)
    src.start(st)
    try:
        _wait(lambda: st.source["state"] == "ended", 5.0)
        assert (
            "bad log line" in st.source["error"] and "playing the 100 frames before it" in st.source["error"]
        )
        assert st.snapshot()["health"]["frames"] == 100
    finally:
        src.stop()


def test_a_bus_that_fails_is_shown_and_opened_again() -> None:
    channel = f"view-{uuid.uuid4().hex[:8]}"
    cfg = resolve_config("virtual", channel)
    st = ViewState()
    src = BusSource(cfg, retry=0.2)
    src.start(st)
    sender = can.Bus(interface="virtual", channel=channel)
    try:
        _wait(lambda: src.bus is not None)
        msgs, _ = session(n=20)
        for m in msgs:
            sender.send(m)
        _wait(lambda: st.snapshot()["health"]["frames"] == len(msgs))
        assert st.source["state"] == "running" and st.source["error"] is None
        assert src.bus is not None
        src.bus.shutdown()  # the interface vanishes under the reader
        _wait(lambda: st.source["error"] is not None and "failed" in st.source["error"])
        _wait(lambda: src.reopened >= 1 and st.source["error"] is None and src.bus is not None)
        for m in msgs[:30]:
            sender.send(m)
        _wait(lambda: st.snapshot()["health"]["frames"] >= len(msgs) + 30)
        texts = " ".join(e["text"] for e in st.snapshot()["events"])
        assert "failed" in texts and "open again" in texts
    finally:
        sender.shutdown()
        src.stop()


def test_a_silent_bus_is_shown() -> None:
    cfg = resolve_config("virtual", f"view-{uuid.uuid4().hex[:8]}")
    st = ViewState()
    src = BusSource(cfg, silent_after=0.3)
    src.start(st)
    sender = can.Bus(interface="virtual", channel=cfg.channel)
    try:
        _wait(lambda: src.bus is not None)
        sender.send(can.Message(arbitration_id=0x7AB, data=bytes(8), is_extended_id=False))
        _wait(lambda: st.source["state"] == "silent", 3.0)
        sender.send(can.Message(arbitration_id=0x7AB, data=bytes(8), is_extended_id=False))
        _wait(lambda: st.source["state"] == "running", 3.0)
    finally:
        sender.shutdown()
        src.stop()


def test_node_runner_and_view_share_a_bus() -> None:
    """The C node in-process on a virtual bus, the view reading that bus: the commands reach the node."""
    channel = f"view-{uuid.uuid4().hex[:8]}"
    cfg = resolve_config("virtual", channel)
    node = Node("mars", sample_rate=200.0)
    node_bus = can.Bus(interface="virtual", channel=channel)
    stop = threading.Event()
    NodeRunner(node_bus, node).start(stop)
    st = ViewState()
    src = BusSource(cfg)
    src.start(st)
    feed = can.Bus(interface="virtual", channel=channel)
    try:
        _wait(lambda: src.bus is not None)
        gyr, acc, mag = still(100)
        for m in to_messages(codec.encode_imu(gyr, acc, mag)):
            feed.send(m)
        _wait(lambda: (st.snapshot()["att"] or {}).get("steps") == 100)
        rec, msg = st.command("select", "ekf")
        src.send(msg)
        _wait(lambda: rec.status == "ok")
        assert node.running_kind.label == "ekf"
    finally:
        stop.set()
        src.stop()
        feed.shutdown()
        time.sleep(0.1)
        node_bus.shutdown()
