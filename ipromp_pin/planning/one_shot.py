"""The one-shot plan of a hand-over: recognise and predict, time, check, re-time until safe.

:func:`plan` takes a fitted model, a loaded robot, the observed first part of the human's motion and
the checks (:class:`~ipromp_pin.safety.CheckSuite`) with what they know
(:class:`~ipromp_pin.safety.CheckContext`) and returns a :class:`PlanResult`: the prediction and the
committed trajectory (toppra + ruckig, on the human's clock: it starts when the observation ends)
with its verdicts, slowed where the checks ask for it (:func:`~ipromp_pin.safety.retime.retime_until_safe`).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..data import Demo
from ..exceptions import ModelError, UnreachableError
from ..human.forecast import ForecastCalibration
from ..motion.timing import TimingReport
from ..motion.trajectory import JointLimits, Trajectory
from ..promp import IProMP, Prediction
from ..promp.inputs import ObservationWarning
from ..robot import Robot, ee_positions, frame_placements
from ..robot.arm_transfer import Preference
from ..robot.kinematics import rotations_to_quat_xyzw
from ..safety import CheckContext, CheckReport, CheckSuite
from .human_forecast import forecast_of, predicted_human
from .timers import PathTimer
from .transfer import Retargeting, kindest_to_human, predicts_gripper, retarget_prediction

LogFn = Callable[[str], None]
"""Where progress messages go (one line each)."""

N_UNCERTAINTY_SAMPLES = 16
"""Joint trajectories drawn from the prediction for the uncertainty check and the preview."""


UNKNOWN_TASK = "unknown_task"
"""The failure of a plan whose observation matches none of the model's tasks."""


@dataclass
class PlanResult:
    """A planned hand-over.

    Attributes:
        robot: The robot settings' name.
        prediction: The model's conditioned prediction.
        trajectory: The committed trajectory (times on the human's clock from :attr:`start_s`;
            ``effort_nm``: the joint torques when the torque check ran).
        timing_report: Verification of the trajectory against the limits and the path.
        checks: The verdicts on the trajectory.
        handover_pose: The gripper's pose at the trajectory's end (7,): x, y, z [m], quaternion xyzw.
        ee_path: The gripper positions (M, 3) [m] along the predicted mean path.
        q_samples: (n, M, n_joints) joint trajectories [rad] drawn from the prediction (the uncertainty
            check's hand-overs, the preview's sampled paths).
        stage_ms: Wall time of every stage in [ms].
        start_s: When the robot starts (the end of the observation), in [s] on the human's clock.
        slowdown: The slow-down ``k >= 1`` the checks asked for (1: none): uniformly, velocity,
            acceleration and jerk limits / k, k^2, k^3 (when the plan failed: the largest tried).
        slowdown_delay_s: How much longer the slowed trajectory takes, in [s].
        slowdown_local: Whether it was slowed only where the checks asked (``slowdown`` is then its
            duration over the unslowed one's), not uniformly.
        retarget: How the joint paths came from the model's robot through the gripper (None: the
            model predicts this arm's joints).
        tool: The robot settings' ``[tool]`` (:meth:`~ipromp_pin.robot.settings.Tool.to_dict`), the
            gripper the checks saw on an arm whose URDF ends at the flange (None: none).
    """

    robot: str
    prediction: Prediction
    trajectory: Trajectory
    timing_report: TimingReport
    checks: CheckReport
    handover_pose: np.ndarray
    ee_path: np.ndarray
    q_samples: np.ndarray
    stage_ms: dict[str, float]
    start_s: float = 0.0
    slowdown: float = 1.0
    slowdown_delay_s: float = 0.0
    slowdown_local: bool = False
    retarget: Retargeting | None = None
    tool: dict | None = None

    @property
    def known(self) -> bool:
        """Whether the observation was recognised as one of the model's tasks (``Prediction.known``):
        the robot acts only on a known task."""
        return bool(self.prediction.known)

    @property
    def passed(self) -> bool:
        """Whether the task is known and every required check and the timing's verification passed."""
        return bool(self.known and self.checks.passed and self.timing_report.passed)

    @property
    def failures(self) -> list[str]:
        """``unknown_task`` when the observation matches none of the tasks, the failed required checks
        (and ``timing`` when its verification failed)."""
        unknown = [] if self.known else [UNKNOWN_TASK]
        return unknown + self.checks.failures + ([] if self.timing_report.passed else ["timing"])


