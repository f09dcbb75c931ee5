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
from pathlib import Path

import numpy as np
from threadpoolctl import ThreadpoolController

from ..data import ROBOT, Dataset, Demo, parse_groups
from ..exceptions import IPrompPinError, ModelError, ModelFileError, NotFittedError
from ..signals.groups import DEFAULT_LOG_GROUPS
from .basis import GaussianBasis
from .distribution import ChannelScaler, TaskModel
from .fitted import FittedModel
from .handover_selection import choose_handover
from .posterior import Prediction, Recognition
from .predictor import Predictor
from .prior_sampling import sample_task_prior
from .provenance import demo_record
from .selection import NOISE_GRID, TEMPERATURE_GRID, choose_coupling, choose_noise, fit_recognition_head
from .serialization import read_model, write_model
from .streaming import StreamingEstimator
from .training import PhaseSettings, demos_by_task, log_task_prior, prepare_training, task_models
from .validation import check_fitted

MAX_POINTS = 100_000
"""Largest number of points of a predicted trajectory (``n_points``)."""

MAX_BLAS_THREADS = 1024
"""Largest ``blas_threads``."""


class IProMP:
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
        n_points: Number M of points of the predicted trajectories.
        task_prior: Prior task probabilities (task -> p, or None for uniform).
        robot_group: Name of the robot's joint-angle group.
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

    Fitted attributes:
        fitted_: The frozen :class:`~ipromp_pin.promp.fitted.FittedModel` (everything below).
        predictor_: Its :class:`~ipromp_pin.promp.predictor.Predictor`.
        observe_: Observed groups (a list, parsed from ``observe``).
        tasks_: Task names.
        models_: Task name -> :class:`~ipromp_pin.promp.distribution.TaskModel`.
        basis_: The :class:`~ipromp_pin.promp.basis.GaussianBasis`.
        scaler_: Per-channel :class:`~ipromp_pin.promp.distribution.ChannelScaler` (all dims).
        groups_: Modelled groups (observed then robot); ``group_slices_`` their dim ranges.
        channel_names_: Group -> channel names; ``joint_names_`` the robot's.
        n_dims_, n_obs_dims_: Number of modelled and of observed dims.
        duration_nominal_s_: ``T_norm`` in [s] (mean training duration).
        noise_ratio_: Chosen ``nu``; ``noise_var_`` task -> (D_obs,) noise variances (scaled units).
        temperature_: Chosen likelihood temperature ``tau``.
        head_: The fitted :class:`~ipromp_pin.promp.head.RecognitionHead` (None with ``head=False``).
        handover_: The fitted :class:`~ipromp_pin.promp.handover.HandoverRegression` (None: not used);
            ``handover_cv_scores_`` its candidate trust factors (``inf``: off) -> CV error.
        condition_noise_ratio_: Chosen ``nu_c`` (see ``condition_noise``); ``condition_cv_scores_``
            ``nu_c`` -> CV RMSE of the robot prediction in [rad] (only with ``condition_noise="auto"``).
        cv_scores_: ``nu`` -> CV score (only with ``noise="auto"``).
        coupled_groups_: Observed groups coupled to the robot (see ``coupling``).
        coupling_cv_scores_: Candidate coupled groups (``"+"``-joined) -> CV RMSE of the robot
            prediction in [rad] (only with ``coupling="auto"`` and more than one candidate).
        task_log_prior_: (K,) log task prior.
        residual_var_: (D,) mean per-sample residual variance of the basis fit (scaled units).
        trained_on_: One :class:`~ipromp_pin.promp.provenance.DemoRecord` per training demo (None
            for a model loaded from a format-version-1 file, which does not record them).
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
        self.n_points = n_points
        self.task_prior = task_prior
        self.robot_group = robot_group
        self.log_groups = log_groups
        self.pooling = pooling
        self.coupling = coupling
        self.blas_threads = blas_threads

    # ------------------------------------------------------------------ parameters
    def get_params(self, deep: bool = True) -> dict[str, object]:
        """The constructor parameters (scikit-learn convention; ``deep`` is accepted and ignored)."""
        return {name: getattr(self, name) for name in _PARAMS}

    def set_params(self, **params: object) -> IProMP:
        """Set constructor parameters (scikit-learn convention); refit to use them."""
        for name, value in params.items():
            if name not in _PARAMS:
                raise ModelError(f"unknown parameter '{name}' (parameters: {', '.join(_PARAMS)})")
            setattr(self, name, value)
        return self

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
        """Validate the parameters -> the observed groups and the coupling (parsed)."""
        observe = parse_groups(self.observe)
        coupling = self.coupling if isinstance(self.coupling, str) else list(self.coupling)
        if self.robot_group in observe:
            raise ModelError(f"the robot group '{self.robot_group}' cannot be an observed group")
        noise = self.noise
        if not (isinstance(noise, str) and noise == "auto"):
            if isinstance(noise, str) or not (float(noise) > 0 and np.isfinite(float(noise))):
                raise ModelError(f"noise must be 'auto' or a positive float, got {noise!r}")
        tau = self.temperature
        if not (isinstance(tau, str) and tau == "auto"):
            if isinstance(tau, str) or not (0.0 < float(tau) <= 1.0):
                raise ModelError(f"temperature must be 'auto' or a float in (0, 1], got {tau!r}")
        nu_c = self.condition_noise
        if not (isinstance(nu_c, str) and nu_c in ("auto", "same")):
            if isinstance(nu_c, str) or not (float(nu_c) > 0 and np.isfinite(float(nu_c))):
                raise ModelError(f"condition_noise must be 'auto', 'same' or a positive float, got {nu_c!r}")
        if not 0.0 <= float(self.pooling) <= 1.0:
            raise ModelError(f"pooling must be in [0, 1], got {self.pooling!r}")
        if isinstance(coupling, str):
            if coupling not in ("auto", "all"):
                raise ModelError(
                    f"coupling must be 'auto', 'all' or a list of observed groups, got {self.coupling!r}"
                )
        elif any(g not in observe for g in coupling) or len(set(coupling)) != len(coupling):
            raise ModelError(f"coupling {coupling} must list distinct observed groups ({observe})")
        for name, value, low, high in (
            ("n_alpha", self.n_alpha, 3, None),
            ("n_points", self.n_points, 2, MAX_POINTS),
            ("n_basis", self.n_basis, 2, None),
        ):
            if not _is_int(value) or value < low or (high is not None and value > high):
                bound = f">= {low}" if high is None else f"in [{low}, {high}]"
                raise ModelError(f"{name} must be an integer {bound}, got {value!r}")
        threads = self.blas_threads
        if threads is not None and (not _is_int(threads) or not 1 <= threads <= MAX_BLAS_THREADS):
            raise ModelError(
                f"blas_threads must be None or an integer in [1, {MAX_BLAS_THREADS}], got {threads!r}"
            )
        prior = self.task_prior
        if prior is not None:
            if not isinstance(prior, Mapping) or not all(
                isinstance(t, str) and _is_number(p) and np.isfinite(p) and p >= 0 for t, p in prior.items()
            ):
                raise ModelError(f"task_prior must map task names to non-negative numbers, got {prior!r}")
        for name in ("ridge", "margin", "alpha_width"):
            value = getattr(self, name)
            if not _is_number(value) or not np.isfinite(value):
                raise ModelError(f"{name} must be a finite number, got {value!r}")
        return observe, coupling

    # ------------------------------------------------------------------ fit
    def fit(
        self,
        data: Dataset | Iterable[Demo],
        y: Sequence[str] | None = None,
        *,
        fk: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> IProMP:
        """Learn the scaling, per-task weight distributions, phase priors, noise ratio and coupling.

        Args:
            data: A :class:`~ipromp_pin.data.Dataset` or demos (grouped by ``demo.task``).
            y: The demos' task names, optional (scikit-learn's ``fit(X, y)``: checked against
                ``demo.task``, so that stratified cross-validation splitters can use them).
            fk: The robot's forward kinematics, joint angles (n, J) in [rad] -> hand-over positions
                (n, 3) in [m] (e.g. :func:`ipromp_pin.robot.ee_positions` of a loaded robot). When
                given, the coupling and the conditioning noise ratio are chosen for the hand-over
                position error instead of the joint RMSE (see ``choose_coupling``).
        """
        observe, coupling = self.check_params()
        if y is not None:
            _check_labels(data, y)
        basis = GaussianBasis(self.n_basis, self.width, self.ridge, self.margin)
        by_task = demos_by_task(data)
        training = prepare_training(by_task, observe, self.robot_group, basis, self.log_groups)
        settings = PhaseSettings(int(self.n_alpha), float(self.alpha_width), float(self.pooling))
        prior = log_task_prior(training.tasks, self.task_prior)
        with self._limit_threads():
            nus = NOISE_GRID if isinstance(self.noise, str) else (float(self.noise),)
            taus = TEMPERATURE_GRID if isinstance(self.temperature, str) else (float(self.temperature),)
            head, rows = None, []
            if len(nus) > 1 or len(taus) > 1 or self.head or self.handover:
                noise = choose_noise(training, settings, prior, nus, taus)
                nu, tau, rows = noise.nu, noise.temperature, noise.rows
                nu_scores = noise.scores if len(nus) > 1 else {}
                if self.head and rows:
                    head = fit_recognition_head(rows, tau, len(training.tasks))
            else:
                nu, tau, nu_scores = nus[0], taus[0], {}
            nu_c = {"auto": None, "same": nu}.get(self.condition_noise, self.condition_noise)  # type: ignore[arg-type]
            nu_c = None if nu_c is None else float(nu_c)
            cands = None if coupling == "auto" else [list(observe) if coupling == "all" else coupling]
            choice = choose_coupling(training, settings, nu_c, cands, fk)
            coupled = choice.groups
            handover, handover_scores = None, {}
            if self.handover and rows:
                ho = choose_handover(training, settings, coupled, choice.nu_condition, rows, tau, fk)
                handover, handover_scores = ho.regression, ho.scores
        models = task_models(training, training.weights, training.alphas, coupled, settings)
        fitted = FittedModel(
            layout=training.layout,
            basis=basis,
            scaler=training.scaler,
            tasks=training.tasks,
            models=models,
            duration_nominal_s=training.duration_nominal_s,
            task_log_prior=prior,
            noise_ratio=nu,
            temperature=tau,
            head=head,
            coupled_groups=tuple(coupled),
            residual_var=training.residual_var,
            noise_cv_scores=nu_scores,
            coupling_cv_scores=choice.scores,
            condition_noise_ratio=choice.nu_condition,
            condition_cv_scores=choice.nu_scores,
            handover=handover,
            handover_cv_scores=handover_scores,
            trained_on=tuple(demo_record(d) for demos in by_task.values() for d in demos),
        )
        try:
            check_fitted(fitted)
        except ModelError as exc:
            raise ModelError(
                f"training produced an unusable model (implausible training data?): {exc}"
            ) from None
        return self._set_fitted(fitted)

    def _set_fitted(self, fitted: FittedModel) -> IProMP:
        """Store a fitted state and its predictor, and expose it as the fitted attributes."""
        layout = fitted.layout
        self.fitted_ = fitted
        self.predictor_ = Predictor(fitted, int(self.n_points))
        self.observe_ = list(layout.observe)
        self.tasks_ = list(fitted.tasks)
        self.models_: dict[str, TaskModel] = dict(fitted.models)
        self.basis_: GaussianBasis = fitted.basis
        self.scaler_: ChannelScaler = fitted.scaler
        self.groups_ = list(layout.groups)
        self.group_slices_ = dict(layout.slices)
        self.channel_names_ = dict(layout.channel_names)
        self.joint_names_ = layout.joint_names
        self.n_dims_ = layout.n_dims
        self.n_obs_dims_ = layout.n_obs_dims
        self.duration_nominal_s_ = fitted.duration_nominal_s
        self.noise_ratio_ = fitted.noise_ratio
        self.temperature_ = fitted.temperature
        self.head_ = fitted.head
        self.handover_ = fitted.handover
        self.handover_cv_scores_ = dict(fitted.handover_cv_scores)
        self.condition_noise_ratio_ = fitted.nu_condition
        self.condition_cv_scores_ = dict(fitted.condition_cv_scores)
        self.noise_var_ = fitted.noise_var()
        self.cv_scores_ = dict(fitted.noise_cv_scores)
        self.coupled_groups_ = list(fitted.coupled_groups)
        self.coupling_cv_scores_ = dict(fitted.coupling_cv_scores)
        self.task_log_prior_ = fitted.task_log_prior
        self.residual_var_ = fitted.residual_var
        self.trained_on_ = fitted.trained_on
        return self

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
        predictor = self._predictor()
        if not isinstance(observation, Demo):
            return [self.recognise(o) for o in _batch(observation)]
        parts, t_last = predictor.encode(observation)
        with self._limit_threads():
            return predictor.recognise(parts, t_last)

    recognize = recognise

    def predict(self, observation: Demo | Sequence[Demo]) -> Prediction | list[Prediction]:
        """Recognise the task and predict the robot's trajectory conditioned on the observation.

        Args:
            observation: Partial demo with the observed groups (>= 2 samples), times in [s] from
                motion start; or a sequence of them (batch: a list of predictions, in order).
        """
        predictor = self._predictor()
        if not isinstance(observation, Demo):
            return [self.predict(o) for o in _batch(observation)]
        parts, t_last = predictor.encode(observation)
        with self._limit_threads():
            return predictor.predict(parts, t_last)

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
        """Learned centre and spread (n, D) of every channel over phases ``z`` (n,).

        For a linear channel these are the mean and standard deviation in original units. A channel
        modelled in log space (EMG, ``log_groups``) is Gaussian in ``log(y + c)``: its centre is the
        median ``exp(mu) - c`` in original units but its spread is the standard deviation of
        ``log(y + c)`` (log units); :meth:`distribution_band` gives bands in original units.

        Returns:
            centre, spread and the channel names as ``"group/channel"`` (observed groups, then robot).
        """
        m = self._task_model(task)
        mean, std = m.distribution(self.basis_(np.asarray(z, dtype=float)))
        return self.scaler_.inverse(mean), std * self.scaler_.scale, self.channel_labels()

    def distribution_band(
        self, task: str, z: np.ndarray, n_sigma: float = 2.0
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
        """Centre and the ``n_sigma`` band (n, D) of every channel over phases ``z`` (n,), all in
        original units: the model's quantiles ``mu +- n_sigma sigma`` mapped through the channel
        scaling (for log-scaled channels ``exp(.) - c``, so the band is asymmetric around the median).

        Returns:
            centre, lower, upper and the channel names as ``"group/channel"``.
        """
        m = self._task_model(task)
        mean, std = m.distribution(self.basis_(np.asarray(z, dtype=float)))
        inv = self.scaler_.inverse
        return inv(mean), inv(mean - n_sigma * std), inv(mean + n_sigma * std), self.channel_labels()

    def train_trajectories(self, task: str, z: np.ndarray) -> np.ndarray:
        """Basis-fitted trajectories (N, n, D) of the training demos at phases ``z``, original units."""
        m = self._task_model(task)
        return self.scaler_.inverse(
            np.einsum("nk,idk->ind", self.basis_(np.asarray(z, float)), m.train_weights)
        )

    def channel_labels(self) -> list[str]:
        """``"group/channel"`` labels of all modelled dims (observed groups, then robot)."""
        return self._predictor().fitted.layout.labels()

    def _task_model(self, task: str) -> TaskModel:
        fitted = self._predictor().fitted
        if task not in fitted.models:
            raise ModelError(f"unknown task '{task}' (tasks: {', '.join(fitted.tasks)})")
        return fitted.models[task]

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


_PARAMS = (
    "observe",
    "n_basis",
    "width",
    "ridge",
    "margin",
    "n_alpha",
    "alpha_width",
    "noise",
    "temperature",
    "condition_noise",
    "head",
    "handover",
    "n_points",
    "task_prior",
    "robot_group",
    "log_groups",
    "pooling",
    "coupling",
    "blas_threads",
)


def _is_int(value: object) -> bool:
    """Whether ``value`` is an integer (``int`` or an integral NumPy integer, not a bool)."""
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def _is_number(value: object) -> bool:
    """Whether ``value`` is a real number (not a bool)."""
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)
