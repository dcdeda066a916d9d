"""Where ``attica view`` gets its frames: a live bus, a log played back, or the simulator with the C node.

- :class:`BusSource`: any python-can bus (:func:`attica.can.bus.open_config`: virtual, socketcan,
  udp_multicast ...). A receive thread (:class:`attica.can.bus.BusReader`) takes the frames off the
  socket as they come, and a second thread feeds them to the :class:`~attica.view.state.ViewState`, so
  nothing the page does can make the socket overflow. A bus that fails (an interface that vanished, a
  closed bus) is shown on the page and logged, then opened again every ``retry`` s until it works.
- :class:`LogSource`: a log (candump ``-L`` .log, .asc, .blf ... read by :func:`attica.can.logs.read_log`)
  played at its own pace times ``speed``, with pause and seek. The frames are kept compactly (about 30
  bytes per classic frame) and keep their recorded time stamps, so frames/s, bus load and latency are
  the recording's at any speed. A seek starts the counters anew (the frames skipped are not losses).
  A line that cannot be read ends the log there: what came before it plays, the error is shown.
- :class:`ImuSource`: the simulator (``attica view --demo``) or a recording's IMU samples, encoded as
  IMU frames (:func:`attica.can.codec.encode_imu`) and sent in real time times ``speed`` to the C node
  (:class:`attica.can.node.Node`, run by :class:`attica.can.runner.NodeRunner`) on a python-can bus;
  the view reads that bus like any other (:class:`BusSource`), so the page's commands reach the C node
  the way they reach a real one. The true attitude, when known, goes to the page as the ghost. At the
  end the samples start again from the first and the node is reset (CMD 2); a seek resets it too.

Every source can be paused, sped up or slowed down (``control``) except a live bus.
"""

from __future__ import annotations

import array
import bisect
import logging
import math
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import can
import numpy as np
from numpy.typing import NDArray

from attica.can import codec
from attica.can.bus import BusConfig, BusOpenError, BusReader, open_config, to_messages
from attica.can.idoffset import to_bus
from attica.view.state import ViewState

__all__ = ["SPEEDS", "BusSource", "ImuSource", "LogSource", "Source", "SourceError"]

log = logging.getLogger("attica.view")

SPEEDS = (0.1, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0)
"""Playback speeds the page offers (any value in 0.01 .. 1000 is accepted)."""


class SourceError(Exception):
    """A request the source cannot do (a command on a log, a seek on a live bus, a bad value)."""


class Source:
    """What every source does; see the module's documentation for each kind."""

    kind = "none"
    can_send = False

    def __init__(self) -> None:
        self.state: ViewState | None = None
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []

    def describe(self) -> str:
        """One line for the page and the terminal."""
        return self.kind

    def start(self, state: ViewState) -> None:
        """Start feeding ``state`` (returns at once; the work runs in threads)."""
        self.state = state
        with state.lock:
            state.can_command = self.can_send
        state.set_source(kind=self.kind, text=self.describe(), state="starting", error=None)

    def _thread(self, target: Callable[[], None], name: str) -> None:
        t = threading.Thread(target=self._guard(target), name=name, daemon=True)
        self._threads.append(t)
        t.start()

    def _guard(self, target: Callable[[], None]) -> Callable[[], None]:
        def run() -> None:
            try:
                target()
            except Exception as exc:  # the server stays up; the page says what stopped
                log.exception("%s stopped", self.kind)
                if self.state is not None:
                    self.state.set_source(
                        state="error", error=f"{self.kind} stopped: {type(exc).__name__}: {exc}"
                    )

        return run

    def stop(self) -> None:
        """Stop the threads (waits for them)."""
        self._stop.set()
        for t in self._threads:
            t.join(3.0)

    def send(self, msg: can.Message) -> None:
        """Send a frame (a command) at its DBC ID; SourceError where there is no bus to send on."""
        raise SourceError(f"a {self.kind} cannot take commands (they need a live bus)")

    def control(self, action: str, value: Any = None) -> None:
        """Playback: ``pause``, ``play``, ``seek`` (s from the start), ``speed`` (factor)."""
        raise SourceError(f"a {self.kind} cannot be paused or moved")


