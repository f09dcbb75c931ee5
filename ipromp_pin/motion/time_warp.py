"""A smooth local slow-down of a reference motion's timeline, for the closed loop's re-target.

A re-targeted motion follows its :class:`~.retarget.ReferenceMotion` ``r(tau)`` (``tau``: time on the
human's predicted timeline) ``k`` times slower: ``dtau/dt = 1 / k``. A :class:`TimeWarp` slows it
further only where asked, by a factor ``g(tau) >= 1``: ``dtau/dt = 1 / (k g(tau))``. The follower's
velocity is then ``r'(tau) tau'`` and its acceleration ``r''(tau) tau'^2 + r'(tau) tau''`` with
``tau'' = -g'(tau) / (k^2 g(tau)^3)``, so ``g`` is kept smooth: the factors asked for are spread
:data:`SPREAD_S` either side and smoothed by a Gaussian of :data:`SMOOTH_S` (both in reference time),
so that the follower slows down and speeds up again over some tenths of a second instead of
braking at once. Where nothing was asked, ``g = 1`` and the follower is the uniformly slowed one.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

GRID_S = 0.01
"""Spacing [s] of the reference-time grid on which ``g`` is kept."""

SMOOTH_S = 0.12
"""Standard deviation [s] (reference time) of the Gaussian that smooths ``g``."""

SPREAD_S = 0.3
"""How far [s] (reference time) either side of where a factor is asked it is applied before the
smoothing (2.5 standard deviations: the smoothed ``g`` keeps about 99 % of a factor asked at one
time)."""


def reference_grid(duration_s: float) -> np.ndarray:
    """The reference times (G,) [s] over ``[0, duration_s]`` at most :data:`GRID_S` apart, evenly."""
    return np.linspace(0.0, duration_s, max(int(np.ceil(duration_s / GRID_S)), 1) + 1)


class TimeWarp:
    """The slow-down factor ``g(tau) >= 1`` (see the module docstring) over the reference
    times ``[0, duration_s]`` [s], held flat outside.

    Args:
        duration_s: The reference's duration ``D`` [s].
        asked: Factors (G,) asked at the grid's times (1 where none; default: none anywhere).
        catch_up: How many times longer the re-target's catch-up to the reference (its blend) takes.
    """

    def __init__(self, duration_s: float, asked: np.ndarray | None = None, catch_up: float = 1.0) -> None:
        self.catch_up = max(float(catch_up), 1.0)
        self.tau = reference_grid(duration_s)
        n = self.tau.size
        self.asked = np.ones(n) if asked is None else np.maximum(np.asarray(asked, dtype=float), 1.0)
        self.step_s = h = float(self.tau[1] - self.tau[0])  # the grid's spacing [s], at most GRID_S
        spread = maximum_filter1d(self.asked, 2 * int(round(SPREAD_S / h)) + 1, mode="nearest")
        self.g = 1.0 + gaussian_filter1d(spread - 1.0, SMOOTH_S / h, mode="nearest")
        self.dg = np.gradient(self.g, h)
        # C(tau) = integral of g from 0: the followed time is k (C(tau) - C(tau0)) after the follow starts
        steps = 0.5 * (self.g[1:] + self.g[:-1]) * np.diff(self.tau)
        self.cumulative = np.concatenate([[0.0], np.cumsum(steps)])

    @property
    def active(self) -> bool:
        """Whether a factor above 1 was asked anywhere."""
        return bool(np.any(self.asked > 1.0)) or self.catch_up > 1.0

    def asking(self, tau_s: np.ndarray, factors: np.ndarray, catch_up: float = 1.0) -> TimeWarp:
        """This warp with ``factors`` (n,) >= 1 more asked at reference times ``tau_s`` (n,) [s] (on
        top of the slow-down the warp already gives there) and its catch-up ``catch_up`` times
        slower; the asked factors only grow."""
        asked = self.asked.copy()
        i = np.clip(np.rint(np.asarray(tau_s, dtype=float) / self.step_s).astype(int), 0, asked.size - 1)
        want = self.factor(tau_s) * np.asarray(factors, dtype=float)
        np.maximum.at(asked, i, want)
        return TimeWarp(float(self.tau[-1]), asked, self.catch_up * max(float(catch_up), 1.0))

    def over(self, duration_s: float) -> TimeWarp:
        """The factors asked here at the same reference times [s], on a reference of
        ``duration_s`` [s] (none asked beyond this one's end), and the same catch-up."""
        asked = np.interp(reference_grid(duration_s), self.tau, self.asked, right=1.0)
        return TimeWarp(duration_s, asked, self.catch_up)

    def factor(self, tau_s: np.ndarray | float) -> np.ndarray:
        """``g`` at reference times ``tau_s`` [s]."""
        return np.interp(tau_s, self.tau, self.g)

    def rates(self, tau_s: np.ndarray, k: float) -> tuple[np.ndarray, np.ndarray]:
        """``tau'`` [1] and ``tau''`` [1/s] at reference times ``tau_s`` (n,) [s], the reference
        followed ``k`` times slower and warped."""
        g = self.factor(tau_s)
        dg = np.interp(tau_s, self.tau, self.dg)
        return 1.0 / (k * g), -dg / (k * k * g**3)

    def span_s(self, tau_from: float, tau_to: float, k: float) -> float:
        """The time [s] the follower takes from reference time ``tau_from`` to ``tau_to`` [s]."""
        c = np.interp([tau_from, tau_to], self.tau, self.cumulative)
        return float(k * (c[1] - c[0]))

    def reference_times(self, elapsed_s: np.ndarray, tau_from: float, k: float) -> np.ndarray:
        """The reference times (n,) [s] the follower reaches ``elapsed_s`` (n,) [s] after it passed
        ``tau_from`` [s] (held at the grid's end beyond it)."""
        c0 = float(np.interp(tau_from, self.tau, self.cumulative))
        return np.interp(c0 + np.asarray(elapsed_s, dtype=float) / k, self.cumulative, self.tau)
