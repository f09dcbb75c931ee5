"""Recognition baseline ``logistic_regression``: a multinomial logistic regression, its penalty ``C``
chosen by stratified cross-validation of the log loss on the training demos."""

from __future__ import annotations

import numpy as np

from .base import Classifier, folds

LOGISTIC_CS = tuple(np.logspace(-3, 3, 13))
"""Inverse penalties ``C`` tried by ``LogisticRegressionCV``."""


def make_logistic_regression(y: np.ndarray) -> Classifier:
    """An unfitted ``LogisticRegressionCV`` for the training labels ``y`` (n,)."""
    from sklearn.linear_model import LogisticRegressionCV
    from sklearn.model_selection import StratifiedKFold

    n_min = int(np.min(np.unique(y, return_counts=True)[1]))
    cv = StratifiedKFold(folds(n_min), shuffle=True, random_state=0)
    return LogisticRegressionCV(
        Cs=list(LOGISTIC_CS),
        cv=cv,
        scoring="neg_log_loss",
        max_iter=5000,
        l1_ratios=(0.0,),
        use_legacy_attributes=False,
    )
