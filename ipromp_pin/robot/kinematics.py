"""Forward kinematics of the arm along a joint path (placements, poses, end-effector positions)."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import NamedTuple

import numpy as np
import pinocchio as pin

from ..exceptions import InfeasibleError
from .model import Robot


def as_joint_path(robot: Robot, q: np.ndarray, name: str = "q") -> np.ndarray:
    """Validated joint path (M, n_joints) in [rad] from ``q`` (M, n_joints) or (n_joints,).

    Raises:
        InfeasibleError: wrong shape, no sample, or NaN/inf angles (``name`` is used in the message).
    """
    q = np.asarray(q, dtype=float)
    if q.ndim == 1:
        q = q[None, :]
    if q.ndim != 2 or q.shape[1] != robot.n_joints or q.shape[0] == 0:
        raise InfeasibleError(f"{name}: expected shape (M, {robot.n_joints}), got {q.shape}")
    if not np.all(np.isfinite(q)):
        row = int(np.nonzero(~np.all(np.isfinite(q), axis=1))[0][0])
        raise InfeasibleError(f"{name}: NaN or inf joint angles (first at sample {row})")
    return q


def frame_placements(
    robot: Robot, q: np.ndarray, frame_id: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Placements of a frame along a joint path.

    Args:
        robot: Loaded robot.
        q: Arm joint angles (M, n_joints) or (n_joints,) in [rad].
        frame_id: Model frame id (default: the end-effector frame ``ee``).

    Returns:
        Positions (M, 3) in [m] and rotation matrices (M, 3, 3), in the base frame.
    """
    q = as_joint_path(robot, q)
    fid = robot.ee_frame_id if frame_id is None else int(frame_id)
    model, data = robot.model, robot.data
    full = robot.full_configuration(q)
    pos = np.empty((q.shape[0], 3))
    rot = np.empty((q.shape[0], 3, 3))
    for i in range(q.shape[0]):
        pin.forwardKinematics(model, data, full[i])
        m = pin.updateFramePlacement(model, data, fid)
        pos[i] = m.translation
        rot[i] = m.rotation
    return pos, rot


def rotations_to_quat_xyzw(rot: np.ndarray) -> np.ndarray:
    """Unit quaternions (n, 4) as x, y, z, w with w >= 0, from rotation matrices (n, 3, 3)."""
    out = np.empty((rot.shape[0], 4))
    for i in range(rot.shape[0]):
        out[i] = pin.Quaternion(rot[i]).coeffs()  # x, y, z, w
    out[out[:, 3] < 0] *= -1.0
    return out


def forward_kinematics(robot: Robot, q: np.ndarray, frame_id: int | None = None) -> np.ndarray:
    """End-effector poses along a joint path, in the format of ``Demo.extras["endpoint_pose"]``.

    Args:
        robot: Loaded robot.
        q: Arm joint angles (M, n_joints) or (n_joints,) in [rad].
        frame_id: Model frame id (default: the calibrated end-effector frame).

    Returns:
        (M, 7): position x, y, z in [m] and quaternion x, y, z, w (w >= 0), in the base frame.
    """
    pos, rot = frame_placements(robot, q, frame_id)
    return np.hstack([pos, rotations_to_quat_xyzw(rot)])


def ee_positions(robot: Robot, q: np.ndarray) -> np.ndarray:
    """End-effector positions (M, 3) in [m] along a joint path (M, n_joints) in [rad]."""
    return frame_placements(robot, q)[0]


def gripper_rotations(robot: Robot, q: np.ndarray) -> np.ndarray:
    """End-effector rotation matrices (M, 3, 3) in the base frame along a joint path (M, n_joints) in
    [rad]."""
    return frame_placements(robot, q)[1]


class GripperKinematics(NamedTuple):
    """The gripper's forward kinematics of one robot, in the form :meth:`IProMP.fit
    <ipromp_pin.promp.IProMP.fit>` and the scores take them
    (``fit(demos, **gripper_kinematics(robot)._asdict())``).

    Attributes:
        fk: Joint configurations (n, n_joints) [rad] -> gripper positions (n, 3) [m].
        fk_rot: Joint configurations (n, n_joints) [rad] -> gripper rotation matrices (n, 3, 3).
    """

    fk: Callable[[np.ndarray], np.ndarray]
    fk_rot: Callable[[np.ndarray], np.ndarray]


def gripper_kinematics(robot: Robot) -> GripperKinematics:
    """The gripper's forward kinematics of ``robot`` (picklable: the evaluation's workers get them)."""
    return GripperKinematics(partial(ee_positions, robot), partial(gripper_rotations, robot))
