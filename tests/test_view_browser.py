"""attica view in a real browser: Debian's chromium, headless, driven through the DevTools protocol.

The page is served by the view reading a python-can virtual bus on which the C node runs in-process,
fed still samples of a level sensor whose x axis points north (yaw 90 deg in ENU by the magnetometer).
The browser test checks that the page loads with no console error, that the readout says yaw 90 and
that the body is drawn so (the nose marker's pixels where an independent projection of the expected
orientation puts them, and not where yaw 0 would), that the status flags follow the node (at rest, mag
rejected), that the bus-health counters and lights and the node's DIAG counters go up when the test
injects a frame with a bad E2E CRC and a counter gap, that a node command goes through the page's
confirmation, and that closing the tab leaves the server running. Screenshots are kept in
build/test-artifacts/ (``ATTICA_DOCS_FIGURES=1``, as ``make docs-figures`` sets it, also writes the demo's
to docs/img/view.png).

chromium is installed by host/tools/install-system-deps.sh; without it the tests skip with the reason
printed, and under CI=true they fail.
"""

from __future__ import annotations

import base64
import contextlib
import itertools
import json
import math
import os
import shutil
import subprocess
import tempfile
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import require_tool
from test_view_server import YAW90_MAG, Rig
from websockets.sync.client import connect

from attica.can.bus import resolve_config
from attica.sim import SimConfig, simulate_with_truth
from attica.view.demo import ImuSource
from attica.view.server import ViewServer
from attica.view.state import ViewState

from helpers import ROOT

ARTIFACTS = ROOT / "build" / "test-artifacts"
DOCS_FIGURE = ROOT / "docs" / "img" / "view.png"
WIDTH, HEIGHT = 1400, 900


