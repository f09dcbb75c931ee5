"""A worker for the Dask cluster tests, importable by the cluster's spawned worker processes (the
tests folder is on their ``sys.path``): it kills the process running one chosen job, once."""

from __future__ import annotations

import os
import signal
from pathlib import Path

from ipromp_pin.evaluation.jobs import Job, JobResult, Worker


class DiesOnce:
    """Runs jobs with ``inner``; the first time job ``index`` runs (``marker`` absent) it writes the
    process id to ``marker`` and kills its own process (SIGKILL: no clean-up, as in a crash or an
    out-of-memory kill)."""

    def __init__(self, inner: Worker, marker: Path, index: int) -> None:
        self.inner = inner
        self.marker = marker
        self.index = index

    def for_one_job(self) -> DiesOnce:
        return DiesOnce(self.inner.for_one_job(), self.marker, self.index)

    def run_job(self, job: Job) -> JobResult:
        if job.index == self.index and not self.marker.exists():
            self.marker.write_text(str(os.getpid()))
            os.kill(os.getpid(), signal.SIGKILL)
        return self.inner.run_job(job)


class DyingRunner:
    """A job runner: ``cluster`` running the protocol's worker wrapped in :class:`DiesOnce`."""

    def __init__(self, cluster, marker: Path, index: int) -> None:
        self.cluster = cluster
        self.marker = marker
        self.index = index

    def run(self, worker: Worker, work):
        return self.cluster.run(DiesOnce(worker, self.marker, self.index), work)
