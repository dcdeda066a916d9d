"""``attica calibrate send FILE``: apply a calibration file to a running node over CAN, and verify it.

The calibration goes as one session (CAL_BEGIN, CAL_SET for fields 0..47, CAL_COMMIT), each command
acknowledged by ATT_CAL_ACK (:func:`attica.can.calibration.send_calibration`); a refusal names the
reason and leaves the node unchanged. ``--verify`` then resets the node's filter, replays a stream
(``--data`` or a simulation) and checks every output set bit for bit against the reference filter
with the same calibration (:func:`attica.can.verify.verify_live`). ``--id-offset N`` talks to a node
whose CAN IDs are the DBC's + N.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from attica.commands._can import (
    KINDS,
    add_bus_arguments,
    add_pacing_arguments,
    add_stream_arguments,
    check_stream_args,
    describe_bus,
    id_offset,
    open_bus,
    parse_kind,
    stream,
)
from attica.commands._common import CliError, describe_calibration, load_calibration

SEND_ONLY = (
    "verify", "with_node", "interface", "channel", "can_config", "can_context", "fd", "data", "count",
    "duration", "rate", "seed", "taps", "breaks", "realtime", "id_offset",
)  # fmt: skip
"""Options of ``calibrate send`` that the fits refuse (their defaults are None or False)."""

FIT_ONLY = ("output", "update", "plot", "field", "min_coverage", "gravity", "misalignment", "min_rest")
"""Options of the fits that ``calibrate send`` refuses."""


def add_send_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``attica calibrate send`` (bus, --verify, its stream, --with-node)."""
    add_bus_arguments(p)
    g = p.add_argument_group("send (calibrate send FILE)")
    g.add_argument(
        "--verify",
        action="store_true",
        help="after the commit, reset the node's filter, replay a stream and check its outputs bit for bit "
        "against the reference with the same calibration",
    )
    g.add_argument(
        "--with-node",
        action="store_true",
        help="run a C node in this process on the same bus (a demonstration without hardware)",
    )
    g.add_argument(
        "--filter", choices=KINDS, help="the --with-node node's filter (default mars); checked with --verify"
    )
    g.add_argument("--timeout", type=float, default=1.0, help="seconds to wait for each ATT_CAL_ACK")
    add_stream_arguments(p)
    add_pacing_arguments(p)


def check_mixed(args: argparse.Namespace) -> None:
    """Refuse options of the fits with ``send`` and options of ``send`` with the fits."""
    flag = {n: "--" + n.replace("_", "-") for n in (*SEND_ONLY, *FIT_ONLY, "filter")}
    if args.sensor == "send":
        given = [flag[n] for n in FIT_ONLY if getattr(args, n, None) is not None]
        if given:
            raise CliError(f"{', '.join(given)}: options of the fits, not of 'calibrate send'")
        if args.filter is not None and not (args.with_node or args.verify):
            raise CliError("--filter names the --with-node node's filter (or the one --verify expects)")
        return
    given = [flag[n] for n in (*SEND_ONLY, "filter") if getattr(args, n, None) not in (None, False)]
    if given:
        raise CliError(f"{', '.join(given)}: options of 'calibrate send', not of 'calibrate {args.sensor}'")


def run_send(args: argparse.Namespace) -> int:
    """``attica calibrate send FILE``."""
    from attica.can.calibration import CalibrationError, CalibrationRefusedError, send_calibration
    from attica.can.node import Node, NodeError
    from attica.can.runner import NodeRunner
    from attica.can.verify import NodeNotAnsweringError, reset_node, verify_live

    if not args.timeout > 0:
        raise CliError(f"--timeout must be > 0, got {args.timeout:g}")
    args.calibration = args.recording
    if not Path(args.calibration).exists():
        raise CliError(f"no such calibration file: {args.calibration}")
    cal = load_calibration(args)
    st = None
    if args.verify:
        check_stream_args(args)
        st = stream(args)
    elif args.data or args.count is not None:
        raise CliError("--data and --count give the stream of --verify; add --verify or drop them")
    node = None
    if args.with_node:
        rate = st.rate if st is not None else 285.714
        try:
            node = Node(
                parse_kind(args.filter or "mars"),
                sample_rate=rate,
                bitrate=args.bitrate,
                data_bitrate=args.data_bitrate if args.fd else 0,
                fd=args.fd,
                id_offset=id_offset(args),
            )
        except NodeError as exc:
            raise CliError(f"node settings refused: {exc}") from None
    bus = open_bus(args)
    node_bus = None
    status = 0
    try:
        service = None
        if node is not None:
            node_bus = open_bus(args, raw=True)  # the node moves its IDs itself
            service = NodeRunner(node_bus, node).service
        where = describe_bus(args) + (" (node in this process)" if node is not None else "")
        print(f"sending {args.calibration} to the node on {where}", flush=True)
        try:
            sent = send_calibration(bus, cal, timeout=args.timeout, service=service)
        except CalibrationRefusedError as exc:
            raise CliError(f"{args.calibration}: {exc}; nothing applied, the node runs unchanged") from None
        except CalibrationError as exc:
            raise CliError(f"{args.calibration}: {exc}; nothing applied") from None
        print(f"  {sent.line()}")
        print(f"  {describe_calibration(cal, args.calibration)}", flush=True)
        if st is not None:
            try:
                ans = reset_node(bus, timeout=max(args.timeout, 2.0), service=service)
            except NodeNotAnsweringError as exc:
                raise CliError(str(exc)) from None
            from attica.settings import FilterKind

            kind = FilterKind(ans.kind)
            if args.filter is not None and kind != parse_kind(args.filter):
                raise CliError(f"the node runs {kind.label}, not {args.filter}")
            print(f"verify: {len(st)} samples at {st.rate:g} Hz to the {kind.label} node", flush=True)
            try:
                rep = verify_live(
                    bus,
                    st,
                    kind,
                    fd=args.fd,
                    realtime=args.realtime,
                    speed=args.speed,
                    window=args.window,
                    reset=False,
                    progress=not args.quiet,
                    service=service,
                    calibration=cal,
                )
            except NodeNotAnsweringError as exc:
                raise CliError(str(exc)) from None
            for line in rep.lines():
                print(line)
            status = 0 if rep.ok else 1
    finally:
        if node_bus is not None:
            node_bus.shutdown()
        bus.shutdown()
    return status
