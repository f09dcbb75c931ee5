"""``ipromp-pin run baxter_handover --robot panda``: the Baxter model drives a Panda placed in the
recordings' scene, retargeted through the gripper (issue 37); the written trajectory is re-evaluated
here independently, from the URDF through Pinocchio; an arm placed out of reach is refused (exit 3)."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest
from helpers_cli import PIPELINE, one_error_line
from helpers_urdf import UrdfArm, panda_out_of_reach, written_joints

from ipromp_pin.app import main


@pytest.fixture(scope="module")
def panda_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("panda") / "out"
    code = main(["run", str(PIPELINE), "--robot", "panda", "--out", str(out), "--no-preview", "--no-retreat"])
    return code, out


def test_run_with_the_panda_passes_and_reports_the_retargeting(panda_run):
    code, out = panda_run
    assert code == 0
    report = json.loads((out / "report.json").read_text())
    assert report["feasibility"]["robot"] == "panda"
    r = report["retarget"]
    assert r["source_robot"] == "baxter_left" and r["reached"]
    assert 0 <= r["ik_residual_mm"] <= 1.0 and r["ik_residual_deg"] <= 0.5
    assert r["ik_residual_mm"] <= r["max_path_residual_mm"] <= 1.0
    text = (out / "report.txt").read_text()
    assert "Executed by panda, retargeted through the gripper from a model of baxter_left" in text


def test_the_written_panda_trajectory_holds_the_urdf_s_limits_torques_and_no_self_collision(panda_run):
    code, out = panda_run
    assert code == 0
    arm = UrdfArm("panda")
    model, idx_v = arm.model, arm.idx_v
    t, q, qd = written_joints(out / "trajectory.csv", arm.names)
    arm.assert_within_limits(q, qd)
    full = arm.full(q)
    # torques of the arm alone (no object) from finite-difference accelerations, under the limits
    data = model.createData()
    qdd = np.gradient(qd, t, axis=0)
    effort = model.effortLimit[idx_v]
    for k in range(0, len(t), 5):
        v = np.zeros(model.nv)
        a = np.zeros(model.nv)
        v[idx_v], a[idx_v] = qd[k], qdd[k]
        tau = pin.rnea(model, data, full[k], v, a)[idx_v]
        assert np.all(np.abs(tau) <= effort), (k, tau)
    arm.assert_no_self_collision(full)


def test_an_arm_placed_out_of_reach_is_refused_with_exit_3_and_the_reason(tmp_path, capsys):
    far = panda_out_of_reach(tmp_path)
    out = tmp_path / "out"
    code = main(["run", str(PIPELINE), "--robot", str(far), "--out", str(out), "--no-preview"])
    assert code == 3
    line = one_error_line(capsys.readouterr().err)
    assert "cannot reach the hand-over pose at its placement" in line and "mm" in line
    assert not (out / "trajectory.csv").exists()


def test_synth_on_the_panda_then_run_trains_on_the_panda_s_own_demos(tmp_path):
    ds, out = tmp_path / "ds", tmp_path / "out"
    assert main(["synth", str(ds), "--tasks", "2", "--demos", "4", "--robot", "panda"]) == 0
    from ipromp_pin.readers import load_dataset

    names = tuple(f"panda_joint{i}" for i in range(1, 8))
    demos = load_dataset(ds, robot_joints=names).all_demos()
    assert len(demos) == 8 and all(d.channel_names["robot"] == names for d in demos)
    args = ["run", str(PIPELINE), "--dataset", str(ds), "--robot", "panda", "--out", str(out), "--no-preview"]
    assert main(args) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["retarget"] is None  # the model is the Panda's own: nothing to retarget
    assert report["feasibility"]["robot"] == "panda"


def test_synth_for_an_arm_without_placement_is_refused(tmp_path, capsys):
    assert (
        main(["synth", str(tmp_path / "ds"), "--tasks", "1", "--demos", "2", "--robot", "baxter_right"]) == 2
    )
    assert "has no [placement]" in one_error_line(capsys.readouterr().err)


def test_run_with_the_six_joint_ur5_writes_its_preview_with_baxter_s_recorded_gripper(tmp_path):
    # the preview's recorded gripper path is Baxter's joints through Baxter's kinematics (it failed
    # with "q: expected shape (M, 6), got (176, 7)" when drawn through the UR5's)
    out = tmp_path / "out"
    assert main(["run", str(PIPELINE), "--robot", "ur5", "--out", str(out), "--no-rosbag"]) == 0
    assert (out / "preview.html").read_text().startswith("<!DOCTYPE html>")
    assert json.loads((out / "report.json").read_text())["feasibility"]["robot"] == "ur5"
