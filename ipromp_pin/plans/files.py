"""A planned hand-over's files, written together into one folder: :func:`write_plan`.

The trajectory files and bags (:mod:`ipromp_pin.outputs.staging`: only when the plan passed its
checks, or marked as failing when the caller allows failing checks), ``report.json`` and
``report.txt`` (:mod:`ipromp_pin.outputs.report`), and on request the preview page and the figures.
The folder ends up holding this plan's files only: the files of an earlier plan, run or replay that
this one does not write are removed, and a failure leaves the folder as it was
(:class:`ipromp_pin.atomic.OutputSet`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from .. import atomic
from ..data import Demo
from ..outputs.files import ALL_OUTPUTS, keyed, trajectory_outputs
from ..outputs.report import report_dict, report_text
from ..outputs.rosbag import check_bag_paths
from ..outputs.staging import OutputOptions, stage_plan, stage_report
from ..promp import IProMP

if TYPE_CHECKING:
    import multiprocessing as mp

    from .handover import HandoverPlan, LogFn


@dataclass(frozen=True)
class WrittenPlan:
    """What :func:`write_plan` wrote.

    Attributes:
        report: The report, equal to the written ``report.json``.
        files: The files written, by report key.
        trajectory_written: Whether the trajectory files were written.
    """

    report: dict
    files: dict[str, Path]
    trajectory_written: bool


def write_plan(
    plan: HandoverPlan,
    out_dir: Path,
    *,
    ros: int = 2,
    rosbag: bool = True,
    ros1_bag: bool = False,
    preview: bool = False,
    plots: bool = False,
    model: IProMP | None = None,
    recording: Demo | None = None,
    allow_failing_checks: bool = False,
    prefetch: mp.process.BaseProcess | None = None,
    log: LogFn | None = None,
) -> WrittenPlan:
    """Write ``plan``'s files into ``out_dir`` together.

    Args:
        plan: The planned hand-over.
        out_dir: The output folder (made if missing).
        ros: ROS version of ``trajectory.json``'s message field names (1 or 2).
        rosbag: Write the rosbag2 folder ``rosbag/`` (MCAP).
        ros1_bag: Also write the ROS 1 bag ``run.bag``.
        preview: Write the self-contained preview page ``preview.html``.
        plots: Write the figures (needs ``model``).
        model: The model that planned it (its distributions, for the figures).
        recording: The whole recording, shown beside the plan in the preview and the figures (the
            recorded robot path, the hand's path after the observation); None: the observation.
        allow_failing_checks: Write the trajectory of a plan that failed its checks, marked.
        prefetch: The process decimating the preview meshes, if one was started.
        log: Progress messages (None: silent).
    """
    say = log or (lambda _msg: None)
    atomic.check_output_dir(out_dir)
    check_bag_paths(out_dir)  # never replace or remove a user's own file named rosbag / run.bag
    shown = recording if recording is not None else plan.observation
    robot, approach = plan.robot, plan.approach
    options = OutputOptions(ros, rosbag, ros1_bag, robot.base_frame, plan.warnings)
    with atomic.OutputSet(out_dir, managed=ALL_OUTPUTS) as out:
        stage_plan(
            approach,
            out,
            plan.observation,
            options,
            allow_failing_checks=allow_failing_checks,
            retreat=plan.retreat,
        )
        if preview:
            stage_preview(plan, shown, out, prefetch, say)
        if plots and model is not None:
            from ..outputs.figures import write_plots  # matplotlib, only with figures

            write_plots(approach, model, shown, out, robot, plan.context.objects, plan.retreat, plan.context)
        scores = plan.scores
        report = stage_report(
            out,
            report_dict(approach, plan.observation, plan.warnings, plan.retreat, scores),
            report_text(approach, plan.observation, plan.warnings, plan.retreat, scores),
        )
        files = keyed(out.commit())
    written = any(name in out.files for name in trajectory_outputs())
    return WrittenPlan(report, files, written)


def stage_preview(
    plan: HandoverPlan,
    shown: Demo,
    out: atomic.OutputSet,
    prefetch: mp.process.BaseProcess | None,
    say: LogFn,
) -> None:
    """Stage ``preview.html``: the self-contained preview page of the planned hand-over (and retreat)."""
    from ..outputs.preview_content import preview_content
    from ..preview import render_html
    from ..preview.mesh_cache import preview_visual_model

    t0 = time.perf_counter()
    visual = preview_visual_model(plan.robot, prefetch)
    ctx = plan.context
    content = preview_content(
        plan.approach,
        plan.robot,
        shown,
        visual_model=visual,
        human=ctx.human,
        objects=ctx.objects,
        retreat=plan.retreat,
    )
    html = render_html(content).encode("utf-8")
    out.write_bytes("preview.html", html)
    say(f"[preview] {out.path('preview.html')} ({len(html) / 1e6:.1f} MB, {time.perf_counter() - t0:.1f} s)")
