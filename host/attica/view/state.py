"""What ``attica view`` shows, kept up to date frame by frame: :class:`ViewState`.

Every frame of the source goes through :meth:`ViewState.feed`, which costs a few microseconds: the
checks and counters are those of ``attica monitor`` (:class:`attica.can.monitor.Monitor`: E2E CRC,
alive-counter gaps, repeats, DLC, unknown IDs, bus load, output sets lost by the node's step counter),
and the frames the page needs are only kept, not decoded: the last output set with good CRCs, the last
ATT_DIAG and ATT_DIAG_BUS, the last IMU sample's parts. :meth:`ViewState.snapshot`, called at the
display rate, decodes those with the codec of :mod:`attica.can.frames` (``decode_outputs``: the same
values as the DBC) and appends one point to the rolling history of the plots. A 1 kHz node is therefore
decoded 30 times a second, not 1000, and nothing the page does can hold up the bus reader (latest wins).

The snapshot is plain JSON data (NaN and infinities as ``null``); its fields are described in
docs/view.md.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import can
import numpy as np

from attica.can import codec
from attica.can.calibration import REASONS, SET_CONVENTION, decode_cal_ack
from attica.can.idoffset import from_bus
from attica.can.monitor import Monitor, diag_bus_named, mag_offset_values
from attica.settings import FilterKind, Flag

__all__ = [
    "COMMANDS",
    "CONVENTIONS",
    "FLAGS",
    "CommandRecord",
    "ViewState",
    "json_number",
]

log = logging.getLogger("attica.view")

CONVENTIONS = ("ENU", "NED", "NWU")
"""Earth frames of the node's outputs (``att_convention_t`` 0, 1, 2; the node's SET_CONVENTION arg)."""

COMMANDS: dict[str, str] = {
    "reset": "reset the filter (CMD 2: att_filter_reset, steps restart at 0)",
    "select": "select a filter kind (CMD 1: a fresh filter of that kind)",
    "convention": "set the output convention ENU / NED / NWU (CMD 8, SET_CONVENTION)",
}
"""The node commands the page offers (those the CAN tools send; docs/can.md, Commands)."""

FLAGS: tuple[tuple[str, str, str, str], ...] = (
    ("AT_REST", "at rest", "the rest detector says the sensor is still", "good"),
    ("ACCEL_REJECTED", "accel rejected", "|a| too far from g: the accel correction was skipped", "warn"),
    (
        "MAG_REJECTED",
        "mag rejected",
        "the field's norm or dip is off: the mag correction was skipped",
        "warn",
    ),
    (
        "INITIALISED",
        "recovering",
        "the attitude is being (re)initialised from the sensors (a start or a recovery)",
        "warn",
    ),
    ("NUMERIC", "numeric", "a numeric failure: the state was kept from before the step", "bad"),
    ("NOT_READY", "not ready", "no valid attitude yet (waiting for a first valid sample)", "bad"),
    ("BIAS_UPDATED", "bias updated", "the gyro bias estimate changed", "good"),
    ("MAG_ABSENT", "no mag", "no magnetometer sample", "info"),
    ("GYRO_INVALID", "gyro invalid", "gyro NaN or infinite: integration skipped", "bad"),
    (
        "GYRO_RANGE",
        "gyro range",
        "a gyro component beyond gyro_range: integrated as read up to twice it (clipped), beyond skipped",
        "bad",
    ),
    ("ACCEL_INVALID", "accel invalid", "accel NaN, infinite or zero: correction skipped", "warn"),
    ("ACCEL_RANGE", "accel range", "|a| beyond accel_range (saturation): correction skipped", "warn"),
    ("MAG_INVALID", "mag invalid", "mag NaN, infinite or huge: correction skipped", "warn"),
    ("GIMBAL", "gimbal", "pitch near +-90 deg: a value was clamped", "warn"),
    ("CLAMPED", "clamped", "an argument was clamped into its domain", "info"),
    ("BAD_ARG", "bad arg", "NULL argument or uninitialised state: nothing done", "bad"),
)
"""The status flags as the page shows them: (ATT_FLAG_* name, label, meaning, severity when set)."""

HEALTH_RECENT = 5.0
"""Seconds a bus-health indicator stays lit after its counter last went up."""

EVENT_SUMMARY = 5.0
"""Seconds between the summary lines of a problem that repeats (the first one is shown at once)."""

COMMAND_TIMEOUT = 1.5
"""Seconds to wait for a command's answer (ATT_STATUS ack or ATT_CAL_ACK)."""

