"""Check a node's CAN output bit for bit against the numpy reference fed the same input.

The node's input is what it got on the bus: the samples as the IMU frames carry them (classic frames:
int16 scaled, so :func:`attica.can.codec.imu_values`; CAN FD: float32, exact), each stepped over the
sample periods the node derives from the E2E counters (1, or k + 1 after k lost samples:
att_filter_step_n; :func:`node_steps`, :attr:`Assembly.steps`). The reference run is
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

The parts: :mod:`attica.can.assembly` (the node's sample assembly), :mod:`attica.can.compare`
(expected outputs, collection, comparison, alignment); this module runs whole verifications.

The report counts, per expected output set: received and equal (ok), received with a good CRC but
different (mismatched), lost; and separately sets with a bad CRC or incomplete (corrupted), sets
received twice (duplicates) and sets for steps that should not exist (unexpected). With a tap or a
log it also counts the input faults the node must have seen (CRC, DLC, unknown IDs, duplicates,
stale partial samples, counter gaps), so that every lost sample is accounted for.

Not compared: ATT_DIAG and ATT_DIAG_BUS (the node's own counters, shown), and ATT_MAG_OFFSET (the
hard-iron offset a mars or mekf filter estimates; the reference's offset is not recorded per step).
That estimate is bit-exact between C and the reference through :func:`attica.crosscheck.crosscheck`'s
full-state comparison; the frame the node sends is checked in tests/test_hard_iron.py (its cadence,
the estimate near the simulated offset, the C and Python decoders alike).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from typing import Any

import can
import numpy as np
from numpy.typing import NDArray

from attica.can import codec
from attica.can.assembly import INPUT_FAULTS, INPUT_IDS, OUTPUT_IDS, Assembly, assemble
from attica.can.bus import from_messages, is_attica_candidate, to_messages
from attica.can.compare import (
    Expected,
    OutputCollector,
    Received,
    VerifyReport,
    align_inputs,
    compare,
    expected_outputs,
    input_values,
    node_dt,
    node_steps,
    sort_outputs,
)
from attica.can.idoffset import silent_node_hint
from attica.can.replay import ImuStream, replay
from attica.settings import FilterKind

__all__ = [
    "Assembly",
    "Expected",
    "INPUT_FAULTS",
    "INPUT_IDS",
    "NodeNotAnsweringError",
    "OUTPUT_IDS",
    "OutputCollector",
    "Received",
    "VerifyReport",
    "align_inputs",
    "assemble",
    "compare",
    "expected_outputs",
    "frames_of",
    "input_values",
    "node_dt",
    "node_steps",
    "reset_node",
    "sort_outputs",
    "verify_frames",
    "verify_live",
]


class NodeNotAnsweringError(RuntimeError):
    """No node answered the reset command (or, without one, no output came back at all)."""


FOREIGN_KEPT = 256
"""Frames of other IDs kept while waiting for a node, for the hint of :func:`silent_node_hint`."""


def _keep_foreign(msg: can.Message, kept: list[can.Message]) -> None:
    """Keep a frame that is not attica's (for the error message when no node answers)."""
    if len(kept) < FOREIGN_KEPT and is_attica_candidate(msg) and msg.arbitration_id not in codec.MSG_LEN:
        kept.append(msg)


