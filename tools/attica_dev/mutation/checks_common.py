"""What the stage B checks share: the digest, the values of C data, the probes of settings fields."""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from typing import Any


def _sha(*parts: Any) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(p if isinstance(p, bytes) else repr(p).encode())
    return h.hexdigest()


def _values(x: Any) -> Any:
    """The members of a C value, recursively (structs and arrays as tuples; padding left out)."""
    from attica.native import ffi

    if not isinstance(x, ffi.CData):
        return x
    t = ffi.typeof(x)
    if t.kind == "pointer":
        return _values(x[0])
    if t.kind == "array":
        return tuple(_values(x[i]) for i in range(len(x)))
    if t.kind == "struct":
        return tuple((name, _values(getattr(x, name))) for name, _ in t.fields)
    return x


def _leaves(ctype: Any, prefix: str = "") -> list[tuple[str, Any]]:
    """(dotted path, C type) of every scalar member of a struct type."""
    out = []
    for name, fld in ctype.fields:
        path = f"{prefix}{name}"
        t = fld.type
        if t.kind == "struct":
            out.extend(_leaves(t, path + "."))
        elif t.kind == "array":
            out.extend((f"{path}.{i}", t.item) for i in range(t.length))
        else:
            out.append((path, t))
    return out


def _set(obj: Any, path: str, value: Any) -> bool:
    *head, last = path.split(".")
    for name in head:
        obj = obj[int(name)] if name.isdigit() else getattr(obj, name)
    try:
        if last.isdigit():
            obj[int(last)] = value
        else:
            setattr(obj, last, value)
    except (OverflowError, TypeError, ValueError):
        return False
    return True


def _probe_values(ctype: Any, lo: float, hi: float) -> list[Any]:
    """Values to try in a field: the bounds and their neighbours outside, specials (floats); edges (ints)."""
    import numpy as np

    if ctype.cname == "float":
        f32 = np.float32
        vals = [lo, hi, float(np.nextafter(f32(lo), f32(-np.inf))), float(np.nextafter(f32(hi), f32(np.inf)))]
        vals += [float(np.nextafter(f32(lo), f32(np.inf))), float(np.nextafter(f32(hi), f32(-np.inf)))]
        vals += [0.0, -0.0, 1.0, -1.0, 1e-45, -1e-45, 0.5, 3e38, float("nan"), float("inf"), float("-inf")]
        return [float(f32(v)) if np.isfinite(v) else v for v in vals]
    if ctype.cname in ("_Bool", "bool"):
        return [False, True]
    ints = [0, 1, 2, 3, 4, 5, 7, 8, 25, 255, 65535, 0xFFFFFFFF, -1]
    for b in (lo, hi):
        if np.isfinite(b) and abs(b) < 2**32:
            ints += [int(b) - 1, int(b), int(b) + 1]
    return ints


def _rules(call: Callable[[int, Any], int]) -> list[tuple[Any, ...]]:
    from attica.native import ffi

    r = ffi.new("att_settings_error_t *")
    out: list[tuple[Any, ...]] = []
    for i in range(400):
        status = int(call(i, r))
        if r.field == ffi.NULL:
            out.append(("end", status))
            return out
        out.append((ffi.string(r.field), ffi.string(r.rule), ffi.string(r.unit), r.min, r.max, status))
    return out


def _filter_rule(kind: int, s: Any, index: int, r: Any) -> int:
    from attica.native import lib

    return int(lib.att_filter_settings_rule(kind, s, index, r))


def _calib_rule(s: Any, index: int, r: Any) -> int:
    from attica.native import lib

    return int(lib.att_calib_settings_rule(s, index, r))


def _node_rule(s: Any, index: int, r: Any) -> int:
    from attica.native import lib

    return int(lib.att_node_settings_rule(s, index, r))


def _why(r: Any) -> tuple[Any, ...]:
    from attica.native import ffi

    def text(p: Any) -> bytes | None:
        return ffi.string(p) if p != ffi.NULL else None

    return (text(r.field), r.min, r.max, text(r.rule), text(r.unit))


def _bounds(rules: list[tuple[Any, ...]]) -> dict[str, tuple[float, float]]:
    out: dict[str, tuple[float, float]] = {}
    for r in rules:
        if r[0] != "end":
            name = r[0].decode().split(".", 1)[1] if b"." in r[0] else r[0].decode()
            out[name] = (float(r[3]), float(r[4]))
    return out
