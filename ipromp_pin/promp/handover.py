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
  :class:`~ipromp_pin.promp.head.WindowSummary`);
* the regression ``y = W x + c``: one ridge regression per observed fraction (:data:`RATIOS`) on the
  task's training demos (targets: their recorded final configurations ``q_i``, as gripper positions
  in the read-out's linearisation ``A q_bar + fk(q_i) - fk(q_bar)``, ``q_bar`` the task's mean;
  without forward kinematics ``q_i``), its penalty chosen by exact leave-one-out
  (:func:`fit_ridge`); online the predictions of the two fractions around the estimated observed
  fraction are interpolated linearly (as the recognition head's logits);
* ``R``: the covariance of the leave-one-out residuals, pooled over the tasks, per fraction;
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

from .head import WindowSummary, interpolation

RATIOS = (0.1, 0.2, 0.4, 0.6, 0.8)
"""Observed fractions at which the regressions are fitted."""

RIDGE_PENALTIES = tuple(float(v) for v in np.logspace(-3, 5, 17))
"""Candidate ridge penalties (standardised features), chosen by leave-one-out."""

TRUST_GRID = (0.1, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0)
"""Candidate trust factors ``s`` (the regression's noise is ``s R``); "off" is also a candidate."""

JACOBIAN_STEP_RAD = 1e-6
"""Step of the central finite differences of the forward kinematics, in [rad]."""


def window_features(window: np.ndarray, dims: np.ndarray) -> np.ndarray:
    """Regression features (2 F,): the mean and the last value of the dims ``dims`` of a window summary
    ((3, D_o) or its (3 D_o,) vector: first, mean and last values, scaled units)."""
    values = np.asarray(window, dtype=float).reshape(3, -1)
    return values[1:, dims].reshape(-1)


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
    for lam in penalties:
        shrink = sv * sv / (sv * sv + lam)
        lever = 1.0 - (u * u) @ shrink - 1.0 / n
        if np.any(lever < 1e-9):
            continue
        resid = (yc - u @ (shrink[:, None] * uy)) / lever[:, None]
        score = float(np.sum(resid * resid))
        if score < best[0]:
            best = (score, float(lam), resid)
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
    """

    ratios: np.ndarray
    dims: np.ndarray
    readout: np.ndarray
    coef: np.ndarray
    intercept: np.ndarray
    residual_cov: np.ndarray
    trust: float

    def __post_init__(self) -> None:
        # C-contiguous copies: a fitted and a loaded regression then give bitwise identical products
        for name in ("ratios", "readout", "coef", "intercept", "residual_cov"):
            object.__setattr__(self, name, np.ascontiguousarray(getattr(self, name), dtype=float))
        object.__setattr__(self, "dims", np.ascontiguousarray(self.dims))

    def observation(
        self, task: int, window: WindowSummary, fraction: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The read-out ``A`` (M, J), the regression's prediction ``y`` (M,) and its noise covariance
        ``s R`` (M, M) for task index ``task`` given the observed window and the estimated observed
        fraction (the regressions of the two fractions around it interpolated linearly)."""
        x = window_features(window.values, self.dims)
        i, w = interpolation([float(r) for r in self.ratios], fraction)
        y = self.coef[i, task] @ x + self.intercept[i, task]
        cov = self.residual_cov[i]
        if w > 0.0:
            y = (1.0 - w) * y + w * (self.coef[i + 1, task] @ x + self.intercept[i + 1, task])
            cov = (1.0 - w) * cov + w * self.residual_cov[i + 1]
        return self.readout[task], y, self.trust * cov
