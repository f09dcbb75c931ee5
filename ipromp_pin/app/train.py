"""``ipromp-pin train DATASET --out MODEL``: train a model on a dataset and save it;
``ipromp-pin train --add-task DIR --model MODEL --out MODEL2``: add new tasks to a trained model."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import TYPE_CHECKING

from ..shipped import DEFAULT_ROBOT
from .arguments import read_dataset

if TYPE_CHECKING:
    from ..data import Dataset, Demo
    from ..robot import Robot


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``train`` command to ``subparsers``."""
    p = subparsers.add_parser("train", help="train a model on a dataset and save it")
    p.add_argument("dataset", type=Path, nargs="?", help="dataset folder: one sub-folder of demos per task")
    p.add_argument(
        "--observe",
        default="orientation,emg",
        help="comma-separated channel groups the model observes of the human (default %(default)s)",
    )
    p.add_argument(
        "--format",
        default="auto",
        help="the demos' format: auto (detected per task folder), native, chen2017, multimodal or bag "
        "(default %(default)s)",
    )
    p.add_argument("--out", type=Path, required=True, help="model file (.npz)")
    p.add_argument(
        "--holdout",
        action="append",
        default=[],
        metavar="TASK/DEMO",
        help="leave a demo out of training, by its index in its task (as run --task/--demo count) or "
        "its name, e.g. give/0 or give/give_000; repeatable",
    )
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
    p.add_argument(
        "--add-task",
        type=Path,
        metavar="DIR",
        help="instead of training: add the tasks of DIR (one sub-folder of demos per new task) to the "
        "model --model, without re-fitting its tasks",
    )
    p.add_argument("--model", type=Path, help="with --add-task: the trained model file to add to")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    """Train on every demo of the dataset and save the model."""
    from .. import atomic
    from ..data import ROBOT, parse_groups, robot_side, skeleton_frames
    from ..exceptions import PipelineError
    from ..planning.human_forecast import forecast_of, forecast_summary, with_forecast
    from ..plans.warnings import single_task_warning, warn_stderr
    from ..promp import IProMP
    from ..robot import gripper_kinematics, load_robot

    atomic.check_output_file(args.out, "model file")
    if args.add_task is not None or args.model is not None:
        return add_tasks(args)
    if args.dataset is None:
        raise PipelineError(
            "command line: field 'dataset': give the dataset folder (or --add-task DIR --model M)"
        )
    observe = parse_groups(args.observe)
    coupling = args.coupling if args.coupling in ("auto", "all") else parse_groups(args.coupling)
    IProMP(observe=observe, coupling=coupling).check_params()  # before reading the data
    frames = skeleton_frames(observe) or None
    robot = load_robot(args.robot)
    ds = read_dataset(args, frames, robot)
    t0 = time.perf_counter()
    side = robot_side(ds.all_demos())  # joints, or a gripper pose path (its own kinematics)
    kinematics = gripper_kinematics(robot)._asdict() if side == ROBOT else {}  # chosen for the hand-over
    held = held_out_demos(ds, args.holdout)
    train = [d for d in ds.all_demos() if not any(d is h for h in held)]
    for h in held:
        print(f"held out {h.task}/{h.name} ({h.source})")
    if side != ROBOT:
        print(f"the robot side is a gripper pose path ('{side}' group): plan with --robot NAME")
    model = IProMP(observe=observe, coupling=coupling, robot_group=side).fit(train, **kinematics)
    model = model.with_human_fit(human_self_check(train, robot))
    model = with_forecast(model, train, robot.settings.human)
    print(forecast_summary(forecast_of(model, source=str(args.out))))
    single = single_task_warning(model)
    if single is not None:
        warn_stderr(single)
    model.save(args.out)  # atomic: a failed save leaves an earlier model file intact
    print(f"trained on {len(train)} demos of {', '.join(ds.tasks)} in {time.perf_counter() - t0:.2f} s")
    print(
        f"noise ratio {model.noise_ratio_:g}; groups coupled to the robot: "
        f"{', '.join(model.coupled_groups_) or 'none (the prediction is the prior)'}"
    )
    print(f"wrote {args.out}")
    return 0


def add_tasks(args: argparse.Namespace) -> int:
    """``--add-task DIR --model M``: every task of DIR added to the model in turn (its other tasks
    kept as trained), saved to ``--out``."""
    from ..data import skeleton_frames
    from ..exceptions import PipelineError
    from ..promp import IProMP
    from ..robot import load_robot

    if args.add_task is None or args.model is None:
        raise PipelineError("command line: field 'add-task': give both --add-task DIR and --model MODEL")
    if args.dataset is not None:
        raise PipelineError(
            f"command line: field 'dataset': {args.dataset} with --add-task: the new tasks' demos are in DIR"
        )
    model = IProMP.load(args.model)
    had_novelty = model.fitted_.novelty is not None
    robot = load_robot(args.robot)
    args.dataset = args.add_task
    ds = read_dataset(args, skeleton_frames(model.observe_) or None, robot)
    t0 = time.perf_counter()
    for task in ds.tasks:
        model.add_task(ds.demos[task])
        print(f"added task {task} from {len(ds.demos[task])} demos")
    model.save(args.out)  # atomic: a failed save leaves an earlier model file intact
    print(
        f"the model has {len(model.tasks_)} tasks ({', '.join(model.tasks_)}), "
        f"{len(model.fitted_.added_tasks)} added after its training; {time.perf_counter() - t0:.2f} s"
    )
    if had_novelty and model.fitted_.novelty is None:
        print("note: the model has no open-set recognition now (too few demos of an added task)")
    print(f"wrote {args.out}")
    return 0


def human_self_check(train: list[Demo], robot: Robot) -> dict | None:
    """The self-check (and calibration) of the training demos' body model
    (:func:`~ipromp_pin.human.fit.self_check`), printed; its JSON object for the model file, or
    None when no training demo has a tracked skeleton (printed as not measured)."""
    from ..human.fit import self_check

    found = self_check(train, robot)
    if found is None:
        print("human model self-check: not measured (no training demo has a tracked skeleton)")
        return None
    for line in found.summary():
        print(line)
    return found.to_json()


def held_out_demos(ds: Dataset, specs: list[str]) -> list[Demo]:
    """The demos ``--holdout TASK/DEMO`` names (index in its task or name); a one-line error
    (:class:`~ipromp_pin.exceptions.PipelineError`) for an unknown task or demo."""
    from ..exceptions import PipelineError

    out = []
    for spec in specs:
        task, sep, which = spec.partition("/")
        if not sep or task not in ds.demos:
            raise PipelineError(
                f"command line: field 'holdout': {spec!r} is not TASK/DEMO of a task ({', '.join(ds.tasks)})"
            )
        demos = ds.demos[task]
        names = [d.name for d in demos]
        if which in names:
            out.append(demos[names.index(which)])
        elif which.lstrip("-").isdigit() and -len(demos) <= int(which) < len(demos):
            out.append(demos[int(which)])
        else:
            raise PipelineError(
                f"command line: field 'holdout': task '{task}' has no demo {which!r} "
                f"({len(demos)} demos: index 0-{len(demos) - 1} or a name such as {names[0]!r})"
            )
    return out
