"""Linear quaternion KF: C against the numpy reference bit for bit, the isotropic covariance against a
float64 4x4 Kalman filter, bias, low-pass measurement, adaptive noise and gate, convergence, bad input.

Motion is generated here in float64 (ZYX Euler angles as smooth random sinusoids, exact body rates
and specific force), so the test does not depend on the simulator.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from attica.native import ffi, lib
from attica.reference.kf import Kf
from attica.settings import SEED_OVERRIDES, BiasMode, FilterKind, Flag, KfSettings, Preset, preset_settings

from helpers import adversarial_floats, assert_same_bits

G = 9.80665
DT = 0.01  # 100 Hz


# --- motion generator (float64) ---------------------------------------------------------------


def _rot_inv(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate earth-frame v into the sensor frame of attitude q (sensor-to-earth), float64."""
    w = q[..., :1]
    u = -q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        -1,
    )


def _euler_quat(phi: np.ndarray, th: np.ndarray, psi: np.ndarray) -> np.ndarray:
    cr, sr = np.cos(phi / 2), np.sin(phi / 2)
    cp, sp = np.cos(th / 2), np.sin(th / 2)
    cy, sy = np.cos(psi / 2), np.sin(psi / 2)
    return np.stack(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ],
        -1,
    )


def motion(
    m: int,
    steps: int,
    seed: int,
    dt: float = DT,
    roll_amp: float = 1.0,
    pitch_amp: float = 0.7,
    yaw_amp: float = 2.0,
    lin_rms: float = 0.5,
    gyro_noise: float = 0.005,
    acc_noise: float = 0.05,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """m independent streams: gyr, acc float32 (steps, m, 3) and true q float64 (steps, m, 4).

    Roll/pitch/yaw are sums of 4 sinusoids (0.05..0.5 Hz) with peak amplitudes up to the given
    values (rad); body rates follow exactly from the Euler rates; the specific force is
    R^T (a_lin + [0, 0, g]) with a_lin the derivative of a sinusoidal velocity scaled to lin_rms.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(steps)[:, None] * dt

    def sines(amp: float) -> tuple[np.ndarray, np.ndarray]:
        a = rng.uniform(0, 1, (4, m))
        a = a / a.sum(0) * amp * rng.uniform(0.3, 1.0, m)
        f = rng.uniform(0.05, 0.5, (4, m)) * 2 * np.pi
        ph = rng.uniform(0, 2 * np.pi, (4, m))
        x = np.zeros((steps, m))
        xd = np.zeros((steps, m))
        for k in range(4):
            x += a[k] * np.sin(f[k] * t + ph[k])
            xd += a[k] * f[k] * np.cos(f[k] * t + ph[k])
        return x, xd

    phi, dphi = sines(roll_amp)
    th, dth = sines(pitch_amp)
    psi, dpsi = sines(yaw_amp)
    sp, cp, st, ct = np.sin(phi), np.cos(phi), np.sin(th), np.cos(th)
    w = np.stack([dphi - dpsi * st, dth * cp + dpsi * ct * sp, -dth * sp + dpsi * ct * cp], -1)
    q = _euler_quat(phi, th, psi)
    lin = np.stack([sines(1.0)[1] for _ in range(3)], -1)
    lin = lin / (np.sqrt(np.mean(lin**2, axis=0, keepdims=True)) + 1e-12) * lin_rms
    acc = _rot_inv(q, lin + np.array([0.0, 0.0, G]))
    gyr = w + rng.normal(0, gyro_noise, w.shape)
    acc = acc + rng.normal(0, acc_noise, acc.shape)
    return gyr.astype(np.float32), acc.astype(np.float32), q


def inclination_deg(q_est: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    """Angle between estimated and true 'up' (sensor frame), degrees."""
    up = np.array([0.0, 0.0, 1.0])
    ue = _rot_inv(q_est.astype(np.float64), up)
    ut = _rot_inv(q_true, up)
    c = np.sum(ue * ut, -1) / np.linalg.norm(ue, axis=-1) / np.linalg.norm(ut, axis=-1)
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def yaw_deg(q: np.ndarray) -> np.ndarray:
    q = q.astype(np.float64)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.degrees(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


# --- C side -----------------------------------------------------------------------------------

FIELDS = [f.name for f in dataclasses.fields(KfSettings)]


def c_settings(dt: float = DT, **fields: Any) -> Any:
    s = ffi.new("att_kf_settings_t *")
    lib.att_kf_settings_default(s, dt)
    for k, v in fields.items():
        if k in ("q_init", "bias_init"):
            setattr(s, k, tuple(float(c) for c in v))
        elif k in ("bias_mode", "bias_n_max"):
            setattr(s, k, int(v))
        elif k in ("init_from_accel", "noise_rates"):
            setattr(s, k, bool(v))
        else:
            setattr(s, k, float(v))
    return s


def c_filters(m: int, per_instance: dict[str, Any]) -> Any:
    """m C filters; per_instance maps a settings field to a scalar or a length-m sequence."""
    fs = ffi.new("att_kf_t[]", m)
    for j in range(m):
        vals = {
            k: (v[j] if np.ndim(v) > (1 if k in ("q_init", "bias_init") else 0) else v)
            for k, v in per_instance.items()
        }
        dt = vals.pop("dt", DT)
        assert lib.att_kf_init(fs + j, c_settings(dt, **vals)) == lib.ATT_OK
    return fs


def c_run(fs: Any, m: int, gyr: np.ndarray, acc: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Step m filters through (steps, m, 3) inputs; returns q (steps,m,4), p (steps,m), flags."""
    steps = gyr.shape[0]
    g = np.ascontiguousarray(gyr, np.float32)
    a = np.ascontiguousarray(acc, np.float32)
    q = np.empty((steps, m, 4), np.float32)
    p = np.empty((steps, m), np.float32)
    fl = np.empty((steps, m), np.uint32)
    n = lib.att_host_kf_run(
        fs, m, ffi.from_buffer("float[]", g), ffi.from_buffer("float[]", a), steps,
        ffi.from_buffer("float[]", q), ffi.from_buffer("float[]", p), ffi.from_buffer("uint32_t[]", fl),
    )  # fmt: skip
    assert n == steps * m
    return q, p, fl


def run_both(per_instance: dict[str, Any], gyr: np.ndarray, acc: np.ndarray) -> tuple[np.ndarray, ...]:
    """Run C and reference in lockstep and require identical bits (q, p, flags) at every step."""
    steps, m, _ = gyr.shape
    fs = c_filters(m, per_instance)
    q_c, p_c, fl_c = c_run(fs, m, gyr, acc)
    ref = Kf(KfSettings(dt=DT, **{k: v for k, v in per_instance.items() if k != "dt"}), n=m)
    if "dt" in per_instance:
        ref = Kf(KfSettings(**per_instance), n=m)
    for t in range(steps):
        fl = ref.step(gyr[t], acc[t])
        np.testing.assert_array_equal(fl, fl_c[t], err_msg=f"flags at step {t}")
        assert_same_bits(ref.quat, q_c[t], f"q at step {t}")
        assert_same_bits(ref.variance, p_c[t], f"p at step {t}")
    assert (ref.steps == np.uint32(steps)).all()
    for j in range(m):
        assert fs[j].st.steps == steps
    return q_c, p_c, fl_c


# --- tests ------------------------------------------------------------------------------------


def test_settings_defaults_match() -> None:
    s = ffi.new("att_kf_settings_t *")
    lib.att_kf_settings_default(s, 0.01)
    d = KfSettings()
    assert [n for n, _ in ffi.typeof("att_kf_settings_t").fields] == FIELDS
    for name in FIELDS:
        c_val = getattr(s, name)
        py_val = getattr(d, name)
        if name == "q_init":
            assert [np.float32(getattr(c_val, k)) for k in "wxyz"] == [np.float32(v) for v in py_val]
        elif name == "bias_init":
            assert [np.float32(getattr(c_val, k)) for k in "xyz"] == [np.float32(v) for v in py_val]
        elif isinstance(py_val, bool):
            assert bool(c_val) == py_val
        elif isinstance(py_val, int):
            assert int(c_val) == int(py_val)
        else:
            assert np.float32(c_val) == np.float32(py_val), name


def test_bit_exact_motion_1e6_steps() -> None:
    """>= 1e6 steps of motion with linear acceleration over varied settings: q, p, flags identical."""
    m, steps = 100, 10_000
    gyr, acc, _ = motion(m, steps, seed=1)
    rng = np.random.default_rng(2)
    per = {
        "q_noise": rng.choice([1e-3, 1e-1, 1e-6], m),
        "r_noise": rng.choice([1e-5, 1e-2, 1e-7], m),
        "r_accel": rng.choice([0.0, 10.0, 1000.0], m),
        "gate": rng.choice([0.0, 0.0, 20.0, 1e-3], m),
        "tau_acc_lp": rng.choice([1.5, 0.0, 0.3], m),
        "bias_mode": rng.choice([int(BiasMode.AT_REST), int(BiasMode.RUNNING), int(BiasMode.OFF)], m),
        "accel_reject": rng.choice([0.0, 0.3], m),
    }
    q_c, p_c, fl_c = run_both(per, gyr, acc)
    assert m * steps >= 1_000_000
    assert np.isfinite(q_c).all() and (p_c > 0).all()
    gated = (fl_c & Flag.ACCEL_REJECTED) != 0
    print(f"\n{m * steps} steps bit-exact; accel rejected or gated in {gated.mean():.3f} of the steps")
    assert gated.any() and not gated.all()


def test_bit_exact_adversarial() -> None:
    """Adversarial samples (NaN, Inf, huge, subnormal, zero, over-range) at the extremes of the settings."""
    m, steps = 40, 3000
    gyr, acc, _ = motion(m, steps, seed=5, dt=0.02)
    rng = np.random.default_rng(6)
    bad = adversarial_floats(steps * m * 3, seed=7).reshape(steps, m, 3)
    sel = rng.random((steps, m)) < 0.15
    gyr[sel] = bad[sel]
    sel = rng.random((steps, m)) < 0.15
    acc[sel] = bad[rng.permutation(steps)][sel]
    acc[rng.random((steps, m)) < 0.02] = 0.0
    per = {
        "dt": rng.choice([0.02, 1.0, 1e-6], m),
        "q_noise": rng.choice([1e-12, 1.0, 1e6], m),
        "r_noise": rng.choice([1e-12, 1.0, 1e6], m),
        "p0": rng.choice([1e-12, 1e6], m),
        "gate": rng.choice([0.0, 1e6, 1e-3], m),
        "r_accel": rng.choice([0.0, 1e6], m),
        "gyro_range": rng.choice([34.906586, 1e3], m),
        "accel_range": rng.choice([156.9064, 1e4], m),
        "noise_rates": False,
        "init_from_accel": rng.random(m) < 0.7,
        "q_init": rng.normal(0, 1, (m, 4)),
    }
    q_c, p_c, fl_c = run_both(per, gyr, acc)
    assert np.isfinite(q_c).all() and np.isfinite(p_c).all() and (p_c > 0).all()
    norm = np.linalg.norm(q_c.astype(np.float64), axis=-1)
    assert np.abs(norm - 1).max() < 1e-6
    assert not (fl_c & Flag.NUMERIC).any()  # no sample can make the state unusable


def test_noise_rates_extremes_are_safe() -> None:
    """Issue 26 R3: with noise_rates the per-step noises q_noise dt and r_noise / dt are no longer
    range-checked (att_kf.h states the ranges of q_noise, r_noise and dt only). Over those ranges they lie in
    [1e-18, 1e6] and [1e-12, 1e12], normal floats; the extremes of dt and both noises (with p0, gate and
    r_accel at theirs) on the adversarial stream above: C equals the reference bit for bit, q stays a unit
    quaternion, p finite, positive and normal, and no step is NUMERIC (as with the per-step noises)."""
    m, steps = 64, 3000
    gyr, acc, _ = motion(m, steps, seed=15, dt=0.02)
    rng = np.random.default_rng(16)
    bad = adversarial_floats(steps * m * 3, seed=17).reshape(steps, m, 3)
    sel = rng.random((steps, m)) < 0.15
    gyr[sel] = bad[sel]
    sel = rng.random((steps, m)) < 0.15
    acc[sel] = bad[rng.permutation(steps)][sel]
    corner = np.array([(d, q, r) for d in (1e-6, 1.0) for q in (1e-12, 1e6) for r in (1e-12, 1e6)])
    pick = np.arange(m) % len(corner)
    per = {
        "dt": corner[pick, 0],
        "q_noise": corner[pick, 1],
        "r_noise": corner[pick, 2],
        "p0": rng.choice([1e-12, 1e6], m),
        "gate": rng.choice([0.0, 1e6, 1e-3], m),
        "r_accel": rng.choice([0.0, 1e6], m),
        "accel_range": rng.choice([156.9064, 1e4], m),
        "noise_rates": True,
    }
    fs = c_filters(m, per)
    q_step = np.array([fs[j].c.q_step for j in range(m)], np.float32)
    r_step = np.array([fs[j].c.r_step for j in range(m)], np.float32)
    tiny = np.finfo(np.float32).tiny
    assert (q_step >= tiny).all() and np.isfinite(r_step).all() and (r_step >= tiny).all()
    assert q_step.min() == np.float32(np.float32(1e-12) * np.float32(1e-6)) and r_step.max() > 1e11
    q_c, p_c, fl_c = run_both(per, gyr, acc)
    assert np.isfinite(q_c).all() and np.isfinite(p_c).all() and (p_c >= tiny).all()
    norm = np.linalg.norm(q_c.astype(np.float64), axis=-1)
    assert np.abs(norm - 1).max() < 1e-6
    assert not (fl_c & Flag.NUMERIC).any()


def _kf64(gyr: np.ndarray, acc: np.ndarray, s: KfSettings, q0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The textbook 4x4 KF (float64): x' = A x, P' = A P A^T + Q, z from the same low-passed gravity,
    K = P (P + R)^-1, x += K (z - x), P = (I - K) P, then x /= |x|, P /= |x|^2 (no bias, no gate)."""
    dt = s.dt
    k_lp = dt / (s.tau_acc_lp + dt)
    q_step, r_step = s.q_noise * dt, s.r_noise / dt
    x = q0.astype(np.float64)
    p = np.eye(4) * s.p0
    lp1 = lp2 = np.array([0.0, 0.0, s.gravity])  # att_kf_reset without init_from_accel
    ps = []
    xs = []
    for t in range(gyr.shape[0]):
        w = gyr[t].astype(np.float64) * dt / 2
        om = np.array(
            [[0, -w[0], -w[1], -w[2]], [w[0], 0, w[2], -w[1]], [w[1], -w[2], 0, w[0]], [w[2], w[1], -w[0], 0]]
        )
        a = np.eye(4) + om
        x = a @ x
        p = a @ p @ a.T + q_step * np.eye(4)
        v = _rot_inv(np.array([x[0], -x[1], -x[2], -x[3]]) / np.linalg.norm(x), acc[t].astype(np.float64))
        lp1 = lp1 + (v - lp1) * k_lp
        lp2 = lp2 + (lp1 - lp2) * k_lp
        u = lp2 / np.linalg.norm(lp2)
        cw = np.sqrt((1 + u[2]) / 2)
        c = np.array([cw, u[1] / (2 * cw), -u[0] / (2 * cw), 0.0])
        z = _qmul(c, x)
        kk = p @ np.linalg.inv(p + r_step * np.eye(4))
        xn = x + kk @ (z - x)
        # the applied rotation, for the low-pass stages: (1 - k) I + k C
        k = kk[0, 0]
        rot = np.array([1 - k + k * c[0], k * c[1], k * c[2], 0.0])
        rot /= np.linalg.norm(rot)
        lp1 = _rot_inv(np.array([rot[0], -rot[1], -rot[2], -rot[3]]), lp1)
        lp2 = _rot_inv(np.array([rot[0], -rot[1], -rot[2], -rot[3]]), lp2)
        p = (np.eye(4) - kk) @ p
        n2 = xn @ xn
        x = xn / np.sqrt(n2)
        p = p / n2
        ps.append(p)
        xs.append(x)
    return np.array(xs), np.array(ps)


def test_covariance_is_isotropic_as_the_4x4_filter() -> None:
    """The 4x4 textbook filter's P stays p I (off-diagonal and unequal diagonal at float64 rounding),
    and its p and attitude agree with the scalar C filter within float32 rounding."""
    gyr, acc, _ = motion(1, 3000, seed=9, lin_rms=0.2)
    s = KfSettings(dt=DT, bias_mode=BiasMode.OFF, q_noise=1e-2, r_noise=1e-4, init_from_accel=False)
    f = c_filters(
        1, {"bias_mode": int(BiasMode.OFF), "q_noise": 1e-2, "r_noise": 1e-4, "init_from_accel": False}
    )
    q_c, p_c, _ = c_run(f, 1, gyr, acc)
    x64, p64 = _kf64(gyr[:, 0], acc[:, 0], s, np.array([1.0, 0, 0, 0]))
    off = np.abs(p64 - np.eye(4) * p64[:, :1, :1]).max(axis=(1, 2)) / p64[:, 0, 0]
    assert off.max() < 1e-12, "the 4x4 covariance is not isotropic"
    rel = np.abs(p_c[:, 0] / p64[:, 0, 0] - 1)
    print(f"\nworst relative difference of p: {rel.max():.2e}; of q: {np.abs(q_c[:, 0] - x64).max():.2e}")
    assert rel.max() < 1e-4
    assert np.abs(q_c[:, 0] - x64).max() < 1e-4


def test_bias_from_the_rest_detector_is_subtracted() -> None:
    """A constant gyro bias: learnt at rest and subtracted, so the yaw stays put (after the 0.86 deg it
    integrates during the 0.5 s the rest detector waits); without it, it drifts 0.03 rad/s for 40 s."""
    steps = 4000
    gyr = np.zeros((steps, 1, 3), np.float32) + np.float32([0.01, -0.02, 0.03])
    acc = np.zeros((steps, 1, 3), np.float32) + np.float32([0, 0, G])
    q_on, _, fl = c_run(c_filters(1, {}), 1, gyr, acc)
    q_off, _, _ = c_run(c_filters(1, {"bias_mode": int(BiasMode.OFF)}), 1, gyr, acc)
    assert (fl[-1, 0] & Flag.AT_REST) and (fl & Flag.BIAS_UPDATED).any()
    assert abs(yaw_deg(q_on[-1, 0])) < 1.0 and abs(yaw_deg(q_on[-1, 0]) - yaw_deg(q_on[1000, 0])) < 1e-3
    assert abs(yaw_deg(q_off[-1, 0])) > 60


def test_gate_rejects_and_flags() -> None:
    """With a gate, a sudden tilt of the measured gravity (0.5 rad) is rejected (flagged, not applied)
    until the variance, growing by q_step a step while nothing is applied, makes it plausible (a
    lasting change is accepted after about 2 s here); without the gate it is followed at once."""
    steps = 800
    gyr = np.zeros((steps, 1, 3), np.float32)
    acc = np.zeros((steps, 1, 3), np.float32) + np.float32([0, 0, G])
    acc[300:] = np.float32([0, G * np.sin(0.5), G * np.cos(0.5)])
    per = {"tau_acc_lp": 0.0, "gate": 20.0, "bias_mode": int(BiasMode.OFF)}
    q_g, p_g, fl_g = run_both(per, gyr, acc)
    q_n, _, fl_n = run_both({**per, "gate": 0.0}, gyr, acc)
    level = np.array([[1.0, 0, 0, 0]])
    gated = (fl_g[:, 0] & Flag.ACCEL_REJECTED) != 0
    assert not gated[:300].any() and gated[300:400].all() and not (fl_n & Flag.ACCEL_REJECTED).any()
    assert inclination_deg(q_g[399:400, 0], level)[0] < 0.01  # not applied
    assert (np.diff(p_g[300:400, 0]) > 0).all()  # the variance grows meanwhile
    assert inclination_deg(q_n[320:321, 0], level)[0] > 25  # followed without the gate
    assert abs(inclination_deg(q_g[-1:, 0], level)[0] - np.degrees(0.5)) < 0.5  # accepted in the end


def test_converges_from_60_deg_roll_error() -> None:
    gyr, acc, q_true = motion(4, 4000, seed=12, lin_rms=0.3)
    e = np.radians(60.0)
    per = {"init_from_accel": False, "q_init": (np.cos(e / 2), np.sin(e / 2), 0.0, 0.0)}
    q_c, _, _ = c_run(c_filters(4, per), 4, gyr, acc)
    err = inclination_deg(q_c, q_true)
    print(f"\ninclination error after 10 s: {err[1000].max():.2f} deg, last 10 s {err[3000:].max():.2f}")
    assert err[0].min() > 30 and err[3000:].max() < 5.0


def test_first_sample_initialises() -> None:
    f = c_filters(1, {})
    assert (
        lib.att_kf_step(f, (0.0, 0.0, 0.0), (float("nan"), 0.0, 0.0)) == Flag.NOT_READY | Flag.ACCEL_INVALID
    )
    fl = lib.att_kf_step(f, (0.0, 0.0, 0.0), (0.0, G * np.sin(0.3), G * np.cos(0.3)))
    assert fl & Flag.INITIALISED and f[0].st.initialised
    assert abs(np.degrees(2 * np.arcsin(f[0].st.q.x)) - np.degrees(0.3)) < 1e-3


@pytest.mark.parametrize(
    "gyr,acc,flag",
    [
        ((np.nan, 0, 0), (0, 0, G), Flag.GYRO_INVALID),
        ((0, -np.inf, 0), (0, 0, G), Flag.GYRO_INVALID),
        ((40.0, 0, 0), (0, 0, G), Flag.GYRO_RANGE),
        ((0.1, 0, 0), (np.nan, 0, 0), Flag.ACCEL_INVALID),
        ((0.1, 0, 0), (np.inf, 0, 0), Flag.ACCEL_INVALID),
        ((0.1, 0, 0), (0, 0, 0), Flag.ACCEL_INVALID),
        ((0.1, 0, 0), (0, 0, 200.0), Flag.ACCEL_RANGE),
    ],
)
def test_bad_input_flagged(gyr: tuple[float, ...], acc: tuple[float, ...], flag: Flag) -> None:
    f = c_filters(1, {})
    ref = Kf(KfSettings(dt=DT))
    for _ in range(3):
        assert lib.att_kf_step(f, (0.0, 0.0, 0.0), (0.0, 0.0, G)) == int(ref.step((0, 0, 0), (0, 0, G))[0])
    before = bytes(ffi.buffer(f))
    fl = lib.att_kf_step(f, gyr, acc)
    assert fl & flag and fl == int(ref.step(np.float32(gyr), np.float32(acc))[0])
    assert_same_bits(ref.quat[0], [f[0].st.q.w, f[0].st.q.x, f[0].st.q.y, f[0].st.q.z], "q")
    assert_same_bits(ref.variance, [f[0].st.p], "p")
    assert bytes(ffi.buffer(f)) != before  # time passed (steps, p)


def test_null_and_bad_args() -> None:
    f = ffi.new("att_kf_t *")
    s = c_settings()
    assert lib.att_kf_init(ffi.NULL, s) == lib.ATT_ERR_NULL
    assert lib.att_kf_init(f, ffi.NULL) == lib.ATT_ERR_NULL
    assert lib.att_kf_step(ffi.NULL, (0, 0, 0), (0, 0, G)) == Flag.BAD_ARG
    lib.att_kf_reset(ffi.NULL)
    lib.att_kf_settings_default(ffi.NULL, DT)
    assert lib.att_kf_retune(ffi.NULL, s) == lib.ATT_ERR_NULL


BAD_SETTINGS = [
    ("dt", np.nan), ("dt", -0.01), ("dt", 0.0), ("dt", 1.5), ("dt", np.inf), ("dt", 1e-7),
    ("q_noise", 0.0), ("q_noise", -1e-4), ("q_noise", np.nan), ("q_noise", np.inf), ("q_noise", 2e6),
    ("r_noise", 0.0), ("r_noise", np.nan), ("r_noise", 2e6),
    ("r_accel", -1.0), ("r_accel", np.nan), ("r_accel", 2e6),
    ("gate", -1.0), ("gate", np.nan), ("gate", np.inf),
    ("p0", 0.0), ("p0", -1.0), ("p0", np.nan), ("p0", np.inf),
    ("gravity", 0.0), ("gravity", -G), ("gravity", np.nan), ("gravity", 0.5), ("gravity", 101.0),
    ("accel_reject", -0.1), ("accel_reject", np.nan), ("accel_reject", np.inf),
    ("accel_range", 0.0), ("accel_range", np.nan), ("accel_range", np.inf), ("accel_range", 9.0),
    ("gyro_range", 0.0), ("gyro_range", np.nan), ("gyro_range", np.inf), ("gyro_range", 2e3),
    ("bias_mode", 4), ("bias_n_max", 0), ("bias_init", (40.0, 0.0, 0.0)),
    ("rest_gyro", -1.0), ("rest_accel", 20.0), ("rest_time", np.nan),
    ("tau_acc_lp", -1.0), ("tau_acc_lp", np.inf),
    ("q_init", (0.0, 0.0, 0.0, 0.0)), ("q_init", (np.nan, 0.0, 0.0, 0.0)),
    ("q_init", (np.inf, 0.0, 0.0, 0.0)), ("q_init", (1e-30, 0.0, 0.0, 0.0)),
]  # fmt: skip


@pytest.mark.parametrize("name,value", BAD_SETTINGS, ids=[f"{n}={v}" for n, v in BAD_SETTINGS])
def test_settings_rejected(name: str, value: Any) -> None:
    f = ffi.new("att_kf_t *")
    assert lib.att_kf_init(f, c_settings()) == lib.ATT_OK
    for _ in range(3):
        lib.att_kf_step(f, (0.1, 0.0, 0.0), (0.0, 0.0, G))
    before = bytes(ffi.buffer(f))
    s = c_settings(**{name: value})
    assert lib.att_kf_settings_validate(s) == lib.ATT_ERR_SETTINGS
    assert lib.att_kf_init(f, s) == lib.ATT_ERR_SETTINGS
    assert lib.att_kf_retune(f, s) == lib.ATT_ERR_SETTINGS
    assert bytes(ffi.buffer(f)) == before


GOOD_SETTINGS = [
    ("dt", 1.0), ("dt", 1e-6), ("q_noise", 1e-12), ("q_noise", 1e6), ("r_noise", 1e-12), ("r_noise", 1e6),
    ("p0", 1e-12), ("p0", 1e6), ("accel_reject", 0.0), ("accel_range", 1e4), ("gyro_range", 1e3),
    ("gate", 1e6), ("r_accel", 1e6), ("q_init", (0.0, 0.0, 0.0, 2.0)),
]  # fmt: skip


@pytest.mark.parametrize("name,value", GOOD_SETTINGS, ids=[f"{n}={v}" for n, v in GOOD_SETTINGS])
def test_settings_accepted(name: str, value: Any) -> None:
    f = ffi.new("att_kf_t *")
    kw = {name: value, "noise_rates": False} if name in ("dt", "q_noise", "r_noise") else {name: value}
    assert lib.att_kf_init(f, c_settings(**kw)) == lib.ATT_OK


def test_noise_rates_scaled_and_validated() -> None:
    f = ffi.new("att_kf_t *")
    assert lib.att_kf_init(f, c_settings(q_noise=2e-3, r_noise=3e-4)) == lib.ATT_OK
    assert f.c.q_step == np.float32(np.float32(2e-3) * np.float32(DT))
    assert f.c.r_step == np.float32(np.float32(3e-4) / np.float32(DT))
    # the per-step values are not range-checked (issue 26 R3: refused before, a limit att_kf.h states
    # nowhere): q_noise dt down to 1e-18, r_noise / dt up to 1e12
    for dt, q, r in ((0.01, 1e-12, 2e4), (1e-6, 1e-12, 1e6), (1.0, 1e6, 1e-12), (1e-6, 1e6, 1e-12)):
        assert lib.att_kf_init(f, c_settings(q_noise=q, r_noise=r, dt=dt)) == lib.ATT_OK
        assert f.c.q_step == np.float32(np.float32(q) * np.float32(dt))
        assert f.c.r_step == np.float32(np.float32(r) / np.float32(dt))


def test_seed_preset_is_the_literal_filter() -> None:
    s = preset_settings(FilterKind.KF, Preset.SEED, dt=DT)
    for name, value in SEED_OVERRIDES[FilterKind.KF].items():
        assert getattr(s, name) == value
    gyr, acc, _ = motion(3, 2000, seed=4)
    run_both(dataclasses.asdict(s), gyr, acc)
