"""What the binding hands out never outlives the C memory it points into.

cffi frees an ``ffi.new`` block when its owning cdata is collected, and a struct member, array element or
``p[0]`` taken from it does not keep it alive. Every test here takes a view from an object that is gone
right after (a temporary Filter, Node or snapshot array), forces ``gc.collect()``, fills the heap with new
filters of other settings (which reuse freed blocks of the same size), and checks the view still reads the
first object's values, bit for bit, against a twin kept alive on purpose. ``ROUNDS`` repetitions make a
dangling view fail reliably (with the raw cffi views of before, every round read another filter's memory).
"""

from __future__ import annotations

import copy
import functools
import gc
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from attica import kinds, native, sim
from attica.can import codec
from attica.reference._common import c_state_values
from attica.reference.filter import Filter as RefFilter
from attica.settings import FilterKind

ffi, lib = native.ffi, native.lib
ROUNDS = 10
KINDS = [k.kind for k in kinds.KINDS if k.has_period] + [k.kind for k in kinds.KINDS if not k.has_period]
DT = 0.01


def _imu(n: int = 50) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rec = sim.simulate(sim.SimConfig(duration=n / 100.0, rate=100.0, seed=3))
    return rec.gyr[:n], rec.acc[:n], rec.mag[:n]


IMU = _imu()


def _filter(kind: FilterKind, dt: float = DT, steps: int = 50) -> native.Filter:
    """A filter of ``kind`` that ran ``steps`` samples (so its state differs from a fresh one's)."""
    f = native.Filter(kind, dt if kinds.info(kind).has_period else None)
    if steps:
        f.run(*(x[:steps] for x in IMU))
    return f


@functools.cache
def _spec(kind: FilterKind) -> dict[str, str]:
    impl = RefFilter(kind, DT if kinds.info(kind).has_period else None).impl
    return {**impl.STATE, **impl.COEFFS}


def _values(kind: FilterKind, kind_state: Any) -> list[int]:
    """Every state field and coefficient of a ``att_<kind>_t`` as float32/int bit patterns."""
    out = []
    for v in c_state_values(_spec(kind), kind_state):
        out.append(int(np.float32(v).view(np.uint32)) if isinstance(v, float) else int(v))
    return out


def _fields(v: Any, t: Any) -> list[int]:
    """Every scalar of a C struct / array (a cdata or a view) by name and index, padding left out (it
    holds whatever a struct copy left there, different from filter to filter)."""
    if t.kind == "struct":
        return [x for name, fld in t.fields for x in _fields(getattr(v, name), fld.type)]
    if t.kind == "array":
        return [x for i in range(t.length) for x in _fields(v[i], t.item)]
    return [int(np.float32(v).view(np.uint32)) if isinstance(v, float) else int(v)]


def _churn(kind: FilterKind) -> list[native.Filter]:
    """Collect garbage, then allocate many filters of other settings (of this kind and others)."""
    gc.collect()
    rates = (0.001, 0.002, 0.004, 0.005, 0.02)
    return [_filter(k, rates[i % len(rates)], steps=5) for i in range(12) for k in (kind, FilterKind.MARS)]


def _check_rounds(kind: FilterKind, take: Callable[[native.Filter], Any], read: Callable[[Any], Any]) -> None:
    """``take`` a view from a filter that dies at once; after the churn ``read`` equals the twin's."""
    twin = _filter(kind)  # the same settings and inputs, kept alive: what the view must still show
    want = read(take(twin))
    bad = 0
    for _ in range(ROUNDS):
        view = take(_filter(kind))  # the Filter is unreachable from here on
        others = _churn(kind)
        if read(view) != want:
            bad += 1
        del others
    assert bad == 0, f"{bad}/{ROUNDS} rounds read memory that is not the first filter's"


@pytest.mark.parametrize("kind", KINDS, ids=lambda k: k.label)
def test_member_view_of_a_temporary_filter_keeps_its_memory(kind: FilterKind) -> None:
    """``Filter(...).state.u.<kind>``: state and coefficients of the filter it came from."""
    _check_rounds(kind, lambda f: getattr(f.state.u, kind.label), lambda v: _values(kind, v))


