"""The web server of ``attica view``: the page, its WebSocket, a JSON snapshot; one process, one port.

Built on the ``websockets`` library (HTTP/1.1 parsing, the WebSocket protocol): the page's files are
answered from ``process_request`` (GET only, from memory, with a Content-Security-Policy that allows
nothing but this origin: the page cannot load anything from elsewhere), and ``/ws`` is the page's
WebSocket.

Routes: ``/`` (the page), ``/view.js``, ``/view.css``, ``/api/state`` (the latest snapshot as JSON, for
scripts and ``curl``), ``/api/health`` (``ok``), ``/ws`` (WebSocket; a browser's Origin must be this
server's, so another site open in the same browser cannot command the node).

Updates at display rate, latest wins: a tick every ``1 / fps`` s takes one snapshot of the
:class:`~attica.view.state.ViewState`; each page gets the latest one when it has acknowledged the one
before (``{"type": "ack"}`` after drawing it), so a slow or hidden tab gets fewer updates, never a
backlog, and nothing waits for it but its own connection. A page that never acknowledges still gets
one every ``ack_timeout`` s.

Messages from the page (JSON): ``ack``; ``command`` (``name``: reset, select with ``arg`` a kind,
convention with ``arg`` ENU/NED/NWU; refused unless ``confirmed`` is true, and in ``read_only`` mode);
``playback`` (``action``: pause, play, seek with ``value`` s, speed with ``value``). Anything else is
answered with an error message and logged; it never closes the server.
"""

from __future__ import annotations

import asyncio
import json
import logging
import threading
import time
from dataclasses import dataclass
from http import HTTPStatus
from importlib import resources
from typing import Any
from urllib.parse import urlsplit

from websockets.asyncio.server import Server, ServerConnection, serve
from websockets.datastructures import Headers
from websockets.exceptions import ConnectionClosed
from websockets.http11 import Request, Response

from attica.kinds import labels
from attica.settings import Flag
from attica.view.sources import SPEEDS, Source, SourceError
from attica.view.state import COMMANDS, CONVENTIONS, FLAGS, ViewState

__all__ = ["STATIC_FILES", "ViewServer"]

log = logging.getLogger("attica.view")

STATIC_FILES = {
    "/": ("index.html", "text/html; charset=utf-8"),
    "/index.html": ("index.html", "text/html; charset=utf-8"),
    "/view.js": ("view.js", "text/javascript; charset=utf-8"),
    "/view.css": ("view.css", "text/css; charset=utf-8"),
    "/favicon.svg": ("favicon.svg", "image/svg+xml"),
}
"""URL path -> (file of attica/view/static, content type)."""

CSP = (
    "default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data:; "
    "connect-src 'self'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'"
)
"""Content-Security-Policy of every response: this origin only (the page works offline)."""


def _static(name: str) -> bytes:
    return resources.files("attica.view").joinpath("static", name).read_bytes()


@dataclass(eq=False)
class _Client:
    ws: ServerConnection
    tick: int = 0  # the last tick sent
    history: int = 0  # the last history point sent
    epoch: int = 0
    waiting: bool = False  # an update sent and not yet acknowledged
    sent_at: float = 0.0
    updates: int = 0


