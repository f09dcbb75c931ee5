"""The hand-over pipeline: data -> model -> observe -> recognise -> predict -> check -> time -> files.

:func:`prepare` does the set-up that ``ipromp-pin run`` and ``ipromp-pin preview`` share (read the
data, pick the observed demo, train or load the model, load the robot, cut the observation, find
the human's hand at the hand-over); :func:`~ipromp_pin.handover.one_shot.plan` runs the online stages;
:func:`run_pipeline` writes the trajectory, the report, the preview page and the figures, and
:func:`run_preview` shows the same plan live. Every stage reports through a ``log`` callable.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import time
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np

from .. import atomic
from ..data import ROBOT, Dataset, Demo, skeleton_frames
from ..exceptions import PipelineError
from ..handover.one_shot import LogFn, PlanResult, check_model_joints, plan
from ..outputs.report import report_dict, report_text, summary_text
from ..outputs.rosbag import BagContent, write_ros1_bag, write_rosbag2
from ..outputs.trajectory_files import trajectory_csv_text, trajectory_json_text
from ..preview import DEFAULT_MAX_TRIANGLES, LivePreview, PreviewContent, render_html, write_html
from ..preview.mesh_cache import cache_entry, cached_visual_model
from ..promp import IProMP
from ..readers import load_dataset
from ..readers.synthetic import make_synthetic_dataset
from ..robot import Robot, ee_positions, load_robot, load_visual_model
from ..signals.groups import group_unit
from .config import PipelineConfig
from .model_cache import fit_cached
from .model_warnings import loaded_model_warnings, single_task_warning, warn_stderr

RUN_OUTPUTS = (
    "trajectory.csv",
    "trajectory.json",
    "rosbag",
    "run.bag",
    "report.json",
    "report.txt",
    "preview.html",
    "prediction.png",
    "phase_posterior.png",
    "distributions.png",
)
"""Every file ``ipromp-pin run`` may write into its output folder. A run stages its files and
commits them together (:class:`ipromp_pin.atomic.OutputSet`): those of an earlier run that this
run does not write (e.g. ``preview.html`` with ``--no-preview``, or the trajectory of a run whose
checks failed) are removed, so the folder always holds one run's files. A new output of the run
must be added here."""

TRAJECTORY_OUTPUTS = ("trajectory.csv", "trajectory.json", "rosbag", "run.bag")
"""The outputs a robot executes (or replays): written only when the checks pass (or, marked, when the user
allows failing checks)."""


@dataclass
class Prepared:
    """Everything the online stages need, set up from a pipeline definition.

    Attributes:
        dataset: The demonstrations.
        demo: The demo whose first part is observed (held out of training).
        model: The fitted model.
        robot: The loaded robot.
        observation: The observed first ``ratio`` of the demo's human motion.
        hand_position_m: (3,) the human hand's last known position in [m] (the hand-over point), or None.
        warnings: Warnings about the model and the data (:mod:`ipromp_pin.commands.model_warnings`), one
            line each.
        mesh_prefetch: The process decimating the preview meshes meanwhile (:func:`start_mesh_prefetch`),
            or None.
    """

    dataset: Dataset
    demo: Demo
    model: IProMP
    robot: Robot
    observation: Demo
    hand_position_m: np.ndarray | None
    warnings: list[str] = field(default_factory=list)
    mesh_prefetch: mp.process.BaseProcess | None = None


def load_data(cfg: PipelineConfig, log: LogFn = print, robot: Robot | None = None) -> Dataset:
    """The dataset of ``cfg``: real recordings, or the built-in synthetic demos.

    Recordings are read with the robot's joints (by name) and checked against its joint limits;
    the robot's forward kinematics locates the gripper when a recording lacks the end-point stream.
    """
    if cfg.dataset is None:
        log(f"[data] built-in synthetic hand-over demos (seed {cfg.synthetic_seed})")
        return make_synthetic_dataset(seed=cfg.synthetic_seed, rate_hz=cfg.rate_hz)
    robot = robot if robot is not None else load_robot(cfg.robot)
    log(f"[data] reading {cfg.dataset} (format {cfg.format})")
    frames = skeleton_frames([*cfg.frames, *cfg.observe])
    ds = load_dataset(
        cfg.dataset,
        format=cfg.format,
        frames=frames or None,
        rate_hz=cfg.rate_hz,
        robot_joints=robot.settings.recorded_arm_joints,
        joint_limits=robot.recorded_joint_limits(),
        end_effector=lambda q: ee_positions(robot, q),
    )
    log(f"[data] {len(ds.all_demos())} demos of tasks {', '.join(ds.tasks)}")
    return ds


def choose_demo(ds: Dataset, cfg: PipelineConfig) -> Demo:
    """The demo to observe (raises :class:`PipelineError` for an unknown task or index)."""
    task = cfg.task or ds.tasks[0]
    if task not in ds.demos:
        raise PipelineError(
            f"{cfg.source}: field 'observation.task': unknown task '{task}' ({', '.join(ds.tasks)})"
        )
    demos = ds.demos[task]
    if not -len(demos) <= cfg.demo < len(demos):
        raise PipelineError(
            f"{cfg.source}: field 'observation.demo': index {cfg.demo} out of range for {len(demos)} demos"
        )
    return demos[cfg.demo]


def get_model(
    cfg: PipelineConfig, ds: Dataset, held_out: Demo, log: LogFn = print, robot: Robot | None = None
) -> IProMP:
    """Load the saved model, or train one on every demo but ``held_out`` (with the ``robot``'s forward
    kinematics when given, so that its settings are chosen for the hand-over position error)."""
    if cfg.load_model is not None:
        log(f"[model] loading {cfg.load_model}")
        model = IProMP.load(cfg.load_model)
        missing = [g for g in cfg.observe if g not in model.observe_]
        if missing:
            raise PipelineError(
                f"{cfg.load_model}: model does not observe {missing} (observes {model.observe_})"
            )
        return model
    train = [d for d in ds.all_demos() if d is not held_out]
    t0 = time.perf_counter()
    fk = None if robot is None else partial(ee_positions, robot)
    what = f"{len(train)} demos ({', '.join(cfg.observe)} + robot)"
    if cfg.model_cache:
        model, cached = fit_cached(IProMP(observe=cfg.observe), train, fk)
    else:
        model, cached = IProMP(observe=cfg.observe).fit(train, fk=fk), None
    if cached is not None:
        log(f"[model] reused the model an earlier run trained on {what}: {cached} (--retrain: train again)")
    else:
        log(f"[model] trained on {what}, {time.perf_counter() - t0:.2f} s")
    if cfg.save_model is not None:
        model.save(cfg.save_model)  # atomic: an earlier file is replaced only by a complete one
        log(f"[model] saved {cfg.save_model}")
    return model


def hand_at_handover(demo: Demo) -> np.ndarray | None:
    """The human hand's last finite position (3,) in [m] in the demo, or None when it is unknown."""
    hand = demo.extras.get("hand_position")
    if hand is None:
        return None
    finite = np.flatnonzero(np.all(np.isfinite(hand), axis=1))
    return hand[finite[-1]] if finite.size else None


