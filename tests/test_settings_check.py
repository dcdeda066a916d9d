"""att_filter_settings_check and the gain/time-constant rule (issue 22, "the C API on a first day").

- The documented main loop (att_filter.h's snippet): the defaults with a time constant set are accepted
  by C and the reference, and give the outputs of the same settings with the gain 0 (the gain beside a
  time constant > 0 is ignored, still range-checked).
- att_filter_settings_check answers what att_filter_settings_validate, att_filter_init and
  att_filter_retune answer, for every kind, over settings with each field pushed to each side of its
  bounds, NaN and +-Inf, and over random perturbations of several fields; the field it names is one
  that was perturbed (or one whose rule names a perturbed field: accel_range's "(gravity, 1e4]");
  the bounds it reports are those enforced.
- The ranges the headers state are the enforced ones, apart from the differences listed in
  STATED_DIFFERS.
- An image that does not call att_filter_settings_check carries none of its names (--gc-sections).
- Python: refused settings raise SettingsError naming the field, its value and range (native.Filter,
  retune, the command line, the node).
"""

from __future__ import annotations

import math
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import attica
from attica import _build, kinds, native, reference
from attica.native import ffi, lib
from attica.reference import detmath as dm
from attica.reference import sensor
from attica.settings import ArsSettings, FilterKind, MarsSettings, Preset
from attica.sim import SimConfig, simulate

from helpers import ROOT, assert_same_bits, need

KINDS = [k.kind for k in kinds.KINDS]
F32 = np.float32


def _f32(x: float) -> float:
    with np.errstate(over="ignore"):
        return float(F32(x))


def _next(x: float, toward: float) -> float:
    return float(np.nextafter(F32(x), F32(toward)))


def _c(kind: FilterKind, dt: float = 0.01, preset: Preset = Preset.DEFAULT, **fields: Any) -> Any:
    s = ffi.new("att_filter_settings_t *")
    assert lib.att_filter_settings_preset(int(kind), int(preset), dt, s) == lib.ATT_OK
    member = getattr(s, kind.label)
    for name, value in fields.items():
        setattr(member, name, value)
    return s


def _copy(s: Any) -> Any:
    t = ffi.new("att_filter_settings_t *")
    ffi.memmove(t, s, ffi.sizeof("att_filter_settings_t"))
    return t


def _leaves(ctype: Any, prefix: str = "") -> list[tuple[str, Any]]:
    """(dotted path, cffi type) of every scalar field of a settings struct (vectors by component)."""
    out: list[tuple[str, Any]] = []
    for name, fld in ctype.fields:
        if fld.type.kind == "struct":
            out += _leaves(fld.type, prefix + name + ".")
        else:
            out.append((prefix + name, fld.type))
    return out


def _put(member: Any, path: str, ctype: Any, value: Any) -> None:
    """Write value into the field at path; bools and enums as raw memory (any byte / int)."""
    *parents, name = path.split(".")
    obj = member
    for p in parents:
        obj = getattr(obj, p)
    if ctype.kind == "primitive" and ctype.cname == "_Bool":
        ffi.cast("unsigned char *", ffi.addressof(obj, name))[0] = value
    elif ctype.kind == "enum":
        ffi.cast("int *", ffi.addressof(obj, name))[0] = value
    else:
        setattr(obj, name, value)


def _get(member: Any, path: str) -> Any:
    obj = member
    for p in path.split("."):
        obj = getattr(obj, p)
    return obj


