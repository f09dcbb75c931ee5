"""The one switch between the package's compiled kernels and their numpy versions: :func:`kernels`.

Every set of numba kernels registers here (:func:`register_kernel_set`): the inference kernels
(``"inference"``: :mod:`ipromp_pin.promp._kernels`, numpy version :mod:`ipromp_pin.promp.numpy_kernels`)
the human checks' (``"human"``: :mod:`ipromp_pin.human.separation_kernels` and
:mod:`ipromp_pin.human.numpy_kernels`, registered by :mod:`ipromp_pin.human.kernels`) and the
retargeting's inverse kinematics (``"ik"``: :mod:`ipromp_pin.robot.ik_kernels`, registered here by
name, used through :mod:`ipromp_pin.robot.arm_chain`; its "numpy" version is Pinocchio's solver in
:mod:`ipromp_pin.robot.arm_transfer`). Both versions of a set give the same results (to rounding:
the tests hold them to 1e-9). One backend holds for every set:

* ``"numba"``: the compiled kernels. Importing :mod:`ipromp_pin` does not import numba; a set's
  module is imported when it is first needed and its machine code is loaded from numba's on-disk
  cache, or compiled on the very first use of a fresh install (announced through :func:`set_announcer`).
* ``"numpy"``: the numpy versions: nothing to compile or load, slower per call (docs/first-minute.md).
* ``"auto"``: per set, decided once per process at its first use: the compiled kernels when numba's
  cache holds them, else the numpy version for the whole process while one background process
  (:func:`start_background_compile`: ``python -m ipromp_pin.promp.warmup``, the one warm-up, which
  compiles every registered set) fills the cache for the next runs. A fresh install's first run does
  not wait for the compile, and a process never mixes the two versions of a set.

The backend is ``$IPROMP_PIN_KERNELS`` when set, else ``"numba"`` for library use; the short commands
(``ipromp-pin run``, ``preview``, ``train``, ``synth``) use ``"auto"``.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

__all__ = [
    "BACKENDS",
    "BACKEND_ENV",
    "COMPILE_SECONDS",
    "FIT_PREDICT_KERNELS",
    "IK",
    "IK_KERNELS",
    "INFERENCE",
    "KernelSet",
    "active_backend",
    "announce",
    "compiled_kernels_cached",
    "kernel_backend",
    "kernel_sets",
    "kernels",
    "kernels_cached",
    "numba_kernels",
    "prefer_backend",
    "register_kernel_set",
    "set_announcer",
    "set_kernel_backend",
    "start_background_compile",
    "use_kernels",
]

BACKENDS = ("numba", "numpy", "auto")
"""Accepted kernel backends."""

BACKEND_ENV = "IPROMP_PIN_KERNELS"
"""Environment variable choosing the backend (overrides the library's and the command line's default)."""

COMPILE_SECONDS = 20
"""Announced duration in [s] of the one-time compile of the inference kernels (docs/first-minute.md)."""

INFERENCE = "inference"
"""Name of the inference kernels' set."""

FIT_PREDICT_KERNELS = (
    "part_stats",
    "x_inverse",
    "part_terms",
    "add_fused_p",
    "finish_soa",
    "recognition",
    "head_posterior",
    "task_posterior",
    "scale_samples",
    "condition_block",
    "channel_values",
    "prediction_cov",
    "readout_update",
)
"""The inference kernels that fitting and prediction call (streaming adds ``stream_sample``,
``sherman_morrison``, ``stream_group``, ``add_sample``, ``basis_rows``)."""


@dataclass(frozen=True)
class KernelSet:
    """A set of numba kernels and its numpy version.

    Attributes:
        compiled: The numba kernels' module (imported on first use).
        numpy: The numpy version's module.
        names: The kernels whose cache entries say that the set is compiled.
        warmup: The module whose ``compile_kernels()`` compiles the set through the real code paths
            (run by the warm-up, ``python -m ipromp_pin.promp.warmup``).
        label: What the notices call the set, e.g. "inference kernels".
    """

    compiled: str
    numpy: str
    names: tuple[str, ...]
    warmup: str
    label: str


