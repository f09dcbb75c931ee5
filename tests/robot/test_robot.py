"""Robot settings and model loading (robots/*.toml, ipromp_pin.robot.settings and .model)."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from ipromp_pin.exceptions import RobotError
from ipromp_pin.robot import (
    ROBOTS_DIR,
    build_robot,
    find_robot_data_dir,
    load_robot,
    load_robot_settings,
    map_recorded_joints,
)

LEFT = ROBOTS_DIR / "baxter_left.toml"


def _variant(tmp_path: Path, old: str, new: str, name: str = "bad.toml") -> Path:
    """Copy of the left-arm settings with one textual substitution (regex, first match)."""
    text = LEFT.read_text()
    changed, n = re.subn(old, new, text, count=1, flags=re.M)
    assert n == 1, f"pattern {old!r} not found"
    path = tmp_path / name
    path.write_text(changed)
    return path


def test_left_settings_load_and_describe_the_arm():
    s = load_robot_settings("baxter_left")
    assert s.arm_joints == ("left_s0", "left_s1", "left_e0", "left_e1", "left_w0", "left_w1", "left_w2")
    assert s.ee_parent_frame == "left_gripper"
    assert s.urdf_path.is_file() and s.srdf_path.is_file()
    assert str(find_robot_data_dir()) in str(s.urdf_path)
    assert np.all(s.acceleration_rad_s2 > 0) and np.all(s.jerk_rad_s3 > 0)


def test_load_robot_is_cached_and_reads_urdf_limits():
    robot = load_robot("baxter_left")
    assert load_robot(LEFT) is robot
    assert load_robot(robot.settings) is robot
    # a changed copy of the file's settings is its own robot, not the cached one
    from dataclasses import replace

    changed = replace(robot.settings, human=replace(robot.settings.human, speed_margin=0.0))
    other = load_robot(changed)
    assert other is not robot and other.settings.human.speed_margin == 0.0
    assert load_robot("baxter_left") is robot and load_robot(changed) is other
    assert robot.arm_q_index.shape == (7,)
    np.testing.assert_allclose(robot.velocity_rad_s, [1.5, 1.5, 1.5, 1.5, 4.0, 4.0, 4.0])
    assert robot.lower_rad[3] == pytest.approx(-0.05) and robot.upper_rad[3] == pytest.approx(2.618)
    # SRDF: 787 pairs, 240 disabled; only pairs the arm can move relative to each other are checked
    assert robot.n_pairs_total == 787 and robot.n_pairs_srdf_removed == 240
    assert 0 < robot.active_pair_ids.size < 787 - 240
    # non-arm joints held where the settings say
    q = robot.q_neutral
    idx = robot.model.joints[robot.model.getJointId("right_e1")].idx_q
    assert q[idx] == pytest.approx(1.855)
    assert robot.collision_model is not None


def test_right_arm_needs_only_a_settings_file():
    robot = load_robot("baxter_right")
    assert robot.joint_names[0] == "right_s0"
    assert robot.model.frames[robot.ee_parent_frame_id].name == "right_gripper"


def test_recorded_names_are_mapped_by_name_not_position():
    s = load_robot_settings("baxter_left")
    recorded = [
        "head_nod",
        "head_pan",
        "left_e0",
        "left_e1",
        "left_s0",
        "left_s1",
        "left_w0",
        "left_w1",
        "left_w2",
    ]
    idx = map_recorded_joints(s, recorded)
    assert [recorded[i] for i in idx] == list(s.arm_joints)
    with pytest.raises(RobotError, match="lack arm joints"):
        map_recorded_joints(s, recorded[:4])


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        (r'"left_w2"\]', '"left_wrist_roll"]', r"arm\.recorded_names\.left_w2.*not one of arm\.joints"),
        (r'parent_frame = "left_gripper"', 'parent_frame = "no_such_frame"', r"end_effector\.parent_frame"),
        (
            r"^acceleration_rad_s2 = .*$",
            "acceleration_rad_s2 = [1.0, 1.0, -1.0, 1.0, 1.0, 1.0, 1.0]",
            "negative",
        ),
        (r"^jerk_rad_s3 = .*$", "jerk_rad_s3 = 0.0", r"limits\.jerk_rad_s3.*zero"),
        (r"^jerk_rad_s3 = .*$", "jerk_rad_s3 = nan", r"limits\.jerk_rad_s3.*finite"),
        (r"^min_m = .*$", "min_m = [1.5, -0.45, -0.08]", r"workspace.*below"),
        (r"^right_e1 = .*$", "right_e1 = 5.0", r"fixed_joints\.right_e1.*outside"),
        (r"^right_e1 = .*$", "right_elbow = 1.0", r"fixed_joints\.right_elbow.*unknown joint"),
        (r"^position_margin_rad = .*$", "position_margin_rad = 2.0", r"position_margin_rad.*implausible"),
        (r'"left_s1", "left_e0"', '"left_e0", "left_s1"', "not in kinematic order"),
        (r'^urdf = ".*"$', 'urdf = "/abs/baxter.urdf"', "relative path"),
        (r'^urdf = ".*"$', 'urdf = "nowhere/baxter.urdf"', "file not found"),
        (
            r"^min_clearance_m = .*$",
            'min_clearance_m = 0.0\ndisabled_pairs = [["left_upper_elbow"]]',
            r"checks\.disabled_pairs.*\[link, link\]",
        ),
        (
            r"^min_clearance_m = .*$",
            'min_clearance_m = 0.0\ndisabled_pairs = [["head", "head"]]',
            r"checks\.disabled_pairs.*itself",
        ),
        (
            r"^min_clearance_m = .*$",
            'min_clearance_m = 0.0\ndisabled_pairs = [["head", "no_such_link"]]',
            r"checks\.disabled_pairs.*unknown link 'no_such_link'",
        ),
        (r'^frame = "ee"$', 'frame = "ee"\nrpy_deg = [0.0, 270.0, 0.0]', r"end_effector\.rpy_deg"),
    ],
)
def test_bad_settings_fail_clearly(tmp_path, old, new, message):
    path = _variant(tmp_path, old, new)
    with pytest.raises(RobotError, match=message) as info:
        load_robot(path, cache=False)
    assert "bad.toml" in str(info.value) or "baxter.urdf" in str(info.value)


def test_unknown_model_joint_fails_clearly(tmp_path):
    path = _variant(tmp_path, r'"left_w2"\]', '"left_wrist_roll"]')
    text = path.read_text().replace('left_w2 = "left_w2"', 'left_w2 = "left_wrist_roll"')
    path.write_text(text)
    with pytest.raises(RobotError, match=r"bad\.toml: field 'arm\.joints': unknown joint 'left_wrist_roll'"):
        load_robot(path, cache=False)


def test_placeholder_velocity_limit_in_urdf_is_rejected(tmp_path):
    """A URDF velocity that is a placeholder (like head_pan's 10000) must not be trusted."""
    share = find_robot_data_dir()
    urdf = share / "example-robot-data/robots/baxter_description/urdf/baxter.urdf"
    text = urdf.read_text()
    # give left_s0 the head's placeholder limit
    start = text.index('<joint name="left_s0"')
    end = text.index("</joint>", start)
    block = re.sub(r'velocity="[^"]*"', 'velocity="10000"', text[start:end])
    (tmp_path / "baxter.urdf").write_text(text[:start] + block + text[end:])
    shutil.copy(
        share / "example-robot-data/robots/baxter_description/srdf/baxter_manipulation.srdf", tmp_path
    )
    settings = LEFT.read_text()
    settings = settings.replace('package = "example-robot-data"', 'package = ""')
    settings = re.sub(r'^urdf = ".*"$', 'urdf = "baxter.urdf"', settings, count=1, flags=re.M)
    settings = re.sub(r'^srdf = ".*"$', 'srdf = "baxter_manipulation.srdf"', settings, count=1, flags=re.M)
    (tmp_path / "local.toml").write_text(settings)
    with pytest.raises(RobotError, match=r"left_s0.*velocity.*placeholder"):
        load_robot(tmp_path / "local.toml", cache=False)


def test_unknown_robot_name():
    with pytest.raises(RobotError, match="not found"):
        load_robot_settings("no_such_robot")


def test_kinematics_only_robot_has_no_collision_model():
    s = load_robot_settings("baxter_left")
    robot = build_robot(s, collision=False)
    assert robot.collision_model is None and robot.collision_data is None
    full = load_robot("baxter_left")
    np.testing.assert_array_equal(robot.q_neutral, full.q_neutral)
    np.testing.assert_array_equal(robot.arm_q_index, full.arm_q_index)
    assert robot.model.frames[robot.ee_frame_id].name == s.ee_frame


def test_panda_settings_describe_another_robot_without_code():
    """robots/panda.toml: a Franka Panda from example-robot-data, through the same schema as Baxter."""
    from ipromp_pin.motion.timing import time_path
    from ipromp_pin.motion.trajectory import JointLimits
    from ipromp_pin.robot import ee_positions
    from ipromp_pin.safety import CheckContext, CheckSuite

    panda = load_robot("panda")
    assert panda.joint_names == tuple(f"panda_joint{i}" for i in range(1, 8))
    assert np.allclose(panda.velocity_rad_s, [2.175] * 4 + [2.61] * 3)  # from the URDF (datasheet)
    ready = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785])
    # the hand's tool centre point at the ready pose: Franka's well-known (0.307, 0, 0.487) m from its
    # base, which its [placement] puts in Baxter's scene
    from ipromp_pin.robot.model import placement_pose

    tcp = placement_pose(panda.settings).act(np.array([0.307, 0.0, 0.487]))
    assert np.allclose(ee_positions(panda, ready[None])[0], tcp, atol=2e-3)
    reach = ready + np.array([0.3, 0.5, 0.0, 0.5, 0.0, 0.3, 0.0])
    path = ready + np.linspace(0.0, 1.0, 40)[:, None] * (reach - ready)
    traj, timing = time_path(path, JointLimits.from_robot(panda))
    assert timing.passed and 0.5 < traj.duration_s < 5.0
    path_checks = CheckSuite.build(panda, ["speed_limits", "joint_limits", "workspace", "self_collision"])
    report = path_checks.report(traj, CheckContext())
    # the workspace is the hand-over box of the scene the Panda is placed in: this path ends where it ends
    inside = panda.settings.workspace.contains(ee_positions(panda, traj.q[-1:])[0])
    assert [v.name for v in report if v.status == "fail"] == ([] if inside else ["workspace"]), report.lines()


