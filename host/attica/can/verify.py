"""Check a node's CAN output bit for bit against the numpy reference fed the same input.

The node's input is what it got on the bus: the samples as the IMU frames carry them (classic frames:
int16 scaled, so :func:`attica.can.codec.imu_values`; CAN FD: float32, exact). The reference run is
:func:`attica.crosscheck.crosscheck`: the C filter over those inputs and the numpy reference in
lockstep segments must agree bit for bit (outputs and full state); then every output set received
from the bus is compared field by field (every bit of every float, the int16 codes, flags, steps,
kind, counter) with the set the reference's outputs encode to.

Three ways to get the node's input:

- live (:func:`verify_live`): we send the stream ourselves (:func:`attica.can.replay.replay`), so
  the input is what we sent;
- a tap (``taps``: frames as seen on the node's side of the bus, e.g. behind a lossy link): the input
  is reconstructed with :func:`assemble`, a model of the node's sample assembly (att_node.h);
- a log (:func:`verify_frames` on a candump log that holds both directions): as for a tap.

The report counts, per expected output set: received and equal (ok), received with a good CRC but
different (mismatched), lost; and separately sets with a bad CRC or incomplete (corrupted), sets
received twice (duplicates) and sets for steps that should not exist (unexpected). With a tap or a
log it also counts the input faults the node must have seen (CRC, DLC, unknown IDs, duplicates,
stale partial samples, counter gaps), so that every lost sample is accounted for.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import can
import numpy as np
from numpy.typing import NDArray

from attica.can import codec
from attica.can.bus import from_messages, is_attica_candidate, to_messages
from attica.can.replay import ImuStream, ReplayStats, StepTracker, replay
from attica.settings import FilterKind, make_settings

__all__ = [
    "Assembly",
    "OutputCollector",
    "VerifyReport",
    "assemble",
    "expected_outputs",
    "node_dt",
    "reset_node",
    "verify_frames",
    "verify_live",
]

INPUT_IDS = frozenset({codec.ID_IMU_GYRO, codec.ID_IMU_ACC, codec.ID_IMU_MAG, codec.ID_IMU_FD, codec.ID_CMD})
"""IDs the node receives (everything else is counted as unknown by the node)."""

OUTPUT_IDS = frozenset({*codec.SET_IDS, codec.ID_DIAG, codec.ID_OUT_FD})
"""IDs the node sends."""

_COMPARED = (
    "counter",
    "kind",
    "flags",
    "steps",
    "q",
    "q16",
    "euler_raw",
    "bias_raw",
    "euler",
    "gyro_bias",
    "cov",
)
"""Fields of :data:`attica.can.codec.SET_DTYPE` compared bit for bit (error_count reflects the node's
receive errors, not the filter)."""

INPUT_FAULTS = ("crc_errors", "dlc_errors", "unknown_ids", "duplicates", "stale_partials", "counter_gaps")
"""Input fault counters of the node (ATT_DIAG) that :func:`assemble` predicts."""


def node_dt(rate: float) -> float:
    """The filter's dt as the node computes it: ``1.0f / sample_rate`` in float32."""
    return float(np.float32(1.0) / np.float32(rate))


# --- the node's sample assembly, as a model -------------------------------------------------------


@dataclass
class Assembly:
    """Samples the node completes from a frame sequence, and the input faults it counts."""

    gyr: NDArray[np.float32]
    acc: NDArray[np.float32]
    mag: NDArray[np.float32]
    counters: dict[str, int]
    frames: int = 0
    commands: int = 0
    started: int = 0  # samples begun (completed + discarded partials)

    def __len__(self) -> int:
        return int(self.gyr.shape[0])


