"""EKF fuzz finding F18: P left indefinite when an update collapses a roll or pitch variance by many
orders of magnitude (docs/robustness.md; reproducer: tests/fuzz/regressions/filter-ekf-P_SPD-collapse.bin)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from attica.settings import EkfSettings

from ekf_support import replay_positive_definite

NAN = math.nan


def test_f18_p_stays_positive_definite_when_a_variance_collapses() -> None:
    """F18 (fuzz_filter at 1bd98f6, tests/fuzz/regressions/filter-ekf-P_SPD-collapse.bin; the defect is
    older: 1aadc0f fails on the input too): dt 0.5 s, p0_bias = p_max = 1e6, six steps without a usable
    accel sample drive roll's and pitch's variances to p_max through the bias; the second update after
    them collapses them from 1e6 to 2e-4, and the rounding of the bias rows (P - K H P) left P indefinite.
    P is now conditioned after an update whose prior roll or pitch variance is more than 2^12 times its
    measurement noise: positive definite after every step here, C and reference bit for bit."""
    hx = float.fromhex
    s = replace(
        EkfSettings(),
        dt=hx("0x1.01017cp-1"),
        q_psi=hx("0x1.018104p-7"),
        p0=hx("0x1.78p-7"),
        p0_bias=1e6,
        p_max=1e6,
        accel_reject=hx("0x1.305c3p-79"),
        bias_init=(hx("0x1.30303p-79"), 0.0, hx("0x1.78018p-79")),
    )
    gyr = np.array(
        [
            [hx("0x1.8p-1"), hx("0x1.8p-1"), hx("0x1.8p-1")],
            [hx("0x1.30303p-79"), hx("0x1.8p-145"), hx("-0x1.93e594p+99")],
            [hx("0x0p+0"), hx("0x0p+0"), hx("0x0p+0")],
            [hx("0x0p+0"), hx("0x0p+0"), hx("0x0p+0")],
            [hx("0x0p+0"), hx("0x0p+0"), hx("0x0p+0")],
            [hx("0x0p+0"), hx("0x0p+0"), hx("0x0p+0")],
            [hx("0x0p+0"), hx("0x0p+0"), hx("0x0p+0")],
            [hx("0x0p+0"), hx("0x0p+0"), hx("0x0p+0")],
            [hx("0x0p+0"), hx("0x0p+0"), hx("0x0p+0")],
            [hx("0x0p+0"), hx("0x0p+0"), hx("0x0p+0")],
        ],
        np.float32,
    )
    acc = np.array(
        [
            [hx("0x1.8p+0"), hx("0x1.8p+0"), hx("0x1.69d014p+3")],
            [hx("0x0p+0"), hx("0x1.fep-142"), hx("-0x1p+39")],
            [hx("0x0p+0"), hx("0x0p+0"), NAN],
            [hx("0x0p+0"), hx("0x0p+0"), NAN],
            [hx("0x0p+0"), hx("0x0p+0"), NAN],
            [hx("0x0p+0"), hx("0x0p+0"), NAN],
            [hx("0x0p+0"), hx("0x0p+0"), NAN],
            [hx("0x0p+0"), hx("0x0p+0"), hx("0x1.cac6c6p+89")],
            [hx("0x0p+0"), hx("0x0p+0"), hx("0x1.39d014p+3")],
            [hx("0x0p+0"), hx("0x0p+0"), hx("0x1.39d014p+3")],
        ],
        np.float32,
    )
    replay_positive_definite(s, gyr, acc)
