"""One source for the settings contracts (issue 26).

The firmware writes each contract once, as a table of checks (ATT_<KIND>_CHECKS, ATT_CALIB_CHECKS,
ATT_NODE_CHECKS); the validators, the checks that name a field and the listings (att_filter_settings_rule,
att_calib_settings_rule, att_node_settings_rule; attica.contract) are expanded from it. Here everything
else that states a range is tested against that listing:

- the public headers' field comments carry each line's rule and unit word for word (a checked copy);
- every field of every settings struct has a line (no field unchecked), and the Python settings classes
  mirror the structs (names; the enums' names and values are those the rules state);
- ``attica settings`` prints the listing and marks refused values; ``attica run --set``'s help points at it;
- docs/settings.md is the listing (``make docs-figures`` writes it);
- the stages' and the node's lines are probed on both sides of each bound, at NaN, +-Inf and denormals:
  the line, att_calib_settings_check / att_node_settings_check, att_filter_calibrate and att_node_init
  agree (the kinds' fields: tests/test_settings_check.py::test_check_agrees_with_init_at_every_bound).
"""

from __future__ import annotations

import enum
import inspect
import math
import re
from dataclasses import fields, replace
from typing import Any

import numpy as np
import pytest

from attica import contract, kinds
from attica.calibration.stages import StageSettings, fill_c
from attica.can.node import Node
from attica.cli import main
from attica.commands import settings as settings_cmd
from attica.native import ffi, lib
from attica.settings import FilterKind

from helpers import ROOT

KINDS = [k.kind for k in kinds.KINDS]
HEADERS = ROOT / "firmware" / "include" / "attica"
F32 = np.float32


def _comments(text: str, struct: str) -> dict[str, str]:
    """Field -> its ``/**< ... */`` comment (whitespace folded) in ``typedef struct { ... } struct;``."""
    m = re.search(rf"typedef struct \{{((?:(?!typedef struct).)*?)\}} {struct};", text, re.S)
    assert m, struct
    out: dict[str, str] = {}
    for d in re.finditer(r"(\w+)(?:\[\d+\])?;\s*/\*\*<(.*?)\*/", m.group(1), re.S):
        out[d.group(1)] = " ".join(d.group(2).split())
    return out


def _c_leaves(ctype: Any, prefix: str = "") -> list[tuple[str, Any]]:
    """(dotted path, type) of every scalar of a C struct, vectors and quaternions as one leaf."""
    out: list[tuple[str, Any]] = []
    for name, f in ctype.fields:
        path = f"{prefix}{name}"
        t = f.type
        if t.kind == "struct" and t.cname not in ("att_vec3_t", "att_quat_t"):
            out += _c_leaves(t, path + ".")
        else:
            out.append((path, t))
    return out


def _is_bool(ctype: Any) -> bool:
    return ctype.kind == "primitive" and ctype.cname == "_Bool"


def _covered(path: str, names: set[str]) -> bool:
    return any(path == n or path.startswith(n + ".") or n.startswith(path + ".") for n in names)


# --- the headers, the structs and the Python classes ---------------------------------------------------


@pytest.mark.parametrize("kind", KINDS, ids=lambda k: k.label)
def test_header_comments_state_each_rule(kind: FilterKind) -> None:
    """att_<kind>.h: each field's comment holds its lines' rules and units word for word (a bool's "0 or 1"
    is its type)."""
    com = _comments((HEADERS / f"att_{kind.label}.h").read_text(), f"att_{kind.label}_settings_t")
    types = dict(_c_leaves(ffi.typeof(f"att_{kind.label}_settings_t")))
    missing = []
    for r in contract.filter_rules(kind):
        root = r.name.split(".")[0]
        if _is_bool(types.get(root, ffi.typeof("float"))) and r.rule == "0 or 1 (bool)":
            continue
        doc = com.get(root, "")
        if r.rule not in doc or (r.unit and r.unit not in doc):
            missing.append(f"{r.field}: {r.text!r} not in {doc!r}")
    assert not missing, "\n".join(missing)


