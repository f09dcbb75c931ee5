"""The robot's part after the hand-over: the retreat, from the hand-over at rest to the task's target.

:func:`plan_retreat` plans the second segment of a run from the one-shot plan's last sample (the
hand-over, at rest) to the target of the recognised task's ``retreat`` entry
(:mod:`ipromp_pin.robot.retreat_target`): the robot's start configuration, a configured joint
configuration, or a configured gripper position reached by damped least-squares inverse kinematics
from the hand-over configuration with the hand-over orientation kept. The segment

1. holds still at the hand-over for the entry's ``dwell_s`` (the gripper closes on, or lets go of,
   the object);
2. follows the straight joint-space line to the target, timed as the approach is
   (:func:`~ipromp_pin.motion.timing.time_path`: toppra + ruckig under the robot's limits), with
   toppra's joint-torque constraint of the joint-torque check for the payload of the phase after
   the hand-over: the object when the robot received it (``holder = "robot_receives"``), none when
   it gave it (``robot_gives``);
3. is checked like the approach: joint limits and self-collision (:mod:`ipromp_pin.robot.checks`)
   along its samples, and every timed-motion check of the run (:mod:`ipromp_pin.checks`: the human
   checks against the human as the run knows it, on the human's clock after the hand-over; the
   joint torques with the post-hand-over payload, :attr:`~ipromp_pin.checks.CheckContext.after_handover`);
   when the failing checks ask for a slower motion it is re-timed once that much slower.

Times: the segment's ``t_s`` runs from 0 at the hand-over (the approach's last sample); on the
human's clock it starts at :attr:`RetreatResult.start_s`, the clock every retreat check's message
names times on.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..checks import CheckContext, MotionCheck, TimedMotion, needed_slowdown, run_checks
from ..checks.joint_torques import JointTorques
from ..exceptions import InfeasibleError
from ..motion.timing import TimingReport, TorqueLimit, time_path
from ..motion.trajectory import JointLimits, Trajectory
from ..robot import CheckResult, FeasibilityReport, IKResult, Robot, check_joint_limits, check_self_collision
from ..robot.inverse_kinematics import solve_ik
from ..robot.kinematics import frame_placements, rotations_to_quat_xyzw
from ..robot.objects import TaskObject
from ..robot.retreat_target import RetreatTarget
from .one_shot import LogFn, PlanResult

PATH_SPACING_RAD = 0.02
"""Joint-space spacing [rad] of the points of the straight retreat path handed to the timing."""

IK_MAX_ITER = 1000
"""Iterations of the inverse kinematics of a position target."""


@dataclass
class RetreatResult:
    """A planned retreat.

    Attributes:
        target: The task's retreat entry.
        task: The recognised task.
        q_target: The configuration reached (n_joints,) in [rad].
        trajectory: The segment (times from 0 at the hand-over; the dwell first, then the motion,
            ending at rest at ``q_target``); ``effort_nm`` holds the joint torques when checked.
        timing_report: Verification of the motion part (None when the target is the hand-over itself).
        report: The checks (joint limits, self-collision, the timed-motion checks); its
            ``handover_pose`` is the pose at the segment's end, ``ee_path`` the gripper path [m].
        payload: The object carried during the motion (None: empty-handed).
        start_s: When the segment starts (the hand-over) in [s] on the human's clock.
        ik: The inverse kinematics of a position target (None otherwise).
        slowdown: The slow-down ``k >= 1`` the checks asked for (1: none).
        stage_ms: Wall time of the planning stages in [ms] (``total``: everything).
    """

    target: RetreatTarget
    task: str
    q_target: np.ndarray
    trajectory: Trajectory
    timing_report: TimingReport | None
    report: FeasibilityReport
    payload: TaskObject | None
    start_s: float
    ik: IKResult | None = None
    slowdown: float = 1.0
    stage_ms: dict[str, float] = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        """Whether every required check passed and the timing verification holds."""
        return bool(self.report.passed and (self.timing_report is None or self.timing_report.passed))

    @property
    def failures(self) -> list[str]:
        """The failed required checks (and ``timing``)."""
        timing_ok = self.timing_report is None or self.timing_report.passed
        return list(self.report.failures) + ([] if timing_ok else ["timing"])

    @property
    def duration_s(self) -> float:
        """The segment's duration in [s], the dwell included."""
        return float(self.trajectory.duration_s)

    def to_dict(self) -> dict:
        """The report's ``retreat`` section (JSON-serialisable)."""
        checks = self.report.to_dict()
        return {
            "task": self.task,
            "target": self.target.to_dict(),
            "q_target_rad": [float(v) for v in self.q_target],
            "end_position_m": [float(v) for v in self.report.handover_pose[:3]],
            "ik_position_error_m": None if self.ik is None else self.ik.position_error_m,
            "start_s": self.start_s,
            "dwell_s": self.target.dwell_s,
            "duration_s": self.duration_s,
            "n_samples": self.trajectory.n_samples,
            "payload": None if self.payload is None else self.payload.to_dict(),
            "slowdown": self.slowdown,
            "passed": self.passed,
            "failures": self.failures,
            "checks": checks["checks"],
            "timing": None if self.timing_report is None else self.timing_report.to_dict(),
            "stage_ms": {k: round(v, 3) for k, v in self.stage_ms.items()},
        }

    def to_text(self) -> str:
        """One line for ``report.txt`` and the summary, then the failed checks' reasons."""
        verdict = "PASSED" if self.passed else "FAILED: " + ", ".join(self.failures)
        what = "empty-handed" if self.payload is None else f"carrying the {self.payload.mass_kg:g} kg object"
        lines = [
            f"Retreat to {target_text(self.target)}: {verdict}; {self.duration_s:.2f} s "
            f"({self.target.dwell_s:g} s dwell), {what}, planned in {self.stage_ms.get('total', 0.0):.0f} ms"
            + (f", slowed {self.slowdown:.2f}x" if self.slowdown > 1.0 else "")
        ]
        lines += [
            f"  retreat {c.name}: {c.reason}" for c in self.report.checks if c.required and not c.passed
        ]
        return "\n".join(lines)


