"""The joint torques of an evaluated motion: its peak |torque| / effort limit with the TRUE task's object.

:func:`peak_torque_ratio` is the joint-torque check's ``peak_torque_ratio`` of a trajectory (the
closed loop's commanded motion, the one-shot plan), the object of the test demo's recorded task
attached while the robot holds it (:mod:`ipromp_pin.robot.objects`; the motion ends at the
hand-over). :func:`one_shot_peak_torque_ratio` times a prediction as ``run`` does
(:func:`~ipromp_pin.handover.one_shot.time_prediction`: toppra under the torque limits of the
recognised task's object, then ruckig) and scores that plan; the slow-down that ``run`` adds when a
timed-motion check asks for one is not made.
"""

from __future__ import annotations

import numpy as np

from ...checks import CheckContext, TimedMotion
from ...checks.joint_torques import JointTorques
from ...exceptions import InfeasibleError
from ...handover.one_shot import time_prediction, torque_limit
from ...motion.trajectory import Trajectory
from ...promp import Prediction
from ...robot.objects import ObjectTable

__all__ = ["one_shot_peak_torque_ratio", "peak_torque_ratio"]


def peak_torque_ratio(
    check: JointTorques, trajectory: Trajectory, task: str, objects: ObjectTable, start_s: float = 0.0
) -> float:
    """The check's peak |torque| / effort limit of ``trajectory`` (started at ``start_s`` [s] on the
    human's clock) with the object of ``task`` in ``objects`` (NaN when the check skips)."""
    motion = TimedMotion.from_trajectory(trajectory, start_s)
    result = check.check(motion, CheckContext(task=task, objects=objects))
    return float(result.values.get("peak_torque_ratio", np.nan))


def one_shot_peak_torque_ratio(
    check: JointTorques, prediction: Prediction, task: str, objects: ObjectTable, rate_hz: float = 100.0
) -> float:
    """:func:`peak_torque_ratio` of the one-shot plan of ``prediction`` (timed at ``rate_hz`` [Hz]
    under the robot's limits and the torque limits of the recognised task's object) with the object
    of the true ``task``; NaN when the path cannot be timed."""
    torque = torque_limit([check], CheckContext(objects=objects), prediction.task)
    try:
        trajectory, _, _ = time_prediction(prediction, check.robot, rate_hz, torque)
    except InfeasibleError:
        return float("nan")
    return peak_torque_ratio(check, trajectory, task, objects, float(prediction.observed_until_s))
