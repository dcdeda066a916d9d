"""The CAN subcommands of ``attica``: node, replay, monitor, verify.

- ``attica node``: the C node in-process on a python-can bus (virtual, udp_multicast, socketcan...).
  (On Linux SocketCAN the stand-alone ``build/attica-node`` does the same without Python.)
- ``attica replay``: send a simulated or recorded IMU stream as frames (real time or as fast as the node
  takes them).
- ``attica monitor``: candump-style view of a bus or a log, decoded with the DBC, with E2E checks, counter
  gaps, bus load; writes candump -L / .asc / .blf logs.
- ``attica verify``: replay a stream to a node and prove its outputs bit-exact against the numpy
  reference (or verify a recorded log of both directions).

Every command takes ``--interface`` (default: python-can's configuration, else ``virtual``),
``--channel``, ``--can-config`` (a python-can config file) and ``--fd``.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
from typing import Any

import can

from attica.settings import FilterKind

__all__ = ["add_subcommands"]


class _UserError(Exception):
    """Printed without traceback by the subcommands (exit status 2)."""


def _bus_args(sp: argparse.ArgumentParser) -> None:
    g = sp.add_argument_group("bus")
    g.add_argument(
        "--interface",
        "-i",
        help="python-can interface: virtual (default unless a python-can config names one), "
        "udp_multicast, socketcan",
    )
    g.add_argument(
        "--channel",
        "-c",
        help="channel: vcan0, a multicast group, a virtual bus name (default per interface)",
    )
    g.add_argument("--can-config", metavar="FILE", help="python-can configuration file to use")
    g.add_argument("--can-context", metavar="SECTION", help="section of the python-can configuration file")
    g.add_argument("--fd", action="store_true", help="CAN FD: IMU_FD in, ATT_OUT_FD out")
    g.add_argument("--bitrate", type=int, default=500_000, help="nominal bit/s (bus load; default 500000)")
    g.add_argument(
        "--data-bitrate", type=int, default=2_000_000, help="CAN FD data phase bit/s (default 2000000)"
    )


def _stream_args(sp: argparse.ArgumentParser) -> None:
    g = sp.add_argument_group("stream")
    g.add_argument("--data", help="recording (.npz in BROAD layout, or .csv); default: simulate")
    g.add_argument("--duration", type=float, default=10.0, help="seconds to simulate (default 10)")
    g.add_argument(
        "--rate", type=float, default=285.714, help="sample rate in Hz when simulating (default 285.714)"
    )
    g.add_argument("--seed", type=int, default=0, help="simulation seed (default 0)")
    g.add_argument("--taps", type=int, default=0, help="simulated taps")
    g.add_argument("--count", type=int, help="send only the first N samples")


def _pacing_args(sp: argparse.ArgumentParser) -> None:
    g = sp.add_argument_group("pacing")
    g.add_argument(
        "--realtime",
        action="store_true",
        help="send at the stream's sample rate (default: as fast as possible)",
    )
    g.add_argument("--speed", type=float, default=1.0, help="real-time speed factor (default 1)")
    g.add_argument(
        "--window",
        type=int,
        default=16,
        help="as fast as possible: most samples ahead of the node's reported steps (0 = no flow control)",
    )
    g.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def _open(args: argparse.Namespace, receive_own: bool = False) -> can.BusABC:
    from attica.can.bus import BusOpenError, open_bus

    try:
        return open_bus(
            args.interface,
            args.channel,
            fd=args.fd,
            config_file=args.can_config,
            context=args.can_context,
            receive_own_messages=receive_own,
        )
    except BusOpenError as exc:
        raise _UserError(str(exc)) from None


def _describe_bus(args: argparse.Namespace) -> str:
    from attica.can.bus import BusOpenError, resolve_config

    try:
        return resolve_config(
            args.interface, args.channel, fd=args.fd, config_file=args.can_config, context=args.can_context
        ).describe()
    except BusOpenError as exc:
        raise _UserError(str(exc)) from None


def _stream(args: argparse.Namespace) -> Any:
    from pathlib import Path

    from attica.can.replay import ImuStream
    from attica.data import load_recording
    from attica.sim import SimConfig, simulate

    if args.count is not None and args.count <= 0:
        raise _UserError("--count must be > 0")
    if args.data:
        path = Path(args.data)
        if not path.exists():
            raise _UserError(f"no such recording: {path}")
        try:
            rec = load_recording(path)
        except ValueError as exc:
            raise _UserError(f"{path}: {exc}") from None
    else:
        duration = args.duration if args.count is None else args.count / args.rate + 0.5
        rec = simulate(SimConfig(duration=duration, rate=args.rate, seed=args.seed, taps=args.taps))
    return ImuStream.from_recording(rec, args.count)


class _Stop:
    """SIGINT/SIGTERM set an event (clean shutdown) instead of raising."""

    def __init__(self) -> None:
        self.event = threading.Event()
        self._old: list[Any] = []

    def __enter__(self) -> threading.Event:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old.append((sig, signal.signal(sig, lambda *_: self.event.set())))
        return self.event

    def __exit__(self, *exc: object) -> None:
        for sig, old in self._old:
            signal.signal(sig, old)


# --- node -----------------------------------------------------------------------------------------


def cmd_node(args: argparse.Namespace) -> int:
    """``attica node``."""
    from attica.can.codec import Node, NodeError
    from attica.can.runner import NodeRunner

    try:
        kind = FilterKind.parse(args.filter)
    except (ValueError, KeyError):
        raise _UserError(f"unknown filter {args.filter!r}") from None
    try:
        node = Node(
            kind,
            sample_rate=args.rate,
            bitrate=args.bitrate,
            data_bitrate=args.data_bitrate if args.fd else 0,
            fd=args.fd,
            output_divider=args.output_divider,
            diag_divider=args.diag_divider,
        )
    except (NodeError, ValueError, TypeError) as exc:
        raise _UserError(f"node settings refused: {exc}") from None
    bus = _open(args)
    try:
        runner = NodeRunner(bus, node)
        if not args.quiet:
            print(
                f"attica node: {kind.label} on {_describe_bus(args)}, {args.rate:g} Hz, output bus load "
                f"{100 * node.bus_load:.1f} % of {args.bitrate} bit/s: ready",
                flush=True,
            )
        with _Stop() as stop:
            stats = runner.serve(stop=stop, count=args.count, idle_timeout=args.idle_timeout)
        print(f"attica node: stats: {stats.line(node.stats())}", flush=True)
    finally:
        bus.shutdown()
    return 0


# --- replay ---------------------------------------------------------------------------------------


def cmd_replay(args: argparse.Namespace) -> int:
    """``attica replay``."""
    from attica.can.replay import replay

    stream = _stream(args)
    bus = _open(args)
    try:
        if not args.quiet:
            how = "in real time" if args.realtime else "as fast as possible"
            print(
                f"replaying {len(stream)} samples at {stream.rate:g} Hz {how} on {_describe_bus(args)}",
                file=sys.stderr,
            )
        try:
            stats = replay(
                bus,
                stream,
                fd=args.fd,
                realtime=args.realtime,
                speed=args.speed,
                window=args.window,
                progress=not args.quiet,
            )
        except KeyboardInterrupt:
            print("attica replay: interrupted", file=sys.stderr)
            return 130
        print(stats.line())
    finally:
        bus.shutdown()
    return 0


# --- monitor --------------------------------------------------------------------------------------


def cmd_monitor(args: argparse.Namespace) -> int:
    """``attica monitor``."""
    from attica.can.monitor import Monitor, MonitorError, open_writer, read_log

    try:
        mon = Monitor(
            args.dbc, bitrate=args.bitrate, data_bitrate=args.data_bitrate, decode=not args.no_decode
        )
    except MonitorError as exc:
        raise _UserError(str(exc)) from None
    writers = []
    try:
        for path in args.write or []:
            writers.append(open_writer(path, channel=args.channel or "can0"))
    except MonitorError as exc:
        for w in writers:
            w.stop()
        raise _UserError(str(exc)) from None
    shown = 0
    out = sys.stdout

    def show(msg: can.Message) -> None:
        nonlocal shown
        line = mon.feed(msg)
        for w in writers:
            w.on_message_received(msg)
        if not args.summary_only and (args.max_lines is None or shown < args.max_lines):
            out.write(line + "\n")
            shown += 1

    try:
        if args.log:
            try:
                for i, msg in enumerate(read_log(args.log)):
                    if args.count is not None and i >= args.count:
                        break
                    show(msg)
            except MonitorError as exc:
                raise _UserError(str(exc)) from None
        else:
            bus = _open(args)
            try:
                t_end = time.monotonic() + args.duration if args.duration else None
                next_stats = time.monotonic() + args.stats_every if args.stats_every else None
                with _Stop() as stop:
                    while not stop.is_set():
                        if args.count is not None and mon.stats.frames >= args.count:
                            break
                        now = time.monotonic()
                        if t_end is not None and now >= t_end:
                            break
                        got = bus.recv(0.1)
                        if got is not None:
                            show(got)
                        if next_stats is not None and now >= next_stats:
                            next_stats = now + args.stats_every
                            print("-- " + mon.summary()[0], file=sys.stderr, flush=True)
            finally:
                bus.shutdown()
    finally:
        for w in writers:
            w.stop()
    out.flush()
    for line in mon.summary():
        print("-- " + line, file=sys.stderr if not args.summary_only else sys.stdout)
    return 0


# --- verify ---------------------------------------------------------------------------------------


def cmd_verify(args: argparse.Namespace) -> int:
    """``attica verify``."""
    from attica.can.codec import Node, NodeError
    from attica.can.monitor import Monitor, MonitorError, read_log
    from attica.can.runner import NodeRunner
    from attica.can.verify import NodeNotAnsweringError, frames_of, verify_frames, verify_live

    kind = FilterKind.parse(args.filter)
    if args.log:
        try:
            frames = frames_of(read_log(args.log))
        except MonitorError as exc:
            raise _UserError(str(exc)) from None
        rep = verify_frames(
            frames, kind, args.rate, fd=True if args.fd else None, output_divider=args.output_divider
        )
        print(f"{args.log}: {rep.frames_received} frames")
        for line in rep.lines():
            print(line)
        return 0 if rep.ok else 1

    stream = _stream(args)
    bus = _open(args)
    runner: NodeRunner | None = None
    node_bus = None
    mon = Monitor(bitrate=args.bitrate, data_bitrate=args.data_bitrate) if args.show else None
    shown = 0

    def on_message(msg: can.Message) -> None:
        nonlocal shown
        if mon is not None and shown < args.show:
            print("   " + mon.feed(msg), flush=True)
            shown += 1

    try:
        if args.with_node:
            try:
                node = Node(
                    kind,
                    sample_rate=stream.rate,
                    bitrate=args.bitrate,
                    data_bitrate=args.data_bitrate if args.fd else 0,
                    fd=args.fd,
                    output_divider=args.output_divider,
                )
            except NodeError as exc:
                raise _UserError(f"node settings refused: {exc}") from None
            node_bus = _open(args)
            runner = NodeRunner(node_bus, node)
        print(
            f"verify: {len(stream)} samples at {stream.rate:g} Hz to the {kind.label} node "
            f"on {_describe_bus(args)}" + (" (node in this process)" if args.with_node else ""),
            flush=True,
        )
        try:
            rep = verify_live(
                bus,
                stream,
                kind,
                fd=args.fd,
                output_divider=args.output_divider,
                realtime=args.realtime,
                speed=args.speed,
                window=args.window,
                reset=not args.no_reset,
                progress=not args.quiet,
                on_message=on_message if mon is not None else None,
                service=runner.service if runner is not None else None,
            )
        except NodeNotAnsweringError as exc:
            raise _UserError(str(exc)) from None
        except ValueError as exc:
            raise _UserError(str(exc)) from None
    finally:
        if node_bus is not None:
            node_bus.shutdown()
        bus.shutdown()
    for line in rep.lines():
        print(line)
    return 0 if rep.ok else 1


# --- registration ---------------------------------------------------------------------------------


def _wrap(fn: Any) -> Any:
    def run(args: argparse.Namespace) -> int:
        try:
            return int(fn(args))
        except _UserError as exc:
            print(f"attica {args.command}: error: {exc}", file=sys.stderr)
            return 2

    return run


def add_subcommands(sub: Any) -> None:
    """Register ``node``, ``replay``, ``monitor`` and ``verify`` on the ``attica`` subparsers."""
    kinds = [k.label for k in FilterKind if k.label != "none"]

    sp = sub.add_parser(
        "node", help="run the C node in-process on a CAN bus (virtual, udp_multicast, socketcan)"
    )
    _bus_args(sp)
    sp.add_argument("--filter", default="ars", choices=kinds, help="filter kind (default ars)")
    sp.add_argument(
        "--rate", type=float, default=285.714, help="sample rate = 1/dt of the filter (default 285.714)"
    )
    sp.add_argument("--output-divider", type=int, default=1, help="send outputs every Nth step (default 1)")
    sp.add_argument("--diag-divider", type=int, default=16, help="ATT_DIAG every Nth output set (0 = never)")
    sp.add_argument("--count", type=int, help="stop after N filter steps")
    sp.add_argument("--idle-timeout", type=float, help="stop after this many seconds without a frame")
    sp.add_argument("-q", "--quiet", action="store_true", help="no start-up line")
    sp.set_defaults(func=_wrap(cmd_node))

    sp = sub.add_parser("replay", help="send a simulated or recorded IMU stream as CAN frames")
    _bus_args(sp)
    _stream_args(sp)
    _pacing_args(sp)
    sp.set_defaults(func=_wrap(cmd_replay))

    sp = sub.add_parser("monitor", help="candump-style view of a bus or log, decoded with the DBC")
    _bus_args(sp)
    sp.add_argument("--log", help="read this log (.log candump -L, .asc, .blf) instead of a bus")
    sp.add_argument("--dbc", help="DBC file (default firmware/can/attica.dbc)")
    sp.add_argument(
        "--write", "-w", action="append", metavar="FILE", help="also write a log (.log, .asc, .blf)"
    )
    sp.add_argument("--count", type=int, help="stop after N frames")
    sp.add_argument("--duration", type=float, help="stop after this many seconds")
    sp.add_argument("--max-lines", type=int, help="print at most N frame lines (counting goes on)")
    sp.add_argument("--summary-only", action="store_true", help="print only the summary")
    sp.add_argument("--no-decode", action="store_true", help="candump text and checks only")
    sp.add_argument("--stats-every", type=float, default=0.0, help="print a stats line every S seconds (bus)")
    sp.set_defaults(func=_wrap(cmd_monitor))

    sp = sub.add_parser("verify", help="replay a stream to a node and check its outputs bit for bit")
    _bus_args(sp)
    _stream_args(sp)
    _pacing_args(sp)
    sp.add_argument("--filter", default="ars", choices=kinds, help="the node's filter (default ars)")
    sp.add_argument("--output-divider", type=int, default=1, help="the node's output divider (default 1)")
    sp.add_argument("--no-reset", action="store_true", help="do not reset the node first (it must be fresh)")
    sp.add_argument("--with-node", action="store_true", help="run the node in this process on the same bus")
    sp.add_argument(
        "--show", type=int, default=0, metavar="N", help="print the first N received frames, decoded"
    )
    sp.add_argument("--log", help="verify a recorded log of both directions instead of a live bus")
    sp.set_defaults(func=_wrap(cmd_verify))
