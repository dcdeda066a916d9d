"""The CAN node's calibration commands (CMD 4..9, ATT_CAL_ACK), acceleration frames and persistence hook."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from calib_support import ordinary

from attica import kinds, native
from attica.calibration.stages import StageSettings, fill_c
from attica.native import ffi, lib
from attica.reference import calib as rc

from helpers import assert_same_bits

RATE = 100.0


def _node(
    fd: bool = True, accel_out: bool = False, calib: StageSettings | None = None, kind: str = "mars"
) -> Any:
    s = ffi.new("att_node_settings_t *")
    k = int(kinds.info(kind).kind)
    assert lib.att_node_settings_default(k, RATE, s) == lib.ATT_OK
    s.fd = fd
    s.data_bitrate = 2_000_000 if fd else 0
    s.accel_out = accel_out
    if calib is not None:
        fill_c(s.calib, calib)
    n = ffi.new("att_node_t *")
    assert lib.att_node_init(n, s) == lib.ATT_OK
    return n, s


def _drain(n: Any) -> list[Any]:
    out = []
    f = ffi.new("att_can_frame_t *")
    while lib.att_node_tx(n, f):
        g = ffi.new("att_can_frame_t *")
        g[0] = f[0]
        out.append(g)
    return out


def _send(n: Any, frame: Any) -> list[Any]:
    assert lib.att_node_rx(n, frame)
    lib.att_node_poll(n)
    return _drain(n)


_counter = [0]


def _cmd(n: Any, cmd: int, arg: int = 0, value: float = 0.0) -> Any:
    c = ffi.new("att_can_cmd_t *")
    _counter[0] = (_counter[0] + 1) & 15
    c.counter, c.cmd, c.arg, c.value = _counter[0], cmd, arg, value
    f = ffi.new("att_can_frame_t *")
    lib.att_can_encode_cmd(c, f)
    frames = _send(n, f)
    assert len(frames) == 1 and frames[0].id == lib.ATT_CAN_ID_CAL_ACK
    assert lib.att_can_check(frames[0]) == lib.ATT_CAN_OK
    a = ffi.new("att_can_cal_ack_t *")
    assert lib.att_can_decode_cal_ack(frames[0], a)
    assert a.counter == _counter[0] and a.cmd == cmd
    return a


def _sample(n: Any, gyr: Any, acc: Any, mag: Any, counter: int) -> list[Any]:
    s = ffi.new("att_sample_t *")
    s.gyr.x, s.gyr.y, s.gyr.z = map(float, gyr)
    s.acc.x, s.acc.y, s.acc.z = map(float, acc)
    s.mag.x, s.mag.y, s.mag.z = map(float, mag)
    f = ffi.new("att_can_frame_t *")
    lib.att_can_encode_imu_fd(s, counter & 15, f)
    return _send(n, f)


def _motion(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n)[:, None] / RATE
    gyr = (0.5 * np.sin(0.9 * t + rng.uniform(0, 6, 3))).astype(np.float32)
    acc = (np.array([0.2, 0.1, 9.8]) + rng.normal(0, 0.2, (n, 3))).astype(np.float32)
    mag = (np.array([5.0, 20.0, -40.0]) + 3 * np.cos(0.4 * t) + rng.normal(0, 0.3, (n, 3))).astype(np.float32)
    return gyr, acc, mag


def _fields(s: StageSettings) -> list[float]:
    c = ffi.new("att_calib_settings_t *")
    fill_c(c, s)
    v = ffi.new("float *")
    out = []
    for i in range(lib.ATT_CALIB_FIELDS):
        assert lib.att_calib_field_get(c, i, v)
        out.append(float(v[0]))
    return out


def _q_of(frames: list[Any]) -> np.ndarray:
    fd = [f for f in frames if f.id == lib.ATT_CAN_ID_OUT_FD]
    assert len(fd) == 1
    return np.frombuffer(bytes(fd[0].data)[8:24], "<f4")


def test_fields_round_trip() -> None:
    rng = np.random.default_rng(2)
    s = ordinary(rng, remap=7, convention=2)
    c = ffi.new("att_calib_settings_t *")
    lib.att_calib_settings_default(c)
    for i, v in enumerate(_fields(s)):
        assert lib.att_calib_field_set(c, i, v)
    want = ffi.new("att_calib_settings_t *")
    fill_c(want, s)
    assert bytes(ffi.buffer(c)) == bytes(ffi.buffer(want))
    assert not lib.att_calib_field_set(c, lib.ATT_CALIB_FIELDS, 1.0)
    for idx, bad in ((46, 1.5), (46, -1.0), (47, float("nan")), (49, 2.0), (46, 2.0**25)):
        assert not lib.att_calib_field_set(c, idx, bad), (idx, bad)
    assert bytes(ffi.buffer(c)) == bytes(ffi.buffer(want))  # refused values change nothing


def test_session_commit_applies_atomically_and_persists() -> None:
    """A session sets every field, commit applies them at once to the running filter (state kept): the
    node's outputs then equal a C filter calibrated at the same step; the hook gets the applied settings."""
    saved: list[bytes] = []

    @ffi.callback("bool(void *, const att_calib_settings_t *)")
    def persist(ctx: Any, cal: Any) -> bool:
        saved.append(bytes(ffi.buffer(cal)))
        return True

    n, _ = _node()
    lib.att_node_set_persist(n, persist, ffi.NULL)
    f = native.Filter("mars", dt=1.0 / RATE)
    gyr, acc, mag = _motion(300)
    s = ordinary(np.random.default_rng(4), remap=0, convention=1, accel_outputs=False)
    for i in range(300):
        if i == 150:
            before = bytes(ffi.buffer(ffi.addressof(n.f, "u")))
            assert _cmd(n, lib.ATT_CAN_CMD_CAL_BEGIN, 1).result == lib.ATT_CAN_ACK_OK
            for k, v in enumerate(_fields(s)):
                a = _cmd(n, lib.ATT_CAN_CMD_CAL_SET, k, v)
                assert a.result == lib.ATT_CAN_ACK_OK and a.index == k and a.session == 1
                assert bytes(ffi.buffer(ffi.addressof(n.f, "u"))) == before  # the shadow only
            assert n.f.cal.active == 0
            a = _cmd(n, lib.ATT_CAN_CMD_CAL_COMMIT)
            assert a.result == lib.ATT_CAN_ACK_OK and a.reason == 0 and a.session == 0
            assert a.persisted == lib.ATT_CAN_PERSIST_OK and a.index == lib.ATT_CALIB_FIELDS
            assert bytes(ffi.buffer(ffi.addressof(n.f, "u"))) == before  # state kept
            f.calibrate(s)
        frames = _sample(n, gyr[i], acc[i], mag[i], i)
        o = f.step(gyr[i], acc[i], mag[i])
        assert_same_bits(_q_of(frames), o["q"], f"step {i}")
    assert len(saved) == 1
    want = ffi.new("att_calib_settings_t *")
    fill_c(want, s)
    assert saved[0] == bytes(ffi.buffer(want))


