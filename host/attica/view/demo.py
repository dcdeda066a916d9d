"""``attica view --demo`` and ``--data``: IMU samples through the C node on a bus (:class:`ImuSource`).

The simulator's (or a recording's) samples are encoded as IMU frames (:func:`attica.can.codec.encode_imu`)
and sent in real time times ``speed`` to the C node (:class:`attica.can.node.Node`, run by
:class:`attica.can.runner.NodeRunner`) on a python-can bus; the view reads that bus like any other
(:class:`~attica.view.sources.BusSource`), so the page's commands reach the C node the way they reach a
real one. The true attitude, when known, goes to the page as the ghost. At the end the samples start
again from the first and the node is reset (CMD 2); a seek resets it too.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Any

import can
import numpy as np
from numpy.typing import NDArray

from attica.can import codec
from attica.can.bus import BusConfig, BusOpenError, open_config, to_messages
from attica.can.idoffset import to_bus
from attica.view.sources import BusSource, Source, SourceError, _Pacer, _speed
from attica.view.state import ViewState

__all__ = ["ImuSource"]

log = logging.getLogger("attica.view")


class ImuSource(Source):
    """IMU samples sent in real time to the C node on a bus, the view reading that bus.

    Parameters
    ----------
    gyr, acc, mag
        float32 (N, 3) samples (rad/s, m/s^2, uT; NaN rows of mag: none).
    rate
        Sample rate, Hz.
    config
        The bus shared by the sample feeder, the node and the view (virtual by default).
    kind
        The node's filter kind.
    truth
        (N, 4) true attitude (w, x, y, z sensor-to-ENU) or None.
    name
        What the page calls the samples (``simulation ...``, a file name).
    fd, bitrate, data_bitrate, id_offset
        The node's CAN settings (classic frames by default).
    speed, paused
        Initial pace.

    """

    kind = "demo"
    can_send = True
    CHUNK = 64

    def __init__(
        self,
        gyr: NDArray[np.float32],
        acc: NDArray[np.float32],
        mag: NDArray[np.float32],
        rate: float,
        config: BusConfig,
        *,
        kind: str = "mars",
        truth: NDArray[np.float64] | None = None,
        name: str = "simulation",
        fd: bool = False,
        bitrate: int = 500_000,
        data_bitrate: int = 2_000_000,
        id_offset: int = 0,
        speed: float = 1.0,
        paused: bool = False,
        source_kind: str = "demo",
    ) -> None:
        from attica.can.node import Node

        super().__init__()
        self.kind = source_kind
        self.gyr = np.ascontiguousarray(gyr, np.float32)
        self.acc = np.ascontiguousarray(acc, np.float32)
        self.mag = np.ascontiguousarray(mag, np.float32)
        self.rate = float(rate)
        self.truth = None if truth is None else np.asarray(truth, np.float64)
        self.name = name
        self.config = config
        self.fd = fd
        self.id_offset = id_offset
        self.node = Node(
            kind,
            sample_rate=self.rate,
            bitrate=bitrate,
            data_bitrate=data_bitrate if fd else 0,
            fd=fd,
            id_offset=id_offset,
        )
        self.node_kind = kind
        n = self.gyr.shape[0]
        if n == 0:
            raise SourceError("no samples to play")
        self.pacer = _Pacer(n / self.rate, _speed(speed), paused)
        self.view = BusSource(config, id_offset=id_offset)
        self.view.running_state = lambda: "paused" if self.pacer.paused else "running"
        self.view.expect_quiet = lambda: self.pacer.paused
        self.sample = 0  # next sample to send
        self.sent = 0  # samples sent in all (their E2E counter: sent mod 16)
        self.sent_frames = 0
        self.loops = 0
        self._cmd_counter = 0
        self._cond = threading.Condition()
        self._seek_to: float | None = None
        self._feed_bus: can.BusABC | None = None
        self._node_bus: can.BusABC | None = None

    def describe(self) -> str:
        """What is played, to which node, on which bus."""
        return f"{self.name} -> C node {self.node_kind} at {self.rate:g} Hz on {self.view.describe()}"

    def start(self, state: ViewState) -> None:
        """Open the buses, start the node, the view's reader and the feeder."""
        from attica.can.runner import NodeRunner

        super().start(state)
        # The view's bus first: python-can's virtual bus hands a frame to its receivers one after the
        # other, in the order they joined, so the view must get a sample before the node does (or it
        # may see the node's answer before the sample, as no real bus would show it).
        self.view.start(state)
        state.set_source(kind=self.kind, text=self.describe())
        if not self.view.opened.wait(5.0):
            raise SourceError(f"cannot open {self.view.describe()}: {state.source.get('error')}")
        try:
            self._node_bus = open_config(self.config)
            self._feed_bus = open_config(self.config)
        except BusOpenError as exc:
            raise SourceError(str(exc)) from None
        self.runner = NodeRunner(self._node_bus, self.node)
        self._thread(self._serve_node, "attica-view-node")
        self._thread(self._run, "attica-view-feed")

    def stop(self) -> None:
        """Stop the feeder, the node and the reader; close the buses."""
        super().stop()
        self.view.stop()
        for bus in (self._feed_bus, self._node_bus):
            if bus is not None:
                bus.shutdown()

    def _serve_node(self) -> None:
        self.runner.serve(stop=self._stop)

    def _publish(self) -> None:
        state = self.state
        assert state is not None
        with state.lock:
            state.playback = self.pacer.as_json(self.sample / self.rate, loops=self.loops, ended=False)

    def _drain(self) -> None:
        bus = self._feed_bus
        assert bus is not None
        for _ in range(100_000):  # the feeder's copy of the bus traffic: not needed, never kept
            if bus.recv(0.0) is None:
                return

    def _send(self, msg: can.Message) -> None:
        bus = self._feed_bus
        assert bus is not None
        deadline = time.monotonic() + 1.0
        while True:
            try:
                bus.send(to_bus(msg, self.id_offset))
                self.sent_frames += 1
                return
            except can.CanOperationError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.0005)

    def _reset_node(self, why: str) -> None:
        self._cmd_counter = (self._cmd_counter + 1) & 0xF
        self._send(to_messages(codec.encode_cmd(int(codec.Cmd.RESET), counter=self._cmd_counter))[0])
        if self.state is not None:
            self.state.note("info", why)

    def _run(self) -> None:
        state = self.state
        assert state is not None
        n = self.gyr.shape[0]
        self.pacer.anchor(0.0)
        state.set_source(state="paused" if self.pacer.paused else "running")
        last_publish = 0.0
        while not self._stop.is_set():
            self._drain()
            with self._cond:
                seek = self._seek_to
                self._seek_to = None
            if seek is not None:
                self.sample = min(int(round(seek * self.rate)), n - 1)
                self.pacer.anchor(self.sample / self.rate)
                self._reset_node(f"seek to {seek:.2f} s: node reset")
            now = time.monotonic()
            if now - last_publish > 0.05:
                self._publish()
                last_publish = now
            if self.pacer.paused:
                with self._cond:
                    self._cond.wait(0.05)
                continue
            if self.sample >= n:
                self.sample = 0
                self.loops += 1
                self.pacer.anchor(0.0)
                self._reset_node(f"{self.name}: from the start again (loop {self.loops}): node reset")
            due = min(int(self.pacer.position() * self.rate) + 1, n)
            count = min(due - self.sample, self.CHUNK)
            if count <= 0:
                wait = (self.sample / self.rate - self.pacer.position()) / self.pacer.speed
                with self._cond:
                    self._cond.wait(min(max(wait, 0.0005), 0.01))
                continue
            k = self.sample
            fr = codec.encode_imu(
                self.gyr[k : k + count],
                self.acc[k : k + count],
                self.mag[k : k + count],
                counter0=self.sent & 0xF,
                fd=self.fd,
            )
            for msg in to_messages(fr):
                self._send(msg)
            if self.truth is not None:
                state.set_truth(self.truth[k + count - 1])
            self.sample += count
            self.sent += count
            if due - self.sample > self.rate * 0.5:  # more than half a second behind: do not catch up
                self.pacer.anchor(self.sample / self.rate)

    def send(self, msg: can.Message) -> None:
        """Send a command (at its DBC ID) to the node, through the view's bus."""
        self.view.send(msg)

    def control(self, action: str, value: Any = None) -> None:
        """Pause, play, seek (s; the node is reset), speed (factor)."""
        state = self.state
        assert state is not None
        seek = self.pacer.control(action, value, self.sample / self.rate)
        with self._cond:
            if seek is not None:
                self._seek_to = seek
            self._cond.notify_all()
        if action in ("pause", "play", "seek"):
            state.set_source(state="paused" if self.pacer.paused else "running")
        self._publish()
