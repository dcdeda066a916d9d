"""The figures of docs/can.md that the build can compute, checked against the build.

Every number of the page that the code determines (constants, ring defaults and limits, struct sizes,
frames per set, message IDs and lengths, command codes, SET_GAIN per kind, calibration field indices,
the node's ranges, bus-load limits) is read here from the cffi binding (``attica.native``), the
preprocessor, a host program or the Cortex-M4F compiler (``attica_dev.footprint.sizeof``) and compared
with the text, so that a change of the code that the page does not follow fails a test. The bus-load
tables themselves are generated (tests/test_node.py, tests/test_calib_node.py compare them).
"""

from __future__ import annotations

import functools
import math
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from attica import _build, kinds, native
from attica.can import codec as c

from helpers import ROOT, need

ffi, lib = native.ffi, native.lib
CAN_MD = ROOT / "docs" / "can.md"
NODE_H = ROOT / "firmware" / "include" / "attica" / "att_node.h"
CAN_H = ROOT / "firmware" / "include" / "attica" / "att_can.h"
FILTER_H = ROOT / "firmware" / "include" / "attica" / "att_filter.h"
RATE = 200.0


@functools.cache
def _text() -> str:
    return CAN_MD.read_text()


def _flat(text: str) -> str:
    """The text with every run of white space one blank (sentences wrap anywhere)."""
    return " ".join(text.split())


def _section(title: str) -> str:
    """The text of the section ``## title`` (up to the next ``## ``)."""
    text = _text()
    start = text.index(f"\n## {title}\n")
    end = text.find("\n## ", start + 1)
    return text[start : end if end >= 0 else len(text)]


def _find(pattern: str, text: str | None = None) -> re.Match[str]:
    """The first match of ``pattern`` in the flattened page (or text); fails naming the pattern."""
    m = re.search(pattern, _flat(_text() if text is None else text))
    assert m is not None, f"docs/can.md no longer says: {pattern}"
    return m


def _table_after(marker: str) -> list[list[str]]:
    """The rows (cells stripped) of the Markdown table that follows the comment ``<!-- marker``."""
    text = _text()
    start = text.index(f"<!-- {marker}")
    rows: list[list[str]] = []
    for line in text[start:].splitlines()[1:]:
        if not line.startswith("|"):
            if rows:
                break
            continue
        cells = [x.strip() for x in line.strip().strip("|").split("|")]
        if not set("".join(cells)) <= set("-: "):
            rows.append(cells)
    return rows[1:]  # without the header


# --- the C side: macros under a configuration, host struct sizes ---------------------------------------


def _preprocess(defines: tuple[str, ...]) -> subprocess.CompletedProcess[str]:
    need(shutil.which("cc") is not None, "cc is not installed")
    return subprocess.run(
        ["cc", "-std=c99", "-dM", "-E", "-I", str(_build.INCLUDE), *defines, "-x", "c", "-"],
        input='#include "attica/att_node.h"\n',
        capture_output=True,
        text=True,
    )


@functools.cache
def _macros(defines: tuple[str, ...] = ()) -> dict[str, str]:
    """The object-like macros att_node.h defines under ``defines``."""
    proc = _preprocess(defines)
    assert proc.returncode == 0, proc.stderr
    return dict(re.findall(r"^#define (\w+) (.+)$", proc.stdout, re.M))


def _builds(defines: tuple[str, ...]) -> bool:
    """att_node.h (with att_config.h's #error checks) preprocesses under ``defines``."""
    return _preprocess(defines).returncode == 0


@functools.cache
def _host_sizeof(types: tuple[str, ...], defines: tuple[str, ...] = ()) -> dict[str, int]:
    """sizeof of public types in a host program compiled under ``defines``."""
    need(shutil.which("cc") is not None, "cc is not installed")
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "sizeof.c"
        body = "".join(f'    printf("{t} %lu\\n", (unsigned long)sizeof({t}));\n' for t in types)
        src.write_text(
            f'#include <stdio.h>\n#include "attica/att_node.h"\nint main(void)\n{{\n{body}    return 0;\n}}\n'
        )
        exe = Path(tmp) / "sizeof"
        subprocess.run(
            ["cc", "-std=c99", "-I", str(_build.INCLUDE), *defines, str(src), "-o", str(exe)], check=True
        )
        out = subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout
    return {name: int(n) for name, n in (line.split() for line in out.splitlines())}


