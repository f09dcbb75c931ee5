"""The hand-over pipeline: data -> model -> observe -> recognise -> predict -> check -> time -> files.

A pipeline definition is a TOML file (see ``pipelines/baxter_handover.toml``);
relative paths in it are relative to its folder. :func:`load_pipeline` reads
and validates it, command-line overrides replace single values, and
:func:`run_pipeline` executes the stages, reporting each one through a
``log`` callable. The stages after the observation (:func:`plan`) are the
online part, benchmarked in ``benchmarks/pipeline.py``.
"""

from __future__ import annotations

import json
import time
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from .data import ROBOT, Dataset, Demo, skeleton_frames
from .exceptions import PipelineError
from .robot import check_path, ee_positions
from .shipped import PIPELINES_DIR
from .timing import JointLimits, time_path

LogFn = Callable[[str], None]

_SCHEMA: dict[str, dict[str, type | tuple[type, ...]]] = {
    "data": {"dataset": str, "format": str, "rate_hz": (int, float), "frames": list, "synthetic_seed": int},
    "model": {"observe": list, "load": str, "save": str},
    "observation": {"task": str, "demo": int, "ratio": (int, float)},
    "robot": {"settings": str},
    "timing": {"control_rate_hz": (int, float)},
    "outputs": {"dir": str, "preview_html": bool, "plots": bool},
}


@dataclass
class PipelineConfig:
    """A validated pipeline definition.

    Attributes:
        source: The definition file (or ``"<defaults>"``).
        dataset: Dataset folder; ``None`` uses the built-in synthetic demos.
        format: Reader format (``auto``, ``chen2017``, ``multimodal``, ``bag``, ``native``).
        rate_hz: Common sampling rate of the aligned streams, in [Hz].
        frames: Skeleton frames to read (multimodal data).
        synthetic_seed: Seed of the synthetic demos.
        observe: Observed human channel groups.
        load_model: A saved model file to use instead of training.
        save_model: Where to save the trained model.
        task: Task of the observed demo (``None``: the first task).
        demo: Index of the observed demo within its task (negative counts from the end).
        ratio: Observed fraction of the human's motion, in (0, 1].
        robot: Robot settings file or name.
        control_rate_hz: Output trajectory sampling rate, in [Hz].
        out_dir: Output folder.
        preview_html: Write ``preview.html``.
        plots: Write PNG figures.
    """

    source: str = "<defaults>"
    dataset: Path | None = None
    format: str = "auto"
    rate_hz: float = 50.0
    frames: list[str] = field(default_factory=list)
    synthetic_seed: int = 0
    observe: list[str] = field(default_factory=lambda: ["orientation", "emg"])
    load_model: Path | None = None
    save_model: Path | None = None
    task: str | None = None
    demo: int = -1
    ratio: float = 0.2
    robot: str = "baxter_left"
    control_rate_hz: float = 100.0
    out_dir: Path = Path("out")
    preview_html: bool = True
    plots: bool = False

    def validate(self) -> PipelineConfig:
        """Check value ranges; raise :class:`PipelineError` naming the field."""
        if not (0.0 < self.ratio <= 1.0):
            raise PipelineError(
                f"{self.source}: field 'observation.ratio': must be in (0, 1], got {self.ratio}"
            )
        if not self.observe:
            raise PipelineError(f"{self.source}: field 'model.observe': no channel group given")
        if ROBOT in self.observe:
            raise PipelineError(f"{self.source}: field 'model.observe': the robot group cannot be observed")
        for name, value in (("data.rate_hz", self.rate_hz), ("timing.control_rate_hz", self.control_rate_hz)):
            if not (np.isfinite(value) and value > 0):
                raise PipelineError(f"{self.source}: field '{name}': must be a positive rate, got {value}")
        return self


def resolve_pipeline_path(path_or_name: str | Path) -> Path:
    """The pipeline file to read: ``path_or_name`` if it is a file, else, for a bare name such as
    ``"baxter_handover"``, the shipped definition of that name (:data:`ipromp_pin.shipped.PIPELINES_DIR`).

    A name that matches neither is returned unchanged (:func:`load_pipeline` reports it as not found).
    """
    path = Path(path_or_name)
    if not path.is_file() and path.suffix == "" and len(path.parts) == 1:
        shipped = PIPELINES_DIR / f"{path.name}.toml"
        if shipped.is_file():
            return shipped
    return path


