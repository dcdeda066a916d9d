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
import dataclasses
import fnmatch
import functools
import hashlib
import json
import os
import random
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
WORK = ROOT / "build" / "mutation"
COVERAGE = ROOT / "build" / "coverage" / "lines.json"
CC = os.environ.get("CC", "gcc")
OPT = "-O2"

# --- the C tokens -------------------------------------------------------------------------------

_PUNCT = sorted(
    (
        "<<= >>= ... -> ++ -- << >> <= >= == != && || += -= *= /= %= &= |= ^= ## "
        "[ ] ( ) { } . & * + - ~ ! / % < > ^ | ? : ; = , #"
    ).split(),
    key=len,
    reverse=True,
)
_NUM = re.compile(r"\.?\d(?:[eEpP][+-]|[0-9A-Za-z_.])*")
_IDENT = re.compile(r"[A-Za-z_]\w*")
_TYPE_WORDS = frozenset(
    "void char short int long float double signed unsigned _Bool bool const volatile static extern inline "
    "register struct union enum typedef restrict".split()
)
_KEYWORDS = _TYPE_WORDS | frozenset(
    "auto break case continue default do else for goto if return sizeof switch while".split()
)


@dataclass(frozen=True)
class Token:
    """A C token: ``kind`` id, num, str, chr or op; ``group`` 0 for code, n for the n-th macro body."""

    kind: str
    text: str
    start: int
    end: int
    group: int


def _logical_line_end(text: str, i: int) -> int:
    """The end of the (backslash-continued) line starting at ``i``: the offset of its newline."""
    while True:
        j = text.find("\n", i)
        if j < 0:
            return len(text)
        if j > 0 and text[j - 1] == "\\":
            i = j + 1
            continue
        return j


def tokenize(text: str) -> list[Token]:
    """The tokens of a C source; preprocessor lines dropped except the bodies of ``#define``."""
    out: list[Token] = []
    groups = [0]

    def scan(lo: int, hi: int, group: int) -> None:
        i = lo
        line_start = group == 0
        while i < hi:
            c = text[i]
            if c == "\n":
                line_start = group == 0
                i += 1
                continue
            if c in " \t\r\f\v":
                i += 1
                continue
            if c == "\\" and text.startswith("\n", i + 1):
                i += 2
                continue
            if text.startswith("/*", i):
                j = text.find("*/", i + 2)
                i = hi if j < 0 else j + 2
                continue
            if text.startswith("//", i):
                j = text.find("\n", i)
                i = hi if j < 0 else j
                continue
            if c == "#" and line_start:
                end = _logical_line_end(text, i)
                m = re.compile(r"#[ \t]*define[ \t]+([A-Za-z_]\w*)").match(text, i, end)
                if m is not None:
                    body = m.end()
                    if text.startswith("(", body):  # function-like: skip the parameters
                        body = text.index(")", body) + 1
                    groups[0] += 1
                    scan(body, end, groups[0])
                i = end
                continue
            line_start = False
            if c in "\"'":
                j = i + 1
                while j < hi and text[j] != c:
                    j += 2 if text[j] == "\\" else 1
                out.append(Token("str" if c == '"' else "chr", text[i : j + 1], i, j + 1, group))
                i = j + 1
                continue
            m = _NUM.match(text, i)
            if m is not None and m.end() <= hi:
                out.append(Token("num", m.group(), i, m.end(), group))
                i = m.end()
                continue
            m = _IDENT.match(text, i)
            if m is not None:
                out.append(Token("id", m.group(), i, m.end(), group))
                i = m.end()
                continue
            for p in _PUNCT:
                if text.startswith(p, i):
                    out.append(Token("op", p, i, i + len(p), group))
                    i += len(p)
                    break
            else:
                raise ValueError(f"unexpected character {c!r} at offset {i}")

    scan(0, len(text), 0)
    out.sort(key=lambda t: (t.group, t.start))
    return out


# --- mutants ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Mutant:
    """One change: ``text[start:end]`` (``orig``) of ``path`` replaced by ``repl``."""

    path: str
    """The source, relative to the repository (``firmware/src/math/att_math.c``)."""
    line: int
    col: int
    op: str
    orig: str
    repl: str
    start: int
    end: int
    source: str
    """The (first) source line, stripped."""

    @property
    def id(self) -> str:
        """``path:line:col:OP``, unique in a set of mutants."""
        return f"{self.path}:{self.line}:{self.col}:{self.op}"

    @property
    def change(self) -> str:
        """``orig -> repl`` (``DEL``: the statement -> ``;``)."""
        orig = " ".join(self.orig.split())
        return f"{orig} -> {self.repl}"

    def apply(self, text: str) -> str:
        """The mutated source."""
        if text[self.start : self.end] != self.orig:
            raise ValueError(f"{self.id}: the source changed under the mutant")
        return text[: self.start] + self.repl + text[self.end :]


_SWAP: dict[str, tuple[str, str]] = {
    "+": ("AOR", "-"),
    "-": ("AOR", "+"),
    "*": ("AOR", "/"),
    "/": ("AOR", "*"),
    "+=": ("AOR", "-="),
    "-=": ("AOR", "+="),
    "*=": ("AOR", "/="),
    "/=": ("AOR", "*="),
    "<": ("ROR", "<="),
    "<=": ("ROR", "<"),
    ">": ("ROR", ">="),
    ">=": ("ROR", ">"),
    "==": ("ROR", "!="),
    "!=": ("ROR", "=="),
    "&&": ("LCR", "||"),
    "||": ("LCR", "&&"),
    "&": ("BIT", "|"),
    "|": ("BIT", "&"),
    "^": ("BIT", "|"),
    "<<": ("BIT", ">>"),
    ">>": ("BIT", "<<"),
    "&=": ("BIT", "|="),
    "|=": ("BIT", "&="),
    "^=": ("BIT", "|="),
    "<<=": ("BIT", ">>="),
    ">>=": ("BIT", "<<="),
    "++": ("INC", "--"),
    "--": ("INC", "++"),
}
_BINARY_ONLY = frozenset("+ - * &".split())
"""Tokens that are also unary (sign, dereference or pointer declarator, address-of): mutated only when
the token before them ends an operand."""
_ASSIGN = frozenset("= += -= *= /= %= &= |= ^= <<= >>=".split())
_INT = re.compile(r"(0[xX][0-9A-Fa-f]+|0[0-7]*|[1-9][0-9]*)([uUlL]*)")
_FLOAT = re.compile(r"(.*?)([fFlL]?)")

OPERATORS = ("AOR", "ROR", "LCR", "NOT", "BIT", "INC", "CONST", "ZERO", "DEL")


def _is_type(t: Token) -> bool:
    return t.kind == "id" and (t.text in _TYPE_WORDS or t.text.endswith("_t"))


def _ends_operand(t: Token | None, cast: bool) -> bool:
    if t is None:
        return False
    if t.kind in ("num", "str", "chr"):
        return True
    if t.kind == "id":
        return t.text not in _KEYWORDS and not t.text.endswith("_t")
    return t.text == "]" or (t.text == ")" and not cast)


def _float_next(text: str) -> str | None:
    """The literal one unit in the last place above a float literal (0: 1.0), as a hex float."""
    import numpy as np

    m = _FLOAT.fullmatch(text)
    assert m is not None
    body, suffix = m.group(1), m.group(2)
    try:
        value = float.fromhex(body) if body[:2].lower() == "0x" else float(body)
    except ValueError:
        return None
    if value == 0.0:
        return "1.0" + suffix
    if suffix in ("f", "F"):
        v32 = np.float32(value)
        nxt = np.nextafter(v32, np.float32(np.inf))
        if not np.isfinite(nxt):
            nxt = np.nextafter(v32, np.float32(0.0))
        new = float(nxt)
    else:
        new = float(np.nextafter(value, np.inf))
    mant, _, exp = new.hex().partition("p")
    if "." in mant:
        mant = mant.rstrip("0").rstrip(".")
    return f"{mant}p{exp}{suffix}"


def _int_mutants(text: str) -> list[tuple[str, str]]:
    m = _INT.fullmatch(text)
    if m is None:
        return []
    digits, suffix = m.group(1), m.group(2)
    value = (
        int(digits, 0)
        if not (len(digits) > 1 and digits[0] == "0" and digits[1] not in "xX")
        else int(digits, 8)
    )
    if digits[:2].lower() == "0x":
        up = f"{value + 1:x}" if any(ch in "abcdef" for ch in digits[2:]) else f"{value + 1:X}"
        plus = digits[:2] + up
    else:
        plus = str(value + 1)
    out = [("CONST", plus + suffix)]
    if value != 0:
        out.append(("ZERO", "0" + suffix))
    return out


def _line_col(text: str, offset: int) -> tuple[int, int, str]:
    line = text.count("\n", 0, offset) + 1
    begin = text.rfind("\n", 0, offset) + 1
    end = text.find("\n", offset)
    return line, offset - begin + 1, text[begin : end if end >= 0 else len(text)].strip()


def mutants_of(path: str, text: str, operators: Sequence[str] = OPERATORS) -> list[Mutant]:
    """Every mutant of one source text (``path``: its name relative to the repository)."""
    toks = tokenize(text)
    found: list[tuple[int, int, str, str]] = []  # (start, end, op, repl)
    by_group: dict[int, list[Token]] = {}
    for t in toks:
        by_group.setdefault(t.group, []).append(t)
    for group, ts in by_group.items():
        _group_mutants(ts, group, text, found)
    out = []
    for start, end, op, repl in sorted(set(found)):
        if op not in operators:
            continue
        line, col, source = _line_col(text, start)
        out.append(Mutant(path, line, col, op, text[start:end], repl, start, end, source))
    return out


def _group_mutants(ts: list[Token], group: int, text: str, found: list[tuple[int, int, str, str]]) -> None:
    """The mutants of one token sequence (the code, or one macro body)."""
    parens: list[bool] = []  # per open parenthesis: it is a cast or a type (the declaration's parameters)
    brackets: list[bool] = []  # per open bracket: an array size of a declaration
    braces: list[str] = []  # "block" or "init"
    stmt_start = 0
    decl = False
    last_close_cast = False
    for k, t in enumerate(ts):
        prev = ts[k - 1] if k > 0 else None
        if k == stmt_start:
            first = k
            while first < len(ts) and ts[first].kind == "id" and ts[first].text.isupper():
                first += 1  # qualifier macros (ATT_NOINLINE) before a type
            decl = group == 0 and first < len(ts) and _is_type(ts[first])
        if t.kind == "op":
            text_ = t.text
            if text_ == "(":
                nxt = ts[k + 1] if k + 1 < len(ts) else None
                parens.append(
                    nxt is not None and _is_type(nxt) and not (prev is not None and prev.text == "sizeof")
                )
            elif text_ == ")":
                last_close_cast = parens.pop() if parens else False
            elif text_ == "[":
                before = ts[k - 2] if k > 1 else None
                declarator = prev is not None and prev.kind == "id" and before is not None
                declarator = (
                    declarator and before is not None and (_is_type(before) or before.text in ("*", ","))
                )
                brackets.append(
                    decl and (declarator or (prev is not None and prev.text == "]" and _size_before(ts, k)))
                )
            elif text_ == "]":
                if brackets:
                    brackets.pop()
            elif text_ == "{":
                inner = bool(braces) and braces[-1] == "init" and prev is not None and prev.text in (",", "{")
                braces.append("init" if inner or (prev is not None and prev.text == "=") else "block")
                if braces[-1] == "block":
                    stmt_start = k + 1
            elif text_ == "}":
                kind = braces.pop() if braces else "block"
                if kind == "block":
                    stmt_start = k + 1
            elif text_ == ";" and not parens:
                if group == 0 and not decl:
                    _deletion(ts, stmt_start, k, found)
                stmt_start = k + 1
            elif text_ == ":" and prev is not None and not parens and _is_label(ts, stmt_start, k):
                stmt_start = k + 1
            if text_ in _SWAP:
                op, repl = _SWAP[text_]
                if text_ in _BINARY_ONLY and not _ends_operand(
                    prev, last_close_cast and prev is not None and prev.text == ")"
                ):
                    pass
                elif (
                    op == "INC"
                    and group == 0
                    and not (prev is not None and prev.kind == "id")
                    and not (k + 1 < len(ts) and ts[k + 1].kind == "id")
                ):
                    pass
                else:
                    found.append((t.start, t.end, op, repl))
            elif text_ == "!":
                found.append((t.start, t.end, "NOT", ""))
        elif t.kind == "num":
            if brackets and brackets[-1]:
                continue  # an array size
            if prev is not None and prev.text == "#":
                continue
            lit = t.text
            is_float = any(ch in lit for ch in ".pP") or (
                lit[:2].lower() != "0x" and any(ch in lit for ch in "eE")
            )
            if is_float:
                new = _float_next(lit)
                if new is not None and new != lit:
                    found.append((t.start, t.end, "CONST", new))
            else:
                for op, repl in _int_mutants(lit):
                    found.append((t.start, t.end, op, repl))


