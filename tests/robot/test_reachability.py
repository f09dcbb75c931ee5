"""The reachability of recorded hand-over poses at a base placement and the placement search
(``ipromp_pin.robot.reachability``, behind ``ipromp-pin place`` and ``benchmarks/placement.py``)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from ipromp_pin.exceptions import DataError, RobotError
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import build_robot, load_robot, load_robot_settings
from ipromp_pin.robot.arm_transfer import TOL_M, TOL_RAD, PoseSolver
from ipromp_pin.robot.reachability import (
    PlacementGrid,
    ReachTest,
    handover_poses,
    search_placement,
    with_pose,
    write_placement,
)
from ipromp_pin.robot.settings import ROBOTS_DIR


@pytest.fixture(scope="module")
def poses():
    return handover_poses(load_robot("baxter_left"), make_synthetic_dataset(n_demos=4).all_demos())


def test_a_placement_tested_through_the_poses_equals_the_arm_built_at_that_placement(poses):
    s = load_robot_settings("ur5")
    test = ReachTest(s)
    moved = with_pose(s.placement, 0.25, -0.1, -0.1, 30.0)
    r = test.reach(poses, moved)
    # independently: the UR5 built at that placement, its own inverse kinematics on the scene poses
    arm = build_robot(dataclasses.replace(s, placement=moved), collision=False)
    solver = PoseSolver(arm)
    reached = 0
    for pose in poses:
        q, ep, er, _ = solver.first(pose, None)
        reached += ep <= TOL_M and er <= TOL_RAD
    assert r is not None and r.n_poses == len(poses) and r.n_reached == reached
    assert r.max_residual_mm <= TOL_M * 1e3 and r.max_residual_deg <= np.degrees(TOL_RAD)


def test_poses_beyond_the_arm_s_chain_are_missed_and_the_bound_stops_early(poses):
    s = load_robot_settings("panda")
    test = ReachTest(s)
    far = with_pose(s.placement, -2.0, 0.0, 0.0, 0.0)
    r = test.reach(poses, far)
    assert r is not None and r.n_reached == 0 and r.worst_miss_mm > 500
    assert test.reach(poses, far, max_misses=2) is None


def test_the_search_never_suggests_fewer_poses_than_the_arm_s_own_placement(poses):
    s = load_robot_settings("xarm7")
    grid = PlacementGrid(x_m=(0.1, 0.4), y_m=(0.0, 0.3), z_m=(-0.1, 0.1))
    found = search_placement(s, poses, grid, refinements=1)
    assert found.at_suggested.n_reached >= found.at_current.n_reached
    assert found.at_suggested.key() >= found.at_current.key()
    # the suggestion is measured on every pose, as ReachTest measures it
    again = ReachTest(s).reach(poses, found.suggested)
    assert again == found.at_suggested
    x, y, z = found.suggested.xyz_m
    assert 0.1 <= x <= 0.4 and 0.0 <= y <= 0.3 and -0.1 <= z <= 0.1  # within the grid's region


def test_a_placement_out_of_reach_is_improved(poses):
    s = load_robot_settings("panda")
    far = dataclasses.replace(s, placement=with_pose(s.placement, -0.6, 0.2, -0.1, 0.0))
    grid = PlacementGrid(x_m=(0.2, 0.4), y_m=(0.0, 0.2), z_m=(0.1,))
    found = search_placement(far, poses, grid, refinements=0)
    assert found.at_current.n_reached == 0
    assert found.at_suggested.fraction == 1.0


def test_an_arm_without_placement_and_a_dataset_without_demos_are_refused(poses):
    with pytest.raises(RobotError, match="placement"):
        search_placement(load_robot_settings("baxter_left"), poses)
    with pytest.raises(DataError, match="no demos"):
        handover_poses(load_robot("baxter_left"), [])
    demo = make_synthetic_dataset(n_tasks=1, n_demos=2).all_demos()[0]
    six = tuple(f"j{i}" for i in range(6))
    short = dataclasses.replace(
        demo,
        groups={**demo.groups, "robot": np.zeros((demo.n_samples, 6))},
        channel_names={**demo.channel_names, "robot": six},
    )
    with pytest.raises(DataError, match="expected 7 joints"):
        handover_poses(load_robot("baxter_left"), [short])


def test_a_written_placement_loads_and_the_shipped_file_is_never_written(tmp_path):
    s = load_robot_settings("panda")
    moved = with_pose(s.placement, 0.125, -0.05, 0.0, -22.5)
    out = write_placement(s, moved, tmp_path / "panda_here.toml", ["a note"])
    back = load_robot_settings(out)
    np.testing.assert_allclose(back.placement.xyz_m, moved.xyz_m)
    np.testing.assert_allclose(back.placement.rpy_deg, moved.rpy_deg)
    assert back.arm_joints == s.arm_joints and back.effort_margin == s.effort_margin
    np.testing.assert_array_equal(back.workspace.max_m, s.workspace.max_m)
    assert "# a note" in out.read_text()
    arm = build_robot(back, collision=False)  # placed where the file says
    data = arm.model.createData()
    pin.framesForwardKinematics(arm.model, data, arm.q_neutral)
    np.testing.assert_allclose(
        data.oMf[arm.model.getFrameId("panda_link0")].translation, moved.xyz_m, atol=1e-12
    )
    before = (ROBOTS_DIR / "panda.toml").read_bytes()
    with pytest.raises(RobotError, match="shipped settings file is never changed"):
        write_placement(s, moved, ROBOTS_DIR / "panda.toml")
    assert (ROBOTS_DIR / "panda.toml").read_bytes() == before
