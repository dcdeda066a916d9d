"""Mutation testing of firmware/src (tools/attica_dev/mutate.py; issue 26: tests measured by what they catch).

- The mutant generator: the operators it applies, the places it leaves alone (comments, strings,
  preprocessor conditions, array sizes, unary signs and pointers), ids unique, samples reproducible.
- A sampled set of mutants (SAMPLE, seed SEED) judged against the oracle (the golden and node runners,
  then the library as attica._native under the digests and the settings contracts): every one is killed,
  stillborn, equivalent (the same object code) or an explained survivor (mutate.EXPLAINED); and the
  oracle's self test: a wrong constant is killed, the same constant spelt otherwise is equivalent (and,
  judged by the outputs alone, survives), a broken line is stillborn.
- Every explanation and every known open gap (mutate.OPEN: survivors a test could kill and none does
  yet; the sample tolerates them, any other unexplained survivor fails it) still names a current mutant.

The whole set: ``make mutation`` (docs/robustness.md).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

from attica_dev import mutate

from helpers import ROOT, need

SAMPLE = 30
SEED = 26

SNIPPET = """\
#include "att_fp.h"
#define ATT_K 0x1.8p+1f /* 3 */
#if ATT_WITH_X > 1
#endif
static const float att_eye[9] = {1.0f, 0.0f, 2.5f};
/* a comment: x < 1 && y */
static float att_f(const float m[3], att_vec3_t *out, uint32_t n)
{
    float a[4];
    uint32_t i;
    for (i = 0u; i < n; i++) {
        a[i] = -m[i] * ATT_K + (float)-m[0];
    }
    if (!(a[0] >= 2.0f) || n == 0x1Fu) {
        out->x = a[1] / 2.0f;
    }
    *out = att_g(&a[0], "a < b");
    return a[2] - 1e-3f;
}
"""


def _changes(text: str) -> dict[str, set[tuple[str, str]]]:
    out: dict[str, set[tuple[str, str]]] = {}
    for m in mutate.mutants_of("x.c", text):
        out.setdefault(m.source, set()).add((m.op, m.change))
    return out


def test_operators_and_the_places_left_alone() -> None:
    ms = mutate.mutants_of("x.c", SNIPPET)
    got = _changes(SNIPPET)
    assert got["#define ATT_K 0x1.8p+1f /* 3 */"] == {("CONST", "0x1.8p+1f -> 0x1.800002p+1f")}
    assert ("CONST", "0.0f -> 1.0f") in got["static const float att_eye[9] = {1.0f, 0.0f, 2.5f};"]
    loop = got["for (i = 0u; i < n; i++) {"]
    assert loop >= {("ROR", "< -> <="), ("INC", "++ -> --"), ("CONST", "0u -> 1u")}
    body = got["a[i] = -m[i] * ATT_K + (float)-m[0];"]
    assert body == {
        ("AOR", "* -> /"),
        ("AOR", "+ -> -"),
        ("CONST", "0 -> 1"),
        ("DEL", "a[i] = -m[i] * ATT_K + (float)-m[0]; -> ;"),
    }  # the unary minus signs are not subtractions
    cond = got["if (!(a[0] >= 2.0f) || n == 0x1Fu) {"]
    assert cond >= {("NOT", "! -> "), ("ROR", ">= -> >"), ("LCR", "|| -> &&"), ("ROR", "== -> !=")}
    assert {("CONST", "0x1Fu -> 0x20u"), ("ZERO", "0x1Fu -> 0u")} <= cond
    assert ("DEL", "out->x = a[1] / 2.0f; -> ;") in got["out->x = a[1] / 2.0f;"]
    assert ("AOR", "- -> +") in got["return a[2] - 1e-3f;"]
    assert not any(m.op == "BIT" for m in ms)  # &a[0] is an address, not a bitwise and
    sources = {m.source for m in ms}
    assert not any("comment" in s or s.startswith(("#include", "#if")) for s in sources)
    assert not any(m.orig in ("3", "4", "9") for m in ms), "array sizes of declarations are never mutated"
    assert not any(m.source.startswith("static float att_f") for m in ms), "a mutant in the declarator"
    for m in ms:  # every mutant applies to exactly its text
        assert SNIPPET[m.start : m.end] == m.orig
        assert m.apply(SNIPPET) != SNIPPET


def test_the_set_is_ordered_unique_and_sampled_reproducibly() -> None:
    ms = mutate.all_mutants(ROOT, "firmware/src/math/*")
    assert len(ms) > 300
    assert len({m.id for m in ms}) == len(ms)
    assert {m.path for m in ms} == {
        "firmware/src/math/att_inline.h",
        "firmware/src/math/att_math.c",
    }  # att_fp.h holds preprocessor checks only
    assert mutate.sample(ms, 20, 7) == mutate.sample(ms, 20, 7)
    assert mutate.sample(ms, 20, 7) != mutate.sample(ms, 20, 8)
    picked = mutate.sample(ms, 20, 7)
    assert [ms.index(m) for m in picked] == sorted(ms.index(m) for m in picked)
    assert not any("/generated/" in m.path for m in mutate.all_mutants(ROOT, "firmware/src/can/*"))


def test_every_explanation_names_a_current_mutant() -> None:
    """An explanation whose line changed is stale: re-judge that mutant and update mutate.EXPLAINED."""
    from attica_dev.mutation.explained import matches

    current = mutate.all_mutants(ROOT)
    stale = [e for e in mutate.EXPLAINED if not any(matches(e, m) for m in current)]
    assert not stale, "\n".join(f"{e.path}: {e.source} ({e.op} {e.change})" for e in stale)
    assert all(len(e.why) > 20 for e in mutate.EXPLAINED)
    gone = [e for e in mutate.OPEN if not any(matches(e, m) for m in current)]
    assert not gone, "a known open gap no longer names a mutant: drop it from mutation.explained.OPEN"


def test_every_explanation_says_what_kind_it_is() -> None:
    """Each explanation begins with its kind: proven equivalent (left out of the score) or not."""
    from attica_dev.mutation.explained import PROVEN, is_proven

    kinds = (*PROVEN, "boundary:", "below output precision:", "unproven:")
    assert all(e.why.startswith(kinds) for e in mutate.EXPLAINED), [
        e.why[:40] for e in mutate.EXPLAINED if not e.why.startswith(kinds)
    ]
    assert is_proven("dead store: x") and not is_proven("boundary: x") and not is_proven("")


def test_score_leaves_out_proven_equivalents_only() -> None:
    """score = killed / (killed + survived - proven); score_raw counts every survivor."""
    from attica_dev.mutation.report import _score
    from attica_dev.mutation.run import Result

    m = mutate.all_mutants(ROOT, "firmware/src/math/*")[0]
    rs = [Result(m, "killed")] * 8 + [Result(m, "equivalent"), Result(m, "stillborn")]
    rs += [Result(m, "survived", explained="unreachable: x"), Result(m, "survived", explained="boundary: y")]
    rs += [Result(m, "survived")]
    c = _score(rs)
    assert (c["killed"], c["survived"], c["proven"], c["equivalent"]) == (8, 3, 1, 1)
    assert c["score"] == 80.0 and abs(c["score_raw"] - 800 / 11) < 1e-9


def test_sampled_mutants_are_killed_or_explained(tmp_path: Path) -> None:
    """SAMPLE mutants drawn with SEED: none survives unexplained; the oracle's self test holds."""
    need(shutil.which("gcc") is not None, "gcc is not installed")
    out = tmp_path / "mutation.json"
    env = dict(os.environ, PYTHONPATH=str(ROOT / "tools"))
    cmd = [sys.executable, "-m", "attica_dev.mutate", "--sample", str(SAMPLE), "--seed", str(SEED)]
    cmd += ["--jobs", "2", "--self-test", "--json", str(out), "-q"]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT, timeout=280)
    assert out.exists(), proc.stderr[-3000:]
    data = json.loads(out.read_text())
    assert {k: v["status"] for k, v in data["self_test"].items()} == {
        "killed": "killed",
        "equivalent": "equivalent",
        "survived": "survived",
        "stillborn": "stillborn",
    }
    assert data["judged"] == SAMPLE
    assert data["killed"] > SAMPLE // 2
    bad = [r for r in data["results"] if r["status"] == "survived" and not r["explained"] and not r["open"]]
    why = "survivors with no explanation (kill them with a test or explain them in mutate.EXPLAINED)"
    assert not bad, why + ":\n" + proc.stdout
    assert proc.returncode == 0, proc.stdout + proc.stderr[-2000:]
