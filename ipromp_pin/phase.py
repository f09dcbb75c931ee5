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

Making it fast (:class:`InferenceEngine`):

* ``P`` is linear in ``X^-1``: ``P = sum_{k<=l} (delta_kl - nu X^-1_kl) Z[(k,l), :]``
  with ``Z[(k,l), (a,b)] = sum_d W_dka W_dlb`` (symmetrised, packed, precomputed
  per task), so P of all candidates of a task is ONE matrix product.
  ``X^-1`` and ``log|X|`` come from one batched Cholesky factorisation of the
  augmented SPD matrix ``[[X, I], [I, c I]]`` (``c = 2 / nu + 1``), whose
  lower-left block is ``L^-T``; ``X`` is well conditioned (eigenvalues in
  ``[nu, nu + ||G||]``), and the result is checked against the dense Cholesky
  reference to 1e-8 by the tests.
* ``a^T Q^-1 a`` and ``log|Q|`` come from one batched Cholesky of ``Q``
  augmented with ``a`` (its last row holds ``L_Q^-1 a``).
* All tasks' candidates lie on one common lattice (:func:`ipromp_pin.model.alpha_candidates`):
  everything that depends only on the candidate (basis matrix, ``G``,
  ``B^T y``, ``X^-1``) is computed once per distinct candidate.
* Basis functions below 1e-11 on every observed phase are dropped (their
  contribution is below 1e-20 relative); the basis is evaluated with two
  exponentials per sample (:meth:`GaussianBasis.values_prefix_t`).
* Streaming: ``G``, ``B^T y`` and ``y^T y`` are running sums (one basis row per
  candidate per new sample).

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
from .model import TaskModel

