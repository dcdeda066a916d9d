"""The C tokens of a firmware source (comments and preprocessor lines dropped, ``#define`` bodies kept)."""

from __future__ import annotations

import re
from dataclasses import dataclass

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
