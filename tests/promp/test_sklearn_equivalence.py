"""The model's own small regressions give scikit-learn's answers on random problems.

The recognition head's logistic regression and LDA and the hand-over's ridge and k-nearest-neighbour
regressions are written here rather than called from scikit-learn because they train several times
faster at the sizes a fit poses them (``benchmarks/sklearn_models.py``, docs/benchmarks.md). These
tests hold each to the library's estimator with the sample weights, penalties and settings the model
uses.
"""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.promp.handover import KNN_NEIGHBOURS, RIDGE_PENALTIES, fit_knn, fit_ridge
from ipromp_pin.promp.head import HEAD_C_GRID, fit_lda, fit_softmax

sklearn = pytest.importorskip("sklearn")
from sklearn.covariance import ledoit_wolf_shrinkage  # noqa: E402
from sklearn.discriminant_analysis import LinearDiscriminantAnalysis  # noqa: E402
from sklearn.linear_model import LogisticRegression, RidgeCV  # noqa: E402
from sklearn.model_selection import LeaveOneOut, cross_val_predict  # noqa: E402
from sklearn.neighbors import KNeighborsRegressor  # noqa: E402
from sklearn.preprocessing import StandardScaler  # noqa: E402


def _classes(seed: int, n: int, f: int, n_classes: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Standardised features (n, f) that separate ``n_classes`` classes a little, labels (n,) and
    positive row weights (n,) as the head's interpolation gives them (some 0, some fractional)."""
    rng = np.random.default_rng(seed)
    y = np.arange(n) % n_classes
    x = rng.normal(size=(n, f)) + 0.8 * rng.normal(size=(n_classes, f))[y]
    x = (x - x.mean(axis=0)) / x.std(axis=0)
    w = rng.choice([0.0, 0.3, 0.7, 1.0], size=n, p=[0.1, 0.2, 0.2, 0.5])
    return x, y, w


def _sklearn_logistic(x, y, w, n_classes, c, tol, max_iter):
    """scikit-learn's (W (T, F), b (T,)) in the head's parametrisation (two classes: one binary model
    whose penalty is that of the symmetric softmax with half its ``C``)."""
    m = LogisticRegression(C=2 * c if n_classes == 2 else c, tol=tol, max_iter=max_iter)
    m.fit(x, y, sample_weight=w)
    if n_classes == 2:
        v, b = m.coef_[0], m.intercept_[0]
        return np.stack([-v / 2, v / 2]), np.array([-b / 2, b / 2])
    return m.coef_, m.intercept_


@pytest.mark.parametrize("n_classes", [2, 3, 5])
@pytest.mark.parametrize("c", [HEAD_C_GRID[0], 1.0, HEAD_C_GRID[-1]])
def test_softmax_fit_is_sklearns_logistic_regression(n_classes: int, c: float) -> None:
    x, y, w = _classes(n_classes, 90, 12, n_classes)
    # both solved tightly: the same minimiser (to 1e-5 of the largest weight: C = 100 is flat near it)
    tight = {"gtol": 1e-10, "ftol": 1e-15, "maxiter": 10000}
    w_ours, b_ours, _ = fit_softmax(x, y, n_classes, c, w, options=tight)
    w_ref, b_ref = _sklearn_logistic(x, y, w, n_classes, c, tol=1e-10, max_iter=10000)
    scale = max(1.0, float(np.abs(w_ref).max()))
    assert np.allclose(w_ours, w_ref, rtol=0, atol=1e-5 * scale)
    # the intercepts of a softmax are defined up to a common constant
    assert np.allclose(b_ours - b_ours.mean(), b_ref - b_ref.mean(), rtol=0, atol=1e-5 * scale)
    # as the head runs it (scipy's and scikit-learn's default tolerances): the same probabilities to 1e-3
    w_run, b_run, _ = fit_softmax(x, y, n_classes, c, w)
    w_lib, b_lib = _sklearn_logistic(x, y, w, n_classes, c, tol=1e-5, max_iter=500)

    def proba(wt: np.ndarray, b: np.ndarray) -> np.ndarray:
        z = x @ wt.T + b
        e = np.exp(z - z.max(axis=1, keepdims=True))
        return e / e.sum(axis=1, keepdims=True)

    assert np.abs(proba(w_run, b_run) - proba(w_lib, b_lib)).max() < 1e-3


def test_lda_fit_is_sklearns_shrunk_lda() -> None:
    for seed, (n, f) in enumerate([(60, 8), (30, 25), (200, 39)]):
        x, y, _ = _classes(seed, n, f, 3)
        coef, intercept = fit_lda(x, y, 3, np.ones(n))
        means = np.stack([x[y == k].mean(axis=0) for k in range(3)])
        lam = ledoit_wolf_shrinkage(x - means[y], assume_centered=True)
        ref = LinearDiscriminantAnalysis(solver="lsqr", shrinkage=lam).fit(x, y)
        assert np.allclose(coef, ref.coef_, rtol=1e-9, atol=1e-9)
        assert np.allclose(intercept, ref.intercept_, rtol=1e-9, atol=1e-9)


def test_weighted_lda_is_sklearns_lda_of_repeated_rows() -> None:
    """Integer row weights weigh as repeated rows do (scikit-learn's LDA takes no weights)."""
    x, y, _ = _classes(7, 45, 6, 3)
    reps = np.random.default_rng(7).integers(1, 4, size=45)
    coef, intercept = fit_lda(x, y, 3, reps.astype(float), shrinkage=0.3)
    ref = LinearDiscriminantAnalysis(solver="lsqr", shrinkage=0.3).fit(
        np.repeat(x, reps, 0), np.repeat(y, reps)
    )
    assert np.allclose(coef, ref.coef_, rtol=1e-9, atol=1e-9)
    assert np.allclose(intercept, ref.intercept_, rtol=1e-9, atol=1e-9)


def _regression(seed: int, n: int, f: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Raw features (n, f) on several scales and targets (n, m) partly linear in them."""
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, f)) * rng.uniform(0.1, 10.0, size=f) + rng.normal(size=f)
    y = x @ rng.normal(size=(f, m)) * 0.1 + rng.normal(size=(n, m))
    return x, y


@pytest.mark.parametrize(("n", "f"), [(20, 8), (12, 16), (40, 3)])
def test_ridge_fit_is_sklearns_ridge_cv(n: int, f: int) -> None:
    x, y = _regression(n, n, f, 3)
    fit = fit_ridge(x, y)
    scaler = StandardScaler().fit(x)
    ref = RidgeCV(alphas=RIDGE_PENALTIES, scoring="neg_mean_squared_error", store_cv_results=True)
    ref.fit(scaler.transform(x), y)
    assert fit.penalty == pytest.approx(ref.alpha_, rel=1e-12)
    j = RIDGE_PENALTIES.index(fit.penalty)
    # with a scorer, cv_results_ holds every row's leave-one-out prediction
    assert np.allclose(fit.residuals, y - ref.cv_results_[:, :, j], rtol=1e-8, atol=1e-8)
    probe = np.random.default_rng(n).normal(size=(5, f)) * x.std(axis=0) + x.mean(axis=0)
    ours = np.stack([fit.predict(p) for p in probe])
    assert np.allclose(ours, ref.predict(scaler.transform(probe)), rtol=1e-8, atol=1e-8)


@pytest.mark.parametrize(("n", "f"), [(20, 8), (8, 3), (15, 12)])
def test_knn_fit_is_sklearns_nearest_neighbours(n: int, f: int) -> None:
    x, y = _regression(n + 100, n, f, 3)
    fit = fit_knn(x, y)
    assert fit is not None
    xs = StandardScaler().fit_transform(x)
    sse = {}
    for k in KNN_NEIGHBOURS:
        if k > n - 1:
            break
        for weights in ("uniform", "distance"):
            loo = cross_val_predict(
                KNeighborsRegressor(n_neighbors=k, weights=weights), xs, y, cv=LeaveOneOut()
            )
            sse[(k, weights == "distance")] = (float(np.sum((y - loo) ** 2)), y - loo)
    best = min(sse, key=lambda key: sse[key][0])
    assert (fit.k, fit.distance) == best
    assert np.allclose(fit.residuals, sse[best][1], rtol=1e-9, atol=1e-9)
    ref = KNeighborsRegressor(n_neighbors=fit.k, weights="distance" if fit.distance else "uniform").fit(xs, y)
    probe = np.random.default_rng(n).normal(size=(5, f)) * x.std(axis=0) + x.mean(axis=0)
    ours = np.stack([fit.predict(p) for p in probe])
    assert np.allclose(ours, ref.predict((probe - fit.mean) / fit.scale), rtol=1e-9, atol=1e-9)