_sets: dict[str, KernelSet] = {}
_state: dict = {
    "backend": os.environ.get(BACKEND_ENV) or "numba",
    "modules": {},  # (set, "numba" | "numpy") -> module, once imported
    "auto": {},  # set -> the version "auto" decided on in this process
    "announced": set(),  # sets whose cold compile was announced
    "announce": None,
}


def register_kernel_set(name: str, kernel_set: KernelSet) -> None:
    """Register a set of kernels under ``name`` (the package that owns them does, at import)."""
    _sets[name] = kernel_set


def kernel_sets() -> dict[str, KernelSet]:
    """The registered kernel sets, by name."""
    return dict(_sets)


register_kernel_set(
    INFERENCE,
    KernelSet(
        "ipromp_pin.promp._kernels",
        "ipromp_pin.promp.numpy_kernels",
        FIT_PREDICT_KERNELS,
        "ipromp_pin.promp.warmup",
        "inference kernels",
    ),
)


IK = "ik"
"""Name of the retargeting's inverse-kinematics kernel set (:mod:`ipromp_pin.robot.arm_chain`)."""

IK_KERNELS = ("chain_fk", "solve_sequence", "solve_first", "linearised_samples")
"""The inverse-kinematics kernels the retargeting calls."""

register_kernel_set(  # here, by name only: importing the robot package does not import the model's
    IK,
    KernelSet(
        "ipromp_pin.robot.ik_kernels",
        "ipromp_pin.robot.arm_transfer",
        IK_KERNELS,
        "ipromp_pin.robot.ik_warmup",
        "inverse-kinematics kernels",
    ),
)


def set_announcer(announce: Callable[[str], None] | None) -> None:
    """Where one-line notices about the kernels go (the one-time compile; ``None``: nowhere)."""
    _state["announce"] = announce


def announce(message: str) -> None:
    """Pass a one-line notice about the kernels to the announcer (:func:`set_announcer`), if any."""
    if _state["announce"] is not None:
        _state["announce"](message)


def kernel_backend() -> str:
    """The current backend (one of :data:`BACKENDS`)."""
    return _state["backend"]


def set_kernel_backend(backend: str) -> str:
    """Choose the backend (one of :data:`BACKENDS`); returns the previous one."""
    if backend not in BACKENDS:
        raise ValueError(f"unknown kernel backend {backend!r} (use one of {', '.join(BACKENDS)})")
    previous = _state["backend"]
    _state["backend"] = backend
    _state["auto"] = {}  # "auto" decides afresh at each set's next first use
    return previous


@contextlib.contextmanager
def use_kernels(backend: str) -> Iterator[None]:
    """Use ``backend`` inside a ``with`` block (e.g. to compare the implementations)."""
    previous = set_kernel_backend(backend)
    try:
        yield
    finally:
        set_kernel_backend(previous)


def kernels(name: str = INFERENCE) -> ModuleType:
    """The kernels module of set ``name`` for the current backend (see the module docstring)."""
    backend = active_backend(name)
    module = _state["modules"].get((name, backend))
    return module if module is not None else _load(name, backend)


def active_backend(name: str = INFERENCE) -> str:
    """``"numba"`` or ``"numpy"``: what :func:`kernels` uses for set ``name`` in this process
    (deciding ``"auto"`` now if the set was not used yet)."""
    backend = _state["backend"]
    return backend if backend != "auto" else _state["auto"].get(name) or _decide(name)


def prefer_backend(name: str, backend: str) -> str:
    """For a process that calls set ``name`` only a few times more (e.g. ``run``: one prediction from
    a model it did not train): under ``"auto"``, take ``backend`` for the set if it was not used yet
    (loading compiled kernels costs more than a few numpy calls). Returns the set's backend."""
    if backend not in ("numba", "numpy"):
        raise ValueError(f"unknown kernel backend {backend!r} (use numba or numpy)")
    if _state["backend"] == "auto" and name not in _state["auto"]:
        _state["auto"][name] = backend
    return active_backend(name)


def numba_kernels(name: str = INFERENCE) -> ModuleType:
    """The compiled kernels module of set ``name``, whatever the backend (announcing a compile the
    cache lacks)."""
    return _load(name, "numba")