def model_warnings(cfg: PipelineConfig, ds: Dataset, demo: Demo, model: IProMP) -> list[str]:
    """Warnings about the model: a loaded one that does not match the data or was trained on ``demo``,
    or a single-task one."""
    if cfg.load_model is not None:
        return loaded_model_warnings(model, ds, demo, str(cfg.load_model))
    single = single_task_warning(model)
    return [] if single is None else [single]


def prepare(
    cfg: PipelineConfig, log: LogFn = print, warn: LogFn = warn_stderr, prefetch_meshes: bool = False
) -> Prepared:
    """The set-up shared by :func:`run_pipeline` and :func:`run_preview` (``warn``: where warnings go;
    ``prefetch_meshes``: decimate the preview meshes meanwhile when they are not cached yet).

    Raises:
        ModelError: the model's joints are not the robot's (e.g. a left-arm model run with
            ``--robot baxter_right``).
    """
    robot = load_robot(cfg.robot)
    ds = load_data(cfg, log, robot)
    demo = choose_demo(ds, cfg)
    prefetch = start_mesh_prefetch(robot) if prefetch_meshes else None
    model = get_model(cfg, ds, demo, log, robot)
    check_model_joints(model, robot)
    warnings = model_warnings(cfg, ds, demo, model)
    for w in warnings:
        warn(w)
    observation = demo.head(cfg.ratio, groups=cfg.observe)
    log(
        f"[observe] {demo.task}/{demo.name}: first {cfg.ratio:.0%} "
        f"({observation.t[-1]:.2f} s, {observation.n_samples} samples) of {', '.join(cfg.observe)}"
    )
    return Prepared(ds, demo, model, robot, observation, hand_at_handover(demo), warnings, prefetch)


