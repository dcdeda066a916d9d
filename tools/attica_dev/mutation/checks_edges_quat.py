"""Stage B: edge cases of mars (fast phase, heading bias, reference candidate), mekf and att_wrap_pi.

Each check drives the library with settings inside the contract (att_mars.h, att_mekf.h) that reach a
line the other checks leave alone: a fast phase of one block, a time constant of the low-pass below 1 s,
the gyro bias learnt from the heading, a reference candidate interrupted by an accepted block, the
recovery's gains, a sample whose norm is exactly the lower norm limit, a scale estimate held at its
bound, a chi-square gate below 1, and the angles that att_wrap_pi reduces to just above pi.
"""

from __future__ import annotations

from typing import Any

from attica_dev.mutation.checks_common import _sha


def _run(kind: str, g: Any, a: Any, m: Any, **settings: Any) -> bytes:
    """The output records (q, bias, flags, covariance ...) of ``kind`` with ``settings`` over (g, a, m)."""
    from attica import native

    f = native.Filter(kind, **settings)
    return bytes(f.run(g, a, m, full=True, check_units=False).tobytes())


def _still(n: int, seed: int, mag: tuple[float, float, float] = (0.0, 20.0, -40.0)) -> tuple[Any, Any, Any]:
    """A noisy stationary stream of n samples (level, the field ``mag`` in the sensor frame)."""
    import numpy as np

    rng = np.random.default_rng(seed)
    f = np.float32
    g = rng.normal(0.0, 0.01, (n, 3)).astype(f)
    a = (np.array([0.0, 0.0, 9.80665]) + rng.normal(0.0, 0.2, (n, 3))).astype(f)
    m = (np.array(mag) + rng.normal(0.0, 0.5, (n, 3))).astype(f)
    return g, a, m


def _mars_fast_check() -> str:
    """mars: the fast phase after the alignment, short or after a short low-pass.

    mars: the fast phase after the alignment, one block long (tau_mag_fast 0.2 s: fast_n = 1) and with
    a low-pass of 0.5 s (tau_acc_lp in (0, 1]: the start of the fast phase waits 6 tau_acc_lp more).
    """
    from attica_dev import digests

    g, a, m = digests.sim_stream()
    dt = digests.dt()
    parts = [
        _run("mars", g, a, m, dt=dt, tau_mag_fast=0.2),
        _run("mars", g, a, m, dt=dt, tau_acc_lp=0.5),
        _run("mars", g, a, m, dt=dt, tau_acc_lp=0.5, tau_mag_fast=0.2),
    ]
    return _sha(parts)


def _mars_bias_mag_check() -> str:
    """mars: the gyro bias learnt from the heading corrections.

    mars: the gyro bias learnt from the heading corrections (tau_bias_mag > 0, no fast phase), for each
    bias mode and a time constant above and below the sample period.
    """
    from attica_dev import digests

    g, a, m = digests.sim_stream()
    dt = digests.dt()
    parts = []
    for mode in (1, 2, 3):
        for tau in (5.0, 0.001):
            parts.append(_run("mars", g, a, m, dt=dt, tau_mag_fast=0.0, tau_bias_mag=tau, bias_mode=mode))
    return _sha(parts)


def _mars_candidate_check() -> str:
    """mars: a reference candidate interrupted, adopted, and a new one after it.

    Mars (FULL): a new field for 2 blocks, the old one for 1 block (the candidate restarts), then the
    new field until the candidate becomes the reference (mag_new_time 3 s: 3 blocks); then a third field,
    rejected by its dip (22 deg off) but within the candidate's tolerance of the adopted one (a new
    candidate, counted from 1).
    """
    import numpy as np

    g, a, m = _still(1500, 3101)
    _, _, mb = _still(1500, 3102, (10.0, 25.0, -60.0))
    _, _, mc = _still(1500, 3104, (1.0, 2.07, -65.76))
    sec = np.arange(1500) // 100
    new = ((sec >= 4) & (sec < 6)) | (sec >= 7)
    m[new] = mb[new]
    m[sec >= 10] = mc[sec >= 10]
    parts = [
        _run("mars", g, a, m, dt=0.01, mag_mode=1, mag_new_time=3.0, tau_mag_fast=0.0, tau_mag=1.0),
        _run("mars", g, a, m, dt=0.01, mag_mode=0, mag_new_time=3.0, tau_mag_fast=0.0, tau_mag=1.0),
    ]
    return _sha(parts)