# --- ATT_NODE_SET_MAX, rings, ring entries, att_node_t -------------------------------------------------


def test_set_max_with_and_without_the_stages() -> None:
    m = _find(
        r"the most one received frame can queue: (\d+) with the calibration stages .*?, (\d+) without them"
    )
    assert int(m.group(1)) == lib.ATT_NODE_SET_MAX == int(_macros()["ATT_NODE_SET_MAX"])
    assert int(m.group(2)) == int(_macros(("-DATT_WITH_CALIB=0",))["ATT_NODE_SET_MAX"])
    # what it counts: 6 (classic set) + 2 (acceleration) + 1 (DIAG) + 1 (DIAG_BUS) + 1 (MAG_OFFSET),
    # without the 2; a command's answer (1) comes instead of a set, never with one
    assert _find(
        r"\((\d+) for a classic set, (\d+) acceleration frames, 1 ATT_DIAG, 1 ATT_DIAG_BUS, 1 ATT_MAG_OFFSET"
    )
    assert lib.ATT_NODE_SET_MAX == 6 + 2 + 1 + 1 + 1
    # one less without a kind that has the hard-iron estimate
    assert _find(r"one less in a build\s+without a kind that estimates a hard-iron offset")
    for cfg in (("-DATT_WITH_HARD_IRON=0",), ("-DATT_WITH_MARS=0", "-DATT_WITH_MEKF=0")):
        assert int(_macros(cfg)["ATT_NODE_SET_MAX"]) == lib.ATT_NODE_SET_MAX - 1, cfg


def test_ring_defaults_limits_and_entries() -> None:
    m = _find(
        r"options of `attica/att_config.h` \((\d+) each by default; powers of two, "
        r"the rx ring (\d+) \.\. (\d+), the tx ring `ATT_NODE_SET_MAX` \.\. (\d+);"
    )
    default, rx_lo, rx_hi, tx_hi = (int(g) for g in m.groups())
    assert default == lib.ATT_NODE_RX_RING == lib.ATT_NODE_TX_RING
    assert (
        _build.config_defaults()["ATT_NODE_RX_RING"]
        == _build.config_defaults()["ATT_NODE_TX_RING"]
        == default
    )
    assert len(ffi.new("att_node_t *").rx) == len(ffi.new("att_node_t *").tx) == default
    # the limits are att_config.h's #error checks
    assert _builds((f"-DATT_NODE_RX_RING={rx_lo}",)) and not _builds((f"-DATT_NODE_RX_RING={rx_lo // 2}",))
    assert _builds((f"-DATT_NODE_RX_RING={rx_hi}",)) and not _builds((f"-DATT_NODE_RX_RING={2 * rx_hi}",))
    assert not _builds((f"-DATT_NODE_RX_RING={rx_lo + 1}",))  # not a power of two
    for calib in ("1", "0"):
        set_max = int(_macros((f"-DATT_WITH_CALIB={calib}",))["ATT_NODE_SET_MAX"])
        smallest = 1 << (set_max - 1).bit_length()  # the smallest power of two >= ATT_NODE_SET_MAX
        cfg = (f"-DATT_WITH_CALIB={calib}",)
        assert _builds((*cfg, f"-DATT_NODE_TX_RING={smallest}")), calib
        assert not _builds((*cfg, f"-DATT_NODE_TX_RING={smallest // 2}")), calib
    assert _builds((f"-DATT_NODE_TX_RING={tx_hi}",)) and not _builds((f"-DATT_NODE_TX_RING={2 * tx_hi}",))
    # a ring entry: att_can_frame_t, or 8 data bytes without CAN FD
    m = _find(
        r"`att_can_frame_t`, (\d+) bytes, or with `ATT_NODE_WITH_FD` 0 \(classic frames only\) "
        r"`att_node_frame_t` with (\d+) data bytes, (\d+) bytes\."
    )
    whole, data, small = (int(g) for g in m.groups())
    assert ffi.sizeof("att_can_frame_t") == ffi.sizeof("att_node_frame_t") == whole
    assert lib.ATT_NODE_FRAME_LEN == ffi.sizeof(ffi.new("att_can_frame_t *").data) == 64
    no_fd = ("-DATT_NODE_WITH_FD=0",)
    assert int(_macros(no_fd)["ATT_NODE_FRAME_LEN"]) == data
    assert _host_sizeof(("att_node_frame_t",), no_fd)["att_node_frame_t"] == small


