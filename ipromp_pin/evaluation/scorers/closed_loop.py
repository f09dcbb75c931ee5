"""The closed-loop scorer: per fit a limit profile (derived from the fit's training demos,
``demonstrated``, or the robot's ``conservative`` one, or a profile file); every test demo is

* predicted once from its cell's window (its first ``obs_ratio``, or its first seconds; the one-shot
  prediction, scored as the one-shot scorer does: recognition, joint errors,
  ``one_shot_handover_error_cm`` = the gripper position error of the one-shot plan's end, which is
  the prediction's last point);
* replayed at its recorded timing, the robot starting at the window's end (``obs_ratio`` as the
  start ratio, the paper's protocol; or the window's seconds as the online start rule's time,
  :func:`start_settings`; :func:`~ipromp_pin.planning.closed_loop.replay_demo`) and scored
  (:func:`~ipromp_pin.evaluation.scoring.score_closed_loop`).

Each cell gains, over all its test trials (recognised or not): ``closed_loop_handover_error_cm``,
``closed_loop_final_error_cm``, ``one_shot_handover_error_cm``, ``arrival_delay_s`` (medians),
``max_limit_ratio`` (maximum), ``refused_replans``, ``replans`` and ``collisions`` (sums).

Demos with a tracked skeleton (:meth:`~ipromp_pin.human.HumanMotion.from_demo`) are replayed with the
human checks (:data:`~ipromp_pin.safety.HUMAN_CHECKS`; the planner knows the human as
observed until each re-plan), then judged against the recorded human motion
(:func:`~ipromp_pin.evaluation.scoring.human_measures` of the final commanded trajectory), and
replayed once more without the human checks. Their cells gain ``human_min_separation_m`` (the
minimum over the trials), ``protective_distance_time_s``, ``arrival_delay_without_human_s``
(medians) and ``contact_speed_violations`` (sum); without a skeleton these are None and the replay
is the one without the human checks.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from ...data import Demo
from ...exceptions import UnreachableError
from ...human import HumanMotion
from ...motion.limits import LimitProfile, choose_limit_profile, read_limit_profile
from ...planning.closed_loop import ClosedLoopResult, ClosedLoopSettings, conditioning_predictor, replay_demo
from ...planning.human_forecast import with_forecast
from ...promp import IProMP
from ...robot import DemoLimitRecipe, Robot, gripper_kinematics
from ...robot.objects import ObjectTable
from ...safety import HUMAN_CHECKS, CheckContext, CheckSuite
from ..arm_plans import TrajectoryJudge, human_of, replay_arm_measures, replay_arm_summary
from ..cells import CellResults, ClosedLoopCell, baseline_summary, median
from ..config import EvaluationConfig
from ..scoring import ClosedLoopScore, TrialResult, mean_handover_rotations, replay_scored, score_trial
from ..windows import FitWindow
from .base import Scorer
from .one_shot import predict_window


@dataclass(frozen=True)
class ClosedLoopOptions:
    """How the closed loop is run in an evaluation.

    Attributes:
        limits: ``"demonstrated"``, ``"conservative"`` or a limit profile file.
        settings: Closed-loop settings; each cell's window replaces the start: a ratio window's
            fraction of each test demo is its ``start_ratio`` (the paper's protocol), a window in
            seconds' end its ``start_after_s`` (the online rule; ``start_confidence`` is kept).
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
        closed_loop: The replay's measures (None: refused before the loop, the executing arm cannot
            reach the recorded start pose).
        arm: The re-plans on the executing arm and the re-evaluation of the commanded trajectory
            (:func:`~..arm_plans.replay_arm_measures`; None: not measured).
    """

    split: int = 0
    closed_loop: ClosedLoopScore | None = None
    arm: dict | None = None

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
    "closed_loop_start_s",
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
    "closed_loop_stop_s",
    "closed_loop_retreat_s",
    "arm",
)
"""The fields of a trial kept in a cell's ``closed_loop_trials`` (floats rounded to 4 decimals)."""


def compact(trial: ClosedLoopTrial) -> dict:
    """The :data:`TRIAL_KEYS` of a trial, floats rounded to 4 decimals."""
    row = trial.to_row() | {"split": trial.split}
    out = {k: row[k] for k in TRIAL_KEYS if k in row}
    return {k: round(v, 4) if isinstance(v, float) else v for k, v in out.items()}


def profile_for(options: ClosedLoopOptions, robot: Robot, train: Sequence[Demo], label: str) -> LimitProfile:
    """The limit profile of one model fit (the demonstrated one from its training demos)."""
    return choose_limit_profile(options.limits, robot, train, label, options.recipe)


def closed_loop_score(trial: ClosedLoopTrial) -> ClosedLoopScore:
    """The trial's closed-loop measures (:func:`replay_trials` scores every trial it replays)."""
    assert trial.closed_loop is not None, "a replayed trial has its closed-loop score"
    return trial.closed_loop


