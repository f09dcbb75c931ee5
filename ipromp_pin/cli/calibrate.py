"""``ipromp-pin calibrate DATASET``: calibrate FK (the arm mount) against the robot's end-point reports."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..shipped import DEFAULT_ROBOT, ROBOTS_DIR


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
        action="store_true",
        help="store the fitted offsets in the [calibration] table of that settings file (the --robot "
        f"file; default {ROBOTS_DIR / (DEFAULT_ROBOT + '.toml')}); the line printed after it names the file",
    )
    p.set_defaults(func=cmd_calibrate)


def cmd_calibrate(args: argparse.Namespace) -> int:
    """Fit, report and optionally store the calibration."""
    from ..commands.calibrate import run_calibration

    run_calibration(args.dataset, args.robot, write=args.write)
    return 0
