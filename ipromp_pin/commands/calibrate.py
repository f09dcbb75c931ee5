"""``ipromp-pin calibrate``: read recorded datasets, fit the FK offsets, report, optionally store them.

Application glue over :mod:`ipromp_pin.robot.calibration` (the fit and the settings-file writer)
and :mod:`ipromp_pin.readers` (the datasets).
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from ..readers import load_dataset
from ..robot.calibration import CalibrationResult, calibrate_tool_offset, write_calibration
from ..robot.model import load_robot
from ..robot.settings import load_robot_settings
from ..shipped import DEFAULT_ROBOT


def run_calibration(
    dataset_paths: str | Path | Sequence[str | Path],
    settings_path: str | Path = DEFAULT_ROBOT,
    write: bool = False,
    *,
    fit: str = "mount",
    command: str | None = None,
    out: Callable[[str], None] | None = print,
) -> CalibrationResult:
    """``ipromp-pin calibrate DATASET [--robot SETTINGS] [--write]``: fit, report and optionally store.

    Args:
        dataset_paths: One or more dataset folders (read with ``ipromp_pin.readers.load_dataset``).
        settings_path: Robot settings file or name.
        write: Store the fitted offsets in the settings file.
        fit: ``"mount"`` (default), ``"tool"`` or ``"both"`` (see :func:`calibrate_tool_offset`).
        command: Command line recorded in the file (default: ``sys.argv``).
        out: Where the text report goes (``None``: silent).
    """
    if isinstance(dataset_paths, str | Path):
        dataset_paths = [dataset_paths]
    settings = load_robot_settings(settings_path)
    robot = load_robot(settings)
    recorded = settings.recorded_arm_joints
    demos, labels = [], []
    limits = robot.recorded_joint_limits()
    for path in dataset_paths:
        ds = load_dataset(path, robot_joints=recorded, joint_limits=limits)
        for d in ds.all_demos():
            demos.append(d)
            labels.append(Path(path).name)
    result = calibrate_tool_offset(robot, demos, labels, fit=fit)
    if out is not None:
        out(result.to_text())
    if write:
        cmd = command if command is not None else " ".join(["ipromp-pin", *sys.argv[1:]])
        written = write_calibration(settings.path, result, cmd)
        if out is not None:
            out(f"  written to {written}")
    return result
