"""The human checks (ipromp_pin.safety.human_clearance, contact_speed): a body part on the robot's
path fails human_clearance and passes once moved away; inside S_p the approach speed is held to the
body region's v_max = F / sqrt(mu k) with the effective mass at the contact point, and a too fast
approach asks for the slow-down that passes; without a human the assumed one is checked; ``run``
reports both checks (where and when) and a failing one exits 3; bad parameters exit 2."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from helpers_cli import ROBOT_FILE, one_error_line, run_tiny

from ipromp_pin import app as cli
from ipromp_pin.exceptions import RobotError
from ipromp_pin.human import BodyPart, HumanMotion
from ipromp_pin.human.geometry import segment_closest_points
from ipromp_pin.human.iso15066 import point_effective_mass_kg
from ipromp_pin.human.robot_capsules import arm_kinematics
from ipromp_pin.human.separation import SeparationAnalyser
from ipromp_pin.motion.trajectory import Trajectory
from ipromp_pin.robot import ee_positions, load_robot, load_robot_settings
from ipromp_pin.robot.human_settings import REGION_LIMITS
from ipromp_pin.safety import CheckContext
from ipromp_pin.safety.contact_speed import SLOWDOWN_MARGIN, ContactSpeed
from ipromp_pin.safety.human_clearance import HumanClearance

NAMES = ("left_s0", "left_s1", "left_e0", "left_e1", "left_w0", "left_w1", "left_w2")
QA = np.array([0.0, -0.6, 0.0, 1.2, 0.0, 0.6, 0.0])
QB = np.array([0.5, -0.2, 0.3, 0.7, 0.2, 0.9, 0.1])


def _motion(duration_s: float = 1.0, t0: float = 0.5) -> Trajectory:
    t = np.arange(0.0, duration_s + 1e-9, 0.01)
    s = t / duration_s
    q = QA + s[:, None] * (QB - QA)
    qd = np.tile((QB - QA) / duration_s, (t.size, 1))
    return Trajectory(t0 + t, q, qd, np.zeros_like(q), NAMES)


def _sphere_human(centre: np.ndarray, region: str, radius: float = 0.1) -> HumanMotion:
    """A single static body part: a sphere about one frame."""
    part = BodyPart("part", "/f", None, radius, region)
    return HumanMotion(
        np.zeros(1), ("/f",), np.asarray(centre, float).reshape(1, 1, 3), (part,), np.array([radius]),
        1.6, 0.15, static=np.array([True]),
    )  # fmt: skip


@pytest.fixture(scope="module")
def robot():
    return load_robot("baxter_left")


def test_a_body_part_on_the_path_fails_and_moved_away_passes(robot):
    motion = _motion()
    mid = ee_positions(robot, motion.q[50:51])[0]
    check = HumanClearance(robot)
    on_path = check.check(motion, CheckContext(human=_sphere_human(mid, "chest")))
    assert on_path.status == "fail" and on_path.measures.min_separation_m < 0
    assert on_path.measures.body_part == "part" and on_path.measures.human == "tracked"
    assert 0.5 < on_path.measures.t_s < 1.5 and on_path.measures.link
    away = check.check(motion, CheckContext(human=_sphere_human(mid + [3.0, 0.0, 0.0], "chest")))
    assert away.status == "pass" and away.measures.min_separation_m > 2.0
    assert away.measures.time_within_sp_s == 0.0
    # the hand region is not judged by the clearance (the hand-over contact is intended)
    hand = check.check(motion, CheckContext(human=_sphere_human(mid, "hand")))
    assert hand.status == "pass" and math.isinf(hand.measures.min_separation_m)


def test_contact_speed_bound_toward_a_hand_matches_the_formula(robot):
    motion = _motion(0.4)
    end = ee_positions(robot, motion.q[-1:])[0]
    centre = end + np.array([0.25, 0.0, 0.0])
    human = _sphere_human(centre, "hand")
    result = ContactSpeed(robot).check(motion, CheckContext(human=human))
    v = result.measures.to_dict()
    assert v["max_speed_ratio"] > 0 and v["region"] == "hand"
    hand = REGION_LIMITS["hand"]
    mu = 1.0 / (1.0 / hand.mass_kg + 1.0 / v["robot_mass_kg"])
    assert v["v_max_m_s"] == pytest.approx(2.0 * hand.force_n / math.sqrt(mu * hand.spring_n_m))
    # the effective mass is Pinocchio's at the robot's closest point, in the separation direction
    sep = SeparationAnalyser(robot).analyse(motion.t_s, motion.q, motion.qd, human)
    n, li, pi = np.unravel_index(int(np.argmax(sep.speed_ratio)), sep.speed_ratio.shape)
    caps = SeparationAnalyser(robot).capsules
    _, _, a, b = arm_kinematics(caps, motion.q[n : n + 1])
    axis_point, _, _ = segment_closest_points(a[0, li], b[0, li], centre, centre)
    u = (centre - axis_point) / np.linalg.norm(centre - axis_point)
    point = axis_point + caps.radius_m[li] * u
    joint = int(robot.arm_joint_ids[caps.anchor[li]])
    assert v["robot_mass_kg"] == pytest.approx(point_effective_mass_kg(robot, motion.q[n], joint, point, u))
    assert v["approach_speed_m_s"] == pytest.approx(float(sep.approach_m_s[n, li, pi]))


def test_a_too_fast_approach_asks_for_the_slowdown_that_passes(robot):
    motion = _motion(0.5)
    end = ee_positions(robot, motion.q[-1:])[0]
    context = CheckContext(human=_sphere_human(end + np.array([0.3, 0.0, 0.0]), "face"))
    check = ContactSpeed(robot)
    fast = check.check(motion, context)
    assert fast.status == "fail" and fast.measures.n_speed_violations > 0
    k = fast.slowdown
    allowed = 1.0 - robot.settings.human.speed_margin
    assert fast.measures.planning_limit_ratio == pytest.approx(allowed)
    assert k == pytest.approx(fast.measures.max_speed_ratio / allowed * SLOWDOWN_MARGIN) and k > 1
    t0 = motion.t_s[0]
    slow = Trajectory(t0 + (motion.t_s - t0) * k, motion.q, motion.qd / k, motion.qdd / k**2, NAMES)
    again = check.check(slow, context)
    assert again.status == "pass" and again.measures.max_speed_ratio <= allowed


def test_the_speed_margin_keeps_room_below_the_limit_and_violations_count_the_limit_itself(robot):
    from dataclasses import replace

    motion = _motion(0.5)
    end = ee_positions(robot, motion.q[-1:])[0]
    context = CheckContext(human=_sphere_human(end + np.array([0.3, 0.0, 0.0]), "face"))
    ratio = ContactSpeed(robot).check(motion, context).measures.max_speed_ratio
    # slowed to 95 % of the limit: beyond a 10 % margin, within the limit itself
    k = ratio / 0.95
    t0 = motion.t_s[0]
    slow = Trajectory(t0 + (motion.t_s - t0) * k, motion.q, motion.qd / k, motion.qdd / k**2, NAMES)
    strict = load_robot(replace(robot.settings, human=replace(robot.settings.human, speed_margin=0.1)))
    loose = load_robot(replace(robot.settings, human=replace(robot.settings.human, speed_margin=0.0)))
    held = ContactSpeed(strict).check(slow, context)
    assert held.status == "fail" and held.measures.n_over_planning_limit > 0
    assert held.measures.n_speed_violations == 0 and "90% of the contact-speed limit" in held.reason
    assert held.measures.max_speed_ratio == pytest.approx(0.95, rel=1e-3)
    free = ContactSpeed(loose).check(slow, context)
    assert free.status == "pass", free.reason


def test_without_a_human_the_assumed_human_is_checked(robot):
    motion = _motion()
    for check in (HumanClearance(robot), ContactSpeed(robot)):
        result = check.check(motion, CheckContext())
        assert result.measures.human == "assumed" and "assumed human" in result.reason


def test_bad_human_parameters_are_one_line_errors(tmp_path, tiny, capsys):
    bad = tmp_path / "bad_human.toml"
    bad.write_text(ROBOT_FILE.read_text().replace("speed_m_s = 1.6", "speed_m_s = -1.0"))
    with pytest.raises(RobotError, match=r"bad_human\.toml: field 'human\.speed_m_s': implausible value -1 "):
        load_robot_settings(bad)
    bad.write_text(ROBOT_FILE.read_text().replace("reaction_time_s = 0.1", "reaction_time_s = nan"))
    with pytest.raises(RobotError, match=r"iso15066\.reaction_time_s.*finite"):
        load_robot_settings(bad)
    bad.write_text(ROBOT_FILE.read_text().replace("speed_margin = 0.1", "speed_margin = 1.0"))
    with pytest.raises(RobotError, match=r"field 'iso15066\.speed_margin': .*plausible range \[0, 0\.5\]"):
        load_robot_settings(bad)
    bad.write_text(ROBOT_FILE.read_text() + "\n[iso15066.regions.hand]\nspring_n_mm = 0\n")
    with pytest.raises(RobotError, match=r"iso15066\.regions\.hand\.spring_n_mm"):
        load_robot_settings(bad)
    assert run_tiny(tiny, tmp_path / "out", "--robot", str(bad)) == 2
    assert "iso15066.regions.hand.spring_n_mm" in one_error_line(capsys.readouterr().err)


def test_run_reports_the_human_checks_and_a_failing_one_exits_3(tmp_path, tiny, capsys):
    out = tmp_path / "out"
    assert run_tiny(tiny, out) == 0
    checks = json.loads((out / "report.json").read_text())["feasibility"]["checks"]
    for name in ("human_clearance", "contact_speed"):
        assert checks[name]["status"] == "pass" and checks[name]["human"] == "assumed"
        assert {"link", "body_part", "t_s", "time_within_sp_s"} <= set(checks[name])
    strict = tmp_path / "strict.toml"
    strict.write_text(
        ROBOT_FILE.read_text().replace(
            "max_inflation_m = 0.15", "max_inflation_m = 0.15\nmin_separation_m = 0.5"
        )
    )
    capsys.readouterr()
    assert run_tiny(tiny, out, "--robot", str(strict)) == cli.EXIT_CHECKS_FAILED
    assert "human_clearance" in one_error_line(capsys.readouterr().err)
    report = json.loads((out / "report.json").read_text())
    failed = report["feasibility"]["checks"]["human_clearance"]
    assert failed["status"] == "fail" and failed["min_separation_m"] < 0.5 and failed["body_part"]
    assert "human_clearance" in report["feasibility"]["failures"]