def _size_before(ts: list[Token], k: int) -> bool:
    """``a[N][M]``: the bracket closed just before ``ts[k]`` held an array size (its opener's context)."""
    depth = 0
    for j in range(k - 1, -1, -1):
        if ts[j].text == "]":
            depth += 1
        elif ts[j].text == "[":
            depth -= 1
            if depth == 0:
                before = ts[j - 2] if j > 1 else None
                return (
                    ts[j - 1].kind == "id"
                    and before is not None
                    and (_is_type(before) or before.text in ("*", ","))
                )
    return False


def _is_label(ts: list[Token], start: int, k: int) -> bool:
    """``case X:`` or ``default:`` (not the ``:`` of a conditional)."""
    return start < k and ts[start].kind == "id" and ts[start].text in ("case", "default")


def _deletion(ts: list[Token], start: int, end: int, found: list[tuple[int, int, str, str]]) -> None:
    """``DEL``: the statement ``ts[start:end+1]`` when it is one assignment (``x = ...;``, ``a.b += 1;``)."""
    if (
        start >= end
        or ts[start].kind not in ("id", "op")
        or ts[start].kind == "id"
        and ts[start].text in _KEYWORDS
    ):
        return
    if ts[start].kind == "op" and ts[start].text not in ("*", "("):
        return
    depth = 0
    for t in ts[start:end]:
        if t.text in ("(", "["):
            depth += 1
        elif t.text in (")", "]"):
            depth -= 1
        elif depth == 0 and t.kind == "op" and t.text in _ASSIGN:
            found.append((ts[start].start, ts[end].end, "DEL", ";"))
            return
        elif t.kind == "op" and t.text in ("{", "}", "?"):
            return


def source_files(tree: Path, pattern: str = "") -> list[Path]:
    """The mutated sources below ``tree``/firmware/src (sorted; generated/ left out; ``pattern``: fnmatch)."""
    out = []
    for p in sorted((tree / "firmware" / "src").rglob("*")):
        rel = p.relative_to(tree).as_posix()
        if p.suffix not in (".c", ".h") or "/generated/" in rel:
            continue
        if pattern and not any(fnmatch.fnmatch(rel, g.strip()) for g in pattern.split(",")):
            continue
        out.append(p)
    return out


def all_mutants(tree: Path, pattern: str = "", operators: Sequence[str] = OPERATORS) -> list[Mutant]:
    """Every mutant of the sources below ``tree`` (a checkout or a snapshot), in a fixed order."""
    out: list[Mutant] = []
    for p in source_files(tree, pattern):
        out.extend(mutants_of(p.relative_to(tree).as_posix(), p.read_text(), operators))
    ids = [m.id for m in out]
    if len(ids) != len(set(ids)):
        raise AssertionError("two mutants share an id")
    return out


def sample(mutants: Sequence[Mutant], n: int, seed: int) -> list[Mutant]:
    """``n`` mutants drawn with ``seed`` (all when n <= 0 or n >= len), in their original order."""
    if n <= 0 or n >= len(mutants):
        return list(mutants)
    idx = sorted(random.Random(seed).sample(range(len(mutants)), n))
    return [mutants[i] for i in idx]


# --- the snapshot and its objects ---------------------------------------------------------------


@dataclass(frozen=True)
class Runner:
    """A test program of stage A: its main source, extra include folders, the firmware sources it links."""

    name: str
    source: str
    includes: tuple[str, ...] = ()
    """Relative to the tree; ``@gen``: the golden runner's generated field table."""
    links: tuple[str, ...] | None = None
    """None: every firmware source."""


_RUNNERS = (
    Runner("golden", "tests/c/att_golden.c", ("@gen",)),
    Runner("node", "tests/c/att_node_run.c"),
    Runner("config", "tests/c/att_config_test.c"),
    Runner("core", "tests/c/att_core_test.c", ("firmware/src/core",), ("firmware/src/math/att_math.c",)),
)
"""The programs of stage A (the suite's own: tests/test_cross.py, test_node_configs.py, test_configs.py and
test_core.py build them), each linked with the firmware objects it needs."""
_SNAPSHOT = (
    "firmware/src",
    "firmware/include",
    "firmware/cflags.txt",
    "host/attica",
    "tools/attica_dev",
    *(r.source for r in _RUNNERS),
)
"""What a base copies: the sources, the runners, and the Python that makes the inputs and runs stage B."""
_IGNORE = ("*.o", "__pycache__", "_native*.so", "_native.stamp")
_UNUSED = ("host/attica/reference/", "host/attica/view/", "host/attica/evaluate/", "host/attica/commands/")
"""Copied but not hashed: the oracle does not use them (other work on them does not rebuild the base)."""


def _obj_name(rel: str) -> str:
    return rel.replace("/", "__").removesuffix(".c") + ".o"


def _snapshot_digest() -> str:
    """A hash of every file the oracle is built from (sources, runners, the Python of inputs and stage B)."""
    h = hashlib.sha256()
    files: list[Path] = []
    for part in _SNAPSHOT:
        p = ROOT / part
        files.extend(sorted(q for q in p.rglob("*") if q.is_file()) if p.is_dir() else [p])
    for f in files:
        rel = f.relative_to(ROOT).as_posix()
        skip = any(fnmatch.fnmatch(f.name, g) for g in _IGNORE) or "__pycache__" in f.parts
        if skip or rel.startswith(_UNUSED):
            continue
        h.update(rel.encode())
        h.update(f.read_bytes())
    h.update(CC.encode())
    return h.hexdigest()[:16]


def _run(cmd: Sequence[str], what: str, cwd: Path | None = None) -> None:
    proc = subprocess.run(list(cmd), capture_output=True, text=True, cwd=cwd)
    if proc.returncode != 0:
        raise RuntimeError(f"{what} failed ({shlex.join(cmd)}):\n{proc.stderr[-4000:]}")


@dataclass
class Base:
    """The unmutated build of one snapshot: objects, the runners' mains, the binding's wrapper, inputs."""

    dir: Path
    tree: Path
    sources: list[str]
    """firmware/src/**/*.c, relative to the tree."""
    includers: dict[str, list[str]]
    """Private header -> the sources that include it (directly or not)."""
    cases: list[Case]
    baseline: dict[str, str]
    """Stage A: case name -> digest of the unmutated run."""
    seconds: dict[str, float]
    binding: dict[str, str]
    """Stage B: check name -> digest of the unmutated library."""
    binding_seconds: float

    @property
    def cflags(self) -> list[str]:
        """The firmware flags (the snapshot's cflags.txt), the optimisation level, position independence."""
        return [*shlex.split((self.tree / "firmware" / "cflags.txt").read_text()), OPT, "-fPIC"]

    @property
    def obj(self) -> Path:
        """The unmutated objects."""
        return self.dir / "obj"

    def compile(
        self, tree: Path, src: str, obj: Path, extra: Sequence[str] = ()
    ) -> subprocess.CompletedProcess[str]:
        """Compile ``tree``/``src`` with the firmware flags (``extra``: more -I).

        The compiler runs in ``tree`` on the relative name, so that the object of an unchanged source is
        the same bytes in every tree (what tells a mutant the compiler made equivalent).
        """
        include = str(self.tree / "firmware" / "include")
        cmd = [CC, *self.cflags, "-I", include, *extra, "-c", src, "-o", str(obj)]
        return subprocess.run(cmd, capture_output=True, text=True, cwd=tree)

    def objects(self, replaced: dict[str, Path] | None = None) -> list[str]:
        """The firmware objects, with ``replaced`` (source -> object) in place of the unmutated ones."""
        replaced = replaced or {}
        return [str(replaced.get(s, self.obj / _obj_name(s))) for s in self.sources]

    def main_flags(self, r: Runner) -> list[str]:
        """The -I flags of a runner's main."""
        out = []
        for inc in r.includes:
            out += ["-I", str(self.dir / "gen") if inc == "@gen" else inc]
        return out

    def link(
        self,
        out_dir: Path,
        replaced: dict[str, Path] | None = None,
        mains: dict[str, Path] | None = None,
        only: Sequence[str] | None = None,
    ) -> dict[str, Path]:
        """Link the stage A programs (``only`` those) into ``out_dir``; returns name -> program.

        ``replaced``: firmware source -> mutated object; ``mains``: runner -> recompiled main object.
        """
        exes = {}
        replaced = replaced or {}
        for r in _RUNNERS:
            if only is not None and r.name not in only:
                continue
            exe = out_dir / f"att_{r.name}"
            main = (mains or {}).get(r.name, self.dir / f"{r.name}_main.o")
            objs = self.objects(replaced)
            if r.links is not None:
                objs = [str(replaced.get(s, self.obj / _obj_name(s))) for s in r.links]
            _run([CC, str(main), *objs, "-lm", "-o", str(exe)], f"link {r.name}")
            exes[r.name] = exe
        return exes

    def link_binding(self, out_dir: Path, replaced: dict[str, Path] | None = None) -> Path:
        """Link the library as ``attica._native`` (the cffi wrapper and host kernels built once)."""
        import sysconfig

        so = out_dir / ("_native" + (sysconfig.get_config_var("EXT_SUFFIX") or ".so"))
        host = sorted(str(p) for p in (self.dir / "host").glob("*.o"))
        _run(
            [
                CC,
                "-shared",
                str(self.dir / "cffi_wrap.o"),
                *host,
                *self.objects(replaced),
                "-lm",
                "-o",
                str(so),
            ],
            "link",
        )
        return so


def _copy_tree(dst: Path) -> None:
    for part in _SNAPSHOT:
        src = ROOT / part
        target = dst / part
        target.parent.mkdir(parents=True, exist_ok=True)
        if src.is_dir():
            shutil.copytree(src, target, ignore=shutil.ignore_patterns(*_IGNORE))
        else:
            shutil.copy2(src, target)


def _includers(base: Base, units: list[tuple[str, str, list[str]]]) -> dict[str, list[str]]:
    """Private header -> the units (key, source, -I flags) that include it, directly or not."""
    tree = base.tree
    out: dict[str, list[str]] = {}
    for s, src, extra in units:
        cmd = [CC, *base.cflags, "-I", str(tree / "firmware" / "include"), *extra, "-MM", src]
        proc = subprocess.run(cmd, capture_output=True, text=True, check=True, cwd=tree)
        for dep in proc.stdout.replace("\\\n", " ").split(":", 1)[1].split():
            p = Path(os.path.normpath(tree / dep))
            try:
                rel = p.relative_to(tree).as_posix()
            except ValueError:
                continue
            if rel.startswith("firmware/src/") and rel.endswith(".h"):
                if s not in out.setdefault(rel, []):
                    out[rel].append(s)
    return out


def _build_wrapper(tree: Path, out: Path) -> None:
    """The cffi wrapper of attica._native (the snapshot's declarations), compiled to ``out``."""
    import sysconfig

    from attica import _build

    saved = (_build.FIRMWARE, _build.INCLUDE, _build.CSRC)
    try:
        _build.FIRMWARE = tree / "firmware"
        _build.INCLUDE = tree / "firmware" / "include"
        _build.CSRC = tree / "host" / "attica" / "csrc"
        ffi = _build.make_ffi([])
        c_file = out.with_suffix(".c")
        ffi.emit_c_code(str(c_file))
    finally:
        _build.FIRMWARE, _build.INCLUDE, _build.CSRC = saved
    inc = ["-I", sysconfig.get_paths()["include"], "-I", str(tree / "firmware" / "include")]
    inc += ["-I", str(tree / "host" / "attica" / "csrc")]
    _run([CC, "-O1", "-fPIC", *inc, "-c", str(c_file), "-o", str(out)], "the cffi wrapper")


def _prepare(jobs: int, log: Callable[[str], None]) -> Base:
    """The base of the current sources: built once per snapshot (build/mutation/base-<hash>), then reused."""
    digest = _snapshot_digest()
    final = WORK / f"base-{digest}"
    meta = final / "base.json"
    if not meta.exists():
        WORK.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f"base-{digest}.", dir=WORK))
        t0 = time.perf_counter()
        log(f"building the unmutated base in {tmp.relative_to(ROOT)} ...")
        try:
            _build_base(tmp, jobs, log)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        try:
            os.replace(tmp, final)
        except OSError:  # another process made the same base meanwhile
            shutil.rmtree(tmp, ignore_errors=True)
        log(f"base ready in {time.perf_counter() - t0:.1f} s")
    _prune(keep=final)
    data = json.loads(meta.read_text())
    return Base(
        final,
        final / "tree",
        data["sources"],
        data["includers"],
        [Case(**c) for c in data["cases"]],
        data["baseline"],
        data["seconds"],
        data["binding"],
        data["binding_seconds"],
    )


def _prune(keep: Path, hours: float = 12.0) -> None:
    """Remove the bases of other snapshots (and runs left by killed processes) older than ``hours``."""
    limit = time.time() - 3600.0 * hours
    for d in WORK.glob("*"):
        if d != keep and d.is_dir() and d.name.startswith(("base-", "run-")) and d.stat().st_mtime < limit:
            shutil.rmtree(d, ignore_errors=True)