@pytest.mark.parametrize(
    ("index", "value", "reason"),
    [
        (38, float("nan"), "mag_matrix"),
        (9, -1.0, "gyro_sensitivity"),
        (46, 30.0, "remap"),
        (47, 5.0, "convention"),
    ],
)
def test_commit_refused_with_reason_changes_nothing(index: int, value: float, reason: str) -> None:
    n, _ = _node()
    gyr, acc, mag = _motion(20)
    for i in range(20):
        _sample(n, gyr[i], acc[i], mag[i], i)
    before = bytes(ffi.buffer(ffi.addressof(n, "f")))
    cal_before = bytes(ffi.buffer(ffi.addressof(n, "cal")))
    assert _cmd(n, lib.ATT_CAN_CMD_CAL_BEGIN, 0).result == lib.ATT_CAN_ACK_OK
    assert _cmd(n, lib.ATT_CAN_CMD_CAL_SET, 0, 1.01).result == lib.ATT_CAN_ACK_OK
    assert _cmd(n, lib.ATT_CAN_CMD_CAL_SET, index, value).result == lib.ATT_CAN_ACK_OK
    a = _cmd(n, lib.ATT_CAN_CMD_CAL_COMMIT)
    assert a.result == lib.ATT_CAN_ACK_REFUSED and rc.ERRORS[a.reason] == reason
    assert a.session == 1 and a.persisted == lib.ATT_CAN_PERSIST_NONE
    assert bytes(ffi.buffer(ffi.addressof(n, "f"))) == before
    assert bytes(ffi.buffer(ffi.addressof(n, "cal"))) == cal_before
    assert _cmd(n, lib.ATT_CAN_CMD_CAL_ABORT).session == 0
    assert _cmd(n, lib.ATT_CAN_CMD_CAL_COMMIT).result == lib.ATT_CAN_ACK_BAD_ARG  # nothing to commit
    assert bytes(ffi.buffer(ffi.addressof(n, "f"))) == before


