"""The firmware on other CPUs: Cortex-M4F under QEMU, aarch64 and riscv64 under qemu-user, x86-64.

Every target builds the same C programs from the firmware sources with the strict flags of
firmware/cflags.txt (through :func:`attica_dev.golden.build_program`) plus its own target flags, and
runs them through a command prefix (an emulator, or nothing natively):

- ``m4f``: arm-none-eabi-gcc for Cortex-M4F (``-mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16
  -mfloat-abi=hard``), linked with our own start-up (firmware/ports/cortex_m/startup.c: vector
  table, .data/.bss; att_fpenv.c: FPU on, FPSCR in IEEE mode and checked), the mps2_an386.ld linker script and
  newlib with semihosting (rdimon) for stdio on host files; run by
  firmware/ports/cortex_m/qemu-m4f.sh under ``qemu-system-arm -M mps2-an386``;
- ``aarch64``, ``riscv64``: static Linux programs from the Debian cross compilers, run by
  ``qemu-aarch64-static`` / ``qemu-riscv64-static``;
- ``x86_64-gcc``, ``x86_64-clang``: native programs.

:func:`golden_cases` builds the inputs of the cross-CPU golden comparison (synthetic adversarial
streams and, when present, real BROAD recordings), :func:`reference_outputs` computes the numpy
reference once, and :func:`compare_target` runs the golden runner of one target over all of it.
``python -m attica_dev.cross`` does all of that and prints the table; ``python -m attica_dev.cross firmware``
builds the Cortex-M4F library and images (``make firmware``).
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica import _build
from attica.settings import FilterKind, implemented_kinds, make_settings
from attica_dev import golden
from attica_dev.boards import BOARDS, SECTIONS, CortexM
from attica_dev.boards import PORT as PORT  # re-exported: the tests and footprint use cross.PORT
from attica_dev.boards import PORT_SOURCES as PORT_SOURCES

ROOT = _build.ROOT
LINKER_SCRIPT = BOARDS["m4f"].script
QEMU_M4F = PORT / "qemu-m4f.sh"
TESTS_C = ROOT / "tests" / "c"
BUILD = ROOT / "build" / "cross"
BROAD = ROOT.parent / "shared" / "data" / "broad"
BROAD_RATE = 285.714
"""Sample rate of the BROAD recordings (Hz)."""

M4F_CPU = BOARDS["m4f"].cpu
"""Cortex-M4F code generation: Thumb-2, FPv4-SP single-precision FPU, hard-float ABI."""
M4F_STACK_LIMIT = 1024
"""-Wstack-usage limit (bytes per function) of the library objects on the Cortex-M4F."""
M4F_LINK = BOARDS["m4f"].link
"""Link flags of Cortex-M4F test images: our start-up, our linker script, newlib + semihosting."""
M4F_SECTIONS = SECTIONS

# Fused multiply-add mnemonics: x86 (vfmadd231ss, vfnmsub..., vfmaddsub...), AArch64 (fmadd, fmsub,
# fnmadd, fnmsub, fmla, fmls), ARMv7 VFPv4 (vfma, vfms, vfnma, vfnms), RISC-V (fmadd.s, fnmsub.s ...).
# Not matched: ARM VFP vmla/vmls/vnmla (multiply then add with two roundings: exact, allowed).
FMA_RE = re.compile(r"^(?:v?fn?m(?:add|sub)\w*|vfn?m[as](?:\.\w+)?|fml[as])(?:\.\w+)?$", re.IGNORECASE)

HEAP_SYMBOLS = ("malloc", "calloc", "realloc", "free", "_sbrk", "_sbrk_r", "_malloc_r", "_free_r", "sbrk")
"""Symbols that mean a heap is linked."""
LIBM_ERRNO_SYMBOLS = ("sqrtf", "__errno", "_impure_ptr", "__ieee754_sqrtf")
"""Symbols that mean libm or errno got linked (the firmware needs neither)."""

_X86 = platform.machine().lower() in ("x86_64", "amd64")


class CrossError(RuntimeError):
    """A build or run failed."""


@dataclass(frozen=True)
class Target:
    """A CPU the firmware is built for and a way to run programs there."""

    name: str
    description: str
    cc: str
    cpu: tuple[str, ...] = ()
    """Code generation flags (CPU, FPU, ABI): every object of the target is compiled with them."""
    flags: tuple[str, ...] = ()
    """More flags for test programs (start-up, semihosting, specs, static linking), compile and link."""
    ldflags: tuple[str, ...] = ()
    harness: tuple[Path, ...] = ()
    """Sources linked into every test program of the target (start-up, semihosting)."""
    prefix: tuple[str, ...] = ()
    """Command prefix that runs a program of the target (emulator)."""
    objdump: str = "objdump"
    opts: tuple[str, ...] = ("-O2",)
    """Optimisation levels of the golden comparison."""
    max_streams: int = 0
    """Filters a run of the golden runner may hold at once (0: no limit): larger cases run in slices."""
    runs_with: tuple[str, ...] = ()
    """Programs the prefix needs besides itself (the emulator behind a script)."""

    @property
    def tools(self) -> tuple[str, ...]:
        """Programs the target needs."""
        return (self.cc, self.objdump, *self.prefix[:1], *self.runs_with)

    def missing(self) -> list[str]:
        """The tools of :attr:`tools` that are not installed."""
        return [t for t in self.tools if shutil.which(t) is None]

    def build(
        self,
        sources: Sequence[Path],
        opt: str = "-O2",
        name: str = "prog",
        out_dir: Path | None = None,
        extra: Sequence[str] = (),
    ) -> Path:
        """Build firmware + harness + ``sources`` into a program for this target; return its path."""
        if out_dir is None:
            out_dir = BUILD / f"{self.name}{opt}"
        try:
            return golden.build_program(
                [*sources, *self.harness],
                self.cc,
                opt,
                [*self.cpu, *self.flags, *extra],
                name,
                out_dir,
                ldflags=self.ldflags,
            )
        except golden.GoldenError as e:
            raise CrossError(str(e)) from e

    def runner(self, opt: str = "-O2", out_dir: Path | None = None) -> Path:
        """The golden runner (tests/c/att_golden.c) built for this target."""
        return self.build([golden.RUNNER_SOURCE], opt, "att_golden", out_dir)


def cortex_m_target(board: CortexM, opts: tuple[str, ...] = ("-O2",)) -> Target:
    """The Target of a Cortex-M board: arm-none-eabi-gcc, our start-up, semihosting, QEMU."""
    return Target(
        board.name,
        f"{board.core}, arm-none-eabi-gcc {' '.join(board.cpu)}, qemu-system-arm -M {board.machine} "
        "(semihosting)",
        "arm-none-eabi-gcc",
        board.cpu,
        board.image_flags,
        board.ldflags,
        PORT_SOURCES,
        board.prefix,
        "arm-none-eabi-objdump",
        opts,
        board.max_streams,
        ("qemu-system-arm",),
    )


TARGETS: dict[str, Target] = {
    "m4f": cortex_m_target(BOARDS["m4f"], ("-O2", "-Os")),
    "m7": cortex_m_target(BOARDS["m7"]),
    "m33": cortex_m_target(BOARDS["m33"]),
    "m0plus": cortex_m_target(BOARDS["m0plus"]),
    "aarch64": Target(
        "aarch64",
        "AArch64, aarch64-linux-gnu-gcc -static, qemu-aarch64-static",
        "aarch64-linux-gnu-gcc",
        (),
        ("-static",),
        ("-lm",),
        (),
        ("qemu-aarch64-static",),
        "aarch64-linux-gnu-objdump",
        ("-O2",),
    ),
    "riscv64": Target(
        "riscv64",
        "RISC-V RV64GC, riscv64-linux-gnu-gcc -static, qemu-riscv64-static",
        "riscv64-linux-gnu-gcc",
        (),
        ("-static",),
        ("-lm",),
        (),
        ("qemu-riscv64-static",),
        "riscv64-linux-gnu-objdump",
        ("-O2",),
    ),
    "x86_64-gcc": Target("x86_64-gcc", "x86-64, gcc, native", "gcc", ldflags=("-lm",)),
    "x86_64-clang": Target("x86_64-clang", "x86-64, clang, native", "clang", ldflags=("-lm",)),
}
"""Every target, by name."""

CROSS_TARGETS = ("m4f", "m7", "m33", "m0plus", "aarch64", "riscv64")
NATIVE_TARGETS = ("x86_64-gcc", "x86_64-clang") if _X86 else ()

SYSTEM_PACKAGES = {
    "arm-none-eabi-gcc": "gcc-arm-none-eabi",
    "qemu-system-arm": "qemu-system-arm",
    "qemu-aarch64-static": "qemu-user-static",
    "qemu-riscv64-static": "qemu-user-static",
    "aarch64-linux-gnu-gcc": "gcc-aarch64-linux-gnu",
    "riscv64-linux-gnu-gcc": "gcc-riscv64-linux-gnu",
    "cmake": "cmake",
    "valgrind": "valgrind",
}
"""Debian package of each tool (host/tools/install-system-deps.sh installs them)."""


def install_hint(tools: Iterable[str]) -> str:
    """``name (package)`` for each tool, for skip messages."""
    return ", ".join(f"{t} (Debian package {SYSTEM_PACKAGES.get(t, t)})" for t in tools)


# --- FMA detection -------------------------------------------------------------------------------


def fma_instructions(obj: Path, objdump: str = "objdump") -> list[str]:
    """Disassembly lines of ``obj`` whose mnemonic is a fused multiply-add (``objdump -d``)."""
    dump = subprocess.run(
        [objdump, "-d", "--no-show-raw-insn", str(obj)], capture_output=True, text=True, check=True
    ).stdout
    hits = []
    func = "?"
    for line in dump.splitlines():
        m = re.match(r"^[0-9a-f]+ <(.+)>:$", line)
        if m:
            func = m.group(1)
            continue
        parts = line.split("\t")
        if len(parts) >= 2 and parts[0].strip().endswith(":"):
            words = parts[1].split()
            if words and FMA_RE.match(words[0]):
                hits.append(f"{obj.name} <{func}>: {parts[1].strip()} {' '.join(parts[2:]).strip()}")
    return hits


def compile_object(target: Target, src: Path, obj: Path, opt: str, extra: Sequence[str] = ()) -> None:
    """Compile one firmware source for ``target`` with the firmware flags (no link)."""
    cmd = [
        target.cc,
        *_build.cflags(),
        opt,
        *target.cpu,
        *extra,
        "-I",
        str(_build.INCLUDE),
        "-c",
        str(src),
        "-o",
        str(obj),
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0 or proc.stderr.strip():
        raise CrossError(f"{' '.join(cmd)}\n{proc.stderr}")


# --- golden cases ----------------------------------------------------------------------------------

Imu = tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]


@dataclass
class FilterCase:
    """One filter configuration over (steps, streams) inputs."""

    name: str
    kind: FilterKind
    settings: Any
    imu: Imu
    source: str
    """``synthetic`` or ``broad``."""
    calibration: Any = None
    """Input/output stages (StageSettings; None: none)."""

    @property
    def steps(self) -> int:
        """Filter steps in the case (steps x streams)."""
        return int(self.imu[0].shape[0] * self.imu[0].shape[1])


SYNTH_STEPS = 500
SYNTH_STREAMS = 200
BROAD_CHUNK = 1250
"""Samples per BROAD stream: every recording is cut into chunks of this length."""
BROAD_CHUNKS_PER_TRIAL = 4
MATH_ROWS = 100_000

VARIANTS: dict[str, tuple[FilterKind, dict[str, Any]]] = {
    "ars-euler-running": (
        FilterKind.ARS,
        {"integration": 1, "bias_mode": 2, "accel_reject": 0.2, "tau": 0.5, "gain": 0.0},
    ),
    "ars-frozen-noinit": (
        FilterKind.ARS,
        {
            "bias_mode": 1,
            "bias_init": (0.01, -0.02, 0.005),
            "init_from_accel": False,
            "q_init": (0.9, 0.1, -0.3, 0.2),
        },
    ),
    "mars-full": (FilterKind.MARS, {"mag_mode": 1}),
    "kf-gate-adaptive": (FilterKind.KF, {"gate": 20.0, "r_accel": 50.0, "accel_reject": 0.5, "bias_mode": 2}),
    "tilt-no-normalise": (FilterKind.TILT, {"normalise": False}),
    "mekf-6axis": (FilterKind.MEKF, {"use_mag": False}),
    "mekf-raw-gated": (
        FilterKind.MEKF,
        {
            "tau_acc_lp": 0.0,
            "gate": 9.0,
            "gate_recover": 0.3,
            "mag_gate": 6.0,
            "r_accel": 30.0,
            "accel_reject": 0.5,
        },
    ),
    "mekf-noinit": (
        FilterKind.MEKF,
        {"init_from_sensors": False, "q_init": (0.3, 0.9, -0.2, 0.1), "m0_init": (0.0, 20.0, -40.0)},
    ),
    "mekf-scale": (FilterKind.MEKF, {"use_mag": False, "gyro_scale_sd": 0.05, "gyro_scale_init": 0.02}),
}
"""Non-default settings compared besides the defaults of every kind (synthetic inputs)."""


def synthetic_cases(
    steps: int = SYNTH_STEPS, streams: int = SYNTH_STREAMS, seed: int = 11
) -> list[FilterCase]:
    """Defaults of every implemented kind and :data:`VARIANTS` on golden.imu_inputs (adversarial)."""
    imu = golden.imu_inputs(steps, streams, seed=seed)
    cases = [
        FilterCase(f"{k.label}-default", k, make_settings(k), imu, "synthetic") for k in implemented_kinds()
    ]
    for name, (kind, overrides) in VARIANTS.items():
        if kind in implemented_kinds():
            cases.append(FilterCase(name, kind, make_settings(kind, **overrides), imu, "synthetic"))
    for name, (kind, cal) in calibrated_variants().items():
        if kind in implemented_kinds():
            cases.append(FilterCase(name, kind, make_settings(kind), imu, "synthetic", cal))
    return cases


def calibrated_variants() -> dict[str, tuple[FilterKind, Any]]:
    """Kinds with non-identity input/output stages (att_calib.h) for the golden comparison."""
    from attica.calibration.stages import StageSettings

    m = (1.02, 0.013, -0.021, -0.017, 0.985, 0.006, 0.011, -0.024, 1.031)
    model: dict[str, Any] = {
        "gyro_misalignment": m,
        "gyro_sensitivity": (1.01, 0.99, 1.003),
        "gyro_offset": (0.01, -0.02, 0.004),
        "accel_misalignment": m[::-1],
        "accel_sensitivity": (0.98, 1.02, 1.0),
        "accel_offset": (0.2, -0.1, 0.05),
        "soft_iron": (1.1, 0.05, -0.02, 0.05, 0.92, 0.01, -0.02, 0.01, 1.05),
        "hard_iron": (12.0, -7.5, 30.0),
        "accel_outputs": True,
    }
    q4 = np.array([0.8775826, 0.2397127, -0.3595691, 0.1917702])
    q = tuple(float(v) for v in q4 / np.linalg.norm(q4))  # a mounting quaternion, unit
    return {
        "ars-calib-ned-quat": (FilterKind.ARS, StageSettings(**model, mounting=q, convention=1)),
        "mars-calib-nwu-remap": (FilterKind.MARS, StageSettings(**model, remap=14, convention=2)),
        "kf-calib-remap-only": (FilterKind.KF, StageSettings(remap=9)),
        "ekf-calib-ned-quat": (FilterKind.EKF, StageSettings(**model, mounting=q, convention=1)),
    }


def broad_files(directory: Path = BROAD) -> list[Path]:
    """The BROAD .npz recordings (empty when absent)."""
    return sorted(directory.glob("*.npz")) if directory.is_dir() else []


def broad_imu(
    files: Sequence[Path], chunk: int = BROAD_CHUNK, per_trial: int = BROAD_CHUNKS_PER_TRIAL
) -> Imu:
    """``per_trial`` chunks of ``chunk`` samples spread over each recording, as (chunk, streams, 3)."""
    from attica.data import load_recording

    parts: list[list[NDArray[np.float32]]] = [[], [], []]
    for path in files:
        rec = load_recording(path)
        n = len(rec.gyr)
        if n < chunk:
            continue
        starts = np.linspace(0, n - chunk, per_trial).astype(int)
        for s in starts:
            for i, arr in enumerate((rec.gyr, rec.acc, rec.mag)):
                parts[i].append(np.asarray(arr[s : s + chunk], np.float32))
    if not parts[0]:
        raise CrossError(f"no BROAD recording has {chunk} samples")
    g, a, m = (np.ascontiguousarray(np.stack(p, axis=1)) for p in parts)
    return g, a, m


def broad_cases(files: Sequence[Path]) -> list[FilterCase]:
    """Every implemented kind with its defaults at the BROAD rate over real recordings."""
    imu = broad_imu(files)
    return [
        FilterCase(f"{k.label}-broad", k, make_settings(k, dt=1.0 / BROAD_RATE), imu, "broad")
        for k in implemented_kinds()
    ]


def reference_case(case: FilterCase) -> NDArray[np.void]:
    """The numpy reference outputs of one case, (steps, streams) records."""
    return golden.reference_filter(case.kind, case.settings, *case.imu, calibration=case.calibration)


def reference_outputs(cases: Sequence[FilterCase], jobs: int = 0) -> dict[str, NDArray[np.void]]:
    """The numpy reference of every case (in ``jobs`` worker processes; 0 = one per CPU)."""
    jobs = jobs or max(1, os.cpu_count() or 1)
    order = sorted(cases, key=lambda c: -c.imu[0].shape[0] * REFERENCE_COST.get(c.kind.label, 5))
    if jobs == 1:
        return {c.name: reference_case(c) for c in order}
    import multiprocessing as mp

    with ProcessPoolExecutor(jobs, mp_context=mp.get_context("fork")) as pool:
        futures = {c.name: pool.submit(reference_case, c) for c in order}
        return {name: f.result() for name, f in futures.items()}


REFERENCE_COST = {"mekf": 14, "kf": 9, "mars": 7, "ekf": 6, "ars": 4, "gyro": 2, "tilt": 1}
"""Rough reference cost per step of each kind (ms per step of all streams), for scheduling."""


@dataclass
class MathData:
    """Inputs (rows and files) and reference outputs of every math function of the runner."""

    rows: dict[str, NDArray[np.float32]]
    files: dict[str, Path]
    want: dict[str, NDArray[np.float32]]


def math_data(workdir: Path, rows: int = MATH_ROWS, seed: int = 20240611) -> MathData:
    """golden.math_inputs of every function, written once, with their reference outputs."""
    data = MathData({}, {}, {})
    for fn in golden.MATH_FUNCS:
        data.rows[fn] = golden.math_inputs(fn, rows, seed=seed)
        data.files[fn] = workdir / f"{fn}.in.bin"
        golden.write_table(data.files[fn], data.rows[fn], fn)
        data.want[fn] = golden.reference_math(fn, data.rows[fn])
    return data


@dataclass
class Result:
    """Outcome of one comparison: steps or rows compared and how many differ."""

    what: str
    compared: int
    differ: int
    detail: str = ""
    seconds: float = 0.0

    @property
    def ok(self) -> bool:
        """All identical."""
        return self.differ == 0 and self.compared > 0


def compare_math(
    runner: Path, prefix: Sequence[str], data: MathData, workdir: Path, jobs: int = 0
) -> list[Result]:
    """Every math function of the runner against the reference (bits, NaN == NaN), ``jobs`` at a time."""

    def one(fn: str) -> Result:
        t0 = time.perf_counter()
        got = golden.run_math(runner, fn, None, prefix=prefix, workdir=workdir, in_file=data.files[fn])
        want = data.want[fn]
        bad = np.nonzero(~golden.same_bits(got, want).all(axis=1))[0] if got.shape == want.shape else [0]
        detail = ""
        if len(bad):
            i = int(bad[0])
            detail = (
                f"first row {i}: in={golden.hex32(data.rows[fn][i])} got={golden.hex32(got[i])} "
                f"ref={golden.hex32(want[i])}"
            )
        return Result(f"math {fn}", want.shape[0], len(bad), detail, time.perf_counter() - t0)

    with ThreadPoolExecutor(jobs or _jobs()) as pool:
        return list(pool.map(one, golden.MATH_FUNCS))


def _jobs() -> int:
    return max(2, os.cpu_count() or 2)


def write_case_inputs(cases: Sequence[FilterCase], workdir: Path) -> dict[str, Path]:
    """One input file per distinct input set (cases share files when they share inputs)."""
    files: dict[str, Path] = {}
    by_id: dict[tuple[int, str], Path] = {}
    for c in cases:
        key = (id(c.imu[0]), c.kind.label)
        if key not in by_id:
            path = workdir / f"{c.source}-{c.kind.label}-{len(by_id)}.in.bin"
            golden.write_filter_input(path, c.kind, *c.imu)
            by_id[key] = path
        files[c.name] = by_id[key]
    return files


def run_case(
    runner: Path,
    prefix: Sequence[str],
    case: FilterCase,
    in_file: Path | None,
    workdir: Path,
    max_streams: int = 0,
) -> NDArray[np.void]:
    """The runner's outputs of one case, (steps, streams) records; in slices of ``max_streams`` streams.

    ``in_file``: the case's inputs already written (None: written here).
    """
    streams = case.imu[0].shape[1]
    if not max_streams or streams <= max_streams:
        return golden.run_filter(
            runner,
            case.kind,
            case.settings,
            *case.imu,
            prefix=prefix,
            workdir=workdir,
            in_file=in_file,
            calibration=case.calibration,
        )
    parts = []
    for s0 in range(0, streams, max_streams):
        g, a, m = (np.ascontiguousarray(v[:, s0 : s0 + max_streams]) for v in case.imu)
        part_file = workdir / f"{case.name}.streams{s0}.in.bin"
        golden.write_filter_input(part_file, case.kind, g, a, m)
        parts.append(
            golden.run_filter(
                runner,
                case.kind,
                case.settings,
                g,
                a,
                m,
                prefix=prefix,
                workdir=workdir,
                in_file=part_file,
                calibration=case.calibration,
            )
        )
        part_file.unlink()
    return np.concatenate(parts, axis=1)


def compare_filters(
    runner: Path,
    prefix: Sequence[str],
    cases: Sequence[FilterCase],
    want: dict[str, NDArray[np.void]],
    files: dict[str, Path],
    workdir: Path,
    jobs: int = 0,
    max_streams: int = 0,
    streams: int = 0,
) -> list[Result]:
    """Every case through the runner against its reference output (every field of every step).

    Cases run ``jobs`` at a time (0: one per CPU), each in its own sub-directory of ``workdir``. With
    ``max_streams``, a case with more streams runs in slices of at most that many (one runner call
    each, for targets whose RAM holds few filters) and the outputs are put back together. With
    ``streams``, only the first ``streams`` streams of every case are compared (a bounded slice for
    slow emulated targets; ``make cross`` compares all).
    """

    def one(c: FilterCase) -> Result:
        t0 = time.perf_counter()
        wd = workdir / c.name
        wd.mkdir(parents=True, exist_ok=True)
        ref = want[c.name]
        in_file: Path | None = files[c.name]
        if streams and streams < c.imu[0].shape[1]:
            g, a, m = (np.ascontiguousarray(v[:, :streams]) for v in c.imu)
            c = FilterCase(c.name, c.kind, c.settings, (g, a, m), c.source, c.calibration)
            ref = ref[:, :streams]
            in_file = None
        got = run_case(runner, prefix, c, in_file, wd, max_streams)
        ok = golden.same_outputs(got, ref) if got.shape == ref.shape else np.zeros(ref.shape, bool)
        detail = ""
        if not ok.all():
            bad = np.argwhere(~ok)
            step, stream = (int(v) for v in bad[np.argmin(bad[:, 0])])
            inputs = " ".join(
                f"{n}={golden.hex32(v[step, stream])}"
                for n, v in zip(("gyr", "acc", "mag"), c.imu, strict=True)
            )
            detail = (
                f"first at step {step} of stream {stream}: {inputs}\n  got: {got[step, stream]}\n"
                f"  ref: {ref[step, stream]}"
            )
        return Result(c.name, int(ok.size), int((~ok).sum()), detail, time.perf_counter() - t0)

    with ThreadPoolExecutor(jobs or _jobs()) as pool:
        return list(pool.map(one, cases))


# --- Cortex-M4F firmware build -----------------------------------------------------------------------


@dataclass
class M4fBuild:
    """Outputs of :func:`build_firmware`."""

    out_dir: Path
    objects: dict[str, list[Path]] = field(default_factory=dict)
    """Library objects per optimisation level (with .su and .ci files next to them)."""
    libraries: dict[str, Path] = field(default_factory=dict)
    images: dict[str, Path] = field(default_factory=dict)


M4F_LIB_OPTS = ("-Os", "-O2")


def library_objects(
    opt: str, out_dir: Path, cc: str = "arm-none-eabi-gcc", board: str = "m4f", defines: Sequence[str] = ()
) -> list[Path]:
    """Compile the firmware sources for a Cortex-M board as a library would be (stack gate on).

    Flags: the firmware flags, ``opt``, the board's CPU flags, ``-ffunction-sections -fdata-sections``
    (so images keep only what they use), ``-Wstack-usage=M4F_STACK_LIMIT`` (an error with -Werror)
    and ``-fstack-usage -fcallgraph-info=su`` (.su and .ci files for the stack analysis); then
    ``defines`` (a build configuration of att_config.h, e.g. ``-DATT_WITH_EKF=0``).
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    target = Target(board, "", cc, BOARDS[board].cpu)
    extra = [
        *M4F_SECTIONS,
        f"-Wstack-usage={M4F_STACK_LIMIT}",
        "-fstack-usage",
        "-fcallgraph-info=su",
        *defines,
    ]
    objs = [out_dir / (src.stem + ".o") for src in _build.firmware_sources()]
    with ThreadPoolExecutor(max(2, os.cpu_count() or 2)) as pool:
        list(
            pool.map(
                lambda so: compile_object(target, so[0], so[1], opt, extra),
                zip(_build.firmware_sources(), objs, strict=True),
            )
        )
    return objs


