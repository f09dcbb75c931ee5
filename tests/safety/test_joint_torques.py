"""The joint-torque check (safety/joint_torques.py) and torque-aware timing (motion/timing.py's
TorqueLimit): torques with the payload while held, the slow-down that fits them, toppra's
torque-constrained profile within its limits, and `run` refusing a too-heavy object."""

from __future__ import annotations

import json

import numpy as np
import pytest
from helpers_cli import one_error_line, run_tiny
from scipy.interpolate import CubicSpline

from ipromp_pin import app as cli
from ipromp_pin.motion.path import prepare_path
from ipromp_pin.motion.timing import TorqueLimit, time_path
from ipromp_pin.motion.toppra_profile import toppra_profile
from ipromp_pin.motion.trajectory import JointLimits, Trajectory
from ipromp_pin.robot import load_robot
from ipromp_pin.robot.dynamics import ArmDynamics
from ipromp_pin.robot.objects import TaskObject
from ipromp_pin.safety import CheckContext, CheckSuite
from ipromp_pin.safety.joint_torques import JointTorques

Q0 = np.array([-0.8, -0.9, 0.4, 1.3, -0.2, 1.2, 1.6])
Q1 = np.array([-0.2, -0.4, 0.1, 0.8, 0.3, 0.9, 1.0])


@pytest.fixture(scope="module")
def robot():
    return load_robot("baxter_left")


def obj(mass: float, holder: str = "robot_gives") -> TaskObject:
    return TaskObject("t", mass, np.array([0.0, 0.0, 0.05]), np.eye(3) * 1e-3, holder)


NAMES = ("left_s0", "left_s1", "left_e0", "left_e1", "left_w0", "left_w1", "left_w2")


def motion(t_total: float, n: int = 201) -> Trajectory:
    """A minimum-jerk-like cosine motion from Q0 to Q1 in ``t_total`` [s]."""
    t = np.linspace(0.0, t_total, n)
    u = 0.5 - 0.5 * np.cos(np.pi * t / t_total)
    du = 0.5 * np.pi / t_total * np.sin(np.pi * t / t_total)
    ddu = 0.5 * (np.pi / t_total) ** 2 * np.cos(np.pi * t / t_total)
    d = Q1 - Q0
    return Trajectory(t, Q0 + u[:, None] * d, du[:, None] * d, ddu[:, None] * d, NAMES)


def test_joint_torques_is_registered_required_and_constrains_the_timing(robot):
    suite = CheckSuite.build(robot)
    assert isinstance(suite.get("joint_torques"), JointTorques) and JointTorques.required
    assert suite.timing_constraints(CheckContext()).torque is not None
    assert (
        CheckSuite.build(robot, exclude=["joint_torques"]).timing_constraints(CheckContext()).torque is None
    )


def test_slow_motion_passes_and_the_payload_counts_only_while_held(robot):
    check = JointTorques(robot)
    m = motion(3.0)
    bare = check.check(m, CheckContext())
    assert bare.passed and "no payload" in bare.reason
    heavy = obj(1.5, "robot_gives")
    gives = check.check(m, CheckContext(payload=heavy, handover_s=3.0))
    assert gives.measures.peak_torque_ratio > bare.measures.peak_torque_ratio
    # robot_receives: the object joins at the hand-over (the last sample), at rest
    receives = check.check(m, CheckContext(payload=obj(1.5, "robot_receives"), handover_s=3.0))
    tau = check.torques(m, CheckContext(payload=obj(1.5, "robot_receives"), handover_s=3.0))
    plain = ArmDynamics(robot).torques(m.q, m.qd, m.qdd)
    np.testing.assert_allclose(tau[:-1], plain[:-1])
    assert not np.allclose(tau[-1], plain[-1])
    assert receives.measures.peak_torque_ratio <= gives.measures.peak_torque_ratio + 1e-12


def test_a_too_fast_motion_asks_for_the_slowdown_that_fits(robot):
    check = JointTorques(robot)
    fast = motion(0.25)
    res = check.check(fast, CheckContext())
    assert not res.passed and res.measures.peak_torque_ratio > res.measures.allowed_ratio
    k = res.slowdown
    assert k > 1.0
    slowed = motion(0.25 * k)  # a uniform slow-down by k: qd / k, qdd / k^2
    assert check.check(slowed, CheckContext()).passed
    # a slightly smaller slow-down may still pass (the estimate is conservative), a much smaller one fails
    assert not check.check(motion(0.25 * (1 + 0.3 * (k - 1))), CheckContext()).passed


def test_a_too_heavy_object_fails_without_a_slowdown(robot):
    res = JointTorques(robot).check(motion(3.0), CheckContext(payload=obj(25.0)))
    assert not res.passed and res.slowdown is None and "slowing down cannot help" in res.reason


def test_subsampling_keeps_the_peaks(robot):
    check = JointTorques(robot, max_samples=20)
    m = motion(0.4, n=401)
    idx = check.sample_indices(m)
    assert idx.size < 60 and idx[-1] == 400
    # the even grid, each joint's velocity and acceleration peaks and the last sample, sorted once
    even = np.linspace(0, 400, 20).round().astype(int)
    peaks = [np.argmax(np.abs(m.qdd), axis=0), np.argmax(np.abs(m.qd), axis=0)]
    np.testing.assert_array_equal(idx, np.unique(np.concatenate([even, *peaks, [400]])))
    full = JointTorques(robot, max_samples=10_000).check(m, CheckContext())
    sub = check.check(m, CheckContext())
    assert sub.measures.peak_torque_ratio == pytest.approx(full.measures.peak_torque_ratio, rel=0.02)