def _mekf_recovery_check() -> str:
    """mekf: recoveries after clipping gyro samples.

    mekf: recoveries after clipping gyro samples with a fast low-pass (the recovery's gain below k_lp)
    and with a recovery of one sample (recovery_time = dt: rec_n = 1).
    """
    g, a, m = _still(600, 3103)
    for i in (100, 101, 300, 450):
        g[i, 2] = 9.9  # >= 0.98 gyro_range: clipping
    parts = [
        _run("mekf", g, a, m, dt=0.01, gyro_range=10.0, tau_acc_lp=0.01, recovery_time=2.0),
        _run("mekf", g, a, m, dt=0.01, gyro_range=10.0, recovery_time=0.01),
    ]
    return _sha(parts)


MAG_GATE_EDGES: tuple[tuple[float, float, float], ...] = (
    (2.4989583492279053, 49.9375114440918, 6.941067840671167e-05),
    (5.3104777336120605, 49.71718978881836, 0.0003141477645840496),
    (7.408517837524414, 49.44809341430664, 0.0006130599649623036),
)
"""(m_x, m_y, mag_gate), float32 values: with m0_init (0, 50, 0), q_init identity and a level accel, the first
step's heading innovation y has y^2 == mag_gate * s exactly (s its variance; found with the reference
mekf: the sample is accepted, and rejected with the float below mag_gate)."""


def _mekf_edges_check() -> str:
    """mekf: a sample at the norm limit, the scale at its bound, the mag gate's edge, a small gate.

    mekf: a mag sample whose norm is exactly the lower norm limit (|m0| (1 - mag_norm_reject): 50 * 0.5,
    accepted); the scale estimate held at -ATT_MEKF_SCALE_MAX (not estimated) while |V| is limited (a spin
    about the vertical without mag); heading innovations exactly at the mag gate (:data:`MAG_GATE_EDGES`); a
    chi-square gate below 1 (0.01: the simulated stream is gated often).
    """
    import numpy as np

    from attica_dev import digests

    f32 = np.float32
    n = 50
    g = np.zeros((n, 3), f32)
    a = np.tile(np.array([0.0, 0.0, 9.80665], f32), (n, 1))
    m = np.tile(np.array([0.0, 25.0, 0.0], f32), (n, 1))
    parts = [
        _run("mekf", g, a, m, dt=0.01, init_from_sensors=False, m0_init=(0.0, 50.0, 0.0), mag_norm_reject=0.5)
    ]
    n = 400
    g = np.tile(np.array([0.0, 0.0, 10.0], f32), (n, 1))
    a = np.tile(np.array([0.0, 0.0, 9.80665], f32), (n, 1))
    parts.append(_run("mekf", g, a, None, dt=0.01, use_mag=False, gyro_scale_sd=0.0, gyro_scale_init=-0.1))
    one_g = np.zeros((1, 3), f32)
    one_a = np.array([[0.0, 0.0, 9.80665]], f32)
    for mx, my, gate in MAG_GATE_EDGES:
        one_m = np.array([[mx, my, 0.0]], f32)
        parts.append(
            _run(
                "mekf",
                one_g,
                one_a,
                one_m,
                dt=0.01,
                init_from_sensors=False,
                m0_init=(0.0, 50.0, 0.0),
                mag_gate=gate,
            )
        )
    sg, sa, sm = digests.sim_stream()
    parts.append(_run("mekf", sg, sa, sm, dt=digests.dt(), gate=0.01))
    return _sha(parts)


def _wrap_pi_check() -> str:
    """att_wrap_pi near the odd multiples of pi.

    att_wrap_pi on the floats within 64 ulps of the odd multiples of pi in [-8192, 8192] (the contract's
    range): among them the angles whose first reduction lands just above pi.
    """
    import numpy as np

    from attica import native

    ks = np.arange(-1304, 1304)
    cent = ((2 * ks + 1) * np.pi).astype(np.float32)
    offs = np.arange(-64, 65, dtype=np.int32)
    x = (cent.view(np.int32)[:, None] + offs[None, :]).astype(np.int32).view(np.float32).ravel()
    x = x[np.abs(x) <= 8192.0]
    return _sha(native.wrap_pi(x).tobytes())


