"""Reference baselines for the evaluation: what a user would try first, with scikit-learn.

On exactly the windows ipromp_pin sees (the first ``obs_ratio`` of each demo's observed groups),
every demo is reduced to **window features**: per observed channel, the mean and the last valid
value over the window (missing samples skipped; a group with no valid sample in the window is
imputed with the training mean), standardised on the training demos. From them:

* recognition: a multinomial logistic regression (``logistic_regression``, its penalty ``C``
  chosen by stratified 5-fold cross-validation of the log loss on the training demos,
  ``LogisticRegressionCV``) and linear discriminant analysis (``lda``, Ledoit-Wolf shrinkage of the
  pooled covariance, estimated on the training demos);
* the robot's motion, per task (the true task given, as for ipromp_pin's errors on the correctly
  recognised trials): a ridge regression (``ridge``, penalty by efficient leave-one-out, ``RidgeCV``)
  and a k-nearest-neighbours regressor (``knn``, number of neighbours and weighting by 5-fold
  ``GridSearchCV``) of the hand-over gripper position in [m] (the final robot configuration through
  forward kinematics) and, separately, of the joint trajectory in [rad] at :data:`N_PHASES`
  normalised phases over the unobserved part ``[obs_ratio, 1]``.

Every setting is chosen on the training demos only. scikit-learn is an optional dependency (the
``baselines`` extra): :func:`require_sklearn` says so in one line when it is missing.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from ..data import ROBOT, Demo
from ..exceptions import IPrompPinError

CLASSIFIERS = ("logistic_regression", "lda")
"""Names of the recognition baselines."""

REGRESSORS = ("ridge", "knn")
"""Names of the motion-prediction baselines."""

N_PHASES = 50
"""Normalised phases over ``[obs_ratio, 1]`` at which trajectories are predicted and compared."""

CV_FOLDS = 5
"""Folds of the baselines' cross-validations on the training demos (fewer when a task has fewer demos)."""

RIDGE_ALPHAS = tuple(np.logspace(-3, 4, 15))
"""Ridge penalties tried by ``RidgeCV`` (standardised features)."""

KNN_NEIGHBOURS = (1, 2, 3, 5, 7, 10)
"""Numbers of neighbours tried by the kNN regressor's grid search (those below the fold size)."""

LOGISTIC_CS = tuple(np.logspace(-3, 3, 13))
"""Inverse penalties ``C`` tried by ``LogisticRegressionCV``."""

FK = Callable[[np.ndarray], np.ndarray]
"""Forward kinematics: joint configurations (n, 7) in [rad] -> gripper positions (n, 3) in [m]."""


class MissingDependencyError(IPrompPinError):
    """An optional dependency is not installed."""


def require_sklearn() -> None:
    """Raise :class:`MissingDependencyError` (one line) when scikit-learn is not installed."""
    try:
        import sklearn  # noqa: F401
    except ImportError as exc:
        raise MissingDependencyError(
            "--baselines needs scikit-learn: pip install 'ipromp_pin[baselines]' (or scikit-learn)"
        ) from exc


def window_features(window: Demo, observe: Sequence[str]) -> np.ndarray:
    """Window features (2 D_o,) of an observed window: per channel of the observed groups, in
    ``observe`` order, the mean and the last valid value (NaN for a group with no valid sample)."""
    means, lasts = [], []
    for g in observe:
        v = np.asarray(window.groups[g], dtype=float)
        valid = ~window.missing[g] if g in window.missing else np.ones(v.shape[0], dtype=bool)
        if np.any(valid):
            means.append(v[valid].mean(axis=0))
            lasts.append(v[valid][-1])
        else:
            means.append(np.full(v.shape[1], np.nan))
            lasts.append(np.full(v.shape[1], np.nan))
    return np.concatenate(means + lasts)


def phase_trajectory(demo: Demo, obs_ratio: float) -> np.ndarray:
    """The demo's robot joint angles (N_PHASES, J) in [rad] at normalised phases over [obs_ratio, 1]."""
    q = demo.groups[ROBOT]
    z = np.linspace(obs_ratio, 1.0, N_PHASES)
    t = demo.t - demo.t[0]
    return np.stack([np.interp(z * t[-1], t, q[:, j]) for j in range(q.shape[1])], axis=1)


@dataclass
class BaselineTrial:
    """One baseline's outcome on one test trial.

    Attributes:
        predicted: Recognised task (classifiers), or the true task (regressors are given it).
        posterior: Predicted probability of the true task (classifiers; NaN for regressors).
        brier: Multi-class Brier score of the predicted probabilities (classifiers; NaN otherwise).
        joint_rmse_rad: RMSE over joints and the unobserved phases, in [rad] (regressors).
        final_joint_error_rad: RMS over joints of the final configuration error, in [rad] (regressors).
        handover_error_cm: Gripper position error at the hand-over, in [cm] (regressors with FK).
    """

    predicted: str
    posterior: float = float("nan")
    brier: float = float("nan")
    joint_rmse_rad: float = float("nan")
    final_joint_error_rad: float = float("nan")
    handover_error_cm: float = float("nan")


def _folds(n: int) -> int:
    return max(2, min(CV_FOLDS, n))


def _standardiser() -> object:
    """Imputation of missing window features by the training mean, then standardisation."""
    from sklearn.impute import SimpleImputer
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    return make_pipeline(SimpleImputer(), StandardScaler())


