"""The robot's conditioned weights for many noise ratios at once (for the cross-validations).

The conditioning of :mod:`~ipromp_pin.promp.conditioning` (one latent block, one noise ratio ``nu``)
needs ``X^-1`` with ``X = nu I + G``, ``G = B^T B``. With the eigendecomposition ``G = V diag(l) V^T``
of each observation part (once), every ``nu`` is a diagonal rescaling::

    I - nu X^-1 = V diag(l / (nu + l)) V^T,     X^-1 = V diag(1 / (nu + l)) V^T

so with ``W~_d = V^T W_d`` and ``b~_d = V^T b_d`` (``W_d = F_d / sqrt(delta_d)``,
``b_d = B^T (y_d - B mu_d)``), the latent posterior of every ``nu`` is

    P(nu) = sum_i l_i / (nu + l_i) M_i,   M_i = sum_d W~_d[i]^T W~_d[i]          (r, r)
    a(nu) = sum_i 1 / (nu + l_i) m_i,     m_i = sum_d W~_d[i] b~_d[i] / sqrt(delta_d)   (r,)

(``i`` runs over the eigenvalues of every part): one product per ``nu`` grid instead of one
factorisation of ``X`` per ``nu``. Only the factor columns that load on the robot matter for its
weights (the other latent blocks are independent of them). The result equals
:func:`~ipromp_pin.promp.conditioning.robot_posterior_mean` (the tests hold it to 1e-8).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .basis import GaussianBasis
from .observation import ObservationPart


@dataclass(frozen=True)
class PartSpectrum:
    """Eigendecomposition of ``G = B^T B`` of the observation parts at one phase.

    Attributes:
        values: (I,) the eigenvalues of every part, concatenated.
        proj: Per part, ``V^T`` (ke, ke) restricted to its ``ke`` active basis functions.
        basis_rows: Per part, ``B`` (n, ke).
        ke: Per part, its number of active basis functions.
    """

    values: np.ndarray
    proj: list[np.ndarray]
    basis_rows: list[np.ndarray]
    ke: list[int]


def part_spectrum(basis: GaussianBasis, parts: list[ObservationPart], duration_s: float) -> PartSpectrum:
    """The spectra of the parts observed over a motion of ``duration_s`` [s] (phase ``t / duration``)."""
    values, proj, rows, kes = [], [], [], []
    for p in parts:
        z = np.asarray(p.t, dtype=float) / duration_s
        ke = basis.support_count(float(z[-1]))
        b = basis(z)[:, :ke]
        lam, vec = np.linalg.eigh(b.T @ b)
        values.append(np.maximum(lam, 0.0))
        proj.append(vec.T)
        rows.append(b)
        kes.append(ke)
    return PartSpectrum(np.concatenate(values), proj, rows, kes)


@dataclass(frozen=True)
class RobotPath:
    """The robot's conditioned weights for every noise ratio of a grid.

    Attributes:
        mean: (n_nu, J, K) conditioned mean of the robot weights (scaled units).
        latent_chol: (n_nu, r, r) lower Cholesky factors of the latent precision ``Q`` of the robot's
            factor columns.
        robot_factor: (J, K, r) the robot rows of those columns.
        robot_diag: (J,) the robot's diagonal variances ``delta_j``.
    """

    mean: np.ndarray
    latent_chol: np.ndarray
    robot_factor: np.ndarray
    robot_diag: np.ndarray

    def readout_cov(self, row: np.ndarray) -> np.ndarray:
        """(n_nu, J, J) covariance of ``row . w_j`` over the joints (``row`` (K,): basis values)."""
        g = np.einsum("k,jkr->rj", row, self.robot_factor)  # (r, J)
        if g.shape[0] == 0:
            cov = np.zeros((self.mean.shape[0], g.shape[1], g.shape[1]))
        else:
            h = np.linalg.solve(self.latent_chol, np.broadcast_to(g, (self.mean.shape[0], *g.shape)))
            cov = np.einsum("nrj,nri->nji", h, h)
        idx = np.arange(g.shape[1])
        cov[:, idx, idx] += float(row @ row) * self.robot_diag
        return cov


@dataclass(frozen=True)
class RobotPrior:
    """What the robot's conditioning reads of a weight distribution (built once per distribution,
    for every observation conditioned on it).

    Attributes:
        mean: (D, K) mean weights (scaled units).
        diag: (D,) diagonal variances ``delta_d``.
        factor: (D, K, r) the factor columns that load on the robot (the other latent blocks are
            independent of its weights).
        robot: The robot's dims.
    """

    mean: np.ndarray
    diag: np.ndarray
    factor: np.ndarray
    robot: slice


def robot_prior(mean: np.ndarray, diag: np.ndarray, factor: np.ndarray, robot: slice) -> RobotPrior:
    """The :class:`RobotPrior` of a weight distribution ``mean`` (D, K), ``diag`` (D,), ``factor``
    (D, K, r) whose robot dims are ``robot``."""
    cols = np.flatnonzero(np.any(factor[robot] != 0.0, axis=(0, 1)))
    return RobotPrior(mean, diag, factor[:, :, cols], robot)


def _latent_terms(
    spectrum: PartSpectrum, parts: list[ObservationPart], prior: RobotPrior, projected: list[np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """The stacked ``M_i`` (I, r r) and ``m_i`` (I, r) of ``prior`` (module docstring), from each
    part's projected residuals ``V^T B^T (y - B mu)`` (ke, D_m)."""
    f = prior.factor
    r = f.shape[2]
    m_blocks, a_blocks = [], []
    for p, vt, ke, proj in zip(parts, spectrum.proj, spectrum.ke, projected, strict=True):
        sd = np.sqrt(prior.diag[np.asarray(p.dims)])
        w = vt @ (f[np.asarray(p.dims), :ke] / sd[:, None, None])  # W~_d (D_m, ke, r)
        w = np.ascontiguousarray(w.transpose(1, 0, 2))  # (ke, D_m, r)
        bt = proj / sd[None, :]  # b~_d / sqrt(delta_d) as columns (ke, D_m)
        m_blocks.append(np.matmul(w.transpose(0, 2, 1), w))
        a_blocks.append(np.matmul(bt[:, None, :], w)[:, 0, :])
    return np.concatenate(m_blocks).reshape(spectrum.values.size, r * r), np.concatenate(a_blocks)


