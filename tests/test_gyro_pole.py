"""The gyro baseline at the pole (D1, issue 26): a step whose Euler increments are not representable.

Near pitch +-pi/2 with a cos_min below |cos(theta)|, sec(theta) * rate * dt leaves the range of
att_wrap_pi (8192 rad). Before the fix that step was NUMERIC with the angles kept, and under a steady
rotation every later step repeated it (docs/robustness.md, D1). Now such a step turns the attitude by
the rotation vector w dt as a quaternion and reads consistent ZYX angles back (att_gyro.c gyro_rotate,
reference/gyro.py rotated_euler), flagged GIMBAL. The reproducers of D1 itself are in test_recovery.py.
"""

from __future__ import annotations

import math

import numpy as np
import recovery_support as rs

from attica import native, reference
from attica.settings import FilterKind, Flag, make_settings

from helpers import assert_same_bits

F32 = np.float32
POLE = [float(F32(np.pi / 2)), float(np.nextafter(F32(np.pi / 2), F32(0)))]
"""The float32 pitches nearest pi/2 (|cos| 4.4e-8 and 7.5e-8)."""


def _draw(rng: np.random.Generator) -> tuple[object, np.ndarray]:
    """Settings at a pole (cos_min below its cosine) and a rate whose singular part |q sin(phi) + r cos(phi)|
    dt is at least 1e-3 rad (a yaw increment beyond 1e4 rad: not representable)."""
    sign = 1.0 if rng.random() < 0.5 else -1.0
    e0 = (rng.uniform(-math.pi, math.pi), sign * POLE[int(rng.integers(2))], rng.uniform(-math.pi, math.pi))
    dt = float(F32(rng.choice([1e-4, 1e-3, 0.01, 0.1, 1.0])))
    gr = 1e3 if rng.random() < 0.3 else 34.906586
    s = make_settings(
        FilterKind.GYRO, dt=dt, gyro_range=gr, cos_min=float(10 ** rng.uniform(-38, -8)), euler_init=e0
    )
    phi = float(F32(e0[0]))
    while True:
        w = rng.normal(size=3) * 10 ** rng.uniform(-1, math.log10(2.0 * gr))
        w = np.clip(w, -2.0 * gr, 2.0 * gr).astype(F32)  # up to twice the range: a reading at the rail
        if abs(float(w[1]) * math.sin(phi) + float(w[2]) * math.cos(phi)) * dt >= 1e-3:
            return s, w


def test_unrepresentable_euler_step_turns_the_quaternion() -> None:
    """300 draws at a pole (either float32 pitch nearest +-pi/2, any roll and yaw, cos_min 1e-38 .. 1e-8, dt
    1e-4 .. 1 s, rates up to 2e3 rad/s: twice the largest range, a reading at the rail), 32 samples of a
    constant rate each: the first step (NUMERIC before the fix, and every step after it) is flagged GIMBAL,
    not NUMERIC, and its attitude is q exp(w dt / 2) within 1e-5 rad plus the float32 rounding of the
    angle (3e-7 |w| dt); no step is NUMERIC; C and reference bit for bit."""
    rng = np.random.default_rng(2601)
    worst = 0.0
    for i in range(300):
        s, w = _draw(rng)
        assert native.settings_problem(FilterKind.GYRO, s) is None
        gyr = np.tile(w, (32, 1))
        acc = np.tile(F32([0.0, 0.0, rs.G_STD]), (32, 1))
        out = native.Filter(FilterKind.GYRO, settings=s).run(gyr, acc, check_units=False)
        ref = reference.Filter(FilterKind.GYRO, settings=s).run(gyr, acc, check_units=False)
        for name in ("q", "euler"):
            assert_same_bits(out[name], ref[name], f"draw {i}: {name}")
        assert (out["flags"] == ref["flags"]).all(), i
        flags = np.asarray(out["flags"], np.uint32)
        assert not (flags & Flag.NUMERIC).any(), (i, s, w)
        assert flags[0] & Flag.GIMBAL, (i, s, w)
        e0 = np.asarray(s.euler_init, np.float64)
        want = rs.turned64(rs.quat_from_euler64(e0), w, s.dt)
        err = rs.quat_angle(out["q"][0], want)
        angle = float(np.linalg.norm(w.astype(np.float64))) * s.dt
        worst = max(worst, err / (1e-5 + 3e-7 * angle))
        assert err < 1e-5 + 3e-7 * angle, (i, err, angle, s, w)
        assert np.abs(out["euler"][:, 1]).max() <= F32(np.pi / 2)
    print(f"\nworst error of the quaternion step / its bound: {worst:.3f}")


def test_representable_steps_are_the_euler_steps() -> None:
    """Off the pole nothing changed: a gimbal passage at cos_min 1e-3 (the clamped, wrong rates of the
    baseline) and a rotation at 1e-6 rad from the pole whose increments stay within the wrap's range are
    the Euler steps of the kind (flags as before: GIMBAL only from the clamp), C and reference bit for bit."""
    for s, w, n in [
        (make_settings(FilterKind.GYRO, dt=0.01), (0.0, 1.0, 0.3), 300),
        (
            make_settings(FilterKind.GYRO, dt=0.01, cos_min=1e-9, euler_init=(0.2, math.pi / 2 - 1e-6, 0.1)),
            (0.0, 0.0, 1e-4),
            32,
        ),
    ]:
        gyr = np.tile(F32(w), (n, 1))
        acc = np.tile(F32([0.0, 0.0, rs.G_STD]), (n, 1))
        out = native.Filter(FilterKind.GYRO, settings=s).run(gyr, acc, check_units=False)
        ref = reference.Filter(FilterKind.GYRO, settings=s).run(gyr, acc, check_units=False)
        assert_same_bits(out["euler"], ref["euler"], str(s))
        flags = np.asarray(out["flags"], np.uint32)
        assert not (flags & Flag.NUMERIC).any()
        # the Euler step of the first sample, by hand in float32 (no quaternion step: the increments fit)
        e = [F32(x) for x in s.euler_init]
        dt = F32(s.dt)
        sphi, cphi = F32(math.sin(e[0])), F32(math.cos(e[0]))
        cth = F32(math.cos(e[1]))
        yaw_inc = float((sphi / cth * F32(w[1]) + cphi / cth * F32(w[2])) * dt)
        assert abs(yaw_inc) < 8192.0
        assert abs(float(out["euler"][0, 2]) - math.remainder(float(e[2]) + yaw_inc, 2 * math.pi)) < 1e-3
