"""The registered baselines. A new one is a file with its estimator factory plus one entry here
(or, at run time, ``CLASSIFIERS.register(name, factory)``)."""

from __future__ import annotations

from .base import ClassifierFactory, Registry, RegressorFactory
from .knn import make_knn
from .lda import make_lda
from .logistic_regression import make_logistic_regression
from .ridge import make_ridge

CLASSIFIERS: Registry[ClassifierFactory] = Registry(
    "classifier", {"logistic_regression": make_logistic_regression, "lda": make_lda}
)
"""Recognition baselines: name -> factory of the labels ``y``."""

REGRESSORS: Registry[RegressorFactory] = Registry("regressor", {"ridge": make_ridge, "knn": make_knn})
"""Motion-prediction baselines: name -> factory of the number of training demos of the task."""
