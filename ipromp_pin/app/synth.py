"""``ipromp-pin synth OUT``: write the built-in synthetic demos in the native format."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from ..exceptions import PipelineError
from .arguments import bounded

if TYPE_CHECKING:
    from ..data import Dataset


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
    p.add_argument(
        "--robot",
        default="baxter_left",
        help="the arm the demos are recorded on (default %(default)s); an arm placed in Baxter's scene "
        "(panda, ur5, xarm7, kinova_jaco2) gets Baxter's demos retargeted through the gripper, with its own "
        "joints",
    )
    p.add_argument(
        "--gripper",
        action="store_true",
        help="write the robot side as Baxter's gripper pose path (a 'gripper' group: x, y, z [m] and qx, qy, "
        "qz, qw in Baxter's base frame, the forward kinematics of the synthetic joints) instead of joints, "
        "as a human-human recording gives it",
    )
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Write ``--tasks`` x ``--demos`` synthetic demos into ``out`` (one folder per task)."""
    from .. import atomic
    from ..readers.native import write_demo
    from ..readers.synthetic import make_synthetic_dataset

    atomic.check_output_dir(args.out)

    ds = make_synthetic_dataset(n_tasks=args.tasks, n_demos=args.demos, seed=args.seed)
    if args.gripper:
        ds = as_gripper(ds, args.robot)
    else:
        ds = on_robot(ds, args.robot)
    suffix = ".csv" if args.csv else ".npz"
    n = 0
    for task, demos in ds.demos.items():
        for d in demos:
            write_demo(d, args.out / task / f"{d.name}{suffix}")
            n += 1
    side = "; the robot side a gripper pose path (no joints)" if args.gripper else ""
    print(f"wrote {n} demos of {', '.join(ds.tasks)} into {args.out} ({suffix} files){side}")
    return 0


def on_robot(ds: Dataset, robot: str) -> Dataset:
    """The synthetic (Baxter left-arm) demos as recorded on ``robot``: unchanged for Baxter's left arm,
    else the robot group retargeted through the gripper to the arm placed in Baxter's scene
    (:func:`ipromp_pin.robot.transfer_path`), named with the arm's recorded joint names.

    Raises:
        PipelineError: the arm is not placed in Baxter's scene, or cannot reach a demo's hand-over.
    """
    from ..data import ROBOT, Demo
    from ..robot import load_robot, transfer_path

    arm = load_robot(robot)
    placement = arm.settings.placement
    if placement is None:
        if arm.settings.recorded_arm_joints != ds.all_demos()[0].channel_names[ROBOT]:
            raise PipelineError(
                f"synth --robot {robot}: the synthetic demos are Baxter's left arm's; robot "
                f"'{arm.settings.name}' has no [placement] in Baxter's scene to retarget them to"
            )
        return ds
    source = load_robot(placement.source)
    demos: dict[str, list[Demo]] = {}
    for task, items in ds.demos.items():
        demos[task] = []
        for d in items:
            moved = transfer_path(source, arm, d.groups[ROBOT])
            if not moved.reached:
                raise PipelineError(f"synth --robot {robot}: {d.name}: {moved.why_not_reached(arm)}")
            groups = {**d.groups, ROBOT: moved.q}
            names = {**d.channel_names, ROBOT: arm.settings.recorded_arm_joints}
            demos[task].append(replace(d, groups=groups, channel_names=names))
    return replace(ds, demos=demos)


def as_gripper(ds: Dataset, robot: str) -> Dataset:
    """The synthetic (Baxter left-arm) demos with their robot side as Baxter's gripper pose path
    (:func:`ipromp_pin.robot.recordings.as_gripper_demos`).

    Raises:
        PipelineError: ``robot`` is not Baxter's left arm (the poses are in its base frame, and no
            joints are written for another arm).
    """
    from ..robot import load_robot
    from ..robot.recordings import as_gripper_demos
    from ..shipped import DEFAULT_ROBOT

    arm = load_robot(robot)
    baxter = load_robot(DEFAULT_ROBOT)
    if arm.settings.name != baxter.settings.name:
        raise PipelineError(
            f"synth --gripper --robot {robot}: a gripper pose path has no joints of any arm (it is Baxter's "
            "gripper in Baxter's base frame, the scene frame); leave out --robot, and plan with --robot NAME"
        )
    return as_gripper_demos(ds, baxter)