_IMU_IDS = frozenset({codec.ID_IMU_GYRO, codec.ID_IMU_ACC, codec.ID_IMU_MAG, codec.ID_IMU_FD})
_PROBLEM_TEXT = {
    "!CRC": "E2E CRC wrong",
    "!GAP": "alive counter gap",
    "!DUP": "counter repeated",
    "!DLC": "wrong length or format for the ID",
    "!UNKNOWN": "ID not in the DBC",
    "!OTHER": "error, remote or extended-ID frame",
    "?CRC": "set CRC not checkable (its quaternion frames were not seen)",
}


def json_number(x: Any) -> float | None:
    """A float for JSON: None for NaN and infinities (JSON has neither)."""
    v = float(x)
    return v if math.isfinite(v) else None


_H = math.sqrt(0.5)
_FROM_ENU = {
    "ENU": np.eye(3),
    "NED": np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]),
    "NWU": np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
}
"""The earth axes of each convention written in ENU's (rows: the convention's x, y, z)."""

_TO_ENU = {"NED": (0.0, -_H, -_H, 0.0), "NWU": (_H, 0.0, 0.0, _H)}
"""The rotation from each convention's earth frame to ENU's, as a quaternion (the inverse of _FROM_ENU's
rotation): a sensor-to-earth q in the convention is ``_TO_ENU * q`` in ENU."""


def orientation_cov(kind: FilterKind, sets: np.ndarray, convention: str) -> list[float | None] | None:
    """The Imu message's 3x3 orientation covariance (row-major, rad^2) of a decoded FD output set.

    :func:`attica.data.export.orientation_covariance` of the set (about ENU's axes, as the node reports
    it whatever its convention) turned onto the convention's earth axes, R C R^T; None for a kind
    without one (gyro, tilt). The yaw variance is the node's: pi^2/3 (unknown) for a 6-axis filter's
    heading (ars, ekf, mekf without the magnetometer) but from a set heading to the next clipping gyro
    sample, as in a file export.
    """
    from attica.data.export import COVARIANCE, orientation_covariance
    from attica.evaluate.trace import euler_deg
    from attica.metrics import quat_mul

    if kind not in COVARIANCE:
        return None
    rec = sets[:1].copy()
    r = _FROM_ENU[convention]
    if convention != "ENU":  # the set's q and Euler angles are the convention's; the cov model wants ENU's
        q_enu = quat_mul(_TO_ENU[convention], rec["q"][0])
        rec["euler"][0] = np.radians(euler_deg(q_enu[None, :]))[0]
    c = orientation_covariance(kind, rec)[0]
    if c[0] >= 0.0:  # -1 in element 0: no orientation estimate, kept as it is
        c = (r @ c.reshape(3, 3) @ r.T).reshape(9)
    return _vec(c)


def _mag_offset(data: bytes | None) -> dict[str, Any] | None:
    """The last ATT_MAG_OFFSET: the hard-iron offset (uT) and whether it was observable.

    None before the first (a filter without the estimate sends none).
    """
    if data is None:
        return None
    x, y, z, estimated = mag_offset_values(data)
    return {"offset": _vec([x, y, z]), "estimated": estimated}


def _vec(v: Any) -> list[float | None]:
    return [json_number(x) for x in np.asarray(v, np.float64).reshape(-1).tolist()]


def _norm(v: Any) -> float | None:
    a = np.asarray(v, np.float64)
    if not np.isfinite(a).all():
        return None
    return float(np.sqrt((a * a).sum()))


