"""``python -m attica_dev.coverage`` (``make coverage``): C line and branch coverage of firmware/src.

The coverage is that of the test suite. It runs the firmware in-process through the cffi binding, so the
binding is what gets instrumented: a copy of the checkout (``build/coverage/tree``, the files ``git ls-
files`` lists, changes included) is built with ``gcc --coverage -O0`` (the numerics are those of every
build: firmware/cflags.txt, and the bit-exact tests still compare them with the reference), its tests run
there, and gcov's JSON (gcc >= 9) is summed per line and per branch over every object (an inline helper
counts once, covered when any object covers it). Tests that build their own programs (the sanitizers, the
cross builds, the fuzz targets, the browser) add nothing here and are left out (``IGNORED``).

Output: per folder of firmware/src, lines and branches covered; the goal of issue 26 (>= 95 % of lines and
>= 90 % of branches in filters, calib, can (the codec) and node); ``build/coverage/uncovered.txt`` (every
uncovered line and every line with an untaken branch, with its source) and ``build/coverage/lines.json``
({file: [covered lines]}, read by ``attica_dev.mutate`` to score mutants in covered code). Exit 1 when a
test fails; the figures are printed either way.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "build" / "coverage"
CC = "gcc --coverage"
GROUPS = ("filters", "calib", "can", "node", "core", "math")
GOAL = {"filters", "calib", "can", "node"}
GOAL_LINES, GOAL_BRANCHES = 95.0, 90.0
IGNORED = (
    "tests/test_sanitize.py",
    "tests/test_cross.py",
    "tests/test_build_gates.py",
    "tests/test_fuzz.py",
    "tests/test_view_browser.py",
    "tests/test_view_soak.py",
    "tests/test_package.py",
    "tests/test_peer_builds.py",
    "tests/test_vcan_uml.py",
    "tests/test_quickstart.py",
    "tests/test_configs.py",
    "tests/test_node_configs.py",
    "tests/test_docs_c.py",
    "tests/test_mutation.py",
    "tests/test_soak.py",
)
"""Tests whose C runs in programs they build themselves (not the binding), or that build no firmware."""


@dataclass
class FileCov:
    """Hits per line and per (line, branch index) of one source file."""

    lines: dict[int, int] = field(default_factory=dict)
    branches: dict[tuple[int, int], int] = field(default_factory=dict)

    def add(self, line: int, count: int, branch_counts: list[int]) -> None:
        """Merge one object's counts of a line (the largest count wins: an inline helper counts once)."""
        self.lines[line] = max(self.lines.get(line, 0), count)
        for i, c in enumerate(branch_counts):
            self.branches[(line, i)] = max(self.branches.get((line, i), 0), c)


def make_tree(tree: Path) -> None:
    """``tree``: the checkout's files as they are now (tracked and new, not ignored)."""
    files = subprocess.run(
        ["git", "ls-files", "-co", "--exclude-standard", "-z"], cwd=ROOT, capture_output=True, check=True
    ).stdout.split(b"\0")
    if tree.exists():
        shutil.rmtree(tree)
    for name in files:
        if not name:
            continue
        src = ROOT / name.decode()
        if src.is_file():
            dst = tree / name.decode()
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst)
    shared = ROOT.parent / "shared"
    if shared.exists() and not (tree.parent / "shared").exists():
        (tree.parent / "shared").symlink_to(shared)  # the tests find BROAD at ../shared


def _env(tree: Path) -> dict[str, str]:
    path = [str(tree / "host"), str(tree / "tools")]
    return {**os.environ, "CC": CC, "PYTHONPATH": os.pathsep.join(path + [os.environ.get("PYTHONPATH", "")])}


_BUILD = """
import os, shutil, sysconfig
from pathlib import Path
from attica import _build as b
objs = b.compile_objects(os.environ["CC"], "-O0")
tmp = b.BUILD / "cffi"
tmp.mkdir(parents=True, exist_ok=True)
built = Path(b.make_ffi(objs).compile(tmpdir=str(tmp)))
shutil.copy2(built, b.PKG / ("_native" + (sysconfig.get_config_var("EXT_SUFFIX") or ".so")))
b.build_live("cc")
b.STAMP.write_text(b.inputs_digest() + "\\n")
"""


def build(tree: Path) -> None:
    """The binding of ``tree`` with gcc --coverage at -O0 (its stamp written for that CC)."""
    for gcda in (tree / "build").rglob("*.gcda"):
        gcda.unlink()
    subprocess.run([sys.executable, "-c", _BUILD], cwd=tree, env=_env(tree), check=True)


def run_tests(tree: Path, jobs: int, extra: Sequence[str]) -> int:
    """The suite (without IGNORED) in ``tree``; its exit status."""
    cmd = [
        sys.executable,
        "-m",
        "pytest",
        "-q",
        "-p",
        "no:cacheprovider",
        "-n",
        str(jobs),
        "--dist",
        "loadfile",
    ]
    cmd += [f"--ignore={t}" for t in IGNORED] + list(extra)
    return subprocess.run(cmd, cwd=tree, env=_env(tree)).returncode


