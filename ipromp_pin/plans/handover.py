"""A hand-over planned from one observation, end to end: :func:`plan` and :class:`HandoverPlan`.

The public way to turn a trained model and the observed first part of a human's motion into the
robot's checked, timed motion and its files::

    plan = ipromp_pin.plan(model, observation, robot="baxter_left")
    plan.task, plan.posterior, plan.passed, plan.trajectory   # recognition, verdict, motion
    plan.write("out")                                         # trajectory, bags, report (preview)

:func:`plan` knows only what a robot would know when it plans: the observation (never the rest of
the recording), the model, the robot, the tasks' objects and the human as observed so far (its
tracked skeleton, or the assumed standing human of the robot settings with the observed hand). It
recognises the task and predicts, times the path from the end of the observation, checks it with
every registered check (:class:`~ipromp_pin.safety.CheckSuite`), slows it where the checks ask,
and plans the retreat after the hand-over when the recognised task's object has one. What needs the
recording's future is a score: :meth:`HandoverPlan.scored` measures the plan against the whole
recording (hand-over position and orientation errors, the gripper's distance from the recorded
hand), as ``ipromp-pin run`` does on a dataset's demo. ``run``, ``plan`` and the batch go through
:func:`plan`; every time of a plan is on the human's clock (t = 0 at the start of the human's motion).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..data import Demo
from ..evaluation.scoring import RecordedScores, recorded_scores
from ..human import HumanMotion
from ..human.fit import Registration, registered, registration_of
from ..motion.trajectory import Trajectory
from ..outputs.report import arrival
from ..planning.one_shot import PlanResult, check_model_joints
from ..planning.one_shot import plan as plan_one_shot
from ..planning.retreat import RetreatResult, plan_retreat
from ..planning.transfer import arm_for, source_robot
from ..promp import IProMP
from ..robot import Robot, load_robot
from ..robot.objects import ObjectTable, load_objects
from ..safety import CheckContext, CheckSuite
from .warnings import missing_object_warnings, range_warnings, single_task_warning

if TYPE_CHECKING:
    from .files import WrittenPlan

LogFn = Callable[[str], None]
"""Where progress messages go (one line each)."""


@dataclass
class HandoverPlan:
    """A planned hand-over (see the module docstring).

    Attributes:
        robot: The robot it was planned for.
        observation: The observed part of the human's motion it was planned from.
        approach: The one-shot plan: the prediction, the committed trajectory and its verdicts.
        retreat: The retreat after the hand-over (None: the task has none, or it was not asked for).
        context: What the checks knew (the human as observed, the objects).
        warnings: One line each, where a user is likely to be fooled.
        scores: The plan measured against the recording's future (:meth:`scored`; None: not scored).
    """

    robot: Robot
    observation: Demo
    approach: PlanResult
    retreat: RetreatResult | None
    context: CheckContext
    warnings: list[str] = field(default_factory=list)
    scores: RecordedScores | None = None

    @property
    def task(self) -> str:
        """The recognised task."""
        return self.approach.prediction.task

    @property
    def posterior(self) -> dict[str, float]:
        """Task -> its posterior probability."""
        p = self.approach.prediction
        return {t: float(v) for t, v in zip(p.tasks, p.posterior, strict=True)}

    @property
    def known(self) -> bool:
        """Whether the observation was recognised as one of the model's tasks (else the plan fails
        with ``unknown_task``: the robot acts only on a known task)."""
        return self.approach.known

    @property
    def novelty_p_value(self) -> float | None:
        """The observation's conformal novelty p-value (None: the model has no novelty detector)."""
        p = float(self.approach.prediction.novelty_p_value)
        return None if p != p else p

    @property
    def trajectory(self) -> Trajectory:
        """The approach's committed trajectory (on the human's clock)."""
        return self.approach.trajectory

    @property
    def passed(self) -> bool:
        """Whether the approach and the retreat passed every required check."""
        return self.approach.passed and (self.retreat is None or self.retreat.passed)

    @property
    def failures(self) -> list[str]:
        """The failed checks (``timing``; the retreat's as ``retreat.<check>``), empty when it passed."""
        later = [] if self.retreat is None else [f"retreat.{f}" for f in self.retreat.failures]
        return self.approach.failures + later

    @property
    def arrival(self) -> dict[str, float | bool]:
        """When the human (predicted) and the robot reach the hand-over, in [s] on the human's clock,
        and how much the checks' slow-down made of it (``report.json``'s ``arrival``:
        :func:`~ipromp_pin.outputs.report.arrival`)."""
        return arrival(self.approach)

    def scored(self, recording: Demo) -> HandoverPlan:
        """This plan with its scores against ``recording``, the whole recording it was planned from
        (its robot group and hand path after the observation)."""
        source = None if self.approach.retarget is None else self.approach.retarget.source
        return replace(self, scores=recorded_scores(self.approach, recording, self.robot, source))

    def write(self, out_dir: str | Path, **options: Any) -> WrittenPlan:
        """Write the plan's files into ``out_dir`` together; ``options``: those of
        :func:`~.files.write_plan` (``preview=True``, ``rosbag=False``, ...)."""
        from .files import write_plan

        return write_plan(self, Path(out_dir), **options)


