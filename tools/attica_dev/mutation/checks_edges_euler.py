"""Stage B: the Euler kinds (ekf, gyro) at the edges that the streams of the other checks do not reach.

Each check drives the C library through its public calls with settings inside the contract
(``att_filter_settings_check`` accepts them) and digests every output record: exact bounds (an
increment of exactly 1/16 rad, a wrap landing on -pi, a tilt error exactly at the settled threshold,
cos(theta) exactly 0 or exactly cos_min), the repair of a covariance that lost positive definiteness,
a re-initialisation during the convergence phase, and the gyro-only kind's quaternion fallback (D1).
"""

from __future__ import annotations

import warnings
from typing import Any

from attica_dev.mutation.checks_common import _sha

NAN = float("nan")
PIO2 = float.fromhex("0x1.921fb6p+0")
"""pi/2 rounded to float32 (above pi/2: cos is -4.37e-8 there), the bound of the pitch settings."""


def _filter(kind: str, dt: float, **settings: Any) -> Any:
    """A native.Filter of ``kind`` (the unit warning of a long dt silenced)."""
    from attica import native

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return native.Filter(kind, dt, **settings)


def _run(f: Any, samples: list[tuple[tuple[float, float, float], tuple[float, float, float]]]) -> list[bytes]:
    """Step ``f`` through (gyr, acc) samples; the bytes of every full output record."""
    return [f.step(g, a).tobytes() for g, a in samples]


def _ekf_bounds_check() -> str:
    """The EKF's exact bounds: the midpoint increment of 1/16 rad, the wrap onto -pi, the settled test.

    - roll's half increment exactly 1/16 rad (dt 1, p 0.125 rad/s) takes the first-order midpoint
      sin/cos (a bound inclusive: att_ekf_sincos_mid), yaw rate 0.5 rad/s shows it in the yaw;
    - a yaw increment to -3 pi + 2^-22 (dt 1, r = that rate) wraps by one step of 2 pi to -pi exactly,
      which att_wrap_pi takes to pi - 2^-22 (the interval is (-pi, pi]);
    - a first accel sample whose tilt error sits exactly on the settled threshold (h2 == 0.01 (h2 + z^2)
      in float32: a = (1 + 2^-23, 0, 9.949876)) is not settled (strict <): the raw sample is the
      measurement, the stages are not started from gravity.
    """
    parts: list[Any] = []
    f = _filter("ekf", 1.0, init_from_accel=False)
    parts.append(_run(f, [((0.125, 0.0, 0.5), (0.0, 0.0, 0.0)), ((0.0, 0.125, 0.0), (0.0, 0.0, 0.0))]))
    a = -float(0x96CBE4) * 2.0**-20  # -3 pi_f + 2^-22, a float
    f = _filter("ekf", 1.0, init_from_accel=False, gyro_range=1000.0)
    parts.append(_run(f, [((0.0, 0.0, a), (0.0, 0.0, 0.0)), ((0.0, 0.0, a), (0.0, 0.0, 9.80665))]))
    f = _filter("ekf", 0.01, init_from_accel=False)
    ax, az = float.fromhex("0x1.000002p+0"), 9.949875831604004
    parts.append(_run(f, [((0.0, 0.0, 0.0), (ax, 0.0, az))] * 3))
    return _sha(parts)


def _ekf_trig_check() -> str:
    """cos(theta) of the prediction exactly 0: the update's guard takes it to +cos_min.

    Pitch 1.52 rad plus an increment d (dt 1, q = d rad/s) with fl(cos(1.52) cos(d)) == fl(sin(1.52)
    sin(d)) in the angle addition (d <= 1/16); an accel sample with a roll error shows the sign.
    """
    parts: list[Any] = []
    d = 0.05079634487628937
    f = _filter("ekf", 1.0, init_from_accel=False, euler_init=(0.0, 1.52, 0.0))
    parts.append(_run(f, [((0.0, d, 0.0), (-9.7, 1.0, 0.5)), ((0.0, 0.0, 0.0), (-9.7, 1.0, 0.5))]))
    return _sha(parts)


