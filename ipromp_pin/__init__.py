"""ipromp_pin: EMG-augmented Interaction ProMPs with Pinocchio feasibility checks."""

from .data import ROBOT, Dataset, Demo
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
from .promp import IProMP, Prediction, Recognition, StreamingEstimator
from .version import __version__

__all__ = [
    "__version__",
    "ROBOT",
    "IProMP",
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
