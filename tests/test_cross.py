"""The firmware on other CPUs: bit-exact golden comparisons on Cortex-M4F, M7, M33 and M0+ (QEMU boards),
aarch64 and riscv64 (qemu-user) and x86-64 (gcc, clang); FMA gates per target; the Cortex-M start-up and
floating-point environment (every FPU board), images (no heap), stack; the CMake and Makefile library
builds; the CAN HALs (bxCAN, FDCAN) and the stand-alone floating-point environment.

Missing cross tools skip with a printed reason (host/tools/install-system-deps.sh installs them);
under CI=true they fail instead. Inputs and numpy reference outputs are computed once per session
(in worker processes, while the runners build) and shared by every target.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import re
import shutil
import subprocess
from collections.abc import Iterator
from concurrent.futures import Future, ProcessPoolExecutor, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from attica import _build
from attica.settings import implemented_kinds
from attica_dev import boards, cross, cycles, footprint, golden
from attica_dev.cross import TARGETS, FilterCase, MathData, Target

from helpers import BROAD, need

JOBS = max(2, os.cpu_count() or 2)
CONFIGS: list[tuple[str, str]] = [
    (name, opt) for name in (*cross.CROSS_TARGETS, *cross.NATIVE_TARGETS) for opt in TARGETS[name].opts
]
"""(target, optimisation) of the golden comparisons."""
FMA_OPTS = ["-O0", "-O2", "-O3", "-Os"]
FMA_TARGETS = [t for t in cross.CROSS_TARGETS if t not in boards.BOARDS or boards.BOARDS[t].fpu]
"""Targets whose CPU has fused multiply-add (the Cortex-M0+ has no FPU: soft float has no fused op)."""
SLICE_STREAMS = {"m0plus": 40}
"""Targets whose emulation is slow (soft float) compare only the first streams of every synthetic case
here (40 x 500 = 20 000 steps per filter kind) and skip the BROAD cases; ``make cross`` runs all of it."""
BROAD_CONFIGS = [c for c in CONFIGS if c[0] not in SLICE_STREAMS]
VARIANT_CONFIGS = {("m4f", "-O2"), *((t, "-O2") for t in cross.NATIVE_TARGETS)}
"""Configurations that also run the non-default settings (the others run every kind's defaults, to keep
the emulated wall time down; ``make cross`` runs every case everywhere)."""


def need_tools(*tools: str) -> None:
    """Skip (fail under CI=true) when a tool is missing, naming its Debian package."""
    missing = [t for t in tools if shutil.which(t) is None]
    need(not missing, f"not installed: {cross.install_hint(missing)} (host/tools/install-system-deps.sh)")


def need_target(target: Target) -> None:
    """Skip (fail under CI=true) when a tool of ``target`` is missing."""
    need_tools(*target.tools)


# --- shared inputs, references and runners ----------------------------------------------------------------


@dataclass
class CrossData:
    """Inputs written once and reference outputs (computed in worker processes)."""

    workdir: Path
    synthetic: list[FilterCase]
    broad: list[FilterCase]
    files: dict[str, Path]
    pending: dict[str, Future[Any]] = field(default_factory=dict)
    want: dict[str, Any] = field(default_factory=dict)
    _math: MathData | None = None

    @property
    def math(self) -> MathData:
        """Math rows, input files and reference outputs (made on first use)."""
        if self._math is None:
            self._math = cross.math_data(self.workdir)
        return self._math

    def reference(self, case: FilterCase) -> Any:
        """The reference outputs of a case (waits for its worker)."""
        if case.name not in self.want:
            job = self.pending.pop(case.name, None)
            self.want[case.name] = job.result() if job is not None else cross.reference_case(case)
        return self.want[case.name]


def _selected(session: pytest.Session, name: str) -> bool:
    return any(getattr(item, "originalname", item.name) == name for item in session.items)


@pytest.fixture(scope="session")
def cross_data(
    tmp_path_factory: pytest.TempPathFactory, request: pytest.FixtureRequest
) -> Iterator[CrossData]:
    """Synthetic (and BROAD, when present) filter cases and math rows with their references."""
    wd = tmp_path_factory.mktemp("cross")
    synthetic = cross.synthetic_cases()
    files_broad = cross.broad_files(BROAD)
    broad = cross.broad_cases(files_broad) if files_broad else []
    wanted = []
    if _selected(request.session, "test_golden_filters"):
        wanted += synthetic
    if _selected(request.session, "test_golden_broad"):
        wanted += broad
    pool = ProcessPoolExecutor(JOBS, mp_context=mp.get_context("fork")) if wanted else None
    pending = {}
    if pool is not None:
        for c in sorted(wanted, key=lambda c: -c.imu[0].shape[0] * cross.REFERENCE_COST.get(c.kind.label, 5)):
            pending[c.name] = pool.submit(cross.reference_case, c)
    files = cross.write_case_inputs([*synthetic, *broad], wd)
    data = CrossData(wd, synthetic, broad, files, pending)
    yield data
    if pool is not None:
        pool.shutdown(wait=False, cancel_futures=True)


@pytest.fixture(scope="session")
def runners(
    cross_data: CrossData, tmp_path_factory: pytest.TempPathFactory
) -> dict[tuple[str, str], Path | str]:
    """The golden runner of every configuration whose tools are installed (a build error as its text).

    Requests ``cross_data`` first so that the references are already computing during the builds.
    """
    out = tmp_path_factory.mktemp("cross_runners")
    configs = [c for c in CONFIGS if not TARGETS[c[0]].missing()]

    def build(cfg: tuple[str, str]) -> Path | str:
        try:
            return TARGETS[cfg[0]].runner(cfg[1], out / f"{cfg[0]}{cfg[1]}")
        except cross.CrossError as e:
            return str(e)

    with ThreadPoolExecutor(JOBS) as pool:
        return dict(zip(configs, pool.map(build, configs), strict=True))


def _runner(runners: dict[tuple[str, str], Path | str], config: tuple[str, str]) -> tuple[Path, Target]:
    target = TARGETS[config[0]]
    need_target(target)
    r = runners[config]
    if isinstance(r, str):
        pytest.fail(r)
    return r, target


def _report(config: tuple[str, str], results: list[cross.Result]) -> None:
    lines = [f"{config[0]} {config[1]}: {r.what}: {r.compared} compared, {r.differ} differ" for r in results]
    print("\n" + "\n".join(lines))
    bad = [f"{r.what}: {r.differ} of {r.compared} differ; {r.detail}" for r in results if not r.ok]
    assert not bad, f"{' '.join(config)} ({TARGETS[config[0]].description}):\n" + "\n".join(bad)


_IDS = [f"{t}{o}" for t, o in CONFIGS]


# --- golden bit-exactness --------------------------------------------------------------------------------


@pytest.mark.parametrize("config", CONFIGS, ids=_IDS)
def test_golden_math(
    runners: dict[tuple[str, str], Path | str], cross_data: CrossData, config: tuple[str, str], tmp_path: Path
) -> None:
    """Every math function of the runner, 1e5 random + adversarial rows each: bits equal the reference."""
    runner, target = _runner(runners, config)
    results = cross.compare_math(runner, target.prefix, cross_data.math, tmp_path)
    assert len(results) == len(golden.MATH_FUNCS)
    _report(config, results)


@pytest.mark.parametrize("config", CONFIGS, ids=_IDS)
def test_golden_filters(
    runners: dict[tuple[str, str], Path | str], cross_data: CrossData, config: tuple[str, str], tmp_path: Path
) -> None:
    """Every filter kind (defaults; variants too on VARIANT_CONFIGS) over 1e5 synthetic adversarial
    steps each (2e4 on the SLICE_STREAMS targets): every output record (q, euler, bias, cov, flags, steps)
    bit-identical to the reference."""
    runner, target = _runner(runners, config)
    cases = [c for c in cross_data.synthetic if config in VARIANT_CONFIGS or c.name.endswith("-default")]
    kinds = {c.kind for c in cases}
    assert kinds == set(implemented_kinds())
    want = {c.name: cross_data.reference(c) for c in cases}
    streams = SLICE_STREAMS.get(config[0], 0)
    results = cross.compare_filters(
        runner,
        target.prefix,
        cases,
        want,
        cross_data.files,
        tmp_path,
        max_streams=target.max_streams,
        streams=streams,
    )
    assert all(r.compared >= (20_000 if streams else 100_000) for r in results)
    _report(config, results)


@pytest.mark.parametrize("config", BROAD_CONFIGS, ids=[f"{t}{o}" for t, o in BROAD_CONFIGS])
def test_golden_broad(
    runners: dict[tuple[str, str], Path | str], cross_data: CrossData, config: tuple[str, str], tmp_path: Path
) -> None:
    """Every filter kind over 1e5 real BROAD samples (4 chunks of 1250 from every recording); every target
    but the SLICE_STREAMS ones (``make cross`` runs those too)."""
    need(bool(cross_data.broad), f"BROAD data not found at {BROAD}")
    runner, target = _runner(runners, config)
    want = {c.name: cross_data.reference(c) for c in cross_data.broad}
    results = cross.compare_filters(
        runner,
        target.prefix,
        cross_data.broad,
        want,
        cross_data.files,
        tmp_path,
        max_streams=target.max_streams,
    )
    assert all(r.compared >= 100_000 for r in results)
    _report(config, results)


# --- FMA gate per target ---------------------------------------------------------------------------------


@pytest.mark.parametrize("name", FMA_TARGETS)
def test_no_fma_on_target(name: str, tmp_path: Path) -> None:
    """No fused multiply-add in any firmware object for the target at -O0/-O2/-O3/-Os (all of these
    CPUs have FMA instructions, so this proves -ffp-contract=off works there)."""
    target = TARGETS[name]
    need_tools(target.cc, target.objdump)
    jobs = [(src, opt) for opt in FMA_OPTS for src in _build.firmware_sources()]

    def one(job: tuple[Path, str]) -> list[str]:
        src, opt = job
        obj = tmp_path / f"{src.stem}{opt}.o"
        cross.compile_object(target, src, obj, opt)
        return [f"{opt} {h}" for h in cross.fma_instructions(obj, target.objdump)]

    with ThreadPoolExecutor(JOBS) as pool:
        hits = [h for hs in pool.map(one, jobs) for h in hs]
    assert not hits, f"{len(hits)} fused multiply-add instruction(s) for {name}:\n" + "\n".join(hits[:40])


@pytest.mark.parametrize("name", FMA_TARGETS)
def test_fma_gate_can_fail(name: str, tmp_path: Path) -> None:
    """The gate sees FMA when contraction is allowed: a*b+c compiled without -ffp-contract=off (GCC's
    default for GNU C is -ffp-contract=fast) becomes vfma.f32 / fmadd / fmadd.s and is detected."""
    target = TARGETS[name]
    need_tools(target.cc, target.objdump)
    src = tmp_path / "fma.c"
    src.write_text(
        "float f(float a, float b, float c);\nfloat f(float a, float b, float c) { return a * b + c; }\n"
    )
    obj = tmp_path / "fma.o"
    subprocess.run(
        [target.cc, *target.cpu, "-O2", "-c", str(src), "-o", str(obj)], check=True, capture_output=True
    )
    hits = cross.fma_instructions(obj, target.objdump)
    assert hits, f"{target.cc} -O2 (contraction allowed) produced no FMA the detector recognises"
    subprocess.run(
        [target.cc, *target.cpu, "-O2", "-ffp-contract=off", "-c", str(src), "-o", str(obj)],
        check=True,
        capture_output=True,
    )
    assert not cross.fma_instructions(obj, target.objdump)


def test_fma_regex_targets() -> None:
    """The mnemonic pattern covers ARMv7-M VFPv4, AArch64 and RISC-V FMA and leaves the rest alone."""
    for m in ("vfma.f32", "vfms.f32", "vfnma.f32", "vfnms.f32", "fmadd", "fmsub", "fnmadd", "fnmsub", "fmla",
              "fmls", "fmadd.s", "fmsub.s", "fnmadd.s", "fnmsub.s", "vfmadd231ss"):  # fmt: skip
        assert cross.FMA_RE.match(m), m
    for m in ("vmla.f32", "vmls.f32", "vnmla.f32", "vmul.f32", "fmul", "fadd", "fmul.s", "fadd.s", "fmv.s"):
        assert not cross.FMA_RE.match(m), m


# --- Cortex-M4F start-up, floating-point environment, semihosting -----------------------------------


@pytest.fixture(scope="module")
def m4f_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Where this module builds its Cortex-M4F images."""
    need_target(TARGETS["m4f"])
    return tmp_path_factory.mktemp("m4f")