def evaluation_suite(robot: Robot, objects: ObjectTable | None, human: bool) -> CheckSuite:
    """The checks of an evaluation's re-plans: the motion's own (limits, workspace, self-collision),
    the joint torques with ``objects``, the human checks when ``human`` (they run on the demos with a
    tracked skeleton)."""
    drop = ["uncertainty"] + ([] if objects is not None else ["joint_torques"])
    return CheckSuite.build(robot, exclude=drop + ([] if human else list(HUMAN_CHECKS)))


def start_settings(settings: ClosedLoopSettings, window: FitWindow) -> ClosedLoopSettings:
    """``settings`` starting the robot at the end of a cell's ``window``: after its fraction of each
    test demo (a ratio window, ``start_ratio``: the paper's protocol) or after its seconds
    (``start_after_s``: the online rule); validated."""
    if window.window.is_ratio:
        return dataclasses.replace(settings, start_ratio=window.window.value, start_after_s=None).validate()
    return dataclasses.replace(settings, start_ratio=None, start_after_s=window.end_s).validate()


def replay_trials(
    model: IProMP,
    robot: Robot,
    test: Sequence[Demo],
    window: FitWindow | float,
    profile: LimitProfile,
    settings: ClosedLoopSettings,
    suite: CheckSuite,
    check_collisions: bool = True,
    split: int = 0,
    mean_rot: dict[str, np.ndarray] | None = None,
    objects: ObjectTable | None = None,
    arm: ArmReplay | None = None,
) -> list[ClosedLoopTrial]:
    """Replay every test demo starting at the end of ``window`` (:func:`start_settings`); one
    :class:`ClosedLoopTrial` each, its one-shot fields from the same window.

    ``suite``: the checks of every re-plan (:func:`evaluation_suite`); its human checks run on the
    demos with a tracked skeleton, against the recorded human as observed until each re-plan, and are
    then judged against the whole recording (:func:`~ipromp_pin.evaluation.scoring.replay_scored`).
    ``mean_rot``: the orientation baseline per task (training demos). ``objects``: the tasks'
    objects; the commanded motion's peak torque ratio is scored with the true task's object.
    ``arm``: the recordings' robot when ``robot`` executes its model retargeted, and the judge of
    every commanded trajectory (:class:`ArmReplay`; a demo without a tracked skeleton is then replayed
    with the human checks of the assumed human, as ``replay`` checks it, and judged against it); a
    replay whose start the arm cannot reach is a trial without ``closed_loop``."""
    observe = list(model.observe_)
    source = None if arm is None else arm.source
    fk, fk_rot = gripper_kinematics(robot if source is None else source)
    window = FitWindow.of(window)
    run = start_settings(settings, window)
    conditioner = conditioning_predictor(model, run.condition_noise)
    out = []
    for d in test:
        prediction = predict_window(model, d, window, observe)
        fraction = window.fraction(d)
        one_shot = score_trial(prediction, d, fraction, fk, fk_rot, (mean_rot or {}).get(d.task))
        checks_human = bool(set(HUMAN_CHECKS) & set(suite.names))
        tracked = HumanMotion.from_demo(d, robot.settings.human) if checks_human else None
        human = tracked
        if human is None and checks_human and arm is not None and arm.judge is not None:
            human = human_of(d, robot)  # the assumed human, as ``replay`` checks it
        used = suite if human is not None else suite.without(HUMAN_CHECKS)

        def replay(checks: CheckSuite, context: CheckContext, demo: Demo = d) -> ClosedLoopResult:
            return replay_demo(model, robot, demo, profile, run, checks, context, conditioner, source)

        context = CheckContext(human=human, objects=objects)
        try:
            score, result = replay_scored(replay, d, robot, used, context, tracked, check_collisions, source)
        except UnreachableError:
            out.append(ClosedLoopTrial(**one_shot.__dict__, split=split, closed_loop=None))
            continue
        measured = None
        if arm is not None and arm.judge is not None:
            judged = arm.judge.judge(result.trajectory, d, human)
            measured = replay_arm_measures(result, judged)
        out.append(ClosedLoopTrial(**one_shot.__dict__, split=split, closed_loop=score, arm=measured))
    return out


