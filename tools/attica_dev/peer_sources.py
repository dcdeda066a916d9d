"""The peers' own C and C++, fetched and built as attica is: Fusion (imufusion sdist), VQF (vqf sdist).

Nothing of the peers is in this repository. :func:`source_dir` runs ``pip download --no-deps
--no-binary PACKAGE PACKAGE==VERSION`` (the published source distribution, never a wheel) into
build/peers/ and unpacks it there; later runs reuse it. ``--no-binary`` names the package rather than
``:all:`` because pip prepares the sdist's metadata in a build environment, and ``:all:`` would also
force that environment's numpy to build from source.

Each peer library has a driver in tests/c (att_peer_fusion.c, att_peer_vqf.cpp) that feeds it the
samples of tests/c/att_bench_common.h, the same stream tests/c/att_bench.c feeds attica, and exposes
one counted call, ``att_peer_step`` (the update and the quaternion out). :func:`build` compiles the
peer's sources and the driver for the host or for a Cortex-M board with:

- the board's code generation flags (:mod:`attica_dev.boards`) and the same optimisation level;
- the optimisation and floating-point flags of firmware/cflags.txt (:data:`PEER_FLAGS`: no FP
  contraction, no errno from math, no vectoriser), but not its warnings, ``-std=c99`` or
  ``-fno-builtin`` (the peers call libm; ``-fno-builtin`` would turn ``sqrtf`` into a library call);
  ``-DNDEBUG`` (a release build);
- VQF: ``-DVQF_SINGLE_PRECISION`` (float, as attica), ``-fno-exceptions -fno-rtti``.

Where a download or a compiler is missing, :class:`PeerUnavailableError` says why and the reports print it
in the peers' rows; attica's rows never depend on the peers.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from attica import _build
from attica_dev.boards import BOARDS, PORT_SOURCES, SECTIONS, STARTUP_SOURCES, CortexM

ROOT = _build.ROOT
PEERS_DIR = ROOT / "build" / "peers"
TESTS_C = ROOT / "tests" / "c"

VERSIONS = {"imufusion": "1.3.3", "vqf": "2.1.2"}
"""The sdist versions counted (the releases measured in issue 9)."""

PEER_FLAGS: tuple[str, ...] = (
    *(
        f
        for f in _build.cflags()
        if f.startswith("-f") and f != "-fno-builtin" and not f.startswith("-fvisibility")
    ),
    "-DNDEBUG",
)
"""The optimisation-relevant flags of firmware/cflags.txt, applied to the peers too, and -DNDEBUG (a
release build: VQF's asserts compile away, as attica has none)."""


PIP: list[str] = [sys.executable, "-m", "pip"]
"""The pip that fetches the sdists (this interpreter's)."""


class PeerUnavailableError(RuntimeError):
    """A peer cannot be fetched or built here (the message says why)."""


@dataclass(frozen=True)
class PeerKind:
    """One counted configuration of a peer (e.g. Fusion 6-axis)."""

    name: str
    """Driver argument and table label (``fusion6``, ``vqf9``...)."""
    axes: int
    """6 (gyro + accel) or 9 (+ mag): compared with attica's filters of the same inputs."""
    call: str
    """What att_peer_step calls, for the tables."""


@dataclass(frozen=True)
class PeerLibrary:
    """A peer library: its sdist, sources, driver and flags."""

    name: str
    """``Fusion`` or ``VQF``."""
    package: str
    """PyPI package of the sdist (and of the Python binding used by ``make bench``)."""
    driver: Path
    sources: Callable[[Path], list[Path]]
    """Peer sources to compile, from the unpacked sdist directory."""
    includes: Callable[[Path], list[Path]]
    cplusplus: bool
    kinds: tuple[PeerKind, ...]
    defines: tuple[str, ...] = ()
    cxx_flags: tuple[str, ...] = ()

    @property
    def version(self) -> str:
        """The sdist version."""
        return VERSIONS[self.package]

    @property
    def label(self) -> str:
        """``Fusion 1.3.3``."""
        return f"{self.name} {self.version}"


LIBRARIES: dict[str, PeerLibrary] = {
    "fusion": PeerLibrary(
        "Fusion",
        "imufusion",
        TESTS_C / "att_peer_fusion.c",
        lambda d: sorted((d / "Fusion").glob("*.c")),
        lambda d: [d / "Fusion"],
        False,
        (
            PeerKind("fusion6", 6, "FusionAhrsUpdateNoMagnetometer"),
            PeerKind("fusion9", 9, "FusionAhrsUpdate"),
        ),
    ),
    "vqf": PeerLibrary(
        "VQF",
        "vqf",
        TESTS_C / "att_peer_vqf.cpp",
        lambda d: [d / "vqf" / "cpp" / "vqf.cpp"],
        lambda d: [d / "vqf" / "cpp"],
        True,
        (PeerKind("vqf6", 6, "VQF::update(gyr, acc)"), PeerKind("vqf9", 9, "VQF::update(gyr, acc, mag)")),
        ("-DVQF_SINGLE_PRECISION",),
        ("-fno-exceptions", "-fno-rtti"),
    ),
}
"""The peers, by short name."""

KINDS: dict[str, tuple[PeerLibrary, PeerKind]] = {
    k.name: (lib, k) for lib in LIBRARIES.values() for k in lib.kinds
}
"""Every counted peer configuration by name."""


# --- fetching ----------------------------------------------------------------------------------------


def _download(package: str, version: str, dest: Path) -> Path:
    dest.mkdir(parents=True, exist_ok=True)
    found = sorted(dest.glob(f"{package}-{version}.tar.gz"))
    if found:
        return found[0]
    cmd = [
        *PIP,
        "download",
        "--no-deps",
        "--no-binary",
        package,
        "--disable-pip-version-check",
        f"{package}=={version}",
        "-d",
        str(dest),
    ]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    except (OSError, subprocess.TimeoutExpired) as e:
        raise PeerUnavailableError(f"pip download {package}=={version} failed: {e}") from e
    found = sorted(dest.glob(f"{package}-{version}.tar.gz"))
    if proc.returncode != 0 or not found:
        tail = [ln for ln in (proc.stderr or proc.stdout).strip().splitlines() if ln.strip()][-1:]
        raise PeerUnavailableError(
            f"pip download {package}=={version} (sdist) failed: {tail[0] if tail else proc.returncode}"
        )
    return found[0]


def _unpack(archive: Path, dest: Path) -> Path:
    dest.mkdir(parents=True, exist_ok=True)
    root = dest / archive.name.removesuffix(".tar.gz")
    if (root / "PKG-INFO").exists():
        return root
    with tempfile.TemporaryDirectory(dir=dest) as tmp, tarfile.open(archive) as tar:
        for member in tar.getmembers():
            target = (Path(tmp) / member.name).resolve()
            if not target.is_relative_to(Path(tmp).resolve()) or member.issym() or member.islnk():
                raise PeerUnavailableError(f"{archive.name}: unsafe member {member.name}")
        tar.extractall(tmp)
        unpacked = Path(tmp) / root.name
        if not unpacked.is_dir():
            raise PeerUnavailableError(f"{archive.name} has no top-level {root.name}/")
        if root.exists():
            shutil.rmtree(root)
        os.replace(unpacked, root)
    return root


def source_dir(lib: PeerLibrary) -> Path:
    """The unpacked sdist of ``lib`` under build/peers/ (downloaded on first use)."""
    archive = _download(lib.package, lib.version, PEERS_DIR / "sdist")
    return _unpack(archive, PEERS_DIR / "src")


# --- building ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Toolchain:
    """Compilers and flags of one target: the host (gcc/clang) or a Cortex-M board."""

    cc: str
    cxx: str
    cpu: tuple[str, ...] = ()
    board: CortexM | None = None

    @property
    def name(self) -> str:
        """``m4f``, ``gcc``..."""
        return self.board.name if self.board else Path(self.cc).name


def host_toolchain(cc: str) -> Toolchain:
    """Gcc -> g++, clang -> clang++."""
    return Toolchain(cc, {"gcc": "g++", "clang": "clang++"}.get(cc, cc + "++"))


def board_toolchain(board: str) -> Toolchain:
    """arm-none-eabi-gcc/g++ with the board's code generation flags."""
    b = BOARDS[board]
    return Toolchain("arm-none-eabi-gcc", "arm-none-eabi-g++", b.cpu, b)


def _run(cmd: Sequence[str]) -> None:
    try:
        proc = subprocess.run(list(cmd), capture_output=True, text=True)
    except OSError as e:
        raise PeerUnavailableError(f"{cmd[0]}: {e}") from e
    if proc.returncode != 0:
        raise PeerUnavailableError(f"build failed: {' '.join(cmd)}\n{proc.stderr[-2000:]}")


@dataclass
class Built:
    """A built peer program and the objects of the peer library (for the footprint attribution)."""

    program: Path
    library: Path | None = None
    """The peer's objects as an archive (lib<name>.a), on Cortex-M builds."""
    objects: list[Path] = field(default_factory=list)


def build(lib: PeerLibrary, tc: Toolchain, opt: str, out_dir: Path, image: int = 0) -> Built:
    """Compile ``lib`` and its driver for ``tc`` at ``opt``.

    ``image`` 0: the benchmark program (host: native; board: semihosted image for QEMU). ``image`` 6 or
    9: a minimal firmware image (-DATT_PEER_IMAGE, newlib-nano, no semihosting, a linker map) for the
    footprint; boards only.
    """
    for tool in (tc.cxx if lib.cplusplus else tc.cc, tc.cc):
        if shutil.which(tool) is None:
            raise PeerUnavailableError(f"{tool} is not installed (host/tools/install-system-deps.sh)")
    src = source_dir(lib)
    key = hashlib.sha256(" ".join([lib.version, tc.name, opt, str(image), *tc.cpu]).encode()).hexdigest()[:8]
    out = out_dir / f"{lib.name.lower()}-{tc.name}{opt}-{image}-{key}"
    out.mkdir(parents=True, exist_ok=True)
    incs = [f"-I{p}" for p in lib.includes(src)] + [f"-I{TESTS_C}"]
    base = [*tc.cpu, *PEER_FLAGS, opt, *lib.defines]
    if tc.board is not None:
        base += list(SECTIONS)
    defines = [f"-DATT_PEER_IMAGE={image}"] if image else []
    peer_objs: list[Path] = []
    for s in lib.sources(src):
        o = out / (s.stem + ".o")
        comp = tc.cxx if s.suffix == ".cpp" else tc.cc
        extra = list(lib.cxx_flags) if s.suffix == ".cpp" else []
        _run([comp, *base, *extra, *incs, "-c", str(s), "-o", str(o)])
        peer_objs.append(o)
    drv = out / "driver.o"
    comp = tc.cxx if lib.cplusplus else tc.cc
    extra = list(lib.cxx_flags) if lib.cplusplus else []
    port_inc = ["-I", str(tc.board.script.parent)] if tc.board else []
    sh = ["-DATT_SEMIHOST_NEWLIB", *tc.board.defines] if tc.board and not image else []
    _run([comp, *base, *extra, *incs, *port_inc, *sh, *defines, "-c", str(lib.driver), "-o", str(drv)])
    prog = out / ("image.elf" if image else "bench.elf" if tc.board else "bench")
    linker = tc.cxx if lib.cplusplus else tc.cc
    if tc.board is None:
        _run([linker, *base, str(drv), *map(str, peer_objs), "-lm", "-o", str(prog)])
        return Built(prog, None, peer_objs)
    archive = out / f"lib{lib.name.lower()}.a"
    archive.unlink(missing_ok=True)
    _run(["arm-none-eabi-ar", "rcs", str(archive), *map(str, peer_objs)])
    port_objs = []
    for s in PORT_SOURCES if not image else STARTUP_SOURCES:
        o = out / f"port_{s.stem}.o"
        _run(
            [
                tc.cc,
                *_build.cflags(),
                opt,
                *tc.cpu,
                *SECTIONS,
                *sh,
                "-I",
                str(tc.board.script.parent),
                "-c",
                str(s),
                "-o",
                str(o),
            ]
        )
        port_objs.append(o)
    if image:
        link = ["--specs=nano.specs", "-nostartfiles", "-T", str(tc.board.script), "-Wl,--gc-sections"]
        link += [f"-Wl,-Map={prog.with_suffix('.map')}"]
    else:
        link = list(tc.board.link)
    _run(
        [linker, *tc.cpu, *extra, str(drv), *map(str, port_objs), str(archive), *link, "-lm", "-o", str(prog)]
    )
    return Built(prog, archive, peer_objs)


def programs(tc: Toolchain, opt: str, out_dir: Path) -> dict[str, Built | str]:
    """The benchmark program of every peer library for ``tc`` (or why it is unavailable), by library."""
    out: dict[str, Built | str] = {}
    for name, lib in LIBRARIES.items():
        try:
            out[name] = build(lib, tc, opt, out_dir)
        except PeerUnavailableError as e:
            out[name] = str(e)
    return out
