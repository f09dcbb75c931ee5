"""The pages the commands write agree with their reports, in a real browser (headless Chromium, as in
``test_preview_browser``; one browser for the module): ``run``'s separation panel states the report's
closest distance (the same figure, body parts and exclusion, and says which distance it shows), the
replay page's time never runs past its end, a replay that succeeded shows no red cross, the HTML
panel fits a 1280x800 window (it scrolls, and folds), and the live preview (``preview --port``)
streams only once a browser is connected, with its panel filled in."""

from __future__ import annotations

import json
import re
import socket
import threading
import time

import pytest
from helpers_cli import PIPELINE
from test_preview_browser import HEIGHT, Browser, find_chromium

from ipromp_pin.app import main
from ipromp_pin.app.config import load_pipeline
from ipromp_pin.app.preview import run_preview

pytestmark = pytest.mark.browser

SEEK = (
    "(() => { const a = viewer.animator; for (const x of a.actions) { x.enabled = true; x.paused = false;"
    " x.play(); } a.pause(); a.seek(T); a.display_progress(T); return 1; })()"
)
CROSS = '"\u2718 "'  # a failed row's mark (CSS: the escape eats one space)
FIGURE = re.compile(r"(\d+) mm \((\S+) - (\S+) at t=(\d+\.\d+) s\)")


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    profile = tmp_path_factory.mktemp("chromium_report") / "profile"
    profile.mkdir()
    chrome = Browser(find_chromium(), profile)
    yield chrome
    chrome.close()


def tiny_args(tiny) -> list[str]:
    ds, model = tiny
    return ["--dataset", str(ds), "--model", str(model), "--task", "rod", "--demo", "1"]


@pytest.fixture(scope="module")
def run_page(browser, tiny, tmp_path_factory):
    """(report.json, session) of ``run``'s page (its separation judged against the assumed human)."""
    out = tmp_path_factory.mktemp("run")
    assert main(["run", str(PIPELINE), *tiny_args(tiny), "--out", str(out), "--no-rosbag"]) == 0
    session = browser.open((out / "preview.html").as_uri())
    browser.wait_for(session, "window.iprompReady && window.iprompSeparationShown !== undefined")
    return json.loads((out / "report.json").read_text()), session


@pytest.fixture(scope="module")
def replay_page(browser, tiny, tmp_path_factory):
    """(report.json, session) of a replay's page."""
    out = tmp_path_factory.mktemp("replay")
    assert main(["replay", str(PIPELINE), *tiny_args(tiny), "--out", str(out)]) == 0
    session = browser.open((out / "preview.html").as_uri())
    browser.wait_for(session, "window.iprompReady && window.iprompTimeline !== undefined")
    return json.loads((out / "report.json").read_text()), session


def text(browser: Browser, session: str, selector: str) -> str:
    return browser.evaluate(session, f"document.querySelector({json.dumps(selector)}).textContent")


def test_the_run_panel_states_the_reports_closest_distance(browser, run_page):
    report, session = run_page
    check = report["feasibility"]["checks"]["human_clearance"]
    stated = text(browser, session, '#ipromp-separation-key [data-check="human_clearance"]')
    found = FIGURE.search(stated)
    assert found is not None, stated
    mm, link, part, t = found.groups()
    assert int(mm) == round(check["min_separation_m"] * 1e3)
    assert (link, part, float(t)) == (check["link"], check["body_part"], check["t_s"])
    assert "hand excluded" in stated
    # the panel says which distance its per-sample value is: the check's, hand excluded
    key = text(browser, session, "#ipromp-separation-key")
    assert "human_clearance's measure" in key and "hand excluded" in key
    # at the report's time (on the one clock, the human's) the per-sample value is the report's figure
    t_s = check["t_s"]
    browser.evaluate(session, SEEK.replace("T", str(t_s)))
    browser.wait_for(session, f"window.iprompSeparationShown.t_s === {t_s}", timeout=30)
    now = text(browser, session, "#ipromp-separation-now")
    assert now.startswith(
        f"t = {t_s:.2f} s: Separation {check['min_separation_m']:.3f} m ({link} to {part})"
    ), now


def test_the_panel_fits_a_1280x800_window_and_folds(browser, run_page, replay_page):
    for _, session in (run_page, replay_page):
        box = browser.evaluate(
            session,
            "(() => { const o = document.getElementById('ipromp-overlay').getBoundingClientRect();"
            " const t = document.getElementById('ipromp-timeline');"
            " return {bottom: o.bottom, right: o.right, below: t ? t.getBoundingClientRect().top : null,"
            " page: document.documentElement.scrollHeight, inner: innerHeight}; })()",
        )
        assert box["inner"] == HEIGHT and box["page"] <= HEIGHT  # nothing hangs below the window
        assert box["bottom"] <= HEIGHT - 8 and box["right"] <= 400
        if box["below"] is not None:  # the replay's time panel is under it, not covered by it
            assert box["bottom"] <= box["below"]
    _, session = run_page
    # the run's panel is longer than the window: it scrolls inside itself
    assert browser.evaluate(
        session,
        "(() => { const o = document.getElementById('ipromp-overlay');"
        " return o.scrollHeight > o.clientHeight && getComputedStyle(o).overflowY === 'auto'; })()",
    )
    browser.evaluate(session, "document.getElementById('ipromp-collapse').click()")
    folded = browser.evaluate(
        session,
        "[document.getElementById('ipromp-overlay').getBoundingClientRect().height,"
        " getComputedStyle(document.getElementById('ipromp-feasibility')).display,"
        " document.getElementById('ipromp-task-name').textContent]",
    )
    assert folded[0] < 150 and folded[1] == "none" and folded[2] == report_task(run_page[0])
    browser.evaluate(session, "document.getElementById('ipromp-collapse').click()")
    assert text(browser, session, "#ipromp-collapse") == "Hide details"


