"""The CAN frame contract of firmware/can/attica.dbc: IDs, lengths, scales, command codes, frame records.

Frames are numpy records of :data:`FRAME_DTYPE`, laid out exactly like ``att_can_frame_t``
(``id`` u32, ``len`` u8, ``fd`` u8, ``data`` 64 x u8, 2 bytes padding; 72 bytes).
"""

from __future__ import annotations

import enum
from typing import Any

import numpy as np
from numpy.typing import NDArray

FRAME_DTYPE = np.dtype(
    [("id", "<u4"), ("len", "u1"), ("fd", "u1"), ("data", "u1", (64,)), ("pad", "u1", (2,))]
)
"""numpy dtype of one ``att_can_frame_t`` (72 bytes; ``pad`` is the C struct's tail padding, kept as a
field so that numpy operations such as ``np.concatenate`` keep the layout)."""

ID_IMU_GYRO = 0x100
ID_IMU_ACC = 0x101
ID_IMU_MAG = 0x102
ID_IMU_FD = 0x110
ID_QUAT_A = 0x200
ID_QUAT_B = 0x201
ID_QUAT16 = 0x202
ID_EULER = 0x203
ID_BIAS = 0x204
ID_STATUS = 0x205
ID_DIAG = 0x206
ID_OUT_FD = 0x210
ID_LIN_ACC = 0x207
ID_EARTH_ACC = 0x208
ID_CAL_ACK = 0x209
ID_DIAG_BUS = 0x20A
ID_MAG_OFFSET = 0x20B
ID_ACCEL_FD = 0x211
ID_CMD = 0x300
DATA_ID_BASE = 0x0A00

MSG_LEN = {
    ID_IMU_GYRO: 8,
    ID_IMU_ACC: 8,
    ID_IMU_MAG: 8,
    ID_IMU_FD: 64,
    ID_QUAT_A: 8,
    ID_QUAT_B: 8,
    ID_QUAT16: 8,
    ID_EULER: 8,
    ID_BIAS: 8,
    ID_STATUS: 8,
    ID_DIAG: 8,
    ID_OUT_FD: 64,
    ID_LIN_ACC: 8,
    ID_EARTH_ACC: 8,
    ID_CAL_ACK: 8,
    ID_DIAG_BUS: 8,
    ID_MAG_OFFSET: 8,
    ID_ACCEL_FD: 64,
    ID_CMD: 8,
}
"""Length of every attica message (the CAN FD ones are 64)."""

NO_CRC = frozenset({ID_QUAT_A, ID_QUAT_B, ID_QUAT16})
"""Messages without room for CRC/counter: covered by the ATT_STATUS CRC of their set."""

GYR_FRAC = 10
ACC_FRAC = 8
MAG_FRAC = 5
QUAT16_FRAC = 14
EULER_FRAC = 13
BIAS_FRAC = 15
FRAC_MIN = -30
FRAC_MAX = 30
NA = -32768
"""int16 code of "not available" (decodes to NaN)."""

BUS_STATES = ("ACTIVE", "WARNING", "PASSIVE", "BUS_OFF")
"""ATT_DIAG_BUS.state by value (``ATT_CAN_BUS_*``): error-active, error warning, error-passive, bus-off."""
LEC_NAMES = ("NONE", "STUFF", "FORM", "ACK", "BIT1", "BIT0", "CRC")
"""ATT_DIAG_BUS.lec by value: the CAN controller's last error code (0: none yet)."""

ACK_ANSWER = 0x80
SET_IDS = (ID_QUAT_A, ID_QUAT_B, ID_QUAT16, ID_EULER, ID_BIAS, ID_STATUS)
"""The classic output set, in the order the node sends it."""


class Cmd(enum.IntEnum):
    """Command codes (CMD.cmd)."""

    SELECT = 1
    RESET = 2
    SET_GAIN = 3


class Gain(enum.IntEnum):
    """Parameters of :attr:`Cmd.SET_GAIN` (CMD.arg)."""

    TAU_ACC = 1
    TAU_MAG = 2
    KF_R = 3
    EKF_R = 4
    DECLINATION = 5


class Ack(enum.IntEnum):
    """Result of a command (bits 4..6 of ATT_STATUS.ack in an answer)."""

    OK = 0
    UNKNOWN_CMD = 1
    BAD_ARG = 2
    REFUSED = 3


def frames(n: int) -> NDArray[np.void]:
    """N zeroed frames."""
    return np.zeros(n, FRAME_DTYPE)


def _frame_bytes(f: Any) -> tuple[int, int, int, bytes]:
    """(id, len, fd, data[:len]) of a frame record, a python-can Message or an (id, bytes) pair."""
    if isinstance(f, np.void) or (isinstance(f, np.ndarray) and f.dtype == FRAME_DTYPE):
        rec = f if isinstance(f, np.void) else f.reshape(-1)[0]
        length = int(rec["len"])
        return int(rec["id"]), length, int(rec["fd"]), bytes(rec["data"][: min(length, 64)].tobytes())
    if hasattr(f, "arbitration_id"):
        data = bytes(f.data)
        return int(f.arbitration_id), len(data), int(bool(f.is_fd)), data
    can_id, data = f
    data = bytes(data)
    return int(can_id), len(data), int(len(data) > 8), data
