"""A candump-style view of an attica bus (or a log), decoded with the DBC, with E2E checks and bus load.

Each frame gives one line: the ``candump -L`` text of the frame, then the message name and its signals
decoded by cantools from firmware/can/attica.dbc (or ``--dbc``), then any problem found::

    (1700000000.123456) vcan0 203#6B1300F0FF0400FF  ATT_EULER crc=107 counter=3 roll=-0.0009765625 ...
    (1700000000.123789) vcan0 100#2A0500000000FFFF  IMU_GYRO crc=42 ... !CRC
    (1700000000.124001) vcan0 101#...  IMU_ACC ... !GAP+2

Problems: ``!CRC`` (E2E CRC wrong; for ATT_STATUS of an output set over the set's quaternion frames),
``!GAP+n`` (n frames of this ID missing by the alive counter), ``!DUP`` (counter repeated),
``!DLC`` (length or CAN FD format wrong for the ID), ``!UNKNOWN`` (not in the DBC). The counters and
the bus load (worst-case bit stuffing, as the node computes it) are summed up at the end and, when
watching a bus, every ``stats_every`` seconds.

Logs: ``--write`` writes what is seen with python-can's writers: ``.log`` (candump -L format, readable
by ``candump``'s tools, ``cantools decode`` and ``canplayer``), ``.asc``, ``.blf`` (and whatever else
``can.Logger`` knows). ``--log`` reads a log instead of a bus: ``.log`` with our own parser (errors name
the line), other formats with ``can.LogReader``.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can

from attica.can import codec

__all__ = [
    "LogError",
    "LogMessage",
    "Monitor",
    "MonitorError",
    "candump_text",
    "format_value",
    "open_writer",
    "read_log",
]


class MonitorError(Exception):
    """A user error of the monitor (missing DBC, unknown log format...)."""


class LogError(MonitorError):
    """A log file could not be read (the message names the file and line)."""


class LogMessage(can.Message):
    """A frame read from a candump log; keeps the log's CAN FD flags digit (e.g. 5 = BRS | FDF)."""

    __slots__ = ("fd_flags",)

    fd_flags: int | None


def candump_text(msg: can.Message, channel: str | None = None) -> str:
    """The ``candump -L`` text of a frame: ``(ts) channel ID#DATA`` (CAN FD: ``ID##<flags>DATA``)."""
    ch = msg.channel if msg.channel is not None else channel
    if ch is None or ch == "":
        ch = "can0"
    if isinstance(ch, int):
        ch = f"can{ch}"
    ts = msg.timestamp or 0.0
    if msg.is_error_frame:
        return f"({ts:.6f}) {ch} 20000080#{bytes(msg.data).hex().upper()}"
    ident = f"{msg.arbitration_id:08X}" if msg.is_extended_id else f"{msg.arbitration_id:03X}"
    if msg.is_remote_frame:
        return f"({ts:.6f}) {ch} {ident}#R"
    data = bytes(msg.data).hex().upper()
    if msg.is_fd:
        flags = getattr(msg, "fd_flags", None)
        if flags is None:
            flags = (1 if msg.bitrate_switch else 0) | (2 if msg.error_state_indicator else 0)
        return f"({ts:.6f}) {ch} {ident}##{flags:X}{data}"
    return f"({ts:.6f}) {ch} {ident}#{data}"


def format_value(v: Any) -> str:
    """A decoded signal value as text: choices by name, floats in Python's shortest exact repr."""
    if isinstance(v, bool):
        return str(int(v))
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else repr(v)
    return str(v)


# --- logs -----------------------------------------------------------------------------------------

_CANDUMP = re.compile(
    r"^\((?P<ts>\d+(?:\.\d*)?)\)\s+(?P<ch>\S+)\s+(?P<id>[0-9A-Fa-f]{1,8})#(?P<rest>\S*)(?:\s+(?P<dir>[RrTt]))?$"
)


