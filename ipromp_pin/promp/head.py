"""A discriminative recognition head, calibrated on the training demos, over the generative posterior.

The generative task posterior of an Interaction ProMP ranks the tasks well when the observed
channels separate them (EMG), but its scale is not a calibrated probability: the samples of a smooth
motion are far from independent, so the likelihood's differences between tasks are hundreds of nats
where the data support a few, and on weakly informative channels (a tracked hand position) a few
hundred weakly estimated weights drown the few informative ones (the start position). The head
combines both in one multinomial logistic regression fitted on held-out training demos:

``log p(k | obs) = log softmax_k( b_k + W_k^T x )``,
``x = ((first, mean, last, g) - m) / s``

with, per observed dim (scaled units, :class:`~ipromp_pin.promp.distribution.ChannelScaler`), the
first, mean and last valid value of the observed window (:class:`WindowSummary`; a dim without a
sample is at its training mean, 0), and ``g`` the generative log posterior of every task clipped at
:data:`LOG_POSTERIOR_CLIP`. ``m``, ``s`` standardise the features on the training rows. ``W``, ``b``
minimise the mean log loss plus ``||W||^2 / (2 C n)``. The rows are the held-out demos of the
leave-one-out cross-validation (:mod:`~ipromp_pin.promp.selection`), each observed at several
fractions (:data:`~ipromp_pin.promp.selection.HEAD_RATIOS`), so ``g`` is what the model says about a
demo it was not fitted on. There is one regression per observed fraction; each is trained on the
rows of its fraction or on the rows of every fraction, with its ``C``, both chosen by grouped
cross-validation (the rows of one demo in one fold) scored on the rows of its fraction
(:func:`fit_head`). Online the fraction is unknown: the logits of the two regressions around the
expected observed fraction under the generative posterior (:func:`observed_fraction`) are
interpolated linearly.

The phase posterior, the MAP phase and the robot's conditioned prediction are not changed by the
head; it only decides the task posterior.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize
from scipy.special import log_softmax

from .observation import ObservationPart

LOG_POSTERIOR_CLIP = -30.0
"""The generative log posterior enters the head clipped at this value (a confident generative mistake
then costs a bounded amount)."""

HEAD_C_GRID = (0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 100.0)
"""Candidate inverse penalties ``C`` of the head."""

HEAD_FOLDS = 5
"""Folds of the head's grouped cross-validation."""


@dataclass(frozen=True)
class WindowSummary:
    """First, mean and last valid value of every observed dim over an observed window (scaled units).

    Attributes:
        values: (3, D_o) rows: the first, mean and last values; 0 (the training mean) for a dim
            without a sample.
    """

    values: np.ndarray

    @property
    def first(self) -> np.ndarray:
        """(D_o,) first valid values."""
        return self.values[0]

    @property
    def mean(self) -> np.ndarray:
        """(D_o,) mean values."""
        return self.values[1]

    @property
    def last(self) -> np.ndarray:
        """(D_o,) last valid values."""
        return self.values[2]

    @classmethod
    def from_parts(cls, parts: list[ObservationPart], n_obs: int) -> WindowSummary:
        """Summary of encoded observation parts (dims ``0 .. n_obs - 1``)."""
        if len(parts) == 1 and parts[0].dims.size == n_obs and parts[0].t.size:
            y = parts[0].y
            out = np.empty((3, n_obs))
            dims = parts[0].dims
            out[0, dims] = y[0]
            out[1, dims] = y.mean(axis=0)
            out[2, dims] = y[-1]
            return cls(out)
        first, last, total = np.zeros(n_obs), np.zeros(n_obs), np.zeros(n_obs)
        count = np.zeros(n_obs)
        t_first, t_last = np.full(n_obs, np.inf), np.full(n_obs, -np.inf)
        for p in parts:
            if p.t.size == 0:
                continue
            d = p.dims
            early = p.t[0] < t_first[d]
            first[d] = np.where(early, p.y[0], first[d])
            t_first[d] = np.where(early, p.t[0], t_first[d])
            late = p.t[-1] > t_last[d]
            last[d] = np.where(late, p.y[-1], last[d])
            t_last[d] = np.where(late, p.t[-1], t_last[d])
            total[d] += p.y.sum(axis=0)
            count[d] += p.t.size
        return cls(np.stack([first, np.divide(total, count, out=np.zeros(n_obs), where=count > 0), last]))

    def vector(self) -> np.ndarray:
        """(3 D_o,) first, mean and last values side by side."""
        return self.values.reshape(-1)


