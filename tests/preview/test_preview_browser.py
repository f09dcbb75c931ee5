"""The preview in a real browser: headless Chromium renders the offline page and the live page.

Chromium is driven through the DevTools protocol over a pipe (``--remote-debugging-pipe``: no port,
no extra dependency): the tests wait until the page reports that every scene command was applied
(``window.iprompReady`` for the offline page, ``window.iprompSynced`` once the live server sent the
whole scene), then for two rendered animation frames, and only then take the screenshot. This is a
real wait on the scene, unlike a fixed ``--virtual-time-budget``, which does not cover websocket
traffic. WebGL runs on SwiftShader (software).

Without Chromium the tests skip, unless ``IPROMP_PIN_REQUIRE_BROWSER=1`` (set by CI), where they fail.
Install it with ``.ci/install_browser.sh``.
"""

from __future__ import annotations

import base64
import io
import json
import os
import queue
import shutil
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from test_preview import load_baxter, make_content, make_panda_content

from ipromp_pin import preview

pytestmark = pytest.mark.browser

WIDTH, HEIGHT = 1280, 800
OVERLAY_RIGHT = 330  # the HTML panel covers x < 330 px at the top left


def find_chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        path = shutil.which(name)
        if path:
            return path
    reason = "headless Chromium not installed (run .ci/install_browser.sh as root)"
    if os.environ.get("IPROMP_PIN_REQUIRE_BROWSER") == "1":
        pytest.fail(f"IPROMP_PIN_REQUIRE_BROWSER=1 but {reason}")
    pytest.skip(reason)


