"""CRC-8 SAE J1850 and the E2E checks of att_can.c (AUTOSAR E2E profile 1 style), bit for bit.

- :func:`crc8`, :func:`e2e_crc`: the CRC of a buffer and of a frame's payload with its data ID.
- :func:`check`: one frame like ``att_can_check``; :func:`check_status_set`: ATT_STATUS of an output
  set over the set's quaternion frames.
"""

from __future__ import annotations

import enum
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from attica.can.layout import (
    ACK_ANSWER,
    DATA_ID_BASE,
    ID_QUAT16,
    ID_QUAT_A,
    ID_QUAT_B,
    ID_STATUS,
    MSG_LEN,
    NO_CRC,
    _frame_bytes,
)


class Check(enum.IntEnum):
    """Result of :func:`check` (``att_can_check_t``)."""

    OK = 0
    UNKNOWN_ID = 1
    DLC = 2
    CRC = 3


def _crc_table() -> NDArray[np.uint8]:
    table = np.zeros(256, np.uint8)
    for b in range(256):
        c = b
        for _ in range(8):
            c = ((c << 1) ^ 0x1D) & 0xFF if c & 0x80 else (c << 1) & 0xFF
        table[b] = c
    return table


CRC_TABLE = _crc_table()
"""CRC-8 J1850 (poly 0x1D) byte table."""


def crc8(data: bytes | bytearray | ArrayLike, crc: int = 0xFF) -> int:
    """Raw CRC-8 J1850 register update (no final XOR), like ``att_can_crc8``.

    The CRC of a buffer is ``crc8(buf) ^ 0xFF`` (0x4B for ``b"123456789"``).
    """
    c = crc & 0xFF
    for b in bytes(
        np.asarray(data, np.uint8).tobytes() if not isinstance(data, (bytes, bytearray)) else data
    ):
        c = int(CRC_TABLE[c ^ b])
    return c


def data_id(can_id: int) -> int:
    """E2E data ID of a CAN ID (``0x0A00 + id``; equals the DBC attribute E2EDataId)."""
    return (DATA_ID_BASE + (can_id & 0x7FF)) & 0xFFFF


def e2e_crc(did: int, payload: bytes | bytearray | ArrayLike) -> int:
    """E2E CRC over the data ID (low byte first) and the payload (bytes 1.. of the frame)."""
    c = crc8(bytes([did & 0xFF, (did >> 8) & 0xFF]))
    return crc8(payload, c) ^ 0xFF


def _crc_rows(init: NDArray[np.uint8], rows: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """Raw register update of many rows at once: init (N,), rows (N, L)."""
    c = init.astype(np.uint8).copy()
    for j in range(rows.shape[1]):
        c = CRC_TABLE[c ^ rows[:, j]]
    return c


def _e2e_rows(ids: NDArray[Any], payload: NDArray[np.uint8]) -> NDArray[np.uint8]:
    did = (DATA_ID_BASE + (ids.astype(np.uint32) & 0x7FF)) & 0xFFFF
    head = np.stack([(did & 0xFF).astype(np.uint8), (did >> 8).astype(np.uint8)], axis=1)
    c = _crc_rows(np.full(ids.shape[0], 0xFF, np.uint8), head)
    return _crc_rows(c, payload) ^ np.uint8(0xFF)


def check(f: Any) -> Check:
    """E2E check of one frame like ``att_can_check`` (ATT_STATUS of a set: see :func:`check_status_set`)."""
    can_id, length, fd, data = _frame_bytes(f)
    want = MSG_LEN.get(can_id)
    if want is None:
        return Check.UNKNOWN_ID
    if length != want or fd != (1 if want == 64 else 0):
        return Check.DLC
    if can_id in NO_CRC or (can_id == ID_STATUS and not data[7] & ACK_ANSWER):
        return Check.OK
    return Check.OK if e2e_crc(data_id(can_id), data[1:]) == data[0] else Check.CRC


def check_status_set(status: Any, quat_a: Any, quat_b: Any, quat16: Any) -> bool:
    """True when ATT_STATUS's CRC matches its bytes and the set's QUAT_A, QUAT_B, QUAT16 frames."""
    parts = [_frame_bytes(x) for x in (status, quat_a, quat_b, quat16)]
    want_ids = (ID_STATUS, ID_QUAT_A, ID_QUAT_B, ID_QUAT16)
    if any(p[0] != w or p[1] != 8 for p, w in zip(parts, want_ids)):
        return False
    st = parts[0][3]
    payload = st[1:] + parts[1][3] + parts[2][3] + parts[3][3]
    return e2e_crc(data_id(ID_STATUS), payload) == st[0]
