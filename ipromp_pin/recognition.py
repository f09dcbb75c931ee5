"""Compatibility alias: the estimator moved to :mod:`ipromp_pin.promp`.

``from ipromp_pin.recognition import IProMP`` keeps working; new code imports from
:mod:`ipromp_pin` or :mod:`ipromp_pin.promp`.
"""

from .promp import (
    NOISE_GRID,
    IProMP,
    Prediction,
    Recognition,
    StreamingEstimator,
    direct_loglik,
    direct_predict,
)

__all__ = [
    "NOISE_GRID",
    "IProMP",
    "Prediction",
    "Recognition",
    "StreamingEstimator",
    "direct_loglik",
    "direct_predict",
]
