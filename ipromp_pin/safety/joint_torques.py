"""``joint_torques``: can the arm's motors deliver the torques the timed motion needs?

At the samples of the motion, Pinocchio's inverse dynamics (RNEA,
:class:`~ipromp_pin.robot.dynamics.ArmDynamics`) gives the arm's joint torques, with the task's
object attached to the gripper frame while the robot holds it (``robot_gives``: up to the hand-over,
:meth:`~.context.CheckContext.handover_time`; ``robot_receives``: from it on). The check passes when
every peak |torque| is at most ``1 - effort_margin`` of the URDF's effort limit (``[limits]
effort_margin`` of the robot settings).

When it fails and gravity alone fits, it asks for the slow-down ``k`` that fits the rest: a uniform
slow-down divides the velocity- and acceleration-dependent part ``d = tau - g`` by ``k^2``, so
``|g| + |d| / k^2 <= allowed`` at every sample and joint gives ``k = sqrt(max |d| / (allowed - |g|))``
(conservative: ``|g + d / k^2| <= |g| + |d| / k^2``). When gravity alone exceeds the limit, going
slower cannot help: no slow-down is asked for.

The check also constrains the timing (toppra's joint-torque constraint with the object the robot
carries during the motion, :meth:`JointTorques.timing_constraints`) and puts the committed motion's
torques into its ``effort_nm`` (:meth:`JointTorques.annotate`, written as the messages' ``effort``).
Long motions are subsampled (at most :attr:`JointTorques.max_samples` evenly spaced samples, plus
each joint's peak |acceleration| and |velocity| and the last one).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..motion.toppra_profile import TorqueLimit
from ..motion.trajectory import Trajectory
from ..robot import Robot
from ..robot.dynamics import ArmDynamics
from ..robot.objects import TaskObject
from .base import Check, TimingConstraints
from .context import CheckContext
from .verdict import Measures, Verdict


def payload_text(payload: TaskObject | None, context: CheckContext) -> str:
    """How a report names the payload (or why there is none)."""
    if payload is not None:
        return f"{payload.mass_kg:g} kg {payload.task} object, {payload.holder}"
    if context.objects is not None and context.task is not None:
        return f"no payload: task '{context.task}' has no entry in {context.objects.path}"
    return "no payload"


@dataclass(frozen=True)
class TorqueMeasures(Measures):
    """Attributes:
    peak_torque_ratio: The largest |torque| / effort limit.
    joint: The joint of it.
    t_s: When [s].
    peak_torque_nm: The torque there [N m].
    allowed_ratio: ``1 - effort_margin``.
    ratios: Per joint the largest |torque| / effort limit.
    payload: The object's settings (None: no payload).
    n_evaluated: Samples evaluated.
    gravity_ratio: The largest |gravity torque| / effort limit (failures only).
    """

    peak_torque_ratio: float
    joint: str
    t_s: float
    peak_torque_nm: float
    allowed_ratio: float
    ratios: list[float]
    payload: dict[str, Any] | None
    n_evaluated: int
    gravity_ratio: float | None = None


class JointTorques(Check):
    """Peak |joint torque| / effort limit along the motion, the payload included.

    Args:
        robot: The loaded robot (its URDF's effort limits, its settings' effort margin).
        max_samples: Most samples evaluated per motion.
        springs: Count the springs of the robot settings (``[springs]``; False: the URDF's RNEA alone).
    """

    name = "joint_torques"
    measures_type = TorqueMeasures
    depends_on = "timing"

    def __init__(self, robot: Robot, max_samples: int = 100, springs: bool = True) -> None:
        super().__init__(robot)
        self.max_samples = max_samples
        self.springs = springs

    @property
    def dynamics(self) -> ArmDynamics:
        """The arm's inverse dynamics (built on first use, then kept)."""
        if getattr(self, "dynamics_", None) is None:
            self.dynamics_ = ArmDynamics(self.robot, springs=self.springs)
        return self.dynamics_

    def sample_indices(self, motion: Trajectory) -> np.ndarray:
        """The indices of the samples the check evaluates (sorted, unique)."""
        n = motion.n_samples
        if n <= self.max_samples:
            return np.arange(n)
        even = np.linspace(0, n - 1, self.max_samples).round().astype(int)
        keep = np.zeros(n, dtype=bool)
        keep[even] = True
        keep[np.argmax(np.abs(motion.qdd), axis=0)] = True
        keep[np.argmax(np.abs(motion.qd), axis=0)] = True
        keep[n - 1] = True
        return np.flatnonzero(keep)

    def allowed_nm(self) -> np.ndarray:
        """The torque each joint may use (n_joints,) in [N m]: ``(1 - effort_margin)`` x the limit."""
        return (1.0 - self.robot.settings.effort_margin) * self.dynamics.effort_limit_nm

    def torques(self, motion: Trajectory, context: CheckContext) -> np.ndarray:
        """Torques (N, n_joints) in [N m] at every sample of ``motion`` (the payload included while held)."""
        payload = context.task_object()
        held = None if payload is None else payload.held_at(motion.t_s, context.handover_time(motion.t_s))
        return self.dynamics.torques(motion.q, motion.qd, motion.qdd, payload, held)

    def timing_constraints(self, context: CheckContext) -> TimingConstraints:
        """toppra's joint-torque constraint with the object the robot carries during the motion."""
        carried = context.carried_object()
        return TimingConstraints(TorqueLimit(self.dynamics.inverse_dynamics(carried), self.allowed_nm()))

    def annotate(self, motion: Trajectory, context: CheckContext) -> Trajectory:
        """``motion`` with its torques at every sample (``effort_nm``)."""
        return dataclasses.replace(motion, effort_nm=self.torques(motion, context))

    def evaluated(self, motion: Trajectory, context: CheckContext) -> tuple[np.ndarray, np.ndarray]:
        """The samples the check evaluates (K,) (:meth:`sample_indices`) and the torques there
        (K, n_joints) in [N m], the payload included while held: what :meth:`check` judges (the
        previews show these)."""
        idx = self.sample_indices(motion)
        payload = context.task_object()
        held = (
            None if payload is None else payload.held_at(motion.t_s[idx], context.handover_time(motion.t_s))
        )
        return idx, self.dynamics.torques(motion.q[idx], motion.qd[idx], motion.qdd[idx], payload, held)

    def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
        """Peak torque ratios; a slow-down when a slower motion would pass."""
        if motion.n_samples == 0:
            return Verdict(self.name, "skip", "no samples")
        dyn = self.dynamics
        idx, tau = self.evaluated(motion, context)
        payload = context.task_object()
        t = motion.t_s[idx]
        limit = dyn.effort_limit_nm
        ratio = np.abs(tau) / limit
        per_joint = ratio.max(axis=0)
        j = int(np.argmax(per_joint))
        i = int(np.argmax(ratio[:, j]))
        allowed = 1.0 - self.robot.settings.effort_margin
        peak = float(per_joint[j])
        m = TorqueMeasures(
            peak_torque_ratio=peak,
            joint=self.robot.joint_names[j],
            t_s=float(t[i]),
            peak_torque_nm=float(tau[i, j]),
            allowed_ratio=allowed,
            ratios=[round(float(r), 4) for r in per_joint],
            payload=None if payload is None else payload.to_dict(),
            n_evaluated=int(idx.size),
        )
        text = (
            f"peak |torque| {peak:.0%} of the effort limit ({m.joint}, {tau[i, j]:+.1f} of {limit[j]:g} N m "
            f"at t={t[i]:.2f} s; allowed {allowed:.0%}; {payload_text(payload, context)})"
        )
        if peak <= allowed:
            return Verdict(self.name, "pass", text, m)
        held = None if payload is None else payload.held_at(t, context.handover_time(motion.t_s))
        g = dyn.torques(motion.q[idx], None, None, payload, held)
        room = allowed * limit - np.abs(g)
        m = dataclasses.replace(m, gravity_ratio=float((np.abs(g) / limit).max()))
        if np.all(room > 0):
            k = math.sqrt(float(np.max(np.abs(tau - g) / room)))
            return Verdict(self.name, "fail", text + f"; {k:.2f}x slower would fit", m, slowdown=k)
        text += f"; gravity alone needs {m.gravity_ratio:.0%}: slowing down cannot help"
        return Verdict(self.name, "fail", text, m)
