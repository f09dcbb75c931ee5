"""Settings of an evaluation (:class:`EvaluationConfig`) and the paper's table (its cells and the
accuracies it reports on ``chen2017_handover``)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from ..exceptions import DataError
from .windows import Window

PAPER_GRID: tuple[tuple[int, float], ...] = ((20, 0.1), (15, 0.1), (10, 0.1), (10, 0.2))
"""(n_train, obs_ratio) cells of the paper's table."""

PAPER_ACCURACY: dict[tuple[int, float, str], dict[str, float]] = {
    (20, 0.1, "orientation"): {"aluminum_hold": 0.90, "spanner_handover": 0.60, "tape_hold": 0.10},
    (20, 0.1, "orientation+emg"): {"aluminum_hold": 1.00, "spanner_handover": 1.00, "tape_hold": 0.70},
    (15, 0.1, "orientation"): {"aluminum_hold": 0.60, "spanner_handover": 0.60, "tape_hold": 0.10},
    (15, 0.1, "orientation+emg"): {"aluminum_hold": 1.00, "spanner_handover": 0.90, "tape_hold": 0.70},
    (10, 0.1, "orientation"): {"aluminum_hold": 0.00, "spanner_handover": 0.00, "tape_hold": 0.80},
    (10, 0.1, "orientation+emg"): {"aluminum_hold": 0.50, "spanner_handover": 0.80, "tape_hold": 0.70},
    (10, 0.2, "orientation"): {"aluminum_hold": 0.30, "spanner_handover": 1.00, "tape_hold": 0.90},
    (10, 0.2, "orientation+emg"): {"aluminum_hold": 1.00, "spanner_handover": 1.00, "tape_hold": 1.00},
}
"""Accuracies reported in the paper (Chen et al. 2017) on ``chen2017_handover``, per task."""

PROTOCOLS = ("paper", "splits", "folds", "open-set")
"""The evaluation protocols."""

ProgressFn = Callable[[int, int, str], None]
"""Called as ``progress(done, total, label)`` after every model fit."""


@dataclass
class EvaluationConfig:
    """Settings of an evaluation run.

    Attributes:
        protocol: ``"paper"``, ``"splits"``, ``"folds"`` (k-fold: per task the demos in ``n_folds``
            seeded random folds, each fold tested once by a model of ``n_train`` of the other folds'
            demos, so that every demo is a test demo once) or ``"open-set"`` (the random splits, each
            task left out in turn: :mod:`~ipromp_pin.evaluation.open_set`).
        observe: Observed channel sets, each a list of group names.
        grid: (n_train, window) cells: a window is an observed fraction of each test demo (a float,
            the paper's ``obs_ratio``) or a :class:`~.windows.Window` (e.g. in seconds).
        n_test: Test demos per task.
        n_splits: Random splits (``splits`` protocol).
        seed: Seed of the random splits.
        model_params: Keyword arguments of the model's constructor.
        baselines: Also run the reference baselines on the same windows
            (:mod:`ipromp_pin.evaluation.baselines`).
        n_folds: Folds of the ``folds`` protocol.
        run_folds: The folds run (0-based; None: every fold).
    """

    protocol: str = "paper"
    observe: list[list[str]] = field(default_factory=lambda: [["orientation"], ["orientation", "emg"]])
    grid: list[tuple[int, float | Window]] = field(default_factory=lambda: [(n, r) for n, r in PAPER_GRID])
    n_test: int = 10
    n_splits: int = 20
    seed: int = 0
    model_params: dict = field(default_factory=dict)
    baselines: bool = False
    n_folds: int = 5
    run_folds: list[int] | None = None

    def check_protocol(self) -> None:
        """Raise a :class:`DataError` naming the field when the protocol is not one of :data:`PROTOCOLS`."""
        if self.protocol not in PROTOCOLS:
            raise DataError(
                None, "protocol", f"unknown protocol '{self.protocol}' (use paper, splits, folds or open-set)"
            )
        bad = [f for f in self.run_folds or [] if not 0 <= f < self.n_folds]
        if self.protocol == "folds" and (self.n_folds < 2 or bad):
            raise DataError(
                None,
                "folds",
                f"{self.n_folds} folds, folds to run {bad}: at least 2 folds, each run one of them",
            )

    def cells(self) -> list[tuple[int, Window]]:
        """The grid's (n_train, window) cells, a bare fraction as a ``ratio`` window, each once."""
        return list(dict.fromkeys((int(n), Window.of(w)) for n, w in self.grid))

    @property
    def repeats(self) -> int:
        """Model fits per (n_train, observed set): 1 for the paper protocol, the folds run for
        ``folds``, ``n_splits`` otherwise."""
        if self.protocol == "folds":
            return len(self.fold_indices())
        return 1 if self.protocol == "paper" else self.n_splits

    def fold_indices(self) -> list[int]:
        """The folds run by the ``folds`` protocol (0-based, in order)."""
        return sorted(set(self.run_folds)) if self.run_folds else list(range(self.n_folds))


def observe_key(observe: Sequence[str]) -> str:
    """Canonical text of an observed channel set, e.g. ``"orientation+emg"``."""
    return "+".join(observe)
