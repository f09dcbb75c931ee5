"""The online stages of a hand-over: recognise and predict, time-parameterise, check.

:func:`plan` takes a fitted model, a loaded robot and the observed first part of the human's motion
and returns a :class:`PlanResult`: the prediction, its feasibility report (Pinocchio checks), the
time-parameterised, jerk-limited trajectory (toppra + ruckig) and its verification. These are the
stages ``benchmarks/pipeline.py`` times.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..checks import (
    MAX_SLOWDOWN,
    MAX_SLOWDOWN_ROUNDS,
    CheckContext,
    MotionCheck,
    TimedMotion,
    needed_slowdown,
    run_checks,
)
from ..checks.joint_torques import JointTorques
from ..data import Demo
from ..exceptions import InfeasibleError, ModelError
from ..motion.timing import TimingReport, TorqueLimit, path_times, time_path
from ..motion.trajectory import JointLimits, Trajectory
from ..promp import IProMP, Prediction
from ..robot import FeasibilityReport, Robot, check_path

LogFn = Callable[[str], None]
"""Where progress messages go (one line each)."""

N_UNCERTAINTY_SAMPLES = 16
"""Joint trajectories drawn from the prediction for the uncertainty check and the preview."""


@dataclass
class PlanResult:
    """Output of the online stages for one observation.

    Attributes:
        prediction: The model's conditioned prediction.
        report: Feasibility report of the predicted path.
        trajectory: Time-parameterised, jerk-limited trajectory.
        timing_report: Verification of the trajectory against the limits and the path.
        stage_ms: Wall time of every stage in [ms].
        q_samples: (n, M, n_joints) joint trajectories in [rad] drawn from the conditioned
            prediction, used by the uncertainty check and shown by the preview.
        start_s: When the robot starts (the end of the observation), in [s] on the human's clock;
            the trajectory's t = 0.
        slowdown: Uniform slow-down ``k >= 1`` the timed-motion checks asked for (1: none): the
            trajectory was re-timed with velocity, acceleration and jerk limits / k, k^2, k^3.
        slowdown_delay_s: How much longer the re-timed trajectory takes, in [s].
    """

    prediction: Prediction
    report: FeasibilityReport
    trajectory: Trajectory
    timing_report: TimingReport
    stage_ms: dict[str, float]
    q_samples: np.ndarray
    start_s: float = 0.0
    slowdown: float = 1.0
    slowdown_delay_s: float = 0.0

    @property
    def passed(self) -> bool:
        """Whether the feasibility checks and the trajectory verification passed."""
        return bool(self.report.passed and self.timing_report.passed)


def check_model_joints(model: IProMP, robot: Robot) -> None:
    """Refuse a model whose robot joints are not the robot's arm joints in kinematic order, matched
    by name through the settings' recorded names (a left-arm model run with a right-arm robot would
    otherwise command the right arm with the left arm's angles).

    Raises:
        ModelError: naming both joint lists.
    """
    names = tuple(model.joint_names_)
    recorded = robot.settings.recorded_names
    if tuple(recorded.get(n, n) for n in names) == robot.joint_names:
        return
    have = robot.settings.recorded_arm_joints
    hint = (
        "the same joints in another order"
        if sorted(recorded.get(n, n) for n in names) == sorted(robot.joint_names)
        else f"a model trained for robot '{robot.settings.name}' is needed"
    )
    raise ModelError(
        f"the model predicts joints {list(names)} but robot '{robot.settings.name}' moves "
        f"{list(have)} ({hint})"
    )


def plan(
    model: IProMP,
    robot: Robot,
    observation: Demo,
    control_rate_hz: float = 100.0,
    hand_position_m: np.ndarray | None = None,
    log: LogFn | None = None,
    *,
    check_joints: bool = True,
    checks: Sequence[MotionCheck] = (),
    context: CheckContext | None = None,
    torque_timing: bool = True,
) -> PlanResult:
    """Online stages: recognise + predict, time-parameterise + smooth, check.

    The checks run on the predicted path; the times their messages name are on the timed
    trajectory's time base (:func:`~ipromp_pin.motion.timing.path_times`: 0 when the robot starts, after
    the observation), like the preview's. When the path cannot be timed, the checks are still run
    and logged before the :class:`~ipromp_pin.exceptions.InfeasibleError` propagates.

    Args:
        model: A fitted :class:`~ipromp_pin.promp.IProMP`.
        robot: A loaded :class:`~ipromp_pin.robot.Robot`.
        observation: The observed first part of the human's motion.
        control_rate_hz: Output sampling rate in [Hz].
        hand_position_m: Human hand position at the hand-over (3,) in [m], if known.
        log: Progress messages (``None``: silent).
        check_joints: Refuse a model whose joints are not the robot's (:func:`check_model_joints`);
            False when the caller has checked them already.
        checks: Timed-motion checks (:mod:`ipromp_pin.checks`) of the timed trajectory, started at the
            end of the observation; their results join the report. When the failing ones ask for a
            slower motion, the path is re-timed once with the limits slowed that much.
        context: What the timed-motion checks know about the world (the human, the object, ...).
        torque_timing: When ``checks`` include the joint-torque check, time the path under its torque
            limits too (toppra's joint-torque constraint with the recognised task's object while the
            robot holds it; :func:`torque_limit`); False: velocity and acceleration limits only.
    """
    say = log or (lambda _msg: None)
    if check_joints:
        check_model_joints(model, robot)
    ms: dict[str, float] = {}
    t0 = time.perf_counter()
    prediction = model.predict(observation)
    t1 = time.perf_counter()
    assert isinstance(prediction, Prediction), "IProMP.predict of one Demo returns one Prediction"
    ms["recognise_predict"] = (t1 - t0) * 1e3
    say(
        f"[recognise] {prediction.task} (posterior {float(np.max(prediction.posterior)):.3f}), "
        f"predicted duration {prediction.duration_s:.2f} s"
    )
    samples = prediction.sample_q(N_UNCERTAINTY_SAMPLES, np.random.default_rng(0))
    # Timed first, so that the checks name times on the trajectory's time base (the robot's clock,
    # from its start), not the prediction's (the human's clock).
    torque = torque_limit(checks, context, prediction.task) if torque_timing else None
    try:
        trajectory, timing_report, torque = time_prediction(prediction, robot, control_rate_hz, torque, say)
    except InfeasibleError:
        report = check_path(robot, prediction.q_mean, q_samples=samples, hand_position_m=hand_position_m)
        say(f"[check] {'pass' if report.passed else 'FAIL: ' + ', '.join(report.failures)}")
        raise
    t2 = time.perf_counter()
    report = check_path(
        robot,
        prediction.q_mean,
        t_s=path_times(trajectory, prediction.q_mean),
        q_samples=samples,
        hand_position_m=hand_position_m,
    )
    t3 = time.perf_counter()
    ms["check"] = (t3 - t2) * 1e3
    ms["time_parameterise_smooth"] = (t2 - t1) * 1e3
    start_s = float(observation.t[-1] - observation.t[0])
    result = PlanResult(prediction, report, trajectory, timing_report, ms, samples, start_s)
    if checks:
        _check_motion(result, robot, list(checks), context, control_rate_hz, torque)
    say(f"[check] {'pass' if report.passed else 'FAIL: ' + ', '.join(report.failures)}")
    say(f"[timing] {trajectory.t_s[-1]:.2f} s at {control_rate_hz:g} Hz, {len(trajectory.t_s)} samples")
    if result.slowdown > 1.0:
        say(f"[timing] slowed {result.slowdown:.2f}x for the checks: {result.slowdown_delay_s:+.2f} s")
    return result


def time_prediction(
    prediction: Prediction,
    robot: Robot,
    rate_hz: float,
    torque: TorqueLimit | None = None,
    say: LogFn | None = None,
) -> tuple[Trajectory, TimingReport, TorqueLimit | None]:
    """The predicted path timed under the robot's limits and ``torque``; when toppra finds no profile
    under the torque limits (gravity alone exceeds them somewhere on the path: slowing down cannot
    help), timed without them (the joint-torque check then fails the plan). The torque limits used
    are returned (None after that fallback)."""
    limits = JointLimits.from_robot(robot)
    if torque is not None:
        try:
            return (*time_path(prediction.q_mean, limits, rate_hz=rate_hz, torque=torque), torque)
        except InfeasibleError as exc:
            if say is not None:
                say(f"[timing] not timeable under the torque limits ({exc}): timed without them")
    return (*time_path(prediction.q_mean, limits, rate_hz=rate_hz), None)


def torque_limit(
    checks: Sequence[MotionCheck], context: CheckContext | None, task: str
) -> TorqueLimit | None:
    """The torque limits of the joint-torque check among ``checks`` for timing the path of ``task``
    (its object included when the robot carries it to the hand-over, ``robot_gives``; a
    ``robot_receives`` object only joins at the end, at rest, where the check verifies it), or None
    without that check."""
    check = next((c for c in checks if isinstance(c, JointTorques)), None)
    if check is None:
        return None
    ctx = context if context is not None else CheckContext()
    payload = CheckContext(task=task, objects=ctx.objects, payload=ctx.payload).task_object()
    carried = payload if payload is not None and payload.holder == "robot_gives" else None
    return TorqueLimit(check.dynamics.inverse_dynamics(carried), check.allowed_nm())


def _check_motion(
    result: PlanResult,
    robot: Robot,
    checks: list[MotionCheck],
    context: CheckContext | None,
    control_rate_hz: float,
    torque: TorqueLimit | None = None,
) -> None:
    """Run the timed-motion checks on ``result``'s trajectory, re-time it slower when the failing checks
    ask for a slower motion (again, up to :data:`~ipromp_pin.checks.MAX_SLOWDOWN_ROUNDS` times and
    :data:`~ipromp_pin.checks.MAX_SLOWDOWN` in all, while the slower one still fails; committed only
    when it passes them), and add the results to its report (in place)."""
    t0 = time.perf_counter()
    base = context if context is not None else CheckContext()  # the caller's context is not changed
    ctx = replace(
        base, task=result.prediction.task, handover_s=result.start_s + float(result.trajectory.t_s[-1])
    )
    results = run_checks(checks, TimedMotion.from_trajectory(result.trajectory, result.start_s), ctx)
    asked, total = results, 1.0
    for _ in range(MAX_SLOWDOWN_ROUNDS + 1):  # slowed again while a slower motion still does not pass
        k = needed_slowdown(asked)
        if k is None or k <= 1.0 or total * k > MAX_SLOWDOWN:
            break
        total *= k * 1.05  # a margin over the checks' first-order estimate
        try:
            limits = JointLimits.from_robot(robot).scaled(1.0 / total, 1.0 / total**2, 1.0 / total**3)
            slow, slow_report = time_path(
                result.prediction.q_mean, limits, rate_hz=control_rate_hz, torque=torque
            )
        except InfeasibleError:
            break
        slow_ctx = replace(ctx, handover_s=result.start_s + float(slow.t_s[-1]))
        asked = run_checks(checks, TimedMotion.from_trajectory(slow, result.start_s), slow_ctx)
        if needed_slowdown(asked) == 1.0:
            result.slowdown_delay_s = float(slow.t_s[-1] - result.trajectory.t_s[-1])
            result.slowdown = total
            result.trajectory, result.timing_report, results, ctx = slow, slow_report, asked, slow_ctx
            break
    result.report.checks.extend(results)
    torques = next((c for c in checks if isinstance(c, JointTorques)), None)
    if torques is not None:  # the torques of the committed timing, for the trajectory files
        motion = TimedMotion.from_trajectory(result.trajectory, result.start_s)
        result.trajectory.effort_nm = torques.motion_torques(motion, ctx)
    result.stage_ms["motion_checks"] = (time.perf_counter() - t0) * 1e3