def check_outputs(cfg: PipelineConfig) -> None:
    """Refuse, before any computation, output paths that cannot be written (a file where the output
    folder should be, a read-only folder, a folder where the model file should be)."""
    atomic.check_output_dir(cfg.out_dir)
    if cfg.save_model is not None:
        atomic.check_output_file(cfg.save_model, "model file")


def run_pipeline(
    cfg: PipelineConfig, log: LogFn = print, warn: LogFn = warn_stderr, *, allow_failing_checks: bool = False
) -> dict:
    """Run every stage of ``cfg`` and write its outputs; returns the report dictionary (``warn``:
    where warnings go, one line each; they are also in the report).

    The outputs are written together (:data:`RUN_OUTPUTS`): complete, or the folder's earlier files
    untouched. When the plan fails its checks (``report["passed"]`` is False) the trajectory files
    and bags are not written (and an earlier run's are removed) unless ``allow_failing_checks``,
    which writes them marked as failing (see :mod:`ipromp_pin.outputs.trajectory_files`).
    """
    t_start = time.perf_counter()
    check_outputs(cfg)
    prep = prepare(cfg, log, warn, prefetch_meshes=cfg.preview_html)
    result = plan(
        prep.model, prep.robot, prep.observation, cfg.control_rate_hz, prep.hand_position_m, log=log
    )
    options = OutputOptions(cfg.ros, cfg.rosbag, cfg.ros1_bag, prep.robot.base_frame, prep.warnings)
    with atomic.OutputSet(cfg.out_dir, managed=RUN_OUTPUTS) as out:
        stage_outputs(result, out, prep.observation, options, allow_failing_checks=allow_failing_checks)
        if cfg.preview_html:
            t0 = time.perf_counter()
            visual = preview_visual_model(prep.robot, prep.mesh_prefetch)
            content = preview_content(result, prep.robot, prep.demo, visual_model=visual)
            html = render_html(content).encode("utf-8")
            out.write_bytes("preview.html", html)
            log(
                f"[preview] {out.path('preview.html')} ({len(html) / 1e6:.1f} MB, "
                f"{time.perf_counter() - t0:.1f} s)"
            )
        if cfg.plots:
            write_plots(result, prep.model, prep.demo, out)
        files = out.commit()
    files = {_FILE_KEYS.get(name, name): path for name, path in files.items()}
    report = report_dict(result, prep.observation, prep.warnings)
    report["files"] = {k: str(v) for k, v in files.items()}
    log(summary_text(result, files, time.perf_counter() - t_start))
    if not result.passed:
        written = [n for n in TRAJECTORY_OUTPUTS if _FILE_KEYS[n] in files]
        log(
            "Checks FAILED: "
            + (
                f"the trajectory was written marked as failing ({', '.join(written)})"
                if written
                else "no trajectory written (--allow-failing-checks writes it, marked)"
            )
        )
    return report


_FILE_KEYS = {
    "trajectory.csv": "trajectory_csv",
    "trajectory.json": "trajectory_json",
    "report.json": "report",
    "report.txt": "report_text",
    "preview.html": "preview",
    "prediction.png": "plot_prediction",
    "phase_posterior.png": "plot_phase",
    "distributions.png": "plot_distributions",
    "rosbag": "rosbag",
    "run.bag": "ros1_bag",
}
"""File name -> key of the run report's ``files`` (kept from earlier versions)."""


