"""Footprint, stack and instructions per update of the firmware on a Cortex-M4F (make footprint, cycles).

Footprint (``python -m attica_dev.footprint footprint``):

- .text (code + constants), .data and .bss the library contributes to minimal firmware images
  (tests/c/att_m4f_image.c: one filter through its own API, all filters through att_filter_*, the
  CAN codec, the CAN node), linked with our start-up, newlib-nano and ``--gc-sections`` against
  libattica.a at -Os and -O2, attributed per input object from the linker map; what the C library
  and libgcc add is listed separately;
- the images' symbols: no heap (malloc, free, _sbrk...), no libm/errno (sqrtf, __errno...);
- state sizes (sizeof att_<kind>_t, att_filter_t, att_node_t) and measured stack high-water marks
  on the target (tests/c/att_m4f_stack.c under QEMU);
- worst-case stack depth from the call graph: -fstack-usage frames (.su) summed along the deepest
  path of -fcallgraph-info (.ci) from each entry point; a tail call (a callee reached from a function
  only by branches, R_ARM_THM_JUMP24/JUMP19 relocations, after its frame is released) runs on the
  caller's caller's stack and does not add the caller's frame; library leaf functions (memcpy, memset)
  from their prologues in the linked image.

Instructions (``python -m attica_dev.footprint cycles``):

- Cortex-M4F: tests/c/att_bench.c (the same synthetic inputs as the x86 callgrind figures) runs under
  ``qemu-system-arm -M mps2-an386 -d exec,nochain -singlestep`` which logs every executed
  instruction; the instructions from the entry of att_filter_step until control is back in main are
  counted for every step (mean and maximum per update). An estimate of cycles is derived from the
  same trace with the Cortex-M4 TRM instruction timings (zero wait states; see :func:`m4_cycles`);
- x86-64: callgrind instructions per att_filter_step via :mod:`attica_dev.bench`.
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from attica import _build
from attica.kinds import KINDS as ALL_KINDS
from attica_dev import cross, cycles
from attica_dev.boards import BOARDS, STARTUP_SOURCES

ROOT = _build.ROOT
OUT = ROOT / "build" / "firmware" / "m4f"
IMAGE_SOURCE = cross.TESTS_C / "att_m4f_image.c"
STACK_SOURCE = cross.TESTS_C / "att_m4f_stack.c"
BENCH_SOURCE = cross.TESTS_C / "att_bench.c"

IMAGES: dict[str, int] = {
    **{k.label: int(k.kind) for k in ALL_KINDS},  # one kind through its own API: ATT_IMAGE = its value
    "all filters (att_filter)": 10,
    "CAN codec (att_can)": 11,
    "CAN node (att_node)": 12,
}
"""Footprint images: name -> ATT_IMAGE of tests/c/att_m4f_image.c."""

STACK_ENTRIES: dict[str, str] = {
    **{k.label: f"att_{k.label}_step" for k in ALL_KINDS},
    "all filters (att_filter)": "att_filter_step",
    "filter init": "att_filter_init",
    "CAN node (att_node)": "att_node_poll",
    "node init": "att_node_init",
}
"""Entry points of the call-graph stack analysis."""

GOALS = {"ars_instr": 500, "kf_instr": 1500, "text": 8192, "stack": 256}
"""Targets of the issue: ARS <= 500 and KF <= 1500 instructions per update, library with codec
<= 8 KiB .text, <= 256 B stack."""

BENCH_STEPS = 1000
"""Steps per kind in the instruction trace: att_bench's inputs move for 700 steps, then rest for 300."""


class FootprintError(RuntimeError):
    """A build, run or analysis failed."""


