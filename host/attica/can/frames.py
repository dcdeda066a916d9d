"""Encoding and decoding of attica frames, bit-identical to firmware/src/can/att_can.c.

- :func:`encode_imu`, :func:`encode_outputs`, :func:`encode_cmd`: vectorised encoders producing the
  same bytes as the C encoders (classic and CAN FD).
- :func:`decode`: any attica message with cantools from the DBC; :func:`decode_outputs`: a whole node
  output stream at once (numpy).
- :func:`to_message`, :func:`from_message`: python-can Messages and frame records.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from attica import resources
from attica.can.e2e import Check, _e2e_rows, check
from attica.can.layout import (
    ACC_FRAC,
    ACK_ANSWER,
    BIAS_FRAC,
    EULER_FRAC,
    GYR_FRAC,
    ID_CMD,
    ID_DIAG,
    ID_DIAG_BUS,
    ID_IMU_ACC,
    ID_IMU_FD,
    ID_IMU_GYRO,
    ID_IMU_MAG,
    ID_MAG_OFFSET,
    ID_OUT_FD,
    ID_STATUS,
    MAG_FRAC,
    MSG_LEN,
    QUAT16_FRAC,
    SET_IDS,
    Ack,
    _frame_bytes,
    frames,
)
from attica.can.quant import _rows3, dequantise, quantise
from attica.settings import FilterKind

if TYPE_CHECKING:
    import can
    import cantools.database

DBC_PATH = resources.dbc_path()
"""The CAN database (firmware/can/attica.dbc; in an installed attica its package-data copy)."""


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
        ("cov", "<f4", (4,)),  # FD only (classic sets carry none: NaN)
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


DIAG_BUS_DTYPE = np.dtype(
    [
        ("counter", "u1"),
        ("state", "u1"),
        ("bus_off", "u1"),
        ("recoveries", "u1"),
        ("error_passive", "u1"),
        ("error_warning", "u1"),
        ("rx_overruns", "u1"),
        ("lec", "u1"),
        ("crc_ok", "?"),
    ]
)
"""One decoded ATT_DIAG_BUS (the CAN controller counters of a node's port)."""


DIAG_BUS_FIELDS = ("bus_off", "recoveries", "error_passive", "error_warning", "rx_overruns")
"""The counters of ATT_DIAG_BUS in frame order, bytes 2..6 (state: byte 1 bits 4..5, lec: byte 7 bits 0..2)"""


MAG_OFFSET_DTYPE = np.dtype([("counter", "u1"), ("estimated", "?"), ("offset", "<f4", (3,)), ("crc_ok", "?")])
"""One decoded ATT_MAG_OFFSET (the hard-iron offset a mars or mekf filter estimates, uT; NA as NaN)."""


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
    """A node output stream split into sets, DIAG frames and command answers (each in arrival order).

    ``diag_bus``: the ATT_DIAG_BUS frames (a node on a Cortex-M port that reports its CAN controller).
    ``mag_offset``: the ATT_MAG_OFFSET frames (a filter that estimates a hard-iron offset).
    """

    sets: NDArray[np.void]
    diag: NDArray[np.void]
    answers: list[Answer] = field(default_factory=list)
    other: int = 0
    diag_bus: NDArray[np.void] = field(default_factory=lambda: np.zeros(0, DIAG_BUS_DTYPE))
    mag_offset: NDArray[np.void] = field(default_factory=lambda: np.zeros(0, MAG_OFFSET_DTYPE))


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
        s["cov"] = np.nan  # not in the classic frames: unknown, not 0 (which would read as certain)
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
    bi = np.nonzero(ids == ID_DIAG_BUS)[0]
    diag_bus = np.zeros(bi.shape[0], DIAG_BUS_DTYPE)
    if bi.shape[0]:
        d = data[bi]
        diag_bus["counter"] = d[:, 1] & 0xF
        diag_bus["state"] = (d[:, 1] >> 4) & 0x3
        for j, name in enumerate(DIAG_BUS_FIELDS):
            diag_bus[name] = d[:, 2 + j]
        diag_bus["lec"] = d[:, 7] & 0x7
        diag_bus["crc_ok"] = _e2e_rows(ids[bi], d[:, 1:8]) == d[:, 0]
    mi = np.nonzero(ids == ID_MAG_OFFSET)[0]
    mag_offset = np.zeros(mi.shape[0], MAG_OFFSET_DTYPE)
    if mi.shape[0]:
        d = data[mi]
        mag_offset["counter"] = d[:, 1] & 0xF
        mag_offset["estimated"] = (d[:, 1] & 0x10) != 0
        mag_offset["offset"] = dequantise(_get_i16(d, 2, 3), MAG_FRAC)
        mag_offset["crc_ok"] = _e2e_rows(ids[mi], d[:, 1:8]) == d[:, 0]
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
    known = np.isin(ids, np.array([*SET_IDS, ID_OUT_FD, ID_DIAG, ID_DIAG_BUS, ID_MAG_OFFSET], np.uint32))
    other = int((~known).sum())
    return OutputStream(sets, diag, answers, other, diag_bus, mag_offset)
