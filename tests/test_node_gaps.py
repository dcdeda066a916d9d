"""Lost samples at the CAN node: integrated over the E2E counter distance, not ignored (issue 24).

The node steps a sample over n = (counter - counter of the last sample stepped) mod 16 periods
(att_filter_step_n): its output frames must be the outputs of ``native.Filter.run(..., steps=...)``, bit
for bit; the host's models of the node (the assembly model, the alignment of verify, the comparison with
an output divider) must predict the same n, the same sets and the same counters as the C node.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from attica import kinds, native, sim
from attica.can import codec as c
from attica.can.assembly import INPUT_FAULTS, assemble
from attica.can.compare import align_inputs, compare, expected_outputs, node_dt, node_steps, sort_outputs
from attica.can.verify import verify_frames
from attica.reference.filter import Filter as RefFilter
from attica.settings import FilterKind, Flag, make_settings

from helpers import assert_same_bits

RATE = 200.0


@functools.cache
def _recording(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rec = sim.simulate(sim.SimConfig(duration=max(n / RATE, 20.0), rate=RATE, seed=seed, taps=2))
    return rec.gyr[:n], rec.acc[:n], rec.mag[:n]


def _node(kind: str, fd: bool = False, **kw: object) -> c.Node:
    # data_bitrate in both modes: the node takes IMU_FD frames in either output mode
    return c.Node(kind, sample_rate=RATE, bitrate=1_000_000, data_bitrate=2_000_000, fd=fd, **kw)  # type: ignore[arg-type]


def _frames(n: int, seed: int, fd: bool) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per sample: its frames (3 classic or 1 FD, counter = index mod 16), and the floats they carry."""
    g, a, m = c.imu_values(*_recording(n, seed))  # the classic frames' values: one input for both forms
    fr = c.encode_imu(g, a, m, fd=fd).reshape(n, -1)
    return fr, (g, a, m)


def _sets(out: np.ndarray) -> np.ndarray:
    return out[out["id"] != c.ID_DIAG]


# --- the node against native.Filter.run(steps=...) --------------------------------------------------


@pytest.mark.parametrize("kind", kinds.labels())
@pytest.mark.parametrize("fd", [False, True], ids=["classic", "fd"])
def test_dropped_samples_are_integrated_bit_for_bit(kind: str, fd: bool) -> None:
    """A gap of 1 (sample 100 lost: n = 2) and of 3 (300..302 lost: n = 4) as att_filter_step_n does it."""
    n = 600
    fr, (g, a, m) = _frames(n, 1, fd)
    keep = np.ones(n, np.bool_)
    keep[100] = False
    keep[300:303] = False
    node = _node(kind, fd)
    out, steps = node.run(np.concatenate(list(fr[keep])))
    st = node.stats()
    assert (st["samples"], st["steps"], steps, st["sets"]) == (n - 4, n, n, n - 4)
    assert (st["counter_gaps"], st["stale_partials"], st["duplicates"]) == (2, 0, 0)
    per = np.ones(n - 4, np.int64)
    per[100] = 2  # sample 101, after sample 100 was lost
    per[299] = 4  # sample 303, after 300..302
    want = native.Filter(kind, dt=node_dt(RATE)).run(g[keep], a[keep], m[keep], steps=per)
    assert (want["steps"] == np.cumsum(per)).all()
    # the numpy reference agrees with the C filter's att_filter_step_n (around the gaps)
    ref = RefFilter(kind, make_settings(FilterKind.parse(kind), None, node_dt(RATE)))
    back = ref.run(g[keep][:310], a[keep][:310], m[keep][:310], steps=per[:310], check_units=False)
    assert_same_bits(back["q"], want["q"][:310], "reference q")
    assert (back["flags"] == want["flags"][:310]).all() and (back["steps"] == want["steps"][:310]).all()
    # byte for byte: the sets are these records encoded (ATT_STATUS.error_count = the gaps seen so far)
    if fd:
        expected = c.encode_outputs(want, FilterKind.parse(kind), fd=True)
    else:
        cuts = [0, 100, 299, n - 4]
        expected = np.concatenate(
            [
                c.encode_outputs(want[i:j], FilterKind.parse(kind), counter0=i & 0xF, error_count=e)
                for e, (i, j) in enumerate(zip(cuts[:-1], cuts[1:]))
            ]
        )
    assert _sets(out).tobytes() == expected.tobytes()


