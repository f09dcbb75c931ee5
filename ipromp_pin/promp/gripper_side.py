"""Models whose robot side is a gripper pose path (``robot_group="gripper"``,
:mod:`ipromp_pin.signals.gripper`).

Before the weights are fitted, every training demo's gripper group is checked, put in the canonical
channel order and made sign-consistent: its quaternion continuous along the demo and in the
hemisphere of one reference quaternion shared by every task (the chordal mean of the training demos'
quaternions; for a task added later, the model's mean hand-over orientation), so that the Gaussian
over the weights averages rotations, not q against -q. The model's forward kinematics are then its
own position channels (the hand-over position the cross-validations score) and the renormalised
quaternion (the hand-over orientation).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np

from ..data import GRIPPER, GRIPPER_CHANNELS, Demo
from ..signals.gripper import (
    QUATERNION,
    aligned_gripper,
    gripper_positions,
    gripper_rotations,
    gripper_values,
    quaternion_reference,
)
from .fitted import FittedModel

Kinematics = Callable[[np.ndarray], np.ndarray]


def is_gripper_group(robot_group: str) -> bool:
    """Whether a model's robot group is a gripper pose path."""
    return robot_group == GRIPPER


def with_gripper(demo: Demo, reference: np.ndarray) -> Demo:
    """``demo`` with its gripper group checked, canonical and in the hemisphere of ``reference`` (4,)."""
    values = gripper_values(demo.source, GRIPPER, demo.groups[GRIPPER], demo.channel_names[GRIPPER])
    return Demo(
        task=demo.task,
        name=demo.name,
        source=demo.source,
        t=demo.t,
        groups={**demo.groups, GRIPPER: aligned_gripper(values, reference)},
        channel_names={**demo.channel_names, GRIPPER: GRIPPER_CHANNELS},
        missing=dict(demo.missing),
        extras=dict(demo.extras),
        duration_s=demo.duration_s,
    )


def aligned_demos(by_task: Mapping[str, list[Demo]]) -> dict[str, list[Demo]]:
    """Every demo's gripper group sign-consistent with the chordal mean of all their quaternions."""
    for demos in by_task.values():
        for d in demos:
            d.require([GRIPPER])
    quats = [
        gripper_values(d.source, GRIPPER, d.groups[GRIPPER], d.channel_names[GRIPPER])[:, QUATERNION]
        for demos in by_task.values()
        for d in demos
    ]
    reference = quaternion_reference(quats)
    return {task: [with_gripper(d, reference) for d in demos] for task, demos in by_task.items()}


def model_reference(fitted: FittedModel) -> np.ndarray:
    """The model's mean gripper quaternion (4,) over its tasks and phases (the hemisphere of its
    training demos)."""
    z = np.linspace(0.0, 1.0, 11)
    robot = fitted.layout.robot_slice
    quats = [fitted.distribution(task, z)[0][:, robot][:, QUATERNION] for task in fitted.tasks]
    mean = np.mean(np.concatenate(quats), axis=0)
    return mean / np.linalg.norm(mean)


def added_demos(fitted: FittedModel, demos: Sequence[Demo]) -> list[Demo]:
    """A new task's demos aligned with a gripper model's hemisphere (unchanged for a joint model)."""
    if not is_gripper_group(fitted.layout.robot_group):
        return list(demos)
    reference = model_reference(fitted)
    return [with_gripper(d, reference) for d in demos]


def gripper_kinematics() -> tuple[Kinematics, Kinematics]:
    """A gripper model's forward kinematics: its positions (n, 7) -> (n, 3) [m] and rotations
    (n, 7) -> (n, 3, 3)."""
    return gripper_positions, gripper_rotations
