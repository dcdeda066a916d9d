"""Stage A of the oracle: the cases of the golden runner, the node runner, the config and core tests."""

from __future__ import annotations

import dataclasses
import hashlib
import subprocess
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

MATH_ROWS = 3000
SYNTH_STEPS = 300
SYNTH_STREAMS = 12


@dataclass(frozen=True)
class Case:
    """One run of a stage A program: ``argv`` with ``{out}`` for the output file; ``tags`` order the cases."""

    name: str
    program: str
    argv: list[str]
    tags: list[str] = field(default_factory=list)


def _edge_variants() -> dict[str, tuple[Any, dict[str, Any]]]:
    """Settings at the edges the golden variants leave out (stage A; synthetic and jump streams)."""
    from attica.settings import FilterKind

    vertical = (0.0, 0.0, -45.0)
    return {
        "mars-vertical-m0": (FilterKind.MARS, {"init_from_sensors": False, "m0_init": vertical}),
        "mekf-vertical-m0": (FilterKind.MEKF, {"init_from_sensors": False, "m0_init": vertical}),
        "mars-m0-init": (FilterKind.MARS, {"init_from_sensors": False, "m0_init": (3.0, 22.0, -40.0)}),
        "mars-m0-y": (FilterKind.MARS, {"init_from_sensors": False, "m0_init": (0.0, 1.0, 0.0)}),
        "mekf-m0-init": (FilterKind.MEKF, {"init_from_sensors": False, "m0_init": (3.0, 22.0, -40.0)}),
        "ekf-q-apart": (FilterKind.EKF, {"q_phi": 2e-3, "q_theta": 5e-4, "r_phi": 2e-4}),
        "mars-bias-init": (FilterKind.MARS, {"bias_init": (0.01, -0.02, 0.005)}),
        "mars-bias-off": (FilterKind.MARS, {"bias_init": (0.01, -0.02, 0.005), "bias_mode": 0}),
        "kf-bias-off": (FilterKind.KF, {"bias_init": (0.01, -0.02, 0.005), "bias_mode": 0}),
        "kf-noinit": (FilterKind.KF, {"init_from_accel": False, "q_init": (0.9, 0.1, -0.3, 0.2)}),
        "gyro-cos-min": (FilterKind.GYRO, {"cos_min": 0.2}),
        "ekf-cos-min": (FilterKind.EKF, {"cos_min": 0.2}),
        "ekf-small-p0": (FilterKind.EKF, {"p0": 0.01}),
        "ekf-capped": (FilterKind.EKF, {"p_max": 0.5, "p0": 0.1}),
        "ekf-narrow-gate": (FilterKind.EKF, {"gate": 0.5, "r_accel": 0.5}),
        "kf-small-r-accel": (FilterKind.KF, {"r_accel": 0.5, "accel_reject": 0.0, "gate": 0.5}),
        "mekf-capped": (FilterKind.MEKF, {"p_max": 0.05}),
    }