class Verdict:
    """What check, validate, init, retune and the rule listing say about one settings struct (they must
    agree)."""

    def __init__(self, kind: FilterKind, s: Any) -> None:
        why = ffi.new("att_settings_error_t *")
        why.field = ffi.cast("char *", 1)  # cleared by every call
        self.status = int(lib.att_filter_settings_check(int(kind), s, why))
        assert int(lib.att_filter_settings_validate(int(kind), s)) == self.status
        f = ffi.new("att_filter_t *")
        assert int(lib.att_filter_init(f, int(kind), s)) == self.status
        running = ffi.new("att_filter_t *")
        assert lib.att_filter_init(running, int(kind), _c(kind)) == lib.ATT_OK
        before = bytes(ffi.buffer(running))
        assert int(lib.att_filter_retune(running, s)) == self.status
        if self.status != lib.ATT_OK:
            assert bytes(ffi.buffer(running)) == before
        self.ok = self.status == lib.ATT_OK
        assert self.ok or self.status == lib.ATT_ERR_SETTINGS
        assert (why.field == ffi.NULL) == self.ok
        self.field = "" if self.ok else ffi.string(why.field).decode()
        self.rule = "" if self.ok else ffi.string(why.rule).decode()
        self.unit = "" if self.ok else ffi.string(why.unit).decode()
        self.min, self.max = float(why.min), float(why.max)
        if not self.ok:
            prefix, _, self.name = self.field.partition(".")
            assert prefix == kind.label, self.field
            assert self.rule and math.isfinite(self.min) and not math.isnan(self.max)
        else:
            self.name = ""
        # the listing (att_filter_settings_rule, line by line) refuses first the line check names
        first = None
        r = ffi.new("att_settings_error_t *")
        for line in range(1000):
            st = int(lib.att_filter_settings_rule(int(kind), s, line, r))
            if r.field == ffi.NULL:
                assert st == lib.ATT_OK
                break
            if st != lib.ATT_OK and first is None:
                first = (ffi.string(r.field).decode(), ffi.string(r.rule).decode())
        else:
            pytest.fail("a settings listing of 1,000 lines")
        assert first == (None if self.ok else (self.field, self.rule)), (first, self.field, self.rule)

    def blames(self, perturbed: list[str]) -> bool:
        """The named field is a perturbed one (a vector for its component), or its rule names one."""
        for p in perturbed:
            if self.name == p or p.startswith(self.name + "."):
                return True
            if re.search(rf"\b{re.escape(p.split('.')[0])}\b", self.rule):
                return True
        return False


def _bases(kind: FilterKind) -> list[Any]:
    """Accepted settings to perturb: the presets at a few rates, and the non-default initialisations."""
    out = [_c(kind, dt, p) for p in Preset for dt in (0.01, 1 / 285.714, 0.001)]
    if kind in (FilterKind.MARS, FilterKind.MEKF):
        fixed = {"init_from_sensors": False, "m0_init": (0.0, 20.0, -40.0), "q_init": (0.9, 0.1, 0.0, 0.2)}
        out.append(_c(kind, 0.01, **fixed))
    for s in out:
        assert Verdict(kind, s).ok
    return out


def _bounds(kind: FilterKind, base: Any, path: str, ctype: Any) -> list[float]:
    """Bounds of a float field as reported when it is NaN (its own first check refuses it)."""
    s = _copy(base)
    _put(getattr(s, kind.label), path, ctype, math.nan)
    v = Verdict(kind, s)
    assert not v.ok and (v.name == path or path.startswith(v.name + ".")), (path, v.field)
    return [b for b in (v.min, v.max) if math.isfinite(b)]


def _candidates(kind: FilterKind, base: Any, path: str, ctype: Any) -> list[Any]:
    """Each side of the field's bounds, the bounds, NaN, +-Inf and a few others."""
    if ctype.kind == "primitive" and ctype.cname == "_Bool":
        return [0, 1, 2, 255]
    if ctype.kind == "enum":
        return [-1, 0, 1, 2, 3, 4]
    if ctype.kind == "primitive" and ctype.cname == "uint32_t":
        return [0, 1, 2, 1000, 1 << 24, (1 << 24) + 1, 0xFFFFFFFF]
    vals = [math.nan, math.inf, -math.inf, 0.0, -0.0, 1.0, -1.0, 3.4e38, -3.4e38, 1e-45]
    for b in _bounds(kind, base, path, ctype):
        vals += [b, _next(b, -math.inf), _next(b, math.inf), _f32(b * 0.5), _f32(b * 2.0)]
    return vals


