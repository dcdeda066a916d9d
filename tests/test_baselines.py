"""Gyro-only and accel-only baselines: bit-exactness, behaviour, guards."""

from __future__ import annotations

import numpy as np
import pytest

from attica import kinds, native
from attica.crosscheck import Stream, crosscheck
from attica.metrics import error_angles
from attica.settings import Flag
from attica.sim import SimConfig, simulate, simulate_with_truth

from helpers import adversarial_floats

RATE = 285.714


def _streams(count: int, duration: float) -> list[Stream]:
    out = []
    for i in range(count):
        rec = simulate(SimConfig(duration=duration, rate=RATE, seed=300 + i, rotation_rms=1.5, taps=10))
        out.append(Stream(rec.gyr, rec.acc, rec.mag, name=f"sim{300 + i}"))
    return out


BASELINES = [k.label for k in kinds.KINDS if k.baseline]
"""The single-sensor kinds (gyro-only, accel-only), from the registry."""

CASES = [(label, {}) for label in BASELINES] + [("tilt", {"normalise": False})]
"""Each baseline with its defaults, and the non-normalised tilt."""


@pytest.mark.parametrize("kind,overrides", CASES)
def test_bit_exact_simulated(kind: str, overrides: dict) -> None:
    dt = {"dt": 1 / RATE} if kinds.info(kind).has_period else {}
    r = crosscheck(kind, _streams(6, 600.0), **dt, **overrides)
    print(f"\n{kind}{overrides}: {r.steps} steps compared")
    assert r.steps >= 1_000_000
    assert r.ok, r.first_mismatch


def _adversarial(n: int, seed: int) -> Stream:
    rng = np.random.default_rng(seed)
    g = rng.normal(0, 3, (n, 3)).astype(np.float32)
    a = (rng.normal(0, 6, (n, 3)) + [0, 0, 9.8]).astype(np.float32)
    for arr in (g, a):
        mask = rng.random(arr.shape) < 0.05
        arr[mask] = adversarial_floats(int(mask.sum()), seed)
    a[rng.random(n) < 0.01] = 0.0
    # drive pitch through +-90 deg: a long constant pitch rate
    g[1000:3000] = [0.0, 2.0, 0.3]
    a[4000:4100] = [12.0, 0.0, 0.5]  # |ax| > g: clamped in the non-normalised tilt
    return Stream(g, a, name=f"adversarial{seed}")


@pytest.mark.parametrize("kind,overrides", CASES)
def test_bit_exact_adversarial(kind: str, overrides: dict) -> None:
    dt = {"dt": 0.01} if kinds.info(kind).has_period else {}
    r = crosscheck(kind, [_adversarial(40_000, s) for s in range(3)], segment=500, **dt, **overrides)
    assert r.steps >= 100_000
    assert r.ok, r.first_mismatch
    for out in r.c_outputs:
        assert np.isfinite(out["q"]).all() and np.isfinite(out["euler"]).all()


def test_gyro_tracks_truth_with_clean_gyro() -> None:
    """Noise- and bias-free rates: Euler-rate integration follows the truth (first-order error only)."""
    rec, truth = simulate_with_truth(
        SimConfig(
            duration=30.0, rate=1000.0, seed=11, rotation_rms=0.5, initial_attitude=(1.0, 0.0, 0.0, 0.0)
        )
    )
    out = native.Filter("gyro", dt=1e-3).run(truth.gyr.astype(np.float32), rec.acc)
    err = np.degrees(error_angles(out["q"].astype(np.float64), rec.quat_true)[0])
    print(f"\ngyro-only on clean rates: max total error {err.max():.3f} deg over 30 s at 1 kHz")
    assert err.max() < 1.0


def test_gyro_gimbal_guard() -> None:
    f = native.Filter("gyro", dt=0.01)
    flags = 0
    for _ in range(300):  # 3 s at 1 rad/s about y: pitch passes +90 deg
        rec = f.step((0.0, 1.0, 0.0), (0.0, 0.0, 9.81))
        flags |= int(rec["flags"])
        assert np.isfinite(rec["euler"]).all()
        assert -np.pi / 2 - 1e-6 <= rec["euler"][1] <= np.pi / 2 + 1e-6
    assert flags & Flag.GIMBAL
    # pitched through the pole by 3 rad in total: the attitude is a 3 rad rotation about y
    q = f.output()["q"]
    angle = 2 * np.degrees(np.arccos(min(1.0, abs(float(q[0])))))
    assert abs(angle - np.degrees(3.0)) < 2.0


@pytest.mark.parametrize(
    "gyr,flag",
    [
        ((np.nan, 0, 0), Flag.GYRO_INVALID),
        ((0, 0, 1e9), Flag.GYRO_RANGE),
        ((np.inf, 0, 0), Flag.GYRO_INVALID),
    ],
)
def test_gyro_bad_input_keeps_state(gyr: tuple, flag: Flag) -> None:
    f = native.Filter("gyro", dt=0.01)
    f.step((0.1, 0.2, 0.3), (0, 0, 9.81))
    before = f.output()
    rec = f.step(gyr, (0, 0, 9.81))
    assert rec["flags"] & flag
    assert rec["q"].tobytes() == before["q"].tobytes()


def test_tilt_angles() -> None:
    f = native.Filter("tilt")
    for phi, theta in [(0.3, -0.2), (-1.0, 0.5), (2.5, 1.2), (0.0, -1.5)]:
        g = 9.80665
        acc = (-g * np.sin(theta), g * np.sin(phi) * np.cos(theta), g * np.cos(phi) * np.cos(theta))
        rec = f.step((0, 0, 0), acc)
        np.testing.assert_allclose(rec["euler"][:2], [phi, theta], atol=2e-6)


def test_tilt_clamp_and_invalid() -> None:
    f = native.Filter("tilt", normalise=False)
    assert f.step((0, 0, 0), (0, 0, 0))["flags"] & Flag.NOT_READY
    rec = f.step((0, 0, 0), (12.0, 0.0, 1.0))
    assert rec["flags"] & Flag.CLAMPED
    assert rec["euler"][1] == np.float32(-np.pi / 2)
    before = rec["q"].copy()
    for bad in [(np.nan, 0, 9.8), (0, 0, 0), (1e20, 0, 0), (0, np.inf, 0)]:
        rec = f.step((0, 0, 0), bad)
        assert rec["flags"] & (Flag.ACCEL_INVALID | Flag.ACCEL_RANGE)
        assert not rec["flags"] & Flag.NOT_READY
        assert rec["q"].tobytes() == before.tobytes()


@pytest.mark.parametrize(
    "kind,field,value",
    [
        ("gyro", "dt", 0.0),
        ("gyro", "cos_min", 0.0),
        ("gyro", "cos_min", 1.0),
        ("gyro", "euler_init", (0.0, 2.0, 0.0)),
        ("tilt", "gravity", -1.0),
        ("tilt", "accel_range", float("nan")),
    ],
)
def test_settings_rejected(kind: str, field: str, value: object) -> None:
    kw: dict[str, object] = {"dt": 0.01} if kinds.info(kind).has_period else {}
    kw[field] = value
    # a bad dt is refused in Python already (ValueError), every other field by the C library
    with pytest.raises((native.NativeError, ValueError), match="out of range|finite sample period"):
        native.Filter(kind, **kw)
