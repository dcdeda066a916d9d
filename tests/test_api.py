"""The Python API: what a user types, and the misuses it refuses or warns about."""

from __future__ import annotations

import dataclasses
import importlib.metadata
import re
import warnings

import numpy as np
import pytest

import attica
from attica import kinds, native, reference
from attica.checks import unit_problems
from attica.settings import ArsSettings, FilterKind, MarsSettings, make_settings

from helpers import ROOT, assert_same_bits

RATE = 200.0


@pytest.fixture(scope="module")
def rec() -> attica.Recording:
    return attica.simulate(attica.SimConfig(duration=12.0, rate=RATE, seed=4, taps=1))


def test_version_is_written_once() -> None:
    text = (ROOT / "firmware" / "include" / "attica" / "att_version.h").read_text()
    major, minor, patch = (
        int(re.search(rf"#define ATT_VERSION_{k} (\d+)", text).group(1)) for k in ("MAJOR", "MINOR", "PATCH")
    )  # type: ignore[union-attr]
    assert attica.VERSION_INFO == (major, minor, patch)
    assert attica.__version__ == f"{major}.{minor}.{patch}"
    assert f'#define ATT_VERSION_STRING "{attica.__version__}"' in text
    assert (native.lib.ATT_VERSION_MAJOR, native.lib.ATT_VERSION_MINOR, native.lib.ATT_VERSION_PATCH) == (
        major,
        minor,
        patch,
    )
    assert importlib.metadata.version("attica") == attica.__version__  # the installed metadata agrees
    cmake = (ROOT / "firmware" / "CMakeLists.txt").read_text()
    assert "att_version.h" in cmake and "project(attica VERSION ${_attica_MAJOR}" in cmake


def test_top_level_exports(rec: attica.Recording) -> None:
    assert attica.Filter is native.Filter
    assert attica.reference is reference
    assert attica.Flag.AT_REST.name == "AT_REST"
    assert attica.flag_names(int(attica.Flag.AT_REST | attica.Flag.BIAS_UPDATED)) == [
        "AT_REST",
        "BIAS_UPDATED",
    ]
    assert attica.describe_flags(0) == "-"
    assert isinstance(rec, attica.Recording)
    for name in attica.__all__:
        assert getattr(attica, name) is not None, name
    assert attica.kinds is kinds


@pytest.mark.parametrize("kind", kinds.KINDS, ids=lambda k: k.label)
def test_every_settings_class_is_exported_and_frozen(kind: kinds.KindInfo) -> None:
    """Each kind's settings dataclass is at the top level (MekfSettings once was not) and read-only
    (MekfSettings once was not frozen)."""
    cls = kind.settings_class
    assert cls.__name__ in attica.__all__ and getattr(attica, cls.__name__) is cls
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(cls(), dataclasses.fields(cls)[0].name, 0)


def test_dt_is_required_and_positional(rec: attica.Recording) -> None:
    with pytest.raises(TypeError, match=r"needs the sample period: native.Filter\('ars', dt\)"):
        native.Filter("ars")
    with pytest.raises(TypeError, match="needs the sample period"):
        reference.Filter("mars")
    with pytest.raises(TypeError, match="dt is the sample period in s"):
        native.Filter("ars", "fast")
    with pytest.raises(ValueError, match="finite sample period > 0"):
        native.Filter("kf", -0.01)
    assert native.Filter("ars", 0.01).settings.dt == 0.01  # positional, as in VQF
    assert reference.Filter("ekf", 0.005).settings.dt == 0.005
    assert native.Filter("tilt").settings == make_settings(FilterKind.TILT)  # no sample period: none needed
    s = make_settings(FilterKind.ARS, dt=1 / RATE)
    assert native.Filter("ars", s).settings == s  # a settings object in the dt place still works
    assert native.Filter("ars", settings=s).settings == s
    assert native.Filter("ars", 0.002, settings=s).settings.dt == 0.002  # dt overrides settings.dt
    with pytest.warns(attica.UnitWarning, match="not a rate in Hz"), pytest.raises(native.NativeError):
        native.Filter("ars", 100)  # a rate passed as dt: warned about, then refused by the C library