def human_as_observed(
    observation: Demo,
    robot: Robot,
    human: HumanMotion | None = None,
    registration: Registration | None = None,
) -> HumanMotion:
    """The human the checks judge, as known at the end of ``observation``: ``human`` when given,
    else the observation's tracked skeleton (through ``registration``, the model's corrected
    registration: :mod:`ipromp_pin.human.fit`), else the robot settings' assumed standing human with
    the observed hand path; later samples unknown (held and growing at the human speed)."""
    settings = robot.settings.human
    if human is None:
        human = HumanMotion.from_demo(observation, settings)
        human = None if human is None else registered(human, registration)
    if human is None:
        human = HumanMotion.assumed_human(settings, observation.t, observation.extras.get("hand_position"))
    return human.until(float(observation.t[-1]))


def plan(
    model: IProMP,
    observation: Demo,
    robot: str | Robot | None = None,
    *,
    objects: str | Path | ObjectTable | None = None,
    human: HumanMotion | None = None,
    suite: CheckSuite | None = None,
    control_rate_hz: float = 100.0,
    retreat: bool = True,
    log: LogFn | None = None,
) -> HandoverPlan:
    """Plan the robot's part of the hand-over the human starts in ``observation``.

    Args:
        model: A fitted :class:`~ipromp_pin.promp.IProMP` (its robot joints the robot's).
        observation: The observed first part of the human's motion (the model's observed groups;
            times in [s] from the start of the motion); nothing after it is used.
        robot: The robot settings (a shipped name, a settings file) or a loaded robot. An arm with a
            ``[placement]`` executes a model of its placement's source robot (e.g. ``"panda"`` with a
            Baxter model): the prediction is retargeted through the gripper (``plan.approach.retarget``).
            None: Baxter's left arm for a model of its joints; a model of gripper poses needs one named
            (any arm follows them, Baxter's left arm too).
        objects: The tasks' objects (a task file, or a table read already; None: the shipped
            ``robots/objects.toml``).
        human: The human the checks judge (None: the observation's tracked skeleton through the
            model's corrected registration, else the assumed human); it is cut to the end of the
            observation.
        suite: The checks (None: every registered check); their caches are reset first, so that
            the plan does not depend on what the suite checked before.
        control_rate_hz: The trajectory's control rate in [Hz].
        retreat: Plan the retreat after the hand-over when the recognised task's object has one.
        log: Progress messages (None: silent).

    Raises:
        ModelError: the model's joints are neither the robot's nor its placement source's, or a model
            of gripper poses without ``robot``.
        InfeasibleError: the predicted path cannot be timed.
    """
    named = arm_for(model, robot, "robot=NAME")
    arm = named if isinstance(named, Robot) else load_robot(named)
    table = objects if isinstance(objects, ObjectTable) else load_objects(objects)
    source = source_robot(model, arm)  # a model of the robot the arm is placed beside: retargeted
    check_model_joints(model, arm if source is None else source)
    checks = suite if suite is not None else CheckSuite.build(arm)
    checks.reset()  # a plan does not depend on the plans before it (e.g. distances computed for them)
    correction = registration_of(getattr(model, "human_fit_", None))
    context = CheckContext(human=human_as_observed(observation, arm, human, correction), objects=table)
    approach = plan_one_shot(
        model,
        arm,
        observation,
        checks,
        context,
        control_rate_hz=control_rate_hz,
        log=log,
        check_joints=False,
        source=source,
    )
    task = approach.prediction.task
    warnings = [w for w in [single_task_warning(model)] if w] + range_warnings(model, observation)
    warnings += missing_object_warnings([task], table)
    entry = table.for_task(task)
    after = None
    if retreat and entry is not None and entry.retreat is not None:
        after = plan_retreat(
            arm, approach, entry.retreat, checks, context, control_rate_hz=control_rate_hz, log=log
        )
    return HandoverPlan(arm, observation, approach, after, context, warnings)
