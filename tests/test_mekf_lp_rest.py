"""The mekf's accel low-pass: ``tau_acc_lp_no_rest`` until the first rest has measured the gyro bias,
``tau_acc_lp`` from then on (stop 47; att_mekf.h step 2, docs/accuracy.md "a longer low-pass once the
bias is measured").

- the state's gain is the no-rest one until the first step flagged AT_REST and the rested one from that
  step on, in C and in the reference, bit for bit;
- a platform that never rests (the rest detector off) gives the same bits as a filter whose
  ``tau_acc_lp`` is the no-rest time constant; with rests it does not;
- ``tau_acc_lp_no_rest`` 0 is ``tau_acc_lp`` throughout;
- a reset starts short again, a retune takes the gain of the phase it is in.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from attica import native
from attica.reference.filter import Filter as RefFilter
from attica.settings import FilterKind, Flag, make_settings
from attica.sim import SimConfig, simulate

RATE = 100.0
DT = float(np.float32(1.0 / RATE))
SQRT2 = np.float32(float.fromhex("0x1.6a09e6p+0"))  # ATT_MEKF_SQRT2


def _inputs(seconds: float, moving: bool = False, seed: int = 4) -> tuple[Any, Any, Any]:
    """``seconds`` simulated: 3 s still, motion with one break, 2 s still; ``moving``: from 4 s on (the
    filter starts in motion and its first rest is the break)."""
    rec = simulate(SimConfig(duration=seconds, rate=RATE, seed=seed, rest_breaks=1))
    first = int(4.0 * RATE) if moving else 0
    return (np.asarray(x, np.float32)[first:] for x in (rec.gyr, rec.acc, rec.mag))  # type: ignore[return-value]


def _gain(tau: float) -> np.float32:
    """att_mekf_coeffs' dt / (sqrt(2) tau + dt) in float32."""
    dt = np.float32(DT)
    return np.float32(dt / np.float32(np.float32(SQRT2 * np.float32(tau)) + dt))


def _mekf(**over: Any) -> Any:
    return make_settings(FilterKind.MEKF, dt=DT, **over)


@pytest.mark.parametrize("use_mag", [False, True])
def test_the_gain_switches_at_the_first_rest(use_mag: bool) -> None:
    s = _mekf(use_mag=use_mag)
    assert (s.tau_acc_lp, s.tau_acc_lp_no_rest) == (1.45, 1.25), "the defaults"
    f, ref = native.Filter(FilterKind.MEKF, s), RefFilter(FilterKind.MEKF, s)
    c = f.state.u.mekf.c
    assert np.float32(c.k_lp) == _gain(1.45) and np.float32(c.k_lp_no_rest) == _gain(1.25)
    gyr, acc, mag = _inputs(20.0, moving=True)
    first_rest = None
    for i in range(len(gyr)):
        out = f.step(gyr[i], acc[i], mag[i])
        ref.step(gyr[i], acc[i], mag[i])
        st = f.state.u.mekf.st
        if first_rest is None and int(out["flags"]) & Flag.AT_REST:
            first_rest = i
        rested = first_rest is not None
        assert bool(st.rested) == rested, i
        assert np.float32(st.k_lp) == (_gain(1.45) if rested else _gain(1.25)), i
        assert bool(ref.impl.rested[0]) == rested and ref.impl.k_lp_now[0] == np.float32(st.k_lp), i
    assert first_rest is not None and first_rest > 200, "the first rest is the break, after motion"
    assert f.output().tobytes() == ref.output()[0].tobytes()


def test_without_a_rest_the_no_rest_time_constant_holds() -> None:
    """With the rest detector off the defaults run as a filter whose tau_acc_lp is 1.25 s, bit for bit;
    with it on they do not (the run has rests)."""
    gyr, acc, mag = _inputs(30.0)
    for use_mag in (False, True):
        never = native.Filter(FilterKind.MEKF, _mekf(use_mag=use_mag, rest_gyro=0.0)).run(gyr, acc, mag)
        short = native.Filter(
            FilterKind.MEKF, _mekf(use_mag=use_mag, rest_gyro=0.0, tau_acc_lp=1.25, tau_acc_lp_no_rest=0.0)
        ).run(gyr, acc, mag)
        assert never.tobytes() == short.tobytes(), use_mag
        rests = native.Filter(FilterKind.MEKF, _mekf(use_mag=use_mag)).run(gyr, acc, mag)
        like = native.Filter(
            FilterKind.MEKF, _mekf(use_mag=use_mag, tau_acc_lp=1.25, tau_acc_lp_no_rest=0.0)
        ).run(gyr, acc, mag)
        assert np.any(rests["flags"] & Flag.AT_REST)
        assert rests["q"].tobytes() != like["q"].tobytes(), "after a rest the longer low-pass runs"


def test_no_rest_zero_is_tau_acc_lp_throughout() -> None:
    gyr, acc, mag = _inputs(20.0, moving=True)
    zero = native.Filter(FilterKind.MEKF, _mekf(tau_acc_lp_no_rest=0.0)).run(gyr, acc, mag)
    same = native.Filter(FilterKind.MEKF, _mekf(tau_acc_lp_no_rest=1.45)).run(gyr, acc, mag)
    assert zero.tobytes() == same.tobytes()
    default = native.Filter(FilterKind.MEKF, _mekf()).run(gyr, acc, mag)
    assert default["q"].tobytes() != zero["q"].tobytes(), "before the first rest the defaults run shorter"
    off = native.Filter(FilterKind.MEKF, _mekf(tau_acc_lp=0.0, tau_acc_lp_no_rest=1.25))
    assert np.float32(off.state.u.mekf.c.k_lp_no_rest) == 0.0, "no low-pass: tau_acc_lp 0 wins"
    with pytest.raises(native.SettingsError, match="tau_acc_lp_no_rest"):
        native.Filter(FilterKind.MEKF, _mekf(tau_acc_lp_no_rest=-1.0))


def test_reset_and_retune_take_the_phase_s_gain() -> None:
    gyr, acc, mag = _inputs(10.0)
    f, ref = native.Filter(FilterKind.MEKF, _mekf()), RefFilter(FilterKind.MEKF, _mekf())
    f.retune(tau_acc_lp_no_rest=1.0)  # before any rest: the new no-rest gain
    ref.retune(tau_acc_lp_no_rest=1.0)
    assert np.float32(f.state.u.mekf.st.k_lp) == _gain(1.0)
    f.run(gyr, acc, mag)
    ref.run(gyr, acc, mag, check_units=False)
    assert bool(f.state.u.mekf.st.rested)
    f.retune(tau_acc_lp=2.0)  # rested: the new tau_acc_lp's gain
    ref.retune(tau_acc_lp=2.0)
    assert np.float32(f.state.u.mekf.st.k_lp) == _gain(2.0) == ref.impl.k_lp_now[0]
    f.run(gyr, acc, mag)
    ref.run(gyr, acc, mag, check_units=False)
    assert f.output().tobytes() == ref.output()[0].tobytes()
    f.reset()
    ref.reset()
    st = f.state.u.mekf.st
    assert not bool(st.rested) and np.float32(st.k_lp) == _gain(1.0)
    assert not bool(ref.impl.rested[0]) and ref.impl.k_lp_now[0] == _gain(1.0)
