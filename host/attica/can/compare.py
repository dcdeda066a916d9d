"""What a node should have sent, and what it did: expected outputs, collected frames, the comparison.

- :func:`expected_outputs`: the outputs of every sample for the node's input (each stepped over its
  sample periods, as the node derives them from the E2E counters), from the C filter and the numpy
  reference in lockstep (they must agree bit for bit);
- :class:`OutputCollector`: the node's output frames from received messages, with its step count;
- :func:`sort_outputs`, :func:`compare`: split the frames into sets and compare every set field by
  field with the set the reference's outputs encode to (:class:`VerifyReport`);
- :func:`node_steps`: which whole samples the node steps, and over how many periods (att_node.c);
- :func:`align_inputs`: which sent samples the node stepped with, found from its outputs.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import can
import numpy as np
from numpy.typing import ArrayLike, NDArray

from attica.can import codec
from attica.can.assembly import INPUT_FAULTS, INPUT_IDS, OUTPUT_IDS
from attica.can.bus import from_messages, is_attica_candidate
from attica.can.replay import ImuStream, ReplayStats, StepTracker
from attica.settings import OUTPUT_INVALID, FilterKind, make_settings

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

    records: NDArray[np.void]  # OUTPUT_DTYPE, one per sample stepped (its last period; flags ORed)
    reference_ok: bool
    reference_detail: str = ""
    mag_offset: NDArray[np.void] | None = None  # MAG_OFFSET_DTYPE per record: the hard-iron estimate, if on


def node_steps(
    counters: ArrayLike, have_last: bool = False, last: int = 0
) -> tuple[NDArray[np.int64], NDArray[np.uint32]]:
    """Which of the whole samples reaching the node in this order (their E2E counters) it steps, and how.

    att_node.c: a sample steps the filter over (counter - counter of the last sample stepped) mod 16
    periods: 1 for the next one, k + 1 after k lost samples, 1 for the first one. A sample whose counter
    equals the last stepped one (after 15 lost samples, 16 periods cannot be told from 0) is a duplicate
    and not stepped; the distance of the next one counts from the last sample stepped. ``have_last``,
    ``last``: the node stepped a sample with counter ``last`` before these.

    Returns (positions of the stepped samples among ``counters``, sample periods of each).
    """
    c = np.asarray(counters, np.int64).reshape(-1) & 0xF
    if c.shape[0] == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.uint32)
    prev = np.concatenate([[last], c[:-1]])
    n = (c - prev) & 0xF
    if not have_last:
        n[0] = 1
    if not (n == 0).any():
        return np.arange(c.shape[0], dtype=np.int64), n.astype(np.uint32)
    keep: list[int] = []
    per: list[int] = []
    for i, ci in enumerate(c.tolist()):
        if have_last:
            d = (ci - last) & 0xF
            if d == 0:
                continue  # the node drops it as a duplicate of the sample just stepped
        else:
            d = 1
        keep.append(i)
        per.append(d)
        have_last, last = True, ci
    return np.array(keep, np.int64), np.array(per, np.uint32)


def expected_outputs(
    kind: FilterKind,
    rate: float,
    gyr: NDArray[np.float32],
    acc: NDArray[np.float32],
    mag: NDArray[np.float32],
    settings: Any = None,
    progress: Callable[[int, int], None] | None = None,
    calibration: Any = None,
    steps: ArrayLike | None = None,
) -> Expected:
    """Outputs of every sample for the node input (the floats the node steps with).

    ``calibration`` is the node's (a Calibration or StageSettings; None: identity, ENU). ``steps``: the
    sample periods the node steps each sample over (:attr:`Assembly.steps`, :func:`node_steps`; None:
    1 each); a record is the output after the sample's last period with the flags ORed over its
    periods, as the node sends it (att_filter_step_n, then att_filter_output).

    Runs :func:`attica.crosscheck.crosscheck`: the C filter and the numpy reference must agree bit for
    bit, else ``reference_ok`` is False and ``reference_detail`` says where. With steps, they run over
    every period (each sample repeated over its periods) and the records of the node's path
    (``native.Filter.run(..., steps=...)``) must equal those periods' last records with the ORed flags.
    """
    from attica import native
    from attica.crosscheck import Stream, crosscheck, records_equal

    s = make_settings(kind, settings, dt=node_dt(rate))
    n = int(gyr.shape[0])
    if n == 0:
        from attica.outputs import OUTPUT_DTYPE

        return Expected(np.zeros(0, OUTPUT_DTYPE), True)
    per = None
    if steps is not None:
        per = np.asarray(steps, np.int64)
        if per.shape != (n,) or (per < 1).any():
            raise ValueError(f"steps must be ({n},) integers >= 1")
        if (per == 1).all():
            per = None
    mo = _expected_offsets(kind, s, gyr, acc, mag, per, calibration)
    idx = np.arange(n) if per is None else np.repeat(np.arange(n), per)
    # many short lockstep segments: the reference steps all of them at once (vectorised)
    segment = max(50, min(1000, int(idx.shape[0]) // 400))
    stream = Stream(gyr, acc, mag, "can") if per is None else Stream(gyr[idx], acc[idx], mag[idx], "can")
    r = crosscheck(kind, [stream], s, segment=segment, progress=progress, calibration=calibration)
    detail = "" if r.ok else f"{r.mismatched_steps} steps differ; {r.first_mismatch}"
    if per is None:
        return Expected(r.c_outputs[0], r.ok, detail, mo)
    every = r.c_outputs[0]
    ends = np.cumsum(per) - 1
    records = every[ends].copy()
    records["flags"] = np.bitwise_or.reduceat(every["flags"], ends - per + 1)
    node_path = native.Filter(kind, s, calibration=calibration).run(
        gyr, acc, mag, steps=per.astype(np.uint32), check_units=False
    )
    same = records_equal(np.asarray(node_path), records)
    if not same.all():
        i = int(np.argmin(same))
        detail = (detail + "; " if detail else "") + (
            f"att_filter_step_n differs from its {int(per[i])} single steps at sample {i}: "
            f"{np.asarray(node_path)[i]!r} vs {records[i]!r}"
        )
    return Expected(records, r.ok and bool(same.all()), detail, mo)


def _expected_offsets(
    kind: FilterKind,
    s: Any,
    gyr: NDArray[np.float32],
    acc: NDArray[np.float32],
    mag: NDArray[np.float32],
    per: NDArray[np.int64] | None,
    calibration: Any,
) -> NDArray[np.void] | None:
    """The hard-iron estimate after each sample (the node's ATT_MAG_OFFSET), None where it does not run.

    From the C filter over the node's path (``att_filter_step_n``); that the C estimate is the
    reference's, bit for bit, is the crosscheck's full-state comparison (its ``hi`` state included).
    """
    from attica import native
    from attica.outputs import MAG_OFFSET_DTYPE

    f = native.Filter(kind, s, calibration=calibration)
    if not f.estimates_mag_offset:
        return None
    mo = np.zeros(int(gyr.shape[0]), MAG_OFFSET_DTYPE)
    steps = per.astype(np.uint32) if per is not None else None
    f.run(gyr, acc, mag, steps=steps, check_units=False, mag_offset=mo)
    return mo


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
    samples_stepped: int = 0  # samples that stepped the filter (one output record each)
    steps_expected: int = 0  # filter steps: their sample periods (lost samples integrated)
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
    offsets_ok: int = 0  # ATT_MAG_OFFSET frames equal to the estimate after the set they followed
    offsets_mismatched: int = 0
    offsets_unmatched: int = 0  # following a set that did not arrive whole: not checked
    offsets_unexpected: int = 0  # from a node whose filter has no hard-iron estimate running
    offsets_corrupted: int = 0  # ATT_MAG_OFFSET frames with a bad CRC
    offsets_missing: int = 0  # DIAGs (after a good set) without their ATT_MAG_OFFSET
    offsets_expected: bool = False  # the reference's filter estimates a hard-iron offset

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
            and self.offsets_mismatched == 0
            and self.offsets_unexpected == 0
            and self.offsets_corrupted == 0
            and self.offsets_missing == 0
        )

    @property
    def samples_lost(self) -> int:
        """Samples sent that never stepped the filter (the node integrated their periods when it could)."""
        return max(self.samples_sent - self.samples_stepped, 0)

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
        held = self.steps_expected - self.samples_stepped
        over = f" (+{held} periods of lost samples integrated)" if held > 0 else ""
        out = [
            f"{self.kind.label} over {mode}: {self.samples_sent} samples sent, {self.samples_stepped} "
            f"stepped, {self.steps_expected} filter steps{over}, {self.sets_expected} output sets expected"
        ]
        out.append(
            f"  received: {self.sets_ok} bit-exact, {self.mismatched} mismatched, {self.missing} missing "
            f"({self.corrupted} corrupted, {self.incomplete} of them incomplete; {self.lost} lost), "
            f"{self.duplicates} duplicates, {self.unexpected} unexpected"
        )
        if self.offsets_expected or self.offsets_unexpected:
            out.append(
                f"  hard-iron offsets (ATT_MAG_OFFSET): {self.offsets_ok} bit-exact, "
                f"{self.offsets_mismatched} mismatched, {self.offsets_missing} missing, "
                f"{self.offsets_corrupted} corrupted, {self.offsets_unmatched} after a set that did not "
                f"arrive whole (not checked), {self.offsets_unexpected} unexpected"
            )
        if self.skipped:
            shown = ", ".join(str(i) for i in self.skipped[:10]) + (" ..." if len(self.skipped) > 10 else "")
            out.append(
                f"  {len(self.skipped)} samples never reached the filter (lost on the way; sample {shown}); "
                "the comparison uses the samples the node did step with, over the periods it derived "
                "from the E2E counters"
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


def _split_sets(
    fr: NDArray[np.void],
) -> tuple[
    NDArray[np.void], int, NDArray[np.void], int, NDArray[np.void], NDArray[np.int64], NDArray[np.int64]
]:
    """Sort output frames: sets, incomplete sets, DIAG frames, answers, ATT_MAG_OFFSET frames.

    Returns (complete sets' frames, incomplete sets, DIAG frames, command answers, ATT_MAG_OFFSET frames,
    for each of those the index of the complete set it follows, and the same for each DIAG frame). A DIAG
    or an offset follows a set when no set frame came between them (the node queues set, its DIAG and
    its offset back to back); only the first offset after a set does; -1: none (its own set was lost or
    broken, which a counter mod 16 alone could not tell from the set 16 earlier).

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
    diag_after: list[int] = []
    offsets: list[int] = []
    after: list[int] = []
    done = 0  # complete sets so far
    link = -1  # the complete set the frames since follow (-1: a set frame came since, or none yet)
    answers = 0
    for i, can_id in enumerate(ids):
        if can_id == codec.ID_DIAG:
            diag.append(i)
            diag_after.append(link)
            continue
        if can_id == codec.ID_MAG_OFFSET:  # the node sends it after the DIAG that follows a set
            offsets.append(i)
            after.append(link)
            link = -1
            continue
        if can_id == codec.ID_STATUS and int(fr["len"][i]) == 8 and int(fr["data"][i, 7]) & codec.ACK_ANSWER:
            answers += 1
            continue
        if can_id == codec.ID_OUT_FD:
            if partial or broken:
                incomplete += 1
                partial, broken = [], False
            keep.append(i)
            done += 1
            link = done - 1
            continue
        if can_id not in codec.SET_IDS:
            continue
        link = -1
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
                done += 1
                link = done - 1
        else:
            # out of sequence: the set in progress (or a set whose start was lost) is broken
            partial, broken = [], True
    if partial or broken:
        incomplete += 1
    sets = fr[np.array(keep, np.int64)]
    offs = fr[np.array(offsets, np.int64)]
    dg = fr[np.array(diag, np.int64)]
    return sets, incomplete, dg, answers, offs, np.array(after, np.int64), np.array(diag_after, np.int64)


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
    offsets: NDArray[np.void] = field(default_factory=lambda: np.zeros(0, codec.MAG_OFFSET_DTYPE))
    """ATT_MAG_OFFSET frames (decoded, CRC good), arrival order."""
    offset_step: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    """The full step of the good set each of :attr:`offsets` followed (-1: not checkable: its own set was
    lost or broken, had a bad CRC, or carries another counter)."""
    offsets_bad_crc: int = 0
    """ATT_MAG_OFFSET frames with a bad CRC."""
    offsets_missing: int = 0
    """Good sets followed by their DIAG (good CRC) but by no ATT_MAG_OFFSET: where the node's estimate
    runs it sends one after every DIAG (counted by :func:`compare` only where one is expected)."""


def sort_outputs(outputs: NDArray[np.void]) -> Received:
    """Split output frames into sets (checked), DIAG frames and command answers."""
    fr = np.atleast_1d(outputs)
    good, incomplete, diag, answers, offs, after, diag_after = _split_sets(fr)
    got = codec.decode_outputs(good).sets if good.shape[0] else np.zeros(0, codec.SET_DTYPE)
    dg = codec.decode_outputs(diag).diag if diag.shape[0] else np.zeros(0, codec.DIAG_DTYPE)
    ok = got[got["crc_ok"]]
    step = _unwrap(ok["steps"])
    mo = codec.decode_outputs(offs).mag_offset if offs.shape[0] else np.zeros(0, codec.MAG_OFFSET_DTYPE)
    # the step of the set each offset followed, by its place among the good sets, where that set is
    # good and carries the offset's counter (-1: not checkable)
    place = np.cumsum(got["crc_ok"]) - 1
    offset_step = np.full(mo.shape[0], -1, np.int64)
    for k, a in enumerate(after.tolist()):
        if a >= 0 and bool(got["crc_ok"][a]) and int(got["counter"][a]) == int(mo["counter"][k]):
            offset_step[k] = step[place[a]]
    crc = mo["crc_ok"]
    # sets with a good DIAG after them but no offset (of any CRC): offsets lost on the way
    with_diag = {
        int(a) for a, c in zip(diag_after.tolist(), dg["crc_ok"].tolist(), strict=True) if a >= 0 and c
    }
    missing = len(with_diag - {int(a) for a in after.tolist() if a >= 0})
    return Received(
        ok,
        step,
        int((~got["crc_ok"]).sum()),
        incomplete,
        answers,
        dg,
        mo[crc],
        offset_step[crc],
        int((~crc).sum()),
        missing,
    )


def compare(
    expected: Expected,
    kind: FilterKind,
    fd: bool,
    outputs: NDArray[np.void] | Received,
    output_divider: int = 1,
) -> VerifyReport:
    """Compare output frames (arrival order) with the expected per-sample outputs.

    The node queues a set after a sample whose filter steps reach or pass a multiple of ``output_divider``
    (every sample with divider 1), its flags ORed over the samples since the previous set; a received set
    is matched to the expected one by its steps field.
    """
    rep = VerifyReport(kind=kind, fd=fd)
    recs = expected.records
    total = recs["steps"].astype(np.int64)  # the filter's steps after each sample
    rep.samples_stepped = int(recs.shape[0])
    rep.steps_expected = int(total[-1]) if total.shape[0] else 0
    rep.reference_ok = expected.reference_ok
    rep.reference_detail = expected.reference_detail
    before = np.concatenate([np.zeros(1, np.int64), total[:-1]])
    emits = total // output_divider > before // output_divider
    chosen = recs[emits].copy()
    last = np.flatnonzero(emits)
    if last.size:  # a set's flags: ORed over every step since the previous set, but whether q is an
        # estimate (NOT_READY, BAD_ARG), which is the set's own sample's (att_node.c, att_node_step)
        starts = np.concatenate([np.zeros(1, np.int64), last[:-1] + 1])
        ored = np.bitwise_or.reduceat(recs["flags"][: last[-1] + 1], starts)
        invalid = np.uint32(OUTPUT_INVALID)
        chosen["flags"] = (ored & ~invalid) | (chosen["flags"] & invalid)
    set_steps = total[emits]
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
    where = np.searchsorted(set_steps, full)
    at = np.minimum(where, max(rep.sets_expected - 1, 0))
    valid = (where < rep.sets_expected) & (set_steps[at] == full if rep.sets_expected else False)
    rep.unexpected = int((~valid).sum())
    if rep.unexpected:
        bad = int(full[~valid][0])
        rep.first_mismatch = (
            f"a set for step {bad}, which should not exist (steps 1..{rep.steps_expected}, "
            f"{rep.sets_expected} sets)"
        )
    idx = np.nonzero(valid)[0]
    j = at[idx]
    _, first = np.unique(j, return_index=True)
    rep.duplicates = int(idx.shape[0] - first.shape[0])
    idx = idx[np.sort(first)]
    j = at[idx]
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
    _compare_offsets(rep, expected, rx, set_steps, np.flatnonzero(emits))
    rep.missing = int((~seen).sum())
    rep.lost = max(rep.missing - rep.corrupted, 0)
    return rep


def _compare_offsets(
    rep: VerifyReport,
    expected: Expected,
    rx: Received,
    set_steps: NDArray[np.int64],
    set_rows: NDArray[np.int64],
) -> None:
    """Each ATT_MAG_OFFSET received against the estimate after the set it followed.

    att_node.c sends it after the DIAG of every diag_divider-th set; compared as the frame encodes it
    (offset, estimated bit).
    """
    got = rx.offsets
    if expected.mag_offset is None:
        rep.offsets_unexpected = int(got.shape[0]) + rx.offsets_bad_crc  # the estimate does not run here
        if rep.offsets_unexpected:  # the cause of any set mismatch too: said first
            hint = (
                f"the node sends ATT_MAG_OFFSET ({rep.offsets_unexpected} frames): it estimates a hard-iron "
                "offset, which these settings do not; give the settings it was started with (--set "
                "hard_iron_tau=...)"
            )
            rep.first_mismatch = hint + (f"; then {rep.first_mismatch}" if rep.first_mismatch else "")
        return
    rep.offsets_expected = True
    rep.offsets_corrupted = rx.offsets_bad_crc
    rep.offsets_missing = rx.offsets_missing
    want = expected.mag_offset
    for k in range(got.shape[0]):
        st = int(rx.offset_step[k])
        j = int(np.searchsorted(set_steps, st))
        if st < 0 or j >= set_steps.shape[0] or int(set_steps[j]) != st:
            rep.offsets_unmatched += 1  # its own set was lost or damaged on the way: not checkable
            continue
        r = int(set_rows[j])
        h = codec.dequantise(codec.quantise(want["offset"][r], codec.MAG_FRAC), codec.MAG_FRAC)
        same = h.tobytes() == np.asarray(got["offset"][k], np.float32).tobytes()
        if same and bool(want["estimated"][r]) == bool(got["estimated"][k]):
            rep.offsets_ok += 1
            continue
        rep.offsets_mismatched += 1
        if not rep.first_mismatch:
            rep.first_mismatch = (
                f"ATT_MAG_OFFSET after the set of step {st}: got {np.asarray(got['offset'][k]).tolist()} uT "
                f"(estimated {bool(got['estimated'][k])}), expected {h.tolist()} uT "
                f"(estimated {bool(want['estimated'][r])})"
            )


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
) -> tuple[NDArray[np.int64], list[int], NDArray[np.uint32]]:
    """Which sent samples the node stepped with, and over how many periods, found from its outputs.

    Output divider 1 only; sample i was sent with E2E counter i mod 16 (:func:`attica.can.replay.replay`).
    Samples lost on the way to the node (dropped frames, full socket buffers) are integrated by the node
    over the counter distance (:func:`node_steps`), so a set's steps field tells its sample's period and
    the sets after a loss differ in their values. Starting from "no loss", at the first received set that
    the C filter does not give (by its steps field, then bit for bit), this tries removing a run of
    1..max_skip whole samples after the last set that agreed (first the runs that leave the fewest output
    sets unseen), models the node's steps over the rest and keeps the run that makes that set
    bit-identical. Returns (indices of the stepped samples, indices of the samples not stepped, the
    periods of each stepped sample). The final proof is the comparison with the reference over the
    stepped samples; alignment only uses the C filter.
    """
    from attica import native

    n = int(gyr.shape[0])
    arrived = np.arange(n, dtype=np.int64)  # samples taken to reach the node whole
    pos, per = node_steps(arrived)
    if rx.sets.shape[0] == 0 or n == 0:
        return arrived[pos], [], per
    s = make_settings(kind, settings, dt=node_dt(rate))
    by_step: dict[int, int] = {}
    for i, st in enumerate(rx.step.tolist()):
        by_step.setdefault(int(st), i)
    steps_rx = np.array(sorted(by_step), np.int64)
    rows = np.array([by_step[int(k)] for k in steps_rx], np.int64)
    offset: int | None = None

    def encoded(out: NDArray[np.void], counter0: int) -> NDArray[np.void]:
        return codec.decode_outputs(codec.encode_outputs(out, kind, counter0=counter0, fd=fd)).sets

    for _ in range(max_losses):
        pos, per = node_steps(arrived)
        stepped = arrived[pos]
        f = native.Filter(kind, s, calibration=calibration)
        out = f.run(gyr[stepped], acc[stepped], mag[stepped], steps=per, check_units=False)
        total = out["steps"].astype(np.int64)
        want = encoded(out, 0)  # divider 1: set index = record index
        where = np.searchsorted(total, steps_rx)
        at = np.minimum(where, total.shape[0] - 1)
        have = (where < total.shape[0]) & (total[at] == steps_rx)
        if not have.any():
            break
        got = rx.sets[rows]
        if offset is None:
            k0 = int(np.argmax(have))
            offset = (int(got["counter"][k0]) - int(want["counter"][at[k0]])) & 0xF
        eq = have.copy()
        eq[have] = _equal_rows(got[have], want[at[have]], offset)
        if eq.all():
            break
        k = int(np.argmin(eq))  # every received set before it agrees
        s_k = int(steps_rx[k])
        target = got[k : k + 1]
        pa = int(at[k - 1]) if k > 0 else -1  # the record of the last set that agreed
        ia = int(pos[pa]) if pa >= 0 else -1  # its sample's place among the arrived ones
        s_a = int(total[pa]) if pa >= 0 else 0
        f = native.Filter(kind, s, calibration=calibration)
        if pa >= 0:
            f.run(
                gyr[stepped[: pa + 1]],
                acc[stepped[: pa + 1]],
                mag[stepped[: pa + 1]],
                steps=per[: pa + 1],
                check_units=False,
            )
        snap = f.state.copy()
        last = int(stepped[pa]) & 0xF if pa >= 0 else 0
        rest = arrived[ia + 1 :]
        gap = s_k - s_a - 1  # samples between the two sets when none was lost at all
        tried: set[tuple[int, int]] = set()
        order = [(x, d) for d in range(min(gap, max_skip), 0, -1) for x in range(0, gap - d + 1)]
        order += [(x, d) for x in range(0, gap + 17) for d in range(1, max_skip + 1)]
        fixed = False
        for x, d in order:
            if (x, d) in tried or x + d > rest.shape[0]:
                continue
            tried.add((x, d))
            cand = np.concatenate([rest[:x], rest[x + d : x + d + gap + 33]])
            cpos, cper = node_steps(cand, pa >= 0, last)
            cum = s_a + np.cumsum(cper, dtype=np.int64)
            hit = np.nonzero(cum == s_k)[0]
            if hit.shape[0] == 0:
                continue
            t = int(hit[0])
            smp = cand[cpos[: t + 1]]
            f.state[0] = snap[0]
            rec = f.run(gyr[smp], acc[smp], mag[smp], steps=cper[: t + 1], check_units=False)
            if _equal_rows(target, encoded(rec[t : t + 1], (pa + 1 + t) & 0xF), offset).all():
                arrived = np.concatenate([arrived[: ia + 1 + x], arrived[ia + 1 + x + d :]])
                fixed = True
                break
        if not fixed:
            break  # a real mismatch: leave it to the comparison
    pos, per = node_steps(arrived)
    stepped = arrived[pos]
    skipped = np.setdiff1d(np.arange(n, dtype=np.int64), stepped).tolist()
    return stepped, skipped, per