def test_node_sizes_on_the_m4f(tmp_path: Path) -> None:
    """The Cortex-M4F sizes of att_node_t and of a ring entry, as the page gives them."""
    need(shutil.which("arm-none-eabi-gcc") is not None, "arm-none-eabi-gcc is not installed")
    from attica_dev import footprint

    m = _find(
        r"`att_node_t` on a Cortex-M4F is ([\d,]+) bytes with the defaults \(every kind, the stages, CAN FD, "
        r"rings of 64\) and ([\d,]+) bytes with the ARS alone, no stages, classic frames and rings of 8"
    )
    default, small = (int(g.replace(",", "")) for g in m.groups())
    types = ("att_node_t", "att_node_frame_t", "att_can_frame_t")
    got = footprint.sizeof(types, [], tmp_path / "default")
    assert got["att_node_t"] == default, got
    assert lib.ATT_NODE_RX_RING == 64
    small_cfg = [*footprint.only("ARS", calib=False), *footprint.NODE_SMALL]
    assert "-DATT_NODE_RX_RING=8" in small_cfg and "-DATT_NODE_WITH_FD=0" in small_cfg
    got_small = footprint.sizeof(types, small_cfg, tmp_path / "small")
    assert got_small["att_node_t"] == small, got_small
    entries = _find(
        r"`att_can_frame_t`, (\d+) bytes, .*? `att_node_frame_t` with 8 data bytes, (\d+) bytes\."
    )
    assert (got["att_node_frame_t"], got_small["att_node_frame_t"]) == tuple(int(g) for g in entries.groups())


# --- frames: IDs, lengths, frames per set, receive IDs -------------------------------------------------


def test_message_table_ids_lengths_and_directions() -> None:
    text = _text()
    for m in c.database().messages:
        length = f"{m.length} FD" if m.is_fd else str(m.length)
        way = "host -> node" if m.senders == ["HOST"] else "node -> host"
        assert f"| 0x{m.frame_id:03X} | {m.name} | {way} | {length} |" in text, m.name
    fd = [m.name for m in c.database().messages if m.is_fd]
    words = ["", "one", "two", "three", "four"]
    assert f"the {words[len(fd)]} CAN FD frames ({', '.join(fd)}) 64 bytes" in _flat(text)
    assert lib.ATT_CAN_FD_LEN == 64 and lib.ATT_CAN_CLASSIC_LEN == 8


def _frames_of_one_set(fd: bool, accel: bool) -> list[int]:
    node = c.Node(
        "ars",
        sample_rate=RATE,
        fd=fd,
        data_bitrate=2_000_000 if fd else 0,
        accel_out=accel,
        diag_divider=1,
    )
    assert node.push_sample((0.0, 0.0, 0.0), (0.0, 0.0, 9.81))
    return [int(i) for i in node.pop()["id"]]


