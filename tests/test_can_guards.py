"""att_can.c refuses what it cannot use: NULL arguments, unknown ids, wrong lengths, frames of another id.

The codec's happy paths are tested elsewhere (test_can_codec.py, test_node*.py, test_calib_node.py); its
argument guards were never run (issue 26: the codec's branch coverage). Here every encoder and decoder of
att_can.h gets NULL for each pointer in turn (the others valid and filled with 0xA5): it returns its
refusal (0, false, or nothing) and writes nothing. The decoders refuse a frame of another id and a short
one with their output untouched; the frame helpers refuse what has no CRC or no room for one; the
decoders not run by the node (ATT_STATUS, the accel frames with no estimate) round-trip.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

from attica._native import ffi, lib

# every function of att_can.h with a pointer argument guards it (att_can_crc8 and att_can_e2e_crc take a
# buffer and its length: the caller's contract, as memcpy's)
GUARDED = sorted(
    n
    for n in dir(lib)
    if n.startswith("att_can_")
    and not n.startswith("att_can_db_")
    and n not in ("att_can_crc8", "att_can_e2e_crc")
    and isinstance(ffi.typeof(getattr(lib, n)), ffi.CType)
    and ffi.typeof(getattr(lib, n)).kind == "function"
    and any(a.kind == "pointer" for a in ffi.typeof(getattr(lib, n)).args)
)
SENTINEL = 0xA5
FRAMES = 6  # the longest array a function takes (att_can_encode_output_set)


def _buffers(fn: Any) -> list[Any]:
    """Valid arguments: each pointer an object filled with 0xA5 (frames: FRAMES of them); scalars 0."""
    args = []
    for a in ffi.typeof(fn).args:
        if a.kind != "pointer":
            args.append(0)
            continue
        item = a.item
        n = FRAMES if item.cname == "att_can_frame_t" else 1
        obj = ffi.new(f"{item.cname}[{n}]")
        ffi.memmove(obj, bytes([SENTINEL]) * ffi.sizeof(obj), ffi.sizeof(obj))
        args.append(obj)
    return args


def _untouched(obj: Any) -> bool:
    data = bytes(ffi.buffer(obj))
    return data == bytes([SENTINEL]) * len(data)


def test_the_guarded_functions() -> None:
    """The list is what att_can.h declares (a new function with a pointer joins it by itself)."""
    assert len(GUARDED) == 26
    some = {"att_can_check", "att_can_seal", "att_can_decode_status", "att_can_encode_output_set"}
    assert some <= set(GUARDED)


@pytest.mark.parametrize("name", GUARDED)
def test_null_arguments_are_refused(name: str) -> None:
    fn = getattr(lib, name)
    kinds = [a.kind for a in ffi.typeof(fn).args]
    for i, kind in enumerate(kinds):
        if kind != "pointer":
            continue
        args = _buffers(fn)
        args[i] = ffi.NULL
        r = fn(*args)
        result = ffi.typeof(fn).result.cname
        if name == "att_can_check":
            assert r == lib.ATT_CAN_ERR_UNKNOWN_ID
        elif result != "void":
            assert not r, (name, i, r)
        for j, a in enumerate(args):
            if j != i and kinds[j] == "pointer":
                assert _untouched(a), (name, "argument", j, "written with argument", i, "NULL")


def _frame(frame_id: int, length: int, fd: bool = False, fill: int = 0) -> Any:
    f = ffi.new("att_can_frame_t *")
    f.id = frame_id
    f.len = length
    f.fd = 1 if fd else 0
    for k in range(64):
        f.data[k] = fill
    return f


DECODERS = {
    "att_can_decode_accel_fd": (lib.ATT_CAN_ID_ACCEL_FD, 64, "att_accel_t"),
    "att_can_decode_accel_part": (lib.ATT_CAN_ID_LIN_ACC, 8, "att_vec3_t"),
    "att_can_decode_cal_ack": (lib.ATT_CAN_ID_CAL_ACK, 8, "att_can_cal_ack_t"),
    "att_can_decode_cmd": (lib.ATT_CAN_ID_CMD, 8, "att_can_cmd_t"),
    "att_can_decode_diag_bus": (lib.ATT_CAN_ID_DIAG_BUS, 8, "att_can_bus_diag_t"),
    "att_can_decode_imu_fd": (lib.ATT_CAN_ID_IMU_FD, 64, "att_sample_t"),
    "att_can_decode_imu_part": (lib.ATT_CAN_ID_IMU_GYRO, 8, "att_vec3_t"),
    "att_can_decode_mag_offset": (lib.ATT_CAN_ID_MAG_OFFSET, 8, "att_mag_offset_t"),
    "att_can_decode_output": (lib.ATT_CAN_ID_EULER, 8, "att_output_t"),
    "att_can_decode_status": (lib.ATT_CAN_ID_STATUS, 8, "att_can_status_t"),
}


def test_every_decoder_is_listed() -> None:
    assert set(DECODERS) == {n for n in GUARDED if n.startswith("att_can_decode_")}


@pytest.mark.parametrize("name", sorted(DECODERS))
def test_decoders_refuse_other_ids_and_short_frames(name: str) -> None:
    """Its own id at its length decodes; an id no decoder takes (0x7FF) and its own id one byte short do
    not, and leave the output as it was."""
    fn = getattr(lib, name)
    own, length, out_type = DECODERS[name]
    out = ffi.new(f"{out_type} *")
    assert fn(_frame(own, length, fd=length == 64), out)
    for f in (_frame(0x7FF, length, fd=length == 64), _frame(own, length - 1, fd=length == 64)):
        ffi.memmove(out, bytes([SENTINEL]) * ffi.sizeof(out_type), ffi.sizeof(out_type))
        assert not fn(f, out), (name, f.id, f.len)
        assert _untouched(out), (name, "output written")


def test_the_message_table() -> None:
    """Lengths of the attica ids (8, or 64 for the FD frames), 0 for any other; a CRC on every frame but
    the quaternion set's (covered by the set's STATUS); att_can_check refuses an unknown id."""
    fd = {lib.ATT_CAN_ID_IMU_FD, lib.ATT_CAN_ID_OUT_FD, lib.ATT_CAN_ID_ACCEL_FD}
    no_crc = {lib.ATT_CAN_ID_QUAT_A, lib.ATT_CAN_ID_QUAT_B, lib.ATT_CAN_ID_QUAT16}
    known = [i for i in range(0x800) if lib.att_can_msg_len(i)]
    assert len(known) == 19 and fd < set(known) and no_crc < set(known)
    for i in known:
        assert lib.att_can_msg_len(i) == (64 if i in fd else 8)
        assert lib.att_can_msg_has_crc(i) == (i not in no_crc)
    assert not lib.att_can_msg_has_crc(0x7FF)
    assert lib.att_can_check(_frame(0x7FF, 8)) == lib.ATT_CAN_ERR_UNKNOWN_ID


def test_frame_helpers_refuse_what_has_no_crc() -> None:
    """att_can_seal leaves a frame alone that has no CRC (a quaternion frame, an unknown id) or no room for
    one (len < 2, len > 64); att_can_counter reads 0 from those without one; att_can_check takes an
    answer's STATUS (its own CRC) and a set's STATUS (the set's CRC: not checked alone)."""
    for f in (_frame(lib.ATT_CAN_ID_QUAT_A, 8, fill=7), _frame(0x7FF, 8, fill=7),
              _frame(lib.ATT_CAN_ID_EULER, 1, fill=7), _frame(lib.ATT_CAN_ID_EULER, 65, fill=7)):  # fmt: skip
        before = bytes(ffi.buffer(f))
        lib.att_can_seal(f)
        assert bytes(ffi.buffer(f)) == before
        if f.len <= 64:  # (a length beyond 64 is no frame: seal refuses it; the counter is not defined)
            assert lib.att_can_counter(f) == 0
    status = ffi.new("att_can_status_t *")
    status.ack = lib.ATT_CAN_ACK_ANSWER | 3
    answer = ffi.new("att_can_frame_t *")
    lib.att_can_encode_status(status, answer)
    assert lib.att_can_check(answer) == lib.ATT_CAN_OK
    answer.data[2] ^= 1
    assert lib.att_can_check(answer) == lib.ATT_CAN_ERR_CRC
    status.ack = 0
    lib.att_can_encode_status(status, answer)
    answer.data[0] ^= 0xFF  # a set's STATUS: the CRC byte is the set's, not checked here
    assert lib.att_can_check(answer) == lib.ATT_CAN_OK


def test_dequantise_refuses_a_scale_out_of_range() -> None:
    for frac in (lib.ATT_CAN_FRAC_MIN - 1, lib.ATT_CAN_FRAC_MAX + 1):
        assert math.isnan(lib.att_can_dequantise(100, frac))
    assert math.isnan(lib.att_can_dequantise(-32768, 10))  # the not-available code
    assert lib.att_can_dequantise(1024, 10) == 1.0


def test_status_round_trip() -> None:
    """ATT_STATUS through att_can_encode_status and att_can_decode_status (the node only encodes it)."""
    st = ffi.new("att_can_status_t *")
    st.counter, st.kind, st.flags, st.steps, st.error_count = 9, 4, 0x1234, 54321, 200
    st.ack = lib.ATT_CAN_ACK_ANSWER | (2 << 4) | 5
    f = ffi.new("att_can_frame_t *")
    lib.att_can_encode_status(st, f)
    back = ffi.new("att_can_status_t *")
    assert lib.att_can_decode_status(f, back)
    for k in ("counter", "kind", "flags", "steps", "error_count", "ack"):
        assert getattr(back, k) == getattr(st, k), k


def test_accel_frames_without_an_estimate() -> None:
    """An att_accel_t without ATT_OUT_ACCEL encodes valid = 0 and decodes with valid 0; an accel part of
    another id is refused."""
    a = ffi.new("att_accel_t *")
    a.valid = 0
    a.gravity.x = 1.5
    f = ffi.new("att_can_frame_t *")
    lib.att_can_encode_accel_fd(a, 3, f)
    back = ffi.new("att_accel_t *")
    back.valid = lib.ATT_OUT_ACCEL
    assert lib.att_can_decode_accel_fd(f, back)
    assert back.valid == 0 and back.gravity.x == 1.5
    v = ffi.new("att_vec3_t *")
    assert not lib.att_can_decode_accel_part(_frame(lib.ATT_CAN_ID_EULER, 8), v)
    assert lib.att_can_decode_accel_part(_frame(lib.ATT_CAN_ID_EARTH_ACC, 8), v)
    assert not lib.att_can_decode_imu_part(_frame(lib.ATT_CAN_ID_EULER, 8), v)
