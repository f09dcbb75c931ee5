"""Command line: ``ipromp-pin run | replay | evaluate | train | preview | calibrate | synth``.

Stable interface (people script against it)::

    ipromp-pin run PIPELINE [--out DIR] [--dataset PATH] [--task T] [--demo I] [--ratio R] ...
    ipromp-pin replay PIPELINE [--dataset D --task T --demo I] --out DIR [--start-ratio R] [--limits L]
    ipromp-pin evaluate DATASET --protocol paper|splits --observe GROUPS --json FILE [--closed-loop]

Errors of the user's input exit with status 2 and a one-line message naming
the file, field and problem; no traceback. ``run`` exits with status 3 when the
planned motion fails its checks (it then writes no trajectory file unless
``--allow-failing-checks``). Progress lines are shown on a terminal only.

Each command imports the modules it runs when it runs (the scientific stack takes a second or
two to import), so that ``--help`` and argument errors answer at once.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from functools import partial
from pathlib import Path
from typing import NoReturn

from .data import parse_groups, skeleton_frames
from .exceptions import IPrompPinError

EXIT_ERROR = 2
"""Exit status of a user error (bad input, unwritable output): one line on standard error."""

EXIT_CHECKS_FAILED = 3
"""Exit status of ``run`` when the planned motion fails a required check or its timing verification."""


class _ProgressLine:
    """Progress ``[done/total] label  elapsed`` rewritten in place on standard error, on a terminal
    only (to a file or a pipe it would be a stream of carriage returns). :meth:`end` finishes an
    unfinished line, so that an error message starts on a line of its own."""

    open_line = False

    def __init__(self) -> None:
        self.t0 = time.perf_counter()
        self.tty = sys.stderr.isatty()

    def __call__(self, done: int, total: int, label: str) -> None:
        if not self.tty:
            return
        stream = sys.stderr
        stream.write(f"\r[{done}/{total}] {label}  ({time.perf_counter() - self.t0:.0f} s)\033[K")
        _ProgressLine.open_line = done != total
        if done == total:
            stream.write("\n")
        stream.flush()

    @staticmethod
    def end() -> None:
        if _ProgressLine.open_line:
            sys.stderr.write("\n")
            sys.stderr.flush()
            _ProgressLine.open_line = False


def _progress() -> _ProgressLine:
    """A progress callable (see :class:`_ProgressLine`)."""
    return _ProgressLine()


def _read_dataset(args: argparse.Namespace, frames, robot, timed: bool = False):
    """The dataset ``args.dataset`` (``args.format``), its arm joints and limits those of ``robot``,
    with a progress line (and, when ``timed``, a line saying what was read in how long)."""
    from .readers import load_dataset

    t0 = time.perf_counter()
    ds = load_dataset(
        args.dataset,
        format=args.format,
        frames=frames,
        robot_joints=robot.settings.recorded_arm_joints,
        joint_limits=robot.recorded_joint_limits(),
        progress=_progress(),
    )
    if timed:
        print(
            f"read {len(ds.all_demos())} demos of {', '.join(ds.tasks)} in {time.perf_counter() - t0:.1f} s"
        )
    return ds


def _port(text: str) -> int:
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a port number: {text!r}") from None
    if not 1 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"port {port} is outside 1-65535")
    return port


def _bounded(kind: type, low: float, high: float | None = None, *, open_low: bool = False):
    """An argparse type: a finite ``kind`` number in [low, high] (``(low, high]`` with ``open_low``)."""

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        ok = math.isfinite(value) and (value > low if open_low else value >= low)
        if not ok or (high is not None and value > high):
            lo = f"({low:g}" if open_low else f"[{low:g}"
            raise argparse.ArgumentTypeError(
                f"{value!r} is outside {lo}, {'inf' if high is None else f'{high:g}'}]"
            )
        return value

    return parse


def default_jobs() -> int:
    """Default ``evaluate --jobs``: every core but one (at least 1), so that the machine stays usable."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return max(1, cores - 1)


