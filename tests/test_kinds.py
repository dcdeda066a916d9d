"""The Python registry of filter kinds (attica.kinds) and the C kind table agree, fact by fact.

The C table is the X-macro list of firmware/src/filters/att_kinds.h; every fact of the registry is
checked against what the C library does (through the cffi binding and the in-process CAN node), and
against the numpy reference, so that neither side can gain, lose or change a kind silently.
"""

from __future__ import annotations

import dataclasses
import inspect
import re
from typing import Any

import numpy as np
import pytest

from attica import kinds, native
from attica import reference as ref
from attica.can import codec as c
from attica.kinds import Heading, KindInfo
from attica.native import NativeError, ffi, lib
from attica.outputs import OUT_BIAS, OUT_EULER, OUT_Q
from attica.settings import SETTINGS_CLASS, FilterKind, implemented_kinds
from attica.sim import SimConfig, simulate

from helpers import ROOT

KINDS_H = ROOT / "firmware" / "src" / "filters" / "att_kinds.h"
CONFIG_H = ROOT / "firmware" / "include" / "attica" / "att_config.h"
RATE = 100.0
DT = 1.0 / RATE
STEPS = 300

_ROW = re.compile(r"^\s*S\(X,\s*([A-Z][A-Z0-9_]*),\s*([a-z][a-z0-9_]*),\s*(\d+)\)\s*\\?\s*$", re.M)
"""A row of ATT_KINDS_EACH: ``    S(X, ARS, ars, 1)        \\`` -> NAME, name, value."""


def c_table() -> list[tuple[str, str, int]]:
    """(NAME, name, value) of every row of the C kind table, in its order."""
    return [(m[1], m[2], int(m[3])) for m in _ROW.finditer(KINDS_H.read_text())]


def variants(k: KindInfo) -> list[Any]:
    """The settings that change what the kind is: its defaults, and its mag switch off when it has one."""
    out: list[Any] = [k.settings_class()]
    if k.mag_switch is not None:
        out.append(dataclasses.replace(out[0], **{k.mag_switch: False}))
    return out


CASES = [pytest.param(k, s, id=f"{k.label}-{k.axes(s)}axis") for k in kinds.KINDS for s in variants(k)]
"""Every kind with each of its :func:`variants`."""


@pytest.fixture(scope="module")
def imu() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A few seconds of simulated 9-axis motion (float32), rad/s, m/s^2, uT."""
    rec = simulate(SimConfig(duration=STEPS / RATE + 1.0, rate=RATE, seed=21))
    g, a, m = (np.asarray(x[:STEPS], np.float32) for x in (rec.gyr, rec.acc, rec.mag))
    return g, a, m


def _with_dt(k: KindInfo, settings: Any) -> Any:
    return dataclasses.replace(settings, dt=DT) if k.has_period else settings


def _filter(k: KindInfo, settings: Any, imu: Any, steps: int = STEPS) -> native.Filter:
    """The C filter of kind k with settings (at RATE), run over the first ``steps`` samples of imu."""
    f = native.Filter(k.kind, settings=_with_dt(k, settings))
    if steps:
        f.run(*(x[:steps] for x in imu))
    return f


# --- the table itself --------------------------------------------------------------------------------


def test_c_table_is_the_registry() -> None:
    """Same kinds, same order, same NAME, name and value; FilterKind and the settings views follow."""
    rows = c_table()
    assert rows, f"no S(X, NAME, name, value) rows in {KINDS_H}"
    assert rows == [(k.kind.name, k.label, int(k.kind)) for k in kinds.KINDS]
    assert [k.kind for k in kinds.KINDS] == list(FilterKind) == implemented_kinds()
    assert dict(SETTINGS_CLASS) == {k.kind: k.settings_class for k in kinds.KINDS}
    assert kinds.labels() == [name for _, name, _ in rows]


def test_build_options_are_in_att_config_h() -> None:
    """Every kind has its ATT_WITH_<NAME> option; every ATT_WITH_ option but the stages' and the
    hard-iron estimate's is a kind."""
    text = CONFIG_H.read_text()
    defined = set(re.findall(r"^#define (ATT_WITH_[A-Z0-9_]+) [01]\b", text, re.M))
    macros = {k.macro for k in kinds.KINDS}
    assert macros <= defined, sorted(macros - defined)
    assert defined - {"ATT_WITH_CALIB", "ATT_WITH_HARD_IRON"} == macros