@pytest.mark.parametrize("board", boards.FPU_BOARDS)
def test_cortex_m_floating_point_environment(board: str, tmp_path: Path) -> None:
    """After startup.c on every FPU board (M4F, M7, M33): FPU on, FPSCR and FPDSCR round-to-nearest, no
    flush-to-zero, no default NaN (in thread mode and in an exception handler), checked by arithmetic; and
    the check can fail."""
    need_target(TARGETS[board])
    elf = TARGETS[board].build([cross.TESTS_C / "att_m4f_fpenv.c"], "-O2", "fpenv.elf", tmp_path)
    proc = subprocess.run(
        [*TARGETS[board].prefix, str(elf)],
        capture_output=True,
        text=True,
        timeout=60,
        stdin=subprocess.DEVNULL,
    )
    print(proc.stdout)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "FAIL" not in proc.stdout and proc.stdout.count("ok ") >= 14


def test_m4f_script_is_the_m4f_board(m4f_dir: Path) -> None:
    """qemu-m4f.sh (the documented runner) is qemu-cortex-m.sh on the M4F board: the status passes through."""
    elf = TARGETS["m4f"].build([cross.TESTS_C / "att_m4f_fpenv.c"], "-O2", "fpenv.elf", m4f_dir)
    proc = subprocess.run(
        [str(cross.QEMU_M4F), str(elf)], capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL
    )
    assert proc.returncode == 0 and "0 failure(s)" in proc.stdout, proc.stdout + proc.stderr
    bad = subprocess.run(
        [str(boards.QEMU_SCRIPT), "m5", str(elf)], capture_output=True, text=True, timeout=60
    )
    assert bad.returncode == 125 and "unknown board" in bad.stderr


