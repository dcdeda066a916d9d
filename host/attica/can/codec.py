"""Python side of the attica CAN interface: codec bit-identical to firmware/src/att_can.c, and the node.

- :func:`quantise` / :func:`dequantise`: the int16 scaling of att_can.h, bit for bit (ties to even,
  clamping to +-32767, NaN -> -32768 and back).
- :func:`crc8`, :func:`e2e_crc`, :func:`check`, :func:`check_status_set`: CRC-8 SAE J1850 and the E2E
  checks of single frames and of an output set.
- :func:`encode_imu`, :func:`encode_outputs`, :func:`encode_cmd`: vectorised encoders producing the
  same bytes as the C encoders (classic and CAN FD).
- :func:`decode`: any attica message with cantools from firmware/can/attica.dbc;
  :func:`decode_outputs`: a whole node output stream at once (numpy).
- :class:`Node`: the C node (att_node.h) in-process through cffi: push frames, poll, pop frames.
- :func:`bus_load`: the bus load rule of the node (mirrors ``att_node_bus_load``).

Frames are numpy records of :data:`FRAME_DTYPE`, laid out exactly like ``att_can_frame_t``
(``id`` u32, ``len`` u8, ``fd`` u8, ``data`` 64 x u8, 2 bytes padding; 72 bytes).
"""

from __future__ import annotations

import enum
import functools
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from attica.outputs import OUTPUT_DTYPE
from attica.settings import FilterKind, make_settings, to_dict

if TYPE_CHECKING:
    import can
    import cantools.database

ROOT = Path(__file__).resolve().parents[3]
DBC_PATH = ROOT / "firmware" / "can" / "attica.dbc"

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


class Ack(enum.IntEnum):
    """Result of a command (bits 4..6 of ATT_STATUS.ack in an answer)."""

    OK = 0
    UNKNOWN_CMD = 1
    BAD_ARG = 2
    REFUSED = 3


class Check(enum.IntEnum):
    """Result of :func:`check` (``att_can_check_t``)."""

    OK = 0
    UNKNOWN_ID = 1
    DLC = 2
    CRC = 3


# --- CRC ------------------------------------------------------------------------------------------


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


# --- quantisation ---------------------------------------------------------------------------------

_MAGIC = np.float32(1.5 * 2.0**23)
_QMAX = np.float32(32767.0)


def quantise(x: ArrayLike, frac_bits: int) -> NDArray[np.int16]:
    """``att_can_quantise`` over an array: round_half_even(x * 2^k) clamped to +-32767, NaN -> -32768."""
    xa = np.asarray(x, np.float32)
    if not FRAC_MIN <= frac_bits <= FRAC_MAX:
        return np.full(xa.shape, NA, np.int16)
    with np.errstate(over="ignore", invalid="ignore"):
        s = xa * np.float32(2.0**frac_bits)
        s = np.minimum(np.maximum(s, -_QMAX), _QMAX)
        nan = np.isnan(s)
        s = np.where(nan, np.float32(0.0), s)
        r = (s + _MAGIC) - _MAGIC
    out: NDArray[np.int16] = np.where(nan, np.int16(NA), r.astype(np.int16)).astype(np.int16)
    return out


def dequantise(v: ArrayLike, frac_bits: int) -> NDArray[np.float32]:
    """``att_can_dequantise`` over an array: v * 2^-k (exact), -32768 -> NaN."""
    va = np.asarray(v, np.int16)
    if not FRAC_MIN <= frac_bits <= FRAC_MAX:
        return np.full(va.shape, np.nan, np.float32)
    out: NDArray[np.float32] = np.where(
        va == NA, np.float32(np.nan), va.astype(np.float32) * np.float32(2.0**-frac_bits)
    ).astype(np.float32)
    return out


# --- frames ---------------------------------------------------------------------------------------


def frames(n: int) -> NDArray[np.void]:
    """N zeroed frames."""
    return np.zeros(n, FRAME_DTYPE)


