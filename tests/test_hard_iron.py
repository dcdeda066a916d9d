"""The hard-iron offset estimated on the device (issue 23; att_hardiron.h, mars and mekf, opt-in).

- C and the reference bit for bit (every step, the state at every segment end) for both kinds on streams
  with a hard-iron offset, soft iron and a gyro bias left, with dropped mag rows and invalid gyro rows (the
  keyframe dropped), a magnet passing (the pair gate), and short memories (the decay clamped at 0);
- the estimate finds the offset from rotation (within 0.5 uT of the simulator's truth; 0.2 uT after 30 s)
  and, once the heading has followed the corrected field, the attitude error is that of a sensor without
  hard iron;
- never pulling the attitude while unobservable: with rotation about one axis only the offset stays
  exactly 0 and every output is the one of the estimate off, bit for bit;
- the applied offset moves by at most hard_iron_rate per axis and second;
- att_filter_mag_offset: the offset, whether the estimate runs and whether it was observable,
  ATT_ERR_KIND for the other kinds;
- the node sends it (ATT_MAG_OFFSET after each ATT_DIAG, only while the estimate runs), and the C and
  Python decoders agree with the DBC's scale.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from attica import metrics, native
from attica.can import codec
from attica.crosscheck import Stream, crosscheck
from attica.outputs import MAG_OFFSET_DTYPE
from attica.settings import FilterKind, MarsSettings, MekfSettings
from attica.sim import SimConfig
from attica.sim.engine import simulate_with_truth
from attica.sim.errors import ErrorSizes, mag_only

RATE = 100.0
KINDS: dict[FilterKind, Any] = {FilterKind.MARS: MarsSettings, FilterKind.MEKF: MekfSettings}
HARD = mag_only(hard_iron=20.0, soft_iron_scale=0.0, soft_iron_coupling=0.0)
"""A hard-iron offset of up to 20 uT per axis and nothing else."""
MAGNET = ((30.0, 50.0, (-1.5, 0.25, 0.1), (1.5, 0.25, 0.1), (0.0, 2.0, 2.2)),)  # a magnet passing 25 cm away


def _sim(seed: int, duration: float = 120.0, errors: ErrorSizes = HARD, **kw: Any) -> tuple[Any, np.ndarray]:
    rec, truth = simulate_with_truth(
        SimConfig(duration=duration, rate=RATE, seed=seed, sensor_errors=errors, **kw)
    )
    assert truth.errors is not None
    return rec, np.array(truth.errors.mag.hard_iron)


def _settings(kind: FilterKind, **over: Any) -> Any:
    return replace(KINDS[kind](dt=1.0 / RATE), **over)


def _hi_state(f: native.Filter, kind: FilterKind) -> Any:
    return getattr(f.state.u, kind.label).st.hi


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
@pytest.mark.parametrize(
    "over",
    [
        {"hard_iron_tau": 30.0, "hard_iron_rate": 2.0},
        {
            "hard_iron_tau": 0.2,
            "hard_iron_rate": 1000.0,
        },  # memory shorter than a pair: the decay clamped at 0
        {"hard_iron_tau": 60.0, "mag_norm_reject": 0.0},  # no pair gate
        {"hard_iron_tau": 60.0, "recovery_time": 0.0},  # no recovery: the clip level all the same
    ],
    ids=["defaults-ish", "short-memory", "no-gate", "no-recovery"],
)
def test_bit_exact_with_the_reference(kind: FilterKind, over: dict[str, Any]) -> None:
    gyr_range = float(_settings(kind).gyro_range)
    errors = replace(HARD, gyro_offset=0.01, soft_iron_scale=0.02)
    rec, _ = _sim(1, duration=70.0, errors=errors)
    gyr, mag = rec.gyr.copy(), rec.mag.copy()
    mag[1000:1030] = np.nan  # dropped mag rows
    mag[2000:2200:3] = np.nan  # a slower magnetometer for 2 s
    gyr[3000:3004] = np.nan  # invalid gyro rows: the keyframe is dropped
    mag[4000:4350] = np.nan  # 3.5 s without a mag sample: the keyframe is dropped after 2 s
    gyr[5000:5003] = 0.99 * gyr_range  # a clipping gyro: no pair over it
    magnet, _ = _sim(2, duration=70.0, mag_dipoles=MAGNET)
    streams = [
        Stream(gyr, rec.acc, mag, name="gaps"),
        Stream(magnet.gyr, magnet.acc, magnet.mag, name="magnet"),
    ]
    res = crosscheck(kind, streams, settings=_settings(kind, **over), segment=1500)
    assert res.ok, res.first_mismatch or f"{res.state_mismatches} state mismatches"
    f = native.Filter(kind, _settings(kind, **over))
    f.run_q(gyr, rec.acc, mag)
    # a memory shorter than a pair keeps one pair's information: one axis, never observable (offset 0)
    long_memory = over["hard_iron_tau"] >= 10.0
    assert _hi_state(f, kind).observable == long_memory
    assert f.mag_offset().offset.any() == long_memory


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_offset_is_found_and_the_heading_follows(kind: FilterKind, seed: int) -> None:
    rec, h_true = _sim(seed, duration=180.0)
    scored = np.arange(rec.n) >= int(
        120 * RATE
    )  # the heading has followed the corrected field (mekf: ~100 s)
    errs = {}
    for tau in (0.0, 60.0):
        f = native.Filter(kind, _settings(kind, hard_iron_tau=tau))
        q = f.run_q(rec.gyr, rec.acc, rec.mag)
        errs[tau] = metrics.evaluate(q, rec.quat_true, scored).total
    h, on, est = f.mag_offset()
    assert on and est and np.max(np.abs(h - h_true)) < 0.5, f"offset {h} against the truth {h_true}"
    clean, _ = _sim(seed, duration=180.0, errors=replace(HARD, hard_iron=0.0))
    q_clean = native.Filter(kind, _settings(kind)).run_q(clean.gyr, clean.acc, clean.mag)
    ref = metrics.evaluate(q_clean, clean.quat_true, scored).total
    assert errs[60.0] < ref + 0.5, f"{errs[60.0]:.2f} deg with the estimate, {ref:.2f} without hard iron"
    assert errs[0.0] > errs[60.0] + 1.0, (
        f"without the estimate {errs[0.0]:.2f} deg: the test would not see it"
    )


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
@pytest.mark.parametrize("gyro_range", [1.0, 0.6])
def test_a_clipping_gyro_is_left_out_with_or_without_a_recovery(kind: FilterKind, gyro_range: float) -> None:
    """Pairs over a clipping gyro sample are dropped also with recovery_time 0 (the clip level is 0.98
    gyro_range either way): before, without a recovery the clipped rotation went into the information."""
    rec, h_true = _sim(0)
    gyr = np.clip(rec.gyr, -gyro_range, gyro_range).astype(np.float32)
    assert np.mean(np.any(np.abs(gyr) >= gyro_range, axis=1)) > 0.1
    found = {}
    for rt in (2.0, 0.0):
        f = native.Filter(kind, _settings(kind, hard_iron_tau=60.0, gyro_range=gyro_range, recovery_time=rt))
        f.run_q(gyr, rec.acc, rec.mag)
        found[rt] = f.mag_offset()
    for rt, (h, on, est) in found.items():
        if gyro_range < 0.7:  # half the rows clip: too little rotation left to see the offset
            assert on and not est and not h.any(), f"recovery_time {rt}: {h} from a clipping gyro"
        else:
            assert est and np.max(np.abs(h - h_true)) < 0.5, f"recovery_time {rt}: {h}, truth {h_true}"
    if kind == FilterKind.MARS:  # its estimate does not depend on the attitude: the same bits
        np.testing.assert_array_equal(found[2.0].offset, found[0.0].offset)


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
def test_unobservable_changes_nothing(kind: FilterKind) -> None:
    """Turns about the vertical only: the offset's vertical part is unobservable, nothing is applied."""
    spins = tuple((t, 2.0, 2.0, (0.0, 0.0, 1.0)) for t in range(5, 55, 5))
    rec, _ = _sim(3, duration=60.0, rotation_rms=0.0, translation_rms=0.0, spins=spins)
    on = native.Filter(kind, _settings(kind, hard_iron_tau=60.0))
    off = native.Filter(kind, _settings(kind))
    out_on = on.run(rec.gyr, rec.acc, rec.mag)
    out_off = off.run(rec.gyr, rec.acc, rec.mag)
    st = _hi_state(on, kind)
    assert st.info[0] > 1.0 and st.info[4] > 1.0, "the turns gave no horizontal information"  # xx, yy
    assert not st.observable
    h, running, est = on.mag_offset()
    assert running and not est and not h.any()
    for key in ("q", "flags"):
        np.testing.assert_array_equal(out_on[key], out_off[key], err_msg=key)


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
def test_the_offset_moves_at_the_bounded_rate(kind: FilterKind) -> None:
    rec, _ = _sim(0, duration=60.0)
    rate = 0.5
    f = native.Filter(kind, _settings(kind, hard_iron_tau=60.0, hard_iron_rate=rate))
    offsets = []
    for i in range(0, rec.n, 10):
        f.run(rec.gyr[i : i + 10], rec.acc[i : i + 10], rec.mag[i : i + 10])
        offsets.append(f.mag_offset().offset)
    steps = np.abs(np.diff(np.array(offsets), axis=0))
    assert steps.max() <= rate * 10 / RATE + 1e-5, steps.max()  # 10 steps, each rounded near |offset| ~ 10 uT
    assert steps.max() >= 0.9 * rate * 10 / RATE, "never at the bound: the test would not see it"


