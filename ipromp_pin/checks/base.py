"""The base of the timed-motion checks: the motion, the context, the check.

A check is built once per robot (:meth:`MotionCheck.__init__` stores the robot; anything expensive,
e.g. collision geometry, is prepared lazily and kept on the instance), then called for every motion:
the one-shot plan of ``run`` and every re-plan's remaining motion in the closed loop.

A failing check may say how to make the motion pass by going slower: ``values["slowdown"]`` is then
the uniform slow-down factor ``k >= 1`` (velocities / k, accelerations / k^2) at which the check
expects to pass (:mod:`.slowdown`). Without it, slowing down is not expected to help.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..human import HumanMotion
from ..motion.retarget import MotionPlan
from ..motion.trajectory import Trajectory
from ..robot import CheckResult, Robot
from ..robot.objects import ObjectTable, TaskObject


@dataclass(frozen=True)
class TimedMotion:
    """A joint motion sampled at a fixed control period, on the human's clock.

    Attributes:
        t_s: Sample times (N,) in [s] on the human's clock (0 at the start of the human's motion, the
            time base of the recordings and of the closed loop), uniformly spaced by ``dt_s``.
        q: Positions (N, n_joints) in [rad].
        qd: Velocities (N, n_joints) in [rad/s].
        qdd: Accelerations (N, n_joints) in [rad/s^2].
        dt_s: Control period in [s].
    """

    t_s: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    dt_s: float

    @classmethod
    def from_trajectory(cls, trajectory: Trajectory, t0_s: float = 0.0) -> TimedMotion:
        """A :class:`~ipromp_pin.motion.trajectory.Trajectory` (times from 0) started at ``t0_s`` [s]
        on the human's clock (``run``: the end of the observation, when the robot starts)."""
        t = np.asarray(trajectory.t_s, dtype=float)
        dt = float(t[1] - t[0]) if t.size > 1 else 0.0
        return cls(t0_s + t, trajectory.q, trajectory.qd, trajectory.qdd, dt)

    @classmethod
    def from_plan(cls, plan: MotionPlan) -> TimedMotion:
        """The remaining motion of a closed-loop re-plan (already on the human's clock)."""
        return cls(plan.t_s, plan.q, plan.qd, plan.qdd, plan.dt_s)

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return int(self.t_s.size)


@dataclass
class CheckContext:
    """What the checks know about the world besides the robot.

    The caller (``run``, the closed loop, ``evaluate``) fills in what it has; a check whose input is
    missing decides itself what to do (skip, or an assumed default that its result states).

    Attributes:
        handover_s: Predicted time of the hand-over in [s] on the human's clock, if known.
        task: The recognised task, if known.
        objects: The objects of the tasks (:mod:`ipromp_pin.robot.objects`); the payload of a motion is
            the object of :attr:`task` (its ``holder`` says whether before or after the hand-over).
        payload: The object in the gripper, when given explicitly (it overrides ``objects``).
        human: The human's body over time (tracked, or the assumed human), as the planner knows it
            (:meth:`~ipromp_pin.human.HumanMotion.until`), or as recorded when judging afterwards.
        after_handover: The motion starts at the hand-over (the retreat,
            :mod:`ipromp_pin.handover.retreat`): the object changes hands at :attr:`handover_s`, its
            first sample, not at its end (False: the motion ends at the hand-over, the approach).
    """

    handover_s: float | None = None
    task: str | None = None
    human: HumanMotion | None = None
    objects: ObjectTable | None = None
    payload: TaskObject | None = None
    after_handover: bool = False

    def task_object(self) -> TaskObject | None:
        """The object of this motion: :attr:`payload`, else the entry of :attr:`task` in :attr:`objects`
        (``None``: no payload)."""
        if self.payload is not None:
            return self.payload
        return None if self.objects is None else self.objects.for_task(self.task)


class MotionCheck(ABC):
    """One check of a timed motion.

    Class attributes:
        name: The check's name in reports (``report.json``'s ``checks`` key).
        required: Whether a failure fails the plan (exit 3), or the check is advisory.

    Args:
        robot: The loaded robot (stored; nothing else happens in ``__init__``).
    """

    name: ClassVar[str]
    required: ClassVar[bool] = True

    def __init__(self, robot: Robot) -> None:
        self.robot = robot

    @abstractmethod
    def check(self, motion: TimedMotion, context: CheckContext) -> CheckResult:
        """Judge ``motion`` -> a :class:`~ipromp_pin.robot.CheckResult` named :attr:`name` (its
        ``values`` hold the deciding numbers, and ``slowdown`` when going slower would help)."""
