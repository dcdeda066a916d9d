"""Seed corpora of the C fuzz targets, made from the simulated test streams (docs/robustness.md).

Each seed is a fuzz input in the target's own format (see the target's header comment):

- ``fuzz_can``: every frame of a simulated stream (IMU parts, IMU_FD, command frames) and of the
  node's output sets for it (classic sets, DIAG, ATT_OUT_FD, command answers);
- ``fuzz_node``: per kind and bus format, a clean sample sequence of the simulated stream, then the
  commands (set gain, reset, select) between samples;
- ``fuzz_filter``: per kind and preset, the simulated stream as raw samples, and one with bad samples
  (NaN, Inf, huge, zero, saturated) in the middle.

Beside them the kept corpora of the long runs (tests/fuzz/corpus/<target>.tar.xz: the corpus of a long
run minimised with libFuzzer's ``-merge=1``, the inputs that reach its coverage) are unpacked as
``kept-<name>``, so the CI slice and ``make fuzz`` start from what the long runs found.

Usage: ``python tests/fuzz/seeds.py OUTDIR`` (writes OUTDIR/<target>/seed-* and kept-*).
"""

from __future__ import annotations

import struct
import sys
import tarfile
from pathlib import Path

import numpy as np

from attica import kinds, sim
from attica.can import codec as c

KINDS = kinds.labels()  # index = kind - 1 (the registry is in value order, from 1)
KNOWN_IDS = [0x100, 0x101, 0x102, 0x110, 0x200, 0x201, 0x202, 0x203, 0x204, 0x205, 0x206, 0x210, 0x300]


def _raw_float(x: float) -> bytes:
    """fz_float: selector < 0xC0 then the 4 bytes of the float32."""
    return b"\x00" + struct.pack("<f", float(np.float32(x)))