def test_mag_offset_api() -> None:
    ars = native.Filter(FilterKind.ARS, 0.01)
    with pytest.raises(native.NativeError, match="not supported"):
        ars.mag_offset()
    f = native.Filter(FilterKind.MARS, _settings(FilterKind.MARS, hard_iron_tau=60.0))
    h, on, est = f.mag_offset()
    assert on and not est and not h.any()
    off = native.Filter(FilterKind.MEKF, _settings(FilterKind.MEKF)).mag_offset()
    assert not off.on and not off.estimated and not off.offset.any()
    assert f.estimates_mag_offset and not ars.estimates_mag_offset
    assert not native.Filter(FilterKind.MEKF, _settings(FilterKind.MEKF)).estimates_mag_offset
    no_mag = _settings(FilterKind.MEKF, hard_iron_tau=60.0, use_mag=False)
    assert not native.Filter(FilterKind.MEKF, no_mag).estimates_mag_offset
    with pytest.raises(native.NativeError):
        native.Filter(FilterKind.MEKF, _settings(FilterKind.MEKF, hard_iron_rate=0.0))


def test_the_node_sends_the_offset() -> None:
    rec, h_true = _sim(1, duration=80.0)
    imu = codec.encode_imu(rec.gyr, rec.acc, rec.mag)
    sent, _ = codec.Node("mars", sample_rate=RATE, hard_iron_tau=60.0).run(imu)
    out = codec.decode_outputs(sent)
    mo = out.mag_offset
    assert len(mo) == len(out.diag) == rec.n // 16 and mo["crc_ok"].all()
    np.testing.assert_array_equal(mo["counter"], out.diag["counter"])  # each after its ATT_DIAG
    assert not mo["estimated"][0] and mo["estimated"][-1]
    assert not mo["offset"][0].any() and np.max(np.abs(mo["offset"][-1] - h_true)) < 0.5, mo["offset"][-1]
    # the C decoder agrees with the Python one, bit for bit
    frames = sent[sent["id"] == codec.ID_MAG_OFFSET]
    h = native.ffi.new("att_mag_offset_t *")
    buf = native.ffi.from_buffer("att_can_frame_t[]", frames)
    for i in range(len(frames)):
        assert native.lib.att_can_decode_mag_offset(buf + i, h)
        got = np.array([h.offset.x, h.offset.y, h.offset.z], np.float32)
        np.testing.assert_array_equal(got.view(np.uint32), mo["offset"][i].view(np.uint32))
        assert h.on and h.estimated == mo["estimated"][i]
    # none without the estimate
    plain, _ = codec.Node("mars", sample_rate=RATE).run(imu)
    assert not (plain["id"] == codec.ID_MAG_OFFSET).any()


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
def test_retune_and_calibrate_restart_the_estimate(kind: FilterKind) -> None:
    """Turned off by a retune: no offset applied, none reported; on again, or a new magnetometer model:
    it starts again from nothing (its keyframe was in another setting or frame). A calibration that
    leaves the magnetometer's stage alone (another output convention, a gyro model) keeps it. C and
    reference bit for bit."""
    from attica.calibration import Calibration, InertialModel, MagModel
    from attica.reference.filter import Filter as RefFilter

    rec, _ = _sim(2, duration=90.0)
    on = _settings(kind, hard_iron_tau=30.0)
    off = _settings(kind)
    c = native.Filter(kind, on)
    ref = RefFilter(kind, on)
    bounds = (0, 4000, 5000, 6500, 7000, 8000, rec.n)
    for j, (a, b) in enumerate(zip(bounds[:-1], bounds[1:])):
        if j == 1:
            assert c.mag_offset().estimated
            c.retune(off)
            ref.retune(off)
            h = c.mag_offset()
            assert not h.on and not h.estimated and not h.offset.any()
        elif j == 2:
            c.retune(on)
            ref.retune(on)
            assert c.mag_offset().on and not c.mag_offset().estimated
        elif j == 3:
            before = c.mag_offset()
            assert before.estimated
            for cal in (
                Calibration(convention="ned"),
                Calibration(gyro=InertialModel(offset=(0.001, 0.0, -0.002))),
                Calibration(),
            ):
                c.calibrate(cal)
                ref.calibrate(cal)
                kept = c.mag_offset()
                assert kept.estimated and np.array_equal(kept.offset, before.offset), cal
        elif j == 4:
            assert c.mag_offset().estimated
            cal = Calibration(mag=MagModel(hard_iron=(0.5, 0.0, 0.0)))
            c.calibrate(cal)
            ref.calibrate(cal)
            assert not c.mag_offset().estimated and not c.mag_offset().offset.any()
        out = c.run(rec.gyr[a:b], rec.acc[a:b], rec.mag[a:b])
        q_ref = np.array([ref.step(rec.gyr[i], rec.acc[i], rec.mag[i])["q"][0] for i in range(a, b)])
        np.testing.assert_array_equal(out["q"].view(np.uint32), q_ref.view(np.uint32), err_msg=f"segment {j}")
        assert ref.state_matches(0, c.state.copy()[0]), ref.state_diff(0, c.state.copy()[0])


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
def test_a_smaller_mag_range_bounds_the_offset_at_once(kind: FilterKind) -> None:
    """A retune to a mag_range below the estimated offset clamps the target and the applied offset to it
    (before, both stayed outside the documented bound until the next solve). C and reference alike."""
    from attica.reference.filter import Filter as RefFilter

    rec, _ = _sim(0, duration=60.0)
    on = _settings(kind, hard_iron_tau=60.0, hard_iron_rate=100.0)
    c = native.Filter(kind, on)
    ref = RefFilter(kind, on)
    n = rec.n
    c.run(rec.gyr, rec.acc, rec.mag)
    for i in range(n):
        ref.step(rec.gyr[i], rec.acc[i], rec.mag[i])
    h = c.mag_offset().offset
    limit = float(np.ceil(np.max(np.abs(h)))) - 4.0
    assert c.mag_offset().estimated and limit > 4.0, h
    small = replace(on, mag_range=limit)
    c.retune(small)
    ref.retune(small)
    st = _hi_state(c, kind)
    for v in (st.offset, st.target):
        assert max(abs(v.x), abs(v.y), abs(v.z)) <= limit
    assert np.max(np.abs(c.mag_offset().offset)) == limit
    assert ref.state_matches(0, c.state.copy()[0]), ref.state_diff(0, c.state.copy()[0])


