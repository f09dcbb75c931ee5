"""The fitted state of a multi-task Interaction ProMP: everything inference reads, frozen.

:class:`FittedModel` is what :meth:`IProMP.fit <ipromp_pin.promp.estimator.IProMP.fit>` learns and
what a model file stores (:mod:`ipromp_pin.promp.serialization`): the channel layout and scaling,
the basis, one :class:`~ipromp_pin.promp.distribution.TaskModel` per task, the nominal duration,
the task prior, the noise ratio and the observed groups coupled to the robot, with the
cross-validation scores that chose them. Inference (:mod:`ipromp_pin.promp.predictor`) never
changes it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..exceptions import ModelError
from .basis import GaussianBasis
from .distribution import ChannelScaler, TaskModel
from .handover import HandoverRegression
from .handover_orientation import OrientationEstimate
from .head import RecognitionHead
from .layout import ChannelLayout
from .novelty import NoveltyDetector
from .provenance import DemoRecord


@dataclass(frozen=True)
class FittedModel:
    """A fitted multi-task Interaction ProMP (scaled units unless said otherwise).

    Attributes:
        layout: Channel layout (observed groups, then the robot).
        basis: The Gaussian basis of every channel.
        scaler: Per-channel scaling of all dims (:class:`ChannelScaler`).
        tasks: Task names (the order of every per-task array).
        models: Task name -> its :class:`TaskModel`.
        duration_nominal_s: ``T_norm`` in [s], the mean training duration (phase ``alpha = T / T_norm``).
        task_log_prior: (K,) log prior probability of every task.
        noise_ratio: ``nu``: observed dim ``d`` has white noise of variance ``nu delta_d``.
        coupled_groups: Observed groups whose weights covary with the robot's.
        residual_var: (D,) mean per-sample residual variance of the demos' basis fits.
        noise_cv_scores: Candidate ``nu`` -> cross-validation score (empty when ``nu`` was given).
        coupling_cv_scores: Candidate coupled groups (``"+"``-joined) -> CV RMSE of the robot
            prediction in [rad] (empty when the coupling was given or had one candidate).
        trained_on: One :class:`~ipromp_pin.promp.provenance.DemoRecord` per training demo, or
            None when unknown (a model file of format version 1).
        head: The discriminative recognition head deciding the task posterior (None: the generative
            posterior).
        temperature: Likelihood temperature ``tau`` of the task and phase posteriors (1: textbook).
        condition_noise_ratio: ``nu_c``, the noise ratio of the conditioning of the robot's weights
            (None: ``noise_ratio``; models fitted before it existed).
        condition_cv_scores: Candidate ``nu_c`` -> CV RMSE of the robot prediction in [rad] with the
            chosen coupling (empty when ``nu_c`` was given).
        handover: The hand-over regression fused into the robot's prediction
            (:mod:`~ipromp_pin.promp.handover`; None: none).
        handover_cv_scores: Candidate trust factor (``inf``: off) -> its CV error (empty when not
            cross-validated).
        orientation: The hand-over orientation estimate conditioned on after the regression
            (:mod:`~ipromp_pin.promp.handover_orientation`; None: none, e.g. fitted without the
            gripper's rotations or a model file of format version 4 or older).
        orientation_cv_scores: Its candidate trust factors (``inf``: off) -> mean hand-over
            orientation error in [deg] on the held-out training demos.
        novelty: The open-set novelty detector with its conformal calibration
            (:mod:`~ipromp_pin.promp.novelty`; None: none, every observation a task explains is known).
        added_tasks: Tasks added after the fit (:func:`~ipromp_pin.promp.new_task.add_task`), the last
            ones of :attr:`tasks`. The recognition head, the hand-over regression and the orientation
            estimate cover the first :attr:`n_fit_tasks` tasks only.
        human_fit: The self-check and calibration of the training demos' body model, as the JSON
            object of :meth:`ipromp_pin.human.fit.HumanFit.to_json` (None: not measured, e.g. no
            skeleton in the training demos or a model file of format version 6 or older).
        human_forecast: The cross-validated forecast of the handing arm from the predicted hand, as
            the JSON object of :meth:`ipromp_pin.human.forecast.ForecastCalibration.to_json` (None:
            none, e.g. no observed hand frame, or a model file of format version 7 or older).
    """

    layout: ChannelLayout
    basis: GaussianBasis
    scaler: ChannelScaler
    tasks: tuple[str, ...]
    models: Mapping[str, TaskModel]
    duration_nominal_s: float
    task_log_prior: np.ndarray
    noise_ratio: float
    coupled_groups: tuple[str, ...]
    residual_var: np.ndarray
    noise_cv_scores: Mapping[float, float]
    coupling_cv_scores: Mapping[str, float]
    trained_on: tuple[DemoRecord, ...] | None = None
    temperature: float = 1.0
    head: RecognitionHead | None = None
    condition_noise_ratio: float | None = None
    condition_cv_scores: Mapping[float, float] = field(default_factory=dict)
    handover: HandoverRegression | None = None
    handover_cv_scores: Mapping[float, float] = field(default_factory=dict)
    orientation: OrientationEstimate | None = None
    orientation_cv_scores: Mapping[float, float] = field(default_factory=dict)
    novelty: NoveltyDetector | None = None
    added_tasks: tuple[str, ...] = ()

    @property
    def n_fit_tasks(self) -> int:
        """Number of tasks of the fit itself (the first ones; the others were added after it)."""
        return len(self.tasks) - len(self.added_tasks)

    human_fit: Mapping[str, Any] | None = None
    human_forecast: Mapping[str, Any] | None = None

    @property
    def nu_condition(self) -> float:
        """The noise ratio the robot's weights are conditioned with (``condition_noise_ratio``, else
        ``noise_ratio``)."""
        return self.noise_ratio if self.condition_noise_ratio is None else float(self.condition_noise_ratio)

    def task_models(self) -> list[TaskModel]:
        """The task models in :attr:`tasks` order."""
        return [self.models[t] for t in self.tasks]

    @property
    def longest_s(self) -> float:
        """Longest plausible motion of any task in [s]: its largest phase candidate times ``T_norm``."""
        return max(float(m.alpha_grid[-1]) for m in self.models.values()) * self.duration_nominal_s

    def noise_var(self) -> dict[str, np.ndarray]:
        """Task -> (D_o,) observation noise variances ``nu delta_d`` of the observed dims."""
        n_obs = self.layout.n_obs_dims
        return {t: self.noise_ratio * m.diag[:n_obs] for t, m in self.models.items()}

    def task_model(self, task: str) -> TaskModel:
        """The model of ``task`` (raises ModelError for an unknown task)."""
        if task not in self.models:
            raise ModelError(f"unknown task '{task}' (tasks: {', '.join(self.tasks)})")
        return self.models[task]

    def distribution(self, task: str, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """Learned centre and spread (n, D) of every channel over phases ``z`` (n,).

        For a linear channel these are the mean and standard deviation in original units. A channel
        modelled in log space (EMG, ``log_groups``) is Gaussian in ``log(y + c)``: its centre is the
        median ``exp(mu) - c`` in original units but its spread is the standard deviation of
        ``log(y + c)`` (log units); :meth:`distribution_band` gives bands in original units.

        Returns:
            centre, spread and the channel names as ``"group/channel"`` (observed groups, then robot).
        """
        mean, std = self.task_model(task).distribution(self.basis(np.asarray(z, dtype=float)))
        return self.scaler.inverse(mean), std * self.scaler.scale, self.layout.labels()

    def distribution_band(
        self, task: str, z: np.ndarray, n_sigma: float = 2.0
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
        """Centre and the ``n_sigma`` band (n, D) of every channel over phases ``z`` (n,), all in
        original units: the model's quantiles ``mu +- n_sigma sigma`` mapped through the channel
        scaling (for log-scaled channels ``exp(.) - c``, so the band is asymmetric around the median).

        Returns:
            centre, lower, upper and the channel names as ``"group/channel"``.
        """
        mean, std = self.task_model(task).distribution(self.basis(np.asarray(z, dtype=float)))
        inv = self.scaler.inverse
        return inv(mean), inv(mean - n_sigma * std), inv(mean + n_sigma * std), self.layout.labels()

    def train_trajectories(self, task: str, z: np.ndarray) -> np.ndarray:
        """Basis-fitted trajectories (N, n, D) of the training demos at phases ``z``, original units."""
        weights = self.task_model(task).train_weights
        return self.scaler.inverse(np.einsum("nk,idk->ind", self.basis(np.asarray(z, float)), weights))
