"""Motion baseline ``knn``: a k-nearest-neighbours regressor, the number of neighbours and the
weighting chosen by a cross-validated grid search on the training demos."""

from __future__ import annotations

from .base import Estimator, folds

KNN_NEIGHBOURS = (1, 2, 3, 5, 7, 10)
"""Numbers of neighbours tried by the kNN regressor's grid search (those below the fold size)."""


def make_knn(n: int) -> Estimator:
    """An unfitted ``GridSearchCV`` over kNN regressors for ``n`` training demos."""
    from sklearn.model_selection import GridSearchCV, KFold
    from sklearn.neighbors import KNeighborsRegressor

    k = folds(n)
    largest = n - -(-n // k)  # training demos in the smallest training fold
    grid = {
        "n_neighbors": [m for m in KNN_NEIGHBOURS if m <= largest] or [1],
        "weights": ["uniform", "distance"],
    }
    return GridSearchCV(
        KNeighborsRegressor(algorithm="brute"),
        grid,
        cv=KFold(k, shuffle=True, random_state=0),
        scoring="neg_mean_squared_error",
    )
