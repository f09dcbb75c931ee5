"""``uncertainty`` (advisory): hand-over configurations drawn from the prediction checked for joint
limits and contact, and the spread of their hand-over positions.

The configurations are the context's ``handover_samples`` (at most :attr:`Uncertainty.max_samples`)
or, without samples, the mean's last configuration +/- 2 ``handover_std_rad`` per joint; without
either the check is skipped. It judges the prediction, not the motion: it never fails a plan.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..motion.trajectory import Trajectory
from ..robot import Robot
from ..robot.collision import in_collision
from ..robot.kinematics import as_joint_path, ee_positions
from .base import Check
from .context import CheckContext
from .verdict import Measures, Status, Verdict


@dataclass(frozen=True)
class UncertaintyMeasures(Measures):
    """Attributes:
    n_configs: Configurations checked.
    kind: How they were drawn.
    n_outside_limits: Outside the URDF's position limits.
    n_in_collision: In contact (a contact test, no distances).
    position_spread_mm: Largest distance of a hand-over position from the motion's [mm].
    """

    n_configs: int
    kind: str
    n_outside_limits: int
    n_in_collision: int
    position_spread_mm: float


class Uncertainty(Check):
    """The prediction's spread at the hand-over (advisory; see the module docstring).

    Args:
        robot: The loaded robot.
        max_samples: Most sampled configurations checked.
    """

    name = "uncertainty"
    measures_type = UncertaintyMeasures
    required = False
    depends_on = "path"

    def __init__(self, robot: Robot, max_samples: int = 16) -> None:
        super().__init__(robot)
        self.max_samples = max_samples

    def applies(self, context: CheckContext) -> bool:
        """Not on the motion after the hand-over (it does not end at the hand-over)."""
        return not context.after_handover

    def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
        robot = self.robot
        q_end = np.asarray(motion.q[-1], dtype=float)
        if context.handover_samples is not None:
            ends = np.asarray(context.handover_samples, dtype=float).reshape(-1, robot.n_joints)
            ends = ends[: self.max_samples]
            kind = f"{ends.shape[0]} sampled hand-overs"
        elif context.handover_std_rad is not None:
            sd = np.broadcast_to(np.asarray(context.handover_std_rad, dtype=float).reshape(-1), q_end.shape)
            ends = np.vstack([q_end + 2 * np.diag(sd), q_end - 2 * np.diag(sd)])
            kind = "mean +/- 2 sigma per joint"
        else:
            return Verdict(self.name, "skip", "no uncertainty given", required=False)
        ends = as_joint_path(robot, ends, "handover_samples")
        outside = np.any((ends < robot.lower_rad) | (ends > robot.upper_rad), axis=1)
        colliding = in_collision(robot, ends)
        p_mean = ee_positions(robot, q_end)[0]
        spread = float(np.max(np.linalg.norm(ee_positions(robot, ends) - p_mean, axis=1)))
        m = UncertaintyMeasures(
            int(ends.shape[0]), kind, int(outside.sum()), int(colliding.sum()), spread * 1e3
        )
        status: Status = "fail" if outside.any() or colliding.any() else "pass"
        reason = (
            f"{kind}: {m.n_outside_limits} outside joint limits, {m.n_in_collision} in collision, "
            f"hand-over spread {m.position_spread_mm:.0f} mm"
        )
        return Verdict(self.name, status, reason, m, required=False)
