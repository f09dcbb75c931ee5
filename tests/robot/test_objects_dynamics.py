"""Task objects (robot/objects.py) and the arm's inverse dynamics with a payload (robot/dynamics.py)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from ipromp_pin.exceptions import RobotError
from ipromp_pin.robot import load_robot
from ipromp_pin.robot.dynamics import GRAVITY_M_S2, ArmDynamics
from ipromp_pin.robot.objects import DEFAULT_OBJECTS, TaskObject, box_inertia, load_objects


@pytest.fixture(scope="module")
def robot():
    return load_robot("baxter_left")


def point(mass: float, com=(0.0, 0.0, 0.0), holder: str = "robot_gives") -> TaskObject:
    return TaskObject("t", mass, np.asarray(com, float), np.zeros((3, 3)), holder)


def test_shipped_objects_cover_the_recordings_and_synthetic_tasks():
    table = load_objects()
    assert table.path == DEFAULT_OBJECTS
    for task in (
        "aluminum_hold",
        "spanner_handover",
        "tape_hold",
        "pincer",
        "screwdriver",
        "tape",
        "rod",
        "wrench",
    ):
        obj = table.for_task(task)
        assert obj is not None and 0 < obj.mass_kg < 2.2 and obj.source  # Baxter's payload: 2.2 kg
        assert np.all(np.linalg.eigvalsh(obj.inertia_kg_m2) > 0)
    assert table.for_task("spanner_handover").holder == "robot_gives"
    assert table.for_task("aluminum_hold").holder == "robot_receives"
    assert table.for_task("unknown") is None


def test_box_inertia_matches_pinocchio():
    size = np.array([0.1, 0.2, 0.3])
    np.testing.assert_allclose(box_inertia(2.0, size), pin.Inertia.FromBox(2.0, *size).inertia)


@pytest.mark.parametrize(
    ("body", "field", "problem"),
    [
        ("mass_kg = -1.0\nholder = 'robot_gives'", "t.mass_kg", "plausible range [0, 35] kg"),
        ("mass_kg = nan\nholder = 'robot_gives'", "t.mass_kg", "must be finite"),
        ("mass_kg = 1.0\ncom_m = [0.0, 0.0, 1.5]\nholder = 'robot_gives'", "t.com_m",
         "1.5 m (plausible range [0, 1] m"),
        ("mass_kg = 1.0\nholder = 'robot_gives'\ninertia_kg_m2 = [[1, 0, 0], [0, -1, 0], [0, 0, 1]]",
         "t.inertia_kg_m2", "positive definite"),
        ("mass_kg = 1.0\nholder = 'human'", "t.holder", "must be one of"),
        ("mass_kg = 1.0\nholder = 'robot_gives'\ncolour = 'red'", "t.colour", "unknown key"),
        ("mass_kg = 1.0\nholder = 'robot_gives'\nshape = { kind = 'sphere' }", "t.shape.kind", "box"),
    ],
)  # fmt: skip
def test_bad_object_files_name_file_field_and_problem(tmp_path, body, field, problem):
    f = tmp_path / "objects.toml"
    f.write_text(f"[t]\n{body}\n")
    with pytest.raises(RobotError) as exc:
        load_objects(f)
    msg = str(exc.value)
    assert str(f) in msg and f"field '{field}'" in msg and problem in msg and "\n" not in msg


def test_unknown_task_in_a_task_file_is_refused(tmp_path):
    f = tmp_path / "objects.toml"
    f.write_text(
        "[rod]\nmass_kg = 0.4\nholder = 'robot_receives'\n[hammer]\nmass_kg = 1\nholder = 'robot_gives'\n"
    )
    table = load_objects(f)
    with pytest.raises(RobotError, match=r"field 'hammer': unknown task 'hammer'"):
        table.check_tasks(["rod", "wrench"])


def test_held_at_follows_the_holder():
    t = np.array([0.0, 1.0, 2.0])
    assert point(1.0, holder="robot_gives").held_at(t, 1.0).tolist() == [True, True, False]
    assert point(1.0, holder="robot_receives").held_at(t, 1.0).tolist() == [False, True, True]


def test_rnea_of_a_static_pose_equals_pinocchio_gravity(robot):
    dyn = ArmDynamics(robot, springs=False)
    rng = np.random.default_rng(1)
    q = rng.uniform(robot.lower_rad + 0.1, robot.upper_rad - 0.1, (5, robot.n_joints))
    data = robot.model.createData()
    expected = np.array(
        [
            pin.computeGeneralizedGravity(robot.model, data, robot.full_configuration(x))[robot.arm_v_index]
            for x in q
        ]
    )
    np.testing.assert_allclose(dyn.torques(q), expected, atol=1e-9)
    # moving: the batched torques equal Pinocchio's RNEA of the full model, sample by sample
    qd, qdd = rng.normal(size=q.shape), rng.normal(size=q.shape)
    full = np.zeros((5, robot.model.nv))
    for i in range(5):
        v, a = full[i].copy(), full[i].copy()
        v[robot.arm_v_index], a[robot.arm_v_index] = qd[i], qdd[i]
        tau = pin.rnea(robot.model, data, robot.full_configuration(q[i]), v, a)[robot.arm_v_index]
        np.testing.assert_allclose(dyn.torques(q, qd, qdd)[i], tau, atol=1e-9)


def test_a_payload_raises_the_shoulder_torque_by_m_g_r(robot):
    dyn = ArmDynamics(robot, springs=False)
    q = np.zeros((1, robot.n_joints))
    mass = 1.5
    extra = dyn.torques(q, payload=point(mass))[0] - dyn.torques(q)[0]
    # lever arm of s1 (a horizontal axis): horizontal distance of the gripper from the s1 axis
    data = robot.model.createData()
    full = robot.full_configuration(q[0])
    pin.forwardKinematics(robot.model, data, full)
    pin.updateFramePlacements(robot.model, data)
    s1 = data.oMi[int(robot.arm_joint_ids[1])]
    grip = data.oMf[robot.ee_parent_frame_id].translation
    axis = s1.rotation[:, 2]
    # holding the weight F = (0, 0, -m g) at lever d needs tau = -axis . (d x F) = m g (axis x d)_z
    r = np.cross(axis, grip - s1.translation)
    expected = mass * GRAVITY_M_S2 * r[2]
    assert abs(expected) > 5.0  # a real lever arm
    assert extra[1] == pytest.approx(expected, rel=1e-6)
    # the springs only shift the torques (same payload effect)
    sprung = ArmDynamics(robot)
    diff = sprung.torques(q, payload=point(mass))[0] - sprung.torques(q)[0]
    np.testing.assert_allclose(diff, extra, atol=1e-9)
    assert sprung.torques(q)[0][1] != pytest.approx(dyn.torques(q)[0][1])


def test_baxter_effort_limits_are_read_from_the_urdf(robot):
    np.testing.assert_array_equal(ArmDynamics(robot).effort_limit_nm, [50, 50, 50, 50, 15, 15, 15])
    assert robot.settings.effort_margin == pytest.approx(0.1)


def test_payload_models_are_cached_by_content_not_by_object_id(robot):
    dyn = ArmDynamics(robot)
    q = np.zeros((1, robot.n_joints))
    torques = [dyn.torques(q, payload=point(m))[0, 1] for m in (0.5, 1.0, 2.0)]  # each object freed after use
    assert torques[0] != torques[1] != torques[2]
    assert torques[2] - torques[1] == pytest.approx(2 * (torques[1] - torques[0]))