def collect(tree: Path) -> dict[str, FileCov]:
    """Gcov JSON of every object of the binding, summed per firmware/src file (paths relative to tree)."""
    out: dict[str, FileCov] = defaultdict(FileCov)
    objdir = tree / "build" / "native"
    for gcda in sorted(objdir.glob("*.gcda")):
        r = subprocess.run(
            ["gcov", "--json-format", "--stdout", "-b", gcda.name],
            cwd=objdir,
            capture_output=True,
            check=True,
        )
        for doc in r.stdout.decode().splitlines():
            if not doc.strip():
                continue
            for f in json.loads(doc)["files"]:
                path = Path(f["file"])
                path = path if path.is_absolute() else (objdir / path)
                try:
                    rel = str(path.resolve().relative_to(tree / "firmware" / "src"))
                except ValueError:
                    continue
                cov = out["firmware/src/" + rel]
                for ln in f["lines"]:
                    cov.add(
                        int(ln["line_number"]), int(ln["count"]), [int(b["count"]) for b in ln["branches"]]
                    )
    return dict(out)


def _group(path: str) -> str:
    return path.split("/")[2]


def _pct(hit: int, total: int) -> float:
    return 100.0 * hit / total if total else 100.0


def report(cov: dict[str, FileCov], tree: Path) -> tuple[list[str], bool]:
    """The summary lines and whether the goal is met."""
    sums: dict[str, list[int]] = {g: [0, 0, 0, 0] for g in GROUPS}
    for path, c in cov.items():
        s = sums.setdefault(_group(path), [0, 0, 0, 0])
        s[0] += sum(1 for v in c.lines.values() if v > 0)
        s[1] += len(c.lines)
        s[2] += sum(1 for v in c.branches.values() if v > 0)
        s[3] += len(c.branches)
    lines = [f"{'firmware/src':<14} {'lines':>18} {'branches':>18}"]
    met = True
    for g, (lh, lt, bh, bt) in sums.items():
        if lt == 0:
            continue
        goal = ""
        if g in GOAL:
            ok = _pct(lh, lt) >= GOAL_LINES and _pct(bh, bt) >= GOAL_BRANCHES
            met = met and ok
            goal = "  goal met" if ok else f"  below the goal ({GOAL_LINES:g} / {GOAL_BRANCHES:g} %)"
        lines.append(
            f"{g:<14} {lh:>6}/{lt:<6} {_pct(lh, lt):5.1f} % {bh:>6}/{bt:<6} {_pct(bh, bt):5.1f} %{goal}"
        )
    tl = [sum(s[i] for s in sums.values()) for i in range(4)]
    lines.append(
        f"{'all':<14} {tl[0]:>6}/{tl[1]:<6} {_pct(tl[0], tl[1]):5.1f} % {tl[2]:>6}/{tl[3]:<6} "
        f"{_pct(tl[2], tl[3]):5.1f} %"
    )
    return lines, met


def uncovered(cov: dict[str, FileCov], tree: Path) -> list[str]:
    """Every uncovered line and every line with an untaken branch, with its source text."""
    out: list[str] = []
    for path in sorted(cov):
        c = cov[path]
        src = (tree / path).read_text().splitlines()
        for ln in sorted(c.lines):
            untaken = sum(1 for (l2, _), v in c.branches.items() if l2 == ln and v == 0)
            if c.lines[ln] == 0:
                out.append(f"{path}:{ln}: not run: {src[ln - 1].strip()}")
            elif untaken:
                total = sum(1 for (l2, _) in c.branches if l2 == ln)
                out.append(f"{path}:{ln}: {untaken} of {total} branches not taken: {src[ln - 1].strip()}")
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Build, run the tests, report."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--jobs", type=int, default=2, help="pytest workers (default 2)")
    p.add_argument("--no-run", action="store_true", help="only report the counters of the last run")
    p.add_argument("--show", type=int, default=40, help="uncovered lines to print (all: uncovered.txt)")
    p.add_argument("pytest_args", nargs="*", help="more pytest arguments (after --)")
    args = p.parse_args(argv)
    tree = OUT / "tree"
    status = 0
    if not args.no_run:
        make_tree(tree)
        build(tree)
        status = run_tests(tree, args.jobs, args.pytest_args)
    cov = collect(tree)
    summary, met = report(cov, tree)
    missing = uncovered(cov, tree)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "uncovered.txt").write_text("\n".join(missing) + "\n")
    covered = {path: sorted(ln for ln, v in c.lines.items() if v > 0) for path, c in sorted(cov.items())}
    (OUT / "lines.json").write_text(json.dumps(covered, indent=0) + "\n")
    print("\n".join(summary))
    print(f"\n{len(missing)} lines uncovered or with an untaken branch ({OUT / 'uncovered.txt'}); the first:")
    print("\n".join(missing[: args.show]))
    if status != 0:
        print(f"\nattica_dev.coverage: the tests failed (pytest exit {status})", file=sys.stderr)
        return 1
    print(
        f"\ngoal (>= {GOAL_LINES:g} % lines, >= {GOAL_BRANCHES:g} % branches in {', '.join(sorted(GOAL))}): "
        + ("met" if met else "not met")
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