def test_gain_beside_time_constant_is_ignored(rec: attica.Recording) -> None:
    """A time constant > 0 is used and the gain beside it ignored (issue 22; refused before), in C and the
    reference alike; the gain is still range-checked."""
    g, a, m = rec.gyr[:600], rec.acc[:600], rec.mag[:600]
    for make in (native.Filter, reference.Filter):
        both = make("ars", 0.01, gain=0.3, tau=0.5)
        assert both.settings.gain == 0.3  # kept as given, unused
        assert_same_bits(both.run(g, a)["q"], make("ars", 0.01, gain=0.0, tau=0.5).run(g, a)["q"], "ars")
        mars = make("mars", 0.01, alpha_mag=0.05)  # tau_mag 20 s by default
        assert_same_bits(mars.run(g, a, m)["q"], make("mars", 0.01, alpha_mag=0.0).run(g, a, m)["q"], "mars")
        make("ars", 0.01, gain=0.3, tau=0.0)  # the per-sample gain alone
        make("mars", 0.01, alpha_acc=0.05, tau_acc=0.0)
        # only the time constant given: the default gain is set to 0 (= unused)
        assert make("ars", 0.01, tau=0.5).settings.gain == 0.0
        assert make("mars", 0.01, tau_acc=0.3, tau_mag=10.0).settings.alpha_acc == 0.0
    with pytest.raises(attica.SettingsError, match=r"ars\.gain = 1\.5 is out of range: allowed \[0, 1\]"):
        native.Filter("ars", 0.01, gain=1.5, tau=0.5)
    from attica.can.node import Node

    Node("ars", sample_rate=100.0, gain=0.3, tau=0.5)


def test_settings_are_read_only(rec: attica.Recording) -> None:
    f = native.Filter("ars", 1 / RATE)
    with pytest.raises(AttributeError):
        f.settings = ArsSettings()  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        f.settings.tau = 1.0  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        MarsSettings().tau_mag = 3.0  # type: ignore[misc]
    r = reference.Filter("ars", 1 / RATE)
    with pytest.raises(AttributeError):
        r.settings = ArsSettings()  # type: ignore[misc]


def test_outputs_print_with_labels(rec: attica.Recording) -> None:
    out = attica.Filter("ars", 1 / RATE).run(rec.gyr, rec.acc)
    text = repr(out)
    assert text.startswith(f"Outputs: {len(rec.gyr)} steps")
    for label in ("q (w x y z)", "euler (deg: roll pitch yaw)", "gyro_bias (rad/s)", "flags", "INITIALISED"):
        assert label in text, label
    assert "..." in text and len(text.splitlines()) == 2 + 4 + 1 + 4  # first and last four steps
    one = out[-1]
    assert str(one).startswith("Outputs: one step") and "AT_REST" in str(one)  # the simulation ends still
    assert isinstance(out["q"], np.ndarray) and type(out["q"]) is np.ndarray  # fields are plain arrays
    assert int(one["steps"]) == len(rec.gyr)
    kf = attica.Filter("kf", 1 / RATE).run(rec.gyr[:3], rec.acc[:3])
    assert "cov (diagonal)" in repr(kf)  # shown where a filter fills it
    ref = reference.Filter("ars", 1 / RATE).run(rec.gyr[:5], rec.acc[:5])
    assert repr(ref).startswith("Outputs: 5 steps")
    assert (ref["q"].view(np.uint32) == out["q"][:5].view(np.uint32)).all()


