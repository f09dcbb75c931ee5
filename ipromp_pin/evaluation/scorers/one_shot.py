"""The one-shot scorer: the model predicts each test demo once from its observed window (its first
``obs_ratio``, or its first seconds: :mod:`..windows`) and the prediction is measured against the
whole demo (recognition, joint errors in [rad], the hand-over gripper position error in [cm], each
also for the unconditioned prior). With a robot and the tasks'
objects, each trial's one-shot plan (the prediction timed as ``run`` times it) also gets its peak
joint torque ratio with the true task's object (:mod:`..scoring`), and each cell the maximum over its
trials, ``peak_torque_ratio``."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict
from typing import Any

import numpy as np

from ...data import Demo
from ...planning.human_forecast import with_forecast
from ...promp import IProMP, Prediction
from ...robot import Robot
from ...robot.objects import ObjectTable
from ...safety import CheckSuite
from ..arm_plans import TrialPlanner, plan_summary
from ..cells import CellResults, baseline_summary, calibration, expected_calibration_error
from ..config import EvaluationConfig
from ..scoring import FK, FKRot, TrialResult, mean_handover_rotations, one_shot_peak_torque_ratio, score_trial
from ..windows import FitWindow
from .base import Scorer

__all__ = ["OneShotScorer", "TrialResult", "predict_window", "score_trial"]


def predict_window(
    model: IProMP, demo: Demo, window: FitWindow | float, observe: Sequence[str]
) -> Prediction:
    """The model's prediction from the ``window`` of the demo's ``observe`` groups (a bare float:
    that fraction of the demo)."""
    prediction = model.predict(FitWindow.of(window).cut(demo, observe))
    assert isinstance(prediction, Prediction), "IProMP.predict of one Demo returns one Prediction"
    return prediction


class OneShotScorer(Scorer):
    """An :class:`~ipromp_pin.promp.IProMP` fitted per job, every test demo predicted once.

    Args:
        model_params: Keyword arguments of the model's constructor.
        fk: Forward kinematics for the model's settings and the hand-over error (None: skipped).
        fk_rot: Gripper rotations, for the hand-over orientation errors (None: skipped).
        robot: The robot whose joint torques the one-shot plans are scored for (with ``objects``).
        objects: The tasks' objects (:mod:`ipromp_pin.robot.objects`); with ``robot``, every trial's
            ``peak_torque_ratio`` is scored and the cells get theirs (``None``: neither, the cells
            are as without torques).
        planner: Plans every trial's one-shot hand-over on the executing arm and scores it
            (:class:`~..arm_plans.TrialPlanner`; each cell gets ``plans``). None: not planned.
    """

    def __init__(
        self,
        model_params: dict | None = None,
        fk: FK | None = None,
        fk_rot: FKRot | None = None,
        robot: Robot | None = None,
        objects: ObjectTable | None = None,
        planner: TrialPlanner | None = None,
    ) -> None:
        self.model_params = dict(model_params or {})
        self.planner = planner
        self.fk = fk
        self.fk_rot = fk_rot
        self.robot = robot
        self.objects = objects
        self.suite_: CheckSuite | None = None

    @property
    def scores_torques(self) -> bool:
        """Whether the trials' one-shot plans are torque-scored (a robot and objects are given)."""
        return self.robot is not None and self.objects is not None

    def fit(self, train: Sequence[Demo], observe: Sequence[str]) -> OneShotScorer:
        """Fit the model on the training demos."""
        self.observe_ = list(observe)
        model = IProMP(observe=list(observe), **self.model_params)
        self.model_ = model.fit(train, fk=self.fk, fk_rot=self.fk_rot)
        if self.planner is not None:  # its plans judge the body as `run` does: forecast where trusted
            self.model_ = with_forecast(self.model_, train, self.planner.robot.settings.human)
        self.mean_rot_ = {} if self.fk_rot is None else mean_handover_rotations(train, self.fk_rot)
        return self

    def score(self, test: Sequence[Demo], window: FitWindow | float, split: int = 0) -> list[TrialResult]:
        """One :class:`TrialResult` per test demo (its one-shot plan torque-scored, with objects)."""
        window = FitWindow.of(window)
        out = []
        for d in test:
            prediction = predict_window(self.model_, d, window, self.observe_)
            fraction = window.fraction(d)
            trial = score_trial(prediction, d, fraction, self.fk, self.fk_rot, self.mean_rot_.get(d.task))
            if self.robot is not None and self.objects is not None:
                if self.suite_ is None:  # once per process (the arm's dynamics are built on first use)
                    self.suite_ = CheckSuite.build(self.robot, ["joint_torques"])
                trial.peak_torque_ratio = one_shot_peak_torque_ratio(
                    self.suite_, self.robot, prediction, d.task, self.objects
                )
            if self.planner is not None:
                trial.plan = self.planner.plan_trial(self.model_, d, window)
            out.append(trial)
        return out

    def fit_facts(self) -> dict[str, str]:
        """``coupled``: the observed groups the fitted model couples to the robot."""
        return {"coupled": "+".join(getattr(self.model_, "coupled_groups_", self.observe_))}

    def cell_fields(self, reps: Sequence[Sequence], config: EvaluationConfig, results: CellResults) -> dict:
        """Calibration, the baselines' summaries and (paper protocol) every trial."""
        flat = [r for rep in reps for r in rep]
        log_loss, brier = calibration([(r.posterior, r.brier) for r in flat])
        out: dict[str, Any] = {
            "log_loss": log_loss,
            "brier": brier,
            "ece": expected_calibration_error([(r.confidence, r.correct) for r in flat]),
            "baselines": baseline_summary(reps, config.protocol == "splits"),
        }
        if self.scores_torques:
            peaks = [r.peak_torque_ratio for r in flat if np.isfinite(r.peak_torque_ratio)]
            out["peak_torque_ratio"] = max(peaks, default=None)
        if self.planner is not None:
            p = self.planner
            source = None if p.source is None else p.source.settings.name
            out["plans"] = plan_summary([r.plan for r in flat], p.robot.settings.name, source)
        if config.protocol != "splits":
            out["trials"] = [self._trial_row(r) for r in flat]
        return out

    def _trial_row(self, trial: TrialResult) -> dict:
        """A trial's record in a cell (``peak_torque_ratio`` only when torques are scored)."""
        row = asdict(trial) | {"correct": trial.correct}
        if not self.scores_torques:
            row.pop("peak_torque_ratio")
        if self.planner is None:
            row.pop("plan")
        return row
