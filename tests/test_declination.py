"""Declination (issue 23): mars and mekf report the heading relative to true north.

- C and the reference bit for bit with a declination set (both signs, the bounds +-float(pi)), on a
  clean start, a disturbed start (the reference adopted later keeps the declination's azimuth) and
  across a reset;
- the physics: on a simulated field whose horizontal part points D east of true north (the truth's
  yaw relative to true north), the filter told D has the heading error of a run without declination,
  the one told 0 is off by D; and the whole run with D is the run with 0 turned about the earth's
  vertical by -D (the filters commute with a turn of their earth frame);
- declination 0 is magnetic north with the same bits as before (tests/digests.txt unchanged);
- the settings contract: [-pi, pi] rad, NaN and +-Inf refused, with the field named.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from attica import metrics, native
from attica.crosscheck import Stream, crosscheck
from attica.settings import FilterKind, MagMode, MarsSettings, MekfSettings
from attica.sim import SimConfig, simulate

RATE = 100.0
PI_F = float(np.float32(math.pi))  # the contract's bound: float(pi), just above pi
START = ((0.0, 30.0, (-12.0, 8.0, -10.0)),)  # uT, earth frame: a field disturbed for the first 30 s
KINDS = {FilterKind.MARS: MarsSettings, FilterKind.MEKF: MekfSettings}


def _settings(kind: FilterKind, **over: Any) -> Any:
    return replace(KINDS[kind](dt=1.0 / RATE), **over)


def _rec(seed: int, decl: float, duration: float = 60.0, **cfg: Any) -> Any:
    d = min(max(decl, -math.pi), math.pi)  # the simulator takes [-pi, pi] in float64
    return simulate(SimConfig(duration=duration, rate=RATE, seed=seed, mag_declination=d, **cfg))


def _qz(angle: float) -> np.ndarray:
    return np.array([math.cos(angle / 2.0), 0.0, 0.0, math.sin(angle / 2.0)])


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
@pytest.mark.parametrize("decl", [0.35, -2.8, PI_F, -PI_F])
def test_bit_exact_with_a_declination(kind: FilterKind, decl: float) -> None:
    streams = [
        Stream(r.gyr, r.acc, r.mag, name=name)
        for name, r in (
            ("clean", _rec(1, decl, 40.0)),
            ("disturbed start", _rec(2, decl, 80.0, mag_disturbances=START)),
        )
    ]
    res = crosscheck(kind, streams, settings=_settings(kind, declination=decl), segment=1000)
    assert res.ok, res.first_mismatch or f"{res.state_mismatches} state mismatches"


def test_bit_exact_full_mode_and_after_a_reset() -> None:
    """mars FULL mode aligns the same way; a reset aligns again with the declination."""
    rec = _rec(3, 0.6, 30.0)
    s = _settings(FilterKind.MARS, declination=0.6, mag_mode=MagMode.FULL)
    res = crosscheck(FilterKind.MARS, [Stream(rec.gyr, rec.acc, rec.mag, name="full")], settings=s)
    assert res.ok, res.first_mismatch
    f = native.Filter(FilterKind.MARS, s)
    q1 = f.run_q(rec.gyr, rec.acc, rec.mag)
    f.reset()
    q2 = f.run_q(rec.gyr, rec.acc, rec.mag)
    assert q1.view(np.uint32).tobytes() == q2.view(np.uint32).tobytes()


def _heading_errors(kind: FilterKind, rec: Any, decl: float) -> tuple[float, float]:
    """(heading RMSE, median signed heading error) in deg, after the start's fast heading phase."""
    q = native.Filter(kind, _settings(kind, declination=decl)).run_q(rec.gyr, rec.acc, rec.mag)
    scored = np.arange(len(q)) >= int(10 * RATE)
    e = metrics.error_quat(q.astype(np.float64), rec.quat_true)[scored]
    signed = np.degrees(2.0 * np.arctan(e[:, 3] / e[:, 0]))  # about the earth's vertical, counter-clockwise
    return metrics.evaluate(q, rec.quat_true, scored).heading, float(np.median(signed))


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
def test_heading_relative_to_true_north(kind: FilterKind) -> None:
    d = math.radians(-14.0)  # a field 14 deg west of true north
    rec = _rec(4, d)
    told, told_offset = _heading_errors(kind, rec, d)
    _, untold_offset = _heading_errors(kind, rec, 0.0)
    plain, plain_offset = _heading_errors(kind, _rec(4, 0.0), 0.0)  # the same run, the field pointing north
    assert told < plain + 0.3, (
        f"told the declination: {told:.2f} deg, without one in a north field {plain:.2f}"
    )
    assert abs(told_offset - plain_offset) < 0.5, (
        f"told: heading offset {told_offset:.2f}, north field {plain_offset:.2f}"
    )
    # not told, its north is the field's: turned by D (negative: clockwise) from true north
    shift = untold_offset - plain_offset
    assert abs(shift + 14.0) < 0.5, (
        f"not told: heading offset {shift:.2f} deg beside a north field (expected -14)"
    )


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
def test_the_run_is_turned_by_the_declination(kind: FilterKind) -> None:
    rec = _rec(5, 0.0, 40.0)
    d = 1.2
    q0 = native.Filter(kind, _settings(kind)).run_q(rec.gyr, rec.acc, rec.mag).astype(np.float64)
    qd = native.Filter(kind, _settings(kind, declination=d)).run_q(rec.gyr, rec.acc, rec.mag)
    turned = metrics.quat_mul(np.broadcast_to(_qz(-d), q0.shape), q0)
    total, _, _ = metrics.error_angles(qd.astype(np.float64), turned)
    assert np.degrees(np.max(total)) < 0.01, f"max {np.degrees(np.max(total)):.4f} deg from Qz(-D) q(D = 0)"


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
@pytest.mark.parametrize("bad", [3.1416, -3.1416, 10.0, math.nan, math.inf, -math.inf])
def test_declination_out_of_range_is_refused(kind: FilterKind, bad: float) -> None:
    with pytest.raises(native.SettingsError) as e:
        native.Filter(kind, _settings(kind, declination=bad))
    assert e.value.field == f"{kind.label}.declination"
    assert e.value.rule == "[-pi, pi]" and e.value.unit == "rad"


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
def test_declination_bounds_accepted(kind: FilterKind) -> None:
    for d in (PI_F, -PI_F, 0.0, -0.0):
        assert native.settings_problem(kind, _settings(kind, declination=d)) is None


