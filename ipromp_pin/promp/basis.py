"""Gaussian basis functions of the phase z in [0, 1].

Every channel of a demonstration is represented as a weighted sum of ``K``
Gaussian bumps of the phase ``z = t / T`` (``T`` = duration of the demo in [s]):
``y(z) = sum_k w_k exp(-(z - c_k)^2 / (2 h^2))``.

Conditioning. The paper authors' basis (wide bumps relative to their spacing)
had a Gram-matrix condition number of about 1e9, which makes the weight fit and
every later solve lose about 9 digits. Here the centres ``c_k`` are uniformly
spaced with spacing ``Delta`` from ``-margin Delta`` to ``1 + margin Delta``
and the default width is ``h = 0.75 Delta``: the sum of the bumps is flat to
about 3e-5 (no ripple), neighbouring bumps overlap little, and one centre
beyond each end (``margin = 1``) lets the fit follow a signal's slope up to the
ends (max error 1.4e-3 for ``z^2`` on [0, 1], against 7e-2 without margin).
The Gram matrix ``int_0^1 phi phi^T dz`` then has a condition number of about
2.2e3 for K = 31 and K = 61 (:meth:`GaussianBasis.condition_number`; ~124
without margin, ~1e9 for a width of 1.5 Delta). The weight fit additionally
uses a small ridge (see :meth:`GaussianBasis.fit_weights`).
"""

from __future__ import annotations

import bisect

import numpy as np
from scipy.linalg import cho_solve

from ..exceptions import ModelError

DEFAULT_RELATIVE_WIDTH = 0.75
"""Default width ``h`` of a bump as a fraction of the centre spacing."""

SUPPORT_TOL = 1e-11
"""A basis function below this value on the whole observed phase interval is left out of the
likelihood (:meth:`GaussianBasis.support_count`)."""


