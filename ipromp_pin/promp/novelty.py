"""Open-set recognition: is the observed motion one of the learned tasks at all?

The task posterior is normalised over the learned tasks, so a motion the model never learned still
gets a task with posterior near 1. The novelty detector scores how far the observed window is from
every learned task, and a split-conformal p-value says how unusual that score is among observations
of known tasks:

* the score of an observation is ``min_k d_k(x)``, with ``x`` the observed window's features (the
  first, mean and last value of every observed dim in scaled units, :class:`~ipromp_pin.promp.window.
  WindowSummary`; or its mean and last values only) and ``d_k`` minus twice the log density (up to a
  constant) of task ``k``'s Gaussian over those features, fitted on the held-out rows of task ``k``
  at each observed fraction of :data:`~ipromp_pin.promp.selection.HEAD_RATIOS` (its covariance shrunk
  toward a multiple of the identity: Ledoit-Wolf's intensity or a fixed one), interpolated linearly
  between the two fractions around the task's own estimate ``t_last / (alpha_k T_norm)``;
* the calibration scores are those of the model's own held-out training rows (the leave-one-out rows
  of :func:`~ipromp_pin.promp.selection.choose_noise`; a row's own task's Gaussians are refitted
  without the rows of its demo, so each row is scored by a detector that did not see it);
* the p-value of a score ``s`` is ``(1 + #{calibration scores >= s}) / (n + 1)`` over the calibration
  rows observed for a similar time (the same nearest fraction of ``t_last / T_norm``, when at least
  :data:`MIN_GROUP_ROWS` rows are; all rows otherwise): an observation is *known* when ``p > alpha``.
  For an observation exchangeable with the calibration rows (a new demo of a known task), the
  probability of ``p <= alpha`` is at most ``alpha`` (split-conformal prediction; Vovk et al. 2005).

The shrinkage and the feature set are chosen by leave-one-task-out cross-validation on the same
held-out training rows: each training task in turn plays the unknown one, the others' rows the known
ones, and the candidate with the largest mean area under the ROC curve is kept
(:func:`fit_novelty`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.linalg.blas import dtrsv

from .head_features import interpolation

__all__ = [
    "DEFAULT_ALPHA",
    "NOVELTY_FEATURES",
    "NOVELTY_SHRINKAGE_GRID",
    "NoveltyDetector",
    "auroc",
    "conformal_p_values",
    "fit_novelty",
    "with_added_task",
]

DEFAULT_ALPHA = 0.05
"""Default largest fraction of known-task observations refused as unknown."""

NOVELTY_SHRINKAGE_GRID = (-1.0, 0.05, 0.2, 0.5, 0.8)
"""Candidate shrinkage intensities of the tasks' covariances (-1: Ledoit-Wolf's)."""

NOVELTY_FEATURES = ("first_mean_last", "mean_last")
"""Candidate feature sets: the window's first, mean and last values, or its mean and last values."""

MIN_GROUP_ROWS = 20
"""Fewest calibration rows of one observed-time group for its own p-values (else all rows count)."""

MIN_TASK_ROWS = 3
"""Fewest held-out rows of a task at every fraction for a detector."""

_JITTER = 1e-6
"""Relative ridge added to every shrunk covariance (a task whose rows coincide)."""


def auroc(known: np.ndarray, novel: np.ndarray) -> float:
    """Area under the ROC curve of scores that should be higher for ``novel`` (n_n,) than for ``known``
    (n_k,): P(novel > known) + P(tie) / 2 (NaN when either is empty)."""
    known, novel = np.asarray(known, float), np.asarray(novel, float)
    if known.size == 0 or novel.size == 0:
        return math.nan
    order = np.sort(known)
    below = np.searchsorted(order, novel, side="left")
    above_or_eq = np.searchsorted(order, novel, side="right")
    return float(np.mean(below + 0.5 * (above_or_eq - below)) / known.size)


def conformal_p_values(calibration: np.ndarray, scores: np.ndarray) -> np.ndarray:
    """Split-conformal p-values (n,) of ``scores`` (n,) against the calibration scores (m,):
    ``(1 + #{calibration >= s}) / (m + 1)``."""
    cal = np.sort(np.asarray(calibration, float))
    s = np.asarray(scores, float)
    n_ge = cal.size - np.searchsorted(cal, s, side="left")
    return (1.0 + n_ge) / (cal.size + 1.0)


def _columns(n_obs: int, features: str) -> np.ndarray:
    """Indices into the (3 D_o,) window vector of a feature set of :data:`NOVELTY_FEATURES`."""
    start = 0 if features == "first_mean_last" else n_obs
    return np.arange(start, 3 * n_obs)


