"""Demonstrations without robot joints (issue 37 item 3): the robot side as a gripper pose path, the
``gripper`` group (x, y, z [m], qx, qy, qz, qw), read by name, checked and made sign-continuous; a
pose is never labelled as joint angles in [rad]."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from helpers_cli import one_error_line

from ipromp_pin.app import main
from ipromp_pin.data import GRIPPER, GRIPPER_CHANNELS, ROBOT, Demo, robot_side
from ipromp_pin.exceptions import DataError
from ipromp_pin.readers import load_dataset, read_demo, write_demo
from ipromp_pin.readers.plausibility import check_demo
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import forward_kinematics, load_robot
from ipromp_pin.robot.recordings import as_gripper_demo
from ipromp_pin.robot.rotations import geodesic_deg


@pytest.fixture(scope="module")
def baxter():
    return load_robot("baxter_left")


@pytest.fixture(scope="module")
def gripper_demo(baxter) -> Demo:
    return as_gripper_demo(make_synthetic_dataset(n_tasks=1, n_demos=2).all_demos()[0], baxter)


def _csv(path: Path, t: np.ndarray, columns: dict[str, np.ndarray]) -> Path:
    header = ["t", *columns]
    data = np.column_stack([t, *columns.values()])
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(",".join(header) + "\n" + "\n".join(",".join(f"{v:.9g}" for v in row) for row in data))
    return path


def _human_hand(t: np.ndarray) -> dict[str, np.ndarray]:
    return {f"/right_hand_1.{a}": 0.1 * np.sin(t + k) + 0.5 for k, a in enumerate("xyz")}


def _rotations_deg(q_xyzw_a: np.ndarray, q_xyzw_b: np.ndarray) -> np.ndarray:
    from ipromp_pin.signals.gripper import gripper_rotations

    pad = np.zeros((len(q_xyzw_a), 3))
    ra = gripper_rotations(np.hstack([pad, q_xyzw_a]))
    rb = gripper_rotations(np.hstack([pad, q_xyzw_b]))
    return np.array([geodesic_deg(a, b) for a, b in zip(ra, rb, strict=True)])


def test_a_gripper_group_is_read_by_name_checked_and_sign_continuous(tmp_path):
    t = np.arange(60) / 50.0
    angle = np.linspace(0.0, 2.0, t.size)  # about z: the scalar goes through 0 -> a sign flip, if left
    quat = np.column_stack([0 * angle, 0 * angle, np.sin(angle), np.cos(angle)])  # a 4 rad turn
    quat[1::2] *= -1.0  # every other sample negated (the same rotations)
    cols = {"gripper.qw": quat[:, 3], "gripper.z": 0.2 + 0 * t, "gripper.qx": quat[:, 0]}
    cols |= {"gripper.x": 0.8 + 0.1 * t, "gripper.qz": quat[:, 2], "gripper.y": 0.3 + 0 * t}
    cols |= {"gripper.qy": quat[:, 1], **_human_hand(t)}
    demo = read_demo(_csv(tmp_path / "give" / "d0.csv", t, cols), format="native")
    assert demo.channel_names[GRIPPER] == GRIPPER_CHANNELS
    g = demo.groups[GRIPPER]
    np.testing.assert_allclose(g[:, 0], 0.8 + 0.1 * t, atol=1e-8)
    np.testing.assert_allclose(np.linalg.norm(g[:, 3:], axis=1), 1.0, atol=1e-9)
    assert np.all(np.einsum("ij,ij->i", g[1:, 3:], g[:-1, 3:]) > 0.9)  # no jump between q and -q
    assert np.max(_rotations_deg(g[:, 3:], quat)) < 1e-4  # the same rotations
    assert robot_side([demo]) == GRIPPER


def test_a_gripper_demo_at_another_rate_is_resampled_as_poses(tmp_path, gripper_demo):
    t = np.arange(0.0, 2.0, 0.01)  # 100 Hz
    angle = np.linspace(0.0, 1.5, t.size)
    quat = np.column_stack([np.sin(angle) / np.sqrt(2), np.sin(angle) / np.sqrt(2), 0 * t, np.cos(angle)])
    cols = {f"gripper.{c}": v for c, v in zip("xyz", [0.7 + 0 * t, 0.2 * t, 0.3 + 0 * t], strict=True)}
    cols |= {f"gripper.{c}": quat[:, k] for k, c in enumerate(["qx", "qy", "qz", "qw"])}
    demo = read_demo(_csv(tmp_path / "give" / "d0.csv", t, cols | _human_hand(t)), format="native")
    assert demo.n_samples == 100  # at 50 Hz
    g = demo.groups[GRIPPER]
    np.testing.assert_allclose(np.linalg.norm(g[:, 3:], axis=1), 1.0, atol=1e-12)
    truth = np.interp(demo.t, t, angle)
    want = np.column_stack([np.sin(truth) / np.sqrt(2), np.sin(truth) / np.sqrt(2), 0 * truth, np.cos(truth)])
    assert np.max(_rotations_deg(g[:, 3:], want)) < 0.01
    np.testing.assert_allclose(g[:, 1], 0.2 * demo.t, atol=1e-9)


@pytest.mark.parametrize(
    ("change", "field", "words"),
    [
        (lambda c: c.update({"gripper.qw": 2 * c["gripper.qw"]}), "gripper/quaternion", "implausible"),
        (lambda c: c["gripper.qy"].__setitem__(7, np.nan), "gripper/qy", "NaN"),
        (
            lambda c: [c.pop(f"gripper.q{a}") for a in "xyzw"],
            "gripper",
            "needs the channels x, y, z, qx, qy, qz, qw",
        ),
        (lambda c: c.update({"gripper.x": 50.0 + 0 * c["gripper.x"]}), "gripper/position", "implausible"),
    ],
    ids=["non-unit", "nan", "position-only", "far"],
)
def test_a_bad_gripper_group_is_refused_naming_file_and_field(tmp_path, gripper_demo, change, field, words):
    d = gripper_demo
    cols = {f"gripper.{c}": d.groups[GRIPPER][:, k].copy() for k, c in enumerate(GRIPPER_CHANNELS)}
    change(cols)
    path = _csv(tmp_path / "give" / "d0.csv", d.t, cols | _human_hand(d.t))
    with pytest.raises(DataError) as err:
        read_demo(path, format="native")
    assert err.value.field == field and str(path) in str(err.value) and words in err.value.problem


def test_a_position_only_group_says_what_a_gripper_group_needs(tmp_path, gripper_demo):
    d = gripper_demo
    cols = {f"gripper.{c}": d.groups[GRIPPER][:, k] for k, c in enumerate("xyz")}
    with pytest.raises(DataError, match="no orientation"):
        read_demo(_csv(tmp_path / "give" / "d0.csv", d.t, cols | _human_hand(d.t)), format="native")


def _xyz_robot_dataset(root: Path, demo: Demo) -> Path:
    """The issue's human-human dataset: the giver's hand as x, y, z in a ``robot`` group."""
    for task in ("give", "take"):
        for i in range(2):
            cols = {f"robot.{c}": demo.groups[GRIPPER][:, k] + 0.01 * i for k, c in enumerate("xyz")}
            _csv(root / task / f"{task}_{i}.csv", demo.t, cols | _human_hand(demo.t + i))
    return root


def test_a_robot_group_of_x_y_z_hints_at_the_gripper_group(tmp_path, gripper_demo):
    root = _xyz_robot_dataset(tmp_path / "hh", gripper_demo)
    with pytest.raises(DataError) as err:
        load_dataset(root)  # the robot group read with Baxter's joints, as `train` does
    assert err.value.field == ROBOT and "'gripper' group" in err.value.problem
    assert "unknown joint name" not in err.value.problem


def test_robot_joints_never_labels_a_pose_as_joint_angles(tmp_path, gripper_demo):
    root = _xyz_robot_dataset(tmp_path / "hh", gripper_demo)
    with pytest.raises(DataError) as err:
        load_dataset(root, robot_joints=("x", "y", "z"))
    assert err.value.field == "robot_joints" and "not joints" in err.value.problem
    assert "'gripper' group" in err.value.problem
    d = gripper_demo
    posed = Demo("give", "d", "built", d.t, {ROBOT: d.groups[GRIPPER][:, :3]}, {ROBOT: ("x", "y", "z")})
    with pytest.raises(DataError, match="a pose, not joint angles in"):
        check_demo(posed)  # a Demo built in Python, checked as every reader checks it


def test_train_on_the_issue_s_dataset_stops_with_one_line_naming_the_gripper_group(
    tmp_path, gripper_demo, capsys
):
    root = _xyz_robot_dataset(tmp_path / "hh", gripper_demo)
    code = main(["train", str(root), "--observe", "/right_hand_1", "--out", str(tmp_path / "m.npz")])
    assert code == 2
    line = one_error_line(capsys.readouterr().err)
    assert "field 'robot'" in line and "'gripper' group" in line and "x, y, z" in line


def test_synth_gripper_writes_baxter_s_gripper_path(tmp_path, baxter):
    out = tmp_path / "syn"
    assert main(["synth", str(out), "--gripper", "--tasks", "1", "--demos", "2", "--csv"]) == 0
    demo = load_dataset(out).all_demos()[0]
    assert ROBOT not in demo.groups and demo.channel_names[GRIPPER] == GRIPPER_CHANNELS
    joints = make_synthetic_dataset(n_tasks=1, n_demos=2).all_demos()[0]
    pose = forward_kinematics(baxter, joints.groups[ROBOT])
    np.testing.assert_allclose(demo.groups[GRIPPER][:, :3], pose[:, :3], atol=1e-9)
    assert np.max(_rotations_deg(demo.groups[GRIPPER][:, 3:], pose[:, 3:])) < 1e-4
    assert main(["synth", str(tmp_path / "p"), "--gripper", "--robot", "panda"]) == 2  # no joints to give


def test_write_and_read_back_a_gripper_demo(tmp_path, gripper_demo):
    for suffix in (".npz", ".csv"):
        back = read_demo(write_demo(gripper_demo, tmp_path / "give" / f"d{suffix}"), format="native")
        np.testing.assert_allclose(back.groups[GRIPPER], gripper_demo.groups[GRIPPER], atol=1e-9)