def _add_pipeline_overrides(p: argparse.ArgumentParser, ratio: bool = True) -> None:
    p.add_argument(
        "pipeline",
        type=Path,
        help="pipeline definition (TOML), e.g. pipelines/baxter_handover.toml, or the name of a shipped one, "
        "e.g. baxter_handover (used when no file of that name is in the current folder)",
    )
    p.add_argument("--out", type=Path, help="output folder (default: the pipeline's outputs.dir)")
    p.add_argument("--dataset", type=Path, help="dataset folder (default: built-in synthetic demos)")
    p.add_argument("--format", help="dataset format: auto, chen2017, multimodal, bag, native")
    p.add_argument("--frames", help="comma-separated skeleton frames to read, e.g. /left_hand_1")
    p.add_argument("--observe", help="comma-separated observed groups, e.g. orientation,emg")
    p.add_argument("--task", help="task of the demo to observe (default: the first task)")
    p.add_argument(
        "--demo", type=int, help="index of the demo in its task, held out of training (default -1)"
    )
    if ratio:
        p.add_argument(
            "--ratio",
            type=_bounded(float, 0.0, 1.0, open_low=True),
            help="observed fraction of the motion, in (0, 1] (default 0.2)",
        )
    p.add_argument("--model", type=Path, help="use this saved model instead of training")
    p.add_argument("--save-model", type=Path, help="save the trained model here")
    p.add_argument(
        "--retrain",
        action="store_true",
        help="train even if an earlier run trained a model on the same demos and settings",
    )
    p.add_argument("--robot", help="robot settings file or shipped name (default: the pipeline's)")
    p.add_argument("--rate", type=float, help="output control rate in [Hz], in [1, 1000] (default 100)")


def _pipeline_config(args: argparse.Namespace):
    from .commands.config import load_pipeline

    return load_pipeline(
        args.pipeline,
        out_dir=args.out,
        dataset=args.dataset,
        format=args.format,
        frames=parse_groups(args.frames) if args.frames else None,
        observe=parse_groups(args.observe) if args.observe else None,
        task=args.task,
        demo=args.demo,
        ratio=getattr(args, "ratio", None),
        load_model=args.model,
        save_model=args.save_model,
        model_cache=False if getattr(args, "retrain", False) else None,
        robot=args.robot,
        control_rate_hz=args.rate,
        preview_html=False if getattr(args, "no_preview", False) else None,
        plots=True if getattr(args, "plots", False) else None,
        ros=getattr(args, "ros", None),
        rosbag=False if getattr(args, "no_rosbag", False) else None,
        ros1_bag=True if getattr(args, "ros1_bag", False) else None,
    )


def cmd_run(args: argparse.Namespace) -> int:
    from .commands.run import run_pipeline

    cfg = _pipeline_config(args)
    report = run_pipeline(cfg, log=print, allow_failing_checks=args.allow_failing_checks)
    if report["passed"]:
        return 0
    failures = list(report["feasibility"]["failures"])
    if not report["trajectory"]["passed"]:
        failures.append("timing")
    written = "written marked as failing" if "trajectory_csv" in report["files"] else "not written"
    _error("run", f"the planned motion failed its checks ({', '.join(failures)}); trajectory {written}")
    return EXIT_CHECKS_FAILED


def _closed_loop_settings(args: argparse.Namespace, control_rate_hz: float, start_ratio: float):
    """The closed-loop settings of the command line (validated: one-line errors naming the option)."""
    from .handover.closed_loop import ClosedLoopSettings

    defaults = ClosedLoopSettings()
    noise = defaults.condition_noise
    if args.condition_noise is not None:
        try:
            noise = None if args.condition_noise == "model" else float(args.condition_noise)
        except ValueError:
            noise = args.condition_noise  # validate() names the field
    return ClosedLoopSettings(
        start_ratio=start_ratio,
        replan_rate_hz=defaults.replan_rate_hz if args.replan_rate is None else args.replan_rate,
        control_rate_hz=control_rate_hz,
        blend_s=defaults.blend_s if args.blend is None else args.blend,
        freeze_phase=defaults.freeze_phase if args.freeze_phase is None else args.freeze_phase,
        condition_noise=noise,
    ).validate("command line")