def _start(f: NDArray[np.void], can_id: int) -> None:
    length = MSG_LEN[can_id]
    f["id"] = can_id
    f["len"] = length
    f["fd"] = 1 if length == 64 else 0


def _seal(f: NDArray[np.void]) -> None:
    """Write the E2E CRC of every frame in f (all with the same length, with a CRC)."""
    if f.shape[0] == 0:
        return
    length = int(f["len"][0])
    data = f["data"]
    data[:, 0] = _e2e_rows(f["id"], data[:, 1:length])


def _put_i16(data: NDArray[np.uint8], col: int, values: NDArray[np.int16]) -> None:
    v = np.ascontiguousarray(values.astype("<i2"))
    data[:, col : col + 2 * v.shape[1]] = v.view(np.uint8).reshape(v.shape[0], -1)


def _put_f32(data: NDArray[np.uint8], col: int, values: NDArray[np.float32]) -> None:
    v = np.ascontiguousarray(values.astype("<f4"))
    data[:, col : col + 4 * v.shape[1]] = v.view(np.uint8).reshape(v.shape[0], -1)


def _get_i16(data: NDArray[np.uint8], col: int, n: int) -> NDArray[np.int16]:
    return np.ascontiguousarray(data[:, col : col + 2 * n]).view("<i2").astype(np.int16)


def _get_f32(data: NDArray[np.uint8], col: int, n: int) -> NDArray[np.float32]:
    return np.ascontiguousarray(data[:, col : col + 4 * n]).view("<f4").astype(np.float32)


def _rows3(x: ArrayLike | None, n: int) -> NDArray[np.float32]:
    if x is None:
        return np.full((n, 3), np.nan, np.float32)
    a = np.asarray(x, np.float32).reshape(-1, 3)
    if a.shape[0] != n:
        raise ValueError(f"expected {n} rows of 3, got shape {a.shape}")
    return a


def encode_imu(
    gyr: ArrayLike, acc: ArrayLike, mag: ArrayLike | None = None, counter0: int = 0, fd: bool = False
) -> NDArray[np.void]:
    """Frames of N samples, like ``att_can_encode_imu`` / ``att_can_encode_imu_fd``.

    Parameters
    ----------
    gyr, acc, mag
        (N, 3) rad/s, m/s^2, uT; ``mag`` None (or NaN rows) = no mag sample.
    counter0
        Counter of the first sample; sample i gets ``(counter0 + i) % 16``.
    fd
        False: 3N classic frames (GYRO, ACC, MAG per sample); True: N IMU_FD frames.

    """
    g = np.asarray(gyr, np.float32).reshape(-1, 3)
    n = g.shape[0]
    a = _rows3(acc, n)
    m = _rows3(mag, n)
    counter = ((counter0 + np.arange(n)) & 0xF).astype(np.uint8)
    if fd:
        out = frames(n)
        _start(out, ID_IMU_FD)
        out["data"][:, 1] = counter
        _put_f32(out["data"], 4, np.concatenate([g, a, m], axis=1))
        _seal(out)
        return out
    out = frames(3 * n).reshape(n, 3)
    for j, (can_id, vals, frac) in enumerate(
        ((ID_IMU_GYRO, g, GYR_FRAC), (ID_IMU_ACC, a, ACC_FRAC), (ID_IMU_MAG, m, MAG_FRAC))
    ):
        f = np.ascontiguousarray(out[:, j])
        _start(f, can_id)
        f["data"][:, 1] = counter
        _put_i16(f["data"], 2, quantise(vals, frac))
        _seal(f)
        out[:, j] = f
    return out.reshape(-1)


def imu_values(
    gyr: ArrayLike, acc: ArrayLike, mag: ArrayLike | None = None
) -> tuple[NDArray[np.float32], ...]:
    """The floats the node receives from classic IMU frames: each value quantised and dequantised."""
    g = np.asarray(gyr, np.float32).reshape(-1, 3)
    n = g.shape[0]
    return (
        dequantise(quantise(g, GYR_FRAC), GYR_FRAC),
        dequantise(quantise(_rows3(acc, n), ACC_FRAC), ACC_FRAC),
        dequantise(quantise(_rows3(mag, n), MAG_FRAC), MAG_FRAC),
    )


