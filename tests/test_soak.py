"""Soak of every filter kind in C (tests/soak/att_soak.c, docs/robustness.md) and the step counter wrap.

``make soak`` runs 1e8 steps per kind; CI runs 1e7 per kind here (ATT_SOAK_STEPS overrides).
"""

from __future__ import annotations

import os
import re
import subprocess
import time
from pathlib import Path

import pytest

from attica import kinds, native

from helpers import ROOT

ffi, lib = native.ffi, native.lib
SOAK = ROOT / "build" / "soak" / "att_soak"
STEPS = int(os.environ.get("ATT_SOAK_STEPS", "10000000"))
KINDS = kinds.labels()


@pytest.fixture(scope="module")
def soak() -> Path:
    r = subprocess.run(["make", "-s", "soak-build"], cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    return SOAK


def test_soak_every_kind(soak: Path) -> None:
    t0 = time.perf_counter()
    r = subprocess.run([str(soak), "--steps", str(STEPS)], capture_output=True, text=True, timeout=1200)
    print(r.stdout, r.stderr, f"soak: {time.perf_counter() - t0:.1f} s wall", sep="\n")
    assert r.returncode == 0, r.stdout + r.stderr
    for kind in KINDS:
        m = re.search(
            rf"att_soak: {kind} +steps (\d+), bad samples (\d+) in (\d+) bursts.*violations 0", r.stdout
        )
        assert m is not None, (kind, r.stdout)
        assert int(m.group(1)) == STEPS and int(m.group(2)) > STEPS // 1000 and int(m.group(3)) > 0


@pytest.mark.parametrize("kind", KINDS)
def test_soak_invariants_fire(soak: Path, kind: str) -> None:
    """The soak can fail: a state overwritten with NaN bytes at step 5000 is reported."""
    r = subprocess.run(
        [str(soak), "--steps", "20000", "--kind", kind, "--break-at", "5000"], capture_output=True, text=True
    )
    assert r.returncode == 1 and "VIOLATION" in r.stderr, r.stdout + r.stderr


@pytest.mark.parametrize("kind", KINDS)
def test_step_counter_wraps(kind: str) -> None:
    """out.steps is a uint32 that wraps to 0 (and on to 1) without disturbing the filter."""
    k = getattr(lib, f"ATT_FILTER_{kind.upper()}")
    s = ffi.new("att_filter_settings_t *")
    f = ffi.new("att_filter_t *")
    out = ffi.new("att_output_t *")
    sample = ffi.new(
        "att_sample_t *", {"gyr": (0.01, 0.0, 0.0), "acc": (0.0, 0.0, 9.80665), "mag": (0.0, 20.0, -40.0)}
    )
    assert lib.att_filter_settings_default(k, 0.0035, s) == lib.ATT_OK
    assert lib.att_filter_init(f, k, s) == lib.ATT_OK
    ref = ffi.new("att_filter_t *")
    ref[0] = f[0]
    state = getattr(f.u, kind).st
    state.steps = 0xFFFFFFFE
    flags = []
    for want in (0xFFFFFFFF, 0, 1):
        flags.append(lib.att_filter_step(f, sample, out))
        assert out.steps == want
    ref_out = ffi.new("att_output_t *")
    for _ in range(3):
        assert lib.att_filter_step(ref, sample, ref_out) == flags.pop(0)
    lib.att_filter_output(f, out)
    lib.att_filter_output(ref, ref_out)
    assert bytes(ffi.buffer(ffi.addressof(out[0], "q"))) == bytes(ffi.buffer(ffi.addressof(ref_out[0], "q")))
