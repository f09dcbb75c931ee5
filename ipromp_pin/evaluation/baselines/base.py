"""What every baseline shares: the optional scikit-learn dependency, the cross-validation folds
and the registry in which a baseline is one entry (name -> estimator factory)."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping

from ...exceptions import IPrompPinError

CV_FOLDS = 5
"""Folds of the baselines' cross-validations on the training demos (fewer when a task has fewer demos)."""

Factory = Callable[..., object]
"""An estimator factory: a classifier's takes the training labels ``y`` (n,), a regressor's the
number ``n`` of training demos of its task; each returns an unfitted scikit-learn estimator."""


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


class Registry(Mapping[str, Factory]):
    """Baseline name -> estimator factory, in registration order. Iterating gives the names, so a
    registry reads as the tuple of names it replaced (``for name in CLASSIFIERS``, ``set(...)``).

    Args:
        kind: ``"classifier"`` or ``"regressor"`` (named in errors).
        entries: Initial (name, factory) pairs.
    """

    def __init__(self, kind: str, entries: Mapping[str, Factory]) -> None:
        self.kind = kind
        self._entries: dict[str, Factory] = dict(entries)

    def __getitem__(self, name: str) -> Factory:
        return self._entries[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def __repr__(self) -> str:
        return f"Registry({self.kind!r}, {list(self._entries)})"

    def register(self, name: str, factory: Factory) -> None:
        """Add a baseline; its results then appear under ``name`` in every evaluation cell."""
        if name in self._entries:
            raise ValueError(f"{self.kind} baseline '{name}' is already registered")
        self._entries[name] = factory

    def unregister(self, name: str) -> None:
        """Remove a baseline (e.g. one a test registered)."""
        del self._entries[name]