_INTERVAL = re.compile(r"^([\[(])([^,]+), ([^,]+)([\])])$")


def _inside(v: Verdict, value: float) -> bool:
    """value lies in the interval the refusal reported (its rule's brackets, its min and max)."""
    m = _INTERVAL.match(v.rule)
    assert m, v.rule
    lo_ok = value >= v.min if m[1] == "[" else value > v.min
    hi_ok = value <= v.max if m[4] == "]" else value < v.max
    return lo_ok and hi_ok


@pytest.mark.parametrize("kind", KINDS, ids=lambda k: k.label)
def test_check_agrees_with_init_at_every_bound(kind: FilterKind) -> None:
    """Each field alone pushed to each side of its bounds, NaN, +-Inf: the four calls agree, the named field
    is the one pushed (or a field whose rule names it), and a plain range refuses exactly the values outside
    the bounds it reports."""
    cases = refused = 0
    for base in _bases(kind):
        for path, ctype in _leaves(ffi.typeof(getattr(base, kind.label))):
            for value in _candidates(kind, base, path, ctype):
                s = _copy(base)
                _put(getattr(s, kind.label), path, ctype, value)
                v = Verdict(kind, s)
                cases += 1
                if v.ok:
                    continue
                refused += 1
                assert v.blames([path]), (path, value, v.field, v.rule)
                if v.name == path and ctype.kind == "primitive" and ctype.cname == "float":
                    if _INTERVAL.match(v.rule):
                        assert not _inside(v, value), (path, value, v.rule, v.min, v.max)
                        closed = [b for b, c in ((v.min, v.rule[0] == "["), (v.max, v.rule[-1] == "]")) if c]
                        for bound in closed:  # a closed bound it reports passes that rule
                            again = _copy(base)
                            _put(getattr(again, kind.label), path, ctype, bound)
                            w = Verdict(kind, again)
                            assert (w.name, w.rule) != (path, v.rule), (path, bound, v.rule)
    assert refused > cases // 4 and refused < cases, (refused, cases)


@pytest.mark.parametrize("kind", KINDS, ids=lambda k: k.label)
def test_check_agrees_with_init_on_random_settings(kind: FilterKind) -> None:
    """Random perturbations of one to four fields (values from every field's pool): the calls agree and the
    named field is a perturbed one (or its rule names one)."""
    rng = np.random.default_rng(22 + int(kind))
    bases = _bases(kind)
    fields = _leaves(ffi.typeof(getattr(bases[0], kind.label)))
    pools = {(i, p): _candidates(kind, b, p, t) for i, b in enumerate(bases) for p, t in fields}
    seen = {True: 0, False: 0}
    for _ in range(4000):
        i = int(rng.integers(len(bases)))
        s = _copy(bases[i])
        size = min(int(rng.integers(1, 5)), len(fields))
        picked = [fields[int(j)] for j in rng.choice(len(fields), size=size, replace=False)]
        for path, ctype in picked:
            pool = pools[(i, path)]
            value = pool[int(rng.integers(len(pool)))]
            if ctype.kind == "primitive" and ctype.cname == "float" and rng.random() < 0.3:
                value = _f32(float(value) * float(10.0 ** rng.uniform(-1, 1)))  # Inf stays, NaN stays
            _put(getattr(s, kind.label), path, ctype, value)
        v = Verdict(kind, s)
        seen[v.ok] += 1
        if not v.ok:
            assert v.blames([p for p, _ in picked]), ([p for p, _ in picked], v.field, v.rule)
    assert seen[True] > 50 and seen[False] > 50, seen