@dataclass
class CommandRecord:
    """A command sent from the page and what became of it."""

    id: int
    name: str
    text: str
    cmd: int
    arg: int
    counter: int
    sent: float  # wall time
    status: str = "sent"  # sent, ok, unknown command, bad argument, refused, no answer, error
    detail: str = ""

    def as_json(self) -> dict[str, Any]:
        """The record as the page gets it."""
        return {
            "id": self.id,
            "name": self.name,
            "text": self.text,
            "status": self.status,
            "detail": self.detail,
            "t": self.sent,
        }


_RESULTS = {0: "ok", 1: "unknown command", 2: "bad argument", 3: "refused"}


@dataclass
class _Window:
    """One tick's totals, for rates over the last second (bus time)."""

    ts: float
    frames: int
    bus_time: float


@dataclass
class _Problem:
    count: int = 0
    reported: int = 0
    last_report: float = 0.0
    example: str = ""


@dataclass
class _Latest:
    """The frames the snapshot decodes (kept, not decoded, per frame)."""

    set_frames: list[tuple[int, bytes]] | None = None
    set_ts: float = 0.0
    set_seq: int = 0
    diag: bytes | None = None
    diag_ts: float = 0.0
    diag_bus: bytes | None = None  # ATT_DIAG_BUS: the CAN controller of a node on a Cortex-M port
    mag_offset: bytes | None = None  # ATT_MAG_OFFSET: the hard-iron offset a mars or mekf estimates
    imu: dict[int, bytes] = field(default_factory=dict)
    imu_ts: float = 0.0
    quat: dict[int, bytes] = field(default_factory=dict)