def test_heading_and_gain_values_are_those_of_c() -> None:
    """kinds.Heading is att_heading_t, the CAN Gain parameters are att_gain_t (both in att_kinds.h)."""
    text = KINDS_H.read_text()
    heading = {m[1]: int(m[2]) for m in re.finditer(r"\bATT_HEADING_([A-Z_]+) = (\d+)", text)}
    gain = {m[1]: int(m[2]) for m in re.finditer(r"\bATT_GAIN_([A-Z_]+) = (\d+)", text)}
    assert heading == {h.name: int(h) for h in Heading}
    assert gain == {g.name: int(g) for g in c.Gain}


SPELLINGS = {
    "label": lambda k: k.label,
    "upper": lambda k: k.label.upper(),
    "value": lambda k: int(k.kind),
    "enum": lambda k: k.kind,
}


@pytest.mark.parametrize("spelling", list(SPELLINGS.values()), ids=list(SPELLINGS))
def test_info_accepts_every_spelling(spelling: Any) -> None:
    for k in kinds.KINDS:
        assert kinds.info(spelling(k)) is k and kinds.info(k) is k
    with pytest.raises(ValueError, match="choose one of: ars, mars"):
        kinds.info("madgwick")


def test_per_kind_tables_cover_every_kind() -> None:
    """The per-kind data kept outside the registry has an entry for every kind (none forgotten)."""
    from attica.evaluate import GRIDS
    from attica.settings import SEED_OVERRIDES
    from attica_dev import cross, footprint

    every = {k.kind for k in kinds.KINDS}
    assert set(SEED_OVERRIDES) == every
    assert set(GRIDS) == every
    assert set(cross.REFERENCE_COST) == set(kinds.labels())
    assert {k.label for k in kinds.KINDS} <= set(footprint.IMAGES) & set(footprint.STACK_ENTRIES)


# --- what C says of each kind --------------------------------------------------------------------------


@pytest.mark.parametrize("k", kinds.KINDS, ids=lambda k: k.label)
def test_name_settings_and_state(k: KindInfo) -> None:
    """att_filter_name, the default settings, the settings struct's fields and the state's members."""
    value = int(k.kind)
    assert ffi.string(lib.att_filter_name(value)).decode() == k.label
    s = ffi.new("att_filter_settings_t *")
    assert lib.att_filter_settings_default(value, DT, s) == lib.ATT_OK
    assert ffi.typeof(getattr(s, k.label)) is ffi.typeof(k.c_settings)
    fields = [name for name, _ in ffi.typeof(k.c_settings).fields]
    assert fields == [f.name for f in dataclasses.fields(k.settings_class)]
    assert k.has_period == ("dt" in fields)
    state = {name for name, _ in dict(ffi.typeof(f"att_{k.label}_t").fields)["st"].type.fields}
    assert ("q" in state, "euler" in state) == (k.q_state, k.euler_state)
    assert ("bias" in state) == k.gyro_bias
    # a covariance from a P matrix (the Kalman filters) or from the complementary filters' model
    assert ("p" in state or "acc_step" in state) == k.covariance


@pytest.mark.parametrize("k", kinds.KINDS, ids=lambda k: k.label)
def test_step_outputs(k: KindInfo, imu: Any) -> None:
    """A step writes q for the quaternion states, euler for the Euler-angle states (the valid bits); the
    full output has a covariance only for the kinds that have one, a bias only for those that estimate it."""
    f = _filter(k, k.settings_class(), imu, STEPS - 1)
    out = f.step(imu[0][-1], imu[1][-1], imu[2][-1], full=False)
    valid = int(out["valid"])
    assert (bool(valid & OUT_Q), bool(valid & OUT_EULER)) == (k.q_state, k.euler_state)
    assert valid & OUT_BIAS
    full = f.output()
    assert bool(np.any(full["cov"] != 0)) == k.covariance
    assert bool(np.any(full["gyro_bias"] != 0)) == k.gyro_bias


