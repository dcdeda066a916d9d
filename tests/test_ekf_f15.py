"""F15 (issue 26, docs/robustness.md): the ekf's P without accel updates near pitch 90 deg.

Without an applied update nothing bounds P: the prediction feeds the bias variance into roll at a gain of
dt tan(theta) per step. Near the gimbal, with the accel samples missing or rejected, roll's variance ran far
beyond p_max between the every-16-steps conditionings and its correlation with the bias beyond what float32
carries: P indefinite. att_ekf_check now conditions P at every step without an applied update (caps and the
positive definiteness test with margin), in C and the reference.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from attica.reference.ekf import Ekf
from attica.settings import EkfSettings, Flag

from ekf_support import DIAG, G, c_filters, check_cov, compare, ekf_default, run_c, run_ref, unpack

F32 = np.float32
ZERO = ("0x0p+0", "0x0p+0", "0x0p+0")
LEVEL = ("0x0p+0", "0x0p+0", "0x1.39d014p+3")  # (0, 0, 9.80665)
NAN_Y = ("0x0p+0", "nan", "0x1.39d014p+3")  # accel invalid: no update
F15_SAMPLES = (
    [(ZERO, LEVEL)] * 4
    + [(("-0x1.575756p-40",) * 3, ("-0x1.575756p-40", "-0x1.575756p-40", "0x1.8d26f8p+1"))]
    + [(ZERO, LEVEL)] * 4
    + [
        (("0x1.3p+0", "0x1.d4p+1", "0x1.bp+0"), ("0x1p+2", "0x0p+0", "0x1.8dd014p+3")),
        (("0x1.f62bd6p-7", "0x1.3207p-6", "-0x1.1e7f9ep-6"), ("0x1.ff391p+0", "-0x1.1a85d4p-126", "0x0p+0")),
        (("-0x1.898814p+10", "nan", "-0x1.5e29fep+9"), ("nan", "nan", "nan")),
    ]
    + [(ZERO, NAN_Y)] * 9
    + [(ZERO, ("0x0p+0", "-0x1.898988p+10", "0x1.39d014p+3"))]
    + [(ZERO, NAN_Y)] * 9
)
"""tests/fuzz/regressions/filter-ekf-P_SPD-gimbal-rejected.bin as samples (ATT_FUZZ_VERBOSE=1): level
at rest, two rejected samples with rates of 1-4 rad/s that turn the estimate to pitch 86 deg, then 20
steps without a usable accel sample (a NaN component; one beyond accel_range)."""


def f15_settings() -> EkfSettings:
    """The reproducer's settings: dt 0.5 s, per-step noises, p0_bias and p_max pi, accel_reject 0.1."""
    return ekf_default(
        dt=0.5,
        q_phi=1e-4,
        q_theta=1e-4,
        q_psi=0.1,
        q_bias=1e-12,
        r_phi=6.0,
        r_theta=6.0,
        p0_bias=float(F32(np.pi)),
        p_max=float(F32(np.pi)),
        accel_reject=0.1,
        tau_acc_lp=0.0,
        euler_init=(float(F32(np.pi)), 0.0, 0.0),
        noise_rates=False,
    )


def test_f15_p_stays_positive_definite_without_updates_near_the_gimbal() -> None:
    """F15 (found by fuzz_filter at 731aa11, issue 26): roll's variance grew 3 -> 18,600 in the 16 steps
    between two conditionings (p_max pi) while the accel samples were unusable at pitch 86 deg, and at step
    31 P was not positive definite. Now every step without an applied update ends with the conditioning:
    P positive definite with margin at every step, roll's variance never above p_max after such a step.
    C and reference bit for bit."""
    gyr = np.array([[[float.fromhex(x) for x in g]] for g, _ in F15_SAMPLES], F32)
    acc = np.array([[[float.fromhex(x) for x in a]] for _, a in F15_SAMPLES], F32)
    s = f15_settings()
    c = run_c(c_filters(s, 1), gyr, acc)
    compare(c, run_ref(Ekf(s, 1), gyr, acc), "F15")
    fl = c["flags"][:, 0]
    no_update = (fl & (Flag.ACCEL_INVALID | Flag.ACCEL_RANGE)) != 0
    assert no_update[-20:].all() and abs(float(c["euler"][-1, 0, 1])) > 1.4  # the reproducer's situation
    check_cov(c["P"][:, 0], "F15")
    p = c["P"][:, 0]
    assert (p[no_update][:, list(DIAG[:3])] <= np.pi * (1 + 2**-20)).all()  # p_max, to the cap's rounding
    full = unpack(p[-1]).astype(np.float64)
    assert (np.diag(np.linalg.cholesky(full)) ** 2 > 2**-13 * np.diag(full)).all()