def _write_cases(d: Path) -> list[Case]:
    """Write the inputs of stage A into ``d``; return the cases (math, filters, node)."""
    import numpy as np

    from attica.calibration.stages import StageSettings
    from attica.settings import implemented_kinds, make_settings
    from attica_dev import cross, digests, golden

    d.mkdir(parents=True)
    cases: list[Case] = []
    cases.append(Case("config", "config", [], ["contract", "node", "calib"]))
    cases.append(Case("core", "core", ["256"], ["math", "core"]))
    for fn in golden.MATH_FUNCS:
        p = d / f"math-{fn}.bin"
        golden.write_table(p, golden.math_inputs(fn, MATH_ROWS, seed=20240611), fn)
        cases.append(Case(f"math:{fn}", "golden", ["math", fn, "@" + p.name, "{out}"], ["math", fn]))
    imu = golden.imu_inputs(SYNTH_STEPS, SYNTH_STREAMS, seed=11)
    sim = digests.sim_stream()
    adv = digests.adversarial_stream()
    tiny = sim[2][:600].copy()
    tiny[:50] *= np.float32(1e-5)  # a first mag sample below 1e-3 uT: no reference field from it
    late = sim[2].copy()
    late[:40] = np.nan  # the mag arrives after the start (the kinds' first-mag paths)
    late[40:60:3] = 0.0
    streams = {
        "synth": imu,
        "sim": sim,
        "adv": adv,
        "adv6": (adv[0], adv[1], None),
        "late": (sim[0], sim[1], late),
        "jumps": _jumps(),
        "sweep": _sweep(),
        "tinymag": (sim[0][:600], sim[1][:600], tiny),
        "flip": _flip(),
        "magvert": (sim[0], sim[1], (sim[1] * np.float32(-4.5)).astype(np.float32)),  # no horizontal field
    }

    def add(name: str, kind: Any, settings: Any, stream: str, calibration: Any = None) -> None:
        label = kind.label
        inp = d / f"{label}-{stream}.bin"
        if not inp.exists():
            g, a, m = streams[stream]
            golden.write_filter_input(inp, kind, g, a, m)
        st = d / f"{name}.settings.txt"
        golden.write_settings(st, kind, settings, calibration)
        cases.append(Case(name, "golden", [label, "@" + st.name, "@" + inp.name, "{out}"], [label, "filter"]))

    for kind in implemented_kinds():
        k = kind.label
        for preset in ("default", "seed"):
            s = digests._settings(kind, preset)
            for stream in ("synth", "sim", "adv"):
                add(f"{k}:{preset}:{stream}", kind, s, stream)
        add(f"{k}:default:adv-nomag", kind, make_settings(kind), "adv6")
        add(f"{k}:default:late-mag", kind, make_settings(kind), "late")
        add(f"{k}:default:vertical-mag", kind, make_settings(kind), "magvert")
        add(f"{k}:default:sweep", kind, make_settings(kind), "sweep")
        add(f"{k}:default:tiny-mag", kind, make_settings(kind), "tinymag")
        add(f"{k}:default:flip", kind, make_settings(kind), "flip")
        add(f"{k}:seed:flip", kind, digests._settings(kind, "seed"), "flip")
        add(f"{k}:calib-digests", kind, make_settings(kind), "sim", digests._calib())
        add(f"{k}:calib-remap", kind, make_settings(kind), "synth", StageSettings(remap=5, convention=2))
        if "dt" in {f.name for f in dataclasses.fields(make_settings(kind))}:
            add(f"{k}:dt-0.05:synth", kind, make_settings(kind, dt=0.05), "synth")  # larger angles a step
    gated: dict[str, dict[str, Any]] = {"ekf": {"gate": 9.0, "r_accel": 10.0, "accel_reject": 0.3}}
    gated["mars"] = {"mag_mode": 1}
    for kind in implemented_kinds():
        add(f"{kind.label}:default:jumps", kind, make_settings(kind), "jumps")
        add(f"{kind.label}:seed:jumps", kind, digests._settings(kind, "seed"), "jumps")
        if kind.label in gated:
            add(f"{kind.label}:gated:jumps", kind, make_settings(kind, **gated[kind.label]), "jumps")
    for name, (kind, overrides) in _edge_variants().items():
        for stream in ("synth", "jumps", "sweep"):
            add(f"{kind.label}:edge:{name}:{stream}", kind, make_settings(kind, **overrides), stream)
    for name, (kind, overrides) in cross.VARIANTS.items():
        add(f"{kind.label}:variant:{name}", kind, make_settings(kind, **overrides), "synth")
        add(f"{kind.label}:variant:{name}:jumps", kind, make_settings(kind, **overrides), "jumps")
    for name, (kind, cal) in cross.calibrated_variants().items():
        add(f"{kind.label}:calibrated:{name}", kind, make_settings(kind), "synth", cal)
    for kind in implemented_kinds():
        k = kind.label
        frames = {"digest": digests.node_stream(kind), "rough": _rough_frames(kind, fd=False)}
        frames["rough-fd"] = _rough_frames(kind, fd=True)
        for name, fr in frames.items():
            p = d / f"node-{k}-{name}.bin"
            np.ascontiguousarray(fr).tofile(p)
            for fd in (0, 1):
                bitrate, data_bitrate = digests.NODE_BITRATES[bool(fd)]
                argv = [str(int(kind)), str(digests.RATE), str(fd), str(bitrate), str(data_bitrate), "0"]
                cases.append(
                    Case(
                        f"node:{k}:{name}:fd{fd}", "node", [*argv, "@" + p.name, "{out}"], [k, "node", "can"]
                    )
                )
        if k == "ars":  # more errors than the DIAG counters and the STATUS error count hold (255)
            p = d / "node-junk.bin"
            junk = np.array(frames["rough"][:1200], copy=True)
            junk["data"][::2, 0] ^= 0x5A
            np.concatenate([junk, junk, frames["digest"][:600]]).tofile(p)
            argv = [str(int(kind)), str(digests.RATE), "0", "1000000", "0", "0", "@" + p.name, "{out}"]
            cases.append(Case("node:ars:junk", "node", argv, ["node", "can"]))
        if k == "mars":
            p = d / "node-offset.bin"
            shifted = np.array(frames["rough"], copy=True)
            shifted["id"] = shifted["id"] + np.uint32(0x20)
            shifted.tofile(p)
            argv = [str(int(kind)), str(digests.RATE), "0", "500000", "0", "0x20", "@" + p.name, "{out}"]
            cases.append(Case("node:mars:offset", "node", argv, ["node", "can"]))
    return cases


