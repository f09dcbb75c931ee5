"""``ipromp-pin replay baxter_handover --robot panda``: the closed loop of the Baxter model drives a
Panda placed in the recordings' scene, every re-plan retargeted through the gripper (issue 37); the
commanded trajectory is re-evaluated here independently, from the Panda's URDF through Pinocchio; an
arm that cannot reach the recorded start is refused with exit 3 and one line."""

from __future__ import annotations

import csv
import json

import jsonschema
import numpy as np
import pytest
from helpers_cli import PIPELINE, one_error_line
from helpers_urdf import UrdfArm, panda_out_of_reach, written_joints

from ipromp_pin.app import main
from ipromp_pin.schemas import load_schema

PANDA_JOINTS = [f"panda_joint{i}" for i in range(1, 8)]


@pytest.fixture(scope="module")
def panda_replay(tmp_path_factory):
    out = tmp_path_factory.mktemp("panda_replay") / "out"
    code = main(["replay", str(PIPELINE), "--robot", "panda", "--out", str(out), "--no-preview"])
    return code, out


def test_replay_with_the_panda_commits_retargeted_re_plans_and_says_so(panda_replay):
    code, out = panda_replay
    assert code == 0
    replans = json.loads((out / "replans.json").read_text())
    report = json.loads((out / "report.json").read_text())
    jsonschema.Draft202012Validator(load_schema("replans")).validate(replans)
    jsonschema.Draft202012Validator(load_schema("replay_report")).validate(report)
    assert replans["robot"] == report["robot"] == "panda" and replans["source_robot"] == "baxter_left"
    assert report["tool"] is None  # the Panda's URDF has its hand
    # the demonstrated profile is Baxter's joints': the Panda runs its conservative one
    assert replans["limit_profile"]["name"] == "conservative"
    assert replans["limit_profile"]["joint_names"] == PANDA_JOINTS
    # the re-targets toward the hand-over (a stop on an unknown observation is the Panda's own motion)
    committed = [r for r in replans["replans"] if r["committed"] and not r["action"]]
    assert committed
    for r in committed:
        moved = r["retarget"]
        assert moved["source_robot"] == "baxter_left" and moved["reached"]
        assert moved["source_path"] == "joints"
        assert moved["ik_residual_mm"] <= 1.0 and moved["ik_residual_deg"] <= 0.5
        assert moved["ik_residual_mm"] <= moved["max_path_residual_mm"]
        assert r["stage_ms"]["arm_transfer"] > 0
    summary = report["retarget"]
    assert summary["source_robot"] == "baxter_left"
    assert summary["retargeted_replans"] >= len(committed)
    assert summary["ik_residual_mm"] == max(r["retarget"]["ik_residual_mm"] for r in committed)
    text = (out / "report.txt").read_text()
    assert "Executed by panda, every re-plan retargeted through the gripper from a model of" in text


def test_the_commanded_panda_trajectory_holds_the_urdf_s_limits_and_no_self_collision(panda_replay):
    code, out = panda_replay
    assert code == 0
    with (out / "trajectory.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [c[2:] for c in rows[0] if c.startswith("q.")] == PANDA_JOINTS
    _, q, qd = written_joints(out / "trajectory.csv", PANDA_JOINTS)
    arm = UrdfArm("panda")
    arm.assert_within_limits(q, qd)
    assert np.ptp(q, axis=0).max() > 0.05  # the Panda moved
    arm.assert_no_self_collision(arm.full(q))


def test_replay_on_an_arm_that_cannot_reach_the_recorded_start_is_refused_with_exit_3(tmp_path, capsys):
    far = panda_out_of_reach(tmp_path)
    out = tmp_path / "out"
    assert main(["replay", str(PIPELINE), "--robot", str(far), "--out", str(out), "--no-preview"]) == 3
    line = one_error_line(capsys.readouterr().err)
    assert "cannot reach the recorded start pose" in line and "mm" in line
    assert not (out / "trajectory.csv").exists()


def test_replay_with_the_six_joint_ur5_writes_its_preview_and_scores_against_baxter_s_gripper(tmp_path):
    out = tmp_path / "out"
    assert main(["replay", str(PIPELINE), "--robot", "ur5", "--out", str(out)]) == 0
    report = json.loads((out / "report.json").read_text())
    replans = json.loads((out / "replans.json").read_text())
    assert report["robot"] == "ur5" and report["retarget"]["source_robot"] == "baxter_left"
    assert report["tool"]["name"].startswith("Robotiq 2F-85")  # the gripper the checks saw
    assert len(replans["limit_profile"]["joint_names"]) == 6
    # scored against the recorded Baxter gripper in the scene frame: a finite error of centimetres
    assert 0.0 <= report["handover_error_cm"] < 10.0
    html = (out / "preview.html").read_text()
    assert "ipromp_pin replay" in html and "shoulder_pan_joint" in html


def test_replay_with_the_kinova_holds_the_urdf_s_limits_torques_and_no_self_collision(tmp_path):
    # the Jaco's continuous joints 1, 4 and 6 are one angle each in the commanded trajectory
    out = tmp_path / "out"
    assert main(["replay", str(PIPELINE), "--robot", "kinova_jaco2", "--out", str(out), "--no-preview"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["robot"] == "kinova_jaco2" and report["retarget"]["source_robot"] == "baxter_left"
    arm = UrdfArm("kinova_jaco2")
    t, q, qd = written_joints(out / "trajectory.csv", arm.names)
    assert np.ptp(q, axis=0).max() > 0.05  # the Jaco moved
    arm.assert_within_limits(q, qd)
    arm.assert_torques_within(t, q, qd)
    arm.assert_no_self_collision(arm.full(q))