def test_p_positive_definite_without_updates_near_the_gimbal() -> None:
    """A property of F15's kind: 1000 instances of the defaults with a frozen bias (q_bias 1e-12, no
    low-pass), dt 5 ms .. 0.5 s, q_phi = q_theta 1e-8 .. 1e-2 rad^2/s, p_max 0.01 .. 1e6, p0_bias 1e-3 ..
    pi, each started by an accel sample at pitch +-(75 .. 89.9) deg, then 150 steps of small rates with
    every accel sample rejected (|a| off by 20 .. 100 % of g) or invalid: P finite and positive definite
    at every step. Before the fix 11 of these 1000 instances had an indefinite P at some step; with the
    conditioning at every step without an update but the old pivot test (d_j > 2^-12 P_jj), one still did
    (instance 544 at step 130: float32 pivots 5e-3 and 1.05e-3, the last -3.8e-4 exact), so this test
    holds both halves of the fix. C and reference bit for bit on 100."""
    rng = np.random.default_rng(15)
    m, n = 1000, 150
    theta = np.where(rng.random(m) < 0.5, 1, -1) * np.radians(rng.uniform(75, 89.9, m))
    phi = rng.uniform(-np.pi, np.pi, m)
    gyr = rng.uniform(-0.05, 0.05, (n, m, 3)).astype(F32)
    up = np.stack([-np.sin(theta), np.cos(theta) * np.sin(phi), np.cos(theta) * np.cos(phi)], -1)
    off = np.where(rng.random((n, m)) < 0.5, rng.uniform(1.2, 2.0, (n, m)), rng.uniform(0.0, 0.8, (n, m)))
    size = G * off
    acc = (up[None] * size[..., None]).astype(F32)
    acc[0] = (up * G).astype(F32)
    acc[rng.random((n, m)) < 0.1, 1] = np.nan
    acc[0, :, 1] = (up[:, 1] * G).astype(F32)
    p_max = np.exp(rng.uniform(np.log(1e-2), np.log(1e6), m)).astype(F32)
    q = np.exp(rng.uniform(np.log(1e-8), np.log(1e-2), m)).astype(F32)
    s = dataclasses.replace(
        ekf_default(accel_reject=0.1, q_bias=1e-12, tau_acc_lp=0.0),
        dt=np.exp(rng.uniform(np.log(5e-3), np.log(0.5), m)).astype(F32),
        q_phi=q,
        q_theta=q,
        p_max=p_max,
        p0=np.minimum(F32(1), p_max),
        p0_bias=np.minimum(np.exp(rng.uniform(np.log(1e-3), np.log(np.pi), m)).astype(F32), p_max),
    )
    c = run_c(c_filters(s, m), gyr, acc)
    assert ((c["flags"][1:] & (Flag.ACCEL_REJECTED | Flag.ACCEL_INVALID)) != 0).all()  # no update applied
    lo, rel = check_cov(c["P"], "without updates near the gimbal")
    print(f"\nsmallest eigenvalue {lo:.2e} (relative {rel:.2e})")
    pick = slice(0, 100)
    per = ("dt", "q_phi", "q_theta", "p_max", "p0", "p0_bias")
    sub = dataclasses.replace(s, **{k: np.asarray(getattr(s, k))[pick] for k in per})
    compare(
        run_c(c_filters(sub, 100), gyr[:, pick], acc[:, pick]),
        run_ref(Ekf(sub, 100), gyr[:, pick], acc[:, pick]),
        "without updates near the gimbal",
    )
