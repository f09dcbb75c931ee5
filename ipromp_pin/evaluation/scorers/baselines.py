"""The baselines as a scorer: fitted on the same training windows as the model, they add their
outcome on every test demo to the trial of the main scorer (``trial.baselines``)."""

from __future__ import annotations

from collections.abc import Sequence

from ...data import Demo
from ..baselines import BaselineTrial, WindowBaselines, require_sklearn
from ..baselines.features import FK
from ..windows import FitWindow
from .base import Scorer


class BaselineScorer(Scorer):
    """Every registered baseline (:mod:`ipromp_pin.evaluation.baselines.registry`), per window.

    Args:
        fk: Forward kinematics for the hand-over regressors (None: none).
    """

    def __init__(self, fk: FK | None = None) -> None:
        self.fk = fk

    def check(self) -> None:
        """scikit-learn must be installed (one-line error)."""
        require_sklearn()

    def fit(self, train: Sequence[Demo], observe: Sequence[str]) -> BaselineScorer:
        """Keep the training demos: the baselines are fitted per window, in :meth:`score`."""
        self.train_ = list(train)
        self.observe_ = list(observe)
        return self

    def score(
        self, test: Sequence[Demo], window: FitWindow | float, split: int = 0
    ) -> list[dict[str, BaselineTrial]]:
        """Per test demo, baseline name -> its outcome on the demo's ``window`` (fitted on the same
        window of every training demo)."""
        return WindowBaselines(self.observe_, window, self.fk).fit(self.train_).score(test)
