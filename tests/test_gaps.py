"""Time in recordings (issue 24): steps over lost samples, C and reference alike; time columns read."""

from __future__ import annotations

import glob
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from attica import native
from attica.data import load_recording
from attica.data import timing as tm
from attica.data.recording import Recording
from attica.metrics import evaluate
from attica.reference.filter import Filter as RefFilter
from attica.settings import Flag

KINDS = ("ars", "mars", "kf", "ekf", "gyro", "tilt", "mekf")
BROAD = sorted(glob.glob(str(Path(__file__).resolve().parents[1].parent / "shared/data/broad/*.npz")))


def _bits(a: np.ndarray) -> np.ndarray:
    return a.view(np.uint32) if a.dtype.kind == "f" else a


@pytest.fixture(scope="module")
def stream() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(5)
    n = 300
    t = np.arange(n) * 0.01
    gyr = np.column_stack([0.6 * np.sin(t), 0.4 * np.cos(1.3 * t), 0.2 + 0.0 * t]).astype(np.float32)
    gyr += rng.normal(0, 0.01, gyr.shape).astype(np.float32)
    acc = (np.array([0.3, -0.2, 9.8]) + rng.normal(0, 0.05, (n, 3))).astype(np.float32)
    mag = (np.array([18.0, 2.0, -42.0]) + rng.normal(0, 0.3, (n, 3))).astype(np.float32)
    mag[1::3] = np.nan  # a slower magnetometer
    steps = np.ones(n, np.uint32)
    steps[[7, 40, 41, 150, 299]] = [2, 4, 15, 3, 7]
    return gyr, acc, mag, steps


@pytest.mark.parametrize("kind", KINDS)
def test_steps_bit_exact_c_and_reference(kind: str, stream: tuple[np.ndarray, ...]) -> None:
    gyr, acc, mag, steps = stream
    out = native.Filter(kind, 0.01).run(gyr, acc, mag, steps=steps)
    ref = RefFilter(kind, 0.01).run(gyr, acc, mag, steps=steps)
    for name in ("q", "euler", "gyro_bias", "cov", "flags", "steps"):
        assert np.array_equal(_bits(out[name]), _bits(ref[name])), (kind, name)
    assert int(out["steps"][-1]) == int(steps.sum())
    q = native.Filter(kind, 0.01).run_q(gyr, acc, mag, steps=steps)
    assert np.array_equal(q.view(np.uint32), out["q"].view(np.uint32))


def _field_bytes(ptr: Any) -> bytes:
    """Every field of a C struct, bit for bit, without its padding (which no step writes: a copy of the
    struct may carry anything there, as at -O0)."""
    ffi = native.ffi
    out = bytearray()

    def walk(tp: Any, off: int) -> None:
        kind = tp.kind
        if kind == "struct" or kind == "union":
            for _, f in tp.fields:
                walk(f.type, off + f.offset)
        elif kind == "array":
            for k in range(tp.length):
                walk(tp.item, off + k * ffi.sizeof(tp.item))
        else:
            out.extend(ffi.buffer(ptr)[off : off + ffi.sizeof(tp)])

    walk(ffi.typeof(ptr).item, 0)
    return bytes(out)


@pytest.mark.parametrize("kind", ["mars", "ekf"])
def test_step_n_is_n_steps_on_the_held_sample(kind: str, stream: tuple[np.ndarray, ...]) -> None:
    gyr, acc, mag, _ = stream
    a = native.Filter(kind, 0.01)
    b = native.Filter(kind, 0.01)
    a.run(gyr[:20], acc[:20], mag[:20])
    b.run(gyr[:20], acc[:20], mag[:20])
    rec = a.step(gyr[20], acc[20], mag[20], n=5)
    flags = 0
    for _ in range(5):
        last = b.step(gyr[20], acc[20], mag[20])
        flags |= int(last["flags"])
    assert _field_bytes(a.state.ptr) == _field_bytes(b.state.ptr)
    assert int(rec["flags"]) == flags
    assert np.array_equal(rec["q"].view(np.uint32), last["q"].view(np.uint32))


