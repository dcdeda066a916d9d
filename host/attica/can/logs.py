"""Bus logs: read and write candump -L (.log), .asc, .blf ... with python-can's readers and writers.

- :func:`read_log`: frames of a log. ``.log`` (candump -L) is read with python-can's
  ``CanutilsLogReader`` through a line counter, so that a bad line is reported as ``file:line`` with
  the line's text, and every frame is checked (standard ID <= 7FF, classic <= 8 bytes, CAN FD lengths);
  other formats with ``can.LogReader``.
- :func:`open_writer`: a python-can writer by suffix (``.log`` is ``CanutilsLogWriter``).
- :class:`LogTee`: logs both directions of a session (frames sent, stamped at sending, and frames
  received), for ``attica replay --write`` and ``attica verify --with-node --write``; with the node's ID
  offset it writes the frames at their bus IDs (:mod:`attica.can.idoffset`).
"""

from __future__ import annotations

import copy
import os
import re
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import IO, Any

import can
from can.io.canutils import CanutilsLogReader

from attica.can.idoffset import to_bus

__all__ = ["LOG_SUFFIXES", "LogError", "LogMessage", "LogTee", "open_writer", "read_log"]

LOG_SUFFIXES = (".log", ".asc", ".blf", ".csv", ".trc")
"""Log formats read and written (by python-can)."""

_FD_LENGTHS = frozenset({0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64})

_CANDUMP_LINE = re.compile(
    r"\(\d+(?:\.\d*)?\)\s+\S+\s+[0-9A-Fa-f]{1,8}#"
    r"(?:[Rr]\d?|#[0-9A-Fa-f](?:[0-9A-Fa-f]{2})*|(?:[0-9A-Fa-f]{2})*)(?:\s+[RTrt])?"
)
"""A candump -L line: ``(seconds) channel ID#DATA`` with whole bytes of hex (``ID##<flags>DATA`` for
CAN FD, ``ID#R[dlc]`` for a remote frame), optionally ``R``/``T`` for the direction. python-can's reader
is lenient (an odd number of hex digits gives a frame whose dlc disagrees with its data, a timestamp
without parentheses or a ``+`` in the data is taken), so each line is matched against this first."""


class LogError(Exception):
    """A log file could not be read or written (the message names the file and, for .log, the line)."""


class LogMessage(can.Message):
    """A CAN FD frame read from a candump log, with the log's flags digit (e.g. 5 = FDF | BRS).

    python-can keeps only BRS and ESI of that digit; candump (can-utils) also writes the FDF bit, and
    the monitor prints the frame as the log has it.
    """

    __slots__ = ("fd_flags",)

    fd_flags: int


def _with_fd_flags(msg: can.Message, line: str) -> can.Message:
    """``msg`` as a :class:`LogMessage` when its line's flags digit says more than BRS and ESI."""
    fields = line.split()  # "(timestamp) channel id##<flags><data>", as python-can splits it
    if len(fields) < 3:
        return msg
    _, sep, rest = fields[2].partition("##")
    if not sep or not rest or rest[0] not in "0123456789abcdefABCDEF":
        return msg
    flags = int(rest[0], 16)
    if flags == (1 if msg.bitrate_switch else 0) | (2 if msg.error_state_indicator else 0):
        return msg
    out = LogMessage(
        timestamp=msg.timestamp,
        arbitration_id=msg.arbitration_id,
        is_extended_id=msg.is_extended_id,
        is_fd=True,
        is_rx=msg.is_rx,
        bitrate_switch=msg.bitrate_switch,
        error_state_indicator=msg.error_state_indicator,
        dlc=msg.dlc,
        data=msg.data,
        channel=msg.channel,
        check=False,
    )
    out.fd_flags = flags
    return out


class _Lines:
    """A text file iterated line by line for CanutilsLogReader, remembering the line last handed out.

    Comment lines (``#``) are skipped (python-can's reader would fail on them).
    """

    def __init__(self, fh: IO[str]) -> None:
        self._fh = fh
        self.lineno = 0
        self.line = ""

    def __iter__(self) -> Iterator[str]:
        for raw in self._fh:
            self.lineno += 1
            if raw.lstrip().startswith("#"):
                continue
            self.line = raw.strip()
            yield raw

    def close(self) -> None:
        self._fh.close()


def _problem(msg: can.Message) -> str:
    """Why a frame read from a candump log is not a valid CAN frame ("" when it is)."""
    n = len(msg.data)
    if not msg.is_extended_id and not msg.is_error_frame and msg.arbitration_id > 0x7FF:
        return f"standard ID {msg.arbitration_id:03X} is above 7FF"
    if n > (64 if msg.is_fd else 8):
        return f"{n} data bytes is too long for a {'CAN FD' if msg.is_fd else 'classic'} frame"
    if msg.is_fd and n not in _FD_LENGTHS:
        return f"{n} bytes is not a valid CAN FD length"
    return ""