def test_check_bad_calls() -> None:
    why = ffi.new("att_settings_error_t *")
    s = _c(FilterKind.ARS)
    assert lib.att_filter_settings_check(99, s, why) == lib.ATT_ERR_KIND and why.field == ffi.NULL
    assert lib.att_filter_settings_check(0, s, why) == lib.ATT_ERR_KIND
    assert lib.att_filter_settings_check(int(FilterKind.ARS), ffi.NULL, why) == lib.ATT_ERR_NULL
    assert lib.att_filter_settings_check(int(FilterKind.ARS), s, ffi.NULL) == lib.ATT_OK
    s.ars.tau_acc_lp = -1.0
    assert lib.att_filter_settings_check(int(FilterKind.ARS), s, ffi.NULL) == lib.ATT_ERR_SETTINGS
    assert lib.att_filter_settings_check(int(FilterKind.ARS), s, why) == lib.ATT_ERR_SETTINGS
    assert ffi.string(why.field) == b"ars.tau_acc_lp" and ffi.string(why.rule) == b"[0, 1e4]"
    assert (why.min, why.max, ffi.string(why.unit)) == (0.0, 10000.0, b"s")


# --- the gain beside a time constant (item 1) -------------------------------------------------------


def _stream() -> tuple[Any, Any, Any]:
    """1000 samples at 285.714 Hz in motion (rotation, translation, taps)."""
    rec = simulate(SimConfig(duration=12.0, rate=285.714, seed=3))
    part = slice(800, 1800)
    return rec.gyr[part], rec.acc[part], rec.mag[part]


def _c_run(kind: FilterKind, s: Any, gyr: Any, acc: Any, mag: Any) -> np.ndarray:
    f = ffi.new("att_filter_t *")
    assert lib.att_filter_init(f, int(kind), s) == lib.ATT_OK
    sample = ffi.new("att_sample_t *")
    out = ffi.new("att_output_t *")
    q = np.empty((len(gyr), 4), np.float32)
    for i in range(len(gyr)):
        for name, row in (("gyr", gyr[i]), ("acc", acc[i]), ("mag", mag[i])):
            v = getattr(sample, name)
            v.x, v.y, v.z = (float(c) for c in row)
        lib.att_filter_step(f, sample, out)
        q[i] = (out.q.w, out.q.x, out.q.y, out.q.z)
    return q


def test_header_snippet_is_accepted_and_the_gain_ignored() -> None:
    """att_filter.h's main loop: defaults, then s.ars.tau = 1.0f (gain left at its default 1): init accepts
    it (it refused it before issue 22) and the outputs are those with gain 0; the reference agrees."""
    gyr, acc, mag = _stream()
    s = _c(FilterKind.ARS, 0.0035)
    s.ars.tau = 1.0
    assert s.ars.gain == 1.0
    assert Verdict(FilterKind.ARS, s).ok
    zero = _copy(s)
    zero.ars.gain = 0.0
    q = _c_run(FilterKind.ARS, s, gyr, acc, mag)
    assert_same_bits(q, _c_run(FilterKind.ARS, zero, gyr, acc, mag), "ars tau 1 gain 1 vs gain 0")
    for gain in (0.3, 1.0):
        r = reference.Filter("ars", 0.0035, gain=gain, tau=1.0)  # refused (SettingsConflictError) before
        assert_same_bits(r.run(gyr, acc, check_units=False)["q"], q, f"reference gain {gain}")
        assert_same_bits(native.Filter("ars", 0.0035, gain=gain, tau=1.0).run_q(gyr, acc), q, "native")
    # the gain is still range-checked when unused
    for bad in (1.5, -0.1, math.nan, math.inf):
        t = _copy(s)
        t.ars.gain = bad
        v = Verdict(FilterKind.ARS, t)
        assert not v.ok and v.field == "ars.gain" and v.rule == "[0, 1]"