def test_frames_per_set() -> None:
    """6 classic frames a set (+2 acceleration frames: 8), or 1 FD frame (+1: 2); then the DIAG."""
    classic = _frames_of_one_set(fd=False, accel=False)
    assert classic == [*range(c.ID_QUAT_A, c.ID_QUAT_A + 6), c.ID_DIAG]
    assert _find(r"classic QUAT_A, QUAT_B, QUAT16, EULER, BIAS, STATUS \((\d+) frames\)").group(1) == str(
        len(classic) - 1
    )
    accel = _frames_of_one_set(fd=False, accel=True)
    fd = _frames_of_one_set(fd=True, accel=False)
    fd_accel = _frames_of_one_set(fd=True, accel=True)
    assert accel[-1] == fd[-1] == fd_accel[-1] == c.ID_DIAG  # the DIAG after the acceleration frames
    assert accel[-3:-1] == [lib.ATT_CAN_ID_LIN_ACC, lib.ATT_CAN_ID_EARTH_ACC]
    assert fd_accel[:-1] == [lib.ATT_CAN_ID_OUT_FD, lib.ATT_CAN_ID_ACCEL_FD] and fd[:-1] == [
        lib.ATT_CAN_ID_OUT_FD
    ]
    m = _find(r"or one ATT_ACCEL_FD: (\d+) classic frames in all, or (\d+) FD frames\)")
    assert (int(m.group(1)), int(m.group(2))) == (len(accel) - 1, len(fd_accel) - 1)
    assert (
        int(_find(r"Classic with the acceleration frames \((\d+) frames per set\)").group(1))
        == len(accel) - 1
    )


def test_receive_ids_and_offset_limits() -> None:
    m = _find(r"\| IDs the node receives \| ([0-9a-fx, ]+) \| ([0-9a-fx, ]+) \|")
    at0 = [int(x, 16) for x in m.group(1).split(",")]
    at20 = [int(x, 16) for x in m.group(2).split(",")]
    assert c.Node("ars", sample_rate=RATE).rx_ids() == at0
    assert c.Node("ars", sample_rate=RATE, id_offset=0x20).rx_ids() == at20
    assert (
        len(at0) == lib.ATT_NODE_RX_IDS_MAX == int(_find(r"`att_node_rx_ids` gives (\d+) IDs then").group(1))
    )
    without_fd = [i for i in at0 if i != lib.ATT_CAN_ID_IMU_FD]
    assert len(without_fd) == int(_find(r"`ATT_NODE_RX_IDS_MAX`, and (\d+) without").group(1))
    m = _find(r"`ATT_NODE_ID_OFFSET_MIN` = (-?\d+) to `ATT_NODE_ID_OFFSET_MAX` = (\d+)")
    assert (int(m.group(1)), int(m.group(2))) == (lib.ATT_NODE_ID_OFFSET_MIN, lib.ATT_NODE_ID_OFFSET_MAX)
    ids = [msg.frame_id for msg in c.database().messages]
    assert min(ids) + lib.ATT_NODE_ID_OFFSET_MIN == 0 and max(ids) + lib.ATT_NODE_ID_OFFSET_MAX == 0x7FF
    m = _find(
        r"\| E2E data ID of ATT_STATUS \(CRC\) \| (0x[0-9A-F]+) \| (0x[0-9A-F]+): unchanged, (0x[0-9A-F]+) \+"
    )
    assert int(m.group(1), 16) == int(m.group(2), 16) == lib.att_can_data_id(lib.ATT_CAN_ID_STATUS)
    assert int(m.group(3), 16) == lib.ATT_CAN_DATA_ID_BASE
    assert _find(r"\| arbitration ID of ATT_STATUS \| 0x205 \| 0x225 \|")


# --- scaling, CRC, bus load ----------------------------------------------------------------------------


def test_scaling_table() -> None:
    fracs = {
        "gyro": lib.ATT_CAN_GYR_FRAC,
        "accel": lib.ATT_CAN_ACC_FRAC,
        "mag": lib.ATT_CAN_MAG_FRAC,
        "quaternion (ATT_QUAT16)": lib.ATT_CAN_QUAT16_FRAC,
        "Euler angles": lib.ATT_CAN_EULER_FRAC,
        "gyro bias": lib.ATT_CAN_BIAS_FRAC,
    }
    rows = {}
    for line in _section("Scaling").splitlines():
        cells = [x.strip() for x in line.strip().strip("|").split("|")]
        if line.startswith("|") and cells[0] in fracs:
            rows[cells[0]] = cells
    assert set(rows) == set(fracs)
    for name, k in fracs.items():
        _, doc_k, lsb, rng = rows[name]
        assert int(doc_k) == k, name
        value, unit = lsb.split(" ", 1) if " " in lsb else (lsb, "")
        milli = unit.startswith("m") and unit != "m/s^2"
        assert float(value) * (1e-3 if milli else 1.0) == pytest.approx(2.0**-k, rel=0.05), name
        assert float(rng.split()[0].lstrip("+-")) == pytest.approx(32767 * 2.0**-k, rel=0.01), name
    m = _find(r"q = round_half_even\(clamp\(x \* 2\^k, -(\d+), \+(\d+)\)\), NaN -> (-\d+)")
    assert (int(m.group(1)), int(m.group(2)), int(m.group(3))) == (32767, 32767, lib.ATT_CAN_NA)