def encode_outputs(
    out: NDArray[np.void],
    kind: int | FilterKind,
    counter0: int = 0,
    error_count: int = 0,
    fd: bool = False,
) -> NDArray[np.void]:
    """Output sets of filter output records (OUTPUT_DTYPE), like ``att_can_encode_output_set`` / ``_fd``.

    Classic: 6 frames per record (QUAT_A, QUAT_B, QUAT16, EULER, BIAS, STATUS); FD: one ATT_OUT_FD.
    """
    o = np.atleast_1d(out)
    n = o.shape[0]
    counter = ((counter0 + np.arange(n)) & 0xF).astype(np.uint8)
    flags = (o["flags"] & 0xFFFF).astype("<u2")
    steps = (o["steps"] & 0xFFFF).astype("<u2")
    if fd:
        f = frames(n)
        _start(f, ID_OUT_FD)
        d = f["data"]
        d[:, 1] = counter
        d[:, 2] = int(kind) & 0xFF
        d[:, 4:6] = flags.view(np.uint8).reshape(n, 2)
        d[:, 6:8] = steps.view(np.uint8).reshape(n, 2)
        vals = np.concatenate([o["q"], o["euler"], o["gyro_bias"], o["cov"]], axis=1)
        _put_f32(d, 8, vals)
        _seal(f)
        return f
    sets = frames(6 * n).reshape(n, 6)
    for j, can_id in enumerate(SET_IDS):
        _start(sets[:, j], can_id)
    _put_f32(sets["data"][:, 0], 0, o["q"][:, :2])
    _put_f32(sets["data"][:, 1], 0, o["q"][:, 2:])
    _put_i16(sets["data"][:, 2], 0, quantise(o["q"], QUAT16_FRAC))
    for j, name, frac in ((3, "euler", EULER_FRAC), (4, "gyro_bias", BIAS_FRAC)):
        d = sets["data"][:, j]
        d[:, 1] = counter
        _put_i16(d, 2, quantise(o[name], frac))
        sets["data"][:, j, 0] = _e2e_rows(sets["id"][:, j], d[:, 1:8])
    st = sets["data"][:, 5]
    st[:, 1] = counter | np.uint8((int(kind) & 0xF) << 4)
    st[:, 2:4] = flags.view(np.uint8).reshape(n, 2)
    st[:, 4:6] = steps.view(np.uint8).reshape(n, 2)
    st[:, 6] = min(max(error_count, 0), 255)
    st[:, 7] = 0
    sets["data"][:, 5, 0] = _status_crc_rows(
        sets["data"][:, 5], sets["data"][:, 0], sets["data"][:, 1], sets["data"][:, 2]
    )
    return sets.reshape(-1)


def _status_crc_rows(
    status: NDArray[np.uint8], qa: NDArray[np.uint8], qb: NDArray[np.uint8], q16: NDArray[np.uint8]
) -> NDArray[np.uint8]:
    rows = np.concatenate([status[:, 1:8], qa[:, :8], qb[:, :8], q16[:, :8]], axis=1)
    return _e2e_rows(np.full(rows.shape[0], ID_STATUS, np.uint32), rows)


def encode_cmd(cmd: int, arg: int = 0, value: float = 0.0, counter: int = 0) -> NDArray[np.void]:
    """One CMD frame (shape (1,)), like ``att_can_encode_cmd``."""
    f = frames(1)
    _start(f, ID_CMD)
    d = f["data"]
    d[0, 1] = counter & 0xF
    d[0, 2] = cmd & 0xFF
    d[0, 3] = arg & 0xFF
    _put_f32(d, 4, np.array([[value]], np.float32))
    _seal(f)
    return f


# --- checks ---------------------------------------------------------------------------------------


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


