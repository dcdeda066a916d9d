"""``attica monitor``: a candump-style view of a bus or a log, decoded with the DBC.

Each frame gives one line (the ``candump -L`` text, the message and its signals, flags by name, then
any problem: ``!CRC``, ``!GAP+n``, ``!DUP``, ``!DLC``, ``!UNKNOWN``); the summary counts them, gives
the bus load, and says when samples or output sets were lost (by the node's step counter, not only the
4-bit alive counters). ``--write`` logs what is seen (.log candump -L, .asc, .blf). ``--id-offset N``:
the node's frames are at their DBC ID + N; they are checked and decoded at the DBC's IDs and shown (and
logged) as they are on the bus; without it the summary names the offset at which frames of unknown ID
are attica frames.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import can

from attica.commands._can import (
    StopSignals,
    add_bus_arguments,
    add_write_argument,
    id_offset,
    log_paths,
    open_bus,
)
from attica.commands._common import CliError

NAME = "monitor"
HELP = "candump-style view of a bus or a log, decoded with the DBC, with E2E checks and losses"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``attica monitor``."""
    add_bus_arguments(p)
    p.add_argument("--log", help="read this log (.log candump -L, .asc, .blf) instead of a bus")
    p.add_argument(
        "--dbc",
        help="DBC file (default: the firmware's attica.dbc, see attica paths; one written by "
        "attica dbc --id-offset D is read at its offset D)",
    )
    add_write_argument(p, "every frame seen")
    p.add_argument("--count", type=int, help="stop after N frames")
    p.add_argument("--duration", type=float, help="stop after this many seconds (bus)")
    p.add_argument("--max-lines", type=int, help="print at most N frame lines (counting goes on)")
    p.add_argument("--summary-only", action="store_true", help="print only the summary")
    p.add_argument("--no-decode", action="store_true", help="candump text and checks only")
    p.add_argument("--stats-every", type=float, default=0.0, help="print a stats line every S seconds (bus)")


def run(args: argparse.Namespace) -> int:
    """``attica monitor``."""
    from attica.can.logs import LogError, LogTee, read_log
    from attica.can.monitor import BusReader, Monitor, MonitorError

    if args.count is not None and args.count <= 0:
        raise CliError("--count must be > 0")
    if args.duration is not None and not args.duration > 0:
        raise CliError(f"--duration must be > 0 s, got {args.duration:g}")
    if args.max_lines is not None and args.max_lines < 0:
        raise CliError(f"--max-lines must be >= 0, got {args.max_lines}")
    if not args.stats_every >= 0:
        raise CliError(f"--stats-every must be >= 0 s, got {args.stats_every:g}")
    if args.log and (args.duration is not None or args.stats_every):
        raise CliError("--duration and --stats-every watch a bus; with --log the whole log is read")
    paths = log_paths(args)
    if args.log:
        source = Path(args.log).resolve()
        same = [p for p in paths if p.resolve() == source]
        if same:
            raise CliError(f"--write {same[0]} is the --log being read (it would be overwritten)")
    try:
        mon = Monitor(
            args.dbc,
            bitrate=args.bitrate,
            data_bitrate=args.data_bitrate,
            decode=not (args.no_decode or args.summary_only),
            id_offset=id_offset(args),
        )
        tee = LogTee(paths, channel=args.channel or "can0")
    except (MonitorError, LogError) as exc:
        raise CliError(str(exc)) from None
    shown = 0
    out = sys.stdout

    def show(msg: can.Message) -> None:
        nonlocal shown
        tee.received(msg)
        if args.summary_only or (args.max_lines is not None and shown >= args.max_lines):
            mon.account(msg)
            return
        out.write(mon.feed(msg) + "\n")
        shown += 1

    try:
        if args.log:
            try:
                for i, msg in enumerate(read_log(args.log)):
                    if args.count is not None and i >= args.count:
                        break
                    show(msg)
            except LogError as exc:
                raise CliError(str(exc)) from None
        else:
            bus = open_bus(args, raw=True)  # the monitor shows the bus as it is; it moves the IDs itself
            try:
                reader = BusReader(bus)
                t_end = time.monotonic() + args.duration if args.duration else None
                next_stats = time.monotonic() + args.stats_every if args.stats_every else None
                with StopSignals() as stop:
                    while not stop.is_set():
                        if args.count is not None and mon.stats.frames >= args.count:
                            break
                        now = time.monotonic()
                        if t_end is not None and now >= t_end:
                            break
                        got = reader.get(0.1)
                        if got is not None:
                            show(got)
                        if next_stats is not None and now >= next_stats:
                            next_stats = now + args.stats_every
                            print("-- " + mon.summary()[0], file=sys.stderr, flush=True)
                # every frame that reached us before the stop is shown and counted
                for msg in reader.stop():
                    if args.count is not None and mon.stats.frames >= args.count:
                        break
                    show(msg)
                mon.stats.dropped += reader.dropped
            finally:
                bus.shutdown()
    finally:
        tee.close()
    out.flush()
    for line in mon.summary():
        print("-- " + line, file=sys.stderr if not args.summary_only else sys.stdout)
    return 0