def _build_base(d: Path, jobs: int, log: Callable[[str], None]) -> None:
    from attica_dev import golden

    tree = d / "tree"
    _copy_tree(tree)
    sources = [p.relative_to(tree).as_posix() for p in sorted((tree / "firmware" / "src").rglob("*.c"))]
    base = Base(d, tree, sources, {}, [], {}, {}, {}, 0.0)
    base.obj.mkdir(parents=True)
    (d / "host").mkdir()
    csrc = tree / "host" / "attica" / "csrc"
    golden.write_fields_header(d / "gen")
    work: list[tuple[Path, str, Path, list[str]]] = [(tree, s, base.obj / _obj_name(s), []) for s in sources]
    for p in sorted(csrc.glob("*.c")):
        work.append((tree, p.relative_to(tree).as_posix(), d / "host" / (p.stem + ".o"), ["-I", str(csrc)]))
    work += [(tree, r.source, d / f"{r.name}_main.o", base.main_flags(r)) for r in _RUNNERS]

    def one(item: tuple[Path, str, Path, list[str]]) -> None:
        proc = base.compile(*item)
        if proc.returncode != 0:
            raise RuntimeError(f"the unmutated {item[1]} does not compile:\n{proc.stderr[-4000:]}")

    with ThreadPoolExecutor(max(jobs, 1)) as ex:
        wrapper = ex.submit(_build_wrapper, tree, d / "cffi_wrap.o")
        list(ex.map(one, work))
        wrapper.result()
    units: list[tuple[str, str, list[str]]] = [(s, s, []) for s in sources]
    units += [(f"main:{r.name}", r.source, base.main_flags(r)) for r in _RUNNERS]
    includers = _includers(base, units)
    log("writing the oracle's inputs ...")
    cases = _write_cases(d / "inputs")
    exes = base.link(d)
    baseline, seconds = {}, {}
    for c in cases:
        t0 = time.perf_counter()
        out = _run_case(c, exes, d / "inputs", d, timeout=600.0)
        seconds[c.name] = time.perf_counter() - t0
        if out.startswith("!"):
            raise RuntimeError(f"the unmutated firmware fails case {c.name}: {out}")
        baseline[c.name] = out
    so_dir = d / "binding"
    so_dir.mkdir()
    so = base.link_binding(so_dir)
    t0 = time.perf_counter()
    status, binding = _binding_run(tree, so, None, "", timeout=600.0)
    if status != "ok":
        raise RuntimeError(f"the binding checks fail on the unmutated library: {status}")
    meta = {
        "sources": sources,
        "includers": includers,
        "cases": [asdict(c) for c in cases],
        "baseline": baseline,
        "seconds": seconds,
        "binding": binding,
        "binding_seconds": time.perf_counter() - t0,
    }
    (d / "base.json").write_text(json.dumps(meta, indent=1))


# --- stage A: the golden runner and the node runner -----------------------------------------------

MATH_ROWS = 3000
SYNTH_STEPS = 300
SYNTH_STREAMS = 12


@dataclass(frozen=True)
class Case:
    """One run of a stage A program: ``argv`` with ``{out}`` for the output file; ``tags`` order the cases."""

    name: str
    program: str
    argv: list[str]
    tags: list[str] = field(default_factory=list)


def _edge_variants() -> dict[str, tuple[Any, dict[str, Any]]]:
    """Settings at the edges the golden variants leave out (stage A; synthetic and jump streams)."""
    from attica.settings import FilterKind

    vertical = (0.0, 0.0, -45.0)
    return {
        "mars-vertical-m0": (FilterKind.MARS, {"init_from_sensors": False, "m0_init": vertical}),
        "mekf-vertical-m0": (FilterKind.MEKF, {"init_from_sensors": False, "m0_init": vertical}),
        "mars-m0-init": (FilterKind.MARS, {"init_from_sensors": False, "m0_init": (3.0, 22.0, -40.0)}),
        "mars-m0-y": (FilterKind.MARS, {"init_from_sensors": False, "m0_init": (0.0, 1.0, 0.0)}),
        "mekf-m0-init": (FilterKind.MEKF, {"init_from_sensors": False, "m0_init": (3.0, 22.0, -40.0)}),
        "ekf-q-apart": (FilterKind.EKF, {"q_phi": 2e-3, "q_theta": 5e-4, "r_phi": 2e-4}),
        "mars-bias-init": (FilterKind.MARS, {"bias_init": (0.01, -0.02, 0.005)}),
        "mars-bias-off": (FilterKind.MARS, {"bias_init": (0.01, -0.02, 0.005), "bias_mode": 0}),
        "kf-bias-off": (FilterKind.KF, {"bias_init": (0.01, -0.02, 0.005), "bias_mode": 0}),
        "kf-noinit": (FilterKind.KF, {"init_from_accel": False, "q_init": (0.9, 0.1, -0.3, 0.2)}),
        "gyro-cos-min": (FilterKind.GYRO, {"cos_min": 0.2}),
        "ekf-cos-min": (FilterKind.EKF, {"cos_min": 0.2}),
        "ekf-small-p0": (FilterKind.EKF, {"p0": 0.01}),
        "ekf-capped": (FilterKind.EKF, {"p_max": 0.5, "p0": 0.1}),
        "ekf-narrow-gate": (FilterKind.EKF, {"gate": 0.5, "r_accel": 0.5}),
        "kf-small-r-accel": (FilterKind.KF, {"r_accel": 0.5, "accel_reject": 0.0, "gate": 0.5}),
        "mekf-capped": (FilterKind.MEKF, {"p_max": 0.05}),
    }


def _write_cases(d: Path) -> list[Case]:
    """Write the inputs of stage A into ``d``; return the cases (math, filters, node)."""
    import numpy as np

    from attica.calibration.stages import StageSettings
    from attica.settings import implemented_kinds, make_settings
    from attica_dev import cross, digests, golden

    d.mkdir(parents=True)
    cases: list[Case] = []
    cases.append(Case("config", "config", [], ["contract", "node", "calib"]))
    cases.append(Case("core", "core", ["256"], ["math", "core"]))
    for fn in golden.MATH_FUNCS:
        p = d / f"math-{fn}.bin"
        golden.write_table(p, golden.math_inputs(fn, MATH_ROWS, seed=20240611), fn)
        cases.append(Case(f"math:{fn}", "golden", ["math", fn, "@" + p.name, "{out}"], ["math", fn]))
    imu = golden.imu_inputs(SYNTH_STEPS, SYNTH_STREAMS, seed=11)
    sim = digests.sim_stream()
    adv = digests.adversarial_stream()
    tiny = sim[2][:600].copy()
    tiny[:50] *= np.float32(1e-5)  # a first mag sample below 1e-3 uT: no reference field from it
    late = sim[2].copy()
    late[:40] = np.nan  # the mag arrives after the start (the kinds' first-mag paths)
    late[40:60:3] = 0.0
    streams = {
        "synth": imu,
        "sim": sim,
        "adv": adv,
        "adv6": (adv[0], adv[1], None),
        "late": (sim[0], sim[1], late),
        "jumps": _jumps(),
        "sweep": _sweep(),
        "tinymag": (sim[0][:600], sim[1][:600], tiny),
        "flip": _flip(),
        "magvert": (sim[0], sim[1], (sim[1] * np.float32(-4.5)).astype(np.float32)),  # no horizontal field
    }

    def add(name: str, kind: Any, settings: Any, stream: str, calibration: Any = None) -> None:
        label = kind.label
        inp = d / f"{label}-{stream}.bin"
        if not inp.exists():
            g, a, m = streams[stream]
            golden.write_filter_input(inp, kind, g, a, m)
        st = d / f"{name}.settings.txt"
        golden.write_settings(st, kind, settings, calibration)
        cases.append(Case(name, "golden", [label, "@" + st.name, "@" + inp.name, "{out}"], [label, "filter"]))

    for kind in implemented_kinds():
        k = kind.label
        for preset in ("default", "seed"):
            s = digests._settings(kind, preset)
            for stream in ("synth", "sim", "adv"):
                add(f"{k}:{preset}:{stream}", kind, s, stream)
        add(f"{k}:default:adv-nomag", kind, make_settings(kind), "adv6")
        add(f"{k}:default:late-mag", kind, make_settings(kind), "late")
        add(f"{k}:default:vertical-mag", kind, make_settings(kind), "magvert")
        add(f"{k}:default:sweep", kind, make_settings(kind), "sweep")
        add(f"{k}:default:tiny-mag", kind, make_settings(kind), "tinymag")
        add(f"{k}:default:flip", kind, make_settings(kind), "flip")
        add(f"{k}:seed:flip", kind, digests._settings(kind, "seed"), "flip")
        add(f"{k}:calib-digests", kind, make_settings(kind), "sim", digests._calib())
        add(f"{k}:calib-remap", kind, make_settings(kind), "synth", StageSettings(remap=5, convention=2))
        if "dt" in {f.name for f in dataclasses.fields(make_settings(kind))}:
            add(f"{k}:dt-0.05:synth", kind, make_settings(kind, dt=0.05), "synth")  # larger angles a step
    gated: dict[str, dict[str, Any]] = {"ekf": {"gate": 9.0, "r_accel": 10.0, "accel_reject": 0.3}}
    gated["mars"] = {"mag_mode": 1}
    for kind in implemented_kinds():
        add(f"{kind.label}:default:jumps", kind, make_settings(kind), "jumps")
        add(f"{kind.label}:seed:jumps", kind, digests._settings(kind, "seed"), "jumps")
        if kind.label in gated:
            add(f"{kind.label}:gated:jumps", kind, make_settings(kind, **gated[kind.label]), "jumps")
    for name, (kind, overrides) in _edge_variants().items():
        for stream in ("synth", "jumps", "sweep"):
            add(f"{kind.label}:edge:{name}:{stream}", kind, make_settings(kind, **overrides), stream)
    for name, (kind, overrides) in cross.VARIANTS.items():
        add(f"{kind.label}:variant:{name}", kind, make_settings(kind, **overrides), "synth")
        add(f"{kind.label}:variant:{name}:jumps", kind, make_settings(kind, **overrides), "jumps")
    for name, (kind, cal) in cross.calibrated_variants().items():
        add(f"{kind.label}:calibrated:{name}", kind, make_settings(kind), "synth", cal)
    for kind in implemented_kinds():
        k = kind.label
        frames = {"digest": digests.node_stream(kind), "rough": _rough_frames(kind, fd=False)}
        frames["rough-fd"] = _rough_frames(kind, fd=True)
        for name, fr in frames.items():
            p = d / f"node-{k}-{name}.bin"
            np.ascontiguousarray(fr).tofile(p)
            for fd in (0, 1):
                bitrate, data_bitrate = digests.NODE_BITRATES[bool(fd)]
                argv = [str(int(kind)), str(digests.RATE), str(fd), str(bitrate), str(data_bitrate), "0"]
                cases.append(
                    Case(
                        f"node:{k}:{name}:fd{fd}", "node", [*argv, "@" + p.name, "{out}"], [k, "node", "can"]
                    )
                )
        if k == "ars":  # more errors than the DIAG counters and the STATUS error count hold (255)
            p = d / "node-junk.bin"
            junk = np.array(frames["rough"][:1200], copy=True)
            junk["data"][::2, 0] ^= 0x5A
            np.concatenate([junk, junk, frames["digest"][:600]]).tofile(p)
            argv = [str(int(kind)), str(digests.RATE), "0", "1000000", "0", "0", "@" + p.name, "{out}"]
            cases.append(Case("node:ars:junk", "node", argv, ["node", "can"]))
        if k == "mars":
            p = d / "node-offset.bin"
            shifted = np.array(frames["rough"], copy=True)
            shifted["id"] = shifted["id"] + np.uint32(0x20)
            shifted.tofile(p)
            argv = [str(int(kind)), str(digests.RATE), "0", "500000", "0", "0x20", "@" + p.name, "{out}"]
            cases.append(Case("node:mars:offset", "node", argv, ["node", "can"]))
    return cases


def _flip() -> tuple[Any, Any, Any]:
    """At rest upright, then at once exactly upside down (the accel opposite the predicted gravity)."""
    import numpy as np

    n = 300
    gyr = np.zeros((2 * n, 3), np.float32)
    acc = np.zeros((2 * n, 3), np.float32)
    acc[:n, 2] = 9.80665
    acc[n:, 2] = -9.80665
    mag = np.zeros((2 * n, 3), np.float32)
    mag[:n] = (0.0, 22.0, -40.0)
    mag[n:] = (0.0, -22.0, 40.0)
    mag[:5] = (0.0, 0.0, -45.0)  # vertical at the start: no heading from it
    return gyr, acc, mag


