"""Evaluation: the paper's recognition experiment and a repeated random-split protocol.

Two protocols, both honest about what is known online (the test demo's total
duration and phase are never given to the model; it sees only the first
``obs_ratio`` of the human channels it is told to observe):

* ``paper``: per task, the first ``n_train`` demos (in the order of the
  authors' ``filename_<task>.cfg``, else the recorded order) train, the next
  ``n_test`` (10) test. Cells: (n_train, obs_ratio) in
  :data:`PAPER_GRID`, for every observed channel set.
* ``splits``: the same cells, each repeated over ``n_splits`` random
  train/test splits per task; reported as mean and standard deviation.

Besides recognition accuracy, every correctly recognised test trial measures
how well the robot's motion is predicted, next to the unconditioned task mean
(the prior), so the value of conditioning is visible:

* joint RMSE in [rad] over the unobserved part of the motion, compared in
  normalised phase (prediction and truth each over their own duration);
* the error of the final (hand-over) joint configuration, RMS over joints in
  [rad];
* the hand-over gripper position error in [cm], through forward kinematics.

The protocol runner is :func:`ipromp_pin.evaluation.protocol.run_protocol`; this module is the
one-shot evaluation's entry point (:func:`evaluate`) and keeps the names it has always offered.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..data import Dataset
from ..robot import gripper_kinematics, load_robot
from ..robot.objects import ObjectTable
from ..shipped import DEFAULT_ROBOT
from .arm_plans import TrialPlanner, recordings_robot
from .cells import PROBABILITY_FLOOR, Cell, cell_fields, summarise
from .config import PAPER_ACCURACY, PAPER_GRID, EvaluationConfig, ProgressFn, observe_key
from .jobs import JobRunner, run_jobs
from .protocol import run_protocol
from .scorers import BaselineScorer, OneShotScorer, TrialResult, score_trial
from .splits import Indices, check_dataset_size, split_paper, split_random
from .tables import baseline_markdown, format_number, overall, to_json, to_markdown, write_results

__all__ = [
    "PAPER_ACCURACY",
    "PAPER_GRID",
    "PROBABILITY_FLOOR",
    "Cell",
    "EvaluationConfig",
    "Indices",
    "ProgressFn",
    "TrialResult",
    "baseline_markdown",
    "cell_fields",
    "check_dataset_size",
    "evaluate",
    "format_number",
    "observe_key",
    "overall",
    "robot_fk",
    "run_jobs",
    "score_trial",
    "split_paper",
    "split_random",
    "summarise",
    "to_json",
    "to_markdown",
    "write_results",
]


def robot_fk(robot: str | None) -> Callable[[np.ndarray], np.ndarray] | None:
    """Forward kinematics of the robot settings ``robot`` (name or file): joint configurations
    (n, 7) in [rad] -> gripper positions (n, 3) in [m]; ``None`` for no robot."""
    return None if robot is None else gripper_kinematics(load_robot(robot)).fk


def robot_fk_rotations(robot: str | None) -> Callable[[np.ndarray], np.ndarray] | None:
    """Gripper rotations of the robot settings ``robot``: joint configurations (n, 7) in [rad] ->
    rotation matrices (n, 3, 3); ``None`` for no robot."""
    return None if robot is None else gripper_kinematics(load_robot(robot)).fk_rot


def evaluate(
    dataset: Dataset,
    config: EvaluationConfig,
    robot: str | None = DEFAULT_ROBOT,
    progress: ProgressFn | None = None,
    jobs: int | JobRunner = 1,
    objects: ObjectTable | None = None,
    plan: bool = False,
) -> list[Cell]:
    """Run one protocol over every cell of ``config`` and return the table.

    Args:
        dataset: Demos of every task, in protocol order (an arm with a ``[placement]``: recorded on
            its placement's source robot, :func:`~.arm_plans.recordings_robot`).
        config: Protocol, grid and observed channel sets.
        robot: Robot settings (name or file) for the hand-over position error through forward
            kinematics; ``None`` skips it. An arm with a ``[placement]`` executes the model of its
            source robot: every trial's one-shot plan is retargeted and planned on it.
        progress: Called as ``progress(done, total, label)`` after every model fit.
        jobs: Worker processes (model fits run in parallel), or a :class:`~.jobs.JobRunner` (a
            Dask cluster); the results do not depend on it.
        objects: The tasks' objects (:mod:`ipromp_pin.robot.objects`): with a robot, every trial's
            one-shot plan is torque-scored and the cells get ``peak_torque_ratio`` (None: not).
        plan: Plan every trial's one-shot hand-over on the robot (timed, checked, re-timed) and
            score it against the recording (:class:`~.arm_plans.TrialPlanner`; each cell's
            ``plans``); always for a placed arm.
    """
    config.check_protocol()
    executing = load_robot(robot) if robot is not None else None
    source = recordings_robot(executing) if executing is not None else None
    recorded = source or executing
    fk = None if recorded is None else gripper_kinematics(recorded).fk
    fk_rot = None if recorded is None else gripper_kinematics(recorded).fk_rot
    extras = [BaselineScorer(fk)] if config.baselines else []
    planner = None
    if executing is not None and (plan or source is not None):
        planner = TrialPlanner(executing, source, objects)
    loaded = recorded if objects is not None and source is None else None
    return run_protocol(
        dataset,
        config,
        OneShotScorer(config.model_params, fk, fk_rot, loaded, objects, planner),
        extras,
        progress,
        jobs,
    )
