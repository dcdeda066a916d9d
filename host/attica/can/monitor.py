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
watching a bus, every ``stats_every`` seconds. A node on a Cortex-M port also reports its CAN
controller (ATT_DIAG_BUS: bus-off episodes and recoveries, error-passive and warning entries, receive
overruns, state, last error code): the summary repeats the last one with a good CRC.

Flags (ATT_STATUS, ATT_OUT_FD) are shown by name (``flags=AT_REST|BIAS_UPDATED``, ``flags=none``).

Lost frames: the alive counters are 4 bits, so they see gaps modulo 16 only; the monitor also follows
the node's 16-bit step counter (ATT_STATUS / ATT_OUT_FD). The node steps once per sample period: a
sample lost before it is integrated by the next one over the counter distance (att_node.h), so its
steps advance by the IMU sample periods, seen or not. The monitor compares them with the IMU sample
periods of this view (the samples seen and those the IMU counters show missing): when the node reports
more, the difference is samples lost from the view beyond what the alive counters show (a log cut
short, a monitor that could not keep up) and the summary says so. Output sets missing between two sets
seen: the set counter's count (modulo 16) that best fits the steps between them less the sample periods
the node integrated, as far as the IMU counters seen tell.

Watching a bus, a receive thread takes the frames off the socket as they come
(:class:`attica.can.bus.BusReader`), so a burst faster than decoding and printing waits in memory instead
of overflowing the socket buffer, and at the end (``--duration``, ``--count``, Ctrl-C) every frame
already received is shown before the summary.

