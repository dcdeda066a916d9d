"""Input/output stages (att_calib.c, att_filter): C against the numpy reference bit for bit, the
settings contract, the 24 remaps and the three conventions against the simulator's truth, heading."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from calib_support import adversarial, c_settings, c_stages, nasty_inputs, ordinary

from attica import kinds, native
from attica.calibration import REMAPS, Calibration, InertialModel, MagModel, Mounting
from attica.calibration.stages import REMAP_NAMES, StageSettings, from_calibration
from attica.native import ffi, lib
from attica.outputs import OUTPUT_DTYPE
from attica.reference import Filter as RefFilter
from attica.reference import calib as rc
from attica.sim import SimConfig, simulate_with_truth

from helpers import assert_same_bits

KINDS = kinds.labels()

HEADING_KINDS = [k.label for k in kinds.KINDS if k.heading() != kinds.Heading.NONE]
"""Kinds that take set_heading with their defaults."""

UPDATE_CASES = [
    pytest.param(k.label, {}, id=k.label) for k in kinds.KINDS if k.heading() == kinds.Heading.UPDATE
] + [
    pytest.param(k.label, {k.mag_switch: False}, id=f"{k.label}-{k.mag_switch}-off")
    for k in kinds.KINDS
    if k.mag_switch is not None and k.heading_no_mag == kinds.Heading.UPDATE
]
"""(kind, settings) that take external heading updates: the 6-axis kinds, and the MEKF without its mag."""


def _cols(a: np.ndarray) -> tuple[Any, Any, Any]:
    return (a[:, 0].copy(), a[:, 1].copy(), a[:, 2].copy())


# --- names and the exact remaps ---------------------------------------------------------------------


def test_remap_names_and_parse() -> None:
    names = [ffi.string(lib.att_calib_remap_name(r)).decode() for r in range(1, 25)]
    assert names == list(REMAP_NAMES)
    assert set(names) == set(REMAPS)
    for r, name in enumerate(names, 1):
        assert lib.att_calib_remap_parse(name.encode()) == r
    for bad in (b"", b"+x+y", b"+x+y+zz", b"+x+x+z", b"x+y+z+", b"+x-y+z", b"+X+Y+Z"):
        assert lib.att_calib_remap_parse(bad) == 0, bad
    assert lib.att_calib_remap_name(0) == ffi.NULL and lib.att_calib_remap_name(25) == ffi.NULL


@pytest.mark.parametrize("name", REMAP_NAMES)
def test_remap_is_an_exact_signed_permutation(name: str) -> None:
    """A remap without a model takes the permutation path and equals the model's matrix exactly."""
    s = StageSettings(remap=REMAP_NAMES.index(name) + 1)
    c = c_stages(s)
    if name == "+x+y+z":
        assert c.active == 0 and c.gyr.mode == 0
        return
    assert c.gyr.mode == 1 and c.acc.mode == 1 and c.mag.mode == 1
    rng = np.random.default_rng(7)
    v = nasty_inputs(rng, 4000, 10.0)
    v[0] = (-0.0, 1.0, np.nan)
    g, a, m = v.copy(), v.copy(), v.copy()
    lib.att_host_calib_apply(
        c, ffi.from_buffer("float[]", g), ffi.from_buffer("float[]", a), ffi.from_buffer("float[]", m), len(v)
    )
    r = np.array(REMAPS[name])
    want = np.empty_like(v)
    for k in range(3):  # row k of R has one +-1: body k = sign * sensor axis
        j = int(np.flatnonzero(r[k])[0])
        want[:, k] = v[:, j] if r[k, j] > 0 else -v[:, j]
    assert_same_bits(g, want, name)
    assert_same_bits(a, want, name)
    zero = np.all(v == 0, axis=1)  # the zero vector (absent) stays as it was
    assert_same_bits(m, np.where(zero[:, None], v, want), name)


# --- the stage alone, 1e6 samples -------------------------------------------------------------------


