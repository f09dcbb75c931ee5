"""The recognition head's features and its interpolation between observed fractions: pure functions
that the head (:mod:`ipromp_pin.promp.head`), its cross-validation and the numpy twin of its compiled
posterior kernel (:mod:`ipromp_pin.promp.numpy_kernels`) share."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["LOG_POSTERIOR_CLIP", "head_features", "interpolation", "observed_fraction"]

LOG_POSTERIOR_CLIP = -30.0
"""The generative log posterior enters the head clipped at this value (a confident generative mistake
then costs a bounded amount)."""


def observed_fraction(posterior: np.ndarray, alpha: np.ndarray, t_last: float, t_norm: float) -> float:
    """Expected observed fraction of the motion under the generative posterior: the tasks' posterior
    (T,) weighting ``t_last / (alpha_k T_norm)`` with their MAP phases ``alpha`` (T,), ``t_last`` and
    ``T_norm`` in [s] (the motion's duration is unknown online)."""
    return float(t_last / t_norm * np.dot(posterior, 1.0 / alpha))


def interpolation(ratios: Sequence[float], fraction: float) -> tuple[int, float]:
    """Index ``i`` and weight ``w`` of the linear interpolation between ``ratios[i]`` and
    ``ratios[i + 1]`` at ``fraction`` (``w = 0`` below the first and above the last)."""
    if fraction <= ratios[0]:
        return 0, 0.0
    i = 0
    while i + 1 < len(ratios) and ratios[i + 1] <= fraction:
        i += 1
    if i + 1 == len(ratios):
        return i, 0.0
    return i, (fraction - ratios[i]) / (ratios[i + 1] - ratios[i])


def head_features(
    window: np.ndarray, generative_log_posterior: np.ndarray, clip: float = LOG_POSTERIOR_CLIP
) -> np.ndarray:
    """Raw head features (F,): the window values (3 D_o,) then the generative log posterior clipped
    below at ``clip``."""
    return np.concatenate([window, np.maximum(generative_log_posterior, clip)])
