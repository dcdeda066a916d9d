"""The filter core: fast paths against their general twins, outputs on demand, retuning, settings
validation, flag names, coefficients derived alike in C and the reference."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from attica import _build, kinds, native
from attica.native import ffi, lib
from attica.outputs import OUT_ALL, OUT_BIAS, OUT_EULER, OUT_Q, OUTPUT_DTYPE
from attica.reference._common import c_state_values, state_values
from attica.reference.filter import Filter as RefFilter
from attica.settings import FilterKind, Flag, implemented_kinds, make_settings, to_dict
from attica.sim import SimConfig, simulate

from helpers import ROOT, assert_same_bits, need

RATE = 285.714


def test_fast_paths_against_general_twins(tmp_path: Path) -> None:
    """tests/c/att_core_test.c: small-angle sin/cos equal the reduced ones bit for bit for |x| <= 0.75
    (every 256th float and the last 65536 below the bound), the rotation-vector series within 1 ulp of
    the exact exponential map below |rv| = 0.25 and equal above, the trig-free alignment rotates onto z."""
    cc = shutil.which("cc") or shutil.which("gcc")
    need(cc is not None, "no C compiler")
    assert cc is not None
    exe = tmp_path / "att_core_test"
    src = [ROOT / "tests" / "c" / "att_core_test.c", ROOT / "firmware" / "src" / "math" / "att_math.c"]
    cmd = [cc, *_build.cflags(), "-O2", "-I", str(ROOT / "firmware" / "include")]
    cmd += ["-I", str(ROOT / "firmware" / "src" / "core"), *map(str, src), "-o", str(exe)]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    proc = subprocess.run([str(exe), "256"], capture_output=True, text=True, timeout=600)
    print(proc.stdout)
    assert proc.returncode == 0, proc.stdout
    assert "0 differ" in proc.stdout and "worst 1 ulp" in proc.stdout


def _sim(duration: float = 20.0, seed: int = 5) -> Any:
    return simulate(SimConfig(duration=duration, rate=RATE, seed=seed))


@pytest.mark.parametrize("kind", kinds.labels())
def test_step_fills_the_per_step_fields_output_the_rest(kind: str) -> None:
    """att_filter_step writes q, gyro_bias, flags, steps (euler for Euler-state kinds; the EKF, whose
    state is the angles, derives q only on request), says so in valid and leaves the rest;
    att_filter_output writes everything, the same values where both write."""
    rec = _sim(5.0)
    f = native.Filter(kind, dt=1 / RATE)
    cheap = f.run(rec.gyr, rec.acc, rec.mag, full=False)
    g = native.Filter(kind, dt=1 / RATE)
    full = g.run(rec.gyr, rec.acc, rec.mag)
    k = kinds.info(kind)
    euler_state = k.euler_state
    want_valid = (OUT_Q if k.q_state else 0) | OUT_BIAS | (OUT_EULER if euler_state else 0)
    assert (cheap["valid"] == want_valid).all()
    assert (full["valid"] == OUT_ALL).all()
    if not k.q_state:
        assert (cheap["q"] == 0).all()  # not written
    for name in (
        (("q",) if k.q_state else ()) + ("gyro_bias", "flags", "steps") + (("euler",) if euler_state else ())
    ):
        assert_same_bits(cheap[name], full[name], name) if name in ("q", "gyro_bias", "euler") else None
        if name in ("flags", "steps"):
            assert (cheap[name] == full[name]).all()
    if not euler_state:
        assert (cheap["euler"] == 0).all()  # not written (the buffer was zeroed)
    assert (cheap["cov"] == 0).all()


def test_step_output_null_and_bad_calls() -> None:
    out = np.zeros((), OUTPUT_DTYPE)
    buf = ffi.from_buffer("att_output_t[]", out)
    f = ffi.new("att_filter_t *")
    s = ffi.new("att_sample_t *")
    assert lib.att_filter_step(f, s, buf) == Flag.BAD_ARG  # never initialised (kind NONE)
    assert int(out["flags"]) == Flag.BAD_ARG and int(out["valid"]) == OUT_ALL
    assert lib.att_filter_step(ffi.NULL, s, buf) == Flag.BAD_ARG
    assert lib.att_filter_step(f, ffi.NULL, ffi.NULL) == Flag.BAD_ARG


def _c_settings(kind: FilterKind, **changes: Any) -> Any:
    s = ffi.new("att_filter_settings_t *")
    assert lib.att_filter_settings_default(int(kind), 1 / RATE, s) == lib.ATT_OK
    member = getattr(s, kind.label)
    for name, value in changes.items():
        setattr(member, name, value)
    return s


RETUNE_CHANGES: dict[str, dict[str, Any]] = {
    "ars": {"tau_acc_lp": 0.7, "bias_mode": 1, "bias_init": (0.01, 0.0, -0.02)},
    "mars": {"tau_acc_lp": 0.7, "tau_mag": 5.0, "mag_norm_reject": 0.3, "rest_time": 0.01},
    "kf": {"r_noise": 0.3},
    "ekf": {"r_phi": 2.0, "r_theta": 2.0},
    "gyro": {"cos_min": 0.01},
    "tilt": {"normalise": False},
    "mekf": {
        "tau_acc_lp": 0.7,
        "gyro_noise": 0.01,
        "mag_norm_reject": 0.3,
        "rest_time": 0.01,
        "gate": 9.0,
        "gyro_scale_sd": 0.005,
    },
}
"""Per kind: settings that a retune changes (test_retune_keeps_the_state)."""


def test_retune_changes_cover_every_kind() -> None:
    assert set(RETUNE_CHANGES) == set(kinds.labels())


@pytest.mark.parametrize("kind", kinds.labels())
def test_retune_keeps_the_state(kind: str) -> None:
    """att_filter_retune with the same settings changes no byte; with new ones the state carries on
    (attitude, bias, memories), and C and reference, both retuned at the same step, stay bit-identical."""
    k = FilterKind.parse(kind)
    rec = _sim(10.0)
    half = rec.gyr.shape[0] // 2
    f = native.Filter(k, dt=1 / RATE)
    ref = RefFilter(k, dt=1 / RATE)
    first = f.run(rec.gyr[:half], rec.acc[:half], rec.mag[:half])
    ref.run(rec.gyr[:half], rec.acc[:half], rec.mag[:half])
    before = bytes(f.state)
    assert lib.att_filter_retune(f.state.ptr, _c_settings(k)) == lib.ATT_OK
    assert bytes(f.state) == before
    changes = RETUNE_CHANGES[kind]
    c_changes = {n: v for n, v in changes.items()}
    assert lib.att_filter_retune(f.state.ptr, _c_settings(k, **c_changes)) == lib.ATT_OK
    ref.retune(**changes)
    assert ref.state_matches(0, f.state[0]), "state after the retune"
    out = f.run(rec.gyr[half:], rec.acc[half:], rec.mag[half:])
    got = ref.run(rec.gyr[half:], rec.acc[half:], rec.mag[half:])
    assert_same_bits(out["q"], got["q"], f"{kind} after retune")
    assert (out["steps"] == got["steps"]).all() and out["steps"][0] == first["steps"][-1] + 1
    fresh = native.Filter(k, make_settings(k, dt=1 / RATE, **changes))
    again = fresh.run(rec.gyr[half:], rec.acc[half:], rec.mag[half:])
    if kinds.info(k).has_period:  # a kind without a sample period (tilt) has no memory: a fresh one is alike
        assert not np.array_equal(again["q"], out["q"]), "the retuned filter kept its state"


@pytest.mark.parametrize("kind", kinds.labels())
def test_retune_refuses_bad_settings_and_leaves_the_filter(kind: str) -> None:
    k = FilterKind.parse(kind)
    f = native.Filter(k, dt=1 / RATE)
    rec = _sim(2.0)
    f.run(rec.gyr, rec.acc, rec.mag)
    before = bytes(f.state)
    field = "dt" if kinds.info(k).has_period else "gravity"
    bad = _c_settings(k, **{field: float("nan")})
    assert lib.att_filter_settings_validate(int(k), bad) == lib.ATT_ERR_SETTINGS
    assert lib.att_filter_retune(f.state.ptr, bad) == lib.ATT_ERR_SETTINGS
    assert bytes(f.state) == before
    assert lib.att_filter_retune(ffi.NULL, bad) == lib.ATT_ERR_NULL
    fresh = ffi.new("att_filter_t *")
    assert lib.att_filter_retune(fresh, _c_settings(k)) == lib.ATT_ERR_KIND


@pytest.mark.parametrize("kind", kinds.labels())
def test_validate_matches_init(kind: str) -> None:
    """att_filter_settings_validate accepts exactly what att_filter_init accepts (defaults, one bad field)."""
    k = FilterKind.parse(kind)
    good = _c_settings(k)
    assert lib.att_filter_settings_validate(int(k), good) == lib.ATT_OK
    f = ffi.new("att_filter_t *")
    assert lib.att_filter_init(f, int(k), good) == lib.ATT_OK
    assert lib.att_filter_settings_validate(99, good) == lib.ATT_ERR_KIND
    assert lib.att_filter_settings_validate(int(k), ffi.NULL) == lib.ATT_ERR_NULL


def test_time_constant_beside_a_gain_is_used_and_the_gain_ignored() -> None:
    """A time constant > 0 is used and the per-sample gain beside it ignored (issue 22): accepted, the same
    coefficients as with the gain 0; the gain is still range-checked."""
    for k in kinds.KINDS:
        kind = k.kind
        for gain, tau in k.gain_time_constants:
            f, g = ffi.new("att_filter_t *"), ffi.new("att_filter_t *")
            s = _c_settings(kind, **{tau: 0.5, gain: 0.1})
            assert lib.att_filter_settings_validate(int(kind), s) == lib.ATT_OK, (kind, tau)
            assert lib.att_filter_init(f, int(kind), s) == lib.ATT_OK
            assert lib.att_filter_init(g, int(kind), _c_settings(kind, **{tau: 0.5, gain: 0.0})) == lib.ATT_OK
            state = [bytes(ffi.buffer(ffi.addressof(x.u, kind.label))) for x in (f, g)]
            assert state[0] == state[1], (kind, tau)  # coefficients and state alike
            s = _c_settings(kind, **{tau: 0.5, gain: 1.5})
            assert lib.att_filter_settings_validate(int(kind), s) == lib.ATT_ERR_SETTINGS, (kind, tau)


def test_flag_names() -> None:
    for flag in Flag:
        assert ffi.string(lib.att_flag_name(int(flag))).decode() == flag.name
    assert lib.att_flag_name(0) == ffi.NULL
    assert lib.att_flag_name(3) == ffi.NULL
    buf = ffi.new("char[64]")
    n = lib.att_flags_format(int(Flag.AT_REST | Flag.GYRO_INVALID), buf, 64)
    assert ffi.string(buf).decode() == "GYRO_INVALID|AT_REST" and n == len("GYRO_INVALID|AT_REST")
    assert lib.att_flags_format(0, buf, 64) == 1 and ffi.string(buf) == b"-"
    n = lib.att_flags_format(0x00030001, buf, 64)
    assert ffi.string(buf).decode() == "GYRO_INVALID|0x00030000" and n == 23
    small = ffi.new("char[8]")
    assert lib.att_flags_format(int(Flag.NUMERIC | Flag.CLAMPED), small, 8) == len("CLAMPED|NUMERIC")
    assert ffi.string(small).decode() == "CLAMPE"[:7] or len(ffi.string(small)) == 7
    assert lib.att_flags_format(int(Flag.NUMERIC), ffi.NULL, 0) == len("NUMERIC")
    assert lib.ATT_FLAGS_OUTPUT_INVALID == int(Flag.NOT_READY | Flag.BAD_ARG)


@pytest.mark.parametrize("kind", kinds.labels())
@pytest.mark.parametrize(
    "changes",
    [{}, {"tau_acc_lp": 0.0}, {"rest_time": 0.123, "rest_gyro": 0.2}],
)
def test_coefficients_derived_alike(kind: str, changes: dict[str, Any]) -> None:
    """Every coefficient the reference derives itself equals the C one bit for bit."""
    k = FilterKind.parse(kind)
    base = make_settings(k, dt=1 / RATE)
    s = make_settings(k, base, **{n: v for n, v in changes.items() if hasattr(base, n)})
    c = native.Filter(k, s)
    ref = RefFilter(k, s)
    for name, layout in ref.impl.COEFFS.items():
        ours = state_values(ref.impl, {name: layout}, 0)
        theirs = c_state_values({name: layout}, getattr(c.state.u, kind))
        assert len(ours) == len(theirs), name
        for a, b in zip(ours, theirs, strict=True):
            if isinstance(a, np.floating):
                assert np.float32(a).view(np.uint32) == np.float32(b).view(np.uint32), name
            else:
                assert int(a) == int(b), name


def test_settings_read_back_unchanged_by_init() -> None:
    """init does not write into the caller's settings (the instance keeps coefficients, not a copy)."""
    for k in implemented_kinds():
        s = _c_settings(k)
        before = bytes(ffi.buffer(s))
        f = ffi.new("att_filter_t *")
        assert lib.att_filter_init(f, int(k), s) == lib.ATT_OK
        assert bytes(ffi.buffer(s)) == before
        assert to_dict(make_settings(k)) is not None
