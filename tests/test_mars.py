"""9-axis complementary filter (MARS): bit-exactness, convergence, heading, mag modes, bad input, settings."""

from __future__ import annotations

import time
from dataclasses import fields, replace
from typing import Any

import numpy as np
import pytest

from attica import native
from attica.crosscheck import records_equal
from attica.native import ffi, lib
from attica.outputs import OUTPUT_DTYPE
from attica.reference.filter import Filter as RefFilter
from attica.reference.mars import MagMode, Mars, MarsSettings
from attica.settings import SEED_OVERRIDES, BiasMode, FilterKind, Flag, Integration, Preset, preset_settings

from helpers import assert_same_bits

DT = 0.01
G = 9.80665
DIP = 1.1
M_EARTH = 49.0 * np.array([0.0, np.cos(DIP), -np.sin(DIP)])  # uT, ENU, magnetic north = +y
GOOD_G = (0.01, -0.02, 0.03)
GOOD_A = (0.0, 0.0, G)
GOOD_M = tuple(M_EARTH)
NAN = float("nan")
INF = float("inf")

# --- float64 truth helpers ---------------------------------------------------------------------


def qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ],
        axis=-1,
    )


def qconj(q: np.ndarray) -> np.ndarray:
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def qrot(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    v4 = np.concatenate([np.zeros(v.shape[:-1] + (1,)), v], axis=-1)
    return qmul(qmul(q, v4), qconj(q))[..., 1:]


def qexp(rv: np.ndarray) -> np.ndarray:
    ang = np.linalg.norm(rv, axis=-1, keepdims=True)
    k = np.where(ang > 0, np.sin(ang / 2) / np.where(ang > 0, ang, 1.0), 0.5)
    return np.concatenate([np.cos(ang / 2), rv * k], axis=-1)


def q_euler(phi: Any, theta: Any, psi: Any) -> np.ndarray:
    phi, theta, psi = np.broadcast_arrays(
        np.asarray(phi, float), np.asarray(theta, float), np.asarray(psi, float)
    )
    z = np.zeros_like(phi)
    qx = np.stack([np.cos(phi / 2), np.sin(phi / 2), z, z], -1)
    qy = np.stack([np.cos(theta / 2), z, np.sin(theta / 2), z], -1)
    qz = np.stack([np.cos(psi / 2), z, z, np.sin(psi / 2)], -1)
    return qmul(qz, qmul(qy, qx))


def euler(q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, float)
    w, x, y, z = np.moveaxis(q / np.linalg.norm(q, axis=-1, keepdims=True), -1, 0)
    phi = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    theta = np.arcsin(np.clip(2 * (w * y - z * x), -1, 1))
    psi = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.stack([phi, theta, psi], -1)


def wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


def tilt_error(q_est: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    """Angle (rad) between the estimated and true up vector seen in the sensor frame."""
    up = np.array([0.0, 0.0, 1.0])
    a = qrot(qconj(np.asarray(q_est, float)), up)
    b = qrot(qconj(q_true), up)
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    return np.arccos(np.clip((a * b).sum(-1), -1, 1))


def heading_error(q_est: np.ndarray, q_true: np.ndarray) -> np.ndarray:
    return np.abs(wrap(euler(q_est)[..., 2] - euler(q_true)[..., 2]))


def simulate(
    n: int, steps: int, seed: int, motion: float = 1.0, q0: np.ndarray | None = None, noise: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Smooth random motion: truth q (steps, n, 4); gyr, acc, mag (steps, n, 3) float64.

    Sample i is taken at attitude q[i]; gyr[i] is the mean rate over (i-1, i] (exact kinematics).
    Roll and pitch stay within about +-60 deg.
    """
    rng = np.random.default_rng(seed)
    if q0 is None:
        q0 = q_euler(rng.uniform(-0.6, 0.6, n), rng.uniform(-0.6, 0.6, n), rng.uniform(-np.pi, np.pi, n))
    # Euler angles as sums of sines; body rates from their derivatives (exact, no drift)
    t = np.arange(steps) * DT
    amp = motion * rng.uniform(0.1, 0.5, (3, 3, n)) * np.array([1.0, 1.0, 2.0])[:, None, None]
    freq = rng.uniform(0.05, 0.6, (3, 3, n))
    ph = rng.uniform(0, 2 * np.pi, (3, 3, n))
    ang = (
        amp[None] * (np.sin(2 * np.pi * freq[None] * t[:, None, None, None] + ph[None]) - np.sin(ph[None]))
    ).sum(2)
    qm = q_euler(ang[:, 0], ang[:, 1], ang[:, 2])  # (steps, n, 4)
    q = qmul(q0[None], qm)
    q = q * np.sign(q[..., :1] + 1e-300)
    # mean body rate over each interval: log of the relative rotation
    dq = qmul(qconj(q[:-1]), q[1:])
    dq = dq * np.sign(dq[..., :1] + 1e-300)
    vn = np.linalg.norm(dq[..., 1:], axis=-1, keepdims=True)
    angle = 2 * np.arctan2(vn, dq[..., :1])
    rate = np.where(vn > 0, dq[..., 1:] / np.where(vn > 0, vn, 1) * angle, 0.0) / DT
    gyr = np.concatenate([rate[:1] * 0, rate], axis=0)
    acc = qrot(qconj(q), np.array([0.0, 0.0, G]))
    mag = qrot(qconj(q), M_EARTH)
    if noise:
        gyr = gyr + rng.normal(0, 0.003, gyr.shape)
        acc = acc + rng.normal(0, 0.03, acc.shape)
        mag = mag + rng.normal(0, 0.3, mag.shape)
    return q, gyr, acc, mag


# --- C side helpers ----------------------------------------------------------------------------

FIELDS = [f.name for f in fields(MarsSettings)]
SEED = SEED_OVERRIDES[FilterKind.MARS]
"""The tests of the literal filter (the article's per-sample gains) run the seed preset."""


def mars_seed(**kw: Any) -> MarsSettings:
    """The seed preset at DT with changes."""
    return replace(preset_settings(FilterKind.MARS, Preset.SEED, dt=DT), **kw)


def c_settings(d: dict[str, Any]) -> Any:
    s = ffi.new("att_mars_settings_t *")
    lib.att_mars_settings_default(s, DT)
    for k, v in {**SEED, **d}.items():
        if k in ("bias_init", "m0_init", "q_init"):
            setattr(s, k, tuple(float(np.float32(x)) for x in v))
        elif k in ("mag_mode", "integration", "bias_mode", "bias_n_max"):
            setattr(s, k, int(v))
        elif k == "init_from_sensors":
            setattr(s, k, bool(v))
        else:
            setattr(s, k, float(np.float32(v)))
    return s


def ref_settings(dicts: list[dict[str, Any]]) -> MarsSettings:
    base = mars_seed()
    keys = sorted({k for d in dicts for k in d})
    kw: dict[str, Any] = {}
    for k in keys:
        kw[k] = np.array([d.get(k, getattr(base, k)) for d in dicts])
    return MarsSettings(**{**{f: getattr(base, f) for f in FIELDS}, **kw})


def c_run(
    d: dict[str, Any], gyr: np.ndarray, acc: np.ndarray, mag: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, Any]:
    s = c_settings(d)
    f = ffi.new("att_mars_t *")
    assert lib.att_mars_init(f, s) == lib.ATT_OK
    count = gyr.shape[0]
    g = np.ascontiguousarray(gyr, np.float32)
    a = np.ascontiguousarray(acc, np.float32)
    m = None if mag is None else np.ascontiguousarray(mag, np.float32)
    quat = np.empty((count, 4), np.float32)
    m0 = np.empty((count, 3), np.float32)
    flags = np.empty(count, np.uint32)
    fb = ffi.from_buffer
    mp = ffi.NULL if m is None else fb("float[]", m)
    got = lib.att_host_mars_run(
        f,
        fb("float[]", g),
        fb("float[]", a),
        mp,
        count,
        fb("float[]", quat),
        fb("float[]", m0),
        fb("uint32_t[]", flags),
    )
    assert got == count
    return quat, m0, flags, f


def compare(
    dicts: list[dict[str, Any]], gyr: np.ndarray, acc: np.ndarray, mag: np.ndarray
) -> tuple[int, Mars, dict[Flag, int]]:
    """Run the reference (n in lockstep) and C (each instance) over (steps, n, 3) inputs.

    Every step's whole output record (q, euler, gyro_bias, cov, flags, steps: att_filter_output) and
    the reference field m0 are compared bit for bit, and after the last step the whole filter state
    (every field of att_mars_t, through the reference's state_matches).
    """
    n = len(dicts)
    g = gyr.astype(np.float32)
    a = acc.astype(np.float32)
    m = mag.astype(np.float32)
    steps = g.shape[0]
    ref = RefFilter(FilterKind.MARS, ref_settings(dicts), n=n)
    recs = np.empty((steps, n), OUTPUT_DTYPE)
    m0_ref = np.empty((steps, n, 3), np.float32)
    for t in range(steps):
        recs[t] = ref.step(g[t], a[t], m[t])
        m0_ref[t] = np.stack([np.asarray(v, np.float32) for v in ref.impl.m0], axis=-1)
    for i in range(n):
        cf = native.Filter(FilterKind.MARS, mars_seed(**d_settings(dicts[i])))
        out = cf.run(g[:, i], a[:, i], m[:, i], check_units=False)  # adversarial inputs on purpose
        ok = records_equal(out, recs[:, i])
        if not ok.all():
            k = int(np.argmin(ok))
            raise AssertionError(f"instance {i} step {k}: C {out[k]!r} vs reference {recs[k, i]!r}")
        _, m0_c, _, _ = c_run(dicts[i], g[:, i], a[:, i], m[:, i])
        assert_same_bits(m0_c, m0_ref[:, i], f"instance {i} m0 per step")
        diff = ref.state_diff(i, cf.state[0])
        assert not diff, f"instance {i}: state differs after {steps} steps in {diff}"
    fl_ref = recs["flags"]
    counts = {fl: int(((fl_ref & fl) != 0).sum()) for fl in Flag}
    print("\nflag counts: " + ", ".join(f"{fl.name} {c}" for fl, c in counts.items() if c))
    return steps * n, ref.impl, counts


def d_settings(d: dict[str, Any]) -> dict[str, Any]:
    """A _variety dict as settings overrides of the dataclass (enums from their numbers)."""
    enums = {"mag_mode": MagMode, "integration": Integration, "bias_mode": BiasMode}
    return {k: enums[k](int(v)) if k in enums else v for k, v in d.items()}


def _variety(n: int, rng: np.random.Generator, q0: np.ndarray) -> list[dict[str, Any]]:
    dicts = []
    for i in range(n):
        d: dict[str, Any] = {
            "mag_mode": i % 2,
            "alpha_acc": rng.uniform(0.005, 0.1),
            "alpha_mag": rng.uniform(0.002, 0.05),
        }
        d["tau_mag"] = 0.0  # the per-sample gains above (a time constant and a gain together are refused)
        if i % 5 == 0:
            d["tau_acc"] = rng.uniform(0.2, 2.0)
            d["alpha_acc"] = 0.0
        if i % 7 == 0:
            d["tau_mag"] = rng.uniform(0.5, 5.0)
            d["alpha_mag"] = 0.0
        if i % 4 == 3:
            d["init_from_sensors"] = False
            err = q_euler(*rng.uniform(-0.5, 0.5, 3))
            d["q_init"] = tuple(qmul(q0[i], err))
            d["m0_init"] = tuple(M_EARTH) if i % 8 == 3 else (0.0, 0.0, 0.0)
        if i % 3 == 0:
            d["bias_init"] = tuple(rng.normal(0, 0.01, 3))
        if i % 9 == 0:
            d["mag_norm_reject"] = 0.0
            d["mag_dip_reject"] = 0.0
            d["accel_reject"] = 0.0
        if i % 2 == 1:  # the defaults' features: rotvec integration, accel low-pass, bias learning
            d["integration"] = int(Integration.ROTVEC)
            d["tau_acc_lp"] = rng.uniform(0.3, 3.0)
            d["bias_mode"] = int(
                (BiasMode.AT_REST, BiasMode.RUNNING, BiasMode.OFF, BiasMode.AT_REST)[i // 2 % 4]
            )
            d["rest_time"] = rng.uniform(0.0, 1.0)
            d["rest_gyro"] = rng.uniform(0.05, 2.0)
            d["rest_accel"] = rng.uniform(0.5, 5.0)
        dicts.append(d)
    return dicts


# --- bit-exact ---------------------------------------------------------------------------------


def test_bit_exact_normal() -> None:
    """1000 instances x 1000 steps of simulated motion (varied settings and mag availability): 1e6 steps."""
    n, steps = 1000, 1000
    rng = np.random.default_rng(7)
    q, gyr, acc, mag = simulate(n, steps, seed=1)
    dicts = _variety(n, rng, q[0])
    for i, d in enumerate(dicts):
        if "bias_init" in d:
            gyr[:, i] += np.array(d["bias_init"])
    idx = np.arange(n)
    mag[:100, idx % 6 == 1] = 0.0  # mag absent at start: late yaw alignment
    sel = idx % 6 == 2
    keep = (np.arange(steps) % 4 == 0)[:, None]
    mag[:, sel] = np.where(keep[:, :, None], mag[:, sel], np.nan)  # mag at a quarter of the rate
    mag[300:400, idx % 6 == 3] += rng.normal(0, 30.0, (100, int((idx % 6 == 3).sum()), 3))  # disturbance
    burst = rng.normal(0, 4.0, (200, int((idx % 6 == 4).sum()), 3))
    acc[500:700, idx % 6 == 4] += burst  # linear acceleration: accel rejection
    t0 = time.perf_counter()
    total, ref, counts = compare(dicts, gyr, acc, mag)
    print(f"mars normal: {total} steps bit-identical in {time.perf_counter() - t0:.1f} s")
    assert total >= 1_000_000
    for fl in (Flag.INITIALISED, Flag.MAG_ABSENT, Flag.MAG_REJECTED, Flag.ACCEL_REJECTED):
        assert counts[fl] > 0, fl
    from_sensors = sum(1 for d in dicts if d.get("init_from_sensors", True))
    assert counts[Flag.INITIALISED] > from_sensors  # late yaw alignments happened too
    assert np.all(np.isfinite(ref.quat))


ADV_VALUES = np.array(
    [
        np.nan,
        np.inf,
        -np.inf,
        0.0,
        -0.0,
        1e30,
        -1e30,
        3.4e38,
        -3.4e38,
        1e-30,
        1e-20,
        40.0,
        -40.0,
        200.0,
        1e19,
    ],
    np.float32,
)


def test_bit_exact_adversarial() -> None:
    """500 instances x 200 steps of corrupted input (NaN/Inf/zero/huge/tiny, saturation, gimbal, opposite
    vectors, missing mag, disturbances) under extreme settings: 1e5 steps, state always finite and unit."""
    n, steps = 500, 200
    rng = np.random.default_rng(11)
    q, gyr, acc, mag = simulate(n, steps, seed=2, motion=3.0)
    dicts = _variety(n, rng, q[0])
    for i, d in enumerate(dicts):
        k = i % 10
        if k == 0:
            d.update(
                accel_range=1e4,
                gyro_range=1e3,
                mag_range=1e5,
                accel_reject=0.0,
                mag_norm_reject=0.0,
                mag_dip_reject=0.0,
            )
        elif k == 1:
            d.update(
                alpha_acc=1.0,
                alpha_mag=1.0,
                tau_mag=0.0,
                accel_reject=0.0,
                mag_norm_reject=0.0,
                mag_dip_reject=0.0,
            )
        elif k == 2:
            d.update(dt=1.0)
        elif k == 3:
            d.update(init_from_sensors=False, q_init=(0.0, 0.0, 0.0, 3.0), m0_init=(0.0, 0.0, -1e-3))
        elif k == 4:
            d.update(bias_init=(34.9, -34.9, 0.0), integration=int(Integration.FIRST_ORDER), dt=1.0)
        elif k == 5:
            d.update(init_from_sensors=False, m0_init=(999.0, 0.0, 0.0), mag_mode=1)
        elif k == 6:
            d.update(alpha_acc=0.0, alpha_mag=0.0)
    g32 = gyr.astype(np.float32)
    a32 = acc.astype(np.float32)
    m32 = mag.astype(np.float32)
    for arr, p in ((g32, 0.12), (a32, 0.12), (m32, 0.12)):
        hit = rng.random(arr.shape) < p
        arr[hit] = ADV_VALUES[rng.integers(0, ADV_VALUES.size, int(hit.sum()))]
        whole = rng.random(arr.shape[:2]) < 0.03
        arr[whole] = 0.0
    special = rng.random((steps, n))
    a32[special < 0.02] = np.array([0.0, 0.0, -G], np.float32)  # upside down: exactly opposite to up
    a32[(special >= 0.02) & (special < 0.04)] = np.array([G, 0.0, 0.0], np.float32)  # gimbal lock
    m_opp = (-qrot(qconj(q), M_EARTH)).astype(np.float32)
    sel = (special >= 0.04) & (special < 0.06)
    m32[sel] = m_opp[sel]  # opposite to the reference field
    sel = (special >= 0.06) & (special < 0.1)
    m32[sel] = m32[sel] + np.array([0.0, 0.0, 40.0], np.float32)  # disturbed field
    m32[:30, ::7] = np.nan  # no mag for a while
    g32[:, ::13] = np.float32(34.9)  # right at the gyro range
    t0 = time.perf_counter()
    total, ref, counts = compare(dicts, g32, a32, m32)
    print(f"mars adversarial: {total} steps bit-identical in {time.perf_counter() - t0:.1f} s")
    assert total >= 100_000
    qq = ref.quat.astype(np.float64)
    assert np.all(np.isfinite(qq))
    assert np.all(np.abs(np.linalg.norm(qq, axis=1) - 1) < 1e-5)
    # NUMERIC cannot happen within the settings contract (bounded samples, finite ranges): never seen
    assert counts[Flag.NUMERIC] == 0
    for fl in Flag:
        if fl not in (Flag.AT_REST, Flag.BIAS_UPDATED, Flag.GIMBAL, Flag.CLAMPED, Flag.BAD_ARG, Flag.NUMERIC):
            assert counts[fl] > 0, fl


# --- behaviour ---------------------------------------------------------------------------------


def _run_c(
    settings: MarsSettings, gyr: np.ndarray, acc: np.ndarray, mag: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The C filter over (steps, n, 3) inputs; settings fields may be per instance. (The behaviour tests
    use C for speed; the reference is bit-identical by the tests above.)"""
    steps, n = gyr.shape[:2]
    quats = np.empty((steps, n, 4), np.float32)
    flags = np.empty((steps, n), np.uint32)
    vec = {"bias_init": 3, "m0_init": 3, "q_init": 4}
    for i in range(n):
        d: dict[str, Any] = {}
        for name in FIELDS:
            v = np.asarray(getattr(settings, name))
            if name in vec:
                d[name] = tuple(v[i] if v.ndim == 2 else v)
            else:
                d[name] = v[i] if v.ndim == 1 else v
        quats[:, i], _, flags[:, i], _ = c_run(d, gyr[:, i], acc[:, i], mag[:, i])
    return quats, flags


@pytest.mark.parametrize("mode", [MagMode.HORIZONTAL, MagMode.FULL])
def test_convergence_from_wrong_start(mode: MagMode) -> None:
    """Start 30/-25/60 deg off in roll/pitch/yaw (q_init), true m0_init; measure settling and accuracy."""
    n, steps = 40, 6000
    q, gyr, acc, mag = simulate(n, steps, seed=3, motion=0.7)
    err = q_euler(np.radians(30.0), np.radians(-25.0), np.radians(60.0))
    q_init = qmul(q[0], np.broadcast_to(err, (n, 4)))
    s = mars_seed(mag_mode=mode, init_from_sensors=False, q_init=q_init, m0_init=tuple(M_EARTH))
    quats, flags = _run_c(s, gyr, acc, mag)
    tilt = tilt_error(quats, q)
    head = heading_error(quats, q)
    tilt0, head0 = np.degrees(tilt[0].mean()), np.degrees(head[0].mean())
    t_tilt = np.argmax((tilt < np.radians(2.0)).all(axis=1)) * DT
    t_head = np.argmax((head < np.radians(2.0)).all(axis=1)) * DT
    late = slice(steps // 2, None)
    tmax, hmax = np.degrees(tilt[late].max()), np.degrees(head[late].max())
    trms = np.degrees(np.sqrt((tilt[late] ** 2).mean()))
    hrms = np.degrees(np.sqrt((head[late] ** 2).mean()))
    rej = (flags & Flag.MAG_REJECTED) != 0
    print(
        f"\nmars {mode.name}: start tilt {tilt0:.1f} deg heading {head0:.1f} deg; "
        f"all instances within 2 deg: tilt after {t_tilt:.2f} s, heading after {t_head:.2f} s; "
        f"last 30 s: tilt max {tmax:.3f} rms {trms:.3f} deg, heading max {hmax:.3f} rms {hrms:.3f} deg; "
        f"mag rejected {rej.mean() * 100:.1f} % of steps"
    )
    assert tilt0 > 35 and head0 > 50
    assert (tilt[late] < np.radians(2.0)).all()
    assert (head[late] < np.radians(3.0)).all()
    if mode == MagMode.HORIZONTAL:
        assert 0.0 < t_tilt < 3.0 and 0.0 < t_head < 8.0
    else:  # the dipped full-vector correction has only ~cos(dip)^2 of its gain in yaw and pulls the tilt
        assert 0.0 < t_tilt < 20.0 and 0.0 < t_head < 40.0


def test_converge_from_sensor_init_large_yaw_error() -> None:
    """Yaw 170 deg off after start (init from q_init): horizontal mode still turns to magnetic north."""
    n, steps = 20, 4000
    q, gyr, acc, mag = simulate(n, steps, seed=4, motion=0.5)
    err = q_euler(0.0, 0.0, np.radians(170.0))
    q_init = qmul(np.broadcast_to(err, (n, 4)), q[0])
    s = mars_seed(init_from_sensors=False, q_init=q_init, m0_init=tuple(M_EARTH))
    quats, _ = _run_c(s, gyr, acc, mag)
    head = heading_error(quats, q)
    t_head = np.argmax((head < np.radians(2.0)).all(axis=1)) * DT
    print(
        f"\nmars yaw 170 deg off: all within 2 deg after {t_head:.2f} s; "
        f"final max {np.degrees(head[-1].max()):.3f} deg"
    )
    assert (head[-1000:] < np.radians(3.0)).all()


def test_heading_against_enu_truth_dipped_field() -> None:
    """Init from sensors with a 63 deg dip field: heading matches the ENU truth from the first step."""
    n, steps = 50, 3000
    q, gyr, acc, mag = simulate(n, steps, seed=5, motion=0.7)
    quats, flags = _run_c(mars_seed(), gyr, acc, mag)
    assert (flags[0] & Flag.INITIALISED).all()
    head = heading_error(quats, q)
    tilt = tilt_error(quats, q)
    m0 = Mars(mars_seed(), 1)
    m0.step(gyr[0, 0], acc[0, 0], mag[0, 0])
    dip = np.degrees(np.arctan2(m0.m0[2][0], m0.m0[1][0]))
    print(
        f"\nmars heading: first step max error {np.degrees(head[0].max()):.2f} deg "
        f"(tilt {np.degrees(tilt[0].max()):.2f}); "
        f"whole run max {np.degrees(head.max()):.3f} rms {np.degrees(np.sqrt((head**2).mean())):.3f} deg; "
        f"m0 = {m0.mag_ref[0]} (dip {dip:.2f} deg, true {-np.degrees(DIP):.2f})"
    )
    assert np.degrees(head[0].max()) < 3.0
    assert np.degrees(head.max()) < 3.0
    assert abs(dip + np.degrees(DIP)) < 1.0
    assert abs(m0.m0[0][0]) == 0.0


def test_heading_late_mag() -> None:
    """No mag for the first 2 s (6-axis, yaw 0), then the first mag sample aligns yaw to magnetic north."""
    n, steps = 20, 1500
    q, gyr, acc, mag = simulate(n, steps, seed=6, motion=0.5)
    mag[:200] = 0.0
    quats, flags = _run_c(mars_seed(), gyr, acc, mag)
    assert (flags[0] & Flag.INITIALISED).all()
    assert (flags[1:200] & Flag.MAG_ABSENT).all()
    assert (flags[200] & Flag.INITIALISED).all()
    assert not (flags[201:] & Flag.INITIALISED).any()
    head = heading_error(quats, q)
    print(
        f"\nmars late mag: heading error before {np.degrees(head[199].max()):.1f} deg, right after "
        f"{np.degrees(head[200].max()):.2f} deg, last 5 s max {np.degrees(head[-500:].max()):.3f} deg"
    )
    assert np.degrees(head[200].max()) < 3.0
    assert np.degrees(head[-500:].max()) < 3.0


def test_disturbed_field_horizontal_vs_full() -> None:
    """Extra 40 uT vertical (earth frame) for 10 s, rejection off: HORIZONTAL keeps roll/pitch, FULL tilts."""
    n, steps = 10, 3000
    q, gyr, acc, mag = simulate(n, steps, seed=8, motion=0.0, noise=False)  # at rest
    dist = mag.copy()
    dist[1000:2000] += qrot(qconj(q[1000:2000]), np.array([0.0, 0.0, 40.0]))
    out = {}
    for mode in (MagMode.HORIZONTAL, MagMode.FULL):
        s = mars_seed(mag_mode=mode, mag_norm_reject=0.0, mag_dip_reject=0.0)
        quats, _ = _run_c(s, gyr, acc, dist)
        e = euler(quats)
        base = e[999]
        d_tilt = np.abs(e[1000:2000, :, :2] - base[:, :2]).max()
        d_yaw = np.abs(wrap(e[1000:2000, :, 2] - base[:, 2])).max()
        out[mode] = (d_tilt, d_yaw)
        print(
            f"\nmars {mode.name} with +40 uT vertical: max roll/pitch change {np.degrees(d_tilt):.5f} deg, "
            f"yaw change {np.degrees(d_yaw):.5f} deg"
        )
    assert out[MagMode.HORIZONTAL][0] < np.radians(1e-3)
    assert out[MagMode.HORIZONTAL][1] < np.radians(1e-3)
    assert out[MagMode.FULL][0] > np.radians(5.0)
    # with the default rejection the disturbance is flagged and changes nothing, in both modes
    for mode in (MagMode.HORIZONTAL, MagMode.FULL):
        quats, flags = _run_c(mars_seed(mag_mode=mode), gyr, acc, dist)
        assert (flags[1000:2000] & Flag.MAG_REJECTED).all()
        assert not (flags[:1000] & Flag.MAG_REJECTED).any()
        e = euler(quats)
        assert np.abs(e[1000:2000] - e[999]).max() < np.radians(1e-3)


def test_horizontal_disturbance_in_motion_keeps_tilt() -> None:
    """In motion, a constant disturbance in any direction leaves horizontal-mode roll/pitch (nearly) alone."""
    n, steps = 10, 2000
    q, gyr, acc, mag = simulate(n, steps, seed=9, motion=0.7)
    rng = np.random.default_rng(9)
    dist = mag + rng.normal(0, 25.0, (1, n, 3))
    s = mars_seed(mag_norm_reject=0.0, mag_dip_reject=0.0)
    q_d, _ = _run_c(s, gyr, acc, dist)
    q_n, _ = _run_c(s, gyr, acc, mag)
    d = np.abs(euler(q_d)[..., :2] - euler(q_n)[..., :2])
    # tilt of yaw-rotated attitudes differs only by float rounding through the nonlinear chain
    print(
        f"\nmars horizontal, constant 25 uT disturbance in motion: "
        f"roll/pitch deviation max {np.degrees(d.max()):.4f} deg"
    )
    assert d.max() < np.radians(0.05)


@pytest.mark.parametrize(
    ("mode", "acc", "mag", "axis"),
    [
        (MagMode.HORIZONTAL, (0.0, 0.0, -G), (0.0, 0.0, 0.0), 0),  # upside down: fallback x axis
        (MagMode.HORIZONTAL, GOOD_A, (0.0, -M_EARTH[1], M_EARTH[2]), 2),  # north/south: z
        (
            MagMode.FULL,
            GOOD_A,
            tuple(-M_EARTH),
            0,
        ),  # full field opposite: horizontal axis perpendicular to m0
    ],
)
def test_opposite_vectors_fallback_axes(mode: MagMode, acc: Any, mag: Any, axis: int) -> None:
    """Exactly opposite vectors (cross product zero) rotate about the documented fallback axis."""
    f, ref = _fresh(
        mag_mode=int(mode), mag_dip_reject=0.0, accel_reject=0.0, alpha_acc=0.1, alpha_mag=0.1, tau_mag=0.0
    )
    z = (0.0, 0.0, 0.0)
    for _ in range(3):
        fl = lib.att_mars_step(f, z, acc, mag)
        assert fl == int(ref.step(z, acc, mag)[0])
        assert_same_bits([f.st.q.w, f.st.q.x, f.st.q.y, f.st.q.z], ref.quat[0], "quat")
    q = np.array([f.st.q.w, f.st.q.x, f.st.q.y, f.st.q.z], float)
    vec = q[1:]
    others = [k for k in range(3) if k != axis]
    assert abs(vec[axis]) > 0.1 and np.all(np.abs(vec[others]) < 1e-6), q


# --- flags ------------------------------------------------------------------------------------


def _fresh(**kw: Any) -> tuple[Any, Mars]:
    d = {"init_from_sensors": False, "m0_init": tuple(M_EARTH), **kw}
    s = c_settings(d)
    f = ffi.new("att_mars_t *")
    assert lib.att_mars_init(f, s) == lib.ATT_OK
    return f, Mars(ref_settings([d]), 1)


@pytest.mark.parametrize(
    ("gyr", "acc", "mag", "expect"),
    [
        ((NAN, 0, 0), GOOD_A, GOOD_M, Flag.GYRO_INVALID),
        ((0, INF, 0), GOOD_A, GOOD_M, Flag.GYRO_INVALID),
        ((0, 0, 80.0), GOOD_A, GOOD_M, Flag.GYRO_RANGE),  # beyond twice gyro_range: corrupt, skipped
        (GOOD_G, (NAN, 0, G), GOOD_M, Flag.ACCEL_INVALID),
        (GOOD_G, (0, 0, 0), GOOD_M, Flag.ACCEL_INVALID),
        (GOOD_G, (0, 0, -INF), GOOD_M, Flag.ACCEL_INVALID),
        (GOOD_G, (0, 0, 200.0), GOOD_M, Flag.ACCEL_RANGE),
        (GOOD_G, (0, 0, 1e30), GOOD_M, Flag.ACCEL_RANGE),
        (GOOD_G, (0, 0, 1.2 * G), GOOD_M, Flag.ACCEL_REJECTED),
        (GOOD_G, GOOD_A, (0, 0, 0), Flag.MAG_ABSENT),
        (GOOD_G, GOOD_A, (NAN, NAN, NAN), Flag.MAG_ABSENT),
        (GOOD_G, GOOD_A, (0, NAN, 0), Flag.MAG_ABSENT),
        (GOOD_G, GOOD_A, (INF, 0, 0), Flag.MAG_INVALID),
        (GOOD_G, GOOD_A, (0, 2000.0, 0), Flag.MAG_INVALID),
        (GOOD_G, GOOD_A, (0, 0, 1e30), Flag.MAG_INVALID),
        (GOOD_G, GOOD_A, tuple(1.5 * M_EARTH), Flag.MAG_REJECTED),  # norm off by 50 %
        (GOOD_G, GOOD_A, (0, 49.0, 0), Flag.MAG_REJECTED),  # dip off by 63 deg
    ],
)
def test_bad_input_flags(gyr: Any, acc: Any, mag: Any, expect: Flag) -> None:
    f, ref = _fresh()
    # settle one good step first
    lib.att_mars_step(f, GOOD_G, GOOD_A, GOOD_M)
    ref.step(GOOD_G, GOOD_A, GOOD_M)
    q_before = (f.st.q.w, f.st.q.x, f.st.q.y, f.st.q.z)
    fl = lib.att_mars_step(f, gyr, acc, mag)
    fr = int(ref.step(gyr, acc, mag)[0])
    assert fl == fr
    assert fl & expect, f"{fl:#x} lacks {expect!r}"
    q_after = np.array([f.st.q.w, f.st.q.x, f.st.q.y, f.st.q.z], np.float32)
    assert_same_bits(q_after, ref.quat[0], "quat")
    assert np.all(np.isfinite(q_after)) and abs(np.linalg.norm(q_after.astype(float)) - 1) < 1e-6
    # the flagged part was skipped: redo the step without the bad sensor and compare
    g2, a2, m2 = gyr, acc, mag
    if expect in (Flag.GYRO_INVALID, Flag.GYRO_RANGE):
        g2 = (0.0, 0.0, 0.0)
    if expect in (Flag.ACCEL_INVALID, Flag.ACCEL_RANGE, Flag.ACCEL_REJECTED):
        a2 = (0.0, 0.0, 0.0)
    if expect in (Flag.MAG_INVALID, Flag.MAG_ABSENT, Flag.MAG_REJECTED):
        m2 = (0.0, 0.0, 0.0)
    f2, _ = _fresh()
    lib.att_mars_step(f2, GOOD_G, GOOD_A, GOOD_M)
    assert (f2.st.q.w, f2.st.q.x, f2.st.q.y, f2.st.q.z) == q_before
    lib.att_mars_step(f2, g2, a2, m2)
    if expect not in (Flag.GYRO_INVALID, Flag.GYRO_RANGE):
        assert (f2.st.q.w, f2.st.q.x, f2.st.q.y, f2.st.q.z) == (f.st.q.w, f.st.q.x, f.st.q.y, f.st.q.z)
    else:  # zero rate integrates to the same attitude as a skipped integration
        assert np.allclose(
            [f2.st.q.w, f2.st.q.x, f2.st.q.y, f2.st.q.z], [f.st.q.w, f.st.q.x, f.st.q.y, f.st.q.z], atol=1e-7
        )


def test_not_ready_init_and_bad_arg() -> None:
    s = c_settings({})
    f = ffi.new("att_mars_t *")
    assert lib.att_mars_init(f, s) == lib.ATT_OK
    ref = Mars(mars_seed(), 1)
    for gyr, acc, mag in [(GOOD_G, (NAN, 0, 0), GOOD_M), (GOOD_G, (0, 0, 0), (0, 0, 0))]:
        fl = lib.att_mars_step(f, gyr, acc, mag)
        assert fl == int(ref.step(gyr, acc, mag)[0])
        assert fl & Flag.NOT_READY and not f.st.initialised
    acc0 = (-G * np.sin(0.3) * 1.0, G * np.sin(0.2) * np.cos(0.3), G * np.cos(0.2) * np.cos(0.3))
    fl = lib.att_mars_step(f, (5.0, 5.0, 5.0), acc0, GOOD_M)
    assert fl == int(ref.step((5.0, 5.0, 5.0), acc0, GOOD_M)[0])
    assert fl == Flag.INITIALISED and f.st.initialised and f.st.m0_valid
    e = euler(np.array([f.st.q.w, f.st.q.x, f.st.q.y, f.st.q.z]))
    assert np.allclose(e[:2], [0.2, 0.3], atol=1e-5)
    assert lib.att_mars_step(ffi.NULL, GOOD_G, GOOD_A, GOOD_M) == Flag.BAD_ARG
    # reset returns to the initial state
    lib.att_mars_reset(f)
    assert (
        not f.st.initialised and not f.st.m0_valid and f.st.steps == 0 and (f.st.q.w, f.st.q.x) == (1.0, 0.0)
    )
    lib.att_mars_reset(ffi.NULL)


def test_extremes_within_the_contract_stay_finite() -> None:
    """A bias that could overflow the first-order step is refused; the largest accepted rates, bias and
    period (first-order integration, dt = 1 s) keep the state finite and unit, with no NUMERIC."""
    s = c_settings({"bias_init": (3e38, 0.0, 0.0)})
    assert lib.att_mars_settings_validate(s) == lib.ATT_ERR_SETTINGS
    d = {"bias_init": (1e3, -1e3, 1e3), "gyro_range": 1e3, "dt": 1.0, "accel_reject": 0.0}
    f, ref = _fresh(**d)
    for g in [(-1e3, 1e3, -1e3), (1e3, 1e3, 1e3), (0.0, -1e3, 0.0)] * 4:
        fl = lib.att_mars_step(f, g, GOOD_A, GOOD_M)
        assert fl == int(ref.step(g, GOOD_A, GOOD_M)[0])
        assert not fl & Flag.NUMERIC
        q = np.array([f.st.q.w, f.st.q.x, f.st.q.y, f.st.q.z])
        assert_same_bits(q.astype(np.float32), ref.quat[0], "quat")
        assert abs(np.linalg.norm(q) - 1) < 1e-6


def test_m0_from_first_mag_with_q_init() -> None:
    """init_from_sensors false and m0_init zero: m0 = q m q* of the first valid mag sample, no yaw change."""
    qi = tuple(q_euler(0.1, -0.2, 0.7))
    f, ref = _fresh(q_init=qi, m0_init=(0.0, 0.0, 0.0))
    assert not f.st.m0_valid
    z = (0.0, 0.0, 0.0)
    assert lib.att_mars_step(f, z, z, z) == int(ref.step(z, z, z)[0])
    assert not f.st.m0_valid
    m = (10.0, 20.0, -30.0)
    fl = lib.att_mars_step(f, z, z, m)
    assert fl == int(ref.step(z, z, m)[0])
    assert f.st.m0_valid and not (fl & Flag.INITIALISED)
    me = qrot(np.array(qi), np.array(m))
    assert np.allclose([f.st.m0.x, f.st.m0.y, f.st.m0.z], me, atol=1e-4)
    assert_same_bits([f.st.m0.x, f.st.m0.y, f.st.m0.z], ref.mag_ref[0], "m0")


# --- settings ----------------------------------------------------------------------------------


def test_settings_defaults_match() -> None:
    s = ffi.new("att_mars_settings_t *")
    lib.att_mars_settings_default(s, DT)
    py = MarsSettings(dt=DT)  # the defaults, not the seed
    c_fields = [name for name, _ in ffi.typeof("att_mars_settings_t").fields]
    assert c_fields == FIELDS
    for name in FIELDS:
        cv = getattr(s, name)
        pv = getattr(py, name)
        if name in ("bias_init", "m0_init"):
            cv = (cv.x, cv.y, cv.z)
        elif name == "q_init":
            cv = (cv.w, cv.x, cv.y, cv.z)
        assert np.array_equal(np.float32(cv), np.float32(pv)), name
    lib.att_mars_settings_default(ffi.NULL, DT)


def test_tau_sets_gain() -> None:
    f, ref = _fresh(tau_acc=0.5, alpha_acc=0.0, tau_mag=2.0, alpha_mag=0.0)
    assert f.c.k_acc == np.float32(np.float32(DT) / (np.float32(0.5) + np.float32(DT)))
    assert f.c.k_mag == np.float32(np.float32(DT) / (np.float32(2.0) + np.float32(DT)))
    assert f.c.k_acc == ref.k_acc[0] and f.c.k_mag == ref.k_mag[0]


BAD_SETTINGS: list[tuple[str, Any]] = [
    ("dt", 0.0),
    ("dt", -0.01),
    ("dt", 1.5),
    ("dt", NAN),
    ("dt", INF),
    ("alpha_acc", -0.1),
    ("alpha_acc", 1.1),
    ("alpha_acc", NAN),
    ("alpha_mag", -0.1),
    ("alpha_mag", 1.1),
    ("alpha_mag", INF),
    ("tau_acc", -1.0),
    ("tau_acc", INF),
    ("tau_mag", -1.0),
    ("tau_mag", NAN),
    ("mag_mode", 2),
    ("mag_mode", 0x7FFFFFFF),
    ("gravity", 0.0),
    ("gravity", NAN),
    ("accel_reject", -0.1),
    ("accel_reject", INF),
    ("accel_range", 0.0),
    ("accel_range", NAN),
    ("gyro_range", -1.0),
    ("gyro_range", NAN),
    ("mag_range", 0.0),
    ("mag_range", NAN),
    ("mag_norm_reject", -0.1),
    ("mag_norm_reject", INF),
    ("mag_dip_reject", -0.1),
    ("mag_dip_reject", NAN),
    ("mag_dip_reject", 3.2),
    ("dt", 1e-7),
    ("gravity", 0.5),
    ("gravity", 101.0),
    ("accel_range", INF),
    ("accel_range", 9.0),  # not above gravity
    ("accel_range", 2e4),
    ("gyro_range", INF),
    ("gyro_range", 1001.0),
    ("mag_range", INF),
    ("mag_range", 2e5),
    ("alpha_mag", 1.5),  # unused beside the default tau_mag = 20 s, still range-checked
    ("alpha_acc", NAN),
    ("bias_init", (35.0, 0.0, 0.0)),  # beyond gyro_range
    ("rest_gyro", 35.0),
    ("rest_accel", 10.0),
    ("rest_time", -1.0),
    ("bias_n_max", 0),
    ("bias_n_max", (1 << 24) + 1),
    ("bias_mode", 4),
    ("integration", 1),  # EULER is the ARS's option only
    ("bias_init", (NAN, 0.0, 0.0)),
    ("bias_init", (0.0, INF, 0.0)),
    ("q_init", (0.0, 0.0, 0.0, 0.0)),
    ("q_init", (NAN, 0.0, 0.0, 0.0)),
    ("q_init", (1e-30, 0.0, 0.0, 0.0)),
    ("m0_init", (INF, 0.0, 0.0)),
    ("m0_init", (1e-30, 0.0, 0.0)),
    ("m0_init", (3e38, 3e38, 0.0)),
    ("m0_init", (1001.0, 0.0, 0.0)),  # beyond mag_range
    ("q_init", (1e-4, 0.0, 0.0, 0.0)),
    ("q_init", (2000.0, 0.0, 0.0, 0.0)),
]


@pytest.mark.parametrize(("name", "value"), BAD_SETTINGS)
def test_settings_rejected(name: str, value: Any) -> None:
    s = ffi.new("att_mars_settings_t *")
    lib.att_mars_settings_default(s, DT)
    if isinstance(value, tuple):
        setattr(s, name, value)
    else:
        setattr(s, name, value)
    f = ffi.new("att_mars_t *")
    f.st.steps = 12345
    assert lib.att_mars_settings_validate(s) == lib.ATT_ERR_SETTINGS
    assert lib.att_mars_init(f, s) == lib.ATT_ERR_SETTINGS
    assert f.st.steps == 12345  # untouched


def test_settings_bool_bytes_checked() -> None:
    """A bool field whose byte is neither 0 nor 1 (possible from a memcpy or a bus) is refused."""
    s = ffi.new("att_mars_settings_t *")
    lib.att_mars_settings_default(s, DT)
    raw = ffi.cast("unsigned char *", ffi.addressof(s[0], "init_from_sensors"))
    raw[0] = 2
    assert lib.att_mars_settings_validate(s) == lib.ATT_ERR_SETTINGS
    raw[0] = 0
    assert lib.att_mars_settings_validate(s) == lib.ATT_OK


def test_settings_accepted_edges_and_null() -> None:
    s = ffi.new("att_mars_settings_t *")
    lib.att_mars_settings_default(s, DT)
    f = ffi.new("att_mars_t *")
    assert lib.att_mars_init(ffi.NULL, s) == lib.ATT_ERR_NULL
    assert lib.att_mars_init(f, ffi.NULL) == lib.ATT_ERR_NULL
    for name, value in [
        ("dt", 1.0),
        ("dt", 1e-6),
        ("alpha_acc", 0.0),
        ("tau_mag", 0.0),
        ("accel_range", 1e4),
        ("gyro_range", 1e3),
        ("mag_range", 1e5),
        ("mag_norm_reject", 0.0),
        ("mag_dip_reject", 0.0),
        ("mag_dip_reject", 3.14159),
        ("mag_mode", 1),
        ("gravity", 1.0),
        ("gravity", 100.0),
        ("m0_init", (0.0, 1e-3, 0.0)),
    ]:
        lib.att_mars_settings_default(s, DT)
        setattr(s, name, value)
        assert lib.att_mars_init(f, s) == lib.ATT_OK, name