@pytest.mark.parametrize("fd", [False, True], ids=["classic", "fd"])
def test_flags_are_the_or_over_the_held_periods(fd: bool) -> None:
    """The set after a gap carries the OR of its n steps' flags (att_filter_output keeps them). The ekf:
    its start is flagged INITIALISED on its own step only (the start of ars, kf, mars and mekf is a
    recovery, flagged on every step of it), so the OR must reach back to the first held period."""
    fr, (g, a, m) = _frames(20, 2, fd)
    node = _node("ekf", fd)
    node.run(np.concatenate(list(fr[:10])))
    node.run(c.encode_cmd(c.Cmd.RESET, counter=1))  # the next step initialises the filter again
    out, _ = node.run(fr[13])  # 10..12 lost: 4 periods, the first of them the initialisation
    sets = c.decode_outputs(out).sets
    f = native.Filter("ekf", dt=node_dt(RATE))
    f.run(g[:10], a[:10], m[:10])
    f.reset()
    single = f.run(g[[13] * 4], a[[13] * 4], m[[13] * 4])
    assert sets.shape[0] == 1 and int(sets["steps"][0]) == 4 == int(single["steps"][3])
    assert single["flags"][0] & Flag.INITIALISED and not single["flags"][3] & Flag.INITIALISED
    assert int(sets["flags"][0]) == int(np.bitwise_or.reduce(single["flags"])) & 0xFFFF
    assert_same_bits(sets["q"][0], single["q"][3], "q after the held periods")
    assert node.output()["flags"] == np.bitwise_or.reduce(single["flags"])


def test_push_sample_is_one_period_and_keeps_the_frame_counters() -> None:
    fr, (g, a, m) = _frames(8, 3, True)
    node = _node("ars")
    node.run(fr[0])  # counter 0
    assert node.push_sample(g[1], a[1], m[1])  # no counter: one period
    node.run(fr[3])  # counter 3: 3 periods after the last frame sample (0); a pushed one moves no counter
    st = node.stats()
    assert (st["samples"], st["steps"], st["counter_gaps"]) == (3, 5, 1)


# --- the output divider ------------------------------------------------------------------------------


def test_output_divider_sets_follow_the_step_count() -> None:
    """With a divider, a set goes out after the sample whose steps reach or pass a multiple of it."""
    n = 900
    fr, (g, a, m) = _frames(n, 4, False)
    keep = np.ones(n, np.bool_)
    for start, length in ((10, 1), (40, 2), (70, 3), (101, 5), (400, 9)):
        keep[start : start + length] = False
    node = _node("kf", output_divider=3)
    out, steps = node.run(np.concatenate(list(fr[keep])))
    assert steps == n == node.stats()["steps"]
    asm = assemble(np.concatenate(list(fr[keep])))
    exp = expected_outputs(FilterKind.KF, RATE, asm.gyr, asm.acc, asm.mag, steps=asm.steps)
    rep = compare(exp, FilterKind.KF, False, out, output_divider=3)
    assert rep.exact, "\n".join(rep.lines())
    total = exp.records["steps"].astype(np.int64)
    crossed = total // 3 > np.concatenate([[0], total[:-1]]) // 3
    assert rep.sets_expected == int(crossed.sum()) == node.stats()["sets"] < n // 3  # one set per sample
    assert (c.decode_outputs(out).sets["steps"] == total[crossed]).all()


def test_reset_restarts_the_divider_grid() -> None:
    fr, _ = _frames(40, 5, False)
    node = _node("ars", output_divider=4)
    node.run(np.concatenate(list(fr[:6])))  # steps 6: one set (at 4), two steps into the next
    node.run(c.encode_cmd(c.Cmd.RESET, counter=1))
    out, _ = node.run(np.concatenate(list(fr[6:14])))
    assert c.decode_outputs(out).sets["steps"].tolist() == [4, 8]