def _speed(value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SourceError(f"speed must be a number, got {value!r}") from None
    if not (0.01 <= v <= 1000.0):
        raise SourceError(f"speed must be within 0.01 .. 1000, got {v:g}")
    return v


class _Pacer:
    """Maps wall time to a position (s from the start) at ``speed``, with pause and seek (thread-safe)."""

    def __init__(self, duration: float, speed: float = 1.0, paused: bool = False) -> None:
        self.duration = duration
        self.speed = speed
        self.paused = paused
        self._pos = 0.0
        self._wall = time.monotonic()
        self._lock = threading.Lock()

    def position(self, now: float | None = None) -> float:
        with self._lock:
            if self.paused:
                return self._pos
            now = time.monotonic() if now is None else now
            return self._pos + (now - self._wall) * self.speed

    def anchor(self, pos: float) -> None:
        with self._lock:
            self._anchor(pos)

    def _anchor(self, pos: float) -> None:
        self._pos = pos
        self._wall = time.monotonic()

    def control(self, action: str, value: Any, actual: float) -> float | None:
        """Apply a control at the actual position; returns the position to seek to, or None."""
        with self._lock:
            return self._control(action, value, actual)

    def _control(self, action: str, value: Any, actual: float) -> float | None:
        if action == "pause":
            self._anchor(actual)
            self.paused = True
        elif action == "play":
            self._anchor(actual)
            self.paused = False
        elif action == "speed":
            self.speed = _speed(value)
            self._anchor(actual)
        elif action == "seek":
            try:
                t = float(value)
            except (TypeError, ValueError):
                raise SourceError(f"seek needs a time in s, got {value!r}") from None
            if not math.isfinite(t):
                raise SourceError(f"seek needs a finite time, got {value!r}")
            t = min(max(t, 0.0), self.duration)
            self._anchor(t)
            return t
        else:
            raise SourceError(f"unknown playback action {action!r}: pause, play, seek, speed")
        return None

    def as_json(self, position: float, **extra: Any) -> dict[str, Any]:
        return {
            "position": position,
            "duration": self.duration,
            "speed": self.speed,
            "paused": self.paused,
            **extra,
        }


# --- a live bus -------------------------------------------------------------------------------------


class BusSource(Source):
    """A python-can bus, read in a thread and fed to the view (see the module's documentation).

    Parameters
    ----------
    config
        The bus (:func:`attica.can.bus.resolve_config`); opened as it is: the view checks the frames
        at bus ID - ``id_offset`` itself, and sends its commands at bus IDs.
    id_offset
        The node's CAN ID offset.
    retry
        Seconds between attempts to open a bus that failed.
    silent_after
        Seconds without a frame after which the page says the bus is silent.

    """

    kind = "bus"
    can_send = True

    def __init__(
        self, config: BusConfig, id_offset: int = 0, retry: float = 1.0, silent_after: float = 2.0
    ) -> None:
        super().__init__()
        self.config = config
        self.id_offset = id_offset
        self.retry = retry
        self.silent_after = silent_after
        self.bus: can.BusABC | None = None
        self.reader: BusReader | None = None
        self.frames = 0
        self.reopened = 0
        self._send_lock = threading.Lock()
        self.opened = threading.Event()
        self.running_state: Callable[[], str] = lambda: "running"
        """The state the page shows while the bus works (an owner that can pause says "paused")."""
        self.expect_quiet: Callable[[], bool] = lambda: False
        """True while silence is expected (a paused demo): no "silent" warning then."""

    def describe(self) -> str:
        """``interface:channel`` and the ID offset."""
        text = self.config.describe()
        return f"{text}, ID offset {self.id_offset:+d}" if self.id_offset else text

    def start(self, state: ViewState) -> None:
        """Open the bus (or keep trying) and feed ``state`` from it."""
        super().start(state)
        self._thread(self._run, "attica-view-bus")

    def _open(self) -> bool:
        assert self.state is not None
        try:
            bus = open_config(self.config)
        except BusOpenError as exc:
            self.state.set_source(state="error", error=f"{exc}; trying again every {self.retry:g} s")
            return False
        self.bus = bus
        self.reader = BusReader(bus)
        self.opened.set()
        self.state.set_source(state=self.running_state(), error=None)
        log.info("reading %s", self.describe())
        return True

    def _close(self) -> None:
        reader, bus = self.reader, self.bus
        self.reader = None
        self.bus = None
        if reader is not None:
            try:
                rest = reader.stop()
            except Exception:  # a failed bus fails again when drained: what it held is gone
                rest = []
            if self.state is not None:
                self.state.feed_many(rest)
                self.state.dropped += reader.dropped
        if bus is not None:
            try:
                bus.shutdown()
            except Exception:  # shutting down a broken bus may fail too: it is gone either way
                log.debug("shutdown of a failed bus", exc_info=True)

    def _run(self) -> None:
        state = self.state
        assert state is not None
        silent = False
        try:
            while not self._stop.is_set():
                if self.reader is None:
                    if not self._open():
                        self._stop.wait(self.retry)
                        continue
                    if self.frames or self.reopened:
                        self.reopened += 1
                        state.note("info", f"bus {self.describe()} open again")
                    else:
                        self.reopened = 0
                reader = self.reader
                assert reader is not None
                try:
                    msg = reader.get(0.1)
                except Exception as exc:  # the bus failed under the reader: say so, open it again
                    state.set_source(
                        state="error",
                        error=f"bus {self.describe()} failed: {type(exc).__name__}: {exc}; "
                        f"opening it again every {self.retry:g} s",
                    )
                    self._close()
                    self.reopened = max(self.reopened, 1)
                    self._stop.wait(self.retry)
                    continue
                if msg is None:
                    quiet = state.health_silence()
                    if self.expect_quiet():
                        silent = False
                    elif quiet is not None and quiet > self.silent_after and not silent:
                        silent = True
                        state.set_source(state="silent")
                        state.note("warning", f"no frame on {self.describe()} for {self.silent_after:g} s")
                    continue
                batch = [msg]
                while len(batch) < 4096:
                    try:
                        more = reader.get(0.0)
                    except Exception:
                        break  # reported at the next get
                    if more is None:
                        break
                    batch.append(more)
                state.feed_many(batch)
                self.frames += len(batch)
                if silent:
                    silent = False
                    state.set_source(state=self.running_state())
        finally:
            self._close()

    def send(self, msg: can.Message) -> None:
        """Send ``msg`` (at its DBC ID) at its bus ID."""
        bus = self.bus
        if bus is None:
            raise SourceError(f"bus {self.describe()} is not open")
        with self._send_lock:
            try:
                bus.send(to_bus(msg, self.id_offset), timeout=0.5)
            except (can.CanError, OSError, ValueError) as exc:
                raise SourceError(f"cannot send on {self.describe()}: {exc}") from None


# --- a log played back ------------------------------------------------------------------------------


class _LogFrames:
    """Frames of a log, compact: time stamps, IDs, flags, lengths and one buffer of data bytes."""

    FD, BRS, ESI, EXT, ERR, RTR = 1, 2, 4, 8, 16, 32

    def __init__(self) -> None:
        self.ts = array.array("d")
        self.ids = array.array("I")
        self.flags = array.array("B")
        self.lens = array.array("B")
        self.offs = array.array("q")
        self.data = bytearray()
        self.channel = "can0"

    def __len__(self) -> int:
        return len(self.ts)

    def add(self, m: can.Message) -> None:
        self.ts.append(float(m.timestamp or 0.0))
        self.ids.append(int(m.arbitration_id))
        self.flags.append(
            (self.FD if m.is_fd else 0)
            | (self.BRS if m.bitrate_switch else 0)
            | (self.ESI if m.error_state_indicator else 0)
            | (self.EXT if m.is_extended_id else 0)
            | (self.ERR if m.is_error_frame else 0)
            | (self.RTR if m.is_remote_frame else 0)
        )
        data = bytes(m.data)
        self.lens.append(len(data))
        self.offs.append(len(self.data))
        self.data += data
        if m.channel is not None and len(self) == 1:
            self.channel = str(m.channel)

    def message(self, i: int) -> can.Message:
        f = self.flags[i]
        n = self.lens[i]
        o = self.offs[i]
        return can.Message(
            timestamp=self.ts[i],
            arbitration_id=self.ids[i],
            is_extended_id=bool(f & self.EXT),
            is_fd=bool(f & self.FD),
            bitrate_switch=bool(f & self.BRS),
            error_state_indicator=bool(f & self.ESI),
            is_error_frame=bool(f & self.ERR),
            is_remote_frame=bool(f & self.RTR),
            dlc=n,
            data=bytes(self.data[o : o + n]),
            channel=self.channel,
            check=False,
        )


class LogSource(Source):
    """A log played back into the view (see the module's documentation).

    Parameters
    ----------
    path
        The log (.log candump -L, .asc, .blf, .csv, .trc).
    speed
        Initial playback speed.
    paused
        Start paused at the beginning.
    loop
        Start again from the beginning at the end (otherwise it stops there, paused).

    """

    kind = "log"
    BATCH = 2000

    def __init__(
        self, path: str | Path, speed: float = 1.0, paused: bool = False, loop: bool = False
    ) -> None:
        super().__init__()
        self.path = Path(path)
        self.loop = loop
        self.frames = _LogFrames()
        self.pacer = _Pacer(0.0, _speed(speed), paused)
        self.index = 0
        self.loaded = False
        self.played = 0
        self._cond = threading.Condition()
        self._seek_to: float | None = None

    def describe(self) -> str:
        """The log's name."""
        return f"log {self.path.name}"

    def start(self, state: ViewState) -> None:
        """Read the log, then play it."""
        super().start(state)
        state.playback = self.pacer.as_json(0.0, loading=True, frames=0, ended=False)
        self._thread(self._run, "attica-view-log")

    def _load(self) -> None:
        from attica.can.logs import LogError, read_log

        state = self.state
        assert state is not None
        state.set_source(state="loading")
        try:
            for m in read_log(self.path):
                self.frames.add(m)
                if len(self.frames) % 100_000 == 0:
                    with state.lock:
                        state.playback = self.pacer.as_json(
                            0.0, loading=True, frames=len(self.frames), ended=False
                        )
                if self._stop.is_set():
                    return
        except LogError as exc:
            n = len(self.frames)
            state.set_source(error=f"{exc} (playing the {n} frames before it)" if n else str(exc))
        t = self.frames.ts
        self.pacer.duration = (t[-1] - t[0]) if len(t) else 0.0
        self.loaded = True
        log.info("%s: %d frames, %.3f s", self.path, len(t), self.pacer.duration)

    def _position(self) -> float:
        t = self.frames.ts
        if not len(t) or self.index == 0:
            return 0.0
        return t[min(self.index, len(t)) - 1] - t[0]

    def _publish(self) -> None:
        state = self.state
        assert state is not None
        ended = self.index >= len(self.frames)
        with state.lock:
            state.playback = self.pacer.as_json(
                self._position(), loading=False, frames=len(self.frames), index=self.index, ended=ended
            )

    def _run(self) -> None:
        state = self.state
        assert state is not None
        self._load()
        if self._stop.is_set():
            return
        fr = self.frames
        n = len(fr)
        if n == 0:
            state.set_source(state="ended")
            self._publish()
            return
        t0 = fr.ts[0]
        state.set_source(state="paused" if self.pacer.paused else "running")
        self.pacer.anchor(0.0)
        last_publish = 0.0
        while not self._stop.is_set():
            with self._cond:
                seek = self._seek_to
                self._seek_to = None
            if seek is not None:
                self.index = bisect.bisect_left(fr.ts, t0 + seek)
                state.reset(f"seek to {seek:.3f} s of {self.path.name}")
                self.pacer.anchor(seek)
            now = time.monotonic()
            if now - last_publish > 0.05:
                self._publish()
                last_publish = now
            if self.index >= n:
                if self.loop:
                    with self._cond:
                        self._seek_to = 0.0
                    continue
                if not self.pacer.paused:
                    self.pacer.control("pause", None, self._position())
                    state.set_source(state="ended")
                    state.note("info", f"{self.path.name}: end of the log ({n} frames)")
                    self._publish()
                with self._cond:
                    self._cond.wait(0.1)
                continue
            if self.pacer.paused:
                with self._cond:
                    self._cond.wait(0.1)
                continue
            pos = self.pacer.position()
            due = bisect.bisect_right(fr.ts, t0 + pos, lo=self.index)
            if due == self.index:
                wait = (fr.ts[self.index] - t0 - pos) / self.pacer.speed
                with self._cond:
                    self._cond.wait(min(max(wait, 0.0005), 0.05))
                continue
            stop = min(due, self.index + self.BATCH)
            state.feed_many([fr.message(i) for i in range(self.index, stop)])
            self.played += stop - self.index
            self.index = stop
            if due - stop > self.BATCH * 20:  # far behind: this machine plays slower than asked
                self.pacer.anchor(self._position())

    def control(self, action: str, value: Any = None) -> None:
        """Pause, play, seek (s), speed (factor)."""
        if not self.loaded:
            raise SourceError("the log is still being read")
        state = self.state
        assert state is not None
        if action == "play" and self.index >= len(self.frames):
            with self._cond:
                self._seek_to = 0.0
        seek = self.pacer.control(action, value, self._position())
        with self._cond:
            if seek is not None:
                self._seek_to = seek
            self._cond.notify_all()
        if action in ("pause", "play", "seek"):
            state.set_source(state="paused" if self.pacer.paused else "running")
        self._publish()


# --- the simulator (or a recording) through the C node ----------------------------------------------


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
