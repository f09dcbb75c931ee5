"""A gripper the URDF does not describe (``[tool]``): its tool centre point is the ``ee`` frame, its
cylinder is in the self-collision and human geometry, its mass in the joint torques (the package's and
the independent re-evaluation's), and the preview draws it."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from ipromp_pin.evaluation.independent import UrdfArm
from ipromp_pin.exceptions import RobotError
from ipromp_pin.human.robot_capsules import arm_kinematics, fit_robot_capsules
from ipromp_pin.outputs.torque_preview import held_object
from ipromp_pin.robot import ROBOTS_DIR, load_robot, load_robot_settings
from ipromp_pin.robot.collision import in_collision
from ipromp_pin.robot.dynamics import ArmDynamics
from ipromp_pin.robot.kinematics import frame_placements
from ipromp_pin.robot.model import TOOL_GEOMETRY
from ipromp_pin.robot.objects import TaskObject

GRAVITY = np.array([0.0, 0.0, -9.81])


def _tool_block(text: str) -> str:
    """The ``[tool]`` table of a settings file's text, up to the next table."""
    found = re.search(r"(?ms)^\[tool\]\n.*?(?=^\[)", text)
    assert found is not None
    return found.group(0)


@pytest.fixture(scope="module")
def bare(tmp_path_factory) -> Path:
    """The shipped UR5 settings without their ``[tool]``: the flange is the ``ee`` frame."""
    text = (ROBOTS_DIR / "ur5.toml").read_text()
    path = tmp_path_factory.mktemp("bare") / "ur5_bare.toml"
    path.write_text(text.replace(_tool_block(text), ""))
    return path


