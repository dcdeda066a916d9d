"""Instructions (and estimated cycles) per update on the Cortex-M boards and x86-64, attica beside the peers.

``python -m attica_dev.cycles`` (``make cycles``):

- Cortex-M4F, M7, M33 (:mod:`attica_dev.boards`): tests/c/att_bench.c (attica, every filter kind
  through att_filter_step) and the peers' drivers (tests/c/att_peer_fusion.c, att_peer_vqf.cpp:
  Fusion and VQF built from their sdists, :mod:`attica_dev.peer_sources`) run the same input stream
  (tests/c/att_bench_common.h) under ``qemu-system-arm -d exec,nochain -singlestep``, which logs
  every executed instruction; the instructions from the entry of the counted call (att_filter_step,
  att_peer_step) until control is back in main are counted for every step (mean and maximum per
  update). An estimate of Cortex-M4 cycles is derived from the same trace with the TRM instruction
  timings (zero wait states; see :func:`m4_cycles`);
- x86-64: callgrind instructions per counted call with :mod:`attica_dev.bench`'s method, gcc and
  clang.

Then the ratios attica / peer for every filter and target (6-axis filters beside the peers' 6-axis
updates, mars beside their 9-axis ones), and with ``--profile`` where each instruction of a step goes
(per function, from the same trace).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from attica import _build
from attica_dev import cross, peer_sources
from attica_dev.boards import BOARDS

ROOT = _build.ROOT
OUT = ROOT / "build" / "firmware" / "cycles"
BENCH_SOURCE = cross.TESTS_C / "att_bench.c"
BENCH_STEPS = 1000
"""Steps per kind in the instruction trace: att_bench's inputs move for 700 steps, then rest for 300."""
GOALS = {"ars_instr": 500, "kf_instr": 1500}
"""Instruction targets per update at -O2 on the M4F (docs/performance.md)."""


class CyclesError(RuntimeError):
    """A build, run or trace failed."""