def load_pipeline(path: str | Path, **overrides) -> PipelineConfig:
    """Read a pipeline definition; ``overrides`` (non-``None`` values) replace its fields.

    Args:
        path: A pipeline file, or the name of a shipped one (see :func:`resolve_pipeline_path`).
        **overrides: Field values that replace the file's.

    Raises:
        PipelineError: unreadable file, unknown section or key, wrong type or value.
    """
    path = resolve_pipeline_path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        known = ", ".join(sorted(f.stem for f in PIPELINES_DIR.glob("*.toml"))) or "none"
        raise PipelineError(f"{path}: pipeline file not found (shipped pipelines: {known})") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise PipelineError(f"{path}: not a valid TOML pipeline file: {exc}") from None
    for section, table in doc.items():
        if section not in _SCHEMA:
            raise PipelineError(f"{path}: unknown section [{section}] (known: {', '.join(_SCHEMA)})")
        if not isinstance(table, dict):
            raise PipelineError(f"{path}: field '{section}': expected a table")
        for key, value in table.items():
            kind = _SCHEMA[section].get(key)
            if kind is None:
                raise PipelineError(f"{path}: field '{section}.{key}': unknown key")
            if not isinstance(value, kind) or (kind in (int, (int, float)) and isinstance(value, bool)):
                raise PipelineError(f"{path}: field '{section}.{key}': wrong type {type(value).__name__}")
    base = path.resolve().parent

    def get(section: str, key: str, default):
        return doc.get(section, {}).get(key, default)

    def rel(value: str) -> Path | None:
        if not value:
            return None
        p = Path(value).expanduser()
        return p if p.is_absolute() else base / p

    robot = get("robot", "settings", "baxter_left")
    if "/" in robot or robot.endswith(".toml"):
        robot = str(rel(robot))
    cfg = PipelineConfig(
        source=str(path),
        dataset=rel(get("data", "dataset", "")),
        format=get("data", "format", "auto"),
        rate_hz=float(get("data", "rate_hz", 50.0)),
        frames=[str(f) for f in get("data", "frames", [])],
        synthetic_seed=int(get("data", "synthetic_seed", 0)),
        observe=[str(g) for g in get("model", "observe", ["orientation", "emg"])],
        load_model=rel(get("model", "load", "")),
        save_model=rel(get("model", "save", "")),
        task=get("observation", "task", "") or None,
        demo=int(get("observation", "demo", -1)),
        ratio=float(get("observation", "ratio", 0.2)),
        robot=robot,
        control_rate_hz=float(get("timing", "control_rate_hz", 100.0)),
        out_dir=Path(get("outputs", "dir", "out")),
        preview_html=bool(get("outputs", "preview_html", True)),
        plots=bool(get("outputs", "plots", False)),
    )
    names = {f.name for f in fields(PipelineConfig)}
    for key, value in overrides.items():
        if key not in names:
            raise PipelineError(f"unknown pipeline override '{key}'")
        if value is not None:
            setattr(cfg, key, value)
    return cfg.validate()


@dataclass
class PlanResult:
    """Output of the online stages for one observation.

    Attributes:
        prediction: The model's :class:`~ipromp_pin.recognition.Prediction`.
        report: Feasibility report of the predicted path.
        trajectory: Time-parameterised, jerk-limited trajectory.
        timing_report: Verification of the trajectory against the limits and the path.
        stage_ms: Wall time of every stage in [ms].
        q_samples: Joint trajectories (n, M, n_joints) in [rad] drawn from the conditioned
            prediction, used by the uncertainty check and shown by the preview.
    """

    prediction: object
    report: object
    trajectory: object
    timing_report: object
    stage_ms: dict[str, float]
    q_samples: np.ndarray


def load_data(cfg: PipelineConfig, log: LogFn = print) -> Dataset:
    """The dataset of ``cfg``: real recordings, or the built-in synthetic demos."""
    if cfg.dataset is None:
        from .synthetic import make_synthetic_dataset

        log(f"[data] built-in synthetic hand-over demos (seed {cfg.synthetic_seed})")
        return make_synthetic_dataset(seed=cfg.synthetic_seed, rate_hz=cfg.rate_hz)
    from .readers import load_dataset
    from .robot import load_robot_settings

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