def check_model_joints(model: IProMP, robot: Robot) -> None:
    """Refuse a model whose robot joints are not the robot's arm joints in kinematic order, matched
    by name through the settings' recorded names (a left-arm model run with a right-arm robot would
    otherwise command the right arm with the left arm's angles).

    A model of gripper poses (:func:`~.transfer.predicts_gripper`) has no joints to check: any arm
    follows its poses by inverse kinematics.

    Raises:
        ModelError: naming both joint lists.
    """
    if predicts_gripper(model):
        return
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


def prediction_context(
    prediction: Prediction,
    context: CheckContext,
    samples: np.ndarray,
    forecast: ForecastCalibration | None = None,
) -> CheckContext:
    """What the checks know once ``prediction`` is made: the recognised task, the predicted hand-over
    time, the sampled hand-over configurations (``samples`` (n, M, n_joints) [rad]) and, with the
    model's ``forecast``, the handing arm where the prediction places it
    (:func:`~.human_forecast.predicted_human`)."""
    return context.replace(
        task=prediction.task,
        handover_s=float(prediction.duration_s),
        handover_samples=samples[:, -1, :],
        human=predicted_human(context.human, prediction, forecast),
    )


def plan(
    model: IProMP,
    robot: Robot,
    observation: Demo,
    suite: CheckSuite | None = None,
    context: CheckContext | None = None,
    *,
    control_rate_hz: float = 100.0,
    log: LogFn | None = None,
    check_joints: bool = True,
    source: Robot | None = None,
) -> PlanResult:
    """Recognise and predict from ``observation``, time the predicted path from the end of the
    observation, check it with ``suite`` and re-time it slower while the checks ask for it.

    Args:
        model: A fitted :class:`~ipromp_pin.promp.IProMP`.
        robot: A loaded :class:`~ipromp_pin.robot.Robot`.
        observation: The observed first part of the human's motion.
        suite: The checks (their torque limits constrain the timing too; default: every registered
            check, :meth:`~ipromp_pin.safety.CheckSuite.build`).
        context: What the checks know about the world (the human as observed, the objects, ...).
        control_rate_hz: Output sampling rate in [Hz].
        log: Progress messages (None: silent).
        check_joints: Refuse a model whose joints are not the robot's (False: checked already).
        source: The robot whose joints the model predicts when it is not ``robot`` (e.g. Baxter's
            left arm for a Panda placed in its scene): the predicted paths are retargeted through the
            gripper (:func:`~.transfer.retarget_prediction`) and everything after is ``robot``'s. A
            model of gripper poses is always followed by ``robot``'s inverse kinematics (``source``:
            the robot of the poses' frame, :func:`~.transfer.source_robot`; None: ``robot``'s own).

    Raises:
        InfeasibleError: the predicted path cannot be timed at all.
        UnreachableError: ``robot`` cannot reach the hand-over pose of ``source``'s prediction.
    """
    say = log or (lambda _msg: None)
    if check_joints:
        check_model_joints(model, robot if source is None else source)
    suite = suite if suite is not None else CheckSuite.build(robot)
    ms: dict[str, float] = {}
    t0 = time.perf_counter()
    with warnings.catch_warnings():  # the plan's own warnings name them (plans.warnings.range_warnings)
        warnings.simplefilter("ignore", ObservationWarning)
        prediction = model.predict(observation)
    assert isinstance(prediction, Prediction), "IProMP.predict of one Demo returns one Prediction"
    t1 = time.perf_counter()
    ms["recognise_predict"] = (t1 - t0) * 1e3
    say(
        f"[recognise] {prediction.task} (posterior {float(np.max(prediction.posterior)):.3f}), "
        f"predicted duration {prediction.duration_s:.2f} s"
    )
    if not prediction.known:
        say(f"[recognise] UNKNOWN: {prediction.unknown_reason}")
    samples = prediction.sample_q(N_UNCERTAINTY_SAMPLES, np.random.default_rng(0))
    q_path, retarget = prediction.q_mean, None
    ctx = prediction_context(
        prediction,
        context if context is not None else CheckContext(),
        samples,
        forecast_of(model, robot.settings.human),
    )
    start_s = float(observation.t[-1] - observation.t[0])
    if source is not None or predicts_gripper(model):  # gripper poses: followed by any arm
        prefer = kindest_to_human(suite, ctx, timed_as_predicted(prediction, start_s))
        q_path, samples, retarget = retargeted(model, prediction, samples, robot, source, say, prefer)
        ctx = ctx.replace(handover_samples=samples[:, -1, :])
        ms["retarget"] = retarget.ms
    limits = JointLimits.from_robot(robot)
    timer = PathTimer(q_path, limits, suite.timing_constraints(ctx), control_rate_hz, start_s, say)
    retimed = suite.retime_until_safe(timer, ctx)
    t2 = time.perf_counter()
    ms["time_check"] = (t2 - t1) * 1e3 - ms.get("retarget", 0.0)
    trajectory = suite.annotate(retimed.motion, ctx)
    pos, rot = frame_placements(robot, trajectory.q[-1:])
    result = PlanResult(
        robot=robot.settings.name,
        prediction=prediction,
        trajectory=trajectory,
        timing_report=retimed.timed.report,  # type: ignore[arg-type]  # a path timer's report
        checks=retimed.report,
        handover_pose=np.hstack([pos[0], rotations_to_quat_xyzw(rot)[0]]),
        ee_path=ee_positions(robot, q_path),
        q_samples=samples,
        stage_ms=ms,
        start_s=start_s,
        slowdown=retimed.slowdown,
        slowdown_delay_s=retimed.delay_s,
        slowdown_local=retimed.local,
        retarget=retarget,
        tool=robot.settings.tool_record,
    )
    ms["annotate"] = (time.perf_counter() - t2) * 1e3
    say(f"[check] {'pass' if result.passed else 'FAIL: ' + ', '.join(result.failures)}")
    say(
        f"[timing] {trajectory.duration_s:.2f} s at {control_rate_hz:g} Hz, {trajectory.n_samples} samples, "
        f"from t = {start_s:.2f} s"
    )
    if result.slowdown != 1.0:
        say(_slowdown_line(result))
    return result


