"""Compatibility module: forward kinematics, feasibility checks and FK calibration moved to
``ipromp_pin.robot.*``; kept so existing imports work.

New homes: :mod:`ipromp_pin.robot.kinematics` (FK), :mod:`ipromp_pin.robot.report` (check results),
:mod:`ipromp_pin.robot.collision` (self-collision), :mod:`ipromp_pin.robot.checks` (the other checks
and ``check_path``), :mod:`ipromp_pin.robot.calibration` (offset fit, settings-file writer). The
``ipromp-pin calibrate`` glue ``run_calibration`` (it reads datasets) is now in
:mod:`ipromp_pin.calibrate`, and is not re-exported here.
"""

from .robot.calibration import (
    CalibrationResult,
    calibrate_tool_offset,
    endpoint_residuals_mm,
    uncalibrated_robot,
    write_calibration,
)
from .robot.checks import (
    check_hand_distance,
    check_joint_limits,
    check_path,
    check_uncertainty,
    check_workspace,
)
from .robot.collision import check_self_collision, collision_sample_indices, densify_path
from .robot.kinematics import ee_positions, forward_kinematics, frame_placements
from .robot.report import CheckResult, FeasibilityReport

__all__ = [
    "CalibrationResult",
    "CheckResult",
    "FeasibilityReport",
    "calibrate_tool_offset",
    "check_hand_distance",
    "check_joint_limits",
    "check_path",
    "check_self_collision",
    "check_uncertainty",
    "check_workspace",
    "collision_sample_indices",
    "densify_path",
    "ee_positions",
    "endpoint_residuals_mm",
    "forward_kinematics",
    "frame_placements",
    "uncalibrated_robot",
    "write_calibration",
]