# --- cantools -------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=1)
def database() -> cantools.database.can.Database:
    """firmware/can/attica.dbc loaded with cantools (strict)."""
    import cantools

    db = cantools.database.load_file(str(DBC_PATH), strict=True)
    assert isinstance(db, cantools.database.can.Database)
    return db


def decode(f: Any) -> tuple[str, dict[str, float | int]]:
    """Decode any attica frame with cantools: ``(message name, {signal: value})``.

    Scaled int16 signals give their physical value (exact in float32); the "NA" code gives NaN; enum
    signals (kind, cmd) give their integer value. Raises ``KeyError`` for an unknown ID.
    """
    can_id, _, _, data = _frame_bytes(f)
    msg = database().get_message_by_frame_id(can_id)
    raw = msg.decode(data, decode_choices=True, scaling=True)
    out: dict[str, float | int] = {}
    assert isinstance(raw, dict)
    for name, v in raw.items():
        if isinstance(v, (int, float)):
            out[name] = v
        elif str(v) == "NA":
            out[name] = math.nan
        else:
            out[name] = int(getattr(v, "value", 0))
    return msg.name, out


def dbc_data_ids() -> dict[int, int]:
    """CAN ID -> E2E data ID as given by the DBC attribute E2EDataId."""
    return {
        m.frame_id: int(m.dbc.attributes["E2EDataId"].value) for m in database().messages if m.dbc is not None
    }


def to_message(f: Any) -> can.Message:
    """A python-can Message of a frame record (CAN FD frames with bit rate switch)."""
    import can

    can_id, length, fd, data = _frame_bytes(f)
    return can.Message(
        arbitration_id=can_id,
        data=data[:length],
        is_extended_id=False,
        is_fd=bool(fd),
        bitrate_switch=bool(fd),
    )


def from_message(msg: can.Message) -> NDArray[np.void]:
    """A frame record (shape (1,)) of a python-can Message."""
    f = frames(1)
    data = bytes(msg.data)
    f["id"] = msg.arbitration_id
    f["len"] = len(data)
    f["fd"] = 1 if msg.is_fd else 0
    f["data"][0, : len(data)] = np.frombuffer(data, np.uint8)
    return f


# --- output stream --------------------------------------------------------------------------------

SET_DTYPE = np.dtype(
    [
        ("counter", "u1"),
        ("kind", "u1"),
        ("flags", "<u2"),
        ("steps", "<u2"),
        ("error_count", "u1"),
        ("q", "<f4", (4,)),  # float32 (QUAT_A/B or OUT_FD)
        ("q16", "<i2", (4,)),  # raw ATT_QUAT16 (classic only)
        ("euler_raw", "<i2", (3,)),  # raw ATT_EULER (classic only)
        ("bias_raw", "<i2", (3,)),  # raw ATT_BIAS (classic only)
        ("euler", "<f4", (3,)),  # dequantised (classic) or float32 (FD)
        ("gyro_bias", "<f4", (3,)),
        ("cov", "<f4", (4,)),  # FD only (classic: 0)
        ("crc_ok", "?"),  # every CRC of the set (STATUS set CRC incl. the quaternion frames)
    ]
)
"""One decoded output set."""

DIAG_DTYPE = np.dtype(
    [
        ("counter", "u1"),
        ("crc_errors", "u1"),
        ("counter_gaps", "u1"),
        ("dlc_errors", "u1"),
        ("unknown_ids", "u1"),
        ("duplicates", "u1"),
        ("stale_partials", "u1"),
        ("crc_ok", "?"),
    ]
)
"""One decoded ATT_DIAG."""

DIAG_FIELDS = ("crc_errors", "counter_gaps", "dlc_errors", "unknown_ids", "duplicates", "stale_partials")
"""The counters of ATT_DIAG, in frame order (bytes 2..7)."""


@dataclass
class Answer:
    """A command answer (ATT_STATUS with ack bit 7)."""

    counter: int
    kind: int
    flags: int
    steps: int
    error_count: int
    cmd: int
    result: Ack
    crc_ok: bool


