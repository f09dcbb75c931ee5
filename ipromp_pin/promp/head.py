"""A discriminative recognition head, calibrated on the training demos, over the generative posterior.

The generative task posterior of an Interaction ProMP ranks the tasks well when the observed
channels separate them (EMG), but its scale is not a calibrated probability: the samples of a smooth
motion are far from independent, so the likelihood's differences between tasks are hundreds of nats
where the data support a few, and on weakly informative channels (a tracked hand position) a few
hundred weakly estimated weights drown the few informative ones (the start position). The head
combines both in one multinomial logistic regression fitted on held-out training demos:

``log p(k | obs) = log softmax_k( b_k + W_k^T x )``,
``x = ((first, mean, last, g) - m) / s``

with, per observed dim (scaled units, :class:`~ipromp_pin.promp.distribution.ChannelScaler`), the first,
mean and last valid value of the observed window (:class:`~ipromp_pin.promp.window.WindowSummary`; a dim
without a sample is at its training mean, 0), and ``g`` the generative log posterior of every task
clipped at :data:`LOG_POSTERIOR_CLIP`. ``m``, ``s`` standardise the features on the training rows.
``W``, ``b`` minimise the mean log loss plus ``||W||^2 / (2 C n)``. The rows are the held-out demos of
the leave-one-out cross-validation (:mod:`~ipromp_pin.promp.selection`), each observed at several
fractions (:data:`~ipromp_pin.promp.selection.HEAD_RATIOS`), so ``g`` is what the model says about a
demo it was not fitted on. There is one regression per observed fraction. Each is chosen by grouped
cross-validation of the log loss (the rows of one demo in one fold, scored on the rows of its fraction;
:func:`fit_head`) among: a multinomial logistic regression (its ``C`` among :data:`HEAD_C_GRID`) or a
linear discriminant analysis (class means and a pooled covariance with Ledoit-Wolf shrinkage, its logits
scaled by a temperature among :data:`LDA_TEMPERATURE_GRID`, which calibrates them), on all the features
or on the window features alone (the weights of ``g`` are then 0), trained on the rows of its fraction
or on the rows of every fraction. Both are linear in ``x``, so inference is the same for all. Online the
fraction is unknown: the logits of the two regressions around the expected observed fraction under the
generative posterior (:func:`observed_fraction`) are interpolated linearly.

The phase posterior, the MAP phase and the robot's conditioned prediction are not changed by the
head; it only decides the task posterior.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize

from .compiled import kernels
from .head_features import LOG_POSTERIOR_CLIP, interpolation
from .window import WindowSummary

HEAD_C_GRID = (0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 100.0)
"""Candidate inverse penalties ``C`` of the head."""

LDA_TEMPERATURE_GRID = (0.1, 0.2, 0.3, 0.5, 0.7, 1.0)
"""Candidate temperatures (factors of the logits) of the linear discriminant analysis."""

HEAD_FOLDS = 5
"""Folds of the head's grouped cross-validation."""

SOFTMAX_MAX_ITER = 500
"""Largest number of L-BFGS iterations of one logistic regression (scipy's other L-BFGS-B options at
their defaults: ``gtol`` 1e-5, ``ftol`` 2.2e-9, 10 correction pairs)."""

LOGISTIC, LDA = 0, 1
"""Codes of the head's model families (:attr:`RecognitionHead.kind`)."""


