"""The CAN node in-process: bit-exact streams, fault injection, bus load, commands."""

from __future__ import annotations

import functools
from collections import Counter
from typing import Any

import numpy as np
import pytest

from attica import kinds, native, sim
from attica.can import codec as c
from attica.can.compare import compare, expected_outputs
from attica.crosscheck import Stream, crosscheck
from attica.reference.filter import Filter as RefFilter
from attica.settings import FilterKind, Flag, make_settings

from helpers import ROOT, assert_same_bits

ffi, lib = native.ffi, native.lib
RATE = 200.0
N_LONG = 100_000
DT = float(np.float32(1.0) / np.float32(RATE))
ERRORS = (
    "crc_errors",
    "counter_gaps",
    "dlc_errors",
    "unknown_ids",
    "duplicates",
    "stale_partials",
    "rx_overflows",
)


@functools.cache
def _recording(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rec = sim.simulate(sim.SimConfig(duration=n / RATE, rate=RATE, seed=seed, taps=4))
    assert rec.gyr.shape[0] == n
    return rec.gyr, rec.acc, rec.mag


@functools.cache
def _reference(kind: str, n: int, seed: int, keep: bytes | None = None) -> np.ndarray:
    """Reference outputs (checked bit for bit against the reference filter) for the dequantised samples.

    ``keep``: the samples the node stepped (a bool mask); each steps over the periods since the one kept
    before it, as the node derives them from the counters (runs of fewer than 15 lost samples here).
    """
    g, a, m = c.imu_values(*_recording(n, seed))
    if keep is not None:
        mask = np.frombuffer(keep, np.bool_)
        g, a, m = g[mask], a[mask], m[mask]
        per = np.diff(np.concatenate([[-1], np.nonzero(mask)[0]]))
        per[0] = 1
        assert per.max() < 16
        exp = expected_outputs(FilterKind.parse(kind), RATE, g, a, m, steps=per)
        assert exp.reference_ok, exp.reference_detail
        assert (exp.records["steps"] == np.cumsum(per)).all()
        return exp.records
    res = crosscheck(kind, [Stream(g, a, m)], make_settings(FilterKind.parse(kind), None, DT), segment=500)
    assert res.ok, res.first_mismatch
    assert res.steps == g.shape[0]
    return res.c_outputs[0]


def _still(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """n samples of a level sensor at rest (gyro 0, accel +g up, a field north and down), float32."""
    gyr = np.zeros((n, 3), np.float32)
    acc = np.tile(np.float32([0.0, 0.0, 9.80665]), (n, 1))
    mag = np.tile(np.float32([20.0, 0.0, -40.0]), (n, 1))
    return gyr, acc, mag


def _sets_only(fr: np.ndarray) -> np.ndarray:
    return fr[fr["id"] != c.ID_DIAG]


def _check_stream(
    out_frames: np.ndarray, ref: np.ndarray, kind: FilterKind, fd: bool, error_count: int = 0
) -> None:
    dec = c.decode_outputs(out_frames)
    n = ref.shape[0]
    s = dec.sets
    assert s.shape[0] == n and dec.other == 0 and not dec.answers
    assert s["crc_ok"].all() and dec.diag["crc_ok"].all()
    assert (s["counter"] == np.arange(n) % 16).all()
    assert (s["kind"] == int(kind)).all()
    assert (s["flags"] == (ref["flags"] & 0xFFFF)).all()
    assert (s["steps"] == (ref["steps"] & 0xFFFF)).all()
    assert_same_bits(s["q"], ref["q"], "q")
    if fd:
        assert_same_bits(s["euler"], ref["euler"], "euler")
        assert_same_bits(s["gyro_bias"], ref["gyro_bias"], "gyro_bias")
        assert_same_bits(s["cov"], ref["cov"], "cov")
    else:
        assert np.isnan(s["cov"]).all()  # classic sets carry no covariance: unknown, not 0
        assert (s["q16"] == c.quantise(ref["q"], c.QUAT16_FRAC)).all()
        assert (s["euler_raw"] == c.quantise(ref["euler"], c.EULER_FRAC)).all()
        assert (s["bias_raw"] == c.quantise(ref["gyro_bias"], c.BIAS_FRAC)).all()
    if error_count == 0:
        # byte for byte: the node's frames are the reference outputs encoded by the Python codec
        expected = c.encode_outputs(ref, kind, fd=fd)
        assert _sets_only(out_frames).tobytes() == expected.tobytes()


# --- the long bit-exact runs ----------------------------------------------------------------------


LONG_KINDS = ["ars", "kf", "mars"]
"""The kinds of the long runs (N_LONG steps: a 6-axis filter, one with a covariance, the 9-axis one);
every kind has a short run (test_node_stream_every_kind)."""


@pytest.mark.parametrize("kind", LONG_KINDS)
@pytest.mark.parametrize("fd", [False, True], ids=["classic", "fd"])
def test_node_stream_bit_exact_vs_reference(kind: str, fd: bool) -> None:
    _node_stream(kind, fd, N_LONG)


@pytest.mark.parametrize("kind", kinds.labels())
@pytest.mark.parametrize("fd", [False, True], ids=["classic", "fd"])
def test_node_stream_every_kind(kind: str, fd: bool) -> None:
    _node_stream(kind, fd, 4000)


def _node_stream(kind: str, fd: bool, n: int) -> None:
    """The node's output frames over n samples: the reference's outputs encoded, bit for bit."""
    gyr, acc, mag = _recording(n, 1)
    node = c.Node(
        kind,
        sample_rate=RATE,
        bitrate=1_000_000 if not fd else 500_000,
        data_bitrate=2_000_000 if fd else 0,
        fd=fd,
    )
    if fd:  # the same floats as the classic frames carry: one reference for both
        frames = c.encode_imu(*c.imu_values(gyr, acc, mag), fd=True)
    else:
        frames = c.encode_imu(gyr, acc, mag)
    out, steps = node.run(frames)
    st = node.stats()
    assert steps == n == st["steps"] == st["samples"] == st["sets"]
    assert st["rx_frames"] == frames.shape[0]
    assert all(st[e] == 0 for e in ERRORS) and st["tx_overflows"] == 0
    assert st["tx_frames"] == out.shape[0] == (1 if fd else 6) * n + n // 16
    ref = _reference(kind, n, 1)
    _check_stream(out, ref, FilterKind.parse(kind), fd)
    dec = c.decode_outputs(out)
    assert dec.diag.shape[0] == n // 16 and (dec.diag["counter"] == 15).all()
    # cantools decodes the same values as the numpy stream decoder
    rng = np.random.default_rng(0)
    per = 1 if fd else 6
    for i in rng.choice(n, 60, replace=False).tolist():
        start = i * per + i // 16  # one DIAG after every 16th set
        sig: dict[str, Any] = {}
        for f in out[start : start + per]:
            name, vals = c.decode(f)
            sig.update({f"{name}.{k}": v for k, v in vals.items()})
        pre = "ATT_OUT_FD." if fd else ""
        q = [
            sig[f"{pre or 'ATT_QUAT_A.'}q_w"],
            sig[f"{pre or 'ATT_QUAT_A.'}q_x"],
            sig[f"{pre or 'ATT_QUAT_B.'}q_y"],
            sig[f"{pre or 'ATT_QUAT_B.'}q_z"],
        ]
        assert_same_bits(np.array(q, np.float32), ref["q"][i], f"cantools q at {i}")
        roll = sig["ATT_OUT_FD.roll" if fd else "ATT_EULER.roll"]
        assert_same_bits(np.float32(roll), dec.sets["euler"][i, 0], f"cantools roll at {i}")
        assert sig["ATT_OUT_FD.steps" if fd else "ATT_STATUS.steps"] == int(ref["steps"][i]) & 0xFFFF


def test_output_and_diag_dividers() -> None:
    n = 3000
    gyr, acc, mag = _recording(n, 2)
    node = c.Node("ars", sample_rate=RATE, output_divider=3, diag_divider=5)
    out, steps = node.run(c.encode_imu(gyr, acc, mag))
    assert steps == n and node.stats()["sets"] == n // 3
    every = _reference("ars", n, 2)
    ref = every[2::3].copy()
    ored = every["flags"][0::3] | every["flags"][1::3] | every["flags"][2::3]  # since the last set
    ref["flags"] = (ored & ~np.uint32(0xC000)) | (ref["flags"] & np.uint32(0xC000))  # NOT_READY: its own
    _check_stream(out, ref, FilterKind.ARS, False)
    dec = c.decode_outputs(out)
    assert dec.diag.shape[0] == (n // 3) // 5
    assert (dec.diag["counter"] == (np.arange(1, dec.diag.shape[0] + 1) * 5 - 1) % 16).all()
    # no DIAG at all
    node = c.Node("ars", sample_rate=RATE, diag_divider=0)
    out, _ = node.run(c.encode_imu(gyr[:100], acc[:100], mag[:100]))
    assert not (out["id"] == c.ID_DIAG).any()


@pytest.mark.parametrize("fd", [False, True], ids=["classic", "fd"])
def test_a_set_carries_the_flags_of_every_step_since_the_previous_set(fd: bool) -> None:
    """With output_divider 10 a gyro clipped for one sample between two sets (recovery off, so no later
    step flags it) is in the next set's flags, as compare() expects; until 2026-12-06 a set had its own
    sample's flags only and the clip never reached the bus."""
    n = 400
    gyr, acc, mag = _still(n)
    gyr[303, 2] = 30.0  # beyond gyro_range 20 rad/s, within the classic frame
    node = c.Node(
        "mars",
        sample_rate=100.0,
        fd=fd,
        data_bitrate=2_000_000 if fd else 0,
        output_divider=10,
        recovery_time=0.0,
        gyro_range=20.0,
    )
    out, _ = node.run(c.encode_imu(gyr, acc, mag, fd=fd))
    sets = c.decode_outputs(out).sets
    assert sets.shape[0] == n // 10
    got = {int(s): int(f) for s, f in zip(sets["steps"], sets["flags"], strict=True)}
    assert got[310] & Flag.GYRO_RANGE and not got[300] & Flag.GYRO_RANGE and not got[320] & Flag.GYRO_RANGE
    g, a, m = (gyr, acc, mag) if fd else c.imu_values(gyr, acc, mag)
    settings = make_settings(FilterKind.MARS, None, 0.01, recovery_time=0.0, gyro_range=20.0)
    exp = expected_outputs(FilterKind.MARS, 100.0, g, a, m, settings=settings)
    rep = compare(exp, FilterKind.MARS, fd, out, output_divider=10)
    assert rep.exact and rep.sets_ok == n // 10, "\n".join(rep.lines())


def test_a_set_says_not_ready_only_when_its_own_sample_is() -> None:
    """NOT_READY and BAD_ARG say whether a set's q is an estimate: they are the set's own sample's, not
    ORed since the previous set (accel missing for the first 3 samples, divider 10: the filters start at
    step 4, and the set at step 10 is an estimate)."""
    n = 40
    gyr, acc, mag = _still(n)
    acc[:3] = np.nan
    for kind in ("ars", "mars", "mekf"):
        node = c.Node(kind, sample_rate=100.0, fd=True, data_bitrate=2_000_000, output_divider=10)
        out, _ = node.run(c.encode_imu(gyr, acc, mag, fd=True))
        sets = c.decode_outputs(out).sets
        assert not (sets["flags"] & Flag.NOT_READY).any(), (kind, sets["flags"])
        exp = expected_outputs(FilterKind.parse(kind), 100.0, gyr, acc, mag)
        assert exp.records["flags"][0] & Flag.NOT_READY  # the first samples were not ready
        rep = compare(exp, FilterKind.parse(kind), True, out, output_divider=10)
        assert rep.exact, "\n".join(rep.lines())


def test_a_reset_starts_the_sets_flags_afresh() -> None:
    """RESET (and SELECT) restart the sets' step grid and their flags: a gyro clipped after the last set
    of the filter that was reset is not in the first set after it (verify expects a clean start)."""
    n, div = 340, 3
    gyr, acc, mag = _still(n)
    gyr += np.float32(0.001)
    gyr[300] = [40.0, 0.0, 0.0]  # step 301: after the set at step 300, no set of its own
    g, a, m = c.imu_values(gyr, acc, mag)
    frames = c.encode_imu(g, a, m).reshape(n, -1)
    node = c.Node("ars", sample_rate=100.0, output_divider=div)
    node.run(np.concatenate(list(frames[:301])))
    node.run(c.encode_cmd(c.Cmd.RESET, counter=1))
    out, _ = node.run(np.concatenate(list(frames[301:])))
    exp = expected_outputs(FilterKind.ARS, 100.0, g[301:], a[301:], m[301:])
    rep = compare(exp, FilterKind.ARS, False, out, output_divider=div)
    assert rep.exact and rep.sets_ok == (n - 301) // div, "\n".join(rep.lines())


# --- fault injection ------------------------------------------------------------------------------

CLASSIC_FAULTS = (
    "drop_one",
    "drop_set",
    "dup",
    "dup_late",
    "reorder",
    "flip",
    "dlc",
    "unknown",
    "partial",
    "bad_cmd",
    "late",
)
FD_FAULTS = ("drop", "dup", "flip", "dlc", "unknown", "bad_cmd")


def _flip(f: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    g = f.copy()
    bit = int(rng.integers(0, 8 * int(f["len"])))
    g["data"][bit // 8] ^= np.uint8(1 << (bit % 8))
    return g


def _bad_cmd(rng: np.random.Generator) -> np.ndarray:
    cmd = c.encode_cmd(c.Cmd.RESET, counter=3)
    return _flip(cmd[0], rng)[None]


def _inject(
    sets: list[np.ndarray], faults: tuple[str, ...], every: int, seed: int
) -> tuple[list[np.ndarray], Counter[str], np.ndarray, Counter[str]]:
    """Apply one fault to every ``every``-th sample set; return frames, expected counters, accepted mask."""
    rng = np.random.default_rng(seed)
    n = len(sets)
    groups = [s.copy() for s in sets]
    accepted = np.ones(n, np.bool_)
    want: Counter[str] = Counter()
    used: Counter[str] = Counter()
    for i in range(every, n - 3, every):
        kind = faults[int(rng.integers(0, len(faults)))]
        used[kind] += 1
        grp = groups[i]
        j = int(rng.integers(0, grp.shape[0]))
        if kind == "drop_one":
            groups[i] = np.delete(grp, j)
            want["stale_partials"] += 1
            accepted[i] = False
        elif kind in ("drop_set", "drop"):
            groups[i] = grp[:0]
            want["counter_gaps"] += 1
            accepted[i] = False
        elif kind == "dup":
            groups[i] = np.insert(grp, j, grp[j])
            want["duplicates"] += 1
        elif kind == "dup_late":
            groups[i] = np.concatenate([grp, grp[j : j + 1]])
            want["duplicates"] += 1
        elif kind == "reorder":
            groups[i] = grp[rng.permutation(grp.shape[0])]
        elif kind == "flip":
            grp[j] = _flip(grp[j], rng)
            want["crc_errors"] += 1
            want["stale_partials" if grp.shape[0] == 3 else "counter_gaps"] += 1
            accepted[i] = False
        elif kind == "dlc":
            choice = int(rng.integers(0, 3))
            if grp.shape[0] == 3:
                grp[j]["len"], grp[j]["fd"] = ((7, 0), (8, 1), (12, 1))[choice]
            else:
                grp[j]["len"], grp[j]["fd"] = ((64, 0), (48, 1), (8, 0))[choice]
            want["dlc_errors"] += 1
            want["stale_partials" if grp.shape[0] == 3 else "counter_gaps"] += 1
            accepted[i] = False
        elif kind == "unknown":
            alien = grp[j].copy()
            alien["id"] = (0x123, c.ID_QUAT_A, c.ID_STATUS, 0x7FF)[int(rng.integers(0, 4))]
            groups[i] = np.insert(grp, j, alien)
            want["unknown_ids"] += 1
        elif kind == "partial":
            groups[i] = grp[j : j + 1]
            want["stale_partials"] += 1
            accepted[i] = False
        elif kind == "bad_cmd":
            groups[i] = np.insert(grp, j, _bad_cmd(rng))
            want["crc_errors"] += 1
        elif kind == "late":
            # one frame of sample i arrives after sample i+1: i is stale; the late frame opens a partial
            # (counter going back = a gap) that sample i+2 makes stale (and jumps forward = a gap)
            groups[i] = np.delete(grp, j)
            groups[i + 1] = np.concatenate([groups[i + 1], grp[j : j + 1]])
            want["stale_partials"] += 2
            want["counter_gaps"] += 2
            accepted[i] = False
    return groups, want, accepted, used


@pytest.mark.parametrize("fd", [False, True], ids=["classic", "fd"])
def test_fault_injection_counted_and_stream_stays_bit_exact(fd: bool) -> None:
    n = 8000
    gyr, acc, mag = _recording(n, 4)
    kind = FilterKind.KF if fd else FilterKind.ARS
    if fd:
        frames = c.encode_imu(*c.imu_values(gyr, acc, mag), fd=True).reshape(n, 1)
    else:
        frames = c.encode_imu(gyr, acc, mag).reshape(n, 3)
    groups, want, accepted, used = _inject(list(frames), FD_FAULTS if fd else CLASSIC_FAULTS, 25, seed=9 + fd)
    assert set(used) == set(FD_FAULTS if fd else CLASSIC_FAULTS), used  # every fault type exercised
    node = c.Node(kind, sample_rate=RATE, bitrate=500_000, data_bitrate=2_000_000 if fd else 0, fd=fd)
    # feed in random-size chunks through push/poll/pop as well as the batch runner
    stream = np.concatenate(groups)
    half = stream.shape[0] // 2
    out1, steps1 = node.run(stream[:half])
    outs = [out1]
    steps = steps1
    pos = half
    rng = np.random.default_rng(1)
    while pos < stream.shape[0]:
        k = int(rng.integers(1, 40))
        assert node.push(stream[pos : pos + k]) == min(k, stream.shape[0] - pos)
        steps += node.poll()
        outs.append(node.pop())
        while node.rx_pending():  # a burst larger than one poll's room: drain before the next one
            steps += node.poll()
            outs.append(node.pop())
        pos += k
    tail, k = node.flush()
    outs.append(tail)
    steps += k
    assert node.rx_pending() == 0
    out = np.concatenate(outs)
    st = node.stats()
    # every sample stepped the filter or was integrated over by the next one: n filter steps in all
    assert steps == st["steps"] == n and st["samples"] == int(accepted.sum())
    for e in ERRORS:
        assert st[e] == want[e], (e, st[e], want[e], used)
    assert st["tx_overflows"] == 0
    ref = _reference(kind.label, n, 4, accepted.tobytes())
    _check_stream(out, ref, kind, fd, error_count=1)
    dec = c.decode_outputs(out)
    # ATT_STATUS carries the saturating error total, ATT_DIAG the counters at the time
    total = sum(want[e] for e in ERRORS)
    if not fd:  # ATT_OUT_FD has no error_count
        assert int(dec.sets["error_count"][-1]) == min(total, 255)
    last = dec.diag[-1]
    for name in ("crc_errors", "counter_gaps", "dlc_errors", "unknown_ids", "duplicates", "stale_partials"):
        assert int(last[name]) <= min(want[name], 255)
    assert (np.diff(dec.diag["crc_errors"].astype(int)) >= 0).all()


def test_rx_overflow_and_tx_backpressure() -> None:
    n = 40
    gyr, acc, mag = _recording(n, 5)
    frames = c.encode_imu(gyr, acc, mag)
    node = c.Node("ars", sample_rate=RATE, diag_divider=4)
    assert node.push(frames[:100]) == lib.ATT_NODE_RX_RING
    assert node.stats()["rx_overflows"] == 100 - lib.ATT_NODE_RX_RING
    # the rx ring holds 21 whole samples = 126+ output frames: poll stops while the tx ring is short of room
    first = node.poll()
    assert 0 < first < 21 and int(lib.att_node_tx_pending(node.state.ptr)) <= lib.ATT_NODE_TX_RING
    assert node.rx_pending() > 0
    out = [node.pop()]
    tail, k = node.flush()
    out.append(tail)
    total = first + k
    assert total == 21 and node.stats()["tx_overflows"] == 0
    sets = c.decode_outputs(np.concatenate(out)).sets
    assert sets.shape[0] == 21 and sets["crc_ok"].all()
    ref = _reference("ars", n, 5)[:21]
    assert_same_bits(sets["q"], ref["q"], "q after backpressure")
    # frames 64..99 were refused: sample 21 has only its gyro frame, 22..32 are gone, 33 lost its gyro
    # frame; the rest: 21 and 33 are stale partials, 21 -> 33 is a gap, 34..39 are stepped: 34 over the
    # 14 periods since 20 (21..33 lost), 35..39 one each
    rest, steps = node.run(frames[100:])
    st = node.stats()
    assert (st["stale_partials"], st["counter_gaps"], steps, st["steps"], st["samples"]) == (2, 1, 19, 40, 27)
    assert c.decode_outputs(rest).sets["steps"].tolist() == [35, 36, 37, 38, 39, 40]


def test_counters_saturate_on_the_bus() -> None:
    node = c.Node("ars", sample_rate=RATE, diag_divider=1)
    node.state.stats.crc_errors = 300
    node.state.stats.duplicates = 70000
    assert lib.att_node_error_count(node.state.ptr) == 255
    gyr, acc, mag = _recording(3, 11)
    out, _ = node.run(c.encode_imu(gyr, acc, mag))
    dec = c.decode_outputs(out)
    assert (dec.sets["error_count"] == 255).all()
    assert (dec.diag["crc_errors"] == 255).all() and (dec.diag["duplicates"] == 255).all()
    assert (dec.diag["counter_gaps"] == 0).all() and dec.diag["crc_ok"].all()
    node = c.Node("ars", sample_rate=RATE)
    node.state.stats.crc_errors = 200
    node.state.stats.stale_partials = 55
    assert lib.att_node_error_count(node.state.ptr) == 255
    node.state.stats.stale_partials = 54
    assert lib.att_node_error_count(node.state.ptr) == 254


def test_either_input_form_in_either_output_mode() -> None:
    n = 64
    gyr, acc, mag = _recording(n, 12)
    classic = c.encode_imu(gyr, acc, mag).reshape(n, 3)
    fd = c.encode_imu(*c.imu_values(gyr, acc, mag), fd=True)
    mixed = np.concatenate([classic[i] if i % 2 else fd[i : i + 1] for i in range(n)])
    ref = _reference("ars", n, 12)
    for out_fd in (False, True):
        node = c.Node("ars", sample_rate=RATE, data_bitrate=2_000_000, fd=out_fd)
        out, steps = node.run(mixed)
        assert steps == n and all(node.stats()[e] == 0 for e in ERRORS)
        _check_stream(out, ref, FilterKind.ARS, out_fd)


def test_c_api_null_and_empty() -> None:
    n = ffi.new("att_node_t *")
    f = ffi.new("att_can_frame_t *")
    s = ffi.new("att_node_settings_t *")
    assert lib.att_node_settings_default(lib.ATT_FILTER_ARS, 100.0, s) == lib.ATT_OK
    assert lib.att_node_init(ffi.NULL, s) == lib.ATT_ERR_NULL
    assert lib.att_node_init(n, ffi.NULL) == lib.ATT_ERR_NULL
    assert not lib.att_node_rx(ffi.NULL, f) and lib.att_node_poll(ffi.NULL) == 0
    assert not lib.att_node_tx(ffi.NULL, f) and lib.att_node_tx_pending(ffi.NULL) == 0
    assert lib.att_node_bus_load(ffi.NULL) == -1.0
    assert lib.att_node_init(n, s) == lib.ATT_OK
    assert not lib.att_node_rx(n, ffi.NULL) and not lib.att_node_tx(n, f) and lib.att_node_poll(n) == 0
    assert lib.att_node_settings_default(0, 100.0, s) == lib.ATT_ERR_KIND
    assert lib.att_node_settings_default(lib.ATT_FILTER_ARS, float("nan"), s) == lib.ATT_ERR_SETTINGS


# --- settings and bus load ------------------------------------------------------------------------


def _settings(**kw: Any) -> Any:
    s = ffi.new("att_node_settings_t *")
    rate = kw.pop("rate", 100.0)
    usable = 0.0 < rate < float("inf")
    assert (
        lib.att_node_settings_default(kw.pop("kind", lib.ATT_FILTER_ARS), rate if usable else 100.0, s) == 0
    )
    s.sample_rate = rate
    for k, v in kw.items():
        setattr(s, k, v)
    return s


BUS_TABLE = [
    # (rate Hz, bitrate, data bitrate, fd, output load %) with DIAG every 16th set (docs/can.md)
    (100, 500_000, 0, False, 16.36875),
    (200, 500_000, 0, False, 32.7375),
    (500, 500_000, 0, False, 81.84375),
    (1000, 500_000, 0, False, 163.6875),
    (1000, 1_000_000, 0, False, 81.84375),
    (1000, 500_000, 2_000_000, True, 42.3875),
    (1000, 1_000_000, 5_000_000, True, 17.80375),
    (2000, 500_000, 2_000_000, True, 84.775),
]


def test_bus_load_table_and_formulas() -> None:
    assert lib.att_node_classic_bits(8) == c.classic_bits(8) == 135
    assert lib.att_node_classic_bits(0) == c.classic_bits(0) == 55
    assert c.fd_frame_time(64, 500_000, 2_000_000) == pytest.approx(34 / 500e3 + 678 / 2e6, rel=1e-12)
    assert lib.att_node_fd_frame_time(64, 500_000, 2_000_000) == pytest.approx(
        34 / 500e3 + 678 / 2e6, rel=1e-6
    )
    assert lib.att_node_fd_frame_time(64, 500_000, 0) == -1.0
    for rate, br, dbr, fd, pct in BUS_TABLE:
        load = c.bus_load(rate, br, dbr, fd)
        assert 100 * load == pytest.approx(pct, rel=1e-12), (rate, br, dbr, fd)
        s = _settings(rate=float(rate), bitrate=br, data_bitrate=dbr, fd=fd)
        assert lib.att_node_bus_load(s) == pytest.approx(load, rel=1e-6)
        n = ffi.new("att_node_t *")
        assert (lib.att_node_init(n, s) == lib.ATT_OK) == (load <= 1.0)
    for div in (1, 2, 5):
        for dd in (0, 1, 16):
            s = _settings(rate=300.0, output_divider=div, diag_divider=dd)
            assert lib.att_node_bus_load(s) == pytest.approx(
                c.bus_load(300.0, output_divider=div, diag_divider=dd), rel=1e-6
            )
    # an ATT_MAG_OFFSET after every ATT_DIAG while the init filter estimates a hard-iron offset
    for dd in (1, 16):
        s = _settings(rate=300.0, kind=lib.ATT_FILTER_MARS, diag_divider=dd)
        s.filter.mars.hard_iron_tau = 60.0
        want = c.bus_load(300.0, diag_divider=dd, mag_offset=True)
        assert want > c.bus_load(300.0, diag_divider=dd)
        assert lib.att_node_bus_load(s) == pytest.approx(want, rel=1e-6)
    assert c.input_bus_load(1000, 500_000) == pytest.approx(3 * 135 * 1000 / 500e3)


def test_docs_tables_match_the_code() -> None:
    text = (ROOT / "docs" / "can.md").read_text()
    assert c.bus_load_table() in text
    assert c.bus_load_table(with_inputs=True) in text
    for m in c.database().messages:
        assert f"| 0x{m.frame_id:03X} | {m.name} |" in text, m.name


def test_init_refuses_bus_load_over_100_percent_and_leaves_the_node_untouched() -> None:
    with pytest.raises(c.NodeError, match=r"163\.7 % of the bus"):
        c.Node("ars", sample_rate=1000.0, bitrate=500_000)
    c.Node("ars", sample_rate=1000.0, bitrate=500_000, output_divider=2)  # 82 %: fine
    c.Node("ars", sample_rate=1000.0, bitrate=500_000, data_bitrate=2_000_000, fd=True)  # FD: 42 %
    node = c.Node("ars", sample_rate=RATE)
    gyr, acc, mag = _recording(50, 6)
    node.run(c.encode_imu(gyr, acc, mag))
    before = bytes(node.state)
    bad = [
        _settings(rate=1000.0),  # bus load 165 %
        _settings(rate=0.0),
        _settings(rate=float("inf")),
        _settings(bitrate=0),
        _settings(bitrate=2_000_000),
        _settings(fd=True),  # FD without a data bitrate
        _settings(data_bitrate=100_000),  # data phase slower than nominal
        _settings(output_divider=0),
    ]
    s = _settings()
    s.filter.ars.dt = -1.0
    bad.append(s)
    s = _settings()
    s.filter.ars.gain = 2.0
    bad.append(s)
    s = _settings(rate=200.0)
    s.filter.ars.dt = 0.01  # the filter's period does not match the sample rate
    bad.append(s)
    for kind in [k.label for k in kinds.KINDS if k.has_period and k.kind != FilterKind.ARS]:
        # every other kind with a dt (the ARS is above; the EKF was once forgotten)
        s = _settings(rate=200.0)
        s.kind = getattr(lib, f"ATT_FILTER_{kind.upper()}")
        assert lib.att_filter_settings_default(s.kind, 0.01, ffi.addressof(s[0], "filter")) == lib.ATT_OK
        bad.append(s)
    for i, s in enumerate(bad):
        assert lib.att_node_init(node.state.ptr, s) == lib.ATT_ERR_SETTINGS, i
    assert bytes(node.state) == before
    with pytest.raises(c.NodeError, match="does not match sample_rate"):
        c.Node("ars", sample_rate=RATE, dt=0.01)
    with pytest.raises(c.NodeError, match="does not match sample_rate"):
        c.Node("ekf", sample_rate=RATE, dt=0.01)
    c.Node("ekf", sample_rate=RATE)
    c.Node("tilt", sample_rate=RATE)  # no dt to match
    s = _settings()
    s.kind = 9
    assert lib.att_node_init(node.state.ptr, s) == lib.ATT_ERR_KIND
    assert bytes(node.state) == before


# --- commands -------------------------------------------------------------------------------------


def _answers(out: np.ndarray) -> list[c.Answer]:
    return c.decode_outputs(out).answers


def _ref_run(ref: RefFilter, g: np.ndarray, a: np.ndarray, m: np.ndarray) -> np.ndarray:
    return ref.run(g, a, m)


def test_command_reset_select_and_set_gain_bit_exact() -> None:
    n = 480
    gyr, acc, mag = _recording(n, 7)
    g, a, m = c.imu_values(gyr, acc, mag)
    samples = c.encode_imu(gyr, acc, mag).reshape(n, 3)
    k1, k2, k3, k4 = 120, 240, 300, 400
    cmds = {
        k1: c.encode_cmd(c.Cmd.SET_GAIN, c.Gain.TAU_ACC, 0.5, counter=1),
        k2: c.encode_cmd(c.Cmd.RESET, counter=2),
        k3: c.encode_cmd(c.Cmd.SELECT, int(FilterKind.KF), counter=3),
        k4: c.encode_cmd(c.Cmd.SET_GAIN, c.Gain.KF_R, 2.5, counter=4),
    }
    stream = np.concatenate(
        [x for i in range(n) for x in ((cmds[i], samples[i]) if i in cmds else (samples[i],))]
    )
    node = c.Node("ars", sample_rate=RATE)
    out, steps = node.run(stream)
    assert steps == n and node.stats()["commands"] == 4
    ans = _answers(out)
    assert [(x.cmd, x.result, x.counter, x.crc_ok) for x in ans] == [
        (3, c.Ack.OK, 1, True),
        (2, c.Ack.OK, 2, True),
        (1, c.Ack.OK, 3, True),
        (3, c.Ack.OK, 4, True),
    ]
    assert [x.kind for x in ans] == [1, 1, 3, 3]
    assert ans[1].steps == 0 and ans[2].steps == 0 and ans[0].steps == k1 and ans[3].steps == k4 - k3
    # the reference, through the same events
    ars = make_settings(FilterKind.ARS, None, DT)
    ref = RefFilter("ars", ars)
    parts = [ref.run(g[:k1], a[:k1], m[:k1])]
    ref2 = ref
    ref2.retune(tau=0.5, gain=0.0)  # set gain keeps the state; a time constant replaces the gain
    parts.append(ref2.run(g[k1:k2], a[k1:k2], m[k1:k2]))
    ref2.reset()
    parts.append(ref2.run(g[k2:k3], a[k2:k3], m[k2:k3]))
    kf = make_settings(FilterKind.KF, None, DT)
    ref3 = RefFilter("kf", kf)
    parts.append(ref3.run(g[k3:k4], a[k3:k4], m[k3:k4]))
    ref4 = ref3
    ref4.retune(r_noise=2.5)
    parts.append(ref4.run(g[k4:], a[k4:], m[k4:]))
    ref_out = np.concatenate(parts)
    sets = c.decode_outputs(out).sets
    assert sets.shape[0] == n and sets["crc_ok"].all()
    assert_same_bits(sets["q"], ref_out["q"], "q through commands")
    assert (sets["euler_raw"] == c.quantise(ref_out["euler"], c.EULER_FRAC)).all()
    assert (sets["steps"] == ref_out["steps"] & 0xFFFF).all() and (
        sets["flags"] == ref_out["flags"] & 0xFFFF
    ).all()
    assert (sets["kind"][:k3] == 1).all() and (sets["kind"][k3:] == 3).all()
    assert float(node.state.fs.kf.r_noise) == 2.5 and node.running_kind == FilterKind.KF


def test_set_gain_changes_the_gain_and_keeps_the_state() -> None:
    gyr, acc, mag = _recording(100, 8)
    node = c.Node("mars", sample_rate=RATE)
    node.run(c.encode_imu(gyr, acc, mag))
    q_before = [float(getattr(node.state.f.u.mars.st.q, k)) for k in "wxyz"]
    out, _ = node.run(
        np.concatenate(
            [
                c.encode_cmd(c.Cmd.SET_GAIN, c.Gain.TAU_ACC, 2.0, counter=5),
                c.encode_cmd(c.Cmd.SET_GAIN, c.Gain.TAU_MAG, 4.0, counter=6),
            ]
        )
    )
    assert [(x.result, x.counter) for x in _answers(out)] == [(c.Ack.OK, 5), (c.Ack.OK, 6)]
    f32 = np.float32
    mars = node.state.f.u.mars
    assert mars.c.k_acc == f32(DT) / (f32(2.0) + f32(DT)) and mars.c.k_mag == f32(DT) / (f32(4.0) + f32(DT))
    assert [float(getattr(mars.st.q, k)) for k in "wxyz"] == q_before and mars.st.steps == 100


@pytest.mark.parametrize(
    ("kind", "cmd", "arg", "value", "result"),
    [
        ("ars", c.Cmd.SET_GAIN, c.Gain.KF_R, 1.0, c.Ack.BAD_ARG),  # not a parameter of ARS
        ("ars", c.Cmd.SET_GAIN, c.Gain.TAU_MAG, 1.0, c.Ack.BAD_ARG),
        ("ars", c.Cmd.SET_GAIN, c.Gain.EKF_R, 1.0, c.Ack.BAD_ARG),
        ("ars", c.Cmd.SET_GAIN, 99, 1.0, c.Ack.BAD_ARG),
        ("ars", c.Cmd.SET_GAIN, c.Gain.TAU_ACC, -1.0, c.Ack.REFUSED),
        ("ars", c.Cmd.SET_GAIN, c.Gain.TAU_ACC, float("nan"), c.Ack.REFUSED),
        ("kf", c.Cmd.SET_GAIN, c.Gain.KF_R, 0.0, c.Ack.REFUSED),
        ("kf", c.Cmd.SET_GAIN, c.Gain.KF_R, float("inf"), c.Ack.REFUSED),
        ("ars", c.Cmd.SELECT, 0, 0.0, c.Ack.BAD_ARG),
        ("ars", c.Cmd.SELECT, 9, 0.0, c.Ack.BAD_ARG),
        ("ars", 0, 0, 0.0, c.Ack.UNKNOWN_CMD),
        ("ars", 10, 1, 0.0, c.Ack.UNKNOWN_CMD),  # 4..9 are the calibration commands (test_calib_node.py)
    ],
)
def test_refused_commands_are_answered_and_change_nothing(
    kind: str, cmd: int, arg: int, value: float, result: c.Ack
) -> None:
    gyr, acc, mag = _recording(60, 9)
    frames = c.encode_imu(gyr, acc, mag)
    node = c.Node(kind, sample_rate=RATE)
    node.run(frames[:90])
    before = bytes(node.state.f)
    out, _ = node.run(c.encode_cmd(cmd, arg, value, counter=11))
    (ans,) = _answers(out)
    assert (ans.cmd, ans.result, ans.counter, ans.kind, ans.steps, ans.crc_ok) == (
        cmd & 0xF,
        result,
        11,
        int(FilterKind.parse(kind)),
        30,
        True,
    )
    assert bytes(node.state.f) == before
    name, sig = c.decode(out[0])
    assert name == "ATT_STATUS" and sig["ack"] == 0x80 | (int(result) << 4) | (cmd & 0xF)
    # the stream goes on as if nothing happened
    rest, steps = node.run(frames[90:])
    assert steps == 30
    ref = _reference(kind, 60, 9)
    assert_same_bits(c.decode_outputs(rest).sets["q"], ref["q"][30:], "q after a refused command")


def test_command_with_bad_crc_is_ignored_and_counted() -> None:
    gyr, acc, mag = _recording(40, 10)
    node = c.Node("ars", sample_rate=RATE)
    node.run(c.encode_imu(gyr[:20], acc[:20], mag[:20]))
    rng = np.random.default_rng(2)
    cmd = c.encode_cmd(c.Cmd.RESET, counter=1)
    bad = np.concatenate([_flip(cmd[0], rng)[None] for _ in range(5)])
    short = cmd.copy()
    short["len"] = 6
    out, _ = node.run(np.concatenate([bad, short]))
    assert out.shape[0] == 0
    st = node.stats()
    assert st["crc_errors"] == 5 and st["dlc_errors"] == 1 and st["commands"] == 0
    assert node.output()["steps"] == 20  # no reset happened
    out, steps = node.run(c.encode_imu(gyr[20:], acc[20:], mag[20:], counter0=20))
    assert steps == 20
    sets = c.decode_outputs(out).sets
    assert (sets["error_count"] == 6).all()
    assert_same_bits(sets["q"], _reference("ars", 40, 10)["q"][20:], "q after bad commands")


def test_select_back_to_the_init_kind_uses_the_init_settings() -> None:
    node = c.Node("ars", sample_rate=RATE, tau=0.25, gain=0.0)
    out, _ = node.run(
        np.concatenate(
            [
                c.encode_cmd(c.Cmd.SELECT, int(FilterKind.TILT), counter=1),
                c.encode_cmd(c.Cmd.SELECT, int(FilterKind.ARS), counter=2),
            ]
        )
    )
    assert [(x.result, x.kind) for x in _answers(out)] == [(c.Ack.OK, 6), (c.Ack.OK, 1)]
    assert float(node.state.fs.ars.tau) == 0.25
    f32 = np.float32
    assert node.state.f.u.ars.c.k == f32(DT) / (f32(0.25) + f32(DT))


@pytest.mark.parametrize("kind", ["ars", "mars", "mekf"])
def test_push_sample_is_the_imu_fd_frame_path_bit_for_bit(kind: str) -> None:
    """att_node_push_sample (an IMU on the node's board) against the same samples as IMU_FD frames:
    the same output frames, flags and counters (an adversarial stretch included)."""
    g, a, m = _recording(600, 11)
    g, a, m = g.copy(), a.copy(), m.copy()
    g[200] = np.nan
    a[201] = np.inf
    m[202:260] = 0.0  # absent mag
    a[300] = 1e6  # saturated
    frames_fd = c.encode_imu(g, a, m, fd=True)
    by_frame = c.Node(kind, sample_rate=RATE)
    by_push = c.Node(kind, sample_rate=RATE)
    want, steps = by_frame.run(frames_fd)
    got = []
    for i in range(g.shape[0]):
        assert by_push.push_sample(g[i], a[i], m[i])
        got.append(by_push.pop())
    assert steps == g.shape[0]
    got_frames = np.concatenate(got)
    assert got_frames.tobytes() == want.tobytes()  # ids, lengths, every data byte
    s_frame, s_push = by_frame.stats(), by_push.stats()
    assert s_frame.pop("rx_frames") == g.shape[0] and s_push.pop("rx_frames") == 0
    s_frame.pop("tx_frames")
    s_push.pop("tx_frames")
    assert s_frame == s_push


def test_push_sample_keeps_the_order_and_refuses_when_tx_is_full() -> None:
    g, a, m = _recording(40, 12)
    node = c.Node("ars", sample_rate=RATE, diag_divider=0)
    # a command waiting in the rx ring is answered before the pushed sample steps
    node.push(c.encode_cmd(c.Cmd.RESET, counter=3))
    assert node.push_sample(g[0], a[0], m[0])
    out = node.pop()
    assert list(out["id"][:2]) == [c.ID_STATUS, c.ID_QUAT_A] and node.stats()["steps"] == 1
    # nobody drains tx: a sample steps while the ring has room for a whole set, then is refused
    pushed = [node.push_sample(g[i], a[i], m[i]) for i in range(1, 40)]
    room = (lib.ATT_NODE_TX_RING - lib.ATT_NODE_SET_MAX) // 6 + 1
    assert pushed == [True] * room + [False] * (39 - room)
    assert node.stats()["rx_overflows"] == 39 - room and node.stats()["steps"] == 1 + room
    assert node.stats()["tx_overflows"] == 0
    node.pop()
    assert node.push_sample(g[0], a[0], m[0]) and node.stats()["steps"] == 2 + room
    assert not lib.att_node_push_sample(ffi.NULL, ffi.NULL)


def test_id_offset_moves_the_node_and_its_rx_ids() -> None:
    node = c.Node("ars", sample_rate=RATE, id_offset=0x40)
    assert node.rx_ids() == [0x140, 0x141, 0x142, 0x150, 0x340]
    assert c.Node("ars", sample_rate=RATE).rx_ids() == [0x100, 0x101, 0x102, 0x110, 0x300]
    g, a, m = _recording(20, 13)
    fr = c.encode_imu(g, a, m)
    moved = fr.copy()
    moved["id"] += 0x40
    out, steps = node.run(moved)
    ref, ref_steps = c.Node("ars", sample_rate=RATE).run(fr)
    assert steps == ref_steps == 20
    assert (out["id"] == ref["id"] + 0x40).all() and (out["data"] == ref["data"]).all()
    out, steps = node.run(fr)  # the DBC's own IDs: another node's
    assert steps == 0 and node.stats()["unknown_ids"] == 60
    for bad in (lib.ATT_NODE_ID_OFFSET_MIN - 1, lib.ATT_NODE_ID_OFFSET_MAX + 1):
        with pytest.raises(c.NodeError, match=f"id_offset {bad} moves an ID out of 0 .. 0x7FF"):
            c.Node("ars", sample_rate=RATE, id_offset=bad)
    assert lib.att_node_rx_ids(ffi.NULL, ffi.new("uint32_t[5]")) == 0


def _node_settings(kind: str = "ars") -> Any:
    s = ffi.new("att_node_settings_t *")
    assert lib.att_node_settings_default(int(FilterKind.parse(kind)), RATE, s) == lib.ATT_OK
    return s


NODE_PROBES: list[tuple[str, Any, str]] = [
    ("sample_rate", 0.0, "sample_rate"),
    ("sample_rate", float("nan"), "sample_rate"),
    ("sample_rate", 1e6, "sample_rate"),
    ("sample_rate", 201.0, "filter.dt"),  # the filter's dt stays 1/200 s
    ("bitrate", 999, "bitrate"),
    ("bitrate", 1_000_001, "bitrate"),
    ("bitrate", 50_000, "bus load"),
    ("data_bitrate", 400_000, "data_bitrate"),
    ("data_bitrate", 16_000_001, "data_bitrate"),
    ("fd", True, "fd"),  # without a data bit rate
    ("id_offset", -257, "id_offset"),
    ("id_offset", 1280, "id_offset"),
    ("output_divider", 0, "output_divider"),
    ("output_divider", 65536, "output_divider"),
]


@pytest.mark.parametrize(("field", "value", "named"), NODE_PROBES)
def test_node_settings_check_names_what_init_refuses(field: str, value: Any, named: str) -> None:
    s = _node_settings()
    setattr(s, field, value)
    why = ffi.new("att_settings_error_t *")
    n = ffi.new("att_node_t *")
    status = lib.att_node_init(n, s)
    assert status == lib.ATT_ERR_SETTINGS
    assert lib.att_node_settings_check(s, why) == status
    assert ffi.string(why.field).decode() == named


def test_node_settings_check_agrees_with_init_on_random_settings() -> None:
    """Random perturbations of node fields, filter fields, the calibration and bools: the check gives
    att_node_init's status every time, names a field exactly when it is ATT_ERR_SETTINGS."""
    rng = np.random.default_rng(22)
    values: dict[str, list[Any]] = {
        "sample_rate": [RATE, 0.0, -1.0, 1e5, 1e5 + 1, float("inf"), 100.0, RATE * 1.0005],
        "bitrate": [125_000, 500_000, 1_000_000, 999, 2_000_000, 0],
        "data_bitrate": [0, 2_000_000, 100, 20_000_000],
        "output_divider": [1, 2, 0, 65535, 65536],
        "diag_divider": [0, 1, 16],
        "id_offset": [0, -256, 1279, -257, 1280, 0x20],
    }
    kinds = ["ars", "mars", "ekf", "mekf"]
    n = ffi.new("att_node_t *")
    why = ffi.new("att_settings_error_t *")
    seen: Counter[str] = Counter()
    for _ in range(3000):
        s = _node_settings(kinds[int(rng.integers(len(kinds)))])
        for name in rng.choice(list(values), size=int(rng.integers(1, 4)), replace=False):
            opts = values[str(name)]
            setattr(s, str(name), opts[int(rng.integers(len(opts)))])
        if rng.random() < 0.2:
            s.fd = True
        if rng.random() < 0.1:
            s.accel_out = True
        if rng.random() < 0.1:
            ffi.cast("uint8_t *", ffi.addressof(s, "fd"))[0] = 2  # not a bool
        if rng.random() < 0.1:
            s.calib.convention = 7  # no such convention
        if rng.random() < 0.1:
            s.filter.ars.tau_acc_lp = -1.0  # refused for ars (other kinds: another member)
        status = lib.att_node_init(n, s)
        assert lib.att_node_settings_check(s, why) == status
        assert (why.field != ffi.NULL) == (status == lib.ATT_ERR_SETTINGS)
        seen[ffi.string(why.field).decode() if why.field != ffi.NULL else "ok"] += 1
    expect = {"ok", "bus load", "calib.convention", "fd", "filter.dt", "id_offset", "sample_rate"}
    assert expect <= set(seen), seen
    assert lib.att_node_settings_check(ffi.NULL, why) == lib.ATT_ERR_NULL


@pytest.mark.parametrize("kind", ["ars", "mars", "mekf"])
def test_a_gyro_clipped_by_the_classic_frame_is_a_clipping_gyro(kind: str) -> None:
    """The classic gyro field holds +-32 rad/s, below the 0.98 x 34.9 rad/s at which the defaults call a
    gyro clipped: a rate beyond the frame's range arrives at full scale, which the node decodes as beyond
    every range (docs/can.md, Scaling), so its filter flags GYRO_RANGE and starts its recovery, as over
    CAN FD; bit for bit with the reference fed codec.imu_values. Until 2026-12-06 the node integrated
    32 rad/s, flagged nothing, and the yaw was still off 2 s later."""
    n, rate = 400, 100.0
    gyr, acc, mag = _still(n)
    gyr[200:210, 2] = 33.0  # within the sensor's 2000 deg/s, beyond the frame's 32 rad/s
    g, a, m = c.imu_values(gyr, acc, mag)
    assert (g[200:210, 2] == c.CLIPPED).all()
    out, _ = c.Node(kind, sample_rate=rate).run(c.encode_imu(gyr, acc, mag))
    sets = c.decode_outputs(out).sets
    exp = expected_outputs(FilterKind.parse(kind), rate, g, a, m)
    assert exp.reference_ok, exp.reference_detail
    assert (sets["flags"] == (exp.records["flags"] & 0xFFFF)).all()
    assert_same_bits(sets["q"], exp.records["q"], "q")
    assert (sets["flags"][200:210] & Flag.GYRO_RANGE).all()
    assert sets["flags"][250] & Flag.INITIALISED  # a recovery under way (the start's ended at 2 s)
    if kind != "ars":  # the recovery turns the heading back to the field's (the gyro's 3.3 rad are lost)
        q0, q1 = sets["q"][199].astype(np.float64), sets["q"][n - 1].astype(np.float64)
        assert np.degrees(2 * np.arccos(min(1.0, abs(float(q0 @ q1))))) < 2.0
