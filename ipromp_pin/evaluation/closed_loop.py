"""``ipromp-pin evaluate --closed-loop``: every test demo of every cell replayed in the closed loop.

The cells, splits and model fits are those of :func:`ipromp_pin.evaluation.evaluate.evaluate` (same random
splits for the same seed). For every fit the limit profile is derived from that fit's training
demos (``demonstrated``) or taken from the settings (``conservative``) or a profile file; every test
demo is then

* predicted once from its first ``obs_ratio`` (the one-shot prediction, scored as ``evaluate`` does:
  recognition, joint errors, ``one_shot_handover_error_cm`` = the gripper position error of the
  one-shot plan's end, which is the prediction's last point);
* replayed at its recorded timing with ``obs_ratio`` as the start ratio
  (:func:`~ipromp_pin.planning.closed_loop.replay_demo`) and scored
  (:func:`~ipromp_pin.evaluation.scoring.score_closed_loop`).

Each cell gains, over all its test trials (recognised or not): ``closed_loop_handover_error_cm``,
``closed_loop_final_error_cm``, ``one_shot_handover_error_cm``, ``arrival_delay_s`` (medians),
``max_limit_ratio`` (maximum), ``refused_replans``, ``replans`` and ``collisions`` (sums).
"""

from __future__ import annotations

from pathlib import Path

from ..data import Dataset
from ..robot import gripper_kinematics, load_robot
from ..robot.objects import ObjectTable
from ..shipped import DEFAULT_ROBOT
from .arm_plans import TrajectoryJudge, recordings_robot
from .cells import ClosedLoopCell
from .config import EvaluationConfig, ProgressFn
from .jobs import JobRunner
from .protocol import run_protocol
from .scorers import BaselineScorer
from .scorers.closed_loop import (
    TRIAL_KEYS,
    ArmReplay,
    ClosedLoopOptions,
    ClosedLoopScorer,
    ClosedLoopTrial,
    profile_for,
    replay_trials,
)
from .tables import closed_loop_markdown, write_closed_loop_results

__all__ = [
    "TRIAL_KEYS",
    "ArmReplay",
    "ClosedLoopCell",
    "ClosedLoopOptions",
    "ClosedLoopTrial",
    "closed_loop_markdown",
    "evaluate_closed_loop",
    "profile_for",
    "replay_trials",
    "write_closed_loop_results",
]


def evaluate_closed_loop(
    dataset: Dataset,
    config: EvaluationConfig,
    options: ClosedLoopOptions | None = None,
    robot: str = DEFAULT_ROBOT,
    progress: ProgressFn | None = None,
    jobs: int | JobRunner = 1,
    objects: ObjectTable | None = None,
    judge: bool = False,
) -> list[ClosedLoopCell]:
    """Run one protocol with the closed loop over every cell of ``config`` (see the module docstring).

    The random splits are those :func:`~ipromp_pin.evaluation.evaluate.evaluate` draws for the same
    seed. With ``config.baselines`` the cells also get the baselines' summaries. With ``objects``
    (:mod:`ipromp_pin.robot.objects`) every re-plan is torque-checked and ``peak_torque_ratio`` scored.
    An arm with a ``[placement]`` replays its source robot's recordings (``dataset``) with every
    re-plan retargeted (:class:`~.scorers.closed_loop.ArmReplay`), its commanded trajectories
    re-evaluated (:class:`~.arm_plans.TrajectoryJudge`), each cell's ``arm`` summarising them;
    ``judge``: re-evaluate them for an arm of its own model too.
    """
    options = options or ClosedLoopOptions()
    options.settings.validate("closed loop")
    config.check_protocol()
    loaded = load_robot(robot)
    source = recordings_robot(loaded)
    arm = None
    if source is not None or judge:
        arm = ArmReplay(source, TrajectoryJudge(loaded, objects))
    name = Path(str(dataset.root)).name
    scorer = ClosedLoopScorer(loaded, options, config.model_params, name, objects, arm)
    extras = [BaselineScorer(gripper_kinematics(source or loaded).fk)] if config.baselines else []
    cells = run_protocol(dataset, config, scorer, extras, progress, jobs)
    return [c for c in cells if isinstance(c, ClosedLoopCell)]
