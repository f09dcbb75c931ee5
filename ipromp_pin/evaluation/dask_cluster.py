"""Evaluation jobs on a Dask cluster (``ipromp-pin evaluate --cluster``), behind the interface of the
local pool (:class:`~.jobs.LocalPool`): ``run(worker, work)`` yields every job's result.

Two kinds of cluster:

* ``dask-local:N``: a :class:`distributed.LocalCluster` of ``N`` worker processes (one thread
  each) started for the run and closed after it;
* ``tcp://HOST:PORT`` (or ``tls://``, ``ws://`` ...): an existing scheduler, e.g. one that
  ``dask-jobqueue`` starts on a SLURM cluster. Its workers need this package (the same version) and
  the robot settings' files at the same paths (the robot travels as its settings and is rebuilt).

The worker (the dataset and the scorers) is sent to every Dask worker once (``scatter``, broadcast);
every job is one task, submitted longest first (:func:`~.jobs.longest_first`). A task whose worker
dies is run again on another one (Dask's ``distributed.scheduler.allowed-failures`` times, 3 by
default) and a job that raises is re-run ``retries`` times, so a lost worker costs a re-run, not a
cell. Each thread runs its jobs with its own copy of the scorers, so workers of
several threads are safe for the fits (the closed loop's robot is shared by a process's threads:
give closed-loop runs workers of one thread, e.g. ``dask-jobqueue``'s ``processes`` equal to its
``cores``). The results do not depend on where a job ran: the cells are those of a ``--jobs`` run of the same
splits and seeds. Dask is an optional dependency (``pip install 'ipromp_pin[dask]'``).

Dask's defaults cost a closed-loop job about 20 %: its ``MALLOC_TRIM_THRESHOLD_`` fixes glibc's
mmap threshold at 128 KiB (every medium-sized array a fresh ``mmap``: system time) and its profiler
samples the job's stack every 10 ms. A local cluster's workers start without either
(:data:`LOCAL_WORKER_CONFIG`); a remote worker started with the variable gets glibc's thresholds
back on its first job (:func:`restore_malloc_thresholds`).
"""

from __future__ import annotations

import ctypes
import importlib
import os
import sys
import threading
import uuid
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from types import ModuleType

from ..exceptions import IPrompPinError
from .jobs import Job, JobResult, Worker, single_threaded_blas

LOCAL_PREFIX = "dask-local:"
"""``--cluster`` prefix of a local cluster (followed by its number of workers)."""

SCHEMES = ("tcp://", "tls://", "ws://", "wss://", "inproc://", "ucx://")
"""Address schemes of an existing Dask scheduler."""

RETRIES = 3
"""Re-runs of a job that raised before its error is reported (a job whose worker died is run again by
Dask's scheduler, up to its ``allowed-failures``)."""

LOCAL_WORKER_CONFIG = {
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    "distributed.worker.profile.enabled": False,
}
"""Dask settings of a local cluster's workers: glibc's own malloc thresholds (Dask's
``MALLOC_TRIM_THRESHOLD_`` fixes the mmap threshold at 128 KiB, so that every medium-sized NumPy
array of the replays is a fresh ``mmap``: +20 % on a job, mostly system time) and no statistical
profiler (a thread sampling the job's stack every 10 ms)."""

M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
"""glibc's ``mallopt`` parameters."""

MMAP_THRESHOLD_BYTES = 32 << 20
"""The mmap threshold a worker of a cluster started with Dask's ``MALLOC_TRIM_THRESHOLD_`` gets
(glibc's own grows up to this value, 32 MiB on 64-bit systems, as arrays are freed); trim at twice it."""


class ClusterError(IPrompPinError):
    """A bad ``--cluster`` value, Dask missing, or a cluster that cannot be reached."""


