"""Every function of the generated CAN codec against the DBC and cantools' own Python codec.

firmware/src/can/generated/att_can_db.{c,h} is generated from firmware/can/attica.dbc
(host/attica/can/gen.py; test_can_codec.py checks it is not stale). att_can.c calls the pack and unpack
functions of the frames the node sends and reads; the rest (init, the raw and physical range checks, the
other direction of each frame) was compiled into every image and binding but never run by a test (issue
26: 64 % of the codec's lines, 25 % of its branches). The binding declares the whole header
(attica._build.codec_cdef), so each function is run here, for every message and signal of the DBC:

- pack and unpack, on random raw values and random payloads, byte for byte and field for field against
  cantools' encode_message / decode_message (an independent implementation of the same DBC), and the
  short buffer refused (-EINVAL);
- init (every field its raw initial value, 0 in this DBC; NULL refused);
- is_in_range (raw) and is_in_phys_range (float) at each bound, one step beyond it and at the type's
  limits, against the DBC's minimum and maximum (exact arithmetic), and NaN outside;
- the frame id and length constants.
"""

from __future__ import annotations

import errno
import math
from fractions import Fraction
from typing import Any

import cantools
import numpy as np
import pytest
from cantools.database.can.c_source import camel_to_snake_case

from attica._native import ffi, lib
from attica.can.gen import DBC

DB = cantools.database.load_file(str(DBC), strict=True)
assert isinstance(DB, cantools.database.can.Database)
MESSAGES = list(DB.messages)
F32 = np.float32

C_LIMITS = {
    "uint8_t": (0, 2**8 - 1),
    "uint16_t": (0, 2**16 - 1),
    "uint32_t": (0, 2**32 - 1),
    "uint64_t": (0, 2**64 - 1),
    "int8_t": (-(2**7), 2**7 - 1),
    "int16_t": (-(2**15), 2**15 - 1),
    "int32_t": (-(2**31), 2**31 - 1),
    "int64_t": (-(2**63), 2**63 - 1),
}


def _prefix(msg: Any) -> str:
    return f"att_can_db_{camel_to_snake_case(msg.name)}"


def _field_types(msg: Any) -> dict[str, str]:
    """C type name of each field of the message's struct."""
    t = ffi.typeof(f"struct {_prefix(msg)}_t")
    return {name: f.type.cname for name, f in t.fields}


def _random_raw(sig: Any, rng: np.random.Generator) -> int | float:
    """A raw value the signal's bits hold: an integer, or for a float32 signal a float32 from random bits
    (NaN drawn again: it has no equality to compare)."""
    if sig.is_float:
        while True:
            v = np.array([rng.integers(0, 2**32)], np.uint32).view(F32)[0]
            if not np.isnan(v):
                return float(v)
    lo, hi = _bits(sig)
    return int(rng.integers(lo, hi, endpoint=True))


def _same(a: float, b: float) -> bool:
    """Equal values, or both NaN (an unpacked payload may hold any NaN)."""
    return (math.isnan(a) and math.isnan(b)) or a == b


def _bits(sig: Any) -> tuple[int, int]:
    """The raw range the signal's bits hold."""
    if sig.is_signed:
        return -(2 ** (sig.length - 1)), 2 ** (sig.length - 1) - 1
    return 0, 2**sig.length - 1


def _phys(sig: Any, raw: int) -> Fraction:
    return Fraction(raw) * Fraction(sig.scale) + Fraction(sig.offset)


def _in_range(sig: Any, raw: int) -> bool:
    """The DBC's range in raw terms, exactly."""
    v = _phys(sig, raw)
    lo_ok = sig.minimum is None or v >= Fraction(sig.minimum)
    hi_ok = sig.maximum is None or v <= Fraction(sig.maximum)
    return lo_ok and hi_ok


def _raw_bound(sig: Any, phys: float, up: bool) -> int:
    """The raw value at a physical bound (rounded into the range)."""
    r = (Fraction(phys) - Fraction(sig.offset)) / Fraction(sig.scale)
    return math.ceil(r) if up else math.floor(r)


def test_every_message_and_signal_has_its_functions() -> None:
    """The header declares pack, unpack and init per message and two range checks per signal, and the
    binding has them all (codec_cdef left none out)."""
    names = {n for n in dir(lib) if n.startswith("att_can_db_")}
    want = set()
    for msg in MESSAGES:
        p = _prefix(msg)
        want |= {f"{p}_pack", f"{p}_unpack", f"{p}_init"}
        for sig in msg.signals:
            s = camel_to_snake_case(sig.name)
            want |= {f"{p}_{s}_is_in_range", f"{p}_{s}_is_in_phys_range"}
    assert names == want


@pytest.mark.parametrize("msg", MESSAGES, ids=lambda m: m.name)
def test_constants(msg: Any) -> None:
    up = _prefix(msg).upper()
    assert getattr(lib, f"{up}_FRAME_ID") == msg.frame_id
    assert getattr(lib, f"{up}_LENGTH") == msg.length


