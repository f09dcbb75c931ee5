"""``ipromp-pin evaluate DATASET``: recognition accuracy and prediction error on a dataset, in the
paper's protocol or over random splits, observing a fraction of each test demo (the paper's windows)
and windows in seconds, optionally with the closed loop."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from ..shipped import DEFAULT_ROBOT
from .arguments import MAX_WINDOW_S, add_closed_loop_options, bounded, closed_loop_settings
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
        choices=["paper", "splits", "both", "folds", "open-set"],
        default="paper",
        help="paper: the paper's experiment, per task the first n_train demos train and the next --n-test "
        "test (its cells train on up to 20: 21+ demos per task); splits: every cell over --splits random "
        "train/test splits per task, mean and standard deviation (for smaller datasets, with --grid full "
        "--n-train); both: one after the other; folds: per task the demos in --folds seeded random folds, "
        "each tested once by a model of n_train of the other folds' demos (every demo a test demo once; "
        "with --grid full --n-train); open-set: the random splits, each task in turn left out of "
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
        help="observed fractions of each test demo's length (--grid full)",
    )
    add_window_options(p)
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
    add_robot_options(p)
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
        help="replay every test demo in the closed loop, the robot starting at the end of the cell's "
        "window (a fraction cell: after that fraction of the test demo, the paper's protocol; a cell in "
        "seconds: after those seconds, the online start rule) and add its hand-over error, arrival "
        "delay, limit ratio, refused re-plans and collisions to each cell",
    )
    add_closed_loop_options(p)
    p.set_defaults(func=main)


def add_robot_options(p: argparse.ArgumentParser) -> None:
    """The options of ``evaluate``'s folds protocol and of the arm that executes the plans."""
    p.add_argument(
        "--folds",
        type=bounded(int, 2, 1000),
        default=5,
        help="folds of the folds protocol (default %(default)s)",
    )
    p.add_argument(
        "--run-folds",
        type=bounded(int, 1, 1000),
        nargs="+",
        metavar="I",
        help="run only these folds of the folds protocol, 1-based (default: every fold)",
    )
    p.add_argument(
        "--robot",
        default=DEFAULT_ROBOT,
        help="robot settings for the hand-over error; an arm with [placement] (panda, ur5, xarm7, "
        "kinova_jaco2) executes the model of its source robot: the recordings are read with the source's "
        "joints and every test plan (one-shot) or re-plan (--closed-loop) is retargeted, planned and "
        "checked on the arm (docs/other_arms.md)",
    )
    p.add_argument(
        "--arm-scores",
        action="store_true",
        help="score the plans on the robot as for a placed arm, for an arm of its own model too: every "
        "one-shot trial planned (timed, checked, re-timed) and scored against the recording, every "
        "executed trajectory re-evaluated independently (always on for a placed arm)",
    )
    p.add_argument(
        "--objects",
        type=Path,
        help="task file of the objects the gripper holds (default: the shipped robots/objects.toml; "
        "each cell gets the peak joint torque ratio; with --closed-loop every re-plan is torque-checked; "
        "docs/objects.md)",
    )


def add_window_options(p: argparse.ArgumentParser) -> None:
    """The options of ``evaluate``'s observation windows in seconds (beside the grid's fractions)."""
    p.add_argument(
        "--windows",
        choices=["both", "fraction", "seconds"],
        default="both",
        help="which cells: fraction = the grid's, each test demo observed for a fraction of its own "
        "length (the paper's protocol: that length is known only once the motion is over); seconds = "
        "each test demo observed for its first seconds, by default the grid's fractions of the training "
        "demos' mean length (a time the robot knows before the motion starts), else --window-s and "
        "--window-of-train; both = the two, in separate tables (default %(default)s)",
    )
    p.add_argument(
        "--window-s",
        type=bounded(float, 0.0, MAX_WINDOW_S, open_low=True),
        nargs="+",
        metavar="S",
        help=f"observe each test demo's first S seconds, in (0, {MAX_WINDOW_S:g}], for every training size "
        "of the grid (instead of the grid's fractions of the training demos' mean length)",
    )
    p.add_argument(
        "--window-of-train",
        type=bounded(float, 0.0, 1.0, open_low=True),
        nargs="+",
        metavar="F",
        help="observe each test demo's first F x the training demos' mean length [s] (each fit's own: the "
        "model's nominal duration), F in (0, 1], for every training size of the grid",
    )


def main(args: argparse.Namespace) -> int:
    """Run ``ipromp-pin evaluate`` (:func:`ipromp_pin.evaluation.run.run_evaluate`)."""
    from ..data import parse_groups
    from ..evaluation.run import EvaluateRequest, grid_from, protocols_from, run_evaluate, window_cells

    fractions = grid_from(args.grid, args.n_train, args.ratios)
    grid = window_cells(fractions, args.windows, args.window_s, args.window_of_train)
    settings = None
    if args.closed_loop:  # validated once here; each cell's window replaces the start
        settings = closed_loop_settings(args, control_rate_hz=100.0)
    request = EvaluateRequest(
        dataset=args.dataset,
        format=args.format,
        observe=[parse_groups(o) for o in (args.observe or ["orientation", "orientation,emg"])],
        grid=grid,
        protocols=protocols_from(args.protocol),
        n_test=args.n_test,
        n_splits=args.splits,
        seed=args.seed,
        n_folds=args.folds,
        run_folds=None if args.run_folds is None else [i - 1 for i in args.run_folds],
        robot=args.robot,
        arm_scores=args.arm_scores,
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
            accuracy_records(cells),
            args.plots / "accuracy.png",
            title=f"Recognition accuracy: {args.dataset.name}",
        )
    return 0


def accuracy_records(cells) -> list[dict]:
    """The records of the accuracy plot: the cells observing a fraction of each test demo, and beside
    them those observing the same fraction of the training demos' mean length (their observed set
    marked ``(s)``); the cells of a fixed number of seconds have no fraction and are left out."""
    records = []
    for c in cells:
        if c.window_kind == "ratio":
            records.append(c.__dict__)
        elif c.window_kind == "train_fraction":
            observe = ",".join(c.observe) + " (s)"
            records.append(c.__dict__ | {"obs_ratio": c.window["value"], "observe": observe})
    return records


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
