"""``attica info REC``: what a recording file holds and how attica reads it.

Prints the format; every stream of the file (for bags and MCAP every topic with its type) with its count,
rate and what it becomes (gyr, acc, mag, quat_true); the recording: samples, time span, sensors, ground
truth; the time report (rate, unit, jitter, gaps, dropped rows) and every warning; and the reader's notes
(topics chosen, time source, frames and units converted). The reader options choose as for a run::

    attica info flight.ulg
    attica info walk_bag --topic /imu/data --mag-topic /imu/mag
    attica info MH_01_easy --no-truth
"""

from __future__ import annotations

import argparse
import math
from typing import Any

NAME = "info"
HELP = "print what a recording file holds: format, streams with counts and rates, time report, sensors"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``attica info``."""
    p.add_argument("recording", metavar="REC", help="a recording file or folder (any format attica reads)")
    g = p.add_argument_group("reader options (the formats they apply to)")
    g.add_argument("--topic", help="the sensor_msgs/Imu topic (bags, MCAP; default: the only one)")
    g.add_argument("--mag-topic", help="the MagneticField topic (bags, MCAP; '' for none)")
    g.add_argument(
        "--log-time",
        action="store_true",
        help="time from the log (receive) time, not header.stamp (bags, MCAP)",
    )
    g.add_argument(
        "--orientation", action="store_true", help="the Imu orientation as ground truth (bags, MCAP)"
    )
    g.add_argument("--frd", action="store_true", help="the data is in FRD/NED axes: convert (bags, MCAP)")
    g.add_argument("--attitude", action="store_true", help="vehicle_attitude as ground truth (ULog)")
    g.add_argument("--no-truth", action="store_true", help="leave the ground truth out (EuRoC)")


def _options(args: argparse.Namespace) -> dict[str, Any]:
    opts: dict[str, Any] = {}
    if args.topic is not None:
        opts["topic"] = args.topic
    if args.mag_topic is not None:
        opts["mag_topic"] = args.mag_topic
    if args.log_time:
        opts["stamp"] = "log"
    for flag in ("orientation", "frd", "attitude"):
        if getattr(args, flag):
            opts[flag] = True
    if args.no_truth:
        opts["truth"] = False
    return opts


def _rate(rate: float | None) -> str:
    return f"{rate:.6g} Hz" if rate is not None and math.isfinite(rate) else "-"


def describe(rec: Any, contents: Any) -> list[str]:
    """The lines ``attica info`` prints for a recording and its contents."""
    import numpy as np

    lines = [f"{contents.path}: {contents.format}"]
    if contents.streams:
        lines.append("streams:")
        rows = [
            (s.name, s.kind, f"{s.count}", _rate(s.rate), f"-> {s.role}" if s.role else "")
            for s in contents.streams
        ]
        widths = [max(len(r[i]) for r in rows) for i in range(4)]
        for r in rows:
            cells = [
                r[0].ljust(widths[0]),
                r[1].ljust(widths[1]),
                r[2].rjust(widths[2]),
                r[3].rjust(widths[3]),
                r[4],
            ]
            lines.append("  " + "  ".join(cells).rstrip())
    t = rec.t
    span = float(t[-1] - t[0]) if rec.n else 0.0
    lines.append(f"recording: {rec.n} samples at {rec.rate:.6g} Hz, {span:.6g} s ({rec.lost} lost in gaps)")
    mag_n = int(np.count_nonzero(np.isfinite(rec.mag).all(axis=1)))
    lines.append("sensors: gyr, acc" + (f", mag ({mag_n} samples)" if mag_n else " (no magnetometer)"))
    if rec.quat_true is not None:
        known = int(np.count_nonzero(np.isfinite(rec.quat_true).all(axis=1)))
        lines.append(f"ground truth: quat_true, known for {known} of {rec.n} samples")
    else:
        lines.append("ground truth: none")
    if rec.timing is not None:
        lines.append(f"time: {rec.timing.summary()}")
    else:
        lines.append(f"time: none in the file, a sample every {1.0 / rec.rate:.6g} s")
    problems = [*(rec.timing.warnings() if rec.timing is not None else []), *contents.warnings]
    lines.append("warnings:" if problems else "warnings: none")
    lines += [f"  - {w}" for w in problems]
    if contents.notes:
        lines.append("notes:")
        lines += [f"  - {n}" for n in contents.notes]
    return lines


def run(args: argparse.Namespace) -> int:
    """``attica info``."""
    from attica.commands._common import CliError
    from attica.data import detect, read_recording

    opts = _options(args)
    try:
        if detect(args.recording) == "ulog":
            opts["everything"] = True  # every message listed, not only those attica reads
        rec, contents = read_recording(args.recording, **opts)
    except (FileNotFoundError, ValueError, ImportError, TypeError) as exc:
        raise CliError(str(exc)) from None
    print("\n".join(describe(rec, contents)))
    return 0