@dataclass(frozen=True)
class OutputOptions:
    """How a run's files are written.

    Attributes:
        ros: ROS version of ``trajectory.json``'s message (2: ``sec``/``nanosec``; 1: ``secs``/``nsecs``).
        rosbag: Write the rosbag2 folder ``rosbag/`` (MCAP storage).
        ros1_bag: Also write the ROS 1 bag ``run.bag``.
        base_frame: The robot's base frame (the frame of the poses in the bags).
        warnings: Warnings of the run, listed in the report.
    """

    ros: int = 2
    rosbag: bool = True
    ros1_bag: bool = False
    base_frame: str = "base"
    warnings: tuple[str, ...] | list[str] = ()


def stage_outputs(
    result: PlanResult,
    out: atomic.OutputSet,
    observation: Demo | None = None,
    options: OutputOptions = OutputOptions(),
    *,
    allow_failing_checks: bool = False,
) -> None:
    """Stage ``trajectory.csv``, ``trajectory.json``, the bags (see :func:`run_pipeline` for failing
    checks), ``report.json`` and ``report.txt`` in ``out``."""
    warnings = list(options.warnings)
    if result.passed or allow_failing_checks:
        comment, extra = None, None
        if not result.passed:
            failures = list(result.report.failures) + ([] if result.timing_report.passed else ["timing"])
            comment = (
                f"ipromp_pin: checks FAILED ({', '.join(failures)}); "
                "written because of --allow-failing-checks"
            )
            extra = {"ipromp_pin_checks": {"passed": False, "failures": failures}}
        out.write_text("trajectory.csv", trajectory_csv_text(result.trajectory, comment))
        out.write_text(
            "trajectory.json", trajectory_json_text(result.trajectory, ros=options.ros, extra=extra)
        )
        if options.rosbag or options.ros1_bag:
            content = BagContent(
                trajectory=result.trajectory,
                plan_time_s=float(result.prediction.observed_until_s),
                handover_pose=result.report.handover_pose,
                base_frame=options.base_frame,
                observation=observation,
            )
            if options.rosbag:
                write_rosbag2(content, out.stage_dir("rosbag"))
            if options.ros1_bag:
                write_ros1_bag(content, out.stage("run.bag"))
    report = report_dict(result, observation, warnings)
    out.write_text("report.json", json.dumps(report, indent=1, allow_nan=False))
    out.write_text("report.txt", report_text(result, observation, warnings) + "\n")


def write_outputs(
    result: PlanResult,
    out_dir: Path,
    observation: Demo | None = None,
    *,
    options: OutputOptions = OutputOptions(),
    allow_failing_checks: bool = False,
) -> dict[str, Path]:
    """Write ``trajectory.csv``, ``trajectory.json``, ``report.json``, ``report.txt`` and, as ``options``
    say, the bags ``rosbag/`` (rosbag2, MCAP) and ``run.bag`` (ROS 1) into ``out_dir`` together
    (:func:`stage_outputs`); returns report key -> path."""
    with atomic.OutputSet(out_dir) as out:
        stage_outputs(result, out, observation, options, allow_failing_checks=allow_failing_checks)
        files = out.commit()
    return {_FILE_KEYS[name]: path for name, path in files.items()}


