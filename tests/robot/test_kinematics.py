"""FK and calibration (ipromp_pin.robot: kinematics, calibration)."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from ipromp_pin.data import ROBOT, Demo
from ipromp_pin.exceptions import DataError
from ipromp_pin.robot import ROBOTS_DIR, load_robot
from ipromp_pin.robot.calibration import (
    calibrate_tool_offset,
    endpoint_residuals_mm,
    uncalibrated_robot,
    write_calibration,
)
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
