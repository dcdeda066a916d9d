"""atheris targets: the host-side parsers of untrusted files (docs/robustness.md).

``ATT_HOST_TARGET`` selects the target:

- ``candump``: a candump -L log (``attica.can.monitor.read_log``: python-can's reader behind the line
  check of ``attica.can.logs``, used by ``attica monitor --log`` and ``attica verify --log``).
  Invariants: only ``LogError`` escapes; every frame read has a length that fits its format; a frame
  written back with ``candump_text`` parses to the same frame.
- ``csv``: a recording (``attica.data.load_csv``, used by ``attica eval``). Invariants: only
  ``ValueError`` escapes; a loaded recording has float32 (N, 3) gyr/acc/mag, finite gyr and acc, and a
  finite rate > 0.

Run ``python tests/fuzz/fuzz_host.py [libFuzzer options] [corpus]`` with ``PYTHONPATH=host``.
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
from pathlib import Path

import atheris

# the heavy dependencies first, uninstrumented: coverage is wanted in our parsers, and instrumenting
# numpy, python-can and cantools would take most of a short run
import can  # noqa: F401
import numpy as np

import attica.can.codec  # noqa: F401

_PARSERS = ["attica.can.logs", "attica.can.monitor", "attica.data"]  # prefixes: attica.data.* too
with atheris.instrument_imports(include=_PARSERS):
    from attica.can.monitor import LogError, candump_text, read_log
    from attica.data import load_csv

TMP = Path(tempfile.mkdtemp(prefix="attica-fuzz-", dir="/dev/shm" if os.path.isdir("/dev/shm") else None))


def _same_frame(a: object, b: object) -> bool:
    keys = ("arbitration_id", "is_extended_id", "is_remote_frame", "is_error_frame", "is_fd", "dlc")
    return all(getattr(a, k) == getattr(b, k) for k in keys) and bytes(a.data) == bytes(b.data)  # type: ignore[attr-defined]


def _reparse(text: str) -> object:
    """The one frame of a candump -L line, read back through read_log (python-can's reader)."""
    path = TMP / "again.log"
    path.write_text(text + "\n", encoding="utf-8")
    frames = list(read_log(path))
    assert len(frames) == 1, (text, frames)
    return frames[0]


def candump(data: bytes) -> None:
    path = TMP / "in.log"
    path.write_bytes(data)
    try:
        msgs = list(read_log(path))
    except LogError:
        return
    for m in msgs:
        assert len(m.data) <= (64 if m.is_fd else 8), m
        if m.is_error_frame:
            continue
        again = _reparse(candump_text(m))
        assert _same_frame(m, again), (m, again)


def csv(data: bytes) -> None:
    path = TMP / "in.csv"
    path.write_bytes(data)
    try:
        rec = load_csv(path)
    except ValueError:
        return
    n = rec.gyr.shape[0]
    for arr in (rec.gyr, rec.acc, rec.mag):
        assert arr.dtype == np.float32 and arr.shape == (n, 3), arr.shape
    assert np.isfinite(rec.gyr).all() and np.isfinite(rec.acc).all()
    assert math.isfinite(rec.rate) and rec.rate > 0.0, rec.rate


TARGETS = {"candump": candump, "csv": csv}


def main() -> None:
    target = TARGETS[os.environ.get("ATT_HOST_TARGET", "candump")]
    atheris.Setup(sys.argv, target)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