def archive(objs: Sequence[Path], lib: Path, ar: str = "arm-none-eabi-ar") -> Path:
    """``ar rcs lib objs`` (replacing lib)."""
    lib.unlink(missing_ok=True)
    subprocess.run([ar, "rcs", str(lib), *map(str, objs)], check=True, capture_output=True)
    return lib


def build_firmware(out_dir: Path | None = None, verbose: bool = True) -> M4fBuild:
    """``make firmware``: the Cortex-M4F library at -Os and -O2 and the test images.

    build/firmware/m4f/: obj-Os/, obj-O2/ (objects, .su, .ci), libattica-Os.a, libattica-O2.a,
    att_golden.elf (golden runner), att_bench.elf (instruction counts), att_m4f_stack.elf (stack
    high-water marks), att_m4f_fpenv.elf (floating-point environment check).
    """
    out_dir = out_dir or (ROOT / "build" / "firmware" / "m4f")
    target = TARGETS["m4f"]
    missing = target.missing()
    if missing:
        raise CrossError(f"missing tools: {install_hint(missing)}")
    b = M4fBuild(out_dir)
    for opt in M4F_LIB_OPTS:
        b.objects[opt] = library_objects(opt, out_dir / f"obj{opt}")
        b.libraries[opt] = archive(b.objects[opt], out_dir / f"libattica{opt}.a")
    b.images["att_golden"] = target.build([golden.RUNNER_SOURCE], "-O2", "att_golden.elf", out_dir)
    b.images["att_bench"] = target.build([TESTS_C / "att_bench.c"], "-O2", "att_bench.elf", out_dir)
    b.images["att_m4f_stack"] = target.build(
        [TESTS_C / "att_m4f_stack.c"], "-O2", "att_m4f_stack.elf", out_dir
    )
    b.images["att_m4f_fpenv"] = target.build(
        [TESTS_C / "att_m4f_fpenv.c"], "-O2", "att_m4f_fpenv.elf", out_dir
    )
    if verbose:
        for opt, lib in b.libraries.items():
            print(
                f"{lib.relative_to(ROOT)}  ({len(b.objects[opt])} objects, -Wstack-usage={M4F_STACK_LIMIT})"
            )
        for img in b.images.values():
            print(f"{img.relative_to(ROOT)}")
    return b


