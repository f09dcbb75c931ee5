"""``workspace``: the hand-over position (the gripper at the motion's last sample) inside the robot
settings' workspace (a box or a sphere)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..motion.trajectory import Trajectory
from ..robot.kinematics import ee_positions
from .base import Check
from .context import CheckContext
from .verdict import Measures, Verdict


@dataclass(frozen=True)
class WorkspaceMeasures(Measures):
    """Attributes:
    position_m: The hand-over position (3,) [m] in the base frame.
    distance_outside_m: Its distance outside the workspace [m] (negative: depth inside).
    t_s: When the motion reaches it [s] (its last sample).
    workspace: The workspace's settings.
    """

    position_m: list[float]
    distance_outside_m: float
    t_s: float
    workspace: dict[str, Any]


class Workspace(Check):
    """The hand-over position inside the workspace. A motion ending where the last one checked ended
    (the slower re-timings of one plan) is judged from a cache: the same configuration, the same
    answer."""

    name = "workspace"
    measures_type = WorkspaceMeasures
    depends_on = "path"

    def applies(self, context: CheckContext) -> bool:
        """Not on the motion after the hand-over (it does not end at the hand-over)."""
        return not context.after_handover

    def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
        end = np.asarray(motion.q[-1], dtype=float)
        key = end.tobytes()
        cached = getattr(self, "cache_", None)
        if cached is None or cached[0] != key:
            p = ee_positions(self.robot, end)[0]
            self.cache_ = (key, p, self.robot.settings.workspace.distance_outside(p))
        _, p, d = self.cache_
        ws = self.robot.settings.workspace
        m = WorkspaceMeasures([float(x) for x in p], float(d), motion.end_s, ws.to_dict())
        pos = f"({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m"
        if d > 0:
            return Verdict(self.name, "fail", f"hand-over position {pos} is {d * 1e3:.0f} mm outside", m)
        return Verdict(self.name, "pass", f"hand-over position {pos} inside ({-d * 1e3:.0f} mm deep)", m)