def timed_as_predicted(prediction: Prediction, start_s: float) -> np.ndarray:
    """Times (M,) [s] of the predicted path's samples for a motion from ``start_s`` [s] that reaches
    the hand-over when the human is predicted to (evenly spaced)."""
    return np.linspace(start_s, max(start_s, float(prediction.duration_s)), prediction.q_mean.shape[0])


def retargeted(
    model: IProMP,
    prediction: Prediction,
    samples: np.ndarray,
    robot: Robot,
    source: Robot | None,
    say: LogFn,
    prefer: Preference | None = None,
) -> tuple[np.ndarray, np.ndarray, Retargeting]:
    """The prediction's mean path and ``samples`` (n, M, ...) as ``robot``'s joint paths [rad]
    (:func:`~.transfer.retarget_prediction`): from ``source``'s joints, or from the predicted gripper
    poses for a model of them (``source`` None: in ``robot``'s own base frame); ``prefer`` chooses
    the hand-over configuration (:func:`~.transfer.kindest_to_human`).

    Raises:
        UnreachableError: ``robot`` cannot reach the predicted hand-over pose.
    """
    from_poses = predicts_gripper(model)
    source = robot if source is None else source
    q_path, samples, retarget = retarget_prediction(
        source, robot, prediction.q_mean, samples, from_poses, prefer
    )
    moved = retarget.to_dict()
    origin = f"gripper poses ({source.settings.name}'s frame)" if from_poses else source.settings.name
    say(
        f"[retarget] {origin} -> {robot.settings.name} through the gripper: hand-over "
        f"residual {moved['ik_residual_mm']:.3f} mm / {moved['ik_residual_deg']:.3f} deg, path at most "
        f"{moved['max_path_residual_mm']:.3f} mm"
    )
    if not retarget.reached:  # refused: never a hand-over shifted to where the arm reaches
        raise UnreachableError(retarget.path.why_not_reached(robot))
    return q_path, samples, retarget


def _slowdown_line(result: PlanResult) -> str:
    """The log line of a plan re-timed for its checks."""
    if result.slowdown_local:
        return (
            f"[timing] slowed where the checks ask (duration {result.slowdown:.2f}x): "
            f"{result.slowdown_delay_s:+.2f} s"
        )
    return f"[timing] slowed {result.slowdown:.2f}x for the checks: {result.slowdown_delay_s:+.2f} s"
