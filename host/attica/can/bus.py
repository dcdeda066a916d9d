"""Open a python-can bus for the attica CAN tools, with clear errors.

Interfaces we support and test (any other python-can interface works too, untested):

- ``virtual`` (the default): python-can's in-process virtual bus. Every bus object opened on the same
  channel in the same Python process sees the frames the others send; nothing leaves the process.
  Default channel ``attica``.
- ``udp_multicast``: python-can's UDP multicast bus; processes on the same host (or LAN) talking
  through a multicast group. Default channel: python-can's IPv4 group ``239.74.163.2`` (port 43113).
  Needs the ``msgpack`` package (``python-can[multicast]``).
- ``socketcan``: Linux SocketCAN (``vcan0``, ``can0``...); a channel is required.

When the user names no interface, python-can's configuration is honoured (``can.util.load_config``:
``can.rc``, the ``CAN_INTERFACE`` / ``CAN_CHANNEL`` / ``CAN_BITRATE`` environment variables, the files
``~/can.conf``, ``/etc/can.conf``, ``~/.can``, ``~/.canrc``, or a file given with ``--can-config``);
only when none of them names an interface is ``virtual`` used.

``open_bus(..., id_offset=N)`` talks to a node whose CAN IDs are moved by N
(:class:`attica.can.idoffset.OffsetBus`): the frames sent and received are at the DBC's IDs.
:class:`BusReader` takes a bus's frames off its socket in a thread (the monitor's receive path).
"""

from __future__ import annotations

import os
import queue
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can
import can.util

from attica.can.idoffset import IdOffsetError, OffsetBus, check_id_offset

__all__ = [
    "BusReader",
    "DEFAULT_CHANNELS",
    "DEFAULT_INTERFACE",
    "BusConfig",
    "BusOpenError",
    "open_bus",
    "resolve_config",
]

DEFAULT_INTERFACE = "virtual"
"""The interface used when neither the user nor a python-can config file names one."""

DEFAULT_CHANNELS: dict[str, str] = {
    "virtual": "attica",
    "udp_multicast": "239.74.163.2",
}
"""Channel used per interface when none is given (socketcan has none: the user must name it)."""


class BusOpenError(Exception):
    """A bus could not be opened (bad interface, channel, configuration file or missing package)."""


@dataclass
class BusConfig:
    """Everything needed to open a bus: the resolved interface, channel and extra keyword arguments."""

    interface: str
    channel: str
    fd: bool = False
    source: str = "default"
    kwargs: dict[str, Any] = field(default_factory=dict)

    def describe(self) -> str:
        """Short text such as ``socketcan:vcan0 (FD)``."""
        return f"{self.interface}:{self.channel}{' (FD)' if self.fd else ''}"


def _configured_interface(path: str | None, context: str | None) -> tuple[str | None, str]:
    """The interface named by python-can's configuration sources, and which source named it."""
    rc = dict(can.rc)
    for key in ("interface", "bustype"):
        if rc.get(key):
            return str(rc[key]), "can.rc"
    env = can.util.load_environment_config(context)
    if env.get("interface"):
        return str(env["interface"]), "environment (CAN_INTERFACE)"
    for section in ([context] if context else []) + ["default"]:
        cfg = can.util.load_file_config(path, section)
        value = cfg.get("interface") or cfg.get("bustype")
        if value:
            where = path if path else "python-can config file (" + ", ".join(can.util.CONFIG_FILES) + ")"
            return value, str(where)
    return None, "default"


def resolve_config(
    interface: str | None = None,
    channel: str | None = None,
    *,
    fd: bool = False,
    bitrate: int | None = None,
    data_bitrate: int | None = None,
    config_file: str | os.PathLike[str] | None = None,
    context: str | None = None,
) -> BusConfig:
    """Work out which bus to open without opening it.

    Parameters
    ----------
    interface
        python-can interface name; ``None`` = python-can's configuration, else ``virtual``.
    channel
        Channel (``vcan0``, a multicast group, a virtual channel name); ``None`` = the configured or
        default channel of the interface.
    fd
        Open the bus for CAN FD frames.
    bitrate, data_bitrate
        Passed on for interfaces that use them (real hardware); ignored by virtual buses.
    config_file
        A python-can configuration file to read instead of the default locations.
    context
        Section of the configuration file (default ``[default]``).

    Raises
    ------
    BusOpenError
        Unknown interface, missing configuration file, or socketcan without a channel.

    """
    path: str | None = None
    if config_file is not None:
        p = Path(config_file)
        if not p.is_file():
            raise BusOpenError(f"python-can configuration file not found: {p}")
        path = str(p)
    source = "command line"
    extra: dict[str, Any] = {}
    if interface is None:
        named, source = _configured_interface(path, context)
        if named is not None:
            try:
                cfg = dict(can.util.load_config(path=path, context=context))
            except (can.CanInterfaceNotImplementedError, ValueError, TypeError) as exc:
                raise BusOpenError(f"bad python-can configuration in {source}: {exc}") from None
            interface = str(cfg.pop("interface"))
            cfg_channel = cfg.pop("channel", None)
            if channel is None and cfg_channel is not None:
                channel = str(cfg_channel)
            extra = {k: v for k, v in cfg.items() if v is not None}
        else:
            interface = DEFAULT_INTERFACE
    if interface not in can.VALID_INTERFACES:
        raise BusOpenError(
            f"unknown CAN interface {interface!r} (from {source}); "
            "try virtual, udp_multicast or socketcan "
            f"(python-can knows: {', '.join(sorted(can.VALID_INTERFACES))})"
        )
    if channel is None:
        if interface not in DEFAULT_CHANNELS:
            raise BusOpenError(f"interface {interface} needs a channel (e.g. --channel vcan0)")
        channel = DEFAULT_CHANNELS[interface]
    if bitrate is not None:
        extra["bitrate"] = bitrate
    if data_bitrate is not None:
        extra["data_bitrate"] = data_bitrate
    if "fd" in extra:
        fd = fd or bool(extra.pop("fd"))
    return BusConfig(interface=interface, channel=channel, fd=fd, source=source, kwargs=extra)