def _mekf_pd_check() -> str:
    """mekf: the positive-definiteness test at the states that need its rounding bound (F16).

    The F16 reproducer's stream (tests/test_mekf_f16.py: dt 1 s, p_max 10, a gyro beyond its range, then
    no usable accel sample; P indefinite at step 24 with a pivot test on P_jj alone), and 200 covariances
    of its shape (three eigenvalues near zero, one negative) written into the state, each followed by one
    step without an update: the outputs and P after every step.
    """
    import warnings

    import numpy as np

    from attica import native
    from attica.settings import FilterKind, make_settings

    f32 = np.float32
    g = float.fromhex("0x1.39d014p+3")
    nan = float("nan")
    h = float.fromhex
    gyr = [(h("0x1.5p+0"), h("-0x1.2p+1"), h("0x1.cp-1"))] + [(0.0, 0.0, 0.0)] * 3
    gyr += [(h("0x1.d8p+0"), h("-0x1.28p+0"), h("-0x1.28p+0"))] + [(1e6, 0.0, 0.0)] * 8 + [(nan, 0.0, 0.0)]
    gyr += [(0.0, 0.0, 0.0)] * 10
    acc = [(h("0x1.ep+2"), h("0x1.a8p+2"), h("0x1.83a028p+2"))] + [(0.0, nan, g)] * 3
    acc += (
        [(h("-0x1.28p+1"), h("-0x1.28p+1"), h("0x1.dfa028p+2"))] + [(0.0, 0.0, g)] * 9 + [(0.0, nan, g)] * 10
    )
    s = make_settings(
        FilterKind.MEKF,
        dt=1.0,
        gyro_noise=1e-4,
        gyro_rate_noise=0.01,
        bias_noise=1e-4,
        accel_noise=0.003,
        gate=16.0,
        gate_recover=2.0,
        p0_att=0.01,
        p0_bias=float(f32(np.pi / 2)),
        p_max=10.0,
        accel_range=float(f32(16 * 9.80665)),
        tau_acc_lp=1.25,
        use_mag=False,
        gyro_scale_sd=0.003,
        recovery_time=2.0,
    )
    parts: list[Any] = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        f = native.Filter("mekf", settings=s)
    for gi, ai in zip(gyr, acc, strict=True):
        parts.append(f.step(np.array(gi, f32), np.array(ai, f32), np.zeros(3, f32)).tobytes())
        parts.append(bytes(np.array(list(f.state.u.mekf.st.p), f32).tobytes()))
    rng = np.random.default_rng(1616)
    s = make_settings(
        FilterKind.MEKF, dt=0.01, p_max=1e3, p0_bias=float(f32(np.pi / 2)), use_mag=False, recovery_time=0.0
    )
    for _ in range(200):
        lam = np.array([10 ** rng.uniform(0, 1.5), 10 ** rng.uniform(-1, 1), 10 ** rng.uniform(-2, 0)])
        lam = np.concatenate(
            [lam, [10 ** rng.uniform(-5, -3), 10 ** rng.uniform(-6, -4), -(10 ** rng.uniform(-9, -7))]]
        )
        v, _ = np.linalg.qr(rng.normal(size=(6, 6)))
        p = v @ np.diag(lam) @ v.T
        sc = np.concatenate([10 ** rng.uniform(0, 0.5, 3), 10 ** rng.uniform(-1.5, 0, 3)]) / np.sqrt(
            np.diag(p)
        )
        packed = (p * sc[:, None] * sc[None, :]).astype(f32)[np.triu_indices(6)]
        f = native.Filter("mekf", settings=s)
        f.step(np.zeros(3, f32), np.array((0.0, 0.0, g), f32), np.zeros(3, f32))
        st = f.state.u.mekf.st.p
        for k, x in enumerate(packed):
            st[k] = float(x)
        parts.append(f.step(np.zeros(3, f32), np.array((0.0, nan, g), f32), np.zeros(3, f32)).tobytes())
        parts.append(bytes(np.array(list(f.state.u.mekf.st.p), f32).tobytes()))
    return _sha(*parts)