def test_crc_figures() -> None:
    m = _find(
        r"polynomial (0x[0-9A-F]+), init (0x[0-9A-F]+), final XOR (0x[0-9A-F]+), not reflected; check value "
        r"over ASCII `123456789` is (0x[0-9A-F]+)"
    )
    poly, init, xor, check = (int(g, 16) for g in m.groups())
    assert (poly, init, xor) == (0x1D, 0xFF, 0xFF)
    assert lib.att_can_crc8(b"123456789", 9, init) ^ xor == check
    assert int(_find(r"Data ID = (0x[0-9A-F]+) \+ CAN ID").group(1), 16) == lib.ATT_CAN_DATA_ID_BASE


def _accepts(rate: float, bitrate: int, data_bitrate: int, fd: bool, accel: bool) -> bool:
    s = ffi.new("att_node_settings_t *")
    assert lib.att_node_settings_default(lib.ATT_FILTER_TILT, rate, s) == lib.ATT_OK  # tilt: no dt to match
    s.bitrate, s.data_bitrate, s.fd, s.accel_out = bitrate, data_bitrate, fd, accel
    return bool(lib.att_node_init(ffi.new("att_node_t *"), s) == lib.ATT_OK)


def test_bus_load_figures() -> None:
    assert int(_find(r"\(8 bytes: (\d+) bits\)").group(1)) == lib.att_node_classic_bits(8)
    m = _find(r"= (\d+) for n = 64 time = 34 / nominal rate \+ data bits / data rate \(500k/2M: (\d+) us\)")
    data_bits = round((c.fd_frame_time(64, 500_000, 2_000_000) - 34 / 500e3) * 2e6)
    assert int(m.group(1)) == data_bits
    assert int(m.group(2)) == round(lib.att_node_fd_frame_time(64, 500_000, 2_000_000) * 1e6)
    m = _find(r"classic (\d+) Hz at 500k, (\d+) Hz at 1M; FD (\d+) Hz at 500k/2M, (\d+) Hz at 1M/5M")
    buses = [
        (500_000, 0, False),
        (1_000_000, 0, False),
        (500_000, 2_000_000, True),
        (1_000_000, 5_000_000, True),
    ]
    m2 = _find(r"fits up to (\d+) Hz at 500 kbit/s and (\d+) Hz at 1 Mbit/s")
    cases = [(*b, False, int(r)) for b, r in zip(buses, m.groups())]
    cases += [(500_000, 0, False, True, int(m2.group(1))), (1_000_000, 0, False, True, int(m2.group(2)))]
    for br, dbr, fd, accel, rate in cases:
        assert _accepts(float(rate), br, dbr, fd, accel), (br, dbr, fd, accel, rate)
        assert not _accepts(float(rate + 1), br, dbr, fd, accel), (br, dbr, fd, accel, rate)
        assert math.floor(1.0 / c.bus_load(1.0, br, dbr, fd, accel_out=accel)) == rate


# --- commands ------------------------------------------------------------------------------------------


