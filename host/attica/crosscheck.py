"""Prove that the C firmware and the numpy reference agree bit for bit on given input streams.

The C filter runs over each whole stream (fast, in C) and leaves a snapshot of its state every
``segment`` steps. The reference then starts one lockstep instance per segment from those
snapshots and runs all segments of all streams at once, so millions of steps are checked in a few
seconds. Every step's output record is compared (floats bit for bit, NaN == NaN; flags and step
counters exactly), and the reference state at the end of each segment must equal the next C
snapshot: no hidden state can drift without being seen.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica import native
from attica.outputs import FLOAT_FIELDS, OUTPUT_DTYPE
from attica.reference.filter import Filter as RefFilter
from attica.settings import FilterKind, make_settings


@dataclass
class Stream:
    """One input stream: gyr (rad/s), acc (m/s^2), optional mag (uT); each (N, 3)."""

    gyr: NDArray[np.float32]
    acc: NDArray[np.float32]
    mag: NDArray[np.float32] | None = None
    name: str = ""


@dataclass
class CrossCheck:
    """Outcome of :func:`crosscheck`."""

    kind: FilterKind
    steps: int = 0
    mismatched_steps: int = 0
    state_mismatches: int = 0
    first_mismatch: str = ""
    c_outputs: list[NDArray[np.void]] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """True when every step and every segment-end state matched."""
        return self.steps > 0 and self.mismatched_steps == 0 and self.state_mismatches == 0


def records_equal(a: NDArray[np.void], b: NDArray[np.void]) -> NDArray[np.bool_]:
    """Per record: all float fields bit-identical (NaN == NaN); flags, steps and valid equal."""
    ok: NDArray[np.bool_] = (a["flags"] == b["flags"]) & (a["steps"] == b["steps"])
    ok &= a["valid"] == b["valid"]
    for name in FLOAT_FIELDS:
        x = a[name]
        y = b[name]
        same = (x.view(np.uint32) == y.view(np.uint32)) | (np.isnan(x) & np.isnan(y))
        ok &= same.reshape(same.shape[0], -1).all(axis=1)
    return ok


def crosscheck(
    kind: str | int | FilterKind,
    streams: Sequence[Stream],
    settings: Any = None,
    segment: int = 1000,
    progress: Callable[[int, int], None] | None = None,
    calibration: Any = None,
    **overrides: Any,
) -> CrossCheck:
    """Run C and reference over ``streams`` and compare every step.

    Parameters
    ----------
    kind
        Filter kind.
    streams
        Input streams (each run from a freshly initialised filter).
    settings, **overrides
        Filter settings (dataclass and/or field overrides such as ``dt``).
    segment
        Steps per reference lockstep segment (smaller = more instances, fewer sequential steps).
    progress
        Called as ``progress(done, total)`` with reference steps done.
    calibration
        Input/output stages of both (a :class:`~attica.calibration.Calibration`, a
        :class:`~attica.calibration.stages.StageSettings` or None: identity, ENU).

    """
    k = FilterKind.parse(kind)
    s = make_settings(k, settings, **overrides)
    result = CrossCheck(kind=k)
    seg_src: list[tuple[int, int, int]] = []  # (stream, start, length)
    snapshots: list[Any] = []
    for si, st in enumerate(streams):
        c = native.Filter(k, s, calibration=calibration)
        out, snaps = c.run(st.gyr, st.acc, st.mag, snapshot_every=segment)
        result.c_outputs.append(out)
        n = len(out)
        for j, start in enumerate(range(0, n, segment)):
            seg_src.append((si, start, min(segment, n - start)))
            snapshots.append(snaps[j])
        # the final C state, to check the end of the last segment
        seg_src.append((si, n, 0))
        snapshots.append(c.state.copy()[0])
    # lockstep reference over all non-empty segments
    segs = [(i, src) for i, src in enumerate(seg_src) if src[2] > 0]
    if not segs:
        return result
    ref = RefFilter(k, s, n=len(segs), calibration=calibration)
    ref.load_c_states([snapshots[i] for i, _ in segs])
    length = max(src[2] for _, src in segs)
    m = len(segs)
    gyr = np.zeros((length, m, 3), np.float32)
    acc = np.zeros((length, m, 3), np.float32)
    mag = np.zeros((length, m, 3), np.float32)
    for col, (_, (si, start, ln)) in enumerate(segs):
        st = streams[si]
        gyr[:ln, col] = st.gyr[start : start + ln]
        acc[:ln, col] = st.acc[start : start + ln]
        if st.mag is not None:
            mag[:ln, col] = st.mag[start : start + ln]
    expected = np.zeros((length, m), OUTPUT_DTYPE)
    valid = np.zeros((length, m), np.bool_)
    for col, (_, (si, start, ln)) in enumerate(segs):
        expected[:ln, col] = result.c_outputs[si][start : start + ln]
        valid[:ln, col] = True
    lengths = np.array([src[2] for _, src in segs])
    for t in range(length):
        rec = ref.step(gyr[t], acc[t], mag[t])
        bad = ~records_equal(rec, expected[t]) & valid[t]
        if bad.any() and not result.first_mismatch:
            col = int(np.argmax(bad).item())
            si, start, _ = segs[col][1]
            result.first_mismatch = (
                f"stream {si} ({streams[si].name or 'unnamed'}) step {start + t}: C {expected[t, col]!r} "
                f"vs reference {rec[col]!r}"
            )
        result.mismatched_steps += int(bad.sum())
        result.steps += int(valid[t].sum())
        # segments ending after this step: compare full state with the next C snapshot
        for end_col in np.nonzero(lengths == t + 1)[0].tolist():
            seg_index = segs[end_col][0]
            if not ref.state_matches(end_col, snapshots[seg_index + 1]):
                result.state_mismatches += 1
                if not result.first_mismatch:
                    result.first_mismatch = f"state differs at the end of segment {seg_index}"
        if progress is not None:
            progress(t + 1, length)
    return result
