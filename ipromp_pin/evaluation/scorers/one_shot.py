"""The one-shot scorer: the model predicts each test demo once from its first ``obs_ratio`` and the
prediction is measured against the whole demo (recognition, joint errors in [rad], the hand-over
gripper position error in [cm], each also for the unconditioned prior). With a robot and the tasks'
objects, each trial's one-shot plan (the prediction timed as ``run`` times it) also gets its peak
joint torque ratio with the true task's object (:mod:`.torques`), and each cell the maximum over its
trials, ``peak_torque_ratio``."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from ...checks.joint_torques import JointTorques
from ...data import ROBOT, Demo
from ...promp import IProMP, Prediction, handover_orientation
from ...robot import Robot
from ...robot.objects import ObjectTable
from ...robot.rotations import chordal_mean, geodesic_deg
from ..baselines import BaselineTrial
from ..cells import CellResults, baseline_summary, calibration
from ..config import EvaluationConfig
from .base import Scorer
from .torques import one_shot_peak_torque_ratio

FK = Callable[[np.ndarray], np.ndarray]
"""Forward kinematics: joint configurations (n, 7) in [rad] -> gripper positions (n, 3) in [m]."""

FKRot = handover_orientation.FKRot
"""Forward kinematics: joint configurations (n, 7) in [rad] -> gripper rotation matrices (n, 3, 3)."""


@dataclass
class TrialResult:
    """Outcome of one test trial.

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
        handover_orientation_error_deg: Geodesic angle between the predicted and the recorded gripper
            rotations at the hand-over (FK of the final configurations), in [deg] (NaN without FK).
        handover_orientation_baseline_deg: The same for the baseline: the mean hand-over rotation
            (chordal L2 mean) of the training demos of the true task, in [deg].
        baselines: Baseline name -> its outcome on the same window (``--baselines``,
            :mod:`ipromp_pin.evaluation.baselines`).
        peak_torque_ratio: Peak |joint torque| / effort limit of the one-shot plan with the true task's
            object (NaN: not scored, no robot or no objects).
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
    handover_orientation_error_deg: float = float("nan")
    handover_orientation_baseline_deg: float = float("nan")
    baselines: dict[str, BaselineTrial] = field(default_factory=dict)
    peak_torque_ratio: float = float("nan")

    @property
    def correct(self) -> bool:
        """True when the task was recognised."""
        return self.predicted == self.task


def phase_interp(t: np.ndarray, q: np.ndarray, duration_s: float, z: np.ndarray) -> np.ndarray:
    """Values of a trajectory ``q`` (N, D) sampled at ``t`` (N,) in [s] at phases ``z`` of ``duration_s``."""
    tz = z * duration_s
    return np.stack([np.interp(tz, t, q[:, j]) for j in range(q.shape[1])], axis=1)


def predict_window(model: IProMP, demo: Demo, obs_ratio: float, observe: Sequence[str]) -> Prediction:
    """The model's prediction from the first ``obs_ratio`` of the demo's ``observe`` groups."""
    prediction = model.predict(demo.head(obs_ratio, groups=observe))
    assert isinstance(prediction, Prediction), "IProMP.predict of one Demo returns one Prediction"
    return prediction