def robot_paths(
    spectrum: PartSpectrum, parts: list[ObservationPart], nus: Sequence[float], priors: Sequence[RobotPrior]
) -> list[RobotPath]:
    """Per prior, the robot's weights conditioned on the parts (at the phase of ``spectrum``) for
    every noise ratio of ``nus``. What depends on the observation alone (the ``nu`` weights, the
    projected residuals of equal means) is computed once, and the latent systems of equal rank are
    factorised and solved in one call each (the same LAPACK calls per matrix: the same numbers)."""
    nu = np.asarray(nus, dtype=float)
    lam = spectrum.values
    inv = 1.0 / (nu[:, None] + lam[None, :])  # (n_nu, I)
    inv_lam = inv * lam[None, :]
    qs, rhs = [], []
    mean_seen: np.ndarray | None = None
    projected: list[np.ndarray] = []
    for prior in priors:
        if mean_seen is None or not np.array_equal(prior.mean, mean_seen):
            mean_seen = prior.mean
            projected = [
                vt @ (b.T @ (p.y - b @ prior.mean[np.asarray(p.dims), :ke].T))
                for p, vt, b, ke in zip(parts, spectrum.proj, spectrum.basis_rows, spectrum.ke, strict=True)
            ]
        big_m, big_a = _latent_terms(spectrum, parts, prior, projected)
        r = prior.factor.shape[2]
        q = (inv_lam @ big_m).reshape(nu.size, r, r)
        q[:, np.arange(r), np.arange(r)] += 1.0
        qs.append(q)
        rhs.append((inv @ big_a)[:, :, None])  # (n_nu, r, 1)
    chol: list[np.ndarray] = [np.empty(0)] * len(priors)
    eta: list[np.ndarray] = [np.empty(0)] * len(priors)
    for r in {q.shape[1] for q in qs}:
        same = [i for i, q in enumerate(qs) if q.shape[1] == r]
        q_all = np.concatenate([qs[i] for i in same])
        c_all = np.linalg.cholesky(q_all)
        e_all = np.linalg.solve(q_all, np.concatenate([rhs[i] for i in same]))[:, :, 0]
        for n, i in enumerate(same):
            chol[i] = c_all[n * nu.size : (n + 1) * nu.size]
            eta[i] = e_all[n * nu.size : (n + 1) * nu.size]
    out = []
    for prior, c, e in zip(priors, chol, eta, strict=True):
        fr = prior.factor[prior.robot]
        w_robot = prior.mean[prior.robot][None] + np.einsum("jkr,nr->njk", fr, e)
        out.append(RobotPath(w_robot, c, fr, prior.diag[prior.robot]))
    return out
