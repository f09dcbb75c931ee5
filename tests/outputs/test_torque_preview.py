"""What the previews and plots show of the arm's dynamics: the torque track is the joint-torque check's
(its peak the check's ``peak_torque_ratio``), the object is held as the check holds it, and the
torque plot is written."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ipromp_pin.exceptions import DataError
from ipromp_pin.motion.trajectory import Trajectory
from ipromp_pin.outputs import plots
from ipromp_pin.outputs.torque_preview import SPHERE_RADIUS_M, held_object, torque_preview
from ipromp_pin.robot import load_robot
from ipromp_pin.robot.objects import TaskObject, load_objects
from ipromp_pin.safety import CheckContext
from ipromp_pin.safety.joint_torques import JointTorques


@pytest.fixture(scope="module")
def robot():
    return load_robot("baxter_left")


def reach(robot, n: int = 80, t0: float = 1.0) -> Trajectory:
    """A smooth reach of the arm, ``n`` samples at 100 Hz from ``t0`` [s] on the human's clock."""
    dt = 0.01
    t = np.arange(n) * dt
    s = 0.5 - 0.5 * np.cos(np.pi * t / t[-1])
    q0 = np.array([0.0, -0.55, 0.0, 0.75, 0.0, 1.26, 0.0])
    q1 = np.array([0.6, -0.2, -0.3, 1.2, 0.2, 0.6, 0.0])
    q = q0 + s[:, None] * (q1 - q0)
    qd = np.gradient(q, dt, axis=0)
    return Trajectory(t0 + t, q, qd, np.gradient(qd, dt, axis=0), tuple(robot.joint_names))


@pytest.mark.parametrize("task, gives", [("spanner_handover", True), ("aluminum_hold", False)])
def test_the_track_is_the_checks_and_holds_the_object_as_it_does(robot, task, gives):
    motion = reach(robot)
    context = CheckContext(task=task, objects=load_objects(), handover_s=float(motion.t_s[-1]))
    check = JointTorques(robot)
    result = check.check(motion, context)  # every sample evaluated: the motion is short
    track, obj = torque_preview(robot, motion, context, check=check)
    assert track is not None and obj is not None
    assert track.ratio.shape == (motion.n_samples, robot.n_joints)
    assert track.ratio.max() == pytest.approx(result.measures.peak_torque_ratio, rel=1e-9)
    np.testing.assert_allclose(track.peak, result.measures.ratios, atol=1e-4)
    assert track.allowed_ratio == pytest.approx(result.measures.allowed_ratio)
    # robot_gives: held up to the hand-over (the motion's end); robot_receives: at the hand-over only
    assert track.held.all() if gives else (track.held.tolist() == [False] * (motion.n_samples - 1) + [True])
    assert obj.held(motion.t_s).tolist() == track.held.tolist()
    assert obj.frame == robot.settings.ee_parent_frame
    assert obj.kind == ("box" if gives else "cylinder") and (gives or obj.axis == 1)
    # every sample (the plot's): the torques the pipeline already has (the effort) are used as they are
    tau = check.torques(motion, context)
    doubled = dataclasses.replace(motion, effort_nm=tau * 2.0)
    again, _ = torque_preview(robot, doubled, context, check=check, every_sample=True)
    assert again is not None and again.samples == "every control sample"
    np.testing.assert_allclose(again.ratio, 2.0 * track.ratio)


def test_no_payload_no_object_and_a_shapeless_object_is_a_sphere(robot):
    motion = reach(robot, 20)
    track, obj = torque_preview(robot, motion, CheckContext(task="unknown_task", objects=load_objects()))
    assert obj is None and track is not None and not track.held.any() and track.payload_at(0) == "empty"
    point = TaskObject("cup", 0.3, np.array([0.0, 0.0, 0.05]), np.zeros((3, 3)), "robot_receives")
    sphere = held_object(robot, point, 2.0)
    assert sphere is not None and sphere.kind == "sphere" and sphere.dims_m == (SPHERE_RADIUS_M,)
    assert sphere.held(np.array([1.9, 2.0])).tolist() == [False, True]


def test_torque_plot_is_written_and_checks_its_input(tmp_path, robot):
    motion = reach(robot)
    tau = JointTorques(robot).torques(motion, CheckContext())
    limit = np.full(7, 50.0)
    path = plots.plot_torques(
        motion.t_s, tau, limit, tmp_path / "torques.png", effort_margin=0.1, held=np.ones(80, bool)
    )
    assert path.stat().st_size > 5000
    with pytest.raises(DataError, match="tau_nm"):
        plots.plot_torques(motion.t_s[:-1], tau, limit, tmp_path / "x.png")
    with pytest.raises(DataError, match="limit_nm"):
        plots.plot_torques(motion.t_s, tau, np.zeros(7), tmp_path / "x.png")
    with pytest.raises(DataError, match="effort_margin"):
        plots.plot_torques(motion.t_s, tau, limit, tmp_path / "x.png", effort_margin=1.0)


def test_the_run_preview_shows_the_checks_torques_and_the_recognised_tasks_object():
    from ipromp_pin.app.config import load_pipeline, resolve_pipeline_path
    from ipromp_pin.app.session import prepare_session
    from ipromp_pin.outputs.preview_content import preview_content
    from ipromp_pin.planning.one_shot import plan

    cfg = load_pipeline(resolve_pipeline_path("baxter_handover"), task="wrench", demo=2)
    s = prepare_session(cfg, log=lambda _msg: None)
    ctx = s.context
    result = plan(s.model, s.robot, s.observed(), s.suite, ctx, control_rate_hz=cfg.control_rate_hz)
    assert result.prediction.task == "wrench" and result.trajectory.effort_nm is not None
    content = preview_content(result, s.robot, s.demo, human=ctx.human, objects=ctx.objects)
    peak = result.checks["joint_torques"].measures.peak_torque_ratio
    m = result.checks["joint_torques"].measures
    # the samples the check evaluated (a subsample of a long motion): the bars' peak is the report's
    assert (
        content.torques is not None
        and content.torques.t_s.size == m.n_evaluated < result.trajectory.n_samples
    )
    assert content.torques.ratio.max() == pytest.approx(peak, rel=1e-12)
    obj = content.held_object
    assert obj is not None and obj.name == "wrench" and obj.kind == "box"  # robot_gives: until the end
    handover = max(result.trajectory.end_s, result.prediction.duration_s)  # when both are there
    assert content.torques.held.all() and obj.held_until_s == pytest.approx(handover)
    assert any(n.startswith("Gripper orientation at the hand-over: ") for n in content.notes)