def test_command_and_answer_codes() -> None:
    cmds = {
        "select filter": lib.ATT_CAN_CMD_SELECT,
        "reset": lib.ATT_CAN_CMD_RESET,
        "set gain": lib.ATT_CAN_CMD_SET_GAIN,
    }
    for name, code in cmds.items():
        assert f"| {code} {name} |" in _text(), name
    cal = {
        "CAL_BEGIN": lib.ATT_CAN_CMD_CAL_BEGIN,
        "CAL_SET": lib.ATT_CAN_CMD_CAL_SET,
        "CAL_COMMIT": lib.ATT_CAN_CMD_CAL_COMMIT,
        "CAL_ABORT": lib.ATT_CAN_CMD_CAL_ABORT,
        "SET_CONVENTION": lib.ATT_CAN_CMD_SET_CONVENTION,
        "SET_REMAP": lib.ATT_CAN_CMD_SET_REMAP,
    }
    for name, code in cal.items():
        assert f"| {code} | {name} |" in _text(), name
    m = _find(
        r"`ack = (0x[0-9a-f]+) \| result << 4 \| cmd`, result (\d) ok, (\d) unknown command, "
        r"(\d) bad argument \(.*?\), (\d) refused"
    )
    assert int(m.group(1), 16) == lib.ATT_CAN_ACK_ANSWER
    assert [int(g) for g in m.groups()[1:]] == [
        lib.ATT_CAN_ACK_OK,
        lib.ATT_CAN_ACK_UNKNOWN_CMD,
        lib.ATT_CAN_ACK_BAD_ARG,
        lib.ATT_CAN_ACK_REFUSED,
    ]
    m = _find(r"\| arg 0 ENU, 1 NED, 2 NWU \|")
    assert (lib.ATT_CONV_ENU, lib.ATT_CONV_NED, lib.ATT_CONV_NWU) == (0, 1, 2) and m
    assert int(_find(r"\| arg 0 \(quaternion identity\), 1\.\.(\d+) \(att_calib_remap_name\)").group(1)) == (
        lib.ATT_CALIB_REMAPS
    )
    m = _find(r"\(0 no hook, 1 saved, 2 failed: applied anyway\)")
    assert (lib.ATT_CAN_PERSIST_NONE, lib.ATT_CAN_PERSIST_OK, lib.ATT_CAN_PERSIST_FAILED) == (0, 1, 2) and m
    assert (
        int(_find(r"e\.g\. (\d+) = soft iron singular or ill-conditioned").group(1))
        == lib.ATT_CALIB_ERR_MAG_MATRIX
    )


_VALUES = {
    c.Gain.TAU_ACC: (0.5, 0.0),
    c.Gain.TAU_MAG: (4.0, 0.0),
    c.Gain.KF_R: (2.5,),
    c.Gain.EKF_R: (2.0,),
    c.Gain.DECLINATION: (0.3, -2.5),
}
"""The values each SET_GAIN parameter is sent with (a time constant also 0: the full correction)."""


def _doc_gains() -> dict[tuple[int, str], dict[str, str]]:
    """The SET_GAIN table: (arg, kind) -> {settings field: rule of its new value}."""
    out: dict[tuple[int, str], dict[str, str]] = {}
    for arg, parameter, kind, written in _table_after("set-gain-table"):
        name = re.match(r"`ATT_CAN_GAIN_(\w+)`", parameter)
        assert name is not None and int(c.Gain[name.group(1)]) == int(arg), parameter
        fields = {}
        for part in written.split(", "):
            m = re.fullmatch(r"`(\w+)\.(\w+)` = (v|0 if v > 0 else 1)", part)
            assert m is not None and m.group(1) == kind, part
            fields[m.group(2)] = m.group(3)
        out[(int(arg), kind)] = fields
    return out


def _value(rule: str, v: float) -> float:
    return v if rule == "v" else (0.0 if v > 0 else 1.0)


