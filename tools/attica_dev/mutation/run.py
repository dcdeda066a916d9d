"""Judging mutants: a private copy of the sources per worker, the pool of workers, the self test."""

from __future__ import annotations

import json
import os
import shutil
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from attica_dev.mutation.config import COVERAGE, WORK
from attica_dev.mutation.explained import explain, open_gap
from attica_dev.mutation.mutants import Mutant, _line_col
from attica_dev.mutation.snapshot import _RUNNERS, Base, _obj_name
from attica_dev.mutation.stage_a import _run_case
from attica_dev.mutation.stage_b import _binding_run


@dataclass
class Result:
    """The fate of one mutant."""

    mutant: Mutant
    status: str
    """``killed``, ``survived`` or ``stillborn``."""
    by: str = ""
    """What killed it (``A:case`` or ``B:check``, with the reason) or the compiler's first error."""
    seconds: float = 0.0
    covered: bool | None = None
    """On a line the test suite runs (None: no coverage data for the file)."""
    explained: str = ""
    open: str = ""
    """A known gap (mutation.explained.OPEN): a survivor a test still has to kill."""


def _hint(path: str) -> list[str]:
    """Words naming the cases closest to a source (tried first: killed mutants stop early)."""
    from attica.settings import implemented_kinds

    words = [k.label for k in implemented_kinds() if f"/{k.label}/" in path]
    if "/math/" in path or "/core/" in path:
        words += ["math"]
    if "/can/" in path or "/node/" in path:
        words += ["node", "can"]
    if "/calib/" in path:
        words += ["calib"]
    if path.endswith(("_check.c", "_checks.h", "att_kinds.h")):
        words += ["contract"]
    return words


class Job:
    """A private copy of the sources for one worker: mutate, compile, link, run, restore."""

    def __init__(self, base: Base, d: Path) -> None:
        self.base = base
        self.dir = d
        self.tree = d / "tree"
        if d.exists():
            shutil.rmtree(d)
        (self.tree / "firmware").mkdir(parents=True)
        shutil.copytree(base.tree / "firmware" / "src", self.tree / "firmware" / "src")
        for r in _RUNNERS:
            (self.tree / r.source).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(base.tree / r.source, self.tree / r.source)
        (d / "obj").mkdir()

    def run(self, m: Mutant, binding: bool, timeout_factor: float, tce: bool = True) -> Result:
        """Build and judge one mutant (``tce``: the unmutated object code again means equivalent)."""
        t0 = time.perf_counter()
        src = self.tree / m.path
        original = src.read_text()
        src.write_text(m.apply(original))
        runners = {r.name: r for r in _RUNNERS}
        try:
            targets = [m.path] if m.path.endswith(".c") else self.base.includers.get(m.path, [])
            replaced: dict[str, Path] = {}
            mains: dict[str, Path] = {}
            for t in targets:
                if t.startswith("main:"):
                    r = runners[t.removeprefix("main:")]
                    obj = self.dir / "obj" / f"{r.name}_main.o"
                    proc = self.base.compile(self.tree, r.source, obj, self.base.main_flags(r))
                    unmutated = self.base.dir / f"{r.name}_main.o"
                else:
                    obj = self.dir / "obj" / _obj_name(t)
                    proc = self.base.compile(self.tree, t, obj)
                    unmutated = self.base.obj / _obj_name(t)
                if proc.returncode != 0:
                    first = next((ln for ln in proc.stderr.splitlines() if "error" in ln), proc.stderr[:200])
                    return Result(m, "stillborn", first.strip()[:200], time.perf_counter() - t0)
                if not tce or obj.read_bytes() != unmutated.read_bytes():
                    if t.startswith("main:"):
                        mains[t.removeprefix("main:")] = obj
                    else:
                        replaced[t] = obj
        finally:
            src.write_text(original)
        if not replaced and not mains:
            why = "the same object code" if targets else "no source includes the header"
            return Result(m, "equivalent", why, time.perf_counter() - t0)
        affected = [
            r.name
            for r in _RUNNERS
            if r.name in mains or r.links is None and replaced or set(r.links or ()) & set(replaced)
        ]
        exes = self.base.link(self.dir, replaced, mains, affected)
        hint = _hint(m.path)
        cases = [c for c in self.base.cases if c.program in exes]
        cases.sort(key=lambda c: 0 if set(c.tags) & set(hint) else 1)
        for c in cases:
            limit = max(2.0, timeout_factor * self.base.seconds[c.name])
            got = _run_case(c, exes, self.base.dir / "inputs", self.dir, limit)
            if got != self.base.baseline[c.name]:
                why = got[1:] if got.startswith("!") else "output differs"
                return Result(m, "killed", f"A:{c.name} ({why})", time.perf_counter() - t0)
        if binding and replaced:
            so = self.base.link_binding(self.dir, replaced)
            limit = max(20.0, timeout_factor * self.base.binding_seconds)
            status, _ = _binding_run(self.base.tree, so, self.base.binding, ",".join(hint), limit)
            if status != "ok":
                return Result(m, "killed", f"B:{status}", time.perf_counter() - t0)
        return Result(m, "survived", "", time.perf_counter() - t0)