def _flip() -> tuple[Any, Any, Any]:
    """At rest upright, then at once exactly upside down (the accel opposite the predicted gravity)."""
    import numpy as np

    n = 300
    gyr = np.zeros((2 * n, 3), np.float32)
    acc = np.zeros((2 * n, 3), np.float32)
    acc[:n, 2] = 9.80665
    acc[n:, 2] = -9.80665
    mag = np.zeros((2 * n, 3), np.float32)
    mag[:n] = (0.0, 22.0, -40.0)
    mag[n:] = (0.0, -22.0, 40.0)
    mag[:5] = (0.0, 0.0, -45.0)  # vertical at the start: no heading from it
    return gyr, acc, mag


def _sweep(steps: int = 1500, streams: int = 4) -> tuple[Any, Any, Any]:
    """Turns about the pitch axis through +-90 degrees again and again (the gimbal zones), deterministic."""
    import numpy as np

    rng = np.random.default_rng([26, 2])
    t = np.arange(steps)[:, None] * 0.01
    wy = np.array([1.0, 0.7, 2.3, -1.3])[None, :streams]
    theta = wy * t
    gyr = np.stack(
        [0.01 * np.sin(0.3 * t + np.zeros_like(wy)), wy + 0 * t, 0.02 * np.cos(0.2 * t) + 0 * wy], -1
    )
    gyr = gyr + rng.normal(0, 1e-4, gyr.shape)
    acc = 9.80665 * np.stack([-np.sin(theta), 0 * theta, np.cos(theta)], -1)
    mag = np.stack([22.0 * np.cos(theta) + 40.0 * np.sin(theta), 0 * theta + 5.0, -40.0 * np.cos(theta)], -1)
    f = np.float32
    return gyr.astype(f), acc.astype(f), mag.astype(f)


def _jumps(steps: int = 1000, streams: int = 4) -> tuple[Any, Any, Any]:
    """Segments of constant attitude whose accel or mag disagree with it at once (deterministic).

    Each segment of 40 to 120 samples holds still (a small gyro bias and noise) with one of: consistent
    sensors; the accel turned 3 to 60 degrees at |g| (the gates and rejections); the accel 2 to 40 % off
    |g|; the mag turned about the vertical (a heading jump) or about a horizontal axis (the dip), at its
    norm; the mag 30 to 60 % off its norm; pitch exactly +-90 degrees (the gimbal cases); a burst of
    rotation.
    """
    import numpy as np

    rng = np.random.default_rng([26, 1])
    g0, b0, dip = 9.80665, 49.0, 1.1
    m_earth = np.array([0.0, b0 * np.cos(dip), -b0 * np.sin(dip)])
    gyr = np.empty((steps, streams, 3))
    acc = np.empty((steps, streams, 3))
    mag = np.empty((steps, streams, 3))

    def rot(axis: Any, angle: float) -> Any:
        u = np.asarray(axis, float) / np.linalg.norm(axis)
        k = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
        return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)

    for j in range(streams):
        bias = rng.normal(0, 0.005, 3)
        t = 0
        while t < steps:
            end = min(t + int(rng.integers(40, 120)), steps)
            n = end - t
            what = int(rng.integers(0, 9))
            r = rot(rng.normal(size=3), rng.uniform(0, np.pi))  # body -> earth
            if what == 6:
                r = rot([0, 1, 0], rng.choice([-1.0, 1.0]) * np.pi / 2) @ rot([1, 0, 0], rng.uniform(-3, 3))
            elif what == 8:
                r = np.diag([1.0, -1.0, -1.0])  # upside down, exactly
            a_b = r.T @ np.array([0.0, 0.0, g0])
            m_b = r.T @ m_earth
            if what == 1:
                a_b = rot(rng.normal(size=3), np.radians(rng.uniform(3, 60))) @ a_b
            elif what == 2:
                a_b = a_b * (1 + rng.choice([-1, 1]) * rng.uniform(0.02, 0.4))
            elif what == 3:
                m_b = r.T @ (rot([0, 0, 1], rng.uniform(-np.pi, np.pi)) @ m_earth)
            elif what == 4:
                m_b = r.T @ (rot([1, 0, 0], rng.uniform(-0.8, 0.8)) @ m_earth)
            elif what == 5:
                m_b = m_b * (1 + rng.choice([-1, 1]) * rng.uniform(0.3, 0.6))
            w = bias + rng.normal(0, 0.002, (n, 3))
            if what == 7:
                w = w + rng.normal(0, 3.0, 3)
            gyr[t:end, j] = w
            acc[t:end, j] = a_b + (0.0 if what in (6, 8) else rng.normal(0, 0.01, (n, 3)))
            mag[t:end, j] = m_b + rng.normal(0, 0.2, (n, 3))
            t = end
    f = np.float32
    return gyr.astype(f), acc.astype(f), mag.astype(f)


