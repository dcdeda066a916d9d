"""The accel low-pass restarted by a clipping gyro sample: ars, kf, ekf and mars (issue 23).

The low-pass stages hold specific force turned into the earth (the ekf: heading) frame by the gyro's
rotation, and that rotation is wrong while the gyro clips. On a clipping sample the stages' gain is 1
(``att_i_recovery_lp_gain``, att_core.h): they restart from that sample, and the recovery's faster gain
follows. The mekf marks its stages invalid instead (tests/test_mekf_recovery.py).

- the restart itself: after the first clipping sample of a turn the two stages hold the same vector (one
  sample), while with the recovery off (``recovery_time`` 0, no restart) they do not;
- what it buys: the suite's clipped turn (14 rad/s against 500 deg/s), the inclination error in the first
  second after the clipping ends. Measured at the commit that added the restart (seeds 1-4), deg:

  =====  ==================  ===================
  kind   with the restart    stages kept before
  =====  ==================  ===================
  ars    0.34-1.91           7.9-11.4
  kf     0.77-1.90           9.5-13.8
  ekf    3.17-4.86           10.8-16.5
  mars   0.35-1.90           7.9-11.5
  =====  ==================  ===================

C and the reference stay bit for bit on clipping streams (tests/test_{ars,kf,ekf}_recovery.py and
tests/test_recovery.py, which compare every step).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from clip_support import CLIP, RATE, clipped_rows, clipping

from attica import metrics, native
from attica.settings import ArsSettings, EkfSettings, FilterKind, KfSettings, MarsSettings

SETTINGS: dict[FilterKind, Any] = {
    FilterKind.ARS: ArsSettings,
    FilterKind.KF: KfSettings,
    FilterKind.EKF: EkfSettings,
    FilterKind.MARS: MarsSettings,
}
KINDS = list(SETTINGS)
FIRST_SECOND_MAX = {FilterKind.ARS: 3.0, FilterKind.KF: 3.0, FilterKind.EKF: 6.0, FilterKind.MARS: 3.0}
"""Inclination RMSE bound (deg) in the first second after the clipped turn, per kind (table above)."""


def _stages(f: native.Filter, kind: FilterKind) -> tuple[np.ndarray, np.ndarray]:
    st = getattr(f.state.u, kind.name.lower()).st
    return (
        np.array([st.lp1.x, st.lp1.y, st.lp1.z], np.float64),
        np.array([st.lp2.x, st.lp2.y, st.lp2.z], np.float64),
    )


def _run(kind: FilterKind, rec: Any, stop: int, **over: Any) -> native.Filter:
    f = native.Filter(kind, replace(SETTINGS[kind](dt=1.0 / RATE, gyro_range=CLIP), **over))
    f.run(rec.gyr[:stop], rec.acc[:stop], rec.mag[:stop], check_units=False)
    return f


@pytest.mark.parametrize("kind", KINDS, ids=[k.name.lower() for k in KINDS])
def test_a_clipping_sample_restarts_the_stages(kind: FilterKind) -> None:
    rec = clipping(4, 12.0)
    first = int(np.flatnonzero(clipped_rows(rec.gyr))[0])
    lp1, lp2 = _stages(_run(kind, rec, first + 1), kind)
    g = float(np.linalg.norm(lp2))
    assert g > 5.0, "the stages hold specific force"
    assert np.linalg.norm(lp1 - lp2) < 1e-5 * g, "both stages restarted from the clipping sample"
    off1, off2 = _stages(_run(kind, rec, first + 1, recovery_time=0.0), kind)
    assert np.linalg.norm(off1 - off2) > 1e-3 * g, "without a recovery the stages keep their history"
    before1, before2 = _stages(_run(kind, rec, first), kind)
    assert np.linalg.norm(before1 - before2) > 1e-3 * g, "before the clipping the stages differ"


@pytest.mark.parametrize("kind", KINDS, ids=[k.name.lower() for k in KINDS])
def test_the_restart_shortens_the_recovery(kind: FilterKind) -> None:
    from attica.evaluate.suite import condition
    from attica.sim import simulate_with_truth

    cond = condition("clipped")
    errs = []
    for seed in (1, 2, 3, 4):
        r, truth = simulate_with_truth(cond.config(seed, 20.0))
        end = int(np.flatnonzero(truth.gyr_clipped.any(axis=1))[-1]) + 1
        s = SETTINGS[kind](dt=1.0 / r.rate, gyro_range=cond.gyro_range)
        out = native.Filter(kind, s).run(r.gyr, r.acc, r.mag, check_units=False)
        _, _, incl = metrics.error_angles(np.asarray(out["q"], np.float64), r.quat_true)
        errs.append(float(np.degrees(np.sqrt(np.mean(incl[end : end + int(r.rate)] ** 2)))))
    assert max(errs) < FIRST_SECOND_MAX[kind], errs