class GaussianBasis:
    """``K`` Gaussian basis functions with uniformly spaced centres on [0, 1].

    Args:
        n_basis: Number of basis functions ``K`` (>= 2).
        width: Standard deviation ``h`` of each bump, in phase units; default
            ``0.75 / (K - 1)`` (0.75 times the centre spacing).
        ridge: Relative ridge added to the normal equations of the weight fit,
            as a fraction of the mean diagonal of ``B^T B``.
        margin: Centres extend this many spacings beyond each end of [0, 1].

    Attributes:
        centres: (K,) centres ``c_k`` in phase units (uniform, spacing ``spacing``).
        spacing: Distance ``Delta`` between neighbouring centres, in phase units.
        step_factor: (K - 1,) ``d_k = exp(-(c_k + Delta / 2) Delta / h^2)``, the constant factors of
            the running product ``phi_{k+1}(z) = phi_k(z) q(z) d_k`` (see :meth:`values_prefix_t`; the
            compiled kernels evaluate the basis this way).
    """

    def __init__(
        self, n_basis: int = 31, width: float | None = None, ridge: float = 1e-6, margin: float = 1.0
    ) -> None:
        if int(n_basis) != n_basis or n_basis < 2:
            raise ModelError(f"n_basis must be an integer >= 2, got {n_basis!r}")
        self.n_basis = int(n_basis)
        self.margin = float(margin)
        if not (0.0 <= self.margin < (self.n_basis - 1) / 2.0):
            raise ModelError(f"margin must be in [0, (n_basis - 1) / 2), got {margin!r}")
        spacing = 1.0 / (self.n_basis - 1 - 2.0 * self.margin)
        self.spacing = spacing
        self.width = float(DEFAULT_RELATIVE_WIDTH * spacing if width is None else width)
        if not (self.width > 0.0 and np.isfinite(self.width)):
            raise ModelError(f"basis width must be positive, got {width!r}")
        self.ridge = float(ridge)
        if not (self.ridge >= 0.0 and np.isfinite(self.ridge)):
            raise ModelError(f"ridge must be >= 0, got {ridge!r}")
        self.centres = -self.margin * spacing + spacing * np.arange(self.n_basis)
        # phi_{k+1} / phi_k = exp(z Delta / h^2) * exp(-(c_k + Delta / 2) Delta / h^2)
        self._centres_list = [float(c) for c in self.centres]
        self._reach = self.width * float(np.sqrt(-2.0 * np.log(SUPPORT_TOL)))
        self.step_factor = np.exp(-(self.centres[:-1] + 0.5 * spacing) * spacing / self.width**2)
        # products of two bumps: phi_k phi_l = tau_|k-l| psi_{k+l} with psi_s(z) = exp(-(z - m_s)^2 / h^2),
        # m_s = c_0 + s Delta / 2 (see gram_factors)
        inv_h2 = 1.0 / self.width**2
        mids = self.centres[0] + 0.5 * spacing * np.arange(2 * self.n_basis - 1)
        self._pair_step = np.exp(-(spacing * mids[:-1] + 0.25 * spacing**2) * inv_h2)
        self._pair_overlap = np.exp(-0.25 * (spacing * np.arange(self.n_basis)) ** 2 * inv_h2)

    def __call__(self, z: np.ndarray) -> np.ndarray:
        """Basis values at phases ``z`` (any shape S) -> array of shape S + (K,)."""
        z = np.asarray(z, dtype=float)
        d = (z[..., None] - self.centres) * (1.0 / self.width)
        return np.exp(-0.5 * d * d)

    def derivative(self, z: np.ndarray) -> np.ndarray:
        """Derivatives ``d phi / dz`` at phases ``z`` (any shape S) -> array of shape S + (K,)."""
        z = np.asarray(z, dtype=float)
        d = (z[..., None] - self.centres) * (1.0 / self.width)
        return -d / self.width * np.exp(-0.5 * d * d)

    def values_prefix_t(self, z: np.ndarray, n_first: int) -> np.ndarray:
        """Values of the first ``n_first`` basis functions at ``z`` (any shape S), basis axis first.

        Returns an array of shape ``(n_first,) + S`` equal to ``moveaxis(self(z)[..., :n_first], -1, 0)``
        to a few ulp, using two exponentials per ``z``: with uniform centres ``c_k = k Delta``,
        ``phi_{k+1}(z) = phi_k(z) q(z) d_k`` with ``q(z) = exp(z Delta / h^2)`` and
        ``d_k = exp(-(c_k + Delta / 2) Delta / h^2)``, a running product of bounded factors.
        Falls back to the direct formula where ``phi_0`` could underflow.
        """
        z = np.asarray(z, dtype=float)
        n_first = int(n_first)
        inv_h2 = 1.0 / (self.width * self.width)
        far = float(np.max(np.abs(z - self.centres[0]))) if z.size else 0.0
        if n_first < 3 or 0.5 * far * far * inv_h2 > 650.0:
            return np.moveaxis(self(z)[..., :n_first], -1, 0).copy()
        spacing = self.spacing
        out = np.empty((n_first,) + z.shape)
        d0 = z - self.centres[0]
        out[0] = np.exp(-0.5 * inv_h2 * d0 * d0)
        step = self.step_factor[: n_first - 1].reshape((-1,) + (1,) * z.ndim)
        np.multiply(np.exp(z * (spacing * inv_h2)), step, out=out[1:])
        for k in range(1, n_first):
            np.multiply(out[k - 1], out[k], out=out[k])
        return out

    def gram_factors(self) -> tuple[np.ndarray, np.ndarray]:
        """Factors of the Gram matrix of the bumps: ``(pair_step (2K-2,), overlap (K,))``.

        With uniform centres, ``phi_k(z) phi_l(z) = overlap_|k-l| psi_{k+l}(z)``, where
        ``overlap_m = exp(-(m Delta)^2 / (4 h^2))`` and ``psi_s(z) = exp(-(z - m_s)^2 / h^2)``,
        ``m_s = c_0 + s Delta / 2``; so ``B^T B`` over any samples is ``overlap_|k-l| S_{k+l}`` with
        the 2K - 1 sums ``S_s = sum_j psi_s(z_j)`` instead of K (K + 1) / 2 sums of products. The
        ``psi_s`` are a running product like the bumps: ``psi_{s+1}(z) = psi_s(z) q(z) pair_step_s``
        with ``q(z) = exp(z Delta / h^2)``.
        """
        return self._pair_step, self._pair_overlap

    def support_count(self, z_max: float, tol: float = SUPPORT_TOL) -> int:
        """Number of leading basis functions that exceed ``tol`` somewhere on [0, ``z_max``].

        Basis functions with centre beyond ``z_max + h sqrt(-2 ln tol)`` are below
        ``tol`` on the whole interval (they are negligible for an observation
        that ends at phase ``z_max``).
        """
        if tol == SUPPORT_TOL:  # the usual call: no array functions on scalars (a few us each)
            return bisect.bisect_right(self._centres_list, float(z_max) + self._reach)
        reach = float(z_max) + self.width * np.sqrt(-2.0 * np.log(tol))
        return int(min(self.n_basis, np.searchsorted(self.centres, reach, side="right")))

    def support_limit(self, n_first: int, tol: float = SUPPORT_TOL) -> float:
        """Phase below which :meth:`support_count` is at most ``n_first`` (inf when ``n_first >= K``)."""
        if n_first >= self.n_basis:
            return np.inf
        return float(self.centres[n_first] - self.width * np.sqrt(-2.0 * np.log(tol)))

    def gram(self, n_points: int = 2000) -> np.ndarray:
        """Gram matrix ``mean_z phi(z) phi(z)^T`` over a dense uniform grid on [0, 1], (K, K)."""
        b = self(np.linspace(0.0, 1.0, n_points))
        return b.T @ b / n_points

    def condition_number(self) -> float:
        """2-norm condition number of :meth:`gram` (about 2.2e3 with the defaults)."""
        return float(np.linalg.cond(self.gram()))

    def fit_weights(self, z: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Ridge least-squares weights of ``values`` (n, D) sampled at phases ``z`` (n,) -> (D, K)."""
        b = self(z)
        gram = b.T @ b
        lam = self.ridge * float(np.trace(gram)) / self.n_basis
        gram[np.diag_indices_from(gram)] += lam
        chol = np.linalg.cholesky(gram)
        rhs = b.T @ values
        return cho_solve((chol, True), rhs).T

    def to_dict(self) -> dict:
        """Constructor parameters as a JSON-able dict."""
        return {"n_basis": self.n_basis, "width": self.width, "ridge": self.ridge, "margin": self.margin}