def test_calib_and_node_header_comments_state_each_rule() -> None:
    """att_calib.h (the models' structs and att_calib_settings_t) and att_node.h (att_node_settings_t)."""
    calib = (HEADERS / "att_calib.h").read_text()
    com = {
        "gyro": _comments(calib, "att_calib_inertial_t"),
        "accel": _comments(calib, "att_calib_inertial_t"),
        "mag": _comments(calib, "att_calib_mag_t"),
        "": _comments(calib, "att_calib_settings_t"),
    }
    node = _comments((HEADERS / "att_node.h").read_text(), "att_node_settings_t")
    missing = []
    for r in contract.calib_rules():
        part, _, leaf = r.name.rpartition(".")
        doc = com[part].get(leaf, "")
        if r.rule != "0 or 1 (bool)" and (r.rule not in doc or (r.unit and r.unit not in doc)):
            missing.append(f"{r.field}: {r.text!r} not in {doc!r}")
    for r in contract.node_rules():
        doc = node.get(r.name, "")
        if r.rule != "0 or 1 (bool)" and (r.rule not in doc or (r.unit and r.unit not in doc)):
            missing.append(f"{r.field}: {r.text!r} not in {doc!r}")
    assert not missing, "\n".join(missing)


@pytest.mark.parametrize("kind", KINDS, ids=lambda k: k.label)
def test_every_field_has_a_rule_and_python_mirrors_it(kind: FilterKind) -> None:
    """Every field of att_<kind>_settings_t has a line; the settings dataclass has exactly the struct's
    fields; a Python enum field's names and values are those its rule states ("OFF (0), FROZEN (1) ...")."""
    rules = contract.filter_rules(kind)
    names = {r.name for r in rules}
    leaves = _c_leaves(ffi.typeof(f"att_{kind.label}_settings_t"))
    assert [p for p, _ in leaves if not _covered(p, names)] == []
    assert names <= {p for p, _ in leaves} | {f"{p}.{c}" for p, _ in leaves for c in "xyz"}
    cls = kinds.info(kind).settings_class
    assert [f.name for f in fields(cls)] == [n for n, _ in ffi.typeof(f"att_{kind.label}_settings_t").fields]
    by_name = {r.name: r for r in rules}
    enums = 0
    for f in fields(cls):
        default = getattr(cls(), f.name)
        if isinstance(default, enum.IntEnum):
            stated = set(re.findall(r"([A-Z_]+) \((\d+)\)", by_name[f.name].rule))
            members = {(m.name, str(m.value)) for m in type(default)}
            assert stated and stated <= members, (f.name, by_name[f.name].rule, members)
            enums += 1
    assert enums == sum(1 for _, t in leaves if t.kind == "enum")


def test_calib_and_node_fields_have_rules_and_python_mirrors_them() -> None:
    """Every field of att_calib_settings_t and att_node_settings_t (but the filter's and the calibration
    inside the node's) has a line; StageSettings and Node take each of them."""
    names = {r.name for r in contract.calib_rules()}
    leaves = [p for p, _ in _c_leaves(ffi.typeof("att_calib_settings_t"))]
    assert [p for p in leaves if not _covered(p, names)] == []
    py = {f.name for f in fields(StageSettings)}
    assert {p.replace("mag.", "").replace(".", "_") for p in leaves} == py
    node = {r.name for r in contract.node_rules()}
    own = [n for n, _ in ffi.typeof("att_node_settings_t").fields if n not in ("kind", "filter", "calib")]
    assert sorted(set(own)) == sorted(node)
    assert set(own) <= set(inspect.signature(Node).parameters)


# --- the command line and the docs ---------------------------------------------------------------------


def test_attica_settings_prints_the_contract(capsys: pytest.CaptureFixture[str]) -> None:
    """Every line, its value and rule; --set marks a refused field (exit 1); run --set's help points here."""
    assert main(["settings", "mars", "calib", "node"]) == 0
    out = capsys.readouterr().out
    for r in contract.filter_rules("mars") + contract.calib_rules() + contract.node_rules():
        assert re.search(rf"^  {re.escape(r.name)} +\S.*  {re.escape(r.text)}", out, re.M), r
    assert "(here (9.80665, 10000])" in out  # accel_range's bound named after gravity, with its value
    assert main(["settings", "ekf", "--set", "cos_min=2", "--set", "tau_acc_lp=0.25"]) == 1
    lines = capsys.readouterr().out.splitlines()
    refused = [ln.split()[0] for ln in lines if ln.endswith("(REFUSED)")]
    assert refused == ["cos_min"]
    assert any(ln.split()[:2] == ["tau_acc_lp", "0.25"] for ln in lines)
    assert main(["settings", "mekf", "--set", "gyro_scale_init=0.05", "--dt", "0.001"]) == 0
    assert re.search(r"^  dt +0\.001 +\[1e-6, 1\] s$", capsys.readouterr().out, re.M)
    for bad in (["settings", "nope"], ["settings", "node", "--set", "x=1"], ["settings", "ars", "--dt", "2"]):
        assert main(bad) == 2
        assert capsys.readouterr().err.startswith("attica: error: ")
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    assert "attica settings KIND" in " ".join(capsys.readouterr().out.split())


