"""The one protocol runner of every evaluation: splits (paper or random), one job per model fit,
the worker pool, the aggregation of the trials by (n_train, window, observed set, task) into
cells. A scorer (:class:`~.scorers.base.Scorer`) says what is fitted and measured; extra scorers
(the baselines) add their outcomes to its trials."""

from __future__ import annotations

import copy
from collections.abc import Sequence

from ..data import ROBOT, Dataset
from ..exceptions import DataError
from .cells import Cell, CellResults, build_cells
from .config import EvaluationConfig, ProgressFn, observe_key
from .jobs import Job, JobResult, JobRunner, build_jobs, longest_first, runner_of
from .scorers.base import Scorer
from .splits import check_dataset_size, take
from .windows import check_windows, nominal_duration_s

__all__ = ["EvaluationConfig", "ProtocolWorker", "run_protocol"]


class ProtocolWorker:
    """Runs jobs on a dataset: fits the scorers on the job's training demos, scores its test demos
    at every window. Given to every worker process once, by the pool initializer.

    Args:
        dataset: Demos of every task.
        scorer: The main scorer (its trials make the cells).
        extras: Scorers whose per-demo outcomes (name -> record) join each trial's ``baselines``.
    """

    def __init__(self, dataset: Dataset, scorer: Scorer, extras: Sequence[Scorer] = ()) -> None:
        self.dataset = dataset
        self.scorer = scorer
        self.extras = list(extras)

    def for_one_job(self) -> ProtocolWorker:
        """A worker sharing the dataset, with its own copies of the scorers (which keep each job's
        fit): what one thread of a multi-threaded Dask worker runs a job with."""
        return ProtocolWorker(self.dataset, copy.deepcopy(self.scorer), copy.deepcopy(self.extras))

    def run_job(self, job: Job) -> JobResult:
        """Fit on the job's training demos and score its test demos at every window (a
        ``train_fraction`` window ends at its fraction of the training demos' mean length)."""
        train, test = take(self.dataset, job.indices)
        nominal_s = nominal_duration_s(train)
        self.scorer.fit(train, job.observe)
        for extra in self.extras:
            extra.fit(train, job.observe)
        out = {}
        for window in job.windows:
            fitted = window.for_fit(nominal_s)
            trials = self.scorer.score(test, fitted, job.rep)
            for extra in self.extras:
                for trial, more in zip(trials, extra.score(test, fitted, job.rep), strict=True):
                    trial.baselines = {**trial.baselines, **more}
            out[window] = trials
        return JobResult(job, out, self.scorer.fit_facts(), nominal_s)


def check_inputs(dataset: Dataset, config: EvaluationConfig, scorers: Sequence[Scorer]) -> None:
    """Everything checked before any model is fitted: the protocol, the dataset's size, the groups
    every demo must hold, the windows (2 samples at least of every demo), the scorers' settings."""
    config.check_protocol()
    check_dataset_size({t: len(d) for t, d in dataset.demos.items()}, config, dataset.root)
    for observe in config.observe:
        for demo in dataset.all_demos():
            demo.require(list(observe) + [ROBOT])
    windows = [w for _, w in config.cells()]
    for scorer in scorers:
        unsupported = sorted({w.kind for w in windows} - set(scorer.window_kinds))
        if unsupported:
            raise DataError(
                None, "window", f"{scorer.label or 'this scorer '}takes {' or '.join(scorer.window_kinds)} "
                f"windows, not {', '.join(unsupported)}",
            )  # fmt: skip
    check_windows(dataset.all_demos(), windows)
    for scorer in scorers:
        scorer.check()


def run_protocol(
    dataset: Dataset,
    config: EvaluationConfig,
    scorer: Scorer,
    extras: Sequence[Scorer] = (),
    progress: ProgressFn | None = None,
    jobs: int | JobRunner = 1,
) -> list[Cell]:
    """Run one protocol of ``config`` with ``scorer`` (and ``extras``) over every cell.

    Args:
        dataset: Demos of every task, in protocol order.
        config: Protocol, grid and observed channel sets.
        scorer: Fitted per job, its trials aggregate into cells of its ``cell_type``.
        extras: Scorers annotating the trials (e.g. :class:`~.scorers.baselines.BaselineScorer`).
        progress: Called as ``progress(done, total, label)`` after every model fit.
        jobs: Worker processes (model fits run in parallel), or where the jobs run (a
            :class:`~.jobs.JobRunner`, e.g. a Dask cluster); the results do not depend on it.
    """
    check_inputs(dataset, config, [scorer, *extras])
    work = longest_first(build_jobs(dataset, config))
    worker = ProtocolWorker(dataset, scorer, extras)
    finished = []
    for done, result in enumerate(runner_of(jobs).run(worker, work), start=1):
        finished.append(result)
        if progress is not None:
            job = result.job
            label = (
                f"{scorer.label}{config.protocol} split {job.rep + 1}/{config.repeats} "
                f"n_train={job.n_train} {observe_key(job.observe)}"
            )
            progress(done, len(work), label)
    results = CellResults(dataset.tasks)
    for result in sorted(finished, key=lambda r: r.job.index):  # the same cells for any ``jobs``
        results.add(result)
    return build_cells(dataset, config, results, scorer.cell_type, scorer.cell_fields)