def run_checked(cmd: Sequence[str], timeout: float = 120.0) -> str:
    """Run a command, return stdout; CrossError with stderr on a non-zero exit."""
    proc = subprocess.run(
        list(cmd), capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL
    )
    if proc.returncode != 0:
        raise CrossError(f"{' '.join(cmd)} exited with {proc.returncode}:\n{proc.stdout}\n{proc.stderr}")
    return proc.stdout


# --- command line ----------------------------------------------------------------------------------


def _table(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h) for i, h in enumerate(headers)]
    fmt = [
        "  ".join(
            c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths, strict=True))
        )
        for r in [list(headers), ["-" * w for w in widths], *rows]
    ]
    return "\n".join(fmt)


def compare_all(
    targets: Sequence[str],
    with_broad: bool = True,
    jobs: int = 0,
    out: Any = sys.stdout,
    opts: Sequence[str] = (),
) -> dict[str, list[Result]]:
    """Build every target's runner, compare it with the reference, print a table; results by config."""
    jobs = jobs or max(2, os.cpu_count() or 2)
    cases = synthetic_cases()
    files_broad = broad_files() if with_broad else []
    if files_broad:
        cases += broad_cases(files_broad)
    elif with_broad:
        print(f"note: BROAD data not found at {BROAD}: synthetic inputs only", file=out)
    results: dict[str, list[Result]] = {}
    with tempfile.TemporaryDirectory(prefix="att_cross_") as tmp:
        wd = Path(tmp)
        t0 = time.perf_counter()
        import multiprocessing as mp

        with ProcessPoolExecutor(jobs, mp_context=mp.get_context("fork")) as pool:
            ref_jobs = {c.name: pool.submit(reference_case, c) for c in cases}
            files = write_case_inputs(cases, wd)
            mdata = math_data(wd)
            configs = [
                (TARGETS[t], opt)
                for t in targets
                if not TARGETS[t].missing()
                for opt in (opts or TARGETS[t].opts)
            ]
            for t in targets:
                if TARGETS[t].missing():
                    print(f"note: {t} skipped, missing {install_hint(TARGETS[t].missing())}", file=out)
            with ThreadPoolExecutor(jobs) as tp:
                runners = dict(
                    zip(configs, tp.map(lambda c: c[0].runner(c[1], wd / f"{c[0].name}{c[1]}"), configs))
                )
            want = {name: f.result() for name, f in ref_jobs.items()}
        print(f"inputs, references and builds: {time.perf_counter() - t0:.1f} s", file=out)

        def one(cfg: tuple[Target, str]) -> tuple[str, list[Result]]:
            t, opt = cfg
            sub = wd / f"run-{t.name}{opt}"
            sub.mkdir()
            res = compare_math(runners[cfg], t.prefix, mdata, sub)
            res += compare_filters(runners[cfg], t.prefix, cases, want, files, sub, max_streams=t.max_streams)
            return f"{t.name} {opt}", res

        with ThreadPoolExecutor(jobs) as tp:
            results = dict(tp.map(one, configs))
    names = [c.name for c in cases]
    headers = ["case", "steps", *results]
    rows = []
    for name in names:
        cells = []
        n = 0
        for res in results.values():
            r = next(r for r in res if r.what == name)
            n = r.compared
            cells.append("identical" if r.ok else f"{r.differ} differ")
        rows.append([name, str(n), *cells])
    math_rows = (
        sum(r.compared for r in next(iter(results.values())) if r.what.startswith("math")) if results else 0
    )
    cells = []
    for res in results.values():
        bad = [r for r in res if r.what.startswith("math") and not r.ok]
        cells.append("identical" if not bad else f"{len(bad)} fns differ")
    rows.append([f"math ({len(golden.MATH_FUNCS)} fns)", str(math_rows), *cells])
    print(_table(headers, rows), file=out)
    for cfg, res in results.items():
        for r in res:
            if not r.ok:
                print(f"{cfg}: {r.what}: {r.differ} of {r.compared} differ; {r.detail}", file=out)
    return results


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m attica_dev.cross [golden|firmware]``."""
    p = argparse.ArgumentParser(
        prog="python -m attica_dev.cross", description=__doc__.split("\n")[0] if __doc__ else ""
    )
    p.add_argument("what", nargs="?", default="golden", choices=["golden", "firmware"])
    p.add_argument("--targets", default=",".join((*CROSS_TARGETS, *NATIVE_TARGETS)), help="comma-separated")
    p.add_argument("--no-broad", action="store_true", help="synthetic inputs only")
    p.add_argument("--opts", default="", help="comma-separated optimisation levels for every target")
    args = p.parse_args(argv)
    if args.what == "firmware":
        try:
            build_firmware()
        except CrossError as e:
            print(f"make firmware: {e}", file=sys.stderr)
            return 1
        return 0
    opts = tuple(o for o in args.opts.split(",") if o)
    results = compare_all([t for t in args.targets.split(",") if t], with_broad=not args.no_broad, opts=opts)
    return 0 if results and all(r.ok for res in results.values() for r in res) else 1


if __name__ == "__main__":
    sys.exit(main())
