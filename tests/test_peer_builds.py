"""The peers' own sources beside attica: Fusion and VQF fetched as sdists and built like attica
(tools/attica_dev/peer_sources.py), their drivers on the host and on the Cortex-M4F, the instruction trace
of their counted call, and the reports when a peer is unavailable.

Needs PyPI for the sdists (pip download into build/peers, reused afterwards), g++, arm-none-eabi-g++ with
the Arm C++ library and QEMU; a missing piece skips with the reason (fails under CI=true).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from attica_dev import boards, cross, cycles, peer_sources

from helpers import need


def _need(*tools: str) -> None:
    missing = [t for t in tools if shutil.which(t) is None]
    need(not missing, f"not installed: {cross.install_hint(missing)} (host/tools/install-system-deps.sh)")


@pytest.fixture(scope="module")
def peers(tmp_path_factory: pytest.TempPathFactory) -> dict[tuple[str, str], peer_sources.Built]:
    """Fusion and VQF drivers for the host (gcc) and the Cortex-M4F at -O2."""
    _need("gcc", "g++", "arm-none-eabi-gcc", "arm-none-eabi-g++", "qemu-system-arm")
    out = tmp_path_factory.mktemp("peers")
    built = {}
    try:
        for name, lib in peer_sources.LIBRARIES.items():
            built[(name, "host")] = peer_sources.build(lib, peer_sources.host_toolchain("gcc"), "-O2", out)
            built[(name, "m4f")] = peer_sources.build(lib, peer_sources.board_toolchain("m4f"), "-O2", out)
    except peer_sources.PeerUnavailableError as e:
        need(False, f"peer sources unavailable: {e}")
    return built


def _run(prefix: list[str], prog: Path, *args: str) -> list[str]:
    proc = subprocess.run(
        [*prefix, str(prog), *args], capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc.stdout.split()


@pytest.mark.parametrize("kind", list(peer_sources.KINDS))
def test_peer_driver_host_and_m4f(peers: dict[tuple[str, str], peer_sources.Built], kind: str) -> None:
    """Each peer configuration runs the benchmark stream on the host and on the M4F: a unit quaternion
    that has moved away from identity, the same attitude on both (to 1e-4: the peers' libm differs), and a
    stack probe on the target."""
    lib, _ = peer_sources.KINDS[kind]
    name = next(n for n, v in peer_sources.LIBRARIES.items() if v is lib)
    host = _run([], peers[(name, "host")].program, kind, "1000")
    m4f = _run(list(boards.BOARDS["m4f"].prefix), peers[(name, "m4f")].program, kind, "1000", "stack")
    assert m4f[:2] == ["stack", kind] and 32 < int(m4f[2]) < 4096
    qh = np.array([float(v) for v in host[host.index("q") + 1 :]])
    qm = np.array([float(v) for v in m4f[m4f.index("q") + 1 :]])
    assert abs(np.linalg.norm(qh) - 1.0) < 1e-3 and np.linalg.norm(qh[1:]) > 1e-3
    assert np.abs(qh - qm).max() < 1e-4, (qh, qm)
    with pytest.raises(AssertionError):
        _run([], peers[(name, "host")].program, "nosuch", "10")


@pytest.mark.parametrize("kind", ["fusion6", "vqf9"])
def test_peer_trace(peers: dict[tuple[str, str], peer_sources.Built], kind: str) -> None:
    """The counted call of a peer's driver (att_peer_step, C and C++ with libm callees) traces every step,
    with the same counts per block as per instruction."""
    lib, _ = peer_sources.KINDS[kind]
    name = next(n for n, v in peer_sources.LIBRARIES.items() if v is lib)
    elf = peers[(name, "m4f")].program
    a = cycles.trace_steps(elf, kind, 20, "att_peer_step")
    b = cycles.trace_steps_per_instruction(elf, kind, 20, "att_peer_step")
    assert len(a.instructions) == 20 and a.instructions == b.instructions and a.by_function == b.by_function
    lo, hi = (100, 3000) if kind.startswith("fusion") else (3000, 100_000)
    assert all(lo < n < hi for n in a.instructions), a.instructions
    assert "att_peer_step" in a.by_function


def test_peer_unavailable_says_why(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """A failed sdist download is a PeerUnavailableError naming the package and pip's reason; the cycles
    report then counts attica anyway and gives the peers' rows as n/a with the reason."""
    _need("arm-none-eabi-gcc", "qemu-system-arm")

    fake_pip = [
        sys.executable,
        "-c",
        "import sys; sys.exit('ERROR: No matching distribution found (offline)')",
    ]
    monkeypatch.setattr(peer_sources, "PEERS_DIR", tmp_path / "peers")
    monkeypatch.setattr(peer_sources, "PIP", fake_pip)
    with pytest.raises(peer_sources.PeerUnavailableError, match=r"imufusion==.*No matching distribution"):
        peer_sources.source_dir(peer_sources.LIBRARIES["fusion"])
    rows = [cycles.Counted("tilt", 0), *cycles.peer_rows()]
    counts = cycles.Counts()
    cycles.count_cortex(("m4f", "-O2"), rows, 10, tmp_path / "cycles", counts)
    tilt = counts.cortex[(("m4f", "-O2"), "tilt")]
    assert isinstance(tilt, cycles.StepCounts) and len(tilt.instructions) == 10
    assert all(isinstance(counts.cortex[(("m4f", "-O2"), r.label)], str) for r in rows if r.peer)
    text = cycles.report(counts, rows, [("m4f", "-O2")], 10)
    assert "n/a" in text and "No matching distribution" in text


def test_peer_flags_match_attica() -> None:
    """The peers get attica's optimisation and floating-point flags (no contraction, no math errno, no
    vectoriser), not its warnings or -fno-builtin."""
    flags = set(peer_sources.PEER_FLAGS)
    assert {"-ffp-contract=off", "-fno-math-errno", "-fno-tree-vectorize", "-DNDEBUG"} <= flags
    assert "-fno-builtin" not in flags and not any(f.startswith("-W") for f in flags)