@dataclass
class OutputStream:
    """A node output stream split into sets, DIAG frames and command answers (each in arrival order)."""

    sets: NDArray[np.void]
    diag: NDArray[np.void]
    answers: list[Answer] = field(default_factory=list)
    other: int = 0


def decode_outputs(fr: NDArray[np.void]) -> OutputStream:
    """Decode a node output stream at once (numpy; same values as :func:`decode` with cantools).

    Classic sets are recognised as 6 consecutive frames QUAT_A..STATUS (the node queues a set
    atomically); a set out of that order raises ``ValueError``.
    """
    fr = np.atleast_1d(fr)
    ids = fr["id"]
    data = fr["data"]
    is_status = ids == ID_STATUS
    answer = is_status & ((data[:, 7] & ACK_ANSWER) != 0)
    set_status = np.nonzero(is_status & ~answer)[0]
    fd_idx = np.nonzero(ids == ID_OUT_FD)[0]
    n_classic = set_status.shape[0]
    sets = np.zeros(n_classic + fd_idx.shape[0], SET_DTYPE)
    if n_classic:
        first = set_status - 5
        if first.min() < 0:
            raise ValueError("output set cut off at the start of the stream")
        block = first[:, None] + np.arange(6)[None, :]
        if not (ids[block] == np.array(SET_IDS, np.uint32)[None, :]).all():
            raise ValueError("output stream: a set is not 6 consecutive frames QUAT_A..STATUS")
        s = sets[:n_classic]
        qa, qb, q16, eu, bi, st = (data[block[:, j]] for j in range(6))
        s["counter"] = st[:, 1] & 0xF
        s["kind"] = st[:, 1] >> 4
        s["flags"] = st[:, 2].astype(np.uint16) | (st[:, 3].astype(np.uint16) << 8)
        s["steps"] = st[:, 4].astype(np.uint16) | (st[:, 5].astype(np.uint16) << 8)
        s["error_count"] = st[:, 6]
        s["q"] = np.concatenate([_get_f32(qa, 0, 2), _get_f32(qb, 0, 2)], axis=1)
        s["q16"] = _get_i16(q16, 0, 4)
        s["euler_raw"] = _get_i16(eu, 2, 3)
        s["bias_raw"] = _get_i16(bi, 2, 3)
        s["euler"] = dequantise(s["euler_raw"], EULER_FRAC)
        s["gyro_bias"] = dequantise(s["bias_raw"], BIAS_FRAC)
        ok = _status_crc_rows(st, qa, qb, q16) == st[:, 0]
        ok &= _e2e_rows(ids[block[:, 3]], eu[:, 1:8]) == eu[:, 0]
        ok &= _e2e_rows(ids[block[:, 4]], bi[:, 1:8]) == bi[:, 0]
        ok &= ((eu[:, 1] & 0xF) == s["counter"]) & ((bi[:, 1] & 0xF) == s["counter"])
        s["crc_ok"] = ok
    if fd_idx.shape[0]:
        s = sets[n_classic:]
        d = data[fd_idx]
        s["counter"] = d[:, 1] & 0xF
        s["kind"] = d[:, 2]
        s["flags"] = d[:, 4].astype(np.uint16) | (d[:, 5].astype(np.uint16) << 8)
        s["steps"] = d[:, 6].astype(np.uint16) | (d[:, 7].astype(np.uint16) << 8)
        vals = _get_f32(d, 8, 14)
        s["q"] = vals[:, 0:4]
        s["euler"] = vals[:, 4:7]
        s["gyro_bias"] = vals[:, 7:10]
        s["cov"] = vals[:, 10:14]
        s["crc_ok"] = _e2e_rows(ids[fd_idx], d[:, 1:64]) == d[:, 0]
        if n_classic:  # keep arrival order when both kinds are present
            order = np.argsort(np.concatenate([set_status, fd_idx]), kind="stable")
            sets = sets[order]
    di = np.nonzero(ids == ID_DIAG)[0]
    diag = np.zeros(di.shape[0], DIAG_DTYPE)
    if di.shape[0]:
        d = data[di]
        diag["counter"] = d[:, 1] & 0xF
        for j, name in enumerate(DIAG_FIELDS):
            diag[name] = d[:, 2 + j]
        diag["crc_ok"] = _e2e_rows(ids[di], d[:, 1:8]) == d[:, 0]
    answers = []
    for i in np.nonzero(answer)[0].tolist():
        d = data[i]
        ack = int(d[7])
        answers.append(
            Answer(
                counter=int(d[1] & 0xF),
                kind=int(d[1] >> 4),
                flags=int(d[2]) | int(d[3]) << 8,
                steps=int(d[4]) | int(d[5]) << 8,
                error_count=int(d[6]),
                cmd=ack & 0xF,
                result=Ack((ack >> 4) & 0x7),
                crc_ok=check(fr[i]) == Check.OK,
            )
        )
    known = np.isin(ids, np.array([*SET_IDS, ID_OUT_FD, ID_DIAG], np.uint32))
    return OutputStream(sets=sets, diag=diag, answers=answers, other=int((~known).sum()))


