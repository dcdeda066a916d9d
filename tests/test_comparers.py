"""The comparers behind every bit-exact test report a single flipped bit in any field.

A regression in a comparer would leave every bit-exact test green, so each one is shown to fail:
``helpers.same_bits``, ``crosscheck.records_equal``, ``crosscheck.crosscheck`` (outputs and the full
state at segment ends, ``reference.filter.Filter.state_matches``) and ``attica verify``'s ``compare``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from attica import crosscheck as cc
from attica import kinds, native, sim
from attica.can import codec as c
from attica.can import compare as compare_mod
from attica.can import verify as v
from attica.outputs import OUTPUT_DTYPE
from attica.reference import filter as ref_filter
from attica.settings import FilterKind

from helpers import same_bits

ffi = native.ffi
KINDS = kinds.labels()


def _flip(arr: np.ndarray, index: tuple[int, ...], bit: int) -> None:
    """Flip one bit of element ``index`` of a numeric array in place."""
    view = arr.view(np.dtype(f"u{arr.dtype.itemsize}"))
    view[index] ^= np.array(1 << bit, view.dtype)


def _stream(n: int = 400, seed: int = 3) -> cc.Stream:
    rec = sim.simulate(sim.SimConfig(duration=n / 100.0, rate=100.0, seed=seed))
    return cc.Stream(rec.gyr[:n], rec.acc[:n], rec.mag[:n], "sim")


def test_same_bits_sees_every_flipped_bit() -> None:
    base = np.array([0.0, -0.0, 1.0, -2.5e-38, 3.4e38, 1e-45, np.inf, 0.1], np.float32)
    assert same_bits(base, base.copy()).all()
    for i in range(base.size):
        for bit in range(32):
            x = base.copy()
            _flip(x, (i,), bit)
            if np.isnan(x[i]) and np.isnan(base[i]):
                continue
            got = same_bits(base, x)
            assert not got[i] and got.sum() == base.size - 1, (i, bit)
    nan = np.array([np.nan], np.float32)
    assert same_bits(nan, nan).all() and not same_bits(nan, np.array([1.0], np.float32)).any()


def _records(kind: str = "kf") -> np.ndarray:
    st = _stream(50)
    out = native.Filter(kind, dt=0.01).run(st.gyr, st.acc, st.mag)
    assert np.isfinite(out["cov"]).all()
    return np.ascontiguousarray(out[-6:])


@pytest.mark.parametrize("name", [n for n in OUTPUT_DTYPE.names])
def test_records_equal_sees_every_flipped_bit(name: str) -> None:
    base = _records("ekf" if name == "cov" else "mars")
    assert cc.records_equal(base, base.copy()).all()
    shape = base[name].shape[1:]
    bits = 8 * base[name].dtype.itemsize
    for elem in np.ndindex(*shape) if shape else [()]:
        for bit in range(bits):
            x = base.copy()
            _flip(x[name], (2, *elem), bit)
            got = cc.records_equal(base, x)
            assert not got[2] and got.sum() == len(base) - 1, (name, elem, bit)


class _FlipOutput(native.Filter):
    """A C filter whose run() returns one output field with one bit flipped (at record FLIP_AT)."""

    field = "q"
    bit = 0
    at = 123

    def run(self, *args: Any, **kw: Any) -> Any:
        out, snaps = super().run(*args, **kw)
        _flip(
            out[type(self).field], (type(self).at,) + (0,) * (out[type(self).field].ndim - 1), type(self).bit
        )
        return out, snaps


@pytest.mark.parametrize("name", list(OUTPUT_DTYPE.names))
@pytest.mark.parametrize("bit", [0, 22, 31])
def test_crosscheck_reports_a_flipped_output_bit(
    monkeypatch: pytest.MonkeyPatch, name: str, bit: int
) -> None:
    st = _stream()
    assert cc.crosscheck("kf", [st], dt=0.01, segment=100).ok
    flip = type("Flip", (_FlipOutput,), {"field": name, "bit": bit})
    monkeypatch.setattr(native, "Filter", flip)
    r = cc.crosscheck("kf", [st], dt=0.01, segment=100)
    assert not r.ok and r.mismatched_steps == 1 and "step 123" in r.first_mismatch, r


def _state_fields(kind: str) -> list[tuple[str, int]]:
    """(name, byte offset in att_filter_t) of every field of the kind's C state struct (nested flat)."""
    t = ffi.typeof(f"att_{kind}_t")
    base = ffi.offsetof("att_filter_t", "u")
    out: list[tuple[str, int]] = []

    def walk(tp: Any, prefix: str, off: int) -> None:
        if tp.kind == "struct":
            for fname, f in tp.fields:
                walk(f.type, f"{prefix}.{fname}" if prefix else fname, off + f.offset)
        elif tp.kind == "array":
            for k in range(tp.length):
                walk(tp.item, f"{prefix}[{k}]", off + k * ffi.sizeof(tp.item))
        else:
            out.append((prefix, off))

    walk(t, "", base)
    return out


