"""The replay's time-scrubbing preview: scene objects, animation tracks, and (in Chromium) the panel
following the scrubbed time."""

from __future__ import annotations

import json
import re

import numpy as np
import pinocchio as pin
import pytest
from test_preview import load_baxter, make_content, objects_by_path, scene_commands

from ipromp_pin.exceptions import DataError
from ipromp_pin.preview.timeline import TimelineEvent, render_timeline_html, write_timeline_html


@pytest.fixture(scope="module")
def content():
    # collision meshes keep the page small and fast to build; the drawing is the same
    return make_content(*load_baxter(pin.GeometryType.COLLISION))


def _events(content) -> list[TimelineEvent]:
    ee = content.ee_mean
    return [
        TimelineEvent(0.6, 0.6, "handover_rod", [0.2, 0.7, 0.1], 3.1, ee[-1] + 0.05, ee[20:], 3.2, True),
        TimelineEvent(1.2, 1.2, "handover_cup", [0.6, 0.3, 0.1], 3.0, ee[-1], ee[30:], 3.0, True),
        TimelineEvent(
            1.6, 1.6, "handover_cup", [0.7, 0.2, 0.1], 3.0, ee[-1], None, 3.4, False, "workspace: out"
        ),
        TimelineEvent(2.0, 2.0, "handover_tape", [0.1, 0.1, 0.8], 2.9, ee[-1] - 0.04, ee[40:], 2.9, True),
    ]


@pytest.fixture(scope="module")
def page(content, tmp_path_factory):
    path = tmp_path_factory.mktemp("timeline") / "preview.html"
    return write_timeline_html(content, _events(content), path, motion_s=3.0, summary=["error 3.0 cm"])


def test_timeline_page_holds_the_changing_prediction(page):
    html = page.read_text()
    commands = scene_commands(html)
    objects = objects_by_path(commands)
    plans = [p for p in objects if "/timeline/plans/" in p]
    assert len(plans) == 3  # one line per committed re-plan
    assert any(p.endswith("/timeline/handover") for p in objects)
    assert len([p for p in objects if "/timeline/trail/" in p]) > 10
    anim = [c for c in commands if c["type"] == "set_animation"]
    assert len(anim) == 1  # one animation drives the robot and the timeline
    clips = {a["path"]: a["clip"] for a in anim[0]["animations"]}
    plan0 = next(c for p, c in clips.items() if p.endswith("/timeline/plans/0"))
    visible = next(t for t in plan0["tracks"] if t["name"] == ".visible")
    # plan 0 is shown from its re-plan (0.6 s) until the next committed one (1.2 s), not before or after
    shown = [k["time"] / plan0["fps"] for k in visible["keys"] if k["value"]]
    hidden = [k["time"] / plan0["fps"] for k in visible["keys"] if not k["value"]]
    assert min(shown) == pytest.approx(0.6, abs=0.04) and 1.2 - 0.04 <= max(hidden) or hidden
    data = json.loads(html.split('id="ipromp-timeline-data">')[1].split("</script>")[0].replace("<\\/", "</"))
    assert [e["committed"] for e in data["events"]] == [True, True, False, True]
    assert data["events"][2]["reason"] == "workspace: out"
    assert data["summary"] == ["error 3.0 cm"] and data["motion_s"] == 3.0


def test_the_page_ends_where_its_stated_duration_does(page):
    """One span on the human's clock: the animation's last frame is the duration the page states, the
    latest of the robot's (3 s), the re-plans' (2 s) and the human hand's (4 s) last samples."""
    html = page.read_text()
    data = json.loads(html.split('id="ipromp-timeline-data">')[1].split("</script>")[0].replace("<\\/", "</"))
    assert data["duration_s"] == pytest.approx(4.0)
    (anim,) = [c for c in scene_commands(html) if c["type"] == "set_animation"]
    ends = [
        k["time"] / a["clip"]["fps"]
        for a in anim["animations"]
        for t in a["clip"]["tracks"]
        for k in t["keys"]
    ]
    assert max(ends) == pytest.approx(data["duration_s"], abs=1e-9)


def test_timeline_rejects_bad_events(content):
    bad = _events(content)[::-1]  # not in time order
    with pytest.raises(DataError, match="events"):
        render_timeline_html(content, bad)
    wrong = [TimelineEvent(0.5, 0.5, "handover_cup", [1.0, 0.0])]
    with pytest.raises(DataError, match="posterior"):
        render_timeline_html(content, wrong)


@pytest.mark.browser
def test_timeline_panel_follows_the_scrubbed_time(page, tmp_path_factory):
    from test_preview_browser import Browser, find_chromium

    profile = tmp_path_factory.mktemp("chromium-timeline") / "profile"
    profile.mkdir()
    browser = Browser(find_chromium(), profile)
    try:
        session = browser.open(page.as_uri())
        browser.wait_for(session, "window.iprompReady && window.iprompTimeline")

        def seek(t: float) -> dict:
            browser.evaluate(
                session,
                f"(() => {{ const s = document.getElementById('ipromp-timeline-slider'); s.value = '{t}';"
                " s.dispatchEvent(new Event('input')); return 1; })()",
            )
            return browser.evaluate(
                session,
                "({task: document.getElementById('ipromp-task-name').textContent,"
                " status: document.getElementById('ipromp-timeline-status').textContent,"
                " time: viewer.animator.time,"
                " rows: [...document.querySelectorAll('#ipromp-posterior tr')].map(r => r.textContent)})",
            )

        before = seek(0.3)
        assert (
            before["task"] == "(none yet: before the first re-plan at 0.60 s)"
            and "waits at rest" in before["status"]
        )
        first = seek(0.8)
        assert first["task"] == "handover_rod" and "committed" in first["status"]
        assert first["time"] == pytest.approx(0.8, abs=1e-6)  # meshcat's animation was moved too
        assert first["rows"][1] == "handover_rod0.700"
        refused = seek(1.7)
        assert "refused" in refused["status"] and "workspace: out" in refused["status"]
        last = seek(2.5)
        assert last["task"] == "handover_tape"
        # played to its end, the page's time is its stated duration, never beyond it
        browser.evaluate(
            session,
            "(() => { const a = viewer.animator; a.mixer.timeScale = 20; a.reset(); a.play(); return 1; })()",
        )
        browser.wait_for(session, "!viewer.animator.playing && viewer.animator.time > 3.5", timeout=30)
        head = browser.evaluate(session, "document.getElementById('ipromp-timeline-time').textContent")
        shown, total = (float(x) for x in re.match(r"Time (\d+\.\d+) s of (\d+\.\d+) s", head).groups())
        assert shown <= total and total == 4.0 and "human's" in head, head
        shot = browser.screenshot(session)
        assert shot.std() > 10.0
    finally:
        browser.close()
    assert np.isfinite(first["time"])
