"""CAN tools end to end on real python-can buses: the virtual bus in-process, udp_multicast across processes.

- >= 1e5 steps replay -> node -> verify over the virtual bus, every output bit-exact, nothing lost;
- the node in another process (``attica node``) over udp_multicast on loopback;
- fault injection between host and node (drop, duplicate, reorder, bit flips, wrong DLC, unknown IDs
  on the way in; drops, flips, duplicates on the way out): every fault detected and counted, no crash,
  no silent loss;
- the monitor: candump -L / .asc / .blf logs round-trip, and ``cantools decode`` agrees with it.
"""

from __future__ import annotations

import os
import random
import re
import signal
import subprocess
import sys
import threading
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

import can
import numpy as np
import pytest

from attica.can import codec
from attica.can.bus import open_bus
from attica.can.monitor import Monitor, candump_text, decoded_fields, open_writer, read_log, same_value
from attica.can.replay import ImuStream, replay
from attica.can.runner import NodeRunner
from attica.can.verify import INPUT_FAULTS, assemble, frames_of, verify_frames, verify_live
from attica.settings import FilterKind
from attica.sim import SimConfig, simulate

from helpers import ROOT, cantools_decode, need

RATE = 285.714
ENV = {**os.environ, "PYTHONPATH": str(ROOT / "host") + os.pathsep + os.environ.get("PYTHONPATH", "")}


def _stream(n: int, seed: int = 0, taps: int = 0) -> ImuStream:
    rec = simulate(SimConfig(duration=n / RATE + 0.5, rate=RATE, seed=seed, taps=taps))
    return ImuStream.from_recording(rec, n)


def _channel() -> str:
    return "t" + uuid.uuid4().hex[:12]


class InProcessNode:
    """The C node on a virtual bus channel, served by a NodeRunner thread."""

    def __init__(self, channel: str, kind: str = "ars", fd: bool = False, **kw: object) -> None:
        self.node = codec.Node(kind, sample_rate=RATE, fd=fd, data_bitrate=2_000_000 if fd else 0, **kw)  # type: ignore[arg-type]
        self.bus = open_bus("virtual", channel, fd=fd)
        self.runner = NodeRunner(self.bus, self.node)
        self.stop = threading.Event()
        self.thread = self.runner.start(self.stop)

    def close(self) -> None:
        self.stop.set()
        self.thread.join(5)
        assert not self.thread.is_alive()
        self.bus.shutdown()


# --- in-process, >= 1e5 steps -------------------------------------------------------------------


def test_virtual_bus_1e5_steps_bit_exact() -> None:
    """The node on the test's thread (NodeRunner.service), sharing a virtual bus channel with the host."""
    n = 100_000
    stream = _stream(n, seed=11, taps=20)
    ch = _channel()
    node = codec.Node("ars", sample_rate=RATE)
    node_bus = open_bus("virtual", ch)
    runner = NodeRunner(node_bus, node)
    host = open_bus("virtual", ch)
    try:
        t0 = time.perf_counter()
        rep = verify_live(host, stream, FilterKind.ARS, window=32, service=runner.service)
        elapsed = time.perf_counter() - t0
    finally:
        host.shutdown()
        node_bus.shutdown()
    print("\n".join(rep.lines()))
    print(f"virtual bus, in-process: {rep.frames_sent + rep.frames_received} frames in {elapsed:.1f} s")
    assert rep.reference_ok, rep.reference_detail
    assert rep.samples_sent == n and rep.samples_stepped == n and rep.steps_expected == n
    assert rep.sets_expected == n
    assert rep.sets_ok == n, rep.first_mismatch
    assert (rep.mismatched, rep.missing, rep.corrupted, rep.duplicates, rep.unexpected) == (0, 0, 0, 0, 0)
    assert rep.skipped == []
    assert rep.exact and rep.ok
    stats = node.stats()
    assert stats["steps"] == n and stats["sets"] == n
    assert all(stats[k] == 0 for k in (*INPUT_FAULTS, "rx_overflows", "tx_overflows"))
    assert rep.node_diag == dict.fromkeys(INPUT_FAULTS, 0)