def target_text(target: RetreatTarget) -> str:
    """The target in words (``start``, ``joints [...]``, ``position (x, y, z) m``)."""
    if target.kind == "position" and target.position_m is not None:
        x, y, z = target.position_m
        return f"position ({x:.3f}, {y:.3f}, {z:.3f}) m"
    if target.kind == "joints" and target.joints_rad is not None:
        return "joints [" + ", ".join(f"{v:.2f}" for v in target.joints_rad) + "] rad"
    return "the start configuration"


def retreat_configuration(
    robot: Robot, target: RetreatTarget, q_handover: np.ndarray, q_start: np.ndarray
) -> tuple[np.ndarray, IKResult | None]:
    """The configuration (n_joints,) [rad] the retreat goes to, and the IK result of a position target
    (damped least squares from ``q_handover``, the hand-over orientation kept).

    Raises:
        RobotError: a position target the IK does not reach (naming the file and field).
    """
    if target.kind == "start":
        return np.asarray(q_start, dtype=float).copy(), None
    if target.kind == "joints" and target.joints_rad is not None:
        return target.joints_rad.copy(), None
    assert target.position_m is not None, "a position target has a position"
    _, rot = frame_placements(robot, q_handover)
    quat = rotations_to_quat_xyzw(rot)[0]
    ik = solve_ik(robot, target.position_m, quat, q_seed=q_handover, max_iter=IK_MAX_ITER)
    lo = robot.lower_rad + robot.settings.position_margin_rad
    hi = robot.upper_rad - robot.settings.position_margin_rad
    if not ik.converged:
        raise target.error(
            "position_m",
            f"not reachable with the hand-over orientation: the inverse kinematics stopped "
            f"{ik.position_error_m * 1e3:.1f} mm and {math.degrees(ik.rotation_error_rad):.1f} deg away "
            f"after {ik.iterations} iterations",
        )
    if np.any(ik.q < lo - 1e-9) or np.any(ik.q > hi + 1e-9):
        raise target.error("position_m", "the inverse kinematics' solution is outside the joint limits")
    return ik.q, ik


