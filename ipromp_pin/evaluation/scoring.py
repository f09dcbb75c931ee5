"""Scoring: what a planned or commanded motion reached, measured against the recorded demo.

The one place where the evaluation (``ipromp-pin evaluate``) and the reports of ``run`` and
``replay`` measure a motion after the fact, with everything the recording knows (its future
included; the checks before execution never use it):

* **hand-over error**: distance in [cm] between the commanded gripper position at the recorded
  hand-over time (the demo's end, where the evaluation takes the hand-over point) and the recorded
  gripper position then; the **final error** is the same where the commanded motion comes to rest;
* **hand-over orientation error**: the geodesic angle in [deg] between the commanded and the recorded
  gripper rotations at the hand-over;
* **arrival delay**: commanded arrival minus the recorded robot's arrival, in [s]. A gripper
  *arrives* at the first time after which it stays within :data:`ARRIVAL_TOLERANCE_M` of where it
  ends. The recorded robot still creeps at 2-6 cm/s when a demo ends, so the same rule is applied to
  both;
* **limit ratio**: the largest |velocity|, |acceleration| or |jerk| (difference of consecutive
  accelerations over the control period) over its limit at any control sample;
* **collisions**: commanded control samples in contact (Pinocchio/coal contact test of every sample,
  independent of the certification before each commit);
* **torques**: the peak |joint torque| / effort limit with the TRUE task's object (the joint-torque
  check of the run's suite);
* **the human** (recordings with a tracked skeleton): the human checks of the run's suite judged
  against the recorded human motion (every sample known; :class:`HumanMeasures`), and the arrival
  delay of the same replay without the human checks;
* a **planned** hand-over's measures against its recording (:func:`recorded_scores`, the scores of
  ``run`` and ``plan`` when the recording has its future): hand-over position and orientation
  errors, and the gripper's distance from the recorded hand where it was last seen;
* the **one-shot** trial's measures (:func:`score_trial`): recognition, joint errors, hand-over
  position and orientation errors of a prediction, also for the unconditioned prior.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from ..data import GRIPPER, ROBOT, Demo
from ..exceptions import InfeasibleError
from ..human import HumanMotion
from ..motion.trajectory import JointLimits, Trajectory
from ..planning.closed_loop import ClosedLoopResult
from ..planning.one_shot import PlanResult
from ..planning.timers import PathTimer
from ..promp import Prediction, handover_orientation
from ..robot import Robot, ee_positions, frame_placements
from ..robot.collision import in_collision
from ..robot.objects import ObjectTable
from ..robot.rotations import chordal_mean, geodesic_deg
from ..safety import HUMAN_CHECKS, CheckContext, CheckSuite
from ..safety.contact_speed import ContactSpeedMeasures
from ..safety.human_clearance import ClearanceMeasures
from ..safety.joint_torques import TorqueMeasures
from ..safety.speed_limits import limit_ratios
from ..signals.gripper import gripper_rotations

ARRIVAL_TOLERANCE_M = 0.01
"""A gripper has arrived once it stays within this distance [m] of its final position."""

FK = Callable[[np.ndarray], np.ndarray]
"""Forward kinematics: joint configurations (n, n_joints) [rad] -> gripper positions (n, 3) [m]."""

FKRot = handover_orientation.FKRot
"""Forward kinematics: joint configurations (n, n_joints) [rad] -> gripper rotations (n, 3, 3)."""


def arrival_time(t_s: np.ndarray, positions_m: np.ndarray, tolerance_m: float = ARRIVAL_TOLERANCE_M) -> float:
    """First time in [s] after which ``positions_m`` (N, 3) stay within ``tolerance_m`` of the last one."""
    far = np.linalg.norm(positions_m - positions_m[-1], axis=1) > tolerance_m
    idx = np.flatnonzero(far)
    return float(t_s[0] if idx.size == 0 else t_s[min(idx[-1] + 1, t_s.size - 1)])


def handover_orientation_error_deg(robot: Robot, q_commanded: np.ndarray, q_recorded: np.ndarray) -> float:
    """Geodesic angle in [deg] between the gripper rotations of a commanded and a recorded arm
    configuration (n_joints,) [rad], e.g. at the hand-over."""
    rot = frame_placements(robot, np.stack([q_commanded, q_recorded]))[1]
    return float(geodesic_deg(rot[0], rot[1]))


# --------------------------------------------------------------------------------------------------
# A planned hand-over against its recording
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RecordedScores:
    """A planned hand-over measured against the whole recording it was planned from (None: the
    recording lacks what the measure needs).

    Attributes:
        handover_error_cm: The planned gripper position at rest vs the recorded robot's at the
            recording's end, [cm].
        handover_orientation_error_deg: The planned vs the recorded gripper rotation there, [deg].
        hand_distance_m: The planned gripper at rest vs the human hand's last recorded position, [m].
        recorded_duration_s: The recording's duration, [s].
    """

    handover_error_cm: float | None
    handover_orientation_error_deg: float | None
    hand_distance_m: float | None
    recorded_duration_s: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable form."""
        return asdict(self)


