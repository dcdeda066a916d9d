"""Host benchmarks of the filters beside the peers: ``python -m attica_dev.bench`` (``make bench``).

Prints, per filter of :data:`FILTERS` and per peer configuration (Fusion 6/9-axis, VQF 6D/9D):

- ns/step through Python, in one run: attica's native batch runs, both the full output record per
  step (:meth:`attica.native.Filter.run`) and the lean path that returns only the quaternions
  (:meth:`attica.native.Filter.run_q`), firmware built with the strict flags at -O2, each with its
  default unit check; VQF's ``updateBatch`` (the vqf package from PyPI:
  its C++ in double precision, a batch loop in C++) and imufusion (PyPI: Fusion's C, one
  ``update`` call per sample from Python, since it has no batch call), all over the same simulated
  samples, best of several repeats;
- instructions/step counted by valgrind's callgrind in ``att_filter_step`` (and everything it calls)
  of tests/c/att_bench.c, and in ``att_peer_step`` of the peers' drivers built from their sdists
  (:mod:`attica_dev.peer_sources`, VQF in single precision), as (I(N2) - I(N1)) / (N2 - N1) so
  start-up and initialisation cancel;
- the ratios attica / peer of both (ns/step for the full and the lean run), for the filters with the
  same inputs, and the issue-9 host goal: the ARS through ``run_q`` at >= 10 M steps/s and faster
  than VQF 6D ``updateBatch`` in the same run;

and the .text size of every firmware object at -O2 and -Os. Numbers only, no pass/fail.
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica import _build
from attica.kinds import labels
from attica_dev import bench_live, golden

BENCH_SOURCE = golden.ROOT / "tests" / "c" / "att_bench.c"


@dataclass(frozen=True)
class BenchCase:
    """One row of the benchmark table: a filter kind with settings overrides."""

    label: str
    kind: str
    overrides: dict[str, Any] = field(default_factory=dict)


FILTERS: list[BenchCase] = [BenchCase(label, label) for label in labels()]
"""Filters to benchmark, one line each: every kind of :mod:`attica.kinds` with its defaults. att_bench
runs a kind with its default settings, so cases with ``overrides`` get only the native timing (the
callgrind columns say n/a)."""

CALLGRIND_CONFIGS: list[tuple[str, str]] = [("gcc", "-O2"), ("clang", "-O2")]
"""(compiler, optimisation) builds of att_bench measured with callgrind."""

SIZE_OPTS = ["-O2", "-Os"]


def simulated_inputs(
    samples: int, rate: float = 100.0
) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]:
    """Gyro, accel and mag (samples, 3) from :mod:`attica.sim` (golden.imu_inputs as a fallback)."""
    try:
        from attica.sim import SimConfig, simulate

        rec = simulate(SimConfig(duration=samples / rate, rate=rate, seed=1))
        gyr = np.ascontiguousarray(rec.gyr[:samples], np.float32)
        acc = np.ascontiguousarray(rec.acc[:samples], np.float32)
        mag = np.ascontiguousarray(rec.mag[:samples], np.float32)
        if gyr.shape == acc.shape == mag.shape == (samples, 3):
            return gyr, acc, mag
    except Exception as e:  # noqa: BLE001 - the simulator is optional for the benchmark
        print(f"note: attica.sim unavailable ({e}); using golden.imu_inputs", file=sys.stderr)
    g, a, m = golden.imu_inputs(samples, 1, seed=1, dt=1.0 / rate)
    return np.ascontiguousarray(g[:, 0]), np.ascontiguousarray(a[:, 0]), np.ascontiguousarray(m[:, 0])


Imu = tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]


CLOCKS: dict[str, Callable[[], float]] = {"wall": time.perf_counter, "cpu": time.process_time}
"""Timers of ``--clock``: wall time (what a user waits; the default), or the process's CPU time, which
leaves out the time the process waits for a core on a shared machine (every timed call is
single-threaded, attica's and the peers' alike)."""


def chunk_slices(n: int, chunk: int) -> list[slice]:
    """The timed calls of a repeat over n samples.

    One call over all (``chunk`` <= 0 or >= n), or consecutive calls over ``chunk`` samples each (a
    shorter tail is left out), the state carried on from call to call.
    """
    if chunk <= 0 or chunk >= n:
        return [slice(0, n)]
    return [slice(i, i + chunk) for i in range(0, n - chunk + 1, chunk)]


def native_ns_per_step(
    case: BenchCase,
    imu: Imu,
    repeat: int,
    dt: float = 0.01,
    clock: Callable[[], float] = time.perf_counter,
    chunk: int = 0,
) -> tuple[float, float]:
    """Best ns per step of the native batch runs over ``repeat`` repeats: (full records, lean q).

    ``Filter.run`` (the whole att_filter_output record per step, the default) and ``Filter.run_q``
    (quaternions only) alternate call by call, so that both see the same machine load; each repeat
    starts from new filters, and every call checks the units and allocates its outputs, as a user's
    call does. ``clock``: see :data:`CLOCKS`; ``chunk``: see :func:`chunk_slices` (the best call counts).
    """
    from attica import native

    best_full = best_lean = float("inf")
    for _ in range(repeat):
        full = native.Filter(case.kind, dt=dt, **case.overrides)
        lean = native.Filter(case.kind, dt=dt, **case.overrides)
        for sl in chunk_slices(imu[0].shape[0], chunk):
            g, a, m = (x[sl] for x in imu)
            steps = g.shape[0]
            t0 = clock()
            full.run(g, a, m)
            best_full = min(best_full, (clock() - t0) / steps)
            t0 = clock()
            lean.run_q(g, a, m)
            best_lean = min(best_lean, (clock() - t0) / steps)
    return float(best_full * 1e9), float(best_lean * 1e9)


def rate_cell(ns: float | None) -> str:
    """M steps/s of a ns/step figure ("n/a" when there is none)."""
    return "n/a" if ns is None or ns <= 0 else f"{1e3 / ns:.2f}"


HOST_GOAL_STEPS_PER_S = 10e6
"""Issue 9, host part: the ARS through the batch binding (``run_q``) at >= 10 M steps/s ..."""
HOST_GOAL_PEER = "vqf6"
"""... and faster than VQF 6D ``updateBatch`` in the same run."""


def host_goal_line(lean: dict[str, float | None], ns: dict[str, float | None]) -> str:
    """The issue-9 host goal for the ARS, judged on this run's figures."""
    ars = lean.get("ars")
    peer = ns.get(HOST_GOAL_PEER)
    if ars is None:
        return "goal ars run_q >= 10 M steps/s and < vqf6 updateBatch: not measured"
    rate = 1e9 / ars
    parts = [
        f"{rate / 1e6:.2f} M steps/s ({ars:.1f} ns/step): "
        + ("met" if rate >= HOST_GOAL_STEPS_PER_S else "missed")
    ]
    if peer is None:
        parts.append("vqf6 not measured")
    else:
        parts.append(
            f"{ars / peer:.2f} x vqf6 updateBatch ({peer:.1f} ns/step): "
            + ("met" if ars < peer else "missed")
        )
    return "goal ars run_q >= 10 M steps/s and faster than vqf6 updateBatch: " + "; ".join(parts)