@dataclass
class ArmReplay:
    """How the closed loop's arm is measured.

    Attributes:
        source: The robot whose joints the recordings and the model hold when the arm executes them
            retargeted (its ``[placement] source``; None: the arm's own).
        judge: Re-evaluates every commanded trajectory (None: not re-evaluated).
    """

    source: Robot | None = None
    judge: TrajectoryJudge | None = None


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
        arm: The recordings' robot when ``robot`` executes its model retargeted (the model is fitted
            with its kinematics; the ``demonstrated`` profile, derived from its joints, becomes the
            arm's ``conservative`` one) and the judge of every commanded trajectory; each cell then
            gets ``arm`` (:class:`ArmReplay`; None: the arm's own model, nothing re-evaluated).
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
        arm: ArmReplay | None = None,
    ) -> None:
        self.robot = robot
        self.arm = arm
        self.options = options
        self.model_params = dict(model_params or {})
        self.label_name = label_name
        self.objects = objects
        self.suite_: CheckSuite | None = None

    def check(self) -> None:
        """Validate the settings and read a profile file, before any fit."""
        self.options.settings.validate("closed loop")
        if self.options.limits not in ("conservative", "demonstrated"):
            read_limit_profile(self.options.limits, self.robot)

    def fit(self, train: Sequence[Demo], observe: Sequence[str]) -> ClosedLoopScorer:
        """Fit the model (with the robot's kinematics) and derive the fit's limit profile."""
        if self.suite_ is None:  # once per process
            self.suite_ = evaluation_suite(self.robot, self.objects, self.options.human)
        self.suite_.reset()  # each job's replays start from no cache, whichever jobs ran before
        source = None if self.arm is None else self.arm.source
        fk, fk_rot = gripper_kinematics(source or self.robot)  # settings chosen for the hand-over position
        model = IProMP(observe=list(observe), **self.model_params)
        self.model_ = model.fit(train, fk=fk, fk_rot=fk_rot)
        if self.options.human:  # the body's forecast, on the training demos (none with handing_arm "held")
            self.model_ = with_forecast(self.model_, train, self.robot.settings.human)
        options = self.options
        if source is not None and options.limits == "demonstrated":  # the demos are the source's joints
            options = dataclasses.replace(options, limits="conservative")
        self.profile_ = profile_for(options, self.robot, train, self.label_name)
        self.mean_rot_ = mean_handover_rotations(train, fk_rot)
        return self

    def score(self, test: Sequence[Demo], window: FitWindow | float, split: int = 0) -> list[ClosedLoopTrial]:
        """One :class:`ClosedLoopTrial` per test demo, the robot starting at the end of ``window``."""
        return replay_trials(
            self.model_,
            self.robot,
            test,
            window,
            self.profile_,
            self.options.settings,
            self.suite_ or evaluation_suite(self.robot, self.objects, self.options.human),
            self.options.check_collisions,
            split,
            self.mean_rot_,
            self.objects,
            self.arm,
        )

    def fit_facts(self) -> dict[str, str]:
        """``coupled`` (the coupled groups) and ``limit_profile`` (the profile's name)."""
        return {"coupled": "+".join(self.model_.coupled_groups_), "limit_profile": self.profile_.name}

    def cell_fields(self, reps: Sequence[Sequence], config: EvaluationConfig, results: CellResults) -> dict:
        """The closed-loop medians, maximum and sums (see the module docstring), the baselines'
        summaries (``--baselines``) and every trial's :func:`compact` record."""
        flat: list[ClosedLoopTrial] = [r for rep in reps for r in rep]
        scores = [closed_loop_score(t) for t in flat if t.closed_loop is not None]
        profiles = [f["limit_profile"] for f in results.fits if "limit_profile" in f]
        return {
            "baselines": baseline_summary(reps, config.protocol == "splits"),
            "limit_profile": profiles[-1] if profiles else self.options.limits,
            "closed_loop_handover_error_cm": median([s.handover_error_cm for s in scores]),
            "closed_loop_final_error_cm": median([s.final_error_cm for s in scores]),
            "one_shot_handover_error_cm": median([t.handover_error_cm for t in flat]),
            "arrival_delay_s": median([s.arrival_delay_s for s in scores]),
            "robot_start_s": median([s.start_s for s in scores]),
            "max_limit_ratio": max((s.max_limit_ratio for s in scores), default=None),
            "refused_replans": int(sum(s.refused_replans for s in scores)),
            "replans": int(sum(s.replans for s in scores)),
            "never_started": int(sum(s.replans == 0 for s in scores)),
            "stopped_unknown": int(sum(s.stop_s is not None for s in scores)),
            "retreated": int(sum(s.retreat_s is not None for s in scores)),
            "collisions": int(sum(s.collisions for s in scores)),
            "closed_loop_handover_orientation_error_deg": median(
                [s.handover_orientation_error_deg for s in scores]
            ),
            "peak_torque_ratio": max(
                (s.peak_torque_ratio for s in scores if np.isfinite(s.peak_torque_ratio)), default=None
            ),
            **human_cell_fields(scores),
            "arm": self.arm_summary(flat),
            "closed_loop_trials": [compact(t) for t in flat],
        }

    def arm_summary(self, flat: Sequence[ClosedLoopTrial]) -> dict | None:
        """The cell's ``arm`` (:func:`~..arm_plans.replay_arm_summary`; None without :attr:`arm`)."""
        if self.arm is None:
            return None
        source = None if self.arm.source is None else self.arm.source.settings.name
        rows = [t.arm if t.closed_loop is not None else None for t in flat]
        return replay_arm_summary(rows, self.robot.settings.name, source)


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