def _classifiers(y: np.ndarray) -> dict[str, object]:
    from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
    from sklearn.linear_model import LogisticRegressionCV
    from sklearn.model_selection import StratifiedKFold

    n_min = int(np.min(np.unique(y, return_counts=True)[1]))
    cv = StratifiedKFold(_folds(n_min), shuffle=True, random_state=0)
    return {
        "logistic_regression": LogisticRegressionCV(
            Cs=list(LOGISTIC_CS),
            cv=cv,
            scoring="neg_log_loss",
            max_iter=5000,
            l1_ratios=(0.0,),
            use_legacy_attributes=False,
        ),
        "lda": LinearDiscriminantAnalysis(solver="lsqr", shrinkage="auto"),
    }


def _regressor(name: str, n: int) -> object:
    from sklearn.linear_model import RidgeCV
    from sklearn.model_selection import GridSearchCV, KFold
    from sklearn.neighbors import KNeighborsRegressor

    if name == "ridge":
        return RidgeCV(alphas=list(RIDGE_ALPHAS))
    folds = _folds(n)
    largest = n - -(-n // folds)  # training demos in the smallest training fold
    grid = {
        "n_neighbors": [k for k in KNN_NEIGHBOURS if k <= largest] or [1],
        "weights": ["uniform", "distance"],
    }
    return GridSearchCV(
        KNeighborsRegressor(algorithm="brute"),
        grid,
        cv=KFold(folds, shuffle=True, random_state=0),
        scoring="neg_mean_squared_error",
    )


class WindowBaselines:
    """The baselines of one observed set and observed fraction, fitted on training demos.

    Args:
        observe: Observed human groups.
        obs_ratio: Observed fraction of every demo, in (0, 1].
        fk: Forward kinematics for the hand-over position (None: no hand-over regressor).
    """

    def __init__(self, observe: Sequence[str], obs_ratio: float, fk: FK | None = None) -> None:
        self.observe = list(observe)
        self.obs_ratio = float(obs_ratio)
        self.fk = fk

    def features(self, demos: Sequence[Demo]) -> np.ndarray:
        """Window features (n, 2 D_o) of the demos' first ``obs_ratio`` (raw: not standardised)."""
        return np.stack([window_features(d.head(self.obs_ratio, self.observe), self.observe) for d in demos])

    def fit(self, train: Sequence[Demo]) -> WindowBaselines:
        """Fit every baseline on the training demos (settings by cross-validation on them)."""
        require_sklearn()
        # one thread: on these tiny problems OpenMP and BLAS threads cost far more than they save
        with threadpool_limits(limits=1):
            return self._fit(train)

    def _fit(self, train: Sequence[Demo]) -> WindowBaselines:
        self.standardiser_ = _standardiser()
        x = self.standardiser_.fit_transform(self.features(train))
        y = np.array([d.task for d in train])
        self.tasks_ = sorted(set(y.tolist()))
        self.classifiers_ = {name: clf.fit(x, y) for name, clf in _classifiers(y).items()}
        self.regressors_: dict[tuple[str, str, str], object] = {}
        for task in self.tasks_:
            rows = np.flatnonzero(y == task)
            demos = [train[i] for i in rows]
            targets = {"trajectory": np.stack([phase_trajectory(d, self.obs_ratio).ravel() for d in demos])}
            if self.fk is not None:
                targets["handover"] = self.fk(np.stack([d.groups[ROBOT][-1] for d in demos]))
            for name in REGRESSORS:
                for kind, target in targets.items():
                    self.regressors_[(name, task, kind)] = _regressor(name, rows.size).fit(x[rows], target)
        return self

    def score(self, test: Sequence[Demo]) -> list[dict[str, BaselineTrial]]:
        """Per test demo, every baseline's outcome (regressors are given the true task)."""
        with threadpool_limits(limits=1):
            return self._score(test)

    def _score(self, test: Sequence[Demo]) -> list[dict[str, BaselineTrial]]:
        x = self.standardiser_.transform(self.features(test))
        out: list[dict[str, BaselineTrial]] = [{} for _ in test]
        for name, clf in self.classifiers_.items():
            proba = clf.predict_proba(x)
            classes = list(clf.classes_)
            for i, d in enumerate(test):
                onehot = np.array([c == d.task for c in classes], dtype=float)
                p_true = float(proba[i, classes.index(d.task)]) if d.task in classes else 0.0
                out[i][name] = BaselineTrial(
                    predicted=str(classes[int(np.argmax(proba[i]))]),
                    posterior=p_true,
                    brier=float(np.sum((proba[i] - onehot) ** 2)),
                )
        for i, d in enumerate(test):
            if d.task not in self.tasks_:
                continue
            q_true = phase_trajectory(d, self.obs_ratio)
            p_true = self.fk(d.groups[ROBOT][-1:])[0] if self.fk is not None else None
            for name in REGRESSORS:
                q = (
                    self.regressors_[(name, d.task, "trajectory")]
                    .predict(x[i : i + 1])[0]
                    .reshape(q_true.shape)
                )
                trial = BaselineTrial(
                    predicted=d.task,
                    joint_rmse_rad=float(np.sqrt(np.mean((q - q_true) ** 2))),
                    final_joint_error_rad=float(np.sqrt(np.mean((q[-1] - q_true[-1]) ** 2))),
                )
                if p_true is not None:
                    p = self.regressors_[(name, d.task, "handover")].predict(x[i : i + 1])[0]
                    trial.handover_error_cm = float(np.linalg.norm(p - p_true) * 100.0)
                out[i][name] = trial
        return out
