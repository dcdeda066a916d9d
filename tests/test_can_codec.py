"""CAN codec: CRC/E2E, quantisation C vs Python, encoders C vs Python, the DBC and its generated C."""

from __future__ import annotations

import math
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import require_tool

from attica import kinds, native
from attica.can import codec as c
from attica.can import gen
from attica.outputs import OUTPUT_DTYPE

from helpers import ROOT, adversarial_floats, need

ffi, lib = native.ffi, native.lib
FRACS_USED = (c.GYR_FRAC, c.ACC_FRAC, c.MAG_FRAC, c.QUAT16_FRAC, c.EULER_FRAC, c.BIAS_FRAC)


def _c_quantise(x: np.ndarray, frac: int) -> np.ndarray:
    x = np.ascontiguousarray(x, np.float32)
    out = np.empty(x.shape, np.int16)
    lib.att_host_can_quantise(ffi.from_buffer("float[]", x), x.size, frac, ffi.from_buffer("int16_t[]", out))
    return out


def _c_dequantise(v: np.ndarray, frac: int) -> np.ndarray:
    v = np.ascontiguousarray(v, np.int16)
    out = np.empty(v.shape, np.float32)
    lib.att_host_can_dequantise(
        ffi.from_buffer("int16_t[]", v), v.size, frac, ffi.from_buffer("float[]", out)
    )
    return out


def _bitwise_crc8(data: bytes) -> int:
    """Independent CRC-8 J1850: bit-serial polynomial division of the message, MSB first."""
    reg = 0xFF
    for byte in data:
        for i in range(7, -1, -1):
            top = (reg >> 7) & 1
            reg = (reg << 1) & 0xFF
            if top ^ ((byte >> i) & 1):
                reg ^= 0x1D
    return reg ^ 0xFF


# --- CRC ------------------------------------------------------------------------------------------


def test_crc8_check_value_and_autosar_vectors() -> None:
    assert c.crc8(b"123456789") ^ 0xFF == 0x4B
    assert lib.att_can_crc8(b"123456789", 9, 0xFF) ^ 0xFF == 0x4B
    assert _bitwise_crc8(b"123456789") == 0x4B
    # AUTOSAR SWS CRC Library, CRC8 SAE J1850 check values
    vectors = {
        "00000000": 0x59,
        "F20183": 0x37,
        "0FAA0055": 0x79,
        "00FF5511": 0xB8,
        "332255AABBCCDDEEFF": 0xCB,
        "926B55": 0x8C,
        "FFFFFFFF": 0x74,
    }
    for hexdata, want in vectors.items():
        data = bytes.fromhex(hexdata)
        assert c.crc8(data) ^ 0xFF == want, hexdata
        assert lib.att_can_crc8(data, len(data), 0xFF) ^ 0xFF == want, hexdata
    # the raw update chains: crc(a + b) == update(update(init, a), b)
    assert c.crc8(b"56789", c.crc8(b"1234")) == c.crc8(b"123456789")
    assert lib.att_can_crc8(ffi.NULL, 3, 0x12) == 0x12


def test_e2e_crc_of_known_frames() -> None:
    f = c.encode_imu([[1.0, -0.5, 0.25]], [[0.0, 0.0, 9.80665]], [[20.0, 0.0, -40.0]], counter0=3)
    want = [
        (0x100, "9103000400fe0001"),
        (0x101, "a80300000000cf09"),
        (0x102, "b6038002000000fb"),
    ]
    for frame, (can_id, hexdata) in zip(f, want):
        data = bytes(frame["data"][:8])
        assert (int(frame["id"]), data.hex()) == (can_id, hexdata)
        did = 0x0A00 + can_id
        assert _bitwise_crc8(bytes([did & 0xFF, did >> 8]) + data[1:]) == data[0]
        assert lib.att_can_e2e_crc(did, data[1:], 7) == data[0]
        assert c.e2e_crc(did, data[1:]) == data[0]
    cmd = bytes(c.encode_cmd(1, 3, 0.0, counter=7)[0]["data"][:8])
    assert cmd.hex() == "f607010300000000"
    assert _bitwise_crc8(bytes([0x00, 0x0D]) + cmd[1:]) == cmd[0]