def test_bad_calibration_commands() -> None:
    n, _ = _node()
    assert _cmd(n, lib.ATT_CAN_CMD_CAL_SET, 0, 1.0).result == lib.ATT_CAN_ACK_BAD_ARG  # no session
    assert _cmd(n, lib.ATT_CAN_CMD_CAL_BEGIN, 2).result == lib.ATT_CAN_ACK_BAD_ARG
    assert _cmd(n, lib.ATT_CAN_CMD_CAL_BEGIN, 0).session == 1
    assert _cmd(n, lib.ATT_CAN_CMD_CAL_SET, 50, 1.0).result == lib.ATT_CAN_ACK_BAD_ARG
    assert _cmd(n, lib.ATT_CAN_CMD_CAL_SET, 46, 2.5).result == lib.ATT_CAN_ACK_BAD_ARG
    assert _cmd(n, lib.ATT_CAN_CMD_SET_CONVENTION, 3).result == lib.ATT_CAN_ACK_REFUSED
    assert _cmd(n, lib.ATT_CAN_CMD_SET_REMAP, 25).result == lib.ATT_CAN_ACK_REFUSED
    assert n.f.cal.active == 0


def test_set_convention_and_remap_atomic_and_kept_on_select() -> None:
    n, _ = _node()
    a = _cmd(n, lib.ATT_CAN_CMD_SET_CONVENTION, 1)
    assert a.result == lib.ATT_CAN_ACK_OK and n.cal.convention == 1 and n.f.cal.convention == 1
    a = _cmd(n, lib.ATT_CAN_CMD_SET_REMAP, 9)
    assert a.result == lib.ATT_CAN_ACK_OK and n.cal.remap == 9 and n.f.cal.gyr.mode == 1
    # selecting another filter keeps the calibration
    c = ffi.new("att_can_cmd_t *")
    c.counter, c.cmd, c.arg = 3, lib.ATT_CAN_CMD_SELECT, lib.ATT_FILTER_ARS
    fr = ffi.new("att_can_frame_t *")
    lib.att_can_encode_cmd(c, fr)
    _send(n, fr)
    assert n.kind == lib.ATT_FILTER_ARS and n.f.cal.convention == 1 and n.f.cal.gyr.mode == 1


def test_remap_zero_clears_the_mounting_and_a_failed_persist_is_reported() -> None:
    """SET_REMAP 0 is the identity mounting (a mounting quaternion set before is dropped); a persistence
    hook that fails is answered PERSIST_FAILED while the settings still apply; a session counts its
    CAL_SETs up to 255 (CAL_COMMIT's index)."""

    @ffi.callback("bool(void *, const att_calib_settings_t *)")
    def refuse(ctx: Any, cal: Any) -> bool:
        return False

    n, _ = _node()
    half = float(np.float32(np.sqrt(0.5)))
    n.cal.mounting.w, n.cal.mounting.x, n.cal.mounting.y, n.cal.mounting.z = half, 0.0, 0.0, half
    lib.att_node_set_persist(n, refuse, ffi.NULL)
    a = _cmd(n, lib.ATT_CAN_CMD_SET_REMAP, 0)
    assert a.result == lib.ATT_CAN_ACK_OK and a.persisted == lib.ATT_CAN_PERSIST_FAILED
    m = n.cal.mounting
    assert (m.w, m.x, m.y, m.z) == (1.0, 0.0, 0.0, 0.0) and n.cal.remap == 0
    lib.att_node_set_persist(ffi.NULL, refuse, ffi.NULL)  # no node: nothing done
    lib.att_node_set_persist(n, ffi.NULL, ffi.NULL)
    assert _cmd(n, lib.ATT_CAN_CMD_CAL_BEGIN, 0).session == 1
    for _ in range(300):
        assert _cmd(n, lib.ATT_CAN_CMD_CAL_SET, 0, 1.0).result == lib.ATT_CAN_ACK_OK
    a = _cmd(n, lib.ATT_CAN_CMD_CAL_COMMIT)
    assert a.result == lib.ATT_CAN_ACK_OK and a.index == 255 and a.persisted == lib.ATT_CAN_PERSIST_NONE


def test_calibration_commands_keep_the_acceleration_outputs() -> None:
    """A node with accel_out keeps sending its acceleration frames after a calibration command (the
    applied stages keep accel_outputs on whatever the command's settings say)."""
    n, _ = _node(accel_out=True, kind="ars")
    assert _cmd(n, lib.ATT_CAN_CMD_SET_CONVENTION, 1).result == lib.ATT_CAN_ACK_OK
    frames = _sample(n, (0.0, 0.0, 0.0), (0.0, 0.0, 9.81), (20.0, 0.0, -40.0), 1)
    acc_fd = [fr for fr in frames if fr.id == lib.ATT_CAN_ID_ACCEL_FD]
    a = ffi.new("att_accel_t *")
    assert len(acc_fd) == 1 and lib.att_can_decode_accel_fd(acc_fd[0], a) and a.valid == lib.ATT_OUT_ACCEL


