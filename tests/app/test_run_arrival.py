"""``run`` says when the human and the robot reach the hand-over (issue 24, item 13), and the replay
preview's panel says what its times are on and what it recognised when (item 17)."""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import pytest
import umsgpack
from helpers_cli import PIPELINE, run_tiny

from ipromp_pin.app import main
from ipromp_pin.outputs.trajectory_files import read_trajectory_csv


def _panel(html: str) -> tuple[dict, dict]:
    """The preview page's panel state and its 3-D task label."""
    match = re.search(r'<script type="application/json" id="ipromp-scene">(.*?)</script>', html, re.S)
    assert match is not None
    commands = [umsgpack.unpackb(base64.b64decode(c)) for c in json.loads(match.group(1))]
    [state] = [c["state"] for c in commands if c["type"] == "ipromp_overlay"]
    [label] = [c for c in commands if c["type"] == "set_object" and c["path"] == "/meshcat/labels/task"]
    return state, label["object"]["textures"][0]


@pytest.mark.parametrize("ratio", ["0.15", "0.3", "0.7"])
def test_run_reports_the_human_and_robot_arrival_and_the_delay(tiny, tmp_path, ratio):
    out = tmp_path / "out"
    ds, model = tiny
    args = ["run", str(PIPELINE), "--dataset", str(ds), "--model", str(model), "--out", str(out)]
    preview = ratio == "0.3"  # the page's panel once; the other windows without the page
    assert main([*args, "--ratio", ratio, "--no-rosbag", *([] if preview else ["--no-preview"])]) == 0
    report = json.loads((out / "report.json").read_text())
    a = report["arrival"]
    t_s = read_trajectory_csv(out / "trajectory.csv").t_s  # on the human's clock
    assert a["human_s"] == pytest.approx(report["predicted_duration_s"])
    assert a["robot_start_s"] == pytest.approx(report["observed_until_s"]) == pytest.approx(t_s[0])
    assert a["robot_s"] == pytest.approx(t_s[-1], abs=1e-6)
    assert a["robot_s"] - a["robot_start_s"] == pytest.approx(report["trajectory"]["duration_s"], abs=1e-6)
    assert a["delay_s"] == pytest.approx(a["robot_s"] - a["human_s"])
    text = (out / "report.txt").read_text()
    when = "after" if a["delay_s"] >= 0 else "before"
    line = next(ln for ln in text.splitlines() if ln.startswith("Arrival"))
    assert f"human {a['human_s']:.2f} s (predicted)" in line and f"robot {a['robot_s']:.2f} s" in line
    assert line.endswith(f"{abs(a['delay_s']):.2f} s {when} the human")
    if preview:
        state, _ = _panel((out / "preview.html").read_text())
        assert line in state["notes"]


def test_run_without_preview_still_reports_the_arrival(tiny, tmp_path, capsys):
    assert run_tiny(tiny, tmp_path / "out") == 0
    assert "Arrival (from the start of the human's motion): human" in capsys.readouterr().out


def test_replay_preview_panel_names_its_time_base_and_the_final_task(tiny, tmp_path):
    out = tmp_path / "out"
    ds, model = tiny
    assert (
        main(["replay", str(PIPELINE), "--dataset", str(ds), "--model", str(model), "--out", str(out)]) == 0
    )
    report = json.loads((out / "report.json").read_text())
    state, label = _panel((out / "preview.html").read_text())
    assert state["timebase"].startswith("Times are on the human's motion")
    assert f"the robot starts at {report['start_s']:.2f} s" in state["timebase"]
    assert "robot trajectory" not in state["timebase"].lower()
    assert label["text"].startswith(f"final task: {report['final_task']}")
    script = Path(__file__).resolve().parents[2] / "ipromp_pin" / "preview" / "static" / "timeline.js"
    assert "none yet: before the first re-plan" in script.read_text()