# --- the step count rules, C node and assembly model ----------------------------------------------


def _one(frames: np.ndarray, *parts: int) -> np.ndarray:
    """The classic frames ``parts`` (0 gyro, 1 acc, 2 mag) of a sample's three."""
    return frames[list(parts)]


def test_step_count_rules_c_and_model() -> None:
    """First sample 1; next 1; after k lost k + 1; a re-sent one after a stale partial 1; 15 lost: a
    duplicate; 16 lost: 1; a discarded partial counts as lost; a late frame costs no period."""
    n = 120
    classic, _ = _frames(n, 6, False)
    fd, _ = _frames(n, 6, True)
    seq = [
        (classic[5], 1),  # the first sample (counter 5): 1
        (classic[6], 1),
        (fd[9], 3),  # 7, 8 lost
        (_one(classic[10], 0, 1), None),  # a partial...
        (fd[10], 1),  # ... discarded by the same sample re-sent as IMU_FD: no gap, 1 period
        (_one(classic[11], 2), None),  # a partial of 11 ...
        (classic[12], 2),  # ... discarded by 12: 11 is lost, 2 periods
        (_one(classic[13], 0), None),  # a partial of 13 ...
        (fd[12], 1),  # ... discarded by 12 again (distance 0 from the last stepped): 1
        (classic[14], 2),
        (_one(classic[15], 0, 2), None),  # 15 loses its acc frame ...
        (classic[16], 2),  # ... stale when 16 starts: 16 steps over 2 ...
        (_one(classic[15], 1), None),  # ... the late acc frame of 15 opens a partial (a gap back)
        (classic[17], 1),  # ... that 17 discards: 17 follows 16, 1 period
        (fd[33], None),  # 18..32 lost (15): 33 has 17's counter, a duplicate
        (fd[34], 1),  # 34 is 17 + 1 by the counters: 1 (the 16 periods are not seen)
        (classic[51], 1),  # 35..50 lost (16): 1
        (classic[60], 9),
    ]
    frames = np.concatenate([f.reshape(-1) for f, _ in seq])
    want = [k for _, k in seq if k is not None]
    node = _node("ars")
    out, steps = node.run(frames)
    got = np.diff(c.decode_outputs(out).sets["steps"].astype(np.int64), prepend=0).tolist()
    assert got == want
    asm = assemble(frames)
    assert asm.steps.tolist() == want and asm.periods == steps == node.stats()["steps"]
    assert asm.counters == {k: node.stats()[k] for k in INPUT_FAULTS}
    assert node.stats()["duplicates"] == 1


def _lossy_stream(rng: np.random.Generator, classic: np.ndarray, fd: np.ndarray) -> np.ndarray:
    """Samples as classic or FD frames with every kind of loss and disorder the node must survive."""
    n = classic.shape[0]
    out: list[np.ndarray] = []
    k = 0
    while k < n:
        r = rng.random()
        if r < 0.05:  # a run of lost samples, up to past the 4-bit counter
            k += int(rng.choice([1, 2, 3, 14, 15, 16, 17, 20]))
            continue
        if rng.random() < 0.2:
            out.append(fd[k])
        else:
            grp = classic[k][rng.permutation(3)]
            if r < 0.10:
                grp = grp[:2]  # a frame lost: a stale partial
            elif r < 0.13:
                grp = np.concatenate([grp, grp[:1]])  # a repeated frame
            elif r < 0.16 and k + 1 < n:  # a frame delayed past the next sample
                out.append(grp[:2])
                out.append(classic[k + 1])
                out.append(grp[2:])
                k += 2
                continue
            elif r < 0.18:  # a partial, then the sample re-sent as IMU_FD
                out.append(grp[:1])
                grp = fd[k]
            out.append(grp)
        k += 1
    return np.concatenate(out)