def _add_closed_loop_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--limits",
        default="demonstrated",
        help="limit profile: demonstrated (from the training demos, default), conservative (robot settings) "
        "or a profile file (TOML, e.g. a replay's limits.toml)",
    )
    p.add_argument(
        "--condition-noise",
        default=None,
        help="noise ratio with which the closed loop conditions the robot trajectory: a positive number, "
        "or model for the model's own (default 0.3, chosen by cross-validation of the closed loop)",
    )
    p.add_argument("--replan-rate", type=float, help="re-plan rate in [Hz] (default 20)")
    p.add_argument("--blend", type=float, help="blend horizon in [s] of a re-plan (default 0.2)")
    p.add_argument(
        "--freeze-phase",
        type=float,
        help="stop re-planning once this fraction of the predicted motion is observed, in (0, 1] "
        "(default 0.9)",
    )


def cmd_replay(args: argparse.Namespace) -> int:
    from .commands.replay import run_replay
    from .handover.closed_loop import ClosedLoopSettings

    cfg = _pipeline_config(args)
    start = ClosedLoopSettings().start_ratio if args.start_ratio is None else args.start_ratio
    settings = _closed_loop_settings(args, cfg.control_rate_hz, start)
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
    written = "written marked as failing" if "trajectory_csv" in outcome.files else "not written"
    _error(
        "replay",
        f"the commanded motion failed its checks ({outcome.score.collisions} samples in collision, "
        f"max limit ratio {outcome.score.max_limit_ratio:.3f}); trajectory {written}",
    )
    return EXIT_CHECKS_FAILED


def cmd_evaluate(args: argparse.Namespace) -> int:
    from . import atomic
    from .evaluation.evaluate import (
        PAPER_GRID,
        EvaluationConfig,
        check_dataset_size,
        evaluate,
        overall,
        to_markdown,
        write_results,
    )
    from .readers import count_demos
    from .robot import load_robot

    if args.closed_loop:
        return _evaluate_closed_loop(args)
    observe = [parse_groups(o) for o in (args.observe or ["orientation", "orientation,emg"])]
    if args.baselines:
        from .evaluation.baselines import require_sklearn

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
    ds = _read_dataset(args, frames, robot, timed=True)
    _compile_kernels_once()
    cells = []
    for cfg in configs:
        protocol = cfg.protocol
        t1 = time.perf_counter()
        cells += evaluate(ds, cfg, robot=args.robot, progress=_progress(), jobs=args.jobs)
        print(f"protocol {protocol}: {time.perf_counter() - t1:.1f} s")
    print(to_markdown(cells))
    meta = {
        "dataset": str(args.dataset),
        "command": " ".join(["ipromp-pin", *sys.argv[1:]]),
        "seconds": round(time.perf_counter() - t0, 2),
    }
    write_results(cells, args.json, md, meta)
    if args.plots:
        from .outputs import plots

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


def _compile_kernels_once() -> None:
    """Compile the numba kernels in this process (announced) before worker processes are forked,
    which then inherit them, instead of each worker compiling its own copy."""
    from .promp.compiled import compiled_kernels_cached, kernel_backend, numba_kernels
    from .promp.warmup import compile_kernels

    if kernel_backend() == "numba" and not compiled_kernels_cached():
        numba_kernels()  # announces the compile
        try:
            compile_kernels()
        except RuntimeError:  # compiled but not cached (read-only cache): the workers compile again
            pass


def _evaluate_closed_loop(args: argparse.Namespace) -> int:
    from . import atomic
    from .commands.replay import check_limits_choice
    from .evaluation.closed_loop import (
        ClosedLoopOptions,
        closed_loop_markdown,
        evaluate_closed_loop,
        write_closed_loop_results,
    )
    from .evaluation.evaluate import PAPER_GRID, EvaluationConfig, check_dataset_size
    from .readers import count_demos
    from .robot import load_robot

    observe = [parse_groups(o) for o in (args.observe or ["orientation", "orientation,emg"])]
    grid = list(PAPER_GRID) if args.grid == "paper" else [(n, r) for n in args.n_train for r in args.ratios]
    for _, ratio in grid:  # every cell's obs_ratio is a start ratio: checked before any computation
        _closed_loop_settings(args, 100.0, ratio)
    settings = _closed_loop_settings(args, 100.0, grid[0][1])
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
    ds = _read_dataset(args, frames, robot, timed=True)
    _compile_kernels_once()
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
        cells += evaluate_closed_loop(
            ds, cfg, options, robot=args.robot, progress=_progress(), jobs=args.jobs
        )
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