@pytest.mark.parametrize("msg", MESSAGES, ids=lambda m: m.name)
def test_pack_and_unpack_agree_with_cantools(msg: Any) -> None:
    """200 random raw records packed (bytes equal cantools' encode_message, scaling off) and 200 random
    payloads unpacked (fields equal decode_message); pack and unpack refuse a buffer one byte short; a
    record packed then unpacked comes back."""
    p = _prefix(msg)
    pack = getattr(lib, f"{p}_pack")
    unpack = getattr(lib, f"{p}_unpack")
    rng = np.random.default_rng(msg.frame_id)
    n = msg.length
    buf = ffi.new(f"uint8_t[{n}]")
    rec = ffi.new(f"struct {p}_t *")
    back = ffi.new(f"struct {p}_t *")
    for _ in range(200):
        raw = {}
        for sig in msg.signals:
            raw[sig.name] = _random_raw(sig, rng)
            setattr(rec, camel_to_snake_case(sig.name), raw[sig.name])
        assert pack(buf, rec, n) == n
        want = DB.encode_message(msg.frame_id, raw, scaling=False, strict=False)
        assert bytes(ffi.buffer(buf, n)) == want
        assert unpack(back, buf, n) == 0
        for sig in msg.signals:
            assert getattr(back, camel_to_snake_case(sig.name)) == raw[sig.name], sig.name
    for _ in range(200):
        data = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
        assert unpack(rec, data, n) == 0
        got = DB.decode_message(msg.frame_id, data, scaling=False, decode_choices=False)
        for sig in msg.signals:
            assert _same(getattr(rec, camel_to_snake_case(sig.name)), float(got[sig.name])), sig.name
    assert pack(buf, rec, n - 1) == -errno.EINVAL
    assert unpack(rec, bytes(n), n - 1) == -errno.EINVAL


@pytest.mark.parametrize("msg", MESSAGES, ids=lambda m: m.name)
def test_init(msg: Any) -> None:
    """Every field its raw initial value (the DBC gives none: 0), whatever was there; NULL refused."""
    p = _prefix(msg)
    rec = ffi.new(f"struct {p}_t *")
    ffi.memmove(rec, b"\xa5" * ffi.sizeof(rec[0]), ffi.sizeof(rec[0]))
    assert getattr(lib, f"{p}_init")(rec) == 0
    for sig in msg.signals:
        assert getattr(rec, camel_to_snake_case(sig.name)) == (sig.raw_initial or 0), sig.name
    assert getattr(lib, f"{p}_init")(ffi.NULL) == -1


@pytest.mark.parametrize("msg", MESSAGES, ids=lambda m: m.name)
def test_range_checks(msg: Any) -> None:
    """is_in_range (raw, the field's C type) at the type's limits, at each raw bound of the DBC's range
    and one beyond, and at 100 random values; is_in_phys_range (float) at each bound as a float, the
    next float beyond it, zero, +-Inf and NaN (outside): each against the DBC's minimum and maximum."""
    p = _prefix(msg)
    types = _field_types(msg)
    rng = np.random.default_rng(msg.frame_id + 1)
    for sig in msg.signals:
        s = camel_to_snake_case(sig.name)
        in_range = getattr(lib, f"{p}_{s}_is_in_range")
        phys_range = getattr(lib, f"{p}_{s}_is_in_phys_range")
        if sig.is_float:  # a float32 signal: no range in this DBC, so every value is in it
            assert types[s] == "float" and sig.minimum is None and sig.maximum is None
            for v in (0.0, -1.5, 3.4e38, -math.inf, math.inf, math.nan):
                assert in_range(v) and phys_range(v), (sig.name, v)
            continue
        lo_t, hi_t = C_LIMITS[types[s]]
        probes = {lo_t, hi_t, 0}
        for bound, up in ((sig.minimum, True), (sig.maximum, False)):
            if bound is not None:
                r = _raw_bound(sig, bound, up)
                probes |= {r - 1, r, r + 1}
        probes |= {int(v) for v in rng.integers(lo_t, hi_t, 100, endpoint=True, dtype=np.int64)}
        for raw in sorted(v for v in probes if lo_t <= v <= hi_t):
            assert bool(in_range(raw)) == _in_range(sig, raw), (sig.name, raw)
        lo = F32(sig.minimum) if sig.minimum is not None else F32(-np.inf)
        hi = F32(sig.maximum) if sig.maximum is not None else F32(np.inf)
        values = [lo, hi, np.nextafter(lo, F32(-np.inf)), np.nextafter(hi, F32(np.inf)), F32(0), F32(np.inf)]
        for v in values + [F32(-np.inf)]:
            assert bool(phys_range(float(v))) == bool(lo <= v <= hi), (sig.name, v)
        assert not phys_range(math.nan), sig.name
