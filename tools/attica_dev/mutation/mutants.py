"""The mutants: the operators, where they apply, every mutant of the sources and a reproducible sample."""

from __future__ import annotations

import fnmatch
import hashlib
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from attica_dev.mutation.tokens import _KEYWORDS, _TYPE_WORDS, Token, tokenize


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
    """``n`` mutants drawn with ``seed`` (all when n <= 0 or n >= len), in their original order.

    The draw is stable under edits elsewhere: each mutant is ranked by a hash of the seed and what it
    changes (file, source line text, operator, change, and which of the equal ones it is), not by its
    position, so adding or removing code in one place leaves the picks elsewhere as they were (a
    new mutant enters the sample only by ranking among the ``n`` lowest).
    """
    if n <= 0 or n >= len(mutants):
        return list(mutants)
    seen: dict[tuple[str, str, str, str], int] = {}
    ranks: list[tuple[bytes, int]] = []
    for i, m in enumerate(mutants):
        key = (m.path, m.source, m.op, m.change)
        k = seen.get(key, 0)
        seen[key] = k + 1
        text = f"{seed}\0{m.path}\0{m.source}\0{m.op}\0{m.change}\0{k}"
        ranks.append((hashlib.sha256(text.encode()).digest(), i))
    idx = sorted(i for _, i in sorted(ranks)[:n])
    return [mutants[i] for i in idx]
