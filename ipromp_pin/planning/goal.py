"""Conditioning a prediction on a goal hand-over pose, through the robot's inverse kinematics.

A goal pose (e.g. where a perception system sees the human's hand, or a pose the application
requires) is turned into a goal configuration by :func:`~ipromp_pin.robot.solve_ik`, seeded with
the predicted configuration at the goal's time (so, for a redundant arm, the solution nearest to
the prediction), and the prediction is conditioned on that configuration as a joint via-point
(:meth:`~ipromp_pin.promp.Prediction.condition_joints`): mean and covariance are updated exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import InfeasibleError
from ..promp import Prediction
from ..robot import IKResult, Robot, solve_ik

GOAL_STD_RAD = 1e-4
"""Default standard deviation in [rad] of the goal configuration's joint angles: a goal pose is a target
the motion must reach, so it must outweigh a confident prediction (whose hand-over joint standard
deviations can be a few milliradians); 1e-4 rad moves the end-effector by about 0.1 mm."""


@dataclass(frozen=True)
class GoalConditioning:
    """A prediction conditioned on a goal pose.

    Attributes:
        prediction: The conditioned prediction.
        ik: The inverse-kinematics solution it was conditioned on (``ik.q``: the goal configuration).
        t_s: Time of the goal on the prediction's time axis, in [s].
    """

    prediction: Prediction
    ik: IKResult
    t_s: float


def condition_on_goal_pose(
    prediction: Prediction,
    robot: Robot,
    position_m: np.ndarray,
    quat_xyzw: np.ndarray | None = None,
    *,
    t_s: float | None = None,
    std_rad: float = GOAL_STD_RAD,
) -> GoalConditioning:
    """Condition ``prediction`` on reaching an end-effector pose.

    Args:
        prediction: A prediction (``model.predict(observation)``).
        robot: The robot whose arm the prediction's joints are (same joint order).
        position_m: (3,) goal position of the end-effector frame in [m], base frame.
        quat_xyzw: (4,) goal orientation, quaternion x, y, z, w (None: position only; the
            orientation then follows the prediction).
        t_s: When the pose is to be reached, in [s] on the prediction's time axis (default: the
            predicted hand-over, ``prediction.duration_s``).
        std_rad: Standard deviation of the goal configuration's joint angles in [rad].

    Raises:
        InfeasibleError: the joints differ from the robot's, or the pose is out of reach (the
            message gives the remaining position and orientation errors).
    """
    if tuple(prediction.joint_names) != tuple(robot.joint_names):
        raise InfeasibleError(
            f"goal pose: the prediction's joints {list(prediction.joint_names)} are not the robot's "
            f"{list(robot.joint_names)}"
        )
    t = float(prediction.duration_s if t_s is None else t_s)
    seed = np.array([np.interp(t, prediction.t, prediction.q_mean[:, j]) for j in range(robot.n_joints)])
    ik = solve_ik(robot, position_m, quat_xyzw, q_seed=seed)
    if not ik.converged:
        raise InfeasibleError(
            f"goal pose out of reach: inverse kinematics stopped {ik.position_error_m * 1e3:.1f} mm and "
            f"{np.degrees(ik.rotation_error_rad):.2f} deg away after {ik.iterations} iterations"
        )
    return GoalConditioning(prediction.condition_joints(t, ik.q, std_rad), ik, t)
