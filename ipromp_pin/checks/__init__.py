"""Checks of a timed motion: what the robot's arm does over time, beside the world it moves in.

The checks of :mod:`ipromp_pin.robot.checks` judge a joint *path* (positions only: limits,
self-collision, the hand-over pose). The checks here judge a *timed* motion (positions, velocities and
accelerations at the control rate, :class:`~.base.TimedMotion`) together with what the caller knows
about the world (:class:`~.base.CheckContext`: the human, the object in the gripper, ...), the inputs
of separation, contact-speed and torque limits.

- :mod:`.base`: :class:`~.base.TimedMotion`, :class:`~.base.CheckContext` and the
  :class:`~.base.MotionCheck` base class;
- :mod:`.registry`: the registered checks (one file each in this package, one line in the registry)
  and :func:`~.registry.run_checks`;
- :mod:`.slowdown`: how much slower a motion must go for its failing checks to pass;
- :mod:`.separation_base`: the base of the checks judged on the robot-body separation (they share
  one analyser when built together).

A new check is one file here (a :class:`~.base.MotionCheck` subclass) plus one line in
:data:`~.registry.MOTION_CHECKS`; ``run``, ``replay``, ``evaluate`` and the reports pick it up.
"""

from .base import CheckContext, MotionCheck, TimedMotion
from .registry import MOTION_CHECKS, build_checks, run_checks
from .slowdown import MAX_SLOWDOWN, MAX_SLOWDOWN_ROUNDS, needed_slowdown

__all__ = [
    "MAX_SLOWDOWN",
    "MAX_SLOWDOWN_ROUNDS",
    "MOTION_CHECKS",
    "CheckContext",
    "MotionCheck",
    "TimedMotion",
    "build_checks",
    "needed_slowdown",
    "run_checks",
]
