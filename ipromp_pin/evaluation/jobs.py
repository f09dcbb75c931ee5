"""The jobs of an evaluation (one model fit each: a split, a training size, an observed set) and
the pool that runs them, or any other jobs (a plan batch's recordings: :mod:`ipromp_pin.plans.batch`).
Worker processes receive their state (e.g. the dataset and the scorers) from the pool's initializer
once, at their start; nothing is read from the parent's module state."""

from __future__ import annotations

import multiprocessing as mp
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from typing import Any, Protocol, TypeVar

from threadpoolctl import threadpool_limits

from ..data import Dataset
from .config import EvaluationConfig
from .splits import Indices, iter_splits
from .windows import Window

J = TypeVar("J")
R = TypeVar("R")
JobT = TypeVar("JobT", contravariant=True)
ResultT = TypeVar("ResultT", covariant=True)


@dataclass
class Job:
    """One model fit of a protocol: a split, a training size and an observed set.

    Attributes:
        rep: Index of the split (0 for the paper protocol).
        n_train: Training demos per task.
        observe: Observed groups.
        indices: Task -> (train, test) demo indices.
        windows: The observation windows at which the test demos are scored.
        index: Position of the job in its protocol's list (results are aggregated in this order,
            whatever order the workers finish in).
    """

    rep: int
    n_train: int
    observe: list[str]
    indices: Indices
    windows: list[Window]
    index: int = 0


@dataclass
class JobResult:
    """What one job returns: per window the test trials, facts about the fit (e.g. ``coupled``,
    the observed groups the fitted model couples to the robot, ``"+"``-joined) and the fit's nominal
    duration [s] (the mean length of its training demos: the end of its ``train_fraction`` windows)."""

    job: Job
    trials: dict[Window, list] = field(default_factory=dict)
    fit: dict[str, str] = field(default_factory=dict)
    nominal_s: float = float("nan")


def build_jobs(dataset: Dataset, config: EvaluationConfig) -> list[Job]:
    """Every job of ``config``: per split (:func:`~.splits.iter_splits`), one per observed set."""
    work = []
    for rep, n_train, indices in iter_splits(dataset, config):
        windows = [w for n, w in config.cells() if n == n_train]
        work += [Job(rep, n_train, list(o), indices, windows) for o in config.observe]
    for i, job in enumerate(work):
        job.index = i
    return work


def longest_first(work: Sequence[Job]) -> list[Job]:
    """The jobs in the order to run them: the longest first (most windows scored, then most training
    demos; ties in protocol order), so that the workers' last jobs are short ones and they finish
    together. The order changes no result: the cells are aggregated by :attr:`Job.index`."""
    return sorted(work, key=lambda job: (-len(job.windows), -job.n_train, job.index))


def run_jobs(
    run: Callable[[J], R],
    work: Sequence[J],
    jobs: int,
    initializer: Callable[..., None] | None = None,
    initargs: tuple = (),
) -> Iterator[R]:
    """``run`` over the jobs, in ``jobs`` forked worker processes when > 1 (results in completion
    order). ``initializer(*initargs)`` runs once in every worker before its first job (with fork,
    ``initargs`` reach the worker without being pickled); serially it is not called."""
    if jobs <= 1 or len(work) <= 1:
        yield from map(run, work)
        return
    with ProcessPoolExecutor(
        max_workers=jobs, mp_context=mp.get_context("fork"), initializer=initializer, initargs=initargs
    ) as pool:
        futures = [pool.submit(run, job) for job in work]
        for f in as_completed(futures):
            yield f.result()


class Worker(Protocol[JobT, ResultT]):
    """What runs a job in a worker (see :class:`~.protocol.ProtocolWorker`,
    :class:`~ipromp_pin.plans.batch.PlanWorker`)."""

    def run_job(self, job: JobT) -> ResultT:
        """Run one job (e.g. fit and score)."""
        ...

    def for_one_job(self) -> Worker[JobT, ResultT]:
        """A worker for one job that shares nothing mutable with this one (threads of a Dask worker)."""
        ...


_installed: list[Worker[Any, Any]] = []
"""This worker process's worker, installed by the pool initializer (empty in the parent)."""


def single_threaded_blas() -> None:
    """Limit this worker process's BLAS to one thread, for good (the model's fits and predictions
    already run on one, ``IProMP(blas_threads=1)``; the replays' planning, checks and scoring did not).
    With a worker per core, a second BLAS thread per worker only competes for the other workers'
    cores (Dask's workers start with ``OPENBLAS_NUM_THREADS=1`` for the same reason)."""
    threadpool_limits(limits=1, user_api="blas")


def install_worker(worker: Worker[Any, Any]) -> None:
    """Pool initializer: make ``worker`` the one :func:`run_installed` uses in this process, with
    :func:`single_threaded_blas`."""
    single_threaded_blas()
    _installed[:] = [worker]


def installed_worker() -> Worker[Any, Any] | None:
    """This process's installed worker (None in the parent process and in a serial run)."""
    return _installed[0] if _installed else None


def run_installed(job: Any) -> Any:
    """Run ``job`` with this process's installed worker."""
    return _installed[0].run_job(job)


class JobRunner(Protocol):
    """Where jobs run: :class:`LocalPool` (this machine's processes) or a cluster
    (:class:`~.dask_cluster.DaskCluster`). The results never depend on it."""

    def run(self, worker: Worker[J, R], work: Sequence[J]) -> Iterator[R]:
        """``worker.run_job`` over the jobs (results in completion order)."""
        ...


@dataclass(frozen=True)
class LocalPool:
    """The jobs in ``jobs`` forked worker processes of this machine (in this process when 1)."""

    jobs: int = 1

    def run(self, worker: Worker[J, R], work: Sequence[J]) -> Iterator[R]:
        """``worker.run_job`` over the jobs (:func:`run_worker_jobs`)."""
        return run_worker_jobs(worker, work, self.jobs)


def runner_of(jobs: int | JobRunner) -> JobRunner:
    """The runner of a number of local worker processes (or the runner itself)."""
    return LocalPool(jobs) if isinstance(jobs, int) else jobs


def run_worker_jobs(worker: Worker[J, R], work: Sequence[J], jobs: int) -> Iterator[R]:
    """``worker.run_job`` over the jobs: in this process when ``jobs`` <= 1, else in ``jobs`` worker
    processes, each given ``worker`` by the pool initializer (results in completion order)."""
    if jobs <= 1 or len(work) <= 1:
        return map(worker.run_job, work)
    return run_jobs(run_installed, work, jobs, initializer=install_worker, initargs=(worker,))