@pytest.mark.parametrize("k", kinds.KINDS, ids=lambda k: k.label)
def test_set_gain_table(k: Any) -> None:
    """Each SET_GAIN parameter writes exactly the settings the table names for the running kind (the
    other bytes of the settings unchanged), and answers bad argument for a pair the table does not list."""
    documented = _doc_gains()
    assert {kind for _, kind in documented} <= {x.label for x in kinds.KINDS}
    still = np.zeros((5, 3), np.float32)
    acc = np.tile(np.array([0.0, 0.0, 9.8], np.float32), (5, 1))
    mag = np.tile(np.array([20.0, 0.0, -40.0], np.float32), (5, 1))
    for gain, values in _VALUES.items():
        for v in values:
            node = c.Node(k.label, sample_rate=RATE)
            node.run(c.encode_imu(still, acc, mag))
            expected = node.state.fs.copy()
            out, _ = node.run(c.encode_cmd(c.Cmd.SET_GAIN, gain, v, counter=5))
            (ans,) = c.decode_outputs(out).answers
            fields = documented.get((int(gain), k.label))
            if fields is None:
                assert ans.result == c.Ack.BAD_ARG, (gain, v)
            else:
                assert ans.result == c.Ack.OK, (gain, v)
                member = getattr(expected, k.label)
                for field, rule in fields.items():
                    setattr(member, field, _value(rule, v))
            assert bytes(node.state.fs) == bytes(expected), (k.label, gain.name, v)
    assert {g for (g, kind) in documented if kind == k.label} == {int(g) for g in k.gains}


# --- calibration fields --------------------------------------------------------------------------------


def test_calibration_field_table() -> None:
    """Index i of CAL_SET writes the member the table names (element i - first of its range)."""
    rows = _table_after("calib-field-table")
    seen: list[int] = []
    for index, field in rows:
        m = re.fullmatch(r"(\d+)(?: \.\. (\d+))?", index)
        f = re.match(r"`([\w.]+)`", field)
        assert m is not None and f is not None, (index, field)
        lo, hi = int(m.group(1)), int(m.group(2) or m.group(1))
        path = f.group(1).split(".")
        base = ffi.offsetof("att_calib_settings_t", *path)
        for i in range(lo, hi + 1):
            s0 = ffi.new("att_calib_settings_t *")
            lib.att_calib_settings_default(s0)
            s1 = ffi.new("att_calib_settings_t *")
            lib.att_calib_settings_default(s1)
            integer = path[-1] in ("remap", "convention", "accel_outputs")
            assert lib.att_calib_field_set(s1, i, 1.0 if integer else 0.5), i
            a, b = bytes(ffi.buffer(s0)), bytes(ffi.buffer(s1))
            first = next(j for j in range(len(a)) if a[j] != b[j])
            element = base + 4 * (i - lo)
            assert element <= first < element + 4, (i, field)
            seen.append(i)
    assert seen == list(range(lib.ATT_CALIB_FIELDS))
    assert int(_find(r"`ATT_CALIB_FIELDS` = (\d+) of them").group(1)) == lib.ATT_CALIB_FIELDS
    assert _find(r"\| (\d+) \| CAL_SET \| arg = field index 0\.\.(\d+),").group(2) == str(
        lib.ATT_CALIB_FIELDS - 1
    )


# --- the C API paragraph and the node's ranges ---------------------------------------------------------


def _declared(header: Path, prefix: str) -> set[str]:
    return set(re.findall(rf"^[a-z_0-9 ]+?\**\b({prefix}\w+)\(", header.read_text(), re.M))


def _named(text: str) -> set[str]:
    """Function names in the text, ``att_can_encode_imu`` / ``_imu_fd`` style lists expanded."""
    names: set[str] = set()
    prefix = ""
    for word in re.findall(r"`([\w]+)", text):
        if word.startswith("att_"):
            names.add(word)
            m = re.match(r"(att_can_(?:encode|decode)_)", word)
            prefix = m.group(1) if m else ""
        elif word.startswith("_") and prefix:
            names.add(prefix + word[1:])
    return names


def test_c_api_paragraph_names_every_function_and_field() -> None:
    api = _flat(_section("C API"))
    named = _named(api)
    for header, prefix in ((NODE_H, "att_node_"), (CAN_H, "att_can_")):
        missing = _declared(header, prefix) - named
        assert not missing, f"docs/can.md's C API does not name {sorted(missing)} ({header.name})"
    m = _find(r"`att_node_settings_t \{([\w, ]+)\}`", api)
    assert [x.strip() for x in m.group(1).split(",")] == [
        f[0] for f in ffi.typeof("att_node_settings_t").fields
    ]
    m = _find(r"`att_can_frame_t \{([\w, \[\]0-9]+)\}`", api)
    assert [re.sub(r"\[\d+\]", "", x.strip()) for x in m.group(1).split(",")] == [
        f[0] for f in ffi.typeof("att_can_frame_t").fields
    ]


