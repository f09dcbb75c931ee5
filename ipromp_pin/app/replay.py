"""``ipromp-pin replay PIPELINE``: one held-out demo replayed in the closed loop, and its files.

:func:`run_replay` sets up the command as ``run`` does (:func:`~ipromp_pin.app.session.prepare_replay`:
the pipeline's data, the chosen demo held out, the model trained on the others or loaded, the limit
profile, the checks primed on the training motions), replays the demo at its recorded timing
(:func:`~ipromp_pin.planning.closed_loop.replay_demo`, simulated clock), scores it against the
recording as ``evaluate --closed-loop`` does (:func:`~ipromp_pin.evaluation.scoring.replay_scored`)
and writes into the output folder, together:

- ``trajectory.csv`` and ``trajectory.json``: the commanded trajectory at the control rate;
- ``replans.json``: every re-plan (time, observed ratio, task posterior, predicted hand-over pose
  and time, planned arrival, the checks' verdicts, committed or refused and why);
- ``report.json`` / ``report.txt``: the hand-over error, arrival delay, limit profile and its source,
  limit ratios, torques, the human measures, re-plan counts and cycle times;
- ``limits.toml``: the limit profile used (reusable with ``--limits limits.toml``);
- ``preview.html``: the time-scrubbing preview (:mod:`ipromp_pin.preview.timeline`);
- ``rosbag/`` (unless ``--no-rosbag``): the commanded trajectory as ``run``'s bag holds a plan, and
  with ``--plots`` ``motion.png`` and ``separation.png`` (:mod:`ipromp_pin.outputs.replay_files`).

Every input is checked before anything is computed (one-line errors naming the file and field).
The modules that compute are imported when it runs, so that ``--help`` answers at once.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from .arguments import (
    DEFAULT_MARK,
    add_closed_loop_options,
    add_pipeline_overrides,
    add_strict_human,
    closed_loop_settings,
    pipeline_config,
    show_default,
)
from .progress import EXIT_CHECKS_FAILED, print_error

if TYPE_CHECKING:
    from .. import atomic
    from ..data import Demo
    from ..evaluation.scoring import ClosedLoopScore
    from ..human import HumanMotion
    from ..outputs.replay_files import ReplayExtras
    from ..planning.closed_loop import ClosedLoopResult, ClosedLoopSettings
    from ..planning.one_shot import LogFn
    from ..safety import CheckReport
    from .config import PipelineConfig
    from .session import Session


@dataclass
class ReplayOutcome:
    """The replay and what it reached.

    Attributes:
        demo: The replayed demo.
        result: The closed loop's commanded trajectory and re-plans.
        score: Hand-over error, arrival delay, limit ratios, collisions.
        files: Written files by kind.
        passed: Whether the commanded trajectory passed
            (:func:`~ipromp_pin.outputs.replay_report.replay_passed`).
    """

    demo: Demo
    result: ClosedLoopResult
    score: ClosedLoopScore
    files: dict[str, Path]
    passed: bool = True


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``replay`` command to ``subparsers``."""
    p = subparsers.add_parser(
        "replay",
        help="replay a held-out demo in the closed loop: the robot starts early and re-plans as the "
        "human moves",
    )
    add_pipeline_overrides(p, ratio=False)
    start = p.add_mutually_exclusive_group()
    show_default(
        start.add_argument(
            "--start-after",
            type=float,  # checked with the other closed-loop settings (one line naming start_after_s)
            metavar="S",
            help=f"the robot starts S seconds after the human's motion starts (default: {DEFAULT_MARK} of "
            "the model's nominal duration, the mean length of its training demos)",
        ),
        start_fraction,
    )
    start.add_argument(
        "--start-ratio",
        type=float,
        help="offline instead: the robot starts after this fraction of the recorded motion's length, in "
        "(0, 1) (a length known only once the motion is over)",
    )
    add_closed_loop_options(p)
    p.add_argument("--no-preview", action="store_true", help="do not write preview.html")
    add_replay_outputs(p)
    p.add_argument(
        "--allow-failing-checks",
        action="store_true",
        help="write the commanded trajectory even when it collides or exceeds the limits, marked as "
        "failing (exit status 3 still)",
    )
    add_strict_human(p)
    p.set_defaults(func=main)


def add_replay_outputs(p: argparse.ArgumentParser) -> None:
    """``replay``'s ``--plots`` and ``--no-rosbag`` (as ``run`` has them)."""
    p.add_argument(
        "--plots",
        action="store_true",
        help="also write PNG figures: motion.png (the commanded motion against its limits, the re-plans "
        "marked) and, with a tracked human, separation.png",
    )
    p.add_argument("--no-rosbag", action="store_true", help="do not write the rosbag2 folder rosbag/ (MCAP)")


def replay_extras(cfg: PipelineConfig) -> ReplayExtras:
    """The optional files of a replay of ``cfg`` (its ``rosbag``, ``ros1_bag`` and ``plots``)."""
    from ..outputs.replay_files import ReplayExtras

    return ReplayExtras(rosbag=cfg.rosbag, ros1_bag=cfg.ros1_bag, plots=cfg.plots)


def start_fraction() -> str:
    """The default start, as ``replay --help`` shows it (``%`` escaped for argparse):
    :data:`~ipromp_pin.planning.closed_loop.START_FRACTION`."""
    from ..planning.closed_loop import START_FRACTION

    return f"{START_FRACTION:.0%}%"


