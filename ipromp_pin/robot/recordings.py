"""Recordings read for a robot: its arm joints (by name), their limits and its kinematics.

:func:`read_recordings` is the one way every command reads a dataset of recordings (``run``,
``replay``, ``preview``, ``train``, ``evaluate``): the robot group holds the robot settings'
recorded arm joints in kinematic order, every angle is checked against the robot's limits, and the
robot's forward kinematics locates the gripper where a recording lacks the end-point stream.
:func:`as_gripper_demos` turns recorded joints into the gripper pose path (the ``gripper`` group)
that a human-human recording gives in their place.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path

from ..data import GRIPPER, GRIPPER_CHANNELS, ROBOT, Dataset, Demo
from ..exceptions import DataError
from ..readers import load_dataset, read_recording
from ..signals.gripper import pose_values
from .kinematics import forward_kinematics, gripper_kinematics
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


def as_gripper_demo(demo: Demo, robot: Robot) -> Demo:
    """``demo`` with its robot group (``robot``'s recorded arm joints, in [rad]) replaced by the
    gripper's pose path (the ``gripper`` group: the ``ee`` frame's position [m] and quaternion x, y,
    z, w in ``robot``'s base frame, sign-continuous): the demo as a recording without robot joints
    would give it.

    Raises:
        DataError: the demo has no robot group of ``robot``'s joints.
    """
    if ROBOT not in demo.groups:
        raise DataError(demo.source, ROBOT, "no robot joints to turn into a gripper pose path")
    have = tuple(demo.channel_names[ROBOT])
    if have != tuple(robot.settings.recorded_arm_joints):
        raise DataError(
            demo.source, ROBOT, f"joints {list(have)} are not robot '{robot.settings.name}''s arm joints"
        )
    pose = forward_kinematics(robot, demo.groups[ROBOT])  # (T, 7): x, y, z, qx, qy, qz, qw
    groups = {g: v for g, v in demo.groups.items() if g != ROBOT}
    names = {g: n for g, n in demo.channel_names.items() if g != ROBOT}
    groups[GRIPPER] = pose_values(pose[:, :3], pose[:, 3:])
    names[GRIPPER] = GRIPPER_CHANNELS
    missing = {g: m for g, m in demo.missing.items() if g != ROBOT}
    return replace(demo, groups=groups, channel_names=names, missing=missing)


def as_gripper_demos(dataset: Dataset, robot: Robot) -> Dataset:
    """Every demo of ``dataset`` as a gripper demo (:func:`as_gripper_demo`)."""
    demos = {task: [as_gripper_demo(d, robot) for d in items] for task, items in dataset.demos.items()}
    return replace(dataset, demos=demos)
