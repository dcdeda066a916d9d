"""The view under a 1 kHz node for a bounded time: memory flat, no frame lost by the bus reader.

The C node runs in-process on a python-can virtual bus at 1000 Hz with CAN FD (IMU_FD in, ATT_OUT_FD
out, a DIAG every 16 sets: classic sets every step at 1 kHz need more than 500 kbit/s); a feeder sends
the IMU samples in real time (a still sensor, yaw 90 deg); the view reads the bus and serves two pages:
one that acknowledges every update and one that takes an update only every 0.4 s (a slow tab: it must
get the latest state, never a backlog). At the end every frame sent on the bus (the feeder's and the
node's) is counted by the view, the E2E and counter checks found nothing, the reader dropped nothing,
and the process's resident memory over the second half is flat.

``ATTICA_VIEW_SOAK_SECONDS`` sets the duration (default 20 s in the test suite; ``make view-soak`` runs
600 s). The figures are printed (pytest -s) for docs/view.md.
"""

from __future__ import annotations

import json
import os
import statistics
import threading
import time

import numpy as np
from test_view_server import YAW90_MAG, G, Rig
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from attica.can import codec
from attica.can.bus import to_messages

SECONDS = float(os.environ.get("ATTICA_VIEW_SOAK_SECONDS", "20"))
RATE = 1000.0


def _rss_mb() -> float:
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    raise AssertionError("no VmRSS")


def _page(url: str, stop: threading.Event, pause: float, seen: dict[str, object]) -> None:
    """A page: acknowledges each update after ``pause`` s; keeps the count and the last update."""
    n = 0
    try:
        with connect(url, max_size=None) as ws:
            while not stop.is_set():
                try:
                    msg = json.loads(ws.recv(timeout=0.5))
                except TimeoutError:
                    continue
                if msg["type"] != "update":
                    continue
                n += 1
                seen["last"] = msg
                seen["received_at"] = time.time()
                seen["updates"] = n
                time.sleep(pause)
                ws.send('{"type":"ack"}')
    except ConnectionClosed:
        pass


def test_soak_1khz_through_the_view() -> None:
    rig = Rig(kind="mars", rate=RATE, fd=True, bitrate=500_000, fps=30.0)
    stop = threading.Event()
    fast: dict[str, object] = {}
    slow: dict[str, object] = {}
    pages = [
        threading.Thread(target=_page, args=(rig.ws_url, stop, 0.0, fast), daemon=True),
        threading.Thread(target=_page, args=(rig.ws_url, stop, 0.4, slow), daemon=True),
    ]
    try:
        for p in pages:
            p.start()
        # the samples, encoded once: 1 s of a still sensor (the counters run on by counter0 per block)
        block = 100
        gyr = np.zeros((block, 3), np.float32)
        acc = np.tile(np.float32([0.0, 0.0, G]), (block, 1))
        mag = np.tile(np.float32(YAW90_MAG), (block, 1))
        encoded = [to_messages(codec.encode_imu(gyr, acc, mag, counter0=c, fd=True)) for c in range(16)]
        rss: list[tuple[float, float]] = []
        late = 0
        t0 = time.monotonic()
        next_rss = t0
        sent = 0
        period = 0.005  # 5 samples every 5 ms
        while True:
            now = time.monotonic()
            if now - t0 >= SECONDS:
                break
            due = int((now - t0) * RATE) + 1
            while sent < due:
                n = min(due - sent, block)
                msgs = encoded[sent & 0xF][:n]
                for m in msgs:
                    rig.feed_bus.send(m)
                sent += n
                rig.frames += n
            if due - sent > RATE * 0.1:
                late += 1
            while rig.feed_bus.recv(0.0) is not None:  # the feeder's copy of the traffic
                pass
            if now >= next_rss:
                rss.append((now - t0, _rss_mb()))
                next_rss += 1.0
            time.sleep(max(0.0, period - (time.monotonic() - now)))
        elapsed = time.monotonic() - t0
        # everything sent reaches the view
        node_tx = lambda: rig.runner.stats.tx_frames  # noqa: E731
        rig.wait(lambda: rig.node.stats()["samples"] == sent, 10, "the node to take every sample")
        rig.wait(
            lambda: rig.snap()["health"]["frames"] == sent + node_tx(), 10, "the view to count every frame"
        )
        h = rig.snap()["health"]
        time.sleep(1.0)  # one more update to each page
        stop.set()
        for p in pages:
            p.join(3)
    finally:
        stop.set()
        rig.close()
    st = rig.node.stats()
    assert st["samples"] == st["steps"] == sent and st["crc_errors"] == st["counter_gaps"] == 0
    assert st["rx_overflows"] == st["tx_overflows"] == 0
    assert h["frames"] == sent + rig.runner.stats.tx_frames
    assert h["crc_errors"] == h["counter_gaps"] == h["missing_sets"] == h["dropped"] == h["repeats"] == 0
    assert h["samples_behind"] == 0 and rig.state.view_errors == 0
    assert h["sets"] == sent
    # the pages: the fast one at about the display rate, the slow one at its own pace, with the latest
    assert int(fast["updates"]) > 10 * elapsed  # type: ignore[call-overload]
    assert int(slow["updates"]) < 3 * elapsed  # type: ignore[call-overload]
    last = slow["last"]
    assert isinstance(last, dict)
    att_ts = last["state"]["att"]["ts"]
    assert abs(att_ts - float(slow["received_at"])) < 1.0  # type: ignore[arg-type]
    # memory: flat over the second half (the first half takes the buffers and the caches)
    half = [m for t, m in rss if t >= SECONDS / 2]
    first, final = (
        statistics.median(half[: max(1, len(half) // 3)]),
        statistics.median(half[-max(1, len(half) // 3) :]),
    )
    growth = final - first
    rate = h["frames"] / elapsed
    print(
        f"\nview soak: {elapsed:.1f} s at {RATE:g} Hz (CAN FD), {sent} samples, {h['frames']} frames "
        f"({rate:.0f} frames/s) all counted by the view, 0 dropped, 0 CRC / counter errors; "
        f"RSS {rss[0][1]:.1f} MB at start, {first:.1f} -> {final:.1f} MB over the second half "
        f"({growth:+.2f} MB); pages: {fast['updates']} updates (acknowledging at once), "
        f"{slow['updates']} (a slow page, 0.4 s per update); feeder late {late} times"
    )
    assert growth < 3.0 + 0.002 * SECONDS, rss
