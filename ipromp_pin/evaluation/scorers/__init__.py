"""Scorers of the evaluation protocol, one per file behind :class:`~.base.Scorer`: the one-shot
prediction, the closed loop, and the baselines (which annotate the trials of the others)."""

from .base import Scorer
from .baselines import BaselineScorer
from .closed_loop import ClosedLoopOptions, ClosedLoopScorer, ClosedLoopTrial
from .one_shot import OneShotScorer, TrialResult, score_trial

__all__ = [
    "BaselineScorer",
    "ClosedLoopOptions",
    "ClosedLoopScorer",
    "ClosedLoopTrial",
    "OneShotScorer",
    "Scorer",
    "TrialResult",
    "score_trial",
]