def test_step_n_bounds() -> None:
    f = native.Filter("ars", 0.01)
    with pytest.raises(ValueError, match="n must be"):
        f.step([0, 0, 0], [0, 0, 9.8], n=0)
    with pytest.raises(ValueError, match="steps must be in 1"):
        f.run(np.zeros((2, 3)), np.tile([0, 0, 9.8], (2, 1)), steps=[1, 0])
    with pytest.raises(ValueError, match="shape"):
        f.run(np.zeros((2, 3)), np.tile([0, 0, 9.8], (2, 1)), steps=[1, 1, 1])
    # beyond the C limit: clamped and flagged
    before = int(f.output()["steps"])
    rec = f.step([0, 0, 0], [0, 0, 9.8], n=native.lib.ATT_FILTER_STEP_N_MAX + 5)
    assert int(rec["flags"]) & Flag.CLAMPED
    assert int(rec["steps"]) == before + native.lib.ATT_FILTER_STEP_N_MAX


@pytest.mark.parametrize("kind", KINDS)
def test_update_is_the_lean_step(kind: str, stream: tuple[np.ndarray, ...]) -> None:
    gyr, acc, mag, steps = stream
    a = native.Filter(kind, 0.01)
    q = native.Filter(kind, 0.01).run_q(gyr[:60], acc[:60], mag[:60], steps=steps[:60])
    fl = native.Filter(kind, 0.01).run(gyr[:60], acc[:60], mag[:60], steps=steps[:60], full=False)["flags"]
    for i in range(60):
        m = None if np.isnan(mag[i, 0]) else mag[i].astype(np.float64)
        got = a.update(gyr[i].astype(np.float64), acc[i].tolist(), m, n=int(steps[i]))
        assert got == int(fl[i])
        assert np.array_equal(a.quat.view(np.uint32), q[i].view(np.uint32))


def test_step_records_are_independent() -> None:
    f = native.Filter("ars", 0.01)
    recs = [f.step([0.1 * i, 0, 0], [0, 0, 9.8]) for i in range(300)]
    assert len({int(r["steps"]) for r in recs}) == 300  # no record overwritten by a later step


def test_retune_dt() -> None:
    """``Filter.retune(dt=...)`` raised TypeError (make_settings got dt twice)."""
    for kind in ("ars", "mekf"):
        f = native.Filter(kind, 0.01)
        f.retune(dt=0.005)
        assert f.settings.dt == 0.005
        r = RefFilter(kind, 0.01)
        r.retune(dt=0.005)
        g = np.tile(np.float32([0.1, 0.2, 0.3]), (30, 1))
        a = np.tile(np.float32([0, 0, 9.8]), (30, 1))
        assert np.array_equal(f.run(g, a)["q"].view(np.uint32), r.run(g, a)["q"].view(np.uint32))
    with pytest.raises(ValueError, match="dt must be"):
        native.Filter("ars", 0.01).retune(dt=-1.0)


@pytest.mark.skipif(not BROAD, reason="../shared/data/broad not found")
def test_dropped_rows_are_integrated() -> None:
    """113 dropped rows: within 10 % of the no-drop error (ignoring the gaps costs far more)."""
    rec = load_recording(next(p for p in BROAD if "01_undisturbed_slow_rotation_A" in p))
    rng = np.random.default_rng(11)
    keep = np.ones(rec.n, bool)
    keep[rng.choice(np.arange(1, rec.n), 113, replace=False)] = False
    idx = np.flatnonzero(keep)
    steps = np.ones(idx.size, np.uint32)
    steps[1:] = np.diff(idx)
    assert rec.quat_true is not None and rec.movement is not None
    for kind in ("mars", "mekf", "ars"):

        def err(sel: object, st: object, k: str = kind) -> float:
            f = native.Filter(k, rec.dt)
            q = f.run_q(rec.gyr[sel], rec.acc[sel], rec.mag[sel], steps=st, check_units=False)
            e = evaluate(q.astype(np.float64), rec.quat_true[sel], rec.movement[sel])
            return e.total if k != "ars" else e.inclination

        full, ignored, integrated = err(slice(None), None), err(keep, None), err(keep, steps)
        assert integrated <= 1.10 * full, (kind, full, integrated)
        assert ignored > 1.15 * full, (kind, full, ignored)


