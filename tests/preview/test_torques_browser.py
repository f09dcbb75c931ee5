"""The torque panel and the held object in a real browser (headless Chromium, as in
``test_preview_browser``): the bars follow the animation's time, coloured by usage, the payload is
stated while held, and the object's shape is visible exactly then."""

from __future__ import annotations

import numpy as np
import pytest
from test_body_browser import SEEK
from test_object_preview import make_track, spanner
from test_preview import load_baxter, make_content
from test_preview_browser import Browser, find_chromium

from ipromp_pin import preview
from ipromp_pin.preview.torques import usage_color

pytestmark = pytest.mark.browser

SHOWN = "window.iprompTorquesShown && window.iprompTorquesShown.t_s === {t}"
VISIBLE = "viewer.scene_tree.find(['meshcat','object','held','shape']).object.visible"


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    profile = tmp_path_factory.mktemp("chromium_torques") / "profile"
    profile.mkdir()
    chrome = Browser(find_chromium(), profile)
    yield chrome
    chrome.close()


def test_bars_and_object_follow_the_time(browser, tmp_path):
    base = make_content(*load_baxter())
    handover = 2.0  # one clock: the animation's time is the human's, like the content's and the track's
    held = base.t_s <= handover + 1e-9
    content = base.replace(torques=make_track(base, 0.0, held), held_object=spanner(handover, True))
    page = preview.write_html(content, tmp_path / "torques.html", max_triangles=20_000)
    session = browser.open(page.as_uri())
    browser.wait_for(session, "window.iprompReady")
    track = content.torques
    for t, holding in ((1.5, True), (2.9, False)):
        browser.evaluate(session, SEEK.replace("T", str(t)))
        browser.wait_for(session, SHOWN.format(t=t), timeout=30)
        text = browser.evaluate(session, "document.getElementById('ipromp-torques-now').textContent")
        assert text.endswith("gripper holding rod (0.42 kg)" if holding else "gripper empty"), text
        assert browser.evaluate(session, VISIBLE) is holding
        i = int(np.searchsorted(track.t_s, t + 1e-9) - 1)
        shown = browser.evaluate(session, "window.iprompTorquesShown.ratio")
        np.testing.assert_allclose(shown, track.ratio[i], atol=1e-3)
    # the bars' colours: a green, an orange or a red pixel in each joint's bar at its usage
    pixels = browser.evaluate(
        session,
        "(() => { const c = document.getElementById('ipromp-torques-bars'); const g = c.getContext('2d');"
        " const out = []; for (let j = 0; j < 7; j++) {"
        " const d = g.getImageData(72, 2 + 14 * j + 7, 1, 1).data; out.push([d[0], d[1], d[2]]); }"
        " return out; })()",
    )
    colours = {"ok": (44, 160, 44), "high": (255, 127, 14), "over": (214, 39, 40)}
    checked = set()
    for j, px in enumerate(pixels):
        r = float(np.round(track.ratio[i, j], 3))
        if r * 170 / max(1.0, float(track.peak.max())) >= 3:  # a bar wide enough to sample
            assert tuple(px) == colours[usage_color(r, track.allowed_ratio)]
            checked.add(usage_color(r, track.allowed_ratio))
    assert len(checked) >= 2  # at least two of the colours seen
    browser.call("Page.close", session=session)
