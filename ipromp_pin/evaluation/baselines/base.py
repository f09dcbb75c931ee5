"""What every baseline shares: the optional scikit-learn dependency, the cross-validation folds
and the registry in which a baseline is one entry (name -> estimator factory)."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from typing import Generic, Protocol, Self, TypeVar

import numpy as np

from ...exceptions import IPrompPinError

CV_FOLDS = 5
"""Folds of the baselines' cross-validations on the training demos (fewer when a task has fewer demos)."""


class Estimator(Protocol):
    """What a baseline uses of a scikit-learn estimator (scikit-learn ships no type information)."""

    def fit(self, x: np.ndarray, y: np.ndarray) -> Self:
        """Fit on features ``x`` (n, D) and targets ``y`` (n,) or (n, K); returns the estimator."""
        ...

    def predict(self, x: np.ndarray) -> np.ndarray:
        """Predictions for the features ``x`` (n, D)."""
        ...


class Classifier(Estimator, Protocol):
    """A fitted scikit-learn classifier: its ``classes_`` and their probabilities."""

    classes_: np.ndarray

    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        """Probabilities (n, n_classes) of the ``classes_`` for the features ``x`` (n, D)."""
        ...


class Transformer(Protocol):
    """What the baselines use of a scikit-learn transformer (the features' standardiser)."""

    def fit_transform(self, x: np.ndarray) -> np.ndarray:
        """Fit on ``x`` (n, D) and return it transformed (n, D)."""
        ...

    def transform(self, x: np.ndarray) -> np.ndarray:
        """The features ``x`` (n, D) transformed (n, D)."""
        ...


Factory = Callable[..., Estimator]
"""An estimator factory: a classifier's takes the training labels ``y`` (n,), a regressor's the
number ``n`` of training demos of its task; each returns an unfitted scikit-learn estimator."""

ClassifierFactory = Callable[[np.ndarray], Classifier]
"""A recognition baseline's factory: training labels ``y`` (n,) -> unfitted classifier."""

RegressorFactory = Callable[[int], Estimator]
"""A motion baseline's factory: number ``n`` of training demos of the task -> unfitted regressor."""

F = TypeVar("F", bound=Factory)


class MissingDependencyError(IPrompPinError):
    """An optional dependency is not installed."""


def require_sklearn() -> None:
    """Raise :class:`MissingDependencyError` (one line) when scikit-learn is not installed."""
    try:
        import sklearn  # noqa: F401
    except ImportError as exc:
        raise MissingDependencyError(
            "--baselines needs scikit-learn: pip install 'ipromp_pin[baselines]' (or scikit-learn)"
        ) from exc


def folds(n: int) -> int:
    """Cross-validation folds for ``n`` training samples of the smallest class (2 to :data:`CV_FOLDS`)."""
    return max(2, min(CV_FOLDS, n))


class Registry(Mapping[str, F], Generic[F]):
    """Baseline name -> estimator factory, in registration order. Iterating gives the names, so a
    registry reads as the tuple of names it replaced (``for name in CLASSIFIERS``, ``set(...)``).

    Args:
        kind: ``"classifier"`` or ``"regressor"`` (named in errors).
        entries: Initial (name, factory) pairs.
    """

    def __init__(self, kind: str, entries: Mapping[str, F]) -> None:
        self.kind = kind
        self._entries: dict[str, F] = dict(entries)

    def __getitem__(self, name: str) -> F:
        return self._entries[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def __repr__(self) -> str:
        return f"Registry({self.kind!r}, {list(self._entries)})"

    def register(self, name: str, factory: F) -> None:
        """Add a baseline; its results then appear under ``name`` in every evaluation cell."""
        if name in self._entries:
            raise ValueError(f"{self.kind} baseline '{name}' is already registered")
        self._entries[name] = factory

    def unregister(self, name: str) -> None:
        """Remove a baseline (e.g. one a test registered)."""
        del self._entries[name]
