"""``attica view``: the attitude, the node and the bus on a local web page (docs/view.md).

One process serves the page on this machine (``--host 127.0.0.1`` and a free port unless ``--port`` is
given; the URL is printed) and feeds it from one source:

- a live bus (default): python-can's configuration or ``--interface virtual | socketcan |
  udp_multicast``, ``--channel``; a bus that fails is shown and opened again;
- ``--log FILE``: a log (.log candump -L, .asc, .blf) played back in real time times ``--speed``,
  with pause, seek and speed on the page;
- ``--demo``: the simulator through the C node (``--filter``, default mars) on a bus (virtual by
  default), in real time, the true attitude as a ghost; ``--data REC`` the same with a recording.

The page shows the body over an earth grid (``--convention`` ENU, NED or NWU: the node's), roll, pitch
and yaw, rolling plots (Euler angles, gyro bias, |a| and |m| against g and the field), the status
flags, the bus health (frames/s, bus load, E2E CRC and counter errors, lost sets, latency), the node's
DIAG counters, and sends the node's commands (reset, filter kind, convention) after a confirmation
(``--read-only``: none). ``--foxglove [PORT]`` also serves Foxglove's live WebSocket protocol.
"""

from __future__ import annotations

import argparse
import asyncio
import ipaddress
import logging
import signal
import sys
from typing import Any

from attica.commands._can import (
    KINDS,
    add_bus_arguments,
    id_offset,
    parse_kind,
)
from attica.commands._common import CliError, add_sim_arguments, check_data_or_sim, sim_options_given

NAME = "view"
HELP = "the attitude, node and bus on a local web page: live bus, log playback or --demo (simulator)"

