"""Recordings read for a robot: its arm joints (by name), their limits and its kinematics.

:func:`read_recordings` is the one way every command reads a dataset of recordings (``run``,
``replay``, ``preview``, ``train``, ``evaluate``): the robot group holds the robot settings'
recorded arm joints in kinematic order, every angle is checked against the robot's limits, and the
robot's forward kinematics locates the gripper where a recording lacks the end-point stream.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from ..data import Dataset, Demo
from ..readers import load_dataset, read_recording
from .kinematics import gripper_kinematics
from .model import Robot


def read_recordings(
    path: str | Path,
    robot: Robot,
    *,
    format: str = "auto",
    frames: Sequence[str] | None = None,
    rate_hz: float = 50.0,
    progress: Callable[[int, int, str], None] | None = None,
) -> Dataset:
    """The dataset at ``path`` (one sub-folder per task) read with ``robot``'s joints, limits and
    kinematics (see the module docstring; the other arguments are
    :func:`~ipromp_pin.readers.load_dataset`'s)."""
    return load_dataset(
        path,
        format=format,
        frames=frames or None,
        rate_hz=rate_hz,
        robot_joints=robot.settings.recorded_arm_joints,
        joint_limits=robot.recorded_joint_limits(),
        end_effector=gripper_kinematics(robot).fk,
        progress=progress,
    )


def read_recording_for(
    path: str | Path,
    robot: Robot,
    *,
    frames: Sequence[str] | None = None,
    rate_hz: float = 50.0,
) -> Demo:
    """The one recording at ``path`` (any supported format, no task label) read with ``robot``'s
    joints, limits and kinematics (:func:`~ipromp_pin.readers.read_recording`)."""
    return read_recording(
        path,
        frames=frames or None,
        rate_hz=rate_hz,
        robot_joints=robot.settings.recorded_arm_joints,
        joint_limits=robot.recorded_joint_limits(),
        end_effector=gripper_kinematics(robot).fk,
    )