def test_mekf_without_the_magnetometer_has_no_estimate() -> None:
    f = native.Filter(FilterKind.MEKF, _settings(FilterKind.MEKF, use_mag=False, hard_iron_tau=60.0))
    assert not f.mag_offset().on


def test_the_monitor_shows_the_offset() -> None:
    """`attica monitor` reports the last ATT_MAG_OFFSET and does not take its every-16th-set counter for a
    gap or a repeat."""
    from attica.can.monitor import Monitor

    rec, h_true = _sim(1, duration=80.0)
    sent, _ = codec.Node("mekf", sample_rate=RATE, hard_iron_tau=60.0).run(
        codec.encode_imu(rec.gyr, rec.acc, rec.mag)
    )
    mon = Monitor()
    msgs = [codec.to_message(f) for f in sent]
    for i, m in enumerate(msgs):
        m.timestamp = 1000.0 + i / (10 * RATE)
    lines = [mon.feed(m) for m in msgs]
    assert not any("!DUP" in ln or "!GAP" in ln for ln in lines)
    assert mon.stats.mag_offset is not None
    x, y, z, est = mon.stats.mag_offset
    assert est and np.max(np.abs(np.array([x, y, z]) - h_true)) < 0.5
    assert any("hard-iron offset (ATT_MAG_OFFSET):" in ln and "(estimated)" in ln for ln in mon.summary())