@pytest.mark.parametrize("seed", range(6))
def test_assembly_model_gives_the_c_node_step_counts(seed: int) -> None:
    """The Python model of the receive path: the same samples, the same n, the same counters as C."""
    n = 1500
    classic, _ = _frames(n, 7, False)
    fd, _ = _frames(n, 7, True)
    frames = _lossy_stream(np.random.default_rng(seed), classic, fd)
    kind = ("ars", "mars", "kf")[seed % 3]
    node = _node(kind)
    out, steps = node.run(frames)
    st = node.stats()
    asm = assemble(frames)
    assert len(asm) == st["samples"] and asm.periods == steps == st["steps"]
    assert asm.counters == {k: st[k] for k in INPUT_FAULTS}
    sets = c.decode_outputs(out).sets
    assert sets.shape[0] == len(asm)
    assert asm.steps.tolist() == np.diff(sets["steps"].astype(np.int64), prepend=0).tolist()
    assert set(asm.steps.tolist()) > {1, 2}  # the stream did have gaps
    # the outputs: native.Filter.run(steps=asm.steps) == the numpy reference, and the node's sets, bit for bit
    exp = expected_outputs(FilterKind.parse(kind), RATE, asm.gyr, asm.acc, asm.mag, steps=asm.steps)
    assert exp.reference_ok, exp.reference_detail
    rep = compare(exp, FilterKind.parse(kind), False, out)
    assert rep.exact, "\n".join(rep.lines())
    assert rep.samples_stepped == len(asm) and rep.steps_expected == st["steps"]
    # and verify of a log of both directions (the inputs rebuilt by the model) says the same
    log = verify_frames(np.concatenate([frames, out]), FilterKind.parse(kind), RATE)
    assert log.exact and log.input_faults == asm.counters
    assert log.samples_lost == log.samples_sent - len(asm) > 0


# --- verify's alignment (no tap: the samples sent, the node's outputs) ------------------------------


@pytest.mark.parametrize(
    "runs, drop_sets, duplicates",
    [
        # 165 has the counter of 149 (15 lost before it): the node drops it as a duplicate
        ([(0, 2), (50, 1), (90, 3), (150, 15), (220, 16), (300, 20)], [], [165]),
        # output sets lost too, around the input losses: sets 59 (sample 59), 60 and 61 (62 and 63)
        ([(60, 2), (130, 4)], [59, 60, 61, 140], []),
    ],
    ids=["inputs", "inputs-and-outputs"],
)
def test_align_inputs_finds_the_lost_samples_and_their_periods(
    runs: list[tuple[int, int]], drop_sets: list[int], duplicates: list[int]
) -> None:
    n = 400
    fr, (g, a, m) = _frames(n, 8, False)
    keep = np.ones(n, np.bool_)
    for start, length in runs:
        keep[start : start + length] = False
    node = _node("mars")
    out, _ = node.run(np.concatenate(list(fr[keep])))
    got = c.decode_outputs(out).sets
    # what the node stepped, by its own sets: their steps fields give each sample's periods
    stepped, per = node_steps(np.nonzero(keep)[0])
    stepped = np.nonzero(keep)[0][stepped]
    assert got.shape[0] == stepped.shape[0]
    assert per.tolist() == np.diff(got["steps"].astype(np.int64), prepend=0).tolist()
    never = sorted(set(range(n)) - set(stepped.tolist()))
    assert never == sorted([*np.nonzero(~keep)[0].tolist(), *duplicates])
    sets = out[out["id"] != c.ID_DIAG].reshape(-1, 6)
    rx = sort_outputs(np.delete(sets, drop_sets, axis=0).reshape(-1))
    seq, skipped, periods = align_inputs(FilterKind.MARS, RATE, g, a, m, rx, fd=False)
    assert skipped == never
    assert seq.tolist() == stepped.tolist() and periods.tolist() == per.tolist()
    exp = expected_outputs(FilterKind.MARS, RATE, g[seq], a[seq], m[seq], steps=periods)
    rep = compare(exp, FilterKind.MARS, False, rx)
    assert rep.mismatched == 0 and rep.unexpected == 0 and rep.missing == len(drop_sets)
