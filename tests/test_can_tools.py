"""The CAN tools' rough edges: losses the monitor must report, logs of one process, flags by name."""

from __future__ import annotations

import re
import subprocess
import sys
import uuid
from pathlib import Path

import can
import numpy as np
import pytest

from attica.can import codec
from attica.can.bus import from_messages, open_bus, to_messages
from attica.can.logs import LogError, read_log
from attica.can.monitor import BusReader, Monitor
from attica.can.node import Node
from attica.cli import main
from attica.sim import SimConfig, simulate

from helpers import ROOT

RATE = 285.714


def _session(n: int, fd: bool = False) -> list[list[can.Message]]:
    """Per sample: the IMU frames sent and the node's frames in answer, as a bus listener sees them."""
    rec = simulate(SimConfig(duration=n / RATE + 0.5, rate=RATE, seed=7))
    node = Node("mars" if fd else "ars", sample_rate=RATE, fd=fd, data_bitrate=2_000_000 if fd else 0)
    imu = codec.encode_imu(rec.gyr[:n], rec.acc[:n], rec.mag[:n], fd=fd).reshape(n, -1)
    per_sample = []
    t = 1_700_000_000.0
    for k in range(n):
        out, _ = node.run(imu[k])
        msgs = to_messages(np.concatenate([imu[k], out]), channel="can0")
        for m in msgs:
            t += 1e-4
            m.timestamp = t
        per_sample.append(msgs)
    return per_sample


def _summary(msgs: list[can.Message]) -> tuple[Monitor, str]:
    mon = Monitor()
    for m in msgs:
        mon.feed(m)
    return mon, "\n".join(mon.summary())


@pytest.mark.parametrize("lost", [39, 32])
def test_monitor_reports_lost_samples_beyond_the_alive_counter(lost: int) -> None:
    session = _session(300)
    whole, text = _summary([m for s in session for m in s])
    assert whole.stats.samples_behind <= 0 and whole.stats.missing_sets == 0 and not whole.lost_anything
    assert "0 output sets missing" in text and "LOST" not in text
    # every frame of `lost` samples gone in a burst (a socket buffer overflowing): the 4-bit counters see
    # lost % 16 of them per ID (none for 32), the node's step counter all of them: the sets missing
    # exactly, the samples beyond those the IMU counters show
    kept = [m for k, s in enumerate(session) if not 100 <= k < 100 + lost for m in s]
    mon, text = _summary(kept)
    assert mon.stats.missing_frames == 6 * (lost % 16)  # 3 IMU and 3 output IDs carry counters
    assert mon.stats.missing_sets == lost
    beyond = lost - lost % 16
    assert mon.stats.samples_behind == beyond
    assert f"{lost} output sets missing by the node's step counter" in text
    assert f"at least {beyond} IMU sample periods the node stepped over are not in this view" in text
    assert mon.lost_anything


@pytest.mark.parametrize("fd", [False, True])
def test_monitor_lost_inputs_integrated_by_the_node_are_no_lost_outputs(fd: bool) -> None:
    """Samples lost before the node (and the monitor): the node integrates them, sends no set for them."""
    n = 300
    rec = simulate(SimConfig(duration=n / RATE + 0.5, rate=RATE, seed=7))
    node = Node("mars" if fd else "ars", sample_rate=RATE, fd=fd, data_bitrate=2_000_000 if fd else 0)
    imu = codec.encode_imu(rec.gyr[:n], rec.acc[:n], rec.mag[:n], fd=fd).reshape(n, -1)
    lost = {40, 41, 42, *range(100, 120), *range(200, 215)}  # runs of 3, 20 and 15
    msgs = []
    for k in range(n):
        if k in lost:
            continue
        out, _ = node.run(imu[k])
        msgs += to_messages(np.concatenate([imu[k], out]), channel="can0")
    mon, text = _summary(msgs)
    assert node.stats()["sets"] == mon.stats.sets == n - len(lost) - 1  # 215: a duplicate of 199
    assert mon.stats.missing_sets == 0 and mon.stats.samples_behind <= 0
    assert "0 output sets missing" in text and "LOST" not in text


