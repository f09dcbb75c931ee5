"""``ipromp-pin preview PIPELINE``: the meshcat preview, live on 127.0.0.1 or a self-contained HTML file."""

from __future__ import annotations

import argparse
from pathlib import Path

from .arguments import add_pipeline_overrides, bounded, pipeline_config, port


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``preview`` command to ``subparsers``."""
    p = subparsers.add_parser(
        "preview", help="meshcat preview: live on 127.0.0.1, or a self-contained HTML file"
    )
    add_pipeline_overrides(p)
    p.add_argument("--html", type=Path, help="write a self-contained HTML file instead of serving live")
    p.add_argument(
        "--port", type=port, default=7000, help="live server port on 127.0.0.1, 1-65535 (default %(default)s)"
    )
    p.add_argument(
        "--speed",
        type=bounded(float, 0.0, 1e6, open_low=True),
        default=1.0,
        help="live streaming speed factor, > 0 (default %(default)g: real time)",
    )
    p.add_argument("--no-wait", action="store_true", help="live: exit when streaming is done")
    p.add_argument(
        "--no-retreat", action="store_true", help="do not plan and show the retreat after the hand-over"
    )
    p.set_defaults(func=cmd_preview)


def cmd_preview(args: argparse.Namespace) -> int:
    """Serve the preview live, or write it as an HTML file."""
    from .. import atomic
    from ..commands.preview import run_preview

    if args.html is not None:
        atomic.check_output_file(args.html, "preview page")
    run_preview(
        pipeline_config(args), html=args.html, port=args.port, speed=args.speed, wait=not args.no_wait
    )
    return 0
