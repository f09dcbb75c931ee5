"""Command line: ``ipromp-pin run | replay | evaluate | train | preview | calibrate | synth``.

Stable interface (people script against it)::

    ipromp-pin run PIPELINE [--out DIR] [--dataset PATH] [--task T] [--demo I] [--ratio R] ...
    ipromp-pin replay PIPELINE [--dataset D --task T --demo I] --out DIR [--start-ratio R] [--limits L]
    ipromp-pin evaluate DATASET --protocol paper|splits --observe GROUPS --json FILE [--closed-loop]

Errors of the user's input exit with status 2 and a one-line message naming
the file, field and problem; no traceback.

Each command imports the modules it runs when it runs (the scientific stack takes a second or
two to import), so that ``--help`` and argument errors answer at once.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from .data import parse_groups, skeleton_frames
from .exceptions import IPrompPinError


def _progress():
    """A progress callable printing ``[done/total] label  elapsed`` on standard error."""
    t0 = time.perf_counter()

    def show(done: int, total: int, label: str) -> None:
        stream = sys.stderr
        stream.write(f"\r[{done}/{total}] {label}  ({time.perf_counter() - t0:.0f} s)\033[K")
        if done == total:
            stream.write("\n")
        stream.flush()

    return show


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
        p.add_argument("--ratio", type=float, help="observed fraction of the motion, in (0, 1] (default 0.2)")
    p.add_argument("--model", type=Path, help="use this saved model instead of training")
    p.add_argument("--save-model", type=Path, help="save the trained model here")
    p.add_argument("--robot", help="robot settings file or shipped name (default: the pipeline's)")
    p.add_argument("--rate", type=float, help="output control rate in [Hz] (default 100)")


def _pipeline_config(args: argparse.Namespace):
    from .config import load_pipeline

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
        robot=args.robot,
        control_rate_hz=args.rate,
        preview_html=False if getattr(args, "no_preview", False) else None,
        plots=True if getattr(args, "plots", False) else None,
    )


def cmd_run(args: argparse.Namespace) -> int:
    from .pipeline import run_pipeline

    cfg = _pipeline_config(args)
    run_pipeline(cfg, log=print)
    return 0


def _closed_loop_settings(args: argparse.Namespace, control_rate_hz: float, start_ratio: float):
    """The closed-loop settings of the command line (validated: one-line errors naming the option)."""
    from .closed_loop import ClosedLoopSettings

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
    from .closed_loop import ClosedLoopSettings
    from .replay import run_replay

    cfg = _pipeline_config(args)
    start = ClosedLoopSettings().start_ratio if args.start_ratio is None else args.start_ratio
    settings = _closed_loop_settings(args, cfg.control_rate_hz, start)
    run_replay(cfg, settings, limits=args.limits, preview=not args.no_preview, log=print)
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    from .evaluate import PAPER_GRID, EvaluationConfig, evaluate, overall, to_markdown, write_results
    from .readers import load_dataset
    from .robot import load_robot_settings

    if args.closed_loop:
        return _evaluate_closed_loop(args)
    observe = [parse_groups(o) for o in (args.observe or ["orientation", "orientation,emg"])]
    frames = skeleton_frames(g for o in observe for g in o) or None
    joints = load_robot_settings(args.robot).recorded_arm_joints
    t0 = time.perf_counter()
    ds = load_dataset(
        args.dataset, format=args.format, frames=frames, robot_joints=joints, progress=_progress()
    )
    print(f"read {len(ds.all_demos())} demos of {', '.join(ds.tasks)} in {time.perf_counter() - t0:.1f} s")
    if args.grid == "paper":
        grid = list(PAPER_GRID)
    else:
        grid = [(n, r) for n in args.n_train for r in args.ratios]
    protocols = ["paper", "splits"] if args.protocol == "both" else [args.protocol]
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
        cells += evaluate(ds, cfg, robot=args.robot, progress=_progress(), jobs=args.jobs)
        print(f"protocol {protocol}: {time.perf_counter() - t1:.1f} s")
    print(to_markdown(cells))
    meta = {
        "dataset": str(args.dataset),
        "command": " ".join(["ipromp-pin", *sys.argv[1:]]),
        "seconds": round(time.perf_counter() - t0, 2),
    }
    md = args.md or (args.json.with_suffix(".md") if args.json else None)
    write_results(cells, args.json, md, meta)
    if args.plots:
        from . import plots

        args.plots.mkdir(parents=True, exist_ok=True)
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


def _evaluate_closed_loop(args: argparse.Namespace) -> int:
    from .closed_loop_eval import (
        ClosedLoopOptions,
        closed_loop_markdown,
        evaluate_closed_loop,
        write_closed_loop_results,
    )
    from .evaluate import PAPER_GRID, EvaluationConfig
    from .readers import load_dataset
    from .replay import check_limits_choice
    from .robot import load_robot, load_robot_settings

    observe = [parse_groups(o) for o in (args.observe or ["orientation", "orientation,emg"])]
    grid = list(PAPER_GRID) if args.grid == "paper" else [(n, r) for n in args.n_train for r in args.ratios]
    for _, ratio in grid:  # every cell's obs_ratio is a start ratio: checked before any computation
        _closed_loop_settings(args, 100.0, ratio)
    settings = _closed_loop_settings(args, 100.0, grid[0][1])
    check_limits_choice(args.limits, load_robot(args.robot), "command line")
    frames = skeleton_frames(g for o in observe for g in o) or None
    joints = load_robot_settings(args.robot).recorded_arm_joints
    t0 = time.perf_counter()
    ds = load_dataset(
        args.dataset, format=args.format, frames=frames, robot_joints=joints, progress=_progress()
    )
    print(f"read {len(ds.all_demos())} demos of {', '.join(ds.tasks)} in {time.perf_counter() - t0:.1f} s")
    protocols = ["paper", "splits"] if args.protocol == "both" else [args.protocol]
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
    md = args.md or (args.json.with_suffix(".md") if args.json else None)
    write_closed_loop_results(cells, args.json, md, meta)
    if args.json:
        print(f"wrote {args.json}" + (f" and {md}" if md else ""))
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    from .promp import IProMP
    from .readers import load_dataset

    observe = parse_groups(args.observe)
    frames = skeleton_frames(observe) or None
    ds = load_dataset(args.dataset, format=args.format, frames=frames, progress=_progress())
    t0 = time.perf_counter()
    coupling = args.coupling if args.coupling in ("auto", "all") else parse_groups(args.coupling)
    model = IProMP(observe=observe, coupling=coupling).fit(ds.all_demos())
    model.save(args.out)
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
    from .calibrate import run_calibration

    run_calibration(args.dataset, args.robot, write=args.write)
    return 0


def cmd_synth(args: argparse.Namespace) -> int:
    from .readers.native import write_demo
    from .synthetic import make_synthetic_dataset

    ds = make_synthetic_dataset(n_tasks=args.tasks, n_demos=args.demos, seed=args.seed)
    n = 0
    for task, demos in ds.demos.items():
        for d in demos:
            write_demo(d, args.out / task / f"{d.name}.npz")
            n += 1
    print(f"wrote {n} demos of {', '.join(ds.tasks)} into {args.out}")
    return 0


def cmd_preview(args: argparse.Namespace) -> int:
    from .pipeline import run_preview

    run_preview(
        _pipeline_config(args), html=args.html, port=args.port, speed=args.speed, wait=not args.no_wait
    )
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``ipromp-pin``."""
    parser = argparse.ArgumentParser(
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
    p.set_defaults(func=cmd_run)

    p = sub.add_parser(
        "replay",
        help="replay a held-out demo in the closed loop: the robot starts early and re-plans as the "
        "human moves",
    )
    _add_pipeline_overrides(p, ratio=False)
    p.add_argument(
        "--start-ratio",
        type=float,
        help="fraction of the human's motion observed before the robot starts, in (0, 1) (default 0.2)",
    )
    _add_closed_loop_options(p)
    p.add_argument("--no-preview", action="store_true", help="do not write preview.html")
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("evaluate", help="recognition accuracy and prediction error on a dataset")
    p.add_argument("dataset", type=Path, help="dataset folder (one sub-folder per task)")
    p.add_argument("--protocol", choices=["paper", "splits", "both"], default="paper")
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
    p.add_argument("--n-train", type=int, nargs="+", default=[10, 15, 20])
    p.add_argument("--ratios", type=float, nargs="+", default=[0.1, 0.2])
    p.add_argument("--n-test", type=int, default=10, help="test demos per task (default 10)")
    p.add_argument("--splits", type=int, default=20, help="random splits of the splits protocol (default 20)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--robot", default="baxter_left", help="robot settings for the hand-over error")
    p.add_argument(
        "--jobs", type=int, default=os.cpu_count() or 1, help="worker processes (default: all cores)"
    )
    p.add_argument("--plots", type=Path, help="write PNG figures into this folder")
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
        "--coupling",
        default="auto",
        help="observed groups that predict the robot: auto (cross-validated), all, or a comma-separated list",
    )
    p.set_defaults(func=cmd_train)

    p = sub.add_parser("preview", help="meshcat preview: live on 127.0.0.1, or a self-contained HTML file")
    _add_pipeline_overrides(p)
    p.add_argument("--html", type=Path, help="write a self-contained HTML file instead of serving live")
    p.add_argument("--port", type=int, default=7000, help="live server port on 127.0.0.1 (default 7000)")
    p.add_argument("--speed", type=float, default=1.0, help="live streaming speed factor (default real time)")
    p.add_argument("--no-wait", action="store_true", help="live: exit when streaming is done")
    p.set_defaults(func=cmd_preview)

    p = sub.add_parser("calibrate", help="calibrate FK (arm mount) against the robot's own end-point reports")
    p.add_argument("dataset", type=Path, nargs="+")
    p.add_argument("--robot", default="baxter_left")
    p.add_argument("--write", action="store_true", help="store the offset in the robot settings file")
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser("synth", help="write the built-in synthetic demos in the native format")
    p.add_argument("out", type=Path)
    p.add_argument("--tasks", type=int, default=3)
    p.add_argument("--demos", type=int, default=20)
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=cmd_synth)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``ipromp-pin`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except IPrompPinError as exc:
        print(f"ipromp-pin {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