def main(args: argparse.Namespace) -> int:
    """Replay the demo; exit status 3 when no re-plan was committed or the commanded motion collides or
    exceeds the limits."""
    cfg = pipeline_config(args)
    settings = closed_loop_settings(
        args,
        control_rate_hz=cfg.control_rate_hz,
        start_ratio=args.start_ratio,
        start_after_s=args.start_after,
    )
    outcome = run_replay(
        cfg,
        settings,
        limits=args.limits,
        preview=not args.no_preview,
        log=print,
        allow_failing_checks=args.allow_failing_checks,
        strict_human=args.strict_human,
    )
    if outcome.passed:
        return 0
    from ..outputs.replay_report import failure_reason

    written = "written marked as failing" if "trajectory_csv" in outcome.files else "not written"
    print_error(
        "replay",
        f"the commanded motion failed its checks: {failure_reason(outcome.result, outcome.score)}; "
        f"trajectory {written}",
    )
    return EXIT_CHECKS_FAILED


def run_replay(
    cfg: PipelineConfig,
    settings: ClosedLoopSettings,
    limits: str = "demonstrated",
    preview: bool = True,
    log: LogFn = print,
    warn: LogFn | None = None,
    *,
    allow_failing_checks: bool = False,
    strict_human: bool = False,
) -> ReplayOutcome:
    """Replay the pipeline's held-out demo in the closed loop and write the files into ``cfg.out_dir``
    together (:data:`REPLAY_OUTPUTS`): complete, or the folder's earlier files untouched.

    ``settings`` are validated by the caller (:meth:`ClosedLoopSettings.validate`; the command line
    does it). The commanded trajectory is written only when it passed (no commanded sample in
    collision, every limit ratio at most 1), unless ``allow_failing_checks`` (then marked, as ``run``
    marks its files).
    """
    t_start = time.perf_counter()  # the total includes loading the planning code
    from .. import atomic
    from ..outputs.files import ALL_OUTPUTS, keyed
    from ..outputs.replay_report import replay_checks, replay_passed, summary_lines
    from ..outputs.rosbag import check_bag_paths
    from ..plans.warnings import warn_stderr
    from ..safety import CheckContext
    from .session import prepare_replay, recorded_human

    check_bag_paths(cfg.out_dir)  # never replace or remove a user's own file named rosbag / run.bag
    setup = prepare_replay(cfg, settings, limits, log, warn or warn_stderr, strict_human)
    session = setup.session
    demo = session.demo
    score, result = setup.scored(settings)
    truth = CheckContext(task=demo.task, objects=session.context.objects)  # the files' torques
    result.trajectory = session.suite.annotate(result.trajectory, truth)
    # the commanded motion judged after the fact, as the score judges it: the report's and the
    # preview's checks (the human checks against the recorded human, when the demo tracks one)
    recorded = recorded_human(session)
    judged = replay_checks(result.trajectory, session.suite, demo.task, truth.objects, recorded)
    with atomic.OutputSet(cfg.out_dir, managed=ALL_OUTPUTS) as out:  # one command's files only
        _stage_files(
            out, session, result, score, judged, recorded, allow_failing_checks, preview, log,
            replay_extras(cfg),
        )  # fmt: skip
        files = keyed(out.commit())
    log(summary_lines(demo, result, score, time.perf_counter() - t_start))
    return ReplayOutcome(demo, result, score, files, replay_passed(score))


def _stage_files(
    out: atomic.OutputSet,
    session: Session,
    result: ClosedLoopResult,
    score: ClosedLoopScore,
    judged: CheckReport,
    recorded: HumanMotion | None,
    allow_failing_checks: bool,
    preview: bool,
    log: LogFn,
    extras: ReplayExtras | None = None,
) -> None:
    """Stage the replay's files: the trajectory (:func:`~ipromp_pin.outputs.staging.stage_trajectory`),
    ``replans.json``, ``limits.toml``, ``preview.html`` and, last, the reports; ``judged``: the
    commanded motion's verdicts after the fact (the report's ``checks``, the preview's), ``recorded``:
    the recorded human they judged (None: no tracked skeleton); ``extras``: the bags and figures
    (:mod:`ipromp_pin.outputs.replay_files`; None: the bags as ``run`` writes them, no figures)."""
    from ..outputs.preview_content import replay_preview_html
    from ..outputs.replay_files import ReplayExtras, replay_bag, stage_replay_plots
    from ..outputs.replay_report import replans_text, replay_failures, report_dict, report_text
    from ..outputs.staging import stage_report, stage_trajectory
    from ..preview.mesh_cache import preview_visual_model

    demo = session.demo
    more = extras if extras is not None else ReplayExtras()
    stage_trajectory(
        out,
        result.trajectory,
        replay_failures(score),
        allow_failing_checks=allow_failing_checks,
        bag=replay_bag(result, demo, session.robot) if more.rosbag or more.ros1_bag else None,
        rosbag=more.rosbag,
        ros1_bag=more.ros1_bag,
    )
    if more.plots:
        stage_replay_plots(out, session.robot, result, judged, recorded)
    out.write_text("replans.json", replans_text(result, demo))
    out.write_text("limits.toml", result.profile.to_toml())
    if preview:
        t0 = time.perf_counter()
        visual = preview_visual_model(session.robot)
        ctx = session.context
        human = recorded if recorded is not None else ctx.human  # else the one the closed loop planned with
        html = replay_preview_html(
            demo, result, score, session.robot, visual, judged, human, ctx.objects, session.source
        )
        out.write_text("preview.html", html)
        log(f"[preview] {out.path('preview.html')} ({time.perf_counter() - t0:.1f} s)")
    report = report_dict(result, score, demo, session.model, session.warnings, judged)
    stage_report(out, report, report_text(result, score, demo, session.warnings, judged))