def test_an_end_effector_rotation_turns_the_ee_frame_and_disabled_pairs_leave_the_collision_model(tmp_path):
    import pinocchio as pin

    base = load_robot(LEFT, cache=False)
    text = re.sub(
        r'^frame = "ee"$', 'frame = "ee"\nrpy_deg = [0.0, 90.0, 0.0]', LEFT.read_text(), count=1, flags=re.M
    )
    text = re.sub(
        r"^min_clearance_m = .*$",
        'min_clearance_m = 0.0\ndisabled_pairs = [["left_upper_elbow", "left_wrist"]]',
        text,
        count=1,
        flags=re.M,
    )
    (tmp_path / "turned.toml").write_text(text)
    turned = load_robot(tmp_path / "turned.toml", cache=False)
    for r in (base, turned):
        pin.framesForwardKinematics(r.model, r.data, r.q_neutral)
    a, b = base.data.oMf[base.ee_frame_id], turned.data.oMf[turned.ee_frame_id]
    np.testing.assert_allclose(b.translation, a.translation, atol=1e-12)  # same point
    np.testing.assert_allclose(b.rotation, a.rotation @ pin.rpy.rpyToMatrix(0.0, np.pi / 2, 0.0), atol=1e-12)

    def links(r):
        cm, _ = r.collision()
        return {frozenset(r.pair_links(k)) for k in range(len(cm.collisionPairs))}

    gone = links(base) - links(turned)
    assert gone == {frozenset({"left_upper_elbow", "left_wrist"})}
    assert turned.n_pairs_srdf_removed > base.n_pairs_srdf_removed
