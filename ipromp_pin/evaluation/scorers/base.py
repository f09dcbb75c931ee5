"""The scorer interface of the evaluation protocol (in the manner of scikit-learn's scorers: any
scorer plugs into the one runner, :func:`~ipromp_pin.evaluation.protocol.run_protocol`)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence

from ...data import Demo
from ..cells import Cell, CellResults
from ..config import EvaluationConfig
from ..windows import WINDOW_KINDS, FitWindow


class Scorer(ABC):
    """Fitted on a split's training demos, scores its test demos at an observation window.

    A scorer is copied into every worker process once (by the pool initializer) and then fitted
    and scored job after job there; ``fit`` replaces the fitted state (trailing ``_``).

    Attributes:
        label: Prefix of the progress label (e.g. ``"closed loop "``).
        cell_type: The cell class the scorer's trials aggregate into.
        window_kinds: The kinds of window it scores (:data:`~..windows.WINDOW_KINDS`).
    """

    label: str = ""
    cell_type: type[Cell] = Cell
    window_kinds: tuple[str, ...] = WINDOW_KINDS

    def check(self) -> None:  # noqa: B027 (optional hook)
        """Check the scorer's settings before any model is fitted (in the parent process)."""

    @abstractmethod
    def fit(self, train: Sequence[Demo], observe: Sequence[str]) -> Scorer:
        """Fit on the training demos, observing the ``observe`` groups; returns ``self``."""

    @abstractmethod
    def score(self, test: Sequence[Demo], window: FitWindow | float, split: int = 0) -> list:
        """One record per test demo (in order), each seeing the ``window`` of the demo
        (:meth:`~..windows.FitWindow.cut`; a bare float: that fraction of each demo); ``split`` is
        the index of the repeat the demos come from."""

    def fit_facts(self) -> dict[str, str]:
        """Facts about the last fit, gathered per job (``coupled``: the coupled groups)."""
        return {}

    def cell_fields(self, reps: Sequence[Sequence], config: EvaluationConfig, results: CellResults) -> dict:
        """Fields of :attr:`cell_type` beyond the shared ones, from a cell's trials per split."""
        return {}