def preview_content(
    result: PlanResult, robot: Robot, demo: Demo | None, visual_model: object = None
) -> PreviewContent:
    """The :class:`~ipromp_pin.preview.PreviewContent` of a planned hand-over."""
    p = result.prediction
    tr = result.trajectory
    ee_samples = np.stack([ee_positions(robot, s) for s in result.q_samples])
    truth = None
    hand = hand_t = None
    if demo is not None and ROBOT in demo.groups:
        truth = ee_positions(robot, demo.groups[ROBOT])
        if "hand_position" in demo.extras:
            hand, hand_t = demo.extras["hand_position"], demo.t
    r = result.report
    collision_links: list[str] = []
    near_limit: list[str] = []
    for c in r.checks:
        if c.name == "self_collision" and c.status == "fail":
            collision_links = list(c.values.get("colliding_links", c.values.get("min_distance_links", [])))
        if c.name == "joint_limits":
            near_limit = list(c.values.get("near_limit_joints", c.values.get("violating_joints", [])))
    return PreviewContent(
        model=robot.model,
        visual_model=visual_model,
        collision_model=robot.collision_model,
        t_s=tr.t_s,
        q=tr.q,
        joint_names=robot.joint_names,
        q_full=robot.full_configuration(tr.q[0]),
        ee_mean=r.ee_path,
        ee_samples=ee_samples,
        ee_truth=truth,
        hand_path=hand,
        hand_t_s=hand_t,
        observed_until_s=p.observed_until_s,
        # the observed fraction is of the human's motion: the recorded demo's, else the predicted one
        human_duration_s=p.duration_s if demo is None else demo.duration_s,
        human_duration_source="predicted" if demo is None else "recorded",
        handover_point=r.handover_pose[:3],
        task=p.task,
        tasks=list(p.tasks),
        posterior=p.posterior,
        feasibility=[(c.name, c.passed, c.reason, c.status, c.required) for c in r.checks],
        collision_links=collision_links,
        near_limit_joints=near_limit,
        title=f"ipromp_pin: {p.task}" + ("" if demo is None else f" ({demo.task}/{demo.name})"),
    )


def start_mesh_prefetch(robot: Robot) -> mp.process.BaseProcess | None:
    """Start decimating the robot's preview meshes into the disk cache in a forked process, when they
    are not cached yet, so that a first run does it while it trains (about 3 s of CPU for Baxter).
    None when they are cached, or where processes cannot be forked."""
    s = robot.settings
    entry = cache_entry(s.urdf_path, s.package_dirs, DEFAULT_MAX_TRIANGLES)
    if entry is None or entry.is_file() or "fork" not in mp.get_all_start_methods():
        return None
    process = mp.get_context("fork").Process(target=preview_visual_model, args=(robot,), daemon=True)
    try:
        process.start()
    except OSError:
        return None
    return process


def preview_visual_model(robot: Robot, prefetch: mp.process.BaseProcess | None = None) -> object:
    """The robot's decimated visual model for the preview, from the on-disk mesh cache when there
    (:func:`~ipromp_pin.preview.mesh_cache.cached_visual_model`; loaded and decimated otherwise),
    after the ``prefetch`` process (:func:`start_mesh_prefetch`), if any, has finished."""
    if prefetch is not None:
        prefetch.join()
    s = robot.settings
    return cached_visual_model(
        robot.model, s.urdf_path, s.package_dirs, DEFAULT_MAX_TRIANGLES, lambda: load_visual_model(robot)
    )


def write_preview(result: PlanResult, robot: Robot, demo: Demo | None, path: Path) -> Path:
    """Write the self-contained offline preview page."""
    write_html(preview_content(result, robot, demo, visual_model=preview_visual_model(robot)), path)
    return path