def _tool(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        raise CyclesError(f"{cross.install_hint([name])} is not installed")
    return path


def reg_count(ops: str) -> int:
    """Registers in the ``{...}`` list of an LDM/STM/PUSH/POP operand string."""
    inner = ops[ops.find("{") + 1 : ops.find("}")]
    n = 0
    for part in inner.split(","):
        part = part.strip()
        m = re.match(r"^([rsd])(\d+)-[rsd](\d+)$", part)
        n += int(m.group(3)) - int(m.group(2)) + 1 if m else (1 if part else 0)
    return n


# --- the trace ----------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Insn:
    """One instruction of the image: size in bytes, mnemonic, operands."""

    size: int
    mnemonic: str
    operands: str


def disassemble(elf: Path) -> dict[int, Insn]:
    """Address -> instruction for the whole image."""
    dis = subprocess.run(
        [_tool("arm-none-eabi-objdump"), "-d", str(elf)], capture_output=True, text=True, check=True
    ).stdout
    out: dict[int, Insn] = {}
    for line in dis.splitlines():
        m = re.match(r"^\s+([0-9a-f]+):\t([0-9a-f ]+?)\s*\t(\S+)\s*(.*)$", line)
        if m:
            size = sum(len(w) // 2 for w in m.group(2).split())
            out[int(m.group(1), 16)] = Insn(size, m.group(3), m.group(4))
    return out


def symbols(elf: Path) -> dict[str, tuple[int, int]]:
    """Function name -> (address, size) (``nm -S``)."""
    out = subprocess.run(
        [_tool("arm-none-eabi-nm"), "-S", "--defined-only", str(elf)],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    syms: dict[str, tuple[int, int]] = {}
    for line in out.splitlines():
        p = line.split()
        if len(p) == 4 and p[2] in "tTwW":
            syms[p[3]] = (int(p[0], 16) & ~1, int(p[1], 16))
    return syms


_BRANCH_P = 2
"""Pipeline refill cycles P of a taken branch in the cycle estimate (the TRM gives 1 to 3)."""


def m4_cycles(insn: Insn, taken: bool) -> int:
    """Cycles of one executed instruction after the Cortex-M4 TRM (r0p1, tables 3-1 and 7-1).

    Zero-wait-state memory; loads 2 cycles (no pipelining of neighbouring loads counted), stores 1;
    LDM/STM/PUSH/POP/VLDM/VSTM/VPUSH/VPOP 1 + registers; taken branches 1 + P with P = 2, plus P when
    PC is loaded; VDIV and VSQRT 14, VMLA/VMLS/VNMLA/VFMA 3, other FPU data processing 1; MLA/MLS 2;
    SDIV/UDIV 12 (worst case). An estimate for budgeting, not a measurement.
    """
    m = insn.mnemonic.split(".")[0].lower()
    ops = insn.operands
    base = m.rstrip("s") if m not in ("vabs", "bls", "mls", "vmls", "vnmls") else m
    if m.startswith("v"):
        if m in ("vdiv", "vsqrt"):
            return 14
        if m in ("vmla", "vmls", "vnmla", "vnmls", "vfma", "vfms", "vfnma", "vfnms"):
            return 3
        if m in ("vldr",):
            return 2
        if m in ("vstr",):
            return 2
        if m in ("vpush", "vpop", "vldmia", "vldmdb", "vstmia", "vstmdb", "vldm", "vstm"):
            return 1 + reg_count(ops)
        if m == "vmov" and ops.count(",") >= 3:
            return 2
        return 1
    if m in ("push", "stmdb", "stmia", "stm", "stmea"):
        return 1 + reg_count(ops)
    if m in ("pop", "ldmia", "ldm", "ldmdb", "ldmfd"):
        return 1 + reg_count(ops) + (_BRANCH_P if "pc" in ops else 0)
    if m.startswith("ldr"):
        if m in ("ldrd",):
            return 3
        return 2 + (_BRANCH_P if ops.startswith("pc") else 0)
    if m.startswith("str"):
        return 2 if m == "strd" else 1
    if m in ("sdiv", "udiv"):
        return 12
    if m in ("mla", "mls"):
        return 2
    if m in ("tbb", "tbh"):
        return 2 + _BRANCH_P
    if m.startswith(("b", "cb")) and base not in ("bic", "bfc", "bfi"):
        return 1 + (_BRANCH_P if taken else 0)
    if "pc" in ops.split(",")[0]:
        return 1 + _BRANCH_P
    return 1


@dataclass
class StepCounts:
    """Instructions (and estimated cycles) per att_filter_step call."""

    instructions: list[int]
    cycles: list[int]
    by_function: dict[str, int] = field(default_factory=dict)
    """Instructions executed in each function over all calls (the profile)."""
    inclusive: dict[str, int] = field(default_factory=dict)
    """Instructions executed in each function and everything it called, over all calls (with calls=True)."""

    @property
    def mean(self) -> float:
        """Mean instructions per update."""
        return sum(self.instructions) / max(1, len(self.instructions))

    @property
    def mean_cycles(self) -> float:
        """Mean estimated cycles per update."""
        return sum(self.cycles) / max(1, len(self.cycles))


class _Calls:
    """A shadow call stack over the executed blocks, for the inclusive profile.

    A block after one ending in BL/BLX is a callee's entry (a frame with its return address); a block at
    a frame's return address pops it; any other block in a new function (a tail call, a jump into a
    split-off ``.part`` function) joins the top frame. Every block's instructions count for every
    function on the stack.
    """

    def __init__(self, owner: dict[int, str]) -> None:
        self.owner = owner
        self.frames: list[tuple[set[str], int]] = []
        self.inclusive: dict[str, int] = {}

    def start(self, pc: int) -> None:
        self.frames = [({self.owner.get(pc, "?")}, -1)]

    def block(self, pc: int, n: int, prev: Insn | None, prev_fall: int) -> None:
        fn = self.owner.get(pc, "?")
        if prev is not None and prev.mnemonic.split(".")[0].lower() in ("bl", "blx"):
            self.frames.append(({fn}, prev_fall))
        else:
            back = next((i for i in range(len(self.frames) - 1, 0, -1) if self.frames[i][1] == pc), 0)
            if back:
                del self.frames[back:]
            self.frames[-1][0].add(fn)
        for f in set().union(*(fr[0] for fr in self.frames)):
            self.inclusive[f] = self.inclusive.get(f, 0) + n


def trace_steps(
    elf: Path,
    kind: str,
    steps: int = BENCH_STEPS,
    function: str = "att_filter_step",
    board: str = "m4f",
    calls: bool = False,
) -> StepCounts:
    """Instructions executed inside ``function`` (and callees) per call, from a QEMU exec trace.

    The program (att_bench, or a peer's driver with ``function="att_peer_step"``) runs ``kind`` for
    ``steps`` steps on ``board`` under ``qemu-system-arm -d in_asm,exec,nochain``, streamed through a
    FIFO: each translation block is listed once with its instructions when QEMU translates it, and
    logged again at every execution (chaining off, so no execution is missed). A call starts at the
    block that begins with the first instruction of ``function`` and ends at the next block inside
    main; every instruction of every block in between is counted (conditional instructions that an
    IT block skips included, as the core issues them). The cycle estimate uses the Cortex-M4 timings
    (:func:`m4_cycles`) whatever the board; the reports print it for the M4F only. Gives the same
    counts as :func:`trace_steps_per_instruction` (tests/test_cross.py checks), several times faster.
    With ``calls``, also the inclusive profile (each function with its callees, :class:`_Calls`).
    """
    _tool("qemu-system-arm")
    insns = disassemble(elf)
    syms = symbols(elf)
    if function not in syms or "main" not in syms:
        raise CyclesError(f"{elf}: no {function} or main")
    entry = syms[function][0]
    main_lo, main_size = syms["main"]
    main_hi = main_lo + main_size
    owner: dict[int, str] = {}
    for name, (addr, size) in syms.items():
        for a in range(addr, addr + size, 2):
            if a in insns:
                owner.setdefault(a, name)

    # per translation block (pc/flags): instructions, cycles of all but the last, last one, its fallthrough
    blocks: dict[str, tuple[int, int, Insn | None, int]] = {}
    block_pcs: dict[str, list[int]] = {}
    executed: dict[str, int] = {}
    counts: list[int] = []
    cycles: list[int] = []
    tracker = _Calls(owner) if calls else None
    with tempfile.TemporaryDirectory(prefix="att_trace_") as tmp:
        fifo = Path(tmp) / "trace"
        os.mkfifo(fifo)
        cmd = BOARDS[board].qemu_command(elf, f"{kind} {steps}", fifo)
        proc = subprocess.Popen(
            cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        inside = False
        n = 0
        cyc = 0
        last: Insn | None = None
        fall = 0
        pending: list[int] = []
        try:
            with open(fifo) as fp:
                for line in fp:
                    if line.startswith("0x") and line[10:11] == ":":
                        pending.append(int(line[2:10], 16))
                        continue
                    i = line.find("[")
                    if i < 0 or not line.startswith("Trace"):
                        continue
                    key = line[i + 10 : i + 27]
                    if pending:
                        pcs = pending
                        pending = []
                        seq = sum(m4_cycles(insns[a], False) for a in pcs[:-1] if a in insns)
                        tail = insns.get(pcs[-1])
                        blocks[key] = (len(pcs), seq, tail, pcs[-1] + (tail.size if tail else 0))
                        block_pcs[key] = pcs
                    pc = int(key[:8], 16)
                    if inside:
                        if last is not None:
                            cyc += m4_cycles(last, pc != fall)
                        if main_lo <= pc < main_hi:
                            counts.append(n)
                            cycles.append(cyc)
                            inside = False
                            continue
                    elif pc == entry:
                        inside, n, cyc, last = True, 0, 0, None
                        if tracker is not None:
                            tracker.start(pc)
                    else:
                        continue
                    b = blocks.get(key)
                    if b is None:
                        raise CyclesError(f"{elf}: block {key} executed before it was listed")
                    if tracker is not None:
                        tracker.block(pc, b[0], last, fall)
                    n += b[0]
                    cyc += b[1]
                    last, fall = b[2], b[3]
                    executed[key] = executed.get(key, 0) + 1
        finally:
            out, err = proc.communicate(timeout=600)
        if proc.returncode != 0:
            raise CyclesError(f"{' '.join(cmd)} exited with {proc.returncode}:\n{err}")
    if len(counts) != steps:
        raise CyclesError(f"{kind}: traced {len(counts)} calls of {function}, expected {steps}")
    prof: dict[str, int] = {}
    for key, times in executed.items():
        for a in block_pcs[key]:
            fn = owner.get(a, "?")
            prof[fn] = prof.get(fn, 0) + times
    return StepCounts(counts, cycles, prof, tracker.inclusive if tracker is not None else {})


def trace_steps_per_instruction(
    elf: Path, kind: str, steps: int = BENCH_STEPS, function: str = "att_filter_step", board: str = "m4f"
) -> StepCounts:
    """:func:`trace_steps` from a trace with one line per instruction (``-singlestep``; slower).

    The program (att_bench, or a peer's driver with ``function="att_peer_step"``) runs ``kind`` for
    ``steps`` steps on ``board`` under ``qemu-system-arm -d exec,nochain -singlestep`` (one log line
    per executed instruction), streamed through a FIFO. A call starts at the first instruction of
    ``function`` and ends at the next instruction inside main. The cycle estimate uses the Cortex-M4
    timings (:func:`m4_cycles`) whatever the board; the reports print it for the M4F only.
    """
    _tool("qemu-system-arm")
    insns = disassemble(elf)
    syms = symbols(elf)
    if function not in syms or "main" not in syms:
        raise CyclesError(f"{elf}: no {function} or main")
    entry = syms[function][0]
    main_lo, main_size = syms["main"]
    main_hi = main_lo + main_size
    counts: list[int] = []
    cycles: list[int] = []
    owner: dict[int, str] = {}
    for name, (addr, size) in syms.items():
        for a in range(addr, addr + size, 2):
            if a in insns:
                owner.setdefault(a, name)
    prof: dict[str, int] = {}
    with tempfile.TemporaryDirectory(prefix="att_trace_") as tmp:
        fifo = Path(tmp) / "trace"
        os.mkfifo(fifo)
        cmd = BOARDS[board].qemu_command(elf, f"{kind} {steps}", fifo, per_instruction=True)
        proc = subprocess.Popen(
            cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        inside = False
        n = 0
        cyc = 0
        prev: Insn | None = None
        prev_pc = 0
        try:
            with open(fifo) as fp:
                for line in fp:
                    i = line.find("[")
                    if i < 0:
                        continue
                    pc = int(line[i + 10 : i + 18], 16)
                    if not inside:
                        if pc == entry:
                            inside, n, cyc, prev = True, 1, 0, insns.get(pc)
                            prev_pc = pc
                            prof[function] = prof.get(function, 0) + 1
                        continue
                    if prev is not None:
                        cyc += m4_cycles(prev, pc != prev_pc + prev.size)
                    if main_lo <= pc < main_hi:
                        counts.append(n)
                        cycles.append(cyc)
                        inside = False
                        continue
                    n += 1
                    prev = insns.get(pc)
                    prev_pc = pc
                    fn = owner.get(pc, "?")
                    prof[fn] = prof.get(fn, 0) + 1
        finally:
            out, err = proc.communicate(timeout=600)
        if proc.returncode != 0:
            raise CyclesError(f"{' '.join(cmd)} exited with {proc.returncode}:\n{err}")
    if len(counts) != steps:
        raise CyclesError(f"{kind}: traced {len(counts)} calls of {function}, expected {steps}")
    return StepCounts(counts, cycles, prof)


def check_trace(elf: Path, kind: str, steps: int = 5, board: str = "m4f") -> tuple[int, list[str]]:
    """Check that the QEMU exec trace logs every executed instruction.

    Each change of PC between two logged instructions must be a sequential step or come from a
    branch-type instruction. Returns the number of instructions logged and the transitions that are
    neither (empty when the trace is complete).
    """
    _tool("qemu-system-arm")
    insns = disassemble(elf)
    with tempfile.TemporaryDirectory(prefix="att_trace_") as tmp:
        log = Path(tmp) / "trace.log"
        cross.run_checked(
            BOARDS[board].qemu_command(elf, f"{kind} {steps}", log, per_instruction=True), timeout=120
        )
        pcs = [
            int(line[i + 10 : i + 18], 16)
            for line in log.read_text().splitlines()
            if (i := line.find("[")) >= 0
        ]
    bad = []
    for a, b in zip(pcs, pcs[1:]):
        ins = insns.get(a)
        if ins is None:
            bad.append(f"{a:08x}: not an instruction of the image")
            continue
        if b == a + ins.size:
            continue
        m = ins.mnemonic.lower()
        branch = m.startswith(("b", "cb", "tb", "pop", "ldm", "bkpt", "svc")) or "pc" in ins.operands
        if not branch:
            bad.append(f"{a:08x} {ins.mnemonic} {ins.operands} -> {b:08x}")
    return len(pcs), bad


# --- what is counted ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Counted:
    """One row of the tables: an attica filter kind or a peer configuration."""

    label: str
    """``ars`` or ``fusion6``...: the argument of the program."""
    axes: int
    """6 or 9 inputs; 0 for the baselines (gyro, tilt), which no peer is compared with."""
    peer: str = ""
    """Peer library short name (peer_sources.LIBRARIES), empty for attica."""

    @property
    def function(self) -> str:
        """The counted call of the program."""
        return "att_peer_step" if self.peer else "att_filter_step"


def attica_rows() -> list[Counted]:
    """Every attica kind with the axes of its defaults (:mod:`attica.kinds`; 0 for the baselines)."""
    from attica.kinds import KINDS

    return [Counted(k.label, 0 if k.baseline else k.axes()) for k in KINDS]


def peer_rows() -> list[Counted]:
    """Every peer configuration (Fusion 6/9-axis, VQF 6D/9D)."""
    return [Counted(k.name, k.axes, lib) for lib, pl in peer_sources.LIBRARIES.items() for k in pl.kinds]


def pairs(rows: Sequence[Counted]) -> list[tuple[Counted, Counted]]:
    """(attica, peer) pairs with the same inputs: 6-axis filters with 6-axis peers, mars with 9-axis."""
    mine = [r for r in rows if not r.peer and r.axes]
    theirs = [r for r in rows if r.peer]
    return [(a, p) for a in mine for p in theirs if p.axes == a.axes]


Config = tuple[str, str]
"""(board, optimisation) of a Cortex-M count."""

DEFAULT_CONFIGS: tuple[Config, ...] = (("m4f", "-O2"), ("m4f", "-Os"), ("m7", "-O2"), ("m33", "-O2"))


@dataclass
class Counts:
    """Everything one report counted: per (config, label) a StepCounts, or why there is none."""

    cortex: dict[tuple[Config, str], StepCounts | str] = field(default_factory=dict)
    x86: dict[tuple[str, str], float | str] = field(default_factory=dict)
    """(``gcc -O2``, label) -> callgrind instructions per step."""
    notes: list[str] = field(default_factory=list)


def count_cortex(
    config: Config,
    rows: Sequence[Counted],
    steps: int,
    out: Path,
    counts: Counts,
    profile: Sequence[str] = (),
) -> None:
    """Trace attica and the peers on one board at one level (``profile``: rows with the call stack)."""
    board, opt = config
    target = cross.TARGETS[board]
    missing = target.missing()
    if missing:
        counts.notes.append(f"{board} {opt}: missing {cross.install_hint(missing)}")
        for r in rows:
            counts.cortex[(config, r.label)] = "n/a"
        return
    elf = target.build([BENCH_SOURCE], opt, "att_bench.elf", out / f"{board}{opt}")
    for r in rows:
        if not r.peer:
            counts.cortex[(config, r.label)] = trace_steps(
                elf, r.label, steps, board=board, calls=r.label in profile
            )
    built: dict[str, Path | str] = {}
    for r in rows:
        if not r.peer:
            continue
        if r.peer not in built:
            try:
                lib = peer_sources.LIBRARIES[r.peer]
                tc = peer_sources.board_toolchain(board)
                built[r.peer] = peer_sources.build(lib, tc, opt, out / "peers").program
            except peer_sources.PeerUnavailableError as e:
                built[r.peer] = str(e)
                counts.notes.append(f"{r.peer} on {board} {opt}: {e}")
        prog = built[r.peer]
        counts.cortex[(config, r.label)] = (
            prog
            if isinstance(prog, str)
            else trace_steps(prog, r.label, steps, r.function, board, calls=r.label in profile)
        )


def count_x86(rows: Sequence[Counted], out: Path, counts: Counts) -> None:
    """Callgrind instructions per step of attica and the peers, gcc and clang -O2."""
    from attica_dev import bench, golden

    if shutil.which("valgrind") is None:
        counts.notes.append("valgrind is not installed: no x86-64 columns")
        return
    for cc, opt in bench.CALLGRIND_CONFIGS:
        if shutil.which(cc) is None:
            counts.notes.append(f"{cc} is not installed: no x86-64 {cc} column")
            continue
        cfg = f"{cc} {opt}"
        prog = golden.build_program([BENCH_SOURCE], cc, opt, name="att_bench", out_dir=out / f"x86-{cc}")
        peers: dict[str, Path | str] = {}
        for r in rows:
            if not r.peer:
                counts.x86[(cfg, r.label)] = bench.instructions_per_step(prog, r.label)
                continue
            if r.peer not in peers:
                try:
                    lib = peer_sources.LIBRARIES[r.peer]
                    peers[r.peer] = peer_sources.build(
                        lib, peer_sources.host_toolchain(cc), opt, out / "peers"
                    ).program
                except peer_sources.PeerUnavailableError as e:
                    peers[r.peer] = str(e)
                    counts.notes.append(f"{r.peer} with {cc}: {e}")
            p = peers[r.peer]
            counts.x86[(cfg, r.label)] = (
                p if isinstance(p, str) else bench.instructions_per_step(p, r.label, function=r.function)
            )


def _mean(c: StepCounts | str | float | None, cycles: bool = False) -> float | None:
    if isinstance(c, StepCounts):
        return c.mean_cycles if cycles else c.mean
    if isinstance(c, float):
        return c
    return None


def _fmt(v: float | None) -> str:
    return "n/a" if v is None else f"{v:,.0f}"


def _ratio(a: float | None, b: float | None) -> str:
    return "n/a" if a is None or b is None or b == 0 else f"{a / b:.2f}"


def _row_label(r: Counted) -> str:
    if not r.peer:
        return r.label
    lib, kind = peer_sources.KINDS[r.label]
    return f"{r.label} ({lib.label} {kind.call})"


def report(
    counts: Counts,
    rows: Sequence[Counted],
    configs: Sequence[Config],
    steps: int,
    profile: Sequence[str] = (),
) -> str:
    """The instruction table, the ratio table, the goals and (optionally) the per-function profile."""
    x86_cfgs = sorted({c for c, _ in counts.x86})
    headers = ["filter"]
    for board, opt in configs:
        name = BOARDS[board].core.replace("Cortex-", "")
        headers += [f"{name} {opt}", "max"] + (["~cycles"] if board == "m4f" else [])
    headers += [f"x86-64 {c}" for c in x86_cfgs]
    table = []
    for r in rows:
        row = [_row_label(r)]
        for cfg in configs:
            c = counts.cortex.get((cfg, r.label))
            row += [_fmt(_mean(c)), str(max(c.instructions)) if isinstance(c, StepCounts) else "n/a"]
            if cfg[0] == "m4f":
                row.append(_fmt(_mean(c, cycles=True)))
        row += [_fmt(_mean(counts.x86.get((c, r.label)))) for c in x86_cfgs]
        table.append(row)
    text = [
        "Instructions per update (the counted call and its callees; tests/c/att_bench_common.h inputs, "
        "dt = 0.01 s, default settings of every filter). Cortex-M: QEMU exec trace, mean and max over "
        f"{steps} steps (700 moving, 300 at rest); ~cycles: Cortex-M4 TRM timings, zero wait states "
        "(estimate). x86-64: callgrind (I(12000) - I(2000)) / 10000. attica: att_filter_step; peers: "
        "att_peer_step (update + quaternion), built from their sdists with the same flags.",
        cross._table(headers, table),
        "",
        "attica / peer (instructions; ~cycles on the M4F; same inputs, same flags, same run; < 1: attica "
        "needs fewer):",
    ]
    rheaders = ["attica / peer"]
    for board, opt in configs:
        name = BOARDS[board].core.replace("Cortex-", "")
        rheaders += [f"{name} {opt}"] + (["~cycles"] if board == "m4f" else [])
    rheaders += [f"x86-64 {c}" for c in x86_cfgs]
    rtable = []
    for a, p in pairs(rows):
        row = [f"{a.label} / {p.label}"]
        for cfg in configs:
            ca, cp = counts.cortex.get((cfg, a.label)), counts.cortex.get((cfg, p.label))
            row.append(_ratio(_mean(ca), _mean(cp)))
            if cfg[0] == "m4f":
                row.append(_ratio(_mean(ca, True), _mean(cp, True)))
        row += [
            _ratio(_mean(counts.x86.get((c, a.label))), _mean(counts.x86.get((c, p.label)))) for c in x86_cfgs
        ]
        rtable.append(row)
    text.append(cross._table(rheaders, rtable))
    text += goal_lines(counts)
    for n in counts.notes:
        text.append(f"note: {n}")
    if profile and configs:
        text.append("")
        text += profile_lines(counts, configs[0], profile, steps)
    return "\n".join(text)


def goal_lines(counts: Counts) -> list[str]:
    """Issue 9's targets on the M4F at -O2 (met / missed), from the counts."""
    cfg: Config = ("m4f", "-O2")
    out = []

    def m(label: str) -> float | None:
        return _mean(counts.cortex.get((cfg, label)))

    for a, p in (("ars", "fusion6"), ("mars", "fusion9")):
        va, vp = m(a), m(p)
        if va is not None and vp is not None and vp > 0:
            r = va / vp
            verdict = "met" if r <= 1.0 else "within the 1.5 limit" if r <= 1.5 else "missed"
            out.append(f"goal {a} <= 1.0 x {p} (at most 1.5 x) on the M4F -O2: {r:.2f} x: {verdict}")
    for k, goal in (("kf", 1500), ("ekf", 1000), ("mekf", 2000)):
        v = m(k)
        if v is not None:
            verdict = "met" if v <= goal else "missed"
            out.append(f"goal {k} <= {goal} instructions on the M4F -O2: {v:,.0f}: {verdict}")
    return [""] + out if out else []


def profile_lines(counts: Counts, cfg: Config, labels: Sequence[str], steps: int) -> list[str]:
    """Per-function instructions per step (from the trace) of ``labels`` on ``cfg``: self and inclusive."""
    out = [
        f"Where the instructions of a step go ({BOARDS[cfg[0]].core} {cfg[1]}, mean over {steps} steps): "
        "self = in the function itself, with callees = it and everything it called (the trace's call "
        "stack), share = self / step."
    ]
    for label in labels:
        c = counts.cortex.get((cfg, label))
        if not isinstance(c, StepCounts):
            out.append(f"  {label}: not counted")
            continue
        total = sum(c.by_function.values())
        n = max(1, len(c.instructions))
        order = sorted(c.by_function, key=lambda fn: (-c.inclusive.get(fn, 0), -c.by_function[fn]))
        rows = [
            [
                fn,
                f"{c.by_function[fn] / n:.1f}",
                f"{c.inclusive[fn] / n:.1f}" if fn in c.inclusive else "-",
                f"{100 * c.by_function[fn] / total:.1f}%",
            ]
            for fn in order
        ]
        out.append(f"{label}: {total / n:.0f} instructions per step")
        out.append(cross._table(["function", "self", "with callees", "share"], rows))
    return out


STAGES: tuple[tuple[str, str, str, str], ...] = (
    ("ars+gyro", "ars", "att_filter_step", "gyro model, the first stage (with the entry of the stage path)"),
    ("ars+ned", "ars", "att_filter_step", "NED output, the only stage (with the entry of the stage path)"),
    ("ars+gyro,accel", "ars+gyro", "att_filter_step", "+ accel model"),
    ("mars+gyro,mag", "mars+gyro", "att_filter_step", "+ mag model (soft iron, hard iron; mars)"),
    (
        "ars+gyro,remap",
        "ars+gyro",
        "att_filter_step",
        "+ mounting remap (gyro folded: 0; accel, mag permuted)",
    ),
    ("ars+remap", "ars", "att_filter_step", "mounting remap alone (3 sensors permuted)"),
    (
        "ars+gyro,accel,quat",
        "ars+gyro,accel",
        "att_filter_step",
        "+ mounting quaternion (gyro, accel folded: 0; the mag rotated)",
    ),
    ("ars+quat", "ars", "att_filter_step", "mounting quaternion alone (3 sensors, 3x3)"),
    ("ars+gyro,ned", "ars+gyro", "att_filter_step", "+ NED output (q per step)"),
    ("ars+gyro,accout", "ars+gyro", "att_filter_step", "+ acceleration outputs kept"),
    ("ars+accout", "", "att_filter_accel", "att_filter_accel on request (per call)"),
)
"""The input/output stages (att_calib.h) counted by :func:`stage_lines`: att_bench label, the row
without the stage ("" = the absolute count), the counted function, and what is enabled."""


def stage_lines(steps: int, out: Path = OUT, board: str = "m4f", opt: str = "-O2") -> list[str]:
    """Instructions per step with each input/output stage enabled, beside the same filter without it."""
    target = cross.TARGETS[board]
    missing = target.missing()
    if missing:
        return [f"stages: missing {cross.install_hint(missing)}"]
    elf = target.build([BENCH_SOURCE], opt, "att_bench.elf", out / f"{board}{opt}")
    base: dict[str, float] = {}
    lines = [
        f"Input/output stages on the {board.upper()} {opt} (att_calib.h; instructions per call, mean over "
        f"{steps} steps; added = beside the row without that stage; with no stage enabled att_filter_step "
        f"pays one test of att_filter_t.cal.active):",
        f"  {'stage':66s} {'instr':>8s} {'added':>8s}",
    ]
    for label, ref, function, what in STAGES:
        if ref and ref not in base:
            base[ref] = trace_steps(elf, ref, steps, board=board).mean
        n = trace_steps(elf, label, steps, function, board).mean
        added = f"{n - base[ref]:+8.1f}" if ref else f"{'':>8s}"
        base.setdefault(label, n) if function == "att_filter_step" else None
        lines.append(f"  {what:66s} {n:8.1f} {added}")
    return lines


def cycles_report(
    steps: int = BENCH_STEPS,
    configs: Sequence[Config] = DEFAULT_CONFIGS,
    out: Path = OUT,
    profile: Sequence[str] = (),
    peers: bool = True,
    x86: bool = True,
    stages: bool = True,
) -> str:
    """Count everything and return the report (``make cycles``); ``stages``: the stage table too."""
    rows = attica_rows() + (peer_rows() if peers else [])
    counts = Counts()
    for i, cfg in enumerate(configs):
        count_cortex(cfg, rows, steps, out, counts, profile if i == 0 else ())
    if x86:
        count_x86(rows, out, counts)
    text = report(counts, rows, configs, steps, profile)
    if stages:
        text += "\n\n" + "\n".join(stage_lines(steps, out))
    return text


def _parse_configs(text: str) -> list[Config]:
    out: list[Config] = []
    for item in filter(None, text.split(",")):
        m = re.fullmatch(r"(\w+?)(-O\w+)", item)
        if m is None or m.group(1) not in BOARDS:
            raise argparse.ArgumentTypeError(
                f"bad configuration {item!r}: BOARD-OPT, e.g. m4f-O2 ({', '.join(BOARDS)})"
            )
        out.append((m.group(1), m.group(2)))
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m attica_dev.cycles``."""
    p = argparse.ArgumentParser(
        prog="python -m attica_dev.cycles", description=__doc__.split("\n")[0] if __doc__ else ""
    )
    p.add_argument("--steps", type=int, default=BENCH_STEPS, help="steps per filter in the trace (1000)")
    p.add_argument(
        "--configs",
        type=_parse_configs,
        default=list(DEFAULT_CONFIGS),
        help="Cortex-M boards and levels, e.g. m4f-O2,m4f-Os,m7-O2,m33-O2 (the default),m0plus-O2",
    )
    p.add_argument(
        "--profile",
        nargs="?",
        const="ars,mars",
        default="",
        help="per-function instructions per step of these rows on the first configuration (ars,mars)",
    )
    p.add_argument("--no-peers", action="store_true", help="attica only")
    p.add_argument("--no-x86", action="store_true", help="no callgrind columns")
    p.add_argument("--no-stages", action="store_true", help="no input/output stage table")
    p.add_argument("--stages-only", action="store_true", help="only the input/output stage table (M4F -O2)")
    args = p.parse_args(argv)
    if args.stages_only:
        try:
            print("\n".join(stage_lines(args.steps)))
        except (CyclesError, cross.CrossError) as e:
            print(f"cycles: {e}", file=sys.stderr)
            return 1
        return 0
    try:
        print(
            cycles_report(
                args.steps,
                args.configs,
                profile=[s for s in args.profile.split(",") if s],
                peers=not args.no_peers,
                x86=not args.no_x86,
                stages=not args.no_stages,
            )
        )
    except (CyclesError, cross.CrossError) as e:
        print(f"cycles: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
