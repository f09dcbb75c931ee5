"""Phase (alpha) estimation: exact Gaussian likelihood of a partial observation per phase candidate.

Model (scaled units, one task). Observed channel ``d`` sampled at times ``t_j``
is ``y_dj = phi(z_j)^T w_d + eps``, ``z_j = t_j / (alpha T_norm)``,
``eps ~ N(0, r_d)``, ``w ~ N(mu, Sigma)`` with the structured covariance
``Sigma = blockdiag(delta_d I_K) + F F^T`` and ``r_d = nu delta_d`` (see
:mod:`ipromp_pin.model`). For one candidate let ``B`` (n, K) be the basis
matrix of the observed phases, ``G = B^T B`` and ``X = nu I + G``. Writing
``W_d = F_d / sqrt(delta_d)`` and ``b_d = B^T (y_d - B mu_d)``, the textbook
marginal likelihood ``N(y; Phi mu, Phi Sigma Phi^T + R)`` (Phi = block-diagonal
over channels) equals, by the Woodbury identity and the matrix determinant
lemma applied twice (first to the per-channel part, then to the rank-r part)::

    P   = sum_d W_d^T (I - nu X^-1) W_d              (r, r)
    a   = sum_d W_d^T X^-1 b_d / sqrt(delta_d)       (r,)
    Q   = I + P
    log p(y) = -1/2 [ n_y log 2 pi + sum_d (n log delta_d + (n - K) log nu + log|X|)
                      + log|Q| + sum_d (e_d^T e_d - b_d^T X^-1 b_d) / (nu delta_d)
                      - a^T Q^-1 a ]

so a candidate costs one K x K and one r x r Cholesky factorisation, shared by
all channels, instead of one (n D) x (n D) factorisation. The latent
coordinates ``eta`` of ``w = mu + F eta + ...`` have the posterior
``N(Q^-1 a, Q^-1)``, which gives the conditioned robot weights directly
(:mod:`ipromp_pin.recognition`); the robot's posterior weight covariance is
``blockdiag(delta_j I) + F_r Q^-1 F_r^T``.

Making it fast (:class:`InferenceEngine`, compiled numba kernels in :mod:`ipromp_pin.kernels`):

* ``P`` is linear in ``X^-1``: ``P = sum_{k<=l} (delta_kl - nu X^-1_kl) Z[(k,l), :]``
  with ``Z[(k,l), (a,b)] = sum_d W_dka W_dlb`` (symmetrised, packed, precomputed
  per task), so P of all candidates of a task is ONE matrix product (BLAS).
  ``X^-1`` and ``log|X|`` come from one Cholesky factorisation per distinct
  candidate (``X`` is well conditioned: eigenvalues in ``[nu, nu + ||G||]``);
  the tests check the result against the dense textbook likelihood to 1e-8.
* ``a^T Q^-1 a`` and ``log|Q|`` come from one Cholesky factorisation of ``Q``
  per (task, candidate). The small factorisations run batched with the
  candidate index innermost (every step is a vector operation over candidates,
  exact IEEE arithmetic, no fast-math).
* All tasks' candidates lie on one common lattice (:func:`ipromp_pin.model.alpha_candidates`):
  everything that depends only on the candidate (basis matrix, ``G``,
  ``B^T y``, ``X^-1``) is computed once per distinct candidate.
* Basis functions below 1e-11 on every observed phase are dropped (their
  contribution is below 1e-20 relative); the basis is evaluated with two
  exponentials per sample (the running product of :meth:`GaussianBasis.values_prefix_t`),
  and ``G = B^T B`` from 2K - 1 sums instead of K (K + 1) / 2, because with uniform
  centres the product of two bumps depends on ``k - l`` and ``k + l`` only
  (:meth:`GaussianBasis.gram_factors`).
* Every task's candidates are consecutive unique candidates, so the per-task work
  runs on contiguous windows; ``X^-1 B^T y`` is computed once per unique candidate
  and ``X^-1 mu`` of every task in one matrix product.
* Streaming: ``G``, ``B^T y`` and ``y^T y`` are running sums (one basis row per
  candidate per new sample).
* The kernels compile on the first inference of a process (importing the package
  does not import numba) and are cached on disk next to the module.

Cost per update: O(T C (K_e^2 r^2 / 4 + r^3 / 3 + K_e D r)) for T tasks, C
candidates, K_e active basis functions, D observed dims, rank r = N - 1: linear
in tasks and candidates.

Phase candidates: at least ``n_alpha`` (default 50) phases inside ``mu +- 3 sigma``
of every task's phase prior; the MAP candidate is refined by a parabola through
the log posterior at it and its two neighbours.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .basis import GaussianBasis
from .exceptions import ModelError
from .model import TaskModel

LOG_2PI = float(np.log(2.0 * np.pi))

PAIR_LANES = 16
"""The (task, candidate) pair arrays are padded to a multiple of this many lanes (whole vector loops)."""


def _kernels():
    """The compiled kernels module (imports numba and compiles / loads cached code on first use)."""
    from . import kernels

    return kernels


@dataclass
class ObservationPart:
    """Scaled samples of observed channels that share their sample times.

    Attributes:
        t: (n,) sample times in [s] from motion start.
        dims: (D_m,) indices of these channels among the model's dims.
        y: (n, D_m) scaled values.
    """

    t: np.ndarray
    dims: np.ndarray
    y: np.ndarray


@dataclass
class PartStats:
    """Sufficient statistics of one observation part for every unique phase candidate.

    Attributes:
        dims: (D_m,) observed dims of the part.
        n: Number of samples.
        ke: Number of leading basis functions used.
        gram: (ke, ke, U) ``B^T B`` per unique candidate (candidate index last; may hold more
            than ``ke`` basis functions, only the first ``ke`` are used).
        proj: (ke, U, D_m) ``B^T y``.
        sq: (D_m,) ``y^T y`` per dim.
    """

    dims: np.ndarray
    n: int
    ke: int
    gram: np.ndarray
    proj: np.ndarray
    sq: np.ndarray


@dataclass
class Terms:
    """Per (task, candidate) results of :meth:`InferenceEngine.terms`.

    Attributes:
        loglik: (T, C) log marginal likelihood (-inf where the observation would
            extend past the end of the motion).
    """

    loglik: np.ndarray


class InferenceEngine:
    """Exact batched likelihood of an observation for every task and phase candidate.

    Everything that depends only on the model is precomputed here: stacked task
    means, scaled low-rank factors ``W = F / sqrt(delta)`` and, when it fits in
    ``z_budget_bytes``, the tensor ``Z[(k, l), (a, b)] = sum_d W_dka W_dlb``
    (symmetrised and packed) that turns ``P = sum_d W_d^T (I - nu X^-1) W_d``
    into one matrix product per task. The per-candidate quantities that depend
    only on the candidate's phase (basis matrix, ``X = nu I + G``, its inverse
    and log-determinant from one Cholesky factorisation of the augmented
    matrix ``[[X, I], [I, c I]]``) are computed once per unique candidate and
    shared by all tasks whose grids contain it.

    Args:
        basis: Model basis.
        models: Task models (all with the same number of candidates).
        n_obs: Number of observed dims D_o (the first dims of every model).
        t_norm: Nominal duration in [s].
        nu: Noise ratio.
        z_budget_bytes: Largest size of the precomputed ``Z`` tensors.
    """

    def __init__(
        self,
        basis: GaussianBasis,
        models: list[TaskModel],
        n_obs: int,
        t_norm: float,
        nu: float,
        z_budget_bytes: float = 64e6,
    ) -> None:
        self.basis = basis
        self.t_norm = float(t_norm)
        self.nu = float(nu)
        self.n_obs = int(n_obs)
        grids = [m.alpha_grid for m in models]
        if len({g.size for g in grids}) != 1:
            raise ValueError("all tasks need the same number of phase candidates")
        self.alphas = np.stack(grids)
        self.log_prior = np.stack([m.alpha_log_prior for m in models])
        self.alpha_unique, inverse = np.unique(self.alphas, return_inverse=True)
        self.cand_index = inverse.reshape(self.alphas.shape)
        self.inv_duration = 1.0 / (self.alpha_unique * self.t_norm)
        n_task = len(models)
        k = basis.n_basis
        self.rank = r = max(m.rank for m in models)
        self.mu = np.stack([m.mean[:n_obs] for m in models])  # (T, D, K)
        self.delta = np.stack([m.diag[:n_obs] for m in models])  # (T, D)
        self.sqrt_delta = np.sqrt(self.delta)
        self.w = np.zeros((n_task, n_obs, k, r))
        for i, m in enumerate(models):
            self.w[i, :, :, : m.rank] = m.factor[:n_obs] / self.sqrt_delta[i][:, None, None]
        pk, pl = [], []
        for ll in range(k):
            for kk in range(ll + 1):
                pk.append(kk)
                pl.append(ll)
        self.pk, self.pl = np.array(pk, dtype=np.int64), np.array(pl, dtype=np.int64)
        ia, ib = np.triu_indices(r)
        self.ia, self.ib = ia, ib
        npk = ia.size
        # index of Q[i, j] in the packed upper triangle
        unpack = np.zeros((r, r), dtype=np.int64)
        unpack[ia, ib] = np.arange(npk)
        unpack[ib, ia] = np.arange(npk)
        self.unpack = unpack
        # every task's candidates are consecutive lattice points, hence consecutive unique candidates
        self.starts = np.ascontiguousarray(self.cand_index[:, 0], dtype=np.int64)
        if not np.array_equal(self.cand_index, self.starts[:, None] + np.arange(self.alphas.shape[1])):
            raise ValueError("every task's phase candidates must be consecutive points of one lattice")
        self._no_z = np.zeros((1, 1, 1))
        self.use_z = n_task * self.pk.size * ia.size * 8 <= z_budget_bytes
        self._z: dict[tuple[int, ...], np.ndarray] = {}
        self._dims_cache: dict[tuple[int, ...], dict[str, np.ndarray]] = {}

    def z_tensor(self, dims: np.ndarray) -> np.ndarray:
        """Packed ``Z`` (T, K(K+1)/2, r(r+1)/2) of the observed dims ``dims`` (cached)."""
        key = tuple(int(d) for d in dims)
        z = self._z.get(key)
        if z is None:
            w = self.w[:, dims]
            n_task, dm, k, r = w.shape
            flat = w.reshape(n_task, dm, k * r)
            full = (np.swapaxes(flat, 1, 2) @ flat).reshape(n_task, k, r, k, r).transpose(0, 1, 3, 2, 4)
            z = full[:, self.pk, self.pl][:, :, self.ia, self.ib]
            off = self.pk != self.pl
            z[:, off] += full[:, self.pl[off], self.pk[off]][:, :, self.ia, self.ib]
            self._z[key] = z = np.ascontiguousarray(z)
        return z

    def _dims(self, dims: np.ndarray) -> dict[str, np.ndarray]:
        """Model arrays of the observed dims ``dims`` in basis-major layouts (cached).

        ``mu_k`` (T, K, D_m) task means; ``w_k`` (T, K D_m, r) ``W_d / sqrt(delta_d)`` with rows
        ordered (basis, dim), so that the first ``ke D_m`` rows are the first ``ke`` basis functions;
        ``mu2`` (T, K) cumulative ``sum_d ||mu_d[:k]||^2 / delta_d``; ``inv_delta`` (T, D_m);
        ``log_delta`` (T,) ``sum_d log delta_d``; ``mu_rows`` (T D_m, K) the means with rows (task, dim);
        ``w_1`` (T, K D_m, r) ``W_d`` with rows (basis, dim); ``w_t`` (T, K, r, D_m) ``W_d`` ordered
        (basis, latent, dim).
        """
        key = tuple(int(d) for d in dims)
        c = self._dims_cache.get(key)
        if c is None:
            mu = self.mu[:, dims]  # (T, Dm, K)
            delta = self.delta[:, dims]
            n_task, dm, k = mu.shape
            w_k = (self.w[:, dims] / self.sqrt_delta[:, dims, None, None]).transpose(0, 2, 1, 3)
            c = {
                "mu_k": np.ascontiguousarray(mu.transpose(0, 2, 1)),
                "mu_rows": np.ascontiguousarray(mu.reshape(n_task * dm, k)),
                "w_k": np.ascontiguousarray(w_k.reshape(n_task, k * dm, self.rank)),
                "w_1": np.ascontiguousarray(
                    self.w[:, dims].transpose(0, 2, 1, 3).reshape(n_task, k * dm, -1)
                ),
                "w_t": np.ascontiguousarray(self.w[:, dims].transpose(0, 2, 3, 1)),
                "mu2": np.ascontiguousarray(
                    np.concatenate(
                        [
                            np.zeros((n_task, 1)),
                            np.cumsum(np.einsum("tdk,td->tk", mu * mu, 1.0 / delta), axis=1),
                        ],
                        axis=1,
                    )
                ),
                "inv_delta": np.ascontiguousarray(1.0 / delta),
                "log_delta": np.ascontiguousarray(np.sum(np.log(delta), axis=1)),
            }
            self._dims_cache[key] = c
        return c

    def part_stats(self, part: ObservationPart, alphas: np.ndarray | None = None) -> PartStats:
        """Statistics of an observation part for the unique candidates (default: the model's)."""
        inv_dur = self.inv_duration if alphas is None else 1.0 / (alphas * self.t_norm)
        z = part.t[:, None] * inv_dur[None, :]  # (n, U)
        ke = self.basis.support_count(float(part.t[-1]) * float(inv_dur.max()))
        y = np.ascontiguousarray(part.y, dtype=float)
        b = self.basis
        inv_h2 = 1.0 / (b.width * b.width)
        d0 = z - b.centres[0]
        if ke < 3 or float(np.max(np.abs(d0))) ** 2 * inv_h2 > 650.0:
            # exact exponentials where the running product could underflow (see values_prefix_t)
            bt = np.moveaxis(b(z)[..., :ke], -1, 0)  # (ke, n, U)
            gram = np.ascontiguousarray(np.einsum("knu,lnu->klu", bt, bt))
            proj = np.ascontiguousarray(np.einsum("knu,nd->kud", bt, y))
        else:
            e0 = np.exp(-0.5 * inv_h2 * d0 * d0)
            q = np.exp(z * (b.spacing * inv_h2))
            pair_step, overlap = b.gram_factors()
            gram, proj = _kernels().part_stats(e0, q, b._step_factor, pair_step, overlap, ke, y)
        return PartStats(part.dims, part.t.size, ke, gram, proj, np.einsum("nd,nd->d", part.y, part.y))

    def x_inverse(self, gram: np.ndarray, nu: float, ke: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``X^-1`` (U, ke, ke) and ``log|X|`` (U,) of ``X = nu I + gram[:ke, :ke]``, ``gram`` (K', K', U)."""
        kern = _kernels()
        gram = np.ascontiguousarray(gram, dtype=float)
        ke = gram.shape[0] if ke is None else int(ke)
        xinv = np.empty((ke, ke, gram.shape[2]))
        logdet = kern.x_inverse(gram, ke, float(nu), xinv, np.empty_like(xinv))
        if not np.all(np.isfinite(logdet)):
            raise ModelError("X = nu I + B^T B is not numerically positive definite")
        return np.moveaxis(xinv, 2, 0), logdet

    def terms(self, stats: list[PartStats], t_last: float, nu: float | None = None) -> Terms:
        """Log likelihood per (task, candidate) from part statistics (compiled kernels).

        Per part, with ``h_d = B^T y_d + nu mu_d`` the data terms reduce to
        ``e_d^T e_d - b_d^T X^-1 b_d = y_d^T y_d + nu ||mu_d||^2 - h_d^T X^-1 h_d`` and
        ``X^-1 b_d = X^-1 h_d - mu_d``; ``X^-1`` comes from one Cholesky factorisation per
        unique candidate, ``P`` from one product with ``Z`` per task, and ``log|Q|``,
        ``a^T Q^-1 a`` from one Cholesky factorisation per (task, candidate).

        Args:
            stats: Part statistics for the unique candidates (``gram`` and ``proj`` may hold more
                than ``ke`` basis functions, only the first ``ke`` are used).
            t_last: Time of the last observed sample in [s].
            nu: Noise ratio (default the engine's).
        """
        nu = self.nu if nu is None else float(nu)
        total, a, pq = self.pair_terms(stats, nu)
        loglik = np.empty(self.alphas.shape)
        kern = _kernels()
        if not kern.finish_soa(pq, a, total, self.unpack, self.alphas, self.t_norm, float(t_last), loglik):
            raise ModelError("Q = I + P is not numerically positive definite")
        return Terms(loglik=loglik)

    def pair_terms(self, stats: list[PartStats], nu: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Terms of every (task, candidate) pair, pairs task-major and innermost: the scalar terms
        (P',), ``a`` (r, P') and packed ``P`` (r(r+1)/2, P'), ``P' >= T C`` padded with zeros."""
        kern = _kernels()
        n_task, n_cand = self.alphas.shape
        n_pair = -(-n_task * n_cand // PAIR_LANES) * PAIR_LANES  # padded: see kernels.finish_soa
        total = np.zeros(n_pair)
        a = np.zeros((self.rank, n_pair))
        pq = np.zeros((self.ia.size, n_pair))
        for st in stats:
            c = self._dims(st.dims)
            z = self.z_tensor(st.dims) if self.use_z else self._no_z
            ok = kern.part_terms(
                st.gram, st.proj, st.sq, st.n, st.ke, nu, self.starts, n_cand, c["mu_k"], c["mu_rows"],
                c["inv_delta"], c["mu2"], c["log_delta"], c["w_k"], c["w_1"], z, self.pk, self.pl,
                self.unpack, self.use_z, total, a, pq,
            )  # fmt: skip
            if not ok:
                raise ModelError("X = nu I + B^T B is not numerically positive definite")
        return total, a, pq


class IncrementalTerms:
    """Log likelihood of a growing observation, updated sample by sample (streaming).

    Holds per unique candidate ``X^-1`` and ``log|X|`` and per (task, candidate) the terms of
    :meth:`InferenceEngine.terms` (``P``, ``a`` and the scalar terms) for ONE observation part with
    every observed dim; :meth:`reset` computes them from part statistics, :meth:`add` adds one sample
    with the same active basis functions exactly (Sherman-Morrison update of ``X^-1``, rank-D update
    of ``P``, see :func:`ipromp_pin.kernels.stream_step`); ``log|Q|`` and ``a^T Q^-1 a`` are
    recomputed from ``Q`` on every call.

    Args:
        engine: The model's inference engine.
    """

    def __init__(self, engine: InferenceEngine) -> None:
        self.engine = engine
        self._kern = _kernels()
        self.ke = -1
        self.dims = np.arange(engine.n_obs)
        self._c = engine._dims(self.dims)

    def reset(self, stats: PartStats, t_last: float) -> np.ndarray:
        """Terms from part statistics ``stats`` (all observed dims) -> log likelihood (T, C)."""
        e = self.engine
        kern = self._kern
        ke = stats.ke
        gram = np.ascontiguousarray(stats.gram)
        self.xinv = np.empty((ke, ke, gram.shape[2]))
        self.logdet = kern.x_inverse(gram, ke, e.nu, self.xinv, np.empty_like(self.xinv))
        if not np.all(np.isfinite(self.logdet)):
            raise ModelError("X = nu I + B^T B is not numerically positive definite")
        self.total, self.a, self.pq = e.pair_terms([stats], e.nu)
        self.ke = ke
        return self._finish(t_last)

    def add(self, phi: np.ndarray, y: np.ndarray, proj: np.ndarray, t_last: float) -> np.ndarray:
        """Add one sample: basis values ``phi`` (K, U), scaled values ``y`` (D,), ``proj`` (K, U, D)
        already including it -> log likelihood (T, C)."""
        e = self.engine
        c = self._c
        ok = self._kern.stream_step(
            self.xinv, self.logdet, phi, y, proj, e.nu, e.starts, e.alphas.shape[1], c["mu_k"],
            c["inv_delta"], c["log_delta"], c["w_t"], e.ia, e.ib, self.total, self.a, self.pq,
        )  # fmt: skip
        if not ok:
            self.ke = -1  # partly updated: rebuilt by the next reset
            raise ModelError("X = nu I + B^T B is not numerically positive definite")
        return self._finish(t_last)

    def _finish(self, t_last: float) -> np.ndarray:
        e = self.engine
        loglik = np.empty(e.alphas.shape)
        if not self._kern.finish_soa(
            self.pq, self.a, self.total, e.unpack, e.alphas, e.t_norm, float(t_last), loglik
        ):
            raise ModelError("Q = I + P is not numerically positive definite")
        return loglik


def refine_peaks(grids: np.ndarray, logpost: np.ndarray) -> np.ndarray:
    """:func:`refine_peak` of every row of ``logpost`` (T, C) on ``grids`` (T, C), vectorised -> (T,)."""
    n_task, n_cand = grids.shape
    rows = np.arange(n_task)
    i = np.argmax(logpost, axis=1)
    j = np.clip(i, 1, n_cand - 2)
    x0, x1, x2 = grids[rows, j - 1], grids[rows, j], grids[rows, j + 1]
    y0, y1, y2 = logpost[rows, j - 1], logpost[rows, j], logpost[rows, j + 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        denom = (x0 - x1) * (x0 - x2) * (x1 - x2)
        ca = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / denom
        cb = (x2 * x2 * (y0 - y1) + x1 * x1 * (y2 - y0) + x0 * x0 * (y1 - y2)) / denom
        vertex = np.minimum(np.maximum(-cb / (2.0 * ca), x0), x2)
    ok = (i == j) & np.isfinite(y0) & np.isfinite(y1) & np.isfinite(y2) & (ca < 0.0)
    return np.where(ok, vertex, grids[rows, i])


def refine_peak(grid: np.ndarray, logpost: np.ndarray) -> float:
    """Phase at the maximum of a log posterior sampled on ``grid``, refined by a parabola.

    The parabola goes through the best candidate and its two neighbours; its vertex is
    kept inside the neighbours' interval. At the grid's edge (or next to an impossible
    candidate) the best candidate itself is returned.
    """
    i = int(np.argmax(logpost))
    if i == 0 or i == grid.size - 1:
        return float(grid[i])
    x0, x1, x2 = grid[i - 1 : i + 2]
    y0, y1, y2 = logpost[i - 1 : i + 2]
    if not np.all(np.isfinite([y0, y1, y2])):
        return float(x1)
    denom = (x0 - x1) * (x0 - x2) * (x1 - x2)
    ca = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / denom
    cb = (x2 * x2 * (y0 - y1) + x1 * x1 * (y2 - y0) + x0 * x0 * (y1 - y2)) / denom
    if not ca < 0.0:
        return float(x1)
    return float(np.clip(-cb / (2.0 * ca), x0, x2))


def log_prior_density(alpha: np.ndarray | float, mu: float, sigma: float) -> np.ndarray:
    """Log density of the Gaussian phase prior (up to a constant)."""
    return -0.5 * ((np.asarray(alpha, dtype=float) - mu) / sigma) ** 2