@pytest.mark.parametrize("kind", ["mars", "kf"])
def test_virtual_bus_fd_and_divider(kind: str) -> None:
    n = 4000
    stream = _stream(n, seed=3)
    for fd, divider in ((True, 1), (False, 3)):
        ch = _channel()
        node = codec.Node(
            kind, sample_rate=RATE, fd=fd, data_bitrate=2_000_000 if fd else 0, output_divider=divider
        )
        node_bus = open_bus("virtual", ch, fd=fd)
        runner = NodeRunner(node_bus, node)
        host = open_bus("virtual", ch, fd=fd)
        try:
            rep = verify_live(
                host, stream, FilterKind.parse(kind), fd=fd, output_divider=divider, service=runner.service
            )
        finally:
            host.shutdown()
            node_bus.shutdown()
        print("\n".join(rep.lines()))
        assert rep.exact and rep.ok, rep.first_mismatch
        assert rep.sets_ok == n // divider


# --- across processes over udp_multicast ----------------------------------------------------------


def _multicast_works(config: Path) -> str:
    """'' when two udp_multicast buses on loopback see each other's frames, else why not."""
    try:
        a = open_bus(config_file=config)
        b = open_bus(config_file=config)
    except Exception as exc:  # noqa: BLE001 - any reason means "not available"
        return f"cannot open udp_multicast: {exc}"
    try:
        a.send(can.Message(arbitration_id=0x7FF, is_extended_id=False, data=b"ping"))
        got = b.recv(2.0)
        return "" if got is not None and bytes(got.data) == b"ping" else "no multicast loopback delivery"
    finally:
        a.shutdown()
        b.shutdown()


@pytest.fixture
def udp_config(tmp_path: Path) -> Path:
    """A python-can config file for a private udp_multicast group and port (exercises --can-config)."""
    port = 40000 + os.getpid() % 20000
    cfg = tmp_path / "can.ini"
    group = f"239.74.163.{os.getpid() % 200 + 20}"
    cfg.write_text(f"[default]\ninterface = udp_multicast\nchannel = {group}\nport = {port}\n")
    why = _multicast_works(cfg)
    if why:
        # loopback may lack the MULTICAST flag: try to set it (root), then retry
        subprocess.run(["ip", "link", "set", "lo", "multicast", "on"], capture_output=True)
        why = _multicast_works(cfg)
    need(
        not why, f"udp multicast on loopback does not work here ({why}; tried 'ip link set lo multicast on')"
    )
    return cfg


def test_udp_multicast_node_in_other_process(udp_config: Path) -> None:
    n = 4000
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "attica.cli",
            "node",
            "--can-config",
            str(udp_config),
            "--filter",
            "ars",
            "--rate",
            str(RATE),
        ],
        env=ENV,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        assert proc.stdout is not None
        ready = proc.stdout.readline()
        assert "ready" in ready, ready
        bus = open_bus(config_file=udp_config)
        try:
            rep = verify_live(bus, _stream(n, seed=5), FilterKind.ARS)
        finally:
            bus.shutdown()
        print("\n".join(rep.lines()))
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    print(out)
    assert proc.returncode == 0
    assert "attica node: stats: steps=" in out
    assert rep.reference_ok
    # UDP may drop datagrams under load; whatever happens must be visible, never silent
    assert rep.mismatched == 0 and rep.unexpected == 0, rep.first_mismatch
    assert rep.sets_ok + rep.missing == rep.sets_expected
    assert rep.samples_lost == len(rep.skipped)
    if rep.skipped or rep.missing:
        print(
            f"udp_multicast lost frames: {len(rep.skipped)} samples, {rep.missing} output sets (all counted)"
        )
    assert rep.sets_ok >= 0.99 * n


# --- fault injection ------------------------------------------------------------------------------


@dataclass
class Expect:
    """What the injected faults must produce."""

    counters: dict[str, int] = field(default_factory=lambda: dict.fromkeys(INPUT_FAULTS, 0))
    lost_samples: list[int] = field(default_factory=list)
    corrupted_sets: int = 0
    duplicate_sets: int = 0
    damaged_steps: list[int] = field(default_factory=list)


