"""A replay passes only when its committed motion did what it is for (issue 24, item 1): a replay
whose every re-plan was refused exits 3, and its reports say why."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from helpers_cli import PIPELINE, ROBOT_FILE, one_error_line

from ipromp_pin.app import main
from ipromp_pin.evaluation.scoring import ClosedLoopScore
from ipromp_pin.outputs.replay_report import replay_failures, replay_passed


def _score(**changes: object) -> ClosedLoopScore:
    base = dict(
        handover_error_cm=3.0, final_error_cm=2.0, arrival_delay_s=0.1, arrival_s=2.0,
        recorded_arrival_s=1.9, handover_time_s=3.0, rest_s=2.1, max_limit_ratio=0.8,
        limit_ratios=[0.8, 0.5, 0.4], position_excess_rad=0.0, collisions=0, replans=20,
        refused_replans=3, final_task="tape",
    )  # fmt: skip
    base.update(changes)
    return ClosedLoopScore(**base)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("changes", "failures"),
    [
        ({}, None),
        ({"refused_replans": 20}, ["no_committed_replan"]),
        ({"replans": 0, "refused_replans": 0}, ["no_committed_replan"]),
        ({"refused_replans": 19}, None),
        ({"refused_replans": 20, "collisions": 2}, ["no_committed_replan", "collisions"]),
        ({"max_limit_ratio": 1.5}, ["limits"]),
    ],
)
def test_replay_without_a_committed_replan_fails(changes, failures):
    score = _score(**changes)
    assert replay_failures(score) == failures
    assert replay_passed(score) == (failures is None)


def _robot_with_workspace(folder: Path, table: str) -> Path:
    text = ROBOT_FILE.read_text()
    start = text.index("[workspace]")
    end = text.index("[checks]")
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "robot.toml"
    path.write_text(text[:start] + "[workspace]\n" + table + "\n\n" + text[end:])
    return path


@pytest.mark.parametrize(
    "workspace",
    [
        'shape = "box"\nmin_m = [5.0, 5.0, 5.0]\nmax_m = [5.5, 5.5, 5.5]',
        'shape = "sphere"\ncenter_m = [-3.0, 0.0, 0.0]\nradius_m = 0.1',
    ],
)
@pytest.mark.parametrize("allow", [False, True])
def test_replay_whose_every_replan_was_refused_exits_3_and_says_why(tiny, tmp_path, capsys, workspace, allow):
    ds, model = tiny
    robot = _robot_with_workspace(tmp_path / "robot", workspace)
    out = tmp_path / "out"
    args = ["replay", str(PIPELINE), "--dataset", str(ds), "--model", str(model), "--robot", str(robot),
            "--out", str(out), "--no-preview"]  # fmt: skip
    code = main([*args, *(["--allow-failing-checks"] if allow else [])])
    assert code == 3
    line = one_error_line(capsys.readouterr().err)
    assert "no re-plan was committed" in line and "workspace" in line
    report = json.loads((out / "report.json").read_text())
    assert report["passed"] is False
    assert "no_committed_replan" in report["failures"]
    assert re.search(r"\d+ refused: workspace \d+", report["failure_reason"])
    assert report["committed_replans"] == 0
    assert "FAILED: no re-plan was committed" in (out / "report.txt").read_text()
    assert (out / "trajectory.csv").exists() == allow
    if allow:
        assert (
            (out / "trajectory.csv")
            .read_text()
            .startswith("# ipromp_pin: checks FAILED (no_committed_replan")
        )
