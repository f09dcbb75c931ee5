"""Multi-task EMG-augmented Interaction ProMP: task recognition, phase estimation and robot prediction.

:class:`IProMP` learns one :class:`~ipromp_pin.model.TaskModel` per task from
demonstrations (observed human channel groups + the robot's joint angles) and,
from the first part of a new human motion (times from motion start; the total
duration is unknown), computes

1. per task the phase posterior over ``n_alpha`` candidates of
   ``alpha = T / T_norm`` (exact marginal likelihood, :mod:`ipromp_pin.phase`),
   refined to a continuous MAP estimate by a parabola;
2. the task posterior ``p(k | obs)`` in log space: task prior times the
   likelihood marginalised over the phase candidates (log-sum-exp);
3. for the most probable task, the Gaussian conditioning of its weight
   distribution on the observation at the MAP phase, giving the robot joint
   trajectory (mean and covariance, in [rad]) over ``t in [0, alpha T_norm]``.

Noise ratio. ``noise="auto"`` chooses the observation-noise ratio ``nu``
(``r_d = nu delta_d``) among ``NOISE_GRID`` by leave-one-out cross-validation on
the training demos only: every training demo (at most ``CV_MAX_FOLDS`` in all,
spread evenly over tasks) is in turn removed from its task's model (the pooled
covariance target and phase priors are refitted without it), its first 10 % and
20 % are observed, and the score is the mean log posterior of its true task plus
the mean log posterior density of its true phase (each observation's score
clipped at -100). A too-small ``nu`` makes the phase estimate overconfident (worse than the
prior alone); a too-large one ignores the observation.

Coupling. Not every observed group need inform the robot: on the hand-over data the forearm
EMG amplitudes differ strongly between repetitions of a task (which is what tells the tasks
apart) but say nothing about where the robot should go, and with 10-20 demos and hundreds of
weights, their sample cross-covariance with the robot is mostly noise that the conditioning
turns into prediction error. With ``coupling="auto"`` the model therefore has two independent
blocks of dims, the *coupled* observed groups with the robot and the remaining observed groups
(still modelled, with their correlations, for recognition and phase), each with its own
Ledoit-Wolf shrinkage (:func:`~ipromp_pin.model.shrink_covariances`; the noisy block no longer
inflates the shrinkage of the coupled one). The coupled groups are chosen among the non-empty
subsets of the observed groups by leave-one-out cross-validation on the training demos (the same
held-out demos as for ``nu``, after ``nu`` has been chosen on the fully coupled model): each
held-out demo's first 10 % and 20 % are observed, its task's weights are conditioned on them at its
true phase, and the score is the RMSE in [rad] of the predicted robot trajectory over the
unobserved phases. With 10-20 demos per task these scores are noisy, so the one-standard-error
rule picks the candidate with the fewest coupled dims (the fewest cross-covariances to estimate)
among those whose mean squared error exceeds the best one's by at most one standard error of
their paired difference over the held-out observations. The empty set (robot independent of
the human: the prediction is the prior) is not a candidate, as the conditioning is the point of
the model and on small training sets its CV error ties with the best coupling's;
``coupling=[]`` selects it explicitly. With two blocks the covariance factor has rank up to
``2 (N - 1)`` (one ``N - 1`` per block).

:func:`direct_predict` is the textbook reference implementation (dense
block-diagonal observation matrix, full covariance ``Phi Sigma Phi^T + R`` per
candidate, dense conditioning) used by the tests and the benchmark to check the
fast path.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from itertools import combinations
from pathlib import Path

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_triangular
from threadpoolctl import ThreadpoolController

from .basis import GaussianBasis
from .data import ROBOT, Dataset, Demo, group_by_task, parse_groups
from .exceptions import DataError, ModelError, NotFittedError, ObservationError
from .model import (
    ChannelScaler,
    TaskModel,
    alpha_candidates,
    alpha_prior,
    fit_demo_weights,
    shrink_covariances,
)
from .phase import (
    LOG_2PI,
    REFINE_NODES,
    REFINE_WEIGHTS,
    IncrementalTerms,
    InferenceEngine,
    ObservationPart,
    PartStats,
    _kernels,
    refine_peak,
)

NOISE_GRID = (0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0)
"""Candidate noise ratios ``nu`` for ``noise="auto"``."""

CV_RATIOS = (0.1, 0.2)
"""Observed fractions of the held-out demo used by the noise cross-validation."""

STREAM_EXTRA_BASIS = 4
"""Basis functions a :class:`StreamingEstimator` keeps beyond the observed window's support, so that its
incremental terms are rebuilt only when the window reaches past them."""

CV_MAX_FOLDS = 30
"""Largest number of held-out demos of the cross-validations (spread evenly over tasks and demos)."""

CV_PHASES = 50
"""Phases of the unobserved part of the motion at which the coupling cross-validation compares the
robot's predicted and true trajectories."""

COUPLING_SE = 1.0
"""Candidates within this many standard errors of the best CV error count as equally good (the one with
the fewest coupled dims is chosen)."""

COUPLING_MAX_GROUPS = 4
"""Up to this many observed groups, ``coupling="auto"`` tries every subset of them."""


_NO_LOG = np.zeros(0, dtype=np.int64)


class LazyGroups(Mapping):
    """Read-only mapping group -> array whose values are computed together on first access.

    Args:
        keys: The groups.
        compute: Returns the dict of every group's array (called at most once).
    """

    def __init__(self, keys: Iterable[str], compute: Callable[[], dict[str, np.ndarray]]) -> None:
        self._keys = tuple(keys)
        self._compute: Callable[[], dict[str, np.ndarray]] | None = compute
        self._values: dict[str, np.ndarray] | None = None

    def _get(self) -> dict[str, np.ndarray]:
        if self._values is None:
            self._values = self._compute()
            self._compute = None
        return self._values

    def __getitem__(self, key: str) -> np.ndarray:
        if key not in self._keys:
            raise KeyError(key)
        return self._get()[key]

    def __iter__(self):
        return iter(self._keys)

    def __len__(self) -> int:
        return len(self._keys)

    def __repr__(self) -> str:
        return f"LazyGroups({list(self._keys)}, computed={self._values is not None})"


@dataclass
class Recognition:
    """Task posterior and phase estimates for a partial observation.

    Attributes:
        task: Most probable task.
        tasks: All task names (order of the arrays below).
        log_posterior: (K,) normalised log p(task | observation).
        posterior: (K,) p(task | observation).
        alpha: (K,) MAP phase ``T / T_norm`` per task (refined between candidates).
        duration_s: Predicted total duration of the most probable task's motion, in [s].
        observed_until_s: Time of the last observed sample, in [s] from motion start.
        phase_grid: (K, n_alpha) phase candidates per task.
        phase_log_post: (K, n_alpha) normalised log posterior of the candidates.
        log_evidence: (K,) log p(observation | task).
    """

    task: str
    tasks: list[str]
    log_posterior: np.ndarray
    posterior: np.ndarray
    alpha: np.ndarray
    duration_s: float
    observed_until_s: float
    phase_grid: np.ndarray
    phase_log_post: np.ndarray
    log_evidence: np.ndarray


