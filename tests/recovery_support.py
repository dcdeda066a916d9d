"""Random accepted settings, fuzzed streams and clean segments for the recovery contract (test_recovery.py).

Settings are drawn inside the ranges the C validator accepts, read from the validator itself
(``att_filter_settings_check`` through :func:`attica.native.settings_problem`), not from a copy of its
table: each field's bounds are those it reports for that field set to NaN, and a draw that a rule between
fields refuses (``accel_range`` in ``(gravity, 1e4]``, ``p0`` in ``[1e-6, p_max]``, ``bias_init`` within
``gyro_range`` ...) has the named field drawn again inside the bounds reported for the other fields'
values, until the validator accepts the whole.
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import math
from typing import Any

import numpy as np

from attica import native
from attica.settings import FilterKind, Preset, make_settings, preset_settings

F32 = np.float32
FLT_MAX = float(np.finfo(np.float32).max)
G_STD = 9.80665
EARTH_FIELD = np.array([0.0, 25.0, -43.3])  # uT, ENU: north +y, dip 60 deg


def _f32(x: float) -> float:
    with np.errstate(over="ignore"):
        return float(F32(x))


def _inward(x: float, toward: float) -> float:
    return float(np.nextafter(F32(x), F32(toward)))


def _in_bounds(v: float, lo: float, hi: float, rule: str) -> float:
    """v as a float32 inside the rule's interval (open ends respected)."""
    v = _f32(v)
    lo_open = rule.startswith("(")
    hi_open = rule.endswith(")") and not rule.endswith("(bool)")
    lo_ok = _inward(lo, hi) if lo_open else lo
    hi_ok = _inward(hi, lo) if hi_open else hi
    return min(max(v, lo_ok), hi_ok)


def _draw_scalar(rng: np.random.Generator, lo: float, hi: float, rule: str, default: float) -> float:
    """A value of [lo, hi] (its ends, the default, or spread over the decades the range spans)."""
    u = rng.random()
    if u < 0.15 and lo <= default <= hi:
        return _in_bounds(default, lo, hi, rule)
    if u < 0.30:
        return _in_bounds(lo if rng.random() < 0.5 else hi, lo, hi, rule)
    top = max(abs(lo), abs(hi))
    if top == 0.0:
        return 0.0
    floor = min(max(top * 1e-12, 1e-38), top)
    if lo >= 0.0:
        floor = max(floor, lo)
        mag = math.exp(rng.uniform(math.log(floor), math.log(max(hi, floor))))
        return _in_bounds(mag, lo, hi, rule)
    mag = math.exp(rng.uniform(math.log(floor), math.log(top)))
    sign = -1.0 if rng.random() < 0.5 else 1.0
    return _in_bounds(sign * mag, lo, hi, rule)


def _unit(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=n)
    return v / np.linalg.norm(v)


def _draw_field(
    rng: np.random.Generator, name: str, current: Any, default: Any, lo: float, hi: float, rule: str
) -> Any:
    """A new value for one dataclass field (or for one component, current being the whole tuple)."""
    if isinstance(default, bool):
        return bool(rng.random() < 0.5)
    if isinstance(default, enum.IntEnum):
        return type(default)(int(rng.choice([m.value for m in type(default)])))
    if isinstance(default, int):  # bias_n_max: [1, 2^24]
        return int(round(math.exp(rng.uniform(0.0, math.log(hi if hi > 1 else 2**24)))))
    if isinstance(default, float):
        return _draw_scalar(rng, lo, hi, rule, default)
    # tuples: vectors and quaternions
    n = len(default)
    if "|q|^2" in rule:  # an initial quaternion: any direction, |q|^2 in [lo, hi]
        n2 = math.exp(rng.uniform(math.log(lo), math.log(hi))) if rng.random() < 0.3 else 1.0
        return tuple(_f32(x) for x in _unit(rng, 4) * math.sqrt(n2) * (1 - 1e-6))
    if "zero, or" in rule:  # a reference field: zero, or its norm in [lo, hi]
        if rng.random() < 0.4:
            return (0.0, 0.0, 0.0)
        norm = _draw_scalar(rng, lo, hi, "[lo, hi]", 50.0)
        norm = min(max(norm, lo * (1 + 1e-5)), hi * (1 - 1e-5))
        return tuple(_f32(x) for x in _unit(rng, 3) * norm)
    # each component in [lo, hi] (bias_init within gyro_range; a refused euler_init component)
    if rng.random() < 0.3:
        return tuple(0.0 for _ in range(n))
    return tuple(_draw_scalar(rng, lo, hi, rule, 0.0) for _ in range(n))


