"""The node's CAN ID offset on the host side: --id-offset on every CAN tool, offset logs, wrong offsets.

The node (C) moves its IDs itself (``Node(id_offset=N)``); the host tools move theirs at the edge
(:mod:`attica.can.idoffset`): two independent implementations that must meet bit for bit. The moved DBC
itself (``attica dbc``): test_can_dbc.py; here cantools decodes an offset log with it.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import can
import numpy as np
import pytest

from attica import resources
from attica.calibration import Calibration, InertialModel
from attica.can import codec
from attica.can.bus import open_bus, to_messages
from attica.can.calibration import NodeSilentError, send_calibration
from attica.can.idoffset import (
    ID_OFFSET_MAX,
    ID_OFFSET_MIN,
    IdOffsetError,
    OffsetBus,
    from_bus,
    from_bus_id,
    guess_id_offset,
    parse_id_offset,
    to_bus,
    to_bus_id,
)
from attica.can.logs import open_writer, read_log
from attica.can.monitor import Monitor, MonitorError, decoded_fields, same_value
from attica.can.replay import ImuStream
from attica.can.runner import NodeRunner
from attica.can.verify import NodeNotAnsweringError, reset_node, verify_live
from attica.cli import main
from attica.native import lib
from attica.settings import FilterKind
from attica.sim import SimConfig, simulate

from helpers import ROOT, cantools_decode

RATE = 285.714
OFFSET = 0x20
ENV = {**os.environ, "PYTHONPATH": str(ROOT / "host") + os.pathsep + os.environ.get("PYTHONPATH", "")}


def _channel() -> str:
    return "t" + uuid.uuid4().hex[:12]


def _stream(n: int, seed: int = 3) -> ImuStream:
    return ImuStream.from_recording(simulate(SimConfig(duration=n / RATE + 0.5, rate=RATE, seed=seed)), n)


class ThreadNode:
    """A C node with an ID offset on a virtual bus channel, served by a NodeRunner thread."""

    def __init__(self, channel: str, id_offset: int, kind: str = "ars") -> None:
        self.node = codec.Node(kind, sample_rate=RATE, id_offset=id_offset)
        self.bus = open_bus("virtual", channel)
        self.stop = threading.Event()
        self.thread = NodeRunner(self.bus, self.node).start(self.stop)

    def close(self) -> None:
        self.stop.set()
        self.thread.join(5)
        self.bus.shutdown()


# --- the offset itself ----------------------------------------------------------------------------


def test_id_offset_range_and_parsing() -> None:
    assert (ID_OFFSET_MIN, ID_OFFSET_MAX) == (lib.ATT_NODE_ID_OFFSET_MIN, lib.ATT_NODE_ID_OFFSET_MAX)
    assert min(codec.MSG_LEN) + ID_OFFSET_MIN == 0 and max(codec.MSG_LEN) + ID_OFFSET_MAX == 0x7FF
    for text, value in (
        ("32", 32),
        ("0x20", 32),
        ("-0x100", -256),
        ("1279", 1279),
        ("0x4FF", 1279),
        ("0", 0),
    ):
        assert parse_id_offset(text) == value
    for text in ("1280", "-257", "0x500", "abc", "0x", "1.5", ""):
        with pytest.raises(IdOffsetError, match=r"-256|out of range") as exc:
            parse_id_offset(text)
        assert "1279" in str(exc.value)


@pytest.mark.parametrize(
    "argv",
    [
        ["verify", "--count", "5"],
        ["verify", "--log", "x.log"],
        ["monitor", "--log", "x.log"],
        ["replay", "--count", "5"],
        ["node"],
        ["calibrate", "send", "cal.json"],
        ["dbc"],
    ],
)
@pytest.mark.parametrize("bad", ["--id-offset=0x500", "--id-offset=-257", "--id-offset=twenty"])
def test_every_can_command_refuses_a_bad_offset(
    argv: list[str], bad: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exc:
        main([*argv, bad])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"attica: error: {argv[0]}: argument --id-offset: " in err
    assert "-256 to 1279" in err and ("out of range" in err or "decimal or 0x hex" in err)


def test_the_mapping_is_one_to_one_and_only_attica_ids_come_from_their_moved_ids() -> None:
    for offset in (OFFSET, -0x100, 0x4FF, -0x20):
        back = [from_bus_id(i, offset) for i in range(0x800)]
        assert sorted(back) == list(range(0x800))  # a permutation of the 11-bit IDs
        assert all(to_bus_id(from_bus_id(i, offset), offset) == i for i in range(0x800))
        attica = {i for i in range(0x800) if from_bus_id(i, offset) in codec.MSG_LEN}
        assert attica == {i + offset for i in codec.MSG_LEN}
    # the offset of attica frames by their E2E CRC; none in random traffic
    s = _stream(3)
    moved = [to_bus(m, -0x20) for m in to_messages(codec.encode_imu(s.gyr, s.acc, s.mag))]
    assert guess_id_offset(moved) == -0x20 and guess_id_offset(moved[:1]) is None
    rng = np.random.default_rng(5)
    noise = [
        can.Message(
            arbitration_id=int(i), is_extended_id=False, data=bytes(rng.integers(0, 256, 8, np.uint8))
        )
        for i in rng.integers(0, 0x800, 500)
    ]
    assert guess_id_offset(noise) is None and guess_id_offset(noise + moved) == -0x20
    ext = can.Message(arbitration_id=0x225, is_extended_id=True, data=b"\x00")
    assert from_bus(ext, OFFSET) is ext and to_bus(ext, OFFSET) is ext  # not attica's kind of frame
    std = can.Message(arbitration_id=0x225, is_extended_id=False, data=b"\x01\x02")
    moved = from_bus(std, OFFSET)
    assert (moved.arbitration_id, bytes(moved.data), std.arbitration_id) == (0x205, b"\x01\x02", 0x225)


def test_offset_bus_moves_frames_both_ways() -> None:
    ch = _channel()
    raw = open_bus("virtual", ch)
    host = open_bus("virtual", ch, id_offset=OFFSET)
    try:
        assert isinstance(host, OffsetBus) and host.id_offset == OFFSET
        frames = codec.encode_imu(np.ones((2, 3)), np.ones((2, 3)), None)
        for m in to_messages(frames):
            host.send(m)
        got = [raw.recv(1.0) for _ in range(6)]
        assert [m.arbitration_id for m in got if m is not None] == [i + OFFSET for i in frames["id"].tolist()]
        assert [bytes(m.data) for m in got if m is not None] == [bytes(f["data"][:8]) for f in frames]
        # from the bus: an attica ID moves back; a frame at an attica DBC ID (another node's, offset 0)
        # and one below the offset are not attica frames at this offset
        for bus_id, want in ((0x225, codec.ID_STATUS), (0x205, 0x1E5), (0x010, 0x7F0)):
            raw.send(can.Message(arbitration_id=bus_id, is_extended_id=False, data=b"\x00" * 8))
            msg = host.recv(1.0)
            assert msg is not None and msg.arbitration_id == want
        assert 0x1E5 not in codec.MSG_LEN and 0x7F0 not in codec.MSG_LEN
    finally:
        host.shutdown()
        raw.shutdown()


# --- verify over the virtual bus ------------------------------------------------------------------


@pytest.mark.parametrize("fd", [False, True])
def test_verify_against_a_node_with_an_offset_is_bit_exact(fd: bool) -> None:
    """The host's offset (Python, at the bus) meets the node's (C, in att_node.c) bit for bit."""
    n = 600
    ch = _channel()
    kind = "mars" if fd else "ars"
    node = codec.Node(kind, sample_rate=RATE, fd=fd, data_bitrate=2_000_000 if fd else 0, id_offset=OFFSET)
    node_bus = open_bus("virtual", ch, fd=fd)  # as it is: the node moves its IDs itself
    seen: list[can.Message] = []
    tap = open_bus("virtual", ch, fd=fd)
    host = open_bus("virtual", ch, fd=fd, id_offset=OFFSET)
    try:
        rep = verify_live(
            host, _stream(n), FilterKind.parse(kind), fd=fd, service=NodeRunner(node_bus, node).service
        )
        msg = tap.recv(0.0)
        while msg is not None:
            seen.append(msg)
            msg = tap.recv(0.0)
    finally:
        host.shutdown()
        tap.shutdown()
        node_bus.shutdown()
    assert rep.ok and rep.exact and rep.sets_ok == n, "\n".join(rep.lines())
    assert node.stats()["unknown_ids"] == 0 and node.stats()["steps"] == n
    ids = {m.arbitration_id for m in seen}
    assert ids and all(i - OFFSET in codec.MSG_LEN for i in ids)  # on the bus: every frame moved


def test_verify_cli_with_node_and_offset_writes_a_log_of_the_bus(tmp_path: Path) -> None:
    log = tmp_path / "bus.log"
    argv = ["verify", "--with-node", "--id-offset", "0x20", "--duration", "2", "-q", "-w", str(log)]
    assert main(argv) == 0
    ids = {m.arbitration_id for m in read_log(log)}
    assert {0x120, 0x121, 0x122, 0x320, 0x220, 0x225} <= ids and not ids & set(codec.MSG_LEN)
    assert main(["verify", "--log", str(log), "--id-offset", "32"]) == 0


@pytest.mark.parametrize(("node_offset", "host_offset"), [(OFFSET, 0), (0, OFFSET)])
def test_a_wrong_offset_fails_verify_quickly_and_says_so(
    node_offset: int, host_offset: int, capsys: pytest.CaptureFixture[str]
) -> None:
    ch = _channel()
    node = ThreadNode(ch, node_offset)
    try:
        for extra in ([], ["--no-reset"]):
            t0 = time.perf_counter()
            code = main(
                [
                    "verify",
                    "-c",
                    ch,
                    "-i",
                    "virtual",
                    f"--id-offset={host_offset}",
                    "--count",
                    "40",
                    "-q",
                    *extra,
                ]
            )
            elapsed = time.perf_counter() - t0
            err = capsys.readouterr().err
            assert code == 2 and elapsed < 10.0, (extra, elapsed)
            assert "no attica output came back at ID offset" in err and "pass the same --id-offset N" in err
            assert ("no node answered a reset command within 2 s" in err) == (not extra), err
        # the calibration sender says the same
        bus = open_bus("virtual", ch, id_offset=host_offset)
        try:
            with pytest.raises(NodeSilentError, match="no attica output came back.*--id-offset"):
                send_calibration(bus, Calibration(), timeout=0.3)
        finally:
            bus.shutdown()
    finally:
        node.close()
    assert node.node.stats()["steps"] == 0 and node.node.stats()["unknown_ids"] > 0


def test_a_reset_timeout_names_the_offset_of_the_frames_seen() -> None:
    """Attica frames at another offset on the bus (a replay at 0x20, no node at 0): the hint names 0x20."""
    ch = _channel()
    other = open_bus("virtual", ch, id_offset=OFFSET)
    host = open_bus("virtual", ch)
    s = _stream(20)
    frames = to_messages(codec.encode_imu(s.gyr, s.acc, s.mag))

    def chatter() -> None:
        while frames:
            other.send(frames.pop(0))

    try:
        with pytest.raises(
            NodeNotAnsweringError, match=r"at ID offset \+0x20 \(32\) by their E2E CRC: pass --id-offset 0x20"
        ):
            reset_node(host, timeout=0.5, service=chatter)
    finally:
        other.shutdown()
        host.shutdown()


# --- node, replay, calibrate send, monitor --------------------------------------------------------


def test_node_and_replay_commands_with_an_offset(tmp_path: Path) -> None:
    ch = _channel()
    n = 300
    result: list[int] = []
    node = threading.Thread(
        target=lambda: result.append(
            main(
                [
                    "node",
                    "-i",
                    "virtual",
                    "-c",
                    ch,
                    "--id-offset",
                    "0x20",
                    "--count",
                    str(n),
                    "--idle-timeout",
                    "10",
                    "-q",
                ]
            )
        )
    )
    node.start()
    time.sleep(0.3)
    log = tmp_path / "replay.log"
    try:
        assert (
            main(
                [
                    "replay",
                    "-i",
                    "virtual",
                    "-c",
                    ch,
                    "--id-offset",
                    "0x20",
                    "--count",
                    str(n),
                    "-q",
                    "-w",
                    str(log),
                ]
            )
            == 0
        )
    finally:
        node.join(20)
    assert result == [0]
    msgs = list(read_log(log))
    assert (
        sum(m.arbitration_id == 0x120 for m in msgs) == n
        and sum(m.arbitration_id == 0x225 for m in msgs) == n
    )
    mon = Monitor(id_offset=OFFSET)
    for m in msgs:
        mon.account(m)
    assert mon.stats.unknown_ids == 0 and mon.stats.last_step == n and not mon.lost_anything


def test_calibrate_send_with_an_offset(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cal = tmp_path / "cal.json"
    Calibration(gyro=InertialModel(offset=(0.01, -0.02, 0.005))).save(cal)
    argv = ["calibrate", "send", str(cal), "-c", _channel(), "--with-node", "--id-offset", "0x20"]
    assert main([*argv, "--verify", "--count", "200", "-q"]) == 0
    out = capsys.readouterr().out
    assert "CAL_COMMIT: acknowledged" in out and "verdict: BIT-EXACT" in out and "ID offset +0x20" in out
    assert main(["calibrate", "gyro", str(cal), "--id-offset", "0x20"]) == 2
    assert "--id-offset: options of 'calibrate send'" in capsys.readouterr().err


@pytest.fixture(scope="module")
def offset_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A candump -L log of a node with ID offset 0x20 (classic, 120 samples, then 40 FD samples)."""
    path = tmp_path_factory.mktemp("offset") / "bus.log"
    writer = open_writer(path, channel="vcan0")
    t = 1_700_000_000.0
    s = _stream(160)
    try:
        for fd, sl in ((False, slice(0, 120)), (True, slice(120, 160))):
            node = codec.Node(
                "mars", sample_rate=RATE, fd=fd, data_bitrate=2_000_000 if fd else 0, id_offset=OFFSET
            )
            imu = codec.encode_imu(s.gyr[sl], s.acc[sl], s.mag[sl], fd=fd)
            imu["id"] += OFFSET  # as the host sends them (to_bus)
            per = 1 if fd else 3
            for k in range(imu.shape[0] // per):
                out, _ = node.run(imu[k * per : (k + 1) * per])
                for m in to_messages(np.concatenate([imu[k * per : (k + 1) * per], out]), channel="vcan0"):
                    t += 1e-4
                    m.timestamp = t
                    writer.on_message_received(m)
    finally:
        writer.stop()
    return path


def _monitor(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "attica.cli", "monitor", *args],
        capture_output=True,
        text=True,
        env=ENV,
        check=True,
    )