def test_a_reference_without_horizontal_part_takes_the_declination() -> None:
    """A new reference of mars (att_i_magref_m0, at a block's end) when the old one has no horizontal
    part: the new one points at the declination's azimuth. FULL mode from a vertical m0_init (no
    alignment), the real field rejected by dip and then adopted as the new reference; C and reference
    bit for bit."""
    d = 0.5
    rec = _rec(6, d, 40.0)
    s = _settings(
        FilterKind.MARS,
        declination=d,
        mag_mode=MagMode.FULL,
        init_from_sensors=False,
        q_init=tuple(float(x) for x in rec.quat_true[0]),
        m0_init=(0.0, 0.0, -49.0),
        mag_new_time=3.0,
    )
    res = crosscheck(FilterKind.MARS, [Stream(rec.gyr, rec.acc, rec.mag, name="vertical m0")], settings=s)
    assert res.ok, res.first_mismatch
    f = native.Filter(FilterKind.MARS, s)
    f.run_q(rec.gyr, rec.acc, rec.mag)
    m0 = f.state.u.mars.st.m0
    assert math.hypot(m0.x, m0.y) > 10.0, "a field with a horizontal part was adopted"
    assert abs(math.atan2(m0.x, m0.y) - d) < 1e-5, f"azimuth {math.atan2(m0.x, m0.y):.6f}, declination {d}"


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
def test_a_retune_of_the_declination_keeps_the_heading(kind: FilterKind) -> None:
    """A retune to another declination changes the coefficients only: C and reference bit for bit after it,
    the heading kept; the new declination applies at the next alignment (a reset)."""
    from attica.reference.filter import Filter as RefFilter

    rec = _rec(7, 0.0, 30.0)
    half = 1500
    s = _settings(kind)
    c = native.Filter(kind, s)
    c.run(rec.gyr[:half], rec.acc[:half], rec.mag[:half])
    ref = RefFilter(kind, s)
    ref.load_c_states([c.state.copy()[0]])
    q_before = c.output()["q"].copy()
    s2 = replace(s, declination=0.4)
    c.retune(s2)
    ref.retune(s2)
    assert ref.state_matches(0, c.state.copy()[0]), ref.state_diff(0, c.state.copy()[0])
    assert c.output()["q"].tobytes() == q_before.tobytes(), "the heading is kept"
    out = c.run(rec.gyr[half:], rec.acc[half:], rec.mag[half:])
    q_ref = np.array(
        [ref.step(rec.gyr[i], rec.acc[i], rec.mag[i])["q"][0] for i in range(half, len(rec.gyr))]
    )
    assert out["q"].view(np.uint32).tobytes() == q_ref.astype(np.float32).view(np.uint32).tobytes()
    c.reset()
    q_reset = c.run_q(rec.gyr, rec.acc, rec.mag)
    q_fresh = native.Filter(kind, s2).run_q(rec.gyr, rec.acc, rec.mag)
    assert q_reset.tobytes() == q_fresh.tobytes(), "after a reset the new declination applies"


