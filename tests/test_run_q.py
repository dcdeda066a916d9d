"""The lean batch path ``Filter.run_q``: bit for bit the q and flags of ``Filter.run`` and of the numpy
reference (every kind, bad rows, mag absent, an output convention), the same state afterwards, and the
misuses it refuses. Also ``run``'s snapshot loop (a separate chunked loop in att_host.c)."""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import pytest

import attica
from attica import kinds, native
from attica.calibration import Calibration
from attica.native import ffi
from attica.reference.filter import Filter as RefFilter
from attica.sim import SimConfig, simulate

from helpers import assert_same_bits

RATE = 100.0
KINDS = kinds.labels()


def _inputs(steps: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Simulated motion with bad rows: NaN / Inf / saturated gyro, NaN / zero / huge accel, absent and
    NaN mag samples, a run of bad rows before the first valid sample."""
    rec = simulate(SimConfig(duration=steps / RATE, rate=RATE, seed=seed))
    g, a, m = (np.array(x[:steps], np.float32) for x in (rec.gyr, rec.acc, rec.mag))
    rng = np.random.default_rng(seed)
    a[:3] = np.nan  # nothing valid yet: NOT_READY
    g[:2, 1] = np.inf
    rows = rng.choice(np.arange(5, steps), size=steps // 40, replace=False)
    for j, r in enumerate(rows):
        which = j % 7
        if which == 0:
            g[r, j % 3] = np.nan
        elif which == 1:
            g[r] = 1e6  # beyond any gyro range
        elif which == 2:
            a[r] = 0.0
        elif which == 3:
            a[r, 2] = np.inf
        elif which == 4:
            a[r] *= 50.0  # rejected or saturated
        elif which == 5:
            m[r] = np.nan  # no mag sample
        else:
            m[r] = 0.0  # no mag sample
    return g, a, m


def _leaves(t: Any, offset: int = 0) -> list[tuple[int, int]]:
    """(offset, size) of every scalar field of a cffi struct / array type, recursively: the padding is
    left out (it holds whatever a struct copy left there)."""
    if t.kind == "struct":
        return [leaf for _, fld in t.fields for leaf in _leaves(fld.type, offset + fld.offset)]
    if t.kind == "array":
        size = ffi.sizeof(t.item)
        return [leaf for i in range(t.length) for leaf in _leaves(t.item, offset + i * size)]
    return [(offset, ffi.sizeof(t))]


def _state_bytes(f: native.Filter) -> list[bytes]:
    """The live part of the C state, field by field: kind, the kind's union member, calibration stages."""
    raw = bytes(f.state)
    ft = ffi.typeof("att_filter_t")
    fields = dict(ft.fields)
    u = fields["u"].offset
    member = dict(fields["u"].type.fields)[f.kind.label]
    leaves = [(fields["kind"].offset, ffi.sizeof("att_filter_kind_t"))]
    leaves += _leaves(member.type, u + member.offset) + _leaves(fields["cal"].type, fields["cal"].offset)
    return [raw[o : o + n] for o, n in leaves]


@pytest.mark.parametrize("with_mag", [True, False], ids=["mag", "no-mag"])
@pytest.mark.parametrize("kind", KINDS)
def test_run_q_is_run_bit_for_bit(kind: str, with_mag: bool) -> None:
    g, a, m = _inputs(3000, 11 + KINDS.index(kind))
    mag = m if with_mag else None
    full = native.Filter(kind, dt=1 / RATE)
    rec = full.run(g, a, mag)
    lean = native.Filter(kind, dt=1 / RATE)
    q, fl = lean.run_q(g, a, mag, flags=True)
    assert q.dtype == np.float32 and q.shape == (g.shape[0], 4) and q.flags.c_contiguous
    assert fl.dtype == np.uint32 and fl.shape == (g.shape[0],)
    assert_same_bits(q, rec["q"], f"{kind} q")
    assert q.view(np.uint32).tobytes() == np.ascontiguousarray(rec["q"]).view(np.uint32).tobytes()
    assert (fl == rec["flags"]).all()
    assert _state_bytes(lean) == _state_bytes(full)  # the same state afterwards
    # the inputs exercised what they should: bad rows flagged, the start not ready
    # a kind that reads the accel waits for a valid one; the gyro baseline starts level
    assert "acc" not in kinds.info(kind).sensors or fl[0] & attica.Flag.NOT_READY
    assert (fl & (attica.Flag.GYRO_INVALID | attica.Flag.ACCEL_INVALID)).any()
    # q only, and the per-step record path (full=False), agree too
    q_only = native.Filter(kind, dt=1 / RATE).run_q(g, a, mag)
    assert q_only.tobytes() == q.tobytes()
    if kinds.info(kind).q_state:  # an Euler-angle state (EKF) is what a step reports; q comes on request
        cheap = native.Filter(kind, dt=1 / RATE).run(g, a, mag, full=False)
        assert_same_bits(q, cheap["q"], f"{kind} q vs full=False")


@pytest.mark.parametrize("kind", KINDS)
def test_run_q_against_the_reference(kind: str) -> None:
    g, a, m = _inputs(300, 40 + KINDS.index(kind))
    for mag in (m, None):
        want = RefFilter(kind, dt=1 / RATE).run(g, a, mag)
        q, fl = native.Filter(kind, dt=1 / RATE).run_q(g, a, mag, flags=True)
        assert_same_bits(q, want["q"], f"{kind} q (mag {'given' if mag is not None else 'None'})")
        assert (fl == want["flags"]).all()


@pytest.mark.parametrize("kind", KINDS)
def test_run_q_in_an_output_convention(kind: str) -> None:
    g, a, m = _inputs(1000, 70 + KINDS.index(kind))
    cal = Calibration(convention="ned")
    rec = native.Filter(kind, dt=1 / RATE, calibration=cal).run(g, a, m)
    q = native.Filter(kind, dt=1 / RATE, calibration=cal).run_q(g, a, m)
    assert_same_bits(q, rec["q"], f"{kind} q (NED)")
    enu = native.Filter(kind, dt=1 / RATE).run_q(g, a, m)
    assert not np.array_equal(q, enu)  # the convention is applied, not ignored


def test_run_q_chunks_and_out_buffer() -> None:
    g, a, m = _inputs(2000, 3)
    whole = native.Filter("mars", dt=1 / RATE).run_q(g, a, m)
    f = native.Filter("mars", dt=1 / RATE)
    buf = np.full((500, 4), np.nan, np.float32)
    parts = []
    for i in range(0, 2000, 500):
        got = f.run_q(g[i : i + 500], a[i : i + 500], m[i : i + 500], out=buf)
        assert got is buf
        parts.append(buf.copy())
    assert np.concatenate(parts).tobytes() == whole.tobytes()
    # the state continues across calls and across run / run_q
    f2 = native.Filter("mars", dt=1 / RATE)
    f2.run(g[:700], a[:700], m[:700])
    assert f2.run_q(g[700:], a[700:], m[700:]).tobytes() == whole[700:].tobytes()


def test_run_q_converts_other_dtypes_and_layouts() -> None:
    g, a, m = _inputs(400, 5)
    want = native.Filter("ars", dt=1 / RATE).run_q(g, a, m)
    g64 = g.astype(np.float64)
    a_f = np.asfortranarray(a)
    m_strided = np.repeat(m, 2, axis=0)[::2]
    assert not m_strided.flags.c_contiguous
    got = native.Filter("ars", dt=1 / RATE).run_q(g64, a_f, m_strided)
    assert got.tobytes() == want.tobytes()
    ints = np.zeros((10, 3), np.int16)
    ints[:, 2] = 10
    q = native.Filter("ars", dt=1 / RATE).run_q(ints, ints, check_units=False)
    assert q.shape == (10, 4) and np.isfinite(q).all()
    assert native.Filter("ars", dt=1 / RATE).run_q(g[:0], a[:0]).shape == (0, 4)


def _bad_calls() -> list[tuple[str, dict[str, Any], type[Exception], str]]:
    g = np.zeros((8, 3), np.float32)
    return [
        ("gyr (8, 2)", {"gyr": g[:, :2]}, ValueError, r"shape \(N, 3\).*gyr \(8, 2\)"),
        ("acc shorter", {"acc": g[:5]}, ValueError, r"the same N.*acc \(5, 3\)"),
        ("mag longer", {"mag": np.zeros((9, 3), np.float32)}, ValueError, r"mag \(9, 3\)"),
        ("gyr 1-D", {"gyr": g[0]}, ValueError, r"gyr \(3,\)"),
        ("gyr 3-D", {"gyr": g[None]}, ValueError, r"gyr \(1, 8, 3\)"),
        ("complex acc", {"acc": g.astype(np.complex64)}, TypeError, "acc must hold real numbers.*complex64"),
        ("bool gyr", {"gyr": g.astype(bool)}, TypeError, "gyr must hold real numbers.*bool"),
        ("text mag", {"mag": np.full((8, 3), "1")}, TypeError, "mag must hold real numbers"),
        ("object gyr", {"gyr": np.array([None] * 24).reshape(8, 3)}, TypeError, "dtype object"),
        ("acc None", {"acc": None}, TypeError, "acc is required"),
        ("out float64", {"out": np.zeros((8, 4))}, TypeError, "out must be a float32 numpy array.*float64"),
        ("out a list", {"out": [[0.0] * 4] * 8}, TypeError, "got list"),
        ("out (8, 3)", {"out": np.zeros((8, 3), np.float32)}, ValueError, r"shape \(8, 4\), got \(8, 3\)"),
        ("out strided", {"out": np.zeros((8, 8), np.float32)[:, ::2]}, ValueError, "C-contiguous"),
        ("out read-only", {"out": np.zeros((8, 4), np.float32)}, ValueError, "writable"),
    ]


@pytest.mark.parametrize("case", _bad_calls(), ids=lambda c: c[0])
def test_run_q_refuses_bad_arguments(case: tuple[str, dict[str, Any], type[Exception], str]) -> None:
    name, changes, exc, match = case
    z = np.zeros((8, 3), np.float32)
    z[:, 2] = 9.81
    args: dict[str, Any] = {"gyr": z * 0, "acc": z.copy(), "mag": z * 4, **changes}
    if name == "out read-only":
        args["out"].flags.writeable = False
    f = native.Filter("mars", dt=1 / RATE)
    before = _state_bytes(f)
    with pytest.raises(exc, match=match):
        f.run_q(args["gyr"], args["acc"], args["mag"], out=args.get("out"))
    assert _state_bytes(f) == before  # refused before any step
    if "out" not in changes:  # run checks its inputs the same way
        with pytest.raises(exc, match=match):
            f.run(args["gyr"], args["acc"], args["mag"])


def test_run_q_refuses_out_overlapping_an_input() -> None:
    block = np.zeros(8 * 3 + 8 * 4, np.float32)
    acc = block[:24].reshape(8, 3)  # float32, C-contiguous: read in place
    acc[:, 2] = 9.81
    with pytest.raises(ValueError, match="overlaps an input"):
        native.Filter("ars", dt=1 / RATE).run_q(
            np.zeros((8, 3), np.float32), acc, out=block[:32].reshape(8, 4)
        )
    q = native.Filter("ars", dt=1 / RATE).run_q(
        np.zeros((8, 3), np.float32), acc, out=block[24:].reshape(8, 4)
    )
    assert np.shares_memory(q, block) and (acc[:, 2] == np.float32(9.81)).all()


def test_run_q_warns_about_units() -> None:
    g, a, m = _inputs(2000, 9)
    with pytest.warns(attica.UnitWarning, match=r"ars Filter.run_q: .*looks like deg/s"):
        native.Filter("ars", dt=1 / RATE).run_q(np.degrees(g) * 10, a, m)
    with pytest.warns(attica.UnitWarning, match="looks like g"):
        native.Filter("ars", dt=1 / RATE).run_q(g, a / 9.80665)
    with warnings.catch_warnings():
        warnings.simplefilter("error", attica.UnitWarning)
        native.Filter("ars", dt=1 / RATE).run_q(g, a / 9.80665, check_units=False)
        native.Filter("ars", dt=1 / RATE).run_q(g, a, m)  # the right units: silent


@pytest.mark.parametrize("every", [1, 7, 500, 2000, 5000])
def test_run_snapshots_from_the_chunked_loop(every: int) -> None:
    """run(snapshot_every=k): the records of a plain run, and snapshot j is the state before step j*k."""
    g, a, m = _inputs(2000, 21)
    plain = native.Filter("mekf", dt=1 / RATE).run(g, a, m)
    f = native.Filter("mekf", dt=1 / RATE)
    rec, snaps = f.run(g, a, m, snapshot_every=every)
    assert rec.tobytes() == plain.tobytes()
    count = -(-2000 // every)
    assert len(snaps) == count
    probe = native.Filter("mekf", dt=1 / RATE)
    for j in sorted({0, 1, count // 2, count - 1} & set(range(count))):
        probe.state[0] = snaps[j]  # a whole att_filter_t copied in
        want = native.Filter("mekf", dt=1 / RATE)
        if j:
            want.run(g[: j * every], a[: j * every], m[: j * every])
        assert _state_bytes(probe) == _state_bytes(want), f"snapshot {j}"
        tail = probe.run_q(g[j * every :], a[j * every :], m[j * every :], check_units=False)
        assert tail.tobytes() == np.ascontiguousarray(plain["q"][j * every :]).tobytes()