def test_node_ranges_are_those_of_att_node_settings_check() -> None:
    """The node's ranges in the text are the rules att_node_settings_check reports."""
    api = _flat(_section("C API"))
    bad = {
        "sample_rate": 0.0,
        "bitrate": 999,
        "data_bitrate": 16_000_001,
        "output_divider": 0,
        "id_offset": lib.ATT_NODE_ID_OFFSET_MAX + 1,
        "fd": True,
    }
    why = ffi.new("att_settings_error_t *")
    for field, value in bad.items():
        s = ffi.new("att_node_settings_t *")
        assert lib.att_node_settings_default(lib.ATT_FILTER_TILT, 100.0, s) == lib.ATT_OK
        setattr(s, field, value)
        assert lib.att_node_settings_check(s, why) == lib.ATT_ERR_SETTINGS, field
        assert ffi.string(why.field).decode() == field
        rule = ffi.string(why.rule).decode()
        unit = ffi.string(why.unit).decode()
        text = f"`{field}` {rule}" + (f" {unit}" if unit else "")
        assert text in api, f"docs/can.md's C API should say: {text}"
    m = _find(r"the filter's dt = 1 / sample_rate within ([\d.]+) %", api)
    tol = float(m.group(1)) / 100
    for off, ok in ((0.9 * tol, True), (1.1 * tol, False)):
        s = ffi.new("att_node_settings_t *")
        assert lib.att_node_settings_default(lib.ATT_FILTER_ARS, RATE, s) == lib.ATT_OK
        s.filter.ars.dt = (1.0 + off) / RATE
        assert (lib.att_node_init(ffi.new("att_node_t *"), s) == lib.ATT_OK) == ok, off


# --- a rate for the node, a period for the filter ------------------------------------------------------


def test_node_takes_a_rate_and_the_filter_a_period() -> None:
    """att_node_settings_default takes Hz, att_filter_settings_default s; the names and comments say so,
    the page says so, and a period given to the node is refused by att_node_init for every kind with a
    period, naming <kind>.dt (validation unchanged: the mistake is caught there already)."""
    node_h, filter_h = NODE_H.read_text(), FILTER_H.read_text()
    assert re.search(r"att_node_settings_default\(att_filter_kind_t kind, float sample_rate,", node_h)
    assert re.search(r"att_filter_settings_default\(att_filter_kind_t kind, float dt,", filter_h)
    comment = node_h[: node_h.index("att_status_t att_node_settings_default(")].rsplit("/**", 1)[1]
    comment = _flat(re.sub(r"^\s*\*", "", comment, flags=re.M))
    assert "RATE in Hz" in comment and "not a period" in comment and "att_filter_settings_default" in comment
    assert "sample period dt (s)" in _flat(filter_h)
    assert _find(r"\*\*A rate, not a period\.\*\* `att_node_settings_default` takes the sample rate in Hz")
    assert _find(r"`att_filter_settings_default\(kind, dt, &fs\)` takes the sample period `dt` in s")
    why = ffi.new("att_settings_error_t *")
    for k in kinds.KINDS:
        s = ffi.new("att_node_settings_t *")
        assert lib.att_node_settings_default(int(k.kind), 0.01, s) == lib.ATT_OK, k.label  # 0.01 "s"
        status = lib.att_node_init(ffi.new("att_node_t *"), s)
        assert (status == lib.ATT_ERR_SETTINGS) == k.has_period, k.label
        if k.has_period:
            assert lib.att_node_settings_check(s, why) == lib.ATT_ERR_SETTINGS
            assert ffi.string(why.field).decode() == f"{k.label}.dt"
            with pytest.raises(c.NodeError, match=r"sample_rate is a rate in Hz, not a period"):
                c.Node(k.label, sample_rate=0.01)
    assert [k.label for k in kinds.KINDS if not k.has_period] == ["tilt"]
    assert _find(r"Only tilt has no period and takes any rate\.")