@pytest.mark.parametrize(("gain", "tau"), [("alpha_acc", "tau_acc"), ("alpha_mag", "tau_mag")])
def test_mars_gain_beside_time_constant_is_ignored(gain: str, tau: str) -> None:
    gyr, acc, mag = _stream()
    s = _c(FilterKind.MARS, 0.0035, **{tau: 0.5, gain: 0.25})
    assert Verdict(FilterKind.MARS, s).ok  # refused before issue 22
    zero = _copy(s)
    setattr(zero.mars, gain, 0.0)
    q = _c_run(FilterKind.MARS, s, gyr, acc, mag)
    assert_same_bits(q, _c_run(FilterKind.MARS, zero, gyr, acc, mag), f"mars {gain} beside {tau}")
    r = reference.Filter("mars", 0.0035, **{tau: 0.5, gain: 0.25})
    assert_same_bits(r.run(gyr, acc, mag, check_units=False)["q"], q, "reference")
    setattr(s.mars, gain, 2.0)
    v = Verdict(FilterKind.MARS, s)
    assert not v.ok and v.field == f"mars.{gain}"


# --- the headers' stated ranges -------------------------------------------------------------------

STATED_DIFFERS: dict[str, str] = {}
"""Fields whose enforced range is not the one their header states. Empty since issue 26 (R2: mars and
mekf checked m0_init per component, up to sqrt(3) mag_range; R3: kf and ekf with noise_rates also
range-checked q dt and r / dt): keep it so."""

_STATED = re.compile(r"([\[(])\s*([-\w.^/]+),\s*([-\w.^/]+)\s*([\])])")


def _stated_ranges(kind: FilterKind) -> dict[str, tuple[str, str, str, str]]:
    """Field -> the first bracketed range of its comment in att_<kind>.h (both bounds one token)."""
    text = (ROOT / "firmware" / "include" / "attica" / f"att_{kind.label}.h").read_text()
    m = re.search(
        rf"typedef struct \{{((?:(?!typedef struct).)*?)\}} att_{kind.label}_settings_t;", text, re.S
    )
    assert m
    out: dict[str, tuple[str, str, str, str]] = {}
    name = ""
    comment: dict[str, str] = {}
    for line in m.group(1).splitlines():
        d = re.match(r"\s*\w+\s+(\w+);\s*/\*\*<(.*)", line)
        if d:
            name = d.group(1)
            comment[name] = d.group(2)
        elif name:
            comment[name] += " " + line.strip()
    for name, doc in comment.items():
        r = _STATED.search(doc)
        if r:
            out[name] = (r[1], r[2], r[3], r[4])
    return out


def _stated_value(token: str, member: Any) -> float | None:
    """A bound of a stated range as a float32: a number, 2^k, pi, pi/2, a field's value or a macro."""
    sign = -1.0 if token.startswith("-") else 1.0
    t = token.lstrip("-")
    consts = {"pi": math.pi, "pi/2": math.pi / 2}
    if t in consts:
        return _f32(sign * consts[t])
    if re.fullmatch(r"2\^-?\d+", t):
        return _f32(sign * 2.0 ** int(t[2:]))
    if re.fullmatch(r"[\d.]+(e-?\d+)?", t):
        return _f32(sign * float(t))
    if t.startswith("ATT_"):
        header = (ROOT / "firmware" / "include" / "attica" / "att_mekf.h").read_text()
        macro = re.search(rf"#define {t} ([\d.]+)f", header)
        return _f32(sign * float(macro[1])) if macro else None
    if hasattr(member, t):
        return _f32(sign * float(getattr(member, t)))
    return None