def test_stage_bit_exact_million_samples() -> None:
    """att_calib_apply == reference Stages.apply on 16 settings (8 adversarial) x 62 500 nasty samples."""
    rng = np.random.default_rng(13)
    settings = [ordinary(rng, remap=int(rng.integers(0, 25)), convention=i % 3) for i in range(8)]
    settings += [adversarial(rng, i) for i in range(8)]
    total = 0
    for idx, s in enumerate(settings):
        n = 62_500
        g0 = nasty_inputs(rng, n, 3.0)
        a0 = nasty_inputs(rng, n, 10.0)
        m0 = nasty_inputs(rng, n, 50.0)
        g, a, m = g0.copy(), a0.copy(), m0.copy()
        c = c_stages(s)
        lib.att_host_calib_apply(
            c, ffi.from_buffer("float[]", g), ffi.from_buffer("float[]", a), ffi.from_buffer("float[]", m), n
        )
        ref = rc.Stages(s)
        rg, ra, rm = ref.apply(_cols(g0), _cols(a0), _cols(m0))
        for what, got, want in (("gyr", g, rg), ("acc", a, ra), ("mag", m, rm)):
            assert_same_bits(got, np.stack(want, axis=-1), f"settings {idx} {what}")
        # an absent mag stays absent: the zero vector unchanged, a NaN component NaN
        zero = np.all(m0 == 0, axis=1)
        assert_same_bits(m[zero], m0[zero], f"settings {idx} zero mag")
        assert np.isnan(m[np.any(np.isnan(m0), axis=1)]).any(axis=1).all()
        total += n
    assert total >= 1_000_000


def test_folded_matrix_matches_reference() -> None:
    rng = np.random.default_rng(3)
    for i in range(40):
        s = adversarial(rng, i) if i % 2 else ordinary(rng, remap=i % 25)
        c = c_stages(s)
        ref = rc.Stages(s)
        for cs, rs in ((c.gyr, ref.gyr), (c.acc, ref.acc), (c.mag, ref.mag)):
            assert cs.mode == rs.mode
            assert_same_bits(np.array(list(cs.a), np.float32), np.array(rs.a, np.float32), f"{i}")


# --- the settings contract --------------------------------------------------------------------------


def _with(**kw: Any) -> StageSettings:
    return StageSettings(**kw)


@pytest.mark.parametrize(
    ("settings", "problem"),
    [
        (_with(gyro_misalignment=[1, 0, 0, 0, 1, 0, 0, 0, np.nan]), "gyro_matrix"),
        (_with(gyro_misalignment=[1, 0, 0, 0, 1, 0, 0, 0, 0]), "gyro_matrix"),
        (_with(gyro_misalignment=[1, 0, 0, 0, 1, 0, 0, 0, 1e-4]), "gyro_matrix"),
        (_with(gyro_misalignment=[2e3, 0, 0, 0, 2e3, 0, 0, 0, 2e3]), "gyro_matrix"),
        (_with(gyro_sensitivity=[1, 0, 1]), "gyro_sensitivity"),
        (_with(gyro_sensitivity=[1, -1, 1]), "gyro_sensitivity"),
        (_with(gyro_offset=[0, np.inf, 0]), "gyro_offset"),
        (_with(gyro_offset=[0, 1001, 0]), "gyro_offset"),
        (_with(accel_misalignment=[1, 1, 1, 1, 1, 1, 1, 1, 1]), "accel_matrix"),
        (_with(accel_sensitivity=[1, 1, 1e4]), "accel_sensitivity"),
        (_with(accel_offset=[2e4, 0, 0]), "accel_offset"),
        (_with(soft_iron=[1, 0, 0, 0, 1, 0, 1, 0, 1e-6]), "mag_matrix"),
        (_with(hard_iron=[0, 0, np.nan]), "mag_offset"),
        (_with(remap=25), "remap"),
        (_with(mounting=[1, 0, 0, 0.1]), "mounting"),
        (_with(mounting=[np.nan, 0, 0, 0]), "mounting"),
        (_with(convention=3), "convention"),
        (_with(gravity=0.5), "gravity"),
    ],
)
def test_settings_refused_with_reason(settings: StageSettings, problem: str) -> None:
    cs = c_settings(settings)
    code = lib.att_calib_settings_check(cs)
    assert rc.ERRORS[code] == problem
    assert rc.check(settings) == problem
    assert lib.att_calib_settings_validate(cs) == lib.ATT_ERR_SETTINGS
    f = native.Filter("ars", dt=0.01)
    f.step((0.1, 0.0, 0.0), (0.0, 0.0, 9.8))
    before = bytes(f.state)
    with pytest.raises(native.NativeError, match=r"att_filter_calibrate"):
        f.calibrate(settings)
    assert bytes(f.state) == before  # never half-applied
    with pytest.raises(ValueError, match=problem):
        rc.Stages(settings)


