"""The joint-torque check: can the arm's motors deliver the torques the timed motion needs?

At the samples of the motion, Pinocchio's inverse dynamics (RNEA,
:class:`~ipromp_pin.robot.dynamics.ArmDynamics`) gives the joint torques of the arm, with the task's
object (:attr:`~.base.CheckContext.payload`) attached to the gripper frame while the robot holds it
(``robot_gives``: up to the hand-over time :attr:`~.base.CheckContext.handover_s`; ``robot_receives``:
from it on). The check passes when every peak |torque| is at most ``1 - effort_margin`` of the URDF's
effort limit (``[limits] effort_margin`` of the robot settings).

When it fails and gravity alone fits, it asks for the slow-down ``k`` that fits the rest: a uniform
slow-down divides the velocity- and acceleration-dependent part ``d = tau - g`` by ``k^2`` (``qd / k``,
``qdd / k^2``), so ``|g| + |d| / k^2 <= allowed`` at every sample and joint gives
``k = sqrt(max |d| / (allowed - |g|))`` (conservative: ``|g + d / k^2| <= |g| + |d| / k^2``).
When gravity alone exceeds the limit (a too-heavy object, an outstretched pose), going slower cannot
help: no slow-down is asked for.

Long motions are subsampled (at most :attr:`JointTorques.max_samples` evenly spaced samples, plus the
samples of each joint's peak |acceleration| and |velocity| and the last one): at 100 Hz and Baxter's
speeds, torques change by far less than the margin between neighbouring samples.
"""

from __future__ import annotations

import math

import numpy as np

from ..robot import CheckResult, Robot
from ..robot.dynamics import ArmDynamics
from ..robot.objects import TaskObject
from .base import CheckContext, MotionCheck, TimedMotion


def payload_text(payload: TaskObject | None, context: CheckContext) -> str:
    """How a report names the payload (or why there is none)."""
    if payload is not None:
        return f"{payload.mass_kg:g} kg {payload.task} object, {payload.holder}"
    if context.objects is not None and context.task is not None:
        return f"no payload: task '{context.task}' has no entry in {context.objects.path}"
    return "no payload"


def handover_time(motion: TimedMotion, context: CheckContext) -> float:
    """When the object changes hands in ``motion``, in [s] on the human's clock: the motions checked
    here end at the hand-over (the one-shot plan, a re-plan's remaining motion), which cannot happen
    before the robot arrives, so the later of ``context.handover_s`` and the motion's last sample.
    A motion after the hand-over (``context.after_handover``, the retreat) starts at it: then
    ``context.handover_s``, else its first sample."""
    if context.after_handover:
        return float(motion.t_s[0]) if context.handover_s is None else float(context.handover_s)
    end = float(motion.t_s[-1])
    return end if context.handover_s is None else max(float(context.handover_s), end)


class JointTorques(MotionCheck):
    """Peak |joint torque| / effort limit along the motion, the payload included (required).

    Args:
        robot: The loaded robot (its URDF's effort limits, its settings' effort margin).
        max_samples: Most samples evaluated per motion (evenly spaced; the peaks of |qdd| and |qd| per
            joint and the last sample are always evaluated).
        springs: Count the springs of the robot settings (``[springs]``; False: the URDF's RNEA alone).
    """

    name = "joint_torques"
    required = True

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

    def sample_indices(self, motion: TimedMotion) -> np.ndarray:
        """The indices of the samples the check evaluates (sorted, unique)."""
        n = motion.n_samples
        if n <= self.max_samples:
            return np.arange(n)
        even = np.linspace(0, n - 1, self.max_samples).round().astype(int)
        keep = np.zeros(n, dtype=bool)  # a mask, not np.unique's sort: the same sorted indices
        keep[even] = True
        keep[np.argmax(np.abs(motion.qdd), axis=0)] = True
        keep[np.argmax(np.abs(motion.qd), axis=0)] = True
        keep[n - 1] = True
        return np.flatnonzero(keep)

    def allowed_nm(self) -> np.ndarray:
        """The torque each joint may use (n_joints,) in [N m]: ``(1 - effort_margin)`` x the limit."""
        return (1.0 - self.robot.settings.effort_margin) * self.dynamics.effort_limit_nm

    def motion_torques(self, motion: TimedMotion, context: CheckContext) -> np.ndarray:
        """Torques (N, n_joints) in [N m] at every sample of ``motion`` (the payload included while held)."""
        payload = context.task_object()
        held = None if payload is None else payload.held_at(motion.t_s, handover_time(motion, context))
        return self.dynamics.torques(motion.q, motion.qd, motion.qdd, payload, held)

    def check(self, motion: TimedMotion, context: CheckContext) -> CheckResult:
        """Peak torque ratios; ``slowdown`` when a slower motion would pass."""
        if motion.n_samples == 0:
            return CheckResult(self.name, "skip", "no samples", {}, self.required)
        dyn = self.dynamics
        idx = self.sample_indices(motion)
        payload = context.task_object()
        t = motion.t_s[idx]
        held = None if payload is None else payload.held_at(t, handover_time(motion, context))
        q, qd, qdd = motion.q[idx], motion.qd[idx], motion.qdd[idx]
        tau = dyn.torques(q, qd, qdd, payload, held)
        limit = dyn.effort_limit_nm
        ratio = np.abs(tau) / limit
        per_joint = ratio.max(axis=0)
        j = int(np.argmax(per_joint))
        i = int(np.argmax(ratio[:, j]))
        allowed = 1.0 - self.robot.settings.effort_margin
        peak = float(per_joint[j])
        what = payload_text(payload, context)
        values: dict = {
            "peak_torque_ratio": peak,
            "joint": self.robot.joint_names[j],
            "t_s": float(t[i]),
            "peak_torque_nm": float(tau[i, j]),
            "allowed_ratio": allowed,
            "ratios": [round(float(r), 4) for r in per_joint],
            "payload": None if payload is None else payload.to_dict(),
            "n_evaluated": int(idx.size),
        }
        text = (
            f"peak |torque| {peak:.0%} of the effort limit ({self.robot.joint_names[j]}, "
            f"{tau[i, j]:+.1f} of {limit[j]:g} N m at t = {t[i]:.2f} s; allowed {allowed:.0%}; {what})"
        )
        if peak <= allowed:
            return CheckResult(self.name, "pass", text, values, self.required)
        g = dyn.torques(q, None, None, payload, held)
        room = allowed * limit - np.abs(g)
        values["gravity_ratio"] = float((np.abs(g) / limit).max())
        if np.all(room > 0):
            values["slowdown"] = math.sqrt(float(np.max(np.abs(tau - g) / room)))
            text += f"; {values['slowdown']:.2f}x slower would fit"
        else:
            text += f"; gravity alone needs {values['gravity_ratio']:.0%}: slowing down cannot help"
        return CheckResult(self.name, "fail", text, values, self.required)
