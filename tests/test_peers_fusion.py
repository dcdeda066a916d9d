"""Fusion as the peers and the suite run it: the README's 5 s rejection timeout, at any rate.

imufusion 1.3 takes ``rejection_timeout`` in seconds (``AhrsSettings`` has the sample rate). Until
2026-12-06 attica gave it 1425, the samples of 5 s at BROAD's rate, which Fusion read as 1425 s: its
acceleration recovery never ran. These tests fail with that value.
"""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest

from attica.data import Recording
from attica.evaluate.suite import suite_methods
from attica.metrics import error_angles
from attica.peers import FUSION_DEFAULT, _run_fusion, peer_by_name

from helpers import need

TILT = math.radians(30.0)


def _need_fusion() -> None:
    need(importlib.util.find_spec("imufusion") is not None, "imufusion missing (pip install '.[peers]')")


def _tilted_at(rate: float, at: float = 10.0, duration: float = 25.0) -> tuple[Recording, np.ndarray]:
    """Still and level, then at ``at`` s the accel turns 30 deg about x with no rotation in the gyro.

    Fusion rejects the accel (10 deg threshold) and, after its rejection timeout, recovers to it.
    Returns the recording and the up direction the accel shows, per sample, as a quaternion's tilt.
    """
    n = int(duration * rate)
    acc = np.tile([0.0, 0.0, 9.80665], (n, 1))
    k = int(at * rate)
    acc[k:] = [0.0, 9.80665 * math.sin(TILT), 9.80665 * math.cos(TILT)]
    rec = Recording(np.zeros((n, 3)), acc, np.full((n, 3), np.nan), rate, name="tilted")
    q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    # the attitude whose gravity reads (0, g sin, g cos): a turn of +30 deg about x, sensor to earth
    q[k:] = [math.cos(TILT / 2.0), math.sin(TILT / 2.0), 0.0, 0.0]
    return rec, q


@pytest.mark.parametrize("rate", [50.0, 285.714, 1000.0])
def test_fusion_recovers_to_the_accel_5_s_after_it_rejects_it(rate: float) -> None:
    _need_fusion()
    rec, q_accel = _tilted_at(rate)
    est = _run_fusion(rec, False, FUSION_DEFAULT)
    _, _, incl = error_angles(est.q, q_accel)
    deg = np.degrees(incl)
    i = lambda t: int(t * rate)  # noqa: E731
    assert deg[i(9.9)] < 0.5  # level, as the accel said
    assert deg[i(13.0)] > 25.0  # 3 s after the step: the accel is rejected, the gyro holds level
    assert deg[i(24.9)] < 2.0  # recovered to the accel after the 5 s timeout (it never would at 1425 s)


def test_the_peer_and_the_suite_give_fusion_the_same_timeout() -> None:
    """The registered peers and the suite's (with a gyro range) run Fusion with the README's settings."""
    _need_fusion()
    rec, q_accel = _tilted_at(100.0)
    peer = peer_by_name("fusion6").estimate(rec)
    (suite,) = suite_methods([], ["fusion6"], gyro_range=math.radians(500.0))
    ranged = suite.estimate(rec)
    for est in (peer, ranged):
        _, _, incl = error_angles(est.q, q_accel)
        assert np.degrees(incl[-10]) < 2.0