def open_bus(
    interface: str | None = None,
    channel: str | None = None,
    *,
    fd: bool = False,
    bitrate: int | None = None,
    data_bitrate: int | None = None,
    config_file: str | os.PathLike[str] | None = None,
    context: str | None = None,
    receive_own_messages: bool = False,
    id_offset: int = 0,
) -> can.BusABC:
    """Open a bus (see :func:`resolve_config` for the parameters).

    ``id_offset``: the node's CAN ID offset; not 0: the bus is an :class:`~attica.can.idoffset.OffsetBus`
    (frames sent get + offset, frames received - offset, so the caller sees the DBC's IDs).

    Raises
    ------
    BusOpenError
        With a message that says what to fix (no such device, msgpack missing, bad config, an ID
        offset out of range...).

    """
    cfg = resolve_config(
        interface,
        channel,
        fd=fd,
        bitrate=bitrate,
        data_bitrate=data_bitrate,
        config_file=config_file,
        context=context,
    )
    if id_offset:
        try:
            check_id_offset(id_offset)
        except IdOffsetError as exc:
            raise BusOpenError(str(exc)) from None
    bus = open_config(cfg, receive_own_messages=receive_own_messages)
    return OffsetBus(bus, id_offset) if id_offset else bus


def open_config(cfg: BusConfig, *, receive_own_messages: bool = False) -> can.BusABC:
    """Open the bus described by a :class:`BusConfig`."""
    kwargs = dict(cfg.kwargs)
    if cfg.interface in ("virtual", "udp_multicast", "socketcan"):
        # these only take the options below; bitrates belong to the (virtual) link, not the socket
        kwargs.pop("bitrate", None)
        kwargs.pop("data_bitrate", None)
    if cfg.interface == "virtual" and cfg.fd:
        kwargs["protocol"] = can.CanProtocol.CAN_FD
    try:
        bus = can.Bus(
            interface=cfg.interface,
            channel=cfg.channel,
            fd=cfg.fd,
            receive_own_messages=receive_own_messages if cfg.interface != "udp_multicast" else False,
            **kwargs,
        )
    except can.CanInterfaceNotImplementedError as exc:
        hint = ""
        if "msgpack" in str(exc):
            hint = " (udp_multicast needs the msgpack package: pip install 'python-can[multicast]')"
        raise BusOpenError(f"cannot open {cfg.describe()}: {exc}{hint}") from None
    except (can.CanError, OSError, ValueError, TypeError) as exc:
        hint = ""
        text = str(exc)
        if cfg.interface == "socketcan" and "No such device" in text:
            hint = (
                f" (no SocketCAN interface {cfg.channel!r}; create one with: ip link add dev {cfg.channel} "
                f"type vcan && ip link set up {cfg.channel})"
            )
        elif cfg.interface == "socketcan" and "Address family not supported" in text:
            hint = " (this kernel has no SocketCAN: load it with modprobe can-raw vcan, or use udp_multicast)"
        raise BusOpenError(f"cannot open {cfg.describe()}: {text}{hint}") from None
    if cfg.interface == "udp_multicast":
        _grow_receive_buffer(bus)
        if not receive_own_messages:
            return EchoFilteredBus(bus, UDP_CHANNEL_NAME)
    return bus


UDP_RECEIVE_BUFFER = 8 << 20
"""Bytes asked for the udp_multicast socket's receive buffer (the kernel caps it at net.core.rmem_max
unless we may force it): every datagram of the group, our own echoes included, lands there, and
the default (about 200 KB) overflows at a few thousand frames/s."""


def _grow_receive_buffer(bus: can.BusABC) -> None:
    import socket

    sock = getattr(getattr(bus, "_multicast", None), "_socket", None)
    if not isinstance(sock, socket.socket):
        return
    force = getattr(socket, "SO_RCVBUFFORCE", None)
    try:
        if force is not None:
            sock.setsockopt(socket.SOL_SOCKET, force, UDP_RECEIVE_BUFFER)
            return
    except OSError:
        pass  # not allowed: fall back to the capped request
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, UDP_RECEIVE_BUFFER)
    except OSError:
        pass