def load_coverage(path: Path = COVERAGE) -> dict[str, set[int]] | None:
    """build/coverage/lines.json ({source: [covered lines]}), or None when absent."""
    if not path.exists():
        return None
    data = json.loads(path.read_text())
    return {k: set(v) for k, v in data.items()}


def run_mutants(
    base: Base,
    mutants: Sequence[Mutant],
    jobs: int = 1,
    binding: bool = True,
    timeout_factor: float = 5.0,
    progress: Callable[[Result, int, int], None] | None = None,
    tce: bool = True,
) -> list[Result]:
    """Judge ``mutants`` with ``jobs`` workers (results in the order of ``mutants``)."""
    run_dir = WORK / f"run-{os.getpid()}-{threading.get_ident()}"
    pool: list[Job] = [Job(base, run_dir / f"job{j}") for j in range(max(jobs, 1))]
    free = list(pool)
    lock = threading.Lock()
    done = [0]
    coverage = load_coverage()

    def one(m: Mutant) -> Result:
        with lock:
            job = free.pop()
        try:
            r = job.run(m, binding, timeout_factor, tce)
        finally:
            with lock:
                free.append(job)
        if coverage is not None and m.path in coverage:
            r.covered = m.line in coverage[m.path]
        r.explained = explain(m)
        r.open = open_gap(m)
        with lock:
            done[0] += 1
            if progress is not None:
                progress(r, done[0], len(mutants))
        return r

    try:
        with ThreadPoolExecutor(max(jobs, 1)) as ex:
            return list(ex.map(one, mutants))
    finally:
        shutil.rmtree(run_dir, ignore_errors=True)


def self_test_mutants(tree: Path) -> dict[str, Mutant]:
    """Hand-made mutants with a known fate.

    A wrong constant (killed); the same constant spelt otherwise (the compiler makes the same object:
    equivalent; judged without that shortcut, the oracle finds no difference: survived); a broken line
    (stillborn).
    """
    path = "firmware/src/math/att_inline.h"
    text = (tree / path).read_text()
    line = "#define ATT_SIN_S1 0x1.11059cp-7f"
    i = text.index(line)
    number, col, source = _line_col(text, i)

    def to(repl: str) -> Mutant:
        return Mutant(path, number, col, "SELF", line, repl, i, i + len(line), source)

    return {
        "killed": to("#define ATT_SIN_S1 0x1.11059ep-7f"),
        "equivalent": to("#define ATT_SIN_S1 0x1.11059c0p-7f"),
        "survived": to("#define ATT_SIN_S1 0x8.882cep-10f"),
        "stillborn": to("#define ATT_SIN_S1 0x1.11059cp-7f )"),
    }


def self_test(base: Base, jobs: int, binding: bool) -> dict[str, Result]:
    """Judge :func:`self_test_mutants` (the "survived" one without the object-code shortcut)."""
    ms = self_test_mutants(base.tree)
    names = ["killed", "equivalent", "stillborn"]
    out = dict(zip(names, run_mutants(base, [ms[n] for n in names], jobs, binding)))
    out["survived"] = run_mutants(base, [ms["survived"]], 1, binding, tce=False)[0]
    return out
