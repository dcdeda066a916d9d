"""``attica replay``: send a simulated or recorded IMU stream to a node as CAN frames.

Real time (``--realtime``, ``--speed``) or as fast as the node takes them (flow control by its reported
steps, ``--window``). ``--write`` logs the traffic of this process, both directions (the frames sent
and those received while replaying), in one run. ``--id-offset N``: the node's CAN IDs are the DBC's
+ N (the frames go out, and are logged, at their bus IDs).
"""

from __future__ import annotations

import argparse
import sys

from attica.commands._can import (
    add_bus_arguments,
    add_pacing_arguments,
    add_stream_arguments,
    add_write_argument,
    check_stream_args,
    describe_bus,
    id_offset,
    log_paths,
    open_bus,
    stream,
)
from attica.commands._common import CliError, add_calibration_argument, describe_calibration, load_calibration

NAME = "replay"
HELP = "send a simulated or recorded IMU stream as CAN frames (real time or as fast as the node goes)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``attica replay``."""
    add_bus_arguments(p)
    add_stream_arguments(p)
    add_pacing_arguments(p)
    add_write_argument(p, "the frames sent and received")
    add_calibration_argument(p, "the node first, over CAN (CAL_BEGIN, CAL_SET..., CAL_COMMIT)")


def run(args: argparse.Namespace) -> int:
    """``attica replay``."""
    from attica.can.calibration import CalibrationError, send_calibration
    from attica.can.logs import LogError, LogTee
    from attica.can.replay import replay

    check_stream_args(args)
    paths = log_paths(args)
    cal = load_calibration(args)
    st = stream(args)
    try:
        tee = LogTee(paths, channel=args.channel or "can0", id_offset=id_offset(args))
    except LogError as exc:
        raise CliError(str(exc)) from None
    bus = open_bus(args)
    try:
        if cal is not None:
            try:
                sent = send_calibration(
                    bus,
                    cal,
                    on_send=tee.sent if tee else None,
                    on_receive=tee.received if tee else None,
                )
            except CalibrationError as exc:
                raise CliError(f"--calibration {args.calibration}: {exc}; nothing replayed") from None
            print(f"{describe_calibration(cal, args.calibration)}: {sent.line()}", file=sys.stderr)
        if not args.quiet:
            how = "in real time" if args.realtime else "as fast as possible"
            print(
                f"replaying {len(st)} samples at {st.rate:g} Hz {how} on {describe_bus(args)}",
                file=sys.stderr,
            )
        try:
            stats = replay(
                bus,
                st,
                fd=args.fd,
                realtime=args.realtime,
                speed=args.speed,
                window=args.window,
                progress=not args.quiet,
                receive=tee.received if tee else None,
                on_send=tee.sent if tee else None,
            )
        except KeyboardInterrupt:
            print("attica replay: interrupted", file=sys.stderr)
            return 130
        print(stats.line())
        if tee:  # the node's answers to the last samples belong in the log too
            msg = bus.recv(0.3)
            while msg is not None:
                tee.received(msg)
                msg = bus.recv(0.3)
        if tee:
            print(f"wrote {tee.frames} frames to {', '.join(str(p) for p in paths)}")
    finally:
        bus.shutdown()
        tee.close()
    return 0
