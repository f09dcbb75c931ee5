"""``speed_limits``: velocity, acceleration and jerk within the joint limits at every sample.

The limits are the context's (the closed loop's limit profile) or the robot's own. The jerk is the
difference of consecutive accelerations over the control period, what a controller replaying the
samples sees. A timing produces motions within its limits by construction, so a violation is a
numerical failure of the timing: it asks for no slow-down (the motion is refused).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..motion.trajectory import JointLimits, Trajectory
from .base import Check
from .context import CheckContext
from .verdict import Measures, Verdict

TOLERANCE = 1e-6
"""Relative tolerance of the ratios (the timings reach their limits exactly)."""

QUANTITIES = ("velocity", "acceleration", "jerk")


@dataclass(frozen=True)
class SpeedLimitMeasures(Measures):
    """Attributes:
    limit_ratios: Largest |velocity|, |acceleration| and |jerk| over their limits (3,).
    quantity: The quantity of the largest ratio.
    joint: Its joint.
    t_s: Its time [s].
    tolerance: The relative tolerance allowed over 1.
    """

    limit_ratios: list[float]
    quantity: str
    joint: str
    t_s: float
    tolerance: float


def limit_ratios(motion: Trajectory, limits: JointLimits) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per quantity (velocity, acceleration, jerk) the largest ratio to its limit (3,), and the sample
    (3,) and joint (3,) where it is."""
    dt = motion.dt_s
    jerk = np.diff(motion.qdd, axis=0) / dt if motion.n_samples > 1 else np.zeros((0, motion.q.shape[1]))
    ratios, samples, joints = np.zeros(3), np.zeros(3, dtype=int), np.zeros(3, dtype=int)
    for k, (x, lim) in enumerate(
        (
            (motion.qd, limits.velocity_rad_s),
            (motion.qdd, limits.acceleration_rad_s2),
            (jerk, limits.jerk_rad_s3),
        )
    ):
        if x.size:
            r = np.abs(x) / lim
            i, j = np.unravel_index(int(np.argmax(r)), r.shape)
            ratios[k], samples[k], joints[k] = r[i, j], i + (k == 2), j
    return ratios, samples, joints


class SpeedLimits(Check):
    """|qd|, |qdd|, |jerk| within the context's (or the robot's) limits at every sample."""

    name = "speed_limits"
    measures_type = SpeedLimitMeasures
    depends_on = "timing"

    def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
        limits = context.limits if context.limits is not None else JointLimits.from_robot(self.robot)
        ratios, samples, joints = limit_ratios(motion, limits)
        k = int(np.argmax(ratios))
        m = SpeedLimitMeasures(
            limit_ratios=[float(x) for x in ratios],
            quantity=QUANTITIES[k],
            joint=limits.joint_names[int(joints[k])],
            t_s=float(motion.t_s[min(int(samples[k]), motion.n_samples - 1)]),
            tolerance=TOLERANCE,
        )
        if ratios[k] > 1.0 + TOLERANCE:
            reason = (
                f"{m.quantity} limit exceeded ({ratios[k]:.3f} of the limit; {m.joint} at t={m.t_s:.2f} s)"
            )
            return Verdict(self.name, "fail", reason, m)
        reason = "at most " + ", ".join(f"{q} {r:.3f}" for q, r in zip(QUANTITIES, ratios, strict=True))
        return Verdict(self.name, "pass", reason + " of the limits", m)
