"""``attica view --log``: a CAN log played back (:class:`LogSource`).

A log (candump ``-L`` .log, .asc, .blf ... read by :func:`attica.can.logs.read_log`) is played at its own
pace times ``speed``, with pause and seek. The frames are kept compactly (about 30 bytes per classic
frame) and keep their recorded time stamps, so frames/s, bus load and latency are the recording's at any
speed. A seek starts the counters anew (the frames skipped are not losses). A line that cannot be read
ends the log there: what came before it plays, the error is shown.
"""

from __future__ import annotations

import array
import bisect
import logging
import threading
import time
from pathlib import Path
from typing import Any

import can

from attica.view.sources import Source, SourceError, _Pacer, _speed
from attica.view.state import ViewState

__all__ = ["LogSource"]

log = logging.getLogger("attica.view")


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
