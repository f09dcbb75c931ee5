"""Which implementation of the human checks' kernels a process uses: :func:`human_kernels`.

The same backends as the inference kernels (:mod:`ipromp_pin.promp.compiled`, ``$IPROMP_PIN_KERNELS``):

* ``"numba"``: :mod:`ipromp_pin.human.separation_kernels` (compiled on first use, cached on disk);
* ``"numpy"``: :mod:`ipromp_pin.human.numpy_kernels` (nothing to compile, nothing written to disk);
* ``"auto"``: the compiled ones only when the process uses the compiled inference kernels
  (:func:`~ipromp_pin.promp.compiled.active_backend`) and numba's cache already holds the human ones;
  else numpy for the process, while the background compile (``python -m ipromp_pin.promp.warmup``,
  which also runs :func:`ipromp_pin.human.warmup.compile_kernels`) fills the cache for the next runs.
"""

from __future__ import annotations

from types import ModuleType

from ..promp import compiled

__all__ = ["KERNELS", "human_kernels", "human_kernels_cached"]

KERNELS = (
    "arm_frames",
    "capsule_distances",
    "approach_speeds",
    "inverse_effective_masses",
    "pair_jtu",
    "separation_summary",
    "chain_mass_matrices",
)
"""The kernels the human checks call."""

compiled.register_warmup("ipromp_pin.human.warmup")  # its compile_kernels(), by name: no import


def human_kernels_cached() -> bool:
    """Whether numba's on-disk cache holds machine code of every kernel in :data:`KERNELS`. Imports numba."""
    from . import separation_kernels

    try:
        return all(len(getattr(separation_kernels, n)._cache._cache_file._load_index()) > 0 for n in KERNELS)
    except Exception:  # numba's cache internals changed: assume a compile is needed
        return False


def human_kernels() -> ModuleType:
    """The human kernels module of the current backend (see the module docstring)."""
    backend = compiled.kernel_backend()
    if backend == "auto":
        if compiled.active_backend() == "numba" and human_kernels_cached():
            backend = "numba"
        else:
            if compiled.active_backend() == "numba":  # inference compiled, the human kernels not yet
                compiled.start_background_compile()
            backend = "numpy"
    if backend == "numba":
        from . import separation_kernels

        return separation_kernels
    from . import numpy_kernels

    return numpy_kernels
