"""``ipromp-pin run PIPELINE``: data -> model -> observe -> recognise -> predict -> check -> time -> files.

:func:`run` sets up the command (:func:`~ipromp_pin.app.session.prepare_session`: data, model,
observation, checks), plans the hand-over and its retreat (:func:`~ipromp_pin.app.session.plan_session`)
and writes the trajectory, the bags, the report, the preview page and the figures together; it
returns a :class:`RunOutcome`. :func:`main` is the command line: its parser (:func:`add_parser`) and
its exit status (3 when the plan failed its checks). The modules that compute are imported when the
command runs, so that ``--help`` answers at once.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from .arguments import add_pipeline_overrides, pipeline_config
from .progress import EXIT_CHECKS_FAILED, print_error

if TYPE_CHECKING:
    from .. import atomic
    from ..planning.one_shot import LogFn, PlanResult
    from ..planning.retreat import RetreatResult
    from .config import PipelineConfig
    from .session import Session


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
    """

    report: dict
    passed: bool
    failures: list[str] = field(default_factory=list)
    files: dict[str, Path] = field(default_factory=dict)
    trajectory_written: bool = False


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
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Run the pipeline; exit status 3 when the planned motion fails its checks."""
    outcome = run(pipeline_config(args), log=print, allow_failing_checks=args.allow_failing_checks)
    if outcome.passed:
        return 0
    written = "written marked as failing" if outcome.trajectory_written else "not written"
    print_error(
        "run", f"the planned motion failed its checks ({', '.join(outcome.failures)}); trajectory {written}"
    )
    return EXIT_CHECKS_FAILED


def run(
    cfg: PipelineConfig, log: LogFn = print, warn: LogFn | None = None, *, allow_failing_checks: bool = False
) -> RunOutcome:
    """Run every stage of ``cfg`` and write its outputs (``warn``: where warnings go, one line each;
    default standard error; they are also in the report).

    The outputs are written together (``outputs.files.RUN``'s files): complete, or the folder's earlier
    files untouched. When the plan fails its checks the trajectory files and bags are not written (and
    an earlier run's are removed) unless ``allow_failing_checks``, which writes them marked as failing
    (see :mod:`ipromp_pin.outputs.staging`).
    """
    from .. import atomic
    from ..outputs.figures import write_plots
    from ..outputs.files import RUN, command_outputs, keyed, trajectory_outputs
    from ..outputs.report import report_dict, report_text, summary_text
    from ..outputs.rosbag import check_bag_paths
    from ..outputs.staging import OutputOptions, plan_failures, stage_plan, stage_report
    from .model_warnings import warn_stderr
    from .session import check_outputs, plan_session, prepare_session

    t_start = time.perf_counter()
    check_outputs(cfg)
    check_bag_paths(cfg.out_dir)  # never replace or remove a user's own file named rosbag / run.bag
    session = prepare_session(cfg, log, warn or warn_stderr, prefetch_meshes=cfg.preview_html)
    robot, observation = session.robot, session.observed()
    result, retreat = plan_session(session, log)
    options = OutputOptions(cfg.ros, cfg.rosbag, cfg.ros1_bag, robot.base_frame, session.warnings)
    with atomic.OutputSet(cfg.out_dir, managed=command_outputs(RUN)) as out:
        stage_plan(
            result, out, observation, options, allow_failing_checks=allow_failing_checks, retreat=retreat
        )
        if cfg.preview_html:
            _stage_preview(result, session, out, log, retreat)
        if cfg.plots:
            write_plots(result, session.model, session.demo, out, session.robot, session.context.objects)
        orientation = recorded_orientation_error(session, result)
        report = stage_report(
            out,
            report_dict(result, observation, session.warnings, orientation, retreat),
            report_text(result, observation, session.warnings, retreat, orientation),
        )
        files = keyed(out.commit())
    log(summary_text(result, files, time.perf_counter() - t_start, retreat))
    written = [n for n in trajectory_outputs(RUN) if n in out.files]
    if not report["passed"]:
        log(
            "Checks FAILED: "
            + (
                f"the trajectory was written marked as failing ({', '.join(written)})"
                if written
                else "no trajectory written (--allow-failing-checks writes it, marked)"
            )
        )
    failures = plan_failures(result, retreat) or []
    return RunOutcome(report, bool(report["passed"]), failures, files, bool(written))


def recorded_orientation_error(session: Session, result: PlanResult) -> float | None:
    """The planned vs the recorded gripper orientation at the hand-over in [deg] (the observed demo's
    last robot sample), or None when the demo has no robot group."""
    from ..data import ROBOT
    from ..evaluation.scoring import handover_orientation_error_deg

    q_true = session.demo.groups.get(ROBOT)
    if q_true is None or not len(q_true):
        return None
    return handover_orientation_error_deg(session.robot, result.trajectory.q[-1], q_true[-1])


def _stage_preview(
    result: PlanResult, session: Session, out: atomic.OutputSet, log: LogFn, retreat: RetreatResult | None
) -> None:
    """Stage ``preview.html``: the self-contained preview page of the planned hand-over (and retreat)."""
    from ..outputs.preview_content import preview_content
    from ..preview import render_html
    from .meshes import preview_visual_model

    t0 = time.perf_counter()
    visual = preview_visual_model(session.robot, session.mesh_prefetch)
    ctx = session.context
    content = preview_content(
        result,
        session.robot,
        session.demo,
        visual_model=visual,
        human=ctx.human,
        objects=ctx.objects,
        retreat=retreat,
    )
    html = render_html(content).encode("utf-8")
    out.write_bytes("preview.html", html)
    log(f"[preview] {out.path('preview.html')} ({len(html) / 1e6:.1f} MB, {time.perf_counter() - t0:.1f} s)")
