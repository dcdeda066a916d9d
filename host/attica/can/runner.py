"""Run the attica node in-process on a python-can bus: frames from the bus in, the node's frames out.

The node is the C node (firmware/src/node/att_node.c) through :class:`attica.can.codec.Node`, the same code
``attica-node`` runs on Linux SocketCAN; this module is its "port" for any python-can bus (the virtual
bus, udp_multicast, socketcan...). The loop is the one of the Linux port: receive frames, push them,
poll, send whatever the node queued.

    bus = open_bus("virtual")
    runner = NodeRunner(bus, Node("ars", sample_rate=285.714))
    runner.serve(stop=event)           # until event is set (or count steps, or idle_timeout)
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import can

from attica.can.bus import from_messages, is_attica_candidate, to_messages
from attica.can.node import Node

__all__ = ["NodeRunner", "RunnerStats"]

BATCH = 256
"""Most frames handed to the node per round."""


@dataclass
class RunnerStats:
    """What the runner itself saw (the node keeps its own counters: :meth:`Node.stats`)."""

    rx_frames: int = 0
    tx_frames: int = 0
    ignored: int = 0  # error, remote and extended-ID frames (not attica's)
    steps: int = 0
    send_retries: int = 0
    send_errors: int = 0
    started: float = field(default_factory=time.perf_counter)
    elapsed: float = 0.0

    def line(self, node_stats: dict[str, int] | None = None) -> str:
        """One-line summary, like the stats line of ``attica-node``."""
        text = (
            f"steps={self.steps} rx_frames={self.rx_frames} tx_frames={self.tx_frames} "
            f"ignored={self.ignored} send_retries={self.send_retries} send_errors={self.send_errors}"
        )
        if node_stats:
            text += " | node: " + " ".join(f"{k}={v}" for k, v in node_stats.items())
        return text


class NodeRunner:
    """Moves frames between a bus and a :class:`Node`.

    Parameters
    ----------
    bus
        An open python-can bus, as it is: a node with an ID offset moves its IDs itself (not an
        :class:`~attica.can.idoffset.OffsetBus`, which would move them twice).
    node
        The node (its ``fd`` setting must match the bus: an FD node needs a bus opened with ``fd=True``
        on interfaces that care, such as socketcan).
    send_timeout
        Seconds to keep retrying a send that fails because the interface's queue is full.

    """

    def __init__(self, bus: can.BusABC, node: Node, send_timeout: float = 1.0) -> None:
        self.bus = bus
        self.node = node
        self.send_timeout = send_timeout
        self.stats = RunnerStats()
        self.channel = str(getattr(bus, "channel_info", "") or "")

    def _send(self, msg: can.Message) -> None:
        deadline = time.monotonic() + self.send_timeout
        while True:
            try:
                self.bus.send(msg)
                self.stats.tx_frames += 1
                return
            except can.CanOperationError:
                if time.monotonic() > deadline:
                    self.stats.send_errors += 1
                    raise
                self.stats.send_retries += 1
                time.sleep(0.0005)

    def pump(self, timeout: float = 0.05) -> int:
        """Run what is queued for the node (up to :data:`BATCH` frames); returns the filter steps run.

        Waits up to ``timeout`` s for the first frame, takes what else is queued, runs it through the
        node and sends the node's frames.
        """
        first = self.bus.recv(timeout)
        if first is None:
            return 0
        msgs = [first]
        while len(msgs) < BATCH:
            m = self.bus.recv(0.0)
            if m is None:
                break
            msgs.append(m)
        self.stats.rx_frames += len(msgs)
        keep = [m for m in msgs if is_attica_candidate(m)]
        self.stats.ignored += len(msgs) - len(keep)
        if not keep:
            return 0
        out, steps = self.node.run(from_messages(keep))
        for msg in to_messages(out):
            self._send(msg)
        self.stats.steps += steps
        return steps

    def service(self) -> int:
        """Take everything queued for the node now, without waiting (for use on the caller's thread)."""
        steps = 0
        while True:
            before = self.stats.rx_frames
            steps += self.pump(0.0)
            if self.stats.rx_frames == before:
                return steps

    def serve(
        self,
        stop: threading.Event | None = None,
        count: int | None = None,
        idle_timeout: float | None = None,
        on_round: Callable[[NodeRunner], None] | None = None,
    ) -> RunnerStats:
        """Run until ``stop`` is set, ``count`` steps ran, or no frame came for ``idle_timeout`` s.

        ``on_round`` is called after every round (progress display).
        """
        last = time.monotonic()
        while stop is None or not stop.is_set():
            if count is not None and self.stats.steps >= count:
                break
            before = self.stats.rx_frames
            self.pump(0.05)
            now = time.monotonic()
            if self.stats.rx_frames != before:
                last = now
            elif idle_timeout is not None and now - last > idle_timeout:
                break
            if on_round is not None:
                on_round(self)
        self.stats.elapsed = time.perf_counter() - self.stats.started
        return self.stats

    def start(self, stop: threading.Event) -> threading.Thread:
        """Serve in a daemon thread until ``stop`` is set; returns the thread."""
        t = threading.Thread(target=self.serve, kwargs={"stop": stop}, name="attica-node", daemon=True)
        t.start()
        return t