def _node_run(kind: FilterKind, rec: Any, cmds: dict[int, float | None], **settings: Any) -> Any:
    """A node of ``kind`` fed ``rec``; before sample i it gets SET_GAIN DECLINATION cmds[i] (None: RESET).

    Returns the decoded output sets and the answers.
    """
    from attica.can import codec as c

    node = c.Node(kind.label, sample_rate=RATE, bitrate=1_000_000, **settings)
    samples = c.encode_imu(rec.gyr, rec.acc, rec.mag)
    parts = []
    start = 0
    for j, (i, v) in enumerate(sorted(cmds.items())):
        parts.append(samples[start * 3 : i * 3])
        if v is None:
            parts.append(c.encode_cmd(c.Cmd.RESET, counter=j + 1))
        else:
            parts.append(c.encode_cmd(c.Cmd.SET_GAIN, c.Gain.DECLINATION, v, counter=j + 1))
        start = i
    parts.append(samples[start * 3 :])
    out, _ = node.run(np.concatenate(parts))
    return c.decode_outputs(out), node


@pytest.mark.parametrize("kind", list(KINDS), ids=lambda k: k.label)
def test_declination_over_can(kind: FilterKind) -> None:
    """The node's SET_GAIN 5 (ATT_CAN_GAIN_DECLINATION; docs/can.md) writes the kind's declination.

    Sent before the first sample the node starts on true north: its outputs are those of a node built
    with the declination, bit for bit. Sent to a running node it keeps the heading (the outputs those of
    the node without it) until a RESET, after which they are those of a node built with it that was
    reset at the same sample. Out of range or NaN: refused, nothing changed.
    """
    from attica.can import codec as c

    d = 0.4
    rec = _rec(3, d, 30.0)
    built, _ = _node_run(kind, rec, {}, declination=d)
    plain, _ = _node_run(kind, rec, {})
    yaw_err = np.degrees(np.abs(built.sets["euler"][-1, 2] - plain.sets["euler"][-1, 2]))
    assert abs(yaw_err - np.degrees(d)) < 1.0, f"the declination turns the heading: {yaw_err:.2f} deg"

    early, node = _node_run(kind, rec, {0: d})
    assert [a.result for a in early.answers] == [c.Ack.OK]
    assert getattr(node.state.fs, kind.label).declination == np.float32(d)
    assert early.sets.tobytes() == built.sets.tobytes(), "sent before the first sample: as if built with it"

    late, _ = _node_run(kind, rec, {1000: d, 2000: None})
    reset_plain, _ = _node_run(kind, rec, {2000: None})
    reset_built, _ = _node_run(kind, rec, {2000: None}, declination=d)
    assert [a.result for a in late.answers] == [c.Ack.OK, c.Ack.OK]
    steps = late.sets["steps"].astype(np.int64)
    n_before = int(np.nonzero(np.diff(steps) < 0)[0][0]) + 1  # the sets before the reset's restart of steps
    assert n_before > 900, n_before
    assert late.sets[:n_before].tobytes() == reset_plain.sets[:n_before].tobytes(), "the heading is kept"
    assert late.sets[n_before:].tobytes() == reset_built.sets[n_before:].tobytes(), "RESET applies it"

    for bad in (3.1416, -4.0, math.nan, math.inf):
        refused, node = _node_run(kind, _rec(3, d, 1.0), {10: bad})
        assert [a.result for a in refused.answers] == [c.Ack.REFUSED], bad
        assert getattr(node.state.fs, kind.label).declination == 0.0
