"""att_filter.h refuses what it cannot use: NULL arguments, a filter never initialised, bad values.

The facade's happy paths run everywhere; these are its refusals, each with the status or flag the
header promises and nothing else changed (issue 26: the branch coverage of firmware/src/filters). A
filter never initialised is a zeroed att_filter_t (kind ATT_FILTER_NONE), as a static one is before
att_filter_init.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

from attica.native import ffi, lib
from attica.settings import Flag

RATE = 100.0


def _filter(kind: int = lib.ATT_FILTER_MARS) -> Any:
    s = ffi.new("att_filter_settings_t *")
    assert lib.att_filter_settings_default(kind, 1.0 / RATE, s) == lib.ATT_OK
    f = ffi.new("att_filter_t *")
    assert lib.att_filter_init(f, kind, s) == lib.ATT_OK
    return f, s


def _sample() -> Any:
    x = ffi.new("att_sample_t *")
    x.acc.z = 9.81
    x.mag.x, x.mag.y, x.mag.z = 0.0, 20.0, -40.0
    return x


def _same(a: Any, b: Any) -> bool:
    return bytes(ffi.buffer(a)) == bytes(ffi.buffer(b))


def test_null_arguments() -> None:
    f, s = _filter()
    cs = ffi.new("att_calib_settings_t *")
    lib.att_calib_settings_default(cs)
    assert lib.att_filter_init(ffi.NULL, lib.ATT_FILTER_MARS, s) == lib.ATT_ERR_NULL
    assert lib.att_filter_init(f, lib.ATT_FILTER_MARS, ffi.NULL) == lib.ATT_ERR_NULL
    assert lib.att_filter_retune(f, ffi.NULL) == lib.ATT_ERR_NULL
    assert lib.att_filter_calibrate(ffi.NULL, cs) == lib.ATT_ERR_NULL
    assert lib.att_filter_calibrate(f, ffi.NULL) == lib.ATT_ERR_NULL
    assert lib.att_filter_set_heading(ffi.NULL, 0.0) == lib.ATT_ERR_NULL
    assert lib.att_filter_heading_update(ffi.NULL, 0.0, 0.5, True) == lib.ATT_ERR_NULL
    before = ffi.new("att_filter_t *")
    before[0] = f[0]
    lib.att_filter_reset(ffi.NULL)  # no crash
    lib.att_filter_output(f, ffi.NULL)
    lib.att_filter_accel(f, ffi.NULL)
    assert _same(f, before)
    out = ffi.new("att_output_t *")
    lib.att_filter_output(ffi.NULL, out)
    assert out.flags == Flag.BAD_ARG and out.valid == lib.ATT_OUT_ALL
    acc = ffi.new("att_accel_t *")
    acc.valid = 7
    acc.gravity.x = 3.0
    lib.att_filter_accel(ffi.NULL, acc)
    assert acc.valid == 0 and acc.gravity.x == 0.0


def test_a_filter_never_initialised() -> None:
    """Every call on it is refused (ATT_ERR_KIND, BAD_ARG) and leaves it zeroed."""
    f = ffi.new("att_filter_t *")
    zero = ffi.new("att_filter_t *")
    _, s = _filter()
    cs = ffi.new("att_calib_settings_t *")
    lib.att_calib_settings_default(cs)
    out = ffi.new("att_output_t *")
    assert lib.att_filter_retune(f, s) == lib.ATT_ERR_KIND
    assert lib.att_filter_calibrate(f, cs) == lib.ATT_ERR_KIND
    assert lib.att_filter_set_heading(f, 0.0) == lib.ATT_ERR_KIND
    assert lib.att_filter_heading_update(f, 0.0, 0.5, True) == lib.ATT_ERR_KIND
    lib.att_filter_reset(f)
    assert lib.att_filter_step(f, _sample(), out) == Flag.BAD_ARG and out.flags == Flag.BAD_ARG
    lib.att_filter_output(f, out)
    assert out.flags == Flag.BAD_ARG
    assert _same(f, zero)


def test_step_n_edges() -> None:
    """n = 0 is refused (BAD_ARG, out cleared); a NULL out still runs the n steps."""
    f, _ = _filter(lib.ATT_FILTER_ARS)
    out = ffi.new("att_output_t *")
    assert lib.att_filter_step_n(f, _sample(), 0, out) == Flag.BAD_ARG and out.flags == Flag.BAD_ARG
    lib.att_filter_step_n(f, _sample(), 3, ffi.NULL)
    lib.att_filter_output(f, out)
    assert out.steps == 3


BAD_HEADINGS = [(math.nan, 0.5), (8193.0, 0.5), (-math.inf, 0.5), (0.0, -0.1), (0.0, 1.5), (0.0, math.nan)]


@pytest.mark.parametrize(("heading", "gain"), BAD_HEADINGS)
def test_heading_update_refuses_bad_values(heading: float, gain: float) -> None:
    """A heading beyond +-8192 rad (or NaN) or a gain outside [0, 1] (or NaN): ATT_ERR_SETTINGS, the
    state kept."""
    f, _ = _filter(lib.ATT_FILTER_ARS)
    lib.att_filter_step(f, _sample(), ffi.NULL)
    before = ffi.new("att_filter_t *")
    before[0] = f[0]
    assert lib.att_filter_heading_update(f, heading, gain, True) == lib.ATT_ERR_SETTINGS
    assert _same(f, before)


def test_accel_outputs_need_their_stage_and_a_sample() -> None:
    """att_filter_accel gives valid 0 (zeros) without the acceleration stage, before the first sample,
    and for a filter whose kind was cleared (ATT_FILTER_NONE, as never initialised) under its stages."""
    f, _ = _filter(lib.ATT_FILTER_ARS)
    acc = ffi.new("att_accel_t *")
    lib.att_filter_step(f, _sample(), ffi.NULL)
    lib.att_filter_accel(f, acc)
    assert acc.valid == 0  # no stage
    cs = ffi.new("att_calib_settings_t *")
    lib.att_calib_settings_default(cs)
    cs.accel_outputs = True
    assert lib.att_filter_calibrate(f, cs) == lib.ATT_OK
    lib.att_filter_reset(f)
    lib.att_filter_accel(f, acc)
    assert acc.valid == 0  # no sample since the reset
    lib.att_filter_step(f, _sample(), ffi.NULL)
    lib.att_filter_accel(f, acc)
    assert acc.valid == lib.ATT_OUT_ACCEL
    f.kind = 0
    lib.att_filter_accel(f, acc)
    assert acc.valid == 0 and acc.gravity.z == 0.0