@dataclass(frozen=True)
class RecognitionHead:
    """The fitted head (see the module docstring): one linear classifier per observed fraction of
    :attr:`ratios`, their logits interpolated linearly in the estimated observed fraction.

    Attributes:
        ratios: (R,) increasing observed fractions the regressions were fitted at.
        coef: (R, T, F) weights ``W`` (F = 3 D_o + T features).
        intercept: (R, T) intercepts ``b``.
        feature_mean, feature_scale: (R, F) standardisation ``m``, ``s`` of the features.
        c: (R,) the chosen inverse penalty ``C`` (logistic regression) or temperature (LDA).
        cv_log_loss: (R, len(HEAD_C_GRID) + len(LDA_TEMPERATURE_GRID)) cross-validated mean log loss
            of every candidate ``C`` then every LDA temperature, with the chosen rows and features.
        kind: (R,) the model family (:data:`LOGISTIC` or :data:`LDA`; None: all logistic, as in
            model files of format version 2).
        generative: (R,) 1 where the generative log posterior is among the features, 0 where only
            the window is (None: all 1).
    """

    ratios: np.ndarray
    coef: np.ndarray
    intercept: np.ndarray
    feature_mean: np.ndarray
    feature_scale: np.ndarray
    c: np.ndarray
    cv_log_loss: np.ndarray
    kind: np.ndarray | None = None
    generative: np.ndarray | None = None
    # derived in __post_init__ (not parameters, not compared)
    _w: np.ndarray = field(init=False, repr=False, compare=False)
    _ratios: np.ndarray = field(init=False, repr=False, compare=False)
    _b: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        # the standardisation folded into the weights: z = W (x - m) / s + b = W' x + b'
        folded = self.coef / self.feature_scale[:, None, :]
        object.__setattr__(self, "_w", np.ascontiguousarray(folded))
        object.__setattr__(self, "_ratios", np.ascontiguousarray(self.ratios, dtype=float))
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
        return self.task_posterior(summary, generative_log_posterior, _ONE, _ONE, float(fraction))[0]

    def task_posterior(
        self,
        summary: WindowSummary,
        generative_log_posterior: np.ndarray,
        generative_posterior: np.ndarray,
        alpha: np.ndarray,
        t_scale: float,
    ) -> tuple[np.ndarray, np.ndarray, int]:
        """The normalised log posterior (T,), the posterior (T,) and the most probable task, at the
        observed fraction :func:`observed_fraction` of the generative posterior (T,) and MAP phases
        ``alpha`` (T,) with ``t_scale = t_last / T_norm`` (one compiled call: ``kernels.head_posterior``).
        A task that cannot explain the observation at all (e.g. too long for it) stays impossible."""
        return kernels().head_posterior(
            np.ascontiguousarray(summary.vector(), dtype=float),
            np.ascontiguousarray(generative_log_posterior, dtype=float),
            generative_posterior, alpha, t_scale, self._ratios, self._w, self._b, LOG_POSTERIOR_CLIP,
        )  # fmt: skip


_ONE = np.ones(1)
"""The one-task weights with which :meth:`RecognitionHead.task_posterior` reads ``t_scale`` as the
observed fraction itself."""