def test_docs_settings_md_is_the_contract() -> None:
    """docs/settings.md holds ``attica settings all --markdown`` between its markers (make docs-figures)."""
    text = (ROOT / "docs" / "settings.md").read_text()
    m = re.search(r"<!-- settings: begin -->\n(.*?)<!-- settings: end -->", text, re.S)
    assert m, "docs/settings.md has no settings markers"
    tables = settings_cmd.contracts(["all"], 0.01, {})
    assert m.group(1) == "\n".join(settings_cmd.render_markdown(tables)) + "\n", "run make docs-figures"


# --- the stages and the node, probed ---------------------------------------------------------------------


def _next(x: float, toward: float) -> float:
    return float(np.nextafter(F32(x), F32(toward)))


def _calib_verdict(st: StageSettings) -> tuple[str | None, int, str | None, str | None]:
    """(first failing line of the listing, att_calib_settings_check's code, the node's refused field,
    att_filter_calibrate's verdict)."""
    failing = [r.field for r in contract.calib_rules(st) if not r.holds]
    cs = ffi.new("att_calib_settings_t *")
    fill_c(cs, st)
    code = int(lib.att_calib_settings_check(cs))
    s = ffi.new("att_node_settings_t *")
    assert lib.att_node_settings_default(int(FilterKind.ARS), 100.0, s) == lib.ATT_OK
    fill_c(s.calib, st)
    why = ffi.new("att_settings_error_t *")
    status = int(lib.att_node_settings_check(s, why))
    node = ffi.string(why.field).decode() if status == lib.ATT_ERR_SETTINGS else None
    f = ffi.new("att_filter_t *")
    fs = ffi.new("att_filter_settings_t *")
    assert lib.att_filter_settings_default(int(FilterKind.ARS), 0.01, fs) == lib.ATT_OK
    assert lib.att_filter_init(f, int(FilterKind.ARS), fs) == lib.ATT_OK
    cal = int(lib.att_filter_calibrate(f, cs))
    return (failing[0] if failing else None), code, node, ("ok" if cal == lib.ATT_OK else "refused")


CALIB_CODES = {
    "calib.gyro.misalignment": 2,
    "calib.gyro.sensitivity": 3,
    "calib.gyro.offset": 4,
    "calib.accel.misalignment": 5,
    "calib.accel.sensitivity": 6,
    "calib.accel.offset": 7,
    "calib.mag.soft_iron": 8,
    "calib.mag.hard_iron": 9,
    "calib.remap": 10,
    "calib.mounting": 11,
    "calib.convention": 12,
    "calib.gravity": 13,
    "calib.accel_outputs": 14,
}
"""att_calib_error_t of each line (att_calib.h)."""

DENORMAL = 1e-45
SPECIALS = (math.nan, math.inf, -math.inf)


def _vector_cases(lo: float, hi: float, lo_open: bool) -> list[tuple[float, bool]]:
    """(component value, accepted) on both sides of [lo, hi] / (lo, hi], NaN, +-Inf, denormals."""
    cases = [(hi, True), (_next(hi, math.inf), False), (lo, not lo_open), (_next(lo, -math.inf), False)]
    cases += [(_next(lo, math.inf), True), (DENORMAL, lo < DENORMAL), (-DENORMAL, lo < -DENORMAL)]
    cases += [(v, False) for v in SPECIALS]
    return cases