def get_model(cfg: PipelineConfig, ds: Dataset, held_out: Demo, log: LogFn = print):
    """Load the saved model, or train one on every demo but ``held_out``."""
    from .recognition import IProMP

    if cfg.load_model is not None:
        log(f"[model] loading {cfg.load_model}")
        model = IProMP.load(cfg.load_model)
        missing = [g for g in cfg.observe if g not in model.observe]
        if missing:
            raise PipelineError(
                f"{cfg.load_model}: model does not observe {missing} (observes {model.observe})"
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


def plan(
    model,
    robot,
    observation: Demo,
    control_rate_hz: float = 100.0,
    hand_position_m: np.ndarray | None = None,
    log: LogFn | None = None,
) -> PlanResult:
    """Online stages: recognise + predict, check, time-parameterise, smooth.

    Args:
        model: A fitted :class:`~ipromp_pin.recognition.IProMP`.
        robot: A loaded :class:`~ipromp_pin.robot.Robot`.
        observation: The observed first part of the human's motion.
        control_rate_hz: Output sampling rate in [Hz].
        hand_position_m: Human hand position at the hand-over (3,) in [m], if known.
        log: Progress messages (``None``: silent).
    """
    say = log or (lambda _msg: None)
    ms: dict[str, float] = {}
    t0 = time.perf_counter()
    prediction = model.predict(observation)
    t1 = time.perf_counter()
    ms["recognise_predict"] = (t1 - t0) * 1e3
    say(
        f"[recognise] {prediction.task} (posterior {float(np.max(prediction.posterior)):.3f}), "
        f"predicted duration {prediction.duration_s:.2f} s"
    )
    samples = prediction.sample_q(16, np.random.default_rng(0))
    report = check_path(
        robot, prediction.q_mean, t_s=prediction.t, q_samples=samples, hand_position_m=hand_position_m
    )
    t2 = time.perf_counter()
    ms["check"] = (t2 - t1) * 1e3
    say(f"[check] {'pass' if report.passed else 'FAIL: ' + ', '.join(report.failures)}")
    trajectory, timing_report = time_path(
        prediction.q_mean, JointLimits.from_robot(robot), rate_hz=control_rate_hz
    )
    t3 = time.perf_counter()
    ms["time_parameterise_smooth"] = (t3 - t2) * 1e3
    say(f"[timing] {trajectory.t_s[-1]:.2f} s at {control_rate_hz:g} Hz, {len(trajectory.t_s)} samples")
    return PlanResult(prediction, report, trajectory, timing_report, ms, samples)


def write_outputs(result: PlanResult, out_dir: Path, observation: Demo | None = None) -> dict[str, Path]:
    """Write ``trajectory.csv``, ``trajectory.json``, ``report.json`` and ``report.txt`` into ``out_dir``."""
    from .export import write_trajectory_csv, write_trajectory_json

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


def report_text(result: PlanResult, observation: Demo | None = None) -> str:
    """The human-readable report: recognition, feasibility checks and trajectory verification."""
    p = result.prediction
    lines = []
    if observation is not None:
        lines.append(f"Observed: {observation.task}/{observation.name} ({observation.source})")
    lines.append(
        f"Recognised task: {p.task}; posterior "
        + ", ".join(f"{t} {v:.3f}" for t, v in zip(p.tasks, p.posterior, strict=True))
    )
    lines.append(
        f"Predicted duration of the motion: {p.duration_s:.2f} s (observed {p.observed_until_s:.2f} s)"
    )
    lines.append(result.report.to_text())
    tr = result.timing_report
    lines.append(tr.to_text() if hasattr(tr, "to_text") else str(tr))
    return "\n".join(lines)


def report_dict(result: PlanResult, observation: Demo | None = None) -> dict:
    """The machine-readable pipeline report (JSON-serialisable)."""
    p = result.prediction
    tr = result.timing_report
    return {
        "format": "ipromp_pin.report",
        "version": 1,
        "recognised_task": p.task,
        "posterior": {t: float(v) for t, v in zip(p.tasks, p.posterior, strict=True)},
        "alpha": {t: float(v) for t, v in zip(p.tasks, p.alpha, strict=True)},
        "predicted_duration_s": float(p.duration_s),
        "observed_until_s": float(p.observed_until_s),
        "observation": None
        if observation is None
        else {"task": observation.task, "demo": observation.name, "source": observation.source},
        "feasibility": result.report.to_dict(),
        "trajectory": tr.to_dict() if hasattr(tr, "to_dict") else dict(tr),
        "passed": bool(result.report.passed and getattr(tr, "passed", True)),
        "stage_ms": {k: round(v, 3) for k, v in result.stage_ms.items()},
    }


def run_pipeline(cfg: PipelineConfig, log: LogFn = print) -> dict:
    """Run every stage of ``cfg`` and write its outputs; returns the report dictionary."""
    from .robot import load_robot

    t_start = time.perf_counter()
    ds = load_data(cfg, log)
    demo = choose_demo(ds, cfg)
    model = get_model(cfg, ds, demo, log)
    robot = load_robot(cfg.robot)
    observation = demo.head(cfg.ratio, groups=cfg.observe)
    log(
        f"[observe] {demo.task}/{demo.name}: first {cfg.ratio:.0%} "
        f"({observation.t[-1]:.2f} s, {observation.n_samples} samples) of {', '.join(cfg.observe)}"
    )
    hand = demo.extras.get("hand_position")
    hand_end = None
    if hand is not None:
        finite = np.flatnonzero(np.all(np.isfinite(hand), axis=1))
        hand_end = hand[finite[-1]] if finite.size else None
    result = plan(model, robot, observation, cfg.control_rate_hz, hand_position_m=hand_end, log=log)
    files = write_outputs(result, cfg.out_dir, observation)
    if cfg.preview_html:
        t0 = time.perf_counter()
        files["preview"] = write_preview(result, robot, demo, cfg.out_dir / "preview.html")
        log(
            f"[preview] {files['preview']} ({files['preview'].stat().st_size / 1e6:.1f} MB, "
            f"{time.perf_counter() - t0:.1f} s)"
        )
    if cfg.plots:
        files.update(write_plots(result, model, demo, cfg.out_dir))
    report = report_dict(result, observation)
    report["files"] = {k: str(v) for k, v in files.items()}
    log(summary_text(result, files, time.perf_counter() - t_start))
    return report


def summary_text(result: PlanResult, files: dict[str, Path], elapsed_s: float) -> str:
    """Short end-of-run summary."""
    p = result.prediction
    r = result.report
    pose = r.handover_pose
    post = ", ".join(f"{t} {v:.3f}" for t, v in zip(p.tasks, p.posterior, strict=True))
    checks = ", ".join(f"{c.name} {c.status}" for c in r.checks)
    tr = result.trajectory
    lines = [
        "",
        f"Recognised task: {p.task}   posterior: {post}",
        f"Hand-over pose: position ({pose[0]:.3f}, {pose[1]:.3f}, {pose[2]:.3f}) m, "
        f"quaternion xyzw ({pose[3]:.3f}, {pose[4]:.3f}, {pose[5]:.3f}, {pose[6]:.3f})",
        f"Checks: {'PASS' if r.passed else 'FAIL'} ({checks})",
        f"Trajectory: {tr.t_s[-1]:.2f} s, {len(tr.t_s)} samples; online stages "
        + ", ".join(f"{k} {v:.1f} ms" for k, v in result.stage_ms.items()),
        "Files: " + ", ".join(str(f) for f in files.values()),
        f"Total {elapsed_s:.1f} s",
    ]
    return "\n".join(lines)


def preview_content(result: PlanResult, robot, demo: Demo | None, visual_model=None):
    """Build the :class:`~ipromp_pin.preview.PreviewContent` of a planned hand-over."""
    from .preview import PreviewContent

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


def write_preview(result: PlanResult, robot, demo: Demo | None, path: Path) -> Path:
    """Write the self-contained offline preview page."""
    from .preview import write_html
    from .robot import load_visual_model

    content = preview_content(result, robot, demo, visual_model=load_visual_model(robot))
    write_html(content, path)
    return path


def write_plots(result: PlanResult, model, demo: Demo, out_dir: Path) -> dict[str, Path]:
    """PNG figures of the prediction, the phase posterior and the learned distributions."""
    from . import plots

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

    Live mode streams the observed samples of the chosen demo one by one into
    the model's streaming estimator (at ``speed`` times real time), updating
    the task posterior and the observation window on the page, then shows the
    planned trajectory and its checks.

    Returns:
        The HTML file written, or ``None`` in live mode.
    """
    from .preview import LivePreview
    from .robot import load_robot, load_visual_model

    ds = load_data(cfg, log)
    demo = choose_demo(ds, cfg)
    model = get_model(cfg, ds, demo, log)
    robot = load_robot(cfg.robot)
    observation = demo.head(cfg.ratio, groups=cfg.observe)
    result = plan(model, robot, observation, cfg.control_rate_hz, log=log)
    if html is not None:
        path = write_preview(result, robot, demo, html)
        log(f"[preview] wrote {path} ({path.stat().st_size / 1e6:.1f} MB): open it in a browser (no server)")
        return path
    content = preview_content(result, robot, demo, visual_model=load_visual_model(robot))
    start = content.replace(
        posterior=np.full(len(result.prediction.tasks), 1.0 / len(result.prediction.tasks)),
        task="",
        observed_until_s=0.0,
    )
    live = LivePreview(start, port=port)
    log(f"[preview] live at {live.url} (127.0.0.1 only); streaming {observation.n_samples} samples")
    try:
        stream = model.stream()
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