PEER_HOST: dict[str, str] = {
    "vqf6": "vqf VQF.updateBatch(gyr, acc), double",
    "vqf9": "vqf VQF.updateBatch(gyr, acc, mag), double",
    "fusion6": "imufusion Ahrs.update_no_magnetometer per sample",
    "fusion9": "imufusion Ahrs.update per sample",
}
"""How each peer configuration is timed through its PyPI binding."""

FUSION_SAMPLES = 20_000
"""Samples of the imufusion timing (a Python call per sample: the first ones of the same inputs)."""


def peer_ns_per_step(
    name: str,
    imu: Imu,
    repeat: int,
    dt: float = 0.01,
    clock: Callable[[], float] = time.perf_counter,
    chunk: int = 0,
) -> float:
    """Best ns per step of a peer through its Python binding over ``repeat`` repeats.

    ImportError when the package is missing. ``clock``: see :data:`CLOCKS`; ``chunk``: see
    :func:`chunk_slices` (VQF's ``updateBatch`` only: imufusion is called once per sample anyway).
    """
    g, a, m = (np.ascontiguousarray(v, np.float64) for v in imu)
    best = float("inf")
    if name.startswith("vqf"):
        import vqf

        for _ in range(repeat):
            est = vqf.VQF(dt)
            for sl in chunk_slices(g.shape[0], chunk):
                gs, as_, ms = g[sl], a[sl], m[sl]
                t0 = clock()
                est.updateBatch(gs, as_, ms) if name == "vqf9" else est.updateBatch(gs, as_)
                best = min(best, (clock() - t0) / gs.shape[0])
        return float(best * 1e9)
    import imufusion

    n = min(FUSION_SAMPLES, g.shape[0])
    gd = np.ascontiguousarray(np.degrees(g[:n]))
    ag = np.ascontiguousarray(a[:n] / 9.80665)
    mu = np.ascontiguousarray(m[:n])
    for _ in range(repeat):
        settings = imufusion.AhrsSettings()
        settings.convention = imufusion.CONVENTION_ENU
        settings.sample_rate = 1.0 / dt
        ahrs = imufusion.Ahrs()
        ahrs.set_settings(settings)
        t0 = clock()
        if name == "fusion9":
            for i in range(n):
                ahrs.update(gd[i], ag[i], mu[i])
                ahrs.get_quaternion()
        else:
            for i in range(n):
                ahrs.update_no_magnetometer(gd[i], ag[i])
                ahrs.get_quaternion()
        best = min(best, clock() - t0)
    return float(best / n * 1e9)


