"""EKF: the recovery after a clipping gyro (recovery_time, issue 23; kf's and mekf's for roll and pitch).

- C and the reference bit for bit (every step, the state at every segment end) on streams whose gyro
  clips: the defaults, without the low-pass, with the gate on (off during a recovery), per-step noises,
  the recovery off; and across a retune in the middle of a recovery (the counter limited);
- the mechanism: during a recovery the roll and pitch variances grow by q_rec per prediction;
- what it buys on the simulator: after turns that clip the gyro the inclination comes back (RMSE below
  0.6 of the one without it; 0.45 measured), every clipped sample and the recovery after it flagged
  INITIALISED;
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
from attica.settings import EkfSettings, FilterKind

from ekf_support import replay_positive_definite
from helpers import assert_same_bits


def _settings(**over: Any) -> EkfSettings:
    return replace(EkfSettings(dt=1.0 / RATE, gyro_range=CLIP), **over)


@pytest.mark.parametrize(
    "over",
    [
        {},
        {"tau_acc_lp": 0.0},
        {"gate": 9.0, "r_accel": 2.0},
        {
            "noise_rates": False,
            "q_phi": 1e-6,
            "q_theta": 1e-6,
            "r_phi": 1e-3,
            "r_theta": 2e-3,
            "recovery_time": 0.5,
        },
        {"recovery_time": 0.0},
    ],
    ids=["defaults", "no-lowpass", "gate", "per-step", "off"],
)
def test_bit_exact_with_the_reference_on_a_clipping_gyro(over: dict[str, Any]) -> None:
    streams = [Stream(r.gyr, r.acc, None, name=f"seed {s}") for s, r in ((4, clipping(4)), (6, clipping(6)))]
    res = crosscheck(FilterKind.EKF, streams, settings=_settings(**over), segment=1500)
    assert res.ok, res.first_mismatch or f"{res.state_mismatches} state mismatches"


def test_a_retune_inside_a_recovery_stays_bit_exact() -> None:
    rec = clipping(4, 20.0)
    s = _settings(recovery_time=4.0)
    half = int(11.5 * RATE)  # within the recovery after the first turn (10 s to 11 s)
    c = native.Filter(FilterKind.EKF, s)
    c.run(rec.gyr[:half], rec.acc[:half])
    ref = RefFilter(FilterKind.EKF, s)
    ref.load_c_states([c.state.copy()[0]])
    assert c.state.u.ekf.st.rec_left > 100, "the retune is made during a recovery with more than 1 s left"
    s2 = replace(s, recovery_time=1.0, tau_acc_lp=0.5)
    c.retune(s2)
    ref.retune(s2)
    assert c.state.u.ekf.st.rec_left == 100, "the counter is limited to the new recovery_time"
    assert ref.state_matches(0, c.state.copy()[0]), ref.state_diff(0, c.state.copy()[0])
    out = c.run(rec.gyr[half:], rec.acc[half:])
    e_ref = np.array([ref.step(rec.gyr[i], rec.acc[i], None)["euler"][0] for i in range(half, len(rec.gyr))])
    assert_same_bits(out["euler"], e_ref, "after the retune")
    assert ref.state_matches(0, c.state.copy()[0]), ref.state_diff(0, c.state.copy()[0])


def test_a_clipping_gyro_is_recovered_from() -> None:
    """recovery_time (default 2 s): after clipping turns the inclination comes back, flagged INITIALISED."""
    rec = clipping(5, 50.0)
    late = np.arange(len(rec.gyr)) > int(5 * RATE)
    clipped = clipped_rows(rec.gyr)
    assert clipped.any()
    err = {}
    for rt in (0.0, 2.0):
        out = native.Filter(FilterKind.EKF, _settings(recovery_time=rt)).run(rec.gyr, rec.acc)
        err[rt] = metrics.evaluate(out["q"], rec.quat_true, late).inclination
        flagged = (out["flags"] & INITIALISED) != 0
        if rt:
            assert flagged[clipped].all(), "every clipped sample is flagged"
            assert 1.9 * RATE * 3 <= flagged[late].sum() <= 4.0 * RATE * 3, "2 s after each clip: recovering"
        else:
            assert not flagged[late].any()
    # measured: 0.45 on this seed, 0.45-0.50 on seeds 1-8; the bound leaves room for simulator changes
    assert err[2.0] < 0.6 * err[0.0], (
        f"inclination RMSE {err[2.0]:.2f} with the recovery vs {err[0.0]:.2f} without"
    )


def test_a_recovery_raises_the_roll_and_pitch_variances() -> None:
    """q_rec = k^2 r / (1 - k) per prediction (k = dt / (recovery_time / 8 + dt), r = r_phi, r_theta per
    sample): at rest after one clipped sample the roll and pitch variances are more than three times the
    normal ones within the recovery, the yaw variance is the normal prediction's, and after it both
    settle back to the normal ones; the 20 steps of the recovery, and no later one, are flagged."""
    n, spike = 300, 200
    gyr = np.zeros((n, 3), np.float32)
    gyr[spike] = (CLIP, 0.0, 0.0)  # one sample at the full scale, then rest again
    acc = np.tile(np.float32([0.0, 0.0, 9.80665]), (n, 1))
    p = {}
    for rt in (0.2, 0.0):
        c = native.Filter(FilterKind.EKF, _settings(recovery_time=rt))
        out = c.run(gyr, acc, check_units=False)
        p[rt] = np.array(c.state.u.ekf.st.p[0:21])
        if rt:
            co = c.state.u.ekf.c
            k = np.float32(0.01) / (np.float32(0.2 / 8) + np.float32(0.01))
            for i in (0, 1):
                assert co.q_rec[i] == pytest.approx(float(k * k / (1 - k) * co.r_step[i]), rel=1e-5)
            flagged = (out["flags"] & INITIALISED) != 0
            assert flagged[spike : spike + 20].all() and not flagged[spike + 20 :].any(), "0.2 s flagged"
    # 15 steps after the spike: within the recovery of 20 steps
    c = native.Filter(FilterKind.EKF, _settings(recovery_time=0.2))
    c.run(gyr[: spike + 15], acc[: spike + 15], check_units=False)
    off = native.Filter(FilterKind.EKF, _settings(recovery_time=0.0))
    off.run(gyr[: spike + 15], acc[: spike + 15], check_units=False)
    pr, po = c.state.u.ekf.st.p, off.state.u.ekf.st.p
    assert float(pr[0]) > 3 * float(po[0]) and float(pr[6]) > 3 * float(po[6]), "roll, pitch less sure"
    assert float(pr[11]) == float(po[11]), "yaw's variance: the prediction's alone"
    # after the recovery both settle back to the same variances
    assert p[0.2][0] == pytest.approx(p[0.0][0], rel=0.05) and p[0.2][6] == pytest.approx(p[0.0][6], rel=0.05)


def test_f17_p_stays_positive_definite_in_a_recovery() -> None:
    """F17 (fuzz_filter at 2cbcd63, tests/fuzz/regressions/filter-ekf-P_SPD-recovery.bin): dt 0.5 s, a bias
    variance of 1e6 (p0_bias = p_max), a gyro sample of FLT_MAX starting a recovery; the next step's
    update, from the recovery's process noise (k = 2/3 at this dt), left P indefinite in float32 (the
    conditioning ran only every 16th step). P is now conditioned at every step of a recovery: positive
    definite after each step here, C and reference bit for bit."""
    hx = float.fromhex
    s = replace(
        EkfSettings(),
        dt=hx("0x1.01017cp-1"),
        q_psi=hx("0x1.018104p-7"),
        gate=hx("0x1.ec73fep-52"),
        p0_bias=1e6,
        p_max=1e6,
        accel_reject=hx("0x1.305c3p-79"),
        bias_init=(hx("0x1.30303p-79"), 0.0, hx("0x1.78018p-79")),
    )
    gyr = np.array([[0.0, 0.0, 0.0], [hx("0x1.fffffep+127"), 0.0, 0.0], [0.0, 0.0, 0.0]], np.float32)
    acc = np.array(
        [
            [-8.0, hx("0x1.fcp+2"), hx("0x1.39d014p+3")],
            [0.0, 0.0, hx("0x1.39d014p+3")],
            [0.0, hx("0x1.7dd1ccp-127"), hx("0x1.39d014p+3")],
        ],
        np.float32,
    )
    out = replay_positive_definite(s, gyr, acc)
    assert out["flags"][0] & INITIALISED, "the last step is in the recovery"
