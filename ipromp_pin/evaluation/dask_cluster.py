"""Jobs on a Dask cluster (``ipromp-pin evaluate --cluster``, ``ipromp-pin plan --cluster``), behind
the interface of the local pool (:class:`~.jobs.LocalPool`): ``run(worker, work)`` yields every
job's result.

Two kinds of cluster:

* ``dask-local:N``: a :class:`distributed.LocalCluster` of ``N`` worker processes (one thread
  each, forked on Linux) started for the run and closed after it;
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
samples the job's stack every 10 ms; and a spawned worker imports the package and loads the robot
again. A local cluster's workers start without either and forked on Linux
(:func:`local_worker_config`); a remote worker started with the variable gets glibc's thresholds
back on its first job (:func:`restore_malloc_thresholds`).
"""

from __future__ import annotations

import ctypes
import importlib
import multiprocessing as mp
import os
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import CancelledError
from dataclasses import dataclass, field
from types import ModuleType

from ..exceptions import IPrompPinError
from .jobs import J, R, Worker, single_threaded_blas

LOCAL_PREFIX = "dask-local:"
"""``--cluster`` prefix of a local cluster (followed by its number of workers)."""

SCHEMES = ("tcp://", "tls://", "ws://", "wss://")
"""Address schemes of an existing Dask scheduler on another machine (``inproc://`` reaches only this
process, ``ucx://`` needs UCX-Py: neither is a cluster of this command)."""

CONNECT_TIMEOUT_S = 15.0
"""How long to try reaching a scheduler [s]."""

WORKER_WAIT_S = 30.0
"""How long to wait for a scheduler's first worker [s]."""

WORKER_MEMORY_BYTES = 600 * 2**20
"""What a local worker needs at least (the package, the robot, a model fit), for the bound on N."""

RETRIES = 3
"""Re-runs of a job that raised before its error is reported (a job whose worker died is run again by
Dask's scheduler, up to its ``allowed-failures``)."""

LOCAL_WORKER_CONFIG: dict[str, object] = {
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    "distributed.worker.profile.enabled": False,
}
"""Dask settings of a local cluster's workers: glibc's own malloc thresholds (Dask's
``MALLOC_TRIM_THRESHOLD_`` fixes the mmap threshold at 128 KiB, so that every medium-sized NumPy
array of the replays is a fresh ``mmap``: +20 % on a job, mostly system time) and no statistical
profiler (a thread sampling the job's stack every 10 ms). On Linux the workers are also forked
(:func:`local_worker_config`)."""


