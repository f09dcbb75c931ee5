"""``ipromp-pin train DATASET --out MODEL``: train a model on a dataset and save it."""

from __future__ import annotations

import argparse
import time
from functools import partial
from pathlib import Path

from ..shipped import DEFAULT_ROBOT
from .arguments import read_dataset


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``train`` command to ``subparsers``."""
    p = subparsers.add_parser("train", help="train a model on a dataset and save it")
    p.add_argument("dataset", type=Path)
    p.add_argument("--observe", default="orientation,emg")
    p.add_argument("--format", default="auto")
    p.add_argument("--out", type=Path, required=True, help="model file (.npz)")
    p.add_argument(
        "--robot",
        default=DEFAULT_ROBOT,
        help="robot settings: the recorded joints of the robot group and their limits (default %(default)s)",
    )
    p.add_argument(
        "--coupling",
        default="auto",
        help="observed groups that predict the robot: auto (cross-validated), all, or a comma-separated list",
    )
    p.set_defaults(func=cmd_train)


def cmd_train(args: argparse.Namespace) -> int:
    """Train on every demo of the dataset and save the model."""
    from .. import atomic
    from ..commands.model_warnings import single_task_warning, warn_stderr
    from ..data import parse_groups, skeleton_frames
    from ..promp import IProMP
    from ..robot import ee_positions, load_robot

    atomic.check_output_file(args.out, "model file")
    observe = parse_groups(args.observe)
    coupling = args.coupling if args.coupling in ("auto", "all") else parse_groups(args.coupling)
    IProMP(observe=observe, coupling=coupling).check_params()  # before reading the data
    frames = skeleton_frames(observe) or None
    robot = load_robot(args.robot)
    ds = read_dataset(args, frames, robot)
    t0 = time.perf_counter()
    fk = partial(ee_positions, robot)  # settings chosen for the hand-over position of this robot
    model = IProMP(observe=observe, coupling=coupling).fit(ds.all_demos(), fk=fk)
    single = single_task_warning(model)
    if single is not None:
        warn_stderr(single)
    model.save(args.out)  # atomic: a failed save leaves an earlier model file intact
    print(
        f"trained on {len(ds.all_demos())} demos of {', '.join(ds.tasks)} in {time.perf_counter() - t0:.2f} s"
    )
    print(
        f"noise ratio {model.noise_ratio_:g}; groups coupled to the robot: "
        f"{', '.join(model.coupled_groups_) or 'none (the prediction is the prior)'}"
    )
    print(f"wrote {args.out}")
    return 0
