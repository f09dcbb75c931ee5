"""The multi-task EMG-augmented Interaction ProMP estimator (:class:`IProMP`), a thin facade.

:meth:`IProMP.fit` learns one :class:`~ipromp_pin.promp.distribution.TaskModel` per task from
demonstrations (observed human channel groups + the robot's joint angles)
(:mod:`~ipromp_pin.promp.training`), choosing the observation-noise ratio and the groups coupled
to the robot by cross-validation on the training demos (:mod:`~ipromp_pin.promp.selection`), and
freezes the result in a :class:`~ipromp_pin.promp.fitted.FittedModel`. From the first part of a new
human motion (times from motion start; the total duration is unknown) it then computes

1. per task the phase posterior over the candidates of ``alpha = T / T_norm`` (exact marginal
   likelihood, :mod:`~ipromp_pin.promp.likelihood`) and its continuous MAP estimate;
2. the task posterior ``p(k | obs)`` in log space (:mod:`~ipromp_pin.promp.posterior`);
3. for the most probable task, the Gaussian conditioning of its weights on the observation at the
   MAP phase, giving the robot joint trajectory (mean and covariance, in [rad]) over
   ``t in [0, alpha T_norm]`` (:mod:`~ipromp_pin.promp.conditioning`).

Samples can also arrive one by one (:meth:`IProMP.stream`, :mod:`~ipromp_pin.promp.streaming`).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import ThreadpoolController

from ..data import ROBOT, Dataset, Demo, parse_groups
from ..exceptions import IPrompPinError, ModelError, ModelFileError, NotFittedError
from ..signals.groups import DEFAULT_LOG_GROUPS
from .fit import checked, fit_model
from .fitted import FittedModel
from .inputs import check_observation
from .new_task import add_task
from .novelty import DEFAULT_ALPHA
from .parameters import MAX_BLAS_THREADS, MAX_POINTS, PARAMETER_CONSTRAINTS, ParameterMixin, parse_params
from .posterior import Prediction, Recognition
from .predictor import Predictor
from .prior_sampling import sample_task_prior
from .serialization import read_model, write_model
from .streaming import StreamingEstimator

__all__ = ["MAX_BLAS_THREADS", "MAX_POINTS", "IProMP"]


class FittedAttribute:
    """A read-only fitted attribute of :class:`IProMP`: ``get`` of its ``fitted_`` state (an
    AttributeError before ``fit``, as for an attribute that is not set)."""

    def __init__(self, get: Callable[[FittedModel], Any], doc: str) -> None:
        self.get = get
        self.__doc__ = doc

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, model: object, owner: type | None = None) -> Any:
        if model is None:
            return self
        fitted = vars(model).get("fitted_")
        if fitted is None:
            raise AttributeError(
                f"'{type(model).__name__}' object has no attribute '{self.name}' (not fitted)"
            )
        return self.get(fitted)

    def __set__(self, model: object, value: object) -> None:
        raise AttributeError(f"{self.name} is a fitted attribute (read-only): refit or load a model")


class IProMP(ParameterMixin):
    """EMG-augmented Interaction ProMP over several tasks (scikit-learn style estimator).

    Args:
        observe: Observed human channel groups, e.g. ``["orientation", "emg"]`` (or "orientation,emg").
        n_basis: Number of Gaussian basis functions per channel ``K``.
        width: Basis width in phase units (default 0.75 x centre spacing).
        ridge: Relative ridge of the per-demo weight fit.
        margin: Basis centres extend this many spacings beyond each end of the phase range.
        n_alpha: Minimum number of phase candidates inside every task's prior support (>= 3).
        alpha_width: Candidates span ``mu +- alpha_width sigma`` of the phase prior.
        noise: Noise ratio ``nu`` (float > 0) or ``"auto"`` (leave-one-out CV over
            :data:`~ipromp_pin.promp.selection.NOISE_GRID`).
        temperature: Likelihood temperature ``tau`` in (0, 1]: the task and phase posteriors use the
            likelihood to the power ``tau`` (the samples of a smooth motion are not independent, so the
            white-noise likelihood counts their evidence many times over; ``tau`` calibrates the
            posteriors). ``"auto"``: chosen jointly with ``noise`` by leave-one-out CV over
            :data:`~ipromp_pin.promp.selection.TEMPERATURE_GRID`; 1.0 is the textbook likelihood.
        condition_noise: Noise ratio ``nu_c`` with which the robot's weights are conditioned on the
            observation: ``"auto"`` (leave-one-out CV of the robot prediction over
            :data:`~ipromp_pin.promp.selection.NOISE_GRID`, jointly with the coupling), ``"same"``
            (the recognition's ``nu``) or a float > 0. The recognition's ``nu`` is chosen for the task
            and phase posteriors; the robot's prediction may trust the observation more or less.
        head: Decide the task posterior by the discriminative head calibrated on held-out training
            demos (:mod:`~ipromp_pin.promp.head`: window summary + generative posterior); False: the
            generative posterior alone.
        handover: Fit the hand-over regression (:mod:`~ipromp_pin.promp.handover`: per task and
            observed fraction a ridge or k-nearest-neighbour regression from the window to the
            hand-over) and condition the robot's
            prediction on it as far as cross-validation trusts it (possibly not at all); False: never.
        novelty_alpha: Open-set recognition (:mod:`~ipromp_pin.promp.novelty`): the largest fraction
            of observations of the learned tasks recognised as unknown (``known = False``), by
            split-conformal calibration on held-out training demos; None: no novelty detector.
        n_points: Number M of points of the predicted trajectories.
        task_prior: Prior task probabilities (task -> p, or None for uniform).
        robot_group: Name of the robot's group: its joint angles (``"robot"``), or ``"gripper"`` for
            demos whose robot side is a gripper pose path (x, y, z [m], qx, qy, qz, qw; the model then
            predicts that path, :mod:`~ipromp_pin.promp.gripper_side`).
        log_groups: Observed groups modelled in log space (EMG envelopes: see
            :class:`~ipromp_pin.promp.distribution.ChannelScaler`); groups not observed are ignored.
        pooling: Weight in [0, 1] of the covariance pooled over tasks in each task's covariance
            (see :func:`~ipromp_pin.promp.distribution.shrink_covariances`).
        coupling: Observed groups whose weights covary with the robot's (the others are modelled
            for recognition only, independent of the robot and of the coupled groups): ``"auto"``
            (chosen by leave-one-out cross-validation of the robot prediction,
            :mod:`~ipromp_pin.promp.selection`), ``"all"`` (every observed group, the textbook
            Interaction ProMP) or a list of observed groups (empty: the robot's prediction is its prior).
        blas_threads: BLAS threads used while fitting and inferring (None = leave unchanged).
            Inference works on many small matrices, for which more threads only add overhead.

    ``__init__`` only stores the parameters; :meth:`fit` validates them.

    Fitted attributes (set by :meth:`fit` and :meth:`load`; the others are read-only views of
    ``fitted_``, each documented below): ``fitted_`` (the frozen
    :class:`~ipromp_pin.promp.fitted.FittedModel`), ``predictor_`` (its
    :class:`~ipromp_pin.promp.predictor.Predictor`), ``observe_``, ``tasks_``, ``models_``,
    ``basis_``, ``scaler_``, ``groups_``, ``group_slices_``, ``channel_names_``, ``joint_names_``,
    ``n_dims_``, ``n_obs_dims_``, ``duration_nominal_s_``, ``noise_ratio_``, ``noise_var_``,
    ``temperature_``, ``head_``, ``handover_``, ``handover_cv_scores_``, ``orientation_``,
    ``orientation_cv_scores_``, ``condition_noise_ratio_``,
    ``condition_cv_scores_``, ``cv_scores_``, ``coupled_groups_``, ``coupling_cv_scores_``,
    ``task_log_prior_``, ``residual_var_``, ``trained_on_``.
    """

    def __init__(
        self,
        observe: Iterable[str] | str = ("orientation", "emg"),
        n_basis: int = 31,
        width: float | None = None,
        ridge: float = 1e-6,
        margin: float = 1.0,
        n_alpha: int = 20,
        alpha_width: float = 3.0,
        noise: float | str = "auto",
        temperature: float | str = "auto",
        condition_noise: float | str = "auto",
        head: bool = True,
        handover: bool = True,
        novelty_alpha: float | None = DEFAULT_ALPHA,
        n_points: int = 100,
        task_prior: Mapping[str, float] | None = None,
        robot_group: str = ROBOT,
        log_groups: Iterable[str] = DEFAULT_LOG_GROUPS,
        pooling: float = 0.0,
        coupling: str | Iterable[str] = "auto",
        blas_threads: int | None = 1,
    ) -> None:
        self.observe = observe
        self.n_basis = n_basis
        self.width = width
        self.ridge = ridge
        self.margin = margin
        self.n_alpha = n_alpha
        self.alpha_width = alpha_width
        self.noise = noise
        self.temperature = temperature
        self.condition_noise = condition_noise
        self.head = head
        self.handover = handover
        self.novelty_alpha = novelty_alpha
        self.n_points = n_points
        self.task_prior = task_prior
        self.robot_group = robot_group
        self.log_groups = log_groups
        self.pooling = pooling
        self.coupling = coupling
        self.blas_threads = blas_threads

    _parameter_constraints = PARAMETER_CONSTRAINTS
    """Parameter -> its declared constraint (:mod:`~ipromp_pin.promp.parameters`)."""

    # ------------------------------------------------------------------ parameters
    def __sklearn_tags__(self):
        """scikit-learn's estimator tags (called by scikit-learn only, so it imports it): demos are
        not arrays (no input validation), ``y`` (the tasks) is optional."""
        from sklearn.utils import InputTags, Tags, TargetTags

        return Tags(
            estimator_type=None,
            target_tags=TargetTags(required=False),
            no_validation=True,
            input_tags=InputTags(two_d_array=False),
        )

    def check_params(self) -> tuple[list[str], str | list[str]]:
        """Validate the parameters against :attr:`_parameter_constraints` -> the observed groups and
        the coupling (parsed)."""
        return parse_params(self.get_params(), self._parameter_constraints)

    # ------------------------------------------------------------------ fit
    def fit(
        self,
        data: Dataset | Iterable[Demo],
        y: Sequence[str] | None = None,
        *,
        fk: Callable[[np.ndarray], np.ndarray] | None = None,
        fk_rot: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> IProMP:
        """Learn the scaling, per-task weight distributions, phase priors, noise ratio and coupling
        (:func:`~ipromp_pin.promp.fit.fit_model`).

        Args:
            data: A :class:`~ipromp_pin.data.Dataset` or demos (grouped by ``demo.task``).
            y: The demos' task names, optional (scikit-learn's ``fit(X, y)``: checked against
                ``demo.task``, so that stratified cross-validation splitters can use them).
            fk: The robot's forward kinematics, joint angles (n, J) in [rad] -> hand-over positions
                (n, 3) in [m] (e.g. :func:`ipromp_pin.robot.ee_positions` of a loaded robot). When
                given, the coupling and the conditioning noise ratio are chosen for the hand-over
                position error instead of the joint RMSE (see ``choose_coupling``).
            fk_rot: The gripper's rotations, joint angles (n, J) in [rad] -> rotation matrices
                (n, 3, 3) (e.g. :func:`ipromp_pin.robot.frame_placements`' second result); with
                ``fk``, the model gets a hand-over orientation estimate where its cross-validation
                keeps one (:mod:`~ipromp_pin.promp.handover_orientation`).
        """
        observe, coupling = self.check_params()
        if y is not None:
            _check_labels(data, y)
        return self._set_fitted(
            fit_model(data, self.get_params(), observe, coupling, fk, self._limit_threads, fk_rot)
        )

    def add_task(self, demos: Iterable[Demo], task_prior: Mapping[str, float] | None = None) -> IProMP:
        """Add one task, learned from ``demos`` (at least 2 of one new task), without re-fitting the
        tasks the model knows (:func:`~ipromp_pin.promp.new_task.add_task` says what is kept and what
        is new). Returns this estimator, changed in place (as ``fit``).

        Args:
            demos: The new task's demos, with the model's observed groups and robot group.
            task_prior: Task -> prior probability over every task, needed when the model was fitted
                with a ``task_prior``.
        """
        fitted = self._predictor().fitted
        with self._limit_threads():
            grown = add_task(fitted, list(demos), self.get_params(), task_prior)
        if task_prior is not None:
            self.task_prior = dict(task_prior)
        return self._set_fitted(checked(grown))

    def with_human_fit(self, record: Mapping[str, Any] | None) -> IProMP:
        """Store the self-check of the training demos' body model (a JSON object,
        :meth:`ipromp_pin.human.fit.HumanFit.to_json`; None: not measured); written by :meth:`save`."""
        return self._set_fitted(replace(self._predictor().fitted, human_fit=record))

    def with_human_forecast(self, record: Mapping[str, Any] | None) -> IProMP:
        """Store the body's forecast calibration (JSON, :mod:`ipromp_pin.human.forecast`; None: none)."""
        return self._set_fitted(replace(self._predictor().fitted, human_forecast=record))

    def _set_fitted(self, fitted: FittedModel) -> IProMP:
        """Store a fitted state and its predictor (the fitted attributes read them)."""
        predictor = Predictor(fitted, int(self.n_points))
        fitted.noise_var()  # raises on a corrupt state (read by noise_var_)
        self.fitted_, self.predictor_ = fitted, predictor
        return self

    fitted_: FittedModel
    predictor_: Predictor
    observe_ = FittedAttribute(lambda f: list(f.layout.observe), "Observed groups (a list).")
    tasks_ = FittedAttribute(lambda f: list(f.tasks), "Task names.")
    human_fit_ = FittedAttribute(
        lambda f: f.human_fit, "The training demos' body-model self-check (a JSON object, or None)."
    )
    human_forecast_ = FittedAttribute(
        lambda f: f.human_forecast, "The handing arm's forecast calibration (a JSON object, or None)."
    )
    models_ = FittedAttribute(lambda f: dict(f.models), "Task name -> its TaskModel.")
    basis_ = FittedAttribute(lambda f: f.basis, "The GaussianBasis.")
    scaler_ = FittedAttribute(lambda f: f.scaler, "Per-channel ChannelScaler (all dims).")
    groups_ = FittedAttribute(lambda f: list(f.layout.groups), "Modelled groups (observed, then robot).")
    group_slices_ = FittedAttribute(lambda f: dict(f.layout.slices), "Group -> its (start, stop) dims.")
    channel_names_ = FittedAttribute(lambda f: dict(f.layout.channel_names), "Group -> channel names.")
    joint_names_ = FittedAttribute(lambda f: f.layout.joint_names, "The robot's joint names.")
    n_dims_ = FittedAttribute(lambda f: f.layout.n_dims, "Number of modelled dims D.")
    n_obs_dims_ = FittedAttribute(lambda f: f.layout.n_obs_dims, "Number of observed dims D_o.")
    duration_nominal_s_ = FittedAttribute(lambda f: f.duration_nominal_s, "T_norm in [s].")
    noise_ratio_ = FittedAttribute(lambda f: f.noise_ratio, "The chosen noise ratio nu.")
    noise_var_ = FittedAttribute(lambda f: f.noise_var(), "Task -> (D_o,) noise variances (scaled).")
    temperature_ = FittedAttribute(lambda f: f.temperature, "The chosen likelihood temperature tau.")
    head_ = FittedAttribute(lambda f: f.head, "The RecognitionHead (None with head=False).")
    handover_ = FittedAttribute(lambda f: f.handover, "The HandoverRegression (None: not used).")
    handover_cv_scores_ = FittedAttribute(lambda f: dict(f.handover_cv_scores), "Trust factor -> CV error.")
    orientation_ = FittedAttribute(lambda f: f.orientation, "The OrientationEstimate (None: not used).")
    orientation_cv_scores_ = FittedAttribute(
        lambda f: dict(f.orientation_cv_scores), "Orientation trust factor -> CV error in [deg]."
    )
    condition_noise_ratio_ = FittedAttribute(lambda f: f.nu_condition, "The chosen nu_c.")
    condition_cv_scores_ = FittedAttribute(lambda f: dict(f.condition_cv_scores), "nu_c -> CV RMSE [rad].")
    cv_scores_ = FittedAttribute(lambda f: dict(f.noise_cv_scores), "nu -> CV score (noise='auto').")
    coupled_groups_ = FittedAttribute(lambda f: list(f.coupled_groups), "Groups coupled to the robot.")
    coupling_cv_scores_ = FittedAttribute(lambda f: dict(f.coupling_cv_scores), "Coupling -> CV RMSE [rad].")
    task_log_prior_ = FittedAttribute(lambda f: f.task_log_prior, "(K,) log task prior.")
    residual_var_ = FittedAttribute(lambda f: f.residual_var, "(D,) mean residual variance of the basis fit.")
    trained_on_ = FittedAttribute(lambda f: f.trained_on, "DemoRecord per training demo (None: unknown).")

    # ---------------------------------------------------------- inference
    def _limit_threads(self) -> contextlib.AbstractContextManager:
        """Context limiting BLAS threads to ``blas_threads`` (the controller is created once per model)."""
        if self.blas_threads is None:
            return contextlib.nullcontext()
        controller = getattr(self, "_threads", None)
        if controller is None:
            controller = self._threads = ThreadpoolController()
        return controller.limit(limits=int(self.blas_threads), user_api="blas")

    def _predictor(self) -> Predictor:
        predictor = getattr(self, "predictor_", None)
        if predictor is None:
            raise NotFittedError("IProMP is not fitted: call fit() before predict/recognise/stream/save")
        return predictor

    def recognise(self, observation: Demo | Sequence[Demo]) -> Recognition | list[Recognition]:
        """Task posterior and phase estimates of a partial observation (no trajectory).

        Args:
            observation: Partial demo with the observed groups (>= 2 samples), times in [s] from
                motion start; or a sequence of them (batch: a list of recognitions, in order).
        """
        return self._infer(observation, Predictor.recognise)

    recognize = recognise

    def predict(self, observation: Demo | Sequence[Demo]) -> Prediction | list[Prediction]:
        """Recognise the task and predict the robot's trajectory conditioned on the observation.

        Args:
            observation: Partial demo with the observed groups (>= 2 samples), times in [s] from
                motion start; or a sequence of them (batch: a list of predictions, in order).
        """
        return self._infer(observation, Predictor.predict)

    def _infer(self, observation: Demo | Sequence[Demo], method: Callable) -> Any:
        """``method`` of the predictor on the encoded observation (or on each of a batch)."""
        predictor = self._predictor()
        if not isinstance(observation, Demo):
            return [self._infer(o, method) for o in _batch(observation)]
        # longer than any learned motion is not an error: no task explains it (``known`` False)
        parts, t_last = predictor.encode(observation, check_length=False)  # shapes, finite values
        check_observation(predictor.fitted, observation, parts)
        with self._limit_threads():
            return method(predictor, parts, t_last)

    def score(self, demos: Sequence[Demo], y: Sequence[str] | None = None, ratio: float = 0.2) -> float:
        """Recognition accuracy: the fraction of ``demos`` whose first ``ratio`` of the motion is
        recognised as their task (scikit-learn's ``score``, so ``GridSearchCV`` can use it).

        Args:
            demos: Full demos (the observed groups are taken from them).
            y: Their task names (default: ``demo.task``; checked against it when given).
            ratio: Observed fraction of each demo, in (0, 1].
        """
        demos = list(_batch(demos))
        if y is not None:
            _check_labels(demos, y)
        observe = self.observe_ if hasattr(self, "observe_") else parse_groups(self.observe)
        recs = self.recognise([d.head(ratio, groups=observe) for d in demos])
        assert isinstance(recs, list)  # a batch in, a list out
        return float(np.mean([r.task == d.task for r, d in zip(recs, demos, strict=True)]))

    def sample_prior(
        self, task: str, n: int, random_state: np.random.Generator | int | None = None
    ) -> list[Demo]:
        """``n`` demonstrations drawn from the prior of ``task`` (every modelled group, ``n_points``
        samples over a duration drawn from the task's phase prior; see
        :mod:`~ipromp_pin.promp.prior_sampling`)."""
        return sample_task_prior(self._predictor().fitted, task, n, int(self.n_points), random_state)

    def stream(self) -> StreamingEstimator:
        """A streaming estimator that refreshes the estimate as samples arrive one by one."""
        return StreamingEstimator(self._predictor(), self._limit_threads)

    # ------------------------------------------------------------- plots
    def distribution(self, task: str, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """Learned centre and spread (n, D) of every channel over phases ``z`` (n,), and the channel
        labels (:meth:`FittedModel.distribution <ipromp_pin.promp.fitted.FittedModel.distribution>`)."""
        return self._predictor().fitted.distribution(task, z)

    def distribution_band(
        self, task: str, z: np.ndarray, n_sigma: float = 2.0
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
        """Centre, lower and upper ``n_sigma`` band (n, D) of every channel over phases ``z`` (n,) in
        original units, and the channel labels (:meth:`FittedModel.distribution_band
        <ipromp_pin.promp.fitted.FittedModel.distribution_band>`)."""
        return self._predictor().fitted.distribution_band(task, z, n_sigma)

    def train_trajectories(self, task: str, z: np.ndarray) -> np.ndarray:
        """Basis-fitted trajectories (N, n, D) of the training demos at phases ``z``, original units."""
        return self._predictor().fitted.train_trajectories(task, z)

    def channel_labels(self) -> list[str]:
        """``"group/channel"`` labels of all modelled dims (observed groups, then robot)."""
        return self._predictor().fitted.layout.labels()

    # ------------------------------------------------------------ files
    def save(self, path: str | Path) -> None:
        """Write the fitted model to a versioned, pickle-free ``.npz`` file."""
        write_model(self.get_params(), self._predictor().fitted, path)

    @classmethod
    def load(cls, path: str | Path) -> IProMP:
        """Read a model written by :meth:`save` (raises ModelFileError on a bad file)."""
        params, fitted = read_model(path)
        model = cls(**params)
        try:
            model.check_params()
        except (ModelError, TypeError, ValueError) as exc:
            raise ModelFileError(f"{path}: corrupt model file (parameters: {exc})") from exc
        try:
            return model._set_fitted(fitted)
        except (IPrompPinError, ValueError, TypeError, IndexError) as exc:
            raise ModelFileError(f"{path}: corrupt model file ({exc})") from exc


def _batch(observations: Iterable[Demo]) -> list[Demo]:
    """A batch of observations as a list (raises ModelError for anything else)."""
    if isinstance(observations, str | bytes) or not isinstance(observations, Iterable):
        raise ModelError(f"expected a Demo or a sequence of Demo objects, got {type(observations).__name__}")
    out = list(observations)
    for o in out:
        if not isinstance(o, Demo):
            raise ModelError(f"expected a Demo or a sequence of Demo objects, got an item {type(o).__name__}")
    return out


def _check_labels(data: Dataset | Iterable[Demo], y: Sequence[str]) -> None:
    """Raise ModelError when the labels ``y`` are not the demos' tasks."""
    demos = data.all_demos() if isinstance(data, Dataset) else list(data)
    labels = [str(v) for v in y]
    if len(labels) != len(demos):
        raise ModelError(f"y has {len(labels)} labels for {len(demos)} demos")
    for d, label in zip(demos, labels, strict=True):
        if label != d.task:
            raise ModelError(f"y says '{label}' for demo {d.name} of task '{d.task}'")
