"""attica view's server: the page's files, its WebSocket (latest wins, commands, playback, bad input),
the command line, and the Foxglove bridge read by a WebSocket client that subscribes and decodes.

:class:`Rig` (also used by tests/test_view_browser.py and tests/test_view_soak.py): the C node running
in-process on a private python-can virtual bus, the view reading that bus, and a feeder that sends it
IMU samples as an IMU would.
"""

from __future__ import annotations

import json
import math
import re
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
import uuid
from pathlib import Path
from typing import Any

import can
import numpy as np
import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import ClientConnection, connect

from attica.can import codec
from attica.can.bus import resolve_config, to_messages
from attica.can.node import Node
from attica.can.runner import NodeRunner
from attica.cli import main
from attica.view.server import STATIC_FILES, ViewServer
from attica.view.sources import BusSource
from attica.view.state import ViewState

from helpers import HOST_ENV, ROOT

G = 9.80665
YAW90_MAG = (20.0, 0.0, -40.0)  # the field (north, down) seen by a level sensor whose x points north
STATIC = Path(__file__).resolve().parent.parent / "host" / "attica" / "view" / "static"


class Rig:
    """The C node on a private virtual bus, the view (state, bus source, server) reading that bus.

    :meth:`feed` sends still samples (a level sensor, yaw 90 deg by its magnetometer unless told
    otherwise); :meth:`start_feeder` does so continuously at ``rate`` in a thread.
    """

    def __init__(
        self,
        kind: str = "mars",
        rate: float = 200.0,
        fd: bool = False,
        bitrate: int = 500_000,
        fps: float = 30.0,
        read_only: bool = False,
        foxglove: Any = None,
        ack_timeout: float = 2.0,
        diag_divider: int = 16,
    ) -> None:
        self.channel = f"view-{uuid.uuid4().hex[:10]}"
        self.rate = rate
        self.fd = fd
        cfg = resolve_config("virtual", self.channel, fd=fd)
        self.node = Node(
            kind,
            sample_rate=rate,
            fd=fd,
            bitrate=bitrate,
            data_bitrate=2_000_000 if fd else 0,
            diag_divider=diag_divider,
        )
        # the view joins the bus first: python-can's virtual bus hands a frame to its receivers in the
        # order they joined, and the view must see a sample before the node's answer to it
        self.state = ViewState(bitrate=bitrate, data_bitrate=2_000_000, m_ref=math.hypot(*YAW90_MAG))
        self.source = BusSource(cfg)
        self.source.start(self.state)
        assert self.source.opened.wait(5), "the view's bus did not open"
        self.node_bus = can.Bus(interface="virtual", channel=self.channel)
        self.stop_event = threading.Event()
        self.runner = NodeRunner(self.node_bus, self.node)
        self.runner_thread = self.runner.start(self.stop_event)
        self.server = ViewServer(
            self.state, self.source, fps=fps, read_only=read_only, foxglove=foxglove, ack_timeout=ack_timeout
        )
        self.url = self.server.start()
        self.feed_bus = can.Bus(interface="virtual", channel=self.channel)
        self.lock = threading.Lock()
        self.samples = 0  # samples sent (and skipped: their counters)
        self.frames = 0  # frames sent
        self.mag: tuple[float, float, float] | None = YAW90_MAG
        self.acc = G
        self._feeder: threading.Thread | None = None

    @property
    def ws_url(self) -> str:
        return self.url.replace("http://", "ws://") + "ws"

    def feed(self, n: int, skip: int = 0, corrupt: bool = False) -> None:
        """Send n samples after ``skip`` lost ones (a counter gap); ``corrupt``: a bad CRC on the first."""
        with self.lock:
            while self.feed_bus.recv(0.0) is not None:  # the feeder's copy of the traffic: not needed
                pass
            self.samples += skip
            gyr = np.zeros((n, 3), np.float32)
            acc = np.tile(np.float32([0.0, 0.0, self.acc]), (n, 1))
            mag = (
                np.full((n, 3), np.nan, np.float32)
                if self.mag is None
                else np.tile(np.float32(self.mag), (n, 1))
            )
            fr = codec.encode_imu(gyr, acc, mag, counter0=self.samples & 0xF, fd=self.fd)
            if corrupt:
                fr["data"][0, 0] ^= 0x5A
            for msg in to_messages(fr):
                self.feed_bus.send(msg)
            self.samples += n
            self.frames += len(fr)

    def start_feeder(self, period: float = 0.05) -> None:
        """Send ``rate * period`` samples every ``period`` s until :meth:`close`."""
        per = max(1, round(self.rate * period))

        def run() -> None:
            nxt = time.monotonic()
            while not self.stop_event.is_set():
                self.feed(per)
                nxt += period
                time.sleep(max(0.0, nxt - time.monotonic()))

        self._feeder = threading.Thread(target=run, name="test-feeder", daemon=True)
        self._feeder.start()

    def wait(self, cond: Any, timeout: float = 10.0, what: str = "") -> Any:
        t0 = time.monotonic()
        while True:
            v = cond()
            if v:
                return v
            assert time.monotonic() - t0 < timeout, f"timed out waiting for {what or cond}"
            time.sleep(0.02)

    def snap(self) -> dict[str, Any]:
        return self.state.snapshot(record=False)

    def close(self) -> None:
        self.stop_event.set()
        if self._feeder is not None:
            self._feeder.join(2)
        self.server.stop()
        self.source.stop()
        self.runner_thread.join(2)
        self.feed_bus.shutdown()
        self.node_bus.shutdown()


