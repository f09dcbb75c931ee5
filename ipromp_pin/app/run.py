"""``ipromp-pin run PIPELINE``: data -> model -> observe -> recognise -> predict -> check -> time -> files.

:func:`run` sets up the command (:func:`~ipromp_pin.app.session.prepare_session`: data, model,
observation, checks), plans the hand-over and its retreat from the observation
(:func:`ipromp_pin.plans.plan`), scores it against the recorded demo and writes the trajectory, the
bags, the report, the preview page and the figures together (:func:`~ipromp_pin.plans.files.write_plan`);
it returns a :class:`RunOutcome`. :func:`main` is the command line: its parser (:func:`add_parser`) and
its exit status (3 when the plan failed its checks). The modules that compute are imported when the
command runs, so that ``--help`` answers at once.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from .arguments import add_pipeline_overrides, add_strict_human, pipeline_config
from .progress import EXIT_CHECKS_FAILED, print_error

if TYPE_CHECKING:
    from ..planning.one_shot import LogFn
    from .config import PipelineConfig


@dataclass
class RunOutcome:
    """What a run did.

    Attributes:
        report: The report, equal to the written ``report.json``.
        passed: Whether the plan (and its retreat) passed every check.
        failures: The failed checks (``timing``, ``retreat.<check>``), empty when it passed.
        files: The files written, by report key.
        trajectory_written: Whether the trajectory files were written (when it passed, or marked as
            failing with ``--allow-failing-checks``).
        unknown_reason: Why the observation matches none of the model's tasks (None: a known task).
    """

    report: dict
    passed: bool
    failures: list[str] = field(default_factory=list)
    files: dict[str, Path] = field(default_factory=dict)
    trajectory_written: bool = False
    unknown_reason: str | None = None


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
    add_strict_human(p)
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Run the pipeline; exit status 3 when the observation matches none of the model's tasks or the
    planned motion fails its checks."""
    outcome = run(
        pipeline_config(args),
        log=print,
        allow_failing_checks=args.allow_failing_checks,
        strict_human=args.strict_human,
    )
    if outcome.passed:
        return 0
    written = "written marked as failing" if outcome.trajectory_written else "not written"
    if outcome.unknown_reason is not None:
        print_error("run", f"{outcome.unknown_reason}; trajectory {written}")
        return EXIT_CHECKS_FAILED
    print_error(
        "run", f"the planned motion failed its checks ({', '.join(outcome.failures)}); trajectory {written}"
    )
    return EXIT_CHECKS_FAILED


def run(
    cfg: PipelineConfig,
    log: LogFn = print,
    warn: LogFn | None = None,
    *,
    allow_failing_checks: bool = False,
    strict_human: bool = False,
) -> RunOutcome:
    """Run every stage of ``cfg`` and write its outputs (``warn``: where warnings go, one line each;
    default standard error; they are also in the report).

    The outputs are written together (:func:`~ipromp_pin.plans.files.write_plan`): complete, or the
    folder's earlier files untouched. When the plan fails its checks the trajectory files and bags
    are not written (and an earlier run's are removed) unless ``allow_failing_checks``, which writes
    them marked as failing (see :mod:`ipromp_pin.outputs.staging`).
    """
    t_start = time.perf_counter()  # the total includes loading the planning code
    from ..outputs.report import summary_text
    from ..outputs.rosbag import check_bag_paths
    from ..plans.files import write_plan
    from ..plans.warnings import warn_stderr
    from ..promp.compiled import IK, INFERENCE, prefer_backend
    from .session import check_outputs, plan_session, prepare_session

    check_outputs(cfg)
    check_bag_paths(cfg.out_dir)  # never replace or remove a user's own file named rosbag / run.bag
    say = warn or warn_stderr
    session = prepare_session(cfg, log, say, prefetch_meshes=cfg.preview_html, strict_human=strict_human)
    prefer_backend(INFERENCE, "numpy")  # one prediction left (a model just trained has decided already)
    prefer_backend(IK, "numpy")  # one retargeting: Pinocchio's solves take less than loading the kernels
    planned = plan_session(session, log)
    for w in planned.warnings:
        if w not in session.warnings:
            say(w)
    planned.warnings = session.warnings + [w for w in planned.warnings if w not in session.warnings]
    written = write_plan(
        planned,
        cfg.out_dir,
        ros=cfg.ros,
        rosbag=cfg.rosbag,
        ros1_bag=cfg.ros1_bag,
        preview=cfg.preview_html,
        plots=cfg.plots,
        model=session.model,
        recording=session.demo,
        allow_failing_checks=allow_failing_checks,
        prefetch=session.mesh_prefetch,
        log=log,
    )
    log(summary_text(planned.approach, written.files, time.perf_counter() - t_start, planned.retreat))
    if not planned.known:
        log(
            f"UNKNOWN TASK ({planned.approach.prediction.unknown_reason}): "
            + (
                "the trajectory was written marked as failing"
                if written.trajectory_written
                else "no trajectory written"
            )
        )
    elif not planned.passed:
        log(
            "Checks FAILED: "
            + (
                "the trajectory was written marked as failing"
                if written.trajectory_written
                else "no trajectory written (--allow-failing-checks writes it, marked)"
            )
        )
    return RunOutcome(
        written.report,
        planned.passed,
        planned.failures,
        written.files,
        written.trajectory_written,
        None if planned.known else planned.approach.prediction.unknown_reason,
    )