def kernels_cached(name: str = INFERENCE, names: tuple[str, ...] | None = None) -> bool:
    """Whether numba's on-disk cache holds valid machine code of the kernels ``names`` (default: the
    set's own list) of set ``name`` (for this source, numba and Python version): then loading them
    takes a fraction of a second. Imports numba."""
    kernel_set = _sets[name]
    module = importlib.import_module(kernel_set.compiled)
    try:
        return all(
            len(getattr(module, n)._cache._cache_file._load_index()) > 0 for n in names or kernel_set.names
        )
    except Exception:  # numba's cache internals changed: assume a compile is needed
        return False


def compiled_kernels_cached(names: tuple[str, ...] = FIT_PREDICT_KERNELS) -> bool:
    """:func:`kernels_cached` of the inference kernels ``names``."""
    return kernels_cached(INFERENCE, names)


def _load(name: str, backend: str) -> ModuleType:
    """Set ``name``'s module of ``backend`` (imported once; a cold compile announced once per set)."""
    key = (name, backend)
    if key not in _state["modules"]:
        kernel_set = _sets[name]
        if backend == "numba":
            if name not in _state["announced"] and not kernels_cached(name):
                _state["announced"].add(name)
                # only the inference kernels' compile is measured (docs/first-minute.md)
                seconds = f"up to about {COMPILE_SECONDS} s, " if name == INFERENCE else ""
                announce(
                    f"[kernels] compiling the {kernel_set.label} ({seconds}once; cached on disk for "
                    "the next runs)"
                )
        _state["modules"][key] = importlib.import_module(
            kernel_set.compiled if backend == "numba" else kernel_set.numpy
        )
    return _state["modules"][key]


def _decide(name: str) -> str:
    """The version ``"auto"`` takes for set ``name`` in this process: compiled when cached, else numpy
    (and the kernels compiled apart, announced once per process)."""
    if kernels_cached(name):
        _state["announced"].add(name)  # loaded, not compiled: nothing to announce
        choice = "numba"
    else:
        choice = "numpy"
        if not any(v == "numpy" for v in _state["auto"].values()):  # the first set found uncompiled
            started = start_background_compile()
            log = _lock_path().parent
            why = (
                f"; compiling them in the background for the next runs (about {COMPILE_SECONDS} s, once)"
                if started
                else f" (a compile is running, or failed within a day: see its log in {log})"
            )
            label = _sets[name].label
            announce(f"[kernels] the {label} are not compiled yet: this run uses their numpy version{why}")
    _state["auto"][name] = choice
    return choice


def _lock_path() -> Path:
    from ..cache import cache_dir

    return cache_dir("kernels") / "compile.lock"


def _lock_is_stale(lock: Path, max_age_s: float = 600.0) -> bool:
    try:
        return time.time() - lock.stat().st_mtime > max_age_s
    except OSError:
        return True


def start_background_compile() -> bool:
    """Start the warm-up (``python -m ipromp_pin.promp.warmup``, compiling every registered set)
    detached, at low priority (output in the cache folder's ``kernels/compile.log``), unless one is
    running (its lock is less than 10 min old) or a compile failed within the last 24 h. Returns
    whether one was started."""
    lock = _lock_path()
    failed = lock.with_name("compile.failed")
    try:
        lock.parent.mkdir(parents=True, exist_ok=True)
        if failed.exists() and time.time() - failed.stat().st_mtime < 86400:
            return False
        if lock.exists():
            if not _lock_is_stale(lock):
                return False
            lock.unlink()
        fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        os.close(fd)
        log = open(lock.with_name("compile.log"), "w")  # noqa: SIM115 (handed to the child)
    except OSError:
        return False
    try:
        options: dict = {"start_new_session": True} if os.name == "posix" else {}
        if os.name == "nt":
            options["creationflags"] = getattr(subprocess, "DETACHED_PROCESS", 0) | getattr(
                subprocess, "CREATE_NEW_PROCESS_GROUP", 0
            )
        others = [s.warmup for n, s in _sets.items() if n != INFERENCE]
        subprocess.Popen(
            [sys.executable, "-m", "ipromp_pin.promp.warmup", "--lock", str(lock)]
            + [f"--also={m}" for m in others],
            stdin=subprocess.DEVNULL,
            stdout=log,
            stderr=subprocess.STDOUT,
            close_fds=True,
            **options,
        )
        return True
    except OSError:
        lock.unlink(missing_ok=True)
        return False
    finally:
        log.close()
