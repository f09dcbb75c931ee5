"""``ipromp-pin run baxter_handover --robot panda``: the Baxter model drives a Panda placed in the
recordings' scene, retargeted through the gripper (issue 37); the written trajectory is re-evaluated
here independently, from the URDF through Pinocchio; an arm placed out of reach is refused (exit 3)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from helpers_cli import PIPELINE, one_error_line

from ipromp_pin.app import main
from ipromp_pin.robot import load_robot_settings

ROBOTS = Path(__file__).resolve().parents[2] / "robots"


def written_joints(path: Path, names: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (N,) [s], positions and velocities (N, J) of trajectory.csv."""
    with path.open() as f:
        rows = list(csv.DictReader(f))
    t = np.array([float(r["time_s"]) for r in rows])
    q = np.array([[float(r[f"q.{n}"]) for n in names] for r in rows])
    qd = np.array([[float(r[f"qd.{n}"]) for n in names] for r in rows])
    return t, q, qd


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
    s = load_robot_settings("panda")
    model = pin.buildModelFromUrdf(str(s.urdf_path))
    names = list(s.arm_joints)
    t, q, qd = written_joints(out / "trajectory.csv", names)
    idx_q = [model.joints[model.getJointId(n)].idx_q for n in names]
    idx_v = [model.joints[model.getJointId(n)].idx_v for n in names]
    lo, hi = model.lowerPositionLimit[idx_q], model.upperPositionLimit[idx_q]
    assert np.all(q >= lo) and np.all(q <= hi)
    assert np.all(np.abs(qd) <= model.velocityLimit[idx_v] + 1e-9)
    full = np.tile(pin.neutral(model), (len(t), 1))
    full[:, idx_q] = q
    for name, value in s.fixed_joints.items():
        full[:, model.joints[model.getJointId(name)].idx_q] = value
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
    # self-collision: the URDF's collision geometry with the SRDF's disabled pairs removed
    geom = pin.buildGeomFromUrdf(model, str(s.urdf_path), pin.COLLISION, package_dirs=list(s.package_dirs))
    geom.addAllCollisionPairs()
    pin.removeCollisionPairs(model, geom, str(s.srdf_path))
    gdata = pin.GeometryData(geom)
    for k in range(0, len(t), 3):
        assert not pin.computeCollisions(model, data, geom, gdata, full[k], True), k


def test_an_arm_placed_out_of_reach_is_refused_with_exit_3_and_the_reason(tmp_path, capsys):
    text = (ROBOTS / "panda.toml").read_text()
    start, end = text.index("\n[placement]") + 1, text.index("[fixed_joints]")
    far = tmp_path / "panda_far.toml"
    far.write_text(
        text[:start] + '[placement]\nsource = "baxter_left"\nxyz_m = [-0.6, 0.2, -0.1]\n\n' + text[end:]
    )
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
