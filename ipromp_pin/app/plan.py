"""``ipromp-pin plan MODEL RECORDING... --out DIR``: a trained model plans the recordings a user brings.

Every RECORDING (a file or a folder of recordings, any supported format, no task label) is read,
its observed window cut, the task recognised and the robot's motion planned, checked, timed and
written into a sub-folder of DIR (:mod:`ipromp_pin.plans.batch`), with ``summary.json`` and
``summary.csv`` beside them (:mod:`ipromp_pin.plans.summary`). One line per recording as it is done
(also in logs, without a terminal). Exit status: 0 every recording planned and passed, 3 some failed
their checks or matched none of the model's tasks, 2 some could not be read (one line each on standard
error) or bad arguments.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from .arguments import add_strict_human, bounded
from .progress import EXIT_CHECKS_FAILED, EXIT_ERROR, print_error

if TYPE_CHECKING:
    from ..plans.batch import PlannedRecording, PlanOptions


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``plan`` command to ``subparsers``."""
    p = subparsers.add_parser(
        "plan",
        help="plan the robot's hand-over for new recordings with a trained model (one sub-folder each)",
        description="Plan, check and time the robot's part of the hand-over each recording starts, "
        "with a model trained by 'ipromp-pin train'. Each recording gets a sub-folder of --out with "
        "its trajectory, bags and report; summary.json and summary.csv list them all.",
    )
    p.add_argument("model", type=Path, help="model file (.npz) written by 'ipromp-pin train'")
    p.add_argument(
        "recordings",
        nargs="+",
        metavar="RECORDING",
        help="a recording (multiModal_states.csv, .bag, rosbag2 folder or .mcap/.db3, native .npz/.csv, "
        "a chen2017 export's stamp) or a folder of recordings",
    )
    p.add_argument("--out", type=Path, required=True, help="output folder: one sub-folder per recording")
    window = p.add_mutually_exclusive_group()
    window.add_argument(
        "--until-s",
        type=bounded(float, 0.0, 600.0, open_low=True),
        metavar="S",
        help="observe the first S seconds of each recording (default: 20%% of the model's nominal "
        "duration, the mean length of its training demos)",
    )
    window.add_argument(
        "--ratio",
        type=bounded(float, 0.0, 1.0, open_low=True),
        help="observe this fraction of each recording's own length, in (0, 1] (offline only: the "
        "length is known once the motion is over; the paper's protocol)",
    )
    p.add_argument(
        "--robot",
        help="robot settings file or shipped name (default baxter_left; a model of gripper poses needs one)",
    )
    p.add_argument(
        "--objects",
        type=Path,
        help="task file of the objects the gripper holds (default: the shipped robots/objects.toml)",
    )
    p.add_argument("--frames", help="comma-separated skeleton frames to read, e.g. /left_hand_1")
    p.add_argument(
        "--rate",
        type=bounded(float, 1.0, 1000.0),
        default=100.0,
        help="output control rate in [Hz] (default 100)",
    )
    p.add_argument("--preview", action="store_true", help="also write each recording's preview.html")
    p.add_argument(
        "--ros", type=int, choices=[1, 2], default=2, help="ROS version of trajectory.json (default 2)"
    )
    p.add_argument("--no-rosbag", action="store_true", help="do not write the rosbag2 folders rosbag/ (MCAP)")
    p.add_argument("--ros1-bag", action="store_true", help="also write run.bag (ROS 1) per recording")
    p.add_argument("--no-retreat", action="store_true", help="do not plan the retreat after the hand-over")
    p.add_argument(
        "--no-score",
        action="store_true",
        help="do not score a plan against the rest of its recording (by default, a recording that goes "
        "on past the window and holds the robot is scored: the hand-over error at its end)",
    )
    p.add_argument(
        "--allow-failing-checks",
        action="store_true",
        help="write the trajectory files of a plan that fails its checks, marked as failing "
        "(exit status 3 still)",
    )
    p.add_argument(
        "--jobs",
        type=bounded(int, 1, 1024),
        default=1,
        help="worker processes (default 1); the outputs are the same",
    )
    p.add_argument(
        "--cluster",
        metavar="CLUSTER",
        help="plan on a Dask cluster instead of --jobs processes: dask-local:N or a scheduler address "
        "such as tcp://HOST:8786 (needs pip install 'ipromp_pin[dask]')",
    )
    add_strict_human(p)
    p.set_defaults(func=main)


@dataclass
class PlanOutcome:
    """What a ``plan`` command did.

    Attributes:
        rows: One summary line per recording, in the order given.
        summary: The summary files written (``summary.json``, ``summary.csv``).
    """

    rows: list[PlannedRecording]
    summary: dict[str, Path]

    @property
    def exit_status(self) -> int:
        """2 when a recording could not be read, else 3 when one failed its checks, else 0."""
        statuses = {r.status for r in self.rows}
        if "unreadable" in statuses:
            return EXIT_ERROR
        return EXIT_CHECKS_FAILED if "failed" in statuses else 0


