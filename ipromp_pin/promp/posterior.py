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
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import solve_triangular

from ..exceptions import ObservationError
from .compiled import kernels

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


@dataclass(frozen=True)
class RobotWeightPosterior:
    """The conditioned robot weights in latent form: ``w = mean + sqrt(diag) xi + factor eta`` with
    ``xi ~ N(0, I)`` and ``eta ~ N(0, Q^-1)``, ``Q = L L^T`` (scaled units).

    Attributes:
        mean: (J, K) posterior mean of the robot weights.
        diag: (J,) per-joint diagonal variance ``delta_j``.
        factor: (J, K, r) the robot rows of the covariance factor.
        q_chol: (r, r) lower Cholesky factor ``L`` of the latent posterior precision ``Q``.
        phi: (M, K) basis values at the prediction's phases.
        offset, scale: (J,) the robot channels' scaling (original = scaled * scale + offset, in [rad]).
    """

    mean: np.ndarray
    diag: np.ndarray
    factor: np.ndarray
    q_chol: np.ndarray
    phi: np.ndarray
    offset: np.ndarray
    scale: np.ndarray

    def sample_q(self, n: int, rng: np.random.Generator | int | None = None) -> np.ndarray:
        """Draw ``n`` robot trajectories (n, M, J) in [rad] (exactly the conditioned Gaussian,
        without forming it)."""
        rng = np.random.default_rng(rng)
        j, k, r = self.factor.shape
        xi = rng.standard_normal((n, j, k)) * np.sqrt(self.diag)[None, :, None]
        zeta = rng.standard_normal((r, n))
        eta = solve_triangular(self.q_chol, zeta, lower=True, trans="T").T if r else zeta.T
        w = self.mean[None] + xi + np.einsum("jkr,nr->njk", self.factor, eta)
        q = np.einsum("mk,njk->nmj", self.phi, w)
        return q * self.scale + self.offset


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


def recognise_from_loglik(
    priors: PhasePriors, loglik: np.ndarray, t_last: float
) -> tuple[Recognition, np.ndarray]:
    """The recognition from the log likelihood (T, C) of every (task, candidate), and the normalised
    log phase posterior (T, C) it holds."""
    evidence, logpost, alpha, finite, *task_post = kernels().recognition(
        loglik, priors.log_prior, priors.alphas, REFINE_WEIGHTS, REFINE_NODES, priors.task_log_prior
    )
    if not finite:  # some task cannot explain the observation
        finite = np.isfinite(evidence)
        alpha[~finite] = priors.alpha_mu[~finite]
    rec = finish_recognition(priors, evidence, alpha, logpost, t_last, tuple(task_post))
    return rec, logpost


def with_task_posterior(rec: Recognition, log_posterior: np.ndarray, priors: PhasePriors) -> Recognition:
    """``rec`` (changed in place and returned) with its task posterior replaced by ``log_posterior``
    (T,) (normalised): the most probable task and its predicted duration follow it; the phase
    estimates stay."""
    best = int(np.argmax(log_posterior))
    rec.task = priors.tasks[best]  # rec is the caller's fresh object: changed in place (no copy)
    rec.log_posterior = log_posterior
    rec.posterior = np.exp(log_posterior)
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
    if not math.isfinite(float(log_post[best])):
        raise ObservationError(None, "t", "the observation is impossible under every task (too long?)")
    return Recognition(
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
