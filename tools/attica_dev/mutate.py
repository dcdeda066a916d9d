"""Mutation testing of firmware/src: which small wrong changes do the golden and bit-exact checks catch.

Each mutant is one change at one place of one firmware source (``file:line:column:operator``):

- ``AOR`` arithmetic ``+ <-> -``, ``* <-> /`` (and ``+= <-> -=``, ``*= <-> /=``);
- ``ROR`` comparisons ``< <-> <=``, ``> <-> >=``, ``== <-> !=``;
- ``LCR`` logic ``&& <-> ||``; ``NOT`` a ``!`` dropped;
- ``BIT`` bitwise ``& <-> |``, ``^ -> |``, ``<< <-> >>`` (and their assignments); ``INC`` ``++ <-> --``;
- ``CONST`` a literal changed: a float by one unit in the last place (its last hex digit + 1; 0 becomes
  1), an integer + 1; ``ZERO`` a non-zero integer literal replaced by 0;
- ``DEL`` an assignment statement deleted.

The sources are firmware/src/**/*.c and the private headers beside them (generated/ is left out);
comments, strings, preprocessor conditions and array sizes of declarations are never touched, but the
bodies of ``#define`` are (the constants and the settings tables live there). The set is ordered by
file, offset and operator, so ``--sample N --seed S`` picks the same mutants from the same sources.

The oracle is what the test suite compares bit for bit. The suite proves that the C library equals the
numpy reference on these inputs, so the outputs of the unmutated library are the reference outputs:

- stage A, the suite's own test programs, linked with the mutated objects: tests/c/att_golden.c over
  every math function (golden.math_inputs), every kind with its default and seed settings, the golden
  suite's variants and calibrated variants (attica_dev.cross) and a few edge settings on
  golden.imu_inputs, the digests' simulated and adversarial streams (mag absent, late, vertical or
  tiny too), jumps of the accel and mag away from the attitude, pitch sweeps through +-90 degrees and
  an exact flip; tests/c/att_node_run.c over the digests' node streams and a rough stream per kind
  (bad CRCs, gaps, duplicates, unknown IDs, wrong lengths, every command, more errors than 255);
  tests/c/att_config_test.c; tests/c/att_core_test.c (for math and core);
- stage B, for the mutants stage A leaves alive: the library linked as ``attica._native`` into a fresh
  Python process running every case of tests/digests.txt (step records, calibration stages with accel
  outputs, heading, retune, node frames), runs with step counts (att_filter_step_n), retunes in
  sequence, every output written into poisoned buffers and the NULL calls, the settings contracts
  (listings, presets and every field probed at and beyond its bounds) of every kind, the stages and
  the node, the stages folded and applied for every remap, the node with stages, accel outputs, the
  persistence and bus hooks and pushed samples, the CAN codec's encoders, checks and decoders, the
  sample checks and the name functions.

A mutant is *killed* when any output bit differs, a program crashes, exits otherwise or runs longer
than a few times the unmutated run; *stillborn* when it does not compile (the firmware flags include
-Werror); *equivalent* when the compiler makes exactly the unmutated object code of it (code the build
does not compile, such as the other branch of ``#if defined(__GNUC__)``, or a change the optimiser
undoes: no test can tell it apart); otherwise it *survived*. Stillborn and equivalent mutants are
counted apart. Score = killed / (killed + survived), overall and over the lines the test suite runs
(build/coverage/lines.json of ``make coverage``, when present). Survivors that cannot be killed are
listed with the reason in :data:`EXPLAINED`.

Only the mutated file is recompiled (or the sources including a mutated header); every other object
is built once per snapshot of the sources (build/mutation/base-<hash>). The checkout is never
written: the sources are copied first and mutated in private folders.

Usage::

    python -m attica_dev.mutate [--sample N] [--seed S] [--files GLOB] [--jobs J] [--list] [--json OUT]
    make mutation MUTATION_ARGS="--jobs 2"      # every mutant
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

# the parts, one module per job (tools/attica_dev/mutation/); re-exported: the tests, the docs and the
# command line below use them as mutate.NAME
from attica_dev.mutation.checks_filter import RETUNES as RETUNES
from attica_dev.mutation.config import CC as CC
from attica_dev.mutation.config import COVERAGE as COVERAGE
from attica_dev.mutation.config import OPT as OPT
from attica_dev.mutation.config import ROOT as ROOT
from attica_dev.mutation.config import WORK as WORK
from attica_dev.mutation.explained import EXPLAINED as EXPLAINED
from attica_dev.mutation.explained import OPEN as OPEN
from attica_dev.mutation.explained import Explained as Explained
from attica_dev.mutation.explained import explain as explain
from attica_dev.mutation.mutants import OPERATORS as OPERATORS
from attica_dev.mutation.mutants import Mutant as Mutant
from attica_dev.mutation.mutants import all_mutants as all_mutants
from attica_dev.mutation.mutants import mutants_of as mutants_of
from attica_dev.mutation.mutants import sample as sample
from attica_dev.mutation.mutants import source_files as source_files
from attica_dev.mutation.report import STATUSES as STATUSES
from attica_dev.mutation.report import _json
from attica_dev.mutation.report import report as report
from attica_dev.mutation.run import Job as Job
from attica_dev.mutation.run import Result as Result
from attica_dev.mutation.run import load_coverage as load_coverage
from attica_dev.mutation.run import run_mutants as run_mutants
from attica_dev.mutation.run import self_test as self_test
from attica_dev.mutation.run import self_test_mutants as self_test_mutants
from attica_dev.mutation.snapshot import Base as Base
from attica_dev.mutation.snapshot import Runner as Runner
from attica_dev.mutation.snapshot import _prepare
from attica_dev.mutation.stage_a import Case as Case
from attica_dev.mutation.stage_b import _binding_worker
from attica_dev.mutation.tokens import Token as Token
from attica_dev.mutation.tokens import tokenize as tokenize


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: list, sample and judge mutants; exit 1 for a survivor not explained nor a known gap."""
    args = list(sys.argv[1:] if argv is None else argv)
    if args[:1] == ["--binding-worker"]:
        return _binding_worker(*args[1:5])
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sample", type=int, default=0, help="judge N mutants drawn with --seed (0: all)")
    ap.add_argument("--seed", type=int, default=26)
    ap.add_argument(
        "--files", default="", help="fnmatch patterns of sources, comma-separated (firmware/src/math/*)"
    )
    ap.add_argument(
        "--ops", default=",".join(OPERATORS), help=f"operators (default all: {','.join(OPERATORS)})"
    )
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--list", action="store_true", help="list the mutants (after --sample) and stop")
    ap.add_argument("--json", type=Path, help="write the results as JSON")
    ap.add_argument("--no-binding", action="store_true", help="stage A only (faster, weaker)")
    ap.add_argument(
        "--timeout-factor", type=float, default=5.0, help="a run longer than this x the unmutated: killed"
    )
    ap.add_argument("--rerun", type=Path, help="judge again the survivors listed in an earlier --json file")
    ap.add_argument(
        "--id", action="append", default=[], help="judge this mutant (file:line:col:OP; repeatable)"
    )
    ap.add_argument(
        "--covered-only", action="store_true", help="judge only mutants on lines the suite covers"
    )
    ap.add_argument(
        "--self-test", action="store_true", help="also judge the hand-made mutants of self_test_mutants"
    )
    ap.add_argument("--nice", type=int, default=10, help="niceness of this process and its children")
    ap.add_argument("-q", "--quiet", action="store_true")
    a = ap.parse_args(args)
    if a.nice:
        os.nice(a.nice)
    ops = [o for o in a.ops.split(",") if o]
    everything = all_mutants(ROOT, a.files, ops)
    chosen = everything
    coverage = load_coverage()
    if a.covered_only:
        if coverage is None:
            ap.error("--covered-only needs build/coverage/lines.json (make coverage)")
        chosen = [m for m in chosen if m.line in coverage.get(m.path, set())]
    chosen = sample(chosen, a.sample, a.seed)
    if a.rerun:
        again = {r["id"] for r in json.loads(a.rerun.read_text())["results"] if r["status"] == "survived"}
        chosen = [m for m in chosen if m.id in again]
    if a.id:
        chosen = [m for m in chosen if m.id in a.id]
    if a.list:
        for m in chosen:
            print(f"{m.id}: {m.change}    {m.source}")
        print(f"{len(chosen)} of {len(everything)} mutants")
        return 0

    def log(msg: str) -> None:
        if not a.quiet:
            print(msg, file=sys.stderr, flush=True)

    base = _prepare(a.jobs, log)
    # the snapshot is what gets mutated (the checkout may change meanwhile)
    snap = {m.id: m for m in all_mutants(base.tree, a.files, ops)}
    chosen = [snap[m.id] for m in chosen if m.id in snap and snap[m.id].orig == m.orig]
    t0 = time.perf_counter()

    def progress(r: Result, i: int, n: int) -> None:
        if not a.quiet and (r.status == "survived" or i % 25 == 0 or i == n):
            el = time.perf_counter() - t0
            print(
                f"[{i}/{n} {el:.0f} s] {r.status:9} {r.mutant.id} {r.mutant.change} {r.by}", file=sys.stderr
            )

    results = run_mutants(base, chosen, a.jobs, not a.no_binding, a.timeout_factor, progress)
    seconds = time.perf_counter() - t0
    extra: dict[str, Any] = {"sample": a.sample, "seed": a.seed, "files": a.files, "ops": ops}
    if a.self_test:
        st = self_test(base, a.jobs, not a.no_binding)
        extra["self_test"] = {name: {"status": r.status, "by": r.by} for name, r in st.items()}
        log("self test: " + ", ".join(f"{n} -> {r.status}" for n, r in st.items()))
    print(report(results, len(everything), seconds, a.jobs))
    if a.json:
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps(_json(results, len(everything), seconds, a.jobs, extra), indent=1))
    return 1 if any(r.status == "survived" and not r.explained and not r.open for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