def _gaussian(x: np.ndarray, shrinkage: float) -> tuple[np.ndarray, np.ndarray]:
    """Mean (F,) and lower Cholesky factor (F, F) of the shrunk covariance of rows ``x`` (n, F)
    (``shrinkage`` -1: Ledoit-Wolf's intensity)."""
    n, f = x.shape
    mean = x.mean(axis=0)
    xc = x - mean
    cov = xc.T @ xc / n
    mu = float(np.trace(cov)) / f
    if shrinkage < 0.0:
        target = cov - mu * np.eye(f)
        dist = float(np.sum(target * target))
        sq = np.sum(xc * xc, axis=1)
        err = sq * sq - 2.0 * np.einsum("ni,ij,nj->n", xc, cov, xc) + float(np.sum(cov * cov))
        lam = 1.0 if dist <= 0.0 else min(1.0, float(np.sum(err)) / (n * n) / dist)
    else:
        lam = shrinkage
    shrunk = (1.0 - lam) * cov + (lam * mu + _JITTER * max(mu, 1e-12)) * np.eye(f)
    return mean, np.linalg.cholesky(shrunk)


@dataclass(frozen=True)
class NoveltyDetector:
    """The fitted novelty score and its conformal calibration (see the module docstring).

    Attributes:
        alpha: Largest fraction of known-task observations refused (0 < alpha < 1).
        ratios: (R,) increasing observed fractions of the tasks' Gaussians.
        columns: (F,) indices of the features in the window vector (3 D_o,).
        mean: (T, R, F) the Gaussians' means (scaled units).
        chol: (T, R, F, F) lower Cholesky factors of their covariances.
        calibration: (n,) scores of the held-out training rows.
        calibration_group: (n,) their observed-time group (index into ``ratios``).
        shrinkage: The chosen shrinkage intensity (-1: Ledoit-Wolf's).
        cv_auroc: (len(NOVELTY_FEATURES) * len(NOVELTY_SHRINKAGE_GRID),) leave-one-task-out AUROC of
            every candidate (features major; NaN with a single task).
    """

    alpha: float
    ratios: np.ndarray
    columns: np.ndarray
    mean: np.ndarray
    chol: np.ndarray
    calibration: np.ndarray
    calibration_group: np.ndarray
    shrinkage: float
    cv_auroc: np.ndarray
    # derived in __post_init__ (not parameters, not compared): Fortran-ordered factors for BLAS'
    # triangular solve, their log determinants (T, R), the fractions as floats
    _chol_f: list = field(init=False, repr=False, compare=False)
    _logdet: np.ndarray = field(init=False, repr=False, compare=False)
    _ratios: list = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        chol = np.asarray(self.chol, dtype=float)
        factors = [
            [np.asfortranarray(chol[k, j]) for j in range(chol.shape[1])] for k in range(chol.shape[0])
        ]
        with np.errstate(divide="ignore", invalid="ignore"):  # a broken factor is refused by check_novelty
            logdet = 2.0 * np.sum(np.log(np.diagonal(chol, axis1=2, axis2=3)), axis=2)
        object.__setattr__(self, "_chol_f", factors)
        object.__setattr__(self, "_logdet", logdet)
        object.__setattr__(self, "_ratios", [float(r) for r in np.asarray(self.ratios).reshape(-1)])

    def _d(self, x: np.ndarray, k: int, j: int) -> float:
        """``d_k`` of the features ``x`` (F,) under task ``k``'s Gaussian at fraction ``j``."""
        z = dtrsv(self._chol_f[k][j], x - self.mean[k, j], lower=1)
        return float(z @ z) + float(self._logdet[k, j])

    def group(self, t_last: float, t_norm: float) -> int:
        """Observed-time group of an observation: the nearest of :attr:`ratios` to ``t_last / T_norm``."""
        return int(np.argmin(np.abs(self.ratios - t_last / t_norm)))

    def score(self, window: np.ndarray, alpha: np.ndarray, t_last: float, t_norm: float) -> float:
        """Novelty score of the window vector (3 D_o,) with the tasks' MAP phases ``alpha`` (T,)
        (non-finite or non-positive: the task cannot explain the observation), ``t_last`` and
        ``T_norm`` in [s]: ``min_k d_k`` (inf when no task can)."""
        x = np.asarray(window, float)[self.columns]
        return min(self.task_score(x, k, float(alpha[k]), t_last, t_norm) for k in range(len(self._chol_f)))

    def task_score(self, x: np.ndarray, k: int, alpha: float, t_last: float, t_norm: float) -> float:
        """``d_k`` of the features ``x`` (F,) (the window's :attr:`columns`) with the task's MAP phase
        ``alpha`` (inf when it cannot explain the observation: non-finite or non-positive)."""
        if not (math.isfinite(alpha) and alpha > 0.0):
            return math.inf
        i, w = interpolation(self._ratios, t_last / (alpha * t_norm))
        d = (1.0 - w) * self._d(x, k, i)
        if w > 0.0:
            d += w * self._d(x, k, i + 1)
        return d

    def p_value(self, score: float, t_last: float, t_norm: float) -> float:
        """Conformal p-value of a score among the calibration rows of the same observed-time group
        (all rows when that group has fewer than :data:`MIN_GROUP_ROWS`)."""
        cal = self.calibration[self.calibration_group == self.group(t_last, t_norm)]
        if cal.size < MIN_GROUP_ROWS:
            cal = self.calibration
        return float(conformal_p_values(cal, np.array([score]))[0])


