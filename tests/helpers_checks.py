"""Toy checks that ask for a slower motion (for the tests of the re-time-until-safe loop and of the
planners that use it)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ipromp_pin.motion.trajectory import Trajectory
from ipromp_pin.safety import Check, CheckContext, Measures, Verdict


@dataclass(frozen=True)
class PeakMeasures(Measures):
    peak_rad_s: float


class SpeedBound(Check):
    """A toy check: every joint speed at most ``bound`` [rad/s]; asks for the slow-down that gives it."""

    name = "speed_bound"

    def __init__(self, robot, bound: float = np.inf, fixable: bool = True, power: float = 1.0) -> None:
        super().__init__(robot)
        self.bound = bound
        self.fixable = fixable
        self.power = power  # < 1: asks for less slow-down than it needs (a first-order estimate)
        self.seen: list[Trajectory] = []
        self.contexts: list[CheckContext] = []

    def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
        self.seen.append(motion)
        self.contexts.append(context)
        peak = float(np.max(np.abs(motion.qd)))
        m = PeakMeasures(peak)
        fits = (peak / self.bound) ** self.power if self.fixable else None
        if peak <= self.bound:
            return Verdict(self.name, "pass", f"peak {peak:.3f} rad/s", m, fits_at=fits)
        return Verdict(
            self.name, "fail", f"peak {peak:.3f} rad/s > {self.bound}", m, slowdown=fits, fits_at=fits
        )


class RegionSpeedBound(SpeedBound):
    """A toy check: joint speeds at most ``bound`` [rad/s] where the motion is between 35 % and 65 % of
    the way from ``q0`` to ``q1`` (a region of the path, like an approach near the human); asks for the
    slow-down each sample needs there (``local``), or only the uniform one; ``stingy`` < 1 asks
    locally for that power of what it needs."""

    name = "region_speed"

    def __init__(self, robot, bound, q0, q1, local: bool = True, stingy: float = 1.0) -> None:
        super().__init__(robot, bound)
        self.q0, self.q1, self.local, self.stingy = np.asarray(q0), np.asarray(q1), local, stingy

    def region(self, motion: Trajectory) -> np.ndarray:
        way = np.linalg.norm(motion.q - self.q0, axis=1) / np.linalg.norm(self.q1 - self.q0)
        return (way > 0.35) & (way < 0.65)

    def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
        self.seen.append(motion)
        speed = np.where(self.region(motion), np.max(np.abs(motion.qd), axis=1), 0.0)
        peak = float(speed.max())
        if peak <= self.bound:
            return Verdict(self.name, "pass", f"peak {peak:.3f} rad/s", PeakMeasures(peak))
        local = np.maximum(speed / self.bound, 1.0) ** self.stingy if self.local else None
        k = peak / self.bound
        return Verdict(self.name, "fail", "too fast", PeakMeasures(peak), slowdown=k, local_slowdown=local)
