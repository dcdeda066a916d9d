"""Python settings dataclasses equal the C defaults; the unified interface's contract."""

from __future__ import annotations

import numpy as np
import pytest

from attica import native
from attica.outputs import OUTPUT_DTYPE
from attica.settings import (
    SEED_OVERRIDES,
    FilterKind,
    Preset,
    implemented_kinds,
    make_settings,
    preset_settings,
    to_dict,
)


@pytest.mark.parametrize("kind", implemented_kinds(), ids=lambda k: k.label)
def test_defaults_match_c(kind: FilterKind) -> None:
    py = to_dict(make_settings(kind, dt=0.01))
    c = native.default_settings(kind, dt=0.01)
    assert set(py) == set(c)
    for name, value in py.items():
        if isinstance(value, tuple):
            assert np.array_equal(np.float32(value), np.float32(c[name])), name
        elif isinstance(value, float):
            assert np.float32(value) == np.float32(c[name]), name
        else:
            assert int(value) == int(c[name]), name


@pytest.mark.parametrize("preset", list(Preset), ids=lambda p: p.label)
@pytest.mark.parametrize("kind", implemented_kinds(), ids=lambda k: k.label)
def test_presets_match_c(kind: FilterKind, preset: Preset) -> None:
    """settings.preset_settings equals att_filter_settings_preset, field by field."""
    py = to_dict(preset_settings(kind, preset, dt=1 / 285.714))
    c = native.default_settings(kind, dt=1 / 285.714, preset=preset)
    for name, value in py.items():
        if isinstance(value, tuple):
            assert np.array_equal(np.float32(value), np.float32(c[name])), name
        elif isinstance(value, float):
            assert np.float32(value) == np.float32(c[name]), name
        else:
            assert int(value) == int(c[name]), name
    # the seed preset differs from the defaults exactly where a setting was tuned
    if preset == Preset.SEED:
        assert (py != to_dict(make_settings(kind, dt=1 / 285.714))) == bool(SEED_OVERRIDES[kind])


def test_preset_bad_arguments() -> None:
    lib, ffi = native.lib, native.ffi
    s = ffi.new("att_filter_settings_t *")
    assert lib.att_filter_settings_preset(lib.ATT_FILTER_ARS, 7, 0.01, s) == lib.ATT_ERR_KIND
    assert lib.att_filter_settings_preset(99, lib.ATT_PRESET_SEED, 0.01, s) == lib.ATT_ERR_KIND
    assert (
        lib.att_filter_settings_preset(lib.ATT_FILTER_ARS, lib.ATT_PRESET_SEED, 0.01, ffi.NULL)
        == lib.ATT_ERR_NULL
    )
    with pytest.raises(ValueError, match="unknown preset"):
        preset_settings(FilterKind.ARS, "tuned")


def test_output_layout() -> None:
    assert native.ffi.sizeof("att_output_t") == OUTPUT_DTYPE.itemsize == 68
    for name in OUTPUT_DTYPE.names or ():
        assert native.ffi.offsetof("att_output_t", name) == OUTPUT_DTYPE.fields[name][1]  # type: ignore[index]


def test_kind_numbers_and_names() -> None:
    for kind in implemented_kinds():
        assert int(getattr(native.lib, f"ATT_FILTER_{kind.name}")) == int(kind)
        assert native.ffi.string(native.lib.att_filter_name(int(kind))).decode() == kind.label
    assert native.ffi.string(native.lib.att_filter_name(99)).decode() == "?"


def test_bad_arguments() -> None:
    lib, ffi = native.lib, native.ffi
    s = ffi.new("att_filter_settings_t *")
    f = ffi.new("att_filter_t *")
    assert lib.att_filter_settings_default(99, 0.01, s) == lib.ATT_ERR_KIND
    assert lib.att_filter_settings_default(lib.ATT_FILTER_ARS, 0.01, ffi.NULL) == lib.ATT_ERR_NULL
    assert lib.att_filter_init(ffi.NULL, lib.ATT_FILTER_ARS, s) == lib.ATT_ERR_NULL
    assert lib.att_filter_init(f, 99, s) == lib.ATT_ERR_KIND
    out = ffi.new("att_output_t *")
    sample = ffi.new("att_sample_t *")
    # zeroed (never initialised) filter: flagged, not crashed
    assert lib.att_filter_step(f, sample, out) == lib.ATT_FLAG_BAD_ARG
    assert lib.att_filter_step(ffi.NULL, sample, out) == lib.ATT_FLAG_BAD_ARG
    assert out.flags == lib.ATT_FLAG_BAD_ARG
    assert lib.att_ars_step(ffi.NULL, (0, 0, 0), (0, 0, 0)) == lib.ATT_FLAG_BAD_ARG
    with pytest.raises(ValueError, match="unknown filter"):
        native.Filter("madgwick")
    with pytest.raises(TypeError, match="no field"):
        native.Filter("ars", 0.01, gian=0.2)
    f2 = native.Filter("ars", 0.01)
    with pytest.raises(ValueError, match="shape"):
        f2.run(np.zeros((10, 3)), np.zeros((9, 3)))
    with pytest.raises(ValueError, match="3 components"):
        f2.step((0, 0), (0, 0, 9.8))


def test_init_failure_leaves_filter_unchanged() -> None:
    lib, ffi = native.lib, native.ffi
    s = ffi.new("att_filter_settings_t *")
    lib.att_filter_settings_default(lib.ATT_FILTER_ARS, 0.01, s)
    f = ffi.new("att_filter_t *")
    assert lib.att_filter_init(f, lib.ATT_FILTER_ARS, s) == lib.ATT_OK
    before = bytes(ffi.buffer(f))
    s.ars.dt = -1.0
    assert lib.att_filter_init(f, lib.ATT_FILTER_ARS, s) == lib.ATT_ERR_SETTINGS
    assert bytes(ffi.buffer(f)) == before
