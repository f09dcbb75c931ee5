"""The compiled inference kernels (:mod:`ipromp_pin.promp._kernels`), imported on first use.

Importing :mod:`ipromp_pin` does not import numba: the kernels module is imported (and its cached
machine code loaded, or compiled on the very first call of a fresh install) only when an inference
first needs it. :func:`kernels` is that one entry point.
"""

from __future__ import annotations

from types import ModuleType

_LOADED: list[ModuleType] = []  # the kernels module once imported (a lookup is cheaper than an import)


def kernels() -> ModuleType:
    """The compiled kernels module (imports numba and loads or compiles the kernels on first use)."""
    if not _LOADED:
        from . import _kernels  # deferred: numba is heavy and only inference needs it

        _LOADED.append(_kernels)
    return _LOADED[0]
