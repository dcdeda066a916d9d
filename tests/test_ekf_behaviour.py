"""Euler-angle EKF behaviour against float64 ground truth: convergence, tracking, gimbal lock, gyro
bias estimation, the chi-square gate and its soft limit, the low-pass measurement under linear
acceleration. Bounds are measured figures (printed) with a margin; defects of the filter found here
are pinned by minimal reproducers at the end of the file (each failed on the filter before its fix)."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest

from attica.reference.ekf import Ekf
from attica.settings import Flag

from ekf_support import (
    DIAG,
    G,
    angle_to_deg,
    c_filters,
    check_canonical,
    check_cov,
    compare,
    core_bytes,
    ekf_default,
    ekf_seed,
    min_eig,
    motion,
    p_of,
    pair,
    quat_angle_deg,
    quat_from_euler64,
    run_c,
    run_ref,
    state,
    step_both,
    tilt_err_deg,
    tilt_of,
    unpack,
)
from helpers import assert_same_bits

F32 = np.float32
NAN = float("nan")
PI2 = float(F32(np.pi / 2))


def _start_before(e_true: np.ndarray) -> np.ndarray:
    """The state before the first sample: the truth at t = 0 (the first interval extrapolated back)."""
    return (e_true[0] - (e_true[1] - e_true[0])).astype(F32)


# --- convergence and tracking --------------------------------------------------------------------

ERR0 = [
    (60, -45),
    (150, 0),
    (-100, 30),
    (0, 80),
    pytest.param(
        (179, -60),
        marks=pytest.mark.xfail(
            strict=True,
            raises=AssertionError,
            reason="defect: from a 100+ deg tilt error the first-order innovation drives theta to -89 deg at "
            "once, and the pitch variance collapses while the pitch is still 70 deg off (62 deg after 2 s)",
        ),
    ),
]


@pytest.mark.parametrize("err0", ERR0)
def test_converges_from_wrong_start(err0: tuple[float, float]) -> None:
    """Seed preset (the notes' filter, no low-pass): start off in roll/pitch by err0 (deg; pitch limited
    to 86 deg); the accel update pulls the tilt back.

    Measured (50 instances, 100 Hz, accel noise 0.2 m/s^2), max tilt error after 2 s / 5 s / over
    10..30 s, rms 10..30 s: (60, -45) 2.3 / 0.63 / 0.25, 0.083 deg; (150, 0) 6.4 / 1.6 / 0.36, 0.091;
    (-100, 30) 3.5 / 0.86 / 0.28, 0.084; (0, 80) 8.5 / 2.1 / 0.33, 0.086. (179, -60): 62 / 22 / 2.9,
    0.32 deg (45 / 14 / 1.9 before the gimbal-lock fixes; the 3-state filter before that gave 6.3 /
    1.7 / 0.54, 0.12 on the same input): the first updates, at a 100+ deg error, drive theta to -80 ..
    -89 deg within two steps, where roll is barely observable (R_phi / cos^2 theta) and the roll
    variance grows to 7e3 rad^2 while the pitch variance falls to 0.036 rad^2 with the pitch still 70
    deg off; the pitch then converges at the rate of a confident state (xfail, still open: the
    first-order innovation is not valid at such errors).
    """
    m, steps, dt = 50, 3000, 0.01
    gyr, acc, e_true = motion(m, steps, dt, seed=21, acc_noise=0.2)
    e0 = e_true[0] + np.radians([err0[0], err0[1], 0.0])
    e0[:, 1] = np.clip(e0[:, 1], -1.5, 1.5)
    s = ekf_seed(init_from_accel=False, euler_init=e0.astype(F32))  # type: ignore[arg-type]
    c = run_c(c_filters(s, m), gyr, acc)
    err = tilt_err_deg(c["euler"], e_true)
    t2, t5 = int(2 / dt), int(5 / dt)
    rms = np.sqrt(np.mean(err[1000:] ** 2))
    print(
        f"\nconvergence from {err0}: tilt error start {err[0].min():.1f} .. {err[0].max():.1f} deg, "
        f"after 2 s max {err[t2].max():.2f}, after 5 s max {err[t5].max():.2f}, "
        f"10..30 s max {err[1000:].max():.2f} rms {rms:.3f} deg"
    )
    assert err[0].min() > 50
    assert err[t2].max() < 12.0
    assert err[t5].max() < 3.5
    assert err[1000:].max() < 1.0
    assert rms < 0.2


@pytest.mark.parametrize("err0", [(60, -45), (150, 0), (-100, 30), (0, 80), (179, -60)])
def test_converges_from_wrong_start_through_the_low_pass(err0: tuple[float, float]) -> None:
    """Default preset with the bias states frozen (p0_bias = q_bias = 1e-12): the measurement is the
    gravity low-passed by two 1.5 s stages, started from the (wrong) state, so the error enters the
    innovation over seconds: slower than the seed preset at first, as accurate after 10 s.

    Measured (as test_converges_from_wrong_start), max tilt error after 2 s / 5 s / 10 s / over 20..30 s:
    (60, -45) 51 / 11 / 0.74 / 0.17 deg; (150, 0) 127 / 12 / 0.62 / 0.17; (-100, 30) 77 / 13 / 0.83 /
    0.17; (0, 80) 59 / 12 / 0.81 / 0.17; (179, -60) 116 / 29 / 1.9 / 0.17. With the bias states on (the
    full default preset) it does not converge in 30 s: see test_wrong_start_leaves_the_bias_alone.
    """
    m, steps, dt = 50, 3000, 0.01
    gyr, acc, e_true = motion(m, steps, dt, seed=21, acc_noise=0.2)
    e0 = e_true[0] + np.radians([err0[0], err0[1], 0.0])
    e0[:, 1] = np.clip(e0[:, 1], -1.5, 1.5)
    s = ekf_default(init_from_accel=False, euler_init=e0.astype(F32), p0_bias=1e-12, q_bias=1e-12)  # type: ignore[arg-type]
    c = run_c(c_filters(s, m), gyr, acc)
    err = tilt_err_deg(c["euler"], e_true)
    start = tilt_err_deg(e0[None].astype(F32), e_true[:1])[0]
    at = {t: err[int(t / dt)].max() for t in (2, 5, 10)}
    late = err[2000:].max()
    print(
        f"\nconvergence through the low-pass from {err0}: start {start.min():.1f} .. {start.max():.1f} deg, "
        f"after the first step max {err[0].max():.1f}; max after 2 s {at[2]:.2f}, 5 s {at[5]:.2f}, 10 s "
        f"{at[10]:.2f}, 20..30 s {late:.3f} deg"
    )
    assert start.min() > 50
    assert at[2] < 3.0 and at[5] < 1.0
    assert at[10] < 1.0
    assert late < 0.3


@pytest.mark.parametrize("preset", ["seed", "default"])
def test_tracks_with_correct_start_including_yaw(preset: str) -> None:
    """Started at the truth, roll/pitch stay close and yaw follows the gyro (no yaw reference).

    Measured over 60 s (50 instances, accel noise 0.2 m/s^2): seed tilt error first step 0.46 deg, then
    max 0.92 deg, full attitude max 0.92 deg; default (low-pass, bias states) first step 0.02 deg, then
    max 0.30 deg, full max 3.0 deg. The default starts its stages from the estimate's gravity when the
    first sample agrees with it within 0.1 rad (all 50 here; with 0.05 rad one instance, whose first
    sample is 3.3 deg off, took it as the measurement with p0 = 1 rad^2: 3.3 deg after the first step).
    """
    m, steps, dt = 50, 6000, 0.01
    gyr, acc, e_true = motion(m, steps, dt, seed=31, acc_noise=0.2)
    base = ekf_seed if preset == "seed" else ekf_default
    s = base(init_from_accel=False, euler_init=_start_before(e_true))  # type: ignore[arg-type]
    c = run_c(c_filters(s, m), gyr, acc)
    full = quat_angle_deg(c["q"], quat_from_euler64(e_true))
    tilt = tilt_err_deg(c["euler"], e_true)
    print(
        f"\ntracking 60 s ({preset}): tilt error first step max {tilt[0].max():.2f}, then max "
        f"{tilt[1:].max():.2f} deg, full attitude max {full[1:].max():.2f} deg"
    )
    assert tilt[0].max() < 5.0
    assert tilt[1:].max() < 2.0
    assert full[1:].max() < 4.0


# --- gimbal lock ---------------------------------------------------------------------------------


@pytest.mark.parametrize("preset", ["seed", "default"])
def test_gimbal_lock_pitch_through_90_noise_free(preset: str) -> None:
    """Pitch at 1 rad/s through +90 deg and on over the top: flags, canonical angles, attitude kept,
    C and reference identical."""
    steps, dt = 600, 0.01
    gyr, acc, e_true = motion(
        1, steps, dt, seed=41, amp=(0.0, 0.0, 0.0), pitch_rate=1.0, acc_noise=0.0, gyro_noise=0.0
    )
    base = ekf_seed if preset == "seed" else ekf_default
    s = base(init_from_accel=False, euler_init=tuple(float(x) for x in _start_before(e_true)[0]))  # type: ignore[arg-type]
    c = run_c(c_filters(s, 1), gyr, acc)
    compare(c, run_ref(Ekf(s, 1), gyr, acc), "gimbal")
    fl = c["flags"][:, 0]
    check_canonical(c["euler"], c["q"], "gimbal")
    check_cov(c["P"], "gimbal")
    full = quat_angle_deg(c["q"][:, 0], quat_from_euler64(e_true[:, 0]))
    theta = c["euler"][:, 0, 1]
    print(
        f"\ngimbal ({preset}): {np.count_nonzero(fl & Flag.GIMBAL)} GIMBAL steps; "
        f"max theta {theta.max():.6f}; "
        f"attitude error max {full.max():.3f} deg, final {full[-1]:.3f} deg"
    )
    assert np.any(fl & Flag.GIMBAL)
    assert theta.max() <= F32(np.pi / 2) and theta.max() > 1.56
    assert full.max() < 0.5


@pytest.mark.parametrize("preset", ["default", "seed"])
def test_gimbal_lock_pitch_through_90_noisy(preset: str) -> None:
    """Noisy sensors through +-90 deg pitch (40 crossings, accel noise 0.1 m/s^2): state healthy and
    tilt kept; yaw and roll may jump there (the singularity of the Euler angles).

    Measured: default tilt error max 2.41 deg, median final attitude error 0.78 deg; seed tilt max 4.2
    deg, attitude 0.16 deg. Yaw's correlations are not carried; what moves yaw with roll at the
    crossings, where they are one rotation, is the pure tilt correction (yaw follows roll by
    sin(theta) dphi). Before it: default 1.94 deg, seed 36.6 deg; with the full 6x6 P and no yaw
    term: 0.58 and 0.20 deg.
    """
    m, dt = 40, 0.01
    rate = np.where(np.arange(m) % 2 == 0, 1.0, -0.7)
    steps = int(2 * np.pi / 0.7 / dt) + 1
    gyr, acc, e_true = motion(
        m, steps, dt, seed=43, amp=(0.3, 0.0, 0.3), pitch_rate=rate, acc_noise=0.1, gyro_noise=0.003
    )
    base = ekf_seed if preset == "seed" else ekf_default
    s = base(init_from_accel=False, euler_init=_start_before(e_true))  # type: ignore[arg-type]
    c = run_c(c_filters(s, m), gyr, acc)
    compare(c, run_ref(Ekf(s, m), gyr, acc), "gimbal noisy")
    check_canonical(c["euler"], c["q"], "gimbal noisy")
    tilt = tilt_err_deg(c["euler"], e_true)
    full = quat_angle_deg(c["q"], quat_from_euler64(e_true))
    fl = c["flags"]
    print(
        f"\ngimbal noisy ({preset}): GIMBAL {np.count_nonzero(fl & Flag.GIMBAL)}, CLAMPED "
        f"{np.count_nonzero(fl & Flag.CLAMPED)}, NUMERIC {np.count_nonzero(fl & Flag.NUMERIC)} steps; "
        f"tilt error "
        f"max {tilt.max():.2f} rms {np.sqrt(np.mean(tilt**2)):.2f} deg; median final attitude error "
        f"{np.median(full[-1]):.2f} deg"
    )
    assert tilt.max() < 12.0
    assert np.median(full[-1]) < 1.5


@pytest.mark.parametrize("preset", ["default", "seed"])
def test_gimbal_lock_hold_at_90(preset: str) -> None:
    """Pitch held at exactly 90 deg while roll and yaw move (20 instances, 10 s): noise-free, GIMBAL every
    step and the tilt exact; with noise (accel 0.1 m/s^2, gyro 0.003 rad/s) the tilt is kept.

    Measured with noise: default tilt error max 0.31 deg (final max 0.27 deg), seed 0.33 deg (final
    0.045 deg); the bound leaves a factor of 5.
    """
    m, steps, dt = 20, 1000, 0.01
    base = ekf_seed if preset == "seed" else ekf_default
    for acc_noise, gyro_noise in ((0.0, 0.0), (0.1, 0.003)):
        gyr, acc, e_true = motion(
            m,
            steps,
            dt,
            seed=3,
            amp=(0.5, 0.0, 0.5),
            offset=(0.0, np.pi / 2, 0.0),
            acc_noise=acc_noise,
            gyro_noise=gyro_noise,
        )
        s = base(init_from_accel=False, euler_init=_start_before(e_true))  # type: ignore[arg-type]
        c = run_c(c_filters(s, m), gyr, acc)
        compare(c, run_ref(Ekf(s, m), gyr, acc), "hold")
        check_canonical(c["euler"], c["q"], "hold")
        tilt = tilt_err_deg(c["euler"], e_true)
        fl = c["flags"]
        print(
            f"\nhold at 90 deg ({preset}), accel noise {acc_noise}: "
            f"GIMBAL on {np.mean(fl & Flag.GIMBAL > 0):.1%} of steps, "
            f"NUMERIC {np.count_nonzero(fl & Flag.NUMERIC)}; tilt error max {tilt.max():.3g}, final "
            f"max {tilt[-1].max():.3g} deg"
        )
        if acc_noise == 0.0:
            check_cov(c["P"], "hold")
            assert np.all(fl & Flag.GIMBAL)
            assert tilt.max() < 0.01
        else:
            assert tilt.max() < 1.5


# --- gyro bias -----------------------------------------------------------------------------------


def test_constant_gyro_bias_estimated_during_motion() -> None:
    """Default preset, a constant gyro bias (sensor frame, components up to 0.03 rad/s) and motion: the
    bias states of x and y converge to it, and the tilt is more accurate than with them frozen.

    Measured (20 instances, roll/pitch/yaw amplitudes 0.6/0.5/1.0 rad, gyro noise 0.002 rad/s, accel
    noise 0.2 m/s^2): bias error of x and y, max over instances, after 10 s 2.2e-2, 60 s 6.5e-3, 180 s
    2.5e-3, 300 s 1.4e-3 rad/s; tilt error over 120..300 s max 1.2 deg, rms 0.37 deg (frozen: 7.9, 4.9).
    b_z, mostly about the vertical (unobserved like yaw), is not learnt at all: 0 of 0.02 rad/s after
    300 s, where the raw accel (no low-pass) learns half of it (see
    test_z_bias_learnt_through_the_low_pass).
    """
    m, dt = 20, 0.01
    steps = int(300 / dt)
    rng = np.random.default_rng(61)
    bias = rng.uniform(-0.03, 0.03, (m, 3))
    gyr, acc, e_true = motion(m, steps, dt, seed=62, acc_noise=0.2, gyro_bias=bias)
    c = run_c(c_filters(ekf_default(), m), gyr, acc)
    frozen = run_c(c_filters(ekf_default(p0_bias=1e-12, q_bias=1e-12), m), gyr, acc)
    err = np.abs(c["bias"] - bias.astype(F32))[..., :2]
    at = {t: err[int(t / dt) - 1].max() for t in (10, 60, 180, 300)}
    late = slice(int(120 / dt), None)
    tilt = tilt_err_deg(c["euler"], e_true)[late]
    tilt0 = tilt_err_deg(frozen["euler"], e_true)[late]
    print(
        f"\nbias: |true| up to {np.abs(bias).max():.3f} rad/s; x/y error max after "
        + ", ".join(f"{t} s {v:.2e}" for t, v in at.items())
        + f" rad/s; tilt error 120..300 s max {tilt.max():.2f} rms {np.sqrt(np.mean(tilt**2)):.3f} deg "
        f"(bias states frozen: {tilt0.max():.2f}, {np.sqrt(np.mean(tilt0**2)):.3f})"
    )
    assert at[10] > 0.01  # it starts far off
    assert at[60] < 1e-2 and at[180] < 4e-3 and at[300] < 2.5e-3
    assert err[-1].mean() < err[int(10 / dt)].mean() / 4
    assert tilt.max() < 2.0 and tilt.max() < tilt0.max() / 3


def test_z_bias_learnt_from_the_raw_accel() -> None:
    """Without the low-pass (tau_acc_lp = 0, otherwise the default preset) a bias about the sensor z
    axis (0.02 rad/s) is learnt through the tilt of that axis in motion, slowly: it lies mostly about the
    vertical, which is not observed. Measured (10 instances, 300 s): median estimate 0.0094 rad/s, none
    of the wrong sign. (The default low-pass stops this: test_z_bias_learnt_through_the_low_pass.)
    """
    dt, m = 0.01, 10
    gyr, acc, _ = motion(m, int(300 / dt), dt, seed=62, acc_noise=0.2, gyro_bias=(0.0, 0.0, 0.02))
    c = run_c(c_filters(ekf_default(tau_acc_lp=0.0), m), gyr, acc)
    bz = c["bias"][:, :, 2]
    print(
        f"\nz bias 0.02 rad/s, raw accel: median estimate after 60 s {np.median(bz[5999]):.4f}, 300 s "
        f"{np.median(bz[-1]):.4f}, smallest {bz[-1].min():.4f} rad/s"
    )
    assert np.median(bz[-1]) > 0.005 and bz[-1].min() > 0.0 and np.median(bz[-1]) > np.median(bz[5999])


# --- gate, soft limit, low-pass ------------------------------------------------------------------


def test_gate_rejects_and_flags() -> None:
    """With a gate (9.21: 99 % of a chi-square with 2 degrees of freedom), a sudden 0.5 rad tilt of the
    measured gravity is rejected: ACCEL_REJECTED, and the step equals the gyro-only prediction of a twin
    (every state byte but steps and flags); without the gate it is applied at once. A lasting change is
    accepted once the variance, growing by Q while nothing is applied, makes it plausible: with nothing
    applied and F = I at rest, P00 grows by exactly q_phi dt a step (1e-5), from its steady state 3.1e-4 to
    y^2 / gate - r = 0.0166 (y = 2 sin(0.25), r = r_phi / dt; P01 = 0): 1627 steps, predicted here from
    those figures and met to the step, then followed exactly. (An earlier docstring said 910 steps; the
    filter before the gimbal-lock fixes gives the same 1627 on this input, so that figure was stale.)

    The bias states are frozen here: with them on, the accepted step is in part taken for a gyro bias
    (-0.0127 rad/s at the end, roll 0.23 deg off after 18 s), the correlation of roll and b_x having grown
    for 9 s while nothing was applied (as the model says it should).
    """
    s = ekf_default(tau_acc_lp=0.0, gate=9.21, p0_bias=1e-12, q_bias=1e-12)
    steps = 3000
    gyr = np.zeros((steps, 1, 3), F32)
    acc = np.zeros((steps, 1, 3), F32) + F32([0, 0, G])
    acc[300:] = F32([0, G * np.sin(0.5), G * np.cos(0.5)])
    c = run_c(c_filters(s, 1), gyr, acc)
    compare(c, run_ref(Ekf(s, 1), gyr, acc), "gate")
    gated = (c["flags"][:, 0] & Flag.ACCEL_REJECTED) != 0
    n = int(np.argmin(gated[300:]))  # steps rejected before the first accepted one
    ungated = run_c(c_filters(dataclasses.replace(s, gate=0.0), 1), gyr, acc)
    roll = np.degrees(c["euler"][:, 0, 0])
    print(
        f"\ngate: rejected {int(gated.sum())} steps, the first {n} after the change (P00 then "
        f"{c['P'][299 + n, 0, 0]:.4f}); roll then {roll[299 + n]:.4f} deg, at the end {roll[-1]:.4f} deg; "
        f"without the gate after 0.1 s {np.degrees(ungated['euler'][310, 0, 0]):.2f} deg"
    )
    assert not gated[:300].any() and gated[300 : 300 + n].all() and not gated[300 + n :].any()
    q, r0 = float(c_filters(s, 1)[0].c.q_step[0]), float(c_filters(s, 1)[0].c.r_step[0])
    need = (2 * np.sin(0.25)) ** 2 / 9.21 - r0  # the predicted P00 at which d^2 <= gate
    n_pred = int(np.ceil((need - float(c["P"][299, 0, 0])) / q))
    print(f"gate: predicted from P00 growing by q dt = {q:.2e} a step: {n_pred} steps")
    assert abs(n - n_pred) <= 1
    assert roll[299 + n] == roll[299]  # nothing applied meanwhile
    assert (np.diff(c["P"][300 : 300 + n, 0, 0]) > 0).all()  # the variance grows
    assert not (ungated["flags"] & Flag.ACCEL_REJECTED).any() and np.degrees(ungated["euler"][310, 0, 0]) > 5
    assert abs(roll[-1] - np.degrees(0.5)) < 0.01
    # one gated step in detail: C and reference, and equal to the twin whose sample is NaN
    f, ref = pair(s)
    f2, ref2 = pair(s)
    for _ in range(20):
        step_both(f, ref, (0.0, 0.0, 0.0), (0.0, 0.0, G))
        step_both(f2, ref2, (0.0, 0.0, 0.0), (0.0, 0.0, G))
    fl = step_both(f, ref, (0.01, 0.0, 0.0), (0.0, G * np.sin(0.5), G * np.cos(0.5)))
    step_both(f2, ref2, (0.01, 0.0, 0.0), (NAN, NAN, NAN))
    assert fl == Flag.ACCEL_REJECTED and core_bytes(f) == core_bytes(f2)


def _chi2(p_pred: np.ndarray, r: tuple[float, float], delta: np.ndarray) -> float:
    """d^2 = y^T S^-1 y (float64) from an applied, ungated correction delta of the state: delta = K y with
    K = P H^T S^-1, so y = S P2^-1 delta[:2]."""
    p = unpack(p_pred).astype(np.float64)
    s = p[:2, :2] + np.diag(r)
    y = s @ np.linalg.solve(p[:2, :2], delta[:2])
    return float(y @ np.linalg.solve(s, y))


def _one_update(s: Any, tilt_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, Any]:
    """40 steps at rest, then one step with the gravity tilted by tilt_deg about x: (correction of the
    state, P after, P of the prediction alone, instance)."""
    f, ref = pair(s)
    twin, ref2 = pair(s)
    for _ in range(40):
        step_both(f, ref, (0.0, 0.0, 0.0), (0.0, 0.0, G))
        step_both(twin, ref2, (0.0, 0.0, 0.0), (0.0, 0.0, G))
    step_both(twin, ref2, (0.0, 0.0, 0.0), (NAN, NAN, NAN))
    e0, b0, _ = state(f)
    a = np.radians(tilt_deg)
    assert step_both(f, ref, (0.0, 0.0, 0.0), (0.0, G * np.sin(a), G * np.cos(a))) == 0
    e1, b1, _ = state(f)
    delta = np.array([*e1, *b1], np.float64) - np.array([*e0, *b0], np.float64)
    return delta, p_of(f), p_of(twin), f


@pytest.mark.parametrize("tilt_deg", [0.5, 3.5, 4.5, 5.5])
def test_gate_soft_limit_scales_the_correction(tilt_deg: float) -> None:
    """Between gate / 4 and gate the innovation covariance is inflated so that d^2 = gate / 4: the
    correction (angles and bias) and the change of P are those of the ungated update times (gate / 4) /
    d^2; below gate / 4 the gated update equals the ungated one bit for bit. d^2 is recomputed here in
    float64 from the ungated correction (gate 1, a step of the measured gravity by tilt_deg)."""
    gate = 1.0
    d_soft, p_soft, p_pred, f = _one_update(ekf_default(tau_acc_lp=0.0, gate=gate, p0=1e-4), tilt_deg)
    d_full, p_full, _, _ = _one_update(ekf_default(tau_acc_lp=0.0, gate=0.0, p0=1e-4), tilt_deg)
    d2 = _chi2(p_pred, (float(f[0].c.r_step[0]), float(f[0].c.r_step[1])), d_full)
    if tilt_deg < 1:
        print(f"\nsoft limit, {tilt_deg} deg: d^2 {d2:.4f} below gate / 4: the same update")
        assert d2 < gate / 4
        assert (d_soft == d_full).all() and (p_soft == p_full).all()
        return
    fk = (gate / 4) / d2
    ratio = d_soft[[0, 3]] / d_full[[0, 3]]  # roll and b_x
    dp = (p_pred[[0, 15]].astype(np.float64) - p_soft[[0, 15]]) / (p_pred[[0, 15]] - p_full[[0, 15]])
    print(
        f"\nsoft limit, {tilt_deg} deg: d^2 {d2:.4f}, (gate / 4) / d^2 {fk:.5f}; correction ratio roll "
        f"{ratio[0]:.5f} b_x {ratio[1]:.5f}; change of P00 {dp[0]:.5f}, of P(b_x) {dp[1]:.5f}"
    )
    assert gate / 4 < d2 < gate
    assert np.abs(ratio / fk - 1).max() < 1e-4
    assert np.abs(dp / fk - 1).max() < 1e-3


@pytest.mark.parametrize("duration", [1.0, 2.0, 4.0])
def test_low_pass_rejects_sustained_linear_acceleration(duration: float) -> None:
    """A sustained linear acceleration (2 m/s^2 along earth x, as a vehicle pulling away) tilts the raw
    measured gravity by atan(2 / g) = 11.5 deg. The default low-pass (two 1.5 s stages of the heading-frame
    accel) passes the fraction 1 - exp(-T / tau) (1 + T / tau) of a step lasting T: 14 % for 1 s, 38 % for
    2 s, 75 % for 4 s; the raw accel (tau_acc_lp = 0, other settings the defaults) passes it all.

    Measured (20 instances, slow motion, bias states frozen so that only the measurement differs), max
    tilt error over the pulse and 10 - T s after it: 1 s 2.8 deg (raw 11.1), 2 s 5.2 (11.6), 4 s 8.7
    (11.6). With the bias states on: 2.9 / 5.5 / 9.2 deg.
    """
    m, dt = 20, 0.01
    steps = int(40 / dt)
    lin = np.zeros((steps, 1, 3))
    lin[int(20 / dt) : int((20 + duration) / dt), 0, 0] = 2.0
    gyr, acc, e_true = motion(m, steps, dt, seed=71, amp=(0.2, 0.2, 0.5), acc_noise=0.05, lin_acc=lin)
    err = {}
    for tau in (1.5, 0.0):
        c = run_c(c_filters(ekf_default(tau_acc_lp=tau, p0_bias=1e-12, q_bias=1e-12), m), gyr, acc)
        err[tau] = tilt_err_deg(c["euler"], e_true)
    window = slice(int(20 / dt), int(30 / dt))
    lp, raw = err[1.5][window].max(), err[0.0][window].max()
    quiet = max(err[1.5][int(10 / dt) : int(20 / dt)].max(), err[0.0][int(10 / dt) : int(20 / dt)].max())
    apparent = np.degrees(np.arctan(2.0 / G))
    x = duration / 1.5
    passed = 1 - np.exp(-x) * (1 + x)
    print(
        f"\nlinear acceleration 2 m/s^2 for {duration} s: tilt error max low-pass {lp:.2f} deg (the low-pass "
        f"passes {passed:.0%} of {apparent:.1f} deg), raw {raw:.2f} deg; "
        f"before the pulse both below {quiet:.2f} deg"
    )
    assert raw > 0.9 * apparent
    assert lp < passed * apparent + 1.5 and lp < raw
    assert quiet < 0.3


# --- regressions: minimal reproducers of fixed defects (each failed before its fix) -------------------


def _repro_streams() -> dict[str, tuple[Any, np.ndarray, np.ndarray]]:
    """The settings and input (steps, 1, 3) of each defect reproducer."""
    out: dict[str, tuple[Any, np.ndarray, np.ndarray]] = {}
    # innovation: theta 89.9 deg, yaw rate 0.01 rad/s, a sample 1 deg off the state's gravity (roll side)
    e0 = np.array([0.0, np.radians(89.9), 0.0], F32)
    up = tilt_of(e0)
    side = np.array([0.0, 1.0, 0.0]) - up[1] * up
    a = G * (np.cos(np.radians(1.0)) * up + np.sin(np.radians(1.0)) * side / np.linalg.norm(side))
    out["innovation"] = (
        ekf_seed(init_from_accel=False, euler_init=tuple(map(float, e0))),
        np.array([[[0.0, 0.0, 0.01]]], F32),
        a.astype(F32)[None, None],
    )
    # bias: at rest, level, perfect gyro, started 60 deg off in roll (30 s)
    steps = 3000
    out["bias"] = (
        ekf_default(init_from_accel=False, euler_init=(float(np.radians(60)), 0.0, 0.0)),
        np.zeros((steps, 1, 3), F32),
        np.zeros((steps, 1, 3), F32) + F32([0, 0, G]),
    )
    # numeric: theta = 90 deg, yaw rate 0.01 rad/s, the exact sample
    out["numeric"] = (
        ekf_default(init_from_accel=False, euler_init=(0.0, PI2, 0.0)),
        np.array([[[0.0, 0.0, 0.01]]], F32),
        np.array([[[-G, 0.0, 0.0]]], F32),
    )
    # indefinite: theta 89.96 deg, a constant rate of 0.5 rad/s, the start attitude's sample (6 steps)
    e1 = np.array([0.849076509475708, 1.5700573921203613, 0.0], F32)
    out["indefinite"] = (
        ekf_default(init_from_accel=False, euler_init=tuple(map(float, e1))),
        np.ascontiguousarray(np.broadcast_to(F32([-0.41658464, 0.32627967, 0.24778196]), (6, 1, 3))),
        np.ascontiguousarray(np.broadcast_to((G * tilt_of(e1)).astype(F32), (6, 1, 3))),
    )
    # unusable gyro: one step with NaN gyro and accel
    out["gyro_unusable"] = (
        ekf_default(init_from_accel=False, euler_init=(0.1, -0.2, 0.3)),
        np.array([[[NAN, 0.0, 0.0]]], F32),
        np.array([[[NAN, 0.0, 0.0]]], F32),
    )
    return out


def _repro(name: str) -> tuple[Any, dict[str, np.ndarray]]:
    s, gyr, acc = _repro_streams()[name]
    return s, run_c(c_filters(s, 1), gyr, acc)


def test_regression_reproducers_are_the_same_in_c_and_reference() -> None:
    """The regression tests below see the C filter; on their streams the reference gives the same bits,
    so C and reference were fixed together."""
    for name, (s, gyr, acc) in _repro_streams().items():
        compare(run_c(c_filters(s, 1), gyr, acc), run_ref(Ekf(s, 1), gyr, acc), name)


def test_update_near_gimbal_lock_moves_toward_the_measurement() -> None:
    """Seed preset, theta = 89.9 deg, a yaw rate of 0.01 rad/s, an accel sample whose gravity is 1 deg
    from the state's: one step. A Kalman update moves the estimate toward the measurement; this one
    moves the gravity direction to 16.5 deg from it, because the roll innovation is divided by
    cos(theta) = 1.7e-3 and the clamped Jacobian correlates roll and pitch almost fully. Seen in the
    runs above: a held 90 deg pitch with accel noise 0.1 m/s^2 goes to a 170 deg tilt error at the first
    step (the 3-state filter before it: 20 deg over the run), 40 noisy crossings of 90 deg 34.9 deg
    (7.4), convergence from (179, -60) deg 45 deg after 2 s (6.3)."""
    s, c = _repro("innovation")
    a = _repro_streams()["innovation"][2][0, 0].astype(np.float64)
    after = float(angle_to_deg(c["euler"][0, 0], a))
    before = float(angle_to_deg(np.array(s.euler_init), a))
    print(f"\ngravity from the measured: before {before:.2f} deg, after the update {after:.2f} deg")
    assert after <= before


def test_wrong_start_leaves_the_bias_alone() -> None:
    """Default preset at rest, level, a perfect gyro (no bias), started 60 deg off in roll: the filter
    learns a gyro bias of 0.066 rad/s (3.8 deg/s) within 5 s, overshoots to -11.4 deg roll at 10 s and
    is still -3.0 deg off after 60 s (bias 0.015 rad/s). With the bias states frozen it is 0.00 deg after
    20 s; without the low-pass 0.00 deg after 1 s. The low-passed measurement lags the state while the
    filter models it as instantaneous (H = [I2 0]): the lasting innovation is taken for a bias, which the
    small bias variance then takes minutes to unlearn. A gyro saturated for two steps (60 deg unseen)
    does the same (2.7 deg off after 60 s at rest); in motion, from the starts of
    test_converges_from_wrong_start, the tilt error over 10..30 s stays up to 16 .. 70 deg."""
    _, c = _repro("bias")
    roll = np.degrees(c["euler"][:, 0, 0])
    bias = np.abs(c["bias"][:, 0]).max()
    print(
        f"\nwrong start at rest: roll after 10 s {roll[999]:.2f}, 30 s {roll[-1]:.2f} deg; "
        f"|bias| max {bias:.4f} rad/s"
    )
    assert np.abs(roll[2000:]).max() < 0.5 and bias < 0.01


def test_z_bias_learnt_through_the_low_pass() -> None:
    """Default preset, a gyro bias of 0.02 rad/s about the sensor z axis, 300 s of motion (10 instances):
    the z bias estimate stays at 0.000 (median), while its variance falls from 1e-4 to 5.6e-5 as if it
    were being learnt. With the raw accel (tau_acc_lp = 0) the same filter learns 0.0094 (median): the
    low-passed measurement lags the tilt it is compared with, so the innovations the z bias causes while
    the sensor tilts back and forth arrive out of phase."""
    dt, m = 0.01, 10
    gyr, acc, _ = motion(m, int(300 / dt), dt, seed=62, acc_noise=0.2, gyro_bias=(0.0, 0.0, 0.02))
    c = run_c(c_filters(ekf_default(), m), gyr, acc)
    est = float(np.median(c["bias"][-1, :, 2]))
    print(f"\nz bias 0.02 rad/s, median estimate after 300 s: {est:.4f} rad/s")
    assert est > 0.005


def test_update_at_gimbal_lock_keeps_the_variances_positive() -> None:
    """Default preset at theta = 90 deg, a yaw rate of 0.01 rad/s and the exact accel sample: the
    clamped Jacobian makes the predicted roll variance 1.0e4 against R = 0.01, and P - K S K^T (not the
    Joseph form) cancels to P00 = -0.06: the update of a valid sample is discarded (NUMERIC). Single
    steps from 20000 random attitudes within 10 deg of the singularity, exact samples, rates up to 5
    rad/s: 1355 fail (seed preset: 130); in the adversarial run of test_ekf.py 3.8e4 of 1.02e6 steps."""
    _, c = _repro("numeric")
    fl = int(c["flags"][0, 0])
    print(f"\nflags {Flag(fl)!r}")
    assert not fl & Flag.NUMERIC


def test_p_positive_definite_near_gimbal_lock() -> None:
    """Default preset at theta = 89.96 deg, a constant rate of 0.5 rad/s, the start attitude's accel
    sample: after 5 steps (no conditioning in between) P's smallest eigenvalue is -0.54 times its largest
    variance. The conditioning every 16 steps repairs it, but until then the gain comes from an indefinite
    P; in the adversarial run of test_ekf.py thousands of the 1.02e6 steps carry such a P."""
    _, c = _repro("indefinite")
    rel = min_eig(c["P"][:, 0]) / c["P"][:, 0, list(DIAG)].max(axis=-1)
    print(f"\nsmallest eigenvalue / largest variance per step: {np.round(rel, 4)}")
    assert (rel > 0).all()


def test_unusable_gyro_prediction_is_p_plus_q() -> None:
    """att_ekf.h: "An unusable gyro sample gives w = 0: the state is kept, P := P + Q". The code still
    applies F with its bias block B = -dt E (which does not depend on w), so the angle-bias covariances
    change by -dt E P_bb (1e-6 here) although the bias did not enter the prediction."""
    s, c = _repro("gyro_unusable")
    f = c_filters(s, 1)
    want = p_of(f)
    for k, i in zip(DIAG, (0, 1, 2, 3, 3, 3), strict=True):
        want[k] = F32(want[k] + F32(f[0].c.q_step[i]))
    changed = np.nonzero(c["P"][0, 0] != want)[0]
    print(f"\nelements of P that differ from P + Q: {changed.tolist()}")
    assert changed.size == 0


def _rxry_t(e: tuple[float, ...], v: Any) -> np.ndarray:
    """R_x(phi)^T R_y(theta)^T v (float64): a heading-frame vector in the sensor frame."""
    cp, sp, ct, st = np.cos(e[0]), np.sin(e[0]), np.cos(e[1]), np.sin(e[1])
    x, y, z = (float(c) for c in v)
    u = (ct * x - st * z, y, st * x + ct * z)  # R_y^T
    return np.array([u[0], cp * u[1] + sp * u[2], -sp * u[1] + cp * u[2]])


def test_lowpass_stages_stay_in_the_heading_frame_through_a_flip() -> None:
    """The stages live in a heading frame (the earth frame turned by the yaw lp_psi), so with zero rates
    and a constant sample, once started from it, R_x(phi)^T R_y(theta)^T R_z(lp_psi - psi) lp must stay
    the sample whatever the updates do: here they pull the pitch from 80 deg through 90 (the truth: 92
    deg pitch, 20 deg roll), and the update that crosses it flips to the equivalent attitude, yaw + pi,
    which turns the heading frame half a turn (taken by the next update's turn). Measured: one flip, the
    stage 7e-4 m/s^2 off (the first-order turn of the corrections, float32); when the flip's half turn
    was missed, the mirrored stages pulled the estimate back and forth across 90 deg (391 flips in 15 s)
    and the stage was 0.63 m/s^2 off. C and reference bit for bit at every step."""
    th, ph = np.deg2rad(92.0), np.deg2rad(20.0)
    a = (-np.sin(th) * G, np.sin(ph) * np.cos(th) * G, np.cos(ph) * np.cos(th) * G)
    a32 = np.array(a, np.float32)
    s = ekf_default(
        init_from_accel=False,
        euler_init=(float(ph), float(np.deg2rad(80.0)), 0.0),
        p0_bias=1e-12,
        q_bias=1e-12,
        p0=1e-4,
    )
    f, ref = pair(s)
    flips = 0
    worst = 0.0
    yaw = 0.0
    for _ in range(1500):
        step_both(f, ref, (0.0, 0.0, 0.0), a32)
        e, _, _ = state(f)
        flips += abs(abs(e[2] - yaw) - np.pi) < 0.1
        yaw = e[2]
        st = f[0].st
        if st.lp_ready:
            # the stages are in the heading frame of yaw lp_psi: turned into the estimate's
            d = e[2] - st.lp_psi
            lp = (
                np.cos(d) * st.lp2.x + np.sin(d) * st.lp2.y,
                np.cos(d) * st.lp2.y - np.sin(d) * st.lp2.x,
                st.lp2.z,
            )
            worst = max(worst, float(np.abs(_rxry_t(e, lp) - a32).max()))
    e, _, _ = state(f)
    print(
        f"\nstages through an update flip: {flips} flip(s), sensor-frame stage off by at most "
        f"{worst:.2g} m/s^2"
    )
    assert flips == 1
    assert worst < 1e-2
    g_est = tilt_of(np.array(e))
    assert np.rad2deg(np.arccos(min(1.0, float(g_est @ (np.array(a) / G))))) < 0.5  # the truth reached


# --- issue 26 R1: no setting and no state leaves the filter NUMERIC for good --------------------------

STUCK: dict[str, Any] = {
    # seed preset, dt 0.1 s, the bias at (2, 34.9, 0) rad/s, pitch 1.5702 rad: at rest the estimated rates
    # take the midpoint of the prediction within 1e-4 rad of gimbal lock, and with cos_min 1e-4 (with the
    # default 1e-3 the increments of dt 0.1 s stay within the wrap's range) the increments leave the wrap's
    # range (8192 rad): the angles kept, the bias restarted at bias_init, the one it had
    "a": ekf_seed(
        dt=0.1,
        bias_init=(2.0, 34.9, 0.0),
        cos_min=1e-4,
        init_from_accel=False,
        euler_init=(-1.5711, 1.5702, 0.0),
    ),
    # defaults, cos_min 1e-30, at pitch float32(pi/2) (cos -4.4e-8, unguarded) while the sensor lies level:
    # the roll innovation (the tilt error / cos(theta)) gives a correction beyond the wrap's range, the
    # update is discarded, P restarts, the angles are kept
    "b": ekf_default(
        cos_min=1e-30, bias_init=(0.0, 0.0, -8.2e-7), init_from_accel=False, euler_init=(0.0, PI2, 0.7)
    ),
    # the same through the guard: cos_min 1e-6, pitch 1.5707964, bias 0.01 rad/s
    "c": ekf_default(
        cos_min=1e-6, bias_init=(0.01, 0.01, 0.01), init_from_accel=False, euler_init=(0.0, 1.5707964, 0.0)
    ),
    # dt 1 s, the bias at (2, 34.9, 0): the attitude spins at 35 rad/s until the midpoint of a prediction
    # passes within 4e-3 rad of gimbal lock, out of the wrap's range; from then on (the state reached after
    # 39 steps from (-0.30, -1.31, -2.94), away from the gimbal) every step repeats it
    "d": ekf_default(
        dt=1.0,
        bias_init=(2.0, 34.9, 0.0),
        init_from_accel=False,
        euler_init=(-0.20119655, -0.17939326, -0.39961708),
    ),
    # dt 1 s, bias_init (0, pi, 10): from the level start the first prediction leaves the wrap's range; a
    # re-initialisation alone would fail the same way at every other step (bias_init restarted into itself)
    "e": ekf_default(dt=1.0, bias_init=(0.0, float(F32(np.pi)), 10.0)),
}
"""Settings (and start) whose state, at rest, failed every step before issue 26: the failing step kept the
state from before it, so with a constant sample the next step repeated the failure (256 of 256 steps
NUMERIC; e: 255, after the start)."""


@pytest.mark.parametrize("case", sorted(STUCK))
def test_numeric_is_left_at_rest(case: str) -> None:
    """256 clean samples at rest (zero rates, level, |a| = g): the filter leaves NUMERIC. A step flagged
    NUMERIC still keeps the attitude from before it; the next usable accel sample re-initialises roll and
    pitch from it (INITIALISED, the yaw kept, P at its start values), and a prediction out of the wrap's
    range with bias_init restarts the bias at zero. Measured: one NUMERIC step in each case, none in the
    last 250; q a finite unit quaternion at every step; C and reference bit for bit."""
    s = STUCK[case]
    n = 256
    gyr = np.zeros((n, 1, 3), F32)
    acc = np.zeros((n, 1, 3), F32) + F32([0.0, 0.0, G])
    c = run_c(c_filters(s, 1), gyr, acc)
    compare(c, run_ref(Ekf(s, 1), gyr, acc), f"stuck {case}")
    fl = c["flags"][:, 0]
    numeric = (fl & Flag.NUMERIC) != 0
    print(f"\n{case}: NUMERIC at steps {np.nonzero(numeric)[0].tolist()}, final angles {c['euler'][-1, 0]}")
    assert numeric.any()  # the state fails (it failed every step before the fix)
    assert numeric.sum() <= 2 and not numeric[8:].any()
    assert not (fl[8:] & (Flag.NOT_READY | Flag.INITIALISED)).any()
    q = c["q"][:, 0].astype(np.float64)
    assert np.isfinite(q).all() and np.abs(np.linalg.norm(q, axis=-1) - 1).max() < 1e-6
    # level, as the samples say (c: within 1.3 deg, its bias_init 0.01 rad/s being unlearnt)
    assert tilt_err_deg(c["euler"][-1], np.zeros((1, 3), F32))[0] < 2.0


def test_recovery_after_numeric() -> None:
    """The steps of a recovery (case b): the NUMERIC step keeps the attitude (NUMERIC_KEPT) and leaves the
    filter not initialised with recover set; a step without a usable accel sample waits (NOT_READY, nothing
    changes but the flags and the step count); the first usable sample re-initialises roll and pitch from
    itself, keeps the yaw, restarts P at p0, p0_bias and starts the stages from the sample (INITIALISED);
    the next step is an ordinary one. C and reference bit for bit."""
    s = STUCK["b"]
    f, ref = pair(s)
    before, bias, _ = state(f)
    fl = step_both(f, ref, (0.0, 0.0, 0.0), (0.0, 0.0, G))
    assert fl & Flag.NUMERIC and state(f)[0] == before
    assert not f[0].st.initialised and f[0].st.recover
    waiting = core_bytes(f)
    fl = step_both(f, ref, (0.0, 0.0, 0.0), (NAN, NAN, NAN))
    assert fl & Flag.NOT_READY and not fl & Flag.NUMERIC and core_bytes(f) == waiting
    fl = step_both(f, ref, (0.0, 0.0, 0.0), (0.0, 0.0, G))
    e, b, p = state(f)
    assert fl & Flag.INITIALISED and not fl & (Flag.NUMERIC | Flag.NOT_READY)
    assert e == (0.0, 0.0, before[2]) and b == bias
    start = np.zeros(21, F32)
    start[list(DIAG[:3])] = s.p0
    start[list(DIAG[3:])] = s.p0_bias
    assert_same_bits(np.asarray(p, F32), start, "P after the re-initialisation")
    st = f[0].st
    assert st.initialised and not st.recover and st.lp_ready and st.lp_psi == before[2]
    assert (st.lp1.x, st.lp1.y, st.lp1.z) == (0.0, 0.0, F32(G))
    fl = step_both(f, ref, (0.0, 0.0, 0.0), (0.0, 0.0, G))
    assert not fl & (Flag.NUMERIC | Flag.NOT_READY | Flag.INITIALISED)


def test_numeric_never_repeats_at_rest() -> None:
    """A property over 4000 random settings and starts (either preset, every dt of the fuzz target, cos_min
    down to 1e-38, gyro_range 0.01 .. 1000 with a bias_init anywhere within it, attitudes within 1e-8 rad of
    gimbal lock and anywhere), then 64 clean samples at rest in a random orientation: no two consecutive
    steps are NUMERIC. Before issue 26 each of the 591 instances that failed a step failed every step after
    it; now 591 fail some step (the adversarial corners: bias_init far beyond any rate at rest with dt up to
    1 s, cos_min down to 1e-38 at gimbal lock), never two in a row. C and reference bit for bit on 200 of
    them."""
    rng = np.random.default_rng(26)
    m, n = 4000, 64
    e0 = np.stack(
        [rng.uniform(-np.pi, np.pi, m), rng.uniform(-np.pi / 2, np.pi / 2, m), rng.uniform(-np.pi, np.pi, m)],
        -1,
    )
    near = rng.random(m) < 0.6
    e0[near, 1] = np.sign(rng.uniform(-1, 1, near.sum())) * (
        np.pi / 2 - 10 ** rng.uniform(-8, -2, near.sum())
    )
    gr = np.where(rng.random(m) < 0.5, 34.906586, 10 ** rng.uniform(-2, 3, m)).astype(F32)
    bias = (rng.uniform(-1, 1, (m, 3)) * gr[:, None] * (rng.random((m, 1)) < 0.7)).astype(F32)
    seed = rng.random(m) < 0.5
    common = {
        "dt": rng.choice([0.0035, 0.01, 0.001, 0.1, 1.0, 0.0001, 0.02, 0.5], m),
        "cos_min": np.where(rng.random(m) < 0.3, 1e-3, 10 ** rng.uniform(-38, -0.5, m)),
        "gyro_range": gr,
        "bias_init": np.clip(bias, -gr[:, None], gr[:, None]),
        "init_from_accel": False,
        "euler_init": e0.astype(F32),
    }
    a, b = ekf_seed(**common), ekf_default(**common)
    per = {
        name: np.where(seed, getattr(a, name), getattr(b, name))
        for name in ("q_phi", "q_theta", "q_psi", "q_bias", "p0_bias", "r_phi", "r_theta", "accel_reject")
    }
    per["tau_acc_lp"] = np.where(seed, 0.0, 1.5)
    per["noise_rates"] = ~seed
    s = dataclasses.replace(b, **per)
    d = rng.normal(size=(m, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[rng.random(m) < 0.5] = (0.0, 0.0, 1.0)
    gyr = np.zeros((n, m, 3), F32)
    acc = np.ascontiguousarray(np.broadcast_to((d * G).astype(F32), (n, m, 3)))
    c = run_c(c_filters(s, m), gyr, acc)
    numeric = (c["flags"] & Flag.NUMERIC) != 0
    twice = numeric[1:] & numeric[:-1]
    failed, repeated = int(numeric.any(0).sum()), int(twice.any(0).sum())
    print(f"\n{failed} of {m} instances NUMERIC at some step, {repeated} twice in a row")
    assert numeric.any(0).sum() > m // 20
    assert not twice.any()
    q = c["q"].astype(np.float64)
    assert np.isfinite(q).all() and np.abs(np.linalg.norm(q, axis=-1) - 1).max() < 1e-6
    pick = np.nonzero(numeric.any(0))[0][:200]
    sub = dataclasses.replace(
        s,
        **{
            f.name: np.asarray(getattr(s, f.name))[pick]
            for f in dataclasses.fields(s)
            if np.ndim(getattr(s, f.name)) >= 1 and np.shape(getattr(s, f.name))[0] == m
        },
    )
    compare(
        run_c(c_filters(sub, len(pick)), gyr[:, pick], acc[:, pick]),
        run_ref(Ekf(sub, len(pick)), gyr[:, pick], acc[:, pick]),
        "recovery property",
    )


# --- F12: P not positive definite at the first update after a gimbal-clamped initialisation --------------

F12_SAMPLES = [
    (("0x1.fe2876p-118", "0x1.798424p-7", "-0x1.b14ba6p-7"), ("0x1.021844p+1", "-0x1.16d218p-125", "0x0p+0")),
    (("0x1.48p+1", "-0x1.f8p+0", "0x1.0cp+1"), ("-0x1.fp+1", "-0x1p+3", "0x1.39d014p+3")),
    (("0x1.ap+1", "0x1.18p+0", "-0x1p-3"), ("-0x1p-3", "0x0p+0", "0x1.1be80ap+4")),
    (("0x1.ep+0", "0x0p+0", "-0x1.68p+0"), ("0x1p-2", "0x1p-4", "0x1.37d014p+3")),
    (("-0x1.fcp+1", "0x1.6p-2", "0x1.04p+1"), ("0x0p+0", "0x0p+0", "0x1.10e80ap+4")),
    (("-0x1.ccp+1", "0x1.6p-2", "0x1.0cp+1"), ("-0x1.fp+1", "-0x1p+3", "0x1.39d014p+3")),
    (("0x0p+0", "-0x1.28p+0", "0x1.d4p+1"), ("-0x1.48p+2", "0x1.ep+1", "0x1.39d014p+3")),
    (("-0x1.98p+1", "-0x1.8p+0", "0x1.a8p+1"), ("0x1p+2", "0x0p+0", "0x1.d5d014p+3")),
    (("-0x1.68p+0", "-0x1.ap-1", "0x1.08p+1"), ("-0x1.fp+1", "-0x1p+3", "0x1.39d014p+3")),
    (("0x0p+0", "0x1.3p+1", "-0x1.dp-1"), ("-0x1.d4p+2", "0x1.ep+1", "0x1.39d014p+3")),
    (("0x1.066fcp+1", "-0x1.07e54ep+2", "0x1.15e502p+3"), ("0x1.efa82ap-41", "0x1.18fep+3", "nan")),
    (("0x1.05e12ap+1", "-0x1.07bddp+2", "0x1.186dbcp+3"), ("0x1.91ee54p-127", "0x1p+63", "0x1.fffffep-1")),
    (("0x1.04p+1", "0x0p+0", "-0x1.ep-1"), ("0x1.08p+2", "0x1.18p+2", "0x1.b9d014p+3")),
    (("0x1p+1", "0x1.4p+0", "0x1.34p+1"), ("0x0p+0", "0x0p+0", "0x1.39d014p+3")),
]
"""tests/fuzz/regressions/filter-ekf-P_SPD-gimbal-init.bin as samples (ATT_FUZZ_VERBOSE=1): the seed
preset at dt 1/285.714 s; the first sample initialises at pitch -pi/2 (GIMBAL, roll variance to p_max at
the next step), ten with the accel rejected, the level sample of step 14 the first accepted update."""


def test_f12_update_after_a_gimbal_init_keeps_p_positive_definite() -> None:
    """F12 (found by fuzz_filter, issue 26): the roll variance left at p_max by the initialisation at the
    gimbal (roll is unobservable there) fed pitch through F's coupling while ten accel samples were rejected:
    the roll/pitch correlation reached -0.99999998 (P00 9e5, P11 1e4), beyond what float32 carries, and the
    first accepted update (step 14) left P indefinite (diagonal 21.8, 0.27, 2.3; correlation -1.0000000075)
    and moved the pitch away from the level sample (-1.04 -> -1.13 rad). Now a roll/pitch block within the
    margin of the positive definiteness test (det P2 <= 2^-12 P00 P11) is conditioned at the end of its
    step (steps 5, 7 and 12 here, besides 2 to 4 as before: CLAMPED): P positive definite with margin at
    every step, and the update of step 14 moves the pitch toward level (to -0.41 rad). C and reference bit
    for bit."""
    gyr = np.array([[[float.fromhex(x) for x in g]] for g, _ in F12_SAMPLES], F32)
    acc = np.array([[[float.fromhex(x) for x in a]] for _, a in F12_SAMPLES], F32)
    s = ekf_seed(dt=float.fromhex("0x1.cac084p-9"))
    c = run_c(c_filters(s, 1), gyr, acc)
    compare(c, run_ref(Ekf(s, 1), gyr, acc), "F12")
    fl = c["flags"][:, 0]
    assert fl[1] & Flag.GIMBAL and fl[-1] == 0  # the gimbal init; step 14: an applied update
    check_cov(c["P"][:, 0], "F12")
    p = unpack(c["P"][-1, 0]).astype(np.float64)
    assert (np.diag(np.linalg.cholesky(p)) ** 2 > 2**-12 * np.diag(p)).all()
    conditioned = np.nonzero(fl & Flag.CLAMPED)[0] + 1
    print(f"\nF12: CLAMPED at steps {conditioned.tolist()}, pitch {c['euler'][-2:, 0, 1]}")
    assert abs(float(c["euler"][-1, 0, 1])) < abs(float(c["euler"][-2, 0, 1]))  # toward the level sample


def test_p_positive_definite_after_gimbal_inits() -> None:
    """A property of F12's kind: 2000 instances of the seed preset at dt 1/285.714 s, each initialised at
    pitch +-pi/2 by an accel sample along x (|a| 0.5 .. 12 m/s^2), then rates up to 4 rad/s per axis and 2 ..
    99 accel samples off by 15 .. 100 % of g (rejected) before good ones (110 steps): P finite and positive
    definite at every step. Before the fix 2 of these 2000 instances had an indefinite P at some step (found
    with the reference, the near singular test switched off). C and reference bit for bit on 100."""
    rng = np.random.default_rng(1)
    m, n = 2000, 110
    gyr = rng.uniform(-4, 4, (n, m, 3)).astype(F32)
    acc = np.zeros((n, m, 3), F32)
    acc[0, :, 0] = np.where(rng.random(m) < 0.5, 1, -1) * rng.uniform(0.5, 12, m)
    k = rng.integers(2, 100, m)
    for j in range(m):
        d = rng.normal(size=(n, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        size = np.where(np.arange(n) < k[j], G * rng.uniform(1.15, 2.0, n), G)
        acc[1:, j] = (d * size[:, None])[1:]
    s = ekf_seed(dt=float.fromhex("0x1.cac084p-9"))
    c = run_c(c_filters(s, m), gyr, acc)
    lo, rel = check_cov(c["P"], "after gimbal inits")
    clamped = int(((c["flags"] & Flag.CLAMPED) != 0).sum())
    print(f"\nsmallest eigenvalue {lo:.2e} (relative {rel:.2e}); CLAMPED steps {clamped} of {m * n}")
    pick = slice(0, 100)
    compare(
        run_c(c_filters(s, 100), gyr[:, pick], acc[:, pick]),
        run_ref(Ekf(s, 100), gyr[:, pick], acc[:, pick]),
        "gimbal inits",
    )
