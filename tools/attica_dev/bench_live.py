"""The per-sample Python loop of ``make bench``: attica's ``Filter.update`` and ``step`` beside vqf's.

A live loop in Python calls the filter once per sample. Every candidate gets the same rows of the same
simulated (N, 3) float64 arrays, ``for i in range(N): f.update(gyr[i], acc[i], mag[i])`` (the row
indexing is part of what a loop pays, for every candidate alike). The candidates run interleaved,
repeat by repeat, and the best repeat of each is kept, so a busy moment of the shared machine does not
fall on one of them only.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

Loop = Callable[[], None]


def _loops(
    gyr: NDArray[np.float64], acc: NDArray[np.float64], mag: NDArray[np.float64], dt: float
) -> dict[str, Loop]:
    from attica import native

    loops: dict[str, Loop] = {}
    n = gyr.shape[0]
    gl, al, ml = gyr.tolist(), acc.tolist(), mag.tolist()
    try:
        import vqf
    except ImportError:
        vqf = None
    if vqf is not None:
        v6 = vqf.VQF(dt)
        v9 = vqf.VQF(dt)

        def vqf6() -> None:
            for i in range(n):
                v6.update(gyr[i], acc[i])

        def vqf9() -> None:
            for i in range(n):
                v9.update(gyr[i], acc[i], mag[i])

        loops["vqf6 VQF.update(gyr[i], acc[i])"] = vqf6
        loops["vqf9 VQF.update(gyr[i], acc[i], mag[i])"] = vqf9
    ars = native.Filter("ars", dt)
    mars = native.Filter("mars", dt)
    mars_s = native.Filter("mars", dt)
    mars_l = native.Filter("mars", dt)

    def ars_update() -> None:
        for i in range(n):
            ars.update(gyr[i], acc[i])

    def mars_update() -> None:
        for i in range(n):
            mars.update(gyr[i], acc[i], mag[i])

    def mars_step() -> None:
        for i in range(n):
            mars_s.step(gyr[i], acc[i], mag[i])

    def mars_lists() -> None:
        for i in range(n):
            mars_l.update(gl[i], al[i], ml[i])

    loops["attica ars Filter.update(gyr[i], acc[i])"] = ars_update
    loops["attica mars Filter.update(gyr[i], acc[i], mag[i])"] = mars_update
    loops["attica mars Filter.step(gyr[i], acc[i], mag[i]) (a record per call)"] = mars_step
    loops["attica mars Filter.update(lists: a driver's floats)"] = mars_lists
    return loops


def live_table(
    gyr: NDArray[np.floating], acc: NDArray[np.floating], mag: NDArray[np.floating], dt: float, repeat: int
) -> list[tuple[str, float]]:
    """``(candidate, best us/sample)`` for each per-sample loop, measured interleaved in this run."""
    g = np.ascontiguousarray(gyr, np.float64)
    a = np.ascontiguousarray(acc, np.float64)
    m = np.ascontiguousarray(mag, np.float64)
    m = np.where(np.isfinite(m), m, 0.0)
    loops = _loops(g, a, m, dt)
    best = dict.fromkeys(loops, float("inf"))
    for _ in range(repeat):
        for name, loop in loops.items():
            t0 = time.perf_counter()
            loop()
            best[name] = min(best[name], (time.perf_counter() - t0) / g.shape[0] * 1e6)
    return list(best.items())


def live_lines(
    gyr: NDArray[np.floating], acc: NDArray[np.floating], mag: NDArray[np.floating], dt: float, repeat: int
) -> list[str]:
    """The printed block: one line per loop, and attica's update against vqf's in the same run."""
    rows = live_table(gyr, acc, mag, dt, repeat)
    out = [
        f"Per-sample Python loop ({gyr.shape[0]} samples, best of {repeat} interleaved repeats), us/sample:"
    ]
    width = max(len(k) for k, _ in rows)
    out += [f"  {k:<{width}}  {v:6.2f}" for k, v in rows]
    us = dict(rows)
    pairs = (
        ("attica ars Filter.update(gyr[i], acc[i])", "vqf6 VQF.update(gyr[i], acc[i])"),
        ("attica mars Filter.update(gyr[i], acc[i], mag[i])", "vqf9 VQF.update(gyr[i], acc[i], mag[i])"),
    )
    for ours, theirs in pairs:
        if ours in us and theirs in us:
            ratio = us[ours] / us[theirs]
            out.append(f"  {ours.split(' Filter')[0]} update / {theirs.split(' ')[0]} update: {ratio:.2f}")
    return out