def straight_path(q_from: np.ndarray, q_to: np.ndarray, spacing_rad: float = PATH_SPACING_RAD) -> np.ndarray:
    """Points (M, n_joints) [rad] on the straight joint-space line from ``q_from`` to ``q_to``."""
    n = max(2, int(math.ceil(float(np.linalg.norm(q_to - q_from)) / spacing_rad)) + 1)
    return np.linspace(q_from, q_to, n)


def post_handover_payload(context: CheckContext) -> TaskObject | None:
    """The object in the gripper after the hand-over: the task's object when the robot received it."""
    obj = context.task_object()
    return obj if obj is not None and obj.holder == "robot_receives" else None


def _timed_motion(
    path: np.ndarray, limits: JointLimits, rate_hz: float, torque: TorqueLimit | None, say: LogFn
) -> tuple[Trajectory, TimingReport, TorqueLimit | None]:
    """``path`` timed under ``limits`` and ``torque`` (without them when toppra finds no profile under
    the torque limits: the joint-torque check then fails the retreat)."""
    if torque is not None:
        try:
            return (*time_path(path, limits, rate_hz=rate_hz, torque=torque), torque)
        except InfeasibleError as exc:
            say(f"[retreat] not timeable under the torque limits ({exc}): timed without them")
    return (*time_path(path, limits, rate_hz=rate_hz), None)


def with_dwell(
    motion: Trajectory | None,
    q_from: np.ndarray,
    dwell_s: float,
    rate_hz: float,
    joint_names: tuple[str, ...],
) -> Trajectory:
    """The segment: ``round(dwell_s * rate_hz)`` samples at rest at ``q_from``, then ``motion`` (whose
    first sample is ``q_from`` at rest; None: no motion, the dwell's end sample closes the segment)."""
    dt = 1.0 / rate_hz
    n_dwell = int(round(dwell_s * rate_hz))
    n_joints = q_from.size
    hold = np.repeat(q_from[None, :], n_dwell, axis=0)
    zero = np.zeros((n_dwell, n_joints))
    if motion is None:
        still = np.zeros((1, n_joints))
        motion = Trajectory(np.zeros(1), q_from[None, :], still, still, joint_names, still)
    jerk = motion.jerk()
    return Trajectory(
        np.concatenate([np.arange(n_dwell) * dt, n_dwell * dt + motion.t_s]),
        np.vstack([hold, motion.q]),
        np.vstack([zero, motion.qd]),
        np.vstack([zero, motion.qdd]),
        joint_names,
        np.vstack([zero, jerk]),
    )


