"""toppra imports ``matplotlib.pyplot`` when it is imported, for its optional plotting helpers
(toppra 0.6: ``toppra/algorithm/algorithm.py`` and ``toppra/parametrizer.py``), which costs more than
the rest of toppra and which this package never uses (its figures use matplotlib's ``Figure``
directly). :func:`defer_pyplot` puts a stand-in module under that name: the import statement binds
it without loading anything, and its first attribute use imports the real ``matplotlib.pyplot``
(which replaces the stand-in in ``sys.modules``) and answers from it, so that code using pyplot
through either works as with an ordinary import.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import Any

__all__ = ["DeferredModule", "defer_pyplot"]

PYPLOT = "matplotlib.pyplot"


class DeferredModule(types.ModuleType):
    """A stand-in for a module not imported yet: a missing attribute imports the real module."""

    def __getattr__(self, attr: str) -> Any:
        if attr.startswith("__"):
            raise AttributeError(attr)
        if sys.modules.get(self.__name__) is self:
            del sys.modules[self.__name__]
        real = importlib.import_module(self.__name__)
        return getattr(real, attr)


def defer_pyplot() -> bool:
    """Put a :class:`DeferredModule` under ``matplotlib.pyplot`` unless it is imported already;
    whether one was put."""
    if PYPLOT in sys.modules:
        return False
    sys.modules[PYPLOT] = DeferredModule(PYPLOT)
    return True
