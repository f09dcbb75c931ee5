"""``ipromp-pin run PIPELINE``: observe -> recognise -> predict -> check -> time -> files."""

from __future__ import annotations

import argparse

from .arguments import add_pipeline_overrides, pipeline_config
from .progress import EXIT_CHECKS_FAILED, print_error


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``run`` command to ``subparsers``."""
    p = subparsers.add_parser(
        "run", help="run a pipeline: observe -> recognise -> predict -> check -> time -> files"
    )
    add_pipeline_overrides(p)
    p.add_argument("--no-preview", action="store_true", help="do not write preview.html")
    p.add_argument("--plots", action="store_true", help="also write PNG figures")
    p.add_argument(
        "--ros",
        type=int,
        choices=[1, 2],
        help="ROS version of trajectory.json's JointTrajectory: 2 = ROS 2 field names (default), 1 = ROS 1",
    )
    p.add_argument("--no-rosbag", action="store_true", help="do not write the rosbag2 folder rosbag/ (MCAP)")
    p.add_argument(
        "--ros1-bag", action="store_true", help="also write run.bag (ROS 1) with the same messages"
    )
    p.add_argument(
        "--no-retreat",
        action="store_true",
        help="do not plan the retreat after the hand-over (the task file's retreat entries; docs/objects.md)",
    )
    p.add_argument(
        "--allow-failing-checks",
        action="store_true",
        help="write the trajectory files even when the checks fail, marked as failing (exit status 3 still)",
    )
    p.set_defaults(func=cmd_run)


def cmd_run(args: argparse.Namespace) -> int:
    """Run the pipeline; exit status 3 when the planned motion fails its checks."""
    from ..commands.run import run_pipeline

    cfg = pipeline_config(args)
    report = run_pipeline(cfg, log=print, allow_failing_checks=args.allow_failing_checks)
    if report["passed"]:
        return 0
    failures = list(report["feasibility"]["failures"])
    if not report["trajectory"]["passed"]:
        failures.append("timing")
    if report.get("retreat"):
        failures += [f"retreat.{f}" for f in report["retreat"]["failures"]]
    written = "written marked as failing" if "trajectory_csv" in report["files"] else "not written"
    print_error("run", f"the planned motion failed its checks ({', '.join(failures)}); trajectory {written}")
    return EXIT_CHECKS_FAILED
