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
from .recognition import IProMP, Prediction, Recognition, StreamingEstimator

__version__ = "0.1.0"

__all__ = [
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