def _flip(msg: can.Message, rng: random.Random) -> can.Message:
    data = bytearray(msg.data)
    bit = rng.randrange(8 * len(data))
    data[bit // 8] ^= 1 << (bit % 8)
    return _copy(msg, data=bytes(data))


def _copy(msg: can.Message, **kw: object) -> can.Message:
    args: dict[str, object] = {
        "arbitration_id": msg.arbitration_id,
        "data": bytes(msg.data),
        "is_extended_id": False,
        "is_fd": msg.is_fd,
        "bitrate_switch": msg.bitrate_switch,
        "check": False,
    }
    args.update(kw)
    return can.Message(**args)  # type: ignore[arg-type]


class Injector:
    """Bridges a host channel and a node channel of the virtual bus, damaging frames by a schedule.

    Input schedule: sample index -> fault; output schedule: output set index -> fault. Frames are
    forwarded a whole sample / set at a time (a sample is released when the next one starts or the
    host goes quiet), so faults can reorder across samples.
    """

    IN_FAULTS = (
        "drop1",
        "drop_all",
        "dup",
        "dup_done",
        "swap",
        "swap_next",
        "flip",
        "dlc_short",
        "dlc_fd",
        "unknown",
    )
    OUT_FAULTS = ("drop", "flip", "flip_quat", "dup_set", "drop_status")

    def __init__(self, host_ch: str, node_ch: str, n: int, seed: int = 7) -> None:
        self.rng = random.Random(seed)
        self.host_in = open_bus("virtual", host_ch)
        self.node_in = open_bus("virtual", node_ch)
        self.expect = Expect()
        self.in_plan: dict[int, str] = {}
        self.out_plan: dict[int, str] = {}
        k = 40
        i = 0
        while k < n // 2 - 40:  # input faults in the first half, 9 samples apart
            self.in_plan[k] = self.IN_FAULTS[i % len(self.IN_FAULTS)]
            k += 9
            i += 1
        self._plan_inputs()
        j = n // 2 + 100
        i = 0
        while j < n - len(self.expect.lost_samples) - 60:  # output faults in the second half, by set index
            self.out_plan[j] = self.OUT_FAULTS[i % len(self.OUT_FAULTS)]
            j += 13
            i += 1
        self._plan_outputs()
        self.stop = threading.Event()
        self.errors: list[BaseException] = []
        self.threads = [
            threading.Thread(target=self._guard, args=(self._inputs,), daemon=True),
            threading.Thread(target=self._guard, args=(self._outputs,), daemon=True),
        ]
        for t in self.threads:
            t.start()

    def _plan_inputs(self) -> None:
        e = self.expect
        c = e.counters
        for k, f in self.in_plan.items():
            if f in ("drop1", "flip", "dlc_short", "dlc_fd"):
                e.lost_samples.append(k)
                c["stale_partials"] += 1
                c["crc_errors"] += f == "flip"
                c["dlc_errors"] += f in ("dlc_short", "dlc_fd")
            elif f == "drop_all":
                e.lost_samples.append(k)
                c["counter_gaps"] += 1
            elif f in ("dup", "dup_done"):
                c["duplicates"] += 1
            elif f == "unknown":
                c["unknown_ids"] += 1
            elif f == "swap_next":
                # G_k A_k G_k+1 M_k A_k+1 M_k+1 G_k+2: G_k+1 discards k (stale); M_k discards k+1 (stale)
                # and restarts k, which is not k+1's successor (gap); A_k+1 discards it (stale) and
                # restarts k+1, discarded by G_k+2 (stale): samples k and k+1 are lost
                e.lost_samples += [k, k + 1]
                c["stale_partials"] += 4
                c["counter_gaps"] += 1
        e.lost_samples.sort()

    def _plan_outputs(self) -> None:
        e = self.expect
        for j, f in self.out_plan.items():
            # set j is of the (j + lost)-th sample (the losses are all before it); the node integrated
            # every lost sample, so its step count is its sample index + 1
            step = j + len(e.lost_samples) + 1
            if f == "dup_set":
                e.duplicate_sets += 1
            else:
                e.corrupted_sets += 1
                e.damaged_steps.append(step)

    def _guard(self, fn: object) -> None:
        try:
            fn()  # type: ignore[operator]
        except BaseException as exc:  # noqa: BLE001 - reported by the test
            self.errors.append(exc)

    def _send_node(self, msgs: list[can.Message]) -> None:
        for m in msgs:
            self.node_in.send(m)

    def _inputs(self) -> None:
        pending: list[can.Message] = []  # frames of the current sample
        held: list[can.Message] = []  # frames moved into the next sample
        sample = 0
        imu = 0
        while not self.stop.is_set():
            msg = self.host_in.recv(0.02)
            if msg is None:
                if pending:
                    self._send_node(self._damage(sample, pending))
                    sample += 1
                    pending = []
                continue
            if msg.arbitration_id not in (codec.ID_IMU_GYRO, codec.ID_IMU_ACC, codec.ID_IMU_MAG):
                self.node_in.send(msg)  # commands
                continue
            pending.append(msg)
            imu += 1
            if imu % 3 == 0:
                out = self._damage(sample, pending)
                if held:
                    out = out[:1] + held + out[1:]
                    held = []
                if self.in_plan.get(sample) == "swap_next":
                    held = [out.pop()]  # this sample's last frame goes after the next one's first
                self._send_node(out)
                sample += 1
                pending = []

    def _damage(self, k: int, frames: list[can.Message]) -> list[can.Message]:
        f = self.in_plan.get(k)
        out = list(frames)
        r = self.rng
        if f == "drop1":
            out.pop(r.randrange(3))
        elif f == "drop_all":
            out = []
        elif f == "dup":
            i = r.randrange(2)  # a repeat inside the sample
            out.insert(i + 1, _copy(out[i]))
        elif f == "dup_done":
            out.append(_copy(out[-1]))  # a repeat of the sample just completed
        elif f == "swap":
            r.shuffle(out)  # any order within a sample is fine
        elif f == "flip":
            i = r.randrange(3)
            out[i] = _flip(out[i], r)
        elif f == "dlc_short":
            i = r.randrange(3)
            out[i] = _copy(out[i], data=bytes(out[i].data)[:7])
        elif f == "dlc_fd":
            i = r.randrange(3)
            out[i] = _copy(out[i], is_fd=True, bitrate_switch=True)
        elif f == "unknown":
            out.insert(r.randrange(4), can.Message(arbitration_id=0x123, is_extended_id=False, data=bytes(8)))
        return out

    def _outputs(self) -> None:
        pending: list[can.Message] = []
        set_index = 0
        while not self.stop.is_set():
            msg = self.node_in.recv(0.02)
            if msg is None:
                continue
            if msg.arbitration_id not in codec.SET_IDS or (
                msg.arbitration_id == codec.ID_STATUS and msg.data[7] & codec.ACK_ANSWER
            ):
                self.host_in.send(msg)  # DIAG, command answers
                continue
            pending.append(msg)
            if msg.arbitration_id != codec.ID_STATUS:
                continue
            f = self.out_plan.get(set_index)
            r = self.rng
            out = list(pending)
            if f == "drop":
                out.pop(r.randrange(1, 5))
            elif f == "flip":
                i = r.choice([3, 4, 5])
                out[i] = _flip(out[i], r)
            elif f == "flip_quat":
                i = r.choice([0, 1, 2])  # no CRC of their own: the STATUS set CRC must catch it
                out[i] = _flip(out[i], r)
            elif f == "dup_set":
                out = out + [_copy(m) for m in out]
            elif f == "drop_status":
                out.pop()
            for m in out:
                self.host_in.send(m)
            pending = []
            set_index += 1

    def close(self) -> None:
        self.stop.set()
        for t in self.threads:
            t.join(5)
        self.host_in.shutdown()
        self.node_in.shutdown()


def test_fault_injection_every_fault_counted() -> None:
    n = 3000
    host_ch, node_ch = _channel(), _channel()
    node = InProcessNode(node_ch)
    inj = Injector(host_ch, node_ch, n)
    tap = open_bus("virtual", node_ch)  # what the node receives
    host = open_bus("virtual", host_ch)
    stream = _stream(n, seed=9)
    try:
        rep = verify_live(host, stream, FilterKind.ARS, window=8, drain_timeout=0.5)
        time.sleep(0.1)
        seen: list[can.Message] = []
        m = tap.recv(0.0)
        while m is not None:
            seen.append(m)
            m = tap.recv(0.0)
    finally:
        host.shutdown()
        tap.shutdown()
        inj.close()
        node.close()
    print("\n".join(rep.lines()))
    assert not inj.errors, inj.errors
    e = inj.expect
    stats = node.node.stats()
    print("node:", stats)
    print("expected:", e)
    # the node counted every input fault, exactly
    assert {k: stats[k] for k in INPUT_FAULTS} == e.counters
    assert stats["rx_overflows"] == 0 and stats["tx_overflows"] == 0
    # the model of the node's assembly, fed what the node received, predicts the same
    asm = assemble(frames_of(m for m in seen if m.arbitration_id not in verify_outputs_ids()))
    assert asm.counters == e.counters
    assert len(asm) == n - len(e.lost_samples) == stats["samples"]
    # ... and the periods the node stepped each sample over: every lost sample integrated by the next
    kept = np.setdiff1d(np.arange(n), e.lost_samples)
    assert asm.steps.tolist() == np.diff(kept, prepend=-1).tolist()
    assert asm.periods == n == stats["steps"]
    # no silent loss: every sample that did not step the filter is one the faults destroyed, and verify
    # found exactly those by aligning the node's outputs with the samples sent
    assert rep.skipped == e.lost_samples
    assert rep.samples_lost == len(e.lost_samples)
    # every output fault detected: damaged sets are corrupted (CRC or incomplete), never "mismatched"
    assert rep.mismatched == 0 and rep.unexpected == 0, rep.first_mismatch
    assert rep.corrupted == e.corrupted_sets
    assert rep.duplicates == e.duplicate_sets
    assert rep.missing == len(e.damaged_steps) and rep.lost == 0
    assert rep.sets_ok == rep.sets_expected - len(e.damaged_steps)
    assert rep.reference_ok
    # the node's own report (ATT_DIAG, 8-bit saturating) agrees
    assert rep.node_diag == {k: min(v, 255) for k, v in e.counters.items()}


def verify_outputs_ids() -> set[int]:
    return {*codec.SET_IDS, codec.ID_DIAG, codec.ID_OUT_FD}


def test_fault_injection_with_tap_model() -> None:
    """The same faults, verified from a tap on the node's side (inputs rebuilt by the assembly model)."""
    n = 1200
    host_ch, node_ch = _channel(), _channel()
    node = InProcessNode(node_ch)
    inj = Injector(host_ch, node_ch, n, seed=3)
    tap = open_bus("virtual", node_ch)
    host = open_bus("virtual", host_ch)
    try:
        rep = verify_live(host, _stream(n, seed=2), FilterKind.ARS, window=8, drain_timeout=0.5, tap=tap)
        assert rep.exact is False  # damaged sets are missing
    finally:
        host.shutdown()
        tap.shutdown()
        inj.close()
        node.close()
    print("\n".join(rep.lines()))
    assert rep.input_faults == inj.expect.counters
    assert rep.samples_stepped == n - len(inj.expect.lost_samples)
    assert rep.steps_expected == n  # the lost samples integrated
    assert rep.mismatched == 0 and rep.unexpected == 0 and rep.lost == 0
    assert rep.corrupted == inj.expect.corrupted_sets


# --- monitor and logs -----------------------------------------------------------------------------


def _traffic(fd: bool, n: int = 200) -> list[can.Message]:
    """Frames of a real run (inputs and outputs) plus a few bad ones, as a listener sees them."""
    ch = _channel()
    node = InProcessNode(ch, "mars" if fd else "ars", fd=fd)
    host = open_bus("virtual", ch, fd=fd)
    listener = open_bus("virtual", ch, fd=fd)
    try:
        rep = verify_live(host, _stream(n, seed=1), FilterKind.MARS if fd else FilterKind.ARS, fd=fd)
        assert rep.exact
        bad = [
            can.Message(arbitration_id=0x123, is_extended_id=False, data=bytes(range(8))),
            can.Message(arbitration_id=codec.ID_IMU_GYRO, is_extended_id=False, data=bytes(7)),
            can.Message(arbitration_id=codec.ID_EULER, is_extended_id=False, data=bytes(8)),  # bad CRC
        ]
        for m in bad:
            host.send(m)
        time.sleep(0.05)
        msgs = []
        m = listener.recv(0.0)
        while m is not None:
            msgs.append(m)
            m = listener.recv(0.0)
    finally:
        host.shutdown()
        listener.shutdown()
        node.close()
    return msgs


def _same_frame(a: can.Message, b: can.Message) -> bool:
    return (
        a.arbitration_id == b.arbitration_id
        and bytes(a.data) == bytes(b.data)
        and a.is_fd == b.is_fd
        and a.is_extended_id == b.is_extended_id
        and abs(a.timestamp - b.timestamp) < 1.5e-6
    )


@pytest.mark.parametrize("fd", [False, True])
def test_monitor_logs_round_trip_and_cantools_agrees(tmp_path: Path, fd: bool) -> None:
    msgs = _traffic(fd)
    assert len(msgs) > 400
    for m in msgs:
        m.channel = "vcan0"
    paths = {s: tmp_path / f"bus{s}" for s in (".log", ".asc", ".blf")}
    for p in paths.values():
        w = open_writer(p, channel="vcan0")
        for m in msgs:
            w.on_message_received(m)
        w.stop()
    # candump -L: every frame back, bit for bit, timestamps to the microsecond
    back = list(read_log(paths[".log"]))
    assert len(back) == len(msgs)
    assert all(_same_frame(a, b) for a, b in zip(msgs, back))
    for suffix in (".asc", ".blf"):
        other = list(read_log(paths[suffix]))
        assert [(m.arbitration_id, bytes(m.data), m.is_fd) for m in other] == [
            (m.arbitration_id, bytes(m.data), m.is_fd) for m in msgs
        ], suffix
    # the log verifies offline, from its own input frames
    rep = verify_frames(frames_of(back[:-3]), FilterKind.MARS if fd else FilterKind.ARS, RATE)
    assert rep.exact and rep.ok, "\n".join(rep.lines())
    rep = verify_frames(frames_of(back), FilterKind.MARS if fd else FilterKind.ARS, RATE)
    assert rep.input_faults["dlc_errors"] == 1 and rep.corrupted == 1  # the bad frames at the end
    # cantools decode (its CLI) and the monitor (its CLI) decode every frame the same
    dbc = ROOT / "firmware" / "can" / "attica.dbc"
    ref = cantools_decode(paths[".log"], dbc)
    mon = subprocess.run(
        [sys.executable, "-m", "attica.cli", "monitor", "--log", str(paths[".log"])],
        capture_output=True,
        text=True,
        check=True,
        env=ENV,
    )
    lines = mon.stdout.splitlines()
    assert len(lines) == len(ref) == len(msgs)
    checked = 0
    for ours, theirs in zip(lines, ref):
        head, name, values = decoded_fields(ours)
        t_head, _, t_body = theirs.partition(" :: ")
        assert head == t_head.removesuffix(" R").removesuffix(" T"), (ours, theirs)
        mt = re.match(r"^(\w+)\((.*)\)$", t_body)
        if mt is None:  # cantools: unknown id / wrong size; the monitor flags the same frames
            assert ("!UNKNOWN" in ours) or ("!DLC" in ours), (ours, theirs)
            continue
        assert mt.group(1) == name, (ours, theirs)
        t_values = {}
        for item in mt.group(2).split(", "):
            k, _, v = item.partition(": ")
            t_values[k] = v.split(" ")[0]
        assert t_values.keys() == values.keys(), (ours, theirs)
        for k in values:
            assert same_value(values[k], t_values[k]), (k, ours, theirs)
        checked += 1
    assert checked >= len(msgs) - 3
    assert "!CRC" in lines[-1] and "!DLC" in lines[-2] and "!UNKNOWN" in lines[-3]
    summary = mon.stderr
    assert "crc errors 1" in summary and "dlc errors 1" in summary and "unknown ids 1" in summary


def test_monitor_bus_view_and_counter_gaps() -> None:
    mon = Monitor()
    stream = _stream(20)
    frames = codec.encode_imu(stream.gyr, stream.acc, stream.mag)
    msgs = [codec.to_message(f) for f in frames]
    for i, m in enumerate(msgs):
        m.timestamp = 1000.0 + i / (3 * RATE)  # three frames per sample period
    lines = [mon.feed(m) for i, m in enumerate(msgs) if i // 3 not in (5, 6)]  # two samples lost
    assert sum("!GAP+2" in ln for ln in lines) == 3  # one per IMU message ID
    assert mon.stats.counter_gaps == 3 and mon.stats.missing_frames == 6
    assert lines[0].startswith(candump_text(msgs[0], "can0")) and "IMU_GYRO" in lines[0]
    frames = len(lines)
    span = mon.stats.span
    assert mon.bus_load() == pytest.approx(frames * codec.classic_bits(8) / 500_000 / span)
    assert 0.2 < mon.bus_load() < 0.3  # 3 x 160 bits at 285.714 Hz of 500 kbit/s: 27 %


def test_cli_errors_are_clear(tmp_path: Path) -> None:
    def run(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "attica.cli", *args], capture_output=True, text=True, env=ENV
        )

    r = run("monitor", "--dbc", str(tmp_path / "missing.dbc"), "--log", str(tmp_path / "x.log"))
    assert r.returncode == 2 and "DBC file not found" in r.stderr
    bad = tmp_path / "bad.log"
    bad.write_text("(1.000000) vcan0 100#0011223344556677\nthis is not a frame\n")
    r = run("monitor", "--log", str(bad))
    assert r.returncode == 2 and "bad.log:2: bad log line" in r.stderr
    r = run("verify", "--interface", "socketcan", "--channel", "nosuchcan0", "--count", "10", "-q")
    assert r.returncode == 2 and "cannot open socketcan:nosuchcan0" in r.stderr
    r = run("node", "--interface", "nosuchinterface")
    assert r.returncode == 2 and "unknown CAN interface 'nosuchinterface'" in r.stderr
    r = run("verify", "--interface", "virtual", "--channel", _channel(), "--count", "10", "-q")
    assert r.returncode == 2 and "no node answered" in r.stderr
    r = run("node", "--rate", "5000")
    assert r.returncode == 2 and "% of the bus" in r.stderr
    cfg = tmp_path / "can.conf"
    cfg.write_text("[default]\ninterface = bogus\n")
    r = run("monitor", "--can-config", str(cfg), "--count", "1")
    assert r.returncode == 2 and "bogus" in r.stderr


def test_replay_realtime_pacing() -> None:
    ch = _channel()
    bus = open_bus("virtual", ch)
    sink = open_bus("virtual", ch)
    stream = _stream(100)
    try:
        t0 = time.perf_counter()
        st = replay(bus, stream, realtime=True, speed=2.0)
        elapsed = time.perf_counter() - t0
        got = 0
        while sink.recv(0.0) is not None:
            got += 1
    finally:
        bus.shutdown()
        sink.shutdown()
    assert st.samples == 100 and got == 300
    assert 0.95 * 99 / (2 * RATE) <= elapsed < 99 / (2 * RATE) + 0.5
    np.testing.assert_equal(st.frames, 300)


def test_remote_frames_keep_their_length_through_the_log(tmp_path: Path) -> None:
    """A remote frame's requested length (candump's ``ID#R<dlc>``) survives read_log -> candump_text ->
    read_log. Found by the CI slice of the host parser fuzzing (atheris, tests/fuzz/fuzz_host.py):
    ``(00000) \\n1 100#r2`` was read with dlc 2 and written back as ``100#R``, dlc 0."""
    for text, dlc in (("100#r2", 2), ("100#R", 0), ("123#R8", 8), ("1234ABCD#R5", 5)):
        path = tmp_path / "in.log"
        path.write_text(f"(1.000000) can0 {text}\n")
        (m,) = list(read_log(path))
        assert m.is_remote_frame and m.dlc == dlc
        path.write_text(candump_text(m) + "\n")
        (again,) = list(read_log(path))
        assert again.is_remote_frame and again.dlc == dlc and again.arbitration_id == m.arbitration_id