# --- time columns ---------------------------------------------------------------------------------


def _csv(path: Path, tname: str, t: np.ndarray, n_mag_every: int = 1, header: str = "") -> None:
    rng = np.random.default_rng(0)
    rows = [f"{tname},gyr_x,gyr_y,gyr_z,acc_x,acc_y,acc_z,mag_x,mag_y,mag_z"]
    for i, ti in enumerate(t):
        g = rng.normal(0, 0.01, 3)
        mag = "20,0,-40" if i % n_mag_every == 0 else ",,"
        rows.append(f"{float(ti)!r},{g[0]},{g[1]},{g[2]},0,0,9.81,{mag}")
    path.write_text(header + "\n".join(rows) + "\n")


@pytest.mark.parametrize(
    ("tname", "scale", "guessed"),
    [
        ("t", 1.0, False),
        ("t", 1e9, True),
        ("time_ns", 1e9, False),
        ("timestamp [ms]", 1e3, False),
        ("t", 1e6, True),
    ],
)
def test_time_units(tmp_path: Path, tname: str, scale: float, guessed: bool) -> None:
    t = 1.7e9 + np.arange(400) / 200.0
    t = np.delete(t, [50, 51, 52, 300])
    _csv(tmp_path / "r.csv", tname, np.round(t * scale, 3) if scale > 1 else t)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        rec = load_recording(tmp_path / "r.csv")
    msgs = [str(x.message) for x in w if issubclass(x.category, tm.TimingWarning)]
    assert rec.rate == pytest.approx(200.0, rel=1e-6)
    assert rec.timing is not None and rec.timing.unit_guessed == guessed
    assert rec.lost == 4 and rec.steps[50] == 4 and rec.steps[297] == 2
    assert any("4 sample(s) lost in 2 gap(s)" in m for m in msgs)
    assert any("unit not stated" in m for m in msgs) == guessed


def test_duplicates_and_backwards_dropped(tmp_path: Path) -> None:
    t = np.arange(100) / 100.0
    t = np.concatenate([t[:10], t[9:10], t[10:20], [0.15], t[20:]])  # a repeat, then one out of order
    _csv(tmp_path / "r.csv", "t", t)
    with pytest.warns(tm.TimingWarning) as w:
        rec = load_recording(tmp_path / "r.csv")
    assert rec.n == 100 and rec.lost == 0
    assert rec.timing is not None and (rec.timing.duplicates, rec.timing.backwards) == (1, 1)
    text = " ".join(str(x.message) for x in w)
    assert "1 row(s) with a repeated time dropped (first: row 10)" in text
    assert "1 row(s) with a time before the previous row's dropped" in text


def test_unit_that_cannot_be_told(tmp_path: Path) -> None:
    _csv(tmp_path / "r.csv", "t", np.arange(50) * 1e12)
    with pytest.raises(ValueError, match="cannot tell the time unit"):
        load_recording(tmp_path / "r.csv")
    _csv(tmp_path / "s.csv", "t", np.arange(50) * 1e12, header="# time_unit=us\n")
    assert load_recording(tmp_path / "s.csv").rate == pytest.approx(1e6 / 1e12)