def _fast_limits(robot) -> JointLimits:
    return JointLimits.from_robot(robot).scaled(1.0, 40.0, 400.0)


def _tight_torque(robot, payload: TaskObject) -> tuple[ArmDynamics, TorqueLimit]:
    """Torque limits 2 N m above the largest gravity torque along the path (so that they bind)."""
    dyn = ArmDynamics(robot)
    path = Q0 + np.linspace(0, 1, 50)[:, None] * (Q1 - Q0)
    g = np.abs(dyn.torques(path, payload=payload)).max(axis=0)
    return dyn, TorqueLimit(dyn.inverse_dynamics(payload), g + 2.0)


def test_toppra_torque_profile_respects_the_limit_at_its_grid_points(robot):
    payload = obj(1.0)
    dyn, torque = _tight_torque(robot, payload)
    limits = _fast_limits(robot)
    path = Q0 + np.linspace(0, 1, 30)[:, None] * (Q1 - Q0)
    s_grid, pts = prepare_path(path, limits)
    spline = CubicSpline(s_grid, pts, bc_type="not-a-knot")
    t, sd, sdd = toppra_profile(spline, s_grid, limits, torque)
    t_free, _, _ = toppra_profile(spline, s_grid, limits)
    assert t[-1] > 1.2 * t_free[-1]  # the torque limits bind
    # at each grid point i < G-1 with the path acceleration of the interval that starts there (toppra's
    # collocation: the constraint binds the pair (sdot_i, sddot_i)); the end is at rest
    s = s_grid[:-1]
    qd = spline(s, 1) * sd[:-1, None]
    qdd = spline(s, 2) * sd[:-1, None] ** 2 + spline(s, 1) * sdd[:, None]
    tau = dyn.torques(spline(s), qd, qdd, payload)
    assert np.all(np.abs(tau) <= torque.limit_nm * (1 + 1e-6) + 1e-6)
    assert np.any(np.abs(tau) > 0.99 * torque.limit_nm)  # and the profile uses them


def test_torque_aware_timing_keeps_the_sampled_trajectory_within_the_limits(robot):
    payload = obj(1.0)
    dyn, torque = _tight_torque(robot, payload)
    limits = _fast_limits(robot)
    path = Q0 + np.linspace(0, 1, 30)[:, None] * (Q1 - Q0)
    free, _ = time_path(path, limits)
    traj, report = time_path(path, limits, torque=torque)
    assert report.passed and traj.t_s[-1] > free.t_s[-1]
    tau = dyn.torques(traj.q, traj.qd, traj.qdd, payload)
    assert np.all(np.abs(tau) <= torque.limit_nm)
    tau_free = dyn.torques(free.q, free.qd, free.qdd, payload)
    assert np.any(np.abs(tau_free) > torque.limit_nm)  # without the constraint it would exceed them


def test_run_refuses_a_too_heavy_object_with_exit_3(tmp_path, tiny, capsys):
    objects = tmp_path / "objects.toml"
    objects.write_text(
        "[rod]\nmass_kg = 20.0\nholder = 'robot_gives'\n[wrench]\nmass_kg = 20.0\nholder = 'robot_gives'\n"
    )
    out = tmp_path / "out"
    assert run_tiny(tiny, out, "--objects", str(objects)) == cli.EXIT_CHECKS_FAILED
    assert "joint_torques" in one_error_line(capsys.readouterr().err)
    report = json.loads((out / "report.json").read_text())
    assert "joint_torques" in report["feasibility"]["failures"]


def test_run_refuses_a_bad_object_file_with_exit_2(tmp_path, tiny, capsys):
    objects = tmp_path / "objects.toml"
    objects.write_text("[rod]\nmass_kg = -2.0\nholder = 'robot_gives'\n")
    assert run_tiny(tiny, tmp_path / "out", "--objects", str(objects)) == 2
    line = one_error_line(capsys.readouterr().err)
    assert str(objects) in line and "rod.mass_kg" in line and "plausible range [0, 35] kg" in line
    assert not (tmp_path / "out").exists()  # before any computation
    objects.write_text("[hammer]\nmass_kg = 2.0\nholder = 'robot_gives'\n")
    assert run_tiny(tiny, tmp_path / "out", "--objects", str(objects)) == 2
    assert "unknown task 'hammer'" in one_error_line(capsys.readouterr().err)


def test_trajectory_files_and_bag_messages_carry_the_torques(tmp_path, tiny, robot):
    from ipromp_pin.outputs.rosbag import JOINT_STATE, BagContent, bag_messages
    from ipromp_pin.outputs.trajectory_files import read_trajectory_csv

    out = tmp_path / "out"
    assert run_tiny(tiny, out, "--task", "rod") == 0  # received at the hand-over: empty-handed before
    doc = json.loads((out / "trajectory.json").read_text())
    effort = np.array([p["effort"] for p in doc["message"]["points"]])
    traj = read_trajectory_csv(out / "trajectory.csv")
    assert effort.shape == traj.q.shape
    # the torques of the written motion (the synthetic tasks' objects arrive/leave at the hand-over)
    plain = ArmDynamics(robot).torques(traj.q, traj.qd, traj.qdd)
    np.testing.assert_allclose(effort[1:-1], plain[1:-1], atol=1e-3)
    traj.effort_nm = effort
    states = [
        m
        for m in bag_messages(BagContent(traj, 0.5, np.r_[0.0, 0, 0, 0, 0, 0, 1]))
        if m.msgtype == JOINT_STATE
    ]
    assert len(states) == traj.n_samples
    np.testing.assert_allclose(states[3].msg.effort, effort[3])