@pytest.mark.parametrize(("k", "settings"), CASES)
def test_inputs(k: KindInfo, settings: Any, imu: Any) -> None:
    """A sensor the kind uses changes its outputs when it changes; another changes no bit."""
    base = np.asarray(_filter(k, settings, imu, 0).run(*imu))
    used = k.inputs(settings)
    assert set(used) <= set(k.sensors) and k.uses_mag(settings) == ("mag" in used)
    assert k.axes(settings) == 3 * len(used)
    turn = np.float32([[0.8, -0.6, 0.0], [0.6, 0.8, 0.0], [0.0, 0.0, 1.0]])  # 37 deg about z
    for i, name in enumerate(kinds.SENSORS):
        changed = list(imu)
        if name == "gyr":
            changed[i] = imu[i] + np.float32([0.05, -0.03, 0.08])
        else:
            changed[i] = np.ascontiguousarray((imu[i] @ turn.T) * np.float32(1.1), np.float32)
        out = np.asarray(_filter(k, settings, imu, 0).run(*changed))
        same = out.tobytes() == base.tobytes()
        assert same == (name not in used), f"{k.label}: {name} {'ignored' if same else 'used'}"


@pytest.mark.parametrize(("k", "settings"), CASES)
def test_heading(k: KindInfo, settings: Any, imu: Any) -> None:
    """set_heading and heading_update are taken or refused as the kind's heading says, by the C
    library and by the reference."""
    mode = k.heading(settings)
    f = _filter(k, settings, imu)
    r = ref.Filter(k.kind, settings=_with_dt(k, settings))
    r.run(*imu)
    for what, call, taken in (
        ("set_heading", lambda x: x.set_heading(0.5), mode != Heading.NONE),
        ("heading_update", lambda x: x.heading_update(-0.5, 0.5), mode == Heading.UPDATE),
    ):
        for obj, error in ((f, NativeError), (r, ValueError)):
            if taken:
                call(obj)
            else:
                with pytest.raises(error):
                    call(obj)
        assert f.output()["q"].tobytes() == r.output()["q"][0].tobytes(), f"{k.label}: {what}: C vs reference"


@pytest.mark.parametrize("k", kinds.KINDS, ids=lambda k: k.label)
@pytest.mark.parametrize("gain", list(c.Gain), ids=lambda g: g.name)
def test_can_gains(k: KindInfo, gain: c.Gain) -> None:
    """The node takes a SET_GAIN of the kind's gains (OK) and no other (BAD_ARG, nothing changed)."""
    value = {
        c.Gain.TAU_ACC: 0.5,
        c.Gain.TAU_MAG: 4.0,
        c.Gain.KF_R: 2.5,
        c.Gain.EKF_R: 2.0,
        c.Gain.DECLINATION: 0.3,
    }[gain]
    node = c.Node(k.label, sample_rate=RATE)
    still = np.zeros((5, 3), np.float32)
    node.run(c.encode_imu(still, still + np.float32([0.0, 0.0, 9.8]), still + np.float32([20.0, 0.0, -40.0])))
    before = bytes(node.state.fs)
    out, _ = node.run(c.encode_cmd(c.Cmd.SET_GAIN, gain, value, counter=3))
    (ans,) = c.decode_outputs(out).answers
    assert (ans.cmd, ans.counter, ans.kind) == (int(c.Cmd.SET_GAIN), 3, int(k.kind))
    if gain in k.gains:
        assert ans.result == c.Ack.OK and bytes(node.state.fs) != before
    else:
        assert ans.result == c.Ack.BAD_ARG and bytes(node.state.fs) == before
    assert set(kinds.gains(k)) == set(k.gains) and len(k.gains) == len(k.gain_names)


# --- the reference --------------------------------------------------------------------------------------


@pytest.mark.parametrize("k", kinds.KINDS, ids=lambda k: k.label)
def test_reference_class(k: KindInfo) -> None:
    """reference.Filter runs the registry's class, whose step takes the kind's sensors in order."""
    cls = k.reference_class()
    r = ref.Filter(k.kind, DT)
    assert type(r.impl) is cls and r.info is k
    params = [p for p in inspect.signature(cls.step).parameters if p != "self"]
    assert tuple(params) == k.sensors
    assert all(hasattr(r.impl, name) for name in cls.EARTH)