def test_flag_byte_refused() -> None:
    cs = c_settings(StageSettings())
    ffi.cast("unsigned char *", ffi.addressof(cs[0], "accel_outputs"))[0] = 2
    assert rc.ERRORS[lib.att_calib_settings_check(cs)] == "flag"
    assert lib.att_calib_settings_check(ffi.NULL) == lib.ATT_CALIB_ERR_NULL


def test_every_well_conditioned_file_is_accepted() -> None:
    """Matrices the calibration file accepts (2-norm condition < 1e3) pass the firmware's check."""
    rng = np.random.default_rng(5)
    from calib_support import _conditioned

    for i in range(3000):
        cond = float(rng.uniform(1.0, 999.0)) if i % 3 else 999.0
        m = _conditioned(rng, cond, scale=float(10 ** rng.uniform(-2, 2.9)), flip=bool(i % 2)).astype(
            np.float32
        )
        if np.linalg.cond(m.reshape(3, 3).astype(np.float64)) >= 1e3 or np.abs(m).max() > 1e3:
            continue
        assert rc.matrix_ok(m), (i, m)
        assert lib.att_calib_settings_check(c_settings(StageSettings(soft_iron=m))) == lib.ATT_CALIB_OK
    for _ in range(300):  # and C and the reference agree on random, often bad, matrices
        m = (rng.normal(size=9) * 10 ** rng.uniform(-25, 4, 9)).astype(np.float32)
        assert rc.matrix_ok(m) == (lib.att_calib_settings_check(c_settings(StageSettings(soft_iron=m))) == 0)


def test_calibration_file_to_firmware() -> None:
    cal = Calibration(
        gyro=InertialModel(offset=(0.01, -0.02, 0.005)),
        accel=InertialModel(sensitivity=(1.01, 0.99, 1.0)),
        mag=MagModel(soft_iron=((1.1, 0.02, 0), (0.02, 0.9, 0), (0, 0, 1.0)), hard_iron=(10, -5, 3)),
        mounting=Mounting(remap="+y+x-z"),
        convention="ned",
    )
    s = from_calibration(cal)
    assert s.remap_name == "+y+x-z" and s.convention == 1
    c = c_stages(s)
    assert c.active == (lib.ATT_CALIB_ACTIVE_INPUT | lib.ATT_CALIB_ACTIVE_CONV)
    assert c_stages(from_calibration(Calibration())).active == 0
    assert c_stages(from_calibration(None, accel_outputs=True)).active == lib.ATT_CALIB_ACTIVE_ACC


# --- every kind through att_filter, >= 1e6 steps ------------------------------------------------------


def _motion(n: int, seed: int, streams: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n)[:, None, None] * 0.01
    ph = rng.uniform(0, 6.3, (1, streams, 3))
    gyr = (0.8 * np.sin(0.7 * t + ph) + rng.normal(0, 0.02, (n, streams, 3))).astype(np.float32)
    acc = (
        np.array([0.3, -0.2, 9.7]) + 2.0 * np.sin(0.3 * t + ph) + rng.normal(0, 0.1, (n, streams, 3))
    ).astype(np.float32)
    mag = (
        np.array([5.0, 20.0, -40.0]) + 8.0 * np.cos(0.5 * t + ph) + rng.normal(0, 0.3, (n, streams, 3))
    ).astype(np.float32)
    # a few bad samples of every sort
    for x in (gyr, acc, mag):
        bad = rng.random((n, streams)) < 0.002
        x[bad] = nasty_inputs(rng, int(bad.sum()), 1e3)
    mag[rng.random((n, streams)) < 0.01] = 0.0
    return gyr, acc, mag


STEPS = 200
STREAMS = 256