@dataclass(frozen=True)
class DaskCluster:
    """Where the jobs run: a local cluster of ``n_workers`` processes (``address`` None) or the
    scheduler at ``address``; ``retries`` re-runs of a job whose worker dies; ``processes`` False
    runs a local cluster's workers as threads of this process (the tests)."""

    address: str | None = None
    n_workers: int = 0
    retries: int = RETRIES
    processes: bool = True

    @classmethod
    def from_spec(cls, spec: str) -> DaskCluster:
        """The cluster of a ``--cluster`` value (``dask-local:N`` or a scheduler address)."""
        spec = spec.strip()
        if spec.startswith(LOCAL_PREFIX):
            count = spec[len(LOCAL_PREFIX) :]
            if not count.isdigit() or not 1 <= int(count) <= 1024:
                raise ClusterError(f"--cluster: '{spec}': the number of workers must be 1-1024")
            return cls(n_workers=int(count))
        if spec.startswith(SCHEMES) and len(spec.split("://", 1)[1]) > 0:
            return cls(address=spec)
        raise ClusterError(
            f"--cluster: '{spec}' is neither {LOCAL_PREFIX}N nor a scheduler address such as tcp://HOST:8786"
        )

    @property
    def label(self) -> str:
        """How the run reports the cluster."""
        return f"{LOCAL_PREFIX}{self.n_workers}" if self.address is None else self.address

    def run(self, worker: Worker, work: Sequence[Job]) -> Iterator[JobResult]:
        """``worker.run_job`` over the jobs on the cluster (results in completion order)."""
        distributed = require_dask()
        if not work:
            return
        cluster = None
        try:
            if self.address is None:
                with dask_config().set(LOCAL_WORKER_CONFIG):
                    cluster = distributed.LocalCluster(
                        n_workers=self.n_workers,
                        threads_per_worker=1,
                        processes=self.processes,
                        dashboard_address=None,
                    )
                client = distributed.Client(cluster)
            else:
                client = distributed.Client(self.address, timeout="30s")
        except OSError as exc:
            if cluster is not None:
                cluster.close()
            raise ClusterError(f"--cluster {self.label}: cannot reach the scheduler ({exc})") from None
        try:
            yield from self._run(distributed, client, worker, work)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()

    def _run(
        self, distributed: ModuleType, client, worker: Worker, work: Sequence[Job]
    ) -> Iterator[JobResult]:
        remote = client.scatter(worker, broadcast=True, hash=False)
        run_id = uuid.uuid4().hex[:8]
        futures = [
            client.submit(run_job, remote, job, key=f"ipromp-job-{run_id}-{job.index}", retries=self.retries)
            for job in work
        ]
        for future in distributed.as_completed(futures):
            yield future.result()


def restore_malloc_thresholds() -> bool:
    """Undo, in this worker process, the fixed malloc thresholds that Dask's default
    ``MALLOC_TRIM_THRESHOLD_`` sets (on the workers of a cluster this package did not start): with it
    every array of 128 KiB or more is a fresh ``mmap``. Only on glibc and when that variable is set;
    returns whether the thresholds were changed."""
    if "MALLOC_TRIM_THRESHOLD_" not in os.environ or not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL("libc.so.6")
        return bool(libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)) and bool(
            libc.mallopt(M_TRIM_THRESHOLD, 2 * MMAP_THRESHOLD_BYTES)
        )
    except (OSError, AttributeError):  # not glibc
        return False


_process: list[bool] = []
"""Non-empty once this worker process is tuned (:func:`~.jobs.single_threaded_blas`,
:func:`restore_malloc_thresholds`)."""

_thread = threading.local()
"""Per thread of a Dask worker: the scattered worker it last ran a job of, and its own copy of it."""


def run_job(worker: Worker, job: Job) -> JobResult:
    """One job on a Dask worker, with this thread's own copy of the scattered worker (its scorers
    keep each job's fit; made once per thread and run, so that what a scorer keeps for the process,
    e.g. the closed loop's collision certifier and its computed distances, serves every later job
    as in the local pool)."""
    if not _process:
        single_threaded_blas()  # Dask's workers usually start with OPENBLAS_NUM_THREADS=1 already
        _process.append(restore_malloc_thresholds())
    held = getattr(_thread, "worker", None)
    if held is None or held[0] is not worker:
        held = _thread.worker = (worker, worker.for_one_job())
    return held[1].run_job(job)


def dask_config() -> ModuleType:
    """The ``dask.config`` module (Dask installed: :func:`require_dask` has succeeded)."""
    return importlib.import_module("dask.config")


def require_dask() -> ModuleType:
    """The ``distributed`` module, or ClusterError saying how to install it."""
    try:
        return importlib.import_module("distributed")
    except ImportError:
        raise ClusterError(
            "--cluster needs Dask: pip install 'ipromp_pin[dask]' (or pip install 'dask[distributed]')"
        ) from None
