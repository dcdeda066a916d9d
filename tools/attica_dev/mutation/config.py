"""Where mutation testing works and what it compiles with.

The repository root, build/mutation, the coverage file of ``make coverage``, the compiler (``$CC``) and
the optimisation level.
"""

from __future__ import annotations

import os
from pathlib import Path

# this file is tools/attica_dev/mutation/config.py: parents[3] is the repository
ROOT = Path(__file__).resolve().parents[3]
WORK = ROOT / "build" / "mutation"
COVERAGE = ROOT / "build" / "coverage" / "lines.json"
CC = os.environ.get("CC", "gcc")
OPT = "-O2"
