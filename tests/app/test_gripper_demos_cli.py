"""Demonstrations without robot joints on the command line (issue 37 item 3): ``synth --gripper``
writes gripper demos, ``train`` fits a model of gripper poses, ``plan``/``run``/``replay`` execute it on
the arm they name (retargeted from the poses themselves), scored against the recorded gripper path."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers_cli import PIPELINE, one_error_line

from ipromp_pin.app import main
from ipromp_pin.promp import IProMP


@pytest.fixture(scope="module")
def gripper_data(tmp_path_factory):
    root = tmp_path_factory.mktemp("gripper")
    data, model = root / "data", root / "model.npz"
    assert main(["synth", str(data), "--gripper", "--demos", "8"]) == 0
    assert main(["train", str(data), "--holdout", "rod/0", "--out", str(model)]) == 0
    return root, data, model


def test_train_records_a_model_of_gripper_poses(gripper_data):
    _, _, model = gripper_data
    m = IProMP.load(model)
    assert m.robot_group == "gripper" and m.joint_names_[-1] == "qw"


def test_plan_on_the_panda_follows_the_predicted_poses_and_scores_them(gripper_data, capsys):
    root, data, model = gripper_data
    out = root / "plans"
    rec = data / "rod" / "rod_000.npz"
    assert main(["plan", str(model), str(rec), "--robot", "panda", "--out", str(out)]) == 0
    report = json.loads((out / "rod_000" / "report.json").read_text())
    assert report["passed"] and report["feasibility"]["robot"] == "panda"
    r = report["retarget"]
    assert r["source_path"] == "gripper_pose" and r["source_robot"] == "baxter_left" and r["reached"]
    assert 0 <= report["scores"]["handover_error_cm"] < 10  # against the recorded gripper pose path
    text = (out / "rod_000" / "report.txt").read_text()
    assert "retargeted through the gripper from a model of gripper poses" in text
    capsys.readouterr()
    assert main(["plan", str(model), str(rec), "--out", str(root / "none")]) == 2  # which arm?
    assert "--robot NAME" in one_error_line(capsys.readouterr().err)


@pytest.mark.parametrize(
    ("command", "arm"), [("run", "panda"), ("replay", "panda"), ("replay", "baxter_left")]
)
def test_run_and_replay_a_gripper_dataset_on_the_panda_and_baxter(gripper_data, command, arm):
    root, data, _ = gripper_data
    out = root / f"{command}_{arm}"
    args = [command, str(PIPELINE), "--dataset", str(data), "--robot", arm, "--out", str(out)]
    assert main([*args, "--no-preview"]) == 0
    report = json.loads((out / "report.json").read_text())
    if command == "run":
        assert report["retarget"]["source_path"] == "gripper_pose"
        assert all(v["status"] == "pass" for v in report["feasibility"]["checks"].values())
        assert np.isfinite(report["scores"]["handover_error_cm"])
    else:
        assert report["robot"] == arm and report["retarget"]["retargeted_replans"] > 0
        assert report["handover_error_cm"] < 10 and report["passed"]
        replans = json.loads((out / "replans.json").read_text())["replans"]
        moved = [r["retarget"] for r in replans if r["retarget"] is not None]
        assert moved and all(m["source_path"] == "gripper_pose" for m in moved)