def _read_candump(p: Path) -> Iterator[can.Message]:
    lines = _Lines(open(p, encoding="utf-8", errors="replace"))
    reader = CanutilsLogReader(lines)  # type: ignore[arg-type]  # any iterable of lines will do
    it = iter(reader)
    try:
        while True:
            try:
                msg = next(it)
            except StopIteration:
                return
            except (ValueError, IndexError) as exc:
                why = str(exc) or type(exc).__name__
                raise LogError(
                    f"{p}:{lines.lineno}: bad log line {lines.line[:80]!r}: {why} "
                    "(expected '(timestamp) channel ID#DATA', the candump -L format)"
                ) from None
            if not _CANDUMP_LINE.fullmatch(lines.line):
                raise LogError(
                    f"{p}:{lines.lineno}: bad log line {lines.line[:80]!r}: not in the candump -L format "
                    "(expected '(timestamp) channel ID#DATA' with two hex digits per data byte)"
                )
            why = _problem(msg)
            if why:
                raise LogError(f"{p}:{lines.lineno}: bad log line {lines.line[:80]!r}: {why}")
            yield _with_fd_flags(msg, lines.line) if msg.is_fd else msg
    finally:
        lines.close()


def read_log(path: str | os.PathLike[str]) -> Iterator[can.Message]:
    """Frames of a log: ``.log`` (candump -L) with line-numbered errors, other formats via python-can.

    Raises
    ------
    LogError
        Missing file, unknown format, or a line that is not a frame.

    """
    p = Path(path)
    if not p.is_file():
        raise LogError(f"no such log file: {p}")
    if p.suffix.lower() == ".log" or p.suffix == "":
        yield from _read_candump(p)
        return
    try:
        reader = can.LogReader(p)
    except ValueError as exc:
        raise LogError(f"{p}: cannot read this log format ({exc}); use {', '.join(LOG_SUFFIXES)}") from None
    try:
        yield from reader
    except Exception as exc:  # python-can readers raise anything on a bad file
        raise LogError(f"{p}: bad log file: {type(exc).__name__}: {exc}") from None
    finally:
        reader.stop()


def open_writer(path: str | os.PathLike[str], channel: str = "can0") -> can.Listener:
    """A python-can writer for ``path`` by its suffix (``.log`` = candump -L, ``.asc``, ``.blf``...).

    Raises
    ------
    LogError
        Unknown suffix or a file that cannot be created.

    """
    p = Path(path)
    kwargs: dict[str, Any] = {}
    if p.suffix.lower() == ".log":
        kwargs["channel"] = channel
    try:
        return can.Logger(p, **kwargs)
    except ValueError as exc:
        raise LogError(f"cannot write {p}: {exc} (use {', '.join(LOG_SUFFIXES)})") from None
    except OSError as exc:
        raise LogError(f"cannot write {p}: {exc}") from None


class LogTee:
    """Writes the frames of a session, both directions, to logs (python-can writers).

    Frames sent are logged as transmitted (``T`` in candump -L) with the time they were sent; frames
    received as received (``R``) with their receive time stamp (now, when they carry none).

    Parameters
    ----------
    paths
        The logs to write (:func:`open_writer`).
    channel
        Channel name of frames that carry none.
    id_offset
        The node's ID offset when the frames handed in are at the DBC's IDs (those of a bus opened with
        that offset): they are written at their bus IDs, as a candump of the bus shows them.

    """

    def __init__(
        self, paths: Sequence[str | os.PathLike[str]], channel: str = "can0", id_offset: int = 0
    ) -> None:
        self.writers: list[can.Listener] = []
        self.frames = 0
        self.id_offset = id_offset
        try:
            for path in paths:
                self.writers.append(open_writer(path, channel=channel))
        except LogError:
            self.close()
            raise
        self.channel = channel

    def _write(self, msg: can.Message, rx: bool) -> None:
        m = copy.copy(to_bus(msg, self.id_offset))
        m.is_rx = rx
        if not m.timestamp:
            m.timestamp = time.time()
        if m.channel is None:
            m.channel = self.channel
        for w in self.writers:
            w.on_message_received(m)
        self.frames += 1

    def sent(self, msg: can.Message) -> None:
        """Log a frame this process sent."""
        self._write(msg, rx=False)

    def received(self, msg: can.Message) -> None:
        """Log a frame this process received."""
        self._write(msg, rx=True)

    def close(self) -> None:
        """Flush and close every log."""
        for w in self.writers:
            w.stop()
        self.writers = []

    def __bool__(self) -> bool:
        return bool(self.writers)
