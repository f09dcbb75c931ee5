"""The closed-loop scorer: per fit a limit profile (derived from the fit's training demos,
``demonstrated``, or the robot's ``conservative`` one, or a profile file); every test demo is

* predicted once from its first ``obs_ratio`` (the one-shot prediction, scored as the one-shot
  scorer does: recognition, joint errors, ``one_shot_handover_error_cm`` = the gripper position
  error of the one-shot plan's end, which is the prediction's last point);
* replayed at its recorded timing with ``obs_ratio`` as the start ratio
  (:func:`~ipromp_pin.handover.closed_loop.replay_demo`) and scored
  (:func:`~ipromp_pin.handover.score.score_closed_loop`).

Each cell gains, over all its test trials (recognised or not): ``closed_loop_handover_error_cm``,
``closed_loop_final_error_cm``, ``one_shot_handover_error_cm``, ``arrival_delay_s`` (medians),
``max_limit_ratio`` (maximum), ``refused_replans``, ``replans`` and ``collisions`` (sums).

Demos with a tracked skeleton (:meth:`~ipromp_pin.human.HumanMotion.from_demo`) are replayed with the
human checks (:data:`~ipromp_pin.handover.human_score.HUMAN_CHECKS`; the planner knows the human as
observed until each re-plan), then judged against the recorded human motion
(:func:`~ipromp_pin.handover.human_score.human_measures` of the final commanded trajectory), and
replayed once more without the human checks. Their cells gain ``human_min_separation_m`` (the
minimum over the trials), ``protective_distance_time_s``, ``arrival_delay_without_human_s``
(medians) and ``contact_speed_violations`` (sum); without a skeleton these are None and the replay
is the one without the human checks.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from functools import partial

import numpy as np

from ...checks import CheckContext, MotionCheck, build_checks
from ...checks.joint_torques import JointTorques
from ...data import Demo
from ...handover.closed_loop import ClosedLoopSettings, conditioning_predictor, replay_demo
from ...handover.human_score import HUMAN_CHECKS, human_measures
from ...handover.score import ClosedLoopScore, score_closed_loop
from ...human import HumanMotion
from ...motion.limits import LimitProfile, conservative_profile, demonstrated_profile, read_limit_profile
from ...motion.trajectory import Trajectory
from ...promp import IProMP
from ...robot import DemoLimitRecipe, Robot, ee_positions, gripper_rotations
from ...robot.clearance import ClearanceCertifier
from ...robot.objects import ObjectTable
from ..cells import CellResults, ClosedLoopCell, baseline_summary, median
from ..config import EvaluationConfig
from .base import Scorer
from .one_shot import TrialResult, mean_handover_rotations, predict_window, score_trial
from .torques import peak_torque_ratio


@dataclass(frozen=True)
class ClosedLoopOptions:
    """How the closed loop is run in an evaluation.

    Attributes:
        limits: ``"demonstrated"``, ``"conservative"`` or a limit profile file.
        settings: Closed-loop settings; each cell's ``obs_ratio`` replaces ``start_ratio``.
        recipe: How the demonstrated profile is derived (default: the robot settings').
        check_collisions: Contact-test every commanded control sample.
        human: Replay demos with a tracked skeleton with the human checks and measure them
            against the recorded human (see the module docstring).
    """

    limits: str = "demonstrated"
    settings: ClosedLoopSettings = field(default_factory=ClosedLoopSettings)
    recipe: DemoLimitRecipe | None = None
    check_collisions: bool = True
    human: bool = True


@dataclass
class ClosedLoopTrial(TrialResult):
    """A one-shot trial (the :class:`TrialResult` fields) with its closed-loop replay's score.

    Attributes:
        split: Index of the split of the test demo.
        closed_loop: The replay's measures.
    """

    split: int = 0
    closed_loop: ClosedLoopScore | None = None

    def to_row(self) -> dict:
        """The record form: the one-shot fields, ``correct``, then the closed loop's prefixed
        ``closed_loop_`` (without ``split``)."""
        row = asdict(self)
        row.pop("split")
        score = row.pop("closed_loop") or {}
        return row | {"correct": self.correct} | {f"closed_loop_{k}": v for k, v in score.items()}


TRIAL_KEYS = (
    "split",
    "demo",
    "predicted",
    "correct",
    "handover_error_cm",
    "closed_loop_handover_error_cm",
    "closed_loop_final_error_cm",
    "closed_loop_arrival_delay_s",
    "closed_loop_max_limit_ratio",
    "closed_loop_replans",
    "closed_loop_refused_replans",
    "closed_loop_collisions",
    "closed_loop_final_task",
    "handover_orientation_error_deg",
    "closed_loop_handover_orientation_error_deg",
    "closed_loop_peak_torque_ratio",
    "closed_loop_human_min_separation_m",
    "closed_loop_protective_distance_time_s",
    "closed_loop_contact_speed_violations",
    "closed_loop_arrival_delay_without_human_s",
)
"""The fields of a trial kept in a cell's ``closed_loop_trials`` (floats rounded to 4 decimals)."""


def compact(trial: ClosedLoopTrial) -> dict:
    """The :data:`TRIAL_KEYS` of a trial, floats rounded to 4 decimals."""
    row = trial.to_row() | {"split": trial.split}
    out = {k: row[k] for k in TRIAL_KEYS if k in row}
    return {k: round(v, 4) if isinstance(v, float) else v for k, v in out.items()}


def profile_for(options: ClosedLoopOptions, robot: Robot, train: Sequence[Demo], label: str) -> LimitProfile:
    """The limit profile of one model fit (the demonstrated one from its training demos)."""
    if options.limits == "conservative":
        return conservative_profile(robot)
    if options.limits == "demonstrated":
        recipe = options.recipe or robot.settings.demonstrated_limits
        return demonstrated_profile(robot, train, recipe, label)
    return read_limit_profile(options.limits, robot)


def closed_loop_score(trial: ClosedLoopTrial) -> ClosedLoopScore:
    """The trial's closed-loop measures (:func:`replay_trials` scores every trial it makes)."""
    assert trial.closed_loop is not None, "a replayed trial has its closed-loop score"
    return trial.closed_loop


def replay_trials(
    model: IProMP,
    robot: Robot,
    test: Sequence[Demo],
    ratio: float,
    profile: LimitProfile,
    settings: ClosedLoopSettings,
    certifier: ClearanceCertifier | None = None,
    check_collisions: bool = True,
    split: int = 0,
    mean_rot: dict[str, np.ndarray] | None = None,
    objects: ObjectTable | None = None,
    human_checks: Sequence[MotionCheck] = (),
) -> list[ClosedLoopTrial]:
    """Replay every test demo with ``ratio`` as the start ratio; one :class:`ClosedLoopTrial` each.

    ``mean_rot``: the orientation baseline per task (:func:`~.one_shot.mean_handover_rotations` of the
    training demos). ``objects``: the tasks' objects; when given, every re-plan runs the joint-torque
    check (slowed where it asks) and the commanded motion's peak torque ratio is scored with the true
    task's object. ``human_checks``: the human's timed-motion checks, for the demos with a tracked
    skeleton (:func:`replay_scored`)."""
    observe = list(model.observe_)

    def fk(q: np.ndarray) -> np.ndarray:
        return ee_positions(robot, q)

    fk_rot = partial(gripper_rotations, robot)

    torques = JointTorques(robot) if objects is not None else None
    checks = [torques] if torques is not None else []

    run = ClosedLoopSettings(**{**settings.to_dict(), "start_ratio": float(ratio)}).validate()
    conditioner = conditioning_predictor(model, run.condition_noise)
    out = []
    for d in test:
        prediction = predict_window(model, d, ratio, observe)
        one_shot = score_trial(prediction, d, ratio, fk, fk_rot, (mean_rot or {}).get(d.task))
        replay = partial(replay_demo, model, robot, d, profile, run, certifier, conditioner)
        score, commanded = replay_scored(replay, d, robot, check_collisions, human_checks, checks, objects)
        if torques is not None and objects is not None:
            score.peak_torque_ratio = peak_torque_ratio(torques, commanded, d.task, objects)
        out.append(ClosedLoopTrial(**one_shot.__dict__, split=split, closed_loop=score))
    return out


def replay_scored(
    replay,
    demo: Demo,
    robot: Robot,
    check_collisions: bool,
    human_checks: Sequence[MotionCheck],
    other_checks: Sequence[MotionCheck] = (),
    objects: ObjectTable | None = None,
) -> tuple[ClosedLoopScore, Trajectory]:
    """Replay ``demo`` (``replay(checks=..., context=...)`` runs the closed loop) and score it.

    Every re-plan runs ``other_checks`` (e.g. the joint torques with ``objects``). With
    ``human_checks`` and a tracked skeleton: the replay with the human checks as well (the planner's
    context is the recorded human, which the planner knows until each re-plan's time), its measures
    against the recorded human motion, and the arrival delay of a replay without the human checks.
    Returns the score and the commanded trajectory.
    """
    human = HumanMotion.from_demo(demo, robot.settings.human) if human_checks else None
    others = list(other_checks)
    if human is None:
        result = replay(checks=others, context=CheckContext(objects=objects))
        return score_closed_loop(result, demo, robot, check_collisions=check_collisions), result.trajectory
    context = CheckContext(human=human, objects=objects)
    result = replay(checks=[*human_checks, *others], context=context)
    score = score_closed_loop(result, demo, robot, check_collisions=check_collisions)
    measures = human_measures(result.trajectory, human, human_checks)
    free_result = replay(checks=others, context=CheckContext(objects=objects))
    free = score_closed_loop(free_result, demo, robot, check_collisions=False)
    scored = replace(
        score,
        human_min_separation_m=measures.min_separation_m,
        protective_distance_time_s=measures.protective_distance_time_s,
        contact_speed_violations=measures.contact_speed_violations,
        arrival_delay_without_human_s=free.arrival_delay_s,
    )
    return scored, result.trajectory


class ClosedLoopScorer(Scorer):
    """An :class:`~ipromp_pin.promp.IProMP` and a limit profile fitted per job, every test demo
    replayed in the closed loop.

    Args:
        robot: The robot (its kinematics choose the model's settings for the hand-over position).
        options: How the closed loop runs.
        model_params: Keyword arguments of the model's constructor.
        label: Name of the dataset, in the demonstrated profile's name.
        objects: The tasks' objects (:mod:`ipromp_pin.robot.objects`): every re-plan is torque-checked
            and each trial's ``peak_torque_ratio`` scored (``None``: neither).
    """

    label = "closed loop "
    cell_type = ClosedLoopCell

    def __init__(
        self,
        robot: Robot,
        options: ClosedLoopOptions,
        model_params: dict | None = None,
        label_name: str = "",
        objects: ObjectTable | None = None,
    ) -> None:
        self.robot = robot
        self.options = options
        self.model_params = dict(model_params or {})
        self.label_name = label_name
        self.objects = objects
        self.certifier_: ClearanceCertifier | None = None
        self.human_checks_: list[MotionCheck] | None = None

    def check(self) -> None:
        """Validate the settings and read a profile file, before any fit."""
        self.options.settings.validate("closed loop")
        if self.options.limits not in ("conservative", "demonstrated"):
            read_limit_profile(self.options.limits, self.robot)

    def fit(self, train: Sequence[Demo], observe: Sequence[str]) -> ClosedLoopScorer:
        """Fit the model (with the robot's kinematics) and derive the fit's limit profile."""
        if self.certifier_ is None:  # once per process
            self.certifier_ = ClearanceCertifier(self.robot)
        self.certifier_.clear()  # each job's replays start from no ball, whichever jobs ran before
        if self.human_checks_ is None:
            self.human_checks_ = build_checks(self.robot, HUMAN_CHECKS) if self.options.human else []
        fk = partial(ee_positions, self.robot)  # settings chosen for the hand-over position
        fk_rot = partial(gripper_rotations, self.robot)
        model = IProMP(observe=list(observe), **self.model_params)
        self.model_ = model.fit(train, fk=fk, fk_rot=fk_rot)
        self.profile_ = profile_for(self.options, self.robot, train, self.label_name)
        self.mean_rot_ = mean_handover_rotations(train, fk_rot)
        return self

    def score(self, test: Sequence[Demo], obs_ratio: float, split: int = 0) -> list[ClosedLoopTrial]:
        """One :class:`ClosedLoopTrial` per test demo."""
        return replay_trials(
            self.model_,
            self.robot,
            test,
            obs_ratio,
            self.profile_,
            self.options.settings,
            self.certifier_,
            self.options.check_collisions,
            split,
            self.mean_rot_,
            self.objects,
            self.human_checks_ or (),
        )

    def fit_facts(self) -> dict[str, str]:
        """``coupled`` (the coupled groups) and ``limit_profile`` (the profile's name)."""
        return {"coupled": "+".join(self.model_.coupled_groups_), "limit_profile": self.profile_.name}

    def cell_fields(self, reps: Sequence[Sequence], config: EvaluationConfig, results: CellResults) -> dict:
        """The closed-loop medians, maximum and sums (see the module docstring), the baselines'
        summaries (``--baselines``) and every trial's :func:`compact` record."""
        flat: list[ClosedLoopTrial] = [r for rep in reps for r in rep]
        scores = [closed_loop_score(t) for t in flat]
        profiles = [f["limit_profile"] for f in results.fits if "limit_profile" in f]
        return {
            "baselines": baseline_summary(reps, config.protocol == "splits"),
            "limit_profile": profiles[-1] if profiles else self.options.limits,
            "closed_loop_handover_error_cm": median([s.handover_error_cm for s in scores]),
            "closed_loop_final_error_cm": median([s.final_error_cm for s in scores]),
            "one_shot_handover_error_cm": median([t.handover_error_cm for t in flat]),
            "arrival_delay_s": median([s.arrival_delay_s for s in scores]),
            "max_limit_ratio": max((s.max_limit_ratio for s in scores), default=None),
            "refused_replans": int(sum(s.refused_replans for s in scores)),
            "replans": int(sum(s.replans for s in scores)),
            "collisions": int(sum(s.collisions for s in scores)),
            "closed_loop_handover_orientation_error_deg": median(
                [s.handover_orientation_error_deg for s in scores]
            ),
            "peak_torque_ratio": max(
                (s.peak_torque_ratio for s in scores if np.isfinite(s.peak_torque_ratio)), default=None
            ),
            **human_cell_fields(scores),
            "closed_loop_trials": [compact(t) for t in flat],
        }


def human_cell_fields(scores: Sequence[ClosedLoopScore]) -> dict:
    """A cell's human measures over the trials measured against a recorded human: the minimum
    separation, the median time inside ``S_p`` and arrival delay without the human checks, the
    sum of the contact-speed violations (all None when no trial was)."""
    measured = [s for s in scores if s.arrival_delay_without_human_s is not None]
    seps = [s.human_min_separation_m for s in measured if s.human_min_separation_m is not None]
    violations = [s.contact_speed_violations for s in measured if s.contact_speed_violations is not None]
    return {
        "human_min_separation_m": min(seps) if seps else None,
        "protective_distance_time_s": median([s.protective_distance_time_s for s in measured]),
        "contact_speed_violations": int(sum(violations)) if violations else None,
        "arrival_delay_without_human_s": median([s.arrival_delay_without_human_s for s in measured]),
    }
