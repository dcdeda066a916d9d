"""Send an IMU stream (simulated, or a recorded .npz / .csv) to the node as CAN frames.

Each sample becomes IMU_GYRO, IMU_ACC, IMU_MAG (classic CAN, int16 scaled) or one IMU_FD frame (CAN FD,
float32 exact), with the sample index mod 16 as counter (:func:`attica.can.codec.encode_imu`).

Pacing:

- real time (``realtime=True``): sample k leaves at ``t0 + k / (rate * speed)``;
- as fast as possible (default), with flow control: at most ``window`` samples may be ahead of the
  node's last reported step (ATT_STATUS / ATT_OUT_FD ``steps``), so neither the node's rx ring nor a
  socket buffer overflows. When the node goes quiet for ``stall_timeout`` s with samples outstanding,
  those samples are taken as lost (they never stepped the filter) and the window moves on (a stall).
  ``window=0`` disables flow control (pure blast; use ``max_frame_rate`` to cap it).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import can
import numpy as np
from numpy.typing import NDArray

from attica.can import codec
from attica.can.bus import is_attica_candidate, to_messages
from attica.data import Recording

__all__ = ["ImuStream", "ReplayStats", "StepTracker", "replay"]

CHUNK = 2048
"""Samples encoded at a time."""


@dataclass
class ImuStream:
    """What is replayed: float32 (N, 3) gyr (rad/s), acc (m/s^2), mag (uT, NaN rows = none), rate (Hz)."""

    gyr: NDArray[np.float32]
    acc: NDArray[np.float32]
    mag: NDArray[np.float32]
    rate: float
    name: str = ""

    @classmethod
    def from_recording(cls, rec: Recording, count: int | None = None) -> ImuStream:
        """The first ``count`` samples (all when None) of a recording."""
        n = len(rec.gyr) if count is None else min(count, len(rec.gyr))
        return cls(
            gyr=np.ascontiguousarray(rec.gyr[:n], np.float32),
            acc=np.ascontiguousarray(rec.acc[:n], np.float32),
            mag=np.ascontiguousarray(rec.mag[:n], np.float32),
            rate=float(rec.rate),
            name=rec.name,
        )

    def __len__(self) -> int:
        return int(self.gyr.shape[0])

    def frames(self, start: int, stop: int, fd: bool) -> NDArray[np.void]:
        """Encoded frames of samples ``start .. stop-1`` (3 per sample classic, 1 FD)."""
        return codec.encode_imu(
            self.gyr[start:stop], self.acc[start:stop], self.mag[start:stop], counter0=start & 0xF, fd=fd
        )


class StepTracker:
    """Follows the node's step count from its ATT_STATUS / ATT_OUT_FD frames (16-bit, unwrapped).

    Only frames whose E2E CRC is right count (for ATT_STATUS: over the set's quaternion frames too).
    """

    def __init__(self) -> None:
        self.steps = 0
        self._low = 0
        self.frames = 0
        self._quat: dict[int, can.Message] = {}

    def feed(self, msg: can.Message) -> None:
        """Look at one received frame."""
        self.frames += 1
        can_id = msg.arbitration_id
        data = msg.data
        if msg.is_extended_id or len(data) < 8:
            return
        if can_id in codec.NO_CRC:
            self._quat[can_id] = msg
            return
        if can_id == codec.ID_STATUS and not data[7] & codec.ACK_ANSWER:
            qa, qb, q16 = (self._quat.get(i) for i in (codec.ID_QUAT_A, codec.ID_QUAT_B, codec.ID_QUAT16))
            self._quat.clear()
            if qa is None or qb is None or q16 is None or not codec.check_status_set(msg, qa, qb, q16):
                return
            low = data[4] | data[5] << 8
        elif can_id == codec.ID_OUT_FD and len(data) == 64:
            if codec.check(msg) != codec.Check.OK:
                return
            low = data[6] | data[7] << 8
        else:
            return
        delta = (low - self._low) & 0xFFFF
        if delta < 0x8000:  # forward only
            self.steps += delta
            self._low = low


@dataclass
class ReplayStats:
    """Outcome of :func:`replay`."""

    samples: int = 0
    frames: int = 0
    elapsed: float = 0.0
    stalls: int = 0
    late: int = 0  # real time: samples sent more than one period late
    send_retries: int = 0

    @property
    def frames_per_s(self) -> float:
        """Frames sent per second."""
        return self.frames / self.elapsed if self.elapsed > 0 else 0.0

    def line(self) -> str:
        """One-line summary."""
        return (
            f"sent {self.samples} samples in {self.frames} frames in {self.elapsed:.2f} s "
            f"({self.frames_per_s:.0f} frames/s, {self.samples / max(self.elapsed, 1e-9):.0f} samples/s); "
            f"stalls {self.stalls}, late {self.late}"
        )


def _progress(total: int, enabled: bool) -> Any:
    from tqdm import tqdm

    return tqdm(
        total=total,
        desc="replay",
        unit="sample",
        unit_scale=True,
        disable=not (enabled and sys.stderr.isatty()),
        leave=False,
        file=sys.stderr,
        mininterval=0.2,
    )


def _send(bus: can.BusABC, msg: can.Message, stats: ReplayStats, timeout: float = 2.0) -> None:
    deadline = time.monotonic() + timeout
    while True:
        try:
            bus.send(msg)
            return
        except can.CanOperationError:
            if time.monotonic() > deadline:
                raise
            stats.send_retries += 1
            time.sleep(0.0005)


def replay(
    bus: can.BusABC,
    stream: ImuStream,
    *,
    fd: bool = False,
    realtime: bool = False,
    speed: float = 1.0,
    window: int = 16,
    stall_timeout: float = 0.1,
    max_frame_rate: float | None = None,
    receive: Callable[[can.Message], None] | None = None,
    acked: Callable[[], int] | None = None,
    progress: bool = False,
    channel: str | None = None,
    service: Callable[[], object] | None = None,
    on_send: Callable[[can.Message], None] | None = None,
) -> ReplayStats:
    """Send ``stream`` on ``bus``.

    Parameters
    ----------
    bus
        Open bus (opened with ``fd=True`` for ``fd``).
    stream
        The samples.
    fd
        One IMU_FD frame per sample instead of three classic frames.
    realtime, speed
        Pace at ``rate * speed`` samples/s instead of as fast as possible.
    window
        Flow control (as fast as possible only): most samples ahead of the node's reported steps;
        0 = none.
    stall_timeout
        Seconds of silence from the node (with samples outstanding) after which those samples are taken
        as lost and sending goes on.
    max_frame_rate
        Cap on frames/s when not in real time (None = no cap).
    receive
        Called with every frame received from the bus while replaying (e.g. the verifier's
        collector). Frames are read from ``bus`` only when ``receive`` or flow control needs them.
    acked
        Number of samples the node has confirmed (defaults to a :class:`StepTracker` on the frames
        received).
    progress
        Show a progress bar (on a terminal).
    channel
        Channel name put into the messages (for loggers).
    service
        Called before every read from the bus: lets an in-process node on the same thread take its
        frames and answer (e.g. ``NodeRunner(...).service``), instead of running it in a thread.
    on_send
        Called with every frame once it was sent (e.g. a log writer, :class:`attica.can.logs.LogTee`).

    """
    if speed <= 0:
        raise ValueError("speed must be > 0")
    stats = ReplayStats()
    tracker = StepTracker()
    get_acked: Callable[[], int] = acked if acked is not None else (lambda: tracker.steps)
    listen = receive is not None or (window > 0 and not realtime) or service is not None

    def drain(timeout: float) -> bool:
        got = False
        if service is not None:
            service()
        msg = bus.recv(timeout)
        while msg is not None:
            got = True
            if is_attica_candidate(msg):
                tracker.feed(msg)
            if receive is not None:
                receive(msg)
            msg = bus.recv(0.0)
        return got

    n = len(stream)
    slack = 0  # samples given up on (lost before they reached the node)
    period = 1.0 / (stream.rate * speed)
    per_sample = 1 if fd else 3
    t0 = time.perf_counter()
    with _progress(n, progress) as bar:
        for start in range(0, n, CHUNK):
            stop = min(n, start + CHUNK)
            msgs = to_messages(stream.frames(start, stop, fd), channel=channel)
            for j in range(stop - start):
                k = start + j
                if realtime:
                    due = t0 + k * period
                    now = time.perf_counter()
                    if now < due:
                        if listen:
                            while now < due:
                                drain(min(due - now, 0.005))
                                now = time.perf_counter()
                        else:
                            time.sleep(due - now)
                    elif now - due > period:
                        stats.late += 1
                elif window > 0:
                    quiet_since = time.monotonic()
                    while k - get_acked() - slack >= window:
                        if drain(0.002):
                            quiet_since = time.monotonic()
                        elif time.monotonic() - quiet_since > stall_timeout:
                            # the node went quiet although samples are outstanding: they were lost on
                            # the way (or the node is gone); stop waiting for them
                            stats.stalls += 1
                            slack = k - get_acked()
                            break
                elif max_frame_rate:
                    due = t0 + k * per_sample / max_frame_rate
                    now = time.perf_counter()
                    if now < due:
                        time.sleep(due - now)
                for msg in msgs[j * per_sample : (j + 1) * per_sample]:
                    _send(bus, msg, stats)
                    if on_send is not None:
                        on_send(msg)
                stats.samples += 1
                stats.frames += per_sample
                if listen and (service is None or (k & 7) == 7):
                    drain(0.0)  # an in-process node takes its frames in batches of 8 samples
                if (k & 63) == 63:
                    bar.update(64)
        bar.update(n - bar.n)
    stats.elapsed = time.perf_counter() - t0
    return stats