@pytest.mark.parametrize("kind", KINDS)
def test_filter_bit_exact_with_calibration(kind: str) -> None:
    """C att_filter_step + att_filter_output + att_filter_accel == the reference: 4 settings (2 adversarial)
    x 256 streams x 200 steps per kind (2e5 steps per kind), records and states bit for bit."""
    rng = np.random.default_rng(hash(kind) % 2**32)
    settings = [
        ordinary(rng, remap=0, convention=1),
        ordinary(rng, remap=int(rng.integers(2, 25)), convention=2),
    ]
    settings += [adversarial(rng, 1 + KINDS.index(kind)), adversarial(rng, 2 + KINDS.index(kind))]
    for si, s in enumerate(settings):
        gyr, acc, mag = _motion(STEPS, 100 * si + KINDS.index(kind), STREAMS)
        ref = RefFilter(kind, dt=0.01, n=STREAMS, calibration=s)
        want = np.empty((STEPS, STREAMS), OUTPUT_DTYPE)
        want_acc = np.empty((STEPS, STREAMS, 9), np.float32)
        for i in range(STEPS):
            want[i] = ref.step(gyr[i], acc[i], mag[i])
            want_acc[i] = np.concatenate(ref.accel(), axis=-1)
        for j in range(STREAMS):
            f = native.Filter(kind, dt=0.01, calibration=s)
            out = np.zeros(STEPS, OUTPUT_DTYPE)
            accel = np.zeros((STEPS, 10), np.float32)
            g, a, m = (np.ascontiguousarray(x[:, j]) for x in (gyr, acc, mag))
            lib.att_host_filter_run_accel(
                f.state.ptr,
                ffi.from_buffer("float[]", g),
                ffi.from_buffer("float[]", a),
                ffi.from_buffer("float[]", m),
                STEPS,
                ffi.from_buffer("att_output_t[]", out),
                ffi.from_buffer("float[]", accel),
            )
            for name in ("q", "euler", "gyro_bias", "cov"):
                assert_same_bits(out[name], want[name][:, j], f"{kind} settings {si} stream {j} {name}")
            assert (out["flags"] == want["flags"][:, j]).all()
            assert (accel[:, 9].view(np.uint32) == lib.ATT_OUT_ACCEL).all()
            assert_same_bits(accel[:, :9], want_acc[:, j], f"{kind} settings {si} stream {j} accel")
            assert ref.state_diff(j, f.state) == []


def test_per_step_record_in_convention() -> None:
    """att_filter_step's own record: q (and euler where reported) in the convention's frame."""
    s = ordinary(np.random.default_rng(1), remap=5, convention=1)
    gyr, acc, mag = _motion(200, 1, 1)
    for kind in KINDS:
        f = native.Filter(kind, dt=0.01, calibration=s)
        full = native.Filter(kind, dt=0.01, calibration=s)
        for i in range(200):
            o = f.step(gyr[i, 0], acc[i, 0], mag[i, 0], full=False)
            w = full.step(gyr[i, 0], acc[i, 0], mag[i, 0])
            assert o["valid"] & lib.ATT_OUT_Q
            assert_same_bits(o["q"], w["q"], kind)
            if o["valid"] & lib.ATT_OUT_EULER:
                assert_same_bits(o["euler"], w["euler"], kind)


def test_identity_calibration_changes_nothing() -> None:
    gyr, acc, mag = _motion(500, 3, 1)
    for kind in KINDS:
        plain = native.Filter(kind, dt=0.01).run(gyr[:, 0], acc[:, 0], mag[:, 0])
        f = native.Filter(kind, dt=0.01, calibration=Calibration(mounting=Mounting(remap="+x+y+z")))
        assert f.state.cal.active == 0
        got = f.run(gyr[:, 0], acc[:, 0], mag[:, 0])
        assert got.tobytes() == plain.tobytes()


# --- conventions and the 24 remaps against the simulator's truth -----------------------------------


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = np.moveaxis(a, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        axis=-1,
    )


def _mat_to_quat(r: np.ndarray) -> np.ndarray:
    """A proper rotation matrix (float64) as a unit quaternion."""
    w = np.sqrt(max(0.0, 1.0 + np.trace(r))) / 2
    if w > 1e-3:
        return np.array(
            [w, (r[2, 1] - r[1, 2]) / (4 * w), (r[0, 2] - r[2, 0]) / (4 * w), (r[1, 0] - r[0, 1]) / (4 * w)]
        )
    i = int(np.argmax(np.diag(r)))
    j, k = (i + 1) % 3, (i + 2) % 3
    v = np.zeros(4)
    v[i + 1] = np.sqrt(max(0.0, 1 + r[i, i] - r[j, j] - r[k, k])) / 2
    v[0] = (r[k, j] - r[j, k]) / (4 * v[i + 1])
    v[j + 1] = (r[j, i] + r[i, j]) / (4 * v[i + 1])
    v[k + 1] = (r[k, i] + r[i, k]) / (4 * v[i + 1])
    return v


