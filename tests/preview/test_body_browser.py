"""The human body and the separation panel in a real browser (headless Chromium, as in
``test_preview_browser``): the capsules are drawn, the panel follows the animation's time and the
replay timeline's slider, with the separation states along it."""

from __future__ import annotations

import numpy as np
import pytest
from test_body_preview import make_body, make_separation
from test_preview import load_baxter, make_content
from test_preview_browser import OVERLAY_RIGHT, Browser, find_chromium

from ipromp_pin import preview
from ipromp_pin.preview.body_scene import COLOR_BODY
from ipromp_pin.preview.timeline import TimelineEvent, write_timeline_html

pytestmark = pytest.mark.browser

SEEK = (
    "(() => { const a = viewer.animator; for (const x of a.actions) { x.enabled = true; x.paused = false;"
    " x.play(); } a.pause(); a.seek(T); a.display_progress(T); return 1; })()"
)
SHOWN = "window.iprompSeparationShown && window.iprompSeparationShown.t_s === T"


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    profile = tmp_path_factory.mktemp("chromium_body") / "profile"
    profile.mkdir()
    chrome = Browser(find_chromium(), profile)
    yield chrome
    chrome.close()


@pytest.fixture(scope="module")
def content():
    base = make_content(*load_baxter())
    body = make_body(base)
    return base.replace(body=body, separation=make_separation(base, body))


def skin_pixels(shot: np.ndarray) -> int:
    """Pixels near the body's colour (translucent over the light background), right of the panel."""
    rgb = shot[:, OVERLAY_RIGHT:, :].astype(int)
    target = np.array([(COLOR_BODY >> 16) & 255, (COLOR_BODY >> 8) & 255, COLOR_BODY & 255])
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    return int(np.sum((np.abs(rgb - target).max(axis=-1) < 60) & (r > g + 15) & (g > b + 5)))


def test_offline_page_draws_the_body_and_follows_the_time(browser, content, tmp_path):
    page = preview.write_html(content, tmp_path / "body.html", max_triangles=20_000)
    session = browser.open(page.as_uri())
    browser.wait_for(session, "window.iprompReady")
    browser.evaluate(session, SEEK.replace("T", "2.2"))
    browser.wait_for(session, SHOWN.replace("T", "2.2"), timeout=30)
    shot = browser.screenshot(session)
    assert skin_pixels(shot) > 5000
    text = browser.evaluate(session, "document.getElementById('ipromp-separation-now').textContent")
    sep = content.separation
    i = int(np.searchsorted(sep.t_s, 2.2 + 1e-9) - 1)  # one clock: the animation's is the human's
    assert text.startswith("t = 2.20 s: Separation " + f"{sep.distance_m[i]:.3f} m")
    assert {"free": "free", "within_sp": "within S_p"}.get(
        sep.state[i], sep.state[i].replace("_", "-")
    ) in text
    key = browser.evaluate(session, "document.getElementById('ipromp-separation-key').textContent")
    # no report's figure to state here (no verdicts): the panel says so, never a minimum of its own
    assert "No check in the report judged this separation" in key and "Closest" not in key
    assert "Per sample: smallest robot-body distance" in key and "violation 1" in key
    # the strip's colour under the cursor's left is the sample's state colour
    visible = browser.evaluate(
        session,
        "['free','within_sp','speed_limited','violation'].filter(s => "
        "viewer.scene_tree.find(['meshcat','human','closest',s]).object.visible)",
    )
    assert visible == [sep.state[i]]
    browser.call("Page.close", session=session)


def test_timeline_slider_has_the_separation_states(browser, content, tmp_path):
    events = [TimelineEvent(t_s=1.0, observed_until_s=1.0, task="handover_cup", committed=True)]
    shifted = content.replace(t_s=content.t_s + 1.0, observed_until_s=None)
    page = write_timeline_html(
        shifted, events, tmp_path / "timeline.html", motion_s=4.0, max_triangles=20_000
    )
    session = browser.open(page.as_uri())
    browser.wait_for(session, "window.iprompReady && window.iprompTimeline === 1")
    browser.evaluate(
        session,
        "(() => { const s = document.getElementById('ipromp-timeline-slider'); s.value = '3.2';"
        " s.dispatchEvent(new Event('input')); return 1; })()",
    )
    browser.wait_for(session, SHOWN.replace("T", "3.2"), timeout=30)
    inside = browser.evaluate(
        session, "document.getElementById('ipromp-separation').parentNode.id === 'ipromp-timeline'"
    )
    assert inside  # the strip is under the slider
    # the strip's pixels: grey before the robot's first sample (t < 1 s), then the states' colours
    pixels = browser.evaluate(
        session,
        "(() => { const c = document.getElementById('ipromp-separation-strip');"
        " const d = c.getContext('2d').getImageData(0, 6, c.width, 1).data; const out = [];"
        " for (let x = 0; x < c.width; x += 8) out.push([d[4 * x], d[4 * x + 1], d[4 * x + 2]]);"
        " return out; })()",
    )
    pixels = np.array(pixels)
    assert tuple(pixels[0]) == (224, 224, 224)
    green = (pixels[:, 1] > 140) & (pixels[:, 0] < 80)
    red = (pixels[:, 0] > 190) & (pixels[:, 1] < 80)
    assert green.any() and red.any()
    browser.call("Page.close", session=session)


def test_live_page_draws_the_body_and_the_separation_panel(browser, content):
    with preview.LivePreview(content, port=0, max_triangles=20_000) as live:
        session = browser.open(live.url)
        browser.wait_for(session, "window.iprompSynced")
        browser.wait_for(session, "window.iprompSeparationShown !== undefined", timeout=30)
        assert skin_pixels(browser.screenshot(session)) > 5000
        text = browser.evaluate(session, "document.getElementById('ipromp-separation-now').textContent")
        assert text.startswith("t = ") and "Separation" in text
        browser.call("Page.close", session=session)