def _configurations(robot, n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(robot.lower_rad, robot.upper_rad, size=(n, robot.n_joints))


@pytest.mark.parametrize("name", ["ur5", "xarm7"])
def test_the_ee_frame_is_the_tool_centre_point_along_the_flanges_z(name):
    robot = load_robot(name)
    tool = robot.settings.tool
    assert tool is not None and 0.1 < tool.length_m < 0.25
    q = _configurations(robot, 20)
    ee_pos, _ = frame_placements(robot, q)
    for k in range(len(q)):
        pin.framesForwardKinematics(robot.model, robot.data, robot.full_configuration(q[k]))
        flange = robot.data.oMf[robot.ee_parent_frame_id]
        expected = flange.translation + flange.rotation @ np.array([0.0, 0.0, tool.length_m])
        assert np.allclose(ee_pos[k], expected, atol=1e-9)


def test_the_tool_is_checked_against_the_links_it_can_reach(bare):
    robot, flange_only = load_robot("ur5"), load_robot(bare)
    cmodel, _ = robot.collision()
    names = [g.name for g in cmodel.geometryObjects]
    tool = names.index(TOOL_GEOMETRY)
    paired = {
        names[p.second if p.first == tool else p.first]
        for p in cmodel.collisionPairs
        if tool in (p.first, p.second)
    }
    assert "upper_arm_link_0" in paired and "wrist_3_link_0" not in paired and "wrist_2_link_0" not in paired
    # configurations in which only the gripper touches the arm: the bare flange is clear there
    q = _configurations(robot, 3000, seed=1)
    with_tool, without = in_collision(robot, q), in_collision(flange_only, q)
    assert not np.any(without & ~with_tool)
    assert np.count_nonzero(with_tool & ~without) >= 5


def test_the_human_checks_see_the_tool_as_a_capsule_from_the_flange_to_the_tool_centre_point():
    robot = load_robot("xarm7")
    caps = fit_robot_capsules(robot)
    k = caps.names.index(TOOL_GEOMETRY)
    assert caps.radius_m[k] == pytest.approx(robot.settings.tool.radius_m)
    q = _configurations(robot, 5)
    _, _, a, b = arm_kinematics(caps, q)
    ee_pos, _ = frame_placements(robot, q)
    ends = np.stack([a[:, k], b[:, k]], axis=1)  # (N, 2, 3)
    to_tip = np.min(np.linalg.norm(ends - ee_pos[:, None], axis=2), axis=1)
    assert np.all(to_tip < 1e-9)
    assert np.allclose(np.linalg.norm(a[:, k] - b[:, k], axis=1), robot.settings.tool.length_m)


def _gravity_torque_of_a_point(robot, q: np.ndarray, frame_point, mass: float) -> np.ndarray:
    """Joint torques holding ``mass`` [kg] at a point fixed to the ee parent frame (its axes)."""
    model, data = robot.model, robot.model.createData()
    full = robot.full_configuration(q)
    pin.computeJointJacobians(model, data, full)
    pin.updateFramePlacements(model, data)
    frame = data.oMf[robot.ee_parent_frame_id]
    jac = pin.getFrameJacobian(model, data, robot.ee_parent_frame_id, pin.LOCAL_WORLD_ALIGNED)
    lever = frame.rotation @ np.asarray(frame_point)
    lin = jac[:3] - np.cross(lever, jac[3:].T).T
    return (lin.T @ (-mass * GRAVITY))[robot.arm_v_index]


def test_the_tool_mass_adds_its_gravity_torque_and_an_object_is_held_at_the_tool_centre_point(bare):
    robot, flange_only = load_robot("ur5"), load_robot(bare)
    tool = robot.settings.tool
    q = _configurations(robot, 4, seed=2)
    arm = ArmDynamics(robot, springs=False)
    added = arm.torques(q) - ArmDynamics(flange_only, springs=False).torques(q)
    cup = TaskObject("cup", 0.5, np.zeros(3), np.zeros((3, 3)), "robot_gives")
    held = arm.torques(q, payload=cup) - arm.torques(q)
    for k in range(len(q)):
        centre = _gravity_torque_of_a_point(robot, q[k], [0.0, 0.0, 0.5 * tool.length_m], tool.mass_kg)
        tip = _gravity_torque_of_a_point(robot, q[k], [0.0, 0.0, tool.length_m], 0.5)
        assert np.allclose(added[k], centre, atol=1e-9)
        assert np.allclose(held[k], tip, atol=1e-9)
    assert np.max(np.abs(added)) > 0.5  # N m: a 0.9 kg gripper is felt
    drawn = held_object(robot, cup, 1.0)  # the preview draws the object where it is held
    assert drawn is not None and np.allclose(drawn.center_m, [0.0, 0.0, tool.length_m])


def test_the_independent_re_evaluation_adds_the_tool_too(bare):
    robot = load_robot("ur5")
    q = _configurations(robot, 6, seed=3)
    t = np.linspace(0.0, 1.0, len(q))
    qd = np.zeros_like(q)
    with_tool = UrdfArm("ur5").torque_ratios(t, q, qd, step=1)
    without = UrdfArm(bare).torque_ratios(t, q, qd, step=1)
    assert np.max(with_tool - without) > 0.005 and np.all(with_tool[:3] >= without[:3] - 0.1)
    geometry, _ = UrdfArm("ur5").geometry()
    assert TOOL_GEOMETRY in [g.name for g in geometry.geometryObjects]


def test_the_preview_draws_the_tool_once_from_the_mesh_cache(tmp_path, monkeypatch):
    from ipromp_pin.preview import mesh_cache

    monkeypatch.setenv("IPROMP_PIN_CACHE_DIR", str(tmp_path))
    robot = load_robot("xarm7")
    for _ in range(2):  # the second from the cache
        visual = mesh_cache.preview_visual_model(robot)
        tools = [g for g in visual.geometryObjects if g.name == TOOL_GEOMETRY]
        assert len(tools) == 1 and type(tools[0].geometry).__name__ == "Cylinder"


@pytest.mark.parametrize(
    ("line", "field", "problem"),
    [
        ("length_m = 0.9", "tool.length_m", r"\[0.01, 0.4\] m"),
        ("radius_m = 0.0", "tool.radius_m", r"\[0.01, 0.2\] m"),
        ("mass_kg = -1.0", "tool.mass_kg", r"\[0, 5\] kg"),
        ("lenght_m = 0.1", "tool.lenght_m", "length_m"),
        ('source = ""', "tool.source", "must not be empty"),
    ],
)
def test_a_bad_tool_is_refused_naming_the_file_and_field(tmp_path, line, field, problem):
    text = (ROBOTS_DIR / "ur5.toml").read_text()
    block = _tool_block(text)
    key = line.split("=")[0].strip()
    lines = [ln for ln in block.splitlines() if ln.split("=")[0].strip() != key.replace("lenght", "length")]
    bad = text.replace(block, "\n".join([*lines, line]) + "\n\n")
    path = tmp_path / "ur5_bad.toml"
    path.write_text(bad)
    with pytest.raises(RobotError) as err:
        load_robot_settings(path)
    message = str(err.value)
    assert str(path) in message and field in message and re.search(problem, message), message


def test_the_tool_centre_point_turns_with_the_ee_frames_rpy():
    ur5 = load_robot_settings("ur5")
    assert ur5.tool is not None
    rpy, offset = np.array([10.0, 80.0, -30.0]), np.array([0.01, -0.02, 0.03])
    turned = dataclasses.replace(ur5, ee_rpy_deg=rpy, tool_offset_m=offset)
    turn = pin.rpy.rpyToMatrix(*np.radians(rpy))
    expected = offset + turn @ np.array([0.0, 0.0, ur5.tool.length_m])
    assert np.allclose(turned.gripper_point_m, expected, atol=1e-12)
    assert np.allclose(turned.ee_turn, turn, atol=1e-12)
