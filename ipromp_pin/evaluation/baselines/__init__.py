"""Reference baselines for the evaluation: what a user would try first, with scikit-learn.

On exactly the windows ipromp_pin sees (the first ``obs_ratio`` of each demo's observed groups, or
its first seconds: :mod:`ipromp_pin.evaluation.windows`; training and test demos alike), every demo
is reduced to **window features**: per observed channel, the mean and the last valid value over the
window (missing samples skipped; a group with no valid sample in the window is imputed with the
training mean), standardised on the training demos. From them:

* recognition: a multinomial logistic regression (``logistic_regression``, its penalty ``C``
  chosen by stratified 5-fold cross-validation of the log loss on the training demos,
  ``LogisticRegressionCV``) and linear discriminant analysis (``lda``, Ledoit-Wolf shrinkage of the
  pooled covariance, estimated on the training demos);
* the robot's motion, per task (the true task given, as for ipromp_pin's errors on the correctly
  recognised trials): a ridge regression (``ridge``, penalty by efficient leave-one-out, ``RidgeCV``)
  and a k-nearest-neighbours regressor (``knn``, number of neighbours and weighting by 5-fold
  ``GridSearchCV``) of the hand-over gripper position in [m] (the final robot configuration through
  forward kinematics) and, separately, of the joint trajectory in [rad] at :data:`N_PHASES`
  normalised phases over the unobserved part ``[obs_ratio, 1]`` of each demo (``obs_ratio``: the
  fraction of the demo's own length its window covers).

Every setting is chosen on the training demos only. scikit-learn is an optional dependency (the
``baselines`` extra): :func:`require_sklearn` says so in one line when it is missing.

A baseline is one file (its estimator factory) plus one entry in :mod:`.registry`.
"""

from .base import CV_FOLDS, Factory, MissingDependencyError, Registry, require_sklearn
from .features import FK, N_PHASES, phase_trajectory, window_features
from .knn import KNN_NEIGHBOURS
from .logistic_regression import LOGISTIC_CS
from .registry import CLASSIFIERS, REGRESSORS
from .ridge import RIDGE_ALPHAS
from .window import BaselineTrial, WindowBaselines

__all__ = [
    "CLASSIFIERS",
    "CV_FOLDS",
    "FK",
    "KNN_NEIGHBOURS",
    "LOGISTIC_CS",
    "N_PHASES",
    "REGRESSORS",
    "RIDGE_ALPHAS",
    "BaselineTrial",
    "Factory",
    "MissingDependencyError",
    "Registry",
    "WindowBaselines",
    "phase_trajectory",
    "require_sklearn",
    "window_features",
]