def test_unit_warnings(rec: attica.Recording) -> None:
    f = attica.Filter("mars", 1 / RATE)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        f.run(rec.gyr, rec.acc, rec.mag)  # right units: silent
    cases = {
        "deg/s": (np.degrees(rec.gyr), rec.acc, rec.mag),
        r"like g \(": (rec.gyr, rec.acc / 9.80665, rec.mag),
        "milli-g": (rec.gyr, rec.acc / 9.80665 * 1000, rec.mag),
        "gauss": (rec.gyr, rec.acc, rec.mag / 100),
        "nT": (rec.gyr, rec.acc, rec.mag * 1000),
    }
    moving = slice(610, 840)  # in motion: a still stretch says nothing about the gyro's unit
    for what, (g, a, m) in cases.items():
        with pytest.warns(attica.UnitWarning, match=what):
            attica.Filter("mars", 1 / RATE).run(g, a, m)
        with pytest.warns(attica.UnitWarning, match=what):
            reference.Filter("mars", 1 / RATE).run(g[moving], a[moving], m[moving])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        attica.Filter("ars", 1 / RATE).run(np.degrees(rec.gyr), rec.acc, check_units=False)
        warnings.simplefilter("ignore", attica.UnitWarning)  # the documented way to silence it
        warnings.simplefilter("error", RuntimeWarning)
        attica.Filter("ars", 1 / RATE).run(np.degrees(rec.gyr), rec.acc)
    nan_mag = np.full_like(rec.mag, np.nan)
    assert unit_problems(rec.gyr, rec.acc, nan_mag) == []  # no mag samples: nothing to judge
    assert unit_problems(np.zeros((10, 3)), rec.acc[:10], None) == []  # at rest: no gyro judgement


@pytest.mark.parametrize(
    "kind,changes", [("ars", {"tau": 0.5}), ("mars", {"tau_mag": 5.0}), ("kf", {"r_noise": 0.3})]
)
def test_retune_keeps_the_state(rec: attica.Recording, kind: str, changes: dict[str, float]) -> None:
    half = 1200
    f = native.Filter(kind, 1 / RATE)
    r = reference.Filter(kind, 1 / RATE)
    first = f.run(rec.gyr[:half], rec.acc[:half], rec.mag[:half])
    r.run(rec.gyr[:half], rec.acc[:half], rec.mag[:half])
    f.retune(**changes)  # att_filter_retune
    r.retune(**changes)
    for name, value in changes.items():
        assert getattr(f.settings, name) == getattr(r.settings, name) == value
    if kind == "ars":
        assert f.settings.gain == 0.0  # only the time constant given: the per-sample gain yields
    assert r.state_matches(0, f.state[0])
    out = f.run(rec.gyr[half:1400], rec.acc[half:1400], rec.mag[half:1400])
    got = r.run(rec.gyr[half:1400], rec.acc[half:1400], rec.mag[half:1400])
    assert (out["q"].view(np.uint32) == got["q"].view(np.uint32)).all()
    assert int(out["steps"][0]) == int(first["steps"][-1]) + 1  # the state went on
    fresh = native.Filter(kind, settings=f.settings).run(
        rec.gyr[half:1400], rec.acc[half:1400], rec.mag[half:1400]
    )
    assert not np.array_equal(fresh["q"], out["q"])


def test_retune_refusals_leave_the_filter_as_it_was(rec: attica.Recording) -> None:
    f = native.Filter("ars", 1 / RATE)
    f.run(rec.gyr[:500], rec.acc[:500])
    before, settings = bytes(f.state), f.settings
    with pytest.raises(native.SettingsError, match=r"ars\.gain = 1\.5"):
        f.retune(gain=1.5, tau=0.2)  # unused, still range-checked
    with pytest.raises(native.NativeError, match=r"att_filter_retune\(ars\): ars\.gravity = -1\.0"):
        f.retune(gravity=-1.0)
    with pytest.raises(TypeError, match="no field"):
        f.retune(gian=0.1)
    assert bytes(f.state) == before and f.settings == settings
    r = reference.Filter("ars", 1 / RATE)
    r.retune(gain=0.5, tau=0.2)  # a gain beside a time constant is ignored, not refused (issue 22)
    assert r.settings.gain == 0.5 and r.settings.tau == 0.2