def test_monitor_an_offset_log(offset_log: Path, tmp_path: Path) -> None:
    n = len(list(read_log(offset_log)))
    mon = _monitor("--log", str(offset_log), "--id-offset", "0x20")
    lines = mon.stdout.splitlines()
    assert len(lines) == n
    for line in lines:  # every frame decoded, at its bus ID, and no problem
        head, name, values = decoded_fields(line)
        assert name in {m.name for m in codec.database().messages} and values, line
        assert int(head.split()[2].partition("#")[0], 16) - OFFSET in codec.MSG_LEN
        assert "!" not in line and "?" not in line, line
    assert "unknown ids 0" in mon.stderr and "0 output sets missing" in mon.stderr
    assert "attica ID offset +0x20 (32)" in mon.stderr
    # without the offset: every frame of unknown ID, and the summary names the offset
    bare = _monitor("--log", str(offset_log))
    assert all(ln.endswith("!UNKNOWN") and decoded_fields(ln)[1] == "" for ln in bare.stdout.splitlines())
    assert f"unknown ids {n}" in bare.stderr
    assert "attica frames at ID offset +0x20 (32) by their E2E CRC: try --id-offset 0x20" in bare.stderr
    # the moved DBC (read at its own offset) decodes exactly as attica.dbc at the node's offset
    dbc = tmp_path / "moved.dbc"
    assert main(["dbc", "--id-offset", "0x20", "-o", str(dbc)]) == 0
    moved = _monitor("--log", str(offset_log), "--id-offset", "0x20", "--dbc", str(dbc))
    assert moved.stdout == mon.stdout
    assert "moved.dbc is written for ID offset +0x20 (32)" in moved.stderr
    with pytest.raises(MonitorError, match="out of range"):
        Monitor(id_offset=0x500)


def test_cantools_decodes_an_offset_log_with_the_moved_dbc(offset_log: Path, tmp_path: Path) -> None:
    dbc = tmp_path / "moved.dbc"
    assert main(["dbc", "--id-offset", "0x20", "-o", str(dbc)]) == 0
    ref = cantools_decode(offset_log, dbc)
    ours = _monitor("--log", str(offset_log), "--id-offset", "0x20").stdout.splitlines()
    assert len(ref) == len(ours) > 0
    for line, theirs in zip(ours, ref):
        head, name, values = decoded_fields(line)
        t_head, _, t_body = theirs.partition(" :: ")
        assert head == t_head.removesuffix(" R").removesuffix(" T")
        mt = re.match(r"^(\w+)\((.*)\)$", t_body)
        assert mt is not None and mt.group(1) == name, (line, theirs)
        t_values = dict(item.partition(": ")[::2] for item in mt.group(2).split(", "))
        assert t_values.keys() == values.keys()
        assert all(same_value(values[k], t_values[k].split(" ")[0]) for k in values), (line, theirs)
    # the original DBC knows none of these IDs
    plain = cantools_decode(offset_log, resources.dbc_path())
    assert not any(re.search(r" :: \w+\(", ln) for ln in plain)
