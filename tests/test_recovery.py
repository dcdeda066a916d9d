"""The recovery contract (issue 26): from any accepted settings and any state a fuzzed stream leaves, N clean
samples bring every kind back to an output that is not NUMERIC and valid.

For each kind, DRAWS draws of:

- settings anywhere in the ranges the C validator accepts (recovery_support.draw_settings: the bounds are
  the validator's own, ``att_filter_settings_check``, not a copy of its table);
- a fuzzed stream (0 .. 300 samples of good motion, rest, NaN, +-Inf, huge, zero, denormal, saturated and
  random-bit values; some streams ending in a burst of bad samples or bad throughout; random step counts n
  through ``att_filter_step_n``: lost-sample runs up to 15, holds up to 300);
- then WINDOW clean samples: a sensor at rest in a random attitude, or rotating slowly (at most 0.5 rad/s
  and half the gyro range) about a fixed axis, accel and mag consistent with the attitude and within the
  ranges of the settings.

Good output (``good_rows``): flags without NUMERIC, NOT_READY and BAD_ARG; q a finite unit quaternion
(| |q| - 1 | <= 1e-5); Euler angles, bias and covariance diagonal finite. The bounds, stated with margin
over the worst case measured in 14,000 draws per kind (docs/robustness.md, "The recovery contract"):

====  ===  ===========  ==========================================================================
kind  N    measured     after the N-th clean sample
====  ===  ===========  ==========================================================================
ars   2    1            every sample good
mars  2    1            every sample good
kf    2    1            every sample good
ekf   4    2            good; a later NUMERIC step is isolated (never two bad samples in a row):
                        a prediction or update out of the wrap's range at a gimbal passage with
                        cos_min far below its default, or with a bias state beyond any rate (the
                        attitude kept, the next sample re-initialises roll and pitch; R1, issue 26)
gyro  2    1            every sample good
tilt  2    1            every sample good
mekf  2    1            every sample good
====  ===  ===========  ==========================================================================

D1 (fixed, filter core): the gyro baseline stayed NUMERIC for ever under a steady rotation once its pitch
was within about 1e-5 rad of +-pi/2 with cos_min below that: sec(theta) times the rates and dt gave an Euler
increment beyond the wrap's range (8192 rad), the step kept the angles, and the next sample repeated it.
Reached from settings (euler_init pitch float32(pi/2), cos_min 1e-12, a yaw rate of 0.3 rad/s at 100 Hz)
and by the motion itself (dt 1 s, cos_min 1e-5, 0.37 rad/s from near level: stuck from sample 430). Such a
step now turns the attitude as a quaternion by the rotation vector w dt and reads consistent Euler angles
back (att_gyro.c gyro_rotate; flagged GIMBAL); the reproducers below are its regression tests.

The numpy reference agrees bit for bit on a few draws per kind (the whole stream, every output field).
tests/fuzz/fuzz_filter.c asserts the same bounds at rest (its table is checked against RECOVERY here).
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest
import recovery_support as rs

from attica import native, reference
from attica.outputs import OUTPUT_DTYPE
from attica.settings import FilterKind, Flag, make_settings

from helpers import ROOT, assert_same_bits

DRAWS = int(os.environ.get("ATT_RECOVERY_DRAWS", "300"))  # 5000: the measurement of docs/robustness.md
WINDOW = 64
REFERENCE_DRAWS = 3
DISTURBED = Flag.NUMERIC | Flag.NOT_READY | 0x3F  # the stream's last step failed, waited or refused a sensor
PI2 = float(np.float32(np.pi / 2))


@dataclass(frozen=True)
class Bound:
    """The recovery bound of a kind: within n clean samples a good output (n stated with margin over the
    measured worst case); isolated: from then on a bad sample can recur but never two in a row, else every
    sample from the n-th on is good."""

    n: int
    worst: int
    isolated: bool = False


RECOVERY: dict[FilterKind, Bound] = {
    FilterKind.ARS: Bound(2, 1),
    FilterKind.MARS: Bound(2, 1),
    FilterKind.KF: Bound(2, 1),
    FilterKind.EKF: Bound(4, 2, isolated=True),
    FilterKind.GYRO: Bound(2, 1),
    FilterKind.TILT: Bound(2, 1),
    FilterKind.MEKF: Bound(2, 1),
}


@dataclass
class Draw:
    """One draw: settings, the fuzzed stream with its step counts, the clean segment."""

    settings: Any
    gyr: np.ndarray
    acc: np.ndarray
    mag: np.ndarray
    steps: np.ndarray
    clean: tuple[np.ndarray, np.ndarray, np.ndarray]
    moving: bool


def _draw(kind: FilterKind, rng: np.random.Generator) -> Draw:
    s = rs.draw_settings(kind, rng)
    length = int(rng.integers(0, 301))
    g, a, m, st = rs.fuzzed_stream(kind, s, rng, length)
    moving = bool(rng.random() < 0.5)
    return Draw(s, g, a, m, st, rs.clean_segment(kind, s, rng, WINDOW, moving), moving)


def _run_c(kind: FilterKind, d: Draw) -> tuple[Any, Any]:
    """The C filter over the fuzzed stream (records, or None when empty), then over the clean segment."""
    f = native.Filter(kind, settings=d.settings)
    fuzz = f.run(d.gyr, d.acc, d.mag, steps=d.steps, check_units=False) if d.steps.size else None
    return fuzz, f.run(*d.clean, check_units=False)


def verdict(ok: np.ndarray, flags: np.ndarray, bound: Bound) -> tuple[bool, int | None]:
    """Whether a clean segment keeps the bound, and the samples it took (the measured N: the first good
    sample for an isolated bound, else the first from which every sample is good; None: never)."""
    if bound.isolated:
        good = np.nonzero(ok)[0]
        if good.size == 0:
            return False, None
        first = int(good[0]) + 1
        after = ok[first - 1 :]
        twice = bool((~after[1:] & ~after[:-1]).any())
        # a later bad sample is a NUMERIC step that kept a valid attitude, nothing else
        odd = bool(((flags[first - 1 :][~after] & (Flag.NUMERIC | rs.INVALID)) != Flag.NUMERIC).any())
        return first <= bound.n and not twice and not odd, first
    n = rs.samples_to_recover(ok)
    return n is not None and n <= bound.n, n


def _assert_same(c: Any, r: Any, what: str) -> None:
    for name in ("q", "euler", "gyro_bias", "cov"):
        assert_same_bits(c[name], r[name], f"{what}: {name}")
    assert (np.asarray(c["flags"]) == np.asarray(r["flags"])).all(), what
    assert (np.asarray(c["steps"]) == np.asarray(r["steps"])).all(), what


@pytest.mark.parametrize("kind", list(RECOVERY), ids=lambda k: k.label)
def test_recovery_contract(kind: FilterKind) -> None:
    """DRAWS draws: every clean segment keeps the kind's bound (module docstring); the worst case measured
    is printed, the streams really disturb the filters, and the reference agrees bit for bit on a few."""
    bound = RECOVERY[kind]
    rng = np.random.default_rng(2600 + int(kind))
    hist: dict[int, int] = {}
    disturbed = numeric_in_stream = isolated_later = compared = 0
    failures: list[str] = []
    for i in range(DRAWS):
        d = _draw(kind, rng)
        fuzz, out = _run_c(kind, d)
        if fuzz is not None:
            disturbed += bool(int(fuzz["flags"][-1]) & DISTURBED)
            numeric_in_stream += bool((fuzz["flags"] & Flag.NUMERIC).any())
        else:
            disturbed += 1  # a fresh filter: NOT_READY until its first sample (or the initial attitude)
        ok = rs.good_rows(out)
        keeps, n = verdict(ok, np.asarray(out["flags"], np.uint32), bound)
        if not keeps:
            flags = [f"{int(x):04x}" for x in out["flags"][:8]]
            failures.append(f"draw {i}: took {n}, flags {flags}..., moving {d.moving}, {d.settings}")
            continue
        assert n is not None
        hist[n] = hist.get(n, 0) + 1
        isolated_later += bool(bound.isolated and not ok[n - 1 :].all())
        # the reference (about 5 ms a step) on a few short draws, the first with a step count n > 1
        if (
            compared < REFERENCE_DRAWS
            and int(d.steps.sum()) <= 100
            and (compared or d.steps.max(initial=1) > 1)
        ):
            ref = reference.Filter(kind, settings=d.settings)
            if d.steps.size:
                _assert_same(
                    fuzz, ref.run(d.gyr, d.acc, d.mag, steps=d.steps, check_units=False), f"draw {i}"
                )
            _assert_same(out, ref.run(*d.clean, check_units=False), f"draw {i}, clean")
            compared += 1
    worst = max(hist)
    print(
        f"\n{kind.label}: {DRAWS} draws, samples to recover {sorted(hist.items())} (worst {worst}, bound "
        f"{bound.n}); streams ending disturbed {disturbed}, with NUMERIC {numeric_in_stream}; isolated later "
        f"NUMERIC {isolated_later}; reference bit for bit on {compared}"
    )
    assert not failures, "\n".join(failures[:5])
    assert worst <= bound.n and compared == REFERENCE_DRAWS
    assert disturbed > DRAWS // 3, disturbed  # the streams leave most filters refusing, NOT_READY or NUMERIC


# --- D1: the gyro baseline stuck NUMERIC near gimbal lock under a steady rotation (fixed) ----------------

D1_CASES = {
    # euler_init at float32(pi/2), a yaw rate at 100 Hz: NUMERIC at every sample before the fix
    "settings": (
        make_settings(FilterKind.GYRO, dt=0.01, cos_min=1e-12, euler_init=(0.0, PI2, 0.0)),
        (0.0, 0.0, 0.3),
    ),
    # reached by the motion: from near level, 0.37 rad/s at dt 1 s, the integrated pitch passes within 1e-5
    # rad of -pi/2 at sample 430 (-1.5707866); before the fix it stayed there, NUMERIC at every sample after
    "motion": (
        make_settings(
            FilterKind.GYRO,
            dt=1.0,
            cos_min=1e-5,
            euler_init=(
                float.fromhex("-0x1.810b2ap-1"),
                float.fromhex("-0x1.d34p-10"),
                float.fromhex("0x1.d8edb6p+0"),
            ),
        ),
        (float.fromhex("-0x1.37395cp-4"), float.fromhex("0x1.d2dc62p-3"), float.fromhex("-0x1.1b99fap-2")),
    ),
}
D1_FIRST = {"settings": 0, "motion": 429}
"""The sample whose Euler step is not representable (NUMERIC from there to the end before the fix)."""


def _d1_run(case: str, n: int) -> Any:
    s, rate = D1_CASES[case]
    gyr = np.tile(np.asarray(rate, np.float32), (n, 1))
    acc = np.tile(np.asarray([0.0, 0.0, rs.G_STD], np.float32), (n, 1))
    return native.Filter(FilterKind.GYRO, settings=s).run(gyr, acc, check_units=False), gyr, acc


@pytest.mark.parametrize("case", sorted(D1_CASES))
def test_d1_reproducer_turns_through_the_pole(case: str) -> None:
    """The D1 reproducers (settings inside the accepted ranges, a steady rotation; C and reference bit for
    bit): the state before sample D1_FIRST has its pitch within 1e-5 rad of +-pi/2, where sec(theta) rate dt
    leaves the wrap's range. That step (NUMERIC before the fix, the angles kept, and so every step after it)
    is now the rotation integrated as a quaternion: flagged GIMBAL, not NUMERIC, the attitude within 1e-5
    rad of q exp(w dt / 2) (float64), the pitch off the pole by about |w| dt; no step is NUMERIC."""
    s, rate = D1_CASES[case]
    assert native.settings_problem(FilterKind.GYRO, s) is None
    out, gyr, acc = _d1_run(case, 512)
    _assert_same(out, reference.Filter(FilterKind.GYRO, settings=s).run(gyr, acc, check_units=False), case)
    first = D1_FIRST[case]
    before = (
        np.asarray(s.euler_init, np.float64) if first == 0 else out["euler"][first - 1].astype(np.float64)
    )
    assert abs(abs(before[1]) - math.pi / 2) < 1e-5
    flags = np.asarray(out["flags"], np.uint32)
    assert not (flags & Flag.NUMERIC).any()
    assert flags[first] == Flag.GIMBAL
    want = rs.turned64(rs.quat_from_euler64(before), rate, s.dt)
    err = rs.quat_angle(out["q"][first], want)
    print(
        f"\n{case}: step {first} off the exact rotation by {err:.2e} rad, pitch {out['euler'][first, 1]:.6f}"
    )
    assert err < 1e-5
    assert abs(float(out["euler"][first, 1])) < math.pi / 2 - 1e-3


@pytest.mark.parametrize("case", sorted(D1_CASES))
def test_d1_gyro_recovers_near_gimbal(case: str) -> None:
    """The recovery contract for D1's inputs: within N clean samples of the rotation, every output good
    (failed before the fix: NUMERIC to the end)."""
    out, _, _ = _d1_run(case, 512)
    first = D1_FIRST[case]
    ok = rs.good_rows(out[first:])
    keeps, n = verdict(ok, np.asarray(out["flags"][first:], np.uint32), RECOVERY[FilterKind.GYRO])
    assert keeps and n == 1


def test_d1_settings_case_follows_the_rotation() -> None:
    """From float32(pi/2) with a yaw rate of 0.3 rad/s at 100 Hz (D1's settings case): over 512 samples the
    attitude stays within 1e-4 rad of the exact rotation (measured 7.4e-6): the quaternion step leaves the
    pole and the Euler steps after it follow (the body x axis tips off the vertical at 0.3 rad/s)."""
    s, rate = D1_CASES["settings"]
    out, _, _ = _d1_run("settings", 512)
    q = rs.quat_from_euler64(np.asarray(s.euler_init, np.float64))
    worst = 0.0
    for i in range(512):
        q = rs.turned64(q, rate, s.dt)
        worst = max(worst, rs.quat_angle(out["q"][i], q))
    print(f"\nworst attitude error over 512 samples: {worst:.2e} rad")
    assert worst < 1e-4


# --- the checks can fail --------------------------------------------------------------------------------


def _records(n: int) -> Any:
    out = np.zeros(n, OUTPUT_DTYPE)
    out["q"] = (1.0, 0.0, 0.0, 0.0)
    return out


def test_good_rows_and_verdict_can_fail() -> None:
    """good_rows refuses each way an output can be invalid; verdict refuses a late, a repeated and a
    never-ending recovery, and an isolated bad sample that is not a NUMERIC step."""
    out = _records(8)
    assert rs.good_rows(out).all()
    bad = [
        ("flags", Flag.NUMERIC),
        ("flags", Flag.NOT_READY),
        ("flags", Flag.BAD_ARG),
        ("q", (math.nan, 0.0, 0.0, 0.0)),
        ("q", (1.0, 1e-2, 0.0, 0.0)),
        ("q", (math.inf, 0.0, 0.0, 0.0)),
        ("euler", (0.0, math.inf, 0.0)),
        ("gyro_bias", (math.nan, 0.0, 0.0)),
        ("cov", (0.0, 0.0, math.nan, 0.0)),
    ]
    for field, value in bad:
        o = out.copy()
        o[field][3] = value
        ok = rs.good_rows(o)
        assert not ok[3] and ok.sum() == 7, (field, value)
    strict, iso = Bound(2, 1), Bound(4, 2, isolated=True)
    flags = np.zeros(8, np.uint32)
    yes = np.ones(8, bool)
    assert verdict(yes, flags, strict) == (True, 1)
    late = yes.copy()
    late[:2] = False
    assert verdict(late, flags, strict) == (False, 3)
    again = yes.copy()
    again[5] = False
    assert verdict(again, flags, strict) == (False, 7)
    assert verdict(~yes, flags, strict) == (False, None)
    numeric = flags.copy()
    numeric[5] = Flag.NUMERIC
    assert verdict(again, numeric, iso) == (True, 1)  # an isolated NUMERIC step
    twice = again.copy()
    twice[6] = False
    numeric[6] = Flag.NUMERIC
    assert verdict(twice, numeric, iso)[0] is False  # two in a row
    not_ready = flags.copy()
    not_ready[5] = Flag.NOT_READY
    assert verdict(again, not_ready, iso)[0] is False  # a later bad sample that is not a NUMERIC step
    assert verdict(late, flags, Bound(2, 1, isolated=True)) == (False, 3)


@pytest.mark.parametrize("kind", [FilterKind.ARS, FilterKind.KF, FilterKind.EKF, FilterKind.MEKF], ids=str)
def test_a_broken_filter_breaks_the_contract(kind: FilterKind) -> None:
    """A filter whose state is overwritten with NaN bytes (as fuzz_filter's ATT_FUZZ_BREAK_AT) does not
    recover: the property reports it."""
    rng = np.random.default_rng(7)
    d = _draw(kind, rng)
    f = native.Filter(kind, settings=make_settings(kind, dt=0.01))
    u = native.ffi.addressof(f.state.ptr[0], "u")
    native.ffi.memmove(u, b"\xff" * native.ffi.sizeof(u[0]), native.ffi.sizeof(u[0]))
    out = f.run(*rs.clean_segment(kind, f.settings, rng, WINDOW, d.moving), check_units=False)
    assert not verdict(rs.good_rows(out), np.asarray(out["flags"], np.uint32), RECOVERY[kind])[0]


def test_fuzz_filter_asserts_the_same_bounds() -> None:
    """tests/fuzz/fuzz_filter.c's recovery table (N and the isolated rule per kind) is RECOVERY."""
    src = (ROOT / "tests" / "fuzz" / "fuzz_filter.c").read_text()
    rows = dict(re.findall(r"\[ATT_FILTER_(\w+)\]\s*=\s*\{(\d+u?,\s*(?:true|false))\}", src))
    assert rows, "no recovery table in fuzz_filter.c"
    table = {
        FilterKind[k]: (int(v.split(",")[0].rstrip("u")), v.split(",")[1].strip() == "true")
        for k, v in rows.items()
        if k != "NONE"
    }
    assert table == {k: (b.n, b.isolated) for k, b in RECOVERY.items()}


def test_settings_are_drawn_over_the_accepted_ranges() -> None:
    """The draws reach both ends of the ranges: for every kind, fields at their bounds and spread over the
    decades between (a sampler stuck at the defaults would prove little)."""
    for kind in RECOVERY:
        rng = np.random.default_rng(99 + int(kind))
        draws = [rs.draw_settings(kind, rng) for _ in range(120)]
        default = make_settings(kind)
        changed = 0
        for f in dataclasses.fields(default):
            values = {repr(getattr(s, f.name)) for s in draws}
            changed += len(values) > 1
            assert native.settings_problem(kind, draws[0]) is None
        assert changed >= len(dataclasses.fields(default)) - 1, (kind, changed)  # all but dt's few choices
        if hasattr(default, "gyro_range"):
            ranges = np.array([s.gyro_range for s in draws])
            assert ranges.min() < 1e-3 and ranges.max() == np.float32(1000.0), kind