def _sweep(steps: int = 1500, streams: int = 4) -> tuple[Any, Any, Any]:
    """Turns about the pitch axis through +-90 degrees again and again (the gimbal zones), deterministic."""
    import numpy as np

    rng = np.random.default_rng([26, 2])
    t = np.arange(steps)[:, None] * 0.01
    wy = np.array([1.0, 0.7, 2.3, -1.3])[None, :streams]
    theta = wy * t
    gyr = np.stack(
        [0.01 * np.sin(0.3 * t + np.zeros_like(wy)), wy + 0 * t, 0.02 * np.cos(0.2 * t) + 0 * wy], -1
    )
    gyr = gyr + rng.normal(0, 1e-4, gyr.shape)
    acc = 9.80665 * np.stack([-np.sin(theta), 0 * theta, np.cos(theta)], -1)
    mag = np.stack([22.0 * np.cos(theta) + 40.0 * np.sin(theta), 0 * theta + 5.0, -40.0 * np.cos(theta)], -1)
    f = np.float32
    return gyr.astype(f), acc.astype(f), mag.astype(f)


def _jumps(steps: int = 1000, streams: int = 4) -> tuple[Any, Any, Any]:
    """Segments of constant attitude whose accel or mag disagree with it at once (deterministic).

    Each segment of 40 to 120 samples holds still (a small gyro bias and noise) with one of: consistent
    sensors; the accel turned 3 to 60 degrees at |g| (the gates and rejections); the accel 2 to 40 % off
    |g|; the mag turned about the vertical (a heading jump) or about a horizontal axis (the dip), at its
    norm; the mag 30 to 60 % off its norm; pitch exactly +-90 degrees (the gimbal cases); a burst of
    rotation.
    """
    import numpy as np

    rng = np.random.default_rng([26, 1])
    g0, b0, dip = 9.80665, 49.0, 1.1
    m_earth = np.array([0.0, b0 * np.cos(dip), -b0 * np.sin(dip)])
    gyr = np.empty((steps, streams, 3))
    acc = np.empty((steps, streams, 3))
    mag = np.empty((steps, streams, 3))

    def rot(axis: Any, angle: float) -> Any:
        u = np.asarray(axis, float) / np.linalg.norm(axis)
        k = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
        return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)

    for j in range(streams):
        bias = rng.normal(0, 0.005, 3)
        t = 0
        while t < steps:
            end = min(t + int(rng.integers(40, 120)), steps)
            n = end - t
            what = int(rng.integers(0, 9))
            r = rot(rng.normal(size=3), rng.uniform(0, np.pi))  # body -> earth
            if what == 6:
                r = rot([0, 1, 0], rng.choice([-1.0, 1.0]) * np.pi / 2) @ rot([1, 0, 0], rng.uniform(-3, 3))
            elif what == 8:
                r = np.diag([1.0, -1.0, -1.0])  # upside down, exactly
            a_b = r.T @ np.array([0.0, 0.0, g0])
            m_b = r.T @ m_earth
            if what == 1:
                a_b = rot(rng.normal(size=3), np.radians(rng.uniform(3, 60))) @ a_b
            elif what == 2:
                a_b = a_b * (1 + rng.choice([-1, 1]) * rng.uniform(0.02, 0.4))
            elif what == 3:
                m_b = r.T @ (rot([0, 0, 1], rng.uniform(-np.pi, np.pi)) @ m_earth)
            elif what == 4:
                m_b = r.T @ (rot([1, 0, 0], rng.uniform(-0.8, 0.8)) @ m_earth)
            elif what == 5:
                m_b = m_b * (1 + rng.choice([-1, 1]) * rng.uniform(0.3, 0.6))
            w = bias + rng.normal(0, 0.002, (n, 3))
            if what == 7:
                w = w + rng.normal(0, 3.0, 3)
            gyr[t:end, j] = w
            acc[t:end, j] = a_b + (0.0 if what in (6, 8) else rng.normal(0, 0.01, (n, 3)))
            mag[t:end, j] = m_b + rng.normal(0, 0.2, (n, 3))
            t = end
    f = np.float32
    return gyr.astype(f), acc.astype(f), mag.astype(f)


def _rough_frames(kind: Any, fd: bool) -> Any:
    """A node input with every kind of trouble and every command (deterministic)."""
    import numpy as np

    from attica.can import codec as c
    from attica_dev import digests

    rng = np.random.default_rng([26, int(kind), int(fd)])
    g, a, m = digests.adversarial_stream()
    n = 400
    m = m[:n].copy()
    m[::7] = np.nan  # absent mag
    imu = c.encode_imu(g[:n], a[:n], m, fd=fd)
    per = 1 if fd else 3
    rows = [imu[i * per : (i + 1) * per].copy() for i in range(n)]
    commands: list[tuple[int, int, float]] = [
        (int(c.Cmd.SET_GAIN), int(p), v) for p in range(0, 6) for v in (0.75, 0.0, -1.0, float("nan"), 1e9)
    ]
    commands += [(int(c.Cmd.SELECT), k, 0.0) for k in (0, 9, int(kind))]
    commands += [(int(c.Cmd.RESET), 0, 0.0), (15, 0, 0.0), (0, 0, 0.0)]
    commands += [(8, conv, 0.0) for conv in (1, 2, 0, 7)] + [(9, r, 0.0) for r in (5, 24, 25, 0)]
    values = [0.02, -0.01, 1.01, 0.0, float("inf"), 1e6, 0.5]
    cal: list[tuple[int, int, float]] = [(4, 0, 0.0)]
    cal += [(5, int(i), float(rng.choice(values))) for i in rng.choice(48, 12, replace=False)]
    cal += [(6, 0, 0.0), (4, 1, 0.0), (5, 12, 0.01), (5, 200, 1.0), (7, 0, 0.0), (6, 0, 0.0), (4, 0, 0.0)]
    cal += [(5, 0, 2.0), (6, 0, 0.0), (4, 7, 0.0)]
    commands += cal
    out = []
    counter = 0
    for i, r in enumerate(rows):
        if i % 4 == 1 and commands:
            cmd, arg, value = commands.pop(0)
            counter = (counter + 1) & 0xF
            out.append(c.encode_cmd(cmd, arg, value, counter=counter))
            if i % 40 == 1:
                out.append(c.encode_cmd(cmd, arg, value, counter=counter))  # a repeated command
        if i % 37 == 5:
            r["data"][0, 3] ^= 0x10  # a bad CRC
        if i % 53 == 11:
            continue  # a lost sample: a counter gap
        if i % 61 == 13:
            r = np.concatenate([r, r])  # duplicates
        if i % 43 == 17:
            r = r[:-1]  # a partial sample (classic) or nothing (FD)
        if i % 71 == 19 and len(r):
            r = r.copy()
            r["len"][0] = 5  # a wrong length
        if i % 67 == 23:
            junk = c.frames(1)
            junk["id"] = 0x123 + i
            junk["len"] = 8
            out.append(junk)
        out.append(r)
    return np.concatenate(out)


def _run_case(c: Case, exes: dict[str, Path], inputs: Path, tmp: Path, timeout: float) -> str:
    """The digest of one run, or ``!reason`` (crash, exit status, timeout)."""
    out = tmp / f"{c.name.replace(':', '-')}.out"
    argv = [str(exes[c.program]), *(str(out) if a == "{out}" else a for a in c.argv)]
    argv = [str(inputs / a[1:]) if a.startswith("@") else a for a in argv]
    try:
        proc = subprocess.run(argv, capture_output=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return "!timeout"
    finally:
        data = out.read_bytes() if out.exists() else b""
        out.unlink(missing_ok=True)
    if proc.returncode < 0:
        return f"!signal {-proc.returncode}"
    if proc.returncode != 0:  # settings refused, a file error, a failed check of the core test
        return f"!exit {proc.returncode}"
    h = hashlib.sha256(data)
    h.update(proc.stdout)
    h.update(str(proc.returncode).encode())
    return h.hexdigest()


# --- stage B: the library as attica._native in a fresh Python process ---------------------------


def _binding_run(
    tree: Path, so: Path, expect: dict[str, str] | None, hint: str, timeout: float
) -> tuple[str, dict[str, str]]:
    """Run the binding checks on ``so`` with the Python of ``tree`` (a base's snapshot).

    Returns ("ok" | "differs: CHECK" | "!reason", the digests computed).
    """
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(tree / "host"), str(tree / "tools")])
    with tempfile.TemporaryDirectory(prefix="att_mut_") as tmp:
        exp = Path(tmp) / "expect.json"
        res = Path(tmp) / "result.json"
        exp.write_text(json.dumps(expect or {}))
        cmd = [
            sys.executable,
            "-m",
            "attica_dev.mutate",
            "--binding-worker",
            str(so),
            str(exp),
            str(res),
            hint,
        ]
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
        except subprocess.TimeoutExpired:
            return "!timeout", {}
        if proc.returncode != 0 or not res.exists():
            return (
                f"!exit {proc.returncode}: {proc.stderr.strip().splitlines()[-1:] if proc.stderr else ''}",
                {},
            )
        data = json.loads(res.read_text())
    return str(data["status"]), dict(data["digests"])


