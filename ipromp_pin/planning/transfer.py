"""A plan for an arm other than the one the model was trained on: the prediction's joint paths are
retargeted through the gripper (:mod:`ipromp_pin.robot.arm_transfer`) before they are timed and
checked on that arm.

:func:`source_robot` finds the model's robot: the arm itself when the model predicts its joints,
else the ``[placement] source`` of its settings (the robot of the recordings, in whose base frame the
arm is placed). :func:`retarget_prediction` turns the predicted mean path and the sampled paths into
the arm's joint paths, with the inverse kinematics' residuals (:class:`Retargeting`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..exceptions import ModelError
from ..promp import IProMP
from ..robot import Robot, TransferredPath, load_robot, transfer_path, transfer_samples


@dataclass(frozen=True)
class Retargeting:
    """How a plan's joint paths came from another robot's prediction.

    Attributes:
        source: The robot whose joints the model predicts (e.g. Baxter's left arm).
        target: The arm that executes the plan.
        path: The mean path on the executing arm, with its residuals.
        ms: Wall time of the retargeting in [ms].
    """

    source: Robot
    target: Robot
    path: TransferredPath
    ms: float

    @property
    def reached(self) -> bool:
        """Whether the executing arm reaches the predicted hand-over pose."""
        return self.path.reached

    def to_dict(self) -> dict:
        """The report's ``retarget`` entry (JSON-serialisable)."""
        return {
            "source_robot": self.source.settings.name,
            "reached": self.reached,
            "ik_residual_mm": round(self.path.handover_residual_mm, 4),
            "ik_residual_deg": round(self.path.handover_residual_deg, 4),
            "max_path_residual_mm": round(self.path.max_path_residual_mm, 4),
            "ms": round(self.ms, 3),
        }


def model_robot_names(model: IProMP, robot: Robot) -> tuple[str, ...]:
    """The model's robot joints as ``robot``'s model names (through its recorded names)."""
    recorded = robot.settings.recorded_names
    return tuple(recorded.get(n, n) for n in model.joint_names_)


def source_robot(model: IProMP, robot: Robot) -> Robot | None:
    """The robot whose joints ``model`` predicts when it is not ``robot`` (None: ``robot`` itself):
    the ``[placement] source`` of ``robot``'s settings.

    Raises:
        ModelError: the model predicts neither ``robot``'s joints nor its placement source's.
    """
    if model_robot_names(model, robot) == robot.joint_names or robot.settings.placement is None:
        return None  # the arm's own model, or no other arm to take it from (check_model_joints says why)
    source = load_robot(robot.settings.placement.source)
    if model_robot_names(model, source) != source.joint_names:
        raise ModelError(
            f"the model predicts joints {list(model.joint_names_)}: neither robot '{robot.settings.name}''s "
            f"nor its placement source '{source.settings.name}''s {list(source.settings.recorded_arm_joints)}"
        )
    return source


def retarget_prediction(
    source: Robot, robot: Robot, q_mean: np.ndarray, samples: np.ndarray
) -> tuple[np.ndarray, np.ndarray, Retargeting]:
    """The mean path (M, n_joints) and the sampled paths (n, M, n_joints) of ``robot`` [rad] whose
    gripper follows ``source``'s along ``q_mean`` (M, n_source) and ``samples`` (n, M, n_source)."""
    t0 = time.perf_counter()
    path = transfer_path(source, robot, q_mean)
    if path.reached:
        moved = transfer_samples(source, robot, samples, path, q_mean)
    else:  # refused: the samples are not followed either
        moved = np.broadcast_to(path.q, (samples.shape[0],) + path.q.shape).copy()
    return path.q, moved, Retargeting(source, robot, path, (time.perf_counter() - t0) * 1e3)