Logs (``--write``, ``--log``): :mod:`attica.can.logs` (python-can's readers and writers).

A node with an ID offset N (``id_offset``): every frame is checked and decoded at its bus ID - N
(:mod:`attica.can.idoffset`) and shown at its bus ID; frames that are not attica's at that offset are
``!UNKNOWN``, and when they are attica frames at another offset by their E2E CRC the summary says which.
A DBC written by ``attica dbc --id-offset D`` (``--dbc``) is read at its own offset D.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import numpy as np

from attica.can import codec
from attica.can.bus import BusReader
from attica.can.dbcshift import dbc_id_offset
from attica.can.idoffset import (
    IdOffsetError,
    check_id_offset,
    from_bus,
    guess_id_offset,
    offset_text,
    option_text,
)
from attica.can.logs import LogError, open_writer, read_log
from attica.settings import describe_flags

__all__ = [
    "BusReader",
    "LogError",
    "Monitor",
    "MonitorError",
    "candump_text",
    "format_value",
    "open_writer",
    "read_log",
]

FLAG_SIGNALS = frozenset({"flags"})
"""Signals shown by flag name (ATT_STATUS.flags, ATT_OUT_FD.flags: ATT_FLAG_* of att_types.h)."""


class MonitorError(Exception):
    """A user error of the monitor (missing DBC, unknown log format...)."""


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
    if msg.is_remote_frame:  # the requested length as candump writes it (R and a digit), when there is one
        dlc = f"{msg.dlc:X}" if 0 < msg.dlc <= 15 else ""
        return f"({ts:.6f}) {ch} {ident}#R{dlc}"
    data = bytes(msg.data).hex().upper()
    if msg.is_fd:  # the log's own flags digit (candump adds FDF 4), else BRS 1 | ESI 2 as python-can writes
        flags = getattr(msg, "fd_flags", None)
        if flags is None:
            flags = (1 if msg.bitrate_switch else 0) | (2 if msg.error_state_indicator else 0)
        return f"({ts:.6f}) {ch} {ident}##{flags:X}{data}"
    return f"({ts:.6f}) {ch} {ident}#{data}"


def flags_text(value: int) -> str:
    """ATT_FLAG_* names of a flags signal: ``AT_REST|BIAS_UPDATED``, ``none`` for 0."""
    text = describe_flags(int(value))
    return "none" if text == "-" else text


def format_value(v: Any) -> str:
    """A decoded signal value as text: choices by name, floats in Python's shortest exact repr."""
    if isinstance(v, bool):
        return str(int(v))
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else repr(v)
    return str(v)


# --- the monitor ----------------------------------------------------------------------------------


@dataclass
class MonitorStats:
    """What the monitor counted."""

    frames: int = 0
    by_name: dict[str, int] = field(default_factory=dict)
    crc_errors: int = 0
    crc_unchecked: int = 0
    counter_gaps: int = 0
    missing_frames: int = 0  # by the 4-bit alive counters: modulo 16
    repeats: int = 0
    dlc_errors: int = 0
    unknown_ids: int = 0
    other: int = 0  # error, remote and extended-ID frames
    fd_frames: int = 0
    bus_time: float = 0.0  # s of bus time used (worst-case stuffing)
    first_ts: float | None = None
    last_ts: float | None = None
    imu_samples: int = 0  # IMU samples begun (IMU_GYRO or IMU_FD frames with a good CRC)
    imu_periods: int = 0  # their sample periods by the counters (those seen + those missing, mod 16)
    sets: int = 0  # output sets with a good CRC (ATT_STATUS of a set, ATT_OUT_FD)
    first_step: int | None = None  # the node's step count (unwrapped) at the first and last set seen
    last_step: int | None = None
    step_divider: int = 0  # smallest step increase between sets (the node's output divider)
    missing_sets: int = 0  # output sets missing by the node's step and set counters (see module doc)
    samples_behind: int = 0  # most steps the node reported beyond the IMU sample periods seen (module doc)
    dropped: int = 0  # frames the monitor had to drop (receive backlog full)
    diag_bus: dict[str, int] | None = None  # the node's last good ATT_DIAG_BUS (its CAN controller)
    mag_offset: tuple[float, float, float, bool] | None = None  # the last good ATT_MAG_OFFSET (uT, estimated)

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
        False: candump text and checks only (no cantools decoding: faster).
    id_offset
        The node's CAN ID offset: the frames fed are bus frames, checked at their bus ID - ``id_offset``.

    """

    UNKNOWN_KEPT = 256
    """Frames of unknown ID kept for the guess of their ID offset (:func:`guess_id_offset`)."""

    def __init__(
        self,
        dbc: str | os.PathLike[str] | None = None,
        bitrate: int = 500_000,
        data_bitrate: int = 2_000_000,
        channel: str = "can0",
        decode: bool = True,
        id_offset: int = 0,
    ) -> None:
        import cantools

        try:
            self.id_offset = check_id_offset(id_offset)
        except IdOffsetError as exc:
            raise MonitorError(str(exc)) from None
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
        self.dbc_offset = dbc_id_offset(db)
        self.bitrate = bitrate
        self.data_bitrate = data_bitrate
        self.channel = channel
        self.decode_signals = decode
        self.stats = MonitorStats()
        self._names = {m.frame_id: m.name for m in db.messages}
        self._unknown: list[can.Message] = []
        self._last_counter: dict[int, int] = {}
        self._quat: dict[int, can.Message] = {}
        self._step_low: int | None = None
        self._step_base = 0  # node steps before this view's samples (see _node_step)
        self._imu_offset = 0  # IMU sample periods seen before the node's last reset
        self._imu_last: int | None = None  # counter of the last IMU sample seen
        self._imu_missing = 0  # IMU samples missing by their counters since the last output set
        self._set_counter: int | None = None  # counter of the last output set seen

    def _dbc_id(self, msg: can.Message) -> int:
        """The DBC's ID of a bus frame: bus ID - the node's offset + the DBC's own offset."""
        shift = self.dbc_offset - self.id_offset
        if not shift or msg.is_extended_id:
            return int(msg.arbitration_id)
        return (msg.arbitration_id + shift) & 0x7FF

    def signals(self, msg: can.Message) -> tuple[str, dict[str, Any]] | None:
        """(message name, decoded signals) by the DBC, or None when the ID is not in it / cannot decode."""
        try:
            m = self.db.get_message_by_frame_id(self._dbc_id(msg))
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

    def _imu_sample(self, counter: int) -> None:
        """An IMU sample begun (IMU_GYRO or IMU_FD with a good CRC): its periods by the counter."""
        st = self.stats
        st.imu_samples += 1
        d = 1 if self._imu_last is None else (counter - self._imu_last) & 0xF  # 0: a repeat
        st.imu_periods += d
        self._imu_missing += max(d - 1, 0)
        self._imu_last = counter

    def _missing_sets(self, delta: int, counter: int) -> int:
        """Output sets missing between the last set and one ``delta`` steps later with ``counter``.

        At most delta // divider - 1; the set counter gives the count modulo 16; of those values the one
        nearest to the steps less the periods the node integrated over the IMU samples the counters show
        missing meanwhile (exact when this view lost no IMU sample the node had).
        """
        most = delta // self.stats.step_divider - 1
        if most <= 0 or self._set_counter is None:
            return max(most, 0)
        by_counter = (counter - self._set_counter - 1) & 0xF
        guess = most - self._imu_missing // self.stats.step_divider
        options = range(by_counter, most + 1, 16)
        return min(options, key=lambda m: abs(m - guess)) if options else most

    def _node_step(self, low: int, counter: int) -> None:
        """Follow the node's 16-bit step count (and the set counter) of a good output set."""
        st = self.stats
        st.sets += 1
        if self._step_low is None or st.last_step is None:
            full = low
            # a node that started within this view reports no more steps than the sample periods seen;
            # one that ran before: count from its first set (a lower bound of the loss, never a false one)
            self._step_base = 0 if low <= st.imu_periods - self._imu_offset else low
            st.first_step = full
        else:
            delta = (low - self._step_low) & 0xFFFF
            if delta >= 0x8000:  # backwards: a reset or an old frame; restart the tracking
                self._step_low = None
                st.last_step = None
                self._node_step(low, counter)
                st.sets -= 1
                return
            full = st.last_step + delta
            if delta:
                st.step_divider = delta if not st.step_divider else min(st.step_divider, delta)
                if delta > st.step_divider:
                    st.missing_sets += self._missing_sets(delta, counter)
        self._step_low = low
        st.last_step = full
        self._set_counter = counter
        self._imu_missing = 0
        behind = (full - self._step_base) - (st.imu_periods - self._imu_offset)
        st.samples_behind = max(st.samples_behind, behind)

    def check(self, msg: can.Message) -> list[str]:
        """The problems of one frame as seen on the bus (updates the counters)."""
        st = self.stats
        probs: list[str] = []
        if msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id:
            st.other += 1
            return ["!OTHER"]
        bus_msg, msg = msg, from_bus(msg, self.id_offset)
        can_id = msg.arbitration_id
        if can_id not in codec.MSG_LEN:
            st.unknown_ids += 1
            if len(self._unknown) < self.UNKNOWN_KEPT:
                self._unknown.append(bus_msg)
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
            else:
                self._node_step(data[4] | data[5] << 8, data[1] & 0xF)
            self._quat.clear()
        elif res == codec.Check.CRC:
            st.crc_errors += 1
            probs.append("!CRC")
        elif can_id == codec.ID_OUT_FD:
            self._node_step(data[6] | data[7] << 8, data[1] & 0xF)
        elif can_id == codec.ID_DIAG_BUS:
            st.diag_bus = diag_bus_values(data)
        elif can_id == codec.ID_MAG_OFFSET:
            st.mag_offset = mag_offset_values(data)
        elif can_id in (codec.ID_IMU_GYRO, codec.ID_IMU_FD):
            self._imu_sample(data[1] & 0xF)
        if answer and (data[7] & 0xF) == int(codec.Cmd.RESET) and not probs:
            self._step_low = None  # the node restarts at step 0
            st.last_step = None
            self._step_base = 0
            self._imu_offset = st.imu_periods
        if (
            can_id not in codec.NO_CRC
            and can_id not in (codec.ID_DIAG, codec.ID_DIAG_BUS, codec.ID_MAG_OFFSET, codec.ID_CMD)
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

    def account(self, msg: can.Message) -> list[str]:
        """Count and check one frame without making its line (faster: no decoding); the problems."""
        st = self.stats
        st.frames += 1
        ts = msg.timestamp or 0.0
        if st.first_ts is None:
            st.first_ts = ts
        st.last_ts = ts
        if not msg.is_error_frame:
            st.bus_time += self._frame_time(msg)
            st.fd_frames += 1 if msg.is_fd else 0
        probs = self.check(msg)
        if not (msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id):
            name = self._names.get(self._dbc_id(msg))
            if name is not None:
                st.by_name[name] = st.by_name.get(name, 0) + 1
        return probs

    def feed(self, msg: can.Message) -> str:
        """Account for one frame and return its line."""
        probs = self.account(msg)
        text = candump_text(msg, self.channel)
        if self.decode_signals and not (msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id):
            dec = self.signals(msg)
            if dec is not None:
                name, values = dec
                text += "  " + name
                if values:
                    text += " " + " ".join(
                        f"{k}={flags_text(int(v)) if k in FLAG_SIGNALS else format_value(v)}"
                        for k, v in values.items()
                    )
        if probs:
            text += "  " + " ".join(probs)
        return text

    def bus_load(self) -> float:
        """Fraction of the bus time used over the frames seen (0 when less than two timestamps)."""
        span = self.stats.span
        return self.stats.bus_time / span if span > 0 else 0.0

    def summary(self) -> list[str]:
        """Counters, bus load and what was lost."""
        st = self.stats
        rate = st.frames / st.span if st.span > 0 else 0.0
        names = ", ".join(f"{k} {v}" for k, v in sorted(st.by_name.items()))
        bus = f"bus load {100 * self.bus_load():.1f} % of {self.bitrate / 1000:g} kbit/s"
        if st.fd_frames:
            bus += f" (CAN FD data phase {self.data_bitrate / 1e6:g} Mbit/s, {st.fd_frames} FD frames)"
        out = [
            f"{st.frames} frames in {st.span:.3f} s ({rate:.0f} frames/s), {bus}",
            f"crc errors {st.crc_errors} (unchecked {st.crc_unchecked}), counter gaps {st.counter_gaps} "
            f"({st.missing_frames} frames missing by the 4-bit counters), repeats {st.repeats}, "
            f"dlc errors {st.dlc_errors}, unknown ids {st.unknown_ids}, other frames {st.other}",
        ]
        if st.sets and st.first_step is not None and st.last_step is not None:
            lost = [f"{st.missing_sets} output sets missing by the node's step counter"]
            if st.samples_behind > 0:
                lost.append(
                    f"at least {st.samples_behind} IMU sample periods the node stepped over are not in "
                    "this view, beyond those the alive counters show (LOST: a log cut short, or frames "
                    "dropped before they were seen)"
                )
            out.append(
                f"IMU samples seen {st.imu_samples}; output sets {st.sets} for node steps "
                f"{st.first_step}..{st.last_step}: " + "; ".join(lost)
            )
        elif st.imu_samples:
            out.append(f"IMU samples seen {st.imu_samples}; no output set from a node")
        if st.diag_bus is not None:
            out.append("node CAN controller (ATT_DIAG_BUS): " + diag_bus_text(st.diag_bus))
        if st.mag_offset is not None:
            x, y, z, est = st.mag_offset
            state = "estimated" if est else "not observable yet"
            out.append(f"hard-iron offset (ATT_MAG_OFFSET): {x:.2f}, {y:.2f}, {z:.2f} uT ({state})")
        if st.dropped:
            out.append(f"DROPPED {st.dropped} frames: the monitor fell too far behind the bus")
        if self.id_offset or self.dbc_offset:
            text = f"attica ID offset {offset_text(self.id_offset)}: frames checked at bus ID - offset"
            if self.dbc_offset:
                text += f"; {self.dbc_path.name} is written for ID offset {offset_text(self.dbc_offset)}"
            out.append(text)
        guess = guess_id_offset(self._unknown) if st.unknown_ids else None
        if guess is not None and guess != self.id_offset:
            out.append(
                f"the frames of unknown ID are attica frames at ID offset {offset_text(guess)} by their "
                f"E2E CRC: try {option_text(guess)}"
            )
        out.append(f"messages: {names or 'none'}")
        return out

    @property
    def lost_anything(self) -> bool:
        """True when the counters show lost or dropped frames."""
        st = self.stats
        return bool(st.missing_frames or st.missing_sets or st.samples_behind > 0 or st.dropped)


def mag_offset_values(data: bytes) -> tuple[float, float, float, bool]:
    """The fields of an ATT_MAG_OFFSET frame's 8 bytes: the offset (uT, NaN for NA) and whether estimated."""
    raw = np.frombuffer(bytes(data[2:8]), "<i2")
    x, y, z = (float(v) for v in codec.dequantise(raw, codec.MAG_FRAC))
    return x, y, z, bool(data[1] & 0x10)


def diag_bus_values(data: bytes) -> dict[str, int]:
    """The fields of an ATT_DIAG_BUS frame's 8 bytes (state, the counters, lec; as in the DBC)."""
    out = {"state": (data[1] >> 4) & 0x3}
    out.update({name: int(data[2 + j]) for j, name in enumerate(codec.DIAG_BUS_FIELDS)})
    out["lec"] = data[7] & 0x7
    return out


def diag_bus_named(data: bytes) -> dict[str, int | str]:
    """:func:`diag_bus_values`, the state and the last error code by name (ACTIVE .. BUS_OFF, NONE .. CRC)."""
    v: dict[str, int | str] = dict(diag_bus_values(data))
    lec = data[7] & 0x7
    v["state"] = codec.BUS_STATES[(data[1] >> 4) & 0x3]
    v["lec"] = codec.LEC_NAMES[lec] if lec < len(codec.LEC_NAMES) else str(lec)
    return v


def diag_bus_text(v: dict[str, int]) -> str:
    """One line of ATT_DIAG_BUS fields: state, bus-off, recoveries, entries, overruns, last error code."""
    lec = v["lec"]
    return (
        f"state {codec.BUS_STATES[v['state'] & 0x3]}, bus-off {v['bus_off']}, recoveries {v['recoveries']}, "
        f"error-passive {v['error_passive']}, error warning {v['error_warning']}, rx overruns "
        f"{v['rx_overruns']}, last error {codec.LEC_NAMES[lec] if lec < len(codec.LEC_NAMES) else lec}"
    )


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
    """Two signal value texts equal (numbers compared as floats, NaN == NaN; names as text).

    A flags value by name (``AT_REST|BIAS_UPDATED``, ``none``) equals its integer.
    """
    try:
        x, y = float(a), float(b)
    except ValueError:
        if a == b:
            return True
        for text, number in ((a, b), (b, a)):
            if number.isdigit() and text == flags_text(int(number)):
                return True
        return False
    return (math.isnan(x) and math.isnan(y)) or x == y
