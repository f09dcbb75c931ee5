"""The conditioned robot weights in latent form, and their exact conditioning on joint via-points.

After the observation, the robot's weights (J joints x K basis functions, scaled units) are

    w = mean + G u,   G = [diag(sqrt(delta_j)) (x) I_K | F],   u = (xi, eta) ~ N(0, Lambda^-1)

with ``xi`` (J K) and ``eta`` (r) the latent coordinates: straight after the observation
``Lambda = blockdiag(I, Q)`` and ``Q = L L^T`` is the latent posterior precision of
:mod:`ipromp_pin.promp.conditioning`. The weight covariance ``G Lambda^-1 G^T`` is never formed.

Conditioning on via-points (joint positions or velocities at given phases, each with Gaussian noise
of standard deviation ``s > 0``) is a Kalman update in the latent space, in information form: with
``H`` the rows that pick the observed values out of ``w`` and ``V = S^-1 H G`` (``S`` the noise
standard deviations), the posterior precision is ``Lambda' = Lambda + V^T V`` (symmetric positive
definite by construction: an SPD matrix plus a positive semi-definite one) and the posterior mean
moves by ``G Lambda'^-1 V^T S^-1 (y - H mean)``. Everything is Cholesky factorisations and
triangular solves (``J K + r`` is a few hundred); no inverse is formed. Conditioning again starts
from the updated form, so via-points can be added one call at a time.

A few linear read-outs of the final configuration (the hand-over regression of
:mod:`~ipromp_pin.promp.handover`) are added by :meth:`RobotWeightPosterior.readout_update` without
factorising ``Lambda'``: by the Woodbury identity the update of the mean and of the trajectory's
covariance needs only ``Lambda^-1 V^T`` (``V`` has a handful of rows), and ``Lambda' = Lambda + V^T V``
is kept as the pending rows ``V`` (:attr:`RobotWeightPosterior.extra_rows`), factorised only when
something asks for it (another via-point, samples); a further read-out (the orientation estimate
after the hand-over regression) solves with ``Lambda + V^T V`` by the Woodbury identity again. The
update is one compiled kernel (``kernels.readout_update``).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np
from scipy.linalg import LinAlgError, cho_solve, cholesky, lapack, solve_triangular

from ..exceptions import ModelError
from .basis import GaussianBasis
from .compiled import kernels

# LAPACK without scipy's checked wrappers, for the read-out update of every prediction (the inputs
# are the model's own finite arrays; the calls are a few microseconds of arithmetic each)
_POTRF, _POTRS = lapack.dpotrf, lapack.dpotrs


def chol_lower(a: np.ndarray, what: str) -> np.ndarray:
    """Lower Cholesky factor (n, n) of a symmetric positive definite ``a`` (LAPACK ``dpotrf``; only
    its lower triangle is read); ModelError naming ``what`` when it is not numerically SPD."""
    low, info = _POTRF(a, lower=1, clean=1)
    if info != 0:
        raise ModelError(f"{what} is not numerically positive definite (LAPACK info {info})")
    return low


def chol_solve(low: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(L L^T)^-1 b`` (n, c) for the lower Cholesky factor ``L`` (n, n) and ``b`` (n, c) (``dpotrs``)."""
    x, _ = _POTRS(low, b, lower=1)
    return x


