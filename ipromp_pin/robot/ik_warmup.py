"""The inverse-kinematics kernels compiled through the real code path: the ``"ik"`` set's part of the
one warm-up (``python -m ipromp_pin.promp.warmup``; :mod:`ipromp_pin.robot.arm_chain` registers the
set with this module as its warm-up)."""

from __future__ import annotations

import time

import numpy as np

from ..promp import compiled
from .arm_chain import chain_placements, ik_kernels_cached
from .arm_transfer import PathSolution, PoseSolver, SolveSteps, transfer_path, transfer_samples
from .model import load_robot

__all__ = ["compile_kernels"]


def compile_kernels() -> float:
    """Compile (or load) every inverse-kinematics kernel with the signatures the retargeting uses: a
    short Baxter path retargeted to the shipped Panda (the one-shot plan's calls) and the closed
    loop's solve of every pose from given seeds; returns the time taken in [s]."""
    t0 = time.perf_counter()
    with compiled.use_kernels("numba"):
        baxter, panda = load_robot("baxter_left"), load_robot("panda")
        mid = 0.5 * (baxter.lower_rad + baxter.upper_rad)
        q = mid + np.linspace(0.0, 0.05, 4)[:, None]
        path = transfer_path(baxter, panda, q)
        transfer_samples(baxter, panda, q[None] + 1e-3, path, q)
        solver = PoseSolver(panda)
        out = PathSolution.empty(q.shape[0], panda.n_joints)
        pos, rot = chain_placements(panda, path.q)
        solver.follow(rot, pos, SolveSteps.seeded(path.q, 10), out)
    if not ik_kernels_cached():
        raise RuntimeError("the inverse-kinematics kernels ran but numba's cache does not hold them")
    return time.perf_counter() - t0