def test_single_frame_check_catches_every_bit_flip() -> None:
    rng = np.random.default_rng(5)
    imu = c.encode_imu(
        rng.normal(0, 3, (4, 3)), rng.normal(0, 9, (4, 3)), rng.normal(0, 50, (4, 3)), counter0=9
    )
    fd = c.encode_imu(rng.normal(0, 3, (2, 3)), rng.normal(0, 9, (2, 3)), None, fd=True)
    cmd = c.encode_cmd(3, 1, 0.25, counter=2)
    frames = np.concatenate([imu, fd, cmd])
    res = np.empty(frames.shape[0], np.uint8)
    lib.att_host_can_check(
        ffi.from_buffer("att_can_frame_t[]", frames), frames.shape[0], ffi.from_buffer("uint8_t[]", res)
    )
    assert (res == 0).all() and all(c.check(f) == c.Check.OK for f in frames)
    for f in frames:
        length = int(f["len"])
        for bit in range(8 * length):
            g = f.copy()
            g["data"][bit // 8] ^= np.uint8(1 << (bit % 8))
            assert c.check(g) == c.Check.CRC
            one = np.array([g], c.FRAME_DTYPE)
            assert lib.att_can_check(ffi.from_buffer("att_can_frame_t[]", one)) == lib.ATT_CAN_ERR_CRC
    # length, format and ID faults
    g = imu[0].copy()
    g["len"] = 7
    assert c.check(g) == c.Check.DLC
    g = imu[0].copy()
    g["fd"] = 1
    assert c.check(g) == c.Check.DLC
    g = fd[0].copy()
    g["fd"] = 0
    assert c.check(g) == c.Check.DLC
    g = imu[0].copy()
    g["id"] = 0x123
    assert c.check(g) == c.Check.UNKNOWN_ID
    for g in (imu[0], fd[0]):
        one = np.array([g], c.FRAME_DTYPE)
        one["len"] = 12
        assert lib.att_can_check(ffi.from_buffer("att_can_frame_t[]", one)) == lib.ATT_CAN_ERR_DLC


def test_status_set_crc_covers_the_quaternion_frames() -> None:
    out = np.zeros(3, OUTPUT_DTYPE)
    out["q"] = [[0.5, 0.5, -0.5, 0.5], [1.0, 0.0, 0.0, 0.0], [0.9, 0.1, 0.2, 0.3]]
    out["euler"] = [[0.1, 0.2, 3.0]] * 3
    out["flags"] = 0x4400
    out["steps"] = [1, 2, 70000]
    sets = c.encode_outputs(out, 1, counter0=14, error_count=3).reshape(3, 6)
    for s in sets:
        qa, qb, q16, _, _, st = s
        assert c.check_status_set(st, qa, qb, q16)
        bufs = [np.array([x], c.FRAME_DTYPE) for x in (st, qa, qb, q16)]
        ptrs = [ffi.from_buffer("att_can_frame_t[]", b) for b in bufs]
        assert lib.att_can_status_crc(*ptrs) == int(st["data"][0])
        for k, part in enumerate((qa, qb, q16)):
            for bit in range(64):
                g = part.copy()
                g["data"][bit // 8] ^= np.uint8(1 << (bit % 8))
                args = [st, qa, qb, q16]
                args[k + 1] = g
                assert not c.check_status_set(*args)
        for bit in range(64):
            g = st.copy()
            g["data"][bit // 8] ^= np.uint8(1 << (bit % 8))
            assert not c.check_status_set(g, qa, qb, q16)
    # sets of different steps do not verify each other
    assert not c.check_status_set(sets[1][5], sets[0][0], sets[0][1], sets[0][2])


# --- quantisation ---------------------------------------------------------------------------------


def _quantise_cases() -> np.ndarray:
    rng = np.random.default_rng(42)
    f32 = np.float32
    parts = [
        adversarial_floats(400_000, seed=7),  # every class of float: NaN, Inf, huge, subnormal
        rng.uniform(-40000, 40000, 350_000).astype(f32),
        rng.normal(0, 3, 200_000).astype(f32),
        # exact ties k + 1/2 across the whole range, and their neighbours
        (np.arange(-32768, 32768, dtype=np.float64) + 0.5).astype(f32),
        np.nextafter((np.arange(-2048, 2048) + 0.5).astype(f32), f32(np.inf)),
        np.nextafter((np.arange(-2048, 2048) + 0.5).astype(f32), f32(-np.inf)),
        np.array(
            [32767.5, -32767.5, 32767.49, -32767.49, 32767.0, -32767.0, 32768.0, -32768.0, 32766.5, -32766.5],
            f32,
        ),
        np.array([np.nan, -np.nan, np.inf, -np.inf, 3.4e38, -3.4e38, 1e-45, -1e-45, 0.0, -0.0], f32),
    ]
    return np.concatenate(parts)


def test_quantise_c_vs_python_over_a_million_values() -> None:
    x = _quantise_cases()
    assert x.size >= 1_000_000
    for frac in (*FRACS_USED, 0, -3, c.FRAC_MIN, c.FRAC_MAX):
        # scale the cases so that the interesting region (ties, edges) lands on the int16 grid of this frac
        with np.errstate(over="ignore", invalid="ignore"):
            xs = (x.astype(np.float64) * 2.0**-frac).astype(np.float32)
        for arr in (x, xs):
            py = c.quantise(arr, frac)
            cc = _c_quantise(arr, frac)
            diff = np.nonzero(py != cc)[0]
            assert diff.size == 0, f"frac {frac}: {diff.size} differ, first x={arr[diff[0]]!r}"
    # out-of-range scales mean "not available" in both
    for frac in (c.FRAC_MIN - 1, c.FRAC_MAX + 1):
        assert (c.quantise(x[:1000], frac) == c.NA).all() and (_c_quantise(x[:1000], frac) == c.NA).all()


def test_quantise_rounds_half_to_even_and_clamps() -> None:
    k = np.arange(-32767, 32767, dtype=np.int64)
    ties = (k + 0.5).astype(np.float32)  # exact in float32
    want = np.where(k % 2 == 0, k, k + 1)
    assert (c.quantise(ties, 0) == want).all()
    assert (_c_quantise(ties, 0) == want).all()
    cases = {2.5: 2, 3.5: 4, -2.5: -2, -3.5: -4, 0.5: 0, -0.5: 0, 1.5: 2}
    for v, q in cases.items():
        assert int(c.quantise(np.float32(v), 0)) == q
    for frac in FRACS_USED:
        edge = np.float32(32767.5 * 2.0**-frac)
        for x, q in (
            (edge, 32767),
            (-edge, -32767),
            (np.float32(np.inf), 32767),
            (np.float32(-np.inf), -32767),
        ):
            assert int(c.quantise(x, frac)) == q and int(_c_quantise(np.array([x]), frac)[0]) == q
        assert int(c.quantise(np.float32(np.nan), frac)) == c.NA
    assert int(lib.att_can_quantise(float("nan"), 10)) == -32768
    assert int(lib.att_can_quantise(1e30, 10)) == 32767
    assert int(lib.att_can_quantise(-1e30, 10)) == -32767


def test_dequantise_is_exact_and_inverts_quantise() -> None:
    v = np.arange(-32768, 32768, dtype=np.int64).astype(np.int16)
    for frac in (*FRACS_USED, 0, c.FRAC_MIN, c.FRAC_MAX):
        py = c.dequantise(v, frac)
        cc = _c_dequantise(v, frac)
        assert np.isnan(py[0]) and np.isnan(cc[0])
        assert (py[1:].view(np.uint32) == cc[1:].view(np.uint32)).all()
        exact = v[1:].astype(np.float64) * 2.0**-frac
        assert (py[1:].astype(np.float64) == exact).all()
        # a sensor field as the node decodes it: full scale is clipped, beyond every range
        sensor = c.dequantise_sensor(v, frac).astype(np.float64)
        full = np.abs(v.astype(np.int64)) == 32767
        assert (sensor[full] == v[full].astype(np.float64) * 2.0**112).all()
        assert (sensor[~full][1:] == exact[~full[1:]]).all() and np.isnan(sensor[0])
        assert (c.quantise(py[1:], frac) == v[1:]).all()
        assert (_c_quantise(cc[1:], frac) == v[1:]).all()
    assert math.isnan(lib.att_can_dequantise(5, c.FRAC_MAX + 1))


# --- encoders C vs Python -------------------------------------------------------------------------


def _c_encode_imu(g: np.ndarray, a: np.ndarray, m: np.ndarray, counter0: int, fd: bool) -> np.ndarray:
    n = g.shape[0]
    out = c.frames(3 * n)
    arrs = [np.ascontiguousarray(x, np.float32) for x in (g, a, m)]
    k = lib.att_host_can_encode_imu(
        *(ffi.from_buffer("float[]", x) for x in arrs),
        n,
        counter0,
        int(fd),
        ffi.from_buffer("att_can_frame_t[]", out),
    )
    return out[:k]


def _c_encode_outputs(o: np.ndarray, kind: int, counter0: int, fd: bool) -> np.ndarray:
    out = c.frames(6 * o.shape[0])
    k = lib.att_host_can_encode_outputs(
        ffi.from_buffer("att_output_t[]", o),
        o.shape[0],
        kind,
        counter0,
        int(fd),
        ffi.from_buffer("att_can_frame_t[]", out),
    )
    return out[:k]


def _random_outputs(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    o = np.zeros(n, OUTPUT_DTYPE)
    for name in ("q", "euler", "gyro_bias", "cov"):
        shape = o[name].shape
        vals = rng.normal(0, 1.5, shape).astype(np.float32)
        specials = adversarial_floats(int(np.prod(shape)), seed + 1).reshape(shape)
        pick = rng.random(shape) < 0.1
        o[name] = np.where(pick, specials, vals)
    o["flags"] = rng.integers(0, 2**32, n, dtype=np.uint64).astype(np.uint32)
    o["steps"] = rng.integers(0, 2**32, n, dtype=np.uint64).astype(np.uint32)
    return o


def test_encoders_c_and_python_give_the_same_bytes() -> None:
    rng = np.random.default_rng(11)
    n = 5000
    g = rng.normal(0, 10, (n, 3)).astype(np.float32)
    a = rng.normal(0, 60, (n, 3)).astype(np.float32)
    m = rng.normal(0, 400, (n, 3)).astype(np.float32)
    specials = adversarial_floats(3 * n, 3).reshape(n, 3)
    g[::13] = specials[::13]
    m[::7] = np.nan
    for fd in (False, True):
        py = c.encode_imu(g, a, m, counter0=5, fd=fd)
        cc = _c_encode_imu(g, a, m, 5, fd)
        assert py.tobytes() == cc.tobytes()
    o = _random_outputs(3000, 2)
    for kind in [int(k.kind) for k in kinds.KINDS]:
        for fd in (False, True):
            py = c.encode_outputs(o, kind, counter0=9, fd=fd)
            cc = _c_encode_outputs(o, kind, 9, fd)
            assert py.tobytes() == cc.tobytes(), (kind, fd)
    for cmd, arg, value, counter in ((1, 3, 0.0, 0), (3, 1, 0.125, 15), (2, 0, float("nan"), 4)):
        st = ffi.new("att_can_cmd_t *", {"counter": counter, "cmd": cmd, "arg": arg, "value": value})
        one = c.frames(1)
        lib.att_can_encode_cmd(st, ffi.from_buffer("att_can_frame_t[]", one))
        assert one.tobytes() == c.encode_cmd(cmd, arg, value, counter).tobytes()


def test_c_decoders_invert_the_encoders() -> None:
    rng = np.random.default_rng(3)
    g, a, m = (rng.normal(0, s, (50, 3)).astype(np.float32) for s in (3, 20, 60))
    frames = c.encode_imu(g, a, m).reshape(50, 3)
    gq, aq, mq = c.imu_values(g, a, m)
    v = ffi.new("att_vec3_t *")
    buf = ffi.from_buffer("att_can_frame_t[]", frames.reshape(-1))
    for i in range(50):
        for j, want in enumerate((gq[i], aq[i], mq[i])):
            assert lib.att_can_decode_imu_part(buf + 3 * i + j, v)
            assert (np.array([v.x, v.y, v.z], np.float32) == want).all()
    fd = c.encode_imu(g, a, m, fd=True)
    s = ffi.new("att_sample_t *")
    assert lib.att_can_decode_imu_fd(ffi.from_buffer("att_can_frame_t[]", fd), s)
    assert (s.gyr.x, s.acc.y, s.mag.z) == (g[0, 0], a[0, 1], m[0, 2])
    o = _random_outputs(4, 8)
    for fd_mode in (False, True):
        fr = c.encode_outputs(o, 2, fd=fd_mode)
        got = np.zeros(1, OUTPUT_DTYPE)
        pg = ffi.from_buffer("att_output_t[]", got)
        fb = ffi.from_buffer("att_can_frame_t[]", fr)
        for k in range(6 if not fd_mode else 1):
            lib.att_can_decode_output(fb + k, pg)
        assert (got["q"].view(np.uint32) == o["q"][:1].view(np.uint32)).all()
        assert int(got["flags"][0]) == int(o["flags"][0]) & 0xFFFF


def test_diag_bus_c_encoder_and_the_host_decoders_agree() -> None:
    """ATT_DIAG_BUS (the ports' CAN controller counters): att_can_encode_diag_bus's frames decode to the
    same fields in C (att_can_decode_diag_bus), with cantools from the DBC and with decode_outputs;
    counters saturate at 255, state and lec keep their 2 and 3 bits, E2E good."""
    rng = np.random.default_rng(26)
    fields = ("bus_off", "recoveries", "error_passive", "error_warning", "rx_overruns")
    assert c.DIAG_BUS_FIELDS == fields and lib.ATT_CAN_BUS_OFF == 3 and len(c.BUS_STATES) == 4
    n = 300
    fr = c.frames(n)
    want = []
    for i in range(n):
        v = {k: int(rng.choice([0, 1, 254, 255, 256, 70000, int(rng.integers(0, 2**32))])) for k in fields}
        v["state"], v["lec"] = int(rng.integers(0, 256)), int(rng.integers(0, 256))
        d = ffi.new("att_can_bus_diag_t *", v)
        lib.att_can_encode_diag_bus(d, i % 256, ffi.from_buffer("att_can_frame_t[]", fr[i : i + 1]))
        want.append({**{k: min(v[k], 255) for k in fields}, "state": v["state"] & 3, "lec": v["lec"] & 7})
    rows = c.decode_outputs(fr).diag_bus
    assert rows.shape == (n,) and rows["crc_ok"].all() and (rows["counter"] == np.arange(n) % 16).all()
    back = ffi.new("att_can_bus_diag_t *")
    for i, w in enumerate(want):
        assert c.check(fr[i]) == c.Check.OK
        assert {k: int(rows[k][i]) for k in w} == w
        name, sig = c.decode(fr[i])
        assert name == "ATT_DIAG_BUS" and {k: int(sig[k]) for k in w} == w
        assert lib.att_can_decode_diag_bus(ffi.from_buffer("att_can_frame_t[]", fr[i : i + 1]), back)
        assert {k: int(getattr(back, k)) for k in w} == w
    assert c.decode_outputs(fr).other == 0


# --- DBC and generated code -----------------------------------------------------------------------


def test_generated_c_is_up_to_date_golden() -> None:
    import cantools

    committed = (gen.GEN / "att_can_db.c").read_text()
    need(
        f"cantools version {cantools.__version__}." in committed,
        "the committed firmware/src/can/generated/att_can_db.{c,h} were made by another cantools version "
        f"than {cantools.__version__}",
    )
    fresh = gen.generate()
    for name, text in fresh.items():
        assert (gen.GEN / name).read_bytes() == text.encode(), (
            f"{name} is stale: run python -m attica.can.gen"
        )
    assert gen.main(["--check"]) == 0


def test_generated_c_is_float_only_and_compiles_with_the_strict_flags(tmp_path: Path) -> None:
    for name in ("att_can_db.c", "att_can_db.h"):
        text = (gen.GEN / name).read_text()
        assert "double" not in text and "Mon " not in text
    flags = (ROOT / "firmware" / "cflags.txt").read_text().split()
    for cc in ("gcc", "clang"):
        exe = require_tool(cc)
        for opt in ("-O0", "-O2"):
            for src in ("att_can_db.c", "att_can.c", "att_node.c"):
                subprocess.run(
                    [
                        exe,
                        *flags,
                        opt,
                        "-I",
                        str(ROOT / "firmware" / "include"),
                        "-c",
                        str(next((ROOT / "firmware" / "src").rglob(src))),
                        "-o",
                        str(tmp_path / "x.o"),
                    ],
                    check=True,
                )


def test_dbc_matches_the_c_constants() -> None:
    db = c.database()
    by_id = {m.frame_id: m for m in db.messages}
    assert set(by_id) == set(c.MSG_LEN)
    for can_id, length in c.MSG_LEN.items():
        m = by_id[can_id]
        assert m.length == length and m.is_fd == (length == 64) and not m.is_extended_frame
        assert int(lib.att_can_msg_len(can_id)) == length
        assert (
            int(lib.att_can_data_id(can_id))
            == c.data_id(can_id)
            == c.dbc_data_ids()[can_id]
            == 0x0A00 + can_id
        )
        assert bool(lib.att_can_msg_has_crc(can_id)) == (can_id not in c.NO_CRC)
        names = [s.name for s in m.signals]
        assert (names[:2] == ["crc", "counter"]) == (can_id not in c.NO_CRC)
        if can_id in c.NO_CRC:
            assert m.dbc is not None and m.dbc.attributes["E2ECoveredBy"].value == "ATT_STATUS"
    names = {
        "IMU_GYRO": lib.ATT_CAN_ID_IMU_GYRO,
        "IMU_ACC": lib.ATT_CAN_ID_IMU_ACC,
        "IMU_MAG": lib.ATT_CAN_ID_IMU_MAG,
        "IMU_FD": lib.ATT_CAN_ID_IMU_FD,
        "ATT_QUAT_A": lib.ATT_CAN_ID_QUAT_A,
        "ATT_QUAT_B": lib.ATT_CAN_ID_QUAT_B,
        "ATT_QUAT16": lib.ATT_CAN_ID_QUAT16,
        "ATT_EULER": lib.ATT_CAN_ID_EULER,
        "ATT_BIAS": lib.ATT_CAN_ID_BIAS,
        "ATT_STATUS": lib.ATT_CAN_ID_STATUS,
        "ATT_DIAG": lib.ATT_CAN_ID_DIAG,
        "ATT_DIAG_BUS": lib.ATT_CAN_ID_DIAG_BUS,
        "ATT_OUT_FD": lib.ATT_CAN_ID_OUT_FD,
        "CMD": lib.ATT_CAN_ID_CMD,
    }
    for name, can_id in names.items():
        assert db.get_message_by_name(name).frame_id == can_id
    scales = {
        ("IMU_GYRO", "gyr_x"): lib.ATT_CAN_GYR_FRAC,
        ("IMU_ACC", "acc_y"): lib.ATT_CAN_ACC_FRAC,
        ("IMU_MAG", "mag_z"): lib.ATT_CAN_MAG_FRAC,
        ("ATT_QUAT16", "q_w"): lib.ATT_CAN_QUAT16_FRAC,
        ("ATT_EULER", "yaw"): lib.ATT_CAN_EULER_FRAC,
        ("ATT_BIAS", "bias_x"): lib.ATT_CAN_BIAS_FRAC,
    }
    for (msg, sig), frac in scales.items():
        s = db.get_message_by_name(msg).get_signal_by_name(sig)
        assert s.scale == 2.0**-frac and s.length == 16 and s.is_signed
        assert s.maximum == 32767 * 2.0**-frac and s.minimum == -32767 * 2.0**-frac
        assert s.choices is not None and s.choices[-32768] == "NA"
    for fd_name in ("IMU_FD", "ATT_OUT_FD"):
        m = db.get_message_by_name(fd_name)
        floats = [s for s in m.signals if s.is_float]
        assert all(s.length == 32 for s in floats) and len(floats) == (9 if fd_name == "IMU_FD" else 14)
    assert (
        c.GYR_FRAC == lib.ATT_CAN_GYR_FRAC
        and c.NA == lib.ATT_CAN_NA
        and c.DATA_ID_BASE == lib.ATT_CAN_DATA_ID_BASE
    )
    assert ffi.sizeof("att_can_frame_t") == c.FRAME_DTYPE.itemsize


def _by_scale(x: np.ndarray, frac: int) -> np.ndarray:
    """What cantools decodes an int16 field to: its code times the scale (full scale too), NA as NaN."""
    q = c.quantise(x, frac)
    return np.where(q == c.NA, np.float32(np.nan), q.astype(np.float32) * np.float32(2.0**-frac))


def test_cantools_decodes_frames_encoded_by_c() -> None:
    rng = np.random.default_rng(21)
    n = 40
    g = rng.normal(0, 5, (n, 3)).astype(np.float32)
    a = rng.normal(0, 30, (n, 3)).astype(np.float32)
    m = rng.normal(0, 200, (n, 3)).astype(np.float32)
    g[0] = [100.0, -100.0, np.nan]  # clamped and NA
    m[1] = np.nan  # no mag sample
    gq, aq, mq = c.imu_values(g, a, m)
    frac = {"gyr": c.GYR_FRAC, "acc": c.ACC_FRAC, "mag": c.MAG_FRAC}
    frames = _c_encode_imu(g, a, m, 6, False).reshape(n, 3)
    for i in range(n):
        for frame, prefix, want in zip(frames[i], ("gyr", "acc", "mag"), (gq[i], aq[i], mq[i])):
            name, sig = c.decode(frame)
            assert sig["counter"] == (6 + i) % 16 and name.startswith("IMU_")
            got = np.array([sig[f"{prefix}_{ax}"] for ax in "xyz"], np.float32)
            # cantools knows the scale only: full scale (+-32767) is 32767 2^-k there, clipped for attica
            full = np.abs(want) == c.CLIPPED
            assert (got[full] == np.sign(want[full]) * np.float32(32767 * 2.0 ** -frac[prefix])).all()
            assert ((got == want) | (np.isnan(got) & np.isnan(want)) | full).all()
    assert c.decode(frames[0][0])[1]["gyr_x"] == 32767 / 1024
    assert (gq[0, :2] == [c.CLIPPED, -c.CLIPPED]).all()  # the node's filter sees a clipped gyro
    fd = _c_encode_imu(g, a, m, 0, True)
    for i in range(n):
        name, sig = c.decode(fd[i])
        assert name == "IMU_FD"
        got = np.array([sig[f"{p}_{ax}"] for p in ("gyr", "acc", "mag") for ax in "xyz"], np.float32)
        want = np.concatenate([g[i], a[i], m[i]])
        # bit for bit; a NaN only has to stay NaN (cantools goes through a Python float)
        assert ((got.view(np.uint32) == want.view(np.uint32)) | (np.isnan(got) & np.isnan(want))).all(), (
            i,
            got,
            want,
        )
    o = _random_outputs(20, 4)
    o["euler"][0] = [0.1, np.nan, 5.0]
    classic = _c_encode_outputs(o, 3, 0, False).reshape(-1, 6)
    fdo = _c_encode_outputs(o, 3, 0, True)
    for i in range(20):
        sig = {}
        for frame in classic[i]:
            sig.update({f"{c.decode(frame)[0]}.{k}": v for k, v in c.decode(frame)[1].items()})
        q = np.array(
            [sig["ATT_QUAT_A.q_w"], sig["ATT_QUAT_A.q_x"], sig["ATT_QUAT_B.q_y"], sig["ATT_QUAT_B.q_z"]],
            np.float32,
        )
        wq = o["q"][i]
        assert ((q.view(np.uint32) == wq.view(np.uint32)) | (np.isnan(q) & np.isnan(wq))).all(), (i, q, wq)
        q16 = np.array([sig[f"ATT_QUAT16.q_{ax}"] for ax in "wxyz"], np.float32)
        want16 = _by_scale(o["q"][i], 14)
        assert ((q16 == want16) | (np.isnan(q16) & np.isnan(want16))).all()
        eu = np.array([sig["ATT_EULER.roll"], sig["ATT_EULER.pitch"], sig["ATT_EULER.yaw"]], np.float32)
        want_eu = _by_scale(o["euler"][i], 13)
        assert ((eu == want_eu) | (np.isnan(eu) & np.isnan(want_eu))).all()
        assert sig["ATT_STATUS.kind"] == 3 and sig["ATT_STATUS.flags"] == int(o["flags"][i]) & 0xFFFF
        assert sig["ATT_STATUS.steps"] == int(o["steps"][i]) & 0xFFFF and sig["ATT_STATUS.ack"] == 0
        name, s2 = c.decode(fdo[i])
        assert name == "ATT_OUT_FD" and s2["kind"] == 3
        got = np.array([s2[k] for k in ("q_w", "q_x", "q_y", "q_z", "roll", "pitch", "yaw")], np.float32)
        want = np.concatenate([o["q"][i], o["euler"][i]])
        assert ((got.view(np.uint32) == want.view(np.uint32)) | (np.isnan(got) & np.isnan(want))).all()
    name, sig = c.decode(c.encode_cmd(3, 2, 0.75, counter=9)[0])
    assert name == "CMD" and (sig["cmd"], sig["arg"], sig["value"], sig["counter"]) == (3, 2, 0.75, 9)
    # cantools and the C code agree on encoding too
    msg = c.database().get_message_by_name("ATT_QUAT_A")
    assert msg.encode({"q_w": 0.5, "q_x": -0.25}) == bytes(
        c.encode_outputs(_quat_out(0.5, -0.25), 1)[0]["data"][:8]
    )


def _quat_out(w: float, x: float) -> np.ndarray:
    o = np.zeros(1, OUTPUT_DTYPE)
    o["q"] = [[w, x, 0.0, 0.0]]
    return o


def test_python_can_roundtrip() -> None:
    f = np.concatenate(
        [
            c.encode_imu([[0.1, 0.2, 0.3]], [[0, 0, 9.8]], None),
            c.encode_imu([[0, 0, 1]], [[0, 0, 9.8]], None, fd=True),
        ]
    )
    for frame in f:
        msg = c.to_message(frame)
        assert msg.is_fd == bool(frame["fd"]) and not msg.is_extended_id and len(msg.data) == frame["len"]
        back = c.from_message(msg)
        assert back.tobytes() == np.array([frame], c.FRAME_DTYPE).tobytes()
        assert c.check(msg) == c.Check.OK
        assert c.decode(msg)[0] == c.decode(frame)[0]
    with pytest.raises(KeyError):
        c.decode((0x7FF, bytes(8)))
