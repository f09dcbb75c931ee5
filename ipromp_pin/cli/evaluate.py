"""``ipromp-pin evaluate DATASET``: recognition accuracy and prediction error on a dataset, in the
paper's protocol or over random splits, optionally with the closed loop."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from ..shipped import DEFAULT_ROBOT
from .arguments import add_closed_loop_options, bounded, closed_loop_settings, read_dataset
from .progress import progress


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
        choices=["paper", "splits", "both"],
        default="paper",
        help="paper: the paper's experiment, per task the first n_train demos train and the next --n-test "
        "test (its cells train on up to 20: 21+ demos per task); splits: every cell over --splits random "
        "train/test splits per task, mean and standard deviation (for smaller datasets, with --grid full "
        "--n-train); both: one after the other (default: paper)",
    )
    p.add_argument(
        "--observe",
        action="append",
        help="comma-separated observed groups (orientation, emg, acc, /left_hand_1 ...); repeat to compare "
        "(default: orientation and orientation,emg)",
    )
    p.add_argument("--json", type=Path, help="write the table as JSON here")
    p.add_argument("--md", type=Path, help="write the table as Markdown here (default: beside --json)")
    p.add_argument("--format", default="auto", help="dataset format (default %(default)s)")
    p.add_argument(
        "--grid", choices=["paper", "full"], default="paper", help="paper's 4 cells or --n-train x --ratios"
    )
    p.add_argument(
        "--n-train",
        type=bounded(int, 2),
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
        "--n-test", type=bounded(int, 1), default=10, help="test demos per task (default %(default)s)"
    )
    p.add_argument(
        "--splits",
        type=bounded(int, 1),
        default=20,
        help="random splits of the splits protocol (default %(default)s)",
    )
    p.add_argument("--seed", type=bounded(int, 0), default=0)
    p.add_argument("--robot", default=DEFAULT_ROBOT, help="robot settings for the hand-over error")
    p.add_argument(
        "--jobs",
        type=bounded(int, 1, 1024),
        default=default_jobs(),
        help=f"worker processes (default: every core but one, here {default_jobs()}, so the machine stays "
        "usable)",
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
    p.set_defaults(func=cmd_evaluate)


def cmd_evaluate(args: argparse.Namespace) -> int:
    from .. import atomic
    from ..data import parse_groups, skeleton_frames
    from ..evaluation.evaluate import (
        PAPER_GRID,
        EvaluationConfig,
        check_dataset_size,
        evaluate,
        overall,
        to_markdown,
        write_results,
    )
    from ..readers import count_demos
    from ..robot import load_robot

    if args.closed_loop:
        return _evaluate_closed_loop(args)
    observe = [parse_groups(o) for o in (args.observe or ["orientation", "orientation,emg"])]
    if args.baselines:
        from ..evaluation.baselines import require_sklearn

        require_sklearn()
    frames = skeleton_frames(g for o in observe for g in o) or None
    md = args.md or (args.json.with_suffix(".md") if args.json else None)
    for path in (args.json, md):
        if path is not None:
            atomic.check_output_file(path)
    if args.plots:
        atomic.check_output_dir(args.plots, "plots folder")
    if args.grid == "paper":
        grid = list(PAPER_GRID)
    else:
        grid = [(n, r) for n in args.n_train for r in args.ratios]
    protocols = ["paper", "splits"] if args.protocol == "both" else [args.protocol]
    configs = [
        EvaluationConfig(
            protocol=protocol,
            observe=observe,
            grid=grid,
            n_test=args.n_test,
            n_splits=args.splits,
            seed=args.seed,
            baselines=args.baselines,
        )
        for protocol in protocols
    ]
    counts = count_demos(args.dataset, format=args.format)  # lists the demo files, reads none
    for cfg in configs:
        check_dataset_size(counts, cfg, args.dataset)
    robot = load_robot(args.robot)
    t0 = time.perf_counter()
    ds = read_dataset(args, frames, robot, timed=True)
    compile_kernels_once()
    cells = []
    for cfg in configs:
        protocol = cfg.protocol
        t1 = time.perf_counter()
        cells += evaluate(ds, cfg, robot=args.robot, progress=progress(), jobs=args.jobs)
        print(f"protocol {protocol}: {time.perf_counter() - t1:.1f} s")
    print(to_markdown(cells))
    meta = {
        "dataset": str(args.dataset),
        "command": " ".join(["ipromp-pin", *sys.argv[1:]]),
        "seconds": round(time.perf_counter() - t0, 2),
    }
    write_results(cells, args.json, md, meta)
    if args.plots:
        from ..outputs import plots

        plots.plot_accuracy(
            [c.__dict__ for c in cells],
            args.plots / "accuracy.png",
            title=f"Recognition accuracy: {args.dataset.name}",
        )
    for key, o in overall(cells).items():
        print(
            f"{key}: mean accuracy {o['mean_accuracy']:.3f}"
            + (f" (paper {o['paper_mean_accuracy']:.3f})" if "paper_mean_accuracy" in o else "")
        )
    if args.json:
        print(f"wrote {args.json}" + (f" and {md}" if md else ""))
    return 0


def compile_kernels_once() -> None:
    """Compile the numba kernels in this process (announced) before worker processes are forked,
    which then inherit them, instead of each worker compiling its own copy."""
    from ..promp.compiled import compiled_kernels_cached, kernel_backend, numba_kernels
    from ..promp.warmup import compile_kernels

    if kernel_backend() == "numba" and not compiled_kernels_cached():
        numba_kernels()  # announces the compile
        try:
            compile_kernels()
        except RuntimeError:  # compiled but not cached (read-only cache): the workers compile again
            pass


def _evaluate_closed_loop(args: argparse.Namespace) -> int:
    from .. import atomic
    from ..commands.replay import check_limits_choice
    from ..data import parse_groups, skeleton_frames
    from ..evaluation.closed_loop import (
        ClosedLoopOptions,
        closed_loop_markdown,
        evaluate_closed_loop,
        write_closed_loop_results,
    )
    from ..evaluation.evaluate import PAPER_GRID, EvaluationConfig, check_dataset_size
    from ..readers import count_demos
    from ..robot import load_robot

    observe = [parse_groups(o) for o in (args.observe or ["orientation", "orientation,emg"])]
    grid = list(PAPER_GRID) if args.grid == "paper" else [(n, r) for n in args.n_train for r in args.ratios]
    for _, ratio in grid:  # every cell's obs_ratio is a start ratio: checked before any computation
        closed_loop_settings(args, control_rate_hz=100.0, start_ratio=ratio)
    settings = closed_loop_settings(args, control_rate_hz=100.0, start_ratio=grid[0][1])
    robot = load_robot(args.robot)
    check_limits_choice(args.limits, robot, "command line")
    md = args.md or (args.json.with_suffix(".md") if args.json else None)
    for path in (args.json, md):
        if path is not None:
            atomic.check_output_file(path)
    protocols = ["paper", "splits"] if args.protocol == "both" else [args.protocol]
    counts = count_demos(args.dataset, format=args.format)  # lists the demo files, reads none
    for protocol in protocols:
        check_dataset_size(
            counts,
            EvaluationConfig(protocol=protocol, observe=observe, grid=grid, n_test=args.n_test),
            args.dataset,
        )
    frames = skeleton_frames(g for o in observe for g in o) or None
    t0 = time.perf_counter()
    ds = read_dataset(args, frames, robot, timed=True)
    compile_kernels_once()
    options = ClosedLoopOptions(limits=args.limits, settings=settings)
    cells = []
    for protocol in protocols:
        cfg = EvaluationConfig(
            protocol=protocol,
            observe=observe,
            grid=grid,
            n_test=args.n_test,
            n_splits=args.splits,
            seed=args.seed,
        )
        t1 = time.perf_counter()
        cells += evaluate_closed_loop(ds, cfg, options, robot=args.robot, progress=progress(), jobs=args.jobs)
        print(f"protocol {protocol} (closed loop): {time.perf_counter() - t1:.1f} s")
    print(closed_loop_markdown(cells))
    meta = {
        "dataset": str(args.dataset),
        "command": " ".join(["ipromp-pin", *sys.argv[1:]]),
        "seconds": round(time.perf_counter() - t0, 2),
        "closed_loop": {
            "limits": args.limits,
            **settings.to_dict(),
            "start_ratio": "obs_ratio of each cell",
        },
    }
    write_closed_loop_results(cells, args.json, md, meta)
    if args.json:
        print(f"wrote {args.json}" + (f" and {md}" if md else ""))
    return 0
