"""Stage B: the settings contracts of every kind, of the stages and of the node (fields probed)."""

from __future__ import annotations

import functools
from typing import Any

from attica_dev.mutation.checks_common import (
    _bounds,
    _calib_rule,
    _filter_rule,
    _leaves,
    _node_rule,
    _probe_values,
    _rules,
    _set,
    _sha,
    _values,
    _why,
)


def _contract_check(kind: Any) -> str:
    """The kind's settings contract: its listing and every field probed (check, validate, init, retune)."""
    import math

    from attica.native import ffi, lib
    from attica.settings import Preset

    parts: list[Any] = []
    why = ffi.new("att_settings_error_t *")
    f = ffi.new("att_filter_t *")
    for preset in Preset:
        for dt in (0.01, 1e-6, 1.0):
            s0 = ffi.new("att_filter_settings_t *")
            ffi.memmove(s0, b"\xa5" * ffi.sizeof(s0[0]), ffi.sizeof(s0[0]))  # every field written?
            parts.append(lib.att_filter_settings_preset(int(kind), int(preset), dt, s0))
            parts.append(bytes(ffi.buffer(ffi.addressof(s0[0], kind.label))))
            rules = _rules(functools.partial(_filter_rule, int(kind), s0))
            parts.append(rules)
            bounds = _bounds(rules)
            parts.append((lib.att_filter_settings_check(int(kind), s0, why), _why(why)))
            if dt != 0.01:
                continue
            member = ffi.typeof(f"att_{kind.label}_settings_t")
            for path, ctype in _leaves(member):
                key = path if path in bounds else path.rsplit(".", 1)[0]
                lo, hi = bounds.get(key, (-math.inf, math.inf))
                for v in _probe_values(ctype, lo, hi):
                    s = ffi.new("att_filter_settings_t *")
                    ffi.memmove(s, s0, ffi.sizeof("att_filter_settings_t"))
                    if not _set(getattr(s, kind.label), path, v):
                        continue
                    st = lib.att_filter_settings_check(int(kind), s, why)
                    valid = lib.att_filter_settings_validate(int(kind), s)
                    init = lib.att_filter_init(f, int(kind), s)
                    assert lib.att_filter_init(f, int(kind), s0) == lib.ATT_OK
                    parts.append((path, v, st, _why(why), valid, init, lib.att_filter_retune(f, s)))
    for k in (0, 8, 99):
        s = ffi.new("att_filter_settings_t *")
        parts.append(
            (k, lib.att_filter_settings_default(k, 0.01, s), lib.att_filter_settings_check(k, s, why))
        )
    return _sha(parts)


def _calib_check() -> str:
    """The stages' contract: listing, every field probed (check, validate, calibrate), field set/get."""
    import math

    from attica.native import ffi, lib

    parts: list[Any] = []
    cs0 = ffi.new("att_calib_settings_t *")
    ffi.memmove(cs0, b"\xa5" * ffi.sizeof(cs0[0]), ffi.sizeof(cs0[0]))  # every field written?
    lib.att_calib_settings_default(cs0)
    parts.append(_values(cs0))
    rules = _rules(functools.partial(_calib_rule, cs0))
    parts.append(rules)
    bounds = _bounds(rules)
    f = ffi.new("att_filter_t *")
    fs = ffi.new("att_filter_settings_t *")
    lib.att_filter_settings_default(1, 0.01, fs)
    for path, ctype in _leaves(ffi.typeof("att_calib_settings_t")):
        parent = path.rsplit(".", 1)[0]
        lo, hi = bounds.get(path, bounds.get(parent, (-math.inf, math.inf)))
        for v in _probe_values(ctype, lo, hi):
            cs = ffi.new("att_calib_settings_t *")
            ffi.memmove(cs, cs0, ffi.sizeof("att_calib_settings_t"))
            if not _set(cs, path, v):
                continue
            lib.att_filter_init(f, 1, fs)
            res = (path, v, lib.att_calib_settings_check(cs), lib.att_calib_settings_validate(cs))
            parts.append((*res, lib.att_filter_calibrate(f, cs), _rules(functools.partial(_calib_rule, cs))))
    parts.append(_matrix_probes(cs0, f, fs))
    val = ffi.new("float *")
    for i in range(-1, 60):
        for x in (
            0.25 + i,
            0.0,
            1.0,
            2.0,
            3.0,
            -1.0,
            0.5,
            24.0,
            25.0,
            4294967296.0,
            float("nan"),
            float("inf"),
        ):
            cs = ffi.new("att_calib_settings_t *")
            lib.att_calib_settings_default(cs)
            ok = lib.att_calib_field_set(cs, i & 0xFFFFFFFF, x)
            val[0] = -7.0
            got = lib.att_calib_field_get(cs, i & 0xFFFFFFFF, val)
            parts.append((i, x, ok, got, val[0], bytes(ffi.buffer(cs))))
    for r in range(0, 27):
        name = lib.att_calib_remap_name(r)
        text = ffi.string(name) if name != ffi.NULL else None
        parts.append((r, text, lib.att_calib_remap_parse(text) if text else None))
    for bad in (b"", b"+x+y", b"+x+y+x", b"-z-y-x", b"+x+y+z+", b"?"):
        parts.append(lib.att_calib_remap_parse(bad))
    return _sha(parts)