def _stream(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rec = sim.simulate(sim.SimConfig(duration=n / 100.0, rate=100.0, seed=seed))
    return rec.gyr[:n], rec.acc[:n], rec.mag[:n]


def _can_seed(frame_id: int, data: bytes) -> bytes:
    idsel = (
        struct.pack("<H", KNOWN_IDS.index(frame_id))
        if frame_id in KNOWN_IDS
        else struct.pack("<H", 0x8000 | frame_id)
    )
    return idsel + b"\x00" + data.ljust(64, b"\x00") + bytes(8)


def can_seeds(out: Path) -> int:
    gyr, acc, mag = _stream(40, 1)
    frames = list(c.encode_imu(gyr, acc, mag)) + list(c.encode_imu(gyr, acc, mag, fd=True))
    frames += [c.encode_cmd(cmd, arg, 0.5, 3)[0] for cmd in (1, 2, 3) for arg in range(5)]
    for fd in (False, True):
        node = c.Node("ars", sample_rate=100.0, data_bitrate=2_000_000 if fd else 0, fd=fd, diag_divider=2)
        frames += list(node.run(c.encode_imu(gyr[:8], acc[:8], mag[:8]))[0])
        frames += list(node.run(c.encode_cmd(3, 1, 0.5, 2))[0])
    n = 0
    seen: set[bytes] = set()
    for f in frames:
        seed = _can_seed(int(f["id"]), bytes(f["data"]))
        if seed not in seen:
            seen.add(seed)
            (out / f"seed-{n:04d}").write_bytes(seed)
            n += 1
    return n


def _sample_bytes(g: np.ndarray, a: np.ndarray, m: np.ndarray) -> bytes:
    return b"".join(_raw_float(v) for v in (*g, *a, *m))


def node_seeds(out: Path) -> int:
    gyr, acc, mag = _stream(24, 2)
    acc = acc.copy()
    acc[:, 2] -= np.float32(9.80665)  # the harness adds g to acc.z
    n = 0
    for k, kind in enumerate(KINDS):
        for fd in (0, 1):
            body = bytearray([k, fd])
            for i in range(len(gyr)):
                op = 7 if fd else 6
                # sample_frames: per component a choice byte (0: fz_float follows), then the float
                body += bytes([op, 0]) + b"".join(
                    b"\x00" + _raw_float(v) for v in (*gyr[i], *acc[i], *mag[i])
                )
                # commands: op 2, counter, selector (cmd = 1 + sel % 3), arg, value byte, corruption 0
                if i == 8:  # set gain (every gain id) to 8/16
                    for gain in c.Gain:
                        body += bytes([2, i & 15, 0x11, gain, 8, 0])
                if i == 12:  # reset
                    body += bytes([2, 3, 0x10, 0, 0, 0])
                if i == 16:  # select every kind
                    for kk in range(1, len(KINDS) + 1):
                        body += bytes([2, 4, 0x12, kk, 0, 0])
            (out / f"seed-{kind}-{'fd' if fd else 'classic'}").write_bytes(bytes(body))
            n += 1
    return n


def filter_seeds(out: Path) -> int:
    gyr, acc, mag = _stream(80, 3)
    n = 0
    bad = [np.nan, np.inf, -np.inf, 3.4e38, 0.0, 1e30, 160.0]
    for k, kind in enumerate(KINDS):
        for preset in (0, 1):
            for with_bad in (False, True):
                body = bytearray([k, preset, 255])  # no mutation, dt index 0 (1/285.714 s)
                for i in range(len(gyr)):
                    g, a, m = gyr[i].copy(), acc[i].copy(), mag[i].copy()
                    if with_bad and 40 <= i < 40 + len(bad):
                        v = bad[i - 40]
                        g[i % 3] = v
                        a[(i + 1) % 3] = v
                    body += b"\x80" + _sample_bytes(g, a, m)
                name = f"seed-{kind}-{'seed' if preset else 'default'}{'-bad' if with_bad else ''}"
                (out / name).write_bytes(bytes(body))
                n += 1
    return n


KEPT = Path(__file__).resolve().parent / "corpus"
"""The kept corpora, one archive per C target (regular files only, flat)."""


def kept_corpus(target: str, out: Path) -> int:
    """Unpack tests/fuzz/corpus/<target>.tar.xz into ``out`` as kept-<name>; the number of inputs."""
    archive = KEPT / f"{target}.tar.xz"
    if not archive.exists():
        return 0
    n = 0
    with tarfile.open(archive, "r:xz") as tf:
        for member in tf.getmembers():
            f = tf.extractfile(member) if member.isfile() and "/" not in member.name else None
            if f is None:
                raise ValueError(f"{archive}: {member.name!r} is not a flat regular file")
            (out / f"kept-{member.name}").write_bytes(f.read())
            n += 1
    return n


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print(__doc__.strip().splitlines()[-1], file=sys.stderr)
        return 2
    root = Path(argv[1])
    for target, make in (("fuzz_can", can_seeds), ("fuzz_node", node_seeds), ("fuzz_filter", filter_seeds)):
        d = root / target
        d.mkdir(parents=True, exist_ok=True)
        print(f"{target}: {make(d)} seeds and {kept_corpus(target, d)} kept inputs in {d}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv))


def filter_input(kind: str, mutations: list[tuple[int, float]], samples: list[list[float]]) -> bytes:
    """A fuzz_filter input: default settings at dt 1/285.714 s, float field mutations, raw samples.

    ``mutations`` are (index of the field in the kind's table of fuzz_filter.c, value); at most 3.
    """
    assert len(mutations) <= 3 and len(samples) <= 255
    body = bytearray([KINDS.index(kind), len(mutations) << 1])
    for field, value in mutations:
        body += bytes([field]) + _raw_float(value)
    body.append(len(samples))
    for s in samples:
        body += b"\x80" + b"".join(_raw_float(v) for v in s)
    return bytes(body)


REST = [0.0, 0.0, 0.0, 0.0, 0.0, 9.80665, 0.0, 20.0, -40.0]


def issue_reproducers() -> dict[str, bytes]:
    """The filter defects issue 11 reports, as fuzz_filter inputs (tests/fuzz/regressions)."""
    huge_gyro = [4.5e19, -4.5e19, 4.5e19, 0.0, 0.0, 9.80665, 0.0, 20.0, -40.0]
    return {
        # kf field 7 = gyro_range, 2 = r_noise: P loses positive definiteness with flags 0
        "filter-kf-P_SPD.bin": filter_input("kf", [(7, 1e30), (2, 16384.0)], [huge_gyro] * 36),
        # ars field 6 = accel_range: one (1e30, 1e30, 1e30) accel sample makes the low-pass NaN
        "filter-ars-lowpass-NaN.bin": filter_input(
            "ars", [(6, float("inf"))], [REST] * 4 + [[0.0, 0.0, 0.0, 1e30, 1e30, 1e30, 0.0, 20.0, -40.0]]
        ),
        # gyro: dt 0.1 at 34.9 rad/s (field 0 = dt): pitch leaves [-pi/2, pi/2] after 5 steps
        "filter-gyro-pitch.bin": filter_input("gyro", [(0, 0.1)], [[0.0, 34.9, 0.0, *REST[3:]]] * 8),
    }
