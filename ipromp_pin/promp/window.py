"""The observed window's features: the first, mean and last valid value of every dim, written once.

:func:`window_summary` is the one computation; the recognition head (:class:`WindowSummary`, over an
encoded observation's parts), the hand-over regression (:func:`window_features`, the mean and last
rows of some dims) and the scikit-learn baselines (:mod:`ipromp_pin.evaluation.baselines.features`,
over a raw window's groups) all read it. A stream keeps the same summary up to date sample by sample
(:class:`RunningWindow`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .observation import ObservationPart

__all__ = ["RunningWindow", "WindowSummary", "window_features", "window_summary"]


def window_summary(y: np.ndarray, valid: np.ndarray | None = None, fill: float = 0.0) -> np.ndarray:
    """(3, D) rows: the first, mean and last of the valid rows of ``y`` (n, D) (samples in time order;
    ``valid`` (n,) bool, default all), or ``fill`` for every dim when no row is valid. The mean is
    taken over a C-ordered array, so that its rounding does not depend on how ``y`` lies in memory."""
    rows = np.ascontiguousarray(y if valid is None else np.asarray(y)[valid], dtype=float)
    if rows.shape[0] == 0:
        return np.full((3, rows.shape[1]), fill)
    return np.stack([rows[0], rows.mean(axis=0), rows[-1]])


def window_features(values: np.ndarray, dims: np.ndarray | None = None) -> np.ndarray:
    """Regression features (2 F,): the mean values then the last values of the dims ``dims`` (default
    all) of a window summary ``values`` ((3, D) or its (3 D,) vector: first, mean and last values)."""
    rows = np.asarray(values, dtype=float).reshape(3, -1)
    return (rows[1:] if dims is None else rows[1:, dims]).reshape(-1)


@dataclass(frozen=True)
class WindowSummary:
    """First, mean and last valid value of every observed dim over an observed window (scaled units).

    Attributes:
        values: (3, D_o) rows: the first, mean and last values; 0 (the training mean) for a dim
            without a sample.
    """

    values: np.ndarray

    @property
    def first(self) -> np.ndarray:
        """(D_o,) first valid values."""
        return self.values[0]

    @property
    def mean(self) -> np.ndarray:
        """(D_o,) mean values."""
        return self.values[1]

    @property
    def last(self) -> np.ndarray:
        """(D_o,) last valid values."""
        return self.values[2]

    @classmethod
    def from_parts(cls, parts: list[ObservationPart], n_obs: int) -> WindowSummary:
        """Summary of encoded observation parts (dims ``0 .. n_obs - 1``; every dim in at most one
        part, as :meth:`~ipromp_pin.promp.observation.ObservationEncoder.encode` and a stream make
        them: groups with the same missing samples share a part)."""
        out = np.zeros((3, n_obs))
        seen = np.zeros(n_obs, dtype=bool)
        for p in parts:
            if seen[p.dims].any():
                raise ValueError("observation parts share a dim: the window summary needs disjoint parts")
            seen[p.dims] = True
            if p.t.size:
                out[:, p.dims] = window_summary(p.y)
        return cls(out)

    def vector(self) -> np.ndarray:
        """(3 D_o,) first, mean and last values side by side."""
        return self.values.reshape(-1)


class RunningWindow:
    """The :func:`window_summary` of a stream's scaled samples (D,), kept up to date as they arrive.

    Attributes:
        values: (3, D) first, mean and last values (0 for a dim without a sample).
        total, count: (D,) running sums and counts of the mean.
    """

    def __init__(self, n_dims: int) -> None:
        self.values = np.zeros((3, n_dims))
        self.total, self.count = np.zeros(n_dims), np.zeros(n_dims)

    def add(self, ys: np.ndarray, have: np.ndarray) -> None:
        """Add the sample ``ys`` (D,) in the dims where ``have`` (D,) is True."""
        values, count = self.values, self.count
        values[0, have & (count == 0)] = ys[have & (count == 0)]
        self.total[have] += ys[have]
        count[have] += 1
        values[2, have] = ys[have]
        np.divide(self.total, count, out=values[1], where=count > 0)

    def summary(self) -> WindowSummary:
        """A copy of the current summary."""
        return WindowSummary(self.values.copy())
