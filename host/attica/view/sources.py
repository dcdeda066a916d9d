"""Where ``attica view`` gets its frames: the sources' common part and a live bus.

- :class:`Source`: what every source offers the server (start, stop, ``control``: pause, seek, speed).
- :class:`BusSource`: any python-can bus (:func:`attica.can.bus.open_config`: virtual, socketcan,
  udp_multicast ...). A receive thread (:class:`attica.can.bus.BusReader`) takes the frames off the
  socket as they come, and a second thread feeds them to the :class:`~attica.view.state.ViewState`, so
  nothing the page does can make the socket overflow. A bus that fails (an interface that vanished, a
  closed bus) is shown on the page and logged, then opened again every ``retry`` s until it works.

A log played back is :class:`attica.view.playback.LogSource`, the simulator or a recording through the C
node :class:`attica.view.demo.ImuSource`. Every source can be paused, sped up or slowed down
(``control``) except a live bus.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from typing import Any

import can

from attica.can.bus import BusConfig, BusOpenError, BusReader, open_config
from attica.can.idoffset import to_bus
from attica.view.state import ViewState

__all__ = ["SPEEDS", "BusSource", "Source", "SourceError"]

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