@dataclass(frozen=True)
class RecognitionHead:
    """The fitted head (see the module docstring): one logistic regression per observed fraction of
    :attr:`ratios`, their logits interpolated linearly in the estimated observed fraction.

    Attributes:
        ratios: (R,) increasing observed fractions the regressions were fitted at.
        coef: (R, T, F) weights ``W`` (F = 3 D_o + T features).
        intercept: (R, T) intercepts ``b``.
        feature_mean, feature_scale: (R, F) standardisation ``m``, ``s`` of the features.
        c: (R,) the chosen inverse penalties ``C``.
        cv_log_loss: (R, len(HEAD_C_GRID)) cross-validated mean log loss of every candidate ``C``.
    """

    ratios: np.ndarray
    coef: np.ndarray
    intercept: np.ndarray
    feature_mean: np.ndarray
    feature_scale: np.ndarray
    c: np.ndarray
    cv_log_loss: np.ndarray

    def __post_init__(self) -> None:
        # the standardisation folded into the weights: z = W (x - m) / s + b = W' x + b'
        folded = self.coef / self.feature_scale[:, None, :]
        object.__setattr__(self, "_w", folded)
        object.__setattr__(self, "_ratios", [float(r) for r in self.ratios])
        object.__setattr__(self, "_b", self.intercept - np.einsum("rtf,rf->rt", folded, self.feature_mean))

    def log_posterior(
        self, summary: WindowSummary, generative_log_posterior: np.ndarray, fraction: float
    ) -> np.ndarray:
        """(T,) normalised log posterior of the tasks.

        Args:
            summary: The observed window's summary.
            generative_log_posterior: (T,) the generative task posterior (log).
            fraction: Estimated observed fraction of the motion (:func:`observed_fraction`).
        """
        x = head_features(summary.vector(), generative_log_posterior)
        i, w = interpolation(self._ratios, fraction)
        z = self._w[i] @ x + self._b[i]
        if w > 0.0:
            z = (1.0 - w) * z + w * (self._w[i + 1] @ x + self._b[i + 1])
        # a task that cannot explain the observation at all (e.g. too long for it) stays impossible
        finite = np.isfinite(generative_log_posterior)
        if not finite.all():
            z = np.where(finite, z, -np.inf)
        z = z - z.max()
        return z - np.log(np.sum(np.exp(z)))


def observed_fraction(posterior: np.ndarray, alpha: np.ndarray, t_last: float, t_norm: float) -> float:
    """Expected observed fraction of the motion under the generative posterior: the tasks' posterior
    (T,) weighting ``t_last / (alpha_k T_norm)`` with their MAP phases ``alpha`` (T,), ``t_last`` and
    ``T_norm`` in [s] (the motion's duration is unknown online)."""
    return float(t_last / t_norm * np.dot(posterior, 1.0 / alpha))


def interpolation(ratios: Sequence[float], fraction: float) -> tuple[int, float]:
    """Index ``i`` and weight ``w`` of the linear interpolation between ``ratios[i]`` and
    ``ratios[i + 1]`` at ``fraction`` (``w = 0`` below the first and above the last)."""
    if fraction <= ratios[0]:
        return 0, 0.0
    i = 0
    while i + 1 < len(ratios) and ratios[i + 1] <= fraction:
        i += 1
    if i + 1 == len(ratios):
        return i, 0.0
    return i, (fraction - ratios[i]) / (ratios[i + 1] - ratios[i])


def head_features(window: np.ndarray, generative_log_posterior: np.ndarray) -> np.ndarray:
    """Raw head features (F,): the window values (3 D_o,) then the clipped generative log posterior."""
    return np.concatenate([window, np.maximum(generative_log_posterior, LOG_POSTERIOR_CLIP)])