@pytest.mark.parametrize("board", list(boards.BOARDS))
def test_cortex_m_board_images(board: str, tmp_path: Path) -> None:
    """Every board's runner image: vector table at the start of its code memory (where the core fetches it
    at reset), .data running in RAM with its load image in code memory, the code for the board's core and
    FPU (build attributes), and a run that answers on semihosting."""
    target = TARGETS[board]
    need_target(target)
    b = boards.BOARDS[board]
    runner = target.runner("-O2", tmp_path)
    assert golden.run(runner, ["list"], target.prefix).startswith("math ")
    out = subprocess.run(
        ["arm-none-eabi-objdump", "-h", str(runner)], capture_output=True, text=True, check=True
    ).stdout
    sections = {
        p[1]: p for p in (line.split() for line in out.splitlines()) if len(p) >= 6 and p[0].isdigit()
    }
    script = b.script.read_text()
    origins = dict(re.findall(r"(FLASH|RAM) \(\w+\)\s*:\s*ORIGIN = (0x[0-9a-fA-F]+)", script))
    flash, ram = int(origins["FLASH"], 16), int(origins["RAM"], 16)
    assert int(sections[".vectors"][3], 16) == flash
    assert int(sections[".data"][3], 16) >= ram and flash <= int(sections[".data"][4], 16) < ram
    attrs = subprocess.run(
        ["arm-none-eabi-readelf", "-A", str(runner)], capture_output=True, text=True, check=True
    ).stdout
    arch = {"m4f": "v7E-M", "m7": "v7E-M", "m33": "v8-M.mainline", "m0plus": "v6S-M"}[board]
    assert f"Tag_CPU_arch: {arch}" in attrs, attrs
    assert ("Tag_ABI_VFP_args: VFP registers" in attrs) == b.fpu, attrs


