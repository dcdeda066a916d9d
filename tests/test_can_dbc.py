"""`attica dbc`: attica.dbc with every message ID moved by the node's ID offset, and nothing else."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from attica import native, resources
from attica.can import codec
from attica.can.dbcshift import OFFSET_ATTRIBUTE, DbcShiftError, dbc_id_offset, shifted_dbc
from attica.can.idoffset import ID_OFFSET_MAX, ID_OFFSET_MIN
from attica.can.replay import ImuStream
from attica.cli import main
from attica.sim import SimConfig, simulate

RATE = 285.714
OFFSET = 0x20


def _stream(n: int, seed: int = 3) -> ImuStream:
    return ImuStream.from_recording(simulate(SimConfig(duration=n / RATE + 0.5, rate=RATE, seed=seed)), n)


def _sample_frames() -> np.ndarray:
    """Frames of every attica message the node and host send, at the DBC's IDs."""
    s = _stream(20)  # an ATT_DIAG every 16th set
    out = []
    for fd in (False, True):
        node = codec.Node(
            "mars", sample_rate=RATE, fd=fd, data_bitrate=2_000_000 if fd else 0, accel_out=True
        )
        imu = codec.encode_imu(s.gyr, s.acc, s.mag, fd=fd)
        sent, _ = node.run(np.concatenate([codec.encode_cmd(int(codec.Cmd.RESET), counter=1), imu]))
        out += [imu, sent, codec.encode_cmd(4, 0, 0.0, counter=2)]
    cal, _ = codec.Node("mars", sample_rate=RATE).run(codec.encode_cmd(4, 0, 0.0, counter=2))
    # ATT_MAG_OFFSET: a filter that estimates a hard-iron offset (after each ATT_DIAG)
    hard, _ = codec.Node("mars", sample_rate=RATE, hard_iron_tau=60.0).run(
        codec.encode_imu(s.gyr, s.acc, s.mag)
    )
    out.append(hard)
    # ATT_DIAG_BUS comes from a node on a Cortex-M port (its CAN controller's counters): the C encoder's
    bus = codec.frames(1)
    counters = {"state": 3, "lec": 3, "bus_off": 2, "recoveries": 1, "error_passive": 4, "error_warning": 5}
    d = native.ffi.new("att_can_bus_diag_t *", {**counters, "rx_overruns": 6})
    native.lib.att_can_encode_diag_bus(d, 7, native.ffi.from_buffer("att_can_frame_t[]", bus))
    return np.concatenate([*out, cal, bus])


@pytest.mark.parametrize("offset", [0, OFFSET, -0x20, ID_OFFSET_MIN, ID_OFFSET_MAX])
def test_the_moved_dbc(offset: int) -> None:
    import cantools

    original = cantools.database.load_file(str(resources.dbc_path()), strict=True)
    text = shifted_dbc(offset)
    moved = cantools.database.load_string(text, database_format="dbc", strict=True)
    assert dbc_id_offset(moved) == offset and dbc_id_offset(original) == 0
    assert f" ID offset {offset} (" in text  # the network comment says it too
    assert [m.name for m in moved.messages] == [m.name for m in original.messages]
    for a, b in zip(original.messages, moved.messages):
        assert b.frame_id == a.frame_id + offset
        assert b.comment == a.comment and b.senders == a.senders and b.is_fd == a.is_fd
        assert (
            b.dbc.attributes["E2EDataId"].value == a.dbc.attributes["E2EDataId"].value == 0x0A00 + a.frame_id
        )
        assert [(s.name, s.start, s.length, s.scale, s.comment, s.choices) for s in b.signals] == [
            (s.name, s.start, s.length, s.scale, s.comment, s.choices) for s in a.signals
        ]
    frames = _sample_frames()
    names = set()
    for f in frames:
        data = bytes(f["data"][: int(f["len"])])
        a = original.get_message_by_frame_id(int(f["id"]))
        b = moved.get_message_by_frame_id(int(f["id"]) + offset)
        assert a.name == b.name
        names.add(a.name)
        va, vb = a.decode(data, decode_choices=False), b.decode(data, decode_choices=False)
        assert {k: repr(v) for k, v in va.items()} == {k: repr(v) for k, v in vb.items()}
        assert b.encode(vb, strict=False) == a.encode(va, strict=False)
    assert names == {m.name for m in original.messages}  # every message tried


def test_the_moved_dbc_at_offset_0_is_the_committed_one() -> None:
    src = resources.dbc_path().read_text()
    text = shifted_dbc(0)
    assert text != src
    stripped = "".join(
        ln
        for ln in text.splitlines(keepends=True)
        if OFFSET_ATTRIBUTE not in ln or ln.startswith('CM_ "attica')
    )
    comment = re.search(r" ID offset 0 \([^\"]*\.", stripped)
    assert comment is not None
    assert stripped.replace(comment.group(0), "") == src  # byte for byte, but for what states the offset


def test_dbc_command(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    assert main(["dbc", "--id-offset", "0x20"]) == 0
    assert capsys.readouterr().out == shifted_dbc(OFFSET)
    out = tmp_path / "x.dbc"
    assert main(["dbc", "--id-offset=-0x100", "-o", str(out)]) == 0
    assert "every message ID -0x100 (-256)" in capsys.readouterr().out
    assert out.read_text() == shifted_dbc(-0x100)
    with pytest.raises(DbcShiftError, match="out of range: it must be from -256 to 1279"):
        shifted_dbc(1280)
    with pytest.raises(DbcShiftError, match="already states an ID offset"):
        shifted_dbc(0, out)
    # never over its own source
    original = resources.dbc_path().read_text()
    src = tmp_path / "attica.dbc"
    src.write_text(original)
    monkeypatch.setattr(resources, "dbc_path", lambda: src)
    assert main(["dbc", "-o", str(src)]) == 2
    assert "is attica's own DBC" in capsys.readouterr().err
    assert src.read_text() == original


def test_the_three_imu_parts_share_one_layout() -> None:
    """att_can_decode_imu_part unpacks IMU_GYRO, IMU_ACC and IMU_MAG with one generated unpack (the
    gyro's): their signals must sit alike (crc, counter, then x, y, z as little-endian int16 in bytes
    2..7), only the scale differs; and the C decoder gives each part's own values."""
    db = codec.database()
    layouts = []
    for name in ("IMU_GYRO", "IMU_ACC", "IMU_MAG"):
        m = db.get_message_by_name(name)
        assert m.length == 8
        layouts.append([(s.start, s.length, s.byte_order, s.is_signed) for s in m.signals])
    assert layouts[0] == layouts[1] == layouts[2]
    g = np.float32([[1.5, -2.25, 40.0]])
    a = np.float32([[0.5, -9.75, 200.0]])
    m = np.float32([[20.0, -40.5, 2000.0]])
    frames = codec.encode_imu(g, a, m)
    buf = native.ffi.from_buffer("att_can_frame_t[]", frames)
    v = native.ffi.new("att_vec3_t *")
    for i, want in enumerate(codec.imu_values(g, a, m)):
        assert native.lib.att_can_decode_imu_part(buf + i, v)
        got = np.float32([v.x, v.y, v.z])
        assert got.view(np.uint32).tolist() == want[0].view(np.uint32).tolist(), (i, got, want)
