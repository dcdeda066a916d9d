"""During a recovery the accel low-pass holds the plain mean of the samples since the clip.

att_i_recovery_lp_gain (att_core.h: its second gain k2, and the mean's end k_end) and its mirror
recovery_lp_gain (attica.reference._common), session 7.

After a clipping gyro sample the stages restart, and while the running mean runs (1 / (n + 1) not below
k_lp / 4, the mekf's k_lp / (2 sqrt 2)) the second stage is held at the first: both are the mean of the
samples since the clip (in the estimate's earth frame, which every correction turns together with the
stages). Before, the second stage was the mean of the first's running means, weighting the samples right
after the clip most (about ln(n / j) for the j-th of n), and the mean ended where its gain was the
stages' own. Checked on every kind that has the recovery, through the state the C holds:

- with the gyro still after the clip, R(q)^T lp2 is the mean of the accel samples since the clip (to
  float rounding), not the early-weighted mean, which is about 10 deg away on this stream (fails on the
  code before);
- the mean runs past the update where its gain is the stages' own, to its end (fails on the code
  before), and the stages part after it;
- the cascade runs again after the mean (a check that k2 does not stay 1; it cannot fail on the code
  before, where the stages were never one);
- what it buys on the simulator: ``attica eval --suite``'s clipped condition (docs/accuracy.md).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from attica import native
from attica.settings import FilterKind

DT = 0.01
RANGE = 10.0  # rad/s: a sample of 10 on an axis clips (>= 0.98 of the range)
SETTLE = 400  # steps before the clip: the start's recovery (2 s) is over
N_MEAN = 60  # steps after the clip, inside the mean (it runs to 4 / k_lp > 200 steps or the recovery's end)
FIELD = np.array([0.0, 20.0, -40.0], np.float32)  # uT, sensor frame, level: north and down
KINDS = [
    ("ars", FilterKind.ARS, {}),
    ("kf", FilterKind.KF, {}),
    ("ekf", FilterKind.EKF, {}),
    ("mars", FilterKind.MARS, {}),
    ("mekf", FilterKind.MEKF, {}),
    ("mekf6", FilterKind.MEKF, {"use_mag": False}),
]


def _tilted(rng: np.random.Generator, n: int) -> np.ndarray:
    """n specific forces, |a| 10.5 m/s^2 (away from g: no rest is detected), their tilt swinging from
    +20 to -20 deg about y over the mean's samples (a linear acceleration that reverses) with a random
    part across it."""
    out = np.empty((n, 3), np.float32)
    for i in range(n):
        v = np.array([0.35 * (1.0 - 2.0 * min(i, N_MEAN) / N_MEAN), rng.uniform(-0.2, 0.2), 1.0])
        out[i] = 10.5 * v / np.linalg.norm(v)
    return out


def _rot(q: Any) -> np.ndarray:
    w, x, y, z = (float(q.w), float(q.x), float(q.y), float(q.z))
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _vec(v: Any) -> np.ndarray:
    return np.array([float(v.x), float(v.y), float(v.z)])


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    c = float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)))
    return float(np.arccos(min(1.0, max(-1.0, c))))


def _run(
    kind: FilterKind, over: dict[str, Any], after: int = N_MEAN + 100
) -> tuple[Any, list[Any], np.ndarray]:
    """The filter after the settle, the clip and ``after`` still samples; its state after each; the accel."""
    f = native.Filter(kind, dt=DT, gyro_range=RANGE, **over)
    still = np.zeros(3, np.float32)
    up = np.array([0.0, 0.0, 9.80665], np.float32)
    for _ in range(SETTLE):
        f.step(still, up, FIELD)
    acc = _tilted(np.random.default_rng(7), after + 1)
    f.step(np.array([RANGE, 0.0, 0.0], np.float32), acc[0], FIELD)  # the clipping sample
    states = []
    for a in acc[1:]:
        f.step(still, a, FIELD)
        st = getattr(f.state.u, kind.label).st
        r = _rot(st.q) if kind != FilterKind.EKF else np.eye(3)  # the ekf's state is Euler angles
        states.append((r, _vec(st.lp1), _vec(st.lp2), int(st.rec_lp_n)))
    return f, states, acc


@pytest.mark.parametrize(("name", "kind", "over"), KINDS, ids=[k[0] for k in KINDS])
def test_the_stages_hold_the_mean_since_the_clip(name: str, kind: FilterKind, over: dict[str, Any]) -> None:
    _, states, acc = _run(kind, over)
    r, lp1, lp2, n = states[N_MEAN - 1]
    assert n == N_MEAN + 1, "the clipping sample and every still one entered the mean"
    # one stage (to the rounding of the correction that turns both, e.g. ars's alignment)
    assert np.abs(lp1 - lp2).max() < 1e-5, "during the mean the two stages are one"
    plain = acc[: N_MEAN + 1].astype(np.float64).mean(axis=0)
    # the cascade's mean of means, for scale: the j-th of n samples weighted by sum_{k >= j} 1 / k
    wts = np.array([sum(1.0 / k for k in range(j, N_MEAN + 2)) for j in range(1, N_MEAN + 2)])
    early = (wts[:, None] * acc[: N_MEAN + 1]).sum(axis=0) / wts.sum()
    assert np.degrees(_angle(plain, early)) > 5.0, "the stream tells the two means apart"
    if name == "ekf":
        return  # its stages live in the heading frame (the yaw left out): the stages' agreement is the check
    seen = r.T @ lp2  # the stages in the sensor frame of the last sample
    assert np.degrees(_angle(seen, plain)) < 0.01, f"{name}: the stages are the plain mean"
    assert abs(np.linalg.norm(seen) - np.linalg.norm(plain)) < 1e-3


def _joined(lp1: np.ndarray, lp2: np.ndarray) -> bool:
    return bool(np.abs(lp1 - lp2).max() < 1e-5)


@pytest.mark.parametrize(("name", "kind", "over"), KINDS, ids=[k[0] for k in KINDS])
def test_the_mean_runs_until_it_is_as_good_as_the_stages(
    name: str, kind: FilterKind, over: dict[str, Any]
) -> None:
    """tau_acc_lp 0.4 s, recovery_time 4 s: the mean runs past the update where its gain is the stages'
    own (n = 1 / k_lp, where it ended until session 7) to n = 4 / k_lp for the first-order cascades
    (ATT_I_REC_MEAN_END: there its variance and age are the cascade's) and 2 sqrt(2) / k_lp for the
    mekf's Butterworth section (ATT_MEKF_REC_MEAN_END: its age is the section's lag); then the stages
    part."""
    tau = 0.4
    mekf = kind == FilterKind.MEKF
    k_lp = DT / ((np.sqrt(2.0) * tau if mekf else tau) + DT)
    n_end = (2.0 * np.sqrt(2.0) if mekf else 4.0) / k_lp
    _, states, _ = _run(kind, {**over, "tau_acc_lp": tau, "recovery_time": 4.0}, after=int(n_end) + 40)
    by_n = {n: (lp1, lp2) for _, lp1, lp2, n in states}
    assert int(round(1.5 / k_lp)) < n_end - 5
    assert _joined(*by_n[int(round(1.5 / k_lp))]), f"{name}: still one past the stages' own gain"
    assert _joined(*by_n[int(n_end) - 3]), f"{name}: still one just before the end"
    assert not _joined(*by_n[int(n_end) + 30]), f"{name}: the cascade runs again after the end"


@pytest.mark.parametrize(("name", "kind", "over"), KINDS, ids=[k[0] for k in KINDS])
def test_the_cascade_resumes_after_the_mean(name: str, kind: FilterKind, over: dict[str, Any]) -> None:
    """tau_acc_lp 0.2 s: the mean's end (1 / (n + 1) below k_lp / 4, about n = 84 at 100 Hz; the mekf's
    about 83) comes within the stream, and from there the cascade runs again: the stages part."""
    _, states, _ = _run(kind, {**over, "tau_acc_lp": 0.2})
    _, lp1, lp2, _ = states[-1]
    assert np.abs(lp1 - lp2).max() > 1e-3, f"{name}: past the floor the cascade runs again"