@dataclass
class Prediction(Recognition):
    """Recognition plus the conditioned robot (and human) trajectory of the most probable task.

    Attributes:
        t: (M,) robot time in [s] from motion start, spanning [0, duration_s].
        q_mean: (M, J) predicted robot joint angles in [rad].
        q_cov: (M, J, J) their covariance in [rad^2].
        q_prior_mean: (M, J) unconditioned mean of the task on the same time grid, in [rad].
        q_prior_std: (M, J) unconditioned standard deviation, in [rad].
        joint_names: Robot joint names.
        human_mean: Observed group -> predicted (conditioned) human channels (M, D) in original units
            (computed on first access: the latent blocks that do not load on the robot are
            conditioned then).
    """

    t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    q_mean: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    q_cov: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))
    q_prior_mean: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    q_prior_std: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    joint_names: tuple[str, ...] = ()
    human_mean: Mapping[str, np.ndarray] = field(default_factory=dict)
    _w_mean: np.ndarray | None = field(default=None, repr=False)
    _w_diag: np.ndarray | None = field(default=None, repr=False)
    _w_factor: np.ndarray | None = field(default=None, repr=False)
    _q_chol: np.ndarray | None = field(default=None, repr=False)
    _phi: np.ndarray | None = field(default=None, repr=False)
    _offset: np.ndarray | None = field(default=None, repr=False)
    _scale: np.ndarray | None = field(default=None, repr=False)

    def sample_q(self, n: int, rng: np.random.Generator | int | None = None) -> np.ndarray:
        """Draw ``n`` robot trajectories (n, M, J) in [rad] from the conditioned weight posterior.

        The robot weights are ``w = m + sqrt(delta) xi + F eta`` with ``xi ~ N(0, I)`` and the
        latent ``eta ~ N(0, Q^-1)`` (exactly the conditioned Gaussian, without forming it).
        """
        rng = np.random.default_rng(rng)
        j, k, r = self._w_factor.shape
        xi = rng.standard_normal((n, j, k)) * np.sqrt(self._w_diag)[None, :, None]
        zeta = rng.standard_normal((r, n))
        eta = solve_triangular(self._q_chol, zeta, lower=True, trans="T").T if r else zeta.T
        w = self._w_mean[None] + xi + np.einsum("jkr,nr->njk", self._w_factor, eta)
        q = np.einsum("mk,njk->nmj", self._phi, w)
        return q * self._scale + self._offset