@functools.cache
def _bounds(kind: FilterKind, name: str) -> tuple[float, float, str]:
    """The bounds and rule the validator reports for field name set to NaN in the kind's defaults (vectors:
    the first component)."""
    base = make_settings(kind)
    value = getattr(base, name)
    if isinstance(value, tuple):
        bad: Any = (math.nan,) + tuple(value[1:])
    elif isinstance(value, bool) or isinstance(value, enum.IntEnum) or isinstance(value, int):
        return (0.0, float(2**24), "")
    else:
        bad = math.nan
    why = native.settings_problem(kind, dataclasses.replace(base, **{name: bad}))
    assert why is not None and why.field.split(".")[1] == name, (kind, name, why)
    return why.minimum, why.maximum, why.rule


def draw_settings(kind: FilterKind, rng: np.random.Generator, dt: float | None = None) -> Any:
    """Settings of kind the C validator accepts, spread over its whole accepted ranges.

    Half the fields keep the value of a preset (default or seed) at a random dt; the others are drawn
    inside their bounds; then every field the validator refuses (a rule between fields) is drawn again
    inside the bounds it reports, until the whole is accepted.
    """
    preset = Preset.SEED if rng.random() < 0.3 else Preset.DEFAULT
    if dt is None:
        dt = float(rng.choice([0.0035, 0.01, 0.001, 0.1, 1.0, 0.0001, 0.02, 0.5, 1e-6]))
    base = preset_settings(kind, preset, dt)
    default = make_settings(kind)
    names = [f.name for f in dataclasses.fields(base)]
    changes: dict[str, Any] = {}
    p_draw = rng.choice([0.1, 0.5, 1.0])
    for name in names:
        if name == "dt" or rng.random() > p_draw:
            continue
        lo, hi, rule = _bounds(kind, name)
        changes[name] = _draw_field(rng, name, getattr(base, name), getattr(default, name), lo, hi, rule)
    s = dataclasses.replace(base, **changes)
    for _ in range(200):
        why = native.settings_problem(kind, s)
        if why is None:
            return s
        path = why.field.split(".")[1:]
        name = path[0]
        cur = getattr(s, name)
        if len(path) == 2:  # one component of a vector (euler_init.y)
            i = "xyz".index(path[1]) if len(cur) == 3 else "wxyz".index(path[1])
            comp = _draw_scalar(rng, why.minimum, why.maximum, why.rule, 0.0)
            new: Any = tuple(comp if j == i else c for j, c in enumerate(cur))
        else:
            new = _draw_field(rng, name, cur, getattr(default, name), why.minimum, why.maximum, why.rule)
        s = dataclasses.replace(s, **{name: new})
    raise AssertionError(f"{kind.label}: no accepted settings after 200 repairs: {why}")


# --- streams ------------------------------------------------------------------------------------------


def gravity_of(kind: FilterKind, s: Any) -> float:
    """|a| of a clean sample at rest for these settings (the kind's gravity; 9.80665 where it has none)."""
    g = getattr(s, "gravity", None)
    if kind == FilterKind.TILT and s.normalise:
        return G_STD
    return float(g) if g is not None else G_STD