class Browser:
    """Headless Chromium controlled over the DevTools protocol on a pipe (fds 3 and 4 of the child)."""

    def __init__(self, binary: str, profile: Path) -> None:
        to_chrome_r, to_chrome_w = os.pipe()
        from_chrome_r, from_chrome_w = os.pipe()

        def child_fds() -> None:  # runs in the child before exec; close_fds happens after it
            os.dup2(to_chrome_r, 3)
            os.dup2(from_chrome_w, 4)

        args = [
            binary,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--disable-quic",
            "--disable-extensions",
            "--mute-audio",
            "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader",
            f"--user-data-dir={profile}",
            f"--window-size={WIDTH},{HEIGHT}",
            "--remote-debugging-pipe",
            "about:blank",
        ]
        self.log = profile.parent / "chromium.log"
        with self.log.open("w") as log:
            self.process = subprocess.Popen(
                args,
                preexec_fn=child_fds,
                pass_fds=(3, 4),
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=log,
            )
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self._send = os.fdopen(to_chrome_w, "wb", buffering=0)
        self._receive = os.fdopen(from_chrome_r, "rb", buffering=0)
        self._messages: queue.Queue = queue.Queue()
        self._next_id = 0
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        buffer = b""
        while chunk := self._receive.read(1 << 16):
            buffer += chunk
            *messages, buffer = buffer.split(b"\0")
            for message in messages:
                self._messages.put(json.loads(message))
        self._messages.put(None)

    def call(
        self, method: str, params: dict | None = None, session: str | None = None, timeout: float = 60.0
    ):
        self._next_id += 1
        message = {"id": self._next_id, "method": method, "params": params or {}}
        if session is not None:
            message["sessionId"] = session
        self._send.write(json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            reply = self._messages.get(timeout=max(0.01, deadline - time.monotonic()))
            if reply is None:
                raise RuntimeError(f"Chromium closed the DevTools pipe; see {self.log}")
            if reply.get("id") == self._next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply["result"]

    def open(self, url: str) -> str:
        target = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        self.call(
            "Emulation.setDeviceMetricsOverride",
            {"width": WIDTH, "height": HEIGHT, "deviceScaleFactor": 1, "mobile": False},
            session,
        )
        self.call("Page.navigate", {"url": url}, session)
        return session

    def evaluate(self, session: str, expression: str):
        result = self.call(
            "Runtime.evaluate",
            {"expression": expression, "returnByValue": True, "awaitPromise": True},
            session,
        )
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def wait_for(self, session: str, expression: str, timeout: float = 120.0):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            value = self.evaluate(session, expression)
            if value:
                return value
            time.sleep(0.2)
        raise TimeoutError(f"'{expression}' still false after {timeout} s; see {self.log}")

    def screenshot(self, session: str) -> np.ndarray:
        """(H, W, 3) uint8 screenshot after two rendered animation frames."""
        self.evaluate(
            session, "new Promise(r => requestAnimationFrame(() => requestAnimationFrame(() => r(1))))"
        )
        data = self.call("Page.captureScreenshot", {"format": "png"}, session, timeout=120)["data"]
        from PIL import Image

        with Image.open(io.BytesIO(base64.b64decode(data))) as image:
            return np.asarray(image.convert("RGB"))

    def close(self) -> None:
        try:
            self.call("Browser.close", timeout=10)
        except (RuntimeError, queue.Empty, OSError):
            pass
        try:
            self.process.wait(10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    binary = find_chromium()
    profile = tmp_path_factory.mktemp("chromium") / "profile"
    profile.mkdir()
    chrome = Browser(binary, profile)
    yield chrome
    chrome.close()


@pytest.fixture(scope="module")
def content():
    return make_content(*load_baxter())


def robot_pixels(shot: np.ndarray) -> int:
    """Pixels of Baxter's dark-red body colour (shaded) right of the HTML panel."""
    rgb = shot[:, OVERLAY_RIGHT:, :].astype(int)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return int(np.sum((r > 50) & (r > 2 * g) & (r > 2 * b)))


@pytest.fixture(scope="module")
def offline(browser, content, tmp_path_factory):
    """(screenshot, session) of the offline page, rendered once for all the checks below."""
    page = preview.write_html(content, tmp_path_factory.mktemp("offline") / "preview.html")
    session = browser.open(page.as_uri())
    n_commands = browser.wait_for(session, "window.iprompReady")
    return browser.screenshot(session), session, n_commands


def test_offline_page_draws_the_robot(offline):
    shot, _, n_commands = offline
    assert shot.shape == (HEIGHT, WIDTH, 3)
    assert n_commands > 40
    scene = shot[:, OVERLAY_RIGHT:, :]
    assert scene.std() > 10.0  # not a blank canvas
    assert robot_pixels(shot) > 5000  # Baxter's red arms and shoulders
    ys, xs = np.nonzero(
        (shot[..., 0] > 50) & (shot[..., 0] > 2 * shot[..., 1]) & (shot[..., 0] > 2 * shot[..., 2])
    )
    assert 0.2 * HEIGHT < np.median(ys) < 0.8 * HEIGHT  # robot in the middle of the view
    assert OVERLAY_RIGHT < np.median(xs) < WIDTH - 100


def test_offline_page_shows_prediction_and_human(offline):
    shot, _, _ = offline
    rgb = shot[:, OVERLAY_RIGHT:, :].astype(int)
    green = (rgb[..., 1] > 100) & (rgb[..., 1] > rgb[..., 0] + 50) & (rgb[..., 1] > rgb[..., 2] + 50)
    blue = (rgb[..., 2] > 100) & (rgb[..., 2] > rgb[..., 0] + 60)
    assert green.sum() > 50  # observed hand path
    assert blue.sum() > 50  # predicted gripper path and its band


def test_offline_page_panel_names_the_task(browser, offline):
    _, session, _ = offline
    assert (
        browser.evaluate(session, "document.getElementById('ipromp-task-name').textContent") == "handover_cup"
    )
    rows = browser.evaluate(
        session, "[...document.querySelectorAll('#ipromp-posterior tr')].map(r => r.textContent)"
    )
    assert rows == ["handover_cup0.820", "handover_rod0.130", "handover_tape0.050"]
    failed = browser.evaluate(
        session, "[...document.querySelectorAll('#ipromp-feasibility li.fail')].map(e => e.textContent)"
    )
    assert failed == ["self-collision: forearm vs torso"]
    # A skipped check is drawn as skipped (a dash, greyed), never with a check mark.
    skipped = browser.evaluate(
        session, "[...document.querySelectorAll('#ipromp-feasibility li.skip')].map(e => e.textContent)"
    )
    assert skipped == ["hand distance (skipped): human hand position unknown"]
    marks = browser.evaluate(
        session,
        "[...document.querySelectorAll('#ipromp-feasibility li')]"
        ".map(e => getComputedStyle(e, '::before').content)",
    )
    assert marks == ['"\u2714 "', '"\u2718 "', '"\u2013 "']  # (CSS: the escape eats one space)
    # The observed fraction is of the human's motion (4 s), not of the robot trajectory (3 s).
    observed = browser.evaluate(session, "document.getElementById('ipromp-observed').textContent")
    assert observed == "Observed: 1.00 s of the human's 4.00 s motion (25 %, recorded duration)"
    timebase = browser.evaluate(session, "document.getElementById('ipromp-timebase').textContent")
    assert (
        timebase == "Times are on the human's motion (t = 0 at its start); the robot comes to rest at 3.00 s"
    )
    # The animation is loaded on the one clock: it spans the human's 4 s motion, longer than the
    # robot's 3 s trajectory.
    duration = browser.evaluate(session, "viewer.animator.duration")
    assert duration == pytest.approx(4.0, abs=0.05)


def scene_extent(shot: np.ndarray) -> tuple[int, float]:
    """(pixels, 5-95 % vertical spread in pixels) of what is drawn over the background, right of the
    panel: the background is a vertical gradient, so each row's median is its background colour."""
    rgb = shot[:, OVERLAY_RIGHT:, :].astype(int)
    drawn = np.abs(rgb - np.median(rgb, axis=1, keepdims=True)).max(axis=-1) > 20
    drawn[:30] = False  # meshcat's "Open Controls" bar
    ys = np.nonzero(drawn)[0]
    return int(drawn.sum()), float(np.percentile(ys, 95) - np.percentile(ys, 5))


def test_another_robot_fills_the_view(browser, tmp_path):
    """A Panda (far smaller than Baxter) is framed by the camera, not drawn tiny in Baxter's view
    (with Baxter's fixed camera it covered about 10,000 pixels and 150 rows)."""
    page = preview.write_html(make_panda_content(), tmp_path / "panda.html")
    session = browser.open(page.as_uri())
    browser.wait_for(session, "window.iprompReady")
    pixels, spread = scene_extent(browser.screenshot(session))
    assert pixels > 25_000 and spread > 0.3 * HEIGHT
    browser.call("Page.close", session=session)


def test_live_page_renders_and_follows_updates(browser, content):
    with preview.LivePreview(content, port=0) as live:
        t0 = time.monotonic()
        session = browser.open(live.url)
        n_commands = browser.wait_for(session, "window.iprompSynced")
        t1 = time.monotonic()
        assert n_commands > 40 and live.n_clients == 1
        shot = browser.screenshot(session)
        print(
            f"live page: scene received after {t1 - t0:.1f} s, screenshot after {time.monotonic() - t0:.1f} s"
        )
        assert robot_pixels(shot) > 5000
        assert (
            browser.evaluate(session, "document.getElementById('ipromp-task-name').textContent")
            == "handover_cup"
        )
        live.update_posterior(np.array([0.05, 0.15, 0.8]))
        browser.wait_for(
            session, "document.getElementById('ipromp-task-name').textContent === 'handover_tape'", timeout=30
        )
        browser.call("Page.close", session=session)