def _rough_frames(kind: Any, fd: bool) -> Any:
    """A node input with every kind of trouble and every command (deterministic)."""
    import numpy as np

    from attica.can import codec as c
    from attica_dev import digests

    rng = np.random.default_rng([26, int(kind), int(fd)])
    g, a, m = digests.adversarial_stream()
    n = 400
    m = m[:n].copy()
    m[::7] = np.nan  # absent mag
    imu = c.encode_imu(g[:n], a[:n], m, fd=fd)
    per = 1 if fd else 3
    rows = [imu[i * per : (i + 1) * per].copy() for i in range(n)]
    commands: list[tuple[int, int, float]] = [
        (int(c.Cmd.SET_GAIN), int(p), v) for p in range(0, 6) for v in (0.75, 0.0, -1.0, float("nan"), 1e9)
    ]
    commands += [(int(c.Cmd.SELECT), k, 0.0) for k in (0, 9, int(kind))]
    commands += [(int(c.Cmd.RESET), 0, 0.0), (15, 0, 0.0), (0, 0, 0.0)]
    commands += [(8, conv, 0.0) for conv in (1, 2, 0, 7)] + [(9, r, 0.0) for r in (5, 24, 25, 0)]
    values = [0.02, -0.01, 1.01, 0.0, float("inf"), 1e6, 0.5]
    cal: list[tuple[int, int, float]] = [(4, 0, 0.0)]
    cal += [(5, int(i), float(rng.choice(values))) for i in rng.choice(48, 12, replace=False)]
    cal += [(6, 0, 0.0), (4, 1, 0.0), (5, 12, 0.01), (5, 200, 1.0), (7, 0, 0.0), (6, 0, 0.0), (4, 0, 0.0)]
    cal += [(5, 0, 2.0), (6, 0, 0.0), (4, 7, 0.0)]
    commands += cal
    out = []
    counter = 0
    for i, r in enumerate(rows):
        if i % 4 == 1 and commands:
            cmd, arg, value = commands.pop(0)
            counter = (counter + 1) & 0xF
            out.append(c.encode_cmd(cmd, arg, value, counter=counter))
            if i % 40 == 1:
                out.append(c.encode_cmd(cmd, arg, value, counter=counter))  # a repeated command
        if i % 37 == 5:
            r["data"][0, 3] ^= 0x10  # a bad CRC
        if i % 53 == 11:
            continue  # a lost sample: a counter gap
        if i % 61 == 13:
            r = np.concatenate([r, r])  # duplicates
        if i % 43 == 17:
            r = r[:-1]  # a partial sample (classic) or nothing (FD)
        if i % 71 == 19 and len(r):
            r = r.copy()
            r["len"][0] = 5  # a wrong length
        if i % 67 == 23:
            junk = c.frames(1)
            junk["id"] = 0x123 + i
            junk["len"] = 8
            out.append(junk)
        out.append(r)
    return np.concatenate(out)


def _run_case(c: Case, exes: dict[str, Path], inputs: Path, tmp: Path, timeout: float) -> str:
    """The digest of one run, or ``!reason`` (crash, exit status, timeout)."""
    out = tmp / f"{c.name.replace(':', '-')}.out"
    argv = [str(exes[c.program]), *(str(out) if a == "{out}" else a for a in c.argv)]
    argv = [str(inputs / a[1:]) if a.startswith("@") else a for a in argv]
    try:
        proc = subprocess.run(argv, capture_output=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return "!timeout"
    finally:
        data = out.read_bytes() if out.exists() else b""
        out.unlink(missing_ok=True)
    if proc.returncode < 0:
        return f"!signal {-proc.returncode}"
    if proc.returncode != 0:  # settings refused, a file error, a failed check of the core test
        return f"!exit {proc.returncode}"
    h = hashlib.sha256(data)
    h.update(proc.stdout)
    h.update(str(proc.returncode).encode())
    return h.hexdigest()
