"""Committed output digests: a tripwire that flags every change of behaviour.

PX4-ECL's functional change indicator is the model. Every case runs a fixed input stream through
the firmware and hashes the raw bits of what comes out:
each kind's step records (``att_filter_step`` only, as a firmware loop pays for) and whole output
records (``att_filter_output`` after each step), with its default and seed settings, on a simulated
9-axis stream and on an adversarial one (NaN, +-Inf, saturation, denormals, zero and absent mag);
the calibration stages with accel outputs; heading set and heading updates; retune; mars's and mekf's
hard-iron estimate on a stream with a hard-iron offset; and the CAN
node's output frames (classic and FD, with commands). The inputs are hashed too, so that a change of
the simulator is told apart from a change of the firmware.

``tests/digests.txt`` holds one ``name sha256`` line per case; ``tests/test_digests.py`` fails when any
differs. A commit that changes behaviour on purpose runs ``python -m attica_dev.digests --update`` and
says why in its message.

The ``run`` cases (whole records per step over one stream) are what the golden runner
(tests/c/att_golden.c) writes too: the single-kind builds of tests/test_configs.py hash the runner's
output and compare with the same lines.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from attica.kinds import uses_mag
from attica.settings import implemented_kinds

ROOT = Path(__file__).resolve().parents[2]
DIGEST_FILE = ROOT / "tests" / "digests.txt"
RATE = 200.0
N_SIM = 3000
N_ADV = 600


def sha(*arrays: Any) -> str:
    """sha256 of the raw bytes of the arrays, in order (hex, 64 characters)."""
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def dt() -> float:
    """The sample period of every stream (float32 of 1 / RATE)."""
    return float(np.float32(1.0) / np.float32(RATE))


def sim_stream() -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]:
    """A simulated 9-axis stream: rotation, translation, taps, bias drift, mag disturbances."""
    from attica import sim

    rec = sim.simulate(sim.SimConfig(duration=N_SIM / RATE, rate=RATE, seed=11, taps=6))
    f = np.float32
    return rec.gyr[:N_SIM].astype(f), rec.acc[:N_SIM].astype(f), rec.mag[:N_SIM].astype(f)


N_FIELD = 14000


def field_stream() -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]:
    """A 9-axis stream whose magnetic field changes (70 s).

    Disturbed for the first 30 s, then the clean field, whose vertical part grows by 6 uT at 50 s: the
    learnt reference of the 9-axis kinds follows the norm and dip, adopts the clean field and runs its
    fast phase (issue 23).
    """
    from attica import sim

    dist = ((0.0, 30.0, (-12.0, 8.0, -10.0)), (50.0, 80.0, (0.0, 0.0, 6.0)))
    rec = sim.simulate(sim.SimConfig(duration=N_FIELD / RATE, rate=RATE, seed=23, mag_disturbances=dist))
    f = np.float32
    return rec.gyr[:N_FIELD].astype(f), rec.acc[:N_FIELD].astype(f), rec.mag[:N_FIELD].astype(f)


def adversarial_stream() -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]:
    """A stream of bad and extreme samples between stretches of good ones (deterministic)."""
    rng = np.random.default_rng(2026)
    g, a, m = (x[:N_ADV].copy() for x in sim_stream())
    special = np.array(
        [
            np.nan,
            np.inf,
            -np.inf,
            0.0,
            -0.0,
            1e-45,
            -1e-45,
            1.17e-38,
            3.4e38,
            -3.4e38,
            1e6,
            -1e6,
            40.0,
            200.0,
        ],
        np.float32,
    )
    for arr in (g, a, m):
        rows = rng.choice(N_ADV, N_ADV // 6, replace=False)
        cols = rng.integers(0, 3, rows.size)
        arr[rows, cols] = rng.choice(special, rows.size)
    m[rng.choice(N_ADV, N_ADV // 10, replace=False)] = 0.0  # absent mag rows
    a[100:140] = 0.0  # free fall
    with np.errstate(over="ignore", invalid="ignore"):
        g[200:220] *= np.float32(50.0)  # beyond the gyro range (and overflowing where already huge)
    return g, a, m


@dataclass(frozen=True)
class Case:
    """One digest: its name and the function that computes it."""

    name: str
    compute: Callable[[], str]


def _settings(kind: Any, preset: str) -> Any:
    from attica.settings import preset_settings

    return preset_settings(kind, preset, dt())


def _filter(kind: Any, preset: str = "default", **kw: Any) -> Any:
    from attica import native

    return native.Filter(kind, settings=_settings(kind, preset), **kw)


def run_records(kind: Any, preset: str, stream: str, full: bool) -> NDArray[np.void]:
    """Records of one kind over one stream (the binding's batch run)."""
    streams = {"sim": sim_stream, "adversarial": adversarial_stream, "field": field_stream}
    g, a, m = streams[stream]()
    return _filter(kind, preset).run(g, a, m, full=full, check_units=False)  # type: ignore[no-any-return]


def _calib() -> Any:
    from attica.calibration.stages import StageSettings

    c, s = np.float32(np.cos(0.3)), np.float32(np.sin(0.3))
    return StageSettings(
        gyro_misalignment=(1.0, 0.01, -0.02, 0.0, 1.0, 0.015, 0.01, 0.0, 1.0),
        gyro_sensitivity=(1.01, 0.99, 1.002),
        gyro_offset=(0.01, -0.02, 0.005),
        accel_misalignment=(1.0, 0.0, 0.0, 0.002, 1.0, 0.0, -0.003, 0.001, 1.0),
        accel_sensitivity=(0.998, 1.003, 1.0),
        accel_offset=(0.05, -0.1, 0.02),
        soft_iron=(1.05, 0.02, 0.0, 0.02, 0.97, 0.0, 0.0, 0.0, 1.0),
        hard_iron=(3.0, -2.0, 5.0),
        mounting=(float(c), 0.0, 0.0, float(s)),
        convention=1,
        accel_outputs=True,
    )


def calib_digest(kind: Any) -> str:
    """Stages on (calibration, mounting, NED output, accel outputs): step records and accel outputs."""
    g, a, m = sim_stream()
    n = 800
    f = _filter(kind, calibration=_calib(), accel_outputs=True)
    recs = []
    accel = np.zeros((n, 9), np.float32)
    for i in range(n):
        recs.append(np.asarray(f.step(g[i], a[i], m[i], full=False)).copy())
        acc = f.accel()
        if acc is not None:
            accel[i] = np.concatenate(acc)
    whole = f.run(g[n:], a[n:], m[n:], full=True, check_units=False)
    return sha(np.array(recs), accel, whole)


def heading_digest(kind: Any) -> str:
    """Set heading and heading updates between runs (the kinds' yaw hooks); refused calls recorded."""
    from attica import native

    g, a, m = sim_stream()
    f = _filter(kind)
    parts: list[Any] = []
    codes: list[int] = []
    cuts = [0, 400, 900, 1500, 2200, N_SIM]
    actions: list[Callable[[], None]] = [
        lambda: f.set_heading(1.0),
        lambda: f.heading_update(-2.5, 0.3),
        lambda: f.set_heading(-3.0),
        lambda: f.heading_update(0.7, 1.0),
    ]
    for j in range(len(cuts) - 1):
        parts.append(
            f.run(
                g[cuts[j] : cuts[j + 1]],
                a[cuts[j] : cuts[j + 1]],
                m[cuts[j] : cuts[j + 1]],
                full=True,
                check_units=False,
            )
        )
        if j < len(actions):
            try:
                actions[j]()
                codes.append(0)
            except native.NativeError as e:
                codes.append(len(str(e)))
            parts.append(np.asarray(f.output()).copy())
    return sha(*parts, np.array(codes, np.int32))


_RETUNE: dict[str, dict[str, Any]] = {
    "ars": {"tau": 0.5, "gain": 0.0, "tau_acc_lp": 0.3},
    "mars": {"tau_acc": 2.0, "alpha_acc": 0.0, "tau_mag": 5.0, "alpha_mag": 0.0},
    "kf": {"r_noise": 2.5e-4, "tau_acc_lp": 0.5},
    "ekf": {"r_phi": 2.0, "r_theta": 2.0},
    "gyro": {"cos_min": 0.01},
    "tilt": {"normalise": False},
    "mekf": {"accel_noise": 0.3, "gyro_scale_sd": 0.0},
}


def retune_digest(kind: Any) -> str:
    """A run, a retune that keeps the state, another run."""
    g, a, m = sim_stream()
    f = _filter(kind)
    first = f.run(g[:1500], a[:1500], m[:1500], full=True, check_units=False)
    f.retune(**_RETUNE[kind.label])
    second = f.run(g[1500:], a[1500:], m[1500:], full=True, check_units=False)
    return sha(first, second)


N_HARD = 8000


def hard_iron_stream() -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]:
    """A simulated stream whose magnetometer has a hard-iron offset of up to 20 uT per axis (40 s)."""
    from attica import sim
    from attica.sim.errors import mag_only

    sizes = mag_only(hard_iron=20.0, soft_iron_scale=0.0, soft_iron_coupling=0.0)
    cfg = sim.SimConfig(duration=N_HARD / RATE, rate=RATE, seed=5, sensor_errors=sizes)
    rec = sim.simulate(cfg)
    f = np.float32
    return rec.gyr[:N_HARD].astype(f), rec.acc[:N_HARD].astype(f), rec.mag[:N_HARD].astype(f)


