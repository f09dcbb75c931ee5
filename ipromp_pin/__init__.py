"""ipromp_pin: EMG-augmented Interaction ProMPs with Pinocchio feasibility checks."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from .exceptions import (
    DataError,
    InfeasibleError,
    IPrompPinError,
    ModelError,
    ModelFileError,
    NotFittedError,
    ObservationError,
    PipelineError,
    RobotError,
)
from .version import __version__

if TYPE_CHECKING:
    from .data import ROBOT, Dataset, Demo
    from .plans import HandoverPlan, plan
    from .promp import IProMP, Prediction, Recognition, StreamingEstimator

_LAZY = {
    "ROBOT": "data",
    "Dataset": "data",
    "Demo": "data",
    "IProMP": "promp",
    "Prediction": "promp",
    "Recognition": "promp",
    "StreamingEstimator": "promp",
    "plan": "plans",
    "HandoverPlan": "plans",
}
"""Names imported on first use: the model's modules take 2-3 s to import (numpy, scipy, numba), which
``import ipromp_pin`` (and so ``ipromp-pin --help``, or a Ctrl-C during start-up) need not wait for."""


def __getattr__(name: str) -> object:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'ipromp_pin' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


__all__ = [
    "__version__",
    "ROBOT",
    "IProMP",
    "HandoverPlan",
    "plan",
    "Prediction",
    "Recognition",
    "StreamingEstimator",
    "DataError",
    "Dataset",
    "Demo",
    "IPrompPinError",
    "InfeasibleError",
    "ModelError",
    "ModelFileError",
    "NotFittedError",
    "ObservationError",
    "PipelineError",
    "RobotError",
]