def _matrix_probes(cs0: Any, f: Any, fs: Any) -> list[Any]:
    """Whole matrices in each matrix of the stages: well and badly conditioned, singular, huge, tiny."""
    import numpy as np

    from attica.native import ffi, lib

    rng = np.random.default_rng(2612)
    mats: list[Any] = [np.zeros(9), np.eye(3).ravel() * 1e3, np.diag([1.0, 1.0, 1e-4]).ravel()]
    mats += [np.diag([1.0, 1.0, 1e-3]).ravel(), np.diag([1.0, -1.0, 1.0]).ravel(), np.full(9, 1e3)]
    for i in range(60):
        u, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        v, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        cond = [1.0, 10.0, 999.0, 1001.0, 3000.0, 3200.0, 1e5][i % 7]
        sv = np.array([cond, np.sqrt(cond), 1.0]) / cond * 10 ** rng.uniform(-2, 2.9)
        mats.append((u @ np.diag(sv) @ v.T).ravel() * (-1 if i % 2 else 1))
    for _ in range(60):
        mats.append(rng.normal(size=9) * 10 ** rng.uniform(-25, 4, 9))
    out: list[Any] = []
    for name in ("gyro.misalignment", "accel.misalignment", "mag.soft_iron"):
        group, member = name.split(".")
        for m in mats:
            cs = ffi.new("att_calib_settings_t *")
            ffi.memmove(cs, cs0, ffi.sizeof("att_calib_settings_t"))
            arr = getattr(getattr(cs, group), member)
            for j, x in enumerate(np.asarray(m, np.float32)):
                arr[j] = float(x)
            lib.att_filter_init(f, 1, fs)
            out.append((lib.att_calib_settings_check(cs), lib.att_filter_calibrate(f, cs)))
    return out


def _node_check() -> str:
    """The node's contract and timing functions: listing, fields probed (check, init), bus load."""
    import math

    from attica.native import ffi, lib

    parts: list[Any] = []
    why = ffi.new("att_settings_error_t *")
    node = ffi.new("att_node_t *")
    for kind in range(0, 9):
        for rate in (100.0, 1000.0, 0.5, 1e5):
            s0 = ffi.new("att_node_settings_t *")
            parts.append((kind, rate, lib.att_node_settings_default(kind, rate, s0)))
            if kind not in (1, 2):
                continue
            rules = _rules(functools.partial(_node_rule, s0))
            parts.append(rules)
            parts.append((lib.att_node_settings_check(s0, why), _why(why), lib.att_node_bus_load(s0)))
            if rate != 100.0:
                continue
            bounds = _bounds(rules)
            for path, ctype in _leaves(ffi.typeof("att_node_settings_t")):
                if path.split(".")[0] in ("filter", "calib"):
                    continue
                lo, hi = bounds.get(path, (-math.inf, math.inf))
                for v in _probe_values(ctype, lo, hi):
                    s = ffi.new("att_node_settings_t *")
                    ffi.memmove(s, s0, ffi.sizeof("att_node_settings_t"))
                    if not _set(s, path, v):
                        continue
                    st = lib.att_node_settings_check(s, why)
                    parts.append(
                        (path, v, st, _why(why), lib.att_node_init(node, s), lib.att_node_bus_load(s))
                    )
    cb = ffi.callback("void(void *, att_can_bus_diag_t *)", lambda ctx, d: None)
    for rate in (100.0, 500.0, 1000.0, 2000.0, 4000.0):
        for bitrate, data_bitrate in (
            (125_000, 0),
            (250_000, 0),
            (500_000, 2_000_000),
            (1_000_000, 8_000_000),
        ):
            for fd, accel, divider in (
                (False, False, 1),
                (False, True, 0),
                (True, True, 7),
                (True, False, 1),
            ):
                s = ffi.new("att_node_settings_t *")
                lib.att_node_settings_default(1, rate, s)
                s.bitrate, s.data_bitrate, s.fd, s.accel_out, s.diag_divider = (
                    bitrate,
                    data_bitrate if fd else 0,
                    fd,
                    accel,
                    divider,
                )
                st = lib.att_node_init(node, s)
                parts.append((st, lib.att_node_bus_load(s), lib.att_node_settings_check(s, why), _why(why)))
                if st == lib.ATT_OK:
                    parts.append((lib.att_node_set_bus_diag(node, cb, ffi.NULL), node.bus_diag != ffi.NULL))
    for n in range(0, 70):
        parts.append((n, lib.att_node_classic_bits(n)))
        for br, dbr in ((1_000_000, 5_000_000), (500_000, 2_000_000), (125_000, 0), (0, 0)):
            parts.append(lib.att_node_fd_frame_time(n, br, dbr))
    return _sha(parts)
