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
(:mod:`ipromp_pin.recognition`). Basis functions that are below 1e-13 on every
observed phase are dropped (their contribution is below rounding).

Phase candidates: ``n_alpha`` (default 60) phases over ``mu +- 3 sigma`` of the
task's phase prior; the MAP candidate is refined by a parabola through the log
posterior at it and its two neighbours.
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
class CandidateTerms:
    """Per-candidate results of :func:`candidate_terms`.

    Attributes:
        loglik: (C,) log marginal likelihood of the observation (-inf where the
            observation would extend past the end of the motion).
        q_chol: (C, r, r) lower Cholesky factor of ``Q`` (None unless asked).
        a: (C, r) vector ``a`` (None unless asked).
        parts: Per observation part, (ke, X Cholesky (C, ke, ke), b (C, ke, D_m)) (None unless asked).
    """

    loglik: np.ndarray
    q_chol: np.ndarray | None = None
    a: np.ndarray | None = None
    parts: list | None = None


def _chol_solve(chol: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve ``L L^T x = rhs`` for batched lower factors (C, m, m) and rhs (C, m, q)."""
    y = np.linalg.solve(chol, rhs)
    return np.linalg.solve(np.swapaxes(chol, -1, -2), y)


def candidate_terms(
    basis: GaussianBasis,
    task: TaskModel,
    parts: list[ObservationPart],
    alphas: np.ndarray,
    t_norm: float,
    nu: float,
    keep: bool = False,
) -> CandidateTerms:
    """Exact log marginal likelihood of an observation for every phase candidate of one task.

    Args:
        basis: Basis of the model.
        task: Task model (scaled units).
        parts: Observed samples.
        alphas: (C,) phase candidates.
        t_norm: Nominal duration in [s].
        nu: Noise ratio ``r_d / delta_d``.
        keep: Also return ``Q``'s factor, ``a`` and the per-part factors (for conditioning).
    """
    alphas = np.asarray(alphas, dtype=float)
    n_cand = alphas.size
    r = task.rank
    big_p = np.zeros((n_cand, r, r))
    a = np.zeros((n_cand, r))
    const = 0.0
    logdet = np.zeros(n_cand)
    quad = np.zeros(n_cand)
    t_last = max(float(p.t[-1]) for p in parts)
    kept = []
    for part in parts:
        n = part.t.size
        dims = part.dims
        dm = dims.size
        z = part.t[None, :] / (alphas[:, None] * t_norm)  # (C, n)
        ke = basis.support_count(float(z.max()))
        b_mat = basis(z)[..., :ke]  # (C, n, ke)
        gram = np.einsum("cnk,cnl->ckl", b_mat, b_mat)
        h = np.einsum("cnk,nd->ckd", b_mat, part.y)
        mu = task.mean[dims, :ke]  # (dm, ke)
        delta = task.diag[dims]
        sqd = np.sqrt(delta)
        w = task.factor[dims, :ke, :] / sqd[:, None, None]  # (dm, ke, r)
        gmu = np.einsum("ckl,dl->ckd", gram, mu)
        b = h - gmu  # (C, ke, dm)
        ete = np.sum(part.y * part.y, axis=0)[None, :] - 2.0 * np.einsum("dk,ckd->cd", mu, h)
        ete = ete + np.einsum("dk,ckd->cd", mu, gmu)
        x = gram + nu * np.eye(ke)
        chol = np.linalg.cholesky(x)
        bh = b / sqd  # (C, ke, dm)
        rhs = np.concatenate(
            [np.broadcast_to(w.transpose(1, 0, 2).reshape(ke, dm * r), (n_cand, ke, dm * r)), bh], axis=2
        )
        sol = _chol_solve(chol, rhs)
        xw = sol[:, :, : dm * r].reshape(n_cand, ke, dm, r)
        xb = sol[:, :, dm * r :]  # (C, ke, dm)
        wtw = np.einsum("dkr,dks->rs", w, w)
        big_p += wtw - nu * np.einsum("dkr,ckds->crs", w, xw)
        a += np.einsum("dkr,ckd->cr", w, xb)
        logdet_x = 2.0 * np.sum(np.log(np.diagonal(chol, axis1=1, axis2=2)), axis=1)
        const += n * dm * LOG_2PI + n * float(np.sum(np.log(delta))) + dm * (n - ke) * np.log(nu)
        logdet += dm * logdet_x
        quad += np.sum(ete / (nu * delta), axis=1) - np.einsum("ckd,ckd->c", bh, xb) / nu
        if keep:
            kept.append((ke, chol, b))
    q = big_p + np.eye(r)
    q_chol = np.linalg.cholesky(q) if r else np.zeros((n_cand, 0, 0))
    if r:
        v = np.linalg.solve(q_chol, a[:, :, None])[:, :, 0]
        logdet_q = 2.0 * np.sum(np.log(np.diagonal(q_chol, axis1=1, axis2=2)), axis=1)
        quad_q = np.sum(v * v, axis=1)
    else:
        logdet_q = quad_q = np.zeros(n_cand)
    loglik = -0.5 * (const + logdet + logdet_q + quad - quad_q)
    loglik = np.where(t_last <= alphas * t_norm * (1.0 + 1e-12), loglik, -np.inf)
    if keep:
        return CandidateTerms(loglik=loglik, q_chol=q_chol, a=a, parts=kept)
    return CandidateTerms(loglik=loglik)


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
