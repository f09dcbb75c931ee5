"""What the checks know about the world besides the motion: :class:`CheckContext`.

A planner fills in what it knows when it plans (never more): the recognised task and the predicted
hand-over time, the human as observed so far, the objects of the tasks, the limits the motion must
keep, the prediction's sampled hand-over configurations. A check whose input is missing decides
itself what to do (skip it, or use a stated default such as the assumed human).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..human import HumanMotion
from ..motion.trajectory import JointLimits
from ..robot.objects import ObjectTable, TaskObject


@dataclass(frozen=True)
class CheckContext:
    """What the checks know about the world (see the module docstring).

    Attributes:
        task: The recognised task, if known.
        handover_s: The predicted hand-over time in [s] on the human's clock (the end of the human's
            predicted motion), if known; a motion toward the hand-over cannot hand over before it
            ends, so the later of the two counts (:meth:`handover_time`).
        human: The human's body over time (tracked, or the assumed human) as the planner knows it
            (:meth:`~ipromp_pin.human.HumanMotion.until`), or as recorded when judging afterwards.
        objects: The objects of the tasks; the payload of a motion is the object of :attr:`task`.
        payload: The object in the gripper, when given explicitly (it overrides ``objects``).
        after_handover: The motion starts at the hand-over (the retreat): the object changes hands
            at :attr:`handover_s`, its first sample, not at its end.
        limits: The joint limits the motion must keep (positions with margin, velocities,
            accelerations, jerks); None: the robot's own (:meth:`JointLimits.from_robot`).
        handover_samples: Hand-over configurations (n, n_joints) [rad] drawn from the prediction, for
            the advisory uncertainty check; or ``handover_std_rad``: their standard deviation
            (n_joints,) [rad].
        handover_std_rad: See ``handover_samples``.
    """

    task: str | None = None
    handover_s: float | None = None
    human: HumanMotion | None = None
    objects: ObjectTable | None = None
    payload: TaskObject | None = None
    after_handover: bool = False
    limits: JointLimits | None = None
    handover_samples: np.ndarray | None = None
    handover_std_rad: np.ndarray | None = None

    def replace(self, **changes: object) -> CheckContext:
        """A copy with ``changes``."""
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]

    def task_object(self) -> TaskObject | None:
        """The object of this motion: :attr:`payload`, else the entry of :attr:`task` in :attr:`objects`
        (None: no payload)."""
        if self.payload is not None:
            return self.payload
        return None if self.objects is None else self.objects.for_task(self.task)

    def carried_object(self) -> TaskObject | None:
        """The object the robot carries during this motion: before the hand-over the object it
        gives (``robot_gives``), after it the object it received (``robot_receives``); a received
        object joins only at the end of the approach, at rest, where the checks verify it."""
        obj = self.task_object()
        if obj is None:
            return None
        wanted = "robot_receives" if self.after_handover else "robot_gives"
        return obj if obj.holder == wanted else None

    def handover_time(self, t_s: np.ndarray) -> float:
        """When the object changes hands in a motion sampled at ``t_s`` (N,) [s] on the human's clock:
        a motion after the hand-over starts at it (:attr:`handover_s`, else its first sample); a motion
        toward it ends at it, which cannot be before the robot arrives: the later of :attr:`handover_s`
        and the last sample."""
        if self.after_handover:
            return float(t_s[0]) if self.handover_s is None else float(self.handover_s)
        end = float(t_s[-1])
        return end if self.handover_s is None else max(float(self.handover_s), end)
