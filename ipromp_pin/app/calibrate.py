"""``ipromp-pin calibrate DATASET``: calibrate FK (the arm mount) against the robot's end-point reports.

:func:`run_calibration` reads the recorded datasets, fits the FK offsets
(:mod:`ipromp_pin.robot.calibration`), reports them and optionally stores them in the settings file;
the modules that compute are imported when it runs, so that ``--help`` answers at once.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from ..shipped import DEFAULT_ROBOT, ROBOTS_DIR

if TYPE_CHECKING:
    from ..robot.calibration import CalibrationResult


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``calibrate`` command to ``subparsers``."""
    p = subparsers.add_parser(
        "calibrate", help="calibrate FK (arm mount) against the robot's own end-point reports"
    )
    p.add_argument(
        "dataset",
        type=Path,
        nargs="+",
        help="dataset folders whose recordings hold the robot's own end-point reports",
    )
    p.add_argument(
        "--robot",
        default=DEFAULT_ROBOT,
        help="robot settings: a shipped name (robots/<name>.toml of the package) or a settings file "
        "(default %(default)s)",
    )
    p.add_argument(
        "--write",
        nargs="?",
        const="",
        metavar="FILE",
        help="store the fitted offsets in the [calibration] table of a settings file: FILE, else the "
        "--robot file when it is yours; a shipped robot's settings are copied to <name>_calibrated.toml "
        "in the current folder (the shipped file is never changed); the line printed after it names the "
        "file and how to use it",
    )
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Fit, report and optionally store the calibration."""
    run_calibration(args.dataset, args.robot, write=args.write is not None, write_to=args.write or None)
    return 0


def run_calibration(
    dataset_paths: str | Path | Sequence[str | Path],
    settings_path: str | Path = DEFAULT_ROBOT,
    write: bool = False,
    *,
    write_to: str | Path | None = None,
    fit: str = "mount",
    command: str | None = None,
    out: Callable[[str], None] | None = print,
) -> CalibrationResult:
    """``ipromp-pin calibrate DATASET [--robot SETTINGS] [--write]``: fit, report and optionally store.

    Args:
        dataset_paths: One or more dataset folders (read with ``ipromp_pin.readers.load_dataset``).
        settings_path: Robot settings file or name.
        write: Store the fitted offsets: in ``write_to``, else in the settings file when it is not
            a shipped one, else in ``<name>_calibrated.toml`` in the current folder.
        write_to: The settings file to write (a copy of ``settings_path`` with the calibration).
        fit: ``"mount"`` (default), ``"tool"`` or ``"both"`` (see :func:`calibrate_tool_offset`).
        command: Command line recorded in the file (default: ``sys.argv``).
        out: Where the text report goes (``None``: silent).
    """
    from ..readers import load_dataset
    from ..robot.calibration import calibrate_tool_offset, write_calibration
    from ..robot.model import load_robot
    from ..robot.settings import load_robot_settings

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
        for label in dict.fromkeys(labels):  # each dataset's body model, in the order given
            for line in human_fit_lines([d for d, k in zip(demos, labels, strict=True) if k == label], robot):
                out(f"{label}: {line}")
    if write:
        cmd = command if command is not None else " ".join(["ipromp-pin", *sys.argv[1:]])
        target = calibration_target(settings.path, write_to)
        written = write_calibration(settings.path, result, cmd, target)
        if out is not None:
            out(
                f"  written to {written}"
                + ("" if written == settings.path else f"; use it with --robot {written}")
            )
    return result


def human_fit_lines(demos: list, robot: object) -> list[str]:
    """The self-check and registration calibration of the demos' body model
    (:func:`~ipromp_pin.human.fit.self_check`) as report lines ("not measured" without a skeleton)."""
    from ..human.fit import self_check

    found = self_check(demos, robot)  # type: ignore[arg-type]
    if found is None:
        return ["human model self-check: not measured (no demo has a tracked skeleton)"]
    return found.summary()


def calibration_target(settings_path: Path, write_to: str | Path | None) -> Path:
    """The file a calibration is written to: ``write_to``; else the settings file itself unless it is
    one the package ships (inside a wheel it may be read-only, and it is shared by every user), then
    ``<name>_calibrated.toml`` in the current folder."""
    if write_to is not None:
        return Path(write_to)
    shipped = settings_path.resolve().parent == ROBOTS_DIR.resolve()
    return Path.cwd() / f"{settings_path.stem}_calibrated.toml" if shipped else settings_path
