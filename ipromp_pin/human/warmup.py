"""The human kernels compiled through the real code path: the human set's part of the one warm-up
(``python -m ipromp_pin.promp.warmup``; :mod:`ipromp_pin.human.kernels` registers the set with this
module as its warm-up)."""

from __future__ import annotations

import time

import numpy as np

from ..promp import compiled
from ..robot import load_robot
from . import separation_kernels as sk
from .body import HumanMotion
from .iso15066 import arm_mass_matrices
from .kernels import human_kernels_cached
from .separation import SeparationAnalyser
from .separation_summary import SeparationSummariser

__all__ = ["compile_kernels"]


def compile_kernels() -> float:
    """Compile (or load) every human kernel through the real code path on a short motion of the shipped
    Baxter's left arm; returns the time taken in [s]. Run by the background compile."""
    t0 = time.perf_counter()
    with compiled.use_kernels("numba"):
        robot = load_robot("baxter_left")
        t = np.linspace(0.0, 0.2, 3)
        q = np.tile(0.5 * (robot.lower_rad + robot.upper_rad), (t.size, 1))
        qd = np.full(q.shape, 0.1)
        analyser = SeparationAnalyser(robot)
        human = HumanMotion.assumed_human(t_s=t)
        analyser.analyse(t, q, qd, human)
        SeparationSummariser(analyser).summary(t, q, qd, human)
        arm_mass_matrices(robot, q, compiled=True)  # a summary calls it only near the human
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
