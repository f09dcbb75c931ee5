"""The human checks' kernels: the set ``"human"`` of the package's one kernel switch
(:mod:`ipromp_pin.promp.compiled`, ``$IPROMP_PIN_KERNELS``): :mod:`ipromp_pin.human.separation_kernels`
compiled, :mod:`ipromp_pin.human.numpy_kernels` their numpy version. :func:`human_kernels` gives the
module of the current backend; the one warm-up compiles them with the inference kernels
(:func:`ipromp_pin.human.warmup.compile_kernels`).
"""

from __future__ import annotations

from types import ModuleType

from ..promp import compiled

__all__ = ["HUMAN", "KERNELS", "human_kernels", "human_kernels_cached"]

HUMAN = "human"
"""Name of the human checks' kernel set."""

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

compiled.register_kernel_set(
    HUMAN,
    compiled.KernelSet(
        "ipromp_pin.human.separation_kernels",
        "ipromp_pin.human.numpy_kernels",
        KERNELS,
        "ipromp_pin.human.warmup",
        "human-check kernels",
    ),
)


def human_kernels_cached() -> bool:
    """Whether numba's on-disk cache holds machine code of every kernel in :data:`KERNELS`. Imports numba."""
    return compiled.kernels_cached(HUMAN)


def human_kernels() -> ModuleType:
    """The human kernels module of the current backend (:func:`ipromp_pin.promp.compiled.kernels`)."""
    return compiled.kernels(HUMAN)
