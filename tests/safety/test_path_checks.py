"""The path checks of a motion (ipromp_pin.safety: joint_limits, workspace, self_collision,
uncertainty) on a straight joint-space motion: a typical hand-over passes, a motion into the torso
fails self-collision naming the links, a joint beyond its margin fails joint_limits, the workspace
is judged at the motion's end, the uncertainty is advisory."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ipromp_pin.data import ROBOT
from ipromp_pin.exceptions import InfeasibleError
from ipromp_pin.motion.trajectory import Trajectory
from ipromp_pin.robot import load_robot
from ipromp_pin.safety import CheckContext, CheckReport, CheckSuite

Q_START = np.array([-0.839, -0.969, 0.377, 1.262, -0.204, 1.189, 1.661])
Q_HANDOVER = np.array([-1.5, -0.498, 0.38, 0.64, -0.49, 0.946, 1.274])
Q_TORSO = np.array([0.13, 0.67, 0.13, 2.46, 1.71, 0.72, 0.57])
PATH_CHECKS = ["joint_limits", "workspace", "self_collision", "uncertainty"]


@pytest.fixture(scope="module")
def robot():
    return load_robot("baxter_left")


def _line(a, b, m=100):
    s = np.linspace(0, 1, m)[:, None]
    return a + s * (b - a)


def check_path(robot, q, *, q_std=None, q_samples=None) -> CheckReport:
    """The path checks of a motion through ``q`` (M, 7) at 100 Hz."""
    q = np.asarray(q, dtype=float)
    z = np.zeros_like(q)
    motion = Trajectory(np.arange(q.shape[0]) * 0.01, q, z, z, tuple(robot.joint_names))
    ends = None if q_samples is None else np.asarray(q_samples)[:, -1, :]
    ctx = CheckContext(handover_samples=ends, handover_std_rad=q_std)
    return CheckSuite.build(robot, PATH_CHECKS).report(motion, ctx)


def test_typical_path_passes_every_check(robot):
    q = _line(Q_START, Q_HANDOVER)
    report = check_path(robot, q, q_std=np.full(7, 0.02))
    assert report.passed, report.lines()
    col = report["self_collision"].measures
    assert col.min_distance_m > 0.01 and col.certified
    assert 0.0 <= col.t_s <= 0.99  # a sample of the motion
    assert report["uncertainty"].required is False
    d = json.loads(json.dumps(report.to_dict()))
    assert set(d) >= {"joint_limits", "self_collision", "workspace"}
    assert all(d[k]["status"] == "pass" for k in ("joint_limits", "self_collision", "workspace"))


def test_colliding_path_fails_and_names_the_links(robot):
    q = _line(Q_START, Q_TORSO)
    report = check_path(robot, q)
    assert not report.passed
    assert "self_collision" in report.failures
    col = report["self_collision"]
    assert not col.measures.certified and "torso" in " ".join(col.measures.links)
    # the folded end pose alone is in collision with the torso
    end = check_path(robot, np.stack([Q_TORSO, Q_TORSO]))["self_collision"]
    assert end.status == "fail" and "torso" in " ".join(end.measures.links)


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


def test_workspace(robot):
    q = _line(Q_START, Q_HANDOVER)
    assert check_path(robot, q)["workspace"].passed
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


@pytest.mark.realdata
def test_recorded_handover_paths_are_feasible(robot, chen2017_dir):
    from ipromp_pin.readers import load_dataset

    ds = load_dataset(chen2017_dir)
    for task, demos in ds.demos.items():
        q = demos[0].groups[ROBOT]
        report = check_path(robot, q)
        assert report["self_collision"].passed and report["workspace"].passed, (task, report.lines())