class IProMP:
    """EMG-augmented Interaction ProMP over several tasks (sklearn-style estimator).

    Args:
        observe: Observed human channel groups, e.g. ``["orientation", "emg"]`` (or "orientation,emg").
        n_basis: Number of Gaussian basis functions per channel ``K``.
        width: Basis width in phase units (default 0.75 x centre spacing).
        ridge: Relative ridge of the per-demo weight fit.
        margin: Basis centres extend this many spacings beyond each end of the phase range.
        n_alpha: Minimum number of phase candidates inside every task's prior support (>= 50 recommended).
        alpha_width: Candidates span ``mu +- alpha_width sigma`` of the phase prior.
        noise: Noise ratio ``nu`` (float > 0) or ``"auto"`` (leave-one-out CV over NOISE_GRID).
        n_points: Number M of points of the predicted trajectories.
        task_prior: Prior task probabilities (task -> p, or None for uniform).
        robot_group: Name of the robot's joint-angle group.
        log_groups: Observed groups modelled in log space (EMG envelopes: see
            :class:`~ipromp_pin.model.ChannelScaler`); groups not observed are ignored.
        pooling: Weight in [0, 1] of the covariance pooled over tasks in each task's
            covariance (see :func:`~ipromp_pin.model.shrink_covariances`).
        coupling: Observed groups whose weights covary with the robot's (the others are modelled
            for recognition only, independent of the robot and of the coupled groups): ``"auto"``
            (chosen by leave-one-out cross-validation of the robot prediction, see the module
            docstring), ``"all"`` (every observed group, the textbook Interaction ProMP) or a list
            of observed groups (empty: the robot's prediction is its prior).
        blas_threads: BLAS threads used while fitting and inferring (None = leave unchanged).
            Inference works on many small matrices, for which more threads only add overhead.

    Fitted attributes:
        tasks_: Task names.
        models_: Task name -> :class:`~ipromp_pin.model.TaskModel`.
        basis_: The :class:`~ipromp_pin.basis.GaussianBasis`.
        scaler_: Per-channel :class:`~ipromp_pin.model.ChannelScaler` (all dims, observed then robot).
        groups_: Modelled groups (observed then robot); ``group_slices_`` their dim ranges.
        channel_names_: Group -> channel names.
        duration_nominal_s_: ``T_norm`` in [s] (mean training duration).
        noise_ratio_: Chosen ``nu``; ``noise_var_`` task -> (D_obs,) noise variances (scaled units).
        cv_scores_: ``nu`` -> CV score (only with ``noise="auto"``).
        coupled_groups_: Observed groups coupled to the robot (see ``coupling``).
        coupling_cv_scores_: Candidate coupled groups (``"+"``-joined) -> CV RMSE of the robot
            prediction in [rad] (only with ``coupling="auto"`` and more than one candidate).
        task_log_prior_: (K,) log task prior.
        residual_var_: (D,) mean per-sample residual variance of the basis fit (scaled units).
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
        n_points: int = 100,
        task_prior: Mapping[str, float] | None = None,
        robot_group: str = ROBOT,
        log_groups: Iterable[str] = ("emg",),
        pooling: float = 0.0,
        coupling: str | Iterable[str] = "auto",
        blas_threads: int | None = 1,
    ) -> None:
        self.observe = parse_groups(observe)
        self.n_basis = n_basis
        self.width = width
        self.ridge = ridge
        self.margin = margin
        self.n_alpha = n_alpha
        self.alpha_width = alpha_width
        self.noise = noise
        self.n_points = n_points
        self.task_prior = None if task_prior is None else dict(task_prior)
        self.robot_group = robot_group
        self.log_groups = tuple(log_groups)
        self.pooling = float(pooling)
        self.coupling = coupling if isinstance(coupling, str) else tuple(coupling)
        self.blas_threads = blas_threads
        self._engine: InferenceEngine | None = None
        self._pred_cache: dict = {}  # model-only arrays of the inference, cleared when the model changes
        self._threads: ThreadpoolController | None = None
        if robot_group in self.observe:
            raise ModelError(f"the robot group '{robot_group}' cannot be an observed group")
        if not (isinstance(noise, str) and noise == "auto"):
            if isinstance(noise, str) or not (float(noise) > 0 and np.isfinite(float(noise))):
                raise ModelError(f"noise must be 'auto' or a positive float, got {noise!r}")
        if not 0.0 <= self.pooling <= 1.0:
            raise ModelError(f"pooling must be in [0, 1], got {pooling!r}")
        if isinstance(self.coupling, str):
            if self.coupling not in ("auto", "all"):
                raise ModelError(
                    f"coupling must be 'auto', 'all' or a list of observed groups, got {coupling!r}"
                )
        else:
            unknown = [g for g in self.coupling if g not in self.observe]
            if unknown or len(set(self.coupling)) != len(self.coupling):
                raise ModelError(
                    f"coupling {list(self.coupling)} must list distinct observed groups ({self.observe})"
                )
        if int(n_alpha) != n_alpha or n_alpha < 3:
            raise ModelError(f"n_alpha must be an integer >= 3, got {n_alpha!r}")
        if int(n_points) != n_points or n_points < 2:
            raise ModelError(f"n_points must be an integer >= 2, got {n_points!r}")

    # ------------------------------------------------------------------ fit
    def fit(self, data: Dataset | Iterable[Demo]) -> IProMP:
        """Learn the scaling, per-task weight distributions, phase priors and noise ratio.

        Args:
            data: A :class:`~ipromp_pin.data.Dataset` or demos (grouped by ``demo.task``).
        """
        by_task = dict(data.demos) if isinstance(data, Dataset) else dict(group_by_task(data))
        if not by_task:
            raise DataError(None, "demos", "no demonstrations to fit")
        groups = [*self.observe, self.robot_group]
        for task, demos in by_task.items():
            if len(demos) < 2:
                src = demos[0].source if demos else None
                raise DataError(src, "task", f"task '{task}' has {len(demos)} demo(s); at least 2 are needed")
        names: dict[str, tuple[str, ...]] = {}
        for demos in by_task.values():
            for d in demos:
                d.require(groups)
                for g in groups:
                    ref = names.setdefault(g, tuple(d.channel_names[g]))
                    if tuple(d.channel_names[g]) != ref:
                        raise DataError(
                            d.source, g, f"channels {d.channel_names[g]} differ from the first demo's {ref}"
                        )
        self.groups_ = groups
        self.channel_names_ = {g: tuple(names[g]) for g in groups}
        sizes = [len(names[g]) for g in groups]
        starts = np.concatenate([[0], np.cumsum(sizes)])
        self.group_slices_ = {g: (int(starts[i]), int(starts[i + 1])) for i, g in enumerate(groups)}
        self.n_dims_ = int(starts[-1])
        self.n_obs_dims_ = int(starts[-2])
        self.joint_names_ = self.channel_names_[self.robot_group]
        self.basis_ = GaussianBasis(self.n_basis, self.width, self.ridge, self.margin)
        all_demos = [d for demos in by_task.values() for d in demos]
        log_dims = np.zeros(self.n_dims_, dtype=bool)
        for g in self.log_groups:
            if g in self.group_slices_ and g != self.robot_group:
                log_dims[slice(*self.group_slices_[g])] = True
        self.scaler_ = ChannelScaler.fit(np.concatenate([self._stack(d) for d in all_demos]), log_dims)
        durations = {task: np.array([d.t[-1] - d.t[0] for d in demos]) for task, demos in by_task.items()}
        self.duration_nominal_s_ = float(np.mean(np.concatenate(list(durations.values()))))
        self.tasks_ = list(by_task)
        weights = {}
        rss = np.zeros(self.n_dims_)
        count = np.zeros(self.n_dims_)
        for task, demos in by_task.items():
            ws = []
            for d in demos:
                w, res, cnt = self._demo_weights(d)
                ws.append(w)
                rss += res
                count += cnt
            weights[task] = np.stack(ws)
        self.residual_var_ = rss / np.maximum(count, 1)
        self._weights = weights
        self._alphas = {task: durations[task] / self.duration_nominal_s_ for task in self.tasks_}
        # the noise ratio is chosen on the fully coupled model (one block of rank N - 1: cheap)
        self.coupled_groups_ = list(self.observe)
        self.models_ = self._task_models(weights, self._alphas)
        self.task_log_prior_ = self._log_task_prior()
        with self._limit_threads():
            if isinstance(self.noise, str):
                self.noise_ratio_, self.cv_scores_ = self._choose_noise(by_task)
            else:
                self.noise_ratio_, self.cv_scores_ = float(self.noise), {}
            if self.coupling == "auto":
                coupled, self.coupling_cv_scores_ = self._choose_coupling(by_task)
            else:
                coupled = list(self.observe) if self.coupling == "all" else list(self.coupling)
                self.coupling_cv_scores_ = {}
        if coupled != self.coupled_groups_:
            self.coupled_groups_ = coupled
            self.models_ = self._task_models(weights, self._alphas)
        self._set_noise()
        return self

    def _stack(self, d: Demo) -> np.ndarray:
        cols = []
        for g in self.groups_:
            v = d.groups[g]
            if g in d.missing:
                v = np.where(d.missing[g][:, None], np.nan, v)
            cols.append(v)
        return np.concatenate(cols, axis=1)

    def _demo_weights(self, d: Demo) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        w = np.zeros((self.n_dims_, self.basis_.n_basis))
        rss = np.zeros(self.n_dims_)
        cnt = np.zeros(self.n_dims_)
        for g in self.groups_:
            lo, hi = self.group_slices_[g]
            valid = ~d.missing[g] if g in d.missing else None
            y = self.scaler_.transform(d.groups[g], slice(lo, hi))
            w[lo:hi], rss[lo:hi] = fit_demo_weights(self.basis_, d.t, y, valid, d.source, g)
            cnt[lo:hi] = d.n_samples if valid is None else int(np.sum(valid))
        return w, rss, cnt

    def _task_models(
        self, weights: dict[str, np.ndarray], alphas: dict[str, np.ndarray]
    ) -> dict[str, TaskModel]:
        priors = [alpha_prior(alphas[t]) for t in self.tasks_]
        cands = alpha_candidates(priors, self.n_alpha, self.alpha_width)
        covs = shrink_covariances(
            [weights[t] for t in self.tasks_], self.pooling, self._coupling_blocks(self.coupled_groups_)
        )
        models = {}
        for task, (mu, sigma), (grid, logw), cov in zip(self.tasks_, priors, cands, covs, strict=True):
            models[task] = TaskModel(
                task=task,
                mean=cov.mean,
                diag=cov.diag,
                factor=cov.factor,
                shrinkage=cov.shrinkage,
                alpha_mu=mu,
                alpha_sigma=sigma,
                alpha_grid=grid,
                alpha_log_prior=logw,
                train_weights=weights[task],
                train_alpha=alphas[task],
            )
        return models

    def _log_task_prior(self) -> np.ndarray:
        if self.task_prior is None:
            return np.full(len(self.tasks_), -np.log(len(self.tasks_)))
        unknown = set(self.task_prior) - set(self.tasks_)
        if unknown:
            raise ModelError(f"task_prior names unknown tasks {sorted(unknown)} (tasks: {self.tasks_})")
        p = np.array([float(self.task_prior.get(t, 0.0)) for t in self.tasks_])
        if np.any(p < 0) or not np.any(p > 0) or not np.all(np.isfinite(p)):
            raise ModelError(f"task_prior must be non-negative with a positive sum, got {self.task_prior}")
        with np.errstate(divide="ignore"):
            return np.log(p / p.sum())

    def _set_noise(self) -> None:
        self._engine = None
        self._pred_cache = {}
        lo, hi = 0, self.n_obs_dims_
        self.noise_var_ = {t: self.noise_ratio_ * m.diag[lo:hi] for t, m in self.models_.items()}

    def _choose_noise(self, by_task: Mapping[str, list[Demo]]) -> tuple[float, dict[float, float]]:
        """Leave-one-out choice of the noise ratio (see the module docstring)."""
        scores = np.zeros(len(NOISE_GRID))
        full = self.models_
        n_eval = 0
        self.noise_ratio_ = NOISE_GRID[0]
        try:
            for task, i in self._held_out(by_task):
                ki = self.tasks_.index(task)
                d = by_task[task][i]
                keep = np.arange(len(by_task[task])) != i
                self.models_ = self._task_models(
                    {**self._weights, task: self._weights[task][keep]},
                    {**self._alphas, task: self._alphas[task][keep]},
                )
                m = self.models_[task]
                self._engine = None
                engine = self._engine_()
                dens_shift = np.log(m.alpha_grid[1] - m.alpha_grid[0])
                alpha_true = self._alphas[task][i]
                for _, parts, t_last in self._cv_observations(d):
                    stats = [engine.part_stats(p) for p in parts]
                    n_eval += 1
                    for j, nu in enumerate(NOISE_GRID):
                        loglik = engine.terms(stats, t_last, nu=nu).loglik
                        rec, grids = self._recognition_from_loglik(loglik, t_last, raw=True)
                        s = rec.log_posterior[ki]
                        # log posterior density of the true phase (interpolated between candidates)
                        dens = grids[ki] - dens_shift
                        s += float(np.interp(alpha_true, m.alpha_grid, dens, left=-50.0, right=-50.0))
                        scores[j] += max(float(s), -100.0)
        finally:
            self.models_ = full
            self._engine = None
        if n_eval == 0:
            return 1.0, {}
        scores /= n_eval
        best = int(np.argmax(scores))
        return float(NOISE_GRID[best]), {
            float(nu): float(v) for nu, v in zip(NOISE_GRID, scores, strict=True)
        }

    def _cv_observations(self, demo: Demo) -> list[tuple[float, list[ObservationPart], float]]:
        """(observed ratio, prepared parts, last sample time in [s]) of the first ``CV_RATIOS`` of a
        held-out training demo (ratios the demo is too short for are left out)."""
        out = []
        for ratio in CV_RATIOS:
            try:
                obs = demo.head(ratio, self.observe)
            except ObservationError:
                continue
            parts, t_last = self._prepare(obs, check_length=False)
            out.append((ratio, parts, t_last))
        return out

    def _held_out(self, by_task: Mapping[str, list[Demo]]) -> list[tuple[str, int]]:
        """(task, demo index) of the demos held out by the cross-validations: at most
        ``CV_MAX_FOLDS`` in all, spread evenly over the tasks with >= 3 demos and over their demos."""
        per_task = max(1, -(-CV_MAX_FOLDS // len(by_task)))
        out = []
        for task, demos in by_task.items():
            if len(demos) < 3:
                continue
            n_held = min(per_task, len(demos))
            held = np.unique(np.linspace(0, len(demos) - 1, n_held).round().astype(int))
            out += [(task, int(i)) for i in held]
        return out

    def _coupling_blocks(self, coupled: list[str]) -> list[np.ndarray]:
        """Independent blocks of dims: the coupled groups with the robot, and the other observed groups."""
        rest = [g for g in self.observe if g not in coupled]
        blocks = [[*coupled, self.robot_group]] + ([rest] if rest else [])
        return [np.concatenate([np.arange(*self.group_slices_[g]) for g in b]) for b in blocks]

    def _coupling_candidates(self) -> list[list[str]]:
        """Candidate coupled groups: every subset of the observed groups, largest first (all groups
        first); with more than ``COUPLING_MAX_GROUPS`` observed groups only all, all but one, one
        and none."""
        n = len(self.observe)
        sizes = range(n, 0, -1) if n <= COUPLING_MAX_GROUPS else [n, n - 1, 1]
        return [
            [g for g in self.observe if g in c] for size in sizes for c in combinations(self.observe, size)
        ]

    def _choose_coupling(self, by_task: Mapping[str, list[Demo]]) -> tuple[list[str], dict[str, float]]:
        """Leave-one-out choice of the observed groups coupled to the robot (see the module docstring)."""
        cands = self._coupling_candidates()
        if len(cands) == 1:
            return cands[0], {}
        lo, hi = self.group_slices_[self.robot_group]
        scale = self.scaler_.scale[lo:hi]
        rows = []  # per held-out observation, the mean squared error of every candidate in [rad^2]
        for task, i in self._held_out(by_task):
            d = by_task[task][i]
            keep = np.arange(len(by_task[task])) != i
            weights = [self._weights[t][keep] if t == task else self._weights[t] for t in self.tasks_]
            ki = [self.tasks_.index(task)]
            covs = [shrink_covariances(weights, self.pooling, self._coupling_blocks(c), ki)[0] for c in cands]
            alpha = float(self._alphas[task][i])
            w_true = self._weights[task][i][lo:hi]
            for ratio, parts, _ in self._cv_observations(d):
                phi = self.basis_(np.linspace(ratio, 1.0, CV_PHASES))
                row = []
                for cov in covs:
                    w = self._robot_posterior_mean(cov.mean, cov.diag, cov.factor, parts, alpha)
                    err = (phi @ (w - w_true).T) * scale
                    row.append(float(np.mean(err * err)))
                rows.append(row)
        if not rows:
            return list(self.observe), {}
        mse = np.array(rows)
        mean = mse.mean(axis=0)
        best = int(np.argmin(mean))
        # one-standard-error rule: the fewest coupled dims whose error is within one standard error
        # (of its paired difference to the best, over the same held-out observations) of the best
        diff = mse - mse[:, [best]]
        se = diff.std(axis=0, ddof=1) / np.sqrt(len(rows)) if len(rows) > 1 else np.zeros(len(cands))
        size = [sum(np.subtract(*self.group_slices_[g][::-1]) for g in c) for c in cands]
        ok = [j for j in range(len(cands)) if mean[j] - mean[best] <= COUPLING_SE * se[j]]
        chosen = min(ok, key=lambda j: (size[j], mean[j]))
        rmse = np.sqrt(mean)
        return cands[chosen], {"+".join(c): float(v) for c, v in zip(cands, rmse, strict=True)}

    def _robot_posterior_mean(
        self,
        mean: np.ndarray,
        diag: np.ndarray,
        factor: np.ndarray,
        parts: list[ObservationPart],
        alpha: float,
    ) -> np.ndarray:
        """Conditioned mean (J, K) of the robot weights of a weight distribution (``mean`` (D, K),
        ``diag`` (D,), ``factor`` (D, K, r)) given an observation at the phase ``alpha``.

        The latent posterior is ``N(Q^-1 a, Q^-1)`` with ``Q = I + sum_d W_d^T (I - nu X^-1) W_d``
        and ``a = sum_d W_d^T X^-1 b_d / sqrt(delta_d)`` (notation of :mod:`ipromp_pin.phase`); the
        robot dims are not observed, so their weights are ``mu + F eta``.
        """
        r = factor.shape[2]
        lo, hi = self.group_slices_[self.robot_group]
        basis = self.basis_
        inv_dur = 1.0 / (alpha * self.duration_nominal_s_)
        ke_p = np.array([basis.support_count(float(p.t[-1]) * inv_dur) for p in parts], dtype=np.int64)
        pos_cat = np.concatenate([np.arange(p.dims.size) for p in parts])  # every column of every part
        dims_cat = np.concatenate([p.dims for p in parts]).astype(np.int64)
        p_off = np.cumsum([0] + [p.dims.size for p in parts]).astype(np.int64)
        w = np.array(mean, dtype=float)  # conditioned in place (robot rows: mu + F eta)
        ok = _kernels().condition_block(
            *_flatten_parts(parts), pos_cat, dims_cat, p_off, ke_p, inv_dur, basis.centres, basis.width,
            basis._step_factor, w.copy(), np.ascontiguousarray(diag, dtype=float),
            np.ascontiguousarray(factor, dtype=float), self.noise_ratio_, w, np.empty((r, r)),
        )  # fmt: skip
        if not ok:
            raise ModelError("X = nu I + B^T B or Q = I + P is not numerically positive definite")
        return w[lo:hi]

    # ---------------------------------------------------------- inference
    def _limit_threads(self):
        """Context limiting BLAS threads to ``blas_threads`` (the controller is created once per model)."""
        if self.blas_threads is None:
            return contextlib.nullcontext()
        if self._threads is None:
            self._threads = ThreadpoolController()
        return self._threads.limit(limits=int(self.blas_threads), user_api="blas")

    def _check_fitted(self) -> None:
        if not hasattr(self, "models_"):
            raise NotFittedError("IProMP is not fitted: call fit() before predict/recognise/stream/save")

    def _prepare(self, obs: Demo, check_length: bool = True) -> tuple[list[ObservationPart], float]:
        """Validate and scale an observation; group channels that share their sample times."""
        self._check_fitted()
        if not isinstance(obs, Demo):
            raise ObservationError(None, "observation", f"expected a Demo, got {type(obs).__name__}")
        src = obs.source
        t = obs.t
        if t[0] < -1e-9:
            raise ObservationError(
                src, "t", f"times must start at motion start (>= 0 s), first is {t[0]:.3f} s"
            )
        gaps = False
        for g in self.observe:
            if g not in obs.groups:
                raise ObservationError(
                    src,
                    g,
                    f"observed group missing from the observation (has: {', '.join(sorted(obs.groups))})",
                )
            lo, hi = self.group_slices_[g]
            n_ch = obs.groups[g].shape[1]
            if n_ch != hi - lo:
                raise ObservationError(
                    src, g, f"has {n_ch} channels, the model expects {hi - lo} {self.channel_names_[g]}"
                )
            gaps = gaps or (g in obs.missing and bool(obs.missing[g].any()))
        if not gaps:  # every group in every sample: one part with all observed dims
            raw = np.concatenate([obs.groups[g] for g in self.observe], axis=1, dtype=float)
            y, finite = self._scale_observed(raw)
            if not finite:
                for g in self.observe:
                    if not np.all(np.isfinite(obs.groups[g])):
                        raise ObservationError(src, g, "NaN or inf values in samples not flagged as missing")
            parts = [ObservationPart(t=t, dims=self._obs_scaling()[0], y=y)]
        else:
            parts = self._parts_with_gaps(obs)
        n_used = sum(p.t.size for p in parts)
        if t.size < 2 or n_used < 2:
            raise ObservationError(src, "t", f"an observation needs at least 2 samples, got {t.size}")
        t_last = float(t[-1])
        if check_length:
            longest = self._longest_s()
            if t_last > longest:
                raise ObservationError(
                    src,
                    "t",
                    f"observation lasts {t_last:.2f} s, longer than any task's plausible motion "
                    f"({longest:.2f} s)",
                )
        return parts, t_last

    def _parts_with_gaps(self, obs: Demo) -> list[ObservationPart]:
        """Observation parts of an observation with missing samples: groups with identical presence
        masks share a part (their samples and times)."""
        masks: dict[bytes, tuple[np.ndarray, list[np.ndarray], list[np.ndarray]]] = {}
        for g in self.observe:
            v = obs.groups[g]
            lo, hi = self.group_slices_[g]
            valid = ~obs.missing[g] if g in obs.missing else np.ones(obs.t.size, dtype=bool)
            if not np.all(np.isfinite(v[valid])):
                raise ObservationError(obs.source, g, "NaN or inf values in samples not flagged as missing")
            if not np.any(valid):
                continue
            entry = masks.setdefault(valid.tobytes(), (valid, [], []))
            entry[1].append(np.arange(lo, hi))
            entry[2].append(self.scaler_.transform(v[valid], slice(lo, hi)))
        return [
            ObservationPart(t=obs.t[valid], dims=np.concatenate(dims), y=np.concatenate(ys, axis=1))
            for valid, dims, ys in masks.values()
        ]

    def _scale_observed(self, raw: np.ndarray) -> tuple[np.ndarray, bool]:
        """Scaled values (n, D_o) of raw samples ``raw`` (n, D_o) of every observed dim (as
        ``ChannelScaler.transform``) and whether every raw value is finite."""
        _, log_idx, log_c, offset, scale = self._obs_scaling()
        raw = np.ascontiguousarray(raw, dtype=float)
        out = np.empty(raw.shape)
        finite = _kernels().scale_samples(raw, log_idx, log_c, offset, scale, out)
        return out, bool(finite)

    def _longest_s(self) -> float:
        """Longest plausible motion of any task in [s] (its largest phase candidate, cached)."""
        longest = self._pred_cache.get("longest")
        if longest is None:
            longest = max(float(m.alpha_grid[-1]) for m in self.models_.values()) * self.duration_nominal_s_
            self._pred_cache["longest"] = longest
        return longest

    def _obs_scaling(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The scaling of a full observed sample (cached): the observed dims (D_o,) (groups in
        ``observe`` order), the log-scaled ones and their shifts, offsets and scales (D_o,) (the
        operations of ``ChannelScaler.transform``)."""
        c = self._pred_cache.get("obs_scaling")
        if c is None:
            sc, n = self.scaler_, self.n_obs_dims_
            log_idx = np.flatnonzero(sc._log[:n])  # observed groups come first, in observe order
            dims = np.concatenate([np.arange(*self.group_slices_[g]) for g in self.observe])
            c = (dims, log_idx, sc.log_shift[log_idx], sc.offset[dims], sc.scale[dims])
            self._pred_cache["obs_scaling"] = c
        return c

    def _engine_(self) -> InferenceEngine:
        if self._engine is None:
            models = [self.models_[t] for t in self.tasks_]
            self._engine = InferenceEngine(
                self.basis_, models, self.n_obs_dims_, self.duration_nominal_s_, self.noise_ratio_
            )
        return self._engine

    def _recognise_parts(self, parts, t_last: float, nu: float | None = None, raw: bool = False, stats=None):
        engine = self._engine_()
        if stats is None:
            stats = [engine.part_stats(p) for p in parts]
        loglik = engine.terms(stats, t_last, nu=nu).loglik
        return self._recognition_from_loglik(loglik, t_last, raw)

    def _recognition_from_loglik(self, loglik: np.ndarray, t_last: float, raw: bool = False):
        engine = self._engine_()
        evidence, logpost, alpha, finite, *task_post = _kernels().recognition(
            loglik, engine.log_prior, engine.alphas, REFINE_WEIGHTS, REFINE_NODES, self.task_log_prior_
        )
        if not finite:  # some task cannot explain the observation
            finite = np.isfinite(evidence)
            mus = np.array([self.models_[t].alpha_mu for t in self.tasks_])
            alpha[~finite] = mus[~finite]
        rec = self._finish_recognition(evidence, alpha, engine.alphas, logpost, t_last, task_post)
        return (rec, logpost) if raw else rec

    def _finish_recognition(self, evidence, alpha, grids, logpost, t_last, task_post=None) -> Recognition:
        """The recognition from the tasks' log evidence and phase estimates (the task posterior
        ``task_post`` from ``kernels.task_posterior``, computed here when not given)."""
        if task_post is None:
            task_post = _kernels().task_posterior(self.task_log_prior_, np.ascontiguousarray(evidence))
        log_post, posterior, best = task_post
        if not math.isfinite(float(log_post[best])):
            raise ObservationError(None, "t", "the observation is impossible under every task (too long?)")
        return Recognition(
            task=self.tasks_[best],
            tasks=list(self.tasks_),
            log_posterior=log_post,
            posterior=posterior,
            alpha=alpha,
            duration_s=float(alpha[best] * self.duration_nominal_s_),
            observed_until_s=t_last,
            phase_grid=grids,
            phase_log_post=logpost,
            log_evidence=evidence,
        )

    def recognise(self, observation: Demo) -> Recognition:
        """Task posterior and phase estimates of a partial observation (no trajectory)."""
        parts, t_last = self._prepare(observation)
        with self._limit_threads():
            return self._recognise_parts(parts, t_last)

    recognize = recognise

    def predict(self, observation: Demo) -> Prediction:
        """Recognise the task and predict the robot's trajectory conditioned on the observation.

        Args:
            observation: Partial demo with the observed groups (>= 2 samples), times in [s] from motion start.
        """
        parts, t_last = self._prepare(observation)
        with self._limit_threads():
            rec = self._recognise_parts(parts, t_last)
            return self._condition(rec, parts)

    def _condition(self, rec: Recognition, parts: list[ObservationPart]) -> Prediction:
        """Condition the winning task's weights on the observation at its MAP phase.

        Same algebra as :mod:`ipromp_pin.phase` for a single candidate, per independent block of
        observed dims (:meth:`_task_blocks`; the blocks' latent posteriors are independent): per
        part, ``X = nu I + G`` (one Cholesky), ``P = sum_d W_d^T (I - nu X^-1) W_d`` and
        ``a = sum_d W_d^T X^-1 b_d / sqrt(delta_d)``; the latent posterior is ``N(Q^-1 a, Q^-1)``
        with ``Q = I + P`` and the observed dims' weights get the extra correction
        ``X^-1 (b_d - G F_d eta)``. The robot's covariance needs only the blocks whose factor
        columns load on the robot (with two blocks, half the latent dims).
        """
        kern = _kernels()
        task = rec.task
        m = self.models_[task]
        alpha = float(rec.alpha[self.tasks_.index(task)])
        w_post = m.mean.copy()
        info = self._task_blocks(task)
        inv_dur = 1.0 / (alpha * self.duration_nominal_s_)
        basis = self.basis_
        ke_p = np.array([basis.support_count(float(p.t[-1]) * inv_dur) for p in parts], dtype=np.int64)
        flat = _flatten_parts(parts)
        layouts = self._block_layouts(task, parts)

        def run(b: int, w: np.ndarray) -> np.ndarray:
            """Condition latent block ``b`` into the weights ``w`` -> the Cholesky factor of its ``Q``."""
            factor = info["factors"][b]
            r = factor.shape[2]
            if layouts[b] is None:  # no observed dim of this block: its latent posterior is the prior
                return np.eye(r)
            keep, pos_cat, dims_cat, p_off = layouts[b]
            if keep is None:
                args = (*flat, ke_p)
            else:
                args = (*_flatten_parts([parts[i] for i in keep]), ke_p[keep])
            lq = np.empty((r, r))
            ok = kern.condition_block(
                *args[:5], pos_cat, dims_cat, p_off, args[5], inv_dur,
                basis.centres, basis.width, basis._step_factor, m.mean, m.diag, factor, self.noise_ratio_,
                w, lq,
            )  # fmt: skip
            if not ok:
                raise ModelError("X = nu I + B^T B or Q = I + P is not numerically positive definite")
            return lq

        robot_chol = [run(b, w_post) for b in info["robot_blocks"]]
        others = [b for b in range(len(layouts)) if b not in info["robot_blocks"]]

        def human_weights() -> np.ndarray:
            # the blocks that do not load on the robot only move the observed dims' weights
            # (human predictions): conditioned when those are first asked for
            w = w_post.copy()
            for b in others:
                run(b, w)
            return w

        n_free = info["robot_cols"].size - sum(c.shape[0] for c in robot_chol)
        lq = robot_chol[0] if len(robot_chol) == 1 and n_free == 0 else _block_diag(robot_chol, n_free)
        return self._make_prediction(rec, info["robot_factor"], m, alpha, w_post, lq, human=human_weights)

    def _block_layouts(self, task: str, parts: list[ObservationPart]) -> list:
        """Per latent block of a task, where its observed dims are in the parts (cached per parts' dims):
        None when no part observes the block, else the parts that do (None: all of them), the
        columns of their values and their model dims (concatenated over those parts) and the offsets
        of each part's entries (see ``kernels.condition_block``)."""
        key = ("layout", task, *(p.dims.tobytes() for p in parts))
        out = self._pred_cache.get(key)
        if out is None:
            out = []
            for block, _ in self._task_blocks(task)["blocks"]:
                sel = [block.select(p.dims) for p in parts]
                keep = [i for i, (pos, _) in enumerate(sel) if pos.size]
                if not keep:
                    out.append(None)
                    continue
                pos_cat = np.concatenate([sel[i][0] for i in keep])
                dims_cat = block.dims[np.concatenate([sel[i][1] for i in keep])]
                p_off = np.cumsum([0] + [sel[i][0].size for i in keep]).astype(np.int64)
                out.append((None if len(keep) == len(parts) else keep, pos_cat, dims_cat, p_off))
            self._pred_cache[key] = out
        return out

    def _task_blocks(self, task: str) -> dict:
        """The independent blocks of a task's latent dims (cached).

        Returns a dict: ``blocks`` per block of the inference engine, the block
        (:class:`~ipromp_pin.phase.LatentBlock`) and the task's factor columns it uses
        (``LatentBlock.cols``); ``factors`` those columns of the factor (D, K, r_b);
        ``robot_blocks`` the blocks whose columns load on the robot; ``robot_cols`` the columns of
        these blocks followed by the robot's columns that load on no observed dim (their latent
        posterior is the prior); ``robot_factor`` the factor restricted to them (D, K, r_R).
        """
        key = ("blocks", task)
        info = self._pred_cache.get(key)
        if info is None:
            m = self.models_[task]
            lo, hi = self.group_slices_[self.robot_group]
            loads = np.any(m.factor != 0.0, axis=1)  # (D, r)
            robot = np.any(loads[lo:hi], axis=0)
            blocks, factors, robot_blocks, cols_r = [], [], [], []
            seen = np.zeros(m.rank, dtype=bool)
            ti = self.tasks_.index(task)
            for block in self._engine_().blocks:
                cols = block.cols[ti]
                seen[cols] = True
                blocks.append((block, cols))
                factors.append(np.ascontiguousarray(m.factor[:, :, cols]))
                if np.any(robot[cols]):
                    robot_blocks.append(len(blocks) - 1)
                    cols_r.append(cols)
            cols_r.append(np.flatnonzero(robot & ~seen))
            robot_cols = np.concatenate(cols_r).astype(np.int64)
            info = {
                "blocks": blocks,
                "factors": factors,
                "robot_blocks": robot_blocks,
                "robot_cols": robot_cols,
                "robot_factor": np.ascontiguousarray(m.factor[:, :, robot_cols]),
            }
            self._pred_cache[key] = info
        return info

    def _grid_cache(self, task: str, factor: np.ndarray, which: str) -> dict[str, np.ndarray]:
        """Model-only quantities on the fixed prediction phase grid (cached per task and ``which``
        factor columns: "robot" those of :meth:`_task_blocks`, "all" every column)."""
        key = ("grid", task, which)
        c = self._pred_cache.get(key)
        if c is None:
            lo, hi = self.group_slices_[self.robot_group]
            m = self.models_[task]
            z = np.linspace(0.0, 1.0, self.n_points)
            phi = self.basis_(z)
            mean, std = m.distribution(phi)
            fr = factor[lo:hi]
            c = {
                "z": z,
                "phi": phi,
                "phi2": np.sum(phi * phi, axis=1),
                "prior_mean": self.scaler_.inverse(mean[:, lo:hi], slice(lo, hi)),
                "prior_std": std[:, lo:hi] * self.scaler_.scale[lo:hi],
                "phi_f": np.ascontiguousarray(np.einsum("mk,jkr->rjm", phi, fr)),  # (r, J, M)
            }
            self._pred_cache[key] = c
        return c

    def _make_prediction(
        self, rec, factor, m: TaskModel, alpha, w_post, lq, which: str = "robot", human=None
    ) -> Prediction:
        """The prediction from the conditioned weights ``w_post`` (D, K) (their observed dims' rows
        completed by ``human()`` when given) and the Cholesky factor ``lq`` of the robot's latent
        posterior precision."""
        lo, hi = self.group_slices_[self.robot_group]
        nj = hi - lo
        duration = alpha * self.duration_nominal_s_
        c = self._grid_cache(m.task, factor, which)
        phi = c["phi"]
        scale = self.scaler_.scale[lo:hi]
        offset = self.scaler_.offset[lo:hi]
        kern = _kernels()
        sc = self.scaler_
        q_mean = kern.channel_values(phi, np.ascontiguousarray(w_post[lo:hi]), scale, offset, _NO_LOG, scale)
        if lq.shape[0]:
            cov = kern.prediction_cov(lq, c["phi_f"], c["phi2"], m.diag[lo:hi], scale)
        else:
            cov = np.zeros((phi.shape[0], nj, nj))
            idx = np.arange(nj)
            cov[:, idx, idx] += c["phi2"][:, None] * m.diag[lo:hi]
            cov *= scale[:, None] * scale[None, :]
        n_obs = self.n_obs_dims_
        slices = [(g, *self.group_slices_[g]) for g in self.observe]

        def human_means() -> dict[str, np.ndarray]:
            w = w_post if human is None else human()
            _, log_idx, _, offset, scale_obs = self._obs_scaling()
            w_obs = np.ascontiguousarray(w[:n_obs])
            vals = kern.channel_values(phi, w_obs, scale_obs, offset, log_idx, sc.log_shift)
            return {g: np.ascontiguousarray(vals[:, glo:ghi]) for g, glo, ghi in slices}

        return Prediction(
            **vars(rec),
            t=c["z"] * duration,
            q_mean=q_mean,
            q_cov=cov,
            q_prior_mean=c["prior_mean"],
            q_prior_std=c["prior_std"],
            joint_names=tuple(self.joint_names_),
            human_mean=LazyGroups(self.observe, human_means),
            _w_mean=w_post[lo:hi],
            _w_diag=m.diag[lo:hi],
            _w_factor=factor[lo:hi],
            _q_chol=lq,
            _phi=phi,
            _offset=offset,
            _scale=scale,
        )

    def stream(self) -> StreamingEstimator:
        """A streaming estimator that refreshes the estimate as samples arrive one by one."""
        self._check_fitted()
        return StreamingEstimator(self)

    # ------------------------------------------------------------- plots
    def distribution(self, task: str, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """Learned mean and std (n, D) of every channel over phases ``z`` (n,), in original units.

        Returns:
            mean, std and the channel names as ``"group/channel"`` (observed groups, then robot).
        """
        self._check_fitted()
        m = self._model(task)
        mean, std = m.distribution(self.basis_(np.asarray(z, dtype=float)))
        return self.scaler_.inverse(mean), std * self.scaler_.scale, self.channel_labels()

    def train_trajectories(self, task: str, z: np.ndarray) -> np.ndarray:
        """Basis-fitted trajectories (N, n, D) of the training demos at phases ``z``, original units."""
        self._check_fitted()
        m = self._model(task)
        return self.scaler_.inverse(
            np.einsum("nk,idk->ind", self.basis_(np.asarray(z, float)), m.train_weights)
        )

    def channel_labels(self) -> list[str]:
        """``"group/channel"`` labels of all modelled dims (observed groups, then robot)."""
        return [f"{g}/{c}" for g in self.groups_ for c in self.channel_names_[g]]

    def _model(self, task: str) -> TaskModel:
        if task not in self.models_:
            raise ModelError(f"unknown task '{task}' (tasks: {', '.join(self.tasks_)})")
        return self.models_[task]

    # ------------------------------------------------------------ files
    def save(self, path: str | Path) -> None:
        """Write the fitted model to a versioned, pickle-free ``.npz`` file."""
        from .serialization import save_model

        self._check_fitted()
        save_model(self, path)

    @classmethod
    def load(cls, path: str | Path) -> IProMP:
        """Read a model written by :meth:`save` (raises ModelFileError on a bad file)."""
        from .serialization import load_model

        return load_model(path)


class StreamingEstimator:
    """Refreshes the estimate as human samples arrive one by one.

    Each :meth:`update` adds the new sample's contribution to running sufficient
    statistics (``B^T B``, ``B^T y`` and ``y^T y`` for every phase candidate; one
    basis row per candidate instead of the whole basis matrix). While every sample
    has every observed group and the number of active basis functions stays the
    same, the likelihood terms are updated incrementally
    (:class:`~ipromp_pin.phase.IncrementalTerms`: Sherman-Morrison update of
    ``X^-1``, rank-D update of ``P``, one Cholesky factorisation of ``Q`` per
    (task, candidate)); otherwise they are recomputed from the statistics. The
    result equals :meth:`IProMP.recognise` / :meth:`IProMP.predict` on a
    :class:`Demo` holding the same samples (to rounding).

    Channel groups that are missing in some samples are tracked separately: groups
    with identical presence histories share their statistics, as in the one-shot call.

    Used as a context manager (``with model.stream() as s: ...``), the estimator limits the BLAS
    threads (``IProMP.blas_threads``) once for the whole block instead of on every update.
    """

    def __init__(self, model: IProMP) -> None:
        self.model = model
        self._engine = model._engine_()
        self._t: list[float] = []
        self._rows: list[np.ndarray] = []  # raw samples (D_o,), NaN in missing groups
        self._absent: list[int] = []  # per sample, bit i set when observed group i is missing
        self._last: Recognition | None = None
        u, k = self._engine.alpha_unique.size, model.basis_.n_basis
        n_obs = model.n_obs_dims_
        self._inv_dur = 1.0 / (self._engine.alpha_unique * model.duration_nominal_s_)
        self._inv_dur_max = float(self._inv_dur.max())
        self._slices = [(g, *model.group_slices_[g]) for g in model.observe]
        self._groups = set(model.observe)
        # presence pattern -> [groups, gram (K, K, U), n, last time]
        self._patterns: list[list] = [[list(model.observe), np.zeros((k, k, u)), 0, 0.0]]
        self._proj = np.zeros((k, u, n_obs))  # B^T y of every observed dim (missing samples add 0)
        self._sq = np.zeros(n_obs)
        self._no_gram = np.zeros((k, 0, u))  # placeholders of kernels.add_sample
        self._no_proj = np.zeros((k, u, 0))
        self._no_y = np.zeros(0)
        self._inc: IncrementalTerms | None = IncrementalTerms(self._engine)
        self._kern = _kernels()
        self._longest = model._longest_s()
        self._held: contextlib.AbstractContextManager | None = None
        # the scaling of a full sample (all observed dims), as ChannelScaler.transform
        _, self._log_idx, self._log_c, self._offset, self._scale = model._obs_scaling()
        self._support_until = -np.inf  # phases below this need at most inc.ke basis functions
        b = model.basis_
        self._sample_basis = (self._inv_dur, b.centres, b.width, b._step_factor)  # kernels.stream_sample
        self._sample_scaling = (self._log_idx, self._log_c, self._offset, self._scale)

    def __enter__(self) -> StreamingEstimator:
        self._held = self.model._limit_threads()
        self._held.__enter__()
        return self

    def __exit__(self, *exc) -> None:
        held, self._held = self._held, None
        if held is not None:
            held.__exit__(*exc)

    @property
    def n_samples(self) -> int:
        """Number of samples received."""
        return len(self._t)

    def update(self, t_s: float, sample: Mapping[str, np.ndarray | None]) -> Recognition | None:
        """Add one sample and return the refreshed recognition (None until 2 samples arrived).

        Args:
            t_s: Sample time in [s] from motion start (strictly increasing).
            sample: Observed group -> values (D,) in original units; a group that is absent or
                None is missing for this sample (e.g. a lost skeleton frame).
        """
        m = self.model
        t_s = float(t_s)
        if not math.isfinite(t_s) or (self._t and t_s <= self._t[-1]) or t_s < -1e-9:
            raise ObservationError("stream", "t", f"sample time {t_s} is not after the previous sample")
        if t_s > self._longest:
            raise ObservationError(
                "stream", "t", f"observation lasts {t_s:.2f} s, longer than any task's plausible motion"
            )
        if not self._groups.issuperset(sample):
            g = next(g for g in sample if g not in self._groups)
            raise ObservationError("stream", g, f"not an observed group ({m.observe})")
        y = np.empty(self._sq.size)
        present = []
        absent = 0
        for i, (g, lo, hi) in enumerate(self._slices):
            v = sample.get(g)
            if v is None:
                y[lo:hi] = np.nan
                absent |= 1 << i
                continue
            v = np.asarray(v, dtype=float).reshape(-1)
            if v.size != hi - lo:
                raise ObservationError(
                    "stream", g, f"sample has {v.size} values, the model expects {hi - lo}"
                )
            y[lo:hi] = v
            present.append(g)
        if self._held is None:
            with m._limit_threads():
                return self._add(t_s, y, absent, present)
        return self._add(t_s, y, absent, present)

    def _check_finite(self, t_s: float, y: np.ndarray, present: list[str]) -> None:
        """Raise ObservationError naming the first present group of ``y`` with a NaN or inf."""
        for g, lo, hi in self._slices:
            if g in present and not np.all(np.isfinite(y[lo:hi])):
                raise ObservationError("stream", g, f"NaN or inf in the sample at t={t_s:.3f} s")

    def _add(self, t_s: float, y: np.ndarray, absent: int, present: list[str]) -> Recognition | None:
        """Check and add the sample ``y`` (D,) (raw values, NaN in the groups flagged in ``absent``)
        to the statistics and refresh the recognition."""
        m = self.model
        if not absent and len(self._patterns) == 1:
            # every group present and one presence history: finiteness check, scaling, basis row and
            # running sums in one call
            pattern = self._patterns[0]
            phi, ys, finite = self._kern.stream_sample(
                t_s, *self._sample_basis, y, *self._sample_scaling, pattern[1], self._proj, self._sq
            )
            if not finite:
                self._check_finite(t_s, y, present)  # raises: every group is present
            pattern[2] += 1
            pattern[3] = t_s
        else:
            self._check_finite(t_s, y, present)
            if not absent:
                ys = m._scale_observed(y.reshape(1, -1))[0].reshape(-1)
            else:
                ys = np.zeros(self._sq.size)
                self._inc = None  # the incremental terms hold one part with every observed dim
                for g, lo, hi in self._slices:
                    if g in present:
                        ys[lo:hi] = v_scaled(m, g, y[lo:hi])
            phi = self._accumulate(t_s, set(present), ys)
        self._t.append(t_s)
        self._rows.append(y)
        self._absent.append(absent)
        if len(self._t) < 2:
            return None
        self._last = self._recognise(phi, ys)
        return self._last

    def _accumulate(self, t_s: float, present: set[str], y: np.ndarray) -> np.ndarray:
        """Add the sample (scaled values ``y`` (D,), 0 in missing groups) -> basis values (K, U)."""
        kern = self._kern
        b = self.model.basis_
        phi = kern.basis_rows(t_s * self._inv_dur, b.centres, b.width, b._step_factor)
        patterns = []
        for groups, gram, n, t_last in self._patterns:
            have = [g for g in groups if g in present]
            absent = [g for g in groups if g not in present]
            if absent:
                patterns.append([absent, gram.copy() if have else gram, n, t_last])
            if have:
                kern.add_sample(gram, self._no_proj, phi, self._no_y)
                patterns.append([have, gram, n + 1, t_s])
        self._patterns = patterns
        kern.add_sample(self._no_gram, self._proj, phi, y)
        self._sq += y * y
        return phi

    def _stats(self) -> list[PartStats]:
        m = self.model
        stats = []
        for groups, gram, n, t_last in self._patterns:
            if n == 0:
                continue
            groups = [g for g in m.observe if g in groups]
            ke = m.basis_.support_count(t_last * self._inv_dur_max)
            dims = np.concatenate([np.arange(*m.group_slices_[g]) for g in groups])
            if dims.size == self._sq.size:
                proj, sq = self._proj, self._sq
            else:
                proj, sq = np.ascontiguousarray(self._proj[:, :, dims]), self._sq[dims]
            stats.append(PartStats(dims, n, ke, gram, proj, sq))
        if sum(s.n for s in stats) < 2:
            raise ObservationError("stream", "t", "need at least 2 observed samples")
        return stats

    def _recognise(self, phi: np.ndarray, y: np.ndarray) -> Recognition:
        t_last = self._t[-1]
        inc = self._inc
        if inc is None:
            loglik = self._engine.terms(self._stats(), t_last).loglik
        else:
            basis = self.model.basis_
            z_last = t_last * self._inv_dur_max
            need = inc.ke if 0 <= inc.ke and z_last < self._support_until else basis.support_count(z_last)
            if inc.ke >= need:
                loglik = inc.add(phi, y, self._proj, t_last)
            else:
                # a few more basis functions than needed (each below the support threshold on the
                # observed window, as the one-shot truncation) so that resets stay rare
                stats = self._stats()[0]
                stats.ke = min(basis.n_basis, need + STREAM_EXTRA_BASIS)
                loglik = inc.reset(stats, t_last)
                self._support_until = basis.support_limit(stats.ke)
        return self.model._recognition_from_loglik(loglik, t_last)

    def observation(self) -> Demo:
        """The samples received so far as a :class:`Demo`."""
        m = self.model
        rows = np.array(self._rows).reshape(len(self._rows), self._sq.size)
        bits = np.array(self._absent, dtype=np.int64)
        gaps = (bits[:, None] >> np.arange(len(self._slices))[None, :]) & 1 == 1  # (n, groups)
        return Demo(
            task="",
            name="stream",
            source="stream",
            t=np.array(self._t),
            groups={g: rows[:, lo:hi].copy() for g, lo, hi in self._slices},
            channel_names={g: m.channel_names_[g] for g in m.observe},
            missing={g: gaps[:, i] for i, g in enumerate(m.observe) if gaps[:, i].any()},
        )

    def recognition(self) -> Recognition:
        """Latest recognition (raises ObservationError before 2 samples)."""
        if self._last is None:
            raise ObservationError("stream", "t", f"need at least 2 samples, got {len(self._t)}")
        return self._last

    def prediction(self) -> Prediction:
        """Conditioned prediction on all samples received so far."""
        if len(self._t) < 2:
            raise ObservationError("stream", "t", f"need at least 2 samples, got {len(self._t)}")
        return self.model.predict(self.observation())


def _flatten_parts(parts: list[ObservationPart]) -> tuple[np.ndarray, ...]:
    """Observation parts as flat arrays (see ``kernels.condition_block``): concatenated times and
    their offsets, concatenated row-major values, their offsets and the parts' widths."""
    if len(parts) == 1:
        p = parts[0]
        return (
            p.t,
            np.array([0, p.t.size], dtype=np.int64),
            p.y.reshape(-1),
            np.array([0, p.y.size], dtype=np.int64),
            np.array([p.dims.size], dtype=np.int64),
        )
    return (
        np.concatenate([p.t for p in parts]),
        np.cumsum([0] + [p.t.size for p in parts]),
        np.concatenate([p.y.reshape(-1) for p in parts]),
        np.cumsum([0] + [p.y.size for p in parts]),
        np.array([p.dims.size for p in parts], dtype=np.int64),
    )


def _block_diag(chols: list[np.ndarray], n_eye: int) -> np.ndarray:
    """Block-diagonal matrix of the lower Cholesky factors ``chols`` followed by an identity of size
    ``n_eye``."""
    n = sum(c.shape[0] for c in chols) + n_eye
    out = np.eye(n)
    i = 0
    for c in chols:
        out[i : i + c.shape[0], i : i + c.shape[0]] = c
        i += c.shape[0]
    return out


def v_scaled(model: IProMP, group: str, values: np.ndarray) -> np.ndarray:
    """Scale raw values of ``group`` with the model's channel scaling."""
    lo, hi = model.group_slices_[group]
    return model.scaler_.transform(values, slice(lo, hi))


# ---------------------------------------------------------------------------------------------
# Direct (textbook) reference implementation
# ---------------------------------------------------------------------------------------------


def _direct_obs_matrix(basis: GaussianBasis, parts, alpha: float, t_norm: float, n_dims: int, k: int):
    """Dense observation matrix (n_y, n_dims * K) and stacked values / noise dims."""
    rows, ys, dims_of_rows = [], [], []
    for part in parts:
        phi = basis(part.t / (alpha * t_norm))
        for j, d in enumerate(part.dims):
            blk = np.zeros((phi.shape[0], n_dims * k))
            blk[:, d * k : (d + 1) * k] = phi
            rows.append(blk)
            ys.append(part.y[:, j])
            dims_of_rows.append(np.full(phi.shape[0], d))
    return np.concatenate(rows), np.concatenate(ys), np.concatenate(dims_of_rows)


def direct_loglik(
    basis, task: TaskModel, parts, alpha: float, t_norm: float, nu: float, sigma: np.ndarray | None = None
) -> float:
    """Textbook log N(y; Phi mu, Phi Sigma Phi^T + R) with a dense Cholesky.

    Args:
        basis, task, parts: Model basis, task model and observation parts (scaled).
        alpha: Phase candidate.
        t_norm: Nominal duration in [s].
        nu: Noise ratio (``R = nu * delta_d`` per observed dim).
        sigma: Dense weight covariance of the task (computed when None).
    """
    n_dims, k = task.mean.shape
    t_last = max(float(p.t[-1]) for p in parts)
    if t_last > alpha * t_norm * (1.0 + 1e-12):
        return -np.inf
    phi, y, dd = _direct_obs_matrix(basis, parts, alpha, t_norm, n_dims, k)
    sigma = task.covariance() if sigma is None else sigma
    cov = phi @ sigma @ phi.T + np.diag(nu * task.diag[dd])
    c, low = cho_factor(cov, lower=True)
    e = y - phi @ task.mean.reshape(-1)
    sol = cho_solve((c, low), e)
    return float(-0.5 * (y.size * LOG_2PI + 2.0 * np.sum(np.log(np.diag(c))) + e @ sol))


def direct_predict(model: IProMP, observation: Demo) -> Prediction:
    """Reference prediction by the textbook equations (slow; for tests and benchmarks)."""
    parts, t_last = model._prepare(observation)
    nu = model.noise_ratio_
    tn = model.duration_nominal_s_
    n_task = len(model.tasks_)
    grids = np.stack([model.models_[t].alpha_grid for t in model.tasks_])
    logpost = np.empty_like(grids)
    evidence = np.empty(n_task)
    alpha = np.empty(n_task)
    for i, task in enumerate(model.tasks_):
        m = model.models_[task]
        sigma = m.covariance()
        ll = np.array([direct_loglik(model.basis_, m, parts, a, tn, nu, sigma) for a in m.alpha_grid])
        lp = ll + m.alpha_log_prior
        evidence[i] = np.logaddexp.reduce(lp)
        logpost[i] = lp - evidence[i]
        alpha[i] = refine_peak(m.alpha_grid, lp)
    rec = model._finish_recognition(evidence, alpha, grids, logpost, t_last)
    m = model.models_[rec.task]
    a_best = float(rec.alpha[model.tasks_.index(rec.task)])
    n_dims, k = m.mean.shape
    phi, y, dd = _direct_obs_matrix(model.basis_, parts, a_best, tn, n_dims, k)
    sigma = m.covariance()
    cov = phi @ sigma @ phi.T + np.diag(nu * m.diag[dd])
    c = cho_factor(cov, lower=True)
    gain_t = cho_solve(c, phi @ sigma)  # C^-1 Phi Sigma, (n_y, p)
    w_mean = m.mean.reshape(-1) + gain_t.T @ (y - phi @ m.mean.reshape(-1))
    w_cov = sigma - (phi @ sigma).T @ gain_t
    lo, hi = model.group_slices_[model.robot_group]
    z = np.linspace(0.0, 1.0, model.n_points)
    b = model.basis_(z)
    big = np.zeros((z.size * (hi - lo), (hi - lo) * k))
    for j in range(hi - lo):
        big[j :: hi - lo, j * k : (j + 1) * k] = b
    sel = slice(lo * k, hi * k)
    scale = model.scaler_.scale[lo:hi]
    q_mean = (big @ w_mean[sel]).reshape(z.size, hi - lo)
    q_cov = np.stack(
        [
            big[i * (hi - lo) : (i + 1) * (hi - lo)]
            @ w_cov[sel, sel]
            @ big[i * (hi - lo) : (i + 1) * (hi - lo)].T
            for i in range(z.size)
        ]
    )
    wr = w_mean.reshape(n_dims, k)
    pred = model._make_prediction(
        rec, m.factor, m, a_best, wr, np.eye(m.rank), "all"
    )  # trajectories replaced below
    pred.q_mean = model.scaler_.inverse(q_mean, slice(lo, hi))
    pred.q_cov = q_cov * scale[None, :, None] * scale[None, None, :]
    return pred
