"""Per-task Interaction ProMP: a Gaussian over the stacked basis weights of all channels.

Representation. After per-channel scaling (:class:`ChannelScaler`, learned on the
training demos of all tasks, so that the orientation quaternion, EMG envelope
and joint angles have comparable magnitudes), each channel ``d`` of a demo of
duration ``T_i`` is fitted (ridge least squares) as ``y_d(z) = phi(z)^T w_d``
with ``z = t / T_i`` (:class:`~ipromp_pin.promp.basis.GaussianBasis`). The weights of
all ``D`` channels (observed human groups first, then the robot joints) are
stacked dim-major into ``w`` of length ``p = D K``.

Regularised covariance. With N = 10-100 demos and p of several hundred weights
the sample covariance ``S_t = X_c^T X_c / N`` of task t is singular. We use
Ledoit-Wolf shrinkage (Ledoit & Wolf, 2004, "A well-conditioned estimator for
large-dimensional covariance matrices") toward a *per-dim scalar* diagonal
target ``T = blockdiag(tau_d I_K)``, ``tau_d`` = mean weight variance of dim d
pooled over all tasks (as regularised discriminant analysis pools class
covariances): ``Sigma_t = (1 - lambda) S_t + lambda T`` with the analytic
intensity ``lambda = min(1, sum_t b_t^2 / sum_t d_t^2)``,
``b_t^2 = N^-2 sum_i ||x_i x_i^T - S_t||_F^2``, ``d_t^2 = ||S_t - T||_F^2``
(computed in O(N^2 p) from the N x N Gram matrices). Pooling makes the diagonal
part identical for all tasks, so their likelihoods differ only through what
the data say about them (not through different noise levels). A small floor
(1e-6 of the mean ``tau``) keeps every diagonal entry positive, so ``Sigma_t``
is symmetric positive definite. It is stored in the structured form
``Sigma_t = blockdiag(delta_d I_K) + F_t F_t^T`` with ``delta_d = lambda tau_d +
floor`` and ``F_t = sqrt((1 - lambda) / N) X_c^T`` compressed to rank <= N - 1
(thin SVD), which the fast inference (:mod:`ipromp_pin.promp.likelihood`) exploits.

Blocks. The dims may be split into independent blocks (zero cross-covariance), each shrunk as
above on its own, with its own intensity, target and factor columns (so ``F_t`` then has rank
<= N - 1 per block): e.g. the human groups that inform the robot together with the robot, and the
human groups used only to recognise the task (:mod:`ipromp_pin.promp.selection`, ``coupling``).

Observation noise. An observed channel ``d`` is seen with white noise of
variance ``r_d = nu * delta_d`` (scaled units): each channel's idiosyncratic
(not shared with other channels) variation is split between a smooth part (in
the weights) and a white part (in time) in the same proportion ``nu`` for every
channel. The per-channel scale ``delta_d`` comes from the data of that channel;
the global ratio ``nu`` is chosen by leave-one-out cross-validation on the
training demos (see :mod:`ipromp_pin.promp.selection`). Sharing ``nu`` lets all
channels share one factorisation per phase candidate.

Phase. ``alpha_i = T_i / T_norm`` with ``T_norm`` the mean training duration
over all tasks in [s]; each task has a Gaussian prior ``N(alpha_mu, alpha_sigma)``
fitted to its demos' ``alpha_i``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..exceptions import DataError, ModelError
from .basis import GaussianBasis

VARIANCE_FLOOR = 1e-6
"""Floor of the per-dim diagonal weight variance, relative to the mean target variance."""


LOG_SHIFT_FRACTION = 0.05
"""Shift ``c`` of a log-scaled channel, ``log(max(y, 0) + c)``, as a fraction of its training median."""


@dataclass
class ChannelScaler:
    """Per-channel scaling ``y_scaled = (f(y) - offset) / scale``.

    ``f`` is the identity, or for log-scaled channels (EMG envelopes)
    ``f(y) = log(max(y, 0) + c)``: muscle-activity amplitudes vary
    multiplicatively between repetitions (grip force, electrode contact), so
    their spread is far closer to Gaussian in log space. ``c`` (a small
    fraction of the channel's training median) keeps silent channels finite.

    Attributes:
        offset: (D,) channel means of ``f(y)`` over the training samples.
        scale: (D,) channel standard deviations of ``f(y)`` (1 for constant channels).
        log_shift: (D,) ``c`` of log-scaled channels, NaN for linear ones (``None``: all linear).
    """

    offset: np.ndarray
    scale: np.ndarray
    log_shift: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.log_shift is None:
            self.log_shift = np.full(np.shape(self.offset), np.nan)
        self._log = np.isfinite(self.log_shift)

    @property
    def log_mask(self) -> np.ndarray:
        """(D,) True for the channels modelled in log space."""
        return self._log

    @property
    def shift(self) -> np.ndarray:
        """(D,) ``log_shift`` once defaulted: the shifts ``c``, NaN for linear channels."""
        assert self.log_shift is not None  # set by __post_init__
        return self.log_shift

    @classmethod
    def fit(cls, values: np.ndarray, log_dims: np.ndarray | None = None) -> ChannelScaler:
        """Learn the scaling from stacked training samples (n, D); NaN rows are ignored per channel.

        Args:
            values: (n, D) training samples in original units.
            log_dims: (D,) boolean mask of the channels modelled in log space.
        """
        shift = np.full(values.shape[1], np.nan)
        if log_dims is not None and np.any(log_dims):
            med = np.nanmedian(np.maximum(values[:, log_dims], 0.0), axis=0)
            shift[log_dims] = np.maximum(LOG_SHIFT_FRACTION * med, 1e-6)
        scaler = cls(offset=np.zeros(values.shape[1]), scale=np.ones(values.shape[1]), log_shift=shift)
        f = scaler._forward(values, slice(None))
        offset = np.nanmean(f, axis=0)
        scale = np.nanstd(f, axis=0)
        tiny = 1e-9 * np.maximum(1.0, np.abs(offset))
        scaler.offset = offset
        scaler.scale = np.where(scale > tiny, scale, 1.0)
        return scaler

    def _forward(self, values: np.ndarray, dims: slice | np.ndarray) -> np.ndarray:
        log = self._log[dims]
        if not np.any(log):
            return values
        out = np.array(values, dtype=float, copy=True)
        out[..., log] = np.log(np.maximum(out[..., log], 0.0) + self.shift[dims][log])
        return out

    def transform(self, values: np.ndarray, dims: slice | np.ndarray = slice(None)) -> np.ndarray:
        """Scale values (..., D') of channels ``dims``."""
        return (self._forward(values, dims) - self.offset[dims]) / self.scale[dims]

    def inverse(self, values: np.ndarray, dims: slice | np.ndarray = slice(None)) -> np.ndarray:
        """Undo :meth:`transform` (log-scaled channels map back through ``exp(.) - c``)."""
        out = values * self.scale[dims] + self.offset[dims]
        log = self._log[dims]
        if np.any(log):
            out[..., log] = np.exp(out[..., log]) - self.shift[dims][log]
        return out


@dataclass
class ShrunkCovariance:
    """Structured shrinkage estimate ``blockdiag(delta_d I_K) + F F^T`` of a weight covariance.

    Attributes:
        mean: (D, K) mean weights.
        diag: (D,) per-dim diagonal variance ``delta_d``.
        factor: (D, K, r) low-rank factor ``F`` (r <= N - 1 per block of dims).
        shrinkage: (D,) Ledoit-Wolf intensity ``lambda`` in [0, 1] of each dim (equal within a block).
    """

    mean: np.ndarray
    diag: np.ndarray
    factor: np.ndarray
    shrinkage: np.ndarray


def shrink_covariance(weights: np.ndarray) -> ShrunkCovariance:
    """Ledoit-Wolf shrinkage of one task's weight covariance (see :func:`shrink_covariances`)."""
    return shrink_covariances([weights])[0]


def shrink_covariances(
    weights: list[np.ndarray],
    pooling: float = 0.0,
    blocks: list[np.ndarray] | None = None,
    tasks: list[int] | None = None,
    cache: ShrinkageCache | None = None,
    factor_blocks: Sequence[int] | None = None,
) -> list[ShrunkCovariance]:
    """Ledoit-Wolf shrinkage of every task's covariance toward one pooled per-dim diagonal target.

    Args:
        weights: Per task, (N_t, D, K) weights of its N_t >= 2 demos.
        pooling: Weight ``beta`` in [0, 1] of the pooled within-task covariance: the low-rank part
            of task t is that of ``(1 - beta) S_t + beta S_pool``, ``S_pool`` the covariance of
            every task's demos about their own task mean (regularised discriminant analysis,
            Friedman 1989). How the human's motion shapes the robot's (the cross-covariance) is
            largely shared by hand-over tasks, and pooling estimates it from all demos.
        blocks: Partition of the dims ``0..D-1`` into index arrays (None: one block of all dims).
            Dims of different blocks are independent (zero cross-covariance); each block is shrunk
            on its own, with its own intensity, and has its own factor columns (rank <= N_t - 1
            each). A block of channels that vary much between demos but are unrelated to the others
            (EMG amplitudes) then neither drives the intensity of the other dims nor couples to them.
        tasks: Indices of the tasks whose estimates are returned (default all); the pooled target
            and intensities always use every task's demos.
        cache: Per-task statistics of weights arrays seen before (:class:`ShrinkageCache`): a
            leave-one-out estimate then recomputes only the task that lost a demo (same numbers).
        factor_blocks: Indices into ``blocks`` of the blocks whose factor columns are returned
            (default all): a caller that reads only the loadings of those blocks' dims skips the
            others' factorisations (their diagonal and intensity are still estimated).

    Returns:
        Per task, the structured SPD estimate, block by block ``(1 - lambda) S_t + lambda T`` with
        ``T = blockdiag(tau_d I_K)``, ``tau_d`` the mean weight variance of dim d pooled
        over tasks, and one intensity per block ``lambda = min(1, sum_t b_t^2 / sum_t d_t^2)``
        (Ledoit-Wolf, with the tasks' estimation errors and distances pooled). The
        diagonal part ``delta_d = lambda tau_d`` is therefore shared by all tasks.
    """
    d, k = weights[0].shape[1:]
    if not 0.0 <= pooling <= 1.0:
        raise ModelError(f"pooling must be in [0, 1], got {pooling}")
    for w in weights:
        if w.shape[0] < 2:
            raise ModelError(f"covariance needs at least 2 demos per task, got {w.shape[0]}")
    if blocks is None:
        blocks = [np.arange(d)]
    blocks = [np.asarray(b, dtype=int).reshape(-1) for b in blocks]
    seen = np.concatenate(blocks) if blocks else np.zeros(0, dtype=int)
    if seen.size != d or not np.array_equal(np.sort(seen), np.arange(d)):
        raise ModelError(f"blocks must partition the {d} dims, got {[b.tolist() for b in blocks]}")
    tasks = list(range(len(weights))) if tasks is None else [int(t) for t in tasks]
    diag = np.empty(d)
    lam_dims = np.empty(d)
    factors: list[list[np.ndarray]] = [[np.zeros((d, k, 0))] for _ in tasks]
    for n_block, dims in enumerate(blocks):
        if dims.size == 0:
            continue
        stats = [_block_stats(w, dims, cache) for w in weights]
        with_factors = factor_blocks is None or n_block in factor_blocks
        lam, diag_b, facs = _shrink_block(stats, pooling, tasks if with_factors else [])
        diag[dims] = diag_b
        lam_dims[dims] = lam
        for i, f in enumerate(facs):
            full = np.zeros((d, k, f.shape[2]))
            full[dims] = f
            factors[i].append(full)
    return [
        ShrunkCovariance(
            mean=np.ascontiguousarray(weights[t].mean(axis=0)),
            diag=diag.copy(),
            factor=np.ascontiguousarray(np.concatenate(facs, axis=2)),
            shrinkage=lam_dims.copy(),
        )
        for t, facs in zip(tasks, factors, strict=True)
    ]


def added_task_covariance(
    weights: list[np.ndarray],
    new: np.ndarray,
    pooling: float,
    blocks: list[np.ndarray],
    diag: np.ndarray,
    shrinkage: np.ndarray,
    cache: ShrinkageCache | None = None,
) -> ShrunkCovariance:
    """The shrunk covariance of a task added to fitted ones without changing them: the fitted tasks'
    shared diagonal ``diag`` (D,) and per-dim intensities ``shrinkage`` (D,) are kept, the new task's
    low-rank part is ``(1 - lambda)`` times its own covariance pooled (weight ``pooling``) with every
    task's, as :func:`shrink_covariances` builds it.

    Args:
        weights: Per fitted task, (N_t, D, K) the training weights.
        new: (N, D, K) the new task's weights (N >= 2).
        pooling, blocks: As in :func:`shrink_covariances` (the fit's coupling blocks).
        diag, shrinkage: The fitted tasks' shared diagonal and intensities.
        cache: The statistics of ``weights`` (:class:`ShrinkageCache`; a caller that builds several
            candidates against the same fitted tasks computes them once).
    """
    n, d, k = new.shape
    if n < 2:
        raise ModelError(f"covariance needs at least 2 demos per task, got {n}")
    factors = [np.zeros((d, k, 0))]
    for dims in (np.asarray(b, dtype=int).reshape(-1) for b in blocks):
        if dims.size == 0:
            continue
        stats = [*(_block_stats(w, dims, cache) for w in weights), _BlockStats(new[:, dims])]
        pool = None
        if pooling > 0.0:
            pool = np.vstack([st.xc for st in stats]) / np.sqrt(sum(st.shape[0] for st in stats))
        lam = float(shrinkage[dims[0]])
        f = stats[-1].unscaled_factor(pool, pooling) * np.sqrt(1.0 - lam)
        full = np.zeros((d, k, f.shape[1]))
        full[dims] = f.reshape(dims.size, k, -1)
        factors.append(full)
    return ShrunkCovariance(
        mean=np.ascontiguousarray(new.mean(axis=0)),
        diag=np.array(diag, dtype=float),
        factor=np.ascontiguousarray(np.concatenate(factors, axis=2)),
        shrinkage=np.array(shrinkage, dtype=float),
    )


class _BlockStats:
    """One task's statistics of one block of dims that do not depend on the other tasks: centred
    weights ``xc`` (N, D_b K), their Gram matrix (N, N), per-dim sums of squares / K (D_b,),
    ``||S_t||_F^2``, ``tau_t`` (D_b,), the Ledoit-Wolf estimation error ``b_t^2``, and (computed when
    first needed, without pooling) the unscaled factor ``V diag(s)`` of the thin SVD of ``xc / sqrt(N)``."""

    def __init__(self, w: np.ndarray) -> None:
        n, d, k = w.shape
        self.shape = (n, d, k)
        xc = (w - w.mean(axis=0)).reshape(n, d * k)
        gram = xc @ xc.T
        self.xc, self.gram = xc, gram
        self.tau_num = np.einsum("ndk,ndk->d", xc.reshape(n, d, k), xc.reshape(n, d, k)) / k
        self.s_fro2 = float(np.sum(gram * gram)) / n**2  # ||S_t||_F^2
        self.tau_t = np.einsum("ndk,ndk->d", xc.reshape(n, d, k), xc.reshape(n, d, k)) / (n * k)
        xsx = np.sum(gram * gram, axis=1) / n  # x_i^T S_t x_i
        self.b2 = float(np.sum(np.diag(gram) ** 2 - 2.0 * xsx + self.s_fro2)) / n**2
        self._unscaled: np.ndarray | None = None

    def unscaled_factor(self, pooled: np.ndarray | None, pooling: float) -> np.ndarray:
        """``V diag(s)`` (D_b K, r) of the thin SVD of the rows ``xc / sqrt(N)`` (with ``pooling``,
        stacked over the ``pooled`` rows; cached without)."""
        if pooling <= 0.0 and self._unscaled is not None:
            return self._unscaled
        rows = self.xc / np.sqrt(self.xc.shape[0])
        if pooling > 0.0:
            rows = np.vstack([np.sqrt(1.0 - pooling) * rows, np.sqrt(pooling) * pooled])
        _, sv, vt = np.linalg.svd(rows, full_matrices=False)
        keep = sv > 1e-10 * max(float(sv[0]), 1e-300)
        out = vt[keep].T * sv[keep]
        if pooling <= 0.0:
            self._unscaled = out
        return out


class ShrinkageCache:
    """The per-task statistics (:class:`_BlockStats`) of registered weights arrays, so that the
    leave-one-out estimates of the cross-validations (one task's weights without one demo, the others
    the registered arrays themselves) recompute only the task that lost a demo. Arrays are
    recognised by identity (the cache holds them, so an identity cannot be reused)."""

    def __init__(self, weights: Sequence[np.ndarray] = ()) -> None:
        self._arrays = {id(w): w for w in weights}
        self._stats: dict[tuple[int, bytes], _BlockStats] = {}

    def stats(self, w: np.ndarray, dims: np.ndarray) -> _BlockStats | None:
        """The cached statistics of ``w[:, dims]`` (None when ``w`` is not registered)."""
        if self._arrays.get(id(w)) is not w:
            return None
        key = (id(w), dims.tobytes())
        out = self._stats.get(key)
        if out is None:
            out = self._stats[key] = _BlockStats(w[:, dims])
        return out


def _block_stats(w: np.ndarray, dims: np.ndarray, cache: ShrinkageCache | None) -> _BlockStats:
    cached = None if cache is None else cache.stats(w, dims)
    return _BlockStats(w[:, dims]) if cached is None else cached


def _shrink_block(
    stats: list[_BlockStats], pooling: float, tasks: list[int]
) -> tuple[float, np.ndarray, list[np.ndarray]]:
    """Ledoit-Wolf intensity, diagonal (D_b,) and factors (D_b, K, r_t) of the tasks ``tasks``, one
    block, from every task's statistics."""
    _, d, k = stats[0].shape
    tau_num, tau_den = np.zeros(d), 0
    for st in stats:
        tau_num += st.tau_num
        tau_den += st.shape[0]
    tau = tau_num / tau_den  # pooled per-dim mean weight variance
    b2_sum = d2_sum = 0.0
    for st in stats:
        # ||S_t - T||_F^2 = ||S_t||^2 - 2 K sum_d tau_t,d tau_d + K sum_d tau_d^2
        d2_sum += max(st.s_fro2 - 2.0 * k * float(st.tau_t @ tau) + k * float(tau @ tau), 0.0)
        b2_sum += st.b2
    lam = 1.0 if d2_sum <= 0.0 else float(min(1.0, max(0.0, b2_sum / d2_sum)))
    floor = VARIANCE_FLOOR * max(float(np.mean(tau)), 1e-12)
    diag = lam * tau + floor
    pool = np.vstack([st.xc for st in stats]) / np.sqrt(tau_den) if pooling > 0.0 else None
    factors = []
    for t in tasks:
        factor = stats[t].unscaled_factor(pool, pooling) * np.sqrt(1.0 - lam)
        factors.append(factor.reshape(d, k, -1))
    return lam, diag, factors


@dataclass
class TaskModel:
    """Interaction ProMP of one task, in scaled units.

    Attributes:
        task: Task name.
        mean: (D, K) mean weights of all dims (observed human dims first, then robot).
        diag: (D,) per-dim diagonal weight variance ``delta_d``.
        factor: (D, K, r) low-rank covariance factor.
        shrinkage: (D,) Ledoit-Wolf shrinkage intensity of each dim (equal within a block of dims).
        alpha_mu: Mean of the phase prior ``alpha = T / T_norm``.
        alpha_sigma: Standard deviation of the phase prior (floored).
        alpha_grid: (n_alpha,) phase candidates.
        alpha_log_prior: (n_alpha,) log prior weights of the candidates (they sum to 1).
        train_weights: (N, D, K) fitted weights of the training demos (for plots).
        train_alpha: (N,) phases ``T_i / T_norm`` of the training demos.
    """

    task: str
    mean: np.ndarray
    diag: np.ndarray
    factor: np.ndarray
    shrinkage: np.ndarray
    alpha_mu: float
    alpha_sigma: float
    alpha_grid: np.ndarray
    alpha_log_prior: np.ndarray
    train_weights: np.ndarray
    train_alpha: np.ndarray

    @classmethod
    def from_estimate(
        cls,
        task: str,
        cov: ShrunkCovariance,
        prior: tuple[float, float],
        candidates: tuple[np.ndarray, np.ndarray],
        weights: np.ndarray,
        alphas: np.ndarray,
    ) -> TaskModel:
        """The model of ``task`` from its shrunk covariance, phase prior ``(mu, sigma)``, phase
        candidates and their log prior weights, and its demos' weights (N, D, K) and phases (N,)."""
        return cls(
            task=task,
            mean=cov.mean,
            diag=cov.diag,
            factor=cov.factor,
            shrinkage=cov.shrinkage,
            alpha_mu=prior[0],
            alpha_sigma=prior[1],
            alpha_grid=candidates[0],
            alpha_log_prior=candidates[1],
            train_weights=weights,
            train_alpha=alphas,
        )

    @property
    def n_demos(self) -> int:
        """Number of training demos N."""
        return int(self.train_weights.shape[0])

    @property
    def rank(self) -> int:
        """Rank r of the low-rank covariance part."""
        return int(self.factor.shape[2])

    def covariance(self, dims: np.ndarray | None = None) -> np.ndarray:
        """Dense weight covariance (dims * K, dims * K) of the selected dims (default all)."""
        dims = np.arange(self.mean.shape[0]) if dims is None else np.asarray(dims)
        k = self.mean.shape[1]
        f = self.factor[dims].reshape(dims.size * k, -1)
        cov = f @ f.T
        cov[np.diag_indices_from(cov)] += np.repeat(self.diag[dims], k)
        return cov

    def distribution(self, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean and std (n, D) of every dim at basis values ``phi`` (n, K), scaled units."""
        mean = phi @ self.mean.T
        proj = np.einsum("nk,dkr->ndr", phi, self.factor)
        var = np.sum(proj * proj, axis=2) + np.sum(phi * phi, axis=1)[:, None] * self.diag
        return mean, np.sqrt(var)


def alpha_prior(alphas: np.ndarray, min_rel_sigma: float = 0.02) -> tuple[float, float]:
    """Gaussian phase prior (mu, sigma) of the training phases, sigma floored at ``min_rel_sigma * mu``."""
    mu = float(np.mean(alphas))
    sigma = float(np.std(alphas, ddof=1)) if alphas.size > 1 else 0.0
    return mu, max(sigma, min_rel_sigma * mu)


def alpha_candidates(
    priors: list[tuple[float, float]], n_alpha: int, width: float = 3.0
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Phase candidates of every task, as windows of one common uniform lattice.

    Task ``k``'s support is ``mu_k +- width sigma_k`` (kept above ``0.2 mu_k``).
    The lattice spacing gives the narrowest support ``n_alpha`` points; every
    task gets the same number ``C`` of consecutive lattice points covering its
    support (so each support holds at least ``n_alpha`` candidates). Candidates
    shared by several tasks are computed once by the inference engine.

    Returns:
        Per task: candidates (C,) and their normalised log prior weights (C,).
    """
    origin, spacing, n_cand = candidate_lattice(priors, n_alpha, width)
    return [lattice_candidates(origin, spacing, n_cand, prior, width) for prior in priors]


def phase_support(prior: tuple[float, float], width: float) -> tuple[float, float]:
    """A phase prior ``(mu, sigma)``'s candidate support ``mu +- width sigma``, kept above ``0.2 mu``."""
    mu, sd = prior
    return max(mu - width * sd, 0.2 * mu), mu + width * sd


def candidate_lattice(
    priors: list[tuple[float, float]], n_alpha: int, width: float
) -> tuple[float, float, int]:
    """The common lattice of :func:`alpha_candidates`: its origin, spacing and the number ``C`` of
    candidates of every task."""
    lo, hi = (np.array(v) for v in zip(*(phase_support(p, width) for p in priors), strict=True))
    spacing = float(np.min(hi - lo)) / n_alpha  # any interval this long holds >= n_alpha lattice points
    n_cand = int(np.max(np.ceil((hi - lo) / spacing - 1e-9))) + 2
    return float(np.min(lo)), spacing, n_cand


def lattice_candidates(
    origin: float, spacing: float, n_cand: int, prior: tuple[float, float], width: float
) -> tuple[np.ndarray, np.ndarray]:
    """One task's ``n_cand`` candidates on the lattice from its support's start, and their
    normalised log prior weights."""
    mu, sd = prior
    start = int(np.floor((phase_support(prior, width)[0] - origin) / spacing + 1e-9))
    grid = origin + spacing * (start + np.arange(n_cand))
    logp = -0.5 * ((grid - mu) / sd) ** 2
    return grid, logp - np.logaddexp.reduce(logp)


def fit_demo_weights(
    basis: GaussianBasis, t: np.ndarray, values: np.ndarray, valid: np.ndarray | None, source: str, field: str
) -> tuple[np.ndarray, np.ndarray]:
    """Weights (D, K) of one channel group of one demo and its residual sum of squares (D,).

    Args:
        basis: The basis.
        t: (T,) times in [s] from motion start.
        values: (T, D) scaled values.
        valid: (T,) mask of usable samples (None = all).
        source, field: For error messages.
    """
    z = (t - t[0]) / (t[-1] - t[0])
    if valid is not None:
        z, values = z[valid], values[valid]
    if z.size < 2:
        raise DataError(source, field, f"only {z.size} usable samples to fit the basis weights")
    w = basis.fit_weights(z, values)
    resid = values - basis(z) @ w.T
    return w, np.sum(resid * resid, axis=0)