def test_coefficients_of_temporary_filters_stay_theirs() -> None:
    """The case once seen in test_mekf: the coefficients of two temporary filters, then compared."""
    for _ in range(ROUNDS):
        fa = native.Filter("mekf", 0.01).state.u.mekf.c
        fb = native.Filter("mekf", 0.001).state.u.mekf.c
        others = _churn(FilterKind.MEKF)
        assert np.isclose(fa.qa / fb.qa, 10.0, rtol=1e-5) and np.isclose(fb.r_acc / fa.r_acc, 10.0, rtol=1e-5)
        del others


@pytest.mark.parametrize("kind", [FilterKind.ARS, FilterKind.MEKF], ids=lambda k: k.label)
def test_state_pointer_element_and_ptr_of_a_temporary_filter(kind: FilterKind) -> None:
    """``.state`` itself, ``.state[0]``, a nested array and ``.state.ptr`` (for C calls) of a dead Filter."""
    label = kind.label
    _check_rounds(kind, lambda f: f.state, lambda v: _values(kind, getattr(v.u, label)))
    _check_rounds(kind, lambda f: f.state[0], lambda v: _values(kind, getattr(v.u, label)))
    _check_rounds(kind, lambda f: f.state.cal, lambda v: _fields(v, ffi.typeof("att_calib_t")))
    if kind == FilterKind.MEKF:  # an array member (the covariance, packed)
        _check_rounds(kind, lambda f: f.state.u.mekf.st.p, lambda v: [float(x) for x in v])
    _check_rounds(kind, lambda f: f.state.ptr, lambda p: _values(kind, getattr(p.u, label)))

    def output_via_ptr(p: Any) -> bytes:
        out = np.zeros((), native.OUTPUT_DTYPE)
        lib.att_filter_output(p, ffi.from_buffer("att_output_t[]", out))
        return out.tobytes()

    _check_rounds(kind, lambda f: f.state.ptr, output_via_ptr)


def test_run_snapshots_outlive_their_array() -> None:
    """An element of ``run(snapshot_every=k)``'s snapshots, the array itself dropped."""
    kind = FilterKind.MARS

    def take(f: native.Filter) -> Any:
        g = native.Filter(kind, DT)
        return g.run(*IMU, snapshot_every=10)[1][3]  # the state before step 30

    _check_rounds(kind, take, lambda v: _values(kind, v.u.mars))


def test_node_state_of_a_temporary_node() -> None:
    """``Node(...).state`` members: the node's filter state and its counters."""
    kind = FilterKind.ARS

    def node(crc: int) -> Any:
        n = codec.Node("ars", sample_rate=100.0, tau=0.25 + crc / 100)
        n.state.stats.crc_errors = crc
        return n

    want = _values(kind, node(7).state.f.u.ars)
    bad = 0
    for _ in range(ROUNDS):
        st = node(7).state.f.u.ars
        stats = node(7).state.stats
        gc.collect()
        others = [node(i) for i in range(12)] + _churn(kind)
        bad += _values(kind, st) != want or stats.crc_errors != 7
        del others
    assert bad == 0, f"{bad}/{ROUNDS} rounds read memory that is not the first node's"


def test_state_is_live_and_copy_is_a_snapshot() -> None:
    """``.state`` shows later steps and writes through; ``.copy()`` / ``bytes()`` do not change after."""
    f = _filter(FilterKind.ARS, steps=0)
    live, snap, raw = f.state, f.state.copy(), bytes(f.state)
    f.run(*IMU)
    assert bytes(live) == bytes(f.state) != raw
    assert bytes(snap) == raw and bytes(copy.deepcopy(live)) == bytes(f.state)
    f.state[0] = snap[0]  # restore the saved state through the live view
    assert bytes(f.state) == raw
    f.state.u.ars.st.q.w = 0.5  # a scalar written through a nested view
    assert f.state.u.ars.st.q.w == 0.5 and snap.u.ars.st.q.w == 1.0
    with pytest.raises(TypeError):
        iter(f.state.u)  # a union is not iterable, as in cffi
    with pytest.raises(TypeError):
        lib.att_filter_reset(f.state)  # C calls take the pointer: .ptr
    lib.att_filter_reset(f.state.ptr)
    assert f.state.u.ars.st.q.w == 1.0