class Chromium:
    """Headless chromium and one DevTools-protocol session to a page (flattened target sessions)."""

    def __init__(self, exe: str) -> None:
        self.dir = tempfile.mkdtemp(prefix="attica-chromium-")
        self.proc = subprocess.Popen(
            [
                exe,
                "--headless=new",
                "--no-sandbox",
                "--disable-gpu",
                "--no-first-run",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--disable-quic",
                "--disable-extensions",
                "--mute-audio",
                "--hide-scrollbars",
                f"--user-data-dir={self.dir}",
                "--remote-debugging-port=0",
                f"--window-size={WIDTH},{HEIGHT}",
                "about:blank",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        port_file = Path(self.dir) / "DevToolsActivePort"
        t0 = time.monotonic()
        while not (port_file.exists() and len(port_file.read_text().splitlines()) >= 2):
            assert self.proc.poll() is None, "chromium exited"
            assert time.monotonic() - t0 < 30, "chromium did not open its DevTools port"
            time.sleep(0.05)
        port, path = port_file.read_text().splitlines()[:2]
        self._stack = contextlib.ExitStack()
        self.ws = self._stack.enter_context(
            connect(f"ws://127.0.0.1:{port}{path}", max_size=None, open_timeout=10)
        )
        self.ids = itertools.count(1)
        self.events: list[dict[str, Any]] = []
        self.session: str | None = None
        self.target: str | None = None

    def call(
        self, method: str, params: dict[str, Any] | None = None, browser: bool = False
    ) -> dict[str, Any]:
        i = next(self.ids)
        msg: dict[str, Any] = {"id": i, "method": method, "params": params or {}}
        if not browser and self.session:
            msg["sessionId"] = self.session
        self.ws.send(json.dumps(msg))
        t0 = time.monotonic()
        while True:
            left = 20 - (time.monotonic() - t0)
            assert left > 0, f"no answer to {method}"
            r = json.loads(self.ws.recv(timeout=left))
            if r.get("id") == i:
                if "error" in r:
                    raise RuntimeError(f"{method}: {r['error']}")
                return dict(r.get("result", {}))
            if "method" in r:
                self.events.append(r)

    def open(self, url: str) -> None:
        """A new tab at ``url`` (console, exceptions and log entries recorded from the start)."""
        self.events.clear()
        self.target = self.call("Target.createTarget", {"url": "about:blank"}, browser=True)["targetId"]
        self.session = self.call(
            "Target.attachToTarget", {"targetId": self.target, "flatten": True}, browser=True
        )["sessionId"]
        for domain in ("Page.enable", "Runtime.enable", "Log.enable"):
            self.call(domain)
        self.call(
            "Emulation.setDeviceMetricsOverride",
            {"width": WIDTH, "height": HEIGHT, "deviceScaleFactor": 1, "mobile": False},
        )
        self.call("Page.navigate", {"url": url})

    def close_tab(self) -> None:
        assert self.target is not None
        self.call("Target.closeTarget", {"targetId": self.target}, browser=True)
        self.session = self.target = None

    def js(self, expr: str) -> Any:
        r = self.call("Runtime.evaluate", {"expression": expr, "returnByValue": True, "awaitPromise": True})
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expr}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def wait(self, expr: str, timeout: float = 15.0) -> Any:
        t0 = time.monotonic()
        while True:
            v = self.js(expr)
            if v:
                return v
            assert time.monotonic() - t0 < timeout, f"the page never made true: {expr}"
            time.sleep(0.1)

    def text(self, element_id: str) -> str:
        return str(self.js(f"document.getElementById({element_id!r}).textContent"))

    def has_class(self, element_id: str, cls: str) -> bool:
        return bool(self.js(f"document.getElementById({element_id!r}).classList.contains({cls!r})"))

    def click(self, element_id: str) -> None:
        """A real mouse click (pressed and released) at the element's centre."""
        x, y = self.js(
            f"(() => {{ const r = document.getElementById({element_id!r}).getBoundingClientRect();"
            " return [r.x + r.width / 2, r.y + r.height / 2]; })()"
        )
        for kind in ("mousePressed", "mouseReleased"):
            self.call(
                "Input.dispatchMouseEvent", {"type": kind, "x": x, "y": y, "button": "left", "clickCount": 1}
            )

    def screenshot(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(base64.b64decode(self.call("Page.captureScreenshot", {"format": "png"})["data"]))

    def errors(self) -> list[str]:
        """Console errors, uncaught exceptions and error log entries (failed loads, CSP) of the tab."""
        try:  # collect what arrived meanwhile
            while True:
                r = json.loads(self.ws.recv(timeout=0.05))
                if "method" in r:
                    self.events.append(r)
        except TimeoutError:
            pass
        out = []
        for e in self.events:
            m, p = e["method"], e.get("params", {})
            if m == "Runtime.exceptionThrown":
                out.append(str(p["exceptionDetails"]))
            elif m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert", "warning"):
                out.append(f"console.{p['type']}: {p.get('args')}")
            elif m == "Log.entryAdded" and p["entry"].get("level") in ("error", "warning"):
                if "willReadFrequently" in p["entry"].get("text", ""):
                    continue  # the test's own pixel readback (getImageData), not the page
                out.append(
                    f"log {p['entry'].get('level')}: {p['entry'].get('text')} {p['entry'].get('url', '')}"
                )
        return out

    def close(self) -> None:
        try:
            self._stack.close()
        finally:
            self.proc.terminate()
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
            shutil.rmtree(self.dir, ignore_errors=True)


@pytest.fixture(scope="module")
def chromium() -> Iterator[Chromium]:
    exe = require_tool("chromium")
    browser = Chromium(exe)
    try:
        yield browser
    finally:
        browser.close()


# --- the projection, independent of the page's code --------------------------------------------------


def _project(cam: dict[str, Any], p: tuple[float, float, float]) -> tuple[float, float]:
    """Where the page's camera (azimuth, elevation, distance, vertical field of view, canvas size in CSS
    pixels) puts the display-frame point p (x east, y north, z up): a pinhole looking at the origin, z up."""
    az, el, dist, fov = cam["az"], cam["el"], cam["dist"], cam["fov"]
    pos = (dist * math.cos(el) * math.cos(az), dist * math.cos(el) * math.sin(az), dist * math.sin(el))
    fwd = tuple(-c / dist for c in pos)
    right = (fwd[1], -fwd[0], 0.0)  # fwd x z
    n = math.hypot(*right)
    right = (right[0] / n, right[1] / n, 0.0)
    up = (
        right[1] * fwd[2] - right[2] * fwd[1],
        right[2] * fwd[0] - right[0] * fwd[2],
        right[0] * fwd[1] - right[1] * fwd[0],
    )
    v = tuple(a - b for a, b in zip(p, pos))
    zc = sum(a * b for a, b in zip(v, fwd))
    f = 0.5 * cam["height"] / math.tan(fov / 2)
    x = cam["width"] / 2 + f * sum(a * b for a, b in zip(v, right)) / zc
    y = cam["height"] / 2 - f * sum(a * b for a, b in zip(v, up)) / zc
    return x, y


def _nose_pixels(b: Chromium, x: float, y: float, r: int = 3) -> int:
    """How many pixels of the scene canvas within r of (x, y) CSS px have the nose marker's colour."""
    rgb = b.js("atticaView.scene().noseRgb")
    data = b.js(
        "(() => { const cv = document.getElementById('scene'); const d = window.devicePixelRatio || 1;"
        " return Array.from(cv.getContext('2d')"
        f".getImageData(Math.round({x} * d) - {r}, Math.round({y} * d) - {r},"
        f" {2 * r + 1}, {2 * r + 1}).data); }})()"
    )
    px = [data[i : i + 3] for i in range(0, len(data), 4)]
    return sum(1 for p in px if sum(abs(a - c) for a, c in zip(p, rgb)) < 60)


def _number(text: str) -> float:
    return float(text.replace("\u2212", "-"))


def _count(text: str) -> int:
    return int(text.split()[0])


def test_page_shows_the_c_node_its_flags_and_the_bus(chromium: Chromium) -> None:
    rig = Rig(kind="mars", rate=200.0)
    b = chromium
    try:
        rig.start_feeder()
        b.open(rig.url)
        b.wait(
            "window.atticaView && atticaView.counts().drawn > 3"
            " && document.getElementById('yaw').textContent !== '–'"
        )
        b.wait("document.getElementById('conn').textContent === 'connected'")
        # the readout
        assert _number(b.text("yaw")) == pytest.approx(90.0, abs=0.15)
        assert abs(_number(b.text("roll"))) < 0.15 and abs(_number(b.text("pitch"))) < 0.15
        assert "mars" in b.text("att-meta") and "ENU" in b.text("att-meta")
        # the rendered body: its nose points north (display +y) ...
        scene = b.js("atticaView.scene()")
        assert scene["nose"] == pytest.approx([0.0, 1.75, 0.0], abs=1e-3)
        cam = b.js("atticaView.camera()")
        north = _project(cam, (0.0, 1.75, 0.0))
        east = _project(cam, (1.75, 0.0, 0.0))  # where yaw 0 would put it
        assert math.dist(north, east) > 40
        b.wait("atticaView.counts().drawn > 10")
        assert _nose_pixels(b, *north) > 10, north
        assert _nose_pixels(b, *east) == 0, east
        # ... and the body's own axes agree: R maps body x to north, body z to up
        rot = scene["R"]
        assert [rot[0][0], rot[1][0], rot[2][0]] == pytest.approx([0, 1, 0], abs=1e-3)
        assert [rot[0][2], rot[1][2], rot[2][2]] == pytest.approx([0, 0, 1], abs=1e-3)
        # the flags: at rest; then a disturbed field (norm x 1.5): mag rejected, and back
        b.wait("document.getElementById('flag-AT_REST').classList.contains('on')")
        assert not b.has_class("flag-MAG_REJECTED", "on")
        rig.mag = tuple(1.5 * v for v in YAW90_MAG)  # type: ignore[assignment]
        b.wait("document.getElementById('flag-MAG_REJECTED').classList.contains('on')", 5)
        rig.mag = YAW90_MAG
        b.wait("!document.getElementById('flag-MAG_REJECTED').classList.contains('on')", 5)
        # bus health before and after a bad E2E CRC and a counter gap
        for key in ("crc_errors", "counter_gaps"):
            assert _count(b.text(f"h-{key}")) == 0 and not b.has_class(f"light-{key}", "on")
        assert b.text("d-crc_errors") in ("0", "–")
        rig.feed(1, corrupt=True)
        rig.feed(4, skip=3)
        b.wait("parseInt(document.getElementById('h-crc_errors').textContent) >= 1", 5)
        b.wait("parseInt(document.getElementById('h-counter_gaps').textContent) >= 1", 5)
        assert b.has_class("light-crc_errors", "on") and b.has_class("light-counter_gaps", "on")
        # the node saw them too: its DIAG counters (one DIAG every 16 sets)
        b.wait("parseInt(document.getElementById('d-crc_errors').textContent) >= 1", 5)
        b.wait("parseInt(document.getElementById('d-counter_gaps').textContent) >= 1", 5)
        assert "!CRC" in b.text("events") and "!GAP" in b.text("events")
        # a command through the page's confirmation
        b.click("cmd-reset")
        b.wait("!document.getElementById('modal').hidden", 3)
        assert "Reset" in b.text("modal-text")
        assert rig.node.stats()["commands"] == 0  # nothing sent before the confirmation
        b.click("modal-ok")
        b.wait("document.getElementById('cmd-log').textContent.includes('reset: ok')", 5)
        assert rig.node.stats()["commands"] == 1
        b.screenshot(ARTIFACTS / "view-bus.png")
        assert b.errors() == []
        # a closed tab: the server goes on
        frames = rig.snap()["health"]["frames"]
        b.close_tab()
        rig.wait(lambda: not rig.server.clients, 5, "the closed tab to be gone")
        rig.wait(lambda: rig.snap()["health"]["frames"] > frames + 100, 5, "more frames")
        assert rig.server.ticks > 0 and rig.state.view_errors == 0
    finally:
        rig.close()


def test_demo_page_simulator_through_the_c_node(chromium: Chromium) -> None:
    """``attica view --demo`` as the command line builds it; its screenshot is docs/img/view.png."""
    rec, _ = simulate_with_truth(SimConfig(duration=60.0, rate=285.714, seed=0, taps=3, rest_breaks=2))
    cfg = resolve_config("virtual", f"view-demo-{uuid.uuid4().hex[:8]}")
    source = ImuSource(
        rec.gyr,
        rec.acc,
        rec.mag,
        rec.rate,
        cfg,
        kind="mars",
        truth=rec.quat_true,
        name="simulation (seed 0, 60 s at 285.714 Hz)",
    )
    state = ViewState(m_ref=49.0)
    source.start(state)
    server = ViewServer(state, source)
    b = chromium
    try:
        b.open(server.start())
        b.wait("window.atticaView && atticaView.scene().truth !== null && atticaView.scene().q !== null")
        assert not b.js("document.getElementById('playback').hidden")
        assert not b.js("document.getElementById('legend-truth').hidden")
        time.sleep(12.0 if os.environ.get("ATTICA_DOCS_FIGURES") == "1" else 5.0)  # motion in the plots
        b.wait("atticaView.counts().history > 100")
        # the node's attitude and the ghost (the simulation's truth) agree
        sc = b.js("atticaView.scene()")
        dot = abs(sum(a * c for a, c in zip(sc["qDisplay"], sc["truth"])))
        assert dot > 0.98, sc
        b.screenshot(ARTIFACTS / "view.png")
        if os.environ.get("ATTICA_DOCS_FIGURES") == "1":
            DOCS_FIGURE.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(ARTIFACTS / "view.png", DOCS_FIGURE)
        # pause from the page: the position stops
        b.click("pb-play")
        b.wait(
            "atticaView.state().playback.paused && document.getElementById('pb-play').textContent === 'Play'",
            5,
        )
        pos = b.js("atticaView.state().playback.position")
        time.sleep(0.5)
        assert b.js("atticaView.state().playback.position") == pos
        assert b.text("source-state") == "paused" and not b.has_class("light-silent", "on")
        b.click("pb-play")
        b.wait(f"atticaView.state().playback.position > {pos}", 5)
        assert b.errors() == []
        b.close_tab()
    finally:
        server.stop()
        source.stop()