def test_monitor_reports_inputs_missing_at_the_end() -> None:
    """The end of a fast replay: the node's answers seen, the last 39 samples' IMU frames not."""
    session = _session(200)
    msgs = []
    for k, s in enumerate(session):
        msgs += [m for m in s if not (k >= 161 and m.arbitration_id in (0x100, 0x101, 0x102))]
    mon, text = _summary(msgs)
    assert mon.stats.counter_gaps == 0  # nothing for the alive counters to see
    assert mon.stats.samples_behind == 39
    assert "at least 39 IMU sample periods" in text


def test_monitor_names_flags_and_claims_fd_only_for_fd() -> None:
    classic = [m for s in _session(20) for m in s]
    mon = Monitor()
    lines = [mon.feed(m) for m in classic]
    status = [ln for ln in lines if " ATT_STATUS " in ln]
    assert "flags=INITIALISED " in status[0] and not re.search(r"flags=\d", "\n".join(lines))
    assert "CAN FD" not in "\n".join(mon.summary())
    fd = [m for s in _session(20, fd=True) for m in s]
    mon = Monitor()
    lines = [mon.feed(m) for m in fd]
    assert any("ATT_OUT_FD" in ln and "flags=INITIALISED" in ln for ln in lines)
    assert "CAN FD data phase 2 Mbit/s" in mon.summary()[0]


def test_bus_reader_keeps_a_burst_and_drains_at_stop() -> None:
    ch = "t" + uuid.uuid4().hex[:12]
    tx = open_bus("virtual", ch)
    rx = open_bus("virtual", ch)
    try:
        reader = BusReader(rx)
        frames = [m for s in _session(400) for m in s]
        for m in frames:
            tx.send(m)
        got = []
        while len(got) < 100:
            m = reader.get(1.0)
            assert m is not None
            got.append(m)
        got += reader.stop()  # everything received before the stop, none lost
        assert len(got) == len(frames) and reader.dropped == 0
        assert [bytes(m.data) for m in got] == [bytes(m.data) for m in frames]
    finally:
        tx.shutdown()
        rx.shutdown()


def test_log_reader_errors_name_the_line(tmp_path: Path) -> None:
    good = "(1.000000) can0 100#0011223344556677\n"
    cases = {
        "x\n": "expected '(timestamp) channel ID#DATA'",
        "(2.0) can0 1FFF#00\n": None,  # 4 hex digits: an extended ID, valid
        "(2.0) can0 800#00\n": "standard ID 800 is above 7FF",
        "(2.0) can0 100#001122334455667788\n": "9 data bytes is too long for a classic frame",
        "(2.0) can0 110##1" + "00" * 9 + "\n": "9 bytes is not a valid CAN FD length",
        "(2.0) can0 100#0G\n": "bad log line",
        # python-can's reader takes these; candump never writes them (found by tests/fuzz/fuzz_host.py)
        "(2.0) can0 100#001122334455667\n": "two hex digits per data byte",  # 7.5 bytes
        "2000 can0 100#00\n": "not in the candump -L format",  # no parentheses
        "(2.0) can0 100#+1+1\n": "not in the candump -L format",
        "(2.0) can0 100##500\n": None,  # CAN FD, flags FDF|BRS, one byte
        "(2.0) can0 100#R\n": None,  # remote frame
        "(2.0) can0 100#0011 T\n": None,  # transmitted
    }
    for line, message in cases.items():
        path = tmp_path / "x.log"
        path.write_text("# a comment\n" + good + line)
        if message is None:
            assert len(list(read_log(path))) == 2
            continue
        with pytest.raises(LogError, match=re.escape(message)) as exc:
            list(read_log(path))
        assert f"{path}:3: bad log line" in str(exc.value)


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    env = {"PYTHONPATH": str(ROOT / "host")}
    import os

    return subprocess.run(
        [sys.executable, "-m", "attica.cli", *args], capture_output=True, text=True, env={**os.environ, **env}
    )