def recorded_scores(
    result: PlanResult, recording: Demo, robot: Robot, source: Robot | None = None
) -> RecordedScores:
    """``result`` (planned from the first part of ``recording``) measured against the recording
    (``source``: the robot the recording's joints are of, when ``robot`` executed a retargeted plan;
    both grippers are in the scene frame; a recording without joints: its gripper pose path)."""
    q_end = result.trajectory.q[-1]
    truth = recording.groups.get(ROBOT)
    error = orientation = hand = None
    pose = recording.groups.get(GRIPPER)
    if truth is None and pose is not None:  # the recorded gripper pose path, in the scene frame
        (pe, re), rt = frame_placements(robot, q_end), gripper_rotations(pose[-1:])
        error = float(np.linalg.norm(pe[0] - pose[-1, :3]) * 100.0)
        orientation = float(geodesic_deg(re[0], rt[0]))
    if truth is not None and len(truth):
        if source is None:
            p = ee_positions(robot, np.stack([q_end, truth[-1]]))
            orientation = handover_orientation_error_deg(robot, q_end, truth[-1])
        else:
            (pe, re), (pt, rt) = frame_placements(robot, q_end), frame_placements(source, truth[-1])
            p = np.vstack([pe, pt])
            orientation = float(geodesic_deg(re[0], rt[0]))
        error = float(np.linalg.norm(p[0] - p[1]) * 100.0)
    path = recording.extras.get("hand_position")
    if path is not None:
        seen = np.flatnonzero(np.all(np.isfinite(path), axis=1))
        if seen.size:
            hand = float(np.linalg.norm(ee_positions(robot, q_end)[0] - path[seen[-1]]))
    return RecordedScores(error, orientation, hand, float(recording.t[-1] - recording.t[0]))


# --------------------------------------------------------------------------------------------------
# Torques and the human
# --------------------------------------------------------------------------------------------------


def peak_torque_ratio(
    suite: CheckSuite, trajectory: Trajectory, task: str, objects: ObjectTable | None
) -> float:
    """The suite's joint-torque check's peak |torque| / effort limit of ``trajectory`` with the object
    of the TRUE ``task`` in ``objects`` (NaN without the check or when it skips)."""
    check = suite.get("joint_torques")
    if check is None:
        return float("nan")
    verdict = check.check(trajectory, CheckContext(task=task, objects=objects))
    return (
        float(verdict.measures.peak_torque_ratio)
        if isinstance(verdict.measures, TorqueMeasures)
        else math.nan
    )


def one_shot_peak_torque_ratio(
    suite: CheckSuite,
    robot: Robot,
    prediction: Prediction,
    task: str,
    objects: ObjectTable,
    rate_hz: float = 100.0,
) -> float:
    """:func:`peak_torque_ratio` of the one-shot plan of ``prediction`` timed as ``run`` times it
    first (toppra + ruckig at ``rate_hz`` [Hz] under the robot's limits and the torque limits of the
    RECOGNISED task's object; without the slow-downs the other checks may ask for) with the object
    of the TRUE ``task``; NaN when the path cannot be timed."""
    ctx = CheckContext(task=prediction.task, objects=objects)
    timer = PathTimer(
        prediction.q_mean,
        JointLimits.from_robot(robot),
        suite.timing_constraints(ctx),
        rate_hz,
        float(prediction.observed_until_s),
        lambda _msg: None,
    )
    try:
        trajectory = timer(1.0).motion
    except InfeasibleError:
        return float("nan")
    return peak_torque_ratio(suite, trajectory, task, objects)