def test_clock_alignment_rules() -> None:
    base = np.arange(10) * 0.01
    t_mag = np.array([0.0, 0.005, 0.012, 0.0125, 0.05, 0.2])
    placed, superseded = tm.place_on(base, t_mag, np.arange(6.0)[:, None])
    assert placed[0, 0] == 0.0 and placed[1, 0] == 1.0 and placed[2, 0] == 3.0 and placed[5, 0] == 4.0
    assert np.isnan(placed[[3, 4, 6, 7, 8, 9], 0]).all()
    assert superseded == 2  # 2 replaced by 3 on row 2; 5 after the last gyro time
    held, first = tm.hold_on(base, np.array([0.015, 0.04]), np.array([[1.0], [2.0]]))
    assert first == 2 and np.isnan(held[:2, 0]).all() and held[2:4, 0].tolist() == [1.0, 1.0]
    assert held[4:, 0].tolist() == [2.0] * 6


def test_recording_time_round_trip(tmp_path: Path) -> None:
    t = 100.0 + np.delete(np.arange(50), [10, 20, 21]) / 50.0
    n = t.size
    rec = Recording(np.zeros((n, 3)), np.tile([0, 0, 9.8], (n, 1)), None, 50.0, time=t)
    assert rec.lost == 3 and rec.t[0] == 0.0
    for suffix in (".npz", ".csv"):
        rec.save(tmp_path / f"r{suffix}")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", tm.TimingWarning)
            back = load_recording(tmp_path / f"r{suffix}")
        assert back.time is not None and np.allclose(back.time, t, rtol=0, atol=1e-9)
        assert np.array_equal(back.steps, rec.steps)
    with pytest.raises(ValueError, match="strictly increasing"):
        Recording(np.zeros((3, 3)), np.zeros((3, 3)), None, 50.0, time=[0.0, 0.0, 1.0])


