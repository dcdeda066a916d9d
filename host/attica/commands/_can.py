"""Options and helpers shared by the CAN subcommands (node, replay, monitor, verify).

Every CAN command takes ``--interface`` (default: python-can's configuration, else ``virtual``),
``--channel``, ``--can-config`` (a python-can config file), ``--can-context``, ``--fd`` and
``--id-offset`` (the node's CAN ID offset: :mod:`attica.can.idoffset`).
"""

from __future__ import annotations

import argparse
import signal
import threading
from pathlib import Path
from types import TracebackType
from typing import Any

import can

from attica.commands._common import (
    CliError,
    add_sim_arguments,
    check_data_or_sim,
    check_output_file,
    load_data,
    note_node_defaults,
    sim_value,
)
from attica.kinds import labels
from attica.settings import FilterKind

KINDS = labels()
"""Filter names the node knows (:mod:`attica.kinds`)."""

STREAM_DURATION = 10.0
"""Seconds simulated by the CAN commands when given no recording."""


def id_offset_type(text: str) -> int:
    """The argparse type of ``--id-offset``: decimal or 0x hex, within the node's range."""
    from attica.can.idoffset import IdOffsetError, parse_id_offset

    try:
        return parse_id_offset(text)
    except IdOffsetError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_id_offset_argument(p: Any, what: str) -> None:
    """``--id-offset N`` on a parser or argument group (default None: 0; ``what`` starts its help)."""
    p.add_argument(
        "--id-offset",
        type=id_offset_type,
        metavar="N",
        help=f"{what} (decimal or 0x hex, -256 .. 1279, a negative hex one as --id-offset=-0x20; "
        "default 0: the IDs of attica.dbc)",
    )


def id_offset(args: argparse.Namespace) -> int:
    """The ``--id-offset`` of the options (0 when not given)."""
    value = getattr(args, "id_offset", None)
    return int(value) if value is not None else 0


def add_bus_arguments(p: argparse.ArgumentParser) -> None:
    """``--interface --channel --can-config --can-context --fd --bitrate --data-bitrate --id-offset``."""
    g = p.add_argument_group("bus")
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
    add_id_offset_argument(
        g, "the node's CAN ID offset: every attica frame at DBC ID + N on the bus (attica-node --id-offset N)"
    )


def add_stream_arguments(p: argparse.ArgumentParser) -> None:
    """``--data``, the simulation options and ``--count``."""
    p.add_argument(
        "--data", help="recording (.npz in BROAD layout, .csv, BROAD .hdf5/.mat); default: simulate"
    )
    add_sim_arguments(p, duration=STREAM_DURATION)
    p.add_argument("--count", type=int, help="send only the first N samples")


def add_pacing_arguments(p: argparse.ArgumentParser) -> None:
    """``--realtime --speed --window -q``."""
    g = p.add_argument_group("pacing")
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


def add_write_argument(p: argparse.ArgumentParser, what: str) -> None:
    """``--write/-w FILE`` (repeatable): logs of the bus traffic."""
    p.add_argument(
        "--write",
        "-w",
        action="append",
        metavar="FILE",
        help=f"also write {what} to a log: .log (candump -L), .asc, .blf (repeatable)",
    )


def open_bus(args: argparse.Namespace, receive_own: bool = False, raw: bool = False) -> can.BusABC:
    """The bus of the command's options (an error opening it is a CliError).

    With ``--id-offset`` the bus moves the IDs (frames at the DBC's IDs for the caller), unless ``raw``:
    the bus as it is (for the in-process node, which applies its offset itself, and for the monitor).
    """
    from attica.can.bus import BusOpenError
    from attica.can.bus import open_bus as _open_bus

    try:
        return _open_bus(
            args.interface,
            args.channel,
            fd=args.fd,
            config_file=args.can_config,
            context=args.can_context,
            receive_own_messages=receive_own,
            id_offset=0 if raw else id_offset(args),
        )
    except BusOpenError as exc:
        raise CliError(str(exc)) from None


def describe_bus(args: argparse.Namespace) -> str:
    """``interface:channel`` of the command's options, and the ID offset when there is one."""
    from attica.can.bus import BusOpenError, resolve_config
    from attica.can.idoffset import offset_text

    try:
        text = resolve_config(
            args.interface, args.channel, fd=args.fd, config_file=args.can_config, context=args.can_context
        ).describe()
    except BusOpenError as exc:
        raise CliError(str(exc)) from None
    offset = id_offset(args)
    return f"{text}, attica ID offset {offset_text(offset)}" if offset else text


def check_stream_args(args: argparse.Namespace) -> None:
    """The stream options' errors, before any work."""
    check_data_or_sim(args)
    if args.count is not None and args.count <= 0:
        raise CliError("--count must be > 0")
    if getattr(args, "speed", 1.0) <= 0:
        raise CliError("--speed must be > 0")


def stream(args: argparse.Namespace) -> Any:
    """The :class:`attica.can.replay.ImuStream` of the options (``--count`` samples at most)."""
    from attica.can.replay import ImuStream

    if not args.data and args.count is not None and args.duration is None:  # simulate what is sent
        args.duration = args.count / sim_value(args, "rate") + 0.5
    note_node_defaults(args)
    rec = load_data(args)
    return ImuStream.from_recording(rec, args.count)


def log_paths(args: argparse.Namespace) -> list[Path]:
    """The ``--write`` logs, checked (suffix and directory) before any work."""
    from attica.can.logs import LOG_SUFFIXES

    out = []
    for item in getattr(args, "write", None) or []:
        path = Path(item)
        if path.suffix.lower() not in LOG_SUFFIXES:
            raise CliError(f"cannot write {path}: unknown log format; use {', '.join(LOG_SUFFIXES)}")
        out.append(check_output_file(path, "log"))
    return out


class StopSignals:
    """SIGINT/SIGTERM set an event (clean shutdown) instead of raising."""

    def __init__(self) -> None:
        self.event = threading.Event()
        self._old: list[Any] = []

    def __enter__(self) -> threading.Event:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old.append((sig, signal.signal(sig, lambda *_: self.event.set())))
        return self.event

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        for sig, old in self._old:
            signal.signal(sig, old)


def parse_kind(name: str) -> FilterKind:
    """A filter kind by name (CliError otherwise)."""
    try:
        return FilterKind.parse(name)
    except ValueError as exc:
        raise CliError(str(exc)) from None
