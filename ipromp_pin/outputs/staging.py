"""Staging a command's files in its :class:`~ipromp_pin.atomic.OutputSet`.

:func:`stage_trajectory` is the one place that decides whether the files a robot executes are
written: when the checks passed; when they failed, only with ``--allow-failing-checks``, and then
marked as failing (a ``#`` comment line first in ``trajectory.csv``, an ``ipromp_pin_checks``
member in ``trajectory.json``, see :mod:`ipromp_pin.outputs.trajectory_files`; in the bags, the
robot's topics under ``/ipromp_pin/failed_checks/`` and a ``/ipromp_pin/checks`` message, see
:mod:`ipromp_pin.outputs.rosbag`). Both ``run`` and
``replay`` stage their trajectory through it, and their reports through :func:`stage_report`
(whose ``files`` lists what the folder will hold after the commit, the report itself included).
:func:`stage_plan` stages the files of a planned hand-over (``run``, ``benchmarks/pipeline.py``).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from dataclasses import dataclass

from .. import atomic
from ..data import Demo
from ..motion.trajectory import Trajectory
from ..planning.one_shot import PlanResult
from ..planning.retreat import RetreatResult
from .files import report_listing
from .retreat_files import RETREAT_CSV, RETREAT_KEY, RetreatSegment
from .rosbag import BagContent, write_ros1_bag, write_rosbag2
from .trajectory_files import trajectory_csv_text, trajectory_json_text

ALLOWED_FAILING = "written because of --allow-failing-checks"
"""The end of the comment that marks a trajectory written although its checks failed."""


@dataclass(frozen=True)
class OutputOptions:
    """How a run's files are written.

    Attributes:
        ros: ROS version of ``trajectory.json``'s message (2: ``sec``/``nanosec``; 1: ``secs``/``nsecs``).
        rosbag: Write the rosbag2 folder ``rosbag/`` (MCAP storage).
        ros1_bag: Also write the ROS 1 bag ``run.bag``.
        base_frame: The robot's base frame (the frame of the poses in the bags).
        warnings: Warnings of the run, listed in the report.
    """

    ros: int = 2
    rosbag: bool = True
    ros1_bag: bool = False
    base_frame: str = "base"
    warnings: tuple[str, ...] | list[str] = ()


def stage_trajectory(
    out: atomic.OutputSet,
    trajectory: Trajectory,
    failures: Sequence[str] | None,
    *,
    allow_failing_checks: bool = False,
    ros: int = 2,
    bag: BagContent | None = None,
    rosbag: bool = False,
    ros1_bag: bool = False,
    retreat: RetreatSegment | None = None,
) -> bool:
    """Stage ``trajectory.csv``, ``trajectory.json`` and, with ``bag``, the bags ``rosbag/`` (rosbag2,
    when ``rosbag``) and ``run.bag`` (ROS 1, when ``ros1_bag``); with ``retreat``, ``retreat.csv`` and
    ``trajectory.json``'s ``retreat`` member (:mod:`ipromp_pin.outputs.retreat_files`).

    Args:
        out: The command's output set.
        trajectory: The commanded trajectory (times in [s], joints in [rad]).
        failures: None when the checks passed, else the names of the failed checks (marked in the
            files when ``allow_failing_checks``).
        allow_failing_checks: Write a trajectory whose checks failed, marked as failing.
        ros: ROS version of ``trajectory.json``'s message.
        bag: What goes into the bags (None: no bag).
        rosbag: Stage the rosbag2 folder (with ``bag``).
        ros1_bag: Stage the ROS 1 bag (with ``bag``).
        retreat: The segment after the hand-over (None: none).

    Returns:
        Whether the trajectory was staged.
    """
    if failures is not None and not allow_failing_checks:
        return False
    comment, extra = None, None
    if failures is not None:
        comment = f"ipromp_pin: checks FAILED ({', '.join(failures)}); {ALLOWED_FAILING}"
        extra = {"ipromp_pin_checks": {"passed": False, "failures": list(failures)}}
    if bag is not None and failures is not None:  # the bags are marked as the CSV and JSON are
        bag = dataclasses.replace(bag, failures=tuple(failures))
    out.write_text("trajectory.csv", trajectory_csv_text(trajectory, comment))
    if retreat is not None:
        extra = {**(extra or {}), RETREAT_KEY: retreat.member(ros=ros)}
        out.write_text(RETREAT_CSV, trajectory_csv_text(retreat.trajectory, comment))
    clock = {"t0": "start of the human's motion", "robot_start_s": float(trajectory.t_s[0])}
    extra = {"clock": clock, **(extra or {})}
    out.write_text("trajectory.json", trajectory_json_text(trajectory, ros=ros, extra=extra))
    if bag is not None and rosbag:
        write_rosbag2(bag, out.stage_dir("rosbag"))
    if bag is not None and ros1_bag:
        write_ros1_bag(bag, out.stage("run.bag"))
    return True


def stage_report(out: atomic.OutputSet, report: dict, text: str) -> dict:
    """Stage ``report.json`` (``report`` with its ``files``: everything staged so far, the two
    reports included, as they will be after the commit) and ``report.txt`` (``text``); returns
    ``report`` with its ``files``. Stage it last."""
    final = {**out.files, "report.json": out.path("report.json"), "report.txt": out.path("report.txt")}
    report["files"] = report_listing(final)
    out.write_text("report.json", json.dumps(report, indent=1, allow_nan=False))
    out.write_text("report.txt", text + "\n")
    return report


def plan_failures(result: PlanResult, retreat: RetreatResult | None = None) -> list[str] | None:
    """None when a planned hand-over (and its retreat) passed, else its failed feasibility checks (and
    ``timing``), then the retreat's as ``retreat.<check>``."""
    later = [] if retreat is None else [f"retreat.{f}" for f in retreat.failures]
    if result.passed and not later:
        return None
    return result.failures + later


def retreat_segment(result: PlanResult, retreat: RetreatResult | None) -> RetreatSegment | None:
    """The retreat of ``result`` as the files hold it (None without one)."""
    if retreat is None:
        return None
    return RetreatSegment(retreat.trajectory, retreat.start_s, retreat.target.dwell_s, retreat.target.kind)


def stage_plan(
    result: PlanResult,
    out: atomic.OutputSet,
    observation: Demo | None = None,
    options: OutputOptions = OutputOptions(),
    *,
    allow_failing_checks: bool = False,
    retreat: RetreatResult | None = None,
) -> bool:
    """Stage the trajectory files and the bags of a planned hand-over (:func:`stage_trajectory`; the
    bags as ``options`` say), with its ``retreat`` as their second segment; returns whether they were
    staged (the retreat's failed checks fail the files as the approach's do). Every time in them is
    on the human's clock (t = 0 at the start of the human's motion; the robot starts at
    ``result.start_s``), as in the reports."""
    approach = result.trajectory
    bag = None
    if options.rosbag or options.ros1_bag:
        bag = BagContent(
            trajectory=approach,
            plan_time_s=float(result.prediction.observed_until_s),
            handover_pose=result.handover_pose,
            base_frame=options.base_frame,
            observation=observation,
            retreat=None if retreat is None else retreat.trajectory,
        )
    return stage_trajectory(
        out,
        approach,
        plan_failures(result, retreat),
        allow_failing_checks=allow_failing_checks,
        ros=options.ros,
        bag=bag,
        rosbag=options.rosbag,
        ros1_bag=options.ros1_bag,
        retreat=retreat_segment(result, retreat),
    )