@pytest.mark.parametrize("kind", KINDS, ids=lambda k: k.label)
def test_stated_ranges_are_enforced(kind: FilterKind) -> None:
    """Every scalar field with a range in its header comment ("[0, 1e4]", "(gravity, 1e4]"): its bounds
    are accepted or refused as the brackets say, one float beyond each is refused, naming the field."""
    base = _c(kind)
    member = getattr(base, kind.label)
    types = dict(_leaves(ffi.typeof(member)))
    differs = set()
    checked = 0
    for name, (open_, lo_t, hi_t, close) in _stated_ranges(kind).items():
        ctype = types.get(name)
        lo, hi = _stated_value(lo_t, member), _stated_value(hi_t, member)
        if ctype is None or lo is None or hi is None:
            continue  # a vector or quaternion (m0_init: below), or a comment's aside in brackets
        integer = ctype.cname == "uint32_t"
        probes = [(lo, open_ == "["), (hi, close == "]")]
        probes += [((lo - 1) if integer else _next(lo, -math.inf), False)] if lo > 0 or not integer else []
        probes += [((hi + 1) if integer else _next(hi, math.inf), False)]
        for value, accepted in probes:
            s = _copy(base)
            _put(getattr(s, kind.label), name, ctype, int(value) if integer else value)
            v = Verdict(kind, s)
            if (v.name == name) == accepted:  # refused where the header accepts, or accepted where it refuses
                differs.add(f"{kind.label}.{name}")
        checked += 1
    # m0_init: stated "zero = ...; else |m0_init| in [1e-3, mag_range]" (a vector: probed here)
    if kind in (FilterKind.MARS, FilterKind.MEKF):
        r = float(member.mag_range)
        for m0, accepted in (
            ((r, 0.0, 0.0), True),
            ((0.0, 0.0, -1e-3), True),
            ((0.0, 0.0, 0.0), True),
            ((r, r, 0.0), False),  # |m0_init| = sqrt(2) mag_range, each component within it
            ((_next(r, math.inf), 0.0, 0.0), False),
            ((0.0, _next(1e-3, 0.0), 0.0), False),
        ):
            s = _copy(base)
            getattr(s, kind.label).m0_init = m0
            v = Verdict(kind, s)
            if v.ok != accepted or (not v.ok and v.name != "m0_init"):
                differs.add(f"{kind.label}.m0_init")
    assert checked >= 2
    expected = {k for k in STATED_DIFFERS if k.startswith(kind.label + ".")}
    assert differs == expected, sorted(differs ^ expected)


