"""KF: the recovery after a clipping gyro (recovery_time, issue 23; the one of ars and mekf for the scalar p).

- C and the reference bit for bit (every step, the state at every segment end) on streams whose gyro
  clips: the defaults, without the low-pass, with the gate on (off during a recovery), per-step noises,
  the recovery off; and across a retune in the middle of a recovery (the counter limited);
- what it buys on the simulator: after turns that clip the gyro the inclination comes back (RMSE at most
  half of the one without it), every clipped sample and the recovery after it flagged INITIALISED;
- with recovery_time 0 (the seed preset's) nothing is flagged after the start.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from clip_support import CLIP, INITIALISED, RATE, clipped_rows, clipping

from attica import metrics, native
from attica.crosscheck import Stream, crosscheck
from attica.reference.filter import Filter as RefFilter
from attica.settings import FilterKind, KfSettings

from helpers import assert_same_bits


def _settings(**over: Any) -> KfSettings:
    return replace(KfSettings(dt=1.0 / RATE, gyro_range=CLIP), **over)


@pytest.mark.parametrize(
    "over",
    [
        {},
        {"tau_acc_lp": 0.0},
        {"gate": 9.0, "r_accel": 2.0},
        {"noise_rates": False, "q_noise": 1e-6, "r_noise": 1e-3, "recovery_time": 0.5},
        {"recovery_time": 0.0},
    ],
    ids=["defaults", "no-lowpass", "gate", "per-step", "off"],
)
def test_bit_exact_with_the_reference_on_a_clipping_gyro(over: dict[str, Any]) -> None:
    streams = [Stream(r.gyr, r.acc, None, name=f"seed {s}") for s, r in ((4, clipping(4)), (6, clipping(6)))]
    res = crosscheck(FilterKind.KF, streams, settings=_settings(**over), segment=1500)
    assert res.ok, res.first_mismatch or f"{res.state_mismatches} state mismatches"


def test_a_retune_inside_a_recovery_stays_bit_exact() -> None:
    rec = clipping(4, 20.0)
    s = _settings(recovery_time=4.0)
    half = int(11.5 * RATE)  # within the recovery after the first turn (10 s to 11 s)
    c = native.Filter(FilterKind.KF, s)
    c.run(rec.gyr[:half], rec.acc[:half])
    ref = RefFilter(FilterKind.KF, s)
    ref.load_c_states([c.state.copy()[0]])
    assert c.state.u.kf.st.rec_left > 100, "the retune is made during a recovery with more than 1 s left"
    s2 = replace(s, recovery_time=1.0, tau_acc_lp=0.5)
    c.retune(s2)
    ref.retune(s2)
    assert c.state.u.kf.st.rec_left == 100, "the counter is limited to the new recovery_time"
    assert ref.state_matches(0, c.state.copy()[0]), ref.state_diff(0, c.state.copy()[0])
    out = c.run(rec.gyr[half:], rec.acc[half:])
    q_ref = np.array([ref.step(rec.gyr[i], rec.acc[i], None)["q"][0] for i in range(half, len(rec.gyr))])
    assert_same_bits(out["q"], q_ref, "after the retune")
    assert ref.state_matches(0, c.state.copy()[0]), ref.state_diff(0, c.state.copy()[0])


def test_a_clipping_gyro_is_recovered_from() -> None:
    """recovery_time (default 2 s): after clipping turns the inclination comes back, flagged INITIALISED."""
    rec = clipping(5, 50.0)
    late = np.arange(len(rec.gyr)) > int(5 * RATE)
    clipped = clipped_rows(rec.gyr)
    assert clipped.any()
    err = {}
    for rt in (0.0, 2.0):
        out = native.Filter(FilterKind.KF, _settings(recovery_time=rt)).run(rec.gyr, rec.acc)
        err[rt] = metrics.evaluate(out["q"], rec.quat_true, late).inclination
        flagged = (out["flags"] & INITIALISED) != 0
        if rt:
            assert flagged[clipped].all(), "every clipped sample is flagged"
            assert 1.9 * RATE * 3 <= flagged[late].sum() <= 4.0 * RATE * 3, "2 s after each clip: recovering"
        else:
            assert not flagged[late].any()
    assert err[2.0] < 0.5 * err[0.0], (
        f"inclination RMSE {err[2.0]:.2f} with the recovery vs {err[0.0]:.2f} without"
    )
