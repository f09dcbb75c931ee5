"""Which implementation of the human checks' kernels a process uses: :func:`human_kernels`.

The same backends as the inference kernels (:mod:`ipromp_pin.promp.compiled`, ``$IPROMP_PIN_KERNELS``):

* ``"numba"``: :mod:`ipromp_pin.human.separation_kernels` (compiled on first use, cached on disk);
* ``"numpy"``: :mod:`ipromp_pin.human.numpy_kernels` (nothing to compile, nothing written to disk);
* ``"auto"``: the compiled ones only when the process uses the compiled inference kernels
  (:func:`~ipromp_pin.promp.compiled.active_backend`) and numba's cache already holds the human ones;
  else numpy for the process, while the background compile (``python -m ipromp_pin.promp.warmup``,
  which also runs :func:`compile_kernels` of this module) fills the cache for the next runs.
"""

from __future__ import annotations

import time
from types import ModuleType

import numpy as np

from ..promp import compiled

__all__ = ["KERNELS", "compile_kernels", "human_kernels", "human_kernels_cached"]

KERNELS = ("arm_frames", "capsule_distances", "approach_speeds", "inverse_effective_masses", "pair_jtu")
"""The kernels the human checks call."""

compiled.register_warmup(__name__)


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


def compile_kernels() -> float:
    """Compile (or load) every human kernel through the real code path on a short motion of the shipped
    Baxter's left arm; returns the time taken in [s]. Run by the background compile."""
    from ..robot import load_robot
    from . import separation_kernels as sk
    from .body import HumanMotion
    from .separation import SeparationAnalyser

    t0 = time.perf_counter()
    with compiled.use_kernels("numba"):
        robot = load_robot("baxter_left")
        t = np.linspace(0.0, 0.2, 3)
        q = np.tile(0.5 * (robot.lower_rad + robot.upper_rad), (t.size, 1))
        qd = np.full(q.shape, 0.1)
        analyser = SeparationAnalyser(robot)
        analyser.analyse(t, q, qd, HumanMotion.assumed_human(t_s=t))
        # the effective-mass kernels run only for close, fast pairs: call them once directly
        caps = analyser.capsules
        origins, axes, ra, rb = sk.arm_frames(
            q, caps.x0, caps.axis_local, caps.anchor, caps.a_local, caps.b_local
        )
        body_r = np.full((t.size, 1), 0.05)
        dist, cr, ch = sk.capsule_distances(ra, rb, caps.radius_m, ra[:, :1].copy(), rb[:, :1].copy(), body_r)
        _, _, unit = sk.approach_speeds(dist, cr, ch, caps.radius_m, origins, axes, qd, caps.anchor, 0.1, 0.1)
        one = np.zeros(1, dtype=np.int64)
        w = sk.pair_jtu(one, one, one, cr, unit, caps.radius_m, origins, axes, caps.anchor, qd)
        sk.inverse_effective_masses(np.eye(q.shape[1])[None], one, np.ascontiguousarray(w))
    if not human_kernels_cached():
        raise RuntimeError("the human kernels ran but numba's cache does not hold them")
    return time.perf_counter() - t0
