"""``ipromp-pin run baxter_handover --robot panda`` (and the Kinova Jaco 2, whose continuous joints
the robot model bounds): the Baxter model drives an arm placed in the recordings' scene, retargeted
through the gripper (issue 37); the written trajectory is re-evaluated here independently, from the
URDF through Pinocchio; an arm placed out of reach is refused (exit 3)."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest
from helpers_cli import PIPELINE, one_error_line
from helpers_urdf import UrdfArm, panda_out_of_reach, written_joints

from ipromp_pin.app import main


@pytest.fixture(scope="module", params=["panda", "kinova_jaco2"])
def arm_run(request, tmp_path_factory):
    name = request.param
    out = tmp_path_factory.mktemp(name) / "out"
    code = main(["run", str(PIPELINE), "--robot", name, "--out", str(out), "--no-preview", "--no-retreat"])
    return name, code, out


def test_run_with_the_arm_passes_and_reports_the_retargeting(arm_run):
    name, code, out = arm_run
    assert code == 0
    report = json.loads((out / "report.json").read_text())
    assert report["feasibility"]["robot"] == name and report["feasibility"]["tool"] is None
    r = report["retarget"]
    assert r["source_robot"] == "baxter_left" and r["reached"]
    assert 0 <= r["ik_residual_mm"] <= 1.0 and r["ik_residual_deg"] <= 0.5
    assert r["ik_residual_mm"] <= r["max_path_residual_mm"] <= 1.0
    text = (out / "report.txt").read_text()
    assert f"Executed by {name}, retargeted through the gripper from a model of baxter_left" in text
    checks = report["feasibility"]["checks"]
    assert {"joint_limits", "self_collision", "human_clearance", "contact_speed", "joint_torques"} <= set(
        checks
    )
    assert all(v["status"] == "pass" for v in checks.values()), checks


def test_the_written_trajectory_holds_the_urdf_s_limits_torques_and_no_self_collision(arm_run):
    name, code, out = arm_run
    assert code == 0
    arm = UrdfArm(name)
    t, q, qd = written_joints(out / "trajectory.csv", arm.names)
    assert np.ptp(q, axis=0).max() > 0.05  # the arm moved
    arm.assert_within_limits(q, qd)
    arm.assert_torques_within(t, q, qd)
    arm.assert_no_self_collision(arm.full(q))


def test_the_kinova_s_continuous_joints_are_one_angle_each_within_two_turns():
    from ipromp_pin.robot import load_robot

    kinova, urdf = load_robot("kinova_jaco2"), UrdfArm("kinova_jaco2")
    assert kinova.model.nq == kinova.n_joints == 6 and sum(urdf.continuous) == 3  # joints 1, 4, 6
    for k, cont in enumerate(urdf.continuous):
        if cont:
            assert (kinova.lower_rad[k], kinova.upper_rad[k]) == (-2 * np.pi, 2 * np.pi)
    # the same kinematics as the URDF's (cos, sin) joints, at angles beyond half a turn too
    q = np.random.default_rng(0).uniform(kinova.lower_rad, kinova.upper_rad, size=(20, 6))
    data, udata = kinova.model.createData(), urdf.model.createData()
    tip = "j2s6s200_end_effector"
    for row, full in zip(kinova.full_configuration(q), urdf.full(q), strict=True):
        pin.framesForwardKinematics(kinova.model, data, row)
        pin.framesForwardKinematics(urdf.model, udata, full)
        # relative to the arm's base link: the package's model is built at its placement
        rel = data.oMf[kinova.model.getFrameId("j2s6s200_link_base")].actInv(
            data.oMf[kinova.model.getFrameId(tip)]
        )
        urel = udata.oMf[urdf.model.getFrameId("j2s6s200_link_base")].actInv(
            udata.oMf[urdf.model.getFrameId(tip)]
        )
        np.testing.assert_allclose(rel.homogeneous, urel.homogeneous, atol=1e-9)


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
    feasibility = json.loads((out / "report.json").read_text())["feasibility"]
    assert feasibility["robot"] == "ur5"
    # the gripper its URDF lacks, which the checks saw, is named in both reports
    assert feasibility["tool"]["name"].startswith("Robotiq 2F-85") and feasibility["tool"]["length_m"] > 0.1
    assert (
        "Feasibility (ur5 with Robotiq 2F-85 on its 8 mm coupling (0.158 m, 0.93 kg))"
        in (out / "report.txt").read_text()
    )


def test_a_pipeline_names_its_arm_once(arm_run, tmp_path):
    """pipelines/panda_handover.toml: the Panda named once, every other key the documented default;
    it plans what ``run baxter_handover --robot panda`` plans."""
    from ipromp_pin.app.config import load_pipeline

    name, code, out = arm_run
    if name != "panda":
        pytest.skip("the shipped pipeline is the Panda's")
    cfg, base = load_pipeline("panda_handover"), load_pipeline(str(PIPELINE))
    assert cfg.robot == "panda" and base.robot == "baxter_left"
    assert (cfg.task, cfg.demo, cfg.ratio, cfg.observe) == (base.task, base.demo, base.ratio, base.observe)
    mine = tmp_path / "out"
    assert main(["run", "panda_handover", "--out", str(mine), "--no-preview", "--no-retreat"]) == 0
    assert (mine / "trajectory.csv").read_text() == (out / "trajectory.csv").read_text()