def reset_node(
    bus: can.BusABC,
    timeout: float = 2.0,
    counter: int = 0,
    service: Callable[[], object] | None = None,
    on_send: Callable[[can.Message], None] | None = None,
    on_receive: Callable[[can.Message], None] | None = None,
) -> codec.Answer:
    """Send CMD reset and wait for the node's answer (the node restarts its filter; steps restart at 0).

    ``on_send`` / ``on_receive`` see the command and every frame received meanwhile (e.g. a log).

    Raises
    ------
    NodeNotAnsweringError
        When no answer arrived within ``timeout`` s; the message names the bus's ID offset and suggests
        ``--id-offset`` (or the offset at which the frames seen are attica frames).

    """
    cmd = to_messages(codec.encode_cmd(int(codec.Cmd.RESET), counter=counter))[0]
    bus.send(cmd)
    if on_send is not None:
        on_send(cmd)
    deadline = time.monotonic() + timeout
    foreign: list[can.Message] = []
    while time.monotonic() < deadline:
        if service is not None:
            service()
        msg = bus.recv(min(max(deadline - time.monotonic(), 0.0), 0.05 if service is not None else 1.0))
        if msg is None:
            continue
        if on_receive is not None:
            on_receive(msg)
        _keep_foreign(msg, foreign)
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
        f"no node answered a reset command within {timeout:g} s: {silent_node_hint(bus, foreign)}"
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
    calibration: Any = None,
    tap: can.BusABC | None = None,
    progress: bool = False,
    on_message: Callable[[can.Message], None] | None = None,
    service: Callable[[], object] | None = None,
    on_send: Callable[[can.Message], None] | None = None,
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
    calibration
        The node's calibration (a Calibration or StageSettings; None: identity, ENU), applied to the
        reference too.
    tap
        A bus on the node's side of a lossy link: the node's input is reconstructed from what it shows
        (:func:`assemble`) instead of taken from what was sent (opened with the same ID offset as
        ``bus``).
    progress
        Progress bars on a terminal.
    on_message
        Called with every received frame (monitor view).
    service
        An in-process node's :meth:`~attica.can.runner.NodeRunner.service`, called before every read
        (the node then runs on this thread).
    on_send
        Called with every frame sent (with ``on_message``: a log of both directions).

    Raises
    ------
    NodeNotAnsweringError
        No node answered the reset; or, with ``reset`` False, not one output frame came back.
    ValueError
        The node runs another filter than ``kind``.

    """
    if reset:
        ans = reset_node(bus, service=service, on_send=on_send, on_receive=on_message)
        if FilterKind(ans.kind) != kind:
            raise ValueError(
                f"the node runs {FilterKind(ans.kind).label}, not {kind.label}: pass --filter accordingly"
            )
    if window > 0:
        window = max(window, 2 * output_divider)  # the node confirms steps only with its output sets
    coll = OutputCollector()
    tap_msgs: list[can.Message] = []
    foreign: list[can.Message] = []

    def receive(msg: can.Message) -> None:
        coll.feed(msg)
        _keep_foreign(msg, foreign)
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
        on_send=on_send,
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
    if not reset and len(stream) >= output_divider and not coll.msgs:
        raise NodeNotAnsweringError(
            f"{rstats.samples} samples sent, not one output frame came back: {silent_node_hint(bus, foreign)}"
        )
    drain_tap()
    faults: dict[str, int] = {}
    periods: NDArray[np.uint32] | None = None
    if tap is not None:
        # everything the node received (on a shared bus a node does not receive its own frames)
        asm = assemble(from_messages([m for m in tap_msgs if m.arbitration_id not in OUTPUT_IDS]))
        gyr, acc, mag = asm.gyr, asm.acc, asm.mag
        faults = asm.counters
        periods = asm.steps
    rx = sort_outputs(coll.frames())
    skipped: list[int] = []
    if tap is None:
        gyr, acc, mag = input_values(stream, fd)
        faults = {}
        if output_divider == 1:
            seq, skipped, periods = align_inputs(
                kind, stream.rate, gyr, acc, mag, rx, fd, settings, calibration=calibration
            )
            gyr, acc, mag = gyr[seq], acc[seq], mag[seq]
    exp = expected_outputs(kind, stream.rate, gyr, acc, mag, settings, calibration=calibration, steps=periods)
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
    calibration: Any = None,
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
    exp = expected_outputs(
        kind, rate, asm.gyr, asm.acc, asm.mag, settings, calibration=calibration, steps=asm.steps
    )
    rep = compare(exp, kind, fd, outputs, output_divider)
    # samples sent as far as the log tells: the periods the node integrated (whole samples missing
    # included, by the counters), or the samples begun when more (a partial one at the end)
    rep.samples_sent = max(asm.started, asm.periods)
    rep.input_faults = asm.counters
    rep.frames_received = int(fr.shape[0])
    return rep


def frames_of(msgs: Iterable[can.Message]) -> NDArray[np.void]:
    """Attica frame records of the data frames with 11-bit IDs among ``msgs``."""
    return np.asarray(from_messages([m for m in msgs if is_attica_candidate(m)]))
