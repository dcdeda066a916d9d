"""What a node should have sent, and what it did: expected outputs, collected frames, the comparison.

- :func:`expected_outputs`: the outputs of every step for the node's input, from the C filter and the
  numpy reference in lockstep (they must agree bit for bit);
- :class:`OutputCollector`: the node's output frames from received messages, with its step count;
- :func:`sort_outputs`, :func:`compare`: split the frames into sets and compare every set field by
  field with the set the reference's outputs encode to (:class:`VerifyReport`);
- :func:`align_inputs`: which sent samples the node stepped with, found from its outputs.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import can
import numpy as np
from numpy.typing import NDArray

from attica.can import codec
from attica.can.assembly import INPUT_FAULTS, INPUT_IDS, OUTPUT_IDS
from attica.can.bus import from_messages, is_attica_candidate
from attica.can.replay import ImuStream, ReplayStats, StepTracker
from attica.settings import FilterKind, make_settings

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


def node_dt(rate: float) -> float:
    """The filter's dt as the node computes it: ``1.0f / sample_rate`` in float32."""
    return float(np.float32(1.0) / np.float32(rate))


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
    calibration: Any = None,
) -> Expected:
    """Outputs of every step for the node input (the floats the node steps with).

    ``calibration`` is the node's (a Calibration or StageSettings; None: identity, ENU).

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
    r = crosscheck(
        kind, [Stream(gyr, acc, mag, "can")], s, segment=segment, progress=progress, calibration=calibration
    )
    detail = "" if r.ok else f"{r.mismatched_steps} steps differ; {r.first_mismatch}"
    return Expected(r.c_outputs[0], r.ok, detail)


def input_values(stream: ImuStream, fd: bool) -> tuple[NDArray[np.float32], ...]:
    """The floats the node steps with when ``stream`` is sent (classic: scaled int16; FD: exact)."""
    if fd:
        return stream.gyr, stream.acc, stream.mag
    return codec.imu_values(stream.gyr, stream.acc, stream.mag)


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
    calibration: Any = None,
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
    offset: int | None = None
    start = 0  # steps before this are known to match
    for _ in range(max_losses):
        m = seq.shape[0]
        f = native.Filter(kind, s, calibration=calibration)
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
        f = native.Filter(kind, s, calibration=calibration)
        if bad_step > 1:
            f.run(gyr[seq[: bad_step - 1]], acc[seq[: bad_step - 1]], mag[seq[: bad_step - 1]])
        snap = f.state.copy()
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