@pytest.fixture
def rig() -> Any:
    r = Rig()
    yield r
    r.close()


def _get(url: str) -> tuple[int, dict[str, str], bytes]:
    try:
        with urllib.request.urlopen(url, timeout=5) as resp:
            return resp.status, dict(resp.headers), resp.read()
    except urllib.error.HTTPError as exc:
        return exc.code, dict(exc.headers), exc.read()


def _messages(ws: ClientConnection, kind: str, timeout: float = 5.0, ack: bool = True) -> dict[str, Any]:
    """The next message of type ``kind`` (updates acknowledged on the way)."""
    t0 = time.monotonic()
    while True:
        left = timeout - (time.monotonic() - t0)
        assert left > 0, f"no {kind} message"
        msg = json.loads(ws.recv(timeout=left))
        if msg["type"] == "update" and ack:
            ws.send('{"type":"ack"}')
        if msg["type"] == kind:
            return msg


def _until(ws: ClientConnection, pred: Any, timeout: float = 10.0) -> dict[str, Any]:
    """The first update whose state satisfies ``pred``."""
    t0 = time.monotonic()
    last = None
    while time.monotonic() - t0 < timeout:
        msg = _messages(ws, "update", timeout=max(0.1, timeout - (time.monotonic() - t0)))
        last = msg["state"]
        if pred(last):
            return msg
    raise AssertionError(f"no update satisfied the condition within {timeout} s; the last: {last}")


# --- the page's files ---------------------------------------------------------------------------------


def test_the_page_and_its_files_are_served_from_this_origin_only(rig: Rig) -> None:
    for path, (name, ctype) in STATIC_FILES.items():
        status, headers, body = _get(rig.url.rstrip("/") + path)
        assert status == 200, path
        assert headers["Content-Type"] == ctype
        assert headers["Content-Security-Policy"].startswith("default-src 'self'")
        assert body == (STATIC / name).read_bytes()
    status, _, body = _get(rig.url + "api/health")
    assert status == 200 and body == b"ok\n"
    rig.feed(20)
    rig.wait(lambda: rig.server.ticks > 3 and rig.snap()["att"])
    status, headers, body = _get(rig.url + "api/state")
    assert status == 200 and headers["Content-Type"] == "application/json"
    assert json.loads(body)["source"]["kind"] == "bus"
    assert _get(rig.url + "nope.js")[0] == 404
    assert _get(rig.url + "../pyproject.toml")[0] == 404
    # offline: every file the page names is served here, and no file names another host
    html = (STATIC / "index.html").read_text()
    for ref in re.findall(r'(?:src|href)="([^"]+)"', html):
        assert "/" + ref in STATIC_FILES, ref
    for f in STATIC.iterdir():
        text = f.read_text()
        urls = [
            u
            for u in re.findall(r"(?:https?:)?//[\w.-]+\.[a-z]{2,}[^\s\"')]*", text)
            if "www.w3.org/2000/svg" not in u
        ]
        assert not urls, (f.name, urls)
        assert "import(" not in text and "@import" not in text