def _log_softmax(z: np.ndarray, work: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Row-wise log softmax of ``z`` (n, T) (``work``: scratch arrays (n, 1) and (n, T), and the
    result is written into ``z``: the same numbers without temporaries)."""
    if work is not None:
        col, e = work
        z.max(axis=1, keepdims=True, out=col)
        z -= col
        np.exp(z, out=e).sum(axis=1, keepdims=True, out=col)
        z -= np.log(col, out=col)
        return z
    z = z - z.max(axis=1, keepdims=True)
    return z - np.log(np.exp(z).sum(axis=1, keepdims=True))


def fit_softmax(
    x: np.ndarray,
    y: np.ndarray,
    n_classes: int,
    c: float,
    weight: np.ndarray | None = None,
    start: np.ndarray | None = None,
    options: dict | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Multinomial logistic regression on standardised ``x`` (n, F), labels ``y`` (n,), row weights
    ``weight`` (n,) (default 1): weighted mean log loss plus ``||W||^2 / (2 C S)`` (``S`` the sum of
    the weights) minimised by scipy's L-BFGS-B (``options``: further options of it) from ``start`` (the
    parameters of a nearby problem; default 0) -> (W (T, F), b (T,), the parameters (T (F + 1),)).
    The minimiser of scikit-learn's ``LogisticRegression(C=c)`` fitted with ``sample_weight=weight``
    (``C = 2 c`` for two classes, where it fits one binary model; tests/promp/test_sklearn_equivalence.py)."""
    n, f = x.shape
    weight = np.ones(n) if weight is None else weight
    total = float(weight.sum())
    onehot = np.eye(n_classes)[y]
    lam = 1.0 / (c * total)
    sw = weight[:, None] / total
    target = sw * onehot
    n_w = n_classes * f
    half_lam = 0.5 * lam

    # scratch arrays reused by every evaluation: logits / log softmax and exp / residuals (n, T),
    # products (n, T), row maxima / sums (n, 1), W-sized products (T, F)
    z, r, prod = np.empty((n, n_classes)), np.empty((n, n_classes)), np.empty((n, n_classes))
    col, wbuf = np.empty((n, 1)), np.empty((n_classes, f))

    def loss(theta: np.ndarray) -> tuple[float, np.ndarray]:
        # -sum(target * log_softmax(z)) + ||W||^2 lam / 2 and its gradient, in the scratch arrays
        w = theta[:n_w].reshape(n_classes, f)
        np.matmul(x, w.T, out=z)
        np.add(z, theta[n_w:], out=z)
        logp = _log_softmax(z, work=(col, r))
        np.subtract(np.multiply(np.exp(logp, out=r), sw, out=r), target, out=r)
        value = -float(np.multiply(target, logp, out=prod).sum()) + half_lam * float(
            np.multiply(w, w, out=wbuf).sum()
        )
        grad = np.empty_like(theta)
        g_w = grad[:n_w].reshape(n_classes, f)
        np.matmul(r.T, x, out=g_w)
        g_w += np.multiply(lam, w, out=wbuf)
        r.sum(axis=0, out=grad[n_w:])
        return value, grad

    theta0 = np.zeros(n_classes * (f + 1)) if start is None else start
    settings = {"maxiter": SOFTMAX_MAX_ITER, **(options or {})}
    theta = minimize(loss, theta0, jac=True, method="L-BFGS-B", options=settings).x
    return theta[:n_w].reshape(n_classes, f), theta[n_w:], theta


def fit_lda(
    x: np.ndarray, y: np.ndarray, n_classes: int, weight: np.ndarray, shrinkage: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Linear discriminant analysis on standardised ``x`` (n, F) with row weights ``weight`` (n,):
    weighted class means, their pooled covariance shrunk toward a multiple of the identity with the
    intensity ``shrinkage`` (None: Ledoit-Wolf's, the squares of the weights in its variance term),
    class priors from the weights -> the logits' (W (T, F), b (T,)). With unit weights scikit-learn's
    ``LinearDiscriminantAnalysis(solver="lsqr", shrinkage=s)`` with ``s`` from
    ``sklearn.covariance.ledoit_wolf_shrinkage`` of the class-centred rows (which takes no row
    weights; tests/promp/test_sklearn_equivalence.py)."""
    n, f = x.shape
    total = float(weight.sum())
    counts = np.array([weight[y == k].sum() for k in range(n_classes)])
    means = np.zeros((n_classes, f))
    have = counts > 0
    means[have] = np.stack([weight[y == k] @ x[y == k] / counts[k] for k in np.flatnonzero(have)])
    xc = x - means[y]
    cov = (xc * weight[:, None]).T @ xc / total
    mu = float(np.trace(cov)) / f
    target = cov - mu * np.eye(f)
    dist = float(np.sum(target * target))
    # sum_i w_i^2 ||x_i x_i^T - S||^2 / W^2, with ||x x^T - S||^2 = |x|^4 - 2 x^T S x + ||S||^2
    sq = np.sum(xc * xc, axis=1)
    err = sq * sq - 2.0 * np.einsum("ni,ij,nj->n", xc, cov, xc) + float(np.sum(cov * cov))
    beta = float(np.sum(weight * weight * err)) / (total * total)
    lam = (1.0 if dist <= 0.0 else min(1.0, beta / dist)) if shrinkage is None else shrinkage
    shrunk = (1.0 - lam) * cov + lam * mu * np.eye(f)
    coef = np.linalg.solve(shrunk, means.T).T  # (T, F)
    with np.errstate(divide="ignore"):
        prior = np.log(counts / total)
    intercept = np.where(have, prior - 0.5 * np.sum(coef * means, axis=1), -1e3)
    return coef, intercept


def fit_head(
    features: np.ndarray,
    labels: np.ndarray,
    groups: np.ndarray,
    ratios: np.ndarray,
    n_tasks: int,
    fractions: np.ndarray | None = None,
) -> RecognitionHead:
    """Fit the head on training rows: one linear classifier per observed fraction, each choosing its
    model family, features, training rows and ``C`` (or LDA temperature) by grouped CV (see the module
    docstring).

    Args:
        features: (n, F) raw head features (:func:`head_features`; the last ``n_tasks`` columns are the
            generative log posterior).
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
    uniq = np.unique(groups)
    fold_of = {g: i % HEAD_FOLDS for i, g in enumerate(uniq)}
    folds = np.array([fold_of[g] for g in groups])
    n_feat = features.shape[1]
    column_sets = (np.arange(n_feat), np.arange(n_feat - n_tasks))  # all features, the window alone
    # training on every row alike is the same problem for every fraction (only its score differs)
    shared = [
        _CvPath(features[:, cols], labels, folds, np.ones(labels.size), n_tasks) for cols in column_sets
    ]
    fits = []
    for here in weights:
        best_score = np.inf
        best: tuple[np.ndarray, _CvPath, int, np.ndarray] | None = None
        for cols, all_rows in zip(column_sets, shared, strict=True):
            for path in (_CvPath(features[:, cols], labels, folds, here, n_tasks), all_rows):
                scores = (path.log_loss @ here) / float(here.sum())
                j = int(np.argmin(scores))
                if scores[j] < best_score:
                    best_score, best = scores[j], (cols, path, j, scores)
        assert best is not None  # the cross-validated log losses are finite
        cols, path, j, scores = best
        w_fit, b = path.final(j)
        coef = np.zeros((n_tasks, n_feat))
        coef[:, cols] = w_fit
        mean, scale = np.zeros(n_feat), np.ones(n_feat)
        mean[cols], scale[cols] = path.mean, path.scale
        kind = LOGISTIC if j < len(HEAD_C_GRID) else LDA
        fits.append(
            (coef, b, mean, scale, np.array(_CvPath.parameter(j)), scores, kind, float(cols.size == n_feat))
        )
    coefs, intercepts, means, scales, cs, cv_loss, kinds, generative = (
        np.stack(a) for a in zip(*fits, strict=True)
    )
    return RecognitionHead(
        levels, coefs, intercepts, means, scales, cs, cv_loss, kind=kinds.astype(float), generative=generative
    )


class _CvPath:
    """The grouped cross-validation of one set of training rows (row weights ``pool`` (n,)) and
    features: standardisation on the used rows, per fold the logistic regressions along the path of
    increasing ``C`` (each warm-started from the previous one) and the LDA (each temperature), and
    every row's held-out log loss.

    Attributes:
        mean, scale: (F,) the standardisation.
        log_loss: (len(HEAD_C_GRID) + len(LDA_TEMPERATURE_GRID), n) per candidate, every row's log
            loss when its fold was held out.
    """

    def __init__(
        self, features: np.ndarray, labels: np.ndarray, folds: np.ndarray, pool: np.ndarray, n_tasks: int
    ) -> None:
        used = pool > 0.0
        self.mean = features[used].mean(axis=0)
        scale = features[used].std(axis=0)
        self.scale = np.where(scale > 1e-12, scale, 1.0)
        self.x = (features - self.mean) / self.scale
        self.labels, self.pool, self.used, self.n_tasks = labels, pool, used, n_tasks
        n_c = len(HEAD_C_GRID)
        self.log_loss = np.zeros((n_c + len(LDA_TEMPERATURE_GRID), labels.size))
        self._final: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        gammas = np.asarray(LDA_TEMPERATURE_GRID)
        for k in range(int(folds.max()) + 1):
            train = used & (folds != k)
            test = folds == k
            rows = np.arange(int(test.sum()))
            x_train, y_train, w_train = self.x[train], labels[train], pool[train]
            x_test, y_test = self.x[test], labels[test]
            theta = None
            for j, c in enumerate(HEAD_C_GRID):
                w, b, theta = fit_softmax(x_train, y_train, n_tasks, c, w_train, theta)
                logp = _log_softmax(x_test @ w.T + b)
                self.log_loss[j, test] = -logp[rows, y_test]
            w, b = fit_lda(x_train, y_train, n_tasks, w_train)
            z = x_test @ w.T + b
            for j, g in enumerate(gammas):
                logp = _log_softmax(g * z)
                self.log_loss[n_c + j, test] = -logp[rows, y_test]

    @staticmethod
    def parameter(j: int) -> float:
        """The ``C`` (logistic regression) or temperature (LDA) of candidate ``j``."""
        n_c = len(HEAD_C_GRID)
        return float(HEAD_C_GRID[j] if j < n_c else LDA_TEMPERATURE_GRID[j - n_c])

    def final(self, j: int) -> tuple[np.ndarray, np.ndarray]:
        """The classifier (W, b) of candidate ``j`` on every used row (cached)."""
        if j not in self._final:
            u = self.used
            x, y, pool = self.x[u], self.labels[u], self.pool[u]
            if j < len(HEAD_C_GRID):
                w, b, _ = fit_softmax(x, y, self.n_tasks, HEAD_C_GRID[j], pool)
            else:
                w, b = fit_lda(x, y, self.n_tasks, pool)
                gamma = self.parameter(j)
                w, b = gamma * w, gamma * b
            self._final[j] = (w, b)
        return self._final[j]