@pytest.mark.parametrize("kind", [FilterKind.MARS, FilterKind.MEKF], ids=lambda k: k.label)
def test_m0_init_is_checked_by_its_norm(kind: FilterKind) -> None:
    """Issue 26 R2: m0_init was checked per component, so |m0_init| up to sqrt(3) mag_range passed, and every
    magnetometer sample (|m| <= mag_range) was then rejected against it. Now a non-zero m0_init is accepted
    exactly when sqrtf(m0 . m0) is in [1e-3, mag_range], computed as the reference's (and C's) mag sample
    check measures |m|: an accepted reference field is a sample the filter takes as within range. Random
    vectors on both sides of both spheres, at several ranges (among them 1e5, the largest)."""
    rng = np.random.default_rng(26)
    base = _c(kind, 0.01, init_from_sensors=False, q_init=(1.0, 0.0, 0.0, 0.0))
    member = getattr(base, kind.label)
    seen = {True: 0, False: 0}
    for mag_range in (1000.0, 48.5, 0.01, 1e5):
        member.mag_range = mag_range
        r = float(F32(mag_range))
        d = rng.normal(size=(300, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        radius = np.concatenate(
            [r * (1 + rng.uniform(-3e-7, 3e-7, 200)), 1e-3 * (1 + rng.uniform(-3e-7, 3e-7, 100))]
        )
        vecs = (d * radius[:, None]).astype(F32)
        vecs[:8] = F32(r / math.sqrt(3)) * np.sign(rng.normal(size=(8, 3))).astype(F32)  # |m| ~ mag_range
        vecs[8:12] = F32(r)  # |m0_init| = sqrt(3) mag_range, each component at it: accepted before the fix
        with np.errstate(all="ignore"):
            v3 = (vecs[:, 0], vecs[:, 1], vecs[:, 2])
            norm = dm.sqrtf(dm.vec3_dot(v3, v3))
            flags, _ = sensor.check_mag(v3, F32(mag_range))
        for k, v in enumerate(vecs):
            s = _copy(base)
            getattr(s, kind.label).m0_init = tuple(float(x) for x in v)
            verdict = Verdict(kind, s)
            expected = bool(norm[k] >= F32(1e-3) and norm[k] <= F32(mag_range))
            assert verdict.ok == expected, (mag_range, v, float(norm[k]))
            assert verdict.ok or (verdict.name, verdict.min, verdict.max) == ("m0_init", float(F32(1e-3)), r)
            if norm[k] >= F32(1e-3):  # the sample check of the same vector agrees (range only)
                assert verdict.ok == (int(flags[k]) == 0), (mag_range, v)
            seen[verdict.ok] += 1
    assert seen[True] > 300 and seen[False] > 300, seen
    # the case: an accepted reference field, and samples of its own norm are used (none rejected as
    # beyond the range)
    s = _copy(base)
    getattr(s, kind.label).m0_init = (30.0, 0.0, -40.0)
    getattr(s, kind.label).mag_range = 50.0
    assert Verdict(kind, s).ok
    getattr(s, kind.label).m0_init = (40.0, 0.0, -40.0)  # |m0| 56.6 > 50, components within it
    v = Verdict(kind, s)
    assert (
        not v.ok
        and v.field == f"{kind.label}.m0_init"
        and v.rule == "zero, or |m0_init| in [1e-3, mag_range]"
    )


# --- the names stay out of the images that do not ask --------------------------------------------


def test_names_are_linked_only_when_asked(tmp_path: Path) -> None:
    """A host image built like a firmware image (-ffunction-sections -fdata-sections --gc-sections) that
    calls att_filter_init holds none of the check's names; one that calls att_filter_settings_check does."""
    cc = shutil.which("cc") or shutil.which("gcc")
    need(cc is not None, "no C compiler")
    assert cc is not None
    main = tmp_path / "main.c"
    main.write_text(
        '#include <stdio.h>\n#include "attica/att_filter.h"\n'
        "static att_filter_t f;\n"
        "int main(void)\n{\n    att_filter_settings_t s;\n    att_settings_error_t why;\n"
        "    att_filter_settings_default(ATT_FILTER_ARS, 0.01f, &s);\n    s.ars.tau = 1.0f;\n"
        "    if (att_filter_init(&f, ATT_FILTER_ARS, &s) != ATT_OK) { return 1; }\n"
        "#ifdef ASK\n    s.ars.tau_acc_lp = -1.0f;\n"
        "    if (att_filter_settings_check(ATT_FILTER_ARS, &s, &why) == ATT_ERR_SETTINGS) {\n"
        '        printf("%s %s\\n", why.field, why.rule);\n    }\n#else\n    (void)why;\n#endif\n'
        "    return 0;\n}\n"
    )
    sources = [str(p) for p in _build.firmware_sources() if "node" not in p.parts and "can" not in p.parts]
    flags = [*_build.cflags(), "-Os", "-ffunction-sections", "-fdata-sections"]
    flags += ["-I", str(ROOT / "firmware" / "include")]
    images = {}
    for name, extra in (("plain", []), ("ask", ["-DASK"])):
        exe = tmp_path / name
        cmd = [cc, *flags, *extra, str(main), *sources, "-Wl,--gc-sections", "-lm", "-o", str(exe)]
        subprocess.run(cmd, check=True, capture_output=True, text=True)
        images[name] = exe.read_bytes()
    run = subprocess.run([str(tmp_path / "ask")], capture_output=True, text=True, check=True)
    assert run.stdout == "ars.tau_acc_lp [0, 1e4]\n"
    subprocess.run([str(tmp_path / "plain")], check=True)
    for text in (b"ars.tau_acc_lp", b"mekf.m0_init", b"(gravity, 1e4]"):
        assert text not in images["plain"], text
        assert text in images["ask"], text


# --- Python: the error names the field --------------------------------------------------------------


def test_python_error_names_the_field_and_range() -> None:
    with pytest.raises(
        attica.SettingsError, match=r"att_filter_init\(ars\): ars\.tau_acc_lp = -1\.0 .*\[0, 1e4\] s"
    ):
        native.Filter("ars", 0.01, tau_acc_lp=-1.0)
    with pytest.raises(
        ValueError, match=r"mars\.accel_range = 5\.0 .*\(gravity, 1e4\] m/s\^2, here \(9\.80665, "
    ):
        native.Filter("mars", 0.01, accel_range=5.0)
    with pytest.raises(native.NativeError, match=r"ekf\.euler_init\.y = 2\.0 .*\[-pi/2, pi/2\] rad"):
        native.Filter("ekf", 0.01, euler_init=(0.0, 2.0, 0.0), init_from_accel=False)
    f = native.Filter("ars", 0.01)
    before = bytes(f.state)
    with pytest.raises(native.SettingsError, match=r"att_filter_retune\(ars\): ars\.gain = 1\.5") as info:
        f.retune(gain=1.5, tau=0.2)  # an unused gain is still range-checked
    assert bytes(f.state) == before
    e = info.value
    assert (e.field, e.value, e.minimum, e.maximum) == ("ars.gain", 1.5, 0.0, 1.0)
    assert (e.rule, e.unit) == ("[0, 1]", "")
    assert native.settings_problem("mekf", attica.MekfSettings()) is None
    p = native.settings_problem(FilterKind.MEKF, attica.MekfSettings(q_init=(0.0, 0.0, 0.0, 0.0)))
    assert p is not None and p.field == "mekf.q_init" and p.value == (0.0, 0.0, 0.0, 0.0)
    assert native.settings_problem("ars", ArsSettings(gain=0.5, tau=2.0)) is None
    assert native.settings_problem("mars", MarsSettings(alpha_mag=0.5)) is None  # tau_mag 20 s by default


def test_cli_and_node_name_the_field() -> None:
    from attica.can.node import Node, NodeError
    from attica.commands._common import CliError, filter_settings

    with pytest.raises(
        CliError, match=r"ars\.rest_gyro = 1\.0 is out of range: allowed \[0, gyro_range\] rad/s"
    ):
        filter_settings(FilterKind.ARS, 100.0, {"rest_gyro": 1.0, "gyro_range": 0.5})
    assert filter_settings(FilterKind.ARS, 100.0, {"gain": 0.3, "tau": 0.5}).gain == 0.3
    with pytest.raises(NodeError, match=r"att_node_init: .*ars\.tau_acc_lp = -1\.0"):
        Node("ars", sample_rate=100.0, tau_acc_lp=-1.0)
    Node("ars", sample_rate=100.0, gain=0.3, tau=0.5)  # refused (SettingsConflictError) before issue 22


@pytest.mark.parametrize("kind", list(FilterKind), ids=lambda k: k.label)
def test_a_preset_writes_the_whole_union(kind: FilterKind) -> None:
    """att_filter_settings_default and _preset clear the union before the kind's member: the bytes past it
    are 0 whatever the caller's memory held, so an image compared or saved byte by byte (the node's
    persisted configuration, examples/c/persist) is the same every time. Before stop 47 the node's
    SELECT of a kind smaller than the largest member left stack bytes there."""
    member = ffi.sizeof(f"att_{kind.label}_settings_t")
    for preset in (lib.ATT_PRESET_DEFAULT, lib.ATT_PRESET_SEED):
        images = []
        for fill in (b"\xaa", b"\x55"):
            s = ffi.new("att_filter_settings_t *")
            ffi.memmove(s, fill * ffi.sizeof(s[0]), ffi.sizeof(s[0]))
            assert lib.att_filter_settings_preset(int(kind), preset, 0.01, s) == lib.ATT_OK
            images.append(bytes(ffi.buffer(s)))
            tail = images[-1][member:]
            assert tail == b"\0" * len(tail), (kind.label, preset)
        assert images[0] == images[1], f"{kind.label}: the member's padding too is cleared"
        s = ffi.new("att_filter_settings_t *")
        ffi.memmove(s, b"\xaa" * ffi.sizeof(s[0]), ffi.sizeof(s[0]))
        assert lib.att_filter_settings_preset(int(kind), 7, 0.01, s) == lib.ATT_ERR_KIND
        assert bytes(ffi.buffer(s)) == b"\xaa" * ffi.sizeof(s[0]), "untouched on an error"
