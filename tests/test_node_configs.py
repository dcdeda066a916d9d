"""The CAN node in other build configurations (att_config.h): small rings, classic frames only, an ID offset.

tests/c/att_node_run.c runs the node of one configuration over a file of frames as a port does (rx,
poll, drain tx after each frame). Its output frames and counters must hash to the committed node
digests (tests/digests.txt, written by the default build through the cffi binding): the small node a
microcontroller gets is the same node, bit for bit. The node's own sizes are in ``make footprint``.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from attica.can import codec as c
from attica.can.layout import FRAME_DTYPE, frames
from attica.settings import FilterKind
from attica_dev import digests, footprint, golden

from helpers import ROOT, need

SMALL = [*footprint.only("ARS", calib=False), *footprint.NODE_SMALL]
"""ARS only, no stages, classic frames only, rings of 8: the quickstart's node."""

CONFIGS: dict[str, list[str]] = {
    "small": SMALL,
    "classic-only": ["-DATT_NODE_WITH_FD=0"],
    "default": [],
}

STATS = (
    "rx_frames crc_errors counter_gaps dlc_errors unknown_ids duplicates stale_partials rx_overflows "
    "tx_overflows samples steps_stat sets tx_frames commands"
).split()


class Runner:
    """tests/c/att_node_run.c built for one configuration."""

    def __init__(self, defines: list[str], out: Path) -> None:
        self.exe = golden.build_program(
            [ROOT / "tests" / "c" / "att_node_run.c"], "gcc", "-O2", defines, "att_node_run", out
        )
        self.out = out

    def run(
        self, kind: FilterKind, fr: np.ndarray, fd: bool = False, id_offset: int = 0
    ) -> tuple[np.ndarray, int, dict[str, int]]:
        """(output frames, steps, counters) of the node over ``fr``."""
        src, dst = self.out / "in.bin", self.out / "out.bin"
        np.ascontiguousarray(fr, FRAME_DTYPE).tofile(src)
        bitrate, data_bitrate = digests.NODE_BITRATES[fd]
        args = [int(kind), digests.RATE, int(fd), bitrate, data_bitrate, id_offset, src, dst]
        proc = subprocess.run([str(self.exe), *map(str, args)], capture_output=True, text=True, timeout=120)
        values = {m.group(1): int(m.group(2)) for m in re.finditer(r"^(\w+)=(-?\d+)$", proc.stdout, re.M)}
        if proc.returncode == 3:
            raise ValueError("refused: " + " ".join(f"{k}={v}" for k, v in values.items()))
        assert proc.returncode == 0, proc.stderr
        assert values["sizeof_frame"] == FRAME_DTYPE.itemsize
        return np.fromfile(dst, FRAME_DTYPE), values["steps"], values


@pytest.fixture(scope="module", params=sorted(CONFIGS))
def runner(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> tuple[str, Runner]:
    need(shutil.which("gcc") is not None, "gcc is not installed")
    name: str = request.param
    return name, Runner(CONFIGS[name], tmp_path_factory.mktemp(name))


def _stats(values: dict[str, int]) -> list[int]:
    return [values[k] for k in STATS]


def _shift(fr: np.ndarray, offset: int) -> np.ndarray:
    out = np.array(fr, FRAME_DTYPE, copy=True)
    out["id"] = (out["id"].astype(np.int64) + offset).astype(np.uint32)
    return out


def test_node_frames_equal_the_committed_digests(runner: tuple[str, Runner]) -> None:
    name, r = runner
    committed = digests.read()
    kinds = [FilterKind.ARS] if name == "small" else list(FilterKind)
    for kind in kinds:
        for fd in (False, True) if name == "default" else (False,):
            out, steps, values = r.run(kind, digests.node_stream(kind), fd)
            key = f"{kind.label}.node.{'fd' if fd else 'classic'}"
            assert digests.node_sha(out, steps, _stats(values)) == committed[key], f"{name}: {key}"


@pytest.mark.parametrize("offset", [0x20, -0x100, 0x4FF])
def test_an_id_offset_moves_every_frame_and_nothing_else(runner: tuple[str, Runner], offset: int) -> None:
    name, r = runner
    stream = digests.node_stream(FilterKind.ARS)
    out, steps, values = r.run(FilterKind.ARS, _shift(stream, offset), id_offset=offset)
    assert out["id"].min() >= 0 and out["id"].max() <= 0x7FF
    back = _shift(out, -offset)
    assert digests.node_sha(back, steps, _stats(values)) == digests.read()["ars.node.classic"], name
    # the same frames at the DBC's own IDs are another node's: counted, never used
    out, steps, values = r.run(FilterKind.ARS, stream[:300], id_offset=offset)
    assert steps == 0 and len(out) == 0 and values["unknown_ids"] == 300


def test_a_classic_only_node_refuses_fd(runner: tuple[str, Runner]) -> None:
    """Without CAN FD (ATT_NODE_WITH_FD 0): fd settings refused, IMU_FD frames not for the node, a
    64-byte frame at a classic ID a length error; the default build steps the same IMU_FD frames."""
    name, r = runner
    g, a, m = digests.sim_stream()
    fd_frames = c.encode_imu(g[:50], a[:50], m[:50], fd=True)
    long_classic = c.encode_imu(g[:10], a[:10], m[:10])
    long_classic["len"] = 64
    long_classic["fd"] = 1
    out, steps, values = r.run(FilterKind.ARS, np.concatenate([fd_frames, long_classic]))
    assert values["dlc_errors"] == 30
    if name == "default":
        assert steps == 50 and values["unknown_ids"] == 0
        assert r.run(FilterKind.ARS, fd_frames, fd=True)[1] == 50
        return
    assert steps == 0 and len(out) == 0 and values["unknown_ids"] == 50
    with pytest.raises(ValueError, match="init=-2$"):  # ATT_ERR_SETTINGS
        r.run(FilterKind.ARS, frames(0), fd=True)


def test_the_small_node_is_small(tmp_path: Path) -> None:
    """sizeof(att_node_t) of the small configuration on the host (the M4F figures: make footprint)."""
    need(shutil.which("gcc") is not None, "gcc is not installed")
    r = Runner(SMALL, tmp_path)
    _, _, values = r.run(FilterKind.ARS, frames(0))
    assert values["sizeof_node"] <= 2048, values["sizeof_node"]


@pytest.mark.parametrize(
    ("defines", "message"),
    [
        (["-DATT_NODE_WITH_FD=2"], "ATT_NODE_WITH_FD must be 0 or 1"),
        (["-DATT_NODE_RX_RING=12"], "ATT_NODE_RX_RING must be a power of two"),
        (["-DATT_NODE_RX_RING=2"], "ATT_NODE_RX_RING must be a power of two from 4"),
        (["-DATT_NODE_TX_RING=8"], "ATT_NODE_TX_RING must be a power of two from ATT_NODE_SET_MAX"),
        (["-DATT_WITH_CALIB=0", "-DATT_NODE_TX_RING=4"], "ATT_NODE_TX_RING must be a power of two"),
    ],
)
def test_bad_node_configuration_stops_the_build(defines: list[str], message: str, tmp_path: Path) -> None:
    need(shutil.which("gcc") is not None, "gcc is not installed")
    with pytest.raises(golden.GoldenError, match=message):
        golden.build_program([ROOT / "tests" / "c" / "att_node_run.c"], "gcc", "-O0", defines, "x", tmp_path)