def test_run_reports_and_integrates_gaps(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from attica.cli import main

    t = np.delete(np.arange(600) / 100.0, [100, 101, 400])
    _csv(tmp_path / "r.csv", "t", t)
    out = str(tmp_path / "o.npz")
    assert main(["run", "--filter", "ars", "--data", str(tmp_path / "r.csv"), "-q", "-o", out]) == 0
    captured = capsys.readouterr()
    assert "attica: warning: r.csv t: 3 sample(s) lost in 2 gap(s)" in captured.err
    text = captured.out
    assert "2 gap(s) with 3 sample(s) lost" in text
    with np.load(tmp_path / "o.npz") as d:
        assert int(d["steps"][-1]) == 600  # the lost periods were stepped


def test_recordings_doc_time_block_runs() -> None:
    import re

    text = (Path(__file__).resolve().parents[1] / "docs" / "recordings.md").read_text()
    part = text.split("## Time in recordings", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", part, re.S)
    assert blocks
    ns: dict[str, object] = {}
    for block in blocks:
        exec(compile(block, "docs/recordings.md", "exec"), ns)
    assert ns["lossy"].lost == 60  # type: ignore[attr-defined]


def test_update_inputs_and_errors() -> None:
    import gc

    from attica import _live  # built beside attica._native: the path Filter.update takes

    assert _live is not None
    f = native.Filter("mars", 0.01)
    ref = native.Filter("mars", 0.01)
    rows = [
        (np.float32([0.1, -0.2, 0.3]), np.float32([0.5, 0.1, 9.7]), np.float32([20, 1, -40])),
        ([1, 0, 0], (0, 0, 10), None),  # ints, tuples, no mag
        (np.array([1e300, 0, 0]), [0.0, 0.0, 9.8], [20.0, 0.0, -40.0]),  # beyond float32: Inf, as numpy
        (np.array([0.1, 0.2, 0.3])[::-1].copy(), np.array([0.0, 0.0, 9.8]), np.array([np.nan] * 3)),
    ]
    for g, a, m in rows:
        flags = f.update(g, a, m)
        rec = ref.step(g, a, m, full=False)
        assert flags == int(rec["flags"])
        assert np.array_equal(f.quat.view(np.uint32), rec["q"].view(np.uint32))
    with pytest.raises(ValueError, match="gyr must have 3 components"):
        f.update([1, 2], [0, 0, 9.8])
    with pytest.raises(TypeError, match="acc must hold real numbers"):
        f.update([0, 0, 0], "abc")
    with pytest.raises(TypeError, match="real numbers"):
        f.update([True, 0, 0], [0, 0, 9.8])
    for bad in (0, -1, True, 2**40, 1.5):
        with pytest.raises(ValueError, match="n must be"):
            f.update([0, 0, 0], [0, 0, 9.8], None, bad)
    # a bound update keeps its filter alive
    u = native.Filter("ars", 0.01).update
    gc.collect()
    assert u([0, 0, 0], [0, 0, 9.8]) & Flag.NOT_READY == 0


def test_resample_unclocked_log(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from attica.cli import main
    from attica.data.resample import resample

    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.002, 0.018, 800))  # a phone-like clock: jitter of many periods
    n = t.size
    gyr = np.column_stack([np.sin(t), np.cos(t), 0 * t])
    mag = np.full((n, 3), np.nan)
    mag[::5] = [20.0, 0.0, -40.0]
    rec = Recording(gyr, np.tile([0, 0, 9.8], (n, 1)), mag, 100.0, time=t, movement=np.ones(n, bool))
    r = resample(rec, 100.0)
    assert np.allclose(np.diff(r.time), 0.01) and r.lost == 0 and r.time[0] == t[0]
    k = 37
    assert r.gyr[k, 0] == pytest.approx(np.interp(r.time[k], t, gyr[:, 0]), abs=1e-6)
    assert np.isfinite(r.mag).all(axis=1).sum() <= np.isfinite(mag).all(axis=1).sum()  # placed, never made up
    assert r.timing is not None and "linear interpolation" in r.timing.source
    rec.save(tmp_path / "p.csv")
    assert main(["run", "--filter", "ars", "--data", str(tmp_path / "p.csv"), "--resample", "100", "-q"]) == 0
    assert "resampled to 100 Hz" in capsys.readouterr().out
    assert main(["run", "--filter", "ars", "--data", str(tmp_path / "p.csv"), "--resample", "-1", "-q"]) == 2


def test_eval_steps_attica_and_peers_over_gaps() -> None:
    pytest.importorskip("vqf")
    import attica
    from attica.evaluate.core import AtticaRun
    from attica.peers import peer_by_name
    from attica.settings import FilterKind, Preset

    sim = attica.simulate(attica.SimConfig(duration=20.0, rate=100.0, seed=9))
    keep = np.ones(sim.n, bool)
    keep[np.random.default_rng(2).choice(np.arange(1, sim.n), 40, replace=False)] = False
    rec = Recording(
        sim.gyr[keep], sim.acc[keep], sim.mag[keep], sim.rate, sim.quat_true[keep], time=sim.t[keep]
    )
    est = AtticaRun(FilterKind.parse("mars"), Preset.DEFAULT, {}).estimate(rec)
    q = native.Filter("mars", rec.dt).run_q(rec.gyr, rec.acc, rec.mag, steps=rec.steps)
    assert np.array_equal(est.q, q.astype(np.float64))
    peer = peer_by_name("vqf9")
    got = peer.estimate(rec)
    assert got.q.shape == (rec.n, 4) and any("40 lost sample(s)" in n for n in got.notes)
    # VQF's own note counts the rows it was given (the 40 held ones have no mag sample): said so
    assert f"on the {sim.n} rows given, samples held: 40 of {sim.n} rows without a mag sample" in got.notes[0]
    whole = peer.estimate(Recording(sim.gyr, sim.acc, sim.mag, sim.rate))
    # with the samples held, the peer stays near its no-loss estimate (no drift from skipped rotation)
    dots = np.abs(np.sum(got.q * whole.q[keep], axis=1))
    assert np.degrees(2 * np.arccos(np.clip(dots.min(), -1, 1))) < 2.0
