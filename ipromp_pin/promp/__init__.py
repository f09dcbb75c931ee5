"""Multi-task EMG-augmented Interaction ProMPs: learn, recognise the task, predict the robot's motion.

The estimator is :class:`IProMP` (:mod:`.estimator`; its parameters and their constraints:
:mod:`.parameters`; what ``fit`` runs: :mod:`.fit`); its parts, one concept per module:

- :mod:`.basis`: Gaussian basis functions of the phase;
- :mod:`.distribution`: the per-task Gaussian over the stacked weights (shrinkage, scaling, phase prior);
- :mod:`.layout`, :mod:`.training`: channel layout, and the task models learned from demonstrations;
- :mod:`.selection`: cross-validation of the noise ratio and of the groups coupled to the robot;
- :mod:`.fitted`: the frozen fitted state; :mod:`.serialization` reads and writes it;
  :mod:`.provenance`: the records of the demos it was trained on;
- :mod:`.observation`: a partial observation checked and scaled into parts;
- :mod:`.latent_blocks`, :mod:`.likelihood`: the exact batched likelihood of every (task, phase);
- :mod:`.posterior`: task and phase posteriors (:class:`Recognition`, :class:`Prediction`);
- :mod:`.conditioning`: the conditioned robot trajectory and its covariance;
- :mod:`.predictor`: the above bundled for one fitted model; :mod:`.streaming`: sample by sample
  (its running sums per presence pattern: :mod:`.stream_parts`);
- :mod:`.window`: the observed window's summary (first, mean and last valid value per dim);
- :mod:`.head`, :mod:`.handover`: the recognition head and the hand-over regression;
- :mod:`.reference`: the textbook implementation the fast one is tested against;
- :mod:`.compiled`: the one switch of every kernel set (``_kernels``: the numba kernels, imported on
  first use; ``numpy_kernels``: their numpy version); :mod:`.warmup`: the one warm-up.
"""

from .basis import GaussianBasis
from .distribution import ChannelScaler, ShrunkCovariance, TaskModel, shrink_covariances
from .estimator import IProMP
from .fitted import FittedModel
from .layout import ChannelLayout
from .posterior import Prediction, Recognition, RobotWeightPosterior
from .predictor import Predictor
from .reference import direct_loglik, direct_predict
from .selection import NOISE_GRID
from .streaming import StreamingEstimator

__all__ = [
    "NOISE_GRID",
    "ChannelLayout",
    "ChannelScaler",
    "FittedModel",
    "GaussianBasis",
    "IProMP",
    "Prediction",
    "Predictor",
    "Recognition",
    "RobotWeightPosterior",
    "ShrunkCovariance",
    "StreamingEstimator",
    "TaskModel",
    "direct_loglik",
    "direct_predict",
    "shrink_covariances",
]
