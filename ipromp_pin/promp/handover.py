"""Hand-over regression: a discriminative estimate of the hand-over, fused into the prediction.

The Interaction ProMP predicts the robot's final (hand-over) configuration through the covariance of
a few hundred weights estimated from 10-20 demos; the Ledoit-Wolf shrinkage that keeps that
covariance usable also attenuates the cross-covariance between the human's motion and the robot's.
A ridge regression per task from a handful of window features to the hand-over is a low-variance
estimate of the same quantity. Both are combined here as Bayesian evidence: the regression's
prediction is a noisy observation of linear read-outs of the final configuration,

``y = A q(T) + e,   e ~ N(0, s R)``

with, per task,

* ``A`` (M, J): with the robot's forward kinematics, the Jacobian of the gripper position at the
  task's mean final configuration (M = 3, [m/rad]: the position to first order, so the regression
  acts on what the hand-over needs and not on the arm's null space); without it the identity
  (M = J, joint space);
* features: the mean and the last value over the observed window of each dim of the groups coupled
  to the robot, or of every observed group (chosen by cross-validation; scaled units;
  :class:`~ipromp_pin.promp.window.WindowSummary`);
* the regression: per observed fraction (:data:`RATIOS`) a ridge regression ``y = W x + c`` or a
  k-nearest-neighbour regression (:func:`fit_knn`), whichever has the smaller leave-one-out squared
  error summed over the tasks at that fraction, on the task's training demos (targets: their
  recorded final configurations ``q_i``, as gripper positions in the read-out's linearisation
  ``A q_bar + fk(q_i) - fk(q_bar)``, ``q_bar`` the task's mean; without forward kinematics ``q_i``),
  the ridge penalty chosen by exact leave-one-out (:func:`fit_ridge`); online the predictions of
  the two fractions around the estimated observed fraction are interpolated linearly (as the
  recognition head's logits);
* ``R``: the covariance of the chosen estimator's leave-one-out residuals, pooled over the tasks,
  per fraction;
* ``s``: a trust factor chosen by cross-validation of the hand-over error on the training demos
  (:func:`~ipromp_pin.promp.handover_selection.choose_handover`; among :data:`TRUST_GRID` and "off":
  the regression is then not used).

The conditioned prediction (mean and covariance of the whole trajectory) is updated by exact Gaussian
conditioning on ``y`` (:meth:`~ipromp_pin.promp.weight_posterior.RobotWeightPosterior.readout_update`);
it keeps its covariance.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .head_features import interpolation
from .window import WindowSummary, window_features

RATIOS = (0.1, 0.2, 0.4, 0.6, 0.8)
"""Observed fractions at which the regressions are fitted."""

RIDGE_PENALTIES = tuple(float(v) for v in np.logspace(-3, 5, 17))
"""Candidate ridge penalties (standardised features), chosen by leave-one-out."""

TRUST_GRID = (0.1, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0)
"""Candidate trust factors ``s`` (the regression's noise is ``s R``); "off" is also a candidate."""

NEIGHBOUR_ARRAYS = (
    "kind",
    "neighbour_x",
    "neighbour_y",
    "neighbour_count",
    "neighbour_mean",
    "neighbour_scale",
    "neighbour_k",
    "neighbour_distance",
)
"""The optional arrays of :class:`HandoverRegression` for k-nearest-neighbour estimates."""

JACOBIAN_STEP_RAD = 1e-6
"""Step of the central finite differences of the forward kinematics, in [rad]."""


@dataclass(frozen=True)
class RidgeFit:
    """A ridge regression with its penalty chosen by leave-one-out.

    Attributes:
        coef: (M, F) weights on the raw features.
        intercept: (M,) intercepts.
        residuals: (n, M) leave-one-out residuals (truth minus prediction) of the training rows.
        penalty: The chosen penalty (on standardised features).
    """

    coef: np.ndarray
    intercept: np.ndarray
    residuals: np.ndarray
    penalty: float

    def predict(self, x: np.ndarray) -> np.ndarray:
        """(M,) prediction for raw features ``x`` (F,)."""
        return self.coef @ x + self.intercept


KNN_NEIGHBOURS = tuple(range(1, 11))
"""Candidate numbers of neighbours of the k-nearest-neighbour estimate, chosen by leave-one-out."""


@dataclass(frozen=True)
class KnnFit:
    """A k-nearest-neighbour regression (Euclidean distance on standardised features), its number of
    neighbours and weighting chosen by leave-one-out.

    Attributes:
        x: (N, F) standardised training features.
        y: (N, M) training targets.
        mean, scale: (F,) the standardisation of the raw features.
        k: Number of neighbours.
        distance: Whether the neighbours are weighted by inverse distance (else uniformly).
        residuals: (N, M) leave-one-out residuals (truth minus prediction) of the training rows.
    """

    x: np.ndarray
    y: np.ndarray
    mean: np.ndarray
    scale: np.ndarray
    k: int
    distance: bool
    residuals: np.ndarray

    def predict(self, x: np.ndarray) -> np.ndarray:
        """(M,) prediction for raw features ``x`` (F,)."""
        d = np.linalg.norm(self.x - (x - self.mean) / self.scale, axis=1)
        return knn_predict(d, self.y, self.k, self.distance)


def knn_predict(d: np.ndarray, y: np.ndarray, k: int, distance: bool) -> np.ndarray:
    """(M,) mean of the targets ``y`` (N, M) of the ``k`` rows nearest by distances ``d`` (N,), uniform
    or by inverse distance (rows at distance 0 then take all the weight)."""
    k = min(k, d.size)
    idx = np.argpartition(d, k - 1)[:k] if k < d.size else np.arange(d.size)
    if not distance:
        return y[idx].mean(axis=0)
    dk = d[idx]
    w = (dk <= 0.0).astype(float) if np.any(dk <= 0.0) else 1.0 / dk
    return w @ y[idx] / w.sum()


def fit_knn(x: np.ndarray, y: np.ndarray, neighbours: Sequence[int] = KNN_NEIGHBOURS) -> KnnFit | None:
    """k-nearest-neighbour regression of ``y`` (n, M) on ``x`` (n, F): features standardised on the
    rows, the number of neighbours (at most ``n - 1``) and the weighting minimising the leave-one-out
    squared error (None for fewer than 2 rows)."""
    n = x.shape[0]
    if n < 2:
        return None
    mean = x.mean(axis=0)
    scale = x.std(axis=0)
    scale = np.where(scale > 1e-12, scale, 1.0)
    xs = (x - mean) / scale
    d = np.sqrt(np.maximum(np.sum((xs[:, None] - xs[None]) ** 2, axis=2), 0.0))
    np.fill_diagonal(d, np.inf)
    best = (np.inf, 1, False, y)
    order = np.argsort(d, axis=1, kind="stable")  # every row's neighbours, nearest first
    for k in neighbours:
        if k > n - 1:
            break
        for distance in (False, True):
            resid = y - _knn_predict_rows(d, order[:, :k], y, distance)
            score = float(np.sum(resid * resid))
            if score < best[0]:
                best = (score, k, distance, resid)
    _, k, distance, resid = best
    return KnnFit(xs, y, mean, scale, int(k), bool(distance), resid)


def _knn_predict_rows(d: np.ndarray, idx: np.ndarray, y: np.ndarray, distance: bool) -> np.ndarray:
    """(n, M) :func:`knn_predict` of every row at once: distances ``d`` (n, N), each row's ``k``
    nearest rows ``idx`` (n, k), targets ``y`` (N, M)."""
    near = y[idx]  # (n, k, M)
    if not distance:
        return near.mean(axis=1)
    dk = np.take_along_axis(d, idx, axis=1)
    with np.errstate(divide="ignore"):
        w = np.where(np.any(dk <= 0.0, axis=1, keepdims=True), (dk <= 0.0).astype(float), 1.0 / dk)
    return np.einsum("nk,nkm->nm", w, near) / w.sum(axis=1, keepdims=True)


def fit_ridge(x: np.ndarray, y: np.ndarray, penalties: Sequence[float] = RIDGE_PENALTIES) -> RidgeFit:
    """Ridge regression of ``y`` (n, M) on ``x`` (n, F) (standardised features, unpenalised intercept),
    the penalty minimising the exact leave-one-out squared error (``e_i / (1 - h_ii)``, ``h`` the hat
    matrix including the intercept)."""
    n = x.shape[0]
    mean = x.mean(axis=0)
    scale = x.std(axis=0)
    scale = np.where(scale > 1e-12, scale, 1.0)
    xs = (x - mean) / scale
    y_mean = y.mean(axis=0)
    yc = y - y_mean
    u, sv, vt = np.linalg.svd(xs, full_matrices=False)
    uy = u.T @ yc
    best = (np.inf, float(penalties[0]), yc)
    # every penalty at once: shrink factors (P, r), leverages (P, n), LOO residuals (P, n, M)
    lams = np.asarray(penalties, dtype=float)
    shrink = sv * sv / (sv * sv + lams[:, None])
    lever = 1.0 - shrink @ (u * u).T - 1.0 / n
    ok = ~np.any(lever < 1e-9, axis=1)
    if ok.any():
        resid = (yc - np.matmul(u, shrink[ok][:, :, None] * uy)) / lever[ok][:, :, None]
        score = np.sum(resid * resid, axis=(1, 2))
        score[np.isnan(score)] = np.inf  # never chosen (as a NaN never compared smaller)
        j = int(np.argmin(score))  # the first of equal scores, as the smallest penalty wins ties
        # a copy: a view would keep every penalty's residuals alive with the fit
        best = (float(score[j]), float(lams[ok][j]), resid[j].copy())
    if not np.isfinite(best[0]):  # too few rows for any penalty: the mean (its leave-one-out residuals)
        resid = yc * (n / (n - 1.0)) if n > 1 else yc
        return RidgeFit(np.zeros((y.shape[1], x.shape[1])), y_mean, resid, float(penalties[-1]))
    _, lam, resid = best
    coef_s = vt.T @ ((sv / (sv * sv + lam))[:, None] * uy)  # (F, M) on standardised features
    coef = (coef_s / scale[:, None]).T
    return RidgeFit(coef=coef, intercept=y_mean - coef @ mean, residuals=resid, penalty=lam)


def readouts(q_end: np.ndarray, fk: Callable[[np.ndarray], np.ndarray] | None) -> np.ndarray:
    """Per task, the read-out ``A`` (T, M, J) of the final configuration: the Jacobian (3, J) of the
    forward kinematics ``fk`` (joint angles (n, J) in [rad] -> positions (n, 3) in [m]) at the task's
    mean final configuration ``q_end`` (T, J) in [rad] (central differences), or the identity."""
    n_task, nj = q_end.shape
    if fk is None:
        return np.repeat(np.eye(nj)[None], n_task, axis=0)
    step = np.eye(nj) * JACOBIAN_STEP_RAD
    out = []
    for q in q_end:
        p = np.asarray(fk(np.concatenate([q + step, q - step])), dtype=float)
        out.append(((p[:nj] - p[nj:]) / (2.0 * JACOBIAN_STEP_RAD)).T)
    return np.stack(out)


@dataclass(frozen=True)
class HandoverRegression:
    """The fitted hand-over regression of every task (see the module docstring).

    Attributes:
        ratios: (R,) increasing observed fractions the regressions were fitted at.
        dims: (F,) the observed dims whose window mean and last value are the features.
        readout: (T, M, J) per task the read-out ``A`` of the final joint angles in [rad].
        coef: (R, T, M, 2 F) regression weights on the features (scaled units).
        intercept: (R, T, M) intercepts.
        residual_cov: (R, M, M) leave-one-out residual covariance ``R`` (pooled over tasks).
        trust: The trust factor ``s`` (the noise covariance is ``s R``).
        kind: (R,) per fraction 0 where the estimate is the ridge regression (``coef``,
            ``intercept``), 1 where it is the k-nearest-neighbour regression (the ``neighbour_*``
            arrays; ``coef`` and ``intercept`` are then 0); None: all ridge (model files of format
            version 3).
        neighbour_x: (R, T, N, 2 F) standardised features of the training demos (N the most demos of a
            task; rows beyond ``neighbour_count`` are 0 and unused).
        neighbour_y: (R, T, N, M) their targets.
        neighbour_count: (R, T) number of training demos (rows) of every regression.
        neighbour_mean, neighbour_scale: (R, T, 2 F) the standardisation of the raw features.
        neighbour_k: (R, T) number of neighbours.
        neighbour_distance: (R, T) 1 where the neighbours are weighted by inverse distance, else 0.
    """

    ratios: np.ndarray
    dims: np.ndarray
    readout: np.ndarray
    coef: np.ndarray
    intercept: np.ndarray
    residual_cov: np.ndarray
    trust: float
    kind: np.ndarray | None = None
    neighbour_x: np.ndarray | None = None
    neighbour_y: np.ndarray | None = None
    neighbour_count: np.ndarray | None = None
    neighbour_mean: np.ndarray | None = None
    neighbour_scale: np.ndarray | None = None
    neighbour_k: np.ndarray | None = None
    neighbour_distance: np.ndarray | None = None

    def __post_init__(self) -> None:
        # C-contiguous copies: a fitted and a loaded regression then give bitwise identical products
        for name in ("ratios", "readout", "coef", "intercept", "residual_cov", *NEIGHBOUR_ARRAYS):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, np.ascontiguousarray(value, dtype=float))
        object.__setattr__(self, "dims", np.ascontiguousarray(self.dims))

    def observation(
        self, task: int, window: WindowSummary, fraction: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The read-out ``A`` (M, J), the regression's prediction ``y`` (M,) and its noise covariance
        ``s R`` (M, M) for task index ``task`` given the observed window and the estimated observed
        fraction (the regressions of the two fractions around it interpolated linearly)."""
        x = window_features(window.values, self.dims)
        i, w = interpolation([float(r) for r in self.ratios], fraction)
        y = self._predict(i, task, x)
        cov = self.residual_cov[i]
        if w > 0.0:
            y = (1.0 - w) * y + w * self._predict(i + 1, task, x)
            cov = (1.0 - w) * cov + w * self.residual_cov[i + 1]
        return self.readout[task], y, self.trust * cov

    def _predict(self, level: int, task: int, x: np.ndarray) -> np.ndarray:
        """(M,) the regression's prediction of fraction index ``level`` for task index ``task`` from
        the raw features ``x`` (2 F,)."""
        if self.kind is None or self.kind[level] == 0:
            return self.coef[level, task] @ x + self.intercept[level, task]
        count, mean, scale = self.neighbour_count, self.neighbour_mean, self.neighbour_scale
        nx, ny, nk, nd = self.neighbour_x, self.neighbour_y, self.neighbour_k, self.neighbour_distance
        # the neighbour arrays are present wherever kind is 1 (validate_fitted checks it)
        assert count is not None and mean is not None and scale is not None
        assert nx is not None and ny is not None and nk is not None and nd is not None
        n = int(count[level, task])
        xs = (x - mean[level, task]) / scale[level, task]
        d = np.linalg.norm(nx[level, task, :n] - xs, axis=1)
        k, distance = int(nk[level, task]), bool(nd[level, task])
        return knn_predict(d, ny[level, task, :n], k, distance)


def neighbour_arrays(fits: list[list[RidgeFit | KnnFit]], n_out: int, n_feat: int) -> dict[str, np.ndarray]:
    """The ``kind`` and ``neighbour_*`` arrays of :class:`HandoverRegression` from the fits (R lists of
    T, one kind per fraction) with M = ``n_out`` outputs and ``n_feat`` (2 F) features."""
    n_ratio, n_task = len(fits), len(fits[0])
    n_rows = max((f.x.shape[0] for row in fits for f in row if isinstance(f, KnnFit)), default=1)
    out = {
        "kind": np.array([float(isinstance(row[0], KnnFit)) for row in fits]),
        "neighbour_x": np.zeros((n_ratio, n_task, n_rows, n_feat)),
        "neighbour_y": np.zeros((n_ratio, n_task, n_rows, n_out)),
        "neighbour_count": np.zeros((n_ratio, n_task)),
        "neighbour_mean": np.zeros((n_ratio, n_task, n_feat)),
        "neighbour_scale": np.ones((n_ratio, n_task, n_feat)),
        "neighbour_k": np.ones((n_ratio, n_task)),
        "neighbour_distance": np.zeros((n_ratio, n_task)),
    }
    for r, row in enumerate(fits):
        for t, f in enumerate(row):
            if not isinstance(f, KnnFit):
                continue
            n = f.x.shape[0]
            out["neighbour_x"][r, t, :n] = f.x
            out["neighbour_y"][r, t, :n] = f.y
            out["neighbour_count"][r, t] = n
            out["neighbour_mean"][r, t] = f.mean
            out["neighbour_scale"][r, t] = f.scale
            out["neighbour_k"][r, t] = f.k
            out["neighbour_distance"][r, t] = float(f.distance)
    return out