UDP_CHANNEL_NAME = "udp0"
"""Channel name given to frames received over udp_multicast (logs need a short alphanumeric name)."""


class EchoFilteredBus(can.BusABC):
    """A bus that drops the echoes of its own frames.

    python-can's udp_multicast bus receives everything it sends through the multicast loopback and
    cannot tell its own datagrams from others'.

    Every frame sent is tagged with a channel name unique to this bus object (the udp_multicast
    interface carries the channel field); received frames with that tag are dropped, the others get
    ``channel`` set to ``display_channel``.
    """

    def __init__(self, inner: can.BusABC, display_channel: str) -> None:
        self._inner = inner
        self._tag = f"attica-{os.getpid()}-{id(self):x}"
        self._display = display_channel
        super().__init__(channel=display_channel)
        self._can_protocol = inner.protocol
        self.channel_info = f"{inner.channel_info} (own echoes filtered)"

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        import time

        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            left = None if deadline is None else max(deadline - time.monotonic(), 0.0)
            msg = self._inner.recv(left)
            if msg is None:
                return None, False
            if msg.channel == self._tag:
                continue  # an echo: look at what follows (without waiting once the time is up)
            msg.channel = self._display
            return msg, False

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Send a copy of ``msg`` tagged as ours."""
        import copy

        tagged = copy.copy(msg)
        tagged.channel = self._tag
        self._inner.send(tagged, timeout)

    def fileno(self) -> int:
        """The inner bus's file descriptor."""
        return int(self._inner.fileno())

    def shutdown(self) -> None:
        """Close the inner bus too."""
        super().shutdown()
        self._inner.shutdown()


def to_messages(frames: Any, channel: str | None = None) -> list[can.Message]:
    """python-can Messages of attica frame records (:data:`attica.can.codec.FRAME_DTYPE`), in order.

    CAN FD frames are sent with bit rate switch, as the node does.
    """
    import numpy as np

    fr = np.atleast_1d(frames)
    ids = fr["id"].tolist()
    lens = fr["len"].tolist()
    fds = fr["fd"].tolist()
    raw = fr["data"]
    out = []
    for i, (can_id, length, fd) in enumerate(zip(ids, lens, fds)):
        out.append(
            can.Message(
                arbitration_id=can_id,
                data=raw[i, :length].tobytes(),
                is_extended_id=False,
                is_fd=bool(fd),
                bitrate_switch=bool(fd),
                channel=channel,
                check=False,
            )
        )
    return out


def from_messages(msgs: list[can.Message]) -> Any:
    """Frame records (:data:`attica.can.codec.FRAME_DTYPE`) of python-can Messages.

    Error, remote and extended-ID frames must be removed first (see :func:`is_attica_candidate`).
    """
    import numpy as np

    from attica.can.codec import FRAME_DTYPE

    fr = np.zeros(len(msgs), FRAME_DTYPE)
    for i, m in enumerate(msgs):
        data = bytes(m.data)
        n = min(len(data), 64)
        fr["id"][i] = m.arbitration_id
        fr["len"][i] = n
        fr["fd"][i] = 1 if m.is_fd else 0
        fr["data"][i, :n] = np.frombuffer(data[:n], np.uint8)
    return fr


def is_attica_candidate(msg: can.Message) -> bool:
    """True for data frames with an 11-bit ID (the only frames attica uses; others are ignored)."""
    return not (msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id)


class BusReader:
    """Takes frames off a bus in a background thread, so that bursts wait in memory, not in the socket.

    Parameters
    ----------
    bus
        An open bus.
    max_backlog
        Most frames kept waiting; beyond that frames are dropped and counted (:attr:`dropped`).

    """

    def __init__(self, bus: can.BusABC, max_backlog: int = 2_000_000) -> None:
        self.bus = bus
        self.max_backlog = max_backlog
        self.dropped = 0
        self._q: queue.SimpleQueue[can.Message] = queue.SimpleQueue()
        self._stop = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="attica-monitor-rx", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                msg = self.bus.recv(0.05)
                if msg is None:
                    continue
                if self._q.qsize() >= self.max_backlog:
                    self.dropped += 1
                else:
                    self._q.put(msg)
        except BaseException as exc:  # reported by get()
            self._error = exc

    def get(self, timeout: float) -> can.Message | None:
        """The next frame (None after ``timeout`` s without one)."""
        try:
            return self._q.get(timeout=timeout)
        except queue.Empty:
            if self._error is not None:
                raise self._error from None
            return None

    def stop(self) -> list[can.Message]:
        """Stop the thread; returns every frame still waiting, then those already in the socket."""
        self._stop.set()
        self._thread.join(2.0)
        rest = []
        while True:
            try:
                rest.append(self._q.get_nowait())
            except queue.Empty:
                break
        for _ in range(1_000_000):  # what the kernel already holds
            msg = self.bus.recv(0.0)
            if msg is None:
                break
            rest.append(msg)
        return rest
