"""``joint_limits``: every sample inside the URDF position limits shrunk by the settings' margin."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..motion.trajectory import Trajectory
from ..robot.kinematics import as_joint_path
from .base import Check
from .context import CheckContext
from .verdict import Measures, Verdict


@dataclass(frozen=True)
class JointLimitMeasures(Measures):
    """Attributes:
    min_slack_rad: Smallest distance to a margin-shrunk limit [rad] (negative: violated).
    joint: The joint of it.
    side: ``"lower"`` or ``"upper"``.
    sample: Its sample index in the motion.
    t_s: Its time [s].
    n_violations: Samples x joints beyond a limit.
    margin_rad: The margins [rad] per joint.
    """

    min_slack_rad: float
    joint: str
    side: str
    sample: int
    t_s: float
    n_violations: int
    margin_rad: list[float]


class JointLimits(Check):
    """Positions within the URDF limits less the settings' margin, at every sample."""

    name = "joint_limits"
    measures_type = JointLimitMeasures
    depends_on = "path"

    def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
        robot = self.robot
        q = as_joint_path(robot, motion.q)
        margin = np.broadcast_to(robot.settings.position_margin_rad, (q.shape[1],))
        lo = robot.lower_rad + margin
        hi = robot.upper_rad - margin
        slack = np.minimum(q - lo, hi - q)
        i, j = np.unravel_index(int(np.argmin(slack)), slack.shape)
        s = float(slack[i, j])
        name = robot.joint_names[j]
        side = "lower" if q[i, j] - lo[j] <= hi[j] - q[i, j] else "upper"
        m = JointLimitMeasures(
            min_slack_rad=s,
            joint=name,
            side=side,
            sample=int(i),
            t_s=float(motion.t_s[i]),
            n_violations=int(np.count_nonzero(slack < 0)),
            margin_rad=[float(x) for x in margin],
        )
        at = f"t={m.t_s:.2f} s"
        if s < 0:
            reason = (
                f"{name} = {q[i, j]:.4f} rad at {at} is {-s:.4f} rad beyond its {side} limit "
                f"(with margin: [{lo[j]:.4f}, {hi[j]:.4f}]); {m.n_violations} violations"
            )
            return Verdict(self.name, "fail", reason, m)
        return Verdict(self.name, "pass", f"smallest slack {s:.4f} rad ({name}, {side} limit, {at})", m)