def score_trial(
    prediction: Prediction,
    demo: Demo,
    obs_ratio: float,
    fk: FK | None,
    fk_rot: FKRot | None = None,
    baseline_rot: np.ndarray | None = None,
) -> TrialResult:
    """Measure one prediction against the full test demo.

    Args:
        prediction: The model's prediction from the observed part of ``demo``.
        demo: The full test demo (its robot group is the ground truth).
        obs_ratio: Observed fraction, in (0, 1].
        fk: Forward kinematics, joint configurations (n, 7) in [rad] -> gripper
            positions (n, 3) in [m]; ``None`` skips the Cartesian error.
        fk_rot: Gripper rotations of joint configurations; ``None`` skips the orientation errors.
        baseline_rot: (3, 3) the baseline's hand-over rotation (:func:`mean_handover_rotations`).
    """
    assert demo.duration_s is not None, "a Demo sets its duration when it is made"
    truth = demo.groups[ROBOT]
    z = np.linspace(obs_ratio, 1.0, 50)
    true_z = phase_interp(demo.t - demo.t[0], truth, demo.duration_s, z)
    pred_z = phase_interp(prediction.t, prediction.q_mean, prediction.duration_s, z)
    prior_z = phase_interp(prediction.t, prediction.q_prior_mean, prediction.duration_s, z)
    rmse = float(np.sqrt(np.mean((pred_z - true_z) ** 2)))
    rmse_prior = float(np.sqrt(np.mean((prior_z - true_z) ** 2)))
    q_true_end = truth[-1]
    q_pred_end = prediction.q_mean[-1]
    q_prior_end = prediction.q_prior_mean[-1]
    fin = float(np.sqrt(np.mean((q_pred_end - q_true_end) ** 2)))
    fin_prior = float(np.sqrt(np.mean((q_prior_end - q_true_end) ** 2)))
    ho = ho_prior = float("nan")
    if fk is not None:
        p = fk(np.stack([q_true_end, q_pred_end, q_prior_end]))
        ho = float(np.linalg.norm(p[1] - p[0]) * 100.0)
        ho_prior = float(np.linalg.norm(p[2] - p[0]) * 100.0)
    rot_err = rot_base = float("nan")
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
        joint_rmse_rad=rmse,
        joint_rmse_prior_rad=rmse_prior,
        final_joint_error_rad=fin,
        final_joint_error_prior_rad=fin_prior,
        handover_error_cm=ho,
        handover_error_prior_cm=ho_prior,
        duration_error_s=float(prediction.duration_s - demo.duration_s),
        brier=float(np.sum((np.asarray(prediction.posterior) - onehot) ** 2)),
        handover_orientation_error_deg=rot_err,
        handover_orientation_baseline_deg=rot_base,
    )


def mean_handover_rotations(train: Sequence[Demo], fk_rot: FKRot) -> dict[str, np.ndarray]:
    """Task -> the chordal L2 mean (3, 3) of the gripper rotations at the hand-over (the last robot
    sample) of that task's training demos: the orientation baseline."""
    by_task: dict[str, list[np.ndarray]] = {}
    for d in train:
        by_task.setdefault(d.task, []).append(d.groups[ROBOT][-1])
    return {task: chordal_mean(fk_rot(np.stack(qs))) for task, qs in by_task.items()}


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
    """

    def __init__(
        self,
        model_params: dict | None = None,
        fk: FK | None = None,
        fk_rot: FKRot | None = None,
        robot: Robot | None = None,
        objects: ObjectTable | None = None,
    ) -> None:
        self.model_params = dict(model_params or {})
        self.fk = fk
        self.fk_rot = fk_rot
        self.robot = robot
        self.objects = objects
        self.torques_: JointTorques | None = None

    @property
    def scores_torques(self) -> bool:
        """Whether the trials' one-shot plans are torque-scored (a robot and objects are given)."""
        return self.robot is not None and self.objects is not None

    def fit(self, train: Sequence[Demo], observe: Sequence[str]) -> OneShotScorer:
        """Fit the model on the training demos."""
        self.observe_ = list(observe)
        model = IProMP(observe=list(observe), **self.model_params)
        self.model_ = model.fit(train, fk=self.fk, fk_rot=self.fk_rot)
        self.mean_rot_ = {} if self.fk_rot is None else mean_handover_rotations(train, self.fk_rot)
        return self

    def score(self, test: Sequence[Demo], obs_ratio: float, split: int = 0) -> list[TrialResult]:
        """One :class:`TrialResult` per test demo (its one-shot plan torque-scored, with objects)."""
        out = []
        for d in test:
            prediction = predict_window(self.model_, d, obs_ratio, self.observe_)
            trial = score_trial(prediction, d, obs_ratio, self.fk, self.fk_rot, self.mean_rot_.get(d.task))
            if self.robot is not None and self.objects is not None:
                if self.torques_ is None:  # once per process (the arm's dynamics are built on first use)
                    self.torques_ = JointTorques(self.robot)
                trial.peak_torque_ratio = one_shot_peak_torque_ratio(
                    self.torques_, prediction, d.task, self.objects
                )
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
            "baselines": baseline_summary(reps, config.protocol == "splits"),
        }
        if self.scores_torques:
            peaks = [r.peak_torque_ratio for r in flat if np.isfinite(r.peak_torque_ratio)]
            out["peak_torque_ratio"] = max(peaks, default=None)
        if config.protocol != "splits":
            out["trials"] = [self._trial_row(r) for r in flat]
        return out

    def _trial_row(self, trial: TrialResult) -> dict:
        """A trial's record in a cell (``peak_torque_ratio`` only when torques are scored)."""
        row = asdict(trial) | {"correct": trial.correct}
        if not self.scores_torques:
            row.pop("peak_torque_ratio")
        return row
