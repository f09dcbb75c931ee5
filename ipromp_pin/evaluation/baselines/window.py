"""The baselines of one observed set and window: fitted on the training demos' windows, scored on
the test demos' (:class:`WindowBaselines`), one :class:`BaselineTrial` per baseline and test demo."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from ...data import ROBOT, Demo
from ..windows import FitWindow
from .base import Estimator, require_sklearn
from .features import FK, phase_trajectory, standardiser, window_features
from .registry import CLASSIFIERS, REGRESSORS


@dataclass
class BaselineTrial:
    """One baseline's outcome on one test trial.

    Attributes:
        predicted: Recognised task (classifiers), or the true task (regressors are given it).
        posterior: Predicted probability of the true task (classifiers; NaN for regressors).
        brier: Multi-class Brier score of the predicted probabilities (classifiers; NaN otherwise).
        confidence: The probability of the predicted task (classifiers; NaN otherwise).
        joint_rmse_rad: RMSE over joints and the unobserved phases, in [rad] (regressors).
        final_joint_error_rad: RMS over joints of the final configuration error, in [rad] (regressors).
        handover_error_cm: Gripper position error at the hand-over, in [cm] (regressors with FK).
    """

    predicted: str
    posterior: float = float("nan")
    brier: float = float("nan")
    confidence: float = float("nan")
    joint_rmse_rad: float = float("nan")
    final_joint_error_rad: float = float("nan")
    handover_error_cm: float = float("nan")


class WindowBaselines:
    """The baselines of one observed set and observation window, fitted on training demos.

    Args:
        observe: Observed human groups.
        window: The window of every demo, training and test alike (:class:`~..windows.FitWindow`;
            a bare float: that observed fraction of every demo, in (0, 1]). The trajectory regressors
            predict each demo's unobserved part, ``[fraction, 1]`` of its own length.
        fk: Forward kinematics for the hand-over position (None: no hand-over regressor).
    """

    def __init__(self, observe: Sequence[str], window: FitWindow | float, fk: FK | None = None) -> None:
        self.observe = list(observe)
        self.window = FitWindow.of(window)
        self.fk = fk

    def features(self, demos: Sequence[Demo]) -> np.ndarray:
        """Window features (n, 2 D_o) of the demos' windows (raw: not standardised)."""
        return np.stack([window_features(self.window.cut(d, self.observe), self.observe) for d in demos])

    def fit(self, train: Sequence[Demo]) -> WindowBaselines:
        """Fit every baseline on the training demos (settings by cross-validation on them)."""
        require_sklearn()
        # one thread: on these tiny problems OpenMP and BLAS threads cost far more than they save
        with threadpool_limits(limits=1):
            return self._fit(train)

    def _fit(self, train: Sequence[Demo]) -> WindowBaselines:
        self.standardiser_ = standardiser()
        x = self.standardiser_.fit_transform(self.features(train))
        y = np.array([d.task for d in train])
        self.tasks_ = sorted(set(y.tolist()))
        self.classifiers_ = {name: make(y).fit(x, y) for name, make in CLASSIFIERS.items()}
        self.regressors_: dict[tuple[str, str, str], Estimator] = {}
        for task in self.tasks_:
            rows = np.flatnonzero(y == task)
            demos = [train[int(i)] for i in rows]
            unobserved = [phase_trajectory(d, self.window.fraction(d)).ravel() for d in demos]
            targets = {"trajectory": np.stack(unobserved)}
            if self.fk is not None:
                targets["handover"] = self.fk(np.stack([d.groups[ROBOT][-1] for d in demos]))
            for name in REGRESSORS:
                for kind, target in targets.items():
                    self.regressors_[(name, task, kind)] = REGRESSORS[name](rows.size).fit(x[rows], target)
        return self

    def score(self, test: Sequence[Demo]) -> list[dict[str, BaselineTrial]]:
        """Per test demo, every baseline's outcome (regressors are given the true task)."""
        with threadpool_limits(limits=1):
            return self._score(test)

    def _score(self, test: Sequence[Demo]) -> list[dict[str, BaselineTrial]]:
        x = self.standardiser_.transform(self.features(test))
        out: list[dict[str, BaselineTrial]] = [{} for _ in test]
        for name, clf in self.classifiers_.items():
            proba = clf.predict_proba(x)
            classes = list(clf.classes_)
            for i, d in enumerate(test):
                onehot = np.array([c == d.task for c in classes], dtype=float)
                p_true = float(proba[i, classes.index(d.task)]) if d.task in classes else 0.0
                out[i][name] = BaselineTrial(
                    predicted=str(classes[int(np.argmax(proba[i]))]),
                    posterior=p_true,
                    brier=float(np.sum((proba[i] - onehot) ** 2)),
                    confidence=float(np.max(proba[i])),
                )
        for i, d in enumerate(test):
            if d.task not in self.tasks_:
                continue
            q_true = phase_trajectory(d, self.window.fraction(d))
            p_hand = self.fk(d.groups[ROBOT][-1:])[0] if self.fk is not None else None
            for name in REGRESSORS:
                q = (
                    self.regressors_[(name, d.task, "trajectory")]
                    .predict(x[i : i + 1])[0]
                    .reshape(q_true.shape)
                )
                trial = BaselineTrial(
                    predicted=d.task,
                    joint_rmse_rad=float(np.sqrt(np.mean((q - q_true) ** 2))),
                    final_joint_error_rad=float(np.sqrt(np.mean((q[-1] - q_true[-1]) ** 2))),
                )
                if p_hand is not None:
                    p = self.regressors_[(name, d.task, "handover")].predict(x[i : i + 1])[0]
                    trial.handover_error_cm = float(np.linalg.norm(p - p_hand) * 100.0)
                out[i][name] = trial
        return out
