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
3. is checked like the approach, by the same checks (:class:`~ipromp_pin.safety.CheckSuite`: the
   human as the run knows it, the joint torques with the post-hand-over payload,
   :attr:`~ipromp_pin.safety.CheckContext.after_handover`) and re-timed slower while they ask for
   it, by the same loop (:func:`~ipromp_pin.safety.retime.retime_until_safe`).

Times: the segment's ``t_s`` is on the human's clock, from :attr:`RetreatResult.start_s` (the
hand-over: the approach's last sample).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..motion.timing import TimingReport
from ..motion.trajectory import JointLimits, Trajectory
from ..robot import IKResult, Robot
from ..robot.inverse_kinematics import solve_ik
from ..robot.kinematics import ee_positions, frame_placements, rotations_to_quat_xyzw
from ..robot.objects import TaskObject
from ..robot.retreat_target import RetreatTarget
from ..safety import CheckContext, CheckReport, CheckSuite, Timed, Timer
from .one_shot import LogFn, PlanResult
from .timers import PathTimer, fixed_timer

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
        trajectory: The segment on the human's clock from :attr:`start_s` (the dwell first, then the
            motion, ending at rest at ``q_target``); ``effort_nm`` holds the joint torques when checked.
        timing_report: Verification of the motion part (None when the target is the hand-over itself).
        checks: The verdicts on the segment.
        end_pose: The gripper's pose at the segment's end (7,): x, y, z [m], quaternion xyzw.
        ee_path: The gripper positions (M, 3) [m] along the segment (subsampled).
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
    checks: CheckReport
    end_pose: np.ndarray
    ee_path: np.ndarray
    payload: TaskObject | None
    start_s: float
    ik: IKResult | None = None
    slowdown: float = 1.0
    stage_ms: dict[str, float] = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        """Whether every required check passed and the timing verification holds."""
        return bool(self.checks.passed and (self.timing_report is None or self.timing_report.passed))

    @property
    def failures(self) -> list[str]:
        """The failed required checks (and ``timing``)."""
        timing_ok = self.timing_report is None or self.timing_report.passed
        return list(self.checks.failures) + ([] if timing_ok else ["timing"])

    @property
    def duration_s(self) -> float:
        """The segment's duration in [s], the dwell included."""
        return float(self.trajectory.duration_s)

    def to_dict(self) -> dict:
        """The report's ``retreat`` section (JSON-serialisable)."""
        return {
            "task": self.task,
            "target": self.target.to_dict(),
            "q_target_rad": [float(v) for v in self.q_target],
            "end_position_m": [float(v) for v in self.end_pose[:3]],
            "ik_position_error_m": None if self.ik is None else self.ik.position_error_m,
            "start_s": self.start_s,
            "dwell_s": self.target.dwell_s,
            "duration_s": self.duration_s,
            "n_samples": self.trajectory.n_samples,
            "payload": None if self.payload is None else self.payload.to_dict(),
            "slowdown": self.slowdown,
            "passed": self.passed,
            "failures": self.failures,
            "checks": self.checks.to_dict(),
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
        lines += [f"  retreat {v.name}: {v.reason}" for v in self.checks if v.blocks]
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


def retreat_timer(
    path: np.ndarray | None,
    q_from: np.ndarray,
    limits: JointLimits,
    suite: CheckSuite,
    context: CheckContext,
    dwell_s: float,
    rate_hz: float,
    start_s: float,
    say: LogFn,
) -> Timer:
    """The retreat's timer: ``round(dwell_s * rate_hz)`` control periods at rest at ``q_from`` from
    ``start_s`` [s], then ``path`` (M, n_joints) [rad] timed from rest to rest (None: no motion; the
    dwell cannot be slowed down)."""
    dt = 1.0 / rate_hz
    n_dwell = int(round(dwell_s * rate_hz))
    dwell = Trajectory.at_rest(start_s, q_from, limits.joint_names, n_dwell + 1, dt)
    if path is None:
        return fixed_timer(dwell, "the retreat does not move: nothing to slow down")
    inner = PathTimer(path, limits, suite.timing_constraints(context), rate_hz, dwell.end_s, say, "retreat")
    return DwellThenPath(dwell, inner)


class DwellThenPath:
    """A :class:`~ipromp_pin.safety.retime.LocalTimer` of a dwell at rest followed by a path timer's
    motion: slowing (uniformly or locally) slows the path only."""

    def __init__(self, dwell: Trajectory, inner: PathTimer) -> None:
        self.dwell, self.inner = dwell, inner

    def __call__(self, k: float) -> Timed:
        return self._after_dwell(self.inner(k))

    def locally(self, timed: Timed, need: np.ndarray) -> Timed:
        """The path slowed where ``need`` (per sample of ``timed``, the dwell's first) asks (``timed``'s
        report is its path's)."""
        return self._after_dwell(self.inner.locally(timed, need[self.dwell.n_samples - 1 :]))

    def _after_dwell(self, timed: Timed) -> Timed:
        return Timed(self.dwell.then(timed.motion), timed.report, timed.scale, timed.path)


def plan_retreat(
    robot: Robot,
    result: PlanResult,
    target: RetreatTarget,
    suite: CheckSuite | None = None,
    context: CheckContext | None = None,
    *,
    control_rate_hz: float = 100.0,
    log: LogFn | None = None,
) -> RetreatResult:
    """Plan, time and check the retreat after ``result``'s hand-over (see the module docstring).

    Args:
        robot: The loaded robot.
        result: The one-shot plan (its last sample is the hand-over, at rest; its first the start).
        target: The recognised task's retreat entry.
        suite: The run's checks (their torque limits constrain the timing, with the payload after the
            hand-over; default: every registered check).
        context: What they know (the human, the objects); copied, never changed.
        control_rate_hz: Output sampling rate in [Hz].
        log: Progress messages (None: silent).

    Raises:
        RobotError: a position target the inverse kinematics does not reach.
        InfeasibleError: the path cannot be timed.
    """
    say = log or (lambda _msg: None)
    suite = suite if suite is not None else CheckSuite.build(robot)
    t0 = time.perf_counter()
    ms: dict[str, float] = {}
    q_from = np.asarray(result.trajectory.q[-1], dtype=float)
    start_s = result.trajectory.end_s
    q_to, ik = retreat_configuration(robot, target, q_from, result.trajectory.q[0])
    base = context if context is not None else CheckContext()
    ctx = base.replace(task=result.prediction.task, handover_s=start_s, after_handover=True)
    t1 = time.perf_counter()
    ms["target"] = (t1 - t0) * 1e3
    moves = float(np.max(np.abs(q_to - q_from))) > 1e-6
    path = straight_path(q_from, q_to) if moves else None
    limits = JointLimits.from_robot(robot)
    timer = retreat_timer(path, q_from, limits, suite, ctx, target.dwell_s, control_rate_hz, start_s, say)
    retimed = suite.retime_until_safe(timer, ctx)
    segment = suite.annotate(retimed.motion, ctx)
    ms["time_check"] = (time.perf_counter() - t1) * 1e3
    pos, rot = frame_placements(robot, segment.q[[-1]])
    step = max(1, segment.n_samples // 100)
    out = RetreatResult(
        target=target,
        task=result.prediction.task,
        q_target=q_to,
        trajectory=segment,
        timing_report=retimed.timed.report,  # type: ignore[arg-type]  # a path timer's report, or None
        checks=retimed.report,
        end_pose=np.hstack([pos[0], rotations_to_quat_xyzw(rot)[0]]),
        ee_path=ee_positions(robot, np.vstack([segment.q[::step], segment.q[-1:]])),
        payload=ctx.carried_object(),
        start_s=start_s,
        ik=ik,
        slowdown=retimed.slowdown,
    )
    ms["total"] = (time.perf_counter() - t0) * 1e3
    out.stage_ms = ms
    verdict = "pass" if out.passed else "fail: " + ", ".join(out.failures)
    say(f"[retreat] {verdict}; {out.duration_s:.2f} s, planned in {ms['total']:.0f} ms")
    return out