def _derived(kind: str, fname: str) -> bool:
    """Coefficients (att_<kind>_coeffs_t, member c): set at init / retune from the settings alone."""
    return fname.startswith("c.")


def _missed_state_fields(monkeypatch: pytest.MonkeyPatch, kind: str, derived: bool) -> list[str]:
    """State fields whose flipped lowest bit the crosscheck's segment-end state check does not report."""
    st = _stream(40)  # two segment ends: every field is compared at each
    assert cc.crosscheck(kind, [st], dt=0.01, segment=20).ok
    missed = []
    for fname, off in _state_fields(kind):
        if _derived(kind, fname) != derived:
            continue

        class FlipState(native.Filter):
            at = off

            @property
            def state(self) -> Any:
                s = super().state.copy()  # a snapshot with one bit flipped
                k = type(self).at
                ffi.buffer(s.ptr)[k] = bytes([ffi.buffer(s.ptr)[k][0] ^ 1])
                return s

        monkeypatch.setattr(native, "Filter", FlipState)
        r = cc.crosscheck(kind, [st], dt=0.01, segment=20)
        monkeypatch.undo()
        if r.ok or r.state_mismatches != 1:
            missed.append(fname)
    return missed


@pytest.mark.parametrize("kind", KINDS)
def test_crosscheck_reports_a_flipped_bit_in_every_dynamic_state_field(
    monkeypatch: pytest.MonkeyPatch, kind: str
) -> None:
    """The segment-end state check (state_matches) sees one flipped bit in any field that evolves."""
    missed = _missed_state_fields(monkeypatch, kind, derived=False)
    assert not missed, f"{kind}: a flipped bit in these state fields is not reported: {missed}"


@pytest.mark.parametrize("kind", KINDS)
def test_crosscheck_reports_a_flipped_bit_in_the_settings_and_gains(
    monkeypatch: pytest.MonkeyPatch, kind: str
) -> None:
    missed = _missed_state_fields(monkeypatch, kind, derived=True)
    assert not missed, f"{kind}: not compared: {missed}"


def test_state_matches_checks_lengths(monkeypatch: pytest.MonkeyPatch) -> None:
    st = _stream(30)
    f = native.Filter("ars", dt=0.01)
    f.run(st.gyr, st.acc)
    ref = ref_filter.Filter("ars", dt=0.01)
    for t in range(30):
        ref.step(st.gyr[t : t + 1], st.acc[t : t + 1], st.mag[t : t + 1])
    assert ref.state_matches(0, f.state[0])
    real = ref_filter.c_state_values
    monkeypatch.setattr(ref_filter, "c_state_values", lambda spec, s: [*real(spec, s), np.float32(1.0)])
    assert not ref.state_matches(0, f.state[0])


def _node_run(kind: FilterKind, fd: bool) -> tuple[v.Expected, np.ndarray]:
    st = _stream(200, 5)
    node = c.Node(kind.label, sample_rate=100.0, data_bitrate=2_000_000 if fd else 0, fd=fd)
    out, steps = node.run(c.encode_imu(st.gyr, st.acc, st.mag, fd=fd))
    assert steps == 200
    g, a, m = c.imu_values(st.gyr, st.acc, st.mag) if not fd else (st.gyr, st.acc, st.mag)
    exp = v.expected_outputs(kind, 100.0, g, a, m)
    assert exp.reference_ok
    return exp, out


@pytest.mark.parametrize("fd", [False, True], ids=["classic", "fd"])
def test_verify_reports_a_flipped_bit_in_every_compared_field(fd: bool) -> None:
    kind = FilterKind.KF
    exp, out = _node_run(kind, fd)
    rx = v.sort_outputs(out)
    assert v.compare(exp, kind, fd, rx).exact
    for name in compare_mod._COMPARED:
        if fd and name in ("q16", "euler_raw", "bias_raw"):
            continue
        arr = rx.sets[name]
        for bit in range(min(8 * arr.dtype.itemsize, 4 if name in ("counter", "kind") else 32)):
            sets = rx.sets.copy()
            _flip(sets[name], (50,) + (0,) * (sets[name].ndim - 1), bit)
            bad = v.Received(sets, rx.step, rx.bad_crc, rx.incomplete, rx.answers, rx.diag)
            rep = v.compare(exp, kind, fd, bad)
            assert not rep.exact and rep.mismatched == 1 and name in rep.first_mismatch, (
                name,
                bit,
                rep.lines(),
            )
    # a flipped bit on the bus (CRC not redone) is a corrupted set, never a silent match
    frames = out.copy()
    k = int(np.nonzero(frames["id"] == (c.ID_OUT_FD if fd else c.ID_QUAT_A))[0][40])
    frames["data"][k, 6] ^= 1
    rep = v.compare(exp, kind, fd, frames)
    assert not rep.exact and rep.corrupted == 1 and rep.sets_ok == 199