def test_calib_lines_probed_at_their_bounds() -> None:
    """Each stage field alone on both sides of its bounds, at NaN, +-Inf and denormals (each component of a
    vector, each entry of a matrix): the listing, the code, the node and att_filter_calibrate agree."""
    base = StageSettings()
    cases: list[tuple[StageSettings, str | None]] = []
    vec_fields = {
        "gyro_sensitivity": ("calib.gyro.sensitivity", 0.0, 1e3, True),
        "accel_sensitivity": ("calib.accel.sensitivity", 0.0, 1e3, True),
        "gyro_offset": ("calib.gyro.offset", -1e3, 1e3, False),
        "accel_offset": ("calib.accel.offset", -1e4, 1e4, False),
        "hard_iron": ("calib.mag.hard_iron", -1e5, 1e5, False),
    }
    for name, (field, lo, hi, lo_open) in vec_fields.items():
        for i in range(3):
            for value, ok in _vector_cases(lo, hi, lo_open):
                v = list(getattr(base, name))
                v[i] = value
                cases.append((replace(base, **{name: tuple(v)}), None if ok else field))
    for name, field in (
        ("gyro_misalignment", "calib.gyro.misalignment"),
        ("accel_misalignment", "calib.accel.misalignment"),
        ("soft_iron", "calib.mag.soft_iron"),
    ):
        big = (1e3, 0.0, 0.0, 0.0, 1e3, 0.0, 0.0, 0.0, 1e3)  # entries at the bound, condition 1
        for i in range(9):
            diagonal = i in (0, 4, 8)  # a denormal there makes the matrix singular
            for value, ok in [
                (1e3, True),
                (_next(1e3, math.inf), False),
                (-1e3, True),
                (DENORMAL, not diagonal),
            ]:
                m = list(big)
                m[i] = value
                cases.append((replace(base, **{name: tuple(m)}), None if ok else field))
            for value in SPECIALS:
                m = list(getattr(base, name))
                m[i] = value
                cases.append((replace(base, **{name: tuple(m)}), field))
        cases.append((replace(base, **{name: (0.0,) * 9}), field))  # singular
        cases.append((replace(base, **{name: (1.0, 0, 0, 0, 1.0, 0, 0, 0, 1e-4)}), field))  # condition 1e4
        cases.append((replace(base, **{name: (1.0, 0, 0, 0, 1.0, 0, 0, 0, 1e-3)}), None))  # condition ~1e3
    for remap, ok in ((0, True), (1, True), (24, True), (25, False), (0xFFFFFFFF, False)):
        cases.append((replace(base, remap=remap), None if ok else "calib.remap"))
    for w, ok in ((0.9985, True), (0.998, False), (1.0014, True), (1.0015, False), (DENORMAL, False)):
        cases.append((replace(base, mounting=(w, 0.0, 0.0, 0.0)), None if ok else "calib.mounting"))
    for value in SPECIALS:
        cases.append((replace(base, mounting=(1.0, value, 0.0, 0.0)), "calib.mounting"))
        cases.append((replace(base, remap=3, mounting=(value, 0.0, 0.0, 0.0)), None))  # the remap decides
    for conv, ok in ((0, True), (1, True), (2, True), (3, False)):
        cases.append((replace(base, convention=conv), None if ok else "calib.convention"))
    for g, ok in (
        (1.0, True),
        (100.0, True),
        (_next(1.0, 0.0), False),
        (_next(100.0, 1e3), False),
        (DENORMAL, False),
    ):
        cases.append((replace(base, gravity=g), None if ok else "calib.gravity"))
    for value in SPECIALS:
        cases.append((replace(base, gravity=value), "calib.gravity"))
    wrong = []
    for st, expect in cases:
        line, code, node, cal = _calib_verdict(st)
        want = (expect, CALIB_CODES[expect] if expect else 0, expect, "refused" if expect else "ok")
        if (line, code, node, cal) != want:
            wrong.append((st, (line, code, node, cal), want))
    assert not wrong, wrong[:3]
    assert len(cases) > 250