def _tool(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        raise FootprintError(f"{cross.install_hint([name])} is not installed")
    return path


# --- library and images --------------------------------------------------------------------------------


def library(opt: str, out: Path = OUT, board: str = "m4f") -> tuple[Path, list[Path]]:
    """libattica<opt>.a for a Cortex-M board (stack gate on) and its objects (.su/.ci beside them)."""
    objs = cross.library_objects(opt, out / f"obj{opt}", board=board)
    return cross.archive(objs, out / f"libattica{opt}.a"), objs


def _compile(src: Path, obj: Path, opt: str, defines: Sequence[str] = (), board: str = "m4f") -> None:
    cmd = [
        _tool("arm-none-eabi-gcc"),
        *_build.cflags(),
        opt,
        *BOARDS[board].cpu,
        *cross.M4F_SECTIONS,
        *defines,
        "-I",
        str(_build.INCLUDE),
        "-I",
        str(cross.PORT),
        "-c",
        str(src),
        "-o",
        str(obj),
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0 or proc.stderr.strip():
        raise FootprintError(f"{' '.join(cmd)}\n{proc.stderr}")


def link_image(
    name: str,
    image: int,
    lib: Path,
    opt: str,
    out: Path,
    board: str = "m4f",
    defines: Sequence[str] = (),
) -> tuple[Path, Path]:
    """Link footprint image ``image`` for ``board`` against ``lib``; return (elf, map).

    ``defines``: the build configuration the library was compiled with (att_config.h options), and
    for image 10 ``-DATT_IMAGE_KIND=...``.
    """
    out.mkdir(parents=True, exist_ok=True)
    slug = re.sub(r"[^a-z0-9]+", "_", name.lower()).strip("_")
    main_o = out / f"image_{slug}.o"
    _compile(IMAGE_SOURCE, main_o, opt, [f"-DATT_IMAGE={image}", *defines], board)
    start_objs = []
    for src in STARTUP_SOURCES:
        start_objs.append(out / f"{src.stem}.o")
        _compile(src, start_objs[-1], opt, (), board)
    elf = out / f"image_{slug}.elf"
    map_file = out / f"image_{slug}.map"
    cmd = [
        _tool("arm-none-eabi-gcc"),
        *BOARDS[board].cpu,
        str(main_o),
        *map(str, start_objs),
        str(lib),
        "--specs=nano.specs",
        "-nostartfiles",
        "-T",
        str(BOARDS[board].script),
        "-Wl,--gc-sections",
        f"-Wl,-Map={map_file}",
        "-o",
        str(elf),
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise FootprintError(f"{' '.join(cmd)}\n{proc.stderr}")
    return elf, map_file


KINDS = tuple(k.kind.name for k in ALL_KINDS)
"""The <NAME> of the ATT_WITH_<NAME> options of att_config.h, one per kind (:mod:`attica.kinds`)."""


def only(*kinds: str, calib: bool = True) -> list[str]:
    """The -D flags of a configuration with just ``kinds`` (and the stages when ``calib``)."""
    flags = [f"-DATT_WITH_{k}={1 if k in kinds else 0}" for k in KINDS]
    return flags if calib else [*flags, "-DATT_WITH_CALIB=0"]


NODE_SMALL = ["-DATT_NODE_WITH_FD=0", "-DATT_NODE_RX_RING=8", "-DATT_NODE_TX_RING=8"]
"""The node options of the small node: classic frames only, rings of 8 frames."""

CONFIGS: dict[str, tuple[list[str], str, int]] = {
    "every kind (the default)": ([], "ARS", 10),
    "every kind, no stages": (["-DATT_WITH_CALIB=0"], "ARS", 10),
    "ARS only": (only("ARS"), "ARS", 13),
    "ARS only, no stages": (only("ARS", calib=False), "ARS", 13),
    "MEKF only": (only("MEKF"), "MEKF", 13),
    "MEKF only, no stages": (only("MEKF", calib=False), "MEKF", 13),
    "node, every kind (the default)": ([], "ARS", 12),
    "node, ARS only, no stages": (only("ARS", calib=False), "ARS", 12),
    "node, ARS only, no stages, classic, rings of 8": ([*only("ARS", calib=False), *NODE_SMALL], "ARS", 12),
}
"""Build configurations of the per-configuration table: name -> (att_config.h flags, the kind the
image runs, ATT_IMAGE of tests/c/att_m4f_image.c: 10 every kind compiled in through att_filter.h
(the kind a volatile), 13 the loop of the kinds' own images through att_filter.h, 12 the CAN node)."""

SIZEOF_TYPES = ("att_filter_t", "att_filter_settings_t", "att_node_t")


def sizeof(types: Sequence[str], defines: Sequence[str], out: Path, board: str = "m4f") -> dict[str, int]:
    """The sizeof of public types on the board under a configuration (arrays of that size, read with nm)."""
    out.mkdir(parents=True, exist_ok=True)
    src = out / "sizeof.c"
    src.write_text(
        '#include "attica/att_filter.h"\n#include "attica/att_node.h"\n'
        + "".join(f"char sz_{t}[sizeof({t})];\n" for t in types)
    )
    obj = out / "sizeof.o"
    _compile(src, obj, "-Os", defines, board)
    proc = subprocess.run(
        [_tool("arm-none-eabi-nm"), "-S", str(obj)], capture_output=True, text=True, check=True
    )
    sizes: dict[str, int] = {}
    for line in proc.stdout.splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[3].startswith("sz_"):
            sizes[parts[3][3:]] = int(parts[1], 16)
    return sizes


@dataclass
class ConfigSizes:
    """One build configuration: the image's library sizes and the state sizes."""

    name: str
    sizes: ImageSizes
    types: dict[str, int]


def config_sizes(
    opt: str = "-Os",
    out: Path = OUT,
    names: Sequence[str] | None = None,
    configs: dict[str, tuple[list[str], str, int]] | None = None,
) -> list[ConfigSizes]:
    """Library .text/.data/.bss of the images of each configuration, and state sizes.

    ``configs``: name -> (att_config.h flags, the kind the image runs, ATT_IMAGE), :data:`CONFIGS` by
    default; ``names`` chooses some of them.
    """
    configs = CONFIGS if configs is None else configs
    result = []
    for name in names if names is not None else configs:
        defines, kind, image = configs[name]
        slug = re.sub(r"[^a-z0-9]+", "_", name.lower()).strip("_")
        d = out / "configs" / f"{slug}{opt}"
        objs = cross.library_objects(opt, d / "obj", defines=defines)
        lib = cross.archive(objs, d / "libattica.a")
        _, map_file = link_image(
            name, image, lib, opt, d, defines=[*defines, f"-DATT_IMAGE_KIND=ATT_FILTER_{kind}"]
        )
        result.append(ConfigSizes(name, map_sizes(map_file), sizeof(SIZEOF_TYPES, defines, d)))
    return result


def config_report(opt: str = "-Os", out: Path = OUT) -> str:
    """The per-configuration table (make footprint): each configuration beside the kinds' own images."""
    rows = []
    for c in config_sizes(opt, out):
        s = c.sizes.attica
        t = c.types
        rows.append(
            [c.name, str(s.text), str(s.data), str(s.bss), str(t["att_filter_t"]), str(t["att_node_t"])]
        )
    head = (
        f"Per build configuration (att_config.h; M4F {opt}, --gc-sections): the library in an image "
        "that runs one kind through att_filter.h (or the node), and the state sizes"
    )
    return (
        head
        + "\n"
        + _table(["configuration", f".text {opt}", ".data", ".bss", "att_filter_t", "att_node_t"], rows)
    )


@dataclass
class Sizes:
    """Bytes of .text (code + read-only data), .data and .bss."""

    text: int = 0
    data: int = 0
    bss: int = 0

    def add(self, section: str, size: int) -> None:
        """Count ``size`` bytes of an input section named ``section``."""
        if section.startswith((".data",)):
            self.data += size
        elif section.startswith((".bss", "COMMON")):
            self.bss += size
        elif section.startswith(
            (".text", ".rodata", ".vectors", ".ARM.exidx", ".ARM.extab", ".init", ".fini")
        ):
            self.text += size


@dataclass
class ImageSizes:
    """An image's sizes by origin."""

    attica: Sizes = field(default_factory=Sizes)
    attica_objects: dict[str, Sizes] = field(default_factory=dict)
    libc: Sizes = field(default_factory=Sizes)
    """newlib, libgcc (memcpy, memset, compiler helpers)."""
    other: Sizes = field(default_factory=Sizes)
    """start-up, the image's main, state."""
    other_objects: dict[str, Sizes] = field(default_factory=dict)
    """``other`` by input object (its path as the map names it)."""
    libc_symbols: set[str] = field(default_factory=set)


_IN_SECTION = re.compile(r"^ (\.\S+|COMMON)\s*(?:(0x[0-9a-f]+)\s+(0x[0-9a-f]+)\s+(\S.*))?$")
_CONT = re.compile(r"^\s+(0x[0-9a-f]+)\s+(0x[0-9a-f]+)\s+(\S.*)$")


def map_sizes(map_file: Path, archive: str = "libattica", members: set[str] | None = None) -> ImageSizes:
    """Attribute the input sections of a GNU ld map file to attica objects, the C library and the rest.

    ``archive`` and ``members``: the library whose objects count as "attica" (the firmware objects of
    libattica by default; a peer's lib<name>.a with every member for the peers' images).
    """
    stems = (
        {s.stem for s in _build.firmware_sources()} if members is None and archive == "libattica" else None
    )
    if members is not None:
        stems = members
    out = ImageSizes()
    lines = map_file.read_text().splitlines()
    try:
        start = next(i for i, line in enumerate(lines) if line.startswith("Linker script and memory map"))
    except StopIteration:
        raise FootprintError(f"{map_file}: not a GNU ld map") from None
    pending: str | None = None
    for line in lines[start:]:
        if line.startswith("/DISCARD/"):
            break
        sec: str | None = None
        size = 0
        origin = ""
        m = _IN_SECTION.match(line)
        if m:
            if m.group(2) is None:
                pending = m.group(1)
                continue
            sec, size, origin = m.group(1), int(m.group(3), 16), m.group(4).strip()
        elif pending is not None:
            c = _CONT.match(line)
            if c:
                sec, size, origin = pending, int(c.group(2), 16), c.group(3).strip()
            pending = None
        if sec is None or size == 0:
            continue
        member = re.search(r"\(([^()]+)\.o\)$", origin)
        if archive in origin and member and (stems is None or member.group(1) in stems):
            out.attica.add(sec, size)
            out.attica_objects.setdefault(member.group(1), Sizes()).add(sec, size)
        elif re.search(r"lib(c|c_nano|g|g_nano|gcc|m|nosys|rdimon\w*|stdc\+\+\w*|supc\+\+\w*)\.a", origin):
            out.libc.add(sec, size)
            name = sec.split(".")[-1]
            if sec.startswith(".text") and member:
                out.libc_symbols.add(f"{member.group(1)}{'' if name in ('text', '') else ':' + name}")
        else:
            out.other.add(sec, size)
            out.other_objects.setdefault(origin, Sizes()).add(sec, size)
    return out


def forbidden_symbols(elf: Path) -> list[str]:
    """Heap, libm or errno symbols defined or referenced in an image (``nm``)."""
    out = subprocess.run(
        [_tool("arm-none-eabi-nm"), str(elf)], capture_output=True, text=True, check=True
    ).stdout
    names = {line.split()[-1] for line in out.splitlines() if line.strip()}
    return sorted(names & {*cross.HEAP_SYMBOLS, *cross.LIBM_ERRNO_SYMBOLS})


# --- stack -----------------------------------------------------------------------------------------------


@dataclass
class CallGraph:
    """Frames (bytes, from .su via the .ci labels) and call edges of the library functions."""

    frame: dict[str, int] = field(default_factory=dict)
    calls: dict[str, set[str]] = field(default_factory=dict)
    names: dict[str, str] = field(default_factory=dict)
    """Title -> plain function name."""
    tail: set[tuple[str, str]] = field(default_factory=set)
    """(caller, callee) plain names where the caller reaches the callee only by tail calls."""

    def by_name(self, name: str) -> str | None:
        """The title of a defined function with plain name ``name``."""
        for title, n in self.names.items():
            if n == name and title in self.frame:
                return title
        return None


_NODE = re.compile(r'^node: \{ title: "([^"]+)" label: "([^"]*)"')
_EDGE = re.compile(r'^edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"')


_FUNC = re.compile(r"^[0-9a-f]+ <([^>]+)>:$")
_RELOC = re.compile(
    r"^\s+[0-9a-f]+: (R_ARM_THM_CALL|R_ARM_THM_JUMP24|R_ARM_THM_JUMP19|R_ARM_CALL|R_ARM_JUMP24)\s+(\S+)"
)


def tail_calls(obj: Path) -> set[tuple[str, str]]:
    """(caller, callee) pairs of an ARM object where every reference is a branch, not a call (BL).

    GCC emits a tail call (sibling call) as ``b.w callee`` after the epilogue has released the caller's
    frame: the callee then runs on the stack of the caller's caller. The branch relocations
    (R_ARM_THM_JUMP24 / JUMP19) of each function section are those tail calls; a callee that is also
    reached by BL from the same caller counts as an ordinary call (its frame nests).
    """
    dis = subprocess.run(
        [_tool("arm-none-eabi-objdump"), "-dr", str(obj)], capture_output=True, text=True, check=True
    ).stdout
    calls: set[tuple[str, str]] = set()
    jumps: set[tuple[str, str]] = set()
    func = ""
    for line in dis.splitlines():
        m = _FUNC.match(line)
        if m:
            func = m.group(1)
            continue
        r = _RELOC.match(line)
        if r and func:
            (calls if r.group(1) in ("R_ARM_THM_CALL", "R_ARM_CALL") else jumps).add((func, r.group(2)))
    return jumps - calls


def call_graph(objs: Sequence[Path], tail: bool = True) -> CallGraph:
    """Read the .ci files (gcc -fcallgraph-info=su) next to ``objs``; with ``tail``, their tail calls."""
    g = CallGraph()
    for obj in objs:
        if tail:
            g.tail |= tail_calls(obj)
        ci = obj.with_suffix(".ci")
        if not ci.exists():
            raise FootprintError(f"{ci} missing (compile with -fcallgraph-info=su)")
        for line in ci.read_text().splitlines():
            m = _NODE.match(line)
            if m:
                title, label = m.group(1), m.group(2)
                g.names[title] = label.split("\\n")[0].removeprefix("__builtin_")
                fm = re.search(r"\\n(\d+) bytes \((\w[\w,]*)\)", label)
                if fm:
                    if fm.group(2) != "static":
                        raise FootprintError(
                            f"{title}: {fm.group(2)} stack frame; only static frames are bounded"
                        )
                    g.frame[title] = int(fm.group(1))
                continue
            e = _EDGE.match(line)
            if e:
                g.calls.setdefault(e.group(1), set()).add(e.group(2))
    return g


def leaf_stack(elf: Path, func: str) -> int | None:
    """Stack bytes a leaf library function pushes (push/stmdb/vpush/sub sp in its disassembly)."""
    dis = subprocess.run(
        [_tool("arm-none-eabi-objdump"), "-d", f"--disassemble={func}", str(elf)],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    total = 0
    found = False
    for line in dis.splitlines():
        parts = line.split("\t")
        if len(parts) < 3:
            continue
        found = True
        mnem, ops = parts[2].strip(), parts[3].strip() if len(parts) > 3 else ""
        if mnem.startswith("bl") and not mnem.startswith("bls") and not mnem.startswith("blt"):
            return None  # not a leaf
        if mnem.startswith("push") or (mnem.startswith("stmdb") and ops.startswith("sp!")):
            total += 4 * cycles.reg_count(ops)
        elif mnem.startswith("vpush"):
            total += (8 if "d" in ops.split("{")[-1][:2] else 4) * cycles.reg_count(ops)
        elif mnem.startswith("sub") and ops.startswith("sp, sp, #") or ops.startswith("sp, #"):
            if mnem.startswith("sub"):
                total += int(ops.split("#")[-1].split()[0], 0)
    return total if found else None


@dataclass
class StackPath:
    """Worst-case stack of an entry point: bytes and the path, with unknowns."""

    entry: str
    bytes: int
    path: list[str]
    unknown: list[str]


def worst_stack(g: CallGraph, entry: str, externals: dict[str, int]) -> StackPath:
    """Deepest frame sum from ``entry`` through the call graph (externals: bytes of library leaves)."""
    title = g.by_name(entry)
    if title is None:
        raise FootprintError(f"{entry} is not in the call graph")
    memo: dict[str, tuple[int, list[str]]] = {}
    unknown: set[str] = set()
    stack: set[str] = set()

    def visit(t: str) -> tuple[int, list[str]]:
        if t in memo:
            return memo[t]
        if t in stack:
            raise FootprintError(f"recursion through {g.names.get(t, t)}: the stack is unbounded")
        name = g.names.get(t, t)
        if t not in g.frame:
            defined = g.by_name(name)
            if defined is not None:
                return visit(defined)
            if name in externals:
                return externals[name], [f"{name} ({externals[name]}, library)"]
            unknown.add(name)
            return 0, [f"{name} (unknown)"]
        stack.add(t)
        here = f"{name} ({g.frame[t]})"
        best: tuple[int, list[str]] = (g.frame[t], [here])
        for callee in sorted(g.calls.get(t, ())):
            r = visit(callee)
            if (name, g.names.get(callee, callee)) in g.tail:
                cand = (r[0], [f"{name} ({g.frame[t]}, tail call)", *r[1]])  # the frame is released first
            else:
                cand = (g.frame[t] + r[0], [here, *r[1]])
            if cand[0] > best[0]:
                best = cand
        stack.discard(t)
        memo[t] = best
        return memo[t]

    total, path = visit(title)
    return StackPath(entry, total, path, sorted(unknown))


# --- running on the target ------------------------------------------------------------------------------


def run_m4f(elf: Path, args: Sequence[str] = (), timeout: float = 300.0) -> str:
    """Run a Cortex-M4F image under QEMU (qemu-m4f.sh); return its stdout."""
    _tool("qemu-system-arm")
    return cross.run_checked([str(cross.QEMU_M4F), str(elf), *args], timeout)


@dataclass
class Measured:
    """Output of tests/c/att_m4f_stack.c: stack high-water marks and sizeof of the state types."""

    stack: dict[tuple[str, str], int] = field(default_factory=dict)
    sizeof: dict[str, int] = field(default_factory=dict)


def measure(opt: str, out: Path = OUT) -> Measured:
    """Build and run tests/c/att_m4f_stack.c at ``opt`` on the Cortex-M4F (QEMU)."""
    elf = cross.TARGETS["m4f"].build([STACK_SOURCE], opt, "att_m4f_stack.elf", out / f"stack{opt}")
    m = Measured()
    for line in run_m4f(elf).splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[0] == "stack":
            m.stack[(parts[1], parts[2])] = int(parts[3])
        elif len(parts) == 3 and parts[0] == "sizeof":
            m.sizeof[parts[1]] = int(parts[2])
    return m


# --- reports -----------------------------------------------------------------------------------------------


def _table(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    return cross._table(headers, rows)


def footprint_report(opts: Sequence[str] = cross.M4F_LIB_OPTS, out: Path = OUT) -> tuple[str, bool]:
    """The footprint and stack tables; the bool is False when an image links a heap or libm/errno."""
    lines: list[str] = []
    ok = True
    sizes: dict[tuple[str, str], ImageSizes] = {}
    graphs: dict[str, tuple[CallGraph, Path]] = {}
    for opt in opts:
        lib, objs = library(opt, out)
        any_elf: Path | None = None
        for name, image in IMAGES.items():
            elf, map_file = link_image(name, image, lib, opt, out / f"images{opt}")
            sizes[(name, opt)] = map_sizes(map_file)
            bad = forbidden_symbols(elf)
            if bad:
                ok = False
                lines.append(f"ERROR: image {name} {opt} links {', '.join(bad)} (heap / libm / errno)")
            if image == 12:
                any_elf = elf
        graphs[opt] = (call_graph(objs), any_elf or elf)
    headers = ["image (Cortex-M4F)"]
    for opt in opts:
        headers += [f".text {opt}", f".data {opt}", f".bss {opt}"]
    headers += [f"+libc .text {opts[0]}"]
    rows = []
    for name in IMAGES:
        row = [name]
        for opt in opts:
            s = sizes[(name, opt)].attica
            row += [str(s.text), str(s.data), str(s.bss)]
        row.append(str(sizes[(name, opts[0])].libc.text))
        rows.append(row)
    lines.append(
        "Library code in minimal images (libattica.a, --gc-sections; .text = code + constants; "
        "+libc = memcpy/memset/helpers pulled from newlib-nano and libgcc)"
    )
    lines.append(_table(headers, rows))
    node = sizes.get(("CAN node (att_node)", opts[0]))
    if node:
        lines.append("")
        lines.append(f"Per object in the node image ({opts[0]}):")
        rows = [
            [stem, str(s.text), str(s.data), str(s.bss)] for stem, s in sorted(node.attica_objects.items())
        ]
        lines.append(_table(["object", ".text", ".data", ".bss"], rows))
        lines.append(f"C library / libgcc functions: {', '.join(sorted(node.libc_symbols)) or 'none'}")
    lines.append("")
    lines.append(
        "Heap / libm / errno symbols in the images: " + ("none" if ok else "FOUND (see errors above)")
    )

    # state sizes and measured stacks
    measured: dict[str, Measured] = {}
    if shutil.which("qemu-system-arm"):
        for opt in opts:
            measured[opt] = measure(opt, out)
    lines.append("")
    if measured:
        first = measured[opts[0]]
        lines.append("State in RAM per instance (sizeof on the Cortex-M4F):")
        lines.append(_table(["type", "bytes"], [[t, str(b)] for t, b in first.sizeof.items()]))
    else:
        lines.append("qemu-system-arm is not installed: no state sizes or measured stack")
    lines.append("")
    lines.append(
        "Stack (bytes): worst case from the call graph (-fstack-usage frames along the deepest "
        "-fcallgraph-info path) and measured high-water mark on the target (QEMU, 3000 steps)"
    )
    headers = ["entry"]
    for opt in opts:
        headers += [f"call graph {opt}", f"measured {opt}"]
    rows = []
    paths: list[str] = []
    meas_key = {
        "all filters (att_filter)": ("att_filter_step", None),
        "filter init": ("att_filter_init", None),
        "CAN node (att_node)": ("att_node_poll", "node"),
        "node init": ("att_node_init", "node"),
    }
    for label, entry in STACK_ENTRIES.items():
        row = [f"{label}: {entry}"]
        for opt in opts:
            g, elf = graphs[opt]
            ext = {f: v for f in ("memcpy", "memset") if (v := leaf_stack(elf, f)) is not None}
            try:
                sp = worst_stack(g, entry, ext)
                row.append(str(sp.bytes) + ("+?" if sp.unknown else ""))
                if opt == opts[0]:
                    paths.append(f"{entry}: " + " -> ".join(sp.path))
            except FootprintError as e:
                row.append("n/a")
                paths.append(f"{entry}: {e}")
            m = measured.get(opt)
            if m is None:
                row.append("-")
            elif label in meas_key:
                fn, k = meas_key[label]
                vals = [v for (f, kk), v in m.stack.items() if f == fn and (k is None or kk == k)]
                row.append(str(max(vals)) if vals else "-")
            else:
                v = m.stack.get(("att_filter_step", label))
                row.append(str(v) if v is not None else "-")
        rows.append(row)
    lines.append(_table(headers, rows))
    lines.append(f"Deepest paths ({opts[0]}):")
    lines.extend("  " + p for p in paths)
    lines.append("")
    lines.append(config_report(opts[0], out))
    return "\n".join(lines), ok


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m attica_dev.footprint``."""
    p = argparse.ArgumentParser(
        prog="python -m attica_dev.footprint", description=__doc__.split("\n")[0] if __doc__ else ""
    )
    p.add_argument("--no-peers", action="store_true", help="attica's tables only")
    p.add_argument(
        "--boards", default="m4f,m7,m33", help="boards of the comparison with the peers (m4f,m7,m33)"
    )
    args = p.parse_args(argv)
    try:
        text, ok = footprint_report()
        print(text, flush=True)
        from attica_dev import app_size  # the quickstart's node application (imports this module)

        print()
        node = app_size.measure()
        print(app_size.report(node), flush=True)
        ok = ok and node.library.text <= app_size.TARGETS["text"] and node.ram <= app_size.TARGETS["ram"]
        if not args.no_peers:
            from attica_dev import peer_footprint

            print()
            print(peer_footprint.report([b for b in args.boards.split(",") if b]))
        return 0 if ok else 1
    except (FootprintError, cross.CrossError) as e:
        print(f"footprint: {e}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
