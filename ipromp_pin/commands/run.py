"""``ipromp-pin run``: data -> model -> observe -> recognise -> predict -> check -> time -> files.

:func:`run_pipeline` sets up the command (:func:`~ipromp_pin.commands.setup.prepare_session`), runs
the online stages (:func:`~ipromp_pin.planning.one_shot.plan`), plans the retreat after the hand-over
(:func:`~ipromp_pin.planning.retreat.plan_retreat`, when the recognised task has one and
``[robot] retreat`` is on) and writes the trajectory, the bags,
the report, the preview page and the figures together (:data:`RUN_OUTPUTS`). Every stage reports
through a ``log`` callable.
"""

from __future__ import annotations

import time

from .. import atomic
from ..data import ROBOT
from ..evaluation.scoring import handover_orientation_error_deg
from ..outputs.figures import write_plots
from ..outputs.files import RUN, command_outputs, keyed, trajectory_outputs
from ..outputs.preview_content import preview_content
from ..outputs.report import report_dict, report_text, summary_text
from ..outputs.rosbag import check_bag_paths
from ..outputs.staging import OutputOptions, stage_plan, stage_report
from ..planning.one_shot import LogFn, PlanResult
from ..planning.retreat import RetreatResult
from ..preview import render_html
from .config import PipelineConfig
from .meshes import preview_visual_model
from .model_warnings import warn_stderr
from .setup import Session, check_outputs, plan_session, prepare_session

RUN_OUTPUTS = command_outputs(RUN)
"""Every file ``ipromp-pin run`` may write into its output folder (:mod:`ipromp_pin.outputs.files`). A
run stages its files and commits them together (:class:`ipromp_pin.atomic.OutputSet`): those of an
earlier run that this run does not write (e.g. ``preview.html`` with ``--no-preview``, or the
trajectory of a run whose checks failed) are removed, so the folder always holds one run's files."""

TRAJECTORY_OUTPUTS = trajectory_outputs(RUN)
"""The outputs a robot executes (or replays): written only when the checks pass (or, marked, when the user
allows failing checks)."""


def run_pipeline(
    cfg: PipelineConfig, log: LogFn = print, warn: LogFn = warn_stderr, *, allow_failing_checks: bool = False
) -> dict:
    """Run every stage of ``cfg`` and write its outputs; returns the report dictionary, equal to the
    written ``report.json`` (``warn``: where warnings go, one line each; they are also in the report).

    The outputs are written together (:data:`RUN_OUTPUTS`): complete, or the folder's earlier files
    untouched. When the plan fails its checks (``report["passed"]`` is False) the trajectory files
    and bags are not written (and an earlier run's are removed) unless ``allow_failing_checks``,
    which writes them marked as failing (see :mod:`ipromp_pin.outputs.staging`).
    """
    t_start = time.perf_counter()
    check_outputs(cfg)
    check_bag_paths(cfg.out_dir)  # never replace or remove a user's own file named rosbag / run.bag
    session = prepare_session(cfg, log, warn, prefetch_meshes=cfg.preview_html)
    robot, observation = session.robot, session.observed()
    result, retreat = plan_session(session, log)
    options = OutputOptions(cfg.ros, cfg.rosbag, cfg.ros1_bag, robot.base_frame, session.warnings)
    with atomic.OutputSet(cfg.out_dir, managed=RUN_OUTPUTS) as out:
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
    if not report["passed"]:
        written = [n for n in TRAJECTORY_OUTPUTS if n in out.files]
        log(
            "Checks FAILED: "
            + (
                f"the trajectory was written marked as failing ({', '.join(written)})"
                if written
                else "no trajectory written (--allow-failing-checks writes it, marked)"
            )
        )
    return report


def recorded_orientation_error(session: Session, result: PlanResult) -> float | None:
    """The planned vs the recorded gripper orientation at the hand-over in [deg] (the observed demo's
    last robot sample), or None when the demo has no robot group."""
    q_true = session.demo.groups.get(ROBOT)
    if q_true is None or not len(q_true):
        return None
    return handover_orientation_error_deg(session.robot, result.trajectory.q[-1], q_true[-1])


def _stage_preview(
    result: PlanResult, session: Session, out: atomic.OutputSet, log: LogFn, retreat: RetreatResult | None
) -> None:
    """Stage ``preview.html``: the self-contained preview page of the planned hand-over (and retreat)."""
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
