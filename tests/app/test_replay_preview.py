"""The replay's preview shows the replay report's figures on the human's clock: the commanded motion's
checks judged after the fact (``report.json``'s ``checks``: the torques with the true task's object,
the human checks against the recorded human) are the page's check list, separation and torque panels,
with the report's times; the time-scrubbing page ends where its stated duration does."""

from __future__ import annotations

import base64
import json
import re

import numpy as np
import pytest
import umsgpack
from helpers_cli import PIPELINE
from helpers_human import write_leaning_dataset

from ipromp_pin.app import main
from ipromp_pin.outputs.trajectory_files import read_trajectory_csv
from ipromp_pin.robot import load_robot

TIME = re.compile(r"t=(\d+\.\d+) s")


def page_data(html: str) -> tuple[dict, list[dict]]:
    """The timeline's data block and the recorded scene commands of a replay's ``preview.html``."""
    data = json.loads(html.split('id="ipromp-timeline-data">')[1].split("</script>")[0].replace("<\\/", "</"))
    scene = re.search(r'<script type="application/json" id="ipromp-scene">(.*?)</script>', html, re.S)
    assert scene is not None
    return data, [umsgpack.unpackb(base64.b64decode(c)) for c in json.loads(scene.group(1))]


def animation_end_s(commands: list[dict]) -> float:
    """The last keyframe time [s] of the page's meshcat animation."""
    (anim,) = [c for c in commands if c["type"] == "set_animation"]
    return max(
        k["time"] / a["clip"]["fps"]
        for a in anim["animations"]
        for tr in a["clip"]["tracks"]
        for k in tr["keys"]
    )


@pytest.fixture(scope="module")
def replayed(tmp_path_factory):
    folder = tmp_path_factory.mktemp("skeleton_dataset")
    tasks = write_leaning_dataset(folder, load_robot("baxter_left").settings.human)
    out = tmp_path_factory.mktemp("replay")
    args = ["replay", str(PIPELINE), "--dataset", str(folder), "--task", tasks[0], "--demo", "1"]
    assert main([*args, "--out", str(out), "--allow-failing-checks"]) in (0, 3)
    report = json.loads((out / "report.json").read_text())
    data, commands = page_data((out / "preview.html").read_text())
    return report, data, commands, read_trajectory_csv(out / "trajectory.csv")


def test_the_report_judges_the_commanded_motion_with_the_checks_it_states(replayed):
    report = replayed[0]
    checks = report["checks"]
    assert {"joint_torques", "human_clearance", "contact_speed"} <= set(checks)
    assert checks["human_clearance"]["human"] == "tracked"
    assert checks["human_clearance"]["min_separation_m"] == pytest.approx(report["human_min_separation_m"])
    assert checks["joint_torques"]["peak_torque_ratio"] == pytest.approx(report["peak_torque_ratio"])
    assert checks["contact_speed"]["n_speed_violations"] == report["contact_speed_violations"]


def test_every_checks_time_in_the_list_is_the_reports(replayed):
    report, data, _, traj = replayed
    rows = {c["name"]: c["detail"] for c in data["overlay"]["feasibility"]}
    timed = {n: c["t_s"] for n, c in report["checks"].items() if c.get("t_s") is not None}
    assert set(timed) == {"joint_torques", "human_clearance", "contact_speed"}
    for name, t in timed.items():
        assert set(TIME.findall(rows[name])) == {f"{t:.2f}"}, rows[name]
        assert np.min(np.abs(traj.t_s - t)) < 1e-6  # a sample of the commanded trajectory


def test_the_panels_state_the_reports_figures(replayed):
    report, data, _, _ = replayed
    checks = report["checks"]
    sep = data["overlay"]["separation"]
    stated = {r["check"]: r for r in sep["reported"]}
    clearance = stated["human_clearance"]
    assert clearance["value"] == pytest.approx(report["human_min_separation_m"], abs=1e-6)
    assert clearance["t_s"] == pytest.approx(checks["human_clearance"]["t_s"], abs=1e-6)
    assert clearance["text"] == checks["human_clearance"]["reason"]
    assert "recorded" in sep["source"] and "hand excluded" in sep["measure"]
    # the curve over the commanded motion: its smallest value is the report's, at the report's time
    d = np.array(sep["distance_m"])
    judged = np.array(sep["judged"])
    assert judged.any()
    assert d[judged].min() == pytest.approx(report["human_min_separation_m"], abs=1e-4)
    t = np.array(sep["t_s"])
    i = int(np.argmin(np.abs(t - checks["human_clearance"]["t_s"])))
    assert d[i] == pytest.approx(report["human_min_separation_m"], abs=1e-4)
    assert sep["link"][i] == checks["human_clearance"]["link"]
    assert sep["body_part"][i] == checks["human_clearance"]["body_part"]
    tq = data["overlay"]["torques"]
    peak = {r["check"]: r for r in tq["reported"]}["joint_torques"]
    assert peak["value"] == pytest.approx(report["peak_torque_ratio"], abs=1e-6)
    assert peak["t_s"] == pytest.approx(checks["joint_torques"]["t_s"], abs=1e-6)
    assert np.max(tq["ratio"]) == pytest.approx(report["peak_torque_ratio"], abs=6e-4)


def test_the_shown_time_ends_at_the_shown_duration_on_the_humans_clock(replayed):
    report, data, commands, traj = replayed
    # the page's last time: the later of the commanded motion's end and the human's recorded motion
    assert data["duration_s"] == pytest.approx(max(traj.t_s[-1], report["handover_time_s"]), abs=1e-6)
    assert animation_end_s(commands) == pytest.approx(data["duration_s"], abs=1e-9)
    assert data["motion_s"] == pytest.approx(report["handover_time_s"])
    assert "human's motion" in data["overlay"]["timebase"]
