"""A second writer on a SocketCAN bus: malformed attica frames at a stated rate, or valid samples.

Used inside the user-mode Linux guest by tests/test_vcan_uml.py (standard library only: raw AF_CAN).

Malformed mode (default) sends, in a fixed random cycle, frames that a correct node must reject and
count, never step with:

- ``unknown``: standard IDs that are not attica inputs (and not attica outputs, so the verifier's
  view of the node's output stays clean) -> the node's ``unknown_ids``;
- ``dlc``: IMU_GYRO/ACC/MAG/CMD frames of a wrong length (0..7) and IMU_FD IDs as 8-byte classic
  frames -> ``dlc_errors``;
- ``crc``: 8-byte IMU_GYRO/ACC/MAG/CMD frames whose E2E CRC is wrong by a nonzero XOR -> ``crc_errors``;
- ``rtr``: remote frames with attica input IDs -> ignored by the port (``ignored``).

It runs until the file given with ``--stop`` exists (or SIGTERM) and writes the counts per class,
the duration and the achieved rate as JSON to ``--report``.

``--valid N`` instead sends N valid IMU samples (GYRO, ACC, MAG with consecutive counters) at
``--rate`` samples/s and exits.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import socket
import struct
import sys
import time

CAN_RTR_FLAG = 0x40000000
FMT = "=IB3x8s"
INPUT_IDS = (0x100, 0x101, 0x102, 0x300)


def crc8(data: bytes, crc: int = 0xFF) -> int:
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


def e2e(can_id: int, payload: bytes) -> int:
    did = 0x0A00 + can_id
    return crc8(bytes([did & 0xFF, did >> 8]) + payload) ^ 0xFF


def frame(can_id: int, data: bytes) -> bytes:
    return struct.pack(FMT, can_id, len(data), data.ljust(8, b"\0"))


def sealed(can_id: int, counter: int, values: tuple[int, int, int]) -> bytes:
    body = bytes([counter & 0xF]) + struct.pack("<hhh", *values) + b"\0"
    body = body[:7]
    return bytes([e2e(can_id, body)]) + body


def malformed(rng: random.Random) -> tuple[str, bytes]:
    k = rng.randrange(4)
    if k == 0:
        while True:
            ident = rng.randrange(0x800)
            if not (0x100 <= ident <= 0x110 or 0x200 <= ident <= 0x2FF or ident == 0x300):
                break
        return "unknown", frame(ident, bytes(rng.randrange(256) for _ in range(rng.randrange(9))))
    if k == 1:
        if rng.random() < 0.25:
            return "dlc", frame(0x110, bytes(rng.randrange(256) for _ in range(8)))
        n = rng.randrange(8)
        return "dlc", frame(rng.choice(INPUT_IDS), bytes(rng.randrange(256) for _ in range(n)))
    if k == 2:
        ident = rng.choice(INPUT_IDS)
        body = bytes(rng.randrange(256) for _ in range(7))
        good = e2e(ident, body)
        return "crc", frame(ident, bytes([good ^ rng.randrange(1, 256)]) + body)
    return "rtr", struct.pack(FMT, rng.choice(INPUT_IDS) | CAN_RTR_FLAG, 8, bytes(8))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--channel", default="vcan0")
    ap.add_argument("--rate", type=float, default=1000.0, help="frames/s (malformed) or samples/s (--valid)")
    ap.add_argument("--stop", help="stop when this file exists")
    ap.add_argument("--report", help="write the counts here (JSON)")
    ap.add_argument("--valid", type=int, default=0, help="send this many valid IMU samples instead")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--priority", type=int, default=0, help="socket priority (SO_PRIORITY) of the frames")
    a = ap.parse_args()
    s = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
    if a.priority:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_PRIORITY, a.priority)
    s.bind((a.channel,))
    rng = random.Random(a.seed)
    stop = False

    def on_term(_sig: int, _frm: object) -> None:
        nonlocal stop
        stop = True

    signal.signal(signal.SIGTERM, on_term)
    period = 1.0 / a.rate
    t0 = time.monotonic()
    if a.valid:
        for i in range(a.valid):
            for ident, vals in ((0x100, (10, -20, 30)), (0x101, (0, 0, 2510)), (0x102, (0, 640, -1280))):
                s.send(frame(ident, sealed(ident, i, vals)))
            time.sleep(max(0.0, t0 + (i + 1) * period - time.monotonic()))
        return 0
    counts = {"unknown": 0, "dlc": 0, "crc": 0, "rtr": 0}
    n = 0
    while not stop and not (a.stop and os.path.exists(a.stop)):
        cls, f = malformed(rng)
        try:
            s.send(f)
        except OSError as exc:  # a full queue: try the same class again later
            print(f"flood: send failed: {exc}", file=sys.stderr)
            time.sleep(0.001)
            continue
        counts[cls] += 1
        n += 1
        time.sleep(max(0.0, t0 + n * period - time.monotonic()))
    dt = time.monotonic() - t0
    rep = {"counts": counts, "frames": n, "seconds": dt, "rate": n / dt if dt > 0 else 0.0}
    if a.report:
        with open(a.report, "w") as fh:
            json.dump(rep, fh)
    print(json.dumps(rep))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
