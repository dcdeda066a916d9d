"""Helpers of the Euler EKF tests (test_ekf.py, test_ekf_behaviour.py): C and reference in lockstep,
the float64 motion generator, covariance and angle checks, adversarial settings and inputs."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from attica import native
from attica.native import ffi, lib
from attica.reference import detmath as dm
from attica.reference._common import c_state_values, state_values
from attica.reference.ekf import Ekf, EkfSettings
from attica.reference.filter import Filter as RefFilter
from attica.settings import FilterKind, Preset, preset_settings

from helpers import adversarial_floats, assert_same_bits, same_bits

G = 9.80665
VEC_FIELDS = ("euler_init", "bias_init")
BOOL_FIELDS = ("init_from_accel", "noise_rates")
DIAG = (0, 6, 11, 15, 18, 20)
"""Packed indices of the variances of phi, theta, psi, b_x, b_y, b_z."""

IX6 = np.array(
    [
        [0, 1, 2, 3, 4, 5],
        [1, 6, 7, 8, 9, 10],
        [2, 7, 11, 12, 13, 14],
        [3, 8, 12, 15, 16, 17],
        [4, 9, 13, 16, 18, 19],
        [5, 10, 14, 17, 19, 20],
    ]
)
"""att_ekf_ix: packed index of element (i, j) of the symmetric 6x6 P."""


def ekf_seed(**kw: Any) -> EkfSettings:
    """The seed preset (the notes' per-step noises, no low-pass, bias states frozen at 0) with changes."""
    return dataclasses.replace(preset_settings(FilterKind.EKF, Preset.SEED), **kw)


def ekf_default(**kw: Any) -> EkfSettings:
    """The default settings (rates, 1.5 s low-pass, bias states) with changes."""
    return dataclasses.replace(EkfSettings(), **kw)


def c_settings(s: EkfSettings, i: int = 0) -> Any:
    """att_ekf_settings_t from a settings object; per-instance (array) fields take element i."""
    cs = ffi.new("att_ekf_settings_t *")
    for f in dataclasses.fields(EkfSettings):
        v = np.asarray(getattr(s, f.name))
        if f.name in VEC_FIELDS:
            e = v.astype(np.float32)
            e = e[i] if e.ndim == 2 else e
            setattr(cs, f.name, tuple(float(x) for x in e))
            continue
        if v.ndim > 0:
            v = v[i]
        if f.name in BOOL_FIELDS:
            setattr(cs, f.name, bool(v))
        else:
            setattr(cs, f.name, float(np.float32(v)))
    return cs


def c_filters(s: EkfSettings, m: int) -> Any:
    fs = ffi.new("att_ekf_t[]", m)
    for i in range(m):
        assert lib.att_ekf_init(ffi.addressof(fs, i), c_settings(s, i)) == lib.ATT_OK
    return fs


def unpack(p21: np.ndarray) -> np.ndarray:
    """The packed upper triangles (..., 21) as full symmetric matrices (..., 6, 6)."""
    return p21[..., IX6]


def run_c(fs: Any, gyr: np.ndarray, acc: np.ndarray) -> dict[str, np.ndarray]:
    """Step C instances in lockstep over gyr, acc (steps, m, 3); outputs per step and instance."""
    steps, m, _ = gyr.shape
    g = np.ascontiguousarray(gyr, np.float32)
    a = np.ascontiguousarray(acc, np.float32)
    out = {
        "euler": np.empty((steps, m, 3), np.float32),
        "bias": np.empty((steps, m, 3), np.float32),
        "P": np.empty((steps, m, 21), np.float32),
        "flags": np.empty((steps, m), np.uint32),
    }
    fb = ffi.from_buffer
    ran = lib.att_host_ekf_run(
        fs,
        m,
        fb("float[]", g),
        fb("float[]", a),
        steps,
        fb("float[]", out["euler"]),
        fb("float[]", out["bias"]),
        fb("float[]", out["P"]),
        fb("uint32_t[]", out["flags"]),
    )
    assert ran == steps * m
    e = out["euler"]
    out["q"] = np.stack(dm.quat_from_euler(e[..., 0], e[..., 1], e[..., 2]), -1).astype(np.float32)
    return out


def run_ref(ref: Ekf, gyr: np.ndarray, acc: np.ndarray) -> dict[str, np.ndarray]:
    steps, m, _ = gyr.shape
    out = {
        "euler": np.empty((steps, m, 3), np.float32),
        "bias": np.empty((steps, m, 3), np.float32),
        "q": np.empty((steps, m, 4), np.float32),
        "P": np.empty((steps, m, 21), np.float32),
        "flags": np.empty((steps, m), np.uint32),
    }
    for k in range(steps):
        out["flags"][k] = ref.step(gyr[k], acc[k])
        out["euler"][k] = np.stack(ref.euler, -1)
        out["bias"][k] = ref.gyro_bias
        out["q"][k] = ref.quat
        out["P"][k] = ref.covariance
    return out


class BitMismatch(Exception):  # noqa: N818 (a mismatch, not an error of the test)
    """C and reference differ. Not an AssertionError, so that an xfail(raises=AssertionError) test (a
    defect reproducer) cannot pass off a mismatch as the expected failure."""


def compare(c: dict[str, np.ndarray], r: dict[str, np.ndarray], what: str) -> None:
    """Every output of every step bit-identical (BitMismatch otherwise)."""
    try:
        for key in ("euler", "bias", "q", "P"):
            assert_same_bits(c[key], r[key], f"{what}/{key}")
    except AssertionError as e:
        raise BitMismatch(str(e)) from None
    bad = c["flags"] != r["flags"]
    if bad.any():
        raise BitMismatch(f"{what}/flags: first differ at {np.argwhere(bad)[0]}")


def assert_state_matches(fs: Any, ref: Ekf, what: str) -> None:
    """Every C state field (angles, bias, P, both low-pass stages, steps, flags) equals the reference's."""
    for i in range(ref.n):
        ours = state_values(ref, Ekf.STATE, i)
        theirs = c_state_values(Ekf.STATE, fs[i])
        assert len(ours) == len(theirs)
        for k, (a, b) in enumerate(zip(ours, theirs, strict=True)):
            same = same_bits(a, b).all() if isinstance(a, np.floating) else int(a) == int(b)
            if not same:
                raise BitMismatch(f"{what}: instance {i} state value {k}: reference {a!r}, C {b!r}")


def euler_matrix(euler: np.ndarray) -> np.ndarray:
    """R (..., 3, 3), sensor-to-earth, of ZYX Euler angles (float64)."""
    e = euler.astype(np.float64)
    cr, sr = np.cos(e[..., 0]), np.sin(e[..., 0])
    cp, sp = np.cos(e[..., 1]), np.sin(e[..., 1])
    cy, sy = np.cos(e[..., 2]), np.sin(e[..., 2])
    return np.stack(
        [
            np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
            np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
            np.stack([-sp, cp * sr, cp * cr], -1),
        ],
        -2,
    )


def tilt_of(euler: np.ndarray) -> np.ndarray:
    """Gravity direction in the sensor frame (..., 3) of ZYX Euler angles (float64)."""
    e = euler.astype(np.float64)
    ph, th = e[..., 0], e[..., 1]
    return np.stack([-np.sin(th), np.sin(ph) * np.cos(th), np.cos(ph) * np.cos(th)], axis=-1)


def tilt_err_deg(euler: np.ndarray, euler_true: np.ndarray) -> np.ndarray:
    """Angle between estimated and true gravity direction (inclination error), deg."""
    d = np.sum(tilt_of(euler) * tilt_of(euler_true), axis=-1)
    return np.degrees(np.arccos(np.clip(d, -1.0, 1.0)))


def angle_to_deg(euler: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Angle between the gravity direction of the angles and a sensor-frame vector up, deg."""
    u = up / np.linalg.norm(up, axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip(np.sum(tilt_of(euler) * u, axis=-1), -1.0, 1.0)))


def quat_angle_deg(q: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    d = np.abs(np.sum(q.astype(np.float64) * q_true, axis=-1))
    return np.degrees(2 * np.arccos(np.clip(d, -1.0, 1.0)))


def quat_from_euler64(e: np.ndarray) -> np.ndarray:
    h = 0.5 * e.astype(np.float64)
    cr, sr = np.cos(h[..., 0]), np.sin(h[..., 0])
    cp, sp = np.cos(h[..., 1]), np.sin(h[..., 1])
    cy, sy = np.cos(h[..., 2]), np.sin(h[..., 2])
    return np.stack(
        [
            cy * cp * cr + sy * sp * sr,
            cy * cp * sr - sy * sp * cr,
            cy * sp * cr + sy * cp * sr,
            sy * cp * cr - cy * sp * sr,
        ],
        axis=-1,
    )


def motion(
    m: int,
    steps: int,
    dt: Any,
    seed: int,
    amp: tuple[float, float, float] = (0.6, 0.5, 1.0),
    pitch_rate: Any = 0.0,
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0),
    acc_noise: float = 0.05,
    gyro_noise: float = 0.002,
    gyro_bias: Any = (0.0, 0.0, 0.0),
    lin_acc: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Smooth random motion given as ZYX Euler angles of time (float64, exact kinematics).

    Returns gyro (steps, m, 3) sampled at the interval midpoints (plus gyro_bias, rad/s, sensor frame,
    (3,) or (m, 3)), accel (steps, m, 3) at the end of each interval (R^T ([0, 0, g] + lin_acc) plus
    noise; lin_acc (steps, m, 3) or (steps, 1, 3), m/s^2, earth frame) and the true Euler angles
    (steps, m, 3) there.
    """
    rng = np.random.default_rng(seed)
    dt = np.broadcast_to(np.asarray(dt, np.float64), (m,))
    k = np.arange(steps, dtype=np.float64)[:, None]
    t_mid = (k + 0.5) * dt
    t_end = (k + 1.0) * dt
    ang = [np.zeros((2, steps, m)) for _ in range(3)]  # value at t_end, rate at t_mid
    for axis in range(3):
        for _ in range(3):
            a = rng.uniform(0, amp[axis] / 3, m)
            w = 2 * np.pi * rng.uniform(0.03, 0.6, m)
            p = rng.uniform(0, 2 * np.pi, m)
            ang[axis][0] += a * np.sin(w * t_end + p)
            ang[axis][1] += a * w * np.cos(w * t_mid + p)
    pr = np.broadcast_to(np.asarray(pitch_rate, np.float64), (m,))
    ang[1][0] += pr * t_end
    ang[1][1] += pr
    ang[2][0] += rng.uniform(-3, 3, m)
    for axis in range(3):
        ang[axis][0] += offset[axis]
    # Euler rates to body rates at the midpoints
    h = 0.5 * dt
    ph_m = [np.zeros((steps, m)) for _ in range(3)]
    for axis in range(3):
        ph_m[axis] = ang[axis][0] - ang[axis][1] * h  # first-order value at the midpoint is enough
    ph, th = ph_m[0], ph_m[1]
    dph, dth, dps = ang[0][1], ang[1][1], ang[2][1]
    p = dph - np.sin(th) * dps
    q = np.cos(ph) * dth + np.sin(ph) * np.cos(th) * dps
    r = -np.sin(ph) * dth + np.cos(ph) * np.cos(th) * dps
    gyr = np.stack([p, q, r], axis=-1) + rng.normal(0, gyro_noise, (steps, m, 3))
    gyr = gyr + np.asarray(gyro_bias, np.float64)
    e_true = np.stack([ang[0][0], ang[1][0], ang[2][0]], axis=-1)
    acc = G * tilt_of(e_true)
    if lin_acc is not None:
        acc = acc + np.einsum("...ji,...j->...i", euler_matrix(e_true), np.broadcast_to(lin_acc, acc.shape))
    acc = acc + rng.normal(0, acc_noise, (steps, m, 3))
    return gyr.astype(np.float32), acc.astype(np.float32), e_true


def check_cov(cov: np.ndarray, what: str) -> tuple[float, float]:
    """Every P (..., 21 packed) finite and positive definite as a full 6x6 matrix (float64 eigenvalues).

    Positive definiteness is tested on the correlation matrix D^-1/2 P D^-1/2 (D = diag P, variances
    > 0), which is positive definite exactly when P is: its eigenvalues lie in (0, 6] and float64 gets
    them to ~1e-15, while those of P itself carry an error of ~1e-16 times its largest variance (P
    spans 1e-12 (bias) to 1e4 (yaw) at once, so a positive definite P can show a -1e-14 eigenvalue).
    Returns the smallest eigenvalue and the smallest eigenvalue relative to the largest variance of its
    matrix. P is stored as its upper triangle, so it is symmetric by construction.
    """
    flat = cov.reshape(-1, 21)
    assert np.isfinite(flat).all(), f"{what}: P not finite"
    assert (flat[:, list(DIAG)] > 0).all(), f"{what}: a variance not > 0"
    lo = np.inf
    rel = np.inf
    for start in range(0, flat.shape[0], 100_000):
        p = unpack(flat[start : start + 100_000]).astype(np.float64)
        eig = np.linalg.eigvalsh(p)
        d = 1.0 / np.sqrt(p[:, range(6), range(6)])
        corr = np.linalg.eigvalsh(p * d[:, :, None] * d[:, None, :])
        bad = corr[:, 0] <= 0
        assert not bad.any(), (
            f"{what}: {int(bad.sum())} matrices not positive definite; first {start + int(np.argmax(bad))}, "
            f"smallest eigenvalue of the correlation matrix {corr[:, 0].min()}"
        )
        lo = min(lo, float(eig[:, 0].min()))
        rel = min(rel, float((eig[:, 0] / p[:, range(6), range(6)].max(axis=1)).min()))
    return lo, rel


def check_canonical(euler: np.ndarray, q: np.ndarray, what: str) -> None:
    pi = np.float32(np.pi)
    assert np.isfinite(euler).all() and np.isfinite(q).all(), what
    assert (np.abs(euler[..., 1]) <= np.float32(np.pi / 2)).all(), f"{what}: theta"
    for i in (0, 2):
        assert ((euler[..., i] > -pi) & (euler[..., i] <= pi)).all(), f"{what}: angle {i}"
    assert np.abs(np.linalg.norm(q.astype(np.float64), axis=-1) - 1).max() < 1e-6


# --- single instances, C and reference side by side ---------------------------------------------


def pair(s: EkfSettings | None = None) -> tuple[Any, Ekf]:
    s = s or ekf_seed(init_from_accel=False, euler_init=(0.1, -0.2, 0.3))
    return c_filters(s, 1), Ekf(s)


def step_both(f: Any, ref: Ekf, g: Any, a: Any) -> int:
    """One step of a C instance and its reference twin; the whole state must stay bit-identical."""
    fl = int(
        lib.att_ekf_step(f, tuple(float(x) for x in np.float32(g)), tuple(float(x) for x in np.float32(a)))
    )
    rf = int(ref.step(np.asarray(g, np.float32), np.asarray(a, np.float32))[0])
    if fl != rf:
        raise BitMismatch(f"flags: C {fl:#x}, reference {rf:#x}")
    assert_state_matches(f, ref, "step")
    return fl


def state(f: Any) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    """(angles, bias, packed P) of C instance 0."""
    st = f[0].st
    return (st.euler.x, st.euler.y, st.euler.z), (st.bias.x, st.bias.y, st.bias.z), tuple(st.p)


def p_of(f: Any) -> np.ndarray:
    return np.array(list(f[0].st.p), np.float32)


def core_bytes(f: Any) -> bytes:
    """The bytes of instance 0's angles, bias, P and low-pass stages (the state but steps and flags)."""
    return bytes(ffi.buffer(ffi.addressof(f[0], "st"), ffi.offsetof("att_ekf_state_t", "steps")))


def min_eig(cov: np.ndarray) -> np.ndarray:
    """The smallest eigenvalue (float64) of every packed P (..., 21) as a full 6x6 matrix."""
    flat = cov.reshape(-1, 21)
    out = np.empty(flat.shape[0])
    for start in range(0, flat.shape[0], 100_000):
        out[start : start + 100_000] = np.linalg.eigvalsh(
            unpack(flat[start : start + 100_000]).astype(np.float64)
        )[:, 0]
    return out.reshape(cov.shape[:-1])


# --- adversarial settings and inputs ---------------------------------------------------------------

ADVERSARIAL_VARIANTS: list[dict[str, Any]] = [
    {},
    {"dt": 1.0, "cos_min": 0.5},
    {"gyro_range": 1e3, "accel_range": 1e4, "accel_reject": 0.0},
    {"p0": 1.0, "p_max": 2.0, "cos_min": 1e-6},
    {
        "q_phi": 1e-20,
        "q_theta": 1e-20,
        "q_psi": 1e-20,
        "q_bias": 1e-20,
        "r_phi": 1e-6,
        "r_theta": 1e-6,
        "dt": 0.1,
    },
    {"r_phi": 1e6, "r_theta": 1e6, "q_psi": 1e6, "q_phi": 1.0, "p_max": 1e6, "p0": 1e6, "p0_bias": 1e6},
    {"init_from_accel": False, "euler_init": (8000.0, 1.5707964, -3.1415927)},
    {"init_from_accel": False, "euler_init": (-3.1415927, -1.5707964, 3.1415927), "cos_min": 0.9},
    {"noise_rates": True, "q_phi": 0.03, "q_theta": 0.03, "q_psi": 1.0, "r_phi": 3.0, "r_theta": 3.0},
    # the default preset and its robust options at their limits
    {"noise_rates": True, "q_phi": 1e-3, "q_theta": 1e-3, "q_psi": 1e-3, "q_bias": 1e-8, "p0_bias": 1e-4,
     "r_phi": 1e-4, "r_theta": 1e-4, "tau_acc_lp": 1.5, "accel_reject": 0.0},
    {"noise_rates": True, "q_bias": 1e-4, "p0_bias": 1.0, "tau_acc_lp": 0.3, "r_accel": 1e6, "gate": 1e-3},
    {"gate": 1e6, "r_accel": 1e3, "accel_reject": 1e3, "tau_acc_lp": 1e4},
    {"gate": 9.0, "tau_acc_lp": 0.05, "bias_init": (34.906586, -34.906586, 0.0), "p0_bias": 1e-20},
    {"dt": 1e-6, "q_phi": 1.0, "q_theta": 1.0, "q_psi": 1.0, "q_bias": 1.0, "r_phi": 1e-12, "r_theta": 1e-12},
    {"gravity": 1.0, "accel_range": 1.0001, "gyro_range": 1e-3, "p_max": 1e-6, "p0": 1e-6, "p0_bias": 1e-20},
    {"gravity": 100.0, "accel_range": 1e4, "cos_min": 0.999999, "init_from_accel": False,
     "euler_init": (0.0, -1.5707964, 8192.0)},
    # the recovery after a clipping gyro (off in the seed preset): the default's and a short one with the
    # gate on and a small range, so that the adversarial samples clip often
    {"recovery_time": 2.0},
    {"recovery_time": 0.05, "gate": 9.0, "tau_acc_lp": 0.5, "gyro_range": 5.0, "noise_rates": True,
     "q_phi": 1e-3, "q_theta": 1e-3, "q_psi": 1e-3, "r_phi": 1e-4, "r_theta": 1e-4},
]  # fmt: skip
"""Settings on top of the seed preset: every range limit of the contract reached somewhere."""


def adversarial_settings(m: int) -> EkfSettings:
    base = dataclasses.asdict(ekf_seed())
    cols: dict[str, list[Any]] = {k: [] for k in base}
    for i in range(m):
        v = {**base, **ADVERSARIAL_VARIANTS[i % len(ADVERSARIAL_VARIANTS)]}
        for k in base:
            cols[k].append(v[k])
    return EkfSettings(**{k: np.asarray(v) for k, v in cols.items()})  # type: ignore[arg-type]


def adversarial_inputs(m: int, steps: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    # pitch driven through +-90 deg (and around) with large rates for every second instance
    pitch_rate = np.where(np.arange(m) % 2 == 0, rng.uniform(-3, 3, m), 0.0)
    gyr, acc, _ = motion(m, steps, 0.01, seed, amp=(2.0, 2.0, 3.0), pitch_rate=pitch_rate, acc_noise=1.0)
    gyr = gyr.copy()
    acc = acc.copy()
    shape = (steps, m)
    for arr in (gyr, acc):
        mask = rng.random(arr.shape) < 0.03
        arr[mask] = adversarial_floats(int(mask.sum()), seed + 1)
    sel = rng.random(shape)
    rng_g = np.float32(34.906586)
    gyr[sel < 0.01] = rng_g  # saturated at the range exactly: accepted
    gyr[(sel >= 0.01) & (sel < 0.02)] = np.nextafter(rng_g, np.float32(99))  # just beyond
    gyr[(sel >= 0.02) & (sel < 0.03)] = np.float32(1e30)
    gyr[(sel >= 0.03) & (sel < 0.04), 1] = np.float32(-30.0)  # fast pitch
    gyr[(sel >= 0.04) & (sel < 0.05)] = np.float32(1e3)  # the largest range of the contract
    sel = rng.random(shape)
    acc[sel < 0.01] = 0.0
    acc[(sel >= 0.01) & (sel < 0.02)] = np.float32(np.nan)
    acc[(sel >= 0.02) & (sel < 0.03)] = [np.inf, 0.0, 0.0]
    acc[(sel >= 0.03) & (sel < 0.04)] = [200.0, 0.0, 0.0]  # saturated
    acc[(sel >= 0.04) & (sel < 0.05)] = [-G, 0.0, 0.0]  # pitch exactly +90 deg
    acc[(sel >= 0.05) & (sel < 0.06)] = [G, 0.0, 0.0]  # pitch exactly -90 deg
    acc[(sel >= 0.06) & (sel < 0.07)] = [0.0, 0.0, -G]  # upside down
    acc[(sel >= 0.07) & (sel < 0.08)] = [1e-30, 0.0, 0.0]  # tiny
    acc[(sel >= 0.08) & (sel < 0.09)] = [0.0, 0.0, 1.5 * G]  # rejected norm
    acc[(sel >= 0.09) & (sel < 0.10)] = [1e4, 0.0, 0.0]  # the largest range of the contract
    return gyr, acc


def replay_positive_definite(s: EkfSettings, gyr: np.ndarray, acc: np.ndarray) -> dict[str, np.ndarray]:
    """Replay a fuzz finding's steps one by one through the C filter and the reference.

    After every step the Euler angles and the whole state must match bit for bit and the C filter's P
    must be positive definite (its least eigenvalue, in float64, above 0).

    Parameters
    ----------
    s : EkfSettings
        The finding's settings.
    gyr, acc : np.ndarray
        (n, 3) float32 samples, rad/s and m/s^2, sensor frame; no magnetometer.

    Returns
    -------
    dict[str, np.ndarray]
        The C filter's outputs of the last step.
    """
    c = native.Filter(FilterKind.EKF, s)
    ref = RefFilter(FilterKind.EKF, s)
    out: dict[str, np.ndarray] = {}
    for i in range(len(gyr)):
        out = c.run(gyr[i : i + 1], acc[i : i + 1], check_units=False)
        r = ref.step(gyr[i], acc[i], None)
        assert_same_bits(out["euler"], r["euler"], f"step {i + 1}")
        assert ref.state_matches(0, c.state.copy()[0]), ref.state_diff(0, c.state.copy()[0])
        p = np.asarray(c.state.u.ekf.st.p[0:21], np.float64)
        least = float(np.linalg.eigvalsh(p[IX6]).min())
        assert least > 0.0, f"step {i + 1}: P not positive definite (least eigenvalue {least:.3g})"
    return out
