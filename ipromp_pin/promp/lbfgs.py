"""L-BFGS minimisation of a smooth unconstrained function, the iterations of
``scipy.optimize.minimize(method="L-BFGS-B")`` without its per-evaluation wrappers.

The recognition head (:mod:`~ipromp_pin.promp.head`) fits hundreds of small logistic regressions
(about a hundred parameters, ten evaluations each) whose loss costs about as much as scipy's wrapper
objects around it (the scalar-function cache, copies, the result object). :func:`minimize_lbfgs`
drives scipy's own L-BFGS-B step routine with the same arguments, defaults and evaluation points as
``minimize`` (no bounds, ``maxcor=10``, ``ftol=2.22e-9``, ``gtol=1e-5``, ``maxls=20``), so its
iterates are the same numbers; with a scipy whose step routine it does not know (before 1.15) it
calls ``minimize``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy
from scipy.optimize import minimize

try:  # scipy >= 1.15: the C port of L-BFGS-B and its reverse-communication step routine
    from scipy.optimize import _lbfgsb

    _SETULB = _lbfgsb.setulb if tuple(int(v) for v in scipy.__version__.split(".")[:2]) >= (1, 15) else None
except (ImportError, AttributeError, ValueError):  # pragma: no cover - other scipy versions
    _SETULB = None

MAXCOR = 10
"""Stored correction pairs (scipy's default)."""

FTOL = 2.2204460492503131e-09
"""Relative reduction of the function below which the iterations stop (scipy's default)."""

GTOL = 1e-5
"""Largest gradient component below which the iterations stop (scipy's default)."""

MAXLS = 20
"""Largest number of line-search steps per iteration (scipy's default)."""

MAXFUN = 15000
"""Largest number of function evaluations (scipy's default)."""


def minimize_lbfgs(
    fun: Callable[[np.ndarray], tuple[float, np.ndarray]], x0: np.ndarray, max_iter: int = 500
) -> np.ndarray:
    """The minimiser (n,) of ``fun`` (parameters (n,) -> value, gradient (n,)) found by L-BFGS from
    ``x0`` (n,) in at most ``max_iter`` iterations: the ``x`` of
    ``scipy.optimize.minimize(fun, x0, jac=True, method="L-BFGS-B", options={"maxiter": max_iter})``.
    ``fun`` must not modify its argument."""
    if _SETULB is None:  # pragma: no cover - scipy < 1.15
        return minimize(fun, x0, jac=True, method="L-BFGS-B", options={"maxiter": max_iter}).x
    x = np.array(np.asarray(x0).ravel(), dtype=np.float64)
    n = x.size
    low, high = np.zeros(n), np.zeros(n)
    bounded = np.zeros(n, np.int32)  # no bounds
    wa = np.zeros(2 * MAXCOR * n + 5 * n + 11 * MAXCOR * MAXCOR + 8 * MAXCOR)
    iwa = np.zeros(3 * n, np.int32)
    task = np.zeros(2, np.int32)
    ln_task = np.zeros(2, np.int32)
    lsave = np.zeros(4, np.int32)
    isave = np.zeros(44, np.int32)
    dsave = np.zeros(29)
    factr = FTOL / np.finfo(float).eps
    # scipy evaluates at x0 first and re-evaluates only where x changed
    x_eval = x.copy()
    f_eval, g_eval = fun(x_eval.copy())
    n_fev, n_iter = 1, 0
    f: float | np.ndarray = np.array(0.0)  # the routine's first call reads a zero
    g = np.zeros(n)
    while True:
        g = g.astype(np.float64)
        _SETULB(
            MAXCOR,
            x,
            low,
            high,
            bounded,
            f,
            g,
            factr,
            GTOL,
            wa,
            iwa,
            task,
            lsave,
            isave,
            dsave,
            MAXLS,
            ln_task,
        )
        if task[0] == 3:  # the routine asks for f and g at x
            if not (x == x_eval).all():  # np.array_equal's answer for arrays of one shape, cheaper
                x_eval = x.copy()
                f_eval, g_eval = fun(x_eval.copy())
                n_fev += 1
            f, g = f_eval, np.atleast_1d(g_eval)
        elif task[0] == 1:  # a new iteration
            n_iter += 1
            if n_iter >= max_iter or n_fev > MAXFUN:
                task[0], task[1] = 5, 504
        else:
            break
    return x