def _parse_candump(line: str) -> can.Message:
    m = _CANDUMP.match(line)
    if m is None:
        raise ValueError("expected '(timestamp) channel ID#DATA' (candump -L format)")
    ident = m.group("id")
    rest = m.group("rest")
    can_id = int(ident, 16)
    extended = len(ident) > 3
    if not extended and can_id > 0x7FF:
        raise ValueError(f"standard ID {ident} is above 7FF")
    fd = False
    brs = esi = False
    flags = None
    remote = False
    if rest.startswith("#"):
        fd = True
        if len(rest) < 2 or rest[1] not in "0123456789ABCDEFabcdef":
            raise ValueError("CAN FD frame without its flags digit after '##'")
        flags = int(rest[1], 16)
        brs, esi = bool(flags & 1), bool(flags & 2)
        rest = rest[2:]
    if rest[:1] in ("R", "r") and not fd:
        remote = True
        data = b""
    else:
        if len(rest) % 2:
            raise ValueError(f"odd number of hex digits in the data {rest!r}")
        try:
            data = bytes.fromhex(rest)
        except ValueError:
            raise ValueError(f"data {rest!r} is not hex") from None
    if len(data) > (64 if fd else 8):
        raise ValueError(f"{len(data)} data bytes is too long for a {'CAN FD' if fd else 'classic'} frame")
    if fd and len(data) not in (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64):
        raise ValueError(f"{len(data)} bytes is not a valid CAN FD length")
    is_err = extended and bool(can_id & 0x20000000)
    ch: str | int = m.group("ch")
    msg = LogMessage(
        timestamp=float(m.group("ts")),
        arbitration_id=can_id & 0x1FFFFFFF,
        is_extended_id=extended,
        is_remote_frame=remote,
        is_error_frame=is_err,
        is_fd=fd,
        bitrate_switch=brs,
        error_state_indicator=esi,
        dlc=len(data),
        data=data,
        channel=ch,
        is_rx=(m.group("dir") or "R").upper() == "R",
        check=False,
    )
    msg.fd_flags = flags
    return msg


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
        with open(p, encoding="utf-8", errors="replace") as fh:
            for lineno, raw in enumerate(fh, 1):
                line = raw.strip()
                if not line or line.startswith("#"):
                    continue
                try:
                    yield _parse_candump(line)
                except ValueError as exc:
                    raise LogError(f"{p}:{lineno}: bad log line {line[:80]!r}: {exc}") from None
        return
    try:
        reader = can.LogReader(p)
    except ValueError as exc:
        raise LogError(
            f"{p}: cannot read this log format ({exc}); use .log, .asc, .blf, .csv or .trc"
        ) from None
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
    MonitorError
        Unknown suffix or a file that cannot be created.

    """
    p = Path(path)
    kwargs: dict[str, Any] = {}
    if p.suffix.lower() == ".log":
        kwargs["channel"] = channel
    try:
        return can.Logger(p, **kwargs)
    except ValueError as exc:
        raise MonitorError(f"cannot write {p}: {exc} (use .log for candump -L, .asc or .blf)") from None
    except OSError as exc:
        raise MonitorError(f"cannot write {p}: {exc}") from None


# --- the monitor ----------------------------------------------------------------------------------


@dataclass
class MonitorStats:
    """What the monitor counted."""

    frames: int = 0
    by_name: dict[str, int] = field(default_factory=dict)
    crc_errors: int = 0
    crc_unchecked: int = 0
    counter_gaps: int = 0
    missing_frames: int = 0
    repeats: int = 0
    dlc_errors: int = 0
    unknown_ids: int = 0
    other: int = 0  # error, remote and extended-ID frames
    bus_time: float = 0.0  # s of bus time used (worst-case stuffing)
    first_ts: float | None = None
    last_ts: float | None = None

    @property
    def span(self) -> float:
        """Seconds between the first and the last frame."""
        if self.first_ts is None or self.last_ts is None:
            return 0.0
        return self.last_ts - self.first_ts


class Monitor:
    """Decodes and checks frames one by one.

    Parameters
    ----------
    dbc
        DBC file (default firmware/can/attica.dbc).
    bitrate, data_bitrate
        For the bus load (worst-case bit stuffing, CAN FD data phase at ``data_bitrate``).
    channel
        Channel name used when a frame carries none.
    decode
        False: candump text and checks only.

    """

    def __init__(
        self,
        dbc: str | os.PathLike[str] | None = None,
        bitrate: int = 500_000,
        data_bitrate: int = 2_000_000,
        channel: str = "can0",
        decode: bool = True,
    ) -> None:
        import cantools

        path = Path(dbc) if dbc is not None else codec.DBC_PATH
        if not path.is_file():
            raise MonitorError(f"DBC file not found: {path}")
        try:
            db = cantools.database.load_file(str(path))
        except Exception as exc:  # cantools raises many kinds of parse errors
            raise MonitorError(f"cannot load the DBC {path}: {exc}") from None
        if not isinstance(db, cantools.database.can.Database):
            raise MonitorError(f"{path} is not a CAN database")
        self.db = db
        self.dbc_path = path
        self.bitrate = bitrate
        self.data_bitrate = data_bitrate
        self.channel = channel
        self.decode_signals = decode
        self.stats = MonitorStats()
        self._last_counter: dict[int, int] = {}
        self._quat: dict[int, can.Message] = {}

    def signals(self, msg: can.Message) -> tuple[str, dict[str, Any]] | None:
        """(message name, decoded signals) by the DBC, or None when the ID is not in it / cannot decode."""
        try:
            m = self.db.get_message_by_frame_id(msg.arbitration_id)
        except KeyError:
            return None
        try:
            values = m.decode(bytes(msg.data), decode_choices=True, scaling=True)
        except Exception:  # wrong length and the like: reported as DLC by the checks
            return m.name, {}
        assert isinstance(values, dict)
        return m.name, dict(values)

    def _frame_time(self, msg: can.Message) -> float:
        n = len(msg.data)
        if msg.is_fd:
            return codec.fd_frame_time(
                n, self.bitrate, self.data_bitrate if msg.bitrate_switch else self.bitrate
            )
        return codec.classic_bits(n) / self.bitrate

    def check(self, msg: can.Message) -> list[str]:
        """The problems of one frame (updates the counters)."""
        st = self.stats
        probs: list[str] = []
        if msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id:
            st.other += 1
            return ["!OTHER"]
        can_id = msg.arbitration_id
        if can_id not in codec.MSG_LEN:
            st.unknown_ids += 1
            return ["!UNKNOWN"]
        res = codec.check(msg)
        if res == codec.Check.DLC:
            st.dlc_errors += 1
            return ["!DLC"]
        data = bytes(msg.data)
        answer = can_id == codec.ID_STATUS and bool(data[7] & codec.ACK_ANSWER)
        if can_id in codec.NO_CRC:
            self._quat[can_id] = msg
        elif can_id == codec.ID_STATUS and not answer:
            parts = [self._quat.get(i) for i in (codec.ID_QUAT_A, codec.ID_QUAT_B, codec.ID_QUAT16)]
            if any(p is None for p in parts):
                st.crc_unchecked += 1
                probs.append("?CRC")
            elif not codec.check_status_set(msg, *parts):
                st.crc_errors += 1
                probs.append("!CRC")
            self._quat.clear()
        elif res == codec.Check.CRC:
            st.crc_errors += 1
            probs.append("!CRC")
        if (
            can_id not in codec.NO_CRC
            and can_id not in (codec.ID_DIAG, codec.ID_CMD)
            and not answer
            and not probs
        ):
            c = data[1] & 0xF
            last = self._last_counter.get(can_id)
            if last is not None:
                missing = (c - last - 1) & 0xF
                if missing == 15:
                    st.repeats += 1
                    probs.append("!DUP")
                elif missing:
                    st.counter_gaps += 1
                    st.missing_frames += missing
                    probs.append(f"!GAP+{missing}")
            self._last_counter[can_id] = c
        return probs

    def feed(self, msg: can.Message) -> str:
        """Account for one frame and return its line."""
        st = self.stats
        st.frames += 1
        ts = msg.timestamp or 0.0
        if st.first_ts is None:
            st.first_ts = ts
        st.last_ts = ts
        if not msg.is_error_frame:
            st.bus_time += self._frame_time(msg)
        text = candump_text(msg, self.channel)
        probs = self.check(msg)
        dec = (
            self.signals(msg)
            if not (msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id)
            else None
        )
        if dec is not None:
            name, values = dec
            st.by_name[name] = st.by_name.get(name, 0) + 1
            if self.decode_signals:
                text += "  " + name
                if values:
                    text += " " + " ".join(f"{k}={format_value(v)}" for k, v in values.items())
        if probs:
            text += "  " + " ".join(probs)
        return text

    def bus_load(self) -> float:
        """Fraction of the bus time used over the frames seen (0 when less than two timestamps)."""
        span = self.stats.span
        return self.stats.bus_time / span if span > 0 else 0.0

    def summary(self) -> list[str]:
        """Counters and bus load."""
        st = self.stats
        rate = st.frames / st.span if st.span > 0 else 0.0
        names = ", ".join(f"{k} {v}" for k, v in sorted(st.by_name.items()))
        return [
            f"{st.frames} frames in {st.span:.3f} s ({rate:.0f} frames/s), "
            f"bus load {100 * self.bus_load():.1f} % of {self.bitrate / 1000:g} kbit/s "
            f"(CAN FD data phase {self.data_bitrate / 1e6:g} Mbit/s)",
            f"crc errors {st.crc_errors} (unchecked {st.crc_unchecked}), counter gaps {st.counter_gaps} "
            f"({st.missing_frames} frames missing), repeats {st.repeats}, dlc errors {st.dlc_errors}, "
            f"unknown ids {st.unknown_ids}, other frames {st.other}",
            f"messages: {names or 'none'}",
        ]


def decoded_fields(line: str) -> tuple[str, str, dict[str, str]]:
    """Split a monitor line into (candump text, message name, {signal: value text}) (for comparisons)."""
    head, _, rest = line.partition("  ")
    parts = rest.split()
    if not parts or parts[0].startswith(("!", "?")):
        return head, "", {}
    name = parts[0]
    values = {}
    for p in parts[1:]:
        if "=" in p:
            k, _, v = p.partition("=")
            values[k] = v
    return head, name, values


def same_value(a: str, b: str) -> bool:
    """Two signal value texts equal (numbers compared as floats, NaN == NaN; names as text)."""
    try:
        x, y = float(a), float(b)
    except ValueError:
        return a == b
    return (math.isnan(x) and math.isnan(y)) or x == y