def cmd_train(args: argparse.Namespace) -> int:
    from . import atomic
    from .commands.model_warnings import single_task_warning, warn_stderr
    from .promp import IProMP
    from .robot import ee_positions, load_robot

    atomic.check_output_file(args.out, "model file")
    observe = parse_groups(args.observe)
    coupling = args.coupling if args.coupling in ("auto", "all") else parse_groups(args.coupling)
    IProMP(observe=observe, coupling=coupling).check_params()  # before reading the data
    frames = skeleton_frames(observe) or None
    robot = load_robot(args.robot)
    ds = _read_dataset(args, frames, robot)
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


def cmd_calibrate(args: argparse.Namespace) -> int:
    from .commands.calibrate import run_calibration

    run_calibration(args.dataset, args.robot, write=args.write)
    return 0


def cmd_synth(args: argparse.Namespace) -> int:
    from . import atomic
    from .readers.native import write_demo
    from .readers.synthetic import make_synthetic_dataset

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


def cmd_preview(args: argparse.Namespace) -> int:
    from . import atomic
    from .commands.preview import run_preview

    if args.html is not None:
        atomic.check_output_file(args.html, "preview page")
    run_preview(
        _pipeline_config(args), html=args.html, port=args.port, speed=args.speed, wait=not args.no_wait
    )
    return 0


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (exit status 2), like every other input error."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``ipromp-pin``."""
    parser = _Parser(
        prog="ipromp-pin",
        description="EMG-augmented Interaction ProMPs: recognise a hand-over task, plan Baxter's part.",
    )
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser(
        "run", help="run a pipeline: observe -> recognise -> predict -> check -> time -> files"
    )
    _add_pipeline_overrides(p)
    p.add_argument("--no-preview", action="store_true", help="do not write preview.html")
    p.add_argument("--plots", action="store_true", help="also write PNG figures")
    p.add_argument(
        "--ros",
        type=int,
        choices=[1, 2],
        help="ROS version of trajectory.json's JointTrajectory: 2 = ROS 2 field names (default), 1 = ROS 1",
    )
    p.add_argument("--no-rosbag", action="store_true", help="do not write the rosbag2 folder rosbag/ (MCAP)")
    p.add_argument(
        "--ros1-bag", action="store_true", help="also write run.bag (ROS 1) with the same messages"
    )
    p.add_argument(
        "--allow-failing-checks",
        action="store_true",
        help="write the trajectory files even when the checks fail, marked as failing (exit status 3 still)",
    )
    p.set_defaults(func=cmd_run)

    p = sub.add_parser(
        "replay",
        help="replay a held-out demo in the closed loop: the robot starts early and re-plans as the "
        "human moves",
    )
    _add_pipeline_overrides(p, ratio=False)
    p.add_argument(
        "--start-ratio",
        type=float,  # checked with the other closed-loop settings (one line naming start_ratio)
        help="fraction of the human's motion observed before the robot starts, in (0, 1) (default 0.2)",
    )
    _add_closed_loop_options(p)
    p.add_argument("--no-preview", action="store_true", help="do not write preview.html")
    p.add_argument(
        "--allow-failing-checks",
        action="store_true",
        help="write the commanded trajectory even when it collides or exceeds the limits, marked as "
        "failing (exit status 3 still)",
    )
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("evaluate", help="recognition accuracy and prediction error on a dataset")
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
    p.add_argument("--format", default="auto", help="dataset format (default auto)")
    p.add_argument(
        "--grid", choices=["paper", "full"], default="paper", help="paper's 4 cells or --n-train x --ratios"
    )
    p.add_argument(
        "--n-train",
        type=_bounded(int, 2),
        nargs="+",
        default=[10, 15, 20],
        help="training demos per task (--grid full)",
    )
    p.add_argument(
        "--ratios",
        type=_bounded(float, 0.0, 1.0, open_low=True),
        nargs="+",
        default=[0.1, 0.2],
        help="observed fractions (--grid full)",
    )
    p.add_argument("--n-test", type=_bounded(int, 1), default=10, help="test demos per task (default 10)")
    p.add_argument(
        "--splits",
        type=_bounded(int, 1),
        default=20,
        help="random splits of the splits protocol (default 20)",
    )
    p.add_argument("--seed", type=_bounded(int, 0), default=0)
    p.add_argument("--robot", default="baxter_left", help="robot settings for the hand-over error")
    p.add_argument(
        "--jobs",
        type=_bounded(int, 1, 1024),
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
    _add_closed_loop_options(p)
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("train", help="train a model on a dataset and save it")
    p.add_argument("dataset", type=Path)
    p.add_argument("--observe", default="orientation,emg")
    p.add_argument("--format", default="auto")
    p.add_argument("--out", type=Path, required=True, help="model file (.npz)")
    p.add_argument(
        "--robot",
        default="baxter_left",
        help="robot settings: the recorded joints of the robot group and their limits (default baxter_left)",
    )
    p.add_argument(
        "--coupling",
        default="auto",
        help="observed groups that predict the robot: auto (cross-validated), all, or a comma-separated list",
    )
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("preview", help="meshcat preview: live on 127.0.0.1, or a self-contained HTML file")
    _add_pipeline_overrides(p)
    p.add_argument("--html", type=Path, help="write a self-contained HTML file instead of serving live")
    p.add_argument(
        "--port", type=_port, default=7000, help="live server port on 127.0.0.1, 1-65535 (default 7000)"
    )
    p.add_argument(
        "--speed",
        type=_bounded(float, 0.0, 1e6, open_low=True),
        default=1.0,
        help="live streaming speed factor, > 0 (default 1: real time)",
    )
    p.add_argument("--no-wait", action="store_true", help="live: exit when streaming is done")
    p.set_defaults(func=cmd_preview)

    p = sub.add_parser("calibrate", help="calibrate FK (arm mount) against the robot's own end-point reports")
    p.add_argument("dataset", type=Path, nargs="+")
    p.add_argument("--robot", default="baxter_left")
    p.add_argument("--write", action="store_true", help="store the offset in the robot settings file")
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser("synth", help="write the built-in synthetic demos in the native format")
    p.add_argument("out", type=Path)
    p.add_argument("--tasks", type=_bounded(int, 1, 20), default=3, help="number of tasks, 1-20 (default 3)")
    p.add_argument(
        "--demos", type=_bounded(int, 2, 1000), default=20, help="demos per task, 2-1000 (default 20)"
    )
    p.add_argument("--seed", type=_bounded(int, 0), default=0)
    p.add_argument("--csv", action="store_true", help="write .csv files (one row per sample) instead of .npz")
    p.set_defaults(func=cmd_synth)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``ipromp-pin`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    # The kernels: for the short commands, the compiled ones when cached, else their numpy version
    # while they compile in the background (a fresh install's first run does not wait); the long
    # ones compile them first (announced). $IPROMP_PIN_KERNELS overrides.
    from .promp.compiled import BACKEND_ENV, set_announcer, set_kernel_backend

    short = args.command in ("run", "preview", "train", "synth")
    previous = set_kernel_backend(os.environ.get(BACKEND_ENV) or ("auto" if short else "numba"))
    set_announcer(lambda message: print(message, file=sys.stderr, flush=True))
    try:
        return int(args.func(args) or 0)
    except IPrompPinError as exc:
        _error(args.command, str(exc))
        return EXIT_ERROR
    except OSError as exc:  # a file the checks could not foresee (a full disk, a vanished folder)
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        _error(args.command, f"{where}{exc.strerror or exc}")
        return EXIT_ERROR
    except KeyboardInterrupt:
        _ProgressLine.end()
        print("interrupted", file=sys.stderr)
        return 130
    finally:
        set_kernel_backend(previous)
        set_announcer(None)


def console_main() -> None:
    """The ``ipromp-pin`` console script: :func:`main`, then a fast exit.

    After the command, the exit handlers run and the output is flushed, then the process ends without
    tearing down the interpreter's modules and objects one by one: that teardown does nothing a
    finished command needs and takes about 0.5 s of a 3 s run (measured with ``os._exit``). Every
    file the command writes is closed when it returns.
    """
    code = main()
    import atexit

    run_exit_handlers = getattr(atexit, "_run_exitfuncs", None)
    if run_exit_handlers is not None:
        run_exit_handlers()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def _error(command: str, message: str) -> None:
    """Print ``message`` as one line, starting on a line of its own (after an unfinished progress line)."""
    _ProgressLine.end()
    text = " ".join(message.split("\n"))
    print(f"ipromp-pin {command}: error: {text}", file=sys.stderr)


if __name__ == "__main__":
    console_main()
