"""Run the fuzz targets for a while each and report executions, coverage and findings (`make fuzz`).

Every C target runs in its ASan+UBSan build for ``--time`` seconds and in its MemorySanitizer build for
a quarter of that, from the seed corpora (tests/fuzz/seeds.py: made from the test streams, with the
kept corpora of tests/fuzz/corpus) and the corpus kept in build/fuzz/corpus/<target> from earlier runs;
the host parsers run under atheris (tests/fuzz/fuzz_host.py) when it is installed. fuzz_filter counts
the classes listed in tests/fuzz/known_findings.txt instead of stopping (their first inputs go to
build/fuzz/findings); today it lists none: every finding so far (F1-F18) is fixed and kept as a
regression input.

Exit status 1 when any target found something outside those lists. A summary table is printed and
written to build/fuzz/report.md.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FUZZ = ROOT / "build" / "fuzz"
HERE = ROOT / "tests" / "fuzz"
C_TARGETS = ("fuzz_can", "fuzz_node", "fuzz_filter")
HOST_TARGETS = ("candump", "csv")


def _stats(text: str) -> tuple[int, int]:
    """(executions, coverage edges) from libFuzzer's output."""
    runs = re.findall(r"stat::number_of_executed_units:\s*(\d+)", text)
    cov = re.findall(r"cov: (\d+)", text)
    n = int(runs[-1]) if runs else 0
    if not runs:
        m = re.findall(r"Done (\d+) runs", text)
        n = int(m[-1]) if m else 0
    return n, int(cov[-1]) if cov else 0


def run_c(target: str, seconds: int, msan: bool, runs: int | None) -> dict[str, object]:
    """One libFuzzer run; returns a row of the report."""
    exe = FUZZ / (f"{target}-msan" if msan else target)
    corpus = FUZZ / "corpus" / target
    corpus.mkdir(parents=True, exist_ok=True)
    art = FUZZ / "artifacts"
    art.mkdir(parents=True, exist_ok=True)
    findings = FUZZ / "findings"
    findings.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ)
    if target == "fuzz_filter":
        env["ATT_FUZZ_KNOWN"] = "@" + str(HERE / "known_findings.txt")
        env["ATT_FUZZ_FINDINGS"] = str(findings)
    args = [
        str(exe),
        f"-max_total_time={seconds}",
        "-print_final_stats=1",
        f"-artifact_prefix={art}/{exe.name}-",
        "-timeout=20",
        "-rss_limit_mb=4096",
        str(corpus),
        str(FUZZ / "seeds" / target),
    ]
    if runs:
        args.insert(1, f"-runs={runs}")
    t0 = time.monotonic()
    r = subprocess.run(args, capture_output=True, text=True, env=env)
    dt = time.monotonic() - t0
    out = r.stderr + r.stdout
    n, cov = _stats(out)
    known = re.findall(r"known finding (\S+): (\d+) inputs", out)
    ok = r.returncode == 0
    if not ok:
        print(out[-4000:], file=sys.stderr)
    return {
        "target": exe.name,
        "seconds": round(dt),
        "executions": n,
        "coverage": cov,
        "known": ", ".join(f"{k} ({v})" for k, v in known),
        "ok": ok,
    }


def run_host(name: str, seconds: int) -> dict[str, object]:
    """One atheris run of tests/fuzz/fuzz_host.py."""
    corpus = FUZZ / "corpus" / f"host_{name}"
    corpus.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "PYTHONPATH": str(ROOT / "host"), "ATT_HOST_TARGET": name}
    t0 = time.monotonic()
    r = subprocess.run(
        [
            sys.executable,
            str(HERE / "fuzz_host.py"),
            f"-max_total_time={seconds}",
            "-print_final_stats=1",
            f"-artifact_prefix={FUZZ}/artifacts/host_{name}-",
            str(corpus),
        ],
        capture_output=True,
        text=True,
        env=env,
    )
    out = r.stderr + r.stdout
    n, cov = _stats(out)
    if r.returncode != 0:
        print(out[-4000:], file=sys.stderr)
    return {
        "target": f"host:{name}",
        "seconds": round(time.monotonic() - t0),
        "executions": n,
        "coverage": cov,
        "known": "",
        "ok": r.returncode == 0,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--time", type=int, default=600, help="seconds per ASan target (MSan: a quarter)")
    ap.add_argument("--runs", type=int, default=0, help="stop a target after this many executions")
    ap.add_argument("--only", nargs="*", default=None, help="targets to run (default: all)")
    a = ap.parse_args()
    subprocess.run(
        [sys.executable, str(HERE / "seeds.py"), str(FUZZ / "seeds")],
        check=True,
        env={**os.environ, "PYTHONPATH": str(ROOT / "host")},
    )
    rows = []
    for t in C_TARGETS:
        if a.only and t not in a.only:
            continue
        rows.append(run_c(t, a.time, False, a.runs or None))
        rows.append(run_c(t, max(a.time // 4, 1), True, None))
    try:
        import atheris  # noqa: F401

        for h in HOST_TARGETS:
            if not a.only or f"host:{h}" in a.only:
                rows.append(run_host(h, max(a.time // 2, 1)))
    except ImportError:
        print("atheris is not installed: host parsers not fuzzed (pip install atheris)")
    lines = [
        "| target | s | executions | coverage (edges) | known findings counted | result |",
        "| --- | ---: | ---: | ---: | --- | --- |",
    ]
    for r in rows:
        lines.append(
            f"| {r['target']} | {r['seconds']} | {r['executions']:,} | {r['coverage']} | "
            f"{r['known'] or '-'} | {'ok' if r['ok'] else 'FINDING'} |"
        )
    table = "\n".join(lines)
    print(table)
    (FUZZ / "report.md").write_text(table + "\n")
    return 0 if all(r["ok"] for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