def test_attica_node_set_turns_the_estimate_on(capsys: pytest.CaptureFixture[str]) -> None:
    """`attica node --set hard_iron_tau=60` serves a mars whose init settings estimate the offset: an
    ATT_MAG_OFFSET follows each ATT_DIAG on the bus (no CLI could turn it on before: a review); a value out
    of range or an unknown name is refused before the node starts."""
    import threading
    import time
    import uuid

    from attica.can.bus import open_bus, to_messages
    from attica.cli import main

    assert main(["node", "-c", "x", "--filter", "mars", "--set", "hard_iron_tau=-1"]) == 2
    assert "hard_iron_tau = -1.0 is out of range" in capsys.readouterr().err
    assert main(["node", "-c", "x", "--filter", "ars", "--set", "hard_iron_tau=60"]) == 2
    assert "no setting 'hard_iron_tau'" in capsys.readouterr().err
    ch, n = "t" + uuid.uuid4().hex[:12], 64
    codes: list[int] = []
    argv = ["node", "-c", ch, "--filter", "mars", "--set", "hard_iron_tau=60", "--count", str(n)]
    node = threading.Thread(target=lambda: codes.append(main([*argv, "--idle-timeout", "20"])))
    bus = open_bus("virtual", ch)
    node.start()
    try:
        said = ""
        t0 = time.monotonic()
        while "ready" not in said and time.monotonic() - t0 < 20:  # its bus is open: frames reach it
            time.sleep(0.05)
            said += capsys.readouterr().out
        gyr = np.zeros((n, 3), np.float32)
        acc = np.tile(np.float32([0.0, 0.0, 9.80665]), (n, 1))
        mag = np.tile(np.float32([20.0, 0.0, -40.0]), (n, 1))
        for msg in to_messages(codec.encode_imu(gyr, acc, mag)):
            bus.send(msg)
        ids: list[int] = []
        t0 = time.monotonic()
        while ids.count(codec.ID_MAG_OFFSET) < n // 16 and time.monotonic() - t0 < 20:
            got = bus.recv(0.5)
            if got is not None:
                ids.append(got.arbitration_id)
    finally:
        node.join(30)
        bus.shutdown()
    assert codes == [0]
    assert ids.count(codec.ID_DIAG) == ids.count(codec.ID_MAG_OFFSET) == n // 16


