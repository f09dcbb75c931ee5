"""Motion baseline ``ridge``: a ridge regression, its penalty chosen by efficient leave-one-out."""

from __future__ import annotations

import numpy as np

from .base import Estimator

RIDGE_ALPHAS = tuple(np.logspace(-3, 4, 15))
"""Ridge penalties tried by ``RidgeCV`` (standardised features)."""


def make_ridge(n: int) -> Estimator:
    """An unfitted ``RidgeCV`` (the number ``n`` of training demos is not needed to configure it)."""
    from sklearn.linear_model import RidgeCV

    return RidgeCV(alphas=list(RIDGE_ALPHAS))