def test_the_page_ships_in_the_sdist(tmp_path: Path) -> None:
    """The page's files are package data: in the sdist (and so in the wheel built from it, through
    pyproject.toml's package-data, which tests/test_package.py builds and installs)."""
    import shutil
    import tarfile

    skip = (".git", ".venv", "build", "dist", "__pycache__", "*.so", "*.stamp", "*.egg-info", "_firmware")
    src = tmp_path / "src"
    shutil.copytree(
        ROOT, src, ignore=shutil.ignore_patterns(*skip, ".pytest_cache", ".mypy_cache", ".ruff_cache")
    )
    r = subprocess.run(
        [sys.executable, "-m", "build", "--sdist", "--outdir", str(tmp_path / "dist"), str(src)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr[-2000:]
    (sdist,) = (tmp_path / "dist").glob("*.tar.gz")
    with tarfile.open(sdist) as tar:
        names = {n.split("/", 1)[1] for n in tar.getnames() if "/" in n}
    for name, _ in STATIC_FILES.values():
        assert f"host/attica/view/static/{name}" in names
    assert '"view/static/*"' in (ROOT / "pyproject.toml").read_text()


# --- the WebSocket ------------------------------------------------------------------------------------


def test_hello_then_updates_at_display_rate_latest_wins() -> None:
    rig = Rig(fps=30.0, ack_timeout=1.0)
    try:
        rig.start_feeder()
        with connect(rig.ws_url) as ws:
            hello = json.loads(ws.recv(timeout=5))
            assert hello["type"] == "hello" and hello["can_command"] is True
            assert {f["name"] for f in hello["flags"]} >= {
                "AT_REST",
                "ACCEL_REJECTED",
                "MAG_REJECTED",
                "NUMERIC",
            }
            assert "mars" in hello["kinds"] and hello["conventions"] == ["ENU", "NED", "NWU"]
            # acknowledging each update: about fps of them
            t0 = time.monotonic()
            n = 0
            while time.monotonic() - t0 < 1.5:
                msg = json.loads(ws.recv(timeout=2))
                if msg["type"] == "update":
                    n += 1
                    ws.send('{"type":"ack"}')
            assert 15 <= n <= 50, n
            # not acknowledging (a slow tab): one update per ack_timeout, always the latest
            first = _messages(ws, "update", ack=False)
            t0 = time.monotonic()
            later = json.loads(ws.recv(timeout=3))
            waited = time.monotonic() - t0
            assert later["type"] == "update" and 0.9 < waited < 2.0, waited
            assert later["tick"] - first["tick"] >= 20  # skipped ticks: the latest state, not a backlog
            assert later["state"]["health"]["frames"] > first["state"]["health"]["frames"]
            # history: the points since the ones already sent, each once
            seqs = [p[0] for p in later["history"]]
            assert seqs == sorted(set(seqs)) and (
                not seqs or seqs[0] > max([p[0] for p in first["history"]] or [0])
            )
    finally:
        rig.close()


def test_commands_need_a_confirmation_and_reach_the_c_node(rig: Rig) -> None:
    rig.start_feeder()
    with connect(rig.ws_url) as ws:
        _messages(ws, "hello")
        _until(ws, lambda s: s["att"] and s["att"]["kind"] == "mars")
        ws.send(json.dumps({"type": "command", "name": "reset"}))
        reply = _messages(ws, "command")
        assert reply["ok"] is False and "confirmed" in reply["text"]
        ws.send(json.dumps({"type": "command", "name": "convention", "arg": "NED", "confirmed": True}))
        assert _messages(ws, "command")["ok"] is True
        # yaw 90 in ENU (x north, z up) is yaw 0, roll 180 in NED
        _until(
            ws,
            lambda s: s["convention"] == "NED" and abs(math.degrees(s["att"]["euler"][2])) < 1.0,
            timeout=5,
        )
        ws.send(json.dumps({"type": "command", "name": "select", "arg": "ekf", "confirmed": True}))
        assert _messages(ws, "command")["ok"] is True
        _until(ws, lambda s: s["att"]["kind"] == "ekf" and s["commands"][-1]["status"] == "ok")
        assert rig.node.running_kind.label == "ekf"
        ws.send(json.dumps({"type": "command", "name": "reset", "confirmed": True}))
        assert _messages(ws, "command")["ok"]
        st = _until(ws, lambda s: s["commands"][-1]["status"] == "ok")["state"]
        assert [c["text"] for c in st["commands"]] == ["set convention NED", "select filter ekf", "reset"]
        ws.send(json.dumps({"type": "command", "name": "select", "arg": "nope", "confirmed": True}))
        reply = _messages(ws, "command")
        assert reply["ok"] is False and "unknown filter" in reply["text"]


def test_read_only_and_log_sources_take_no_commands(tmp_path: Path) -> None:
    rig = Rig(read_only=True)
    try:
        with connect(rig.ws_url) as ws:
            assert _messages(ws, "hello")["can_command"] is False
            ws.send(json.dumps({"type": "command", "name": "reset", "confirmed": True}))
            reply = _messages(ws, "command")
            assert reply["ok"] is False and "read-only" in reply["text"]
            ws.send(json.dumps({"type": "playback", "action": "pause"}))
            reply = _messages(ws, "playback")
            assert reply["ok"] is False and "cannot be paused" in reply["text"]
        assert rig.node.stats()["commands"] == 0
    finally:
        rig.close()


def test_a_foreign_origin_is_refused(rig: Rig) -> None:
    with pytest.raises(InvalidStatus) as exc:
        connect(rig.ws_url, origin="http://evil.example")  # type: ignore[arg-type]
    assert exc.value.response.status_code == 403
    host = rig.url.split("/")[2]
    with connect(rig.ws_url, origin=f"http://{host}") as ws:  # type: ignore[arg-type]
        assert _messages(ws, "hello")["type"] == "hello"


def test_bad_messages_and_closed_tabs_never_stop_the_server(rig: Rig) -> None:
    rig.start_feeder()
    with connect(rig.ws_url) as ws:
        _messages(ws, "hello")
        for bad in ("not json", "[1, 2]", '{"type": "nope"}', '{"type": "playback", "action": "rewind"}'):
            ws.send(bad)
        errors = [_messages(ws, "error"), _messages(ws, "error"), _messages(ws, "error")]
        assert all(e["text"] for e in errors)
    for _ in range(3):  # tabs that vanish without a closing handshake
        with connect(rig.ws_url) as ws:
            ws.recv(timeout=5)
            ws.socket.shutdown(socket.SHUT_RDWR)
            ws.socket.close()
    time.sleep(0.3)
    with connect(rig.ws_url) as ws:
        _messages(ws, "hello")
        msg = _until(ws, lambda s: s["att"] is not None)
        assert msg["state"]["source"]["state"] == "running"
    assert _get(rig.url + "api/health")[0] == 200
    rig.wait(lambda: not rig.server.clients, 5, "the closed connections to go")


# --- the command line -------------------------------------------------------------------------------


def test_cli_demo_serves_the_simulator_through_the_c_node() -> None:
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "attica",
            "view",
            "--demo",
            "--duration",
            "30",
            "--exit-after",
            "60",
            "--fps",
            "10",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=HOST_ENV,
    )
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        m = re.match(r"attica view: (http://127\.0\.0\.1:(\d+)/) ", line)
        assert m, line
        url = m.group(1)
        t0 = time.monotonic()
        while True:
            st = json.loads(_get(url + "api/state")[2])
            if st["att"] and st["truth"] and st["health"]["frames"] > 500:
                break
            assert time.monotonic() - t0 < 10, st
            time.sleep(0.2)
        assert st["source"]["kind"] == "demo" and st["att"]["kind"] == "mars" and st["can_command"]
        assert st["playback"]["duration"] == pytest.approx(30.0, abs=0.01)
        # the ghost (truth, ENU) and the node's attitude agree: the filter follows the simulation
        q = np.array(st["att"]["q"])
        t = np.array(st["truth"]["q"])
        assert abs(abs(float(q @ t)) - 1) < 0.05, (q, t)
        with connect(url.replace("http", "ws") + "ws") as ws:
            _messages(ws, "hello")
            ws.send(json.dumps({"type": "playback", "action": "pause"}))
            assert _messages(ws, "playback")["ok"]
            _until(ws, lambda s: s["source"]["state"] == "paused" and s["playback"]["paused"])
            ws.send(json.dumps({"type": "playback", "action": "seek", "value": 20.0}))
            _messages(ws, "playback")
            _until(ws, lambda s: abs(s["playback"]["position"] - 20.0) < 0.01)
            ws.send(json.dumps({"type": "playback", "action": "play"}))
            _until(ws, lambda s: s["playback"]["position"] > 20.2 and s["commands"] == [])
        proc.send_signal(signal.SIGINT)  # Ctrl-C: a clean stop
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert re.search(r"attica view: \d+ frames seen, crc errors 0, counter gaps 0, dropped 0", out), out
    assert "Traceback" not in err, err


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--loop"], "--loop"),
        (["--speed", "2"], "a live bus"),
        (["--filter", "ars"], "--filter"),
        (["--port", "70000"], "--port"),
        (["--fps", "0"], "--fps"),
        (["--log", "/no/such.log"], "no such log file"),
        (["--log", "x.log", "--interface", "virtual"], "--log plays a file"),
        (["--duration", "5"], "--duration"),
        (["--demo", "--data", "x.npz"], "not allowed with"),
    ],
)
def test_cli_errors(argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    try:
        rc = main(["view", *argv])
    except SystemExit as exc:  # argparse's own errors
        rc = int(exc.code or 0)
    assert rc == 2
    assert message in capsys.readouterr().err


# --- Foxglove ---------------------------------------------------------------------------------------


def test_foxglove_bridge_publishes_the_transform_and_the_imu() -> None:
    from attica.view.foxglove import FoxgloveBridge

    bridge = FoxgloveBridge("127.0.0.1", 0)
    rig = Rig(foxglove=bridge)
    try:
        rig.start_feeder()
        with connect(f"ws://127.0.0.1:{bridge.port}", subprotocols=["foxglove.sdk.v1"]) as ws:  # type: ignore[list-item]
            info = json.loads(ws.recv(timeout=5))
            assert info["op"] == "serverInfo" and info["name"] == "attica"
            channels: dict[str, dict[str, Any]] = {}
            while len(channels) < 3:
                msg = json.loads(ws.recv(timeout=5))
                if msg["op"] == "advertise":
                    channels.update({c["topic"]: c for c in msg["channels"]})
            assert channels["/tf"]["schemaName"] == "foxglove.FrameTransform"
            assert channels["/tf"]["encoding"] == "json" and channels["/imu"]["schemaName"] == "attica.Imu"
            subs = {i + 1: topic for i, topic in enumerate(channels)}
            ws.send(
                json.dumps(
                    {
                        "op": "subscribe",
                        "subscriptions": [{"id": i, "channelId": channels[t]["id"]} for i, t in subs.items()],
                    }
                )
            )
            got: dict[str, tuple[int, dict[str, Any]]] = {}
            t0 = time.monotonic()
            while len(got) < 3:
                assert time.monotonic() - t0 < 10, got.keys()
                data = ws.recv(timeout=5)
                if isinstance(data, str):
                    continue
                op, sub, log_time = struct.unpack_from("<BIQ", data)
                assert op == 1
                got[subs[sub]] = (log_time, json.loads(data[13:]))
        _, tf = got["/tf"]
        assert tf["parent_frame_id"] == "enu" and tf["child_frame_id"] == "imu"
        r = tf["rotation"]  # yaw 90 deg about z: (w, z) = (cos 45, sin 45)
        assert r["w"] == pytest.approx(math.sqrt(0.5), abs=1e-3) and r["z"] == pytest.approx(
            math.sqrt(0.5), abs=1e-3
        )
        assert abs(r["x"]) < 1e-3 and abs(r["y"]) < 1e-3
        log_time, imu = got["/imu"]
        assert imu["orientation"] == pytest.approx(r, abs=1e-6)
        assert imu["linear_acceleration"]["z"] == pytest.approx(G, abs=0.01)
        assert imu["angular_velocity"] == {"x": 0.0, "y": 0.0, "z": 0.0}
        stamp = imu["header"]["stamp"]
        assert stamp["sec"] * 10**9 + stamp["nsec"] == log_time
        assert abs(log_time / 1e9 - time.time()) < 30  # bus time of a live bus: now
        _, status = got["/attica/status"]
        assert status["yaw"] == pytest.approx(math.pi / 2, abs=1e-3) and status["kind"] == "mars"
        assert bridge.published > 0
    finally:
        rig.close()
        bridge.stop()
