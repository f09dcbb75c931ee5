"""``ipromp-pin synth OUT``: write the built-in synthetic demos in the native format."""

from __future__ import annotations

import argparse
from pathlib import Path

from .arguments import bounded


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``synth`` command to ``subparsers``."""
    p = subparsers.add_parser("synth", help="write the built-in synthetic demos in the native format")
    p.add_argument("out", type=Path, help="folder to write the dataset into: one sub-folder per task")
    p.add_argument(
        "--tasks", type=bounded(int, 1, 20), default=3, help="number of tasks, 1-20 (default %(default)s)"
    )
    p.add_argument(
        "--demos", type=bounded(int, 2, 1000), default=20, help="demos per task, 2-1000 (default %(default)s)"
    )
    p.add_argument(
        "--seed",
        type=bounded(int, 0, 2**32 - 1),
        default=0,
        help="seed of the random generator: the same seed writes the same demos (default %(default)s)",
    )
    p.add_argument("--csv", action="store_true", help="write .csv files (one row per sample) instead of .npz")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Write ``--tasks`` x ``--demos`` synthetic demos into ``out`` (one folder per task)."""
    from .. import atomic
    from ..readers.native import write_demo
    from ..readers.synthetic import make_synthetic_dataset

    atomic.check_output_dir(args.out)

    ds = make_synthetic_dataset(n_tasks=args.tasks, n_demos=args.demos, seed=args.seed)
    suffix = ".csv" if args.csv else ".npz"
    n = 0
    for task, demos in ds.demos.items():
        for d in demos:
            write_demo(d, args.out / task / f"{d.name}{suffix}")
            n += 1
    print(f"wrote {n} demos of {', '.join(ds.tasks)} into {args.out} ({suffix} files)")
    return 0
