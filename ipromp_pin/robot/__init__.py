"""The robot side: settings files, the Pinocchio model, forward kinematics, feasibility checks, calibration.

Modules, each one concept, from the bottom up:

* :mod:`~ipromp_pin.robot.settings`: robot settings files (``robots/*.toml``), validated;
* :mod:`~ipromp_pin.robot.model`: the :class:`Robot` (kinematic + collision models) built from them,
  and :func:`load_robot`'s cache;
* :mod:`~ipromp_pin.robot.kinematics`: forward kinematics along a joint path;
* :mod:`~ipromp_pin.robot.inverse_kinematics`: damped least-squares inverse kinematics;
* :mod:`~ipromp_pin.robot.arm_transfer`: retargeting a joint path to another arm through the gripper
  (its inverse kinematics compiled: :mod:`~ipromp_pin.robot.arm_chain`,
  :mod:`~ipromp_pin.robot.ik_kernels`);
* :mod:`~ipromp_pin.robot.collision`: contact tests; :mod:`~ipromp_pin.robot.clearance`: certified
  self-collision clearance along a path;
* :mod:`~ipromp_pin.robot.dynamics`: inverse dynamics with a payload;
* :mod:`~ipromp_pin.robot.calibration`: FK offset calibration and the settings-file writer.

The checks that judge a motion with these are :mod:`ipromp_pin.safety`'s. The names below are
re-exported here (``from ipromp_pin.robot import load_robot``).
"""

from .arm_transfer import TransferredPath, transfer_path, transfer_samples
from .calibration import (
    CalibrationResult,
    calibrate_tool_offset,
    endpoint_residuals_mm,
    uncalibrated_robot,
    write_calibration,
)
from .inverse_kinematics import IKResult, solve_ik
from .kinematics import (
    GripperKinematics,
    ee_positions,
    forward_kinematics,
    frame_placements,
    gripper_kinematics,
    gripper_rotations,
)
from .model import (
    Robot,
    add_tool_geometry,
    add_tool_inertia,
    build_robot,
    clear_robot_cache,
    load_robot,
    load_visual_model,
    map_recorded_joints,
)
from .settings import (
    EE_FRAME,
    ROBOTS_DIR,
    DemoLimitRecipe,
    RobotSettings,
    Tool,
    Workspace,
    find_robot_data_dir,
    load_robot_settings,
    resolve_settings_path,
)

__all__ = [
    "EE_FRAME",
    "ROBOTS_DIR",
    "CalibrationResult",
    "DemoLimitRecipe",
    "GripperKinematics",
    "IKResult",
    "Robot",
    "RobotSettings",
    "Tool",
    "TransferredPath",
    "Workspace",
    "add_tool_geometry",
    "add_tool_inertia",
    "build_robot",
    "calibrate_tool_offset",
    "clear_robot_cache",
    "ee_positions",
    "endpoint_residuals_mm",
    "find_robot_data_dir",
    "forward_kinematics",
    "frame_placements",
    "gripper_kinematics",
    "gripper_rotations",
    "load_robot",
    "load_robot_settings",
    "load_visual_model",
    "map_recorded_joints",
    "resolve_settings_path",
    "solve_ik",
    "transfer_path",
    "transfer_samples",
    "uncalibrated_robot",
    "write_calibration",
]
