"""``attica node``: the C node in-process on a python-can bus (virtual, udp_multicast, socketcan ...).

On Linux SocketCAN the stand-alone ``build/attica-node`` (``make node``) does the same without Python.
``--id-offset N`` moves every CAN ID the node receives and sends by N (as ``attica-node --id-offset N``);
``attica dbc --id-offset N`` writes the matching DBC.
"""

from __future__ import annotations

import argparse

from attica.commands._can import (
    KINDS,
    StopSignals,
    add_bus_arguments,
    describe_bus,
    id_offset,
    open_bus,
    parse_kind,
)
from attica.commands._common import (
    CliError,
    add_calibration_argument,
    describe_calibration,
    filter_settings,
    load_calibration,
    parse_overrides,
)

NAME = "node"
HELP = "run the C node in-process on a CAN bus (virtual, udp_multicast, socketcan)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``attica node``."""
    add_bus_arguments(p)
    p.add_argument("--filter", default="ars", choices=KINDS, help="filter kind (default ars)")
    p.add_argument(
        "--rate", type=float, default=285.714, help="sample rate = 1/dt of the filter (default 285.714)"
    )
    p.add_argument("--output-divider", type=int, default=1, help="send outputs every Nth step (default 1)")
    p.add_argument("--diag-divider", type=int, default=16, help="ATT_DIAG every Nth output set (0 = never)")
    p.add_argument(
        "--set",
        action="append",
        metavar="NAME=VALUE",
        help="change a setting of the filter's init settings (repeatable; e.g. hard_iron_tau=60 makes a "
        "mars or mekf node send ATT_MAG_OFFSET); `attica settings KIND` lists them",
    )
    add_calibration_argument(p, "the node from the start (CAN commands can change it later)")
    p.add_argument("--count", type=int, help="stop after N filter steps")
    p.add_argument("--idle-timeout", type=float, help="stop after this many seconds without a frame")
    p.add_argument("-q", "--quiet", action="store_true", help="no start-up line")


def run(args: argparse.Namespace) -> int:
    """``attica node``."""
    from attica.can.node import Node, NodeError
    from attica.can.runner import NodeRunner

    kind = parse_kind(args.filter)
    overrides = parse_overrides(kind, args.set or [])
    filter_settings(kind, args.rate, overrides)  # a refusal names the field and its range
    cal = load_calibration(args)
    try:
        node = Node(
            kind,
            sample_rate=args.rate,
            bitrate=args.bitrate,
            data_bitrate=args.data_bitrate if args.fd else 0,
            fd=args.fd,
            output_divider=args.output_divider,
            diag_divider=args.diag_divider,
            calibration=cal,
            id_offset=id_offset(args),
            **overrides,
        )
    except (NodeError, ValueError, TypeError) as exc:
        raise CliError(f"node settings refused: {exc}") from None
    bus = open_bus(args, raw=True)  # the node moves its IDs itself
    try:
        runner = NodeRunner(bus, node)
        if not args.quiet:
            print(
                f"attica node: {kind.label} on {describe_bus(args)}, {args.rate:g} Hz, output bus load "
                f"{100 * node.bus_load:.1f} % of {args.bitrate} bit/s: ready",
                flush=True,
            )
            if cal is not None:
                print(f"attica node: {describe_calibration(cal, args.calibration)}", flush=True)
        with StopSignals() as stop:
            stats = runner.serve(stop=stop, count=args.count, idle_timeout=args.idle_timeout)
        print(f"attica node: stats: {stats.line(node.stats())}", flush=True)
    finally:
        bus.shutdown()
    return 0