def hard_iron_digest(kind: Any) -> str:
    """The hard-iron estimate on (mars, mekf; att_hardiron.h).

    Step records, then the offset, its target, information and lag after every quarter of the stream.
    """
    g, a, m = hard_iron_stream()
    f = _filter(kind)
    f.retune(hard_iron_tau=20.0, hard_iron_rate=4.0)
    parts: list[Any] = []
    for i in range(0, N_HARD, N_HARD // 4):
        j = i + N_HARD // 4
        parts.append(f.run(g[i:j], a[i:j], m[i:j], full=True, check_units=False))
        h = f.mag_offset()
        st = getattr(f.state.u, kind.label).st.hi
        vals = [*h.offset, st.target.x, st.target.y, st.target.z, *st.info, *st.z, st.lag]
        parts.append(np.array(vals, np.float32))
        parts.append(np.array([h.on, h.estimated], np.uint8))
    return sha(*parts)


NODE_BITRATES = {False: (1_000_000, 0), True: (1_000_000, 5_000_000)}
"""(bitrate, data_bitrate) of the node digests, classic and FD."""


def node_stream(kind: Any) -> Any:
    """The frames of the node digests: 1200 classic IMU samples with gain commands, a NaN gain, a reset."""
    from attica.can import codec as c

    g, a, m = sim_stream()
    n = 1200
    samples = c.encode_imu(g[:n], a[:n], m[:n]).reshape(n, 3)
    gains = {
        "ars": [c.Gain.TAU_ACC],
        "mars": [c.Gain.TAU_ACC, c.Gain.TAU_MAG],
        "kf": [c.Gain.KF_R],
        "ekf": [c.Gain.EKF_R],
    }.get(kind.label, [c.Gain.TAU_ACC])
    cmds = {
        300 + 100 * j: c.encode_cmd(c.Cmd.SET_GAIN, int(p), 0.75, counter=j + 1) for j, p in enumerate(gains)
    }
    cmds[700] = c.encode_cmd(c.Cmd.SET_GAIN, int(c.Gain.TAU_ACC), float("nan"), counter=7)
    cmds[900] = c.encode_cmd(c.Cmd.RESET, counter=8)
    return np.concatenate(
        [x for i in range(n) for x in ((cmds[i], samples[i]) if i in cmds else (samples[i],))]
    )


def node_sha(out: Any, steps: int, stats: Any) -> str:
    """The digest of a node run: output frames (id, length, data), steps and the 14 counters."""
    return sha(out["id"], out["len"], out["data"], np.array([steps], np.int64), np.asarray(stats, np.int64))


def node_digest(kind: Any, fd: bool) -> str:
    """The node's output frames (id, length, data) for IMU frames and commands of the kind."""
    from attica.can import codec as c

    bitrate, data_bitrate = NODE_BITRATES[fd]
    node = c.Node(kind, sample_rate=RATE, fd=fd, bitrate=bitrate, data_bitrate=data_bitrate)
    out, steps = node.run(node_stream(kind))
    return node_sha(out, steps, list(node.stats().values()))


def _inputs(stream: Callable[[], tuple[Any, ...]]) -> str:
    return sha(*stream())


def _run(kind: Any, preset: str, stream: str, full: bool) -> str:
    return sha(run_records(kind, preset, stream, full))


def cases() -> Iterator[Case]:
    """Every digest case, in file order."""
    yield Case("input.sim", partial(_inputs, sim_stream))
    yield Case("input.adversarial", partial(_inputs, adversarial_stream))
    yield Case("input.field", partial(_inputs, field_stream))
    yield Case("input.hard_iron", partial(_inputs, hard_iron_stream))
    for kind in implemented_kinds():
        k = kind.label
        for preset in ("default", "seed"):
            for stream in ("sim", "adversarial"):
                for full in (True, False):
                    part = "run" if full else "step"
                    yield Case(f"{k}.{preset}.{stream}.{part}", partial(_run, kind, preset, stream, full))
        if uses_mag(kind):
            yield Case(f"{k}.default.field.run", partial(_run, kind, "default", "field", True))
        if k in ("mars", "mekf"):
            yield Case(f"{k}.hard_iron", partial(hard_iron_digest, kind))
        yield Case(f"{k}.calib", partial(calib_digest, kind))
        yield Case(f"{k}.retune", partial(retune_digest, kind))
        if k != "tilt":
            yield Case(f"{k}.heading", partial(heading_digest, kind))
        for fd in (False, True):
            yield Case(f"{k}.node.{'fd' if fd else 'classic'}", partial(node_digest, kind, fd))


def compute(only: str = "") -> dict[str, str]:
    """Name to digest of every case whose name starts with ``only``."""
    return {c.name: c.compute() for c in cases() if c.name.startswith(only)}


def read(path: Path = DIGEST_FILE) -> dict[str, str]:
    """The committed digests."""
    out: dict[str, str] = {}
    for line in path.read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, value = line.split()
            out[name] = value
    return out


def write(digests: dict[str, str], path: Path = DIGEST_FILE) -> None:
    """Write the digest file."""
    head = (
        "# Output digests (tools/attica_dev/digests.py; tests/test_digests.py). A commit that changes\n"
        "# one on purpose regenerates this file (python -m attica_dev.digests --update) and says why.\n"
    )
    path.write_text(head + "".join(f"{k} {v}\n" for k, v in digests.items()))


def main(argv: list[str] | None = None) -> int:
    """Compare with (or, with --update, rewrite) tests/digests.txt."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--update", action="store_true", help="rewrite tests/digests.txt")
    args = ap.parse_args(argv)
    now = compute()
    if args.update:
        write(now)
        print(f"wrote {len(now)} digests to {DIGEST_FILE}")
        return 0
    old = read()
    bad = [k for k in sorted(set(now) | set(old)) if now.get(k) != old.get(k)]
    for k in bad:
        print(f"changed: {k} {old.get(k, '-')[:16]} -> {now.get(k, '-')[:16]}")
    print(f"{len(now) - len(bad)} of {len(now)} digests unchanged")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