EXTRA = "pip install 'attica[view]'"


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``attica view``."""
    add_bus_arguments(p)
    g = p.add_argument_group("source (default: the live bus)")
    src = g.add_mutually_exclusive_group()
    src.add_argument(
        "--demo", action="store_true", help="the simulator through the C node on the bus (no hardware needed)"
    )
    src.add_argument(
        "--data", metavar="REC", help="a recording (.npz, .csv ...) through the C node, like --demo"
    )
    src.add_argument("--log", metavar="FILE", help="play back a log (.log candump -L, .asc, .blf)")
    g.add_argument("--filter", choices=KINDS, help="--demo / --data: the C node's filter (default mars)")
    g.add_argument(
        "--speed", type=float, help="--log / --demo / --data: playback speed (default 1: real time)"
    )
    g.add_argument("--paused", action="store_true", help="--log / --demo / --data: start paused")
    g.add_argument("--loop", action="store_true", help="--log: start again at the end (--demo always loops)")
    add_sim_arguments(p, duration=120.0)
    w = p.add_argument_group("page")
    w.add_argument(
        "--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine)"
    )
    w.add_argument("--port", type=int, default=0, help="port (default 0: a free one, printed)")
    w.add_argument("--fps", type=float, default=30.0, help="updates per second at most (default 30)")
    w.add_argument(
        "--convention",
        choices=("ENU", "NED", "NWU"),
        type=str.upper,
        default="ENU",
        help="earth frame of the node's outputs (default ENU; a convention command from the page changes it)",
    )
    w.add_argument("--read-only", action="store_true", help="no node commands from the page")
    w.add_argument(
        "--mag-ref",
        type=float,
        metavar="UT",
        help="reference |m| of the plot, uT (default: the simulated field with --demo, else none)",
    )
    w.add_argument(
        "--foxglove",
        nargs="?",
        type=int,
        const=8765,
        metavar="PORT",
        help="also serve Foxglove's live WebSocket protocol on PORT (default 8765; needs attica[foxglove])",
    )
    w.add_argument("--open", action="store_true", help="open the page in the default browser")
    w.add_argument("--exit-after", type=float, metavar="S", help="stop after S seconds (scripts, tests)")
    w.add_argument("-q", "--quiet", action="store_true", help="log warnings and errors only")
    w.add_argument("-v", "--verbose", action="store_true", help="log every page connection and command")


class _Formatter(logging.Formatter):
    def format(self, record: logging.LogRecord) -> str:
        text = record.getMessage()
        if record.exc_info:
            text += "\n" + self.formatException(record.exc_info)
        if record.levelno >= logging.WARNING:
            return f"attica view: {record.levelname.lower()}: {text}"
        return f"attica view: {text}"


def _logging(args: argparse.Namespace) -> None:
    log = logging.getLogger("attica.view")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_Formatter())
    log.handlers[:] = [handler]
    log.propagate = False
    log.setLevel(logging.WARNING if args.quiet else logging.DEBUG if args.verbose else logging.INFO)
    logging.getLogger("websockets").setLevel(logging.WARNING)


def _check(args: argparse.Namespace) -> None:
    playback = args.demo or args.data or args.log
    if not 0 <= args.port <= 65535:
        raise CliError(f"--port must be within 0 .. 65535, got {args.port}")
    if args.foxglove is not None and not 0 <= args.foxglove <= 65535:
        raise CliError(f"--foxglove port must be within 0 .. 65535, got {args.foxglove}")
    if not 1 <= args.fps <= 120:
        raise CliError(f"--fps must be within 1 .. 120, got {args.fps:g}")
    if args.exit_after is not None and not args.exit_after > 0:
        raise CliError(f"--exit-after must be > 0 s, got {args.exit_after:g}")
    if args.speed is not None and not 0.01 <= args.speed <= 1000:
        raise CliError(f"--speed must be within 0.01 .. 1000, got {args.speed:g}")
    if not playback:
        given = [
            o for o, v in (("--speed", args.speed), ("--paused", args.paused), ("--loop", args.loop)) if v
        ]
        if given:
            raise CliError(f"{', '.join(given)}: a live bus plays as it comes; use them with --log or --demo")
    if args.loop and not args.log:
        raise CliError("--loop is for --log (--demo and --data always loop)")
    if args.filter and not (args.demo or args.data):
        raise CliError("--filter chooses the C node of --demo / --data; a live node has its own")
    if args.log:
        from pathlib import Path

        bus = [
            o
            for o, v in (("--interface", args.interface), ("--channel", args.channel), ("--fd", args.fd))
            if v
        ]
        if bus:
            raise CliError(f"{', '.join(bus)}: --log plays a file, not a bus")
        if not Path(args.log).is_file():
            raise CliError(f"no such log file: {args.log}")
    if not args.demo:
        sim = sim_options_given(args)
        if sim and not args.data:
            raise CliError(f"{', '.join(sim)} describe the simulation of --demo")
    check_data_or_sim(args)
    if args.mag_ref is not None and not args.mag_ref > 0:
        raise CliError(f"--mag-ref must be > 0 uT, got {args.mag_ref:g}")


def _bus_config(args: argparse.Namespace) -> Any:
    from attica.can.bus import BusOpenError, resolve_config

    try:
        return resolve_config(
            args.interface,
            args.channel,
            fd=args.fd,
            bitrate=None,
            config_file=args.can_config,
            context=args.can_context,
        )
    except BusOpenError as exc:
        raise CliError(str(exc)) from None


def _source(args: argparse.Namespace) -> tuple[Any, float | None]:
    """The source of the options and the |m| reference it brings."""
    from attica.commands._common import load_data, note_node_defaults, sim_config
    from attica.view.demo import ImuSource
    from attica.view.playback import LogSource
    from attica.view.sources import BusSource, SourceError

    speed = args.speed if args.speed is not None else 1.0
    if args.log:
        return LogSource(args.log, speed=speed, paused=args.paused, loop=args.loop), None
    cfg = _bus_config(args)
    if not (args.demo or args.data):
        return BusSource(cfg, id_offset=id_offset(args)), None
    kind = parse_kind(args.filter or "mars")
    m_ref = None
    if args.demo:
        from attica.sim import simulate_with_truth

        sc = sim_config(args)
        note_node_defaults(args)
        try:
            rec, _ = simulate_with_truth(sc)
        except ValueError as exc:
            raise CliError(f"simulation: {exc} (use a longer --duration or fewer --breaks)") from None
        name = f"simulation (seed {sc.seed}, {sc.duration:g} s at {sc.rate:g} Hz)"
        m_ref = float(sc.mag_field)
    else:
        rec = load_data(args)
        name = str(args.data)
    try:
        source = ImuSource(
            rec.gyr,
            rec.acc,
            rec.mag,
            rec.rate,
            cfg,
            kind=kind.label,
            truth=rec.quat_true,
            name=name,
            fd=args.fd,
            bitrate=args.bitrate,
            data_bitrate=args.data_bitrate,
            id_offset=id_offset(args),
            speed=speed,
            paused=args.paused,
            source_kind="demo" if args.demo else "recording",
        )
    except (SourceError, ValueError) as exc:
        raise CliError(f"the C node: {exc}") from None
    return source, m_ref


async def _serve(server: Any, exit_after: float | None) -> None:
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            loop.add_signal_handler(sig, stop.set)
        except (NotImplementedError, RuntimeError):  # not the main thread, or no signals here
            pass
    if exit_after is not None:
        loop.call_later(exit_after, stop.set)
    await server.serve(stop)


def run(args: argparse.Namespace) -> int:
    """``attica view``."""
    _check(args)
    try:
        from attica.view.server import ViewServer
    except ImportError as exc:
        raise CliError(f"attica view needs the websockets package ({exc}): {EXTRA}") from None
    from attica.view.sources import SourceError
    from attica.view.state import ViewState

    _logging(args)
    log = logging.getLogger("attica.view")
    try:
        if ipaddress.ip_address(args.host).is_loopback is False:
            log.warning(
                "listening on %s: the page and its node commands are open to the network "
                "(--read-only turns the commands off)",
                args.host,
            )
    except ValueError:  # a host name: assume it is not only this machine
        if args.host != "localhost":
            log.warning("listening on %s: the page may be reachable from the network", args.host)
    source, m_ref = _source(args)
    state = ViewState(
        bitrate=args.bitrate,
        data_bitrate=args.data_bitrate,
        id_offset=0 if args.log else id_offset(args),
        convention=args.convention,
        m_ref=args.mag_ref if args.mag_ref is not None else m_ref,
    )
    bridge = None
    if args.foxglove is not None:
        from attica.view.foxglove import FoxgloveBridge, FoxgloveMissingError

        try:
            bridge = FoxgloveBridge(args.host, args.foxglove)
        except FoxgloveMissingError as exc:
            raise CliError(str(exc)) from None
        except Exception as exc:  # the SDK's own error for a port in use and the like
            raise CliError(f"the Foxglove bridge could not start on port {args.foxglove}: {exc}") from None
    server = ViewServer(
        state,
        source,
        host=args.host,
        port=args.port,
        fps=args.fps,
        read_only=args.read_only,
        foxglove=bridge,
    )
    try:
        try:
            source.start(state)
        except SourceError as exc:
            raise CliError(str(exc)) from None

        async def announce() -> None:
            while server.port == 0 or not server.ready.is_set():
                await asyncio.sleep(0.01)
            print(f"attica view: {server.url}  ({source.describe()}); Ctrl-C stops", flush=True)
            if bridge is not None:
                print(f"attica view: Foxglove: open connection {bridge.url}", flush=True)
            if args.open:
                import webbrowser

                webbrowser.open(server.url)

        async def main() -> None:
            task = asyncio.create_task(announce())
            try:
                await _serve(server, args.exit_after)
            finally:
                task.cancel()

        try:
            asyncio.run(main())
        except OSError as exc:
            raise CliError(f"cannot serve on {args.host}:{args.port}: {exc}") from None
    finally:
        source.stop()
        if bridge is not None:
            bridge.stop()
    h = state.snapshot(record=False)["health"]
    print(
        f"attica view: {h['frames']} frames seen, crc errors {h['crc_errors']}, counter gaps "
        f"{h['counter_gaps']}, dropped {h['dropped']}; {server.connections} page connections",
        flush=True,
    )
    return 0