@pytest.mark.parametrize("fd", [False, True])
def test_verify_with_node_writes_a_log_that_verifies(tmp_path: Path, fd: bool) -> None:
    log = tmp_path / "bus.log"
    asc = tmp_path / "bus.asc"
    kind = "mars" if fd else "ars"
    extra = ["--fd"] if fd else []
    assert (
        main(
            [
                "verify",
                "--with-node",
                "--filter",
                kind,
                "--duration",
                "4",
                "-q",
                "-w",
                str(log),
                "-w",
                str(asc),
                *extra,
            ]
        )
        == 0
    )
    text = log.read_text().splitlines()
    assert any(ln.endswith(" T") for ln in text) and any(ln.endswith(" R") for ln in text)  # both directions
    assert main(["verify", "--log", str(log), "--filter", kind]) == 0
    mon = _cli("monitor", "--log", str(log), "--summary-only")
    assert mon.returncode == 0
    assert (
        "counter gaps 0" in mon.stdout and "0 output sets missing" in mon.stdout and "LOST" not in mon.stdout
    )
    assert ("CAN FD" in mon.stdout) == fd
    n_imu = sum(1 for m in read_log(log) if m.arbitration_id in (0x100, 0x110))
    assert n_imu == round(4 * RATE)
    assert len(list(read_log(asc))) == len(text)


def test_replay_writes_both_directions(tmp_path: Path) -> None:
    from attica.can.runner import NodeRunner

    ch = "t" + uuid.uuid4().hex[:12]
    bus = open_bus("virtual", ch)
    runner = NodeRunner(bus, Node("ars", sample_rate=RATE))
    import threading

    stop = threading.Event()
    thread = runner.start(stop)
    log = tmp_path / "replay.log"
    try:
        code = main(["replay", "-i", "virtual", "-c", ch, "--duration", "3", "-q", "-w", str(log)])
    finally:
        stop.set()
        thread.join(5)
        bus.shutdown()
    assert code == 0
    frames = from_messages(list(read_log(log)))
    ids = frames["id"]
    assert int((ids == codec.ID_IMU_GYRO).sum()) == round(3 * RATE)
    assert int((ids == codec.ID_STATUS).sum()) == round(3 * RATE)  # the node's answers, to the last one
    mon = Monitor()
    for m in read_log(log):
        mon.account(m)
    assert not mon.lost_anything and mon.stats.last_step == round(3 * RATE)


def test_candump_io_is_python_cans(tmp_path: Path) -> None:
    """.log files are written by python-can's CanutilsLogWriter and read by its CanutilsLogReader."""
    from attica.can import logs

    w = logs.open_writer(tmp_path / "x.log")
    try:
        assert isinstance(w, can.CanutilsLogWriter)
        w.on_message_received(
            can.Message(
                timestamp=1.5, arbitration_id=0x100, is_extended_id=False, data=b"\x01\x02", channel="can0"
            )
        )
    finally:
        w.stop()
    assert (tmp_path / "x.log").read_text().split() == ["(1.500000)", "can0", "100#0102", "R"]
    assert logs.CanutilsLogReader is can.CanutilsLogReader
    (m,) = read_log(tmp_path / "x.log")
    assert (m.arbitration_id, bytes(m.data), m.is_rx) == (0x100, b"\x01\x02", True)


def test_log_reader_fd_flags_come_from_the_frame_field(tmp_path: Path) -> None:
    # Found by the candump fuzzer (tests/fuzz/fuzz_host.py): a "##" inside the channel name made the
    # flags digit be read from the wrong field (a ValueError escaped read_log). The flags digit is the
    # one after the frame field's "##", where python-can reads it.
    path = tmp_path / "x.log"
    path.write_bytes(b"(1.5) vc\x00\x00na\x00\x0000## 110##6AA\n(2.0) can0 110##5AA\n")
    frames = list(read_log(path))
    assert [f.arbitration_id for f in frames] == [0x110, 0x110]
    assert all(f.is_fd and bytes(f.data) == b"\xaa" for f in frames)
    assert getattr(frames[0], "fd_flags", None) == 6 and getattr(frames[1], "fd_flags", None) == 5
