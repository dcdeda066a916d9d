"""``attica verify``: replay a stream to a node and prove its outputs bit-exact against the reference.

Live: sends the stream (``--with-node`` runs the C node in this process on the same bus), collects
every output set and compares it bit for bit with the numpy reference fed the samples the node got.
``--log``: the same proof from a recorded log of both directions. ``--write`` logs this session's
traffic, both directions, so that ``attica verify --log`` and ``attica monitor --log`` can check it.
``--id-offset N``: the node's CAN IDs are the DBC's + N (on the bus, in the logs and for ``--with-node``).
"""

from __future__ import annotations

import argparse

import can

from attica.commands._can import (
    KINDS,
    add_bus_arguments,
    add_pacing_arguments,
    add_stream_arguments,
    add_write_argument,
    check_stream_args,
    describe_bus,
    id_offset,
    log_paths,
    open_bus,
    parse_kind,
    stream,
)
from attica.commands._common import (
    CliError,
    add_calibration_argument,
    describe_calibration,
    filter_settings,
    load_calibration,
    parse_overrides,
)

NAME = "verify"
HELP = "replay a stream to a node (or read a log) and check every output set bit for bit"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``attica verify``."""
    add_bus_arguments(p)
    add_stream_arguments(p)
    add_pacing_arguments(p)
    p.add_argument("--filter", default="ars", choices=KINDS, help="the node's filter (default ars)")
    p.add_argument("--output-divider", type=int, default=1, help="the node's output divider (default 1)")
    p.add_argument(
        "--set",
        action="append",
        metavar="NAME=VALUE",
        help="a setting of the node's init filter settings, as `attica node --set` started it (repeatable; "
        "the reference uses them, and so does the --with-node node; e.g. hard_iron_tau=60: its "
        "ATT_MAG_OFFSET frames are checked too)",
    )
    p.add_argument("--no-reset", action="store_true", help="do not reset the node first (it must be fresh)")
    p.add_argument("--with-node", action="store_true", help="run the node in this process on the same bus")
    p.add_argument(
        "--show", type=int, default=0, metavar="N", help="print the first N received frames, decoded"
    )
    add_calibration_argument(p, "the reference: the node's calibration (and the --with-node node's)")
    p.add_argument("--log", help="verify a recorded log of both directions instead of a live bus")
    add_write_argument(p, "the frames sent and received (live)")


def _verify_log(args: argparse.Namespace) -> int:
    from attica.can.codec import MSG_LEN
    from attica.can.idoffset import (
        from_bus,
        guess_id_offset,
        offset_text,
        option_text,
        silent_node_hint,
        to_bus,
    )
    from attica.can.logs import LogError, read_log
    from attica.can.verify import frames_of, verify_frames

    if args.write:
        raise CliError("--write logs a live session; with --log there is nothing new to write")
    kind = parse_kind(args.filter)
    cal = load_calibration(args)
    rate = args.rate if args.rate is not None else 285.714
    overrides = parse_overrides(kind, args.set or [])
    settings = filter_settings(kind, rate, overrides) if overrides else None
    offset = id_offset(args)
    try:
        msgs = [from_bus(m, offset) for m in read_log(args.log)]
    except LogError as exc:
        raise CliError(str(exc)) from None
    frames = frames_of(msgs)
    if frames.shape[0] and not any(int(i) in MSG_LEN for i in set(frames["id"].tolist())):
        raise CliError(f"{args.log}: {frames.shape[0]} frames, {silent_node_hint(offset, msgs[:1000])}")
    rep = verify_frames(
        frames,
        kind,
        rate,
        fd=True if args.fd else None,
        output_divider=args.output_divider,
        settings=settings,
        calibration=cal,
    )
    where = f", attica ID offset {offset_text(offset)}" if offset else ""
    print(f"{args.log}: {rep.frames_received} frames{where}")
    if cal is not None:
        print(f"  reference: {describe_calibration(cal, args.calibration)}")
    for line in rep.lines():
        print(line)
    guess = None if rep.ok else guess_id_offset(to_bus(m, offset) for m in msgs[:1000])
    if guess is not None and guess != offset:
        print(f"  the log's frames are attica frames at ID offset {offset_text(guess)}: {option_text(guess)}")
    return 0 if rep.ok else 1


def run(args: argparse.Namespace) -> int:
    """``attica verify``."""
    from attica.can.idoffset import to_bus
    from attica.can.logs import LogError, LogTee
    from attica.can.monitor import Monitor
    from attica.can.node import Node, NodeError
    from attica.can.runner import NodeRunner
    from attica.can.verify import NodeNotAnsweringError, verify_live

    if args.output_divider < 1:
        raise CliError("--output-divider must be >= 1")
    if args.log:
        return _verify_log(args)
    kind = parse_kind(args.filter)
    check_stream_args(args)
    paths = log_paths(args)
    cal = load_calibration(args)
    overrides = parse_overrides(kind, args.set or [])  # a mistyped name before any work
    st = stream(args)
    offset = id_offset(args)
    settings = filter_settings(kind, st.rate, overrides) if overrides else None  # refusals name the field
    node = None
    if args.with_node:
        try:
            node = Node(
                kind,
                sample_rate=st.rate,
                bitrate=args.bitrate,
                data_bitrate=args.data_bitrate if args.fd else 0,
                fd=args.fd,
                output_divider=args.output_divider,
                calibration=cal,
                id_offset=offset,
                **overrides,
            )
        except NodeError as exc:
            raise CliError(f"node settings refused: {exc}") from None
    try:
        tee = LogTee(paths, channel=args.channel or "can0", id_offset=offset)
    except LogError as exc:
        raise CliError(str(exc)) from None
    mon = (
        Monitor(bitrate=args.bitrate, data_bitrate=args.data_bitrate, id_offset=offset) if args.show else None
    )
    shown = 0

    def on_message(msg: can.Message) -> None:
        nonlocal shown
        tee.received(msg)
        if mon is not None and shown < args.show:
            print("   " + mon.feed(to_bus(msg, offset)), flush=True)  # as on the bus
            shown += 1

    bus = open_bus(args)
    node_bus = None
    try:
        runner = None
        if node is not None:
            node_bus = open_bus(args, raw=True)  # the node moves its IDs itself
            runner = NodeRunner(node_bus, node)
        print(
            f"verify: {len(st)} samples at {st.rate:g} Hz to the {kind.label} node "
            f"on {describe_bus(args)}" + (" (node in this process)" if node is not None else ""),
            flush=True,
        )
        if cal is not None:
            print(f"  reference: {describe_calibration(cal, args.calibration)}", flush=True)
        try:
            rep = verify_live(
                bus,
                st,
                kind,
                fd=args.fd,
                output_divider=args.output_divider,
                realtime=args.realtime,
                speed=args.speed,
                window=args.window,
                reset=not args.no_reset,
                progress=not args.quiet,
                on_message=on_message if (mon is not None or tee) else None,
                service=runner.service if runner is not None else None,
                on_send=tee.sent if tee else None,
                settings=settings,
                calibration=cal,
            )
        except (NodeNotAnsweringError, ValueError) as exc:
            raise CliError(str(exc)) from None
    finally:
        if node_bus is not None:
            node_bus.shutdown()
        bus.shutdown()
        tee.close()
    for line in rep.lines():
        print(line)
    if tee:
        print(f"  wrote {tee.frames} frames to {', '.join(str(p) for p in paths)}")
    return 0 if rep.ok else 1