def main(args: argparse.Namespace) -> int:
    """Plan every recording; the exit status of :attr:`PlanOutcome.exit_status`."""
    from ..data import ObservationWindow, parse_groups
    from ..plans.batch import PlanOptions

    options = PlanOptions(
        window=ObservationWindow(until_s=args.until_s, ratio=args.ratio),
        frames=tuple(parse_groups(args.frames)) if args.frames else None,
        control_rate_hz=args.rate,
        retreat=not args.no_retreat,
        score=not args.no_score,
        preview=args.preview,
        ros=args.ros,
        rosbag=not args.no_rosbag,
        ros1_bag=args.ros1_bag,
        allow_failing_checks=args.allow_failing_checks,
    )
    outcome = run(
        args.model, args.recordings, args.out, options, robot=args.robot, objects=args.objects,
        jobs=args.jobs, cluster=args.cluster, log=lambda line: print(line, flush=True),
        strict_human=args.strict_human,
    )  # fmt: skip
    for row in outcome.rows:
        if row.status == "unreadable" or row.known is False:
            print_error("plan", f"{row.recording}: {row.error}" if row.known is False else str(row.error))
    failed = [r for r in outcome.rows if r.status == "failed"]
    if failed:
        print_error(
            "plan",
            f"{len(failed)} of {len(outcome.rows)} recordings failed their checks "
            f"(see {outcome.summary['summary.csv']})",
        )
    return outcome.exit_status


def run(
    model_path: Path,
    recordings: list[str],
    out_dir: Path,
    options: PlanOptions,
    *,
    robot: str | Path | None = None,
    objects: Path | None = None,
    jobs: int = 1,
    cluster: str | None = None,
    log=print,
    strict_human: bool = False,
) -> PlanOutcome:
    """Plan ``recordings`` with the model at ``model_path`` into ``out_dir`` (see the module docstring);
    ``log``: one line per recording as it is done (flushed: the command's lines reach a log file as
    they are printed, e.g. under nohup or SLURM); ``strict_human``: refuse a model whose human model
    is known not to fit its training demonstrations (:mod:`.human_fit`), else warn."""
    from .. import atomic
    from ..evaluation.dask_cluster import DaskCluster
    from ..planning.one_shot import check_model_joints
    from ..planning.transfer import arm_for, source_robot
    from ..plans.batch import PlanWorker, batch_jobs, plan_batch
    from ..plans.summary import counts, write_summary
    from ..plans.warnings import warn_stderr
    from ..promp import IProMP
    from ..robot import Robot, load_robot
    from ..robot.objects import load_objects
    from .human_fit import check_human_fit

    t0 = time.perf_counter()
    # a bad spec fails here, before any work; the cluster says when it has started
    runner = None if cluster is None else DaskCluster.from_spec(cluster, log=log)
    atomic.check_output_dir(out_dir)
    model = IProMP.load(model_path)
    named = arm_for(model, robot, "--robot NAME")  # a model of gripper poses names no arm itself
    arm = named if isinstance(named, Robot) else load_robot(named)
    check_model_joints(model, source_robot(model, arm) or arm)  # a placed arm takes its source's model
    check_human_fit(model, str(model_path), strict_human, warn_stderr)
    table = load_objects(objects)
    work = batch_jobs(recordings, out_dir)
    worker = PlanWorker(model, arm, table, options)
    nominal = float(model.duration_nominal_s_)
    log(
        f"[plan] {len(work)} recording{'s' * (len(work) != 1)}, {options.window.text(nominal)}, "
        f"model {model_path} ({', '.join(model.tasks_)}), robot {arm.settings.name}, "
        + (
            f"on the Dask cluster {runner.label}"
            if runner is not None
            else f"{jobs} process{'es' * (jobs > 1)}"
        )
    )

    def progress(done: int, total: int, row: PlannedRecording) -> None:
        log(f"[{done}/{total}] {row.line()}")

    rows = plan_batch(worker, work, runner if runner is not None else jobs, progress)
    about = {
        "model": str(model_path),
        "robot": arm.settings.name,
        "window": options.window.text(nominal),
    }
    summary = write_summary(out_dir, rows, about)
    n = counts(rows)
    log(
        f"[plan] {n['passed']} passed, {n['failed']} failed, {n['unreadable']} not planned "
        f"in {time.perf_counter() - t0:.1f} s; summary: {summary['summary.csv']}"
    )
    return PlanOutcome(rows, summary)
