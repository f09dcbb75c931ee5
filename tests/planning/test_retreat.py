"""The retreat after the hand-over (planning/retreat.py, robot/retreat_target.py): where it ends, the
payload of the phase after the hand-over, its torque failure, the IK target, the slow-down re-timing,
and the bad-configuration errors (exit 2, one line, before anything is computed)."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from helpers_cli import one_error_line, run_tiny

from ipromp_pin.exceptions import RobotError
from ipromp_pin.motion.timing import time_path
from ipromp_pin.motion.trajectory import JointLimits, Trajectory
from ipromp_pin.planning.retreat import plan_retreat
from ipromp_pin.robot import ee_positions, frame_placements, load_robot
from ipromp_pin.robot.dynamics import ArmDynamics
from ipromp_pin.robot.objects import ObjectTable, TaskObject, load_objects
from ipromp_pin.robot.retreat_target import RetreatTarget, parse_retreat
from ipromp_pin.safety import Check, CheckContext, CheckSuite, Verdict

Q_START = np.array([-0.8, -0.9, 0.4, 1.3, -0.2, 1.2, 1.6])
Q_HANDOVER = np.array([-0.2, -0.4, 0.1, 0.8, 0.3, 0.9, 1.0])


@pytest.fixture(scope="module")
def robot():
    return load_robot("baxter_left")


@pytest.fixture(scope="module")
def approach(robot):
    """A stand-in for the one-shot plan: its trajectory (start -> hand-over, at rest), start time and task."""
    traj, _ = time_path(np.linspace(Q_START, Q_HANDOVER, 30), JointLimits.from_robot(robot), start_s=0.8)
    return SimpleNamespace(trajectory=traj, start_s=0.8, prediction=SimpleNamespace(task="t"))


def table(obj: TaskObject) -> ObjectTable:
    return ObjectTable(Path("objects.toml"), {obj.task: obj})


def obj(mass: float, holder: str, retreat: RetreatTarget | None = None) -> TaskObject:
    return TaskObject("t", mass, np.array([0.0, 0.0, 0.05]), np.eye(3) * 1e-3, holder, "", retreat)


def torque_checks(robot):
    return CheckSuite.build(robot, ["joint_limits", "self_collision", "joint_torques"])


def test_a_retreat_to_start_dwells_then_ends_at_rest_at_the_start(robot, approach):
    target = RetreatTarget("start", dwell_s=0.5)
    r = plan_retreat(robot, approach, target, torque_checks(robot), CheckContext())
    tr = r.trajectory
    np.testing.assert_allclose(tr.q[0], Q_HANDOVER, atol=1e-9)  # from the hand-over ...
    np.testing.assert_allclose(tr.q[-1], approach.trajectory.q[0], atol=1e-9)  # ... back to the start
    assert np.abs(tr.qd[-1]).max() < 1e-9 and np.abs(tr.qdd[-1]).max() < 1e-9
    assert tr.start_s == pytest.approx(r.start_s)  # on the human's clock, from the hand-over
    dwell = tr.t_s - r.start_s <= 0.5 + 1e-9
    assert np.count_nonzero(dwell) == 51  # 0.5 s at 100 Hz, then the motion's first sample (still there)
    assert np.abs(tr.q[dwell] - Q_HANDOVER).max() < 1e-12 and not tr.qd[dwell].any()
    assert np.all(np.diff(tr.t_s) > 0)
    assert r.start_s == pytest.approx(approach.trajectory.t_s[-1])
    assert r.passed, r.failures
    assert [c.name for c in r.checks] == ["joint_limits", "self_collision", "joint_torques"]
    assert r.timing_report is not None and r.timing_report.passed
    assert r.duration_s > 0.5 + 0.5  # the dwell, then a motion of the same length as the approach's
    doc = r.to_dict()
    assert doc["target"]["to"] == "start" and doc["passed"] and doc["n_samples"] == tr.n_samples


def test_the_payload_is_carried_only_after_a_robot_receives_hand_over(robot, approach):
    target = RetreatTarget("start", dwell_s=0.2)
    checks = torque_checks(robot)
    received = plan_retreat(
        robot,
        approach,
        target,
        checks,
        CheckContext(objects=table(obj(2.0, "robot_receives"))),
    )
    given = plan_retreat(
        robot, approach, target, checks, CheckContext(objects=table(obj(2.0, "robot_gives")))
    )
    assert received.payload is not None and received.payload.mass_kg == 2.0
    assert given.payload is None
    after = CheckContext(task="t", objects=table(obj(2.0, "robot_gives")), after_handover=True)
    assert after.carried_object() is None
    # the torques written: the given object's are the bare arm's (after the hand-over sample) ...
    dyn = ArmDynamics(robot)
    g = given.trajectory
    plain = dyn.torques(g.q, g.qd, g.qdd)
    np.testing.assert_allclose(given.trajectory.effort_nm[1:], plain[1:], atol=1e-6)
    # ... the received object's add its weight at every sample (2 kg at the gripper: several N m at s1)
    r = received.trajectory
    extra = np.abs(r.effort_nm - dyn.torques(r.q, r.qd, r.qdd))
    assert extra[:, 1].min() > 3.0
    ratio = {
        name: res.checks["joint_torques"].measures.peak_torque_ratio
        for name, res in (("received", received), ("given", given))
    }
    assert ratio["received"] > ratio["given"]  # (the given object still counts at the hand-over sample)


def test_the_retreat_is_timed_under_the_torques_of_its_payload(robot, approach, monkeypatch):
    import ipromp_pin.planning.timers as module

    seen = []
    real = module.time_path

    def spy(path, limits, **kw):
        seen.append(kw.get("torque"))
        return real(path, limits, **kw)

    monkeypatch.setattr(module, "time_path", spy)
    q = np.array([0.1, -0.3, 0.2, 0.9, 0.1, 0.8, 0.3])
    zero = np.zeros(7)
    dyn = ArmDynamics(robot)
    for holder, mass in (("robot_receives", 2.0), ("robot_gives", 0.0)):
        ctx = CheckContext(objects=table(obj(2.0, holder)))
        plan_retreat(robot, approach, RetreatTarget("start"), torque_checks(robot), ctx)
        torque = seen.pop()
        assert torque is not None  # toppra's joint-torque constraint, with the phase's payload:
        carried = obj(mass, "robot_receives") if mass else None
        expected = dyn.torques(q[None], None, None, carried)[0]
        np.testing.assert_allclose(torque.inverse_dynamics(q, zero, zero), expected, atol=1e-9)
    plan_retreat(robot, approach, RetreatTarget("start"), CheckSuite.build(robot, ["joint_limits"]))
    assert seen.pop() is None  # without the torque check, no torque constraint


def test_a_too_heavy_received_object_fails_the_retreats_torque_check(robot, approach):
    ctx = CheckContext(objects=table(obj(12.0, "robot_receives")))
    r = plan_retreat(robot, approach, RetreatTarget("start", dwell_s=0.0), torque_checks(robot), ctx)
    assert not r.passed and r.failures == ["joint_torques"]
    tq = r.checks["joint_torques"]
    assert "slowing down cannot help" in tq.reason and tq.slowdown is None


def test_a_position_target_is_reached_within_1_mm_with_the_hand_over_orientation(robot, approach):
    p_handover = ee_positions(robot, Q_HANDOVER)[0]
    goal = p_handover + np.array([-0.15, 0.05, 0.10])
    target = RetreatTarget("position", position_m=goal, dwell_s=0.3)
    r = plan_retreat(robot, approach, target, torque_checks(robot), CheckContext())
    assert r.ik is not None and r.ik.converged
    end, rot_end = frame_placements(robot, r.trajectory.q[-1])
    assert np.linalg.norm(end[0] - goal) < 1e-3
    _, rot_ho = frame_placements(robot, Q_HANDOVER)
    angle = math.acos(np.clip((np.trace(rot_ho[0].T @ rot_end[0]) - 1) / 2, -1, 1))
    assert math.degrees(angle) < 0.2
    assert r.to_dict()["ik_position_error_m"] < 1e-3 and r.passed


def test_an_unreachable_position_target_is_a_one_line_error(robot, approach):
    target = RetreatTarget(
        "position", position_m=np.array([1.5, 0.9, 0.8]), field="rod.retreat", path=Path("o.toml")
    )
    with pytest.raises(RobotError, match=r"o.toml: field 'rod.retreat.position_m': not reachable") as exc:
        plan_retreat(robot, approach, target)
    assert "\n" not in str(exc.value)


class _NeedsSlowerThan(Check):
    """Fails when a joint moves faster than ``limit`` [rad/s], asking for the slow-down that fits."""

    name = "speed_cap"
    limit = 0.3

    def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
        peak = float(np.abs(motion.qd).max())
        if peak <= self.limit:
            return Verdict(self.name, "pass", f"{peak:.2f} rad/s")
        return Verdict(self.name, "fail", f"{peak:.2f} rad/s", slowdown=peak / self.limit)


def test_a_check_asking_for_a_slower_retreat_gets_it_re_timed(robot, approach):
    target = RetreatTarget("start", dwell_s=0.2)
    fast = plan_retreat(robot, approach, target, CheckSuite([]))
    slow = plan_retreat(robot, approach, target, CheckSuite([_NeedsSlowerThan(robot)]))
    assert slow.passed and slow.slowdown > 1.0
    assert np.abs(slow.trajectory.qd).max() <= _NeedsSlowerThan.limit
    assert slow.duration_s > fast.duration_s + 0.5
    np.testing.assert_allclose(slow.trajectory.q[-1], Q_START, atol=1e-9)


def test_retreat_to_the_hand_over_itself_is_the_dwell_alone(robot, approach):
    r = plan_retreat(robot, approach, RetreatTarget("joints", joints_rad=Q_HANDOVER.copy(), dwell_s=0.3))
    assert r.timing_report is None and r.passed
    assert r.trajectory.n_samples == 31 and r.duration_s == pytest.approx(0.3)
    assert not r.trajectory.qd.any()


@pytest.mark.parametrize(
    "entry, field, problem",
    [
        ('"start"', "rod.retreat", "must be a table"),
        ('{ to = "home" }', "rod.retreat.to", 'must be "start"'),
        ('{ to = "start", speed = 1 }', "rod.retreat.speed", "unknown key"),
        ("{ joints_rad = [0.0, 1.0], position_m = [0.5, 0.2, 0.1] }", "rod.retreat", "exactly one of"),
        ("{ position_m = [0.5, 0.2] }", "rod.retreat.position_m", "list of 3 numbers"),
        ("{ position_m = [0.5, nan, 0.1] }", "rod.retreat.position_m", "must be finite"),
        (
            "{ position_m = [2.5, 0.0, 0.1] }",
            "rod.retreat.position_m",
            "2.502 m from the base frame's origin",
        ),
        ('{ joints_rad = [0.0, "a"] }', "rod.retreat.joints_rad", "must hold numbers"),
        ('{ to = "start", dwell_s = -1 }', "rod.retreat.dwell_s", "must be in [0, 10] s"),
    ],
)
def test_bad_retreat_entries_name_the_file_field_and_problem(tmp_path, entry, field, problem):
    path = tmp_path / "objects.toml"
    path.write_text(f"[rod]\nmass_kg = 0.4\nholder = 'robot_receives'\nretreat = {entry}\n")
    with pytest.raises(RobotError) as exc:
        load_objects(path)
    msg = str(exc.value)
    assert msg.startswith(f"{path}: field '{field}': ") and problem in msg and "\n" not in msg


@pytest.mark.parametrize(
    "joints, problem",
    [
        ("[0.0, 0.0, 0.0]", "has 3 angles, robot 'baxter_left' has 7 arm joints"),
        ("[0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0]", "left_e1 = 3.0000 rad outside its limits less the margin"),
    ],
)
def test_joint_targets_the_robot_cannot_take_are_refused(tmp_path, robot, joints, problem):
    path = tmp_path / "objects.toml"
    path.write_text(
        f"[rod]\nmass_kg = 0.4\nholder = 'robot_receives'\nretreat = {{ joints_rad = {joints} }}\n"
    )
    objects = load_objects(path)
    with pytest.raises(RobotError, match="field 'rod.retreat.joints_rad'") as exc:
        objects.check_robot(robot)
    assert problem in str(exc.value)


def test_the_shipped_tasks_retreat_to_their_start(robot):
    objects = load_objects()
    objects.check_robot(robot)
    for o in objects.objects.values():
        assert o.retreat is not None and o.retreat.kind == "start" and o.retreat.dwell_s == 0.5
    assert parse_retreat({"to": "start"}, Path("f"), "x.retreat").dwell_s == 0.5  # the documented default


def test_a_bad_retreat_config_exits_2_before_any_computation(tmp_path, tiny, capsys):
    objects = tmp_path / "objects.toml"
    objects.write_text(
        "[rod]\nmass_kg = 0.4\nholder = 'robot_receives'\nretreat = { joints_rad = [0.1, 0.2] }\n"
    )
    assert run_tiny(tiny, tmp_path / "out", "--objects", str(objects)) == 2
    line = one_error_line(capsys.readouterr().err)
    assert str(objects) in line and "rod.retreat.joints_rad" in line and "has 2 angles" in line
    assert not (tmp_path / "out").exists()


class _SlowNearHandover(Check):
    """A toy check: joint speeds at most ``bound`` [rad/s] within 0.3 rad of the hand-over (the retreat's
    first part), asking for the slow-down each sample needs there."""

    name = "slow_near"

    def __init__(self, robot, bound: float) -> None:
        super().__init__(robot)
        self.bound = bound

    def near(self, motion: Trajectory) -> np.ndarray:
        return np.linalg.norm(motion.q - Q_HANDOVER, axis=1) < 0.3

    def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
        speed = np.where(self.near(motion), np.max(np.abs(motion.qd), axis=1), 0.0)
        if speed.max() <= self.bound:
            return Verdict(self.name, "pass", "slow enough")
        need = np.maximum(speed / self.bound, 1.0)
        return Verdict(self.name, "fail", "too fast", slowdown=float(need.max()), local_slowdown=need)


def test_the_retreat_is_slowed_only_where_a_check_asks_after_its_dwell(robot, approach):
    target = RetreatTarget("start", dwell_s=0.5)
    free = plan_retreat(robot, approach, target, CheckSuite([]), CheckContext()).trajectory
    check = _SlowNearHandover(robot, 1.0)
    peak = float(np.abs(free.qd[check.near(free)]).max())
    check.bound = 0.5 * peak
    r = plan_retreat(robot, approach, target, CheckSuite([check]), CheckContext())
    tr = r.trajectory
    assert r.passed and np.abs(tr.qd[check.near(tr)]).max() <= 0.5 * peak
    dwell = tr.t_s - r.start_s <= 0.5 + 1e-9
    assert np.count_nonzero(dwell) == 51 and not tr.qd[dwell].any()  # the dwell is kept as it was
    np.testing.assert_allclose(tr.q[-1], free.q[-1], atol=1e-9)
    # slowed near the hand-over only: in less time than twice the motion (a uniform 2x slow-down)
    assert free.duration_s < tr.duration_s < 0.5 + 2.0 * (free.duration_s - 0.5) - 0.05
