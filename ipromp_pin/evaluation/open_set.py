"""The ``open-set`` protocol: leave one task out, is it recognised as unknown?

Every random split of the ``splits`` protocol (the same splits for a seed) is repeated once per task:
the model is fitted on the training demos of the *other* tasks, with its novelty detector
(:mod:`ipromp_pin.promp.novelty`, ``novelty_alpha`` = ``alpha``), and every test demo, of the known
tasks and of the left-out one, is observed at each ratio of the grid. Per cell (n_train, ratio,
observed set, left-out task):

* ``false_reject_rate``: the fraction of the known tasks' test observations refused as unknown
  (the conformal guarantee bounds it by ``alpha`` for observations like the training ones);
* ``false_accept_rate``: the fraction of the left-out task's test observations accepted as known;
* ``auroc``: the area under the ROC curve of the novelty score, known against left-out (mean over
  the splits);
* ``accepted_accuracy``: the recognition accuracy over the accepted observations of known tasks.

Beside it (``baselines``), on the baselines' window features of the same windows
(:mod:`~ipromp_pin.evaluation.baselines`) and calibrated the same split-conformal way on
out-of-fold scores of the training demos (:data:`~ipromp_pin.evaluation.baselines.CV_FOLDS` folds):
the logistic regression's largest class probability (score ``1 - max p``; its penalty chosen by
``LogisticRegressionCV`` on all the training rows, the out-of-fold scores by logistic regressions with
that penalty) and scikit-learn's ``LocalOutlierFactor(novelty=True)`` (score minus ``score_samples``).
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import cast

import numpy as np
from threadpoolctl import threadpool_limits

from ..data import Dataset, Demo
from ..exceptions import DataError
from ..promp import IProMP
from ..promp.novelty import DEFAULT_ALPHA, auroc, conformal_p_values
from .baselines import require_sklearn
from .baselines.base import folds
from .baselines.features import standardiser, window_features
from .baselines.logistic_regression import make_logistic_regression
from .config import EvaluationConfig, ProgressFn, observe_key
from .jobs import Job, JobResult, JobRunner, longest_first, runner_of
from .splits import check_dataset_size, iter_splits, take
from .tables import finite

__all__ = [
    "OPEN_SET_BASELINES",
    "OpenSetCell",
    "OpenSetJob",
    "OpenSetWorker",
    "evaluate_open_set",
    "open_set_json",
    "open_set_markdown",
]

OPEN_SET_BASELINES = ("logistic_regression", "local_outlier_factor")
"""The novelty baselines (see the module docstring)."""


@dataclass
class OpenSetJob(Job):
    """One model fit of the open-set protocol: a split with the task ``unknown`` left out of training."""

    unknown: str = ""


@dataclass
class OpenSetCell:
    """One cell of the open-set table (see the module docstring); ``baselines``: name ->
    ``false_reject_rate``, ``false_accept_rate``, ``auroc``."""

    protocol: str
    n_train: int
    obs_ratio: float
    observe: list[str]
    unknown_task: str
    alpha: float
    n_known: int
    n_unknown: int
    n_splits: int
    false_reject_rate: float
    false_accept_rate: float
    auroc: float
    auroc_std: float
    accepted_accuracy: float
    baselines: dict[str, dict[str, float]] = field(default_factory=dict)
    trials: list[dict] = field(default_factory=list)


def _estimator(name: str, y: np.ndarray, c: float | None = None):  # noqa: ANN202 (sklearn has no types)
    """An unfitted estimator of the baseline ``name`` for training labels ``y`` (``c``: the logistic
    regression's penalty, None: chosen by cross-validation)."""
    if name == "logistic_regression":
        if c is None:
            return make_logistic_regression(y)
        from sklearn.linear_model import LogisticRegression

        return LogisticRegression(C=c, max_iter=5000)
    from sklearn.neighbors import LocalOutlierFactor

    return LocalOutlierFactor(novelty=True, n_neighbors=max(1, min(20, y.size - 1)))


def _novelty(name: str, est, x: np.ndarray) -> np.ndarray:  # noqa: ANN001
    """Novelty scores (n,) of rows ``x`` under a fitted baseline (higher: more novel)."""
    if name == "logistic_regression":
        return 1.0 - est.predict_proba(x).max(axis=1)
    return -est.score_samples(x)


def baseline_scores(
    train_x: np.ndarray, y: np.ndarray, test_x: np.ndarray, name: str
) -> tuple[np.ndarray, np.ndarray]:
    """Out-of-fold calibration scores (n_train,) of the training rows and the test rows' scores
    (n_test,) of the baseline ``name`` (standardised within each fold)."""
    from sklearn.model_selection import StratifiedKFold

    scaler = standardiser()
    est = _estimator(name, y).fit(scaler.fit_transform(train_x), y)
    scores = _novelty(name, est, scaler.transform(test_x))
    c = float(np.ravel(est.C_)[0]) if name == "logistic_regression" else None
    n_min = int(np.min(np.unique(y, return_counts=True)[1]))
    calibration = np.empty(y.size)
    for fit_rows, held in StratifiedKFold(folds(n_min), shuffle=True, random_state=0).split(train_x, y):
        scaler = standardiser()
        est = _estimator(name, y[fit_rows], c).fit(scaler.fit_transform(train_x[fit_rows]), y[fit_rows])
        calibration[held] = _novelty(name, est, scaler.transform(train_x[held]))
    return calibration, scores


class OpenSetWorker:
    """Runs open-set jobs: fits the model (and the baselines) on the known tasks' training demos,
    scores every test demo at every ratio.

    Args:
        dataset: Demos of every task.
        model_params: The model's keyword arguments (``novelty_alpha`` set to ``alpha``).
        alpha: The largest fraction of known observations refused.
        baselines: Also score the novelty baselines.
    """

    def __init__(self, dataset: Dataset, model_params: dict, alpha: float, baselines: bool) -> None:
        self.dataset, self.model_params, self.alpha, self.baselines = dataset, model_params, alpha, baselines

    def for_one_job(self) -> OpenSetWorker:
        """A worker sharing the dataset (nothing else is kept between jobs)."""
        return OpenSetWorker(self.dataset, copy.deepcopy(self.model_params), self.alpha, self.baselines)

    def run_job(self, job: OpenSetJob) -> JobResult:
        """Fit on the known tasks' training demos, score every test demo at every ratio."""
        train, test = take(self.dataset, job.indices)
        train = [d for d in train if d.task != job.unknown]
        params = {"handover": False, **self.model_params, "novelty_alpha": self.alpha}
        model = IProMP(observe=list(job.observe), **params).fit(train)
        out = {}
        for window in job.windows:  # fractions of each test demo only (build_open_set_jobs)
            ratio = window.value
            rows: list[dict] = []
            for d in test:
                rec = model.recognise(d.head(ratio, job.observe))
                assert not isinstance(rec, list)  # one observation, one recognition
                rows.append(
                    {
                        "task": d.task,
                        "demo": d.name,
                        "split": job.rep,
                        "unknown": d.task == job.unknown,
                        "predicted": rec.task,
                        "novelty_score": rec.novelty_score,
                        "p_value": rec.novelty_p_value,
                        "known": bool(rec.known),
                        "baselines": {},
                    }
                )
            if self.baselines:
                self._baselines(train, test, ratio, job.observe, rows)
            out[window] = rows
        return JobResult(job, out, {"coupled": "+".join(model.fitted_.coupled_groups)})

    def _baselines(
        self, train: Sequence[Demo], test: Sequence[Demo], ratio: float, observe: Sequence[str], rows: list
    ) -> None:
        """Add every baseline's score, p-value and decision to the rows of the test demos."""
        with threadpool_limits(limits=1):
            train_x = np.stack([window_features(d.head(ratio, observe), observe) for d in train])
            test_x = np.stack([window_features(d.head(ratio, observe), observe) for d in test])
            y = np.array([d.task for d in train])
            for name in OPEN_SET_BASELINES:
                calibration, scores = baseline_scores(train_x, y, test_x, name)
                p = conformal_p_values(calibration, scores)
                for row, s, pv in zip(rows, scores, p, strict=True):
                    row["baselines"][name] = {
                        "novelty_score": float(s),
                        "p_value": float(pv),
                        "known": bool(pv > self.alpha),
                    }


def build_open_set_jobs(dataset: Dataset, config: EvaluationConfig) -> list[OpenSetJob]:
    """Per random split, per left-out task, per observed set: one job."""
    work = []
    for rep, n_train, indices in iter_splits(dataset, config):
        ratios = [w for n, w in config.cells() if n == n_train and w.is_ratio]
        for unknown in dataset.tasks:
            work += [
                OpenSetJob(rep, n_train, list(o), indices, ratios, unknown=unknown) for o in config.observe
            ]
    for i, job in enumerate(work):
        job.index = i
    return work


def _rates(rows: Sequence[dict], key: Callable[[dict], dict]) -> dict[str, float]:
    """False reject and accept rates and the mean per-split AUROC of trials (``key``: where a trial
    keeps the scorer's ``novelty_score`` and ``known``)."""
    known = [r for r in rows if not r["unknown"]]
    novel = [r for r in rows if r["unknown"]]
    per_split = []
    for split in sorted({r["split"] for r in rows}):
        k = [key(r)["novelty_score"] for r in known if r["split"] == split]
        u = [key(r)["novelty_score"] for r in novel if r["split"] == split]
        per_split.append(auroc(np.array(k), np.array(u)))
    return {
        "false_reject_rate": float(np.mean([not key(r)["known"] for r in known])) if known else float("nan"),
        "false_accept_rate": float(np.mean([key(r)["known"] for r in novel])) if novel else float("nan"),
        "auroc": float(np.nanmean(per_split)) if per_split else float("nan"),
        "auroc_std": float(np.nanstd(per_split)) if per_split else float("nan"),
    }


def _of(name: str) -> Callable[[dict], dict]:
    """Where a trial keeps the baseline ``name``'s outcome."""
    return lambda row: row["baselines"][name]


def open_set_cells(
    dataset: Dataset, config: EvaluationConfig, results: Sequence[JobResult], alpha: float
) -> list:
    """The cells (grid, then observed set, then left-out task) of the jobs' trials."""
    grouped: dict[tuple, list[dict]] = {}
    for result in sorted(results, key=lambda r: r.job.index):
        job = result.job
        assert isinstance(job, OpenSetJob)
        for window, rows in result.trials.items():
            key = (job.n_train, window.value, observe_key(job.observe), job.unknown)
            grouped.setdefault(key, []).extend(rows)
    cells = []
    for n_train, ratio in [(n, w.value) for n, w in config.cells() if w.is_ratio]:
        for observe in config.observe:
            for unknown in dataset.tasks:
                rows = grouped[(n_train, ratio, observe_key(observe), unknown)]
                ours = _rates(rows, lambda r: r)
                accepted = [r for r in rows if not r["unknown"] and r["known"]]
                names = sorted({n for r in rows for n in r["baselines"]}, key=OPEN_SET_BASELINES.index)
                cells.append(
                    OpenSetCell(
                        protocol=config.protocol,
                        n_train=n_train,
                        obs_ratio=ratio,
                        observe=list(observe),
                        unknown_task=unknown,
                        alpha=alpha,
                        n_known=sum(not r["unknown"] for r in rows),
                        n_unknown=sum(r["unknown"] for r in rows),
                        n_splits=len({r["split"] for r in rows}),
                        accepted_accuracy=float(np.mean([r["predicted"] == r["task"] for r in accepted]))
                        if accepted
                        else float("nan"),
                        baselines={
                            name: {k: v for k, v in _rates(rows, _of(name)).items() if k != "auroc_std"}
                            for name in names
                        },
                        trials=rows,
                        **ours,
                    )
                )
    return cells


def evaluate_open_set(
    dataset: Dataset,
    config: EvaluationConfig,
    alpha: float = DEFAULT_ALPHA,
    progress: ProgressFn | None = None,
    jobs: int | JobRunner = 1,
) -> list[OpenSetCell]:
    """Run the open-set protocol of ``config`` (its splits, grid and observed sets) at ``alpha``.

    Raises:
        DataError: fewer than 3 tasks (a left-out task leaves at least 2 to tell apart), too few demos.
    """
    if len(dataset.tasks) < 3:
        raise DataError(
            dataset.root,
            None,
            f"the open-set protocol needs 3+ tasks (one left out), got {len(dataset.tasks)}",
        )
    check_dataset_size({t: len(d) for t, d in dataset.demos.items()}, config, dataset.root)
    if config.baselines:
        require_sklearn()
    work = cast(list[OpenSetJob], longest_first(build_open_set_jobs(dataset, config)))
    worker = OpenSetWorker(dataset, dict(config.model_params), alpha, config.baselines)
    finished = []
    for done, result in enumerate(runner_of(jobs).run(worker, work), start=1):
        finished.append(result)
        if progress is not None:
            job = result.job
            assert isinstance(job, OpenSetJob)
            label = (
                f"open-set split {job.rep + 1}/{config.repeats} without {job.unknown} "
                f"n_train={job.n_train} {observe_key(job.observe)}"
            )
            progress(done, len(work), label)
    return open_set_cells(dataset, config, finished, alpha)


def open_set_json(cells: Sequence[OpenSetCell], meta: dict | None = None) -> dict:
    """The JSON document of an open-set evaluation (``cells`` with their trials, ``overall``, ``meta``)."""
    return finite(
        {
            "format": "ipromp_pin.evaluation",
            "version": 1,
            "meta": meta or {},
            "overall": open_set_overall(cells),
            "cells": [asdict(c) for c in cells],
        }
    )


def open_set_overall(cells: Sequence[OpenSetCell]) -> dict[str, dict[str, float]]:
    """Per observed set: the mean of every rate over its cells, and the worst false reject rate."""
    out: dict[str, dict[str, float]] = {}
    for key in dict.fromkeys(observe_key(c.observe) for c in cells):
        mine = [c for c in cells if observe_key(c.observe) == key]
        out[key] = {
            "cells": len(mine),
            "mean_auroc": float(np.nanmean([c.auroc for c in mine])),
            "min_auroc": float(np.nanmin([c.auroc for c in mine])),
            "mean_false_reject_rate": float(np.nanmean([c.false_reject_rate for c in mine])),
            "max_false_reject_rate": float(np.nanmax([c.false_reject_rate for c in mine])),
            "mean_false_accept_rate": float(np.nanmean([c.false_accept_rate for c in mine])),
        }
    return out


def _f(x: float | None, digits: int = 2) -> str:
    return "-" if x is None or not np.isfinite(x) else f"{x:.{digits}f}"


def open_set_markdown(cells: Sequence[OpenSetCell]) -> str:
    """The open-set table (and the baselines' AUROC and rates beside ours), as Markdown."""
    names = [n for n in OPEN_SET_BASELINES if any(n in c.baselines for c in cells)]
    head = (
        "| n_train | obs ratio | observed | unknown task | alpha | false reject | false accept | AUROC "
        "| accepted acc |"
    )
    rule = "|---|---|---|---|---|---|---|---|---|"
    for n in names:
        head += f" {n} AUROC / FRR / FAR |"
        rule += "---|"
    lines = ["### Open-set recognition, leave-one-task-out", "", head, rule]
    for c in cells:
        line = (
            f"| {c.n_train} | {c.obs_ratio:g} | {observe_key(c.observe)} | {c.unknown_task} | {c.alpha:g} "
            f"| {_f(c.false_reject_rate)} | {_f(c.false_accept_rate)} "
            f"| {_f(c.auroc, 3)} ± {_f(c.auroc_std, 3)} | {_f(c.accepted_accuracy)} |"
        )
        for n in names:
            b = c.baselines.get(n, {})
            rates = f"{_f(b.get('false_reject_rate'))} / {_f(b.get('false_accept_rate'))}"
            line += f" {_f(b.get('auroc'), 3)} / {rates} |"
        lines.append(line)
    lines.append("")
    for key, o in open_set_overall(cells).items():
        lines.append(
            f"- {key}: mean AUROC {o['mean_auroc']:.3f} (min {o['min_auroc']:.3f}), false reject rate "
            f"mean {o['mean_false_reject_rate']:.3f} (max {o['max_false_reject_rate']:.3f}), false accept "
            f"rate mean {o['mean_false_accept_rate']:.3f} over {o['cells']} cells"
        )
    return "\n".join(lines) + "\n"