C_CONV = {
    "enu": np.array([1.0, 0, 0, 0]),
    "ned": np.array([0.0, np.sqrt(0.5), np.sqrt(0.5), 0]),  # NED <- ENU
    "nwu": np.array([np.sqrt(0.5), 0, 0, -np.sqrt(0.5)]),  # NWU <- ENU
}


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = np.abs(np.sum(a * b, axis=-1)) / np.linalg.norm(a, axis=-1) / np.linalg.norm(b, axis=-1)
    return 2 * np.arccos(np.clip(d, 0, 1))


@pytest.fixture(scope="module")
def sim() -> Any:
    return simulate_with_truth(
        SimConfig(duration=40.0, rate=100.0, seed=11, gyro_bias=0.0, gyro_bias_drift=0.0)
    )


@pytest.mark.parametrize("name", REMAP_NAMES)
def test_conventions_for_every_remap_against_truth(name: str, sim: Any) -> None:
    """The sensor mounted by each remap: the 9-axis filter's body attitude in ENU, NED and NWU matches the
    truth (q_body = q_sensor * r^-1, then conv <- ENU); NED/NWU convert to ENU (quaternion within rounding,
    earth-frame vectors exactly); the filter state is the same in every convention."""
    rec, truth = sim
    r = np.array(REMAPS[name], float)
    rq = _mat_to_quat(r)
    q_body = _qmul(rec.quat_true, rq * np.array([1, -1, -1, -1]))
    moving = rec.movement & (np.arange(len(rec.gyr)) > 500)
    results: dict[str, Any] = {}
    for conv in ("enu", "ned", "nwu"):
        cal = Calibration(mounting=Mounting(remap=name), convention=conv)
        f = native.Filter("mars", dt=0.01, calibration=cal, accel_outputs=True)
        out = np.zeros(len(rec.gyr), OUTPUT_DTYPE)
        accel = np.zeros((len(rec.gyr), 10), np.float32)
        lib.att_host_filter_run_accel(
            f.state.ptr,
            ffi.from_buffer("float[]", rec.gyr),
            ffi.from_buffer("float[]", rec.acc),
            ffi.from_buffer("float[]", rec.mag),
            len(rec.gyr),
            ffi.from_buffer("att_output_t[]", out),
            ffi.from_buffer("float[]", accel),
        )
        want = _qmul(np.broadcast_to(C_CONV[conv], q_body.shape), q_body)
        err = np.degrees(_angle(out["q"].astype(np.float64), want))[moving]
        assert np.sqrt(np.mean(err**2)) < 3.0, (name, conv, np.sqrt(np.mean(err**2)))
        results[conv] = (out, accel, bytes(f.state.u))
    enu_out, enu_acc, enu_state = results["enu"]
    for conv in ("ned", "nwu"):
        out, accel, state = results[conv]
        assert state == enu_state  # the convention touches the outputs only
        back = _qmul(
            np.broadcast_to(C_CONV[conv] * np.array([1, -1, -1, -1]), out["q"].shape),
            out["q"].astype(np.float64),
        )
        assert np.abs(back - enu_out["q"]).max() < 3e-7  # one rounding of each of 4 terms
        assert_same_bits(accel[:, :6], enu_acc[:, :6], f"{name} {conv} gravity/linear")
        e = enu_acc[:, 6:9]
        perm = np.stack(
            [e[:, 1], e[:, 0], -e[:, 2]] if conv == "ned" else [e[:, 1], -e[:, 0], e[:, 2]], axis=-1
        )
        assert_same_bits(accel[:, 6:9], perm, f"{name} {conv} earth")
    # the accelerations against the truth: earth-frame linear acceleration (ENU)
    lin_err = np.abs(enu_acc[moving, 6:9] - truth.acc_lin[moving])
    assert np.sqrt(np.mean(lin_err**2)) < 0.5


# --- heading ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", HEADING_KINDS)
@pytest.mark.parametrize("conv", ("enu", "ned", "nwu"))
def test_set_heading(kind: str, conv: str) -> None:
    gyr, acc, mag = _motion(60, 5, 1)
    cal = Calibration(convention=conv)
    f = native.Filter(kind, dt=0.01, calibration=cal)
    ref = RefFilter(kind, dt=0.01, calibration=cal)
    for i in range(60):
        f.step(gyr[i, 0], acc[i, 0], mag[i, 0])
        ref.step(gyr[i, 0], acc[i, 0], mag[i, 0])
    before = f.output()
    f.set_heading(1.25)
    ref.set_heading(1.25)
    after = f.output()
    assert ref.state_diff(0, f.state) == []
    assert abs(float(after["euler"][2]) - 1.25) < 2e-6

    # tilt kept: the angle of the up axis (body frame) does not change
    def up(q: np.ndarray) -> np.ndarray:
        w, x, y, z = q.astype(np.float64)
        return np.array([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])

    assert np.abs(np.abs(up(after["q"])) - np.abs(up(before["q"]))).max() < 5e-6
    assert_same_bits(ref.output()["q"][0], after["q"], kind)