def specials(s: Any, kind: FilterKind) -> np.ndarray:
    """Bad component values: NaN, +-Inf, huge, zero, tiny, and values just beyond the sensor ranges."""
    vals = [math.nan, math.inf, -math.inf, FLT_MAX, -FLT_MAX, 1e30, -1e30, 0.0, -0.0, 1e-45, 1e-38, 3e38]
    for name in ("gyro_range", "accel_range", "mag_range"):
        r = getattr(s, name, None)
        if r is not None:
            vals += [_f32(r * 1.0001), -_f32(r * 1.0001), _f32(r), _f32(r * 0.999), _f32(r * 1e3)]
    return np.array(vals, np.float32)


def fuzzed_stream(
    kind: FilterKind, s: Any, rng: np.random.Generator, length: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """length samples mixing good motion, rest, any values (special, huge, random bit patterns), good
    samples with one bad component and saturated samples; in a fifth of the streams the last 1 .. 20
    samples are all bad, in a tenth every sample is. Step counts n: mostly 1, some runs of lost samples
    (2 .. 15 periods), a few long holds (16 .. 300)."""
    g = gravity_of(kind, s)
    sp = specials(s, kind)
    out = np.zeros((length, 9), np.float64)
    all_bad = rng.random() < 0.1
    tail = int(rng.integers(1, 21)) if rng.random() < 0.2 else 0
    np_err = np.seterr(all="ignore")
    for i in range(length):
        mode = rng.uniform(0.45, 1.0) if all_bad or i >= length - tail else rng.random()
        row = np.array([0, 0, 0, 0, 0, g, 0, 20, -40], np.float64)
        if mode < 0.3:  # good motion
            row[0:3] = rng.normal(0, 1.0, 3)
            row[3:6] += rng.normal(0, 3.0, 3)
            row[6:9] += rng.normal(0, 8.0, 3)
        elif mode < 0.45:  # rest
            pass
        elif mode < 0.7:  # anything
            for j in range(9):
                u = rng.random()
                if u < 0.4:
                    row[j] = sp[rng.integers(sp.size)]
                elif u < 0.7:
                    row[j] = rng.choice([-1, 1]) * 10 ** rng.uniform(-40, 38.5)
                else:  # any bit pattern: denormals, NaN payloads, every exponent
                    row[j] = np.array([rng.integers(0, 2**32)], np.uint32).view(F32)[0]
        elif mode < 0.9:  # a good sample with one bad component
            row[rng.integers(9)] = sp[rng.integers(sp.size)]
        else:  # saturated: every component at or beyond its range
            row[:] = sp[rng.integers(sp.size, size=9)]
        out[i] = row
    x = out.astype(np.float32)  # beyond the float32 range: +-Inf, as a sensor driver's cast gives
    np.seterr(**np_err)
    steps = np.ones(length, np.uint32)
    u = rng.random(length)
    steps[u > 0.85] = rng.integers(2, 16, int((u > 0.85).sum()))
    steps[u > 0.98] = rng.integers(16, 301, int((u > 0.98).sum()))
    return x[:, 0:3].copy(), x[:, 3:6].copy(), x[:, 6:9].copy(), steps


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)