def local_worker_config() -> dict[str, object]:
    """:data:`LOCAL_WORKER_CONFIG`, and on Linux forked workers (as the local pool's): they start with
    the package imported and the robot loaded instead of importing them again (spawned, each of
    2 workers took about 14 s on 2 busy cores before its first job; forked, none)."""
    config = dict(LOCAL_WORKER_CONFIG)
    if sys.platform.startswith("linux") and "fork" in mp.get_all_start_methods():
        config["distributed.worker.multiprocessing-method"] = "fork"
    return config


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
    runs a local cluster's workers as threads of this process (the tests); ``log`` (when given) gets
    one line when the cluster has started or been reached (:meth:`DaskSession.describe`)."""

    address: str | None = None
    n_workers: int = 0
    retries: int = RETRIES
    processes: bool = True
    log: Callable[[str], object] | None = field(default=None, compare=False, repr=False)

    @classmethod
    def from_spec(cls, spec: str, log: Callable[[str], object] | None = None) -> DaskCluster:
        """The cluster of a ``--cluster`` value (``dask-local:N`` or a scheduler address
        ``SCHEME://HOST:PORT``), or ClusterError naming what is wrong with it; ``log``: where the line
        saying that it started or was reached goes."""
        spec = spec.strip()
        if spec.startswith(LOCAL_PREFIX):
            count = spec[len(LOCAL_PREFIX) :]
            most = max_local_workers()
            if not count.isdigit() or not 1 <= int(count) <= most:
                raise ClusterError(
                    f"--cluster: '{spec}': the number of local workers must be 1-{most} (this machine's "
                    f"cores and memory; a bigger cluster is a scheduler address such as tcp://HOST:8786)"
                )
            return cls(n_workers=int(count), log=log)
        scheme, sep, rest = spec.partition("://")
        if not sep or f"{scheme}://" not in SCHEMES:
            raise ClusterError(
                f"--cluster: '{spec}' is neither {LOCAL_PREFIX}N nor a scheduler address such as "
                f"tcp://HOST:8786 (schemes: {', '.join(s[:-3] for s in SCHEMES)})"
            )
        host, colon, port = rest.rpartition(":")
        if not colon or not host or "/" in rest:
            raise ClusterError(
                f"--cluster: '{spec}': give the scheduler's host and port, e.g. {scheme}://HOST:8786"
            )
        if not port.isdigit() or not 1 <= int(port) <= 65535:
            raise ClusterError(f"--cluster: '{spec}': the port must be a number in 1-65535, got '{port}'")
        return cls(address=spec, log=log)

    @property
    def label(self) -> str:
        """How the run reports the cluster."""
        return f"{LOCAL_PREFIX}{self.n_workers}" if self.address is None else self.address

    def run(self, worker: Worker[J, R], work: Sequence[J]) -> Iterator[R]:
        """``worker.run_job`` over the jobs on the cluster, started (or connected to) for this call
        and closed after it (results in completion order)."""
        if not work:
            return
        session = self.open()
        try:
            yield from session.run(worker, work)
        finally:
            session.close()

    def open(self, prepare: Callable[[], object] | None = None) -> DaskSession:
        """Start the local cluster (or connect to the scheduler) and return the session that runs
        jobs on it until it is closed. ``prepare`` (e.g. :func:`prepare_worker`) is run once on every
        worker present, as a task, while the caller goes on (e.g. reads the dataset)."""
        distributed = require_dask()
        cluster = None
        try:
            if self.address is None:
                with dask_config().set(local_worker_config()):
                    cluster = distributed.LocalCluster(
                        n_workers=self.n_workers,
                        threads_per_worker=1,
                        processes=self.processes,
                        dashboard_address=None,
                    )
                client = distributed.Client(cluster)
            else:
                client = distributed.Client(self.address, timeout=f"{CONNECT_TIMEOUT_S:g}s")
        except (OSError, TimeoutError) as exc:
            if cluster is not None:
                cluster.close()
            raise ClusterError(
                f"--cluster {self.label}: cannot reach the scheduler at {self.label} within "
                f"{CONNECT_TIMEOUT_S:g} s ({exc or type(exc).__name__})"
            ) from None
        if self.address is not None:
            try:
                client.wait_for_workers(1, timeout=WORKER_WAIT_S)
            except (OSError, TimeoutError):
                client.close()
                raise ClusterError(
                    f"--cluster {self.label}: the scheduler has no workers (waited {WORKER_WAIT_S:g} s); "
                    "start some with dask-worker, or dask-jobqueue on SLURM"
                ) from None
        session = DaskSession(self, distributed, client, cluster)
        if self.log is not None:
            self.log(session.describe())
        if prepare is not None:
            session.prepare(prepare)
        return session


class DaskSession:
    """A started local cluster (or a connected scheduler) and its client: a
    :class:`~.jobs.JobRunner` for every protocol of a run (the workers start, import the package and
    load the robot once, not once per protocol). :meth:`close` ends it (a local cluster is shut down).
    """

    def __init__(self, spec: DaskCluster, distributed: ModuleType, client, cluster=None) -> None:
        self.spec = spec
        self.distributed = distributed
        self.client = client
        self.cluster = cluster
        self.prepared: list = []

    @property
    def label(self) -> str:
        """How the run reports the cluster."""
        return self.spec.label

    def describe(self) -> str:
        """One line: the cluster started (local) or reached (its scheduler's address) and its workers
        now (``[cluster] started a local Dask cluster at tcp://127.0.0.1:PORT: 2 workers, 2 threads``)."""
        info = self.client.scheduler_info()
        workers = info.get("workers", {})
        threads = sum(int(w.get("nthreads", 0)) for w in workers.values())
        address = info.get("address") or self.spec.address or "?"
        count = f"{len(workers)} worker{'s' * (len(workers) != 1)}, {threads} thread{'s' * (threads != 1)}"
        if self.cluster is not None:
            kind = "processes" if self.spec.processes else "threads of this process"
            return f"[cluster] started a local Dask cluster at {address} ({kind}): {count}"
        waiting = "" if workers else " (none yet: the jobs wait for workers to join)"
        return f"[cluster] connected to the Dask scheduler at {address}: {count}{waiting}"

    def prepare(self, prepare: Callable[[], object]) -> None:
        """Run ``prepare`` once on every worker present, as a task (not waited for: the jobs queue
        behind it)."""
        workers = list(self.client.scheduler_info().get("workers", {}))
        self.prepared = [
            self.client.submit(prepare, key=f"ipromp-prepare-{uuid.uuid4().hex[:8]}", workers=[w], pure=False)
            for w in workers
        ]

    def run(self, worker: Worker[J, R], work: Sequence[J]) -> Iterator[R]:
        """``worker.run_job`` over the jobs, in the order given (results in completion order)."""
        if not work:
            return
        remote = self.client.scatter(worker, broadcast=True, hash=False)
        run_id = uuid.uuid4().hex[:8]
        futures = [
            self.client.submit(
                run_job, remote, job, key=f"ipromp-job-{run_id}-{i}", retries=self.spec.retries
            )
            for i, job in enumerate(work)
        ]
        try:
            for future in self.distributed.as_completed(futures):
                yield future.result()
        except (CancelledError, OSError) as exc:  # FutureCancelledError is a CancelledError
            raise ClusterError(
                f"--cluster {self.label}: the cluster stopped running the jobs (its workers or its "
                f"scheduler were lost: {type(exc).__name__})"
            ) from None

    def close(self) -> None:
        """Close the client, and the local cluster if the session started one."""
        self.prepared = []
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()

    def __enter__(self) -> DaskSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def prepare_worker(robot: str | None = None) -> float:
    """What a worker does before its first job, while the parent reads the dataset: import the
    evaluation (with the models, the closed loop and its checks) and load ``robot`` (cached: the
    scattered scorers' robot is then this one); a forked worker has both already. The compiled kernels
    are left to load on first use, as in the local pool. Returns the time taken in [s]; a failure is
    left to the first job to report."""
    t0 = time.perf_counter()
    try:
        importlib.import_module("ipromp_pin.evaluation.protocol")
        importlib.import_module("ipromp_pin.evaluation.scorers.closed_loop")
        if robot is not None:
            from ..robot import load_robot

            load_robot(robot)
    except Exception:  # noqa: BLE001 (an optimisation: the jobs report what is wrong)
        pass
    return time.perf_counter() - t0


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


def run_job(worker: Worker[J, R], job: J) -> R:
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


def max_local_workers() -> int:
    """The most local workers this machine can run: its cores, and its memory at
    :data:`WORKER_MEMORY_BYTES` each (at least 1)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    try:
        memory = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return max(cores, 1)
    return max(1, min(cores, memory // WORKER_MEMORY_BYTES))


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