@dataclass(frozen=True)
class RobotWeightPosterior:
    """The conditioned robot weights in latent form: ``w = mean + sqrt(diag) xi + factor eta`` with
    ``(xi, eta) ~ N(0, Lambda^-1)`` (scaled units). Without via-points ``Lambda = blockdiag(I, Q)``,
    ``Q = L L^T`` (``xi ~ N(0, I)`` and ``eta ~ N(0, Q^-1)`` independent).

    Attributes:
        mean: (J, K) posterior mean of the robot weights.
        diag: (J,) per-joint diagonal variance ``delta_j``.
        factor: (J, K, r) the robot rows of the covariance factor.
        q_chol: (r, r) lower Cholesky factor ``L`` of the latent posterior precision ``Q``.
        phi: (M, K) basis values at the prediction's phases.
        offset, scale: (J,) the robot channels' scaling (original = scaled * scale + offset, in [rad]).
        basis: The basis (to evaluate it at via-points' phases); None: via-points cannot be added.
        info_chol: (J K + r, J K + r) lower Cholesky factor of ``Lambda`` once via-points were added
            (None: ``Lambda = blockdiag(I, Q)``).
        extra_rows: (m, J K + r) rows ``V`` not yet factorised: the precision is ``Lambda + V^T V``
            (None: none; see :meth:`readout_update`).
    """

    mean: np.ndarray
    diag: np.ndarray
    factor: np.ndarray
    q_chol: np.ndarray
    phi: np.ndarray
    offset: np.ndarray
    scale: np.ndarray
    basis: GaussianBasis | None = None
    info_chol: np.ndarray | None = None
    extra_rows: np.ndarray | None = None

    def evolve(self, **changes: object) -> RobotWeightPosterior:
        """A copy with the fields ``changes`` replaced (as :func:`dataclasses.replace`, without its
        per-field ``__init__``; the cached factorisations are not carried over)."""
        new = object.__new__(RobotWeightPosterior)
        state = {f: self.__dict__[f] for f in _FIELDS}
        state.update(changes)
        new.__dict__.update(state)
        return new

    @property
    def n_latent(self) -> int:
        """Number of latent coordinates ``J K + r``."""
        j, k, r = self.factor.shape
        return j * k + r

    def precision_chol(self) -> np.ndarray:
        """Lower Cholesky factor of the latent precision ``Lambda`` (J K + r, J K + r) (with pending
        :attr:`extra_rows`, factorised on the first call and cached)."""
        if self.extra_rows is not None:
            cached = self.__dict__.get("_extra_chol")
            if cached is None:
                base = replace(self, extra_rows=None).precision_chol()
                lam = base @ base.T + self.extra_rows.T @ self.extra_rows
                try:
                    cached = cholesky(lam, lower=True)
                except LinAlgError as exc:
                    raise ModelError(f"read-out update is not numerically positive definite ({exc})") from exc
                object.__setattr__(self, "_extra_chol", cached)
            return cached
        if self.info_chol is not None:
            return self.info_chol
        j, k, r = self.factor.shape
        out = np.eye(j * k + r)
        out[j * k :, j * k :] = self.q_chol
        return out

    def loadings(self, rows: np.ndarray, joints: np.ndarray) -> np.ndarray:
        """``H G`` (m, J K + r) for ``m`` scalar read-outs ``rows[i] . w[joints[i]]`` (rows: (m, K))."""
        rows = np.asarray(rows, dtype=float)
        joints = np.asarray(joints, dtype=np.int64)
        j, k, r = self.factor.shape
        out = np.zeros((rows.shape[0], j * k + r))
        sd = np.sqrt(self.diag)
        for i, (row, jj) in enumerate(zip(rows, joints, strict=True)):
            out[i, jj * k : (jj + 1) * k] = sd[jj] * row
            out[i, j * k :] = row @ self.factor[jj]
        return out

    def trajectory_loadings(self, rows: np.ndarray) -> np.ndarray:
        """``G^T P^T`` for the read-outs of every joint at every row: (J K + r, M, J) for rows (M, K)."""
        rows = np.asarray(rows, dtype=float)
        j, k, r = self.factor.shape
        m = rows.shape[0]
        out = np.zeros((j * k + r, m, j))
        sd = np.sqrt(self.diag)
        for jj in range(j):
            out[jj * k : (jj + 1) * k, :, jj] = (sd[jj] * rows).T
        out[j * k :] = np.einsum("mk,jkr->rmj", rows, self.factor)
        return out

    def q_mean(self, rows: np.ndarray | None = None) -> np.ndarray:
        """Mean joint values (M, J) in [rad] at the basis rows (default: the prediction's phases)."""
        rows = self.phi if rows is None else rows
        return rows @ self.mean.T * self.scale + self.offset

    def q_cov(self, rows: np.ndarray | None = None) -> np.ndarray:
        """Covariance (M, J, J) in [rad^2] of the joints at the basis rows (default: the prediction's
        phases): ``S P G Lambda^-1 G^T P^T S`` by one triangular solve."""
        rows = self.phi if rows is None else rows
        a = self.trajectory_loadings(rows)  # (n_u, M, J)
        n_u, m, j = a.shape
        b = solve_triangular(self.precision_chol(), a.reshape(n_u, m * j), lower=True).reshape(n_u, m, j)
        cov = np.einsum("umi,umj->mij", b, b)
        return cov * self.scale[None, :, None] * self.scale[None, None, :]

    def sample_q(self, n: int, rng: np.random.Generator | int | None = None) -> np.ndarray:
        """Draw ``n`` robot trajectories (n, M, J) in [rad] (exactly the conditioned Gaussian,
        without forming it)."""
        rng = np.random.default_rng(rng)
        j, k, r = self.factor.shape
        if self.info_chol is None and self.extra_rows is None:
            xi = rng.standard_normal((n, j, k)) * np.sqrt(self.diag)[None, :, None]
            zeta = rng.standard_normal((r, n))
            eta = solve_triangular(self.q_chol, zeta, lower=True, trans="T").T if r else zeta.T
            w = self.mean[None] + xi + np.einsum("jkr,nr->njk", self.factor, eta)
        else:
            u = solve_triangular(
                self.precision_chol(), rng.standard_normal((j * k + r, n)), lower=True, trans="T"
            )
            xi = u[: j * k].T.reshape(n, j, k) * np.sqrt(self.diag)[None, :, None]
            w = self.mean[None] + xi + np.einsum("jkr,rn->njk", self.factor, u[j * k :])
        q = np.einsum("mk,njk->nmj", self.phi, w)
        return q * self.scale + self.offset

    def condition(
        self,
        rows: np.ndarray,
        joints: np.ndarray,
        values: np.ndarray,
        std: np.ndarray,
        derivative: np.ndarray | None = None,
    ) -> RobotWeightPosterior:
        """The posterior after ``m`` noisy scalar via-points ``values[i] = rows[i] . w[joints[i]]``
        in original units (+ noise of standard deviation ``std[i] > 0``).

        Args:
            rows: (m, K) basis values at the via-points' phases (or, for a velocity, the basis
                derivative with respect to time, in [1/s]).
            joints: (m,) joint indices.
            values: (m,) target values in [rad] (or [rad/s] for derivative rows).
            std: (m,) noise standard deviations in the same units (> 0).
            derivative: (m,) True where the row is a derivative (no offset).

        Raises:
            ModelError: bad shapes, non-positive or non-finite ``std``, or a numerically singular update.
        """
        rows = np.atleast_2d(np.asarray(rows, dtype=float))
        joints = np.asarray(joints, dtype=np.int64).reshape(-1)
        values = np.asarray(values, dtype=float).reshape(-1)
        std = np.asarray(std, dtype=float).reshape(-1)
        m = rows.shape[0]
        deriv = np.zeros(m, dtype=bool) if derivative is None else np.asarray(derivative, bool).reshape(-1)
        nj, k, _ = self.factor.shape
        if rows.shape[1] != k or not (joints.size == values.size == std.size == deriv.size == m):
            raise ModelError(f"via-points: {m} rows of {rows.shape[1]} values (need {k}) do not match")
        if np.any((joints < 0) | (joints >= nj)):
            raise ModelError(f"via-points: joint index out of range 0..{nj - 1}")
        if not np.all(np.isfinite(values)) or not np.all(np.isfinite(rows)):
            raise ModelError("via-points: values must be finite")
        if not np.all((std > 0) & np.isfinite(std)):
            raise ModelError(f"via-points: noise standard deviations must be positive and finite, got {std}")
        scale = self.scale[joints]
        y = (values - np.where(deriv, 0.0, self.offset[joints])) / scale  # scaled units
        s = std / scale
        v = self.loadings(rows, joints) / s[:, None]  # S^-1 H G, (m, n_u)
        resid = (y - np.einsum("mk,mk->m", rows, self.mean[joints])) / s
        chol = self.precision_chol()
        lam = chol @ chol.T + v.T @ v
        try:
            new_chol = cholesky(lam, lower=True)
        except LinAlgError as exc:
            raise ModelError(f"via-point update is not numerically positive definite ({exc})") from exc
        u_mean = cho_solve((new_chol, True), v.T @ resid)
        jk = nj * k
        dw = u_mean[:jk].reshape(nj, k) * np.sqrt(self.diag)[:, None] + self.factor @ u_mean[jk:]
        return replace(self, mean=self.mean + dw, info_chol=new_chol, extra_rows=None)

    def _base_factor(self) -> np.ndarray:
        """The lower factor of the precision's last latent coordinates that are not the identity:
        ``L`` of ``Q`` (r, r) without via-points, :attr:`info_chol` after them (pending rows aside)."""
        return self.q_chol if self.info_chol is None else self.info_chol

    def _pending(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The pending rows ``E`` (:attr:`extra_rows`; (0, J K + r) when none), ``U = Lambda_0^-1 E^T``
        (J K + r, m_e) for the precision ``Lambda_0`` without them and the lower factor of
        ``I + E U`` (m_e, m_e): the Woodbury form of ``(Lambda_0 + E^T E)^-1`` (cached)."""
        cached = self.__dict__.get("_pending_factors")
        if cached is None:
            n_u = self.n_latent
            if self.extra_rows is None:
                cached = (np.zeros((0, n_u)), np.zeros((n_u, 0)), np.zeros((0, 0)))
            else:
                e = np.ascontiguousarray(self.extra_rows, dtype=float)
                base = self._base_factor()
                ue = np.array(e.T, order="C")
                b0 = n_u - base.shape[0]
                if base.shape[0]:
                    ue[b0:] = chol_solve(base, ue[b0:])
                cached = (e, ue, chol_lower(np.eye(e.shape[0]) + e @ ue, "read-out update"))
            object.__setattr__(self, "_pending_factors", cached)
        return cached

    def readout_update(
        self,
        row: np.ndarray,
        readout: np.ndarray,
        values: np.ndarray,
        cov: np.ndarray,
        phi_f: np.ndarray | None = None,
    ) -> tuple[RobotWeightPosterior, np.ndarray, np.ndarray]:
        """The posterior after observing ``values = readout q(z) + e``, ``e ~ N(0, cov)``: linear
        read-outs of the joints at one phase (``row`` (K,): the basis there; e.g. the gripper position
        to first order at the hand-over), and the change of the prediction at the phases :attr:`phi`.

        Exact Gaussian conditioning in the latent space, by the Woodbury identity (see the module
        docstring): the precision update is kept as :attr:`extra_rows`.

        Args:
            row: (K,) basis values at the read-out's phase.
            readout: (m, J) read-out of the joint angles in [rad] (values in its units, e.g. [m]).
            values: (m,) the observed values.
            cov: (m, m) their noise covariance (symmetric positive definite).
            phi_f: (r, J, M) ``phi`` times the robot rows of the factor (computed when not given).

        Returns:
            The new posterior, the change (M, J) of the mean joint angles in [rad] and the decrease
            (M, J, J) of their covariance in [rad^2] at the phases :attr:`phi`.
        """
        readout = np.ascontiguousarray(np.atleast_2d(np.asarray(readout, dtype=float)))
        base, (extra, extra_u, extra_s) = self._base_factor(), self._pending()
        if phi_f is None:
            phi_f = np.einsum("mk,jkr->rjm", self.phi, self.factor)
        c = np.ascontiguousarray
        ok, v, dw, d_mean, d_cov = kernels().readout_update(
            c(self.mean), np.sqrt(self.diag), c(self.factor), c(base), c(extra), c(extra_u), c(extra_s),
            c(self.phi), c(phi_f), c(self.scale), c(self.offset), c(row, dtype=float), readout,
            c(values, dtype=float), c(cov, dtype=float),
        )  # fmt: skip
        if not ok:
            raise ModelError(
                "read-out noise covariance or read-out update is not numerically positive definite"
            )
        rows = v if self.extra_rows is None else np.vstack([self.extra_rows, v])
        new = self.evolve(mean=self.mean + dw, extra_rows=rows)
        return new, d_mean, d_cov


_FIELDS = tuple(f.name for f in fields(RobotWeightPosterior))
