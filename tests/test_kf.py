"""Linear quaternion KF: C against the numpy reference bit for bit, convergence, P stays SPD, bad input.

Motion is generated here in float64 (ZYX Euler angles as smooth random sinusoids, exact body rates
and specific force), so the test does not depend on the simulator.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from attica.native import ffi, lib
from attica.reference.kf import Kf, KfSettings, KfYawMode
from attica.settings import SEED_OVERRIDES, FilterKind, Flag, Preset, preset_settings

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
SEED = SEED_OVERRIDES[FilterKind.KF]
"""The tests of the literal filter run the seed preset (the notes' per-step Q and R)."""


def kf_seed(**kw: Any) -> KfSettings:
    """The seed preset with changes."""
    return dataclasses.replace(preset_settings(FilterKind.KF, Preset.SEED), **kw)


def c_settings(dt: float = DT, **fields: Any) -> Any:
    s = ffi.new("att_kf_settings_t *")
    lib.att_kf_settings_default(s, dt)
    for k, v in {**SEED, **fields}.items():
        if k == "q_init":
            s.q_init = tuple(float(c) for c in v)
        elif k == "yaw_mode":
            s.yaw_mode = int(v)
        elif k in ("init_from_accel", "noise_rates"):
            setattr(s, k, bool(v))
        else:
            setattr(s, k, float(v))
    return s


def c_filters(m: int, per_instance: dict[str, Any]) -> Any:
    """m C filters; per_instance maps a settings field to a scalar or a length-m sequence."""
    fs = ffi.new("att_kf_t[]", m)
    for j in range(m):
        vals = {k: (v[j] if np.ndim(v) > (1 if k == "q_init" else 0) else v) for k, v in per_instance.items()}
        dt = vals.pop("dt", DT)
        assert lib.att_kf_init(fs + j, c_settings(dt, **vals)) == lib.ATT_OK
    return fs


def c_run(fs: Any, m: int, gyr: np.ndarray, acc: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Step m filters through (steps, m, 3) inputs; returns q (steps,m,4), P (steps,m,4,4), flags."""
    steps = gyr.shape[0]
    g = np.ascontiguousarray(gyr, np.float32)
    a = np.ascontiguousarray(acc, np.float32)
    q = np.empty((steps, m, 4), np.float32)
    p = np.empty((steps, m, 4, 4), np.float32)
    fl = np.empty((steps, m), np.uint32)
    n = lib.att_host_kf_run(
        fs, m, ffi.from_buffer("float[]", g), ffi.from_buffer("float[]", a), steps,
        ffi.from_buffer("float[]", q), ffi.from_buffer("float[]", p), ffi.from_buffer("uint32_t[]", fl),
    )  # fmt: skip
    assert n == steps * m
    return q, p, fl


def c_state(f: Any) -> tuple[np.ndarray, np.ndarray]:
    q = np.array([f.q.w, f.q.x, f.q.y, f.q.z], np.float32)
    p = np.array([[f.p[i][j] for j in range(4)] for i in range(4)], np.float32)
    return q, p


def check_p_spd(p: np.ndarray, what: str) -> None:
    """p (..., 4, 4) float32: finite, bitwise symmetric, Cholesky (float64) succeeds."""
    p2 = p.reshape(-1, 4, 4)
    assert np.isfinite(p2).all(), f"{what}: P not finite"
    bits = p2.view(np.uint32)
    assert (bits == bits.transpose(0, 2, 1)).all(), f"{what}: P not bitwise symmetric"
    np.linalg.cholesky(p2.astype(np.float64))  # raises LinAlgError if not positive definite
    assert np.linalg.eigvalsh(p2.astype(np.float64)).min() > 0, f"{what}: P not positive definite"


def run_both(
    per_instance: dict[str, Any], gyr: np.ndarray, acc: np.ndarray, check_spd: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Run C and reference in lockstep and require identical bits at every step."""
    steps, m, _ = gyr.shape
    fs = c_filters(m, per_instance)
    q_c, p_c, fl_c = c_run(fs, m, gyr, acc)
    ref = Kf(kf_seed(**per_instance), n=m)
    for t in range(steps):
        fl = ref.step(gyr[t], acc[t])
        np.testing.assert_array_equal(fl, fl_c[t], err_msg=f"flags at step {t}")
        assert_same_bits(ref.quat, q_c[t], f"q at step {t}")
        assert_same_bits(ref.covariance, p_c[t], f"P at step {t}")
        if check_spd:
            check_p_spd(p_c[t], f"step {t}")
    assert (ref.steps == np.uint32(steps)).all()
    for j in range(m):
        assert fs[j].steps == steps
    return q_c, p_c, fl_c


# --- tests ------------------------------------------------------------------------------------


def test_settings_defaults_match() -> None:
    s = ffi.new("att_kf_settings_t *")
    lib.att_kf_settings_default(s, 0.01)
    d = KfSettings()
    for name in FIELDS:
        c_val = getattr(s, name)
        py_val = getattr(d, name)
        if name == "q_init":
            assert [np.float32(getattr(c_val, k)) for k in "wxyz"] == [np.float32(v) for v in py_val]
        elif isinstance(py_val, bool):
            assert bool(c_val) == py_val
        elif isinstance(py_val, int):
            assert int(c_val) == int(py_val)
        else:
            assert np.float32(c_val) == np.float32(py_val), name
    assert s.yaw_mode == lib.ATT_KF_YAW_STATE == KfYawMode.STATE
    assert lib.ATT_KF_YAW_ZERO == KfYawMode.ZERO


def test_bit_exact_motion_1e6_steps_p_spd() -> None:
    """1000 instances x 1000 steps of motion (mixed settings): every q, P, flag identical; P SPD."""
    m, steps = 1000, 1000
    rng = np.random.default_rng(11)
    gyr, acc, q_true = motion(m, steps, seed=1)
    h = rng.uniform(-0.6, 0.6, m)
    q_init = np.stack([np.cos(h), np.sin(h), np.zeros(m), np.zeros(m)], -1)  # up to 69 deg roll
    per = {
        "yaw_mode": rng.integers(0, 2, m),
        "accel_reject": rng.choice([0.0, 0.1, 0.3], m),
        "init_from_accel": rng.random(m) < 0.5,
        "q_init": q_init,
        "q_noise": rng.choice([1e-4, 1e-6, 1e-3], m),
        "r_noise": rng.choice([10.0, 1.0, 100.0], m),
        "p0": rng.choice([1.0, 0.01], m),
    }
    # half in the defaults' mode (q_noise per s, r_noise in unit^2 s), with the same per-step noises
    rates = rng.random(m) < 0.5
    per["noise_rates"] = rates
    per["q_noise"] = np.where(rates, per["q_noise"] / DT, per["q_noise"])
    per["r_noise"] = np.where(rates, per["r_noise"] * DT, per["r_noise"])
    q_c, p_c, fl_c = run_both(per, gyr, acc, check_spd=True)
    print(f"\n{m * steps} steps bit-exact; flags seen: {sorted(set(np.unique(fl_c).tolist()))}")
    assert np.isfinite(q_c).all()
    assert np.abs(np.linalg.norm(q_c.astype(np.float64), axis=-1) - 1).max() < 1e-6
    inc = inclination_deg(q_c[-1], q_true[-1])
    print(f"inclination error after 10 s: median {np.median(inc):.2f}, max {inc.max():.2f} deg")
    assert np.median(inc) < 2.0


def _adversarial(m: int, steps: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    g = rng.normal(0, 2, (steps, m, 3)).astype(np.float32)
    a = (rng.normal(0, 3, (steps, m, 3)) + [0, 0, G]).astype(np.float32)
    for arr in (g, a):
        mask = rng.random(arr.shape) < 0.03
        arr[mask] = adversarial_floats(int(mask.sum()), seed + 1)
    a[rng.random((steps, m)) < 0.02] = 0.0  # zero vector
    a[rng.random((steps, m)) < 0.02] = [G, 0.0, 0.0]  # gimbal lock: pitch -90 deg
    a[rng.random((steps, m)) < 0.02] = [-G, 1e-7, 0.0]  # gimbal lock: pitch +90 deg
    a[rng.random((steps, m)) < 0.01] = [0.0, 0.0, -G]  # upside down
    a[rng.random((steps, m)) < 0.01] = [200.0, 0.0, 0.0]  # over accel range
    a[rng.random((steps, m)) < 0.01] = [0.0, 0.0, 1e30]  # huge
    a[rng.random((steps, m)) < 0.02] = [0.0, 0.0, 1.5 * G]  # rejected
    g[rng.random((steps, m)) < 0.02] = [50.0, 0.0, 0.0]  # over gyro range
    g[rng.random((steps, m)) < 0.02] = [34.9, -34.9, 34.9]  # just inside the range
    g[rng.random((steps, m)) < 0.01] = [1e30, 0.0, 0.0]
    return g, a


def test_bit_exact_adversarial() -> None:
    """>= 1e5 steps of NaN/Inf/zero/huge/gimbal/saturated input and extreme settings, bit-exact."""
    m, steps = 250, 400
    gyr, acc = _adversarial(m, steps, seed=5)
    rng = np.random.default_rng(6)
    per = {
        "dt": rng.choice([0.01, 0.0035, 1.0, 1e-6], m),
        "yaw_mode": rng.integers(0, 2, m),
        "accel_reject": rng.choice([0.0, 0.1, 2.0], m),
        "init_from_accel": rng.random(m) < 0.7,
        "q_init": rng.normal(0, 1, (m, 4)),
        "q_noise": rng.choice([1e-4, 1e-12, 1e12, 1.0], m),
        "r_noise": rng.choice([10.0, 1e-12, 1e12], m),
        "p0": rng.choice([1.0, 1e-12, 1e12], m),
        "gyro_range": rng.choice([34.906586, 1e3], m),  # up to the largest ranges of the contract
        "accel_range": rng.choice([156.9064, 1e4], m),
    }
    # rates where q_noise * dt and r_noise / dt stay within the valid 1e-12 .. 1e12
    per["noise_rates"] = (rng.random(m) < 0.5) & (per["q_noise"] != 1e-12) & (per["r_noise"] != 1e12)
    q_c, p_c, fl_c = run_both(per, gyr, acc)
    print(f"\n{m * steps} adversarial steps bit-exact; NUMERIC in {(fl_c & Flag.NUMERIC != 0).sum()} steps")
    assert m * steps >= 100_000
    assert np.isfinite(q_c).all() and np.isfinite(p_c).all()
    assert np.abs(np.linalg.norm(q_c.astype(np.float64), axis=-1) - 1).max() < 1e-6
    bits = p_c.view(np.uint32)
    assert (bits == np.swapaxes(bits, -1, -2)).all()
    seen = (Flag.GYRO_INVALID, Flag.GYRO_RANGE, Flag.ACCEL_INVALID, Flag.ACCEL_RANGE, Flag.ACCEL_REJECTED)
    for flag in (*seen, Flag.INITIALISED, Flag.NOT_READY):
        assert (fl_c & flag).any(), flag


def test_c_long_motion_p_spd() -> None:
    """The C filter over 3e5 steps (50 min at 100 Hz) of motion: P stays SPD and symmetric, q accurate."""
    gyr, acc, q_true = motion(3, 100_000, seed=21)
    fs = c_filters(3, {})
    q_c, p_c, fl_c = c_run(fs, 3, gyr, acc)
    check_p_spd(p_c, "long run")
    assert np.isfinite(q_c).all()
    inc = inclination_deg(q_c, q_true)
    rms = float(np.sqrt(np.mean(inc[1000:] ** 2)))
    diag = np.einsum("...ii->...i", p_c[1000:].astype(np.float64))
    print(f"\n3e5 steps: inclination RMS {rms:.2f} deg, max {inc[1000:].max():.2f}; "
          f"P diag range {diag.min():.4g}..{diag.max():.4g}")  # fmt: skip
    assert rms < 1.5
    assert diag.max() < 0.1 and diag.min() > 0.01


def test_p_bounded_when_update_skipped_during_fast_spin() -> None:
    """Spinning at 30 rad/s with every accel sample rejected: P must not grow geometrically."""
    n = 100_000
    gyr = np.tile(np.float32([0.0, 0.0, 30.0]), (n, 1))[:, None, :]
    acc = np.tile(np.float32([0.0, 0.0, 2.0 * G]), (n, 1))[:, None, :]
    fs = c_filters(1, {})
    q_c, p_c, fl_c = c_run(fs, 1, gyr, acc)
    assert (fl_c[1:] & Flag.ACCEL_REJECTED).all()
    check_p_spd(p_c, "spin")
    diag = np.einsum("...ii->...i", p_c[-1, 0].astype(np.float64))
    print(f"\nafter {n} skipped updates at 30 rad/s: P diag {diag}")
    assert diag.max() < 1.0 + n * 1e-4 * 1.01
    # the rotation is still integrated; first order A = I + dt/2 Omega, normalised, turns by
    # 2 atan(dt/2 |w|) per step (0.2978 rad instead of 0.3 here: the notes' discretisation)
    yaw = np.unwrap(np.radians(yaw_deg(q_c[:1000, 0])))
    step = np.diff(yaw).mean()
    assert abs(step - 2 * np.arctan(DT / 2 * 30.0)) < 1e-5


def _convergence_errors(lin_rms: float, seeds: range) -> np.ndarray:
    """Per seed: inclination error (deg) over 30 s from a 60 deg wrong start (earth-frame roll)."""
    h = np.radians(30.0)
    err_q = np.array([np.cos(h), np.sin(h), 0.0, 0.0])
    out = []
    for seed in seeds:
        gyr, acc, q_true = motion(1, 3000, seed=seed, lin_rms=lin_rms)
        wrong = _qmul(err_q, q_true[0, 0])
        assert abs(inclination_deg(wrong, q_true[0, 0]) - 60.0) < 1e-6
        fs = c_filters(1, {"init_from_accel": False, "q_init": wrong})
        q_c, _, _ = c_run(fs, 1, gyr, acc)
        out.append(inclination_deg(q_c[:, 0], q_true[:, 0]))
    return np.array(out)


def test_converges_from_60_deg_roll_error() -> None:
    """Defaults at 100 Hz, 60 deg wrong start. Measured (20 seeds): pure rotation < 2 deg from 2.8 s on;
    with 0.5 m/s^2 RMS linear acceleration < 2.6 deg from 5 s on."""
    s = int(1 / DT)
    rot = _convergence_errors(0.0, range(100, 120))
    last_above = np.array([(np.nonzero(e >= 2.0)[0].max() + 1) * DT for e in rot])
    print(f"\nrotation only: < 2 deg from {last_above.max():.2f} s (median {np.median(last_above):.2f} s), "
          f"max after 10 s {rot[:, 10 * s:].max():.2f} deg")  # fmt: skip
    assert rot[:, 0].min() > 50.0
    assert last_above.max() < 3.5
    assert rot[:, 10 * s :].max() < 1.0
    lin = _convergence_errors(0.5, range(100, 120))
    print(f"0.5 m/s^2 linear acc: max after 5 s {lin[:, 5 * s:].max():.2f} deg, "
          f"RMS after 10 s {np.sqrt(np.mean(lin[:, 10 * s:] ** 2)):.2f} deg")  # fmt: skip
    assert lin[:, 5 * s :].max() < 3.5
    assert np.sqrt(np.mean(lin[:, 10 * s :] ** 2)) < 1.2


def test_converges_static() -> None:
    """At rest with noise: 60 deg roll error below 2 deg within 3 s (measured 2.3 s)."""
    rng = np.random.default_rng(3)
    n = 2000
    gyr = rng.normal(0, 0.005, (n, 1, 3)).astype(np.float32)
    acc = (np.array([0.0, 0.0, G]) + rng.normal(0, 0.05, (n, 1, 3))).astype(np.float32)
    h = np.radians(30.0)
    fs = c_filters(1, {"init_from_accel": False, "q_init": (np.cos(h), np.sin(h), 0.0, 0.0)})
    q_c, _, _ = c_run(fs, 1, gyr, acc)
    inc = inclination_deg(q_c[:, 0], np.array([1.0, 0.0, 0.0, 0.0]))
    last_above = (np.nonzero(inc >= 2.0)[0].max() + 1) * DT
    print(f"\nstatic: < 2 deg from {last_above:.2f} s; after 10 s {inc[1000]:.3f} deg")
    assert last_above < 3.0
    assert inc[1000:].max() < 0.3


@pytest.mark.parametrize("mode", [KfYawMode.STATE, KfYawMode.ZERO])
def test_yaw_mode(mode: KfYawMode) -> None:
    """STATE keeps the yaw (gyro only); ZERO pulls it toward 0 like the notes."""
    n = 3000
    yaw0 = 1.0
    q0 = (np.cos(yaw0 / 2), 0.0, 0.0, np.sin(yaw0 / 2))
    gyr = np.zeros((n, 1, 3), np.float32)
    acc = np.tile(np.float32([0.0, 0.0, G]), (n, 1))[:, None, :]
    fs = c_filters(1, {"init_from_accel": False, "q_init": q0, "yaw_mode": mode})
    q_c, _, _ = c_run(fs, 1, gyr, acc)
    yaw = np.radians(yaw_deg(q_c[:, 0]))
    print(f"\n{mode.name}: yaw after 30 s {yaw[-1]:.4f} rad (start {yaw0})")
    if mode == KfYawMode.STATE:
        assert abs(yaw[-1] - yaw0) < 1e-5
    else:
        assert abs(yaw[-1]) < 0.1


def test_first_sample_initialises() -> None:
    f = ffi.new("att_kf_t *")
    assert lib.att_kf_init(f, c_settings()) == lib.ATT_OK
    fl = lib.att_kf_step(f, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert fl & Flag.NOT_READY and fl & Flag.ACCEL_INVALID and not f.initialised
    phi, th = 0.3, -0.2
    acc = (-G * np.sin(th), G * np.sin(phi) * np.cos(th), G * np.cos(phi) * np.cos(th))
    fl = lib.att_kf_step(f, (5.0, 5.0, 5.0), acc)
    assert fl & Flag.INITIALISED and f.initialised
    q, p = c_state(f)
    expect = _euler_quat(np.float64(phi), np.float64(th), np.float64(0.0))
    assert np.abs(q - expect).max() < 1e-6
    np.testing.assert_array_equal(p, np.eye(4, dtype=np.float32))
    lib.att_kf_reset(f)
    assert not f.initialised and f.steps == 0
    assert lib.att_kf_step(f, (0.0, 0.0, 0.0), (np.nan, 0.0, G)) & Flag.NOT_READY


def _level_filter() -> Any:
    f = ffi.new("att_kf_t *")
    assert lib.att_kf_init(f, c_settings()) == lib.ATT_OK
    for _ in range(50):
        lib.att_kf_step(f, (0.01, -0.02, 0.03), (0.1, -0.2, G))
    return f


@pytest.mark.parametrize(
    "gyr,acc,flag",
    [
        ((np.nan, 0, 0), (0, 0, G), Flag.GYRO_INVALID),
        ((0, -np.inf, 0), (0, 0, G), Flag.GYRO_INVALID),
        ((0, 0, 40.0), (0, 0, G), Flag.GYRO_RANGE),
        ((0.1, 0, 0), (0, np.nan, G), Flag.ACCEL_INVALID),
        ((0.1, 0, 0), (0, 0, 0), Flag.ACCEL_INVALID),
        ((0.1, 0, 0), (np.inf, 0, 0), Flag.ACCEL_INVALID),
        ((0.1, 0, 0), (200.0, 0, 0), Flag.ACCEL_RANGE),
        ((0.1, 0, 0), (0, 0, 1e30), Flag.ACCEL_RANGE),
        ((0.1, 0, 0), (0, 0, 1.2 * G), Flag.ACCEL_REJECTED),
        ((0.1, 0, 0), (0, 0, 0.8 * G), Flag.ACCEL_REJECTED),
    ],
)
def test_bad_input_flagged(gyr: tuple[float, ...], acc: tuple[float, ...], flag: Flag) -> None:
    f = _level_filter()
    q0, p0 = c_state(f)
    fl = lib.att_kf_step(f, gyr, acc)
    q1, p1 = c_state(f)
    assert fl & flag and f.flags == fl
    assert not fl & Flag.NUMERIC
    assert np.isfinite(q1).all() and np.isfinite(p1).all()
    assert abs(np.linalg.norm(q1.astype(np.float64)) - 1) < 1e-6
    check_p_spd(p1, str(flag))
    if flag in (Flag.GYRO_INVALID, Flag.GYRO_RANGE):
        # no propagation, P grows by Q (then /|x|^2 after the update): diag between P and P + Q
        d0, d1 = np.diag(p0).astype(np.float64), np.diag(p1).astype(np.float64)
        assert (d1 <= d0 + 1e-4 * 1.001).all()
    else:
        # prediction only: q moved by the gyro, P grew by Q
        assert not np.array_equal(q1, q0)
        d0, d1 = np.diag(p0).astype(np.float64), np.diag(p1).astype(np.float64)
        assert (d1 > d0).all() and (d1 < d0 + 1e-4 * 1.01).all()
    # the same step in the reference gives the same bits
    ref_flags = _ref_replay(gyr, acc)
    assert ref_flags == fl


def _ref_replay(gyr: tuple[float, ...], acc: tuple[float, ...]) -> int:
    ref = Kf(kf_seed(), n=1)
    f = _level_filter()
    for _ in range(50):
        ref.step((0.01, -0.02, 0.03), (0.1, -0.2, G))
    fl = int(ref.step(gyr, acc)[0])
    lib.att_kf_step(f, gyr, acc)
    q, p = c_state(f)
    assert_same_bits(ref.quat[0], q, "q")
    assert_same_bits(ref.covariance[0], p, "P")
    return fl


def test_both_sensors_bad_keeps_attitude() -> None:
    f = _level_filter()
    q0, p0 = c_state(f)
    fl = lib.att_kf_step(f, (np.nan, 0.0, 0.0), (0.0, 0.0, 0.0))
    q1, p1 = c_state(f)
    assert fl & Flag.GYRO_INVALID and fl & Flag.ACCEL_INVALID
    np.testing.assert_allclose(q1, q0, atol=1e-7)
    np.testing.assert_allclose(np.diag(p1), np.diag(p0) + np.float32(1e-4), rtol=1e-5)


def _corrupt_and_step(p_bad: np.ndarray) -> tuple[int, Any, Kf]:
    f = _level_filter()
    ref = Kf(kf_seed(), n=1)
    for _ in range(50):
        ref.step((0.01, -0.02, 0.03), (0.1, -0.2, G))
    for i in range(4):
        for j in range(4):
            f.p[i][j] = float(p_bad[i, j])
            ref.p[i][j] = np.array([p_bad[i, j]], np.float32)
    fl = lib.att_kf_step(f, (0.01, 0.0, 0.0), (0.0, 0.0, G))
    assert int(ref.step((0.01, 0.0, 0.0), (0.0, 0.0, G))[0]) == fl
    q, p = c_state(f)
    assert_same_bits(ref.quat[0], q, "q")
    assert_same_bits(ref.covariance[0], p, "P")
    return fl, f, ref


def test_numeric_cholesky_failure_skips_update() -> None:
    """A non positive definite P (corrupted state): update skipped, NUMERIC, state finite."""
    p_bad = -np.eye(4, dtype=np.float32) * 20.0
    f = _level_filter()
    q0, _ = c_state(f)
    fl, f, _ = _corrupt_and_step(p_bad)
    assert fl & Flag.NUMERIC
    q1, p1 = c_state(f)
    assert np.isfinite(q1).all() and np.isfinite(p1).all()
    assert abs(np.linalg.norm(q1.astype(np.float64)) - 1) < 1e-6


def test_numeric_nonfinite_p_keeps_state() -> None:
    """P with NaN (corrupted state): NUMERIC, the whole state from before the step is kept."""
    p_bad = np.eye(4, dtype=np.float32)
    p_bad[1, 2] = p_bad[2, 1] = np.nan
    fl, f, _ = _corrupt_and_step(p_bad)
    assert fl & Flag.NUMERIC
    q1, _ = c_state(f)
    assert np.isfinite(q1).all()


def test_null_and_bad_args() -> None:
    s = c_settings()
    f = ffi.new("att_kf_t *")
    assert lib.att_kf_init(ffi.NULL, s) == lib.ATT_ERR_NULL
    assert lib.att_kf_init(f, ffi.NULL) == lib.ATT_ERR_NULL
    assert lib.att_kf_step(ffi.NULL, (0.0, 0.0, 0.0), (0.0, 0.0, G)) == Flag.BAD_ARG
    lib.att_kf_reset(ffi.NULL)
    lib.att_kf_settings_default(ffi.NULL, 0.01)


BAD_SETTINGS = [
    ("dt", np.nan), ("dt", -0.01), ("dt", 0.0), ("dt", 1.5), ("dt", np.inf),
    ("q_noise", 0.0), ("q_noise", -1e-4), ("q_noise", np.nan), ("q_noise", np.inf), ("q_noise", 1e13),
    ("q_noise", 1e-13),
    ("r_noise", 0.0), ("r_noise", -10.0), ("r_noise", np.nan), ("r_noise", 1e13),
    ("p0", 0.0), ("p0", -1.0), ("p0", np.nan), ("p0", np.inf),
    ("gravity", 0.0), ("gravity", -G), ("gravity", np.nan), ("gravity", np.inf),
    ("accel_reject", -0.1), ("accel_reject", np.nan), ("accel_reject", np.inf),
    ("accel_range", np.inf), ("accel_range", 2e4), ("gyro_range", np.inf), ("gyro_range", 2e3),
    ("gravity", 0.5), ("dt", 1e-7),
    ("accel_range", 0.0), ("accel_range", np.nan), ("accel_range", -1.0),
    ("gyro_range", 0.0), ("gyro_range", np.nan), ("gyro_range", -1.0),
    ("yaw_mode", 2), ("yaw_mode", 0x7FFFFFFF),
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
    assert lib.att_kf_init(f, s) == lib.ATT_ERR_SETTINGS
    assert bytes(ffi.buffer(f)) == before


GOOD_SETTINGS = [
    ("dt", 1.0), ("dt", 1e-6), ("q_noise", 1e-12), ("q_noise", 1e12), ("r_noise", 1e-12), ("r_noise", 1e12),
    ("p0", 1e-12), ("p0", 1e12), ("accel_reject", 0.0), ("accel_range", 1e4), ("gyro_range", 1e3),
    ("yaw_mode", 1), ("q_init", (0.0, 0.0, 0.0, 2.0)),
]  # fmt: skip


@pytest.mark.parametrize("name,value", GOOD_SETTINGS, ids=[f"{n}={v}" for n, v in GOOD_SETTINGS])
def test_settings_accepted(name: str, value: Any) -> None:
    f = ffi.new("att_kf_t *")
    assert lib.att_kf_init(f, c_settings(**{name: value})) == lib.ATT_OK


def test_reference_run_matches_step() -> None:
    gyr, acc, _ = motion(1, 200, seed=9)
    a = Kf()
    quats, flags = a.run(gyr[:, 0], acc[:, 0])
    b = Kf()
    for t in range(200):
        b.step(gyr[t, 0], acc[t, 0])
    assert_same_bits(quats[-1], b.quat[0], "run vs step")
    assert quats.shape == (200, 4) and flags.shape == (200,)
    assert b.cov_diag.shape == (1, 4) and b.covariance.shape == (1, 4, 4)
    b.reset()
    assert (b.steps == 0).all()
    np.testing.assert_array_equal(b.covariance[0], np.eye(4, dtype=np.float32))


def test_noise_rates_scaled_and_validated() -> None:
    """noise_rates: Q = q_noise dt and R = r_noise / dt per step, each within 1e-12 .. 1e12."""
    f = ffi.new("att_kf_t *")
    assert lib.att_kf_init(f, c_settings(0.01, noise_rates=True, q_noise=1e-3, r_noise=0.1)) == lib.ATT_OK
    assert f.q_step == np.float32(np.float32(1e-3) * np.float32(0.01))
    assert f.r_step == np.float32(np.float32(0.1) / np.float32(0.01))
    assert lib.att_kf_init(f, c_settings(0.01, noise_rates=False, q_noise=1e-3)) == lib.ATT_OK
    assert f.q_step == np.float32(1e-3)
    for bad in ({"q_noise": 1e-11}, {"r_noise": 1e11}):
        assert lib.att_kf_init(f, c_settings(0.01, noise_rates=True, **bad)) == lib.ATT_ERR_SETTINGS
        assert lib.att_kf_init(f, c_settings(0.01, noise_rates=False, **bad)) == lib.ATT_OK