def plan_retreat(
    robot: Robot,
    result: PlanResult,
    target: RetreatTarget,
    *,
    checks: Sequence[MotionCheck] = (),
    context: CheckContext | None = None,
    control_rate_hz: float = 100.0,
    torque_timing: bool = True,
    log: LogFn | None = None,
) -> RetreatResult:
    """Plan, time and check the retreat after ``result``'s hand-over (see the module docstring).

    Args:
        robot: The loaded robot.
        result: The one-shot plan (its last sample is the hand-over, at rest; its first the start).
        target: The recognised task's retreat entry.
        checks: The run's timed-motion checks.
        context: What they know (the human, the objects); copied, never changed.
        control_rate_hz: Output sampling rate in [Hz].
        torque_timing: Time the motion under the joint-torque check's limits with the payload.
        log: Progress messages (``None``: silent).

    Raises:
        RobotError: a position target the inverse kinematics does not reach.
        InfeasibleError: the path cannot be timed.
    """
    say = log or (lambda _msg: None)
    t0 = time.perf_counter()
    ms: dict[str, float] = {}
    q_from = np.asarray(result.trajectory.q[-1], dtype=float)
    start_s = result.start_s + float(result.trajectory.t_s[-1])
    q_to, ik = retreat_configuration(robot, target, q_from, result.trajectory.q[0])
    base = context if context is not None else CheckContext()
    ctx = dataclasses.replace(base, task=result.prediction.task, handover_s=start_s, after_handover=True)
    payload = post_handover_payload(ctx)
    torques = next((c for c in checks if isinstance(c, JointTorques)), None)
    torque = None
    if torques is not None and torque_timing:
        torque = TorqueLimit(torques.dynamics.inverse_dynamics(payload), torques.allowed_nm())
    t1 = time.perf_counter()
    ms["target"] = (t1 - t0) * 1e3
    limits = JointLimits.from_robot(robot)
    moves = float(np.max(np.abs(q_to - q_from))) > 1e-6
    path = straight_path(q_from, q_to) if moves else None
    motion, timing, used = None, None, None
    if path is not None:
        motion, timing, used = _timed_motion(path, limits, control_rate_hz, torque, say)
    segment = with_dwell(motion, q_from, target.dwell_s, control_rate_hz, robot.joint_names)
    t2 = time.perf_counter()
    ms["time_parameterise_smooth"] = (t2 - t1) * 1e3
    out = RetreatResult(
        target,
        result.prediction.task,
        q_to,
        segment,
        timing,
        _path_report(robot, segment, start_s),
        payload,
        start_s,
        ik,
    )
    t3 = time.perf_counter()
    ms["check"] = (t3 - t2) * 1e3
    if checks:
        _check_retreat(out, robot, list(checks), ctx, control_rate_hz, used, path)
    ms["motion_checks"] = (time.perf_counter() - t3) * 1e3
    ms["total"] = (time.perf_counter() - t0) * 1e3
    out.stage_ms = ms
    say(out.to_text())
    return out


def _path_report(robot: Robot, segment: Trajectory, start_s: float) -> FeasibilityReport:
    """Joint limits and self-collision along the segment's samples (times named on the human's clock,
    the segment starting at ``start_s``, as the timed-motion checks name them)."""
    q, t = segment.q, start_s + segment.t_s
    checks: list[CheckResult] = [
        check_joint_limits(robot, q, t_s=t),
        check_self_collision(robot, q, t_s=t),
    ]
    pos, rot = frame_placements(robot, q[[-1]])
    end = np.hstack([pos[0], rotations_to_quat_xyzw(rot)[0]])
    step = max(1, q.shape[0] // 100)
    ee, _ = frame_placements(robot, np.vstack([q[::step], q[-1:]]))
    return FeasibilityReport(robot.settings.name, checks, end, ee)


def _check_retreat(
    out: RetreatResult,
    robot: Robot,
    checks: list[MotionCheck],
    ctx: CheckContext,
    rate_hz: float,
    torque: TorqueLimit | None,
    path: np.ndarray | None,
) -> None:
    """The timed-motion checks of ``out``'s segment on the human's clock; re-timed once when the
    failing checks ask for a slower motion and that passes them (in place, like the approach)."""
    results = run_checks(checks, TimedMotion.from_trajectory(out.trajectory, out.start_s), ctx)
    k = needed_slowdown(results)
    if k is not None and k > 1.0 and path is not None:
        k *= 1.05  # a margin over the checks' estimate, as for the approach
        try:
            limits = JointLimits.from_robot(robot).scaled(1.0 / k, 1.0 / k**2, 1.0 / k**3)
            slow, slow_report = time_path(path, limits, rate_hz=rate_hz, torque=torque)
        except InfeasibleError:
            slow = None
        if slow is not None:
            segment = with_dwell(slow, out.trajectory.q[0], out.target.dwell_s, rate_hz, robot.joint_names)
            slow_results = run_checks(checks, TimedMotion.from_trajectory(segment, out.start_s), ctx)
            if needed_slowdown(slow_results) == 1.0:
                out.trajectory, out.timing_report, results, out.slowdown = (
                    segment,
                    slow_report,
                    slow_results,
                    k,
                )
                out.report = _path_report(robot, segment, out.start_s)
    out.report.checks.extend(results)
    torques = next((c for c in checks if isinstance(c, JointTorques)), None)
    if torques is not None:
        out.trajectory.effort_nm = torques.motion_torques(
            TimedMotion.from_trajectory(out.trajectory, out.start_s), ctx
        )