def assemble(frames: NDArray[np.void]) -> Assembly:
    """Model of att_node.c's receive path (att_node.h): which samples complete, which faults count.

    Every frame is checked (known ID, length/format, E2E CRC) and then assembled: a classic part with a
    counter other than the partial sample's discards the partial (stale) and begins a new sample; a
    repeated part, or a frame of the sample just completed, is a duplicate; a new sample whose counter
    does not follow the previous sample's is counted once as a counter gap. Commands are counted and
    otherwise ignored here.
    """
    fr = np.atleast_1d(frames)
    counts = dict.fromkeys(INPUT_FAULTS, 0)
    g: list[NDArray[np.float32]] = []
    a: list[NDArray[np.float32]] = []
    m: list[NDArray[np.float32]] = []
    part: dict[int, NDArray[np.float32]] = {}
    part_counter = 0
    last_counter = 0
    have_last = False
    commands = 0
    started = 0
    fracs = {
        codec.ID_IMU_GYRO: codec.GYR_FRAC,
        codec.ID_IMU_ACC: codec.ACC_FRAC,
        codec.ID_IMU_MAG: codec.MAG_FRAC,
    }

    def begin(c: int) -> bool:
        nonlocal have_last, last_counter, started
        replaced = False
        if part:
            counts["stale_partials"] += 1
            part.clear()
            replaced = True
        elif have_last and c == last_counter:
            counts["duplicates"] += 1
            return False
        if have_last and c != ((last_counter + 1) & 0xF) and not (replaced and c == last_counter):
            counts["counter_gaps"] += 1
        have_last = True
        last_counter = c
        started += 1
        return True

    for rec in fr:
        can_id = int(rec["id"])
        if can_id not in INPUT_IDS:
            counts["unknown_ids"] += 1
            continue
        chk = codec.check(rec)
        if chk == codec.Check.DLC:
            counts["dlc_errors"] += 1
            continue
        if chk == codec.Check.CRC:
            counts["crc_errors"] += 1
            continue
        if chk != codec.Check.OK:
            counts["unknown_ids"] += 1
            continue
        data = rec["data"]
        c = int(data[1]) & 0xF
        if can_id == codec.ID_CMD:
            commands += 1
            continue
        if can_id == codec.ID_IMU_FD:
            if begin(c):
                v = np.frombuffer(data[4:40].tobytes(), "<f4").astype(np.float32)
                g.append(v[0:3])
                a.append(v[3:6])
                m.append(v[6:9])
            continue
        if part and c == part_counter:
            if can_id in part:
                counts["duplicates"] += 1
                continue
        else:
            if not begin(c):
                continue
            part_counter = c
        raw = np.frombuffer(data[2:8].tobytes(), "<i2")
        part[can_id] = codec.dequantise(raw, fracs[can_id])
        if len(part) == 3:
            g.append(part[codec.ID_IMU_GYRO])
            a.append(part[codec.ID_IMU_ACC])
            m.append(part[codec.ID_IMU_MAG])
            part.clear()

    def stack(rows: list[NDArray[np.float32]]) -> NDArray[np.float32]:
        return np.array(rows, np.float32).reshape(-1, 3)

    return Assembly(
        stack(g), stack(a), stack(m), counts, frames=int(fr.shape[0]), commands=commands, started=started
    )


# --- expected outputs -----------------------------------------------------------------------------


@dataclass
class Expected:
    """The reference's outputs for a node input, and whether C and numpy agreed on them."""

    records: NDArray[np.void]  # OUTPUT_DTYPE, one per step
    reference_ok: bool
    reference_detail: str = ""


