"""An evaluation run from a typed request (:class:`EvaluateRequest`, what ``ipromp-pin evaluate``
builds), with the prologue every evaluation shares: outputs and settings checked, the dataset's size checked
from its file list, the dataset read once, the inference kernels compiled once (before the worker
processes fork), then every protocol run, printed and written.

The command line (:mod:`ipromp_pin.app.evaluate`) builds the request from its arguments, e.g.
``EvaluateRequest(dataset=args.dataset, grid=window_cells(grid_from(args.grid, args.n_train,
args.ratios), args.windows, args.window_s, args.window_of_train),
protocols=protocols_from(args.protocol), closed_loop_settings=<the --condition-noise ... options>,
command=" ".join(["ipromp-pin", *sys.argv[1:]]), progress=<a progress-line factory>, ...)``, and
calls :func:`run_evaluate`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any, cast

from .. import atomic, readers
from ..data import Dataset, skeleton_frames
from ..exceptions import DataError
from ..human.placement import check_assumed_human
from ..motion.limits import check_profile_choice
from ..planning.closed_loop import ClosedLoopSettings
from ..robot import Robot, load_robot
from ..robot.objects import load_objects
from ..robot.recordings import read_recordings
from ..shipped import DEFAULT_ROBOT
from .arm_plans import recordings_robot
from .baselines import require_sklearn
from .cells import Cell
from .closed_loop import ClosedLoopOptions, evaluate_closed_loop
from .config import PAPER_GRID, EvaluationConfig, ProgressFn
from .dask_cluster import DaskCluster, prepare_worker, require_dask
from .evaluate import evaluate
from .jobs import JobRunner
from .open_set import OpenSetCell, evaluate_open_set, open_set_json, open_set_markdown
from .splits import check_dataset_size
from .tables import (
    closed_loop_markdown,
    overall,
    paper_comparison,
    to_markdown,
    write_closed_loop_results,
    write_results,
)
from .windows import Window


@dataclass
class EvaluateRequest:
    """Everything an evaluation run needs (what ``ipromp-pin evaluate`` passes).

    Attributes:
        dataset: Dataset folder.
        format: Dataset format (``"auto"``, ...).
        observe: Observed channel sets, each a list of group names.
        grid: (n_train, window) cells: a window is a fraction of each test demo (a float) or a
            :class:`~.windows.Window` (:func:`window_cells` adds those in seconds to a grid).
        protocols: Protocols to run, in order (``"paper"``, ``"splits"``).
        n_test: Test demos per task.
        n_splits: Random splits (``splits`` protocol).
        seed: Seed of the random splits (and of the folds).
        n_folds: Folds of the ``folds`` protocol.
        run_folds: The folds it runs (0-based; None: all).
        robot: Robot settings (name or file). An arm with a ``[placement]`` executes the model of its
            source robot: the recordings are read with the source's joints, every test plan (one-shot)
            or re-plan (closed loop) retargeted to the arm, planned and checked there
            (:mod:`~.arm_plans`).
        arm_scores: Score the plans on the robot for an arm of its own model too: every one-shot
            trial planned (:class:`~.arm_plans.TrialPlanner`), every commanded trajectory
            re-evaluated (always for a placed arm).
        jobs: Worker processes.
        cluster: A Dask cluster to run the model fits on instead (``dask-local:N`` or a scheduler
            address such as ``tcp://HOST:8786``; :mod:`~ipromp_pin.evaluation.dask_cluster`).
        baselines: Also run the reference baselines (needs scikit-learn).
        closed_loop: Replay every test demo in the closed loop (``--closed-loop``).
        limits: Limit profile of the closed loop (``demonstrated``, ``conservative`` or a file).
        objects: Task file of the objects (``--objects``; None: the shipped ``robots/objects.toml``):
            the closed loop torque-checks every re-plan with them; both protocols score each cell's
            ``peak_torque_ratio`` (the one-shot plans' or the commanded motions', true task's object).
        closed_loop_settings: The closed loop's settings (each cell's window replaces the start:
            :func:`~.scorers.closed_loop.start_settings`; None: the defaults).
        json: JSON results file (None: not written).
        md: Markdown results file (None: beside the JSON, if any).
        plots: Folder of the accuracy plot (one-shot evaluation; None: no plot).
        alpha: The open-set protocol's largest fraction of known-task observations refused.
        command: The command line, recorded in the JSON's ``meta``.
        progress: Makes a progress callable ``(done, total, label)`` (None: no progress).
        log: Prints a line of the run's report.
    """

    dataset: Path
    format: str = "auto"
    observe: list[list[str]] = field(default_factory=lambda: [["orientation"], ["orientation", "emg"]])
    grid: list[tuple[int, float | Window]] = field(default_factory=lambda: [(n, r) for n, r in PAPER_GRID])
    protocols: list[str] = field(default_factory=lambda: ["paper"])
    n_test: int = 10
    n_splits: int = 20
    seed: int = 0
    n_folds: int = 5
    run_folds: list[int] | None = None
    robot: str = DEFAULT_ROBOT
    arm_scores: bool = False
    jobs: int = 1
    cluster: str | None = None
    baselines: bool = False
    closed_loop: bool = False
    limits: str = "demonstrated"
    objects: Path | None = None
    closed_loop_settings: ClosedLoopSettings | None = None
    json: Path | None = None
    md: Path | None = None
    plots: Path | None = None
    alpha: float = 0.05
    command: str = ""
    progress: Callable[[], ProgressFn] | None = None
    log: Callable[[str], None] = print

    @property
    def md_path(self) -> Path | None:
        """The Markdown file: ``md``, else beside the JSON file."""
        return self.md or (self.json.with_suffix(".md") if self.json else None)

    def configs(self) -> list[EvaluationConfig]:
        """One evaluation config per protocol."""
        return [
            EvaluationConfig(
                protocol=protocol,
                observe=self.observe,
                grid=self.grid,
                n_test=self.n_test,
                n_splits=self.n_splits,
                seed=self.seed,
                baselines=self.baselines,
                n_folds=self.n_folds,
                run_folds=self.run_folds,
            )
            for protocol in self.protocols
        ]

    def ratios(self) -> list[float]:
        """The fractions of the cells that observe a fraction of each test demo."""
        windows = [Window.of(w) for _, w in self.grid]
        return [w.value for w in windows if w.is_ratio]

    def settings(self) -> ClosedLoopSettings:
        """The closed loop's settings (each cell replaces their start)."""
        return self.closed_loop_settings or ClosedLoopSettings(control_rate_hz=100.0)


def grid_from(choice: str, n_train: list[int], ratios: list[float]) -> list[tuple[int, float]]:
    """The cells of ``--grid``: the paper's (``"paper"``), else every (n_train, ratio) pair."""
    return list(PAPER_GRID) if choice == "paper" else [(n, r) for n in n_train for r in ratios]


WINDOW_PROTOCOLS = ("both", "fraction", "seconds")
"""The choices of ``evaluate --windows``: which cells an evaluation reports."""


def window_cells(
    grid: list[tuple[int, float]],
    windows: str = "both",
    seconds: list[float] | None = None,
    train_fractions: list[float] | None = None,
) -> list[tuple[int, float | Window]]:
    """The cells of an evaluation: ``grid``'s, each observing a fraction of each test demo (the
    paper's protocol, unchanged), then the cells observing windows in seconds (:mod:`.windows`).

    The windows in seconds, for every training size of ``grid``: the first ``seconds`` [s] of each
    test demo and the ``train_fractions`` of the training demos' mean length; with neither given,
    the fractions of ``grid`` itself, of the training demos' mean length ((n, r) -> (n, r of train),
    the counterpart of every cell of the grid).

    Args:
        windows: ``"both"`` (default), ``"fraction"`` (the grid's cells only) or ``"seconds"`` (the
            cells in seconds only). With the closed loop, the robot starts at the end of each cell's
            window: a fraction of each test demo (the paper's protocol) or the window's seconds (the
            online start rule; the default cells in seconds are its default, a fraction of the
            model's nominal duration).

    Raises:
        DataError: an unknown choice, or windows in seconds asked for with ``"fraction"`` (one line).
    """
    seconds, train_fractions = list(seconds or []), list(train_fractions or [])
    asked = bool(seconds or train_fractions)
    if windows not in WINDOW_PROTOCOLS:
        raise DataError(None, "windows", f"unknown choice '{windows}' (use {', '.join(WINDOW_PROTOCOLS)})")
    if windows == "fraction" and asked:
        raise DataError(None, None, "--window-s and --window-of-train need --windows both or seconds")
    fraction: list[tuple[int, float | Window]] = [(n, r) for n, r in grid]
    if windows == "fraction":
        return fraction
    sizes = list(dict.fromkeys(n for n, _ in grid))
    if asked:
        extra = [Window("seconds", s) for s in seconds] + [
            Window("train_fraction", f) for f in train_fractions
        ]
        timed: list[tuple[int, float | Window]] = [(n, w) for n in sizes for w in extra]
    else:
        timed = [(n, Window("train_fraction", r)) for n, r in grid]
    return timed if windows == "seconds" else fraction + timed


def protocols_from(choice: str) -> list[str]:
    """The protocols of ``--protocol``: ``"both"`` is the paper's, then the random splits."""
    return ["paper", "splits"] if choice == "both" else [choice]


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


def check_request(request: EvaluateRequest) -> Robot:
    """Every check before any demo is read: baselines' dependency, closed-loop settings (each cell's
    ratio as start ratio), output files, limit profile, dataset size (from its file list); returns
    the loaded robot."""
    if request.baselines:
        require_sklearn()
    if request.cluster is not None:
        DaskCluster.from_spec(request.cluster)
        require_dask()
    if "open-set" in request.protocols and (request.closed_loop or request.plots):
        raise DataError(None, "--protocol", "open-set has no closed loop and no accuracy plot")
    if request.closed_loop:
        base = request.settings()
        for ratio in request.ratios():  # every ratio cell's obs_ratio is a start ratio
            dataclasses.replace(base, start_ratio=ratio).validate("command line")
    for path in (request.json, request.md_path):
        if path is not None:
            atomic.check_output_file(path)
    if request.plots and not request.closed_loop:
        atomic.check_output_dir(request.plots, "plots folder")
    robot = load_robot(request.robot)
    check_assumed_human(robot)  # an assumed human inside the robot's fixed links
    load_objects(request.objects)  # a bad task file fails here, before any demo is read
    if request.closed_loop:
        check_profile_choice(request.limits, robot, "command line")
    counts = readers.count_demos(request.dataset, format=request.format)  # lists the demo files, reads none
    for cfg in request.configs():
        check_dataset_size(counts, cfg, request.dataset)
    return robot


def read_dataset(request: EvaluateRequest, robot: Robot) -> Dataset:
    """The dataset, its arm joints and limits those of ``robot`` (of its placement's source for an
    arm with a ``[placement]``: :func:`~.arm_plans.recordings_robot`); says what was read in how long."""
    t0 = time.perf_counter()
    recorded = recordings_robot(robot) or robot
    ds = read_recordings(
        request.dataset,
        recorded,
        format=request.format,
        frames=skeleton_frames(g for o in request.observe for g in o),
        progress=request.progress() if request.progress else None,
    )
    request.log(
        f"read {len(ds.all_demos())} demos of {', '.join(ds.tasks)} in {time.perf_counter() - t0:.1f} s"
        + (
            ""
            if recorded is robot
            else f", recorded on {recorded.settings.name} (executed by {robot.settings.name})"
        )
    )
    return ds


def open_runner(request: EvaluateRequest) -> contextlib.AbstractContextManager[int | JobRunner]:
    """Where the request's jobs run, as a context: ``request.jobs`` local processes, or a Dask session
    (:meth:`~ipromp_pin.evaluation.dask_cluster.DaskCluster.open`) started now, so that its workers
    start, import the package and load the robot while the dataset is read, and serve every protocol."""
    if request.cluster is None:
        return contextlib.nullcontext(request.jobs)
    cluster = DaskCluster.from_spec(request.cluster, log=request.log)
    return cluster.open(partial(prepare_worker, request.robot))


def run_evaluations(request: EvaluateRequest, ds: Dataset, where: int | JobRunner) -> list[Cell]:
    """Every protocol of the request on ``ds`` (one-shot or closed loop), each timed, run ``where``
    (a number of local processes or a runner: :func:`open_runner`)."""
    cells: list[Cell] = []
    options = ClosedLoopOptions(limits=request.limits, settings=request.settings())
    objects = load_objects(request.objects)
    if request.objects is not None:
        objects.check_tasks(ds.tasks)
    for cfg in request.configs():
        progress = request.progress() if request.progress else None
        t1 = time.perf_counter()
        if cfg.protocol == "open-set":
            cells += evaluate_open_set(ds, cfg, request.alpha, progress, where)  # type: ignore[arg-type]
            request.log(f"protocol open-set: {time.perf_counter() - t1:.1f} s")
        elif request.closed_loop:
            cells += evaluate_closed_loop(
                ds, cfg, options, request.robot, progress, where, objects, request.arm_scores
            )
            request.log(f"protocol {cfg.protocol} (closed loop): {time.perf_counter() - t1:.1f} s")
        else:
            cells += evaluate(ds, cfg, request.robot, progress, where, objects, plan=request.arm_scores)
            request.log(f"protocol {cfg.protocol}: {time.perf_counter() - t1:.1f} s")
    return cells


def report(request: EvaluateRequest, cells: list[Cell], seconds: float) -> None:
    """Print the tables, write the JSON, Markdown and plot, and print the summary."""
    md = request.md_path
    meta: dict = {
        "dataset": str(request.dataset),
        "command": request.command,
        "seconds": round(seconds, 2),
        **executed_by(request.robot),
    }
    open_set: list[OpenSetCell] = [c for c in cast(list[Any], cells) if isinstance(c, OpenSetCell)]
    if open_set:  # its own table (the other protocols' cells, if any, below)
        request.log(open_set_markdown(open_set))
        cells = [c for c in cells if not isinstance(c, OpenSetCell)]
        if request.json:
            target = (
                request.json if not cells else request.json.with_name(request.json.stem + "_open_set.json")
            )
            atomic.write_text(target, json.dumps(open_set_json(open_set, meta), indent=1, allow_nan=False))
            request.log(f"wrote {target}")
        if md:
            target_md = md if not cells else md.with_name(md.stem + "_open_set.md")
            atomic.write_text(target_md, open_set_markdown(open_set))
        if not cells:
            return
    if request.closed_loop:
        settings = request.settings().to_dict()
        start = {
            "start_ratio": "obs_ratio of each ratio cell",
            "start_after_s": "seconds of each cell in seconds",
        }
        meta["closed_loop"] = {"limits": request.limits, **settings, **start}
        request.log(closed_loop_markdown(cells))  # type: ignore[arg-type]
        write_closed_loop_results(cells, request.json, md, meta)  # type: ignore[arg-type]
    else:
        request.log(to_markdown(cells))
        write_results(cells, request.json, md, meta)
        for key, o in overall(cells).items():
            paper = f"; {paper_comparison(o)}" if "paper_mean_accuracy" in o else ""
            request.log(f"{key}: mean accuracy {o['mean_accuracy']:.3f} over {o['cells']} cells{paper}")
    if request.json:
        request.log(f"wrote {request.json}" + (f" and {md}" if md else ""))


def executed_by(robot: str) -> dict[str, str | None]:
    """The results' ``robot`` (the executing arm's name) and ``source_robot`` (the robot of the
    recordings and the model when the arm executes it retargeted; None: its own)."""
    loaded = load_robot(robot)
    source = recordings_robot(loaded)
    return {"robot": loaded.settings.name, "source_robot": None if source is None else source.settings.name}


def run_evaluate(request: EvaluateRequest) -> list[Cell]:
    """Run the evaluation of ``request`` (see the module docstring) and return its cells.

    Raises:
        IPrompPinError: bad input (one line naming the file or option and the problem), before any
            demo is read where it can be known then.
    """
    robot = check_request(request)
    t0 = time.perf_counter()
    with open_runner(request) as where:
        ds = read_dataset(request, robot)
        compile_kernels_once()
        cells = run_evaluations(request, ds, where)
    report(request, cells, time.perf_counter() - t0)
    return cells