@dataclass(frozen=True)
class NoveltyRow:
    """One held-out training row as the detector reads it.

    Attributes:
        task: Index of its task.
        demo: Index of its held-out demo (rows of one demo share it).
        window: (3 D_o,) window vector.
        ratio: Its observed fraction (of :data:`~ipromp_pin.promp.selection.HEAD_RATIOS`).
        alpha: (T,) MAP phases of the leave-one-out model.
        t_last: Last observed time in [s].
    """

    task: int
    demo: int
    window: np.ndarray
    ratio: float
    alpha: np.ndarray
    t_last: float


def _fits(
    x: np.ndarray,
    rows: Sequence[NoveltyRow],
    levels: np.ndarray,
    n_tasks: int,
    shrinkage: float,
    skip: int = -1,
    only: int | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Means (T, R, F) and Cholesky factors (T, R, F, F) of the tasks' Gaussians on the rows' features
    ``x`` (n, F), without the rows of demo ``skip`` (``only``: that task's alone, the others' zero)."""
    f = x.shape[1]
    mean, chol = np.zeros((n_tasks, levels.size, f)), np.zeros((n_tasks, levels.size, f, f))
    task = np.array([r.task for r in rows])
    ratio = np.array([r.ratio for r in rows])
    demo = np.array([r.demo for r in rows])
    for k in range(n_tasks) if only is None else (only,):
        for j, level in enumerate(levels):
            sel = (task == k) & (ratio == level) & (demo != skip)
            mean[k, j], chol[k, j] = _gaussian(x[sel], shrinkage)
    return mean, chol


def _row_scores(
    rows: Sequence[NoveltyRow],
    x: np.ndarray,
    levels: np.ndarray,
    n_tasks: int,
    shrinkage: float,
    t_norm: float,
) -> np.ndarray:
    """(n, T) every row's ``d_k`` under every task, its own task's Gaussians without its demo."""
    empty = np.zeros(0)

    def detector(mean: np.ndarray, chol: np.ndarray) -> NoveltyDetector:
        return NoveltyDetector(0.0, levels, np.arange(x.shape[1]), mean, chol, empty, empty, 0.0, empty)

    full = detector(*_fits(x, rows, levels, n_tasks, shrinkage))
    out = np.empty((len(rows), n_tasks))
    loo: dict[int, NoveltyDetector] = {}
    for n, r in enumerate(rows):
        if r.demo not in loo:
            loo[r.demo] = detector(*_fits(x, rows, levels, n_tasks, shrinkage, skip=r.demo, only=r.task))
        for k in range(n_tasks):
            det = loo[r.demo] if k == r.task else full
            out[n, k] = det.task_score(x[n], k, float(r.alpha[k]), r.t_last, t_norm)
    return out


def _cv_auroc(d: np.ndarray, tasks: np.ndarray, n_tasks: int) -> float:
    """Mean leave-one-task-out AUROC of the rows' per-task scores ``d`` (n, T) (NaN with one task)."""
    if n_tasks < 2:
        return math.nan
    values = []
    for u in range(n_tasks):
        keep = np.arange(n_tasks) != u
        score = d[:, keep].min(axis=1)
        values.append(auroc(score[tasks != u], score[tasks == u]))
    return float(np.nanmean(values))


def fit_novelty(
    rows: Sequence[NoveltyRow], n_tasks: int, n_obs: int, t_norm: float, alpha: float = DEFAULT_ALPHA
) -> NoveltyDetector | None:
    """The novelty detector of the held-out training rows (None when a task has fewer than
    :data:`MIN_TASK_ROWS` rows at some fraction: too few to model it).

    Args:
        rows: The held-out rows (every task's, at the fractions of the head).
        n_tasks: Number of tasks T.
        n_obs: Number D_o of observed dims.
        t_norm: ``T_norm`` in [s].
        alpha: Largest fraction of known-task observations to refuse.
    """
    if not rows:
        return None
    levels = np.unique([r.ratio for r in rows])
    tasks = np.array([r.task for r in rows])
    for k in range(n_tasks):
        for level in levels:
            if (
                int(np.unique([r.demo for r in rows if r.task == k and r.ratio == level]).size)
                < MIN_TASK_ROWS
            ):
                return None
    windows = np.array([r.window for r in rows])
    best: tuple[float, int, str, float, np.ndarray] | None = None
    cv = []
    for features in NOVELTY_FEATURES:
        cols = _columns(n_obs, features)
        for shrinkage in NOVELTY_SHRINKAGE_GRID:
            d = _row_scores(rows, windows[:, cols], levels, n_tasks, shrinkage, t_norm)
            value = _cv_auroc(d, tasks, n_tasks)
            cv.append(value)
            key = -math.inf if math.isnan(value) else value
            if best is None or key > best[0]:
                best = (key, len(cv) - 1, features, shrinkage, d.min(axis=1))
    assert best is not None
    _, _, features, shrinkage, calibration = best
    cols = _columns(n_obs, features)
    mean, chol = _fits(windows[:, cols], rows, levels, n_tasks, shrinkage)
    group = np.array([int(np.argmin(np.abs(levels - r.t_last / t_norm))) for r in rows])
    return NoveltyDetector(
        alpha=float(alpha),
        ratios=levels.astype(float),
        columns=cols,
        mean=mean,
        chol=chol,
        calibration=np.asarray(calibration, float),
        calibration_group=group,
        shrinkage=float(shrinkage),
        cv_auroc=np.array(cv, dtype=float),
    )


def with_added_task(
    detector: NoveltyDetector, rows: Sequence[NoveltyRow], t_norm: float
) -> NoveltyDetector | None:
    """``detector`` with a task added after the fit: its Gaussians fitted on its rows ``rows`` (its
    demos' windows at every fraction of :attr:`NoveltyDetector.ratios`, ``task`` the new index, ``alpha``
    the MAP phases of every task, the new one last) with the fitted feature set and shrinkage; its rows'
    scores (its own Gaussians without the row's demo) join the calibration. The fitted tasks' calibration
    scores are kept: with one more task to be near, their scores could only fall, so the kept ones make
    the p-values of known observations larger, never smaller (the false-reject guarantee holds).
    None when the new task has fewer than :data:`MIN_TASK_ROWS` demos (too few to model it)."""
    new = len(detector._chol_f)
    if int(np.unique([r.demo for r in rows]).size) < MIN_TASK_ROWS:
        return None
    x = np.array([np.asarray(r.window, float)[detector.columns] for r in rows])
    levels = np.asarray(detector.ratios, float)
    mean, chol = _fits(x, rows, levels, new + 1, detector.shrinkage, only=new)
    grown = replace(
        detector,
        mean=np.concatenate([detector.mean, mean[new:]]),
        chol=np.concatenate([detector.chol, chol[new:]]),
    )
    scores, loo = [], {}
    for r in rows:
        if r.demo not in loo:
            m, c = _fits(x, rows, levels, new + 1, detector.shrinkage, skip=r.demo, only=new)
            loo[r.demo] = replace(grown, mean=np.concatenate([detector.mean, m[new:]]),
                                  chol=np.concatenate([detector.chol, c[new:]]))  # fmt: skip
        scores.append(loo[r.demo].score(r.window, r.alpha, r.t_last, t_norm))
    group = [int(np.argmin(np.abs(levels - r.t_last / t_norm))) for r in rows]
    return replace(
        grown,
        calibration=np.concatenate([detector.calibration, scores]),
        calibration_group=np.concatenate([detector.calibration_group, group]).astype(
            detector.calibration_group.dtype
        ),
    )


NOVELTY_ARRAYS = ("ratios", "columns", "mean", "chol", "calibration", "calibration_group", "cv_auroc")
"""The detector's arrays in a model file (``novelty_<name>``; :mod:`~ipromp_pin.promp.serialization`)."""

MAX_NOVELTY_SIZE = 100_000
"""Largest number of fractions, features or calibration rows a model file may declare."""


def novelty_meta(detector: NoveltyDetector) -> dict:
    """The detector's header field of a model file (its scalars and sizes)."""
    return {
        "alpha": float(detector.alpha),
        "ratios": int(detector.ratios.size),
        "features": int(detector.columns.size),
        "calibration": int(detector.calibration.size),
        "shrinkage": float(detector.shrinkage),
    }


def novelty_arrays(detector: NoveltyDetector | None) -> dict[str, np.ndarray]:
    """The detector's arrays of a model file (none without a detector)."""
    if detector is None:
        return {}
    return {f"novelty_{name}": np.asarray(getattr(detector, name), dtype=float) for name in NOVELTY_ARRAYS}


def novelty_shapes(meta: object, n_tasks: int, n_obs: int) -> dict[str, tuple[int | None, ...]]:
    """Expected shapes of the detector's arrays of a header field (ValueError naming the problem)."""
    if not isinstance(meta, dict) or set(meta) != {"alpha", "ratios", "features", "calibration", "shrinkage"}:
        raise ValueError("must be null or give alpha, ratios, features, calibration and shrinkage")
    sizes = [meta[k] for k in ("ratios", "features", "calibration")]
    if not all(isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= MAX_NOVELTY_SIZE for v in sizes):
        raise ValueError(f"ratios, features and calibration must be integers in 1-{MAX_NOVELTY_SIZE}")
    r, f, n = sizes
    if f > 3 * n_obs:
        raise ValueError(f"{f} features, more than the {3 * n_obs} of the window")
    return {
        "novelty_ratios": (r,),
        "novelty_columns": (f,),
        "novelty_mean": (n_tasks, r, f),
        "novelty_chol": (n_tasks, r, f, f),
        "novelty_calibration": (n,),
        "novelty_calibration_group": (n,),
        "novelty_cv_auroc": (None,),
    }


def novelty_from_arrays(meta: dict | None, arrays: dict[str, np.ndarray]) -> NoveltyDetector | None:
    """The detector of a model file's header field and arrays (shapes checked; None when it has none)."""
    if meta is None:
        return None
    a = {name: np.asarray(arrays[f"novelty_{name}"], dtype=float) for name in NOVELTY_ARRAYS}
    for name in ("columns", "calibration_group"):
        v = a[name]
        if not np.all(np.isfinite(v)) or np.any(v != np.round(v)) or np.any(v < 0):
            raise ValueError(f"novelty_{name} must hold non-negative integers")
    return NoveltyDetector(
        alpha=float(meta["alpha"]),
        ratios=a["ratios"],
        columns=a["columns"].astype(np.int64),
        mean=a["mean"],
        chol=a["chol"],
        calibration=a["calibration"],
        calibration_group=a["calibration_group"].astype(np.int64),
        shrinkage=float(meta["shrinkage"]),
        cv_auroc=a["cv_auroc"],
    )


def check_novelty(detector: NoveltyDetector, n_tasks: int, n_obs: int) -> None:
    """Raise ValueError naming what makes a detector unusable: alpha outside (0, 0.5], shapes, non-finite
    numbers, columns or groups out of range, Cholesky factors with non-positive diagonals."""
    if not (isinstance(detector.alpha, float) and 0.0 < detector.alpha <= 0.5):
        raise ValueError(f"novelty alpha {detector.alpha!r} is not in (0, 0.5]")
    r, f = detector.ratios.size, detector.columns.size
    if detector.mean.shape != (n_tasks, r, f) or detector.chol.shape != (n_tasks, r, f, f):
        raise ValueError("novelty mean/chol shapes do not fit the tasks, fractions and features")
    if detector.calibration.shape != detector.calibration_group.shape or detector.calibration.ndim != 1:
        raise ValueError("novelty calibration and calibration_group differ in shape")
    for name in ("ratios", "mean", "chol", "calibration"):
        if not np.all(np.isfinite(getattr(detector, name))):
            raise ValueError(f"novelty {name} holds NaN or inf")
    if r and (np.any(np.diff(detector.ratios) <= 0) or detector.ratios[0] <= 0 or detector.ratios[-1] > 1):
        raise ValueError("novelty ratios are not increasing fractions in (0, 1]")
    if np.any(detector.columns >= 3 * n_obs) or np.any(detector.calibration_group >= r):
        raise ValueError("novelty columns or calibration groups out of range")
    if np.any(np.diagonal(detector.chol, axis1=2, axis2=3) <= 0):
        raise ValueError("novelty Cholesky factors have non-positive diagonals")
