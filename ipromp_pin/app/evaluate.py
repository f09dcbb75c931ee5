"""``ipromp-pin evaluate DATASET``: recognition accuracy and prediction error on a dataset, in the
paper's protocol or over random splits, optionally with the closed loop."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from ..shipped import DEFAULT_ROBOT
from .arguments import add_closed_loop_options, bounded, closed_loop_settings
from .progress import progress

MAX_SPLITS = 1000
"""Most random splits ``--splits`` accepts (each split trains a model per cell: 1000 already take
hours on the real recordings)."""


def default_jobs() -> int:
    """Default ``evaluate --jobs``: every core but one (at least 1), so that the machine stays usable."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return max(1, cores - 1)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``evaluate`` command to ``subparsers``."""
    p = subparsers.add_parser("evaluate", help="recognition accuracy and prediction error on a dataset")
    p.add_argument("dataset", type=Path, help="dataset folder (one sub-folder per task)")
    p.add_argument(
        "--protocol",
        choices=["paper", "splits", "both", "open-set"],
        default="paper",
        help="paper: the paper's experiment, per task the first n_train demos train and the next --n-test "
        "test (its cells train on up to 20: 21+ demos per task); splits: every cell over --splits random "
        "train/test splits per task, mean and standard deviation (for smaller datasets, with --grid full "
        "--n-train); both: one after the other; open-set: the random splits, each task in turn left out of "
        "training, is it recognised as unknown (false reject/accept rates, AUROC; see docs/open_set.md) "
        "(default: paper)",
    )
    p.add_argument(
        "--observe",
        action="append",
        help="comma-separated observed groups (orientation, emg, acc, /left_hand_1 ...); repeat to compare "
        "(default: orientation and orientation,emg)",
    )
    _add_alpha(p)
    p.add_argument("--json", type=Path, help="write the table as JSON here")
    p.add_argument("--md", type=Path, help="write the table as Markdown here (default: beside --json)")
    p.add_argument("--format", default="auto", help="dataset format (default %(default)s)")
    p.add_argument(
        "--grid", choices=["paper", "full"], default="paper", help="paper's 4 cells or --n-train x --ratios"
    )
    p.add_argument(
        "--n-train",
        type=bounded(int, 2, 100_000),
        nargs="+",
        default=[10, 15, 20],
        help="training demos per task (--grid full)",
    )
    p.add_argument(
        "--ratios",
        type=bounded(float, 0.0, 1.0, open_low=True),
        nargs="+",
        default=[0.1, 0.2],
        help="observed fractions (--grid full)",
    )
    p.add_argument(
        "--n-test",
        type=bounded(int, 1, 100_000),
        default=10,
        help="test demos per task (default %(default)s)",
    )
    p.add_argument(
        "--splits",
        type=bounded(int, 1, MAX_SPLITS),
        default=20,
        help="random splits of the splits protocol (default %(default)s)",
    )
    p.add_argument(
        "--seed",
        type=bounded(int, 0, 2**32 - 1),
        default=0,
        help="seed of the random train/test splits (default %(default)s)",
    )
    p.add_argument("--robot", default=DEFAULT_ROBOT, help="robot settings for the hand-over error")
    p.add_argument(
        "--objects",
        type=Path,
        help="task file of the objects the gripper holds (default: the shipped robots/objects.toml; "
        "each cell gets the peak joint torque ratio; with --closed-loop every re-plan is torque-checked; "
        "docs/objects.md)",
    )
    p.add_argument(
        "--jobs",
        type=bounded(int, 1, 1024),
        default=default_jobs(),
        help=f"worker processes (default: every core but one, here {default_jobs()}, so the machine stays "
        "usable)",
    )
    p.add_argument(
        "--cluster",
        metavar="CLUSTER",
        help="run the model fits on a Dask cluster instead of --jobs processes: dask-local:N (N local "
        "workers started for the run) or a scheduler address such as tcp://HOST:8786 (needs "
        "pip install 'ipromp_pin[dask]'; the cells are the same)",
    )
    p.add_argument("--plots", type=Path, help="write PNG figures into this folder")
    p.add_argument(
        "--baselines",
        action="store_true",
        help="also run logistic regression, LDA, ridge and kNN on window features of the same windows "
        "(needs scikit-learn)",
    )
    p.add_argument(
        "--closed-loop",
        action="store_true",
        help="replay every test demo in the closed loop (start ratio = the cell's obs ratio) and add "
        "its hand-over error, arrival delay, limit ratio, refused re-plans and collisions to each cell",
    )
    add_closed_loop_options(p)
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Run ``ipromp-pin evaluate`` (:func:`ipromp_pin.evaluation.run.run_evaluate`)."""
    from ..data import parse_groups
    from ..evaluation.run import EvaluateRequest, grid_from, protocols_from, run_evaluate

    grid = grid_from(args.grid, args.n_train, args.ratios)
    settings = None
    if args.closed_loop:  # validated once here; each cell's ratio replaces the start ratio
        settings = closed_loop_settings(args, control_rate_hz=100.0, start_ratio=grid[0][1])
    request = EvaluateRequest(
        dataset=args.dataset,
        format=args.format,
        observe=[parse_groups(o) for o in (args.observe or ["orientation", "orientation,emg"])],
        grid=grid,
        protocols=protocols_from(args.protocol),
        n_test=args.n_test,
        n_splits=args.splits,
        seed=args.seed,
        robot=args.robot,
        jobs=args.jobs,
        cluster=args.cluster,
        baselines=args.baselines,
        closed_loop=args.closed_loop,
        limits=args.limits,
        objects=args.objects,
        closed_loop_settings=settings,
        json=args.json,
        md=args.md,
        plots=args.plots,
        alpha=args.alpha,
        command=" ".join(["ipromp-pin", *sys.argv[1:]]),
        progress=progress,
    )
    cells = run_evaluate(request)
    if args.plots and not args.closed_loop:
        from ..outputs import plots

        plots.plot_accuracy(
            [c.__dict__ for c in cells],
            args.plots / "accuracy.png",
            title=f"Recognition accuracy: {args.dataset.name}",
        )
    return 0


def _alpha(text: str) -> float:
    """A ``--alpha`` value: a number in (0, 0.5]."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not 0.0 < value <= 0.5:
        raise argparse.ArgumentTypeError(f"{value:g} is not in (0, 0.5]")
    return value


def _add_alpha(p: argparse.ArgumentParser) -> None:
    """The open-set protocol's ``--alpha``."""
    p.add_argument(
        "--alpha",
        type=_alpha,
        default=0.05,
        help="open-set protocol: the largest fraction of known-task observations refused as unknown, in "
        "(0, 0.5] (the models' novelty_alpha; default %(default)s)",
    )
