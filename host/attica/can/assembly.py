"""A model of the node's sample assembly (att_node.c's receive path, att_node.h).

:func:`assemble` says which samples a node completes from a frame sequence, over how many sample periods
it steps each (att_filter_step_n with the E2E counter distance: lost samples are integrated), and which
input faults it counts (CRC, DLC, unknown IDs, duplicates, stale partial samples, counter gaps), so that
a tap or a log can be checked without the node.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from attica.can import codec

INPUT_IDS = frozenset({codec.ID_IMU_GYRO, codec.ID_IMU_ACC, codec.ID_IMU_MAG, codec.ID_IMU_FD, codec.ID_CMD})
"""IDs the node receives (everything else is counted as unknown by the node)."""


OUTPUT_IDS = frozenset(
    {*codec.SET_IDS, codec.ID_DIAG, codec.ID_DIAG_BUS, codec.ID_MAG_OFFSET, codec.ID_OUT_FD}
)
"""IDs the node sends."""


INPUT_FAULTS = ("crc_errors", "dlc_errors", "unknown_ids", "duplicates", "stale_partials", "counter_gaps")
"""Input fault counters of the node (ATT_DIAG) that :func:`assemble` predicts."""


@dataclass
class Assembly:
    """Samples the node completes from a frame sequence, their step counts, and the input faults it counts."""

    gyr: NDArray[np.float32]
    acc: NDArray[np.float32]
    mag: NDArray[np.float32]
    counters: dict[str, int]
    frames: int = 0
    commands: int = 0
    started: int = 0  # samples begun (completed + discarded partials)
    steps: NDArray[np.uint32] = field(default_factory=lambda: np.zeros(0, np.uint32))
    """Sample periods the node steps each sample over (``Filter.run(..., steps=...)``): 1, or k + 1 after
    k lost samples (by the E2E counters, mod 16)."""

    def __len__(self) -> int:
        return int(self.gyr.shape[0])

    @property
    def periods(self) -> int:
        """Filter steps the node runs for these samples (the sum of :attr:`steps`)."""
        return int(self.steps.sum(dtype=np.int64))


def assemble(frames: NDArray[np.void]) -> Assembly:
    """Model of att_node.c's receive path (att_node.h): which samples complete, which faults count.

    Every frame is checked (known ID, length/format, E2E CRC) and then assembled: a classic part with a
    counter other than the partial sample's discards the partial (stale) and begins a new sample; a
    repeated part, or a frame of the sample just completed, is a duplicate; a new sample whose counter
    does not follow the previous sample's is counted once as a counter gap. A complete sample steps over
    (counter - counter of the last sample stepped) mod 16 periods: 1 for the next one, k + 1 after k lost
    samples (whole, or partial ones discarded), 1 for the first sample and for a distance of 0 (a re-sent
    sample after a stale partial). Commands are counted and otherwise ignored here.
    """
    fr = np.atleast_1d(frames)
    counts = dict.fromkeys(INPUT_FAULTS, 0)
    g: list[NDArray[np.float32]] = []
    a: list[NDArray[np.float32]] = []
    m: list[NDArray[np.float32]] = []
    n: list[int] = []
    part: dict[int, NDArray[np.float32]] = {}
    part_counter = 0
    last_counter = 0  # counter of the last sample stepped
    have_last = False  # a sample was stepped
    commands = 0
    started = 0
    fracs = {
        codec.ID_IMU_GYRO: codec.GYR_FRAC,
        codec.ID_IMU_ACC: codec.ACC_FRAC,
        codec.ID_IMU_MAG: codec.MAG_FRAC,
    }

    def begin(c: int) -> bool:
        nonlocal started
        replaced = bool(part)
        have_prev = replaced or have_last
        prev = part_counter if replaced else last_counter  # the sample started before this one
        if replaced:
            counts["stale_partials"] += 1
            part.clear()
        elif have_last and c == last_counter:
            counts["duplicates"] += 1
            return False
        if have_prev and c != ((prev + 1) & 0xF) and not (replaced and c == prev):
            counts["counter_gaps"] += 1
        started += 1
        return True

    def stepped(c: int) -> None:
        nonlocal have_last, last_counter
        n.append((((c - last_counter) & 0xF) or 1) if have_last else 1)
        have_last = True
        last_counter = c

    for rec in fr:
        can_id = int(rec["id"])
        if can_id not in INPUT_IDS:
            counts["unknown_ids"] += 1
            continue
        chk = codec.check(rec)
        if chk == codec.Check.DLC:
            counts["dlc_errors"] += 1
            continue
        if chk == codec.Check.CRC:
            counts["crc_errors"] += 1
            continue
        if chk != codec.Check.OK:
            counts["unknown_ids"] += 1
            continue
        data = rec["data"]
        c = int(data[1]) & 0xF
        if can_id == codec.ID_CMD:
            commands += 1
            continue
        if can_id == codec.ID_IMU_FD:
            if begin(c):
                v = np.frombuffer(data[4:40].tobytes(), "<f4").astype(np.float32)
                g.append(v[0:3])
                a.append(v[3:6])
                m.append(v[6:9])
                stepped(c)
            continue
        if part and c == part_counter:
            if can_id in part:
                counts["duplicates"] += 1
                continue
        else:
            if not begin(c):
                continue
            part_counter = c
        raw = np.frombuffer(data[2:8].tobytes(), "<i2")
        part[can_id] = codec.dequantise_sensor(raw, fracs[can_id])  # as att_can_decode_imu_part
        if len(part) == 3:
            g.append(part[codec.ID_IMU_GYRO])
            a.append(part[codec.ID_IMU_ACC])
            m.append(part[codec.ID_IMU_MAG])
            part.clear()
            stepped(c)

    def stack(rows: list[NDArray[np.float32]]) -> NDArray[np.float32]:
        return np.array(rows, np.float32).reshape(-1, 3)

    return Assembly(
        stack(g),
        stack(a),
        stack(m),
        counts,
        frames=int(fr.shape[0]),
        commands=commands,
        started=started,
        steps=np.array(n, np.uint32),
    )
