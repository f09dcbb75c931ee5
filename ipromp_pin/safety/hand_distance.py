"""``hand_distance``: the gripper within the settings' distance of the human hand at the hand-over,
when the hand's position there is known (skipped, and then advisory, when it is not)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..motion.trajectory import Trajectory
from ..robot.kinematics import ee_positions
from .base import Check
from .context import CheckContext
from .verdict import Measures, Verdict


@dataclass(frozen=True)
class HandDistanceMeasures(Measures):
    """Attributes:
    distance_m: Gripper-hand distance at the hand-over [m] (None: skipped).
    max_distance_m: The largest allowed [m].
    hand_position_m: The hand's position (3,) [m] (None: unknown).
    t_s: When the motion reaches the hand-over [s].
    """

    distance_m: float | None
    max_distance_m: float
    hand_position_m: list[float] | None
    t_s: float


class HandDistance(Check):
    """Gripper-hand distance at the hand-over (see the module docstring)."""

    name = "hand_distance"
    measures_type = HandDistanceMeasures
    depends_on = "path"

    def applies(self, context: CheckContext) -> bool:
        """Not on the motion after the hand-over (it does not end at the hand-over)."""
        return not context.after_handover

    def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
        limit = self.robot.settings.max_hand_distance_m
        hand = context.hand_position_m
        if hand is None or not np.all(np.isfinite(hand)):
            m = HandDistanceMeasures(None, limit, None, motion.end_s)
            return Verdict(self.name, "skip", "human hand position unknown", m, required=False)
        h = np.asarray(hand, dtype=float).reshape(3)
        d = float(np.linalg.norm(ee_positions(self.robot, motion.q[-1])[0] - h))
        m = HandDistanceMeasures(d, limit, [float(x) for x in h], motion.end_s)
        if d > limit:
            reason = f"gripper is {d * 1e3:.0f} mm from the hand (max {limit * 1e3:.0f} mm)"
            return Verdict(self.name, "fail", reason, m)
        return Verdict(self.name, "pass", f"gripper-hand distance {d * 1e3:.0f} mm", m)