LOG_2PI = float(np.log(2.0 * np.pi))


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
        gram: (U, ke, ke) ``B^T B`` per unique candidate.
        proj: (U, ke, D_m) ``B^T y``.
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
        q_chol: (T, C, r, r) lower Cholesky factor of ``Q`` (only with ``keep``).
        a: (T, C, r) vector ``a`` (only with ``keep``).
        parts: Per part (dims, ke, X^-1 (T, C, ke, ke), G (T, C, ke, ke), b (T, C, ke, D_m))
            (only with ``keep``).
    """

    loglik: np.ndarray
    q_chol: np.ndarray | None = None
    a: np.ndarray | None = None
    parts: list | None = None


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
        self.pk, self.pl = np.array(pk), np.array(pl)
        self.pair_diag = (self.pk == self.pl).astype(float)
        ia, ib = np.triu_indices(r)
        self.ia, self.ib = ia, ib
        unpack = np.zeros((r, r), dtype=int)
        unpack[ia, ib] = np.arange(ia.size)
        unpack[ib, ia] = np.arange(ia.size)
        self.unpack = unpack
        self.use_z = n_task * self.pk.size * ia.size * 8 <= z_budget_bytes
        self._z: dict[tuple[int, ...], np.ndarray] = {}
        self._buffers: dict[str, np.ndarray] = {}

    def _buffer(self, name: str, shape: tuple[int, ...]) -> np.ndarray:
        """A reusable work array (avoids page faults of fresh large allocations on every call)."""
        buf = self._buffers.get(name)
        if buf is None or buf.shape != shape:
            buf = self._buffers[name] = np.empty(shape)
        return buf

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

    def part_stats(self, part: ObservationPart, alphas: np.ndarray | None = None) -> PartStats:
        """Statistics of an observation part for the unique candidates (default: the model's)."""
        alphas = self.alpha_unique if alphas is None else alphas
        z = part.t[None, :] / (alphas[:, None] * self.t_norm)
        ke = self.basis.support_count(float(z.max()))
        bt = np.swapaxes(self.basis.values_prefix_t(z, ke), 0, 1)  # (U, ke, n)
        gram = bt @ np.swapaxes(bt, 1, 2)
        proj = bt @ part.y
        return PartStats(part.dims, part.t.size, ke, gram, proj, np.sum(part.y * part.y, axis=0))

    def terms(
        self,
        stats: list[PartStats],
        t_last: float,
        tasks: np.ndarray | None = None,
        alphas: np.ndarray | None = None,
        index: np.ndarray | None = None,
        keep: bool = False,
        nu: float | None = None,
    ) -> Terms:
        """Log likelihood per (task, candidate) from part statistics.

        Args:
            stats: Part statistics (computed for the unique candidates ``alphas``).
            t_last: Time of the last observed sample in [s].
            tasks: Task indices (default all).
            alphas: (T', C) candidates (default the model's grids).
            index: (T', C) index of each candidate in the unique candidates of ``stats``.
            keep: Also return the factors needed for conditioning.
            nu: Noise ratio (default the engine's).
        """
        nu = self.nu if nu is None else float(nu)
        if tasks is None:
            tasks, alphas, index = slice(None), self.alphas, self.cand_index
        mu_all, sd_all, w_all = self.mu[tasks], self.sqrt_delta[tasks], self.w[tasks]
        delta_all = self.delta[tasks]
        n_task, n_cand = alphas.shape
        r = self.rank
        p_packed = np.zeros((n_task, n_cand, self.ia.size))
        a = np.zeros((n_task, n_cand, r))
        total = np.zeros((n_task, n_cand))
        kept = []
        for st in stats:
            ke, dims = st.ke, st.dims
            dm = dims.size
            n_u = st.gram.shape[0]
            aug = self._buffer("aug", (n_u, 2 * ke, 2 * ke))
            diag_idx = np.arange(ke)
            aug[:, :ke, :ke] = st.gram
            aug[:, diag_idx, diag_idx] += nu
            aug[:, ke:, :ke] = 0.0
            aug[:, ke:, ke:] = 0.0
            aug[:, ke + diag_idx, diag_idx] = 1.0
            aug[:, ke + diag_idx, ke + diag_idx] = 2.0 / nu + 1.0
            chol = np.linalg.cholesky(aug)
            lit = np.ascontiguousarray(chol[:, ke:, :ke])  # L^-T
            xinv_u = lit @ np.swapaxes(lit, 1, 2)
            logdet_x = 2.0 * np.sum(np.log(chol[:, diag_idx, diag_idx]), axis=1)
            xinv = xinv_u[index]  # (T, C, ke, ke)
            gram = st.gram[index]
            proj = st.proj[index]  # (T, C, ke, dm)
            mu_t = np.swapaxes(mu_all[:, dims, :ke], 1, 2)[:, None]  # (T, 1, ke, dm)
            gmu = gram @ mu_t  # (T, C, ke, dm)
            b = proj - gmu
            ete = st.sq - np.einsum("tcdk,tcdk->tcd", np.swapaxes(proj + b, 2, 3), np.swapaxes(mu_t, 2, 3))
            bh = b / sd_all[:, None, None, dims]
            xb = xinv @ bh
            total += (np.sum(ete / delta_all[:, None, dims], axis=2) - np.sum(bh * xb, axis=(2, 3))) / nu
            w = w_all[:, dims, :ke].reshape(n_task, dm * ke, r)
            a += np.swapaxes(xb, 2, 3).reshape(n_task, n_cand, dm * ke) @ w
            m = ke * (ke + 1) // 2
            if self.use_z and isinstance(tasks, slice):
                coef_u = self.pair_diag[:m] - nu * xinv_u[:, self.pk[:m], self.pl[:m]]
                p_packed += coef_u[index] @ self.z_tensor(dims)[:, :m]
            else:
                wk = w_all[:, dims, :ke]  # (T, dm, ke, r)
                y = xinv @ np.swapaxes(wk, 1, 2).reshape(n_task, 1, ke, dm * r)  # (T, C, ke, dm*r)
                y = np.swapaxes(y.reshape(n_task, n_cand, ke, dm, r), 2, 3).reshape(
                    n_task, n_cand, dm * ke, r
                )
                pp = np.swapaxes(w, 1, 2)[:, None] @ (w[:, None] - nu * y)
                p_packed += pp[..., self.ia, self.ib]
            const = st.n * dm * LOG_2PI + dm * (st.n - ke) * np.log(nu)
            total += const + st.n * np.sum(np.log(delta_all[:, dims]), axis=1)[:, None]
            total += dm * logdet_x[index]
            if keep:
                kept.append((dims, ke, xinv, gram, b))
        qa = self._buffer("qa", (n_task, n_cand, r + 1, r + 1))
        qa[..., :r, :r] = np.take(p_packed, self.unpack, axis=2)
        qa[..., np.arange(r), np.arange(r)] += 1.0
        qa[..., r, :r] = a
        qa[..., :r, r] = a
        qa[..., r, r] = np.sum(a * a, axis=2) + 1.0
        lq = np.linalg.cholesky(qa)
        diag = np.diagonal(lq, axis1=2, axis2=3)
        v = lq[..., r, :r]
        total += 2.0 * np.sum(np.log(diag[..., :r]), axis=2) - np.sum(v * v, axis=2)
        loglik = -0.5 * total
        loglik = np.where(t_last <= alphas * self.t_norm * (1.0 + 1e-12), loglik, -np.inf)
        if keep:
            return Terms(loglik=loglik, q_chol=lq[..., :r, :r], a=a, parts=kept)
        return Terms(loglik=loglik)


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