def _binding_worker(so: str, expect_path: str, result_path: str, hint: str) -> int:
    """Stage B inside the worker process: load ``so`` as attica._native and run every check."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("attica._native", so)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    sys.modules["attica._native"] = mod
    import attica
    from attica import _build

    attica._native = mod
    _build.is_stale = lambda: False  # the checkout's stamp says nothing about this library
    from attica import native

    assert native.lib is mod.lib
    expect: dict[str, str] = json.loads(Path(expect_path).read_text())
    out: dict[str, str] = {}
    status = "ok"
    for name, check in _ordered(list(_binding_checks()), hint):
        import numpy as np

        with np.errstate(all="ignore"):
            out[name] = check()
        if expect and expect.get(name) != out[name]:
            status = f"differs: {name}"
            break
    Path(result_path).write_text(json.dumps({"status": status, "digests": out}))
    return 0


def _ordered(items: list[tuple[str, Any]], hint: str) -> list[tuple[str, Any]]:
    """Items whose name mentions a word of ``hint`` first (the checks of the mutated file's kind)."""
    words = [w for w in hint.split(",") if w]
    return sorted(items, key=lambda it: 0 if any(w in it[0] for w in words) else 1)


def _sha(*parts: Any) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(p if isinstance(p, bytes) else repr(p).encode())
    return h.hexdigest()


def _binding_checks() -> Iterator[tuple[str, Callable[[], str]]]:
    """The stage B checks: name -> a function returning the digest of what it saw."""
    from attica.settings import implemented_kinds
    from attica_dev import digests

    sim = functools.cache(digests.sim_stream)
    digests.sim_stream = lambda: tuple(x.copy() for x in sim())  # type: ignore[assignment,return-value]
    for c in digests.cases():
        if not c.name.startswith("input."):
            yield f"digest:{c.name}", c.compute
    for kind in implemented_kinds():
        yield f"steps:{kind.label}", functools.partial(_steps_check, kind)
        yield f"contract:{kind.label}", functools.partial(_contract_check, kind)
        yield f"outputs:{kind.label}", functools.partial(_outputs_check, kind)
        yield f"retune:{kind.label}", functools.partial(_retune_check, kind)
    yield "contract:calib", _calib_check
    yield "calib:stages", _stages_check
    yield "contract:node", _node_check
    for kind in implemented_kinds():
        yield f"node:{kind.label}:sessions", functools.partial(_node_sessions, kind)
    yield "can:codec", _can_check
    yield "names", _names_check
    yield "sensor", _sensor_check


def _steps_check(kind: Any) -> str:
    """Filter.run with step counts (att_filter_step_n) over the adversarial stream, defaults and seed."""
    import numpy as np

    from attica import native
    from attica.settings import Preset, preset_settings
    from attica_dev import digests

    g, a, m = digests.adversarial_stream()
    rng = np.random.default_rng(2601)
    steps = rng.choice(np.array([1, 1, 1, 1, 2, 3, 5, 17, 400], np.uint32), g.shape[0]).astype(np.uint32)
    steps[[50, 300]] = [65535, 1000]
    parts = []
    for preset in (Preset.DEFAULT, Preset.SEED):
        f = native.Filter(kind, settings=preset_settings(kind, preset, digests.dt()))
        parts.append(f.run(g, a, m, full=True, check_units=False, steps=steps).tobytes())
        r = f.step(g[0], a[0], m[0], n=7)
        parts.append(np.asarray(r).tobytes())
    return _sha(*parts)


def _outputs_check(kind: Any) -> str:
    """Every output written whatever the caller's buffer held (poisoned with 0xA5 bytes).

    att_filter_step, att_filter_step_n, att_filter_output, att_filter_accel, before and after valid
    samples, after reset, with and without the stages; heading calls; the calls with NULL arguments.
    """
    import numpy as np

    from attica.calibration.stages import StageSettings, fill_c
    from attica.native import ffi, lib
    from attica_dev import digests

    g, a, m = digests.adversarial_stream()
    parts: list[Any] = []
    f = ffi.new("att_filter_t *")
    s = ffi.new("att_filter_settings_t *")
    out = ffi.new("att_output_t *")
    acc = ffi.new("att_accel_t *")
    smp = ffi.new("att_sample_t *")
    cs = ffi.new("att_calib_settings_t *")
    fill_c(cs, StageSettings(accel_outputs=True, remap=3, convention=2))

    def poison(x: Any) -> None:
        ffi.memmove(x, b"\xa5" * ffi.sizeof(x[0]), ffi.sizeof(x[0]))

    def record(tag: Any) -> None:
        parts.append((tag, bytes(ffi.buffer(out)), _values(acc)))

    for variant in range(3):
        parts.append(lib.att_filter_settings_default(int(kind), 0.01, s))
        parts.append(lib.att_filter_init(f, int(kind), s))
        if variant == 2:
            parts.append(lib.att_filter_calibrate(f, cs))
        for i in list(range(0, 12)) + [150, 151, 400]:
            smp.gyr, smp.acc, smp.mag = (tuple(float(x) for x in v[i]) for v in (g, a, m))
            if variant == 1 and i < 3:
                smp.acc = (0.0, 0.0, 0.0)
            poison(out)
            n = 1 + i % 3
            flags = lib.att_filter_step_n(f, smp, n, out) if n > 1 else lib.att_filter_step(f, smp, out)
            record(("step", i, flags))
            poison(out)
            lib.att_filter_output(f, out)
            poison(acc)
            lib.att_filter_accel(f, acc)
            record(("output", i))
            if i == 5:
                lib.att_filter_reset(f)
                poison(out)
                lib.att_filter_output(f, out)
                record("reset")
    parts.append(lib.att_filter_step(f, smp, ffi.NULL))
    parts.append(lib.att_filter_step(f, ffi.NULL, out))
    parts.append(lib.att_filter_step(ffi.NULL, smp, out))
    parts.append(lib.att_filter_step_n(f, smp, 0, out))
    parts.append((lib.att_filter_init(f, int(kind), ffi.NULL), lib.att_filter_init(ffi.NULL, int(kind), s)))
    parts.append((lib.att_filter_retune(f, ffi.NULL), lib.att_filter_calibrate(f, ffi.NULL)))
    parts.append(
        (lib.att_filter_set_heading(ffi.NULL, 0.0), lib.att_filter_heading_update(ffi.NULL, 0.0, 0.5, True))
    )
    parts.append(lib.att_filter_settings_default(int(kind), 0.01, ffi.NULL))
    fresh = ffi.new("att_filter_t *")
    poison(fresh)
    poison(out)
    lib.att_filter_output(ffi.NULL, out)
    record("null output")
    parts.append(lib.att_filter_step(fresh, smp, ffi.NULL))
    parts.append((lib.att_filter_set_heading(fresh, 1.0), lib.att_filter_retune(fresh, s)))
    for heading, gain, valid in (
        (1.0, 0.5, True),
        (float("nan"), 0.5, True),
        (1.0, 2.0, True),
        (7.0, 0.5, False),
    ):
        lib.att_filter_init(f, int(kind), s)
        for i in range(5):
            smp.gyr, smp.acc, smp.mag = (tuple(float(x) for x in v[i]) for v in (g, a, m))
            lib.att_filter_step(f, smp, ffi.NULL)
        parts.append(
            (lib.att_filter_heading_update(f, heading, gain, valid), lib.att_filter_set_heading(f, heading))
        )
        poison(out)
        lib.att_filter_output(f, out)
        record(("heading", heading, gain))
    return _sha(parts, np.zeros(1))


RETUNES: dict[str, list[dict[str, Any]]] = {
    "ars": [{"bias_mode": 2}, {"tau": 0.5, "gain": 0.0, "tau_acc_lp": 0.0}, {"integration": 1}],
    "mars": [{"mag_mode": 1}, {"bias_mode": 0}, {"tau_mag": 0.0, "alpha_mag": 0.05}],
    "kf": [{"gate": 20.0, "r_accel": 50.0}, {"noise_rates": False}, {"bias_mode": 2, "tau_acc_lp": 0.0}],
    "ekf": [{"gate": 9.0, "r_accel": 10.0}, {"q_bias": 1e-12}, {"noise_rates": False, "cos_min": 0.2}],
    "gyro": [{"cos_min": 0.2}, {"cos_min": 1e-6}, {"gyro_range": 1.0}, {"dt": 0.02}],
    "tilt": [{"normalise": False}, {"normalise": True}],
    "mekf": [
        {"gyro_scale_sd": 0.05},
        {"gyro_scale_sd": 0.02, "accel_noise": 0.5},
        {"gyro_scale_sd": 0.0},
        {"use_mag": False},
        {"gyro_scale_sd": 0.03, "tau_acc_lp": 0.0, "gate": 9.0},
    ],
}
"""Retunes in sequence per kind (stage B), each after a stretch of the simulated stream: a setting switched
on, changed while on and switched off again (the retune hooks keep or restart the states)."""


def _retune_check(kind: Any) -> str:
    """A run, then each retune of :data:`RETUNES` (refused ones recorded) followed by another run."""
    import dataclasses

    from attica import native
    from attica.settings import make_settings
    from attica_dev import digests

    g, a, m = digests.sim_stream()
    jg, ja, jm = (x[:, 0] for x in _jumps())
    f = native.Filter(kind, settings=make_settings(kind, dt=digests.dt()))
    parts: list[Any] = [f.run(g[:300], a[:300], m[:300], full=True, check_units=False).tobytes()]
    names = {fl.name for fl in dataclasses.fields(make_settings(kind))}
    for j, change in enumerate(RETUNES.get(kind.label, [])):
        change = {k: v for k, v in change.items() if k in names}
        try:
            f.retune(**change)
            parts.append(("ok", j))
        except (native.NativeError, ValueError) as e:
            parts.append(("refused", j, type(e).__name__))
        lo, hi = 300 + 250 * j, 550 + 250 * j
        parts.append(f.run(g[lo:hi], a[lo:hi], m[lo:hi], full=True, check_units=False).tobytes())
        lo, hi = 200 * j, 200 * j + 200
        parts.append(f.run(jg[lo:hi], ja[lo:hi], jm[lo:hi], full=True, check_units=False).tobytes())
    return _sha(parts)


def _leaves(ctype: Any, prefix: str = "") -> list[tuple[str, Any]]:
    """(dotted path, C type) of every scalar member of a struct type."""
    out = []
    for name, fld in ctype.fields:
        path = f"{prefix}{name}"
        t = fld.type
        if t.kind == "struct":
            out.extend(_leaves(t, path + "."))
        elif t.kind == "array":
            out.extend((f"{path}.{i}", t.item) for i in range(t.length))
        else:
            out.append((path, t))
    return out


def _set(obj: Any, path: str, value: Any) -> bool:
    *head, last = path.split(".")
    for name in head:
        obj = obj[int(name)] if name.isdigit() else getattr(obj, name)
    try:
        if last.isdigit():
            obj[int(last)] = value
        else:
            setattr(obj, last, value)
    except (OverflowError, TypeError, ValueError):
        return False
    return True


def _probe_values(ctype: Any, lo: float, hi: float) -> list[Any]:
    """Values to try in a field: the bounds and their neighbours outside, specials (floats); edges (ints)."""
    import numpy as np

    if ctype.cname == "float":
        f32 = np.float32
        vals = [lo, hi, float(np.nextafter(f32(lo), f32(-np.inf))), float(np.nextafter(f32(hi), f32(np.inf)))]
        vals += [float(np.nextafter(f32(lo), f32(np.inf))), float(np.nextafter(f32(hi), f32(-np.inf)))]
        vals += [0.0, -0.0, 1.0, -1.0, 1e-45, -1e-45, 0.5, 3e38, float("nan"), float("inf"), float("-inf")]
        return [float(f32(v)) if np.isfinite(v) else v for v in vals]
    if ctype.cname in ("_Bool", "bool"):
        return [False, True]
    ints = [0, 1, 2, 3, 4, 5, 7, 8, 25, 255, 65535, 0xFFFFFFFF, -1]
    for b in (lo, hi):
        if np.isfinite(b) and abs(b) < 2**32:
            ints += [int(b) - 1, int(b), int(b) + 1]
    return ints


def _rules(call: Callable[[int, Any], int]) -> list[tuple[Any, ...]]:
    from attica.native import ffi

    r = ffi.new("att_settings_error_t *")
    out: list[tuple[Any, ...]] = []
    for i in range(400):
        status = int(call(i, r))
        if r.field == ffi.NULL:
            out.append(("end", status))
            return out
        out.append((ffi.string(r.field), ffi.string(r.rule), ffi.string(r.unit), r.min, r.max, status))
    return out


def _filter_rule(kind: int, s: Any, index: int, r: Any) -> int:
    from attica.native import lib

    return int(lib.att_filter_settings_rule(kind, s, index, r))


def _calib_rule(s: Any, index: int, r: Any) -> int:
    from attica.native import lib

    return int(lib.att_calib_settings_rule(s, index, r))


def _node_rule(s: Any, index: int, r: Any) -> int:
    from attica.native import lib

    return int(lib.att_node_settings_rule(s, index, r))


def _why(r: Any) -> tuple[Any, ...]:
    from attica.native import ffi

    def text(p: Any) -> bytes | None:
        return ffi.string(p) if p != ffi.NULL else None

    return (text(r.field), r.min, r.max, text(r.rule), text(r.unit))


def _bounds(rules: list[tuple[Any, ...]]) -> dict[str, tuple[float, float]]:
    out: dict[str, tuple[float, float]] = {}
    for r in rules:
        if r[0] != "end":
            name = r[0].decode().split(".", 1)[1] if b"." in r[0] else r[0].decode()
            out[name] = (float(r[3]), float(r[4]))
    return out


def _contract_check(kind: Any) -> str:
    """The kind's settings contract: its listing and every field probed (check, validate, init, retune)."""
    import math

    from attica.native import ffi, lib
    from attica.settings import Preset

    parts: list[Any] = []
    why = ffi.new("att_settings_error_t *")
    f = ffi.new("att_filter_t *")
    for preset in Preset:
        for dt in (0.01, 1e-6, 1.0):
            s0 = ffi.new("att_filter_settings_t *")
            ffi.memmove(s0, b"\xa5" * ffi.sizeof(s0[0]), ffi.sizeof(s0[0]))  # every field written?
            parts.append(lib.att_filter_settings_preset(int(kind), int(preset), dt, s0))
            parts.append(bytes(ffi.buffer(ffi.addressof(s0[0], kind.label))))
            rules = _rules(functools.partial(_filter_rule, int(kind), s0))
            parts.append(rules)
            bounds = _bounds(rules)
            parts.append((lib.att_filter_settings_check(int(kind), s0, why), _why(why)))
            if dt != 0.01:
                continue
            member = ffi.typeof(f"att_{kind.label}_settings_t")
            for path, ctype in _leaves(member):
                key = path if path in bounds else path.rsplit(".", 1)[0]
                lo, hi = bounds.get(key, (-math.inf, math.inf))
                for v in _probe_values(ctype, lo, hi):
                    s = ffi.new("att_filter_settings_t *")
                    ffi.memmove(s, s0, ffi.sizeof("att_filter_settings_t"))
                    if not _set(getattr(s, kind.label), path, v):
                        continue
                    st = lib.att_filter_settings_check(int(kind), s, why)
                    valid = lib.att_filter_settings_validate(int(kind), s)
                    init = lib.att_filter_init(f, int(kind), s)
                    assert lib.att_filter_init(f, int(kind), s0) == lib.ATT_OK
                    parts.append((path, v, st, _why(why), valid, init, lib.att_filter_retune(f, s)))
    for k in (0, 8, 99):
        s = ffi.new("att_filter_settings_t *")
        parts.append(
            (k, lib.att_filter_settings_default(k, 0.01, s), lib.att_filter_settings_check(k, s, why))
        )
    return _sha(parts)


def _calib_check() -> str:
    """The stages' contract: listing, every field probed (check, validate, calibrate), field set/get."""
    import math

    from attica.native import ffi, lib

    parts: list[Any] = []
    cs0 = ffi.new("att_calib_settings_t *")
    ffi.memmove(cs0, b"\xa5" * ffi.sizeof(cs0[0]), ffi.sizeof(cs0[0]))  # every field written?
    lib.att_calib_settings_default(cs0)
    parts.append(_values(cs0))
    rules = _rules(functools.partial(_calib_rule, cs0))
    parts.append(rules)
    bounds = _bounds(rules)
    f = ffi.new("att_filter_t *")
    fs = ffi.new("att_filter_settings_t *")
    lib.att_filter_settings_default(1, 0.01, fs)
    for path, ctype in _leaves(ffi.typeof("att_calib_settings_t")):
        parent = path.rsplit(".", 1)[0]
        lo, hi = bounds.get(path, bounds.get(parent, (-math.inf, math.inf)))
        for v in _probe_values(ctype, lo, hi):
            cs = ffi.new("att_calib_settings_t *")
            ffi.memmove(cs, cs0, ffi.sizeof("att_calib_settings_t"))
            if not _set(cs, path, v):
                continue
            lib.att_filter_init(f, 1, fs)
            res = (path, v, lib.att_calib_settings_check(cs), lib.att_calib_settings_validate(cs))
            parts.append((*res, lib.att_filter_calibrate(f, cs), _rules(functools.partial(_calib_rule, cs))))
    parts.append(_matrix_probes(cs0, f, fs))
    val = ffi.new("float *")
    for i in range(-1, 60):
        for x in (
            0.25 + i,
            0.0,
            1.0,
            2.0,
            3.0,
            -1.0,
            0.5,
            24.0,
            25.0,
            4294967296.0,
            float("nan"),
            float("inf"),
        ):
            cs = ffi.new("att_calib_settings_t *")
            lib.att_calib_settings_default(cs)
            ok = lib.att_calib_field_set(cs, i & 0xFFFFFFFF, x)
            val[0] = -7.0
            got = lib.att_calib_field_get(cs, i & 0xFFFFFFFF, val)
            parts.append((i, x, ok, got, val[0], bytes(ffi.buffer(cs))))
    for r in range(0, 27):
        name = lib.att_calib_remap_name(r)
        text = ffi.string(name) if name != ffi.NULL else None
        parts.append((r, text, lib.att_calib_remap_parse(text) if text else None))
    for bad in (b"", b"+x+y", b"+x+y+x", b"-z-y-x", b"+x+y+z+", b"?"):
        parts.append(lib.att_calib_remap_parse(bad))
    return _sha(parts)


def _matrix_probes(cs0: Any, f: Any, fs: Any) -> list[Any]:
    """Whole matrices in each matrix of the stages: well and badly conditioned, singular, huge, tiny."""
    import numpy as np

    from attica.native import ffi, lib

    rng = np.random.default_rng(2612)
    mats: list[Any] = [np.zeros(9), np.eye(3).ravel() * 1e3, np.diag([1.0, 1.0, 1e-4]).ravel()]
    mats += [np.diag([1.0, 1.0, 1e-3]).ravel(), np.diag([1.0, -1.0, 1.0]).ravel(), np.full(9, 1e3)]
    for i in range(60):
        u, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        v, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        cond = [1.0, 10.0, 999.0, 1001.0, 3000.0, 3200.0, 1e5][i % 7]
        sv = np.array([cond, np.sqrt(cond), 1.0]) / cond * 10 ** rng.uniform(-2, 2.9)
        mats.append((u @ np.diag(sv) @ v.T).ravel() * (-1 if i % 2 else 1))
    for _ in range(60):
        mats.append(rng.normal(size=9) * 10 ** rng.uniform(-25, 4, 9))
    out: list[Any] = []
    for name in ("gyro.misalignment", "accel.misalignment", "mag.soft_iron"):
        group, member = name.split(".")
        for m in mats:
            cs = ffi.new("att_calib_settings_t *")
            ffi.memmove(cs, cs0, ffi.sizeof("att_calib_settings_t"))
            arr = getattr(getattr(cs, group), member)
            for j, x in enumerate(np.asarray(m, np.float32)):
                arr[j] = float(x)
            lib.att_filter_init(f, 1, fs)
            out.append((lib.att_calib_settings_check(cs), lib.att_filter_calibrate(f, cs)))
    return out


def _values(x: Any) -> Any:
    """The members of a C value, recursively (structs and arrays as tuples; padding left out)."""
    from attica.native import ffi

    if not isinstance(x, ffi.CData):
        return x
    t = ffi.typeof(x)
    if t.kind == "pointer":
        return _values(x[0])
    if t.kind == "array":
        return tuple(_values(x[i]) for i in range(len(x)))
    if t.kind == "struct":
        return tuple((name, _values(getattr(x, name))) for name, _ in t.fields)
    return x


def _stages_check() -> str:
    """att_calib_init's folded stages and att_calib_apply on nasty samples.

    Every remap, with and without a model, a mounting quaternion, each convention; the conventions'
    quaternion and vector maps.
    """
    import numpy as np

    from attica.calibration.stages import StageSettings, fill_c
    from attica.native import ffi, lib
    from attica_dev import golden

    rng = np.random.default_rng(2613)
    sp = golden.special_floats()
    n = 500
    v = rng.normal(0.0, 5.0, (n, 3)).astype(np.float32)
    pick = rng.random((n, 3)) < 0.1
    v[pick] = rng.choice(sp, int(pick.sum()))
    v[::50] = 0.0
    parts: list[Any] = []
    for i in range(60):
        kw: dict[str, Any] = {}
        if i % 2:
            m = (np.eye(3) + rng.normal(0, 0.02, (3, 3))).ravel()
            kw = {
                "gyro_misalignment": tuple(m),
                "gyro_sensitivity": tuple(rng.uniform(0.9, 1.1, 3)),
                "gyro_offset": tuple(rng.normal(0, 0.02, 3)),
                "accel_misalignment": tuple(m[::-1]),
                "accel_sensitivity": tuple(rng.uniform(0.9, 1.1, 3)),
                "accel_offset": tuple(rng.normal(0, 0.2, 3)),
                "soft_iron": tuple((np.eye(3) + rng.normal(0, 0.05, (3, 3))).ravel()),
                "hard_iron": tuple(rng.normal(0, 20, 3)),
            }
        elif i % 4 == 2:
            kw = {"hard_iron": (1.0, -2.0, 0.5)}
        remap = i % 25
        if remap == 0 and i % 3:
            q = rng.normal(size=4)
            kw["mounting"] = tuple(q / np.linalg.norm(q))
        s = StageSettings(remap=remap, convention=i % 3, accel_outputs=bool(i % 2), **kw)
        cs = ffi.new("att_calib_settings_t *")
        fill_c(cs, s)
        c = ffi.new("att_calib_t *")
        parts.append((lib.att_calib_init(c, cs), _values(c)))
        g, a, m_ = v.copy(), v.copy(), v.copy()
        buf = [ffi.from_buffer("float[]", x) for x in (g, a, m_)]
        lib.att_host_calib_apply(c, *buf, n)
        parts.append(g.tobytes() + a.tobytes() + m_.tobytes())
    for conv in range(4):
        for row in golden.math_inputs("quat_mul", 40, seed=conv)[:, :4]:
            q = ffi.new("att_quat_t *", tuple(float(x) for x in row))
            parts.append(_values(lib.att_calib_quat_to(q[0], conv)))
            w = ffi.new("att_vec3_t *", tuple(float(x) for x in row[1:]))
            parts.append(_values(lib.att_calib_vec_to(w[0], conv)))
    return _sha(parts)


def _node_check() -> str:
    """The node's contract and timing functions: listing, fields probed (check, init), bus load."""
    import math

    from attica.native import ffi, lib

    parts: list[Any] = []
    why = ffi.new("att_settings_error_t *")
    node = ffi.new("att_node_t *")
    for kind in range(0, 9):
        for rate in (100.0, 1000.0, 0.5, 1e5):
            s0 = ffi.new("att_node_settings_t *")
            parts.append((kind, rate, lib.att_node_settings_default(kind, rate, s0)))
            if kind not in (1, 2):
                continue
            rules = _rules(functools.partial(_node_rule, s0))
            parts.append(rules)
            parts.append((lib.att_node_settings_check(s0, why), _why(why), lib.att_node_bus_load(s0)))
            if rate != 100.0:
                continue
            bounds = _bounds(rules)
            for path, ctype in _leaves(ffi.typeof("att_node_settings_t")):
                if path.split(".")[0] in ("filter", "calib"):
                    continue
                lo, hi = bounds.get(path, (-math.inf, math.inf))
                for v in _probe_values(ctype, lo, hi):
                    s = ffi.new("att_node_settings_t *")
                    ffi.memmove(s, s0, ffi.sizeof("att_node_settings_t"))
                    if not _set(s, path, v):
                        continue
                    st = lib.att_node_settings_check(s, why)
                    parts.append(
                        (path, v, st, _why(why), lib.att_node_init(node, s), lib.att_node_bus_load(s))
                    )
    cb = ffi.callback("void(void *, att_can_bus_diag_t *)", lambda ctx, d: None)
    for rate in (100.0, 500.0, 1000.0, 2000.0, 4000.0):
        for bitrate, data_bitrate in (
            (125_000, 0),
            (250_000, 0),
            (500_000, 2_000_000),
            (1_000_000, 8_000_000),
        ):
            for fd, accel, divider in (
                (False, False, 1),
                (False, True, 0),
                (True, True, 7),
                (True, False, 1),
            ):
                s = ffi.new("att_node_settings_t *")
                lib.att_node_settings_default(1, rate, s)
                s.bitrate, s.data_bitrate, s.fd, s.accel_out, s.diag_divider = (
                    bitrate,
                    data_bitrate if fd else 0,
                    fd,
                    accel,
                    divider,
                )
                st = lib.att_node_init(node, s)
                parts.append((st, lib.att_node_bus_load(s), lib.att_node_settings_check(s, why), _why(why)))
                if st == lib.ATT_OK:
                    parts.append((lib.att_node_set_bus_diag(node, cb, ffi.NULL), node.bus_diag != ffi.NULL))
    for n in range(0, 70):
        parts.append((n, lib.att_node_classic_bits(n)))
        for br, dbr in ((1_000_000, 5_000_000), (500_000, 2_000_000), (125_000, 0), (0, 0)):
            parts.append(lib.att_node_fd_frame_time(n, br, dbr))
    return _sha(parts)


def _node_sessions(kind: Any) -> str:
    """The node with what att_node_run cannot set, over the rough streams.

    Stages at init, accel outputs, a DIAG divider, the persistence hook (failing every other save) and
    a port's bus counters.
    """
    import numpy as np

    from attica.calibration.stages import StageSettings, fill_c
    from attica.native import ffi, lib

    parts: list[Any] = []
    saves: list[Any] = []

    def persist(ctx: Any, cal: Any) -> bool:
        saves.append(_values(cal))
        return len(saves) % 2 == 1

    def bus(ctx: Any, d: Any) -> None:
        d.state, d.lec = len(saves) % 4, 6
        d.bus_off, d.recoveries, d.error_passive, d.error_warning, d.rx_overruns = 1, 2, 3, 4, 300

    persist_cb = ffi.callback("bool(void *, const att_calib_settings_t *)", persist)
    bus_cb = ffi.callback("void(void *, att_can_bus_diag_t *)", bus)
    stages = StageSettings(
        gyro_offset=(0.01, -0.02, 0.005),
        accel_sensitivity=(0.998, 1.003, 1.0),
        hard_iron=(3.0, -2.0, 5.0),
        remap=7,
        convention=1,
    )
    node = ffi.new("att_node_t *")
    f = ffi.new("att_can_frame_t *")
    for fd in (False, True):
        frames = np.ascontiguousarray(_rough_frames(kind, fd))
        for variant in range(2):
            s = ffi.new("att_node_settings_t *")
            parts.append(lib.att_node_settings_default(int(kind), 200.0, s))
            s.fd = fd
            s.data_bitrate = 5_000_000 if fd else 0
            s.accel_out = True
            s.diag_divider = 3 if variant else 1
            if variant:
                fill_c(s.calib, stages)
            parts.append(lib.att_node_init(node, s))
            lib.att_node_set_persist(node, persist_cb, ffi.NULL)
            parts.append(lib.att_node_set_bus_diag(node, bus_cb if variant else ffi.NULL, ffi.NULL))
            buf = ffi.from_buffer("att_can_frame_t[]", frames)
            seen = bytearray()
            fbuf = ffi.buffer(f)
            for i in range(len(frames)):
                seen += bytes((lib.att_node_rx(node, buf + i), lib.att_node_poll(node) & 0xFF))
                seen += lib.att_node_tx_pending(node).to_bytes(4, "little")
                while lib.att_node_tx(node, f):
                    seen += fbuf[:70]  # id, len, fd, data (not the tail padding)
            parts.append(bytes(seen))
            parts.append((_values(node.stats), lib.att_node_error_count(node), saves[:]))
            ids = ffi.new("uint32_t[]", 64)
            parts.append((lib.att_node_rx_ids(node, ids), list(ids)))
    # an IMU on the node's board: samples pushed (between frames), the tx ring drained only now and then
    from attica_dev import digests

    g, a, m = digests.adversarial_stream()
    s = ffi.new("att_node_settings_t *")
    lib.att_node_settings_default(int(kind), 200.0, s)
    s.accel_out = True
    parts.append(lib.att_node_init(node, s))
    smp = ffi.new("att_sample_t *")
    frames = np.ascontiguousarray(_rough_frames(kind, False))
    buf = ffi.from_buffer("att_can_frame_t[]", frames)
    seen = bytearray()
    fbuf = ffi.buffer(f)
    for i in range(300):
        smp.gyr, smp.acc, smp.mag = (tuple(float(x) for x in v[i]) for v in (g, a, m))
        if i % 10 == 3:
            lib.att_node_rx(node, buf + i)
        seen += bytes((lib.att_node_push_sample(node, smp),))
        while i % 7 != 0 and lib.att_node_tx(node, f):
            seen += fbuf[:70]
    parts.append((bytes(seen), _values(node.stats)))
    d = ffi.new("att_can_diag_t *")
    lib.att_node_diag(node, d)
    parts.append(_values(d))
    null = ffi.NULL
    parts.append((lib.att_node_rx(node, null), lib.att_node_rx(null, f), lib.att_node_push_sample(null, smp)))
    parts.append(
        (lib.att_node_push_sample(node, null), lib.att_node_tx(null, f), lib.att_node_tx(node, null))
    )
    parts.append((lib.att_node_poll(null), lib.att_node_tx_pending(null), lib.att_node_rx_ids(null, ids)))
    parts.append(
        (
            lib.att_node_init(null, s),
            lib.att_node_init(node, null),
            lib.att_node_set_bus_diag(null, null, null),
        )
    )
    why = ffi.new("att_settings_error_t *")
    parts.append(
        (lib.att_node_settings_default(int(kind), 100.0, null), lib.att_node_settings_check(null, why))
    )
    parts.append(_why(why))
    return _sha(parts)


def _can_check() -> str:
    """The CAN codec: quantisation, CRCs, message table, check and seal, encoders and decoders."""
    import numpy as np

    from attica.native import ffi, lib
    from attica_dev import golden

    parts: list[Any] = []
    xs = np.concatenate([golden.special_floats(), np.linspace(-40, 40, 161, dtype=np.float32)])
    for frac in (-31, -30, -1, 0, 5, 8, 10, 13, 14, 15, 30, 31):
        q = [lib.att_can_quantise(float(x), frac) for x in xs]
        parts.append(
            (frac, q, [lib.att_can_dequantise(v, frac) for v in (-32768, -32767, -1, 0, 1, 12345, 32767)])
        )
    rng = np.random.default_rng(7)
    for n in (0, 1, 7, 8, 63, 64):
        data = bytes(rng.integers(0, 256, n, dtype=np.uint8))
        buf = ffi.new("uint8_t[]", data or b"\0")
        parts.append(
            (lib.att_can_crc8(buf, n, 0xFF), lib.att_can_crc8(buf, n, 0), lib.att_can_e2e_crc(0xA05, buf, n))
        )
    for cid in range(0, 0x800):
        parts.append((lib.att_can_msg_len(cid), lib.att_can_msg_has_crc(cid), lib.att_can_data_id(cid)))
    fr = ffi.new("att_can_frame_t *")
    for cid in (
        0x100,
        0x101,
        0x102,
        0x110,
        0x200,
        0x204,
        0x205,
        0x206,
        0x209,
        0x20A,
        0x210,
        0x211,
        0x300,
        0x7FF,
    ):
        for length in (0, 2, 7, 8, 9, 64):
            for fd in (0, 1):
                fr.id, fr.len, fr.fd = cid, length, fd
                for j in range(64):
                    fr.data[j] = int(rng.integers(0, 256))
                parts.append((cid, length, fd, lib.att_can_check(fr), lib.att_can_counter(fr)))
                lib.att_can_seal(fr)
                parts.append((lib.att_can_check(fr), bytes(fr.data)))
    parts.append(_codec_roundtrips())
    cmd = ffi.new("att_can_cmd_t *")
    for c_, arg, value, counter in ((3, 1, 0.75, 5), (1, 7, float("nan"), 15), (200, 255, -1e30, 16)):
        cmd.cmd, cmd.arg, cmd.value, cmd.counter = c_, arg, value, counter & 0xFF
        lib.att_can_encode_cmd(cmd, fr)
        back = ffi.new("att_can_cmd_t *")
        parts.append(
            (bytes(fr.data), fr.id, fr.len, lib.att_can_decode_cmd(fr, back), bytes(ffi.buffer(back)))
        )
    return _sha(parts)


def _codec_roundtrips() -> list[Any]:
    """Every encoder on random and special values, its frames checked, corrupted and decoded again."""
    import numpy as np

    from attica.native import ffi, lib
    from attica_dev import golden

    rng = np.random.default_rng(2614)
    sp = golden.special_floats()

    def floats(n: int, scale: float) -> list[float]:
        x = rng.normal(0.0, scale, n).astype(np.float32)
        pick = rng.random(n) < 0.15
        x[pick] = rng.choice(sp, int(pick.sum()))
        return [float(v) for v in x]

    out: list[Any] = []
    fr = ffi.new("att_can_frame_t[6]")

    def frames(k: int) -> None:
        for j in range(k):
            out.append((_values(fr[j]), lib.att_can_check(ffi.addressof(fr, j)), lib.att_can_counter(fr + j)))
            bad = ffi.new("att_can_frame_t *", fr[j])
            bad.data[int(rng.integers(0, 8))] ^= 1 << int(rng.integers(0, 8))
            out.append(lib.att_can_check(bad))

    for i in range(40):
        counter = int(rng.integers(0, 256))
        smp = ffi.new("att_sample_t *")
        for name, scale in (("gyr", 5.0), ("acc", 30.0), ("mag", 200.0)):
            setattr(smp, name, floats(3, scale))
        if i % 5 == 0:
            smp.mag = (float("nan"),) * 3
        v = ffi.new("att_vec3_t *")
        lib.att_can_encode_imu(smp, counter, fr)
        frames(3)
        out.extend((lib.att_can_decode_imu_part(fr + j, v), _values(v)) for j in range(4))
        lib.att_can_encode_imu_fd(smp, counter, fr)
        frames(1)
        back = ffi.new("att_sample_t *")
        out.append((lib.att_can_decode_imu_fd(fr, back), _values(back)))
        acc = ffi.new("att_accel_t *")
        acc.gravity, acc.linear, acc.earth = floats(3, 9.8), floats(3, 50.0), floats(3, 50.0)
        acc.valid = int(rng.choice([0, 1, int(lib.ATT_OUT_ACCEL), int(lib.ATT_OUT_ACCEL)]))
        lib.att_can_encode_accel(acc, counter, fr)
        frames(2)
        out.extend((lib.att_can_decode_accel_part(fr + j, v), _values(v)) for j in range(3))
        lib.att_can_encode_accel_fd(acc, counter, fr)
        frames(1)
        acc2 = ffi.new("att_accel_t *")
        ffi.memmove(acc2, b"\xa5" * ffi.sizeof(acc2[0]), ffi.sizeof(acc2[0]))
        out.append((lib.att_can_decode_accel_fd(fr, acc2), _values(acc2)))
        ack = ffi.new("att_can_cal_ack_t *", [int(x) for x in rng.integers(0, 256, 7)])
        lib.att_can_encode_cal_ack(ack, fr)
        frames(1)
        ack2 = ffi.new("att_can_cal_ack_t *")
        out.append((lib.att_can_decode_cal_ack(fr, ack2), _values(ack2)))
        o = ffi.new("att_output_t *")
        o.q, o.euler, o.gyro_bias = floats(4, 1.0), floats(3, 3.0), floats(3, 0.5)
        for j, c in enumerate(floats(4, 1e-3)):
            o.cov[j] = c
        o.flags, o.steps, o.valid = (int(x) for x in rng.integers(0, 2**32, 3, dtype=np.uint64))
        kind = int(rng.integers(0, 9))
        n = lib.att_can_encode_output_set(o, kind, counter, int(rng.integers(0, 256)), fr)
        frames(int(n))
        out.append((n, lib.att_can_status_crc(fr + 5, fr, fr + 1, fr + 2)))
        for j in range(int(n)):
            o2 = ffi.new("att_output_t *")
            out.append((lib.att_can_decode_output(fr + j, o2), _values(o2)))
        lib.att_can_encode_output_fd(o, kind, counter, fr)
        frames(1)
        o2 = ffi.new("att_output_t *")
        out.append((lib.att_can_decode_output(fr, o2), _values(o2)))
        st = ffi.new("att_can_status_t *", [int(x) for x in rng.integers(0, 256, 2)])
        st.flags, st.steps = (int(x) for x in rng.integers(0, 65536, 2))
        st.error_count, st.ack = (int(x) for x in rng.integers(0, 256, 2))
        lib.att_can_encode_status(st, fr)
        frames(1)
        st2 = ffi.new("att_can_status_t *")
        out.append((lib.att_can_decode_status(fr, st2), _values(st2)))
        d = ffi.new("att_can_diag_t *", [int(x) for x in rng.integers(0, 400, 6)])
        lib.att_can_encode_diag(d, counter, fr)
        frames(1)
        bd = ffi.new("att_can_bus_diag_t *", [int(x) for x in rng.integers(0, 8, 2)])
        bd.bus_off, bd.recoveries, bd.error_passive, bd.error_warning, bd.rx_overruns = (
            int(x) for x in rng.integers(0, 400, 5)
        )
        lib.att_can_encode_diag_bus(bd, counter, fr)
        frames(1)
        bd2 = ffi.new("att_can_bus_diag_t *")
        out.append((lib.att_can_decode_diag_bus(fr, bd2), _values(bd2)))
    return out


def _sensor_check() -> str:
    """The public sample checks (att_sensor.h; the filters use their inline twins) on special vectors."""
    import numpy as np

    from attica.native import ffi, lib
    from attica_dev import golden

    rows = golden.math_inputs("vec3_cross", 600, seed=5)
    rows = np.concatenate([rows[:, :3], rows[:, 3:], np.zeros((4, 3), np.float32)])
    rows[-3] = (float(2.0**-50), 0.0, 0.0)  # |v|^2 = 2^-100 exactly
    rows[-2] = (np.nan, 0.0, 0.0)
    rows[-1] = (0.0, 0.0, np.inf)
    norm = ffi.new("float *")
    parts: list[Any] = []
    for r in rows:
        v = ffi.new("att_vec3_t *", tuple(float(x) for x in r))[0]
        for rng_ in (34.906586, 156.9064, 1000.0, float(np.linalg.norm(r.astype(np.float64))), 0.0):
            norm[0] = -5.0
            a = lib.att_sensor_check_accel(v, rng_, norm)
            parts.append((lib.att_sensor_check_gyro(v, rng_), a, norm[0]))
            norm[0] = -5.0
            parts.append((lib.att_sensor_check_mag(v, rng_, norm), norm[0]))
        parts.append(_values(lib.att_sensor_tilt(v)))
    for sec in (0.0, -1.0, 0.5, 1e-9, 1e9, float("nan"), float("inf"), 3.0):
        for dt in (0.01, 1e-6, 1.0, 0.0, float("nan")):
            parts.append(lib.att_sensor_samples(sec, dt))
    return _sha(parts)


def _names_check() -> str:
    """The names of kinds, flags and calibration errors; flags formatted into buffers of every size."""
    from attica.native import ffi, lib

    def text(p: Any) -> bytes | None:
        return ffi.string(p) if p != ffi.NULL else None

    parts: list[Any] = [text(lib.att_filter_name(k)) for k in range(0, 12)]
    parts += [text(lib.att_flag_name(1 << i)) for i in range(32)]
    parts += [text(lib.att_flag_name(v)) for v in (0, 3, 0xFFFFFFFF)]
    parts += [text(lib.att_calib_error_name(e)) for e in range(0, 40)]
    buf = ffi.new("char[]", 400)
    for flags in (0, 1, 0x5, 0x8000, 0x10000, 0xFFFF, 0xFFFFFFFF, 0x80000001):
        for size in (0, 1, 2, 5, 9, 17, 64, 400):
            n = lib.att_flags_format(flags, buf if size else ffi.NULL, size)
            parts.append((flags, size, n, ffi.string(buf) if size else None))
    return _sha(parts)


# --- running mutants ----------------------------------------------------------------------------


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


# --- survivors that cannot be killed ------------------------------------------------------------


@dataclass(frozen=True)
class Explained:
    """A survivor with its reason: matched by file, the stripped source line, operator and change."""

    path: str
    source: str
    op: str
    change: str
    why: str


EXPLAINED: tuple[Explained, ...] = (
    Explained(
        "firmware/src/filters/mars/att_mars.c",
        "st->flags |= ATT_FLAG_MAG_REJECTED;",
        "BIT",
        "|= -> &=",
        (
            "unreachable: att_mars_set_m0 fails only for |m0|^2 < 2^-100 or a non-finite m0, and this m0 "
            "is a rotation of a mag sample that passed the sensor check (finite, |m|^2 >= 2^-100)"
        ),
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        "p[ATT_MEKF_IX(0u, 0u)] > 0.0f && p[ATT_MEKF_IX(1u, 1u)] > 0.0f &&",
        "CONST",
        "0.0f -> 1.0f",
        (
            "equivalent: diag_ok only selects the fast path; att_mekf_repair tests every variance (cap, > 0)"
            " and the positive definiteness again and leaves a valid P unchanged, with no flag"
        ),
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        "p[ATT_MEKF_IX(4u, 4u)] > 0.0f && p[ATT_MEKF_IX(5u, 5u)] > 0.0f;",
        "CONST",
        "4u -> 5u",
        (
            "equivalent: diag_ok only selects the fast path; att_mekf_repair tests every variance (cap, > 0)"
            " and the positive definiteness again and leaves a valid P unchanged, with no flag"
        ),
    ),
    Explained(
        "firmware/src/calib/att_calib.c",
        "if (model_identity && r > 0u) {",
        "CONST",
        "0u -> 1u",
        (
            "equivalent: remap 1 is the identity, so with an identity model it returns through the "
            "model_identity && mount_identity branch above; r > 0 and r > 1 select the same cases here"
        ),
    ),
    Explained(
        "firmware/src/calib/att_calib.c",
        "if (index < 15u) {",
        "ROR",
        "< -> <=",
        (
            "equivalent: index 15 returns from the accel-matrix branch above (index >= 15 && index < 24) "
            "and never reaches this test"
        ),
    ),
    Explained(
        "firmware/src/can/att_can.c",
        "m.crc = 0u;",
        "DEL",
        "m.crc = 0u; -> ;",
        (
            "equivalent: the packed CRC byte is overwritten by att_can_seal before the frame leaves the "
            "encoder"
        ),
    ),
    Explained(
        "firmware/src/can/att_can.c",
        "m.crc = 0u;",
        "CONST",
        "0u -> 1u",
        (
            "equivalent: the packed CRC byte is overwritten by att_can_seal before the frame leaves the "
            "encoder"
        ),
    ),
    Explained(
        "firmware/src/core/att_core.h",
        "if (!(n2 >= ATT_NORM2_MIN)) {",
        "ROR",
        ">= -> >",
        (
            "boundary: differs only for a low-passed specific force of exactly |v|^2 = 2^-100 (|v| = "
            "2^-50 m/s^2) reaching att_i_align_up; no input of the suite or the oracle lands on that "
            "float"
        ),
    ),
    Explained(
        "firmware/src/core/att_core.h",
        (
            "#define ATT_ROTVEC_Z_SMALL 0x1p-4f /* |rv|^2 up to which the series of "
            "att_i_quat_from_rotvec_fast hold */"
        ),
        "CONST",
        "0x1p-4f -> 0x1.000002p-4f",
        (
            "boundary: moves the series/exact switch by one float (|rv|^2 = 1/16 + 2^-28 only); both "
            "paths agree within 1 ulp there (tests/c/att_core_test.c) and no step's rotation vector has "
            "that square norm"
        ),
    ),
    Explained(
        "firmware/src/core/att_core.h",
        "#define ATT_ROTVEC_C2 0x1.555556p-9f     /* 1/384 */",
        "CONST",
        "0x1.555556p-9f -> 0x1.555558p-9f",
        (
            "below output precision: the z^2/384 term (z <= 1/16) moves by < 2e-11, under half an ulp of "
            "the cosine (~1); no rounding of the sum changed on any input"
        ),
    ),
    Explained(
        "firmware/src/filters/ars/att_ars.c",
        "flags |= ATT_FLAG_NUMERIC; /* keep the attitude and the low-pass states from before */",
        "BIT",
        "|= -> &=",
        (
            "unreachable: the product of the unit correction qc and the normalised q always passes "
            "att_i_quat_normalize_bounded (the suite does not reach this line either)"
        ),
    ),
    Explained(
        "firmware/src/filters/att_filter.c",
        "f->cal.acc_body = att_i_vec3(0.0f, 0.0f, 0.0f);",
        "CONST",
        "0.0f -> 1.0f",
        (
            "dead store: reset clears have_acc, acc_body is read only when have_acc, and the next step "
            "writes it before setting have_acc"
        ),
    ),
    Explained(
        "firmware/src/filters/att_filter.c",
        "out->flags = 0u;",
        "DEL",
        "out->flags = 0u; -> ;",
        (
            "dead store: every caller of att_filter_clear fills the record through the kind's hook, "
            "which writes flags"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        (
            "#define ATT_EKF_SETTLED 0x1.47ae14p-7f       /* (0.1 rad)^2: the tilt error (sin^2) that "
            "ends the convergence phase */"
        ),
        "CONST",
        "0x1.47ae14p-7f -> 0x1.47ae16p-7f",
        (
            "boundary: a threshold one ulp higher; only a tilt-error ratio within 2^-24 of it would end "
            "the convergence phase one step earlier; no input lands there"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "#define ATT_EKF_INC_S3 (-0x1.555556p-3f) /* -1/6 */",
        "CONST",
        "0x1.555556p-3f -> 0x1.555558p-3f",
        (
            "below output precision: the d^3/6 term (d <= 1/16 rad) moves by < 5e-12, under half an ulp "
            "of the sine increments; no rounding changed on any input"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "a = (a - 0x1.921fb6p+2f) - (-0x1.777a5cp-23f);",
        "CONST",
        "0x1.777a5cp-23f -> 0x1.777a5ep-23f",
        (
            "below output precision: the low part of 2 pi moves by 2^-47 rad, under half an ulp of every "
            "wrapped angle above 1e-7 rad"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        (
            "const float sum = ((((((((((((((((((p[0] + p[1]) + p[3]) + p[4]) + p[5]) + p[6]) + p[8]) + "
            "p[9]) + p[10]) +"
        ),
        "AOR",
        "+ -> -",
        (
            "equivalent: the sum only tests that P and the angles are finite; a difference is finite "
            "exactly when the sum is (no overflow at these magnitudes)"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        (
            "const float sum = ((((((((((((((((((p[0] + p[1]) + p[3]) + p[4]) + p[5]) + p[6]) + p[8]) + "
            "p[9]) + p[10]) +"
        ),
        "CONST",
        "5 -> 6",
        (
            "equivalent in reachable states: p[5] (a correlation) is non-finite only together with the "
            "variances it is computed from, which the sum still holds"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        (
            "const float sum = ((((((((((((((((((p[0] + p[1]) + p[3]) + p[4]) + p[5]) + p[6]) + p[8]) + "
            "p[9]) + p[10]) +"
        ),
        "ZERO",
        "10 -> 0",
        (
            "equivalent in reachable states: p[10] (a correlation) is non-finite only together with the "
            "variances it is computed from, which the sum still holds"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        (
            "return att_i_isfinitef(sum) && p[0] > 0.0f && p[6] > 0.0f && p[11] > 0.0f && p[15] > 0.0f "
            "&& p[18] > 0.0f &&"
        ),
        "ROR",
        "> -> >=",
        (
            "unreachable: the yaw variance p[11] starts at p0 > 0 and only grows (q_psi dt added every "
            "step, yaw is never measured), so it is never exactly 0"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "if (att_i_absf(ctm) < c->cos_min) {",
        "ROR",
        "< -> <=",
        (
            "boundary: differs only when |cos(theta_mid)| equals cos_min exactly (then ctm is replaced "
            "by the same value, sign aside); no input lands there"
        ),
    ),
    Explained(
        "firmware/src/filters/ekf/att_ekf.c",
        "s->r_accel = 0.0f;",
        "DEL",
        "s->r_accel = 0.0f; -> ;",
        "equivalent: the seed preset starts from att_ekf_settings_default, whose r_accel is already 0",
    ),
    Explained(
        "firmware/src/filters/gyro/att_gyro.c",
        "e.y = att_i_clampf(e.y, -ATT_PIO2_F, ATT_PIO2_F);",
        "DEL",
        "e.y = att_i_clampf(e.y, -ATT_PIO2_F, ATT_PIO2_F); -> ;",
        (
            "equivalent: theta = atan2(-m20, cps m00 + sps m10) where cps and sps take the signs of m00 "
            "and m10, so x >= 0 and theta is already within [-pi/2, pi/2]"
        ),
    ),
    Explained(
        "firmware/src/filters/mars/att_mars.c",
        "st->dip_hi = 0.0f;",
        "DEL",
        "st->dip_hi = 0.0f; -> ;",
        "dead store: the dip limits are read only once m0 is valid, and att_mars_m0_limits sets them then",
    ),
    Explained(
        "firmware/src/filters/mars/att_mars.c",
        (
            "if (accel_ok && c->reject_on && att_i_absf(att_i_sqrtf(n2) / c->gravity - 1.0f) > "
            "c->accel_reject) {"
        ),
        "CONST",
        "1.0f -> 0x1.000002p+0f",
        (
            "boundary: moves the rejection band by 2^-23 g; only |a| within 1.2e-7 g of the band's edge "
            "sees it"
        ),
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        "#define ATT_MEKF_UNROLL ATT_MEKF_PRAGMA(GCC unroll 6)",
        "ZERO",
        "6 -> 0",
        (
            "equivalent: unrolling changes the code, not the arithmetic (the same operations in the same "
            "order; no reassociation without fast-math)"
        ),
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        "st->dip_hi = 2.0f;",
        "CONST",
        "2.0f -> 0x1.000002p+1f",
        "equivalent: 2 means no upper dip limit (sin(dip) <= 1); 2 + 2^-22 is the same no limit",
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        (
            "if (mnorm < st->m0_lo || mnorm > st->m0_hi || me.z < st->dip_lo * mnorm || me.z > "
            "st->dip_hi * mnorm) {"
        ),
        "ROR",
        "> -> >=",
        "boundary: differs only when |m| equals the upper norm limit exactly; no input lands there",
    ),
    Explained(
        "firmware/src/filters/mekf/att_mekf.c",
        (
            "rest = gyro_ok && accel_ok && att_i_vec3_dot(d, d) < c->rest_gyro2 && n2 > c->acc2_lo && n2 "
            "< c->acc2_hi;"
        ),
        "ROR",
        "< -> <=",
        "boundary: differs only when |w - b|^2 equals rest_gyro^2 exactly; no input lands there",
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "return 8u * n + 47u + (34u + 8u * n - 1u) / 4u;",
        "ZERO",
        "1u -> 0u",
        "equivalent: 34 + 8n is 2 mod 4, so floor((33 + 8n) / 4) = floor((34 + 8n) / 4) for every n",
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "memset(s, 0, sizeof *s);",
        "CONST",
        "0 -> 1",
        (
            "equivalent: every field is assigned after the memset; only padding and the bytes of the "
            "settings union beyond the selected kind's member differ"
        ),
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "s->data_bitrate = 0u;",
        "DEL",
        "s->data_bitrate = 0u; -> ;",
        "equivalent: the memset above already zeroed it",
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "s->fd = false;",
        "DEL",
        "s->fd = false; -> ;",
        "equivalent: the memset above already zeroed it",
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "if (!(load >= 0.0f) || load > 1.0f) {",
        "ROR",
        ">= -> >",
        (
            "unreachable: a validated node's load is a positive rate times a positive frame time, never "
            "exactly 0"
        ),
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "return (a > 255u || b > 255u - a) ? 255u : a + b;",
        "ROR",
        "> -> >=",
        "equivalent: at a = 255 both sides give 255 (255 + 0 or the saturation)",
    ),
    Explained(
        "firmware/src/node/att_node.c",
        "return (a > 255u || b > 255u - a) ? 255u : a + b;",
        "CONST",
        "255u -> 256u",
        "unreachable: a is the running saturated total (<= 255), never 256 or more",
    ),
)
"""Survivors that no output can tell apart (equivalent mutants) or that only matter for states no input
reaches, each with its reason. A survivor not listed here is a gap: kill it with a test (or a case of
the oracle) or explain it here."""


def explain(m: Mutant) -> str:
    """The reason :data:`EXPLAINED` gives for a mutant ("" when none)."""
    for e in EXPLAINED:
        if e.path == m.path and e.op == m.op and e.change == m.change and e.source == m.source:
            return e.why
    return ""


# --- self test ----------------------------------------------------------------------------------


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


# --- report -------------------------------------------------------------------------------------

STATUSES = ("killed", "survived", "equivalent", "stillborn")


def _score(rs: Sequence[Result]) -> dict[str, Any]:
    """Counts by status and the score: killed / (killed + survived), percent."""
    out: dict[str, Any] = {st: sum(r.status == st for r in rs) for st in STATUSES}
    judged = out["killed"] + out["survived"]
    out["score"] = 100.0 * out["killed"] / judged if judged else 100.0
    return out


def report(results: Sequence[Result], total: int, seconds: float, jobs: int) -> str:
    """Per file: mutants, killed, survived, equivalent, stillborn, score; every survivor; the totals."""

    def row(name: str, rs: Sequence[Result]) -> str:
        c = _score(rs)
        counts = " ".join(f"{c[st]:6}" for st in STATUSES)
        return f"{name:46} {len(rs):7} {counts} {c['score']:6.1f}%"

    head = " ".join(f"{st[:6]:>6}" for st in STATUSES)
    lines = [f"{'file (firmware/src/)':46} {'mutants':>7} {head} {'score':>7}"]
    for f in sorted({r.mutant.path for r in results}):
        lines.append(row(f.removeprefix("firmware/src/"), [r for r in results if r.mutant.path == f]))
    lines.append(row("all", results))
    if any(r.covered is not None for r in results):
        lines.append(row("in covered lines (build/coverage/lines.json)", [r for r in results if r.covered]))
    else:
        lines.append("no build/coverage/lines.json (make coverage): the score is over every line")
    survivors = [r for r in results if r.status == "survived"]
    unexplained = [r for r in survivors if not r.explained]
    lines.append(
        f"{len(results)} of {total} mutants in {seconds:.0f} s with {jobs} job(s): "
        f"{len(results) / max(seconds, 1e-9):.2f} mutants/s, "
        f"{seconds * jobs / max(len(results), 1):.2f} s per mutant and job"
        f"; survivors explained {len(survivors) - len(unexplained)}, unexplained {len(unexplained)}"
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
            "seconds": round(r.seconds, 3),
        }
        for r in results
    ]
    out.update(extra)
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: list, sample and judge mutants of firmware/src; exit 1 when a survivor is unexplained."""
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
    return 1 if any(r.status == "survived" and not r.explained for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
