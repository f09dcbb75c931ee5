"""Recognition baseline ``lda``: linear discriminant analysis with Ledoit-Wolf shrinkage of the
pooled covariance, estimated on the training demos."""

from __future__ import annotations

import numpy as np

from .base import Classifier


def make_lda(y: np.ndarray) -> Classifier:
    """An unfitted shrinkage LDA (the labels ``y`` (n,) are not needed to configure it)."""
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis

    return LinearDiscriminantAnalysis(solver="lsqr", shrinkage="auto")