class ViewState:
    """The state of the page, fed frame by frame (:meth:`feed`), read at display rate (:meth:`snapshot`).

    Parameters
    ----------
    bitrate, data_bitrate
        Nominal and CAN FD data bit rates (bus load, as ``attica monitor`` computes it).
    id_offset
        The node's CAN ID offset: frames are checked and decoded at bus ID - offset.
    dbc
        DBC for the monitor's checks (default the firmware's attica.dbc).
    convention
        Earth frame of the node's outputs (ENU, NED or NWU): the node does not say it on the bus.
    g_ref, m_ref
        References of the |a| and |m| plots (m/s^2, uT); ``m_ref`` None: none drawn.
    history
        Points kept for the plots (one per display tick with a new output set).

    Every method takes :attr:`lock`; one thread feeds, any other may read.

    """

    def __init__(
        self,
        *,
        bitrate: int = 500_000,
        data_bitrate: int = 2_000_000,
        id_offset: int = 0,
        dbc: str | None = None,
        convention: str = "ENU",
        g_ref: float = 9.80665,
        m_ref: float | None = None,
        history: int = 3600,
    ) -> None:
        if convention not in CONVENTIONS:
            raise ValueError(f"convention must be one of {', '.join(CONVENTIONS)}, got {convention!r}")
        self.lock = threading.RLock()
        self._monitor_args: dict[str, Any] = {
            "dbc": dbc,
            "bitrate": bitrate,
            "data_bitrate": data_bitrate,
            "decode": False,
            "id_offset": id_offset,
        }
        self.id_offset = id_offset
        self.convention = convention
        self.g_ref = g_ref
        self.m_ref = m_ref
        self.source: dict[str, Any] = {"kind": "none", "text": "", "state": "starting", "error": None}
        self.playback: dict[str, Any] | None = None
        self.can_command = False
        self.truth_q: list[float] | None = None
        self.dropped = 0  # frames the source's reader had to drop (its backlog was full)
        self.view_errors = 0  # frames whose handling raised (a bug: logged with the traceback)
        self._history: deque[tuple[Any, ...]] = deque(maxlen=history)
        self._history_seq = 0
        self.epoch = 0  # + 1 at every reset (a seek): the page clears its plots
        self._events: deque[dict[str, Any]] = deque(maxlen=50)
        self._event_seq = 0
        self._commands: deque[CommandRecord] = deque(maxlen=12)
        self._command_seq = 0
        self._counter = 0
        self._last_wall: float | None = None  # wall time of the last frame fed
        self.reset()

    # --- feeding -------------------------------------------------------------------------------------

    def reset(self, why: str | None = None) -> None:
        """Start the counters, the history and the decoded state anew (a seek, a new log)."""
        with self.lock:
            self.monitor = Monitor(**self._monitor_args)
            self._latest = _Latest()
            self._last_imu_frame: float | None = None
            self._latency: deque[float] = deque(maxlen=256)
            self._windows: deque[_Window] = deque(maxlen=400)
            self._lit: dict[str, float] = {}
            self._seen: dict[str, int] = {}
            self._problems: dict[tuple[str, int], _Problem] = {}
            self._history.clear()
            self._recorded_set = 0
            self.epoch += 1
            self.truth_q = None
            if why:
                self.note("info", why)

    def feed(self, msg: can.Message) -> None:
        """Check, count and keep one frame (any frame: a bad one is counted and shown, never raised)."""
        with self.lock:
            try:
                self._feed(msg)
            except Exception:  # a frame must never stop the view: count it, log it with the traceback
                self.view_errors += 1
                if self.view_errors <= 5:
                    log.exception("could not handle frame %r", msg)

    def feed_many(self, msgs: list[can.Message]) -> None:
        """:meth:`feed` every frame of ``msgs`` under one lock."""
        with self.lock:
            for m in msgs:
                self.feed(m)

    def _feed(self, msg: can.Message) -> None:
        self._last_wall = time.time()
        probs = self.monitor.account(msg)
        if msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id:
            if probs:
                self._problem(probs, msg)
            return
        m = from_bus(msg, self.id_offset)
        can_id = int(m.arbitration_id)
        data = bytes(m.data)
        ts = float(msg.timestamp or 0.0)
        if probs:
            self._problem(probs, msg)
        bad = any(p.startswith(("!CRC", "!DLC", "!UNKNOWN")) for p in probs)
        if bad or can_id not in codec.MSG_LEN or len(data) != codec.MSG_LEN[can_id]:
            return
        latest = self._latest
        if can_id in codec.NO_CRC:
            latest.quat[can_id] = data
        elif can_id in (codec.ID_EULER, codec.ID_BIAS):
            latest.quat[can_id] = data
        elif can_id == codec.ID_STATUS:
            if data[7] & codec.ACK_ANSWER:
                self._answer(data[7] & 0xF, (data[7] >> 4) & 0x7, data[1] & 0xF, "")
            elif "?CRC" not in probs:  # the set's CRC (over its quaternion frames) is good
                parts = [latest.quat.get(i) for i in codec.SET_IDS[:5]]
                if all(p is not None for p in parts):
                    latest.set_frames = [(i, p) for i, p in zip(codec.SET_IDS[:5], parts) if p is not None]
                    latest.set_frames.append((can_id, data))
                    self._set_arrived(ts)
            latest.quat.clear()
        elif can_id == codec.ID_OUT_FD:
            latest.set_frames = [(can_id, data)]
            self._set_arrived(ts)
        elif can_id == codec.ID_DIAG:
            latest.diag = data
            latest.diag_ts = ts
        elif can_id == codec.ID_DIAG_BUS:
            latest.diag_bus = data
        elif can_id == codec.ID_MAG_OFFSET:
            latest.mag_offset = data
        elif can_id == codec.ID_CAL_ACK:
            ack = decode_cal_ack(m)
            if ack is not None:
                why = f"{ack.reason_name}: {REASONS.get(ack.reason_name, '')}" if ack.result == 3 else ""
                self._answer(ack.cmd, ack.result, ack.counter, why)
        elif can_id in _IMU_IDS:
            if can_id in (codec.ID_IMU_GYRO, codec.ID_IMU_FD):
                latest.imu.clear()
            latest.imu[can_id] = data
            latest.imu_ts = ts
            self._last_imu_frame = ts

    def _set_arrived(self, ts: float) -> None:
        latest = self._latest
        latest.set_ts = ts
        latest.set_seq += 1
        if self._last_imu_frame is not None:
            lat = ts - self._last_imu_frame
            if 0.0 <= lat < 1.0:
                self._latency.append(lat)

    def _problem(self, probs: list[str], msg: can.Message) -> None:
        from attica.can.monitor import candump_text

        now = time.time()
        for p in probs:
            key = "!GAP" if p.startswith("!GAP") else p
            pr = self._problems.setdefault((key, int(msg.arbitration_id)), _Problem())
            pr.count += 1
            if pr.reported == 0:
                pr.reported = pr.count
                pr.last_report = now
                level = "info" if key == "?CRC" else "warning"
                self.note(level, f"{p} {_PROBLEM_TEXT.get(key, '')}: {candump_text(msg)}")
            else:
                pr.example = candump_text(msg)

    def _flush_problems(self, now: float) -> None:
        for (key, can_id), pr in self._problems.items():
            if pr.count > pr.reported and now - pr.last_report >= EVENT_SUMMARY:
                n = pr.count - pr.reported
                level = "info" if key == "?CRC" else "warning"
                self.note(
                    level,
                    f"{n} more {key} on ID {can_id:03X} ({_PROBLEM_TEXT.get(key, '')}), last: {pr.example}",
                )
                pr.reported = pr.count
                pr.last_report = now

    def note(self, level: str, text: str) -> None:
        """An event for the page's list and the log (``level``: info, warning, error)."""
        with self.lock:
            self._event_seq += 1
            self._events.append({"seq": self._event_seq, "t": time.time(), "level": level, "text": text})
        getattr(log, level if level in ("info", "warning", "error") else "info")("%s", text)

    def set_source(self, **fields: Any) -> None:
        """Update the source's description (kind, text, state, error)."""
        with self.lock:
            old_error = self.source.get("error")
            self.source.update(fields)
            error = self.source.get("error")
            if error and error != old_error:
                self.note("error", str(error))

    def health_silence(self) -> float | None:
        """Seconds since the last frame was fed (None before the first)."""
        last = self._last_wall
        return None if last is None else time.time() - last

    def set_truth(self, q: Any) -> None:
        """The simulator's (or recording's) true attitude now: w, x, y, z, sensor-to-ENU."""
        a = np.asarray(q, np.float64).reshape(4)
        with self.lock:
            self.truth_q = None if not np.isfinite(a).all() else [float(x) for x in a]

    # --- commands ------------------------------------------------------------------------------------

    def command(self, name: str, arg: int = 0) -> tuple[CommandRecord, can.Message]:
        """A command of the page (:data:`COMMANDS`) as a frame at the DBC's ID, and its record.

        Raises ValueError for an unknown command or argument.
        """
        from attica.can.bus import to_messages

        if name == "reset":
            cmd, text = int(codec.Cmd.RESET), "reset"
        elif name == "select":
            kind = FilterKind.parse(arg)
            cmd, arg, text = int(codec.Cmd.SELECT), int(kind), f"select filter {kind.label}"
        elif name == "convention":
            if isinstance(arg, str):
                if arg.upper() not in CONVENTIONS:
                    raise ValueError(f"unknown convention {arg!r}: {', '.join(CONVENTIONS)}")
                arg = CONVENTIONS.index(arg.upper())
            if arg not in (0, 1, 2):
                raise ValueError(f"convention must be 0 (ENU), 1 (NED) or 2 (NWU), got {arg!r}")
            cmd, text = SET_CONVENTION, f"set convention {CONVENTIONS[arg]}"
        else:
            raise ValueError(f"unknown command {name!r}: {', '.join(COMMANDS)}")
        with self.lock:
            self._counter = (self._counter + 1) & 0xF
            self._command_seq += 1
            rec = CommandRecord(self._command_seq, name, text, cmd, int(arg), self._counter, time.time())
            self._commands.append(rec)
        msg = to_messages(codec.encode_cmd(cmd, int(arg), counter=rec.counter))[0]
        return rec, msg

    def command_failed(self, rec: CommandRecord, why: str) -> None:
        """The command could not be sent."""
        with self.lock:
            rec.status = "error"
            rec.detail = why
        self.note("error", f"command {rec.text}: {why}")

    def _answer(self, cmd: int, result: int, counter: int, detail: str) -> None:
        for rec in reversed(self._commands):
            if rec.status == "sent" and rec.cmd == cmd and rec.counter == counter:
                rec.status = _RESULTS.get(result, f"result {result}")
                rec.detail = detail
                level = "info" if result == 0 else "warning"
                self.note(level, f"command {rec.text}: the node answered {rec.status}")
                if result == 0 and cmd == SET_CONVENTION:
                    self.convention = CONVENTIONS[rec.arg]
                return

    # --- reading -------------------------------------------------------------------------------------

    def _decode_set(self) -> dict[str, Any] | None:
        latest = self._latest
        if latest.set_frames is None:
            return None
        fr = codec.frames(len(latest.set_frames))
        for i, (can_id, data) in enumerate(latest.set_frames):
            fr["id"][i] = can_id
            fr["len"][i] = len(data)
            fr["fd"][i] = 1 if len(data) > 8 else 0
            fr["data"][i, : len(data)] = np.frombuffer(data, np.uint8)
        sets = codec.decode_outputs(fr).sets
        s = sets[0]
        flags = int(s["flags"])
        fd = len(latest.set_frames) == 1
        cov = None
        try:
            k = FilterKind(int(s["kind"]))
            kind = k.label
            if fd:  # a classic set has no covariance
                cov = orientation_cov(k, sets, self.convention)
        except ValueError:
            kind = f"kind {int(s['kind'])}"
        return {
            "q": _vec(s["q"]),
            "euler": _vec(s["euler"]),
            "bias": _vec(s["gyro_bias"]),
            "flags": flags,
            "flag_names": [f.name for f in Flag if f.name is not None and flags & f.value],
            "kind": kind,
            "steps": int(s["steps"]),
            "counter": int(s["counter"]),
            "error_count": int(s["error_count"]),
            "fd": fd,
            "cov": cov,
            "ts": latest.set_ts,
        }

    def _decode_imu(self) -> dict[str, Any]:
        imu = self._latest.imu
        gyr = acc = mag = None
        if codec.ID_IMU_FD in imu:
            v = np.frombuffer(imu[codec.ID_IMU_FD][4:40], "<f4").astype(np.float64)
            gyr, acc, mag = v[0:3], v[3:6], v[6:9]
        else:
            for can_id, frac, name in (
                (codec.ID_IMU_GYRO, codec.GYR_FRAC, "gyr"),
                (codec.ID_IMU_ACC, codec.ACC_FRAC, "acc"),
                (codec.ID_IMU_MAG, codec.MAG_FRAC, "mag"),
            ):
                if can_id in imu:
                    raw = np.frombuffer(imu[can_id][2:8], "<i2")
                    v = codec.dequantise(raw, frac).astype(np.float64)
                    if name == "gyr":
                        gyr = v
                    elif name == "acc":
                        acc = v
                    else:
                        mag = v
        return {
            "gyr": None if gyr is None else _vec(gyr),
            "acc": None if acc is None else _vec(acc),
            "mag": None if mag is None else _vec(mag),
            "acc_norm": None if acc is None else _norm(acc),
            "mag_norm": None if mag is None else _norm(mag),
            "g_ref": self.g_ref,
            "m_ref": self.m_ref,
            "ts": self._latest.imu_ts or None,
        }

    def _diag(self) -> dict[str, Any] | None:
        d = self._latest.diag
        if d is None:
            return None
        out: dict[str, Any] = {name: int(d[2 + j]) for j, name in enumerate(codec.DIAG_FIELDS)}
        out["ts"] = self._latest.diag_ts
        return out

    def _health(self, now: float) -> dict[str, Any]:
        st = self.monitor.stats
        ts = st.last_ts
        if ts is not None and (not self._windows or self._windows[-1].ts != ts):
            self._windows.append(_Window(ts, st.frames, st.bus_time))
        rate = load = None
        if self._windows and ts is not None and st.first_ts is not None:
            last = self._windows[-1]
            # the earliest point of the last second (the first frame counts as one at its time)
            points = [_Window(st.first_ts, 1, 0.0), *self._windows]
            first = next((w for w in points if last.ts - w.ts <= 1.0), last)
            if first is last:
                first = points[-2] if len(points) > 1 else last
            span = last.ts - first.ts
            if span > 0:
                rate = (last.frames - first.frames) / span
                load = (last.bus_time - first.bus_time) / span
        counts = {
            "crc_errors": st.crc_errors,
            "counter_gaps": st.counter_gaps,
            "missing_frames": st.missing_frames,
            "repeats": st.repeats,
            "dlc_errors": st.dlc_errors,
            "unknown_ids": st.unknown_ids,
            "other": st.other,
            "missing_sets": st.missing_sets,
            "dropped": st.dropped + self.dropped,
            "view_errors": self.view_errors,
        }
        for name, value in counts.items():
            if value > self._seen.get(name, 0):
                self._lit[name] = now
            self._seen[name] = value
        lat = sorted(self._latency)
        silent = None if self._last_wall is None else now - self._last_wall
        return {
            **counts,
            "frames": st.frames,
            "frames_per_s": rate,
            "bus_load": load,
            "bus_load_mean": self.monitor.bus_load(),
            "bitrate": self.monitor.bitrate,
            "crc_unchecked": st.crc_unchecked,
            "imu_samples": st.imu_samples,
            "sets": st.sets,
            "samples_behind": max(st.samples_behind, 0),
            "latency_ms": None if not lat else 1e3 * lat[len(lat) // 2],
            "latency_max_ms": None if not lat else 1e3 * lat[-1],
            "silent_s": silent,
            "recent": sorted(k for k, t in self._lit.items() if now - t <= HEALTH_RECENT),
            "by_name": dict(sorted(st.by_name.items())),
        }

    def snapshot(self, record: bool = True) -> dict[str, Any]:
        """The state for the page (JSON data); ``record``: append a point to the plots' history."""
        now = time.time()
        with self.lock:
            self._flush_problems(now)
            for rec in self._commands:
                if rec.status == "sent" and now - rec.sent > COMMAND_TIMEOUT:
                    rec.status = "no answer"
                    rec.detail = f"no answer within {COMMAND_TIMEOUT:g} s"
                    self.note("warning", f"command {rec.text}: no answer within {COMMAND_TIMEOUT:g} s")
            att = self._decode_set()
            imu = self._decode_imu()
            if att is not None:
                att["age"] = None if self._last_wall is None else now - self._last_wall
            if record and att is not None and self._latest.set_seq != self._recorded_set:
                self._recorded_set = self._latest.set_seq
                self._history_seq += 1
                e, b = att["euler"], att["bias"]
                self._history.append((self._history_seq, att["ts"], *e, *b, imu["acc_norm"], imu["mag_norm"]))
            return {
                "t": now,
                "epoch": self.epoch,
                "source": dict(self.source),
                "playback": None if self.playback is None else dict(self.playback),
                "can_command": self.can_command,
                "convention": self.convention,
                "att": att,
                "truth": None if self.truth_q is None else {"q": list(self.truth_q)},
                "imu": imu,
                "health": self._health(now),
                "diag": self._diag(),
                "diag_bus": None if self._latest.diag_bus is None else diag_bus_named(self._latest.diag_bus),
                "mag_offset": _mag_offset(self._latest.mag_offset),
                "events": list(self._events)[-20:],
                "commands": [c.as_json() for c in self._commands],
                "history_seq": self._history_seq,
            }

    def history_since(self, seq: int, limit: int = 2000) -> list[list[float | None]]:
        """The plots' points after ``seq`` (at most ``limit``, the newest).

        Each: [seq, ts, roll, pitch, yaw, bias x, y, z, |a|, |m|], angles in rad, rates in rad/s.
        """
        with self.lock:
            pts = [p for p in self._history if p[0] > seq]
        return [[p[0], *(json_number(x) if x is not None else None for x in p[1:])] for p in pts[-limit:]]