@pytest.mark.parametrize("kind", [FilterKind.MARS, FilterKind.MEKF])
def test_run_records_the_offset_of_every_step(kind: FilterKind) -> None:
    """Filter.run(mag_offset=...) holds after each row what mag_offset() says after stepping to it, with
    rows that advance several periods too (att_host_filter_run's moff, the outputs of `attica run`)."""
    rec, _ = _sim(2, duration=40.0)
    steps = np.ones(rec.n, np.uint32)
    steps[500:520] = 3  # lost samples: each of these rows advances three periods
    f = native.Filter(kind, _settings(kind, hard_iron_tau=60.0))
    mo = np.zeros(rec.n, MAG_OFFSET_DTYPE)
    out = f.run(rec.gyr, rec.acc, rec.mag, steps=steps, mag_offset=mo)
    assert mo["on"].all() and not mo["estimated"][0] and mo["estimated"][-1]
    g = native.Filter(kind, _settings(kind, hard_iron_tau=60.0))
    for i in list(range(0, 600)) + list(range(rec.n - 300, rec.n)):
        if i == rec.n - 300:
            g.run(rec.gyr[600:i], rec.acc[600:i], rec.mag[600:i], steps=steps[600:i])
        row = g.run(rec.gyr[i : i + 1], rec.acc[i : i + 1], rec.mag[i : i + 1], steps=steps[i : i + 1])
        assert row.tobytes() == out[i : i + 1].tobytes()
        h = g.mag_offset()
        assert h.offset.tobytes() == mo["offset"][i].tobytes() and h.estimated == mo["estimated"][i], i
    assert np.unique(mo["offset"], axis=0).shape[0] > 100  # it moves: rows that repeat one would fail
    # the same records with and without the offsets recorded
    plain = native.Filter(kind, _settings(kind, hard_iron_tau=60.0)).run(
        rec.gyr, rec.acc, rec.mag, steps=steps
    )
    assert plain.tobytes() == out.tobytes()


