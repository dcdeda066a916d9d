"""Send a calibration to a running node over CAN (CMD 4..7, answered by ATT_CAL_ACK).

:func:`send_calibration` opens a session that starts from the node's applied configuration
(CAL_BEGIN arg 0), writes the calibration's fields 0..47 one CAL_SET each (gyro, accel, mag models,
mounting quaternion, remap, convention; docs/can.md lists the indices), waits for each ATT_CAL_ACK and
commits. The node's gravity (field 48) and acceleration outputs (field 49) are its own settings and are
left as they are. A refused commit (the node's ``att_calib_settings_check``) is aborted and raised as
:class:`CalibrationRefusedError` with the reason; the node then runs unchanged.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import can
import numpy as np

from attica.can import codec
from attica.can.bus import is_attica_candidate, to_messages
from attica.can.e2e import check
from attica.can.idoffset import silent_node_hint

CAL_BEGIN = 4
CAL_SET = 5
CAL_COMMIT = 6
CAL_ABORT = 7
SET_CONVENTION = 8
SET_REMAP = 9

SENT_FIELDS = 48
"""Fields 0..47 are the calibration file's; 48 (gravity) and 49 (accel_outputs) stay the node's."""

RESULTS = {0: "ok", 1: "unknown command", 2: "bad argument", 3: "refused"}
"""ATT_CAL_ACK.result."""

PERSISTED = {0: "no persistence hook", 1: "saved by the port hook", 2: "the port hook failed"}
"""ATT_CAL_ACK.persisted."""

REASONS = {
    "null": "no settings",
    "gyro_matrix": "gyro misalignment singular, ill-conditioned or not finite",
    "gyro_sensitivity": "gyro sensitivity out of range",
    "gyro_offset": "gyro offset out of range",
    "accel_matrix": "accel misalignment singular, ill-conditioned or not finite",
    "accel_sensitivity": "accel sensitivity out of range",
    "accel_offset": "accel offset out of range",
    "mag_matrix": "soft iron singular, ill-conditioned or not finite",
    "mag_offset": "hard iron out of range",
    "remap": "remap number out of range",
    "mounting": "mounting quaternion not a unit quaternion",
    "convention": "unknown convention",
    "gravity": "gravity out of range",
    "flag": "accel_outputs not 0 or 1",
}
"""What each ``att_calib_error_t`` (by its :data:`attica.reference.calib.ERRORS` name) means."""


class CalibrationError(RuntimeError):
    """The node did not take the calibration (no answer, a command refused); nothing was applied."""


class NodeSilentError(CalibrationError):
    """No ATT_CAL_ACK arrived in time."""


class CalibrationRefusedError(CalibrationError):
    """The node refused the commit: ``reason`` is the att_calib_error_t name of the first bad group."""

    def __init__(self, reason: str) -> None:
        self.reason = reason
        super().__init__(f"the node refused the calibration: {reason} ({REASONS.get(reason, 'invalid')})")


@dataclass(frozen=True)
class CalAck:
    """One ATT_CAL_ACK (0x209)."""

    counter: int
    cmd: int
    result: int
    reason: int
    index: int
    persisted: int
    session: int

    @property
    def reason_name(self) -> str:
        """The att_calib_error_t name of ``reason``."""
        from attica.reference.calib import ERRORS

        return ERRORS[self.reason] if self.reason < len(ERRORS) else f"error {self.reason}"


def decode_cal_ack(msg: can.Message) -> CalAck | None:
    """The ATT_CAL_ACK in ``msg`` (None when it is another frame or its CRC is bad)."""
    if not is_attica_candidate(msg) or msg.arbitration_id != codec.ID_CAL_ACK or len(msg.data) != 8:
        return None
    if check(msg) != codec.Check.OK:
        return None
    d = bytes(msg.data)
    return CalAck(d[1] & 0xF, d[2], d[3], d[4], d[5], d[6], d[7])


def calibration_fields(calibration: Any) -> list[float]:
    """The 48 float32 values CAL_SET sends (fields 0..47) of a Calibration or StageSettings."""
    from attica.calibration.stages import fields
    from attica.reference.calib import as_stage_settings

    return [float(np.float32(v)) for v in fields(as_stage_settings(calibration))[:SENT_FIELDS]]


@dataclass
class SendReport:
    """What :func:`send_calibration` did."""

    fields: int = 0
    commands: int = 0
    persisted: int = 0
    elapsed: float = 0.0

    def line(self) -> str:
        """One line for the terminal."""
        return (
            f"CAL_BEGIN, {self.fields} x CAL_SET, CAL_COMMIT: acknowledged ({self.commands} commands in "
            f"{self.elapsed * 1e3:.0f} ms; {PERSISTED.get(self.persisted, str(self.persisted))})"
        )


class _Session:
    def __init__(
        self,
        bus: can.BusABC,
        timeout: float,
        counter: int,
        service: Callable[[], object] | None,
        on_send: Callable[[can.Message], None] | None,
        on_receive: Callable[[can.Message], None] | None,
    ) -> None:
        self.bus = bus
        self.timeout = timeout
        self.counter = counter
        self.service = service
        self.on_send = on_send
        self.on_receive = on_receive
        self.commands = 0

    def command(self, cmd: int, arg: int = 0, value: float = 0.0) -> CalAck:
        self.counter = (self.counter + 1) & 0xF
        msg = to_messages(codec.encode_cmd(cmd, arg, value, counter=self.counter))[0]
        self.bus.send(msg)
        self.commands += 1
        if self.on_send is not None:
            self.on_send(msg)
        deadline = time.monotonic() + self.timeout
        foreign: list[can.Message] = []
        while time.monotonic() < deadline:
            if self.service is not None:
                self.service()
            wait = min(max(deadline - time.monotonic(), 0.0), 0.02 if self.service is not None else 0.5)
            got = self.bus.recv(wait)
            if got is None:
                continue
            if self.on_receive is not None:
                self.on_receive(got)
            if len(foreign) < 256 and is_attica_candidate(got) and got.arbitration_id not in codec.MSG_LEN:
                foreign.append(got)
            ack = decode_cal_ack(got)
            if ack is not None and ack.cmd == cmd and ack.counter == self.counter:
                return ack
        why = silent_node_hint(self.bus, foreign)
        raise NodeSilentError(f"no ATT_CAL_ACK to command {cmd} within {self.timeout:g} s: {why}")


def send_calibration(
    bus: can.BusABC,
    calibration: Any,
    *,
    timeout: float = 1.0,
    counter: int = 0,
    service: Callable[[], object] | None = None,
    on_send: Callable[[can.Message], None] | None = None,
    on_receive: Callable[[can.Message], None] | None = None,
) -> SendReport:
    """Apply ``calibration`` (a Calibration or StageSettings) to the node on ``bus``, atomically.

    Parameters
    ----------
    bus
        Bus shared with the node.
    calibration
        What to apply (fields 0..47; the node keeps its gravity and acceleration outputs).
    timeout
        Seconds to wait for each acknowledgement.
    counter
        Command counter before the first command (each command increments it, modulo 16).
    service
        An in-process node's :meth:`~attica.can.runner.NodeRunner.service`, called while waiting.
    on_send, on_receive
        See every frame sent and received (a log).

    Raises
    ------
    CalibrationRefusedError
        The node refused the commit (the session is aborted; the node runs unchanged).
    CalibrationError
        A command was not acknowledged or answered with an error (the session is aborted when possible).

    """
    values = calibration_fields(calibration)
    t0 = time.perf_counter()
    s = _Session(bus, timeout, counter, service, on_send, on_receive)
    ack = s.command(CAL_BEGIN, 0)
    if ack.result != 0:
        raise CalibrationError(f"CAL_BEGIN answered {RESULTS.get(ack.result, ack.result)}")
    try:
        for index, value in enumerate(values):
            ack = s.command(CAL_SET, index, value)
            if ack.result != 0 or ack.index != index:
                raise CalibrationError(
                    f"CAL_SET field {index} = {value!r} answered {RESULTS.get(ack.result, ack.result)}"
                )
        ack = s.command(CAL_COMMIT)
        if ack.result == 3:
            raise CalibrationRefusedError(ack.reason_name)
        if ack.result != 0:
            raise CalibrationError(f"CAL_COMMIT answered {RESULTS.get(ack.result, ack.result)}")
    except CalibrationError:
        try:
            s.command(CAL_ABORT)
        except NodeSilentError:
            pass
        raise
    return SendReport(
        fields=len(values), commands=s.commands, persisted=ack.persisted, elapsed=time.perf_counter() - t0
    )