def callgrind_instructions(program: Path, kind: str, steps: int, function: str = "att_filter_step") -> int:
    """Instructions executed inside ``function`` (and its callees) for ``steps`` steps (callgrind)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "callgrind.out"
        proc = subprocess.run(
            [
                "valgrind",
                "--tool=callgrind",
                f"--callgrind-out-file={out}",
                f"--toggle-collect={function}",
                str(program),
                kind,
                str(steps),
            ],
            capture_output=True,
            text=True,
        )
    if proc.returncode != 0:
        raise RuntimeError(f"callgrind failed for {kind}: {proc.stderr.strip()[-500:]}")
    m = re.search(r"Collected\s*:\s*(\d+)", proc.stderr)
    if m is None:
        raise RuntimeError(f"no 'Collected' line in callgrind output:\n{proc.stderr[-500:]}")
    return int(m.group(1))


def instructions_per_step(
    program: Path, kind: str, n1: int = 2_000, n2: int = 12_000, function: str = "att_filter_step"
) -> float:
    """(I(n2) - I(n1)) / (n2 - n1) for ``function`` (att_filter_step; att_peer_step of a peer's driver)."""
    i1 = callgrind_instructions(program, kind, n1, function)
    i2 = callgrind_instructions(program, kind, n2, function)
    return (i2 - i1) / (n2 - n1)


def text_size(obj: Path) -> int:
    """Bytes in the .text sections of an object (``size -A``)."""
    out = subprocess.run(["size", "-A", str(obj)], capture_output=True, text=True, check=True).stdout
    total = 0
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 2 and (parts[0] == ".text" or parts[0].startswith(".text.")) and parts[1].isdigit():
            total += int(parts[1])
    return total


def object_sizes(cc: str, opts: Sequence[str], workdir: Path) -> dict[str, dict[str, int]]:
    """.text bytes per firmware source (stem) per optimisation level."""
    sizes: dict[str, dict[str, int]] = {}
    for opt in opts:
        for src in _build.firmware_sources():
            obj = workdir / f"{cc}{opt}-{src.stem}.o"
            cmd = [cc, *_build.cflags(), opt, "-I", str(_build.INCLUDE), "-c", str(src), "-o", str(obj)]
            subprocess.run(cmd, check=True, capture_output=True)
            sizes.setdefault(src.stem, {})[opt] = text_size(obj)
    return sizes


def peer_rows(
    imu: Imu,
    repeat: int,
    configs: Sequence[tuple[str, str]],
    out: Path,
    ns: dict[str, float | None],
    instr: dict[tuple[str, str], float | None],
    notes: list[str],
    clock: Callable[[], float] = time.perf_counter,
    chunk: int = 0,
) -> list[list[str]]:
    """The peers' rows (ns/step through their bindings, callgrind of their C); fills ``ns`` and ``instr``."""
    from attica_dev import peer_sources

    rows = []
    progs: dict[tuple[str, str], Path | str] = {}
    for name, (lib, kind) in peer_sources.KINDS.items():
        try:
            ns[name] = peer_ns_per_step(name, imu, repeat, clock=clock, chunk=chunk)
            cell = f"{ns[name]:.1f}"
        except ImportError as e:
            ns[name] = None
            cell = "n/a"
            notes.append(
                f"{name}: the Python package {lib.package} is not installed ({e}): pip install '.[peers]'"
            )
        row = [f"{name} ({lib.label} {kind.call})", cell, "-", rate_cell(ns[name])]
        for cc, opt in configs:
            key = (cc, lib.name)
            if key not in progs:
                try:
                    progs[key] = peer_sources.build(lib, peer_sources.host_toolchain(cc), opt, out).program
                except peer_sources.PeerUnavailableError as e:
                    progs[key] = str(e)
                    notes.append(f"{lib.name} with {cc}: {e}")
            prog = progs[key]
            if isinstance(prog, str):
                instr[(f"{cc} {opt}", name)] = None
                row.append("n/a")
                continue
            v = instructions_per_step(prog, name, function="att_peer_step")
            instr[(f"{cc} {opt}", name)] = v
            row.append(f"{v:.0f}")
        rows.append(row)
    return rows


def ratio_table(
    configs: Sequence[tuple[str, str]],
    ns: dict[str, float | None],
    instr: dict[tuple[str, str], float | None],
    lean: dict[str, float | None] | None = None,
) -> str:
    """Ratios attica / peer for the filters with the same inputs.

    ns/step of the full ``run`` (and of the lean ``run_q`` when ``lean`` is given) and callgrind
    instructions.
    """
    from attica_dev import cycles

    def r(a: float | None, b: float | None) -> str:
        return "n/a" if a is None or b is None or b == 0 else f"{a / b:.2f}"

    headers = ["attica / peer", "ns/step (Python)"]
    headers += ["ns/step run_q"] if lean is not None else []
    headers += [f"instr ({cc} {opt})" for cc, opt in configs]
    rows = []
    for a, p in cycles.pairs([*cycles.attica_rows(), *cycles.peer_rows()]):
        row = [f"{a.label} / {p.label}", r(ns.get(a.label), ns.get(p.label))]
        row += [r(lean.get(a.label), ns.get(p.label))] if lean is not None else []
        row += [
            r(instr.get((f"{cc} {opt}", a.label)), instr.get((f"{cc} {opt}", p.label))) for cc, opt in configs
        ]
        rows.append(row)
    return _table(headers, rows)


def _table(headers: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h) for i, h in enumerate(headers)]
    line = "  ".join(
        h.ljust(w) if i == 0 else h.rjust(w) for i, (h, w) in enumerate(zip(headers, widths, strict=True))
    )
    out = [line, "  ".join("-" * w for w in widths)]
    for r in rows:
        out.append(
            "  ".join(
                c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths, strict=True))
            )
        )
    return "\n".join(out)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmarks and print the tables."""
    p = argparse.ArgumentParser(
        prog="python -m attica_dev.bench", description=__doc__.split("\n")[0] if __doc__ else ""
    )
    p.add_argument("--samples", type=int, default=200_000, help="samples for the native timing (200000)")
    p.add_argument("--repeat", type=int, default=7, help="repeats of every timing, best taken (7)")
    p.add_argument("--no-peers", action="store_true", help="attica only")
    p.add_argument(
        "--clock",
        choices=sorted(CLOCKS),
        default="wall",
        help="wall time (default) or the process's CPU time (steadier on a shared machine)",
    )
    p.add_argument(
        "--chunk",
        type=int,
        default=0,
        help="time calls over consecutive chunks of this many samples and keep the best one (0: one "
        "call over all samples, the default); short calls are rarely preempted on a shared machine",
    )
    args = p.parse_args(argv)
    clock = CLOCKS[args.clock]
    calls = f"calls of {args.chunk} samples" if 0 < args.chunk < args.samples else "one call per repeat"

    imu = simulated_inputs(args.samples)
    have_valgrind = shutil.which("valgrind") is not None
    configs = [(cc, opt) for cc, opt in CALLGRIND_CONFIGS if shutil.which(cc)]
    programs: dict[tuple[str, str], Path] = {}
    with tempfile.TemporaryDirectory(prefix="att_bench_") as tmp:
        if have_valgrind:
            for cc, opt in configs:
                programs[(cc, opt)] = golden.build_program(
                    [BENCH_SOURCE], cc, opt, name="att_bench", out_dir=Path(tmp) / f"{cc}{opt}"
                )
        headers = ["filter", "ns/step (Python)", "ns/step run_q", "M steps/s"]
        if have_valgrind:
            headers += [f"instr/step ({cc} {opt})" for cc, opt in programs]
        rows = []
        ns: dict[str, float | None] = {}
        lean: dict[str, float | None] = {}
        instr: dict[tuple[str, str], float | None] = {}
        for case in FILTERS:
            full_ns, lean_ns = native_ns_per_step(case, imu, args.repeat, clock=clock, chunk=args.chunk)
            ns[case.label], lean[case.label] = full_ns, lean_ns
            row = [case.label, f"{full_ns:.1f}", f"{lean_ns:.1f}", rate_cell(lean_ns)]
            for (cc, opt), prog in programs.items():
                if case.overrides:
                    row.append("n/a")
                    continue
                try:
                    instr[(f"{cc} {opt}", case.label)] = instructions_per_step(prog, case.kind)
                    row.append(f"{instr[(f'{cc} {opt}', case.label)]:.0f}")
                except RuntimeError as e:
                    row.append("error")
                    print(f"note: {e}", file=sys.stderr)
            rows.append(row)
        notes: list[str] = []
        if not args.no_peers:
            rows += peer_rows(
                imu, args.repeat, list(programs), Path(tmp), ns, instr, notes, clock, args.chunk
            )
        print(
            f"Filters ({args.samples} simulated samples at 100 Hz, best of {args.repeat} repeats, {calls}, "
            f"{args.clock} clock; ns/step: attica "
            "native.Filter.run (batch in C, -O2, the full output record per step), ns/step run_q: "
            "native.Filter.run_q (the same steps, quaternions only), M steps/s: of run_q for attica, of the "
            "peer's call for the peers; peers through their PyPI bindings: "
            + "; ".join(f"{k}: {v}" for k, v in PEER_HOST.items())
            + f" (imufusion over the first {FUSION_SAMPLES} samples); callgrind: att_filter_step / "
            "att_peer_step and callees, default settings, (I(12000) - I(2000)) / 10000, peers from their "
            "sdists, VQF single precision)"
        )
        print(_table(headers, rows))
        if not args.no_peers:
            print()
            print("attica / peer, same run (< 1: attica faster or fewer instructions):")
            print(ratio_table(list(programs), ns, instr, lean))
            print()
            print(host_goal_line(lean, ns))
        for n in notes:
            print(f"note: {n}")
        if not args.no_peers:
            print()
            live = min(args.samples, 20_000)
            print(
                "\n".join(
                    bench_live.live_lines(imu[0][:live], imu[1][:live], imu[2][:live], 0.01, args.repeat)
                )
            )
        if not have_valgrind:
            print(
                "note: valgrind is not installed, so there is no instructions/step column "
                "(host/tools/install-system-deps.sh installs it)"
            )

        print()
        print("Firmware objects, .text bytes")
        size_rows: list[list[str]] = []
        size_headers = ["object"]
        per_cc: list[dict[str, dict[str, int]]] = []
        for cc in ("gcc", "clang"):
            if shutil.which(cc) is None:
                continue
            size_headers += [f"{cc} {opt}" for opt in SIZE_OPTS]
            per_cc.append(object_sizes(cc, SIZE_OPTS, Path(tmp)))
        stems = [s.stem for s in _build.firmware_sources()]
        for stem in stems:
            size_rows.append([stem + ".o", *[str(sz[stem][opt]) for sz in per_cc for opt in SIZE_OPTS]])
        size_rows.append(
            ["total", *[str(sum(sz[s][opt] for s in stems)) for sz in per_cc for opt in SIZE_OPTS]]
        )
        print(_table(size_headers, size_rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