def test_heading_refusals() -> None:
    tilt = native.Filter("tilt", dt=0.01)
    with pytest.raises(native.NativeError, match="not supported"):
        tilt.set_heading(0.5)
    fresh = native.Filter("ars", dt=0.01)
    with pytest.raises(native.NativeError, match="not initialised"):
        fresh.set_heading(0.5)
    fresh.step((0, 0, 0), (0, 0, 9.8))
    before = bytes(fresh.state)
    for bad in (float("nan"), float("inf"), 1e5):
        with pytest.raises(native.NativeError, match="out of range"):
            fresh.set_heading(bad)
    with pytest.raises(native.NativeError, match="out of range"):
        fresh.heading_update(0.1, 1.5)
    with pytest.raises(native.NativeError, match="out of range"):
        fresh.heading_update(0.1, float("nan"))
    fresh.heading_update(1.0, 0.5, valid=False)
    assert bytes(fresh.state) == before
    mars = native.Filter("mars", dt=0.01)
    mars.step((0, 0, 0), (0, 0, 9.8), (0, 20, -40))
    with pytest.raises(native.NativeError, match="not supported"):
        mars.heading_update(0.1, 0.1)


@pytest.mark.parametrize(("kind", "settings"), UPDATE_CASES)
def test_external_heading_update_bounds_yaw_drift(kind: str, settings: dict[str, Any]) -> None:
    """A 6-axis filter with a gyro z bias drifts in yaw; a 5 Hz external heading (truth + 1 deg noise) with
    gain 0.3 holds it; C and the reference agree bit for bit."""
    cfg = SimConfig(
        duration=60.0, rate=50.0, seed=4, gyro_bias=0.0, gyro_bias_drift=0.0, initial_attitude=(1, 0, 0, 0)
    )
    rec, _ = simulate_with_truth(cfg)
    gyr = rec.gyr + np.float32([0.0, 0.0, 0.05])  # 2.9 deg/s of drift about the sensor z axis
    w, x, y, z = rec.quat_true.T
    yaw_true = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    noise = np.random.default_rng(0).normal(0, 0.02, len(yaw_true))
    s = native.default_settings(kind, 0.02)
    over = {"bias_mode": 0} if "bias_mode" in s else {}  # no bias estimation: the update holds the drift
    over.update(settings)
    f0 = native.Filter(kind, dt=0.02, **over)
    f1 = native.Filter(kind, dt=0.02, **over)
    ref = RefFilter(kind, dt=0.02, **over)
    err0, err1 = [], []
    for i in range(len(gyr)):
        o0 = f0.step(gyr[i], rec.acc[i])
        o1 = f1.step(gyr[i], rec.acc[i])
        if i < 250:  # the reference alongside for the first updates
            ref.step(gyr[i], rec.acc[i])
        if i % 10 == 0 and i > 0:
            h = float(yaw_true[i] + noise[i])
            f1.heading_update(h, 0.3)
            o1 = f1.output()
            if i < 250:
                ref.heading_update(h, 0.3)
                assert ref.state_diff(0, f1.state) == []
        if i > 1500:
            err0.append(abs(np.angle(np.exp(1j * (float(o0["euler"][2]) - yaw_true[i])))))
            err1.append(abs(np.angle(np.exp(1j * (float(o1["euler"][2]) - yaw_true[i])))))
    e0, e1 = np.degrees(np.mean(err0)), np.degrees(np.mean(err1))
    print(f"{kind}: mean |yaw error| {e0:.2f} deg without, {e1:.2f} deg with the external heading")
    if kinds.info(kind).baseline:  # the gyro baseline: no tilt correction at all, the heading only helps
        assert e1 < 0.8 * e0, (e0, e1)
    elif kinds.info(kind).mag_switch is not None:  # the 6-axis MEKF holds its yaw (z bias) well by itself
        assert e1 < 4.0 and e1 <= e0, (e0, e1)
    else:
        assert e1 < 4.0 and e1 < 0.5 * e0, (e0, e1)
