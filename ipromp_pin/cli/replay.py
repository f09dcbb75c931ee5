"""``ipromp-pin replay PIPELINE``: a held-out demo replayed in the closed loop."""

from __future__ import annotations

import argparse

from .arguments import (
    DEFAULT_MARK,
    add_closed_loop_options,
    add_pipeline_overrides,
    closed_loop_default,
    closed_loop_settings,
    pipeline_config,
    show_default,
)
from .progress import EXIT_CHECKS_FAILED, print_error


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``replay`` command to ``subparsers``."""
    p = subparsers.add_parser(
        "replay",
        help="replay a held-out demo in the closed loop: the robot starts early and re-plans as the "
        "human moves",
    )
    add_pipeline_overrides(p, ratio=False)
    show_default(
        p.add_argument(
            "--start-ratio",
            type=float,  # checked with the other closed-loop settings (one line naming start_ratio)
            help="fraction of the human's motion observed before the robot starts, in (0, 1) "
            f"(default {DEFAULT_MARK})",
        ),
        closed_loop_default("start_ratio"),
    )
    add_closed_loop_options(p)
    p.add_argument("--no-preview", action="store_true", help="do not write preview.html")
    p.add_argument(
        "--allow-failing-checks",
        action="store_true",
        help="write the commanded trajectory even when it collides or exceeds the limits, marked as "
        "failing (exit status 3 still)",
    )
    p.set_defaults(func=cmd_replay)


def cmd_replay(args: argparse.Namespace) -> int:
    """Replay the demo; exit status 3 when no re-plan was committed or the commanded motion collides or
    exceeds the limits."""
    from ..commands.replay import run_replay

    cfg = pipeline_config(args)
    settings = closed_loop_settings(args, control_rate_hz=cfg.control_rate_hz, start_ratio=args.start_ratio)
    outcome = run_replay(
        cfg,
        settings,
        limits=args.limits,
        preview=not args.no_preview,
        log=print,
        allow_failing_checks=args.allow_failing_checks,
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