def write_plots(
    result: PlanResult, model: IProMP, demo: Demo, out_dir: Path | atomic.OutputSet
) -> dict[str, Path]:
    """PNG figures of the prediction, the phase posterior and the learned distributions, written into
    a folder or staged in an :class:`~ipromp_pin.atomic.OutputSet` (then they appear at its commit)."""
    from ..outputs import plots  # deferred: matplotlib is only needed with --plots (about 0.4 s to import)

    if isinstance(out_dir, atomic.OutputSet):
        out = out_dir

        def target(name: str) -> Path:
            return out.stage(name)  # a temporary file, renamed into place by the set's commit

    else:

        def target(name: str) -> Path:
            return Path(out_dir) / name

    files = {}
    p = result.prediction
    files["plot_prediction"] = plots.plot_prediction(
        p.t,
        p.q_mean,
        np.sqrt(np.maximum(np.diagonal(p.q_cov, axis1=1, axis2=2), 0.0)),
        target("prediction.png"),
        truth_t_s=demo.t,
        q_truth=demo.groups.get(ROBOT),
        observed_until_s=p.observed_until_s,
        joint_names=list(p.joint_names),
        title=f"{p.task}: conditioned prediction vs recorded",
    )
    # The joint posterior log p(task, alpha | obs) = log p(task | obs) + log p(alpha | task, obs):
    # one scale for every task (each task's phase posterior alone is normalised on its own).
    files["plot_phase"] = plots.plot_phase_posterior(
        {t: p.phase_grid[k] for k, t in enumerate(p.tasks)},
        {t: p.log_posterior[k] + p.phase_log_post[k] for k, t in enumerate(p.tasks)},
        target("phase_posterior.png"),
        tasks=list(p.tasks),
        ylabel="log p(task, alpha | observation)",
        title="joint posterior of task and phase over the phase candidates",
    )
    z = np.linspace(0.0, 1.0, 100)
    _, std, _ = model.distribution(p.task, z)
    centre, lower, upper, labels = model.distribution_band(p.task, z, 2.0)
    files["plot_distributions"] = plots.plot_distributions(
        z,
        centre,
        std,
        target("distributions.png"),
        band=(lower, upper),
        demos=model.train_trajectories(p.task, z),
        dim_names=labels,
        units=[group_unit(label.split("/", 1)[0]) for label in labels],
        title=f"learned distribution of task {p.task} (mean or median, 2-sigma band, training demos)",
    )
    if isinstance(out_dir, atomic.OutputSet):  # where the staged figures will be after the commit
        names = {key: name for name, key in _FILE_KEYS.items()}
        return {key: out_dir.path(names[key]) for key in files}
    return files


def run_preview(
    cfg: PipelineConfig,
    *,
    html: Path | None = None,
    port: int = 7000,
    speed: float = 1.0,
    wait: bool = True,
    log: LogFn = print,
) -> Path | None:
    """``ipromp-pin preview``: a self-contained HTML file, or a live page on 127.0.0.1.

    Live mode streams the observed samples of the chosen demo one by one into the model's
    streaming estimator (at ``speed`` times real time), updating the task posterior and the
    observation window on the page, then shows the planned trajectory and its checks.

    Returns:
        The HTML file written, or ``None`` in live mode.
    """
    if not (np.isfinite(speed) and speed > 0):
        raise PipelineError(f"preview speed must be a positive factor, got {speed}")
    prep = prepare(cfg, log, prefetch_meshes=True)
    observation = prep.observation
    result = plan(prep.model, prep.robot, observation, cfg.control_rate_hz, prep.hand_position_m, log=log)
    if html is not None:
        path = write_preview(result, prep.robot, prep.demo, html)
        log(f"[preview] wrote {path} ({path.stat().st_size / 1e6:.1f} MB): open it in a browser (no server)")
        return path
    visual = preview_visual_model(prep.robot, prep.mesh_prefetch)
    content = preview_content(result, prep.robot, prep.demo, visual_model=visual)
    tasks = list(result.prediction.tasks)
    start = content.replace(posterior=np.full(len(tasks), 1.0 / len(tasks)), task="", observed_until_s=0.0)
    live = LivePreview(start, port=port)
    log(f"[preview] live at {live.url} (127.0.0.1 only); streaming {observation.n_samples} samples")
    try:
        stream = prep.model.stream()
        t_wall = time.perf_counter()
        for i, t in enumerate(observation.t):
            rec = stream.update(float(t), {g: observation.groups[g][i] for g in observation.groups})
            if rec is not None and (i % 3 == 0 or i == observation.n_samples - 1):
                live.update_posterior(rec.posterior, tasks=list(rec.tasks))
                live.update_observation(float(t))
                log(
                    f"  t={t:5.2f} s  "
                    + "  ".join(f"{k} {v:.2f}" for k, v in zip(rec.tasks, rec.posterior, strict=True))
                )
            delay = t / speed - (time.perf_counter() - t_wall)
            if delay > 0:
                time.sleep(delay)
        live.show(content)
        log(f"[preview] recognised {result.prediction.task}; trajectory and checks shown")
        if wait:
            log("[preview] press Ctrl-C to stop the server")
            while True:
                time.sleep(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        live.close()
    return None
