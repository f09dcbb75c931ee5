"""Task and phase posteriors of a partial observation, and the prediction that follows from them.

From the log likelihood of every (task, phase candidate) pair
(:meth:`~ipromp_pin.promp.likelihood.InferenceEngine.log_likelihood`):

1. per task the phase posterior over its candidates of ``alpha = T / T_norm`` and its log evidence
   (log-sum-exp over the candidates), and the continuous MAP phase: the log posterior, an analytic
   function of the phase, is interpolated around the best candidate by degree-5 polynomials at
   :data:`REFINE_STEPS` points per spacing and the best fine point refined by a parabola
   (reference implementation: :func:`ipromp_pin.promp.reference.refine_peak`);
2. the task posterior ``p(k | obs)`` in log space: task prior times evidence, normalised.

:class:`Recognition` holds these; :class:`Prediction` adds the conditioned robot trajectory
(:mod:`ipromp_pin.promp.conditioning`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from ..exceptions import ObservationError
from .compiled import kernels
from .weight_posterior import RobotWeightPosterior

VIA_POINT_STD_RAD = 1e-3
"""Default standard deviation of a joint-angle via-point in [rad]."""

VIA_POINT_STD_RAD_S = 1e-2
"""Default standard deviation of a joint-velocity via-point in [rad/s]."""

REFINE_STEPS = 8
"""Fine points per candidate spacing at which the log phase posterior is interpolated."""

REFINE_NODES = np.arange(-2, 4)
"""Stencil of the interpolation, in candidate spacings from the left end of the interval (6 points)."""


def _refine_weights() -> np.ndarray:
    """Lagrange weights (REFINE_STEPS, 6) of the stencil at the fractions ``j / REFINE_STEPS`` of one
    interval."""
    x = np.arange(REFINE_STEPS) / REFINE_STEPS
    w = np.ones((REFINE_STEPS, REFINE_NODES.size))
    for p, xp in enumerate(REFINE_NODES):
        for q, xq in enumerate(REFINE_NODES):
            if q != p:
                w[:, p] *= (x - xq) / (xp - xq)
    return w


REFINE_WEIGHTS = _refine_weights()
"""(REFINE_STEPS, 6) interpolation weights of the stencil :data:`REFINE_NODES`."""


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
            assert self._compute is not None  # cleared only once the values are computed
            self._values = self._compute()
            self._compute = None
        return self._values

    def __getitem__(self, key: str) -> np.ndarray:
        if key not in self._keys:
            raise KeyError(key)
        return self._get()[key]

    def __iter__(self) -> Iterator[str]:
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
        novelty_score: How far the observation is from every learned task
            (:mod:`~ipromp_pin.promp.novelty`; NaN: the model has no novelty detector, inf: no task
            can explain the observation).
        novelty_p_value: Its conformal p-value among held-out observations of the learned tasks
            (NaN: no detector; 0: no task can explain the observation).
        known: Whether the observation is one of the learned tasks (``novelty_p_value > alpha``);
            ``task`` stays the most probable learned task either way.
        unknown_reason: Why the observation is unknown (None when known).
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
    novelty_score: float = math.nan
    novelty_p_value: float = math.nan
    known: bool = True
    unknown_reason: str | None = None


IMPOSSIBLE_REASON = "the observation is impossible under every task (longer than any learned motion?)"
"""The :attr:`Recognition.unknown_reason` of an observation no task can explain."""


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
        robot_weights: The conditioned robot weights (what :meth:`sample_q` draws from).

    :meth:`condition_joints` and :meth:`condition_state` add joint via-points (the robot's current
    state, a goal configuration ...) and return a new prediction whose ``q_mean``, ``q_cov``,
    ``robot_weights`` and samples are conditioned on them; the task and phase estimates and
    ``human_mean`` stay those of the observation.
    """

    t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    q_mean: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    q_cov: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))
    q_prior_mean: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    q_prior_std: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    joint_names: tuple[str, ...] = ()
    human_mean: Mapping[str, np.ndarray] = field(default_factory=dict)
    robot_weights: RobotWeightPosterior | None = field(default=None, repr=False)

    def sample_q(self, n: int, rng: np.random.Generator | int | None = None) -> np.ndarray:
        """Draw ``n`` robot trajectories (n, M, J) in [rad] from the conditioned weight posterior."""
        if self.robot_weights is None:
            raise ValueError("this prediction holds no weight posterior to sample from")
        return self.robot_weights.sample_q(n, rng)

    def condition_joints(
        self,
        t_s: float | np.ndarray,
        q_rad: np.ndarray,
        std_rad: float | np.ndarray = VIA_POINT_STD_RAD,
        joints: Iterable[str | int] | None = None,
    ) -> Prediction:
        """The prediction conditioned on joint via-points (like ``condition_position`` of ProMP
        libraries, with the covariance updated).

        Args:
            t_s: (n,) times of the via-points in [s] on this prediction's time axis, in
                ``[0, duration_s]`` (``duration_s``: the hand-over).
            q_rad: (n, J_sel) joint angles in [rad] (or (J_sel,) with one time); NaN leaves a joint
                free at that time.
            std_rad: Standard deviation of each via-point in [rad] (> 0; scalar or per value): how
                closely the conditioned trajectory must pass.
            joints: The joints (names or indices) of ``q_rad``'s columns (default: all, in order).

        Returns:
            A new :class:`Prediction`.
        """
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        given, cols, vals, std = self._via_points(t, q_rad, std_rad, joints, "t_s")
        if self.robot_weights is None or self.robot_weights.basis is None:
            raise ValueError("this prediction holds no weight posterior to condition")
        z = np.repeat(t / self.duration_s, cols.shape[1])[given]
        phi = self.robot_weights.basis(z)
        return self._conditioned(phi, cols.reshape(-1)[given], vals, std, np.zeros(vals.size, dtype=bool))

    def condition_state(
        self,
        q_rad: np.ndarray,
        qd_rad_s: np.ndarray | None = None,
        t_s: float | None = None,
        std_rad: float = VIA_POINT_STD_RAD,
        std_rad_s: float = VIA_POINT_STD_RAD_S,
    ) -> Prediction:
        """The prediction conditioned on the robot's current joint state.

        Args:
            q_rad: (J,) current joint angles in [rad].
            qd_rad_s: (J,) current joint velocities in [rad/s] (None: positions only).
            t_s: Time of the state in [s] on this prediction's time axis (default ``observed_until_s``,
                the end of the observation: now).
            std_rad, std_rad_s: Standard deviations of the positions [rad] and velocities [rad/s].
        """
        t = float(self.observed_until_s if t_s is None else t_s)
        out = self.condition_joints(t, q_rad, std_rad)
        if qd_rad_s is None:
            return out
        given, cols, vals, std = self._via_points(np.array([t]), qd_rad_s, std_rad_s, None, "t_s")
        rw = out.robot_weights
        assert rw is not None and rw.basis is not None  # condition_joints has checked them
        dphi = rw.basis.derivative(np.full(vals.size, t / self.duration_s)) / self.duration_s
        return out._conditioned(dphi, cols.reshape(-1)[given], vals, std, np.ones(vals.size, dtype=bool))

    def _via_points(
        self, t: np.ndarray, values: np.ndarray, std: float | np.ndarray, joints, field_name: str
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Flattened via-points: mask of the given (non-NaN) values, joint indices (n, J_sel),
        their values and standard deviations."""
        names = list(self.joint_names)
        if joints is None:
            idx = np.arange(len(names))
        else:
            unknown = [j for j in joints if isinstance(j, str) and j not in names]
            if unknown:
                raise ObservationError(
                    None, "joints", f"unknown joints {unknown} (joints: {', '.join(names)})"
                )
            idx = np.array([names.index(j) if isinstance(j, str) else int(j) for j in joints], dtype=np.int64)
            if np.any((idx < 0) | (idx >= len(names))):
                raise ObservationError(None, "joints", f"index out of range for {len(names)} joints")
        v = np.asarray(values, dtype=float)
        if v.ndim < 2 and v.size == t.size * idx.size:
            v = v.reshape(t.size, idx.size)
        if v.shape != (t.size, idx.size):
            raise ObservationError(None, "q", f"expected shape ({t.size}, {idx.size}), got {v.shape}")
        if not np.all(np.isfinite(t)) or np.any(t < -1e-9) or np.any(t > self.duration_s + 1e-9):
            raise ObservationError(
                None, field_name, f"via-point times must be in [0, {self.duration_s:.3f}] s, got {t}"
            )
        s = np.broadcast_to(np.asarray(std, dtype=float), v.shape).reshape(-1)
        cols = np.broadcast_to(idx, v.shape)
        given = ~np.isnan(v.reshape(-1))
        return given, cols, v.reshape(-1)[given], s[given]

    def _conditioned(
        self, rows: np.ndarray, joints: np.ndarray, values: np.ndarray, std: np.ndarray, deriv: np.ndarray
    ) -> Prediction:
        assert self.robot_weights is not None  # checked by the callers (condition_joints)
        rw = self.robot_weights.condition(rows, joints, values, std, deriv)
        return replace(self, q_mean=rw.q_mean(), q_cov=rw.q_cov(), robot_weights=rw)


@dataclass(frozen=True)
class PhasePriors:
    """What turns per-candidate log likelihoods into a recognition, for one set of task models.

    Attributes:
        tasks: Task names.
        alphas: (T, C) phase candidates of every task.
        log_prior: (T, C) their log prior weights.
        alpha_mu: (T,) prior mean phases (the estimate of a task that cannot explain the observation).
        task_log_prior: (T,) log prior of the tasks.
        duration_nominal_s: ``T_norm`` in [s].
    """

    tasks: tuple[str, ...]
    alphas: np.ndarray
    log_prior: np.ndarray
    alpha_mu: np.ndarray
    task_log_prior: np.ndarray
    duration_nominal_s: float


def recognition_terms(priors: PhasePriors, loglik: np.ndarray) -> tuple:
    """The compiled recognition of the log likelihood (T, C) under ``priors``
    (``kernels.recognition``): the tasks' log evidence (T,), log phase posteriors (T, C), MAP phases
    (T,), whether every evidence is finite, and the task posterior (log posterior (T,), posterior
    (T,), best index)."""
    return kernels().recognition(
        loglik, priors.log_prior, priors.alphas, REFINE_WEIGHTS, REFINE_NODES, priors.task_log_prior
    )


def recognise_from_loglik(
    priors: PhasePriors, loglik: np.ndarray, t_last: float
) -> tuple[Recognition, np.ndarray]:
    """The recognition from the log likelihood (T, C) of every (task, candidate), and the normalised
    log phase posterior (T, C) it holds."""
    evidence, logpost, alpha, finite, *task_post = recognition_terms(priors, loglik)
    if not finite:  # some task cannot explain the observation
        finite = np.isfinite(evidence)
        alpha[~finite] = priors.alpha_mu[~finite]
    rec = finish_recognition(priors, evidence, alpha, logpost, t_last, tuple(task_post))
    return rec, logpost


def with_task_posterior(
    rec: Recognition,
    log_posterior: np.ndarray,
    priors: PhasePriors,
    posterior: np.ndarray | None = None,
    best: int | None = None,
) -> Recognition:
    """``rec`` (changed in place and returned) with its task posterior replaced by ``log_posterior``
    (T,) (normalised; ``posterior`` its exponential and ``best`` its most probable task when the
    caller has them): the most probable task and its predicted duration follow it; the phase
    estimates stay."""
    best = int(np.argmax(log_posterior)) if best is None else int(best)
    rec.task = priors.tasks[best]  # rec is the caller's fresh object: changed in place (no copy)
    rec.log_posterior = log_posterior
    rec.posterior = np.exp(log_posterior) if posterior is None else posterior
    rec.duration_s = float(rec.alpha[best] * priors.duration_nominal_s)
    return rec


def finish_recognition(
    priors: PhasePriors,
    evidence: np.ndarray,
    alpha: np.ndarray,
    logpost: np.ndarray,
    t_last: float,
    task_post: tuple[np.ndarray, np.ndarray, int] | None = None,
) -> Recognition:
    """The recognition from the tasks' log evidence (T,), MAP phases (T,) and log phase posteriors
    (T, C); the task posterior ``task_post`` (log posterior, posterior, best index) from the
    compiled ``task_posterior`` kernel, computed here when not given."""
    if task_post is None:
        task_post = kernels().task_posterior(priors.task_log_prior, np.ascontiguousarray(evidence))
    log_post, posterior, best = task_post
    unexplained = not math.isfinite(float(log_post[best]))
    if unexplained:  # no task explains it: the task prior, unknown (the caller decides)
        log_post = priors.task_log_prior - np.logaddexp.reduce(priors.task_log_prior)
        posterior = np.exp(log_post)
        best = int(np.argmax(log_post))
        alpha = np.where(np.isfinite(evidence), alpha, priors.alpha_mu)
    rec = Recognition(
        task=priors.tasks[best],
        tasks=list(priors.tasks),
        log_posterior=log_post,
        posterior=posterior,
        alpha=alpha,
        duration_s=float(alpha[best] * priors.duration_nominal_s),
        observed_until_s=t_last,
        phase_grid=priors.alphas,
        phase_log_post=logpost,
        log_evidence=evidence,
    )
    if unexplained:
        rec.novelty_score, rec.novelty_p_value = math.inf, 0.0
        rec.known, rec.unknown_reason = False, IMPOSSIBLE_REASON
    return rec