NODE_CASES: list[tuple[str, Any, bool]] = [
    ("sample_rate", 100000.0, True),
    ("sample_rate", _next(100000.0, math.inf), False),
    ("sample_rate", 0.0, False),
    ("sample_rate", DENORMAL, True),  # the node's line holds; the filter's dt then refuses it
    ("sample_rate", -DENORMAL, False),
    ("sample_rate", math.nan, False),
    ("sample_rate", math.inf, False),
    ("sample_rate", -math.inf, False),
    ("bitrate", 999, False),
    ("bitrate", 1000, True),
    ("bitrate", 1_000_000, True),
    ("bitrate", 1_000_001, False),
    ("data_bitrate", 0, True),
    ("data_bitrate", 499_999, False),
    ("data_bitrate", 500_000, True),
    ("data_bitrate", 16_000_000, True),
    ("data_bitrate", 16_000_001, False),
    ("output_divider", 0, False),
    ("output_divider", 1, True),
    ("output_divider", 65535, True),
    ("output_divider", 65536, False),
    ("id_offset", -257, False),
    ("id_offset", -256, True),
    ("id_offset", 1279, True),
    ("id_offset", 1280, False),
    ("diag_divider", 0, True),
    ("diag_divider", 0xFFFFFFFF, True),
]


@pytest.mark.parametrize(("field", "value", "ok"), NODE_CASES, ids=lambda v: str(v))
def test_node_lines_probed_at_their_bounds(field: str, value: Any, ok: bool) -> None:
    """A node field alone on each side of its bounds (NaN, +-Inf, denormals for the rate): its line, the
    check's named field and att_node_init agree; an accepted value is never the one blamed."""
    s = ffi.new("att_node_settings_t *")
    assert lib.att_node_settings_default(int(FilterKind.ARS), 100.0, s) == lib.ATT_OK
    setattr(s, field, value)
    r = ffi.new("att_settings_error_t *")
    line = []
    for i in range(64):
        st = lib.att_node_settings_rule(s, i, r)
        if r.field == ffi.NULL:
            break
        if ffi.string(r.field).decode() == field:
            line.append(st == lib.ATT_OK)
    assert line and all(line) == ok, (field, value, line)
    why = ffi.new("att_settings_error_t *")
    status = int(lib.att_node_settings_check(s, why))
    named = ffi.string(why.field).decode() if why.field != ffi.NULL else None
    n = ffi.new("att_node_t *")
    assert int(lib.att_node_init(n, s)) == status
    if ok:
        assert named != field, (value, named)
    else:
        assert status == lib.ATT_ERR_SETTINGS and named == field, (value, named)


def test_node_bool_bytes_are_refused() -> None:
    """fd and accel_out holding a byte other than 0 or 1 (only through raw memory) are refused by name."""
    for field in ("fd", "accel_out"):
        s = ffi.new("att_node_settings_t *")
        assert lib.att_node_settings_default(int(FilterKind.ARS), 100.0, s) == lib.ATT_OK
        ffi.buffer(ffi.addressof(s[0], field), 1)[0] = b"\x02"
        why = ffi.new("att_settings_error_t *")
        assert lib.att_node_settings_check(s, why) == lib.ATT_ERR_SETTINGS
        assert ffi.string(why.field).decode() == field


def test_rule_listing_bad_calls() -> None:
    """NULL arguments and unknown kinds: a status and field NULL, never a line."""
    r = ffi.new("att_settings_error_t *")
    fs = ffi.new("att_filter_settings_t *")
    assert lib.att_filter_settings_default(int(FilterKind.ARS), 0.01, fs) == lib.ATT_OK
    assert lib.att_filter_settings_rule(int(FilterKind.ARS), ffi.NULL, 0, r) == lib.ATT_ERR_NULL
    assert r.field == ffi.NULL
    assert lib.att_filter_settings_rule(int(FilterKind.ARS), fs, 0, ffi.NULL) == lib.ATT_ERR_NULL
    assert lib.att_filter_settings_rule(99, fs, 0, r) == lib.ATT_ERR_KIND and r.field == ffi.NULL
    assert lib.att_calib_settings_rule(ffi.NULL, 0, r) == lib.ATT_ERR_NULL and r.field == ffi.NULL
    assert lib.att_node_settings_rule(ffi.NULL, 0, r) == lib.ATT_ERR_NULL and r.field == ffi.NULL
    n = len(contract.filter_rules(FilterKind.ARS))
    assert lib.att_filter_settings_rule(int(FilterKind.ARS), fs, n, r) == lib.ATT_OK and r.field == ffi.NULL
    assert lib.att_filter_settings_rule(int(FilterKind.ARS), fs, 0xFFFFFFFF, r) == lib.ATT_OK
    assert r.field == ffi.NULL
