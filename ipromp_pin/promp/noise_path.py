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


def robot_path(
    spectrum: PartSpectrum,
    parts: list[ObservationPart],
    robot: slice,
    nus: Sequence[float],
    mean: np.ndarray,
    diag: np.ndarray,
    factor: np.ndarray,
) -> RobotPath:
    """The robot's weights conditioned on the parts (at the phase of ``spectrum``) for every noise
    ratio of ``nus``, from a weight distribution ``mean`` (D, K), ``diag`` (D,), ``factor`` (D, K, r)."""
    nu = np.asarray(nus, dtype=float)
    cols = np.flatnonzero(np.any(factor[robot] != 0.0, axis=(0, 1)))
    f = factor[:, :, cols]
    r = cols.size
    m_blocks, a_blocks = [], []
    for p, vt, b, ke in zip(parts, spectrum.proj, spectrum.basis_rows, spectrum.ke, strict=True):
        dims = np.asarray(p.dims)
        sd = np.sqrt(diag[dims])
        w = vt @ (f[dims, :ke] / sd[:, None, None])  # W~_d (D_m, ke, r)
        w = np.ascontiguousarray(w.transpose(1, 0, 2))  # (ke, D_m, r)
        resid = p.y - b @ mean[dims, :ke].T  # (n, D_m)
        bt = (vt @ (b.T @ resid)) / sd[None, :]  # b~_d / sqrt(delta_d) as columns (ke, D_m)
        m_blocks.append(np.matmul(w.transpose(0, 2, 1), w))
        a_blocks.append(np.matmul(bt[:, None, :], w)[:, 0, :])
    lam = spectrum.values
    big_m = np.concatenate(m_blocks).reshape(lam.size, r * r)
    big_a = np.concatenate(a_blocks)
    inv = 1.0 / (nu[:, None] + lam[None, :])  # (n_nu, I)
    q = ((inv * lam[None, :]) @ big_m).reshape(nu.size, r, r)
    q[:, np.arange(r), np.arange(r)] += 1.0
    chol = np.linalg.cholesky(q)
    a = inv @ big_a  # (n_nu, r)
    eta = np.linalg.solve(q, a[:, :, None])[:, :, 0]
    fr = f[robot]
    w_robot = mean[robot][None] + np.einsum("jkr,nr->njk", fr, eta)
    return RobotPath(mean=w_robot, latent_chol=chol, robot_factor=fr, robot_diag=diag[robot])