class ViewServer:
    """Serve the page of a :class:`ViewState` fed by a :class:`Source`.

    Parameters
    ----------
    state
        What the page shows.
    source
        Where the frames come from (commands and playback controls go to it).
    host, port
        Where to listen (port 0: a free port, see :attr:`port` once started).
    fps
        Display rate: snapshots per second (1 .. 120).
    read_only
        Refuse every node command.
    foxglove
        A :class:`attica.view.foxglove.FoxgloveBridge` to publish every snapshot to, or None.
    ack_timeout
        Seconds after which a page that did not acknowledge gets the next update anyway.

    """

    def __init__(
        self,
        state: ViewState,
        source: Source,
        host: str = "127.0.0.1",
        port: int = 0,
        fps: float = 30.0,
        read_only: bool = False,
        foxglove: Any = None,
        ack_timeout: float = 2.0,
    ) -> None:
        if not 1.0 <= fps <= 120.0:
            raise ValueError(f"fps must be within 1 .. 120, got {fps:g}")
        self.state = state
        self.source = source
        self.host = host
        self.port = port
        self.fps = fps
        self.read_only = read_only
        self.foxglove = foxglove
        self.ack_timeout = ack_timeout
        self.files = {path: (_static(name), ctype) for path, (name, ctype) in STATIC_FILES.items()}
        self.clients: set[_Client] = set()
        self.connections = 0
        self.ticks = 0
        self._snap: dict[str, Any] = {}
        self._snap_json = "{}"
        self._cond: asyncio.Condition | None = None
        self._server: Server | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self.ready = threading.Event()
        self._stopped: asyncio.Event | None = None
        self._error: BaseException | None = None

    # --- the page's files --------------------------------------------------------------------------

    @property
    def url(self) -> str:
        """``http://host:port/`` of the page."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    def _response(self, status: HTTPStatus, body: bytes, ctype: str) -> Response:
        headers = Headers(
            [
                ("Content-Type", ctype),
                ("Content-Length", str(len(body))),
                ("Cache-Control", "no-store"),
                ("Content-Security-Policy", CSP),
                ("X-Content-Type-Options", "nosniff"),
                ("Referrer-Policy", "no-referrer"),
                ("Connection", "close"),
            ]
        )
        return Response(status.value, status.phrase, headers, body)

    def _process_request(self, conn: ServerConnection, request: Request) -> Response | None:
        path = urlsplit(request.path).path
        if path == "/ws":
            origin = request.headers.get("Origin")
            host = request.headers.get("Host")
            if origin is not None and urlsplit(origin).netloc != host:
                log.warning("refused a WebSocket from origin %s (this server is %s)", origin, host)
                return self._response(HTTPStatus.FORBIDDEN, b"cross-origin WebSocket refused\n", "text/plain")
            return None
        if path in self.files:
            body, ctype = self.files[path]
            return self._response(HTTPStatus.OK, body, ctype)
        if path == "/api/state":
            body = json.dumps(self._snap or self.state.snapshot(record=False)).encode()
            return self._response(HTTPStatus.OK, body, "application/json")
        if path == "/api/health":
            return self._response(HTTPStatus.OK, b"ok\n", "text/plain")
        return self._response(HTTPStatus.NOT_FOUND, b"not found\n", "text/plain")

    # --- WebSocket -----------------------------------------------------------------------------------

    def hello(self) -> dict[str, Any]:
        """What the page learns once: the source, flags, kinds, commands, speeds."""
        from attica import __version__

        return {
            "type": "hello",
            "version": __version__,
            "fps": self.fps,
            "read_only": self.read_only,
            "source": dict(self.state.source),
            "can_command": self.state.can_command and not self.read_only,
            "commands": COMMANDS,
            "kinds": labels(),
            "conventions": list(CONVENTIONS),
            "speeds": list(SPEEDS),
            "flags": [
                {"name": n, "bit": int(Flag[n]), "label": lab, "text": text, "severity": sev}
                for n, lab, text, sev in FLAGS
            ],
        }

    async def _handler(self, ws: ServerConnection) -> None:
        assert self._cond is not None
        client = _Client(ws)
        self.clients.add(client)
        self.connections += 1
        log.info("page connected from %s", ws.remote_address)
        sender: asyncio.Task[None] | None = None
        try:
            await ws.send(json.dumps(self.hello()))
            sender = asyncio.create_task(self._send_loop(client))
            async for raw in ws:
                await self._on_message(client, raw)
        except ConnectionClosed:
            pass
        except Exception:  # a page must never stop the server
            log.exception("page connection failed")
        finally:
            if sender is not None:
                sender.cancel()
            self.clients.discard(client)
            log.info("page disconnected (%s)", ws.remote_address)

    async def _send_loop(self, client: _Client) -> None:
        assert self._cond is not None
        try:
            while True:
                async with self._cond:
                    await self._cond.wait_for(
                        lambda: (
                            self.ticks > client.tick
                            and (not client.waiting or time.monotonic() - client.sent_at > self.ack_timeout)
                        )
                    )
                    tick = self.ticks
                    snap_json = self._snap_json
                    epoch = self._snap.get("epoch", 0)
                if epoch != client.epoch:
                    client.epoch = epoch
                    client.history = 0
                hist = self.state.history_since(client.history)
                if hist:
                    client.history = int(hist[-1][0] or 0)
                text = (
                    f'{{"type":"update","tick":{tick},"state":{snap_json},'
                    f'"history":{json.dumps(hist, allow_nan=False)}}}'
                )
                client.tick = tick
                client.waiting = True
                client.sent_at = time.monotonic()
                await client.ws.send(text)
                client.updates += 1
        except ConnectionClosed:
            pass

    async def _reply(self, client: _Client, **fields: Any) -> None:
        try:
            await client.ws.send(json.dumps(fields))
        except ConnectionClosed:
            pass

    async def _on_message(self, client: _Client, raw: str | bytes) -> None:
        assert self._cond is not None
        try:
            msg = json.loads(raw)
            if not isinstance(msg, dict):
                raise ValueError("not a JSON object")
        except ValueError as exc:
            log.warning("bad message from a page: %s", exc)
            await self._reply(client, type="error", text=f"bad message: {exc}")
            return
        kind = msg.get("type")
        if kind == "ack":
            async with self._cond:
                client.waiting = False
                self._cond.notify_all()
        elif kind == "command":
            await self._command(client, msg)
        elif kind == "playback":
            try:
                self.source.control(str(msg.get("action")), msg.get("value"))
                await self._reply(client, type="playback", ok=True)
            except SourceError as exc:
                await self._reply(client, type="playback", ok=False, text=str(exc))
        else:
            log.warning("unknown message type %r from a page", kind)
            await self._reply(client, type="error", text=f"unknown message type {kind!r}")

    async def _command(self, client: _Client, msg: dict[str, Any]) -> None:
        name = str(msg.get("name"))
        if self.read_only:
            await self._reply(client, type="command", ok=False, text="read-only: commands are off")
            return
        if msg.get("confirmed") is not True:
            await self._reply(client, type="command", ok=False, text="a command needs confirmed: true")
            return
        if not self.source.can_send:
            await self._reply(
                client, type="command", ok=False, text=f"a {self.source.kind} takes no commands"
            )
            return
        try:
            rec, frame = self.state.command(name, msg.get("arg", 0))
        except ValueError as exc:
            await self._reply(client, type="command", ok=False, text=str(exc))
            return
        log.info("sending command %s", rec.text)
        try:
            await asyncio.get_running_loop().run_in_executor(None, self.source.send, frame)
        except SourceError as exc:
            self.state.command_failed(rec, str(exc))
            await self._reply(client, type="command", ok=False, id=rec.id, text=str(exc))
            return
        await self._reply(client, type="command", ok=True, id=rec.id, text=f"sent: {rec.text}")

    async def _ticker(self) -> None:
        assert self._cond is not None and self._stopped is not None
        period = 1.0 / self.fps
        nxt = time.monotonic()
        while not self._stopped.is_set():
            try:
                snap = self.state.snapshot()
                snap_json = json.dumps(snap, allow_nan=False)
            except Exception:  # never stop ticking: log it, try again next tick
                log.exception("snapshot failed")
            else:
                if self.foxglove is not None:
                    try:
                        self.foxglove.publish(snap)
                    except Exception:
                        log.exception("Foxglove bridge failed")
                async with self._cond:
                    self._snap = snap
                    self._snap_json = snap_json
                    self.ticks += 1
                    self._cond.notify_all()
            nxt += period
            now = time.monotonic()
            if nxt < now - period:
                nxt = now
            try:
                await asyncio.wait_for(self._stopped.wait(), max(nxt - now, 0.0))
            except asyncio.TimeoutError:  # noqa: UP041 - the builtin only from Python 3.11 on
                pass
            # re-check clients waiting for an ack that timed out
            async with self._cond:
                self._cond.notify_all()

    async def serve(self, stop: asyncio.Event | None = None) -> None:
        """Serve until ``stop`` is set (or :meth:`stop` is called)."""
        self._cond = asyncio.Condition()
        self._stopped = stop if stop is not None else asyncio.Event()
        self._loop = asyncio.get_running_loop()
        async with serve(
            self._handler,
            self.host,
            self.port,
            process_request=self._process_request,
            max_size=2**16,
            write_limit=2**16,
        ) as server:
            self._server = server
            sock = next(iter(server.sockets))
            self.port = int(sock.getsockname()[1])
            ticker = asyncio.create_task(self._ticker())
            self.ready.set()
            log.info("serving %s", self.url)
            await self._stopped.wait()
            ticker.cancel()
            for c in list(self.clients):
                await c.ws.close()

    # --- in a thread (tests, embedding) --------------------------------------------------------------

    def start(self, timeout: float = 10.0) -> str:
        """Serve in a background thread; returns the page's URL once listening."""

        def run() -> None:
            try:
                asyncio.run(self.serve())
            except BaseException as exc:
                self._error = exc
                self.ready.set()

        self._thread = threading.Thread(target=run, name="attica-view-server", daemon=True)
        self._thread.start()
        if not self.ready.wait(timeout):
            raise RuntimeError("the server did not start")
        if self._error is not None:
            raise self._error
        return self.url

    def stop(self) -> None:
        """Stop serving (from any thread) and wait for the server's thread."""
        loop, stopped = self._loop, self._stopped
        if loop is not None and stopped is not None and not loop.is_closed():
            try:
                loop.call_soon_threadsafe(stopped.set)
            except RuntimeError:  # the loop already ended
                pass
        if self._thread is not None:
            self._thread.join(5.0)
