"""The scores and the report of a run, as text and as JSON."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from attica_dev.mutation.explained import is_proven
from attica_dev.mutation.run import Result

STATUSES = ("killed", "survived", "equivalent", "stillborn")


def _proven(r: Result) -> bool:
    """A survivor whose explanation proves it equivalent (explained.PROVEN)."""
    return r.status == "survived" and is_proven(r.explained)


def _score(rs: Sequence[Result]) -> dict[str, Any]:
    """Counts by status and the scores, percent.

    ``score`` is killed / (killed + survived - proven), the usual mutation score: the mutants proven
    equivalent (``proven``: survivors whose explanation proves that no accepted input tells them apart)
    are left out like those with the same object code (``equivalent``). ``score_raw`` is killed /
    (killed + survived), every survivor counted.
    """
    out: dict[str, Any] = {st: sum(r.status == st for r in rs) for st in STATUSES}
    out["proven"] = sum(_proven(r) for r in rs)
    raw = out["killed"] + out["survived"]
    judged = raw - out["proven"]
    out["score"] = 100.0 * out["killed"] / judged if judged else 100.0
    out["score_raw"] = 100.0 * out["killed"] / raw if raw else 100.0
    return out


def report(results: Sequence[Result], total: int, seconds: float, jobs: int) -> str:
    """Per file: mutants, killed, survived, equivalent, stillborn, score; every survivor; the totals."""

    def row(name: str, rs: Sequence[Result]) -> str:
        c = _score(rs)
        counts = " ".join(f"{c[st]:6}" for st in STATUSES)
        return f"{name:46} {len(rs):7} {counts} {c['proven']:6} {c['score']:6.1f}% {c['score_raw']:6.1f}%"

    head = " ".join(f"{st[:6]:>6}" for st in STATUSES)
    lines = [
        "score: killed / (killed + survived - proven); raw: killed / (killed + survived); proven: survivors"
        " proven equivalent (explained.PROVEN)",
        f"{'file (firmware/src/)':46} {'mutants':>7} {head} {'proven':>6} {'score':>7} {'raw':>7}",
    ]
    for f in sorted({r.mutant.path for r in results}):
        lines.append(row(f.removeprefix("firmware/src/"), [r for r in results if r.mutant.path == f]))
    lines.append(row("all", results))
    if any(r.covered is not None for r in results):
        lines.append(row("in covered lines (build/coverage/lines.json)", [r for r in results if r.covered]))
    else:
        lines.append("no build/coverage/lines.json (make coverage): the score is over every line")
    survivors = [r for r in results if r.status == "survived"]
    unexplained = [r for r in survivors if not r.explained]
    gaps = [r for r in unexplained if r.open]
    lines.append(
        f"{len(results)} of {total} mutants in {seconds:.0f} s with {jobs} job(s): "
        f"{len(results) / max(seconds, 1e-9):.2f} mutants/s, "
        f"{seconds * jobs / max(len(results), 1):.2f} s per mutant and job"
        f"; survivors explained {len(survivors) - len(unexplained)}, unexplained {len(unexplained)}"
        f" ({len(gaps)} of them known open gaps)"
    )
    if survivors:
        lines.append("")
        lines.append("survivors:")
    for r in survivors:
        cov_txt = "" if r.covered is None else (" [covered]" if r.covered else " [not covered]")
        lines.append(
            f"  {r.mutant.path}:{r.mutant.line}:{r.mutant.col} {r.mutant.op}: {r.mutant.change}{cov_txt}"
        )
        lines.append(f"      {r.mutant.source}")
        if r.explained:
            lines.append(f"      explained: {r.explained}")
        elif r.open:
            lines.append(f"      {r.open}")
    return "\n".join(lines)


def _json(
    results: Sequence[Result], total: int, seconds: float, jobs: int, extra: dict[str, Any]
) -> dict[str, Any]:
    out: dict[str, Any] = {"total_mutants": total, "judged": len(results), **_score(results)}
    out.update(seconds=seconds, jobs=jobs, coverage=any(r.covered is not None for r in results))
    out["covered"] = _score([r for r in results if r.covered])
    out["results"] = [
        {
            "id": r.mutant.id,
            "status": r.status,
            "by": r.by,
            "change": r.mutant.change,
            "source": r.mutant.source,
            "covered": r.covered,
            "explained": r.explained,
            "open": r.open,
            "seconds": round(r.seconds, 3),
        }
        for r in results
    ]
    out.update(extra)
    return out