# --- bus load -------------------------------------------------------------------------------------


def classic_bits(n: int) -> int:
    """Worst-case bits of a classic frame with n data bytes, 11-bit ID, incl. 3 bits intermission."""
    n = min(n, 8)
    return 8 * n + 47 + (34 + 8 * n - 1) // 4


def fd_frame_time(n: int, bitrate: int, data_bitrate: int) -> float:
    """Worst-case time in s of a CAN FD frame with n data bytes (11-bit ID, bit rate switch)."""
    n = min(n, 64)
    crc = 21 if n > 16 else 17
    stuff = (22 + 8 * n - 1) // 4
    nominal = 17 + 4 + 1 + 2 + 7 + 3
    data = 5 + 8 * n + (stuff - 4) + 4 + crc + (1 + (3 + crc) // 4)
    return nominal / bitrate + data / data_bitrate


def bus_load(
    sample_rate: float,
    bitrate: int = 500_000,
    data_bitrate: int = 0,
    fd: bool = False,
    output_divider: int = 1,
    diag_divider: int = 16,
    accel_out: bool = False,
) -> float:
    """Fraction of the bus time used by the node's outputs (mirror of ``att_node_bus_load``, in float64).

    ``accel_out``: ATT_LIN_ACC + ATT_EARTH_ACC (classic) or ATT_ACCEL_FD after every set.
    """
    t_classic = classic_bits(8) / bitrate
    t_set = fd_frame_time(64, bitrate, data_bitrate) if fd else 6 * t_classic
    if accel_out:
        t_set += fd_frame_time(64, bitrate, data_bitrate) if fd else 2 * t_classic
    if diag_divider:
        t_set += t_classic / diag_divider
    return sample_rate / output_divider * t_set


def input_bus_load(
    sample_rate: float, bitrate: int = 500_000, data_bitrate: int = 0, fd: bool = False
) -> float:
    """Fraction of the bus time used by the IMU input frames (3 classic or 1 IMU_FD per sample)."""
    t = fd_frame_time(64, bitrate, data_bitrate) if fd else 3 * classic_bits(8) / bitrate
    return sample_rate * t


BUS_TABLE_RATES = (50.0, 100.0, 200.0, 285.714, 500.0, 1000.0, 2000.0)
"""Output rates (Hz) of the bus load table in docs/can.md."""

BUS_TABLE_COLUMNS = (
    ("classic 500k", 500_000, 0, False),
    ("classic 1M", 1_000_000, 0, False),
    ("FD 500k/2M", 500_000, 2_000_000, True),
    ("FD 500k/5M", 500_000, 5_000_000, True),
    ("FD 1M/2M", 1_000_000, 2_000_000, True),
    ("FD 1M/5M", 1_000_000, 5_000_000, True),
)
"""Bus configurations (name, nominal bit/s, data bit/s, fd) of the bus load table in docs/can.md."""


def bus_load_table(with_inputs: bool = False, accel_out: bool = False) -> str:
    """The markdown bus load table of docs/can.md (outputs only, or outputs + IMU inputs), DIAG every 16th.

    ``accel_out``: with the acceleration frames.
    """
    head = "| output rate | " + " | ".join(name for name, *_ in BUS_TABLE_COLUMNS) + " |"
    rule = "|---|" + "---|" * len(BUS_TABLE_COLUMNS)
    rows = [head, rule]
    for rate in BUS_TABLE_RATES:
        cells = []
        for _, br, dbr, fd in BUS_TABLE_COLUMNS:
            out = bus_load(rate, br, dbr, fd, accel_out=accel_out)
            load = out + (input_bus_load(rate, br, dbr, fd) if with_inputs else 0.0)
            refused = " **refused**" if out > 1.0 else ""
            cells.append(f"{100 * load:.1f} %{refused}")
        rows.append(f"| {rate:g} Hz | " + " | ".join(cells) + " |")
    return "\n".join(rows)


# --- node -----------------------------------------------------------------------------------------

STATS_FIELDS = (
    "rx_frames",
    "crc_errors",
    "counter_gaps",
    "dlc_errors",
    "unknown_ids",
    "duplicates",
    "stale_partials",
    "rx_overflows",
    "tx_overflows",
    "samples",
    "steps",
    "sets",
    "tx_frames",
    "commands",
)
"""Fields of ``att_node_stats_t``."""


class NodeError(RuntimeError):
    """att_node_init refused the settings."""


class Node:
    """The C node (att_node.h) in-process: push frames, poll, pop frames.

    Parameters
    ----------
    kind
        Filter kind (name or :class:`FilterKind`).
    settings
        Filter settings dataclass (defaults when None); ``dt`` is set to ``1 / sample_rate`` (float32)
        unless given in ``overrides``.
    sample_rate
        Hz.
    bitrate, data_bitrate, fd, output_divider, diag_divider
        As in ``att_node_settings_t``.
    calibration, accel_out
        The node's calibration (a :class:`~attica.calibration.Calibration` or
        :class:`~attica.calibration.stages.StageSettings`; None: identity, ENU) and its acceleration frames.
    **overrides
        Filter settings fields to change.

    Raises
    ------
    NodeError
        When ``att_node_init`` refuses the settings (the message names the bus load when > 100 %).

    """

    def __init__(
        self,
        kind: str | int | FilterKind,
        settings: Any = None,
        sample_rate: float = 100.0,
        bitrate: int = 500_000,
        data_bitrate: int = 0,
        fd: bool = False,
        output_divider: int = 1,
        diag_divider: int = 16,
        calibration: Any = None,
        accel_out: bool = False,
        **overrides: Any,
    ) -> None:
        from attica import native
        from attica.calibration.stages import fill_c
        from attica.reference.calib import as_stage_settings

        self._native = native
        ffi, lib = native.ffi, native.lib
        self.kind = FilterKind.parse(kind)
        dt = float(np.float32(1.0) / np.float32(sample_rate))
        overrides.setdefault("dt", dt)
        dt_over = overrides.pop("dt")
        self.settings = make_settings(self.kind, settings, dt_over, **overrides)
        s = ffi.new("att_node_settings_t *")
        native._check(
            lib.att_filter_settings_default(int(self.kind), dt, ffi.addressof(s, "filter")),
            "att_filter_settings_default",
        )
        native._fill(getattr(s.filter, self.kind.label), to_dict(self.settings))
        s.kind = int(self.kind)
        s.sample_rate = sample_rate
        s.bitrate = bitrate
        s.data_bitrate = data_bitrate
        s.fd = fd
        s.output_divider = output_divider
        s.diag_divider = diag_divider
        fill_c(s.calib, as_stage_settings(calibration, float(getattr(self.settings, "gravity", 9.80665))))
        s.accel_out = accel_out
        self._s = s
        self.fd = fd
        self.bus_load = float(lib.att_node_bus_load(s))
        self._n = ffi.new("att_node_t *")
        status = int(lib.att_node_init(self._n, s))
        if status != lib.ATT_OK:
            why = "a setting is out of range" if status == lib.ATT_ERR_SETTINGS else f"status {status}"
            sdt = getattr(self.settings, "dt", None)
            if sdt is not None and abs(sdt * sample_rate - 1.0) > 1e-3:
                why = f"the filter's dt {sdt:g} s does not match sample_rate {sample_rate:g} Hz"
            if self.bus_load > 1.0:
                why = f"the outputs need {100 * self.bus_load:.1f} % of the bus (> 100 %)"
            raise NodeError(f"att_node_init: {why}")
        self._one = ffi.new("att_can_frame_t *")

    @property
    def state(self) -> Any:
        """The C node (``att_node_t *``; live)."""
        return self._n

    def stats(self) -> dict[str, int]:
        """The node counters."""
        st = self._n.stats
        return {name: int(getattr(st, name)) for name in STATS_FIELDS}

    def output(self) -> NDArray[np.void]:
        """Output of the last filter step (OUTPUT_DTYPE record, shape ())."""
        out = np.zeros((), OUTPUT_DTYPE)
        self._native.ffi.memmove(out, self._native.ffi.addressof(self._n, "out"), OUTPUT_DTYPE.itemsize)
        return out

    @property
    def running_kind(self) -> FilterKind:
        """The filter kind now running (changes with a select command)."""
        return FilterKind(int(self._n.kind))

    def push(self, fr: NDArray[np.void]) -> int:
        """att_node_rx for each frame; returns how many the rx ring took."""
        fr = np.ascontiguousarray(np.atleast_1d(fr), FRAME_DTYPE)
        ffi, lib = self._native.ffi, self._native.lib
        buf = ffi.from_buffer("att_can_frame_t[]", fr)
        return sum(1 for i in range(fr.shape[0]) if lib.att_node_rx(self._n, buf + i))

    def poll(self) -> int:
        """att_node_poll: returns the steps run."""
        return int(self._native.lib.att_node_poll(self._n))

    def pop(self) -> NDArray[np.void]:
        """Every frame waiting in the tx ring."""
        lib = self._native.lib
        n = int(lib.att_node_tx_pending(self._n))
        out = frames(n)
        buf = self._native.ffi.from_buffer("att_can_frame_t[]", out)
        for i in range(n):
            lib.att_node_tx(self._n, buf + i)
        return out

    def rx_pending(self) -> int:
        """Frames waiting in the rx ring (att_node_poll leaves some while the tx ring is short of room)."""
        return int(self._n.rx_head - self._n.rx_tail) & 0xFFFFFFFF

    def flush(self) -> tuple[NDArray[np.void], int]:
        """Poll and pop until the rx ring is empty; returns (frames sent, steps run)."""
        outs = [self.pop()]
        steps = 0
        while True:
            steps += self.poll()
            outs.append(self.pop())
            if self.rx_pending() == 0:
                return np.concatenate(outs), steps

    def run(self, fr: NDArray[np.void]) -> tuple[NDArray[np.void], int]:
        """Feed frames as a port does (rx, poll, drain tx after each); returns (frames sent, steps run)."""
        fr = np.ascontiguousarray(np.atleast_1d(fr), FRAME_DTYPE)
        ffi, lib = self._native.ffi, self._native.lib
        cap = 8 * fr.shape[0] + 128
        out = frames(cap)
        n_out = ffi.new("size_t *")
        steps = lib.att_host_node_run(
            self._n,
            ffi.from_buffer("att_can_frame_t[]", fr),
            fr.shape[0],
            ffi.from_buffer("att_can_frame_t[]", out),
            cap,
            n_out,
        )
        return out[: int(n_out[0])], int(steps)
