"""ARS: the recovery after a clipping gyro (recovery_time, issue 23; the port of mars's).

- C and the reference bit for bit (every step, the state at every segment end) on a stream whose gyro
  clips, with the defaults (full alignment, low-pass on), without the low-pass, with a partial correction
  (tau, gain_c) and with the recovery off; and across a retune in the middle of a recovery;
- what it buys on the simulator: after turns that clip the gyro the inclination comes back (RMSE well
  below the one without it), every clipped sample and the recovery after it flagged INITIALISED;
- with recovery_time 0 nothing is flagged after the start and nothing changes (the seed preset's
  digests, tests/digests.txt, did not change).
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
from attica.settings import ArsSettings, FilterKind

from helpers import assert_same_bits


@pytest.mark.parametrize(
    "over",
    [
        {},
        {"tau_acc_lp": 0.0},
        {"recovery_time": 0.5, "tau": 1.0, "gain_c": 10.0},
        {"recovery_time": 0.0},
    ],
    ids=["defaults", "no-lowpass", "partial", "off"],
)
def test_bit_exact_with_the_reference_on_a_clipping_gyro(over: dict[str, Any]) -> None:
    streams = [
        Stream(r.gyr, r.acc, None, name=f"seed {seed}") for seed, r in ((4, clipping(4)), (6, clipping(6)))
    ]
    s = replace(ArsSettings(dt=1.0 / RATE, gyro_range=CLIP), **over)
    res = crosscheck(FilterKind.ARS, streams, settings=s, segment=1500)
    assert res.ok, res.first_mismatch or f"{res.state_mismatches} state mismatches"


def test_a_retune_inside_a_recovery_stays_bit_exact() -> None:
    rec = clipping(4, 20.0)
    s = ArsSettings(dt=1.0 / RATE, gyro_range=CLIP, recovery_time=4.0, tau=0.5)
    half = int(11.5 * RATE)  # within the recovery after the first turn (10 s to 11 s)
    c = native.Filter(FilterKind.ARS, s)
    c.run(rec.gyr[:half], rec.acc[:half], rec.mag[:half])
    ref = RefFilter(FilterKind.ARS, s)
    ref.load_c_states([c.state.copy()[0]])
    assert c.state.u.ars.st.rec_left > 0, "the retune is made during a recovery"
    s2 = replace(s, recovery_time=1.0, tau_acc_lp=0.5)
    c.retune(s2)
    ref.retune(s2)
    assert ref.state_matches(0, c.state.copy()[0]), ref.state_diff(0, c.state.copy()[0])
    out = c.run(rec.gyr[half:], rec.acc[half:], rec.mag[half:])
    q_ref = np.array(
        [ref.step(rec.gyr[i], rec.acc[i], rec.mag[i])["q"][0] for i in range(half, len(rec.gyr))]
    )
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
        s = replace(ArsSettings(dt=1.0 / RATE, gyro_range=CLIP), recovery_time=rt)
        out = native.Filter(FilterKind.ARS, s).run(rec.gyr, rec.acc, rec.mag)
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