def test_run_mag_offset_refusals() -> None:
    rec, _ = _sim(3, duration=2.0)
    with pytest.raises(native.NativeError, match="not supported"):
        native.Filter(FilterKind.ARS, 1.0 / RATE).run(
            rec.gyr, rec.acc, mag_offset=np.zeros(rec.n, MAG_OFFSET_DTYPE)
        )
    f = native.Filter(FilterKind.MARS, _settings(FilterKind.MARS, hard_iron_tau=60.0))
    for bad in (np.zeros(rec.n - 1, MAG_OFFSET_DTYPE), np.zeros((rec.n, 4), np.float32), [0.0] * rec.n):
        with pytest.raises(ValueError, match="mag_offset must be"):
            f.run(rec.gyr, rec.acc, rec.mag, mag_offset=bad)  # type: ignore[arg-type]
    ro = np.zeros(rec.n, MAG_OFFSET_DTYPE)
    ro.flags.writeable = False
    with pytest.raises(ValueError, match="writeable"):
        f.run(rec.gyr, rec.acc, rec.mag, mag_offset=ro)
    assert f.mag_offset().offset.tobytes() == bytes(12)  # nothing ran


def test_mag_offset_dtype_is_the_c_struct() -> None:
    assert native.ffi.sizeof("att_mag_offset_t") == MAG_OFFSET_DTYPE.itemsize
    for name in ("offset", "on", "estimated"):
        assert native.ffi.offsetof("att_mag_offset_t", name) == MAG_OFFSET_DTYPE.fields[name][1]


def test_verify_compares_the_offset_frames() -> None:
    """compare() (attica verify) checks each ATT_MAG_OFFSET against the estimate after the set it followed:
    a node's frames pass, a changed offset (its CRC sealed again) or a frame from a node whose estimate
    should not run fails, and an offset after a set that did not arrive whole is not checked."""
    from attica.can.compare import compare, expected_outputs
    from attica.can.e2e import data_id, e2e_crc

    rec, _ = _sim(4, duration=60.0)
    imu = codec.encode_imu(rec.gyr, rec.acc, rec.mag)
    sent, _ = codec.Node("mars", sample_rate=RATE, hard_iron_tau=60.0).run(imu)
    gyr, acc, mag = codec.imu_values(rec.gyr, rec.acc, rec.mag)
    on = _settings(FilterKind.MARS, hard_iron_tau=60.0)
    exp = expected_outputs(FilterKind.MARS, RATE, gyr, acc, mag, on)
    rep = compare(exp, FilterKind.MARS, False, sent)
    n_off = int(np.count_nonzero(sent["id"] == codec.ID_MAG_OFFSET))
    assert rep.exact and rep.offsets_ok == n_off == rec.n // 16 and rep.offsets_mismatched == 0
    assert codec.decode_outputs(sent).mag_offset["estimated"].any()  # estimated ones among them
    assert any("ATT_MAG_OFFSET): " + f"{n_off} bit-exact" in line for line in rep.lines())

    bad = sent.copy()
    k = int(np.flatnonzero(bad["id"] == codec.ID_MAG_OFFSET)[-1])
    bad["data"][k, 2] ^= 0x01  # one LSB of off_x (2^-5 uT)
    bad["data"][k, 0] = e2e_crc(data_id(codec.ID_MAG_OFFSET), bytes(bad["data"][k, 1:8]))
    rep = compare(exp, FilterKind.MARS, False, bad)
    assert (
        not rep.exact and rep.offsets_mismatched == 1 and "ATT_MAG_OFFSET after the set" in rep.first_mismatch
    )

    # the set it followed broken (its STATUS lost), or lost whole: the offset is not checked
    before = np.arange(sent.shape[0]) < k
    status = int(np.flatnonzero((sent["id"] == codec.ID_STATUS) & before)[-1])
    quat_a = int(np.flatnonzero((sent["id"] == codec.SET_IDS[0]) & before)[-1])
    # the 16 sets before it lost too: the set 16 earlier carries the same counter, but is not its set
    sixteen = list(range(int(np.flatnonzero((sent["id"] == codec.SET_IDS[0]) & before)[-16]), status + 1))
    sixteen = [i for i in sixteen if int(sent["id"][i]) not in (codec.ID_DIAG, codec.ID_MAG_OFFSET)]
    for gone in ([status], list(range(quat_a, status + 1)), sixteen):
        rep = compare(exp, FilterKind.MARS, False, np.delete(sent, gone))
        assert rep.offsets_unmatched == 1 and rep.offsets_ok == n_off - 1 and rep.offsets_mismatched == 0
        assert rep.offsets_missing == 0

    # an offset lost, or damaged (bad CRC): counted, and the run is not exact
    rep = compare(exp, FilterKind.MARS, False, np.delete(sent, k))
    assert rep.offsets_missing == 1 and rep.offsets_ok == n_off - 1 and not rep.exact
    crc = sent.copy()
    crc["data"][k, 0] ^= 0xFF
    rep = compare(exp, FilterKind.MARS, False, crc)
    assert rep.offsets_corrupted == 1 and rep.offsets_missing == 0 and not rep.exact

    # a node without the estimate against a reference with it: the offsets are missing, not unchecked
    plain, _ = codec.Node("mars", sample_rate=RATE).run(imu[: 16 * 30 * 3])
    short = expected_outputs(FilterKind.MARS, RATE, gyr[: 16 * 30], acc[: 16 * 30], mag[: 16 * 30], on)
    rep = compare(short, FilterKind.MARS, False, plain)
    assert rep.offsets_missing == 30 and not rep.exact

    off = expected_outputs(FilterKind.MARS, RATE, gyr, acc, mag, _settings(FilterKind.MARS))
    rep = compare(off, FilterKind.MARS, False, sent)
    assert off.mag_offset is None and rep.offsets_unexpected == n_off and not rep.exact
    assert "give the settings it was started with" in rep.first_mismatch