def report_task(report: dict) -> str:
    return report["recognised_task"]


def test_a_succeeded_replay_shows_no_cross_and_its_refusals_neutrally(browser, replay_page):
    report, session = replay_page
    assert report["passed"] and report["committed_replans"] > 0
    rows = browser.evaluate(
        session,
        "[...document.querySelectorAll('#ipromp-feasibility li')].map(e =>"
        " [e.dataset.check, e.className, getComputedStyle(e, '::before').content, e.textContent])",
    )
    assert rows and not [r for r in rows if r[2] == CROSS or r[1] == "fail"], rows
    (replans,) = [r for r in rows if r[0] == "re-plans"]
    assert replans[1] == "info" and f"{report['refused_replans']} refused" in replans[3]


def test_the_replay_time_never_passes_its_end(browser, replay_page):
    report, session = replay_page
    # every time the page shows while it plays to its end (5x real time), recorded as it changes
    browser.evaluate(
        session,
        "(() => { const h = document.getElementById('ipromp-timeline-time'); window.shownTimes = [];"
        " new MutationObserver(() => window.shownTimes.push(h.textContent))"
        ".observe(h, {childList: true, characterData: true, subtree: true});"
        " const a = viewer.animator; a.mixer.timeScale = 5; a.reset(); a.play(); return 1; })()",
    )
    browser.wait_for(session, "!viewer.animator.playing && window.shownTimes.length >= 2", timeout=60)
    end = browser.evaluate(session, "window.shownTimes[window.shownTimes.length - 1]")
    # the slider dragged to its end, and the animation sought past it
    browser.evaluate(
        session,
        "(() => { const s = document.getElementById('ipromp-timeline-slider'); s.value = '1000';"
        " s.dispatchEvent(new Event('input')); return 1; })()",
    )
    browser.evaluate(session, SEEK.replace("T", "viewer.animator.duration + 0.5"))
    browser.wait_for(session, "window.shownTimes.length >= 3")
    browser.evaluate(
        session, "new Promise(r => requestAnimationFrame(() => requestAnimationFrame(() => r(1))))"
    )
    shown = browser.evaluate(session, "window.shownTimes")
    pairs = [tuple(map(float, re.match(r"Time (\d+\.\d+) s of (\d+\.\d+) s", s).groups())) for s in shown]
    (total,) = {e for _, e in pairs}
    # the animation itself ends at the stated end
    assert browser.evaluate(session, "viewer.animator.duration") == pytest.approx(total, abs=0.006)
    assert max(t for t, _ in pairs) <= total and end.startswith(f"Time {total:.2f} s of"), shown
    # the end is the later of the robot's rest and the human's recorded motion, on the human's clock
    assert total == pytest.approx(max(report["rest_s"], report["handover_time_s"]), abs=0.011)
    assert "human's clock" in end


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_the_live_preview_streams_to_a_connected_page_with_its_panel(browser, tiny):
    ds, model = tiny
    cfg = load_pipeline(PIPELINE, dataset=ds, load_model=model, task="rod", demo=1)
    lines: list[str] = []
    worker = threading.Thread(
        target=run_preview,
        args=(cfg,),
        kwargs={
            "port": free_port(),
            "wait": False,
            "log": lines.append,
            "wait_for_page": True,
            "page_timeout_s": 120.0,
        },  # fmt: skip
        daemon=True,
    )
    worker.start()
    deadline = time.monotonic() + 120
    while not any("live at" in ln for ln in lines) and time.monotonic() < deadline:
        time.sleep(0.1)
    (url,) = [re.search(r"http://\S+/", ln).group(0) for ln in lines if "live at" in ln]
    time.sleep(1.0)  # longer than the observation streams (0.6 s at real time)
    assert not [ln for ln in lines if ln.startswith("  t=")], lines  # nothing streamed to nobody
    session = browser.open(url)
    browser.wait_for(session, "window.iprompSynced && window.iprompSeparationShown !== undefined")
    panel = browser.evaluate(
        session,
        "[document.querySelectorAll('#ipromp-posterior tr').length,"
        " document.querySelectorAll('#ipromp-feasibility li').length,"
        " document.getElementById('ipromp-title').textContent,"
        " document.querySelector('#ipromp-separation-key [data-check=\"human_clearance\"]').textContent]",
    )
    assert panel[0] == 2 and panel[1] >= 8 and "rod" in panel[2] and "mm" in panel[3], panel
    worker.join(120)
    assert not worker.is_alive()
    connected = next(i for i, ln in enumerate(lines) if "a browser is connected" in ln)
    streamed = [i for i, ln in enumerate(lines) if ln.startswith("  t=")]
    assert streamed and min(streamed) > connected
    browser.call("Page.close", session=session)