def test_m4f_semihosting_runner(m4f_dir: Path) -> None:
    """The runner on the M4F: argv from the command line, stdout/stderr, exit status via SYS_EXIT_EXTENDED,
    host files through newlib; the vector table is at 0 and .data is copied from its load address."""
    target = TARGETS["m4f"]
    runner = target.runner("-O2", m4f_dir)
    listed = golden.run(runner, ["list"], target.prefix)
    assert listed.startswith("math ") and "filters" in listed
    proc = subprocess.run(
        [*target.prefix, str(runner), "math", "nosuch", "a", "b"], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 1 and "unknown math function" in proc.stderr
    out = subprocess.run(
        ["arm-none-eabi-objdump", "-h", str(runner)], capture_output=True, text=True, check=True
    ).stdout
    sections = {
        p[1]: p for p in (line.split() for line in out.splitlines()) if len(p) >= 6 and p[0].isdigit()
    }
    assert int(sections[".vectors"][3], 16) == 0, "vector table not at address 0"
    data = sections[".data"]
    assert int(data[3], 16) >= 0x20000000 and int(data[4], 16) < 0x00400000, (
        ".data must run in RAM, load from flash"
    )
    syms = cycles.symbols(runner)
    assert {"Reset_Handler", "att_port_fp_init", "_exit"} <= set(syms)


def test_m4f_library_images_no_heap(tmp_path: Path) -> None:
    """libattica.a for the M4F builds with -Wstack-usage, and every footprint image (each filter, all
    filters, codec, node) links without heap, libm or errno symbols."""
    need_target(TARGETS["m4f"])
    lib, objs = footprint.library("-Os", tmp_path)
    assert len(objs) == len(_build.firmware_sources())
    problems = []
    for name, image in footprint.IMAGES.items():
        elf, map_file = footprint.link_image(name, image, lib, "-Os", tmp_path / "images")
        bad = footprint.forbidden_symbols(elf)
        if bad:
            problems.append(f"{name}: {', '.join(bad)}")
        sizes = footprint.map_sizes(map_file)
        assert sizes.attica.text > 0, name
        assert sizes.attica.data == 0 and sizes.attica.bss == 0, f"{name}: the library has static state"
    assert not problems, "\n".join(problems)


def test_m4f_stack_gate_can_fail(tmp_path: Path) -> None:
    """-Wstack-usage=M4F_STACK_LIMIT with the firmware flags stops a build whose frame is larger."""
    need_tools("arm-none-eabi-gcc")
    src = tmp_path / "big.c"
    src.write_text(
        "#include <string.h>\nvoid g(char *p);\nvoid f(void);\n"
        f"void f(void) {{ char buf[{cross.M4F_STACK_LIMIT + 64}]; memset(buf, 1, sizeof buf); g(buf); }}\n"
    )
    target = Target("m4f", "", "arm-none-eabi-gcc", cross.M4F_CPU)
    with pytest.raises(cross.CrossError, match="stack usage"):
        cross.compile_object(
            target, src, tmp_path / "big.o", "-O2", [f"-Wstack-usage={cross.M4F_STACK_LIMIT}"]
        )


def test_m4f_call_graph_tail_calls(tmp_path: Path) -> None:
    """A callee reached only by a branch after the epilogue (a tail call) runs on the caller's caller's
    stack: the call-graph bound takes the larger of the two, not their sum; a call (BL) nests."""
    need_tools("arm-none-eabi-gcc", "arm-none-eabi-objdump")
    src = tmp_path / "tail.c"
    src.write_text(
        "int g(int x);\nint h(int x);\nint f(int x);\n"
        "int f(int x) { if (x > 3) { return g(x + 1); } return h(x) * 3 + 1; }\n"
    )
    obj = tmp_path / "tail.o"
    target = Target("m4f", "", "arm-none-eabi-gcc", cross.M4F_CPU)
    cross.compile_object(target, src, obj, "-O2", list(cross.M4F_SECTIONS))
    assert footprint.tail_calls(obj) == {("f", "g")}
    g = footprint.CallGraph(
        frame={"f": 100, "g": 50, "h": 20},
        calls={"f": {"g", "h"}},
        names={"f": "f", "g": "g", "h": "h"},
        tail={("f", "g")},
    )
    assert footprint.worst_stack(g, "f", {}).bytes == 120  # max(100 + h, g)
    g.tail = set()
    assert footprint.worst_stack(g, "f", {}).bytes == 150  # every edge nests


def test_m4f_stack_measured_within_call_graph(tmp_path: Path) -> None:
    """The call-graph worst case bounds the stack measured on the target (QEMU, painted stack)."""
    need_target(TARGETS["m4f"])
    need_tools("qemu-system-arm")
    lib, objs = footprint.library("-O2", tmp_path)
    elf, _ = footprint.link_image("node", footprint.IMAGES["CAN node (att_node)"], lib, "-O2", tmp_path)
    graph = footprint.call_graph(objs)
    ext = {f: v for f in ("memcpy", "memset") if (v := footprint.leaf_stack(elf, f)) is not None}
    measured = footprint.measure("-O2", tmp_path)
    assert (
        measured.sizeof["att_filter_t"] > 0
        and measured.sizeof["att_node_t"] > measured.sizeof["att_filter_t"]
    )
    checked = 0
    for (fn, kind), used in measured.stack.items():
        bound = footprint.worst_stack(graph, fn, ext)
        # the node's persistence hook (att_node_set_persist) is the application's function: its stack is
        # the application's to add; the measured runs set no hook
        unknown = [
            u for u in bound.unknown if not (fn.startswith("att_node") and u == "Indirect Call Placeholder")
        ]
        assert not unknown, f"{fn}: unknown callees {unknown}"
        assert used <= bound.bytes, f"{fn} ({kind}): measured {used} B > call-graph bound {bound.bytes} B"
        assert used > 0, f"{fn} ({kind}): nothing measured"
        checked += 1
    assert checked >= 10


def test_m4f_instruction_trace(tmp_path: Path) -> None:
    """The QEMU exec trace logs every executed instruction (each PC change is sequential or a branch) and
    counts every call of att_filter_step, repeatably."""
    need_target(TARGETS["m4f"])
    elf = TARGETS["m4f"].build([cycles.BENCH_SOURCE], "-O2", "att_bench.elf", tmp_path)
    a = cycles.trace_steps(elf, "tilt", 30)
    b = cycles.trace_steps(elf, "tilt", 30)
    assert a.instructions == b.instructions and len(a.instructions) == 30
    # the per-block trace counts exactly what the per-instruction trace counts, function by function
    c = cycles.trace_steps_per_instruction(elf, "tilt", 30)
    assert (a.instructions, a.cycles, a.by_function) == (c.instructions, c.cycles, c.by_function)
    # the inclusive profile: the counted call holds everything, every function at least its own part
    d = cycles.trace_steps(elf, "tilt", 30, calls=True)
    assert d.by_function == a.by_function and d.inclusive["att_filter_step"] == sum(a.instructions)
    assert all(d.inclusive[fn] >= n for fn, n in d.by_function.items())
    assert d.inclusive["att_tilt_step"] > d.by_function["att_tilt_step"]
    assert all(50 < n < 5000 for n in a.instructions)
    assert all(c >= n for c, n in zip(a.cycles, a.instructions, strict=True))
    logged, gaps = cycles.check_trace(elf, "tilt", 3)
    assert logged > 1000 and not gaps, "the exec trace misses instructions:\n" + "\n".join(gaps[:20])


# --- library builds for users ----------------------------------------------------------------------------


INTEGRATION = cross.ROOT / "examples" / "c"


def _run_example(path: Path) -> str:
    proc = subprocess.run([str(path)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert re.match(r"^steps 1000 flags 0x[0-9a-f]{4} q( [0-9a-f]{8}){4} yaw ", proc.stdout), proc.stdout
    return proc.stdout


@pytest.fixture(scope="module")
def cmake_example(tmp_path_factory: pytest.TempPathFactory) -> str:
    """examples/c through firmware/CMakeLists.txt with the host compiler; the example's output."""
    need_tools("cmake", "cc")
    build = tmp_path_factory.mktemp("cmake")
    subprocess.run(
        ["cmake", "-S", str(INTEGRATION), "-B", str(build), "-DCMAKE_EXPORT_COMPILE_COMMANDS=ON"],
        check=True,
        capture_output=True,
    )
    proc = subprocess.run(["cmake", "--build", str(build), "-j", str(JOBS)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    commands = (build / "compile_commands.json").read_text()
    for flag in ("-ffp-contract=off", "-fno-fast-math", "-fno-math-errno", "-fno-lto", "-Werror"):
        assert flag in commands, f"{flag} not on the attica compile lines"
    return _run_example(build / "example")


def test_cmake_library(cmake_example: str) -> None:
    """firmware/CMakeLists.txt: target attica builds with the host compiler and the example runs."""
    assert "steps 1000" in cmake_example


@pytest.fixture(scope="module")
def make_example(tmp_path_factory: pytest.TempPathFactory) -> str:
    """examples/c through firmware/attica.mk with the host compiler; the example's output."""
    need_tools("make", "cc")
    build = tmp_path_factory.mktemp("mk")
    proc = subprocess.run(
        ["make", "-f", str(INTEGRATION / "Makefile"), f"BUILD={build}", "-j", str(JOBS)],
        capture_output=True,
        text=True,
        cwd=_build.ROOT,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert (build / "attica" / "libattica.a").exists()
    for flag in ("-ffp-contract=off", "-fno-fast-math", "-fno-math-errno", "-fno-lto", "-Werror"):
        assert flag in proc.stdout, f"{flag} not on the attica compile lines"
    return _run_example(build / "example")


def test_makefile_fragment(make_example: str) -> None:
    """firmware/attica.mk: the example builds through the fragment (ATTICA_LIB) and runs."""
    assert "steps 1000" in make_example


def test_cmake_and_make_agree(cmake_example: str, make_example: str) -> None:
    """The two library builds give the same bits."""
    assert make_example == cmake_example


def test_cmake_cortex_m4f(tmp_path: Path) -> None:
    """The CMake library and the Cortex-M port (bxCAN and FDCAN HALs, floating-point environment)
    cross-compiled with the Cortex-M4F toolchain file."""
    need_tools("cmake", "arm-none-eabi-gcc")
    toolchain = cross.PORT / "arm-none-eabi-m4f.cmake"
    subprocess.run(
        [
            "cmake",
            "-S",
            str(_build.FIRMWARE),
            "-B",
            str(tmp_path),
            f"-DCMAKE_TOOLCHAIN_FILE={toolchain}",
            "-DATTICA_CORTEX_M_BXCAN=ON",
            "-DATTICA_CORTEX_M_FDCAN=ON",
            "-DATTICA_CORTEX_M_FPENV=ON",
            "-DCMAKE_BUILD_TYPE=MinSizeRel",
        ],
        check=True,
        capture_output=True,
    )
    proc = subprocess.run(
        ["cmake", "--build", str(tmp_path), "-j", str(JOBS)], capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    attrs = subprocess.run(
        ["arm-none-eabi-readelf", "-A", str(tmp_path / "libattica.a")],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert "VFPv4-D16" in attrs and "VFP registers" in attrs
    for port in ("bxcan", "fdcan", "fpenv"):
        assert (tmp_path / f"libattica_{port}.a").exists(), port


def _documented_cross_builds() -> list[tuple[str, str]]:
    """(where, shell text) of every documented command that names the Cortex-M4F toolchain file: the
    ```sh blocks of the docs (continuation lines joined) and the command in the toolchain file's own
    comment."""
    found: list[tuple[str, str]] = []
    for md in [_build.ROOT / "README.md", *sorted((_build.ROOT / "docs").glob("*.md"))]:
        lang: str | None = None  # the language of the open fence, None outside one
        start = 0
        lines: list[str] = []
        for n, line in enumerate(md.read_text().splitlines(), 1):
            if lang is None and line.startswith("```"):
                lang, start, lines = line[3:].strip(), n + 1, []
            elif lang is not None and line.strip() == "```":
                block = "\n".join(lines).replace("\\\n", " ")
                if lang in ("", "sh", "bash", "shell") and "arm-none-eabi-m4f.cmake" in block:
                    found.append((f"{md.name}:{start}", block))
                lang = None
            elif lang is not None:
                lines.append(line)
    toolchain = cross.PORT / "arm-none-eabi-m4f.cmake"
    for line in toolchain.read_text().splitlines():
        if re.match(r"^#\s+cmake ", line):
            found.append((toolchain.name, line.lstrip("#").strip()))
    return found


def test_documented_cross_build_runs_as_written(tmp_path: Path) -> None:
    """The cross-build commands of the docs, run literally from the directory they are written for (a
    directory whose firmware/ is the repository's; the build goes there, not into the checkout). With a
    relative CMAKE_TOOLCHAIN_FILE they once failed: cmake looks for it in the build directory."""
    need_tools("cmake", "arm-none-eabi-gcc")
    commands = _documented_cross_builds()
    where = [w for w, _ in commands]
    assert any(w.startswith("integration.md") for w in where) and "arm-none-eabi-m4f.cmake" in where, where
    for i, (source, text) in enumerate(commands):
        run_dir = tmp_path / f"run{i}"
        run_dir.mkdir()
        (run_dir / "firmware").symlink_to(_build.FIRMWARE, target_is_directory=True)
        proc = subprocess.run(
            ["bash", "-e", "-c", text], cwd=run_dir, capture_output=True, text=True, timeout=900
        )
        assert proc.returncode == 0, f"{source}: {text}\n{proc.stdout[-3000:]}{proc.stderr[-3000:]}"
        cache = next(run_dir.rglob("CMakeCache.txt")).read_text()
        m = re.search(r"^CMAKE_TOOLCHAIN_FILE:FILEPATH=(.+)$", cache, re.M)
        assert m is not None, source
        assert Path(m.group(1)).resolve() == (cross.PORT / "arm-none-eabi-m4f.cmake").resolve(), source
        if "--build" in text:
            lib = next(run_dir.rglob("libattica.a"))
            attrs = subprocess.run(
                ["arm-none-eabi-readelf", "-A", str(lib)], capture_output=True, text=True, check=True
            ).stdout
            assert "VFPv4-D16" in attrs, source


# --- CAN HALs: bxCAN, FDCAN / M_CAN ------------------------------------------------------------------------

HALS = {
    "bxcan": (cross.PORT / "att_can_hal.c", cross.TESTS_C / "att_can_hal_test.c"),
    "fdcan": (cross.PORT / "att_fdcan_hal.c", cross.TESTS_C / "att_fdcan_hal_test.c"),
}
"""Each CAN HAL of firmware/ports/cortex_m and its host test against a fake register block."""
SMALL_NODE = (
    "-DATT_NODE_WITH_FD=0",
    "-DATT_WITH_CALIB=0",
    "-DATT_WITH_HARD_IRON=0",
    "-DATT_NODE_RX_RING=8",
    "-DATT_NODE_TX_RING=8",
)
"""The small node of issue 22: classic frames only, no stages, rings of 8 (4 receive IDs instead of 5); with
every kind, the tx ring of 8 needs the hard-iron estimate left out (ATT_MAG_OFFSET would make a set 9)."""


def _run_hal_test(hal: str, cc: str, tmp_path: Path, config: tuple[str, ...] = ()) -> str:
    prog = golden.build_program(
        list(HALS[hal]), cc, "-O2", ["-I", str(cross.PORT), *config], f"att_{hal}_hal_test", tmp_path
    )
    proc = subprocess.run([str(prog)], capture_output=True, text=True, timeout=120)
    print(proc.stdout)
    assert proc.returncode == 0 and "FAIL" not in proc.stdout, proc.stdout + proc.stderr
    assert "0 failure(s)" in proc.stdout
    return proc.stdout


@pytest.mark.parametrize("cc", ["gcc", "clang"])
@pytest.mark.parametrize("hal", list(HALS))
def test_can_hal_host(hal: str, cc: str, tmp_path: Path) -> None:
    """A CAN HAL against its fake controller on the host, frames through a real node. Both: bit timing,
    init and its refusals, the acceptance filter (every 11-bit ID reaches the receive FIFO iff it is one
    of the node's IDs, decided from the filter registers by the controller's matching rules, id_offset 0
    and three others), output sets bit-identical to a direct filter, other nodes' traffic kept out, full
    FIFOs, bus-off. bxCAN: extended IDs, busy mailboxes. FDCAN: the G4 and H7 register maps and message
    RAM layouts, classic and CAN FD frames in both directions (DLC 9..15, BRS), protected registers."""
    need_tools(cc)
    out = _run_hal_test(hal, cc, tmp_path)
    assert out.count("reach") >= (4 if hal == "bxcan" else 8)  # the acceptance checks ran


@pytest.mark.parametrize("hal", list(HALS))
def test_can_hal_small_node(hal: str, tmp_path: Path) -> None:
    """The HALs with the small node configuration (classic only, no stages, rings of 8): 4 receive IDs,
    one bxCAN filter bank, two FDCAN filter elements."""
    need_tools("gcc")
    out = _run_hal_test(hal, "gcc", tmp_path, SMALL_NODE)
    assert "exactly the node's 4 reach" in out


_DIAG_BUS_LINE = re.compile(r"^diag_bus (\S+) (.+?) data=([0-9a-f]{16}) (.*)$")


@pytest.mark.parametrize("hal", list(HALS))
def test_can_hal_diag_bus_decoded_on_the_host(hal: str, tmp_path: Path) -> None:
    """The ATT_DIAG_BUS frames the HAL tests' nodes sent (after bus-off, error-passive, overruns; printed
    by tests/c/att_hal_test_common.h with what the driver counted) decode on the host to those counters:
    the E2E check, cantools from the DBC, the numpy stream decoder and the monitor's reading agree."""
    from attica.can import codec
    from attica.can.monitor import diag_bus_named, diag_bus_values

    need_tools("gcc")
    out = _run_hal_test(hal, "gcc", tmp_path)
    seen: set[str] = set()
    for line in out.splitlines():
        m = _DIAG_BUS_LINE.match(line)
        if m is None:
            continue
        seen.add(f"{m.group(1)}: {m.group(2)}")
        want = {k: min(int(v), 255) for k, v in (kv.split("=") for kv in m.group(4).split())}
        data = bytes.fromhex(m.group(3))
        f = codec.frames(1)
        f["id"], f["len"], f["data"][0, :8] = codec.ID_DIAG_BUS, 8, list(data)
        assert codec.check(f[0]) == codec.Check.OK, line
        name, sig = codec.decode(f[0])
        assert name == "ATT_DIAG_BUS" and {k: int(sig[k]) for k in want} == want, (line, sig)
        row = codec.decode_outputs(f).diag_bus
        assert row.shape == (1,) and bool(row["crc_ok"][0]), line
        assert {k: int(row[k][0]) for k in want} == want, line
        assert diag_bus_values(data) == want
        named = diag_bus_named(data)
        assert named["state"] == codec.BUS_STATES[want["state"]]
        assert named["lec"] == codec.LEC_NAMES[want["lec"]]
    variants = ("bxcan",) if hal == "bxcan" else ("fdcan-G4", "fdcan-H7")
    for v in variants:  # a quiet bus, a frame queued during a back-off (state BUS_OFF), after the faults
        assert {f"{v}: quiet bus", f"{v}: queued during the back-off", f"{v}: after the faults"} <= seen, seen


@pytest.mark.parametrize("hal", list(HALS))
def test_can_hal_compiles_for_m4f(hal: str, tmp_path: Path) -> None:
    """The HAL compiles for the Cortex-M4F with the strict firmware flags, without heap or libm calls."""
    need_tools("arm-none-eabi-gcc", "arm-none-eabi-nm")
    obj = tmp_path / f"{hal}.o"
    cross.compile_object(TARGETS["m4f"], HALS[hal][0], obj, "-Os", ["-I", str(cross.PORT)])
    undefined = subprocess.run(
        ["arm-none-eabi-nm", "-u", str(obj)], capture_output=True, text=True, check=True
    )
    names = {line.split()[-1] for line in undefined.stdout.splitlines() if line.strip()}
    allowed = {
        "att_node_rx",
        "att_node_tx",
        "att_node_poll",
        "att_node_rx_ids",
        "att_node_set_bus_diag",
        "memset",
        "memcpy",
    }
    assert names <= allowed, names


@pytest.mark.parametrize("board", list(boards.BOARDS))
def test_fpenv_stands_alone(board: str, tmp_path: Path) -> None:
    """att_fpenv.c (the floating-point environment) needs nothing else: no vector table, no start-up, no
    C library; it defines exactly att_port_fp_init, att_port_fp_ok and att_port_fpscr, which startup.c
    calls and no longer defines (so a vendor start-up links att_fpenv.c alone)."""
    need_tools("arm-none-eabi-gcc", "arm-none-eabi-nm")
    target = TARGETS[board]
    fpenv, start = tmp_path / "fpenv.o", tmp_path / "startup.o"
    cross.compile_object(target, cross.PORT / "att_fpenv.c", fpenv, "-Os", ["-I", str(cross.PORT)])
    cross.compile_object(target, cross.PORT / "startup.c", start, "-Os", ["-I", str(cross.PORT)])

    def syms(obj: Path) -> tuple[set[str], set[str]]:
        out = subprocess.run(
            ["arm-none-eabi-nm", str(obj)], capture_output=True, text=True, check=True
        ).stdout
        rows = [line.split() for line in out.splitlines() if line.strip()]
        return {r[-1] for r in rows if r[-2] == "T"}, {r[-1] for r in rows if r[-2] == "U"}

    api = {"att_port_fp_init", "att_port_fp_ok", "att_port_fpscr"}
    defined, undefined = syms(fpenv)
    assert defined == api and not undefined, (defined, undefined)
    defined, undefined = syms(start)
    assert not defined & api and {"att_port_fp_init", "att_port_fp_ok"} <= undefined


def test_golden_configs_cover_every_cpu() -> None:
    """The comparison covers the Cortex-M4F, M7, M33 and M0+, aarch64, riscv64, x86-64 with gcc and clang."""
    names = {t for t, _ in CONFIGS}
    assert {"m4f", "m7", "m33", "m0plus", "aarch64", "riscv64"} <= names
    if cross.NATIVE_TARGETS:
        assert {"x86_64-gcc", "x86_64-clang"} <= names
    assert {o for t, o in CONFIGS if t == "m4f"} == {"-O2", "-Os"}
