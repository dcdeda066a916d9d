"""Shared test helpers: bit comparison, adversarial inputs, skip-or-fail under CI."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
BROAD = ROOT.parent / "shared" / "data" / "broad"
IN_CI = os.environ.get("CI") == "true"


def need(condition: bool, reason: str) -> None:
    """Skip with a printed reason when condition is false; under CI=true fail instead."""
    if condition:
        return
    if IN_CI:
        pytest.fail(f"required under CI=true: {reason}")
    print(f"SKIP: {reason}")
    pytest.skip(reason)


def broad_trials() -> list[Path]:
    """The BROAD .npz trials in ../shared (skips or fails when absent)."""
    files = sorted(BROAD.glob("*.npz")) if BROAD.is_dir() else []
    need(bool(files), f"BROAD data not found at {BROAD}")
    return files


def same_bits(a: Any, b: Any) -> np.ndarray:
    """Element-wise: identical float32 bits, or both NaN (NaN payloads are not compared)."""
    a = np.asarray(a, np.float32)
    b = np.asarray(b, np.float32)
    both_nan = np.isnan(a) & np.isnan(b)
    return (a.view(np.uint32) == b.view(np.uint32)) | both_nan


def assert_same_bits(a: Any, b: Any, what: str = "") -> None:
    """Fail with the first differing element when a and b are not bit-identical."""
    ok = same_bits(a, b)
    if not ok.all():
        idx = np.argwhere(~ok)[0]
        av = np.asarray(a, np.float32)[tuple(idx)]
        bv = np.asarray(b, np.float32)[tuple(idx)]
        raise AssertionError(
            f"{what}: {int((~ok).sum())} of {ok.size} differ; first at {tuple(idx)}: "
            f"{float(av)!r} ({float(av).hex()}) vs {float(bv)!r} ({float(bv).hex()})"
        )


def special_values() -> np.ndarray:
    """Hand-picked float32 edge cases."""
    f = np.float32
    tiny = np.finfo(np.float32).tiny
    big = np.finfo(np.float32).max
    one_up = np.nextafter(f(1), f(2))
    one_down = np.nextafter(f(1), f(0))
    vals = [
        0.0,
        -0.0,
        np.nan,
        np.inf,
        -np.inf,
        1.0,
        -1.0,
        one_up,
        -one_up,
        one_down,
        -one_down,
        tiny,
        -tiny,
        tiny / 4,
        -tiny / 4,
        1e-45,
        big,
        -big,
        1e30,
        -1e30,
        8192.0,
        -8192.0,
        np.nextafter(f(8192), f(9000)),
        0.5,
        -0.5,
        2.0,
        1e-20,
        1e-8,
    ]
    pio2 = np.float32(np.pi / 2)
    vals += [k * pio2 for k in range(-8, 9)] + [k * np.float32(np.pi / 4) for k in range(-8, 9)]
    return np.array(vals, np.float32)


def adversarial_floats(n: int, seed: int) -> np.ndarray:
    """n float32 values: random bit patterns (every class of float) mixed with special values."""
    rng = np.random.default_rng(seed)
    bits = rng.integers(0, 2**32, n, dtype=np.uint64).astype(np.uint32)
    out = bits.view(np.float32).copy()
    sv = special_values()
    idx = rng.integers(0, n, n // 4)
    out[idx] = sv[rng.integers(0, sv.size, idx.size)]
    return out


HOST_ENV = {**os.environ, "PYTHONPATH": str(ROOT / "host") + os.pathsep + os.environ.get("PYTHONPATH", "")}
"""The environment of a subprocess that imports attica from this checkout."""


def cantools_decode(log: Path, dbc: Path) -> list[str]:
    """``cantools decode --single-line DBC < LOG`` (cantools' own command line): its output lines."""
    with open(log) as fh:
        return subprocess.run(
            [sys.executable, "-m", "cantools", "decode", "--single-line", str(dbc)],
            stdin=fh,
            capture_output=True,
            text=True,
            check=True,
            env=HOST_ENV,
        ).stdout.splitlines()


def markdown_table(text: str, after: str, first_col: str) -> tuple[list[str], dict[str, list[str]], int]:
    """The first table in ``text`` after the string ``after`` whose header starts with ``first_col``.

    Returns its column names, its rows by their first cell, and the index (in the lines of the text from
    ``after`` on) of the first line after the table.
    """
    lines = text[text.index(after) :].splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith(f"| {first_col} |"))
    header = [c.strip() for c in lines[first].strip().strip("|").split("|")]
    rows: dict[str, list[str]] = {}
    i = first + 2
    while i < len(lines) and lines[i].startswith("|"):
        cells = [c.strip() for c in lines[i].strip().strip("|").split("|")]
        rows[cells[0]] = cells
        i += 1
    return header, rows, i
