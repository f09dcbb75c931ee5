"""The hand-over pipeline: data -> model -> observe -> recognise -> predict -> check -> time -> files.

:func:`prepare` does the set-up that ``ipromp-pin run`` and ``ipromp-pin preview`` share (read the
data, pick the observed demo, train or load the model, load the robot, cut the observation, find
the human's hand at the hand-over); :func:`~ipromp_pin.planning.plan` runs the online stages;
:func:`run_pipeline` writes the trajectory, the report, the preview page and the figures, and
:func:`run_preview` shows the same plan live. Every stage reports through a ``log`` callable.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .config import PipelineConfig
from .data import ROBOT, Dataset, Demo, skeleton_frames
from .exceptions import PipelineError
from .export import write_trajectory_csv, write_trajectory_json
from .planning import LogFn, PlanResult, plan
from .preview import LivePreview, PreviewContent, write_html
from .promp import IProMP
from .readers import load_dataset
from .report import report_dict, report_text, summary_text
from .robot import Robot, ee_positions, load_robot, load_robot_settings, load_visual_model
from .synthetic import make_synthetic_dataset


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
    """

    dataset: Dataset
    demo: Demo
    model: IProMP
    robot: Robot
    observation: Demo
    hand_position_m: np.ndarray | None


def load_data(cfg: PipelineConfig, log: LogFn = print) -> Dataset:
    """The dataset of ``cfg``: real recordings, or the built-in synthetic demos."""
    if cfg.dataset is None:
        log(f"[data] built-in synthetic hand-over demos (seed {cfg.synthetic_seed})")
        return make_synthetic_dataset(seed=cfg.synthetic_seed, rate_hz=cfg.rate_hz)
    joints = load_robot_settings(cfg.robot).recorded_arm_joints
    log(f"[data] reading {cfg.dataset} (format {cfg.format})")
    frames = skeleton_frames([*cfg.frames, *cfg.observe])
    ds = load_dataset(
        cfg.dataset, format=cfg.format, frames=frames or None, rate_hz=cfg.rate_hz, robot_joints=joints
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


def get_model(cfg: PipelineConfig, ds: Dataset, held_out: Demo, log: LogFn = print) -> IProMP:
    """Load the saved model, or train one on every demo but ``held_out``."""
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
    model = IProMP(observe=cfg.observe).fit(train)
    log(
        f"[model] trained on {len(train)} demos ({', '.join(cfg.observe)} + robot), "
        f"{time.perf_counter() - t0:.2f} s"
    )
    if cfg.save_model is not None:
        model.save(cfg.save_model)
        log(f"[model] saved {cfg.save_model}")
    return model


def hand_at_handover(demo: Demo) -> np.ndarray | None:
    """The human hand's last finite position (3,) in [m] in the demo, or None when it is unknown."""
    hand = demo.extras.get("hand_position")
    if hand is None:
        return None
    finite = np.flatnonzero(np.all(np.isfinite(hand), axis=1))
    return hand[finite[-1]] if finite.size else None


def prepare(cfg: PipelineConfig, log: LogFn = print) -> Prepared:
    """The set-up shared by :func:`run_pipeline` and :func:`run_preview`."""
    ds = load_data(cfg, log)
    demo = choose_demo(ds, cfg)
    model = get_model(cfg, ds, demo, log)
    robot = load_robot(cfg.robot)
    observation = demo.head(cfg.ratio, groups=cfg.observe)
    log(
        f"[observe] {demo.task}/{demo.name}: first {cfg.ratio:.0%} "
        f"({observation.t[-1]:.2f} s, {observation.n_samples} samples) of {', '.join(cfg.observe)}"
    )
    return Prepared(ds, demo, model, robot, observation, hand_at_handover(demo))


def run_pipeline(cfg: PipelineConfig, log: LogFn = print) -> dict:
    """Run every stage of ``cfg`` and write its outputs; returns the report dictionary."""
    t_start = time.perf_counter()
    prep = prepare(cfg, log)
    result = plan(
        prep.model, prep.robot, prep.observation, cfg.control_rate_hz, prep.hand_position_m, log=log
    )
    files = write_outputs(result, cfg.out_dir, prep.observation)
    if cfg.preview_html:
        t0 = time.perf_counter()
        files["preview"] = write_preview(result, prep.robot, prep.demo, cfg.out_dir / "preview.html")
        log(
            f"[preview] {files['preview']} ({files['preview'].stat().st_size / 1e6:.1f} MB, "
            f"{time.perf_counter() - t0:.1f} s)"
        )
    if cfg.plots:
        files.update(write_plots(result, prep.model, prep.demo, cfg.out_dir))
    report = report_dict(result, prep.observation)
    report["files"] = {k: str(v) for k, v in files.items()}
    log(summary_text(result, files, time.perf_counter() - t_start))
    return report


def write_outputs(result: PlanResult, out_dir: Path, observation: Demo | None = None) -> dict[str, Path]:
    """Write ``trajectory.csv``, ``trajectory.json``, ``report.json`` and ``report.txt`` into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    files = {
        "trajectory_csv": write_trajectory_csv(result.trajectory, out_dir / "trajectory.csv"),
        "trajectory_json": write_trajectory_json(result.trajectory, out_dir / "trajectory.json"),
    }
    report_path = out_dir / "report.json"
    report_path.write_text(json.dumps(report_dict(result, observation), indent=1, allow_nan=False))
    files["report"] = report_path
    text_path = out_dir / "report.txt"
    text_path.write_text(report_text(result, observation) + "\n")
    files["report_text"] = text_path
    return files


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
        handover_point=r.handover_pose[:3],
        task=p.task,
        tasks=list(p.tasks),
        posterior=p.posterior,
        feasibility=[(c.name, c.passed, c.reason) for c in r.checks],
        collision_links=collision_links,
        near_limit_joints=near_limit,
        title=f"ipromp_pin: {p.task}" + ("" if demo is None else f" ({demo.task}/{demo.name})"),
    )


def write_preview(result: PlanResult, robot: Robot, demo: Demo | None, path: Path) -> Path:
    """Write the self-contained offline preview page."""
    write_html(preview_content(result, robot, demo, visual_model=load_visual_model(robot)), path)
    return path


def write_plots(result: PlanResult, model: IProMP, demo: Demo, out_dir: Path) -> dict[str, Path]:
    """PNG figures of the prediction, the phase posterior and the learned distributions."""
    from . import plots  # deferred: matplotlib is only needed with --plots (about 0.4 s to import)

    files = {}
    p = result.prediction
    files["plot_prediction"] = plots.plot_prediction(
        p.t,
        p.q_mean,
        np.sqrt(np.maximum(np.diagonal(p.q_cov, axis1=1, axis2=2), 0.0)),
        out_dir / "prediction.png",
        truth_t_s=demo.t,
        q_truth=demo.groups.get(ROBOT),
        observed_until_s=p.observed_until_s,
        joint_names=list(p.joint_names),
        title=f"{p.task}: conditioned prediction vs recorded",
    )
    files["plot_phase"] = plots.plot_phase_posterior(
        {t: p.phase_grid[k] for k, t in enumerate(p.tasks)},
        {t: p.phase_log_post[k] for k, t in enumerate(p.tasks)},
        out_dir / "phase_posterior.png",
        tasks=list(p.tasks),
    )
    z = np.linspace(0.0, 1.0, 100)
    mean, std, labels = model.distribution(p.task, z)
    files["plot_distributions"] = plots.plot_distributions(
        z,
        mean,
        std,
        out_dir / "distributions.png",
        demos=model.train_trajectories(p.task, z),
        dim_names=labels,
        title=f"learned distribution of task {p.task} (mean, 2 sigma, training demos)",
    )
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
    prep = prepare(cfg, log)
    observation = prep.observation
    result = plan(prep.model, prep.robot, observation, cfg.control_rate_hz, prep.hand_position_m, log=log)
    if html is not None:
        path = write_preview(result, prep.robot, prep.demo, html)
        log(f"[preview] wrote {path} ({path.stat().st_size / 1e6:.1f} MB): open it in a browser (no server)")
        return path
    content = preview_content(result, prep.robot, prep.demo, visual_model=load_visual_model(prep.robot))
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
            delay = t / max(speed, 1e-6) - (time.perf_counter() - t_wall)
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