def _ekf_repair_check() -> str:
    """Conditionings that find P not positive definite with margin: shrunk, and shrunk then zeroed.

    A pitch of 1.24 rad with dt 0.35 s, fast rotation and no accel (F15: every step conditioned) loses
    the margin at the third step by a pivot whose sum needs every term of row j of L^-1 (not only
    m_j,j-1), which the shrink repairs; a random case (dt 0.36 s, r ~1e-15) needs the correlations
    zeroed at its second step. Accel updates follow, so the repaired P shows in the angles.
    """
    parts: list[Any] = []
    f = _filter(
        "ekf",
        0.3500218987464905,
        init_from_accel=False,
        euler_init=(0.0, 1.2422610521316528, 0.0),
        q_bias=0.0003038311842828989,
        p0_bias=8.400277137756348,
        gyro_range=1000.0,
        cos_min=1e-6,
    )
    gyr = [
        (3.874046564102173, -5.3141021728515625, -1.4491395950317383),
        (-0.567530632019043, -5.336648464202881, 3.766145706176758),
        (-0.32946985960006714, -0.11721154302358627, -1.0260372161865234),
    ]
    parts.append(_run(f, [(g, (NAN, 0.0, 0.0)) for g in gyr]))
    parts.append(_run(f, [((0.01, 0.02, 0.03), (-9.0, 0.5, 0.6))] * 4))
    f = _filter(
        "ekf",
        0.3612412214279175,
        init_from_accel=False,
        euler_init=(0.0, -0.6357579231262207, 0.0),
        q_phi=3.8348087372241935e-08,
        q_theta=5.302468533696647e-11,
        q_bias=2.148168398719008e-08,
        r_phi=1.59883196854555e-15,
        r_theta=4.056230349653011e-16,
        p0=4.412816451804247e-06,
        p0_bias=0.08682501316070557,
        gyro_range=1000.0,
        cos_min=1.5913483366603032e-06,
        tau_acc_lp=0.0,
    )
    samples = [
        (
            (1.0324511528015137, 0.5846476554870605, 0.7283413410186768),
            (-3.3354649543762207, -3.193676471710205, 9.223005294799805),
        ),
        (
            (0.49662014842033386, 0.3446520268917084, -0.3712652623653412),
            (0.7414612174034119, 0.7034767270088196, 6.501323699951172),
        ),
    ]
    parts.append(_run(f, samples))
    parts.append(_run(f, [((0.01, 0.02, 0.03), (-3.0, -3.0, 9.0))] * 4))
    return _sha(parts)


def _ekf_recover_check() -> str:
    """A re-initialisation (after a step flagged NUMERIC) during the convergence phase ends that phase.

    Pitch 1.5 rad, an accel sample far from it starts the convergence phase (raw samples as the
    measurement); a prediction beyond the wrap's range (dt 1, 1000 rad/s) flags NUMERIC; the next
    sample re-initialises; after an unusable gyro sample the stages restart from gravity (a sample
    within 0.1 rad of the estimate, the convergence phase over), not from the raw sample.
    """
    f = _filter(
        "ekf",
        1.0,
        init_from_accel=False,
        euler_init=(0.0, 1.5, 0.0),
        gyro_range=1000.0,
        r_phi=1e6,
        r_theta=1e6,
        p0=1e-6,
    )
    samples = [
        ((0.0, 0.0, 0.0), (0.0, 0.0, 9.80665)),
        ((-1000.0, 0.0, 1000.0), (0.0, 0.0, 9.80665)),
        ((0.0, 0.0, 0.0), (0.0, 0.0, 9.80665)),
        ((NAN, 0.0, 0.0), (0.5, 0.2, 9.7)),
        ((0.0, 0.0, 0.0), (0.5, 0.2, 9.7)),
    ]
    return _sha(_run(f, samples))


def _gyro_edges_check() -> str:
    """The gyro-only kind: the quaternion fallback at the pole (D1) and |cos(theta)| exactly cos_min.

    At pitch pi/2 (float32) with cos_min 1e-9 the Euler increments of 1000 rad/s over 1 s leave the wrap's
    range: the rotation is integrated as a quaternion and read back (GIMBAL). With cos_min set to the
    library's own cos(1) and pitch 1 the guard is not taken (strict <): no GIMBAL.
    """
    from attica.native import lib

    parts: list[Any] = []
    f = _filter("gyro", 1.0, euler_init=(0.3, PIO2, -0.2), cos_min=1e-9, gyro_range=1000.0)
    parts.append(_run(f, [((0.0, 0.0, 1000.0), (0.0, 0.0, 0.0)), ((5.0, 1000.0, -3.0), (0.0, 0.0, 0.0))]))
    f = _filter("gyro", 1.0, euler_init=(0.4, -PIO2, 0.1), cos_min=1e-9, gyro_range=1000.0)
    parts.append(_run(f, [((700.0, 0.0, 1000.0), (0.0, 0.0, 0.0))]))
    cm = float(lib.att_cosf(1.0))
    f = _filter("gyro", 0.01, euler_init=(0.0, 1.0, 0.0), cos_min=cm)
    parts.append(_run(f, [((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))] * 2))
    return _sha(parts)