def expected_outputs(
    kind: FilterKind,
    rate: float,
    gyr: NDArray[np.float32],
    acc: NDArray[np.float32],
    mag: NDArray[np.float32],
    settings: Any = None,
    progress: Callable[[int, int], None] | None = None,
) -> Expected:
    """Outputs of every step for the node input (the floats the node steps with).

    Runs :func:`attica.crosscheck.crosscheck`: the C filter and the numpy reference must agree bit for
    bit, else ``reference_ok`` is False and ``reference_detail`` says where.
    """
    from attica.crosscheck import Stream, crosscheck

    s = make_settings(kind, settings, dt=node_dt(rate))
    if gyr.shape[0] == 0:
        from attica.outputs import OUTPUT_DTYPE

        return Expected(np.zeros(0, OUTPUT_DTYPE), True)
    # many short lockstep segments: the reference steps all of them at once (vectorised)
    segment = max(50, min(1000, int(gyr.shape[0]) // 400))
    r = crosscheck(kind, [Stream(gyr, acc, mag, "can")], s, segment=segment, progress=progress)
    detail = "" if r.ok else f"{r.mismatched_steps} steps differ; {r.first_mismatch}"
    return Expected(r.c_outputs[0], r.ok, detail)


def input_values(stream: ImuStream, fd: bool) -> tuple[NDArray[np.float32], ...]:
    """The floats the node steps with when ``stream`` is sent (classic: scaled int16; FD: exact)."""
    if fd:
        return stream.gyr, stream.acc, stream.mag
    return codec.imu_values(stream.gyr, stream.acc, stream.mag)


# --- collecting and comparing the outputs ---------------------------------------------------------


class OutputCollector:
    """Keeps the node's output frames (in arrival order) from received messages."""

    def __init__(self) -> None:
        self.msgs: list[can.Message] = []
        self.tracker = StepTracker()
        self.received = 0
        self.inputs: list[can.Message] = []
        self.keep_inputs = False
        self.first_time: float | None = None
        self.last_time: float | None = None

    def feed(self, msg: can.Message) -> None:
        """Look at one received message."""
        self.received += 1
        now = time.perf_counter()
        if self.first_time is None:
            self.first_time = now
        self.last_time = now
        if not is_attica_candidate(msg):
            return
        if msg.arbitration_id in OUTPUT_IDS:
            self.msgs.append(msg)
            self.tracker.feed(msg)
        elif self.keep_inputs and msg.arbitration_id in INPUT_IDS:
            self.inputs.append(msg)

    @property
    def steps(self) -> int:
        """The node's step count as last reported."""
        return self.tracker.steps

    def frames(self) -> NDArray[np.void]:
        """The output frames kept so far."""
        return np.asarray(from_messages(self.msgs))


@dataclass
class VerifyReport:
    """Outcome of a verification (see the module docstring)."""

    kind: FilterKind
    fd: bool
    samples_sent: int = 0
    steps_expected: int = 0
    sets_expected: int = 0
    sets_ok: int = 0
    mismatched: int = 0
    lost: int = 0
    missing: int = 0
    corrupted: int = 0
    incomplete: int = 0
    duplicates: int = 0
    unexpected: int = 0
    reference_ok: bool = True
    reference_detail: str = ""
    first_mismatch: str = ""
    input_faults: dict[str, int] = field(default_factory=dict)
    node_diag: dict[str, int] = field(default_factory=dict)
    error_count: int = 0
    answers: int = 0
    skipped: list[int] = field(default_factory=list)
    frames_sent: int = 0
    frames_received: int = 0
    elapsed: float = 0.0
    replay: ReplayStats | None = None

    @property
    def exact(self) -> bool:
        """Every expected output set arrived and is bit-identical to the reference; nothing else arrived."""
        return (
            self.reference_ok
            and self.sets_expected > 0
            and self.sets_ok == self.sets_expected
            and self.mismatched == 0
            and self.lost == 0
            and self.corrupted == 0
            and self.unexpected == 0
        )

    @property
    def samples_lost(self) -> int:
        """Samples sent that never stepped the filter."""
        return max(self.samples_sent - self.steps_expected, 0)

    @property
    def ok(self) -> bool:
        """:attr:`exact`, no duplicates, and no input faults."""
        return (
            self.exact
            and self.duplicates == 0
            and not any(self.input_faults.values())
            and self.samples_lost == 0
        )

    def lines(self) -> list[str]:
        """Human-readable report."""
        mode = "CAN FD" if self.fd else "classic CAN"
        out = [
            f"{self.kind.label} over {mode}: {self.samples_sent} samples sent, "
            f"{self.steps_expected} filter steps, {self.sets_expected} output sets expected"
        ]
        out.append(
            f"  received: {self.sets_ok} bit-exact, {self.mismatched} mismatched, {self.missing} missing "
            f"({self.corrupted} corrupted, {self.incomplete} of them incomplete; {self.lost} lost), "
            f"{self.duplicates} duplicates, {self.unexpected} unexpected"
        )
        if self.skipped:
            shown = ", ".join(str(i) for i in self.skipped[:10]) + (" ..." if len(self.skipped) > 10 else "")
            out.append(
                f"  {len(self.skipped)} samples never reached the filter (lost on the way; sample {shown}); "
                "the comparison uses the samples the node did step with"
            )
        if self.input_faults:
            faults = ", ".join(f"{k} {v}" for k, v in self.input_faults.items())
            out.append(f"  input faults the node must count: {faults}; samples lost {self.samples_lost}")
        if self.node_diag:
            out.append("  node ATT_DIAG: " + ", ".join(f"{k} {v}" for k, v in self.node_diag.items()))
        ref = (
            "C == numpy reference, bit for bit"
            if self.reference_ok
            else f"C != reference: {self.reference_detail}"
        )
        out.append(f"  reference: {ref}")
        if self.first_mismatch:
            out.append(f"  first mismatch: {self.first_mismatch}")
        if self.elapsed > 0:
            total = self.frames_sent + self.frames_received
            out.append(
                f"  {self.frames_sent} frames sent, {self.frames_received} received in {self.elapsed:.2f} s: "
                f"{total / self.elapsed:.0f} frames/s end to end, "
                f"{self.steps_expected / self.elapsed:.0f} steps/s"
            )
        if self.ok:
            verdict = "BIT-EXACT"
        elif self.exact:
            verdict = "BIT-EXACT, BUT WITH LOSSES OR FAULTS (all counted above)"
        else:
            verdict = "FAILED"
        out.append(f"  verdict: {verdict}")
        return out


def _split_sets(fr: NDArray[np.void]) -> tuple[NDArray[np.void], int, NDArray[np.void], int]:
    """Sort output frames: (complete sets' frames, incomplete sets, DIAG frames, command answers).

    The complete sets' frames (classic sets and OUT_FD frames) stay in arrival order.

    A classic set is QUAT_A, QUAT_B, QUAT16, EULER, BIAS, STATUS back to back (the node queues a set at
    once); a set broken by a missing, extra or out-of-order frame counts once as incomplete and its
    remaining frames are skipped up to the next QUAT_A.
    """
    ids = fr["id"].tolist()
    keep: list[int] = []
    partial: list[int] = []
    broken = False
    incomplete = 0
    diag: list[int] = []
    answers = 0
    for i, can_id in enumerate(ids):
        if can_id == codec.ID_DIAG:
            diag.append(i)
            continue
        if can_id == codec.ID_STATUS and int(fr["len"][i]) == 8 and int(fr["data"][i, 7]) & codec.ACK_ANSWER:
            answers += 1
            continue
        if can_id == codec.ID_OUT_FD:
            if partial or broken:
                incomplete += 1
                partial, broken = [], False
            keep.append(i)
            continue
        if can_id not in codec.SET_IDS:
            continue
        pos = codec.SET_IDS.index(can_id)
        if pos == 0:
            if partial or broken:
                incomplete += 1
            partial, broken = [i], False
        elif broken:
            continue
        elif partial and len(partial) == pos:
            partial.append(i)
            if pos == 5:
                keep.extend(partial)
                partial = []
        else:
            # out of sequence: the set in progress (or a set whose start was lost) is broken
            partial, broken = [], True
    if partial or broken:
        incomplete += 1
    return fr[np.array(keep, np.int64)], incomplete, fr[np.array(diag, np.int64)], answers


def _describe(name: str, got: Any, want: Any) -> str:
    def show(x: Any) -> str:
        arr = np.asarray(x)
        if arr.dtype.kind == "f":
            return "[" + ", ".join(f"{float(v)!r} ({float(v).hex()})" for v in arr.reshape(-1)) + "]"
        return str(arr.tolist())

    return f"{name}: got {show(got)}, expected {show(want)}"


def _unwrap(low: NDArray[Any]) -> NDArray[np.int64]:
    """Full step numbers of 16-bit step fields in arrival order (starting from 0)."""
    out = np.zeros(low.shape[0], np.int64)
    prev_low = 0
    prev = 0
    for i, v in enumerate(low.tolist()):
        delta = (v - prev_low) & 0xFFFF
        prev = prev + delta if delta < 0x8000 else prev - (0x10000 - delta)
        prev_low = v
        out[i] = prev
    return out


def _rows(a: NDArray[Any]) -> NDArray[np.uint8]:
    arr = np.ascontiguousarray(a)
    return arr.view(np.uint8).reshape(arr.shape[0], -1)


def _equal_rows(got: NDArray[np.void], want: NDArray[np.void], counter_offset: int) -> NDArray[np.bool_]:
    """Per set: every compared field bit-identical (counters shifted by ``counter_offset``)."""
    ok = np.ones(got.shape[0], np.bool_)
    for name in _COMPARED:
        if name == "counter":
            ok &= got["counter"] == ((want["counter"].astype(np.int64) + counter_offset) & 0xF).astype(
                np.uint8
            )
        else:
            ok &= (_rows(got[name]) == _rows(want[name])).all(axis=1)
    return ok


def _mismatch_text(got: np.void, want: np.void, counter_offset: int) -> str:
    diffs = []
    for name in _COMPARED:
        a = np.asarray(got[name])
        b = np.asarray(want[name])
        if name == "counter":
            b = np.asarray((int(b) + counter_offset) & 0xF, a.dtype)
        if a.tobytes() != b.tobytes():
            diffs.append(_describe(name, a, b))
    return "; ".join(diffs)


@dataclass
class Received:
    """The node's output frames sorted out: good sets with their step numbers, and what was wrong."""

    sets: NDArray[np.void]  # SET_DTYPE, CRC good, arrival order
    step: NDArray[np.int64]  # full step number of each
    bad_crc: int
    incomplete: int
    answers: int
    diag: NDArray[np.void]


def sort_outputs(outputs: NDArray[np.void]) -> Received:
    """Split output frames into sets (checked), DIAG frames and command answers."""
    fr = np.atleast_1d(outputs)
    good, incomplete, diag, answers = _split_sets(fr)
    got = codec.decode_outputs(good).sets if good.shape[0] else np.zeros(0, codec.SET_DTYPE)
    dg = codec.decode_outputs(diag).diag if diag.shape[0] else np.zeros(0, codec.DIAG_DTYPE)
    ok = got[got["crc_ok"]]
    return Received(ok, _unwrap(ok["steps"]), int((~got["crc_ok"]).sum()), incomplete, answers, dg)


def compare(
    expected: Expected,
    kind: FilterKind,
    fd: bool,
    outputs: NDArray[np.void] | Received,
    output_divider: int = 1,
) -> VerifyReport:
    """Compare output frames (arrival order) with the expected per-step outputs."""
    rep = VerifyReport(kind=kind, fd=fd)
    recs = expected.records
    steps = int(recs.shape[0])
    rep.steps_expected = steps
    rep.reference_ok = expected.reference_ok
    rep.reference_detail = expected.reference_detail
    chosen = recs[output_divider - 1 :: output_divider]
    rep.sets_expected = int(chosen.shape[0])
    want = (
        codec.decode_outputs(codec.encode_outputs(chosen, kind, fd=fd)).sets
        if rep.sets_expected
        else np.zeros(0, codec.SET_DTYPE)
    )
    rx = outputs if isinstance(outputs, Received) else sort_outputs(outputs)
    rep.incomplete = rx.incomplete
    rep.answers = rx.answers
    good_diag = rx.diag[rx.diag["crc_ok"]]
    if good_diag.shape[0]:
        last = good_diag[-1]
        rep.node_diag = {name: int(last[name]) for name in INPUT_FAULTS}
    rep.corrupted = rx.incomplete + rx.bad_crc
    if rx.sets.shape[0] and not fd:
        rep.error_count = int(rx.sets["error_count"][-1])
    full = rx.step
    valid = (full >= 1) & (full <= steps) & (full % output_divider == 0)
    rep.unexpected = int((~valid).sum())
    if rep.unexpected:
        bad = int(full[~valid][0])
        rep.first_mismatch = f"a set for step {bad}, which should not exist (steps 1..{steps})"
    idx = np.nonzero(valid)[0]
    j = full[idx] // output_divider - 1
    _, first = np.unique(j, return_index=True)
    rep.duplicates = int(idx.shape[0] - first.shape[0])
    idx = idx[np.sort(first)]
    j = full[idx] // output_divider - 1
    seen = np.zeros(rep.sets_expected, np.bool_)
    seen[j] = True
    if idx.shape[0]:
        got = rx.sets[idx]
        w = want[j]
        offset = (int(got["counter"][0]) - int(w["counter"][0])) & 0xF
        eq = _equal_rows(got, w, offset)
        rep.sets_ok = int(eq.sum())
        rep.mismatched = int((~eq).sum())
        if rep.mismatched and not rep.first_mismatch:
            k = int(np.argmin(eq))
            rep.first_mismatch = f"step {int(full[idx[k]])}: " + _mismatch_text(got[k], w[k], offset)
    rep.missing = int((~seen).sum())
    rep.lost = max(rep.missing - rep.corrupted, 0)
    return rep


def align_inputs(
    kind: FilterKind,
    rate: float,
    gyr: NDArray[np.float32],
    acc: NDArray[np.float32],
    mag: NDArray[np.float32],
    rx: Received,
    fd: bool,
    settings: Any = None,
    max_skip: int = 32,
    max_losses: int = 256,
) -> tuple[NDArray[np.int64], list[int]]:
    """Which sent samples the node stepped with, found from its outputs (output divider 1 only).

    Samples lost on the way to the node (dropped frames, full socket buffers) shift every later step.
    Starting from "no loss", at the first step whose received set differs from the C filter's, this
    tries skipping 1..max_skip samples there and keeps the skip that makes that set bit-identical.
    Returns (indices of the stepped samples, indices of the skipped samples). The final proof is the
    comparison with the reference over the stepped samples; alignment only uses the C filter.
    """
    from attica import native

    n = int(gyr.shape[0])
    seq = np.arange(n, dtype=np.int64)
    skipped: list[int] = []
    if rx.sets.shape[0] == 0 or n == 0:
        return seq, skipped
    s = make_settings(kind, settings, dt=node_dt(rate))
    by_step: dict[int, int] = {}
    for i, st in enumerate(rx.step.tolist()):
        by_step.setdefault(int(st), i)
    steps_rx = np.array(sorted(by_step), np.int64)
    rows = np.array([by_step[int(k)] for k in steps_rx], np.int64)
    ffi = native.ffi
    offset: int | None = None
    start = 0  # steps before this are known to match
    for _ in range(max_losses):
        m = seq.shape[0]
        f = native.Filter(kind, s)
        out = f.run(gyr[seq], acc[seq], mag[seq])
        want = codec.decode_outputs(codec.encode_outputs(out, kind, fd=fd)).sets
        sel = (steps_rx >= max(start, 1)) & (steps_rx <= m)
        if not sel.any():
            break
        st = steps_rx[sel]
        got = rx.sets[rows[sel]]
        w = want[st - 1]
        if offset is None:
            offset = (int(got["counter"][0]) - int(w["counter"][0])) & 0xF
        eq = _equal_rows(got, w, offset)
        if eq.all():
            break
        k = int(np.argmin(eq))
        bad_step = int(st[k])
        target = got[k : k + 1]
        # state just before the bad step
        f = native.Filter(kind, s)
        if bad_step > 1:
            f.run(gyr[seq[: bad_step - 1]], acc[seq[: bad_step - 1]], mag[seq[: bad_step - 1]])
        snap = ffi.new("att_filter_t *")
        snap[0] = f.state[0]
        fixed = False
        for d in range(1, max_skip + 1):
            if bad_step - 1 + d >= m:
                break
            cand = int(seq[bad_step - 1 + d])
            f.state[0] = snap[0]
            rec = f.run(gyr[cand : cand + 1], acc[cand : cand + 1], mag[cand : cand + 1])
            rec["steps"] = bad_step  # the node's step count does not see the skipped samples
            ws = codec.decode_outputs(
                codec.encode_outputs(rec, kind, counter0=int(w["counter"][k]), fd=fd)
            ).sets
            if _equal_rows(target, ws, offset).all():
                skipped.extend(seq[bad_step - 1 : bad_step - 1 + d].tolist())
                seq = np.concatenate([seq[: bad_step - 1], seq[bad_step - 1 + d :]])
                fixed = True
                break
        if not fixed:
            break  # a real mismatch: leave it to the comparison
        start = bad_step
    return seq, skipped


# --- whole runs -----------------------------------------------------------------------------------


class NodeNotAnsweringError(RuntimeError):
    """No node answered the reset command."""


def reset_node(
    bus: can.BusABC, timeout: float = 2.0, counter: int = 0, service: Callable[[], object] | None = None
) -> codec.Answer:
    """Send CMD reset and wait for the node's answer (the node restarts its filter; steps restart at 0).

    Raises
    ------
    NodeNotAnsweringError
        When no answer arrived within ``timeout`` s.

    """
    cmd = to_messages(codec.encode_cmd(int(codec.Cmd.RESET), counter=counter))[0]
    bus.send(cmd)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if service is not None:
            service()
        msg = bus.recv(min(max(deadline - time.monotonic(), 0.0), 0.05 if service is not None else 1.0))
        if msg is None:
            continue
        if (
            is_attica_candidate(msg)
            and msg.arbitration_id == codec.ID_STATUS
            and len(msg.data) == 8
            and msg.data[7] & codec.ACK_ANSWER
            and (msg.data[7] & 0xF) == int(codec.Cmd.RESET)
        ):
            ans = codec.decode_outputs(from_messages([msg])).answers[0]
            if ans.crc_ok:
                return ans
    raise NodeNotAnsweringError(
        f"no node answered a reset command within {timeout:g} s (is a node running on this bus?)"
    )


def verify_live(
    bus: can.BusABC,
    stream: ImuStream,
    kind: FilterKind,
    *,
    fd: bool = False,
    output_divider: int = 1,
    realtime: bool = False,
    speed: float = 1.0,
    window: int = 16,
    drain_timeout: float = 1.0,
    reset: bool = True,
    settings: Any = None,
    tap: can.BusABC | None = None,
    progress: bool = False,
    on_message: Callable[[can.Message], None] | None = None,
    service: Callable[[], object] | None = None,
) -> VerifyReport:
    """Replay ``stream`` to a node on ``bus`` and check every output set it sends back.

    Parameters
    ----------
    bus
        Bus shared with the node.
    stream
        Samples to send.
    kind
        The node's filter (its settings: the kind's defaults with ``dt = 1.0f / rate``, or ``settings``).
    fd, output_divider
        As configured on the node.
    realtime, speed, window
        Pacing (see :func:`attica.can.replay.replay`).
    drain_timeout
        After the last sample, wait this long without a new frame before giving up on missing outputs.
    reset
        Send CMD reset first and wait for the answer (needed when the node ran before).
    settings
        Filter settings of the node when not the defaults.
    tap
        A bus on the node's side of a lossy link: the node's input is reconstructed from what it shows
        (:func:`assemble`) instead of taken from what was sent.
    progress
        Progress bars on a terminal.
    on_message
        Called with every received frame (monitor view).
    service
        An in-process node's :meth:`~attica.can.runner.NodeRunner.service`, called before every read
        (the node then runs on this thread).

    """
    if reset:
        ans = reset_node(bus, service=service)
        if FilterKind(ans.kind) != kind:
            raise ValueError(
                f"the node runs {FilterKind(ans.kind).label}, not {kind.label}: pass --filter accordingly"
            )
    if window > 0:
        window = max(window, 2 * output_divider)  # the node confirms steps only with its output sets
    coll = OutputCollector()
    tap_msgs: list[can.Message] = []

    def receive(msg: can.Message) -> None:
        coll.feed(msg)
        if on_message is not None:
            on_message(msg)

    def drain_tap() -> None:
        if tap is None:
            return
        msg = tap.recv(0.0)
        while msg is not None:
            if is_attica_candidate(msg):
                tap_msgs.append(msg)
            msg = tap.recv(0.0)

    t0 = time.perf_counter()
    rstats = replay(
        bus,
        stream,
        fd=fd,
        realtime=realtime,
        speed=speed,
        window=window,
        receive=receive,
        acked=lambda: coll.steps,
        progress=progress,
        service=service,
    )
    want_steps = len(stream)
    last_count = coll.received
    last_change = time.monotonic()
    while coll.steps < want_steps:
        if service is not None:
            service()
        msg = bus.recv(0.02)
        drain_tap()
        while msg is not None:
            receive(msg)
            msg = bus.recv(0.0)
        if coll.received != last_count:
            last_count = coll.received
            last_change = time.monotonic()
        elif time.monotonic() - last_change > drain_timeout:
            break
    # the set of the last step may still be on its way after its STATUS: take what is queued
    if service is not None:
        service()
    msg = bus.recv(0.05)
    while msg is not None:
        receive(msg)
        msg = bus.recv(0.0)
    elapsed = time.perf_counter() - t0
    drain_tap()
    faults: dict[str, int] = {}
    if tap is not None:
        # everything the node received (on a shared bus a node does not receive its own frames)
        asm = assemble(from_messages([m for m in tap_msgs if m.arbitration_id not in OUTPUT_IDS]))
        gyr, acc, mag = asm.gyr, asm.acc, asm.mag
        faults = asm.counters
    rx = sort_outputs(coll.frames())
    skipped: list[int] = []
    if tap is None:
        gyr, acc, mag = input_values(stream, fd)
        faults = {}
        if output_divider == 1:
            seq, skipped = align_inputs(kind, stream.rate, gyr, acc, mag, rx, fd, settings)
            gyr, acc, mag = gyr[seq], acc[seq], mag[seq]
    exp = expected_outputs(kind, stream.rate, gyr, acc, mag, settings)
    rep = compare(exp, kind, fd, rx, output_divider)
    rep.samples_sent = len(stream)
    rep.input_faults = faults
    rep.skipped = skipped
    rep.frames_sent = rstats.frames
    rep.frames_received = coll.received
    rep.elapsed = elapsed
    rep.replay = rstats
    return rep


def verify_frames(
    frames: NDArray[np.void],
    kind: FilterKind,
    rate: float,
    *,
    fd: bool | None = None,
    output_divider: int = 1,
    settings: Any = None,
) -> VerifyReport:
    """Verify a recorded bus (both directions, e.g. a candump log): inputs rebuilt with :func:`assemble`.

    The log must start with the node freshly initialised or reset (a reset command's answer in the log
    starts the comparison after it).
    """
    fr = np.atleast_1d(frames)
    ids = fr["id"]
    is_answer = (ids == codec.ID_STATUS) & (fr["len"] == 8) & ((fr["data"][:, 7] & codec.ACK_ANSWER) != 0)
    resets = np.nonzero(is_answer & ((fr["data"][:, 7] & 0xF) == int(codec.Cmd.RESET)))[0]
    if resets.shape[0]:
        fr = fr[int(resets[-1]) + 1 :]
        ids = fr["id"]
    inputs = fr[np.isin(ids, np.array(sorted(INPUT_IDS), np.uint32))]
    outputs = fr[np.isin(ids, np.array(sorted(OUTPUT_IDS | {codec.ID_STATUS}), np.uint32))]
    if fd is None:
        fd = bool((ids == codec.ID_OUT_FD).any())
    asm = assemble(inputs)
    exp = expected_outputs(kind, rate, asm.gyr, asm.acc, asm.mag, settings)
    rep = compare(exp, kind, fd, outputs, output_divider)
    rep.samples_sent = asm.started  # samples begun; whole samples missing show as counter_gaps
    rep.input_faults = asm.counters
    rep.frames_received = int(fr.shape[0])
    return rep


def frames_of(msgs: Iterable[can.Message]) -> NDArray[np.void]:
    """Attica frame records of the data frames with 11-bit IDs among ``msgs``."""
    return np.asarray(from_messages([m for m in msgs if is_attica_candidate(m)]))