def test_attica_verify_set_checks_the_offsets(capsys: pytest.CaptureFixture[str], tmp_path: Any) -> None:
    """attica verify --set: the node's init settings, for the reference and the --with-node node (live)
    and for a log; a node sending ATT_MAG_OFFSET verifies bit-exact only when told its settings."""
    from attica.cli import main

    log = tmp_path / "hi.log"
    argv = ["verify", "--with-node", "--filter", "mars", "--duration", "20", "-q"]
    assert main([*argv, "--set", "hard_iron_tau=60", "--write", str(log)]) == 0
    out = capsys.readouterr().out
    n = int(out.split("hard-iron offsets (ATT_MAG_OFFSET): ")[1].split()[0])
    assert n == round(20 * 285.714) // 16 and "verdict: BIT-EXACT" in out
    assert main(["verify", "--log", str(log), "--filter", "mars", "--set", "hard_iron_tau=60"]) == 0
    assert f"ATT_MAG_OFFSET): {n} bit-exact" in capsys.readouterr().out
    assert main(["verify", "--log", str(log), "--filter", "mars"]) == 1  # not told: the sets differ too
    assert "verdict: FAILED" in capsys.readouterr().out


def test_attica_run_chunks_keep_the_offsets(monkeypatch: pytest.MonkeyPatch) -> None:
    """attica run steps in chunks (its progress bar): the per-row offsets are the same in any chunking."""
    from attica.commands import run as run_cmd
    from attica.sim import simulate

    rec = simulate(SimConfig(duration=30.0, rate=RATE, seed=6, sensor_errors=HARD))
    s = _settings(FilterKind.MEKF, hard_iron_tau=60.0)
    whole: dict[str, Any] = {}
    out = run_cmd.run_native(FilterKind.MEKF, rec, s, False, None, whole)
    monkeypatch.setattr(run_cmd, "CHUNK", 777)
    parts: dict[str, Any] = {}
    out2 = run_cmd.run_native(FilterKind.MEKF, rec, s, False, None, parts)
    assert out.tobytes() == out2.tobytes() and whole["mag_offset"].tobytes() == parts["mag_offset"].tobytes()
    assert whole["mag_offset"]["estimated"][-1]