@pytest.mark.parametrize("fd", [True, False])
def test_acceleration_frames(fd: bool) -> None:
    s = ordinary(np.random.default_rng(8), remap=3, convention=1)
    n, ns = _node(fd=fd, accel_out=True, calib=s, kind="ars")
    f = native.Filter("ars", dt=1.0 / RATE, calibration=s)
    gyr, acc, mag = _motion(100, 3)
    for i in range(100):
        ss = ffi.new("att_sample_t *")
        ss.gyr.x, ss.gyr.y, ss.gyr.z = map(float, gyr[i])
        ss.acc.x, ss.acc.y, ss.acc.z = map(float, acc[i])
        ss.mag.x, ss.mag.y, ss.mag.z = map(float, mag[i])
        if fd:
            fr = ffi.new("att_can_frame_t *")
            lib.att_can_encode_imu_fd(ss, i & 15, fr)
            frames = _send(n, fr)
        else:
            parts = ffi.new("att_can_frame_t[3]")
            lib.att_can_encode_imu(ss, i & 15, parts)
            frames = []
            for k in range(3):
                frames += _send(n, parts + k)
        if fd:
            f.step(gyr[i], acc[i], mag[i])
        else:  # classic inputs are quantised: feed the filter what the node decoded
            vals = []
            for k in range(3):
                v3 = ffi.new("att_vec3_t *")
                assert lib.att_can_decode_imu_part(parts + k, v3)
                vals.append(np.array([v3.x, v3.y, v3.z], np.float32))
            f.step(*vals)
        g, lin, earth = f.accel()
        for fr in frames:
            assert lib.att_can_check(fr) == lib.ATT_CAN_OK
        if fd:
            acc_fd = [fr for fr in frames if fr.id == lib.ATT_CAN_ID_ACCEL_FD]
            assert len(acc_fd) == 1
            a = ffi.new("att_accel_t *")
            assert lib.att_can_decode_accel_fd(acc_fd[0], a) and a.valid == lib.ATT_OUT_ACCEL
            got = np.array([[v.x, v.y, v.z] for v in (a.gravity, a.linear, a.earth)], np.float32)
            assert_same_bits(got, np.stack([g, lin, earth]), f"step {i}")
        else:
            ids = [fr.id for fr in frames]
            assert lib.ATT_CAN_ID_LIN_ACC in ids and lib.ATT_CAN_ID_EARTH_ACC in ids
            v = ffi.new("att_vec3_t *")
            for fr in frames:
                if fr.id in (lib.ATT_CAN_ID_LIN_ACC, lib.ATT_CAN_ID_EARTH_ACC):
                    assert lib.att_can_decode_accel_part(fr, v)
                    want = lin if fr.id == lib.ATT_CAN_ID_LIN_ACC else earth
                    assert np.abs(np.array([v.x, v.y, v.z]) - want).max() <= 2.0**-9 + 1e-7
    plain = ffi.new("att_node_settings_t *")
    plain[0] = ns[0]
    plain.accel_out = False
    assert lib.att_node_bus_load(ns) > lib.att_node_bus_load(plain)


def test_node_refuses_invalid_calibration_at_init() -> None:
    s = ffi.new("att_node_settings_t *")
    lib.att_node_settings_default(lib.ATT_FILTER_ARS, RATE, s)
    s.calib.gravity = 0.0
    n = ffi.new("att_node_t *")
    assert lib.att_node_init(n, s) == lib.ATT_ERR_SETTINGS


def test_docs_tables_and_example() -> None:
    """docs/can.md carries the acceleration load table; the docs/integration.md example compiles."""
    import re
    import shutil
    import subprocess

    from attica.can import codec

    from helpers import ROOT

    assert codec.bus_load_table(accel_out=True) in (ROOT / "docs" / "can.md").read_text()
    text = (ROOT / "docs" / "integration.md").read_text()
    block = re.search(r"## Calibration, mounting and NED output\n\n```c\n(.*?)```", text, re.S)
    assert block is not None
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:  # pragma: no cover - the build needs a compiler anyway
        pytest.skip("no C compiler")
    stubs = "_Bool read_imu(att_sample_t *in);\nvoid publish(att_quat_t q, att_vec3_t e, uint32_t flags);\n"
    head = '#include "attica/att_filter.h"\n'
    src = block.group(1).replace(head, head + stubs)
    r = subprocess.run(
        [cc, "-std=c99", "-Wall", "-Wextra", "-Werror", "-Wno-unused-function", "-fsyntax-only",
         "-I", str(ROOT / "firmware" / "include"), "-x", "c", "-"],
        input=src, text=True, capture_output=True,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
