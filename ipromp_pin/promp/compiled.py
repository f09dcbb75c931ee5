"""Which implementation of the inference kernels a process uses: :func:`kernels` is the one entry point.

Two implementations with the same functions and results (to rounding: the tests hold them to 1e-9):

* ``"numba"``: the compiled kernels (:mod:`ipromp_pin.promp._kernels`). Importing :mod:`ipromp_pin`
  does not import numba; the kernels module is imported when an inference first needs it and its
  machine code is loaded from numba's on-disk cache, or compiled on the very first use of a fresh
  install (about 20 s, once; announced through :func:`set_announcer`).
* ``"numpy"``: the same kernels in plain numpy (:mod:`ipromp_pin.promp.numpy_kernels`): nothing to
  compile or load, a little slower per call on large problems.

The backend is ``$IPROMP_PIN_KERNELS`` when set, else ``"numba"`` for library use; the short
commands (``ipromp-pin run``, ``preview``, ``train``) use ``"auto"``: decided once per process, at
its first inference, the compiled kernels when numba's cache already holds them, else the numpy
kernels for the whole process while a background process (``python -m ipromp_pin.promp.warmup``,
detached, at low priority, one at a time) compiles them into the cache for the next runs. So a
fresh install's first run does not wait for the compile, and a process never mixes the two.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from types import ModuleType

__all__ = [
    "BACKENDS",
    "BACKEND_ENV",
    "COMPILE_SECONDS",
    "FIT_PREDICT_KERNELS",
    "compiled_kernels_cached",
    "active_backend",
    "kernel_backend",
    "kernels",
    "numba_kernels",
    "register_warmup",
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
"""Announced duration in [s] of the one-time compile (measured: 17-20 s on one core, see
``benchmarks/first_minute.py``)."""

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
"""The kernels that fitting and prediction call (streaming adds ``stream_sample``, ``sherman_morrison``,
``stream_group``, ``add_sample``, ``basis_rows``)."""

_state: dict = {
    "backend": os.environ.get(BACKEND_ENV) or "numba",
    "numba": None,  # the compiled kernels module once imported
    "numpy": None,
    "auto_numpy": False,  # auto mode decided on the numpy kernels for this process
    "announce": None,
    "announced_compile": False,
    "warmups": [],  # modules whose compile_kernels() the background compile also runs
}


def set_announcer(announce: Callable[[str], None] | None) -> None:
    """Where one-line notices about the kernels go (the one-time compile; ``None``: nowhere)."""
    _state["announce"] = announce


def _say(message: str) -> None:
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
    _state["auto_numpy"] = False  # "auto" decides afresh at its next first inference
    return previous


@contextlib.contextmanager
def use_kernels(backend: str) -> Iterator[None]:
    """Use ``backend`` inside a ``with`` block (e.g. to compare the implementations)."""
    previous = set_kernel_backend(backend)
    try:
        yield
    finally:
        set_kernel_backend(previous)


def active_backend() -> str:
    """``"numba"`` or ``"numpy"``: what :func:`kernels` uses in this process (deciding ``"auto"`` now if
    no inference has yet). Other packages' kernels follow it, so that a process never mixes them."""
    return "numpy" if kernels() is _state["numpy"] else "numba"


def register_warmup(module: str) -> None:
    """Have the background compile also run ``module``'s ``compile_kernels()`` (another package's
    numba kernels, e.g. ``"ipromp_pin.human.warmup"``), after the inference kernels."""
    if module not in _state["warmups"]:
        _state["warmups"].append(module)


def _numpy_module() -> ModuleType:
    if _state["numpy"] is None:
        from . import numpy_kernels

        _state["numpy"] = numpy_kernels
    return _state["numpy"]


def _numba_module(announce_compile: bool = True) -> ModuleType:
    if _state["numba"] is None:
        from . import _kernels  # deferred: numba is heavy and only inference needs it

        _state["numba"] = _kernels
        if announce_compile and not _state["announced_compile"] and not compiled_kernels_cached():
            _state["announced_compile"] = True
            _say(
                f"[kernels] compiling the inference kernels (up to about {COMPILE_SECONDS} s, once; "
                "cached on disk for the next runs)"
            )
    return _state["numba"]


def numba_kernels() -> ModuleType:
    """The compiled kernels module, whatever the backend (announcing a compile the cache lacks)."""
    return _state["numba"] or _numba_module()


def compiled_kernels_cached(names: tuple[str, ...] = FIT_PREDICT_KERNELS) -> bool:
    """Whether numba's on-disk cache holds valid machine code of the kernels ``names`` (for this
    source, numba and Python version): then loading them takes a fraction of a second. Imports numba."""
    from . import _kernels

    try:
        return all(len(getattr(_kernels, n)._cache._cache_file._load_index()) > 0 for n in names)
    except Exception:  # numba's cache internals changed: assume a compile is needed
        return False


def kernels() -> ModuleType:
    """The kernels module of the current backend (see the module docstring)."""
    backend = _state["backend"]
    if backend == "numba":
        return _state["numba"] or _numba_module()
    if backend == "numpy":
        return _state["numpy"] or _numpy_module()
    return _auto()


def _auto() -> ModuleType:
    """Decided once per process: compiled kernels when cached, else numpy (and compile them apart)."""
    if _state["numba"] is not None:
        return _state["numba"]
    if _state["auto_numpy"]:
        return _state["numpy"]
    if compiled_kernels_cached():
        return _numba_module(announce_compile=False)
    started = start_background_compile()
    _say(
        "[kernels] the inference kernels are not compiled yet: this run uses their numpy version"
        + (
            f"; compiling them in the background for the next runs (about {COMPILE_SECONDS} s, once)"
            if started
            else f" (a compile is running, or failed within a day: see its log in {_lock_path().parent})"
        )
    )
    _state["auto_numpy"] = True
    return _numpy_module()


def _lock_path() -> Path:
    from ..cache import cache_dir

    return cache_dir("kernels") / "compile.lock"


def _lock_is_stale(lock: Path, max_age_s: float = 600.0) -> bool:
    try:
        return time.time() - lock.stat().st_mtime > max_age_s
    except OSError:
        return True


def start_background_compile() -> bool:
    """Start ``python -m ipromp_pin.promp.warmup`` detached (output in the cache folder's
    ``kernels/compile.log``), unless one is running (its lock is less than 10 min old) or a compile
    failed within the last 24 h. Returns whether one was started."""
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
        subprocess.Popen(
            [sys.executable, "-m", "ipromp_pin.promp.warmup", "--lock", str(lock)]
            + [f"--also={m}" for m in _state["warmups"]],
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