@dataclass(frozen=True)
class HumanMeasures:
    """What the human checks measured of a commanded motion against a human motion.

    Attributes:
        min_separation_m: Smallest robot-body distance outside the hand region, [m].
        protective_distance_time_s: Time closer than ``S_p``, [s].
        contact_speed_violations: Control samples inside ``S_p`` faster than the contact-speed limit.
        max_speed_ratio: Largest approach speed over its limit inside ``S_p`` (None: never inside).
        link: Robot link of the closest pair.
        body_part: Body part of the closest pair.
        t_s: When the closest pair was closest, [s] on the human's clock.
        passed: Whether every human check passed.
        assumed: Whether the human was the assumed one (no skeleton).
    """

    min_separation_m: float | None
    protective_distance_time_s: float | None
    contact_speed_violations: int | None
    max_speed_ratio: float | None
    link: str
    body_part: str
    t_s: float | None
    passed: bool
    assumed: bool

    def to_dict(self) -> dict:
        """JSON-serialisable form."""
        return asdict(self)


def _finite(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(float(x)) else float(x)


def human_measures(trajectory: Trajectory, human: HumanMotion, suite: CheckSuite) -> HumanMeasures:
    """The suite's human checks (:data:`~ipromp_pin.safety.HUMAN_CHECKS`) on ``trajectory`` (times on
    the human's clock) against ``human`` (every sample known) -> :class:`HumanMeasures`."""
    verdicts = suite.only(HUMAN_CHECKS).run(trajectory, CheckContext(human=human))
    clear = next((v.measures for v in verdicts if isinstance(v.measures, ClearanceMeasures)), None)
    speed = next((v.measures for v in verdicts if isinstance(v.measures, ContactSpeedMeasures)), None)
    first = clear if clear is not None else speed
    return HumanMeasures(
        min_separation_m=None if clear is None else _finite(clear.min_separation_m),
        protective_distance_time_s=_finite(first.time_within_sp_s) if first is not None else None,
        contact_speed_violations=None if speed is None else int(speed.n_speed_violations),
        max_speed_ratio=None if speed is None else _finite(speed.max_speed_ratio),
        link="" if first is None else first.link,
        body_part="" if first is None else first.body_part,
        t_s=None if first is None else _finite(first.t_s),
        passed=all(v.passed for v in verdicts),
        assumed=bool(human.assumed),
    )


# --------------------------------------------------------------------------------------------------
# The closed loop
# --------------------------------------------------------------------------------------------------


@dataclass
class ClosedLoopScore:
    """The measures of one closed-loop run against its recorded demo (see the module docstring).

    Attributes:
        handover_error_cm: Commanded vs recorded gripper position at the recorded hand-over time, [cm].
        final_error_cm: Commanded resting vs recorded hand-over gripper position, [cm].
        arrival_delay_s: Commanded minus recorded arrival, [s].
        arrival_s: Commanded arrival, [s] from the motion start.
        recorded_arrival_s: Recorded robot's arrival, [s].
        handover_time_s: Recorded hand-over time (the demo's end), [s].
        rest_s: When the commanded motion comes to rest, [s].
        max_limit_ratio: Largest of ``limit_ratios``.
        limit_ratios: Largest |v|, |a|, |jerk| over their limits at any control sample (3,).
        position_excess_rad: Largest excursion beyond the margin-shrunk position limits, [rad].
        collisions: Commanded control samples in contact.
        replans: Re-plans made.
        refused_replans: Re-plans not committed.
        final_task: Task of the last committed re-plan toward a hand-over ("" if none; not a stop or
            retreat on an unknown observation).
        handover_orientation_error_deg: Commanded vs recorded gripper rotation at the recorded
            hand-over time, [deg].
        peak_torque_ratio: Largest |joint torque| / effort limit of the commanded motion with the true
            task's object (NaN: not scored).
        human_min_separation_m: Smallest robot-body distance outside the hand region against the
            recorded human, [m] (None: no skeleton, or not measured).
        protective_distance_time_s: Time closer than the protective separation distance, [s].
        contact_speed_violations: Control samples inside it faster than the contact-speed limit.
        arrival_delay_without_human_s: ``arrival_delay_s`` of the same replay without the human
            checks, [s].
        start_s: When the robot started (its first re-plan), [s] from the motion start.
        stop_s: When the robot stopped on an observation turned unknown after the start, [s] from the
            motion start (the first time; None: never, :mod:`~ipromp_pin.planning.unknown_stop`).
        retreat_s: When it retreated after holding, [s] (None: never).
    """

    handover_error_cm: float
    final_error_cm: float
    arrival_delay_s: float
    arrival_s: float
    recorded_arrival_s: float
    handover_time_s: float
    rest_s: float
    max_limit_ratio: float
    limit_ratios: list[float]
    position_excess_rad: float
    collisions: int
    replans: int
    refused_replans: int
    final_task: str
    handover_orientation_error_deg: float = float("nan")
    peak_torque_ratio: float = float("nan")
    human_min_separation_m: float | None = None
    protective_distance_time_s: float | None = None
    contact_speed_violations: int | None = None
    arrival_delay_without_human_s: float | None = None
    start_s: float = float("nan")
    stop_s: float | None = None
    retreat_s: float | None = None

    def to_dict(self) -> dict:
        """JSON-serialisable form."""
        return asdict(self)


def recorded_gripper(demo: Demo, robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """The demo's recorded gripper path in the scene frame: positions (T, 3) [m] and rotations
    (T, 3, 3), of ``robot``'s joints, or of its gripper pose path when it recorded no joints."""
    if ROBOT not in demo.groups and GRIPPER in demo.groups:
        pose = demo.groups[GRIPPER]
        return pose[:, :3], gripper_rotations(pose)
    return frame_placements(robot, demo.groups[ROBOT])


def score_closed_loop(
    result: ClosedLoopResult,
    demo: Demo,
    robot: Robot,
    tolerance_m: float = ARRIVAL_TOLERANCE_M,
    check_collisions: bool = True,
    source: Robot | None = None,
) -> ClosedLoopScore:
    """The commanded motion's measures against the recorded demo it replayed (without the torques and
    the human: :func:`replay_scored` adds those); ``source``: the robot the demo's joints are of when
    ``robot`` executed it retargeted (both grippers are in the scene frame)."""
    traj = result.trajectory
    t_demo = demo.t - demo.t[0]
    t_end = float(t_demo[-1])
    q_at = np.array([np.interp(t_end, traj.t_s, traj.q[:, j]) for j in range(traj.q.shape[1])])
    p_cmd = ee_positions(robot, traj.q)
    p_true, r_true = recorded_gripper(demo, robot if source is None else source)
    (p_at, p_rest), r_cmd = frame_placements(robot, np.stack([q_at, traj.q[-1]]))
    arrival = arrival_time(traj.t_s, p_cmd, tolerance_m)
    recorded = arrival_time(t_demo, p_true, tolerance_m)
    lim = result.profile.limits
    ratios = limit_ratios(traj, lim)[0]
    excess = float(np.max(np.maximum(np.maximum(lim.lower_rad - traj.q, traj.q - lim.upper_rad), 0.0)))
    collisions = int(np.count_nonzero(in_collision(robot, traj.q))) if check_collisions else 0
    committed = [r for r in result.replans if r.committed and not r.action]  # toward a hand-over
    return ClosedLoopScore(
        handover_error_cm=float(np.linalg.norm(p_at - p_true[-1]) * 100.0),
        final_error_cm=float(np.linalg.norm(p_rest - p_true[-1]) * 100.0),
        arrival_delay_s=arrival - recorded,
        arrival_s=arrival,
        recorded_arrival_s=recorded,
        handover_time_s=t_end,
        rest_s=result.arrival_s,
        start_s=float(result.start_s),
        max_limit_ratio=float(ratios.max()),
        limit_ratios=[float(x) for x in ratios],
        position_excess_rad=excess,
        collisions=collisions,
        replans=len(result.replans),
        refused_replans=result.n_refused,
        final_task=committed[-1].task if committed else "",
        handover_orientation_error_deg=float(geodesic_deg(r_cmd[0], r_true[-1])),
        stop_s=result.first_event_s("unknown"),
        retreat_s=result.first_event_s("retreat"),
    )


Replay = Callable[[CheckSuite, CheckContext], ClosedLoopResult]
"""Runs the closed loop of one demo with these checks and what they know."""


def replay_scored(
    replay: Replay,
    demo: Demo,
    robot: Robot,
    suite: CheckSuite,
    context: CheckContext,
    judge_human: HumanMotion | None,
    check_collisions: bool = True,
    source: Robot | None = None,
) -> tuple[ClosedLoopScore, ClosedLoopResult]:
    """Replay ``demo`` with ``suite`` and ``context`` and score it (``run`` of the replay command and
    every trial of ``evaluate --closed-loop`` alike).

    The score gets the peak torque ratio with the TRUE task's object (``context.objects``, when the
    suite has the joint-torque check) and, with ``judge_human`` (the recorded human, every sample
    known) and the suite's human checks, their measures against it and the arrival delay of the same
    replay without the human checks (:data:`~ipromp_pin.safety.HUMAN_CHECKS`). Returns the score and
    the replay (``source``: the robot the demo's joints are of, when ``robot`` executed it retargeted).
    """
    result = replay(suite, context)
    score = score_closed_loop(result, demo, robot, check_collisions=check_collisions, source=source)
    if context.objects is not None:
        score.peak_torque_ratio = peak_torque_ratio(suite, result.trajectory, demo.task, context.objects)
    humans = suite.only(HUMAN_CHECKS)
    if judge_human is None or not humans.checks:
        return score, result
    measures = human_measures(result.trajectory, judge_human, humans)
    free_result = replay(suite.without(HUMAN_CHECKS), context.replace(human=None))
    free = score_closed_loop(free_result, demo, robot, check_collisions=False, source=source)
    scored = replace(
        score,
        human_min_separation_m=measures.min_separation_m,
        protective_distance_time_s=measures.protective_distance_time_s,
        contact_speed_violations=measures.contact_speed_violations,
        arrival_delay_without_human_s=free.arrival_delay_s,
    )
    return scored, result


# --------------------------------------------------------------------------------------------------
# One-shot trials
# --------------------------------------------------------------------------------------------------


@dataclass
class TrialResult:
    """Outcome of one one-shot test trial.

    Attributes:
        task: True task of the test demo.
        demo: Test demo name.
        predicted: Recognised task.
        posterior: Posterior of the true task.
        joint_rmse_rad: RMSE over joints and the unobserved phase, conditioned prediction, in [rad].
        joint_rmse_prior_rad: The same for the unconditioned task mean, in [rad].
        final_joint_error_rad: RMS over joints of the final configuration error, in [rad].
        final_joint_error_prior_rad: The same for the prior mean, in [rad].
        handover_error_cm: Gripper position error at the hand-over, in [cm] (NaN without FK).
        handover_error_prior_cm: The same for the prior mean, in [cm].
        duration_error_s: Predicted minus true duration of the motion, in [s].
        brier: Multi-class Brier score of the task posterior (sum over tasks of squared errors).
        confidence: The posterior of the recognised task (its largest), for the calibration error.
        handover_orientation_error_deg: Geodesic angle between the predicted and the recorded gripper
            rotations at the hand-over, in [deg] (NaN without FK).
        handover_orientation_baseline_deg: The same for the baseline: the mean hand-over rotation
            (chordal L2 mean) of the training demos of the true task, in [deg].
        baselines: Baseline name -> its outcome on the same window (``--baselines``).
        peak_torque_ratio: Peak |joint torque| / effort limit of the one-shot plan with the true task's
            object (NaN: not scored).
        observed_s: Time of the last observed sample, in [s] from the demo's start.
        observed_fraction: The fraction of the demo's length its window covers (the unobserved part
            the joint errors are over starts there).
        plan: The one-shot plan on the executing arm, scored (:class:`~.arm_plans.PlannedTrial`;
            None: not planned).
    """

    task: str
    demo: str
    predicted: str
    posterior: float
    joint_rmse_rad: float
    joint_rmse_prior_rad: float
    final_joint_error_rad: float
    final_joint_error_prior_rad: float
    handover_error_cm: float
    handover_error_prior_cm: float
    duration_error_s: float
    brier: float = float("nan")
    confidence: float = float("nan")
    handover_orientation_error_deg: float = float("nan")
    handover_orientation_baseline_deg: float = float("nan")
    baselines: dict[str, Any] = field(default_factory=dict)
    peak_torque_ratio: float = float("nan")
    observed_s: float = float("nan")
    observed_fraction: float = float("nan")
    plan: Any = None

    @property
    def correct(self) -> bool:
        """True when the task was recognised."""
        return self.predicted == self.task


def phase_interp(t: np.ndarray, q: np.ndarray, duration_s: float, z: np.ndarray) -> np.ndarray:
    """Values of a trajectory ``q`` (N, D) sampled at ``t`` (N,) in [s] at phases ``z`` of ``duration_s``."""
    tz = z * duration_s
    return np.stack([np.interp(tz, t, q[:, j]) for j in range(q.shape[1])], axis=1)


def score_trial(
    prediction: Prediction,
    demo: Demo,
    obs_ratio: float,
    fk: FK | None,
    fk_rot: FKRot | None = None,
    baseline_rot: np.ndarray | None = None,
) -> TrialResult:
    """Measure one prediction against the full test demo (its robot group is the ground truth).

    Args:
        prediction: The model's prediction from the observed part of ``demo``.
        demo: The full test demo.
        obs_ratio: Observed fraction of the demo's length, in (0, 1] (its window's end over its
            duration, for a window in seconds).
        fk: Gripper positions of joint configurations (None: no Cartesian error).
        fk_rot: Gripper rotations of joint configurations (None: no orientation errors).
        baseline_rot: (3, 3) the baseline's hand-over rotation (:func:`mean_handover_rotations`).
    """
    assert demo.duration_s is not None, "a Demo sets its duration when it is made"
    truth = demo.groups[ROBOT]
    z = np.linspace(obs_ratio, 1.0, 50)
    true_z = phase_interp(demo.t - demo.t[0], truth, demo.duration_s, z)
    pred_z = phase_interp(prediction.t, prediction.q_mean, prediction.duration_s, z)
    prior_z = phase_interp(prediction.t, prediction.q_prior_mean, prediction.duration_s, z)
    q_true_end, q_pred_end, q_prior_end = truth[-1], prediction.q_mean[-1], prediction.q_prior_mean[-1]
    ho = ho_prior = rot_err = rot_base = float("nan")
    if fk is not None:
        p = fk(np.stack([q_true_end, q_pred_end, q_prior_end]))
        ho = float(np.linalg.norm(p[1] - p[0]) * 100.0)
        ho_prior = float(np.linalg.norm(p[2] - p[0]) * 100.0)
    if fk_rot is not None:
        r_true, r_pred = fk_rot(np.stack([q_true_end, q_pred_end]))
        rot_err = float(geodesic_deg(r_pred, r_true))
        if baseline_rot is not None:
            rot_base = float(geodesic_deg(baseline_rot, r_true))
    k_true = prediction.tasks.index(demo.task) if demo.task in prediction.tasks else None
    onehot = np.array([t == demo.task for t in prediction.tasks], dtype=float)
    return TrialResult(
        task=demo.task,
        demo=demo.name,
        predicted=prediction.task,
        posterior=float(prediction.posterior[k_true]) if k_true is not None else 0.0,
        joint_rmse_rad=float(np.sqrt(np.mean((pred_z - true_z) ** 2))),
        joint_rmse_prior_rad=float(np.sqrt(np.mean((prior_z - true_z) ** 2))),
        final_joint_error_rad=float(np.sqrt(np.mean((q_pred_end - q_true_end) ** 2))),
        final_joint_error_prior_rad=float(np.sqrt(np.mean((q_prior_end - q_true_end) ** 2))),
        handover_error_cm=ho,
        handover_error_prior_cm=ho_prior,
        duration_error_s=float(prediction.duration_s - demo.duration_s),
        brier=float(np.sum((np.asarray(prediction.posterior) - onehot) ** 2)),
        confidence=float(np.max(prediction.posterior)),
        handover_orientation_error_deg=rot_err,
        handover_orientation_baseline_deg=rot_base,
        observed_s=float(prediction.observed_until_s),
        observed_fraction=float(obs_ratio),
    )


def mean_handover_rotations(train: Sequence[Demo], fk_rot: FKRot) -> dict[str, np.ndarray]:
    """Task -> the chordal L2 mean (3, 3) of the gripper rotations at the hand-over (the last robot
    sample) of that task's training demos: the orientation baseline."""
    by_task: dict[str, list[np.ndarray]] = {}
    for d in train:
        by_task.setdefault(d.task, []).append(d.groups[ROBOT][-1])
    return {task: chordal_mean(fk_rot(np.stack(qs))) for task, qs in by_task.items()}
