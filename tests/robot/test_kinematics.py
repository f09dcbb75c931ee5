"""FK, feasibility checks and calibration (ipromp_pin.robot: kinematics, checks, collision, calibration)."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from ipromp_pin.data import ROBOT, Demo
from ipromp_pin.exceptions import DataError, InfeasibleError
from ipromp_pin.robot import ROBOTS_DIR, load_robot
from ipromp_pin.robot.calibration import (
    calibrate_tool_offset,
    endpoint_residuals_mm,
    uncalibrated_robot,
    write_calibration,
)
from ipromp_pin.robot.checks import check_path
from ipromp_pin.robot.collision import check_self_collision
from ipromp_pin.robot.kinematics import forward_kinematics, frame_placements

# A typical hand-over start pose of the recordings and a pose with the forearm folded into the torso.
Q_START = np.array([-0.839, -0.969, 0.377, 1.262, -0.204, 1.189, 1.661])
Q_HANDOVER = np.array([-1.5, -0.498, 0.38, 0.64, -0.49, 0.946, 1.274])
Q_TORSO = np.array([0.13, 0.67, 0.13, 2.46, 1.71, 0.72, 0.57])


@pytest.fixture(scope="module")
def robot():
    return load_robot("baxter_left")


def _line(a, b, m=100):
    s = np.linspace(0, 1, m)[:, None]
    return a + s * (b - a)


def test_fk_format_and_calibrated_frame(robot):
    pose = forward_kinematics(robot, Q_START)
    assert pose.shape == (1, 7)
    assert np.linalg.norm(pose[0, 3:]) == pytest.approx(1.0)
    nominal = uncalibrated_robot(robot)
    p0 = forward_kinematics(nominal, Q_START)[0, :3]
    # the calibration moves the end-effector by the fitted ~10 mm, mostly down
    shift = pose[0, :3] - p0
    assert 0.007 < np.linalg.norm(shift) < 0.013
    assert shift[2] < -0.007


def test_typical_path_passes_every_check(robot):
    q = _line(Q_START, Q_HANDOVER)
    report = check_path(robot, q, q_std=np.full(7, 0.02), hand_position_m=None)
    assert report.passed, report.to_text()
    col = report["self_collision"].values
    assert col["min_distance_m"] > 0.01
    assert col["max_step_rad"] <= robot.settings.collision_max_step_rad + 1e-12
    assert report["hand_distance"].status == "skip"
    assert report["uncertainty"].required is False
    d = json.loads(json.dumps(report.to_dict()))
    assert d["passed"] is True and set(d["checks"]) >= {"joint_limits", "self_collision", "workspace"}
    assert "PASSED" in report.to_text()


def test_colliding_path_fails_and_names_the_links(robot):
    q = _line(Q_START, Q_TORSO)
    report = check_path(robot, q)
    assert not report.passed
    assert "self_collision" in report.failures
    col = report["self_collision"]
    assert col.measures.min_distance_m < 0
    # the folded end pose alone is in collision with the torso
    end = check_self_collision(robot, Q_TORSO[None])
    assert end.status == "fail" and "torso" in end.measures.links


def test_out_of_limit_path_fails_joint_limits(robot):
    q = _line(Q_START, Q_HANDOVER)
    q[60:, 3] = robot.lower_rad[3] - 0.01  # elbow beyond its lower limit
    report = check_path(robot, q)
    jl = report["joint_limits"]
    assert jl.status == "fail" and jl.measures.joint == "left_e1" and jl.measures.min_slack_rad < 0
    # within the hard limit but inside the margin also fails
    q2 = _line(Q_START, Q_HANDOVER)
    q2[-1, 3] = robot.lower_rad[3] + 0.5 * robot.settings.position_margin_rad[3]
    assert not check_path(robot, q2)["joint_limits"].passed


def test_workspace_and_hand_distance(robot):
    q = _line(Q_START, Q_HANDOVER)
    report = check_path(robot, q, hand_position_m=np.array([5.0, 0.0, 0.0]))
    assert report["hand_distance"].status == "fail"
    p = report.handover_pose[:3]
    near = check_path(robot, q, hand_position_m=p + [0.05, 0.0, 0.0])
    assert near["hand_distance"].status == "pass"
    assert near["hand_distance"].values["distance_m"] == pytest.approx(0.05, abs=1e-9)
    assert near["workspace"].passed
    # pointing the arm straight up leaves the hand-over workspace
    up = _line(Q_START, np.array([0.0, -1.5, 0.0, 0.0, 0.0, 0.0, 0.0]))
    assert check_path(robot, up)["workspace"].status == "fail"


def test_uncertainty_samples_are_advisory(robot):
    q = _line(Q_START, Q_HANDOVER)
    samples = np.stack([q, q + 0.01, _line(Q_START, Q_TORSO)])
    report = check_path(robot, q, q_samples=samples)
    unc = report["uncertainty"]
    assert unc.measures.n_in_collision == 1 and unc.status == "fail"
    assert report.passed  # advisory only


def test_bad_path_input_raises(robot):
    q = _line(Q_START, Q_HANDOVER)
    q[5, 2] = np.nan
    with pytest.raises(InfeasibleError, match="NaN"):
        check_path(robot, q)
    with pytest.raises(InfeasibleError, match="shape"):
        check_path(robot, np.zeros((10, 6)))


def test_calibration_recovers_a_known_offset(robot, tmp_path):
    """Synthetic end-points from a known mount + tool offset are recovered; the file round-trips."""
    nominal = uncalibrated_robot(robot)
    rng = np.random.default_rng(0)
    q = _line(Q_START, Q_HANDOVER, 60) + rng.normal(0, 0.2, (60, 7))
    q = np.clip(q, robot.lower_rad, robot.upper_rad)
    p, r = frame_placements(nominal, q, nominal.ee_parent_frame_id)
    mount, tool = np.array([0.002, -0.001, -0.01]), np.array([0.0, 0.003, 0.008])
    ep = np.hstack([p + mount + np.einsum("nij,j->ni", r, tool), np.tile([0, 0, 0, 1.0], (60, 1))])
    demo = Demo(
        "t",
        "d",
        "synthetic",
        np.arange(60) * 0.02,
        {ROBOT: q},
        {ROBOT: robot.joint_names},
        extras={"endpoint_pose": ep},
    )
    res = calibrate_tool_offset(robot, [demo], fit="both")
    np.testing.assert_allclose(res.mount_offset_m, mount, atol=1e-9)
    np.testing.assert_allclose(res.offset_m, tool, atol=1e-9)
    assert res.after_mm["max"] < 1e-6 and res.before_mm["median"] > 5
    settings = tmp_path / "copy.toml"
    shutil.copy(ROBOTS_DIR / "baxter_left.toml", settings)
    write_calibration(settings, res, "pytest")
    calibrated = load_robot(settings, cache=False)
    assert np.max(endpoint_residuals_mm(calibrated, demo)) < 1e-6
    assert 'calibrated_by = "pytest"' in settings.read_text()
    no_endpoints = Demo("t", "d", "x", demo.t, {ROBOT: q}, {ROBOT: robot.joint_names})
    with pytest.raises(DataError, match="endpoint"):
        calibrate_tool_offset(robot, [no_endpoints])


@pytest.mark.realdata
@pytest.mark.parametrize("dataset", ["chen2017_dir", "handover2017_dir"])
def test_fk_matches_recorded_endpoints(robot, dataset, request):
    """FK of recorded joints vs Baxter's own end-point reports: < 2 mm median with the stored
    calibration; ~10 mm without it (a wrong frame or a missing calibration would be caught)."""
    from ipromp_pin.readers import load_dataset

    ds = load_dataset(request.getfixturevalue(dataset))
    demos = [d for task in ds.demos.values() for d in task[:6]]
    nominal = uncalibrated_robot(robot)
    after = np.concatenate([endpoint_residuals_mm(robot, d) for d in demos])
    before = np.concatenate([endpoint_residuals_mm(nominal, d) for d in demos])
    assert np.median(after) < 2.0, np.median(after)
    assert 7.0 < np.median(before) < 14.0, np.median(before)
    # a fresh fit on these demos agrees with the stored one within a few mm
    res = calibrate_tool_offset(robot, demos)
    assert np.linalg.norm(res.mount_offset_m - robot.settings.mount_offset_m) < 0.003
    assert res.after_mm["median"] < 2.0


@pytest.mark.realdata
def test_recorded_handover_paths_are_feasible(robot, chen2017_dir):
    from ipromp_pin.readers import load_dataset

    ds = load_dataset(chen2017_dir)
    for task, demos in ds.demos.items():
        q = demos[0].groups[ROBOT]
        report = check_path(robot, q)
        assert report["self_collision"].passed and report["workspace"].passed, (task, report.to_text())