def _fit_softmax(
    x: np.ndarray, y: np.ndarray, n_classes: int, c: float, weight: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Multinomial logistic regression on standardised ``x`` (n, F), labels ``y`` (n,), row weights
    ``weight`` (n,) (default 1): weighted mean log loss plus ``||W||^2 / (2 C S)`` (``S`` the sum of
    the weights) minimised by L-BFGS -> (W (T, F), b (T,))."""
    n, f = x.shape
    weight = np.ones(n) if weight is None else weight
    total = float(weight.sum())
    onehot = np.eye(n_classes)[y]
    lam = 1.0 / (c * total)
    sw = weight[:, None] / total

    def loss(theta: np.ndarray) -> tuple[float, np.ndarray]:
        w = theta[: n_classes * f].reshape(n_classes, f)
        b = theta[n_classes * f :]
        logp = log_softmax(x @ w.T + b, axis=1)
        r = (np.exp(logp) - onehot) * sw
        value = -np.sum(sw * onehot * logp) + 0.5 * lam * np.sum(w * w)
        grad = np.concatenate([(r.T @ x + lam * w).ravel(), r.sum(axis=0)])
        return float(value), grad

    res = minimize(loss, np.zeros(n_classes * (f + 1)), jac=True, method="L-BFGS-B", options={"maxiter": 500})
    return res.x[: n_classes * f].reshape(n_classes, f), res.x[n_classes * f :]


def fit_head(
    features: np.ndarray,
    labels: np.ndarray,
    groups: np.ndarray,
    ratios: np.ndarray,
    n_tasks: int,
    fractions: np.ndarray | None = None,
) -> RecognitionHead:
    """Fit the head on training rows: one regression per observed fraction, each choosing its training
    rows and ``C`` among :data:`HEAD_C_GRID` by grouped CV.

    Args:
        features: (n, F) raw head features (:func:`head_features`).
        labels: (n,) task index of every row.
        groups: (n,) the demo of every row (rows of one demo share a fold).
        ratios: (n,) the observed fraction of every row (the regressions' fractions are these values).
        n_tasks: Number of tasks T.
        fractions: (n,) the observed fraction of every row as estimated online
            (:func:`observed_fraction`): a row then counts for the regressions with the weights of
            the interpolation at its estimate, as online (default: ``ratios``).
    """
    levels = np.unique(ratios)
    fractions = ratios if fractions is None else fractions
    weights = np.zeros((levels.size, labels.size))
    for n, frac in enumerate(fractions):
        i, w = interpolation([float(r) for r in levels], float(frac))
        weights[i, n] += 1.0 - w
        if w > 0.0:
            weights[i + 1, n] += w
    fits = [_fit_one(features, labels, groups, weights[i], n_tasks) for i in range(levels.size)]
    return RecognitionHead(levels, *(np.stack(a) for a in zip(*fits, strict=True)))


def _fit_one(
    features: np.ndarray, labels: np.ndarray, groups: np.ndarray, here: np.ndarray, n_tasks: int
) -> tuple[np.ndarray, ...]:
    """The regression of one observed fraction, whose rows have the weights ``here`` (n,): trained on
    them, or on every row alike (more demos, features less specific), and its ``C``, both chosen by
    grouped CV scored on the rows ``here`` -> (W, b, m, s, C, CV log loss of every candidate C at the
    chosen training rows)."""
    uniq = np.unique(groups)
    fold_of = {g: i % HEAD_FOLDS for i, g in enumerate(uniq)}
    folds = np.array([fold_of[g] for g in groups])
    best_score, best = np.inf, None
    for pool in (here, np.ones_like(here)):
        used = pool > 0.0
        mean = features[used].mean(axis=0)
        scale = features[used].std(axis=0)
        scale = np.where(scale > 1e-12, scale, 1.0)
        x = (features - mean) / scale
        scores = []
        for c in HEAD_C_GRID:
            total = 0.0
            for k in range(min(HEAD_FOLDS, uniq.size)):
                train = used & (folds != k)
                test = (here > 0.0) & (folds == k)
                w, b = _fit_softmax(x[train], labels[train], n_tasks, c, pool[train])
                logp = log_softmax(x[test] @ w.T + b, axis=1)
                total -= float(np.sum(here[test] * logp[np.arange(int(test.sum())), labels[test]]))
            scores.append(total / float(here.sum()))
        j = int(np.argmin(scores))
        if scores[j] < best_score:
            best_score, best = scores[j], (pool, mean, scale, x, float(HEAD_C_GRID[j]), np.array(scores))
    pool, mean, scale, x, c, scores = best
    used = pool > 0.0
    w, b = _fit_softmax(x[used], labels[used], n_tasks, c, pool[used])
    return w, b, mean, scale, np.array(c), scores