def clean_segment(
    kind: FilterKind, s: Any, rng: np.random.Generator, length: int, moving: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """length valid samples of a sensor at rest (zero rates) in a random attitude, or rotating slowly about a
    fixed body axis (at most 0.5 rad/s and half the gyro range); accel and mag consistent with the attitude
    (|a| = the kind's gravity, the earth field or m0_init's norm and direction, scaled into mag_range)."""
    g = gravity_of(kind, s)
    dt = float(getattr(s, "dt", 0.01))
    r0 = _axis_angle(_unit(rng, 3), rng.uniform(0, math.pi))
    if rng.random() < 0.3:
        r0 = np.eye(3)
    m0 = np.asarray(getattr(s, "m0_init", (0.0, 0.0, 0.0)), np.float64)
    field = m0 if np.linalg.norm(m0) > 0 else EARTH_FIELD
    mag_range = float(getattr(s, "mag_range", 1e5))
    if np.linalg.norm(field) > 0.5 * mag_range:
        field = field / np.linalg.norm(field) * 0.5 * mag_range
    rate = 0.0
    axis = _unit(rng, 3)
    if moving:
        rate = min(0.5, 0.5 * float(getattr(s, "gyro_range", 1e3))) * rng.uniform(0.1, 1.0)
    gyr = np.zeros((length, 3))
    acc = np.zeros((length, 3))
    mag = np.zeros((length, 3))
    for i in range(length):
        r = r0 @ _axis_angle(axis, rate * dt * (i + 1))  # sensor-to-earth after this sample's rotation
        gyr[i] = axis * rate
        acc[i] = r.T @ np.array([0.0, 0.0, g])
        mag[i] = r.T @ field
    return gyr.astype(F32), acc.astype(F32), mag.astype(F32)


# --- checks -------------------------------------------------------------------------------------------

INVALID = 0xC000  # ATT_FLAGS_OUTPUT_INVALID: NOT_READY | BAD_ARG
NUMERIC = 0x2000


def good_rows(out: Any) -> np.ndarray:
    """Per record: the flags are neither NUMERIC nor NOT_READY/BAD_ARG, and q is a finite unit quaternion
    (| |q| - 1 | <= 1e-5), the Euler angles, bias and covariance diagonal finite."""
    flags = np.asarray(out["flags"], np.uint32)
    q = np.asarray(out["q"], np.float64)
    with np.errstate(invalid="ignore", over="ignore"):
        unit = np.abs(np.sqrt((q * q).sum(-1)) - 1.0) <= 1e-5
    finite = (
        np.isfinite(q).all(-1)
        & np.isfinite(out["euler"]).all(-1)
        & np.isfinite(out["gyro_bias"]).all(-1)
        & np.isfinite(out["cov"]).all(-1)
    )
    return ((flags & (NUMERIC | INVALID)) == 0) & unit & finite


def samples_to_recover(ok: np.ndarray) -> int | None:
    """The smallest N such that every clean sample from the N-th on (1-based) gives a good output; None
    when the last one is not good."""
    if not ok[-1]:
        return None
    bad = np.nonzero(~ok)[0]
    return int(bad[-1]) + 2 if bad.size else 1


# --- float64 attitudes (the D1 checks of the gyro baseline) -------------------------------------------


def quat_from_euler64(e: Any) -> np.ndarray:
    """ZYX Euler angles (phi, theta, psi), rad, to q = Qz(psi) Qy(theta) Qx(phi) (w, x, y, z), float64."""
    h = 0.5 * np.asarray(e, np.float64)
    cr, sr = np.cos(h[..., 0]), np.sin(h[..., 0])
    cp, sp = np.cos(h[..., 1]), np.sin(h[..., 1])
    cy, sy = np.cos(h[..., 2]), np.sin(h[..., 2])
    return np.stack(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ],
        axis=-1,
    )


def turned64(q: Any, w: Any, dt: float) -> np.ndarray:
    """q * exp(w dt / 2): the attitude q (w, x, y, z) after a constant body rate w (rad/s) over dt."""
    a = np.asarray(q, np.float64)
    v = np.asarray(w, np.float64) * float(dt)
    angle = float(np.linalg.norm(v))
    d = (
        np.array([1.0, 0.0, 0.0, 0.0])
        if angle == 0.0
        else np.r_[math.cos(angle / 2), v / angle * math.sin(angle / 2)]
    )
    return np.array(
        [
            a[0] * d[0] - a[1] * d[1] - a[2] * d[2] - a[3] * d[3],
            a[0] * d[1] + a[1] * d[0] + a[2] * d[3] - a[3] * d[2],
            a[0] * d[2] - a[1] * d[3] + a[2] * d[0] + a[3] * d[1],
            a[0] * d[3] + a[1] * d[2] - a[2] * d[1] + a[3] * d[0],
        ]
    )


def quat_angle(q: Any, r: Any) -> float:
    """The angle (rad) of the rotation between two unit quaternions."""
    a = np.asarray(q, np.float64)
    b = np.asarray(r, np.float64)
    d = abs(float(np.dot(a / np.linalg.norm(a), b / np.linalg.norm(b))))
    return 2.0 * math.acos(min(1.0, d))
