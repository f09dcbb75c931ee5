"""The set-up every command that plans on one held-out demo shares (``run``, ``preview``, ``replay``),
and the plan of ``run`` and ``preview`` (:func:`plan_session`) and the replay's set-up
(:func:`prepare_replay`).

:func:`prepare_session` builds a :class:`Session` from a pipeline definition, once per command: it
loads the robot, reads the data (the built-in synthetic demos by default), picks the observed demo
(held out of training), starts decimating the preview meshes meanwhile when asked, trains, reuses
or loads the model, checks its joints against the robot's, collects the warnings and cuts the
observation. A command's own checks of the demo and the model run as soon as their inputs exist
(:class:`SetupChecks`), so that bad input fails before the computation that needs it.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import time
from dataclasses import dataclass, field
from pathlib import Path

from .. import atomic
from ..data import GRIPPER, ROBOT, Dataset, Demo, robot_side, skeleton_frames
from ..evaluation.scoring import ClosedLoopScore, replay_scored
from ..exceptions import DataError, PipelineError
from ..fields import did_you_mean
from ..human import HumanMotion
from ..human.fit import registered
from ..human.placement import check_assumed_human
from ..motion.limits import LimitProfile, check_profile_choice, choose_limit_profile
from ..planning.closed_loop import ClosedLoopResult, ClosedLoopSettings, replay_demo, start_time
from ..planning.human_forecast import forecast_of, forecast_summary, with_forecast
from ..planning.one_shot import LogFn, check_model_joints
from ..planning.transfer import predicts_gripper, scene_robot
from ..plans import HandoverPlan, plan
from ..plans.warnings import (
    loaded_model_warnings,
    missing_object_warnings,
    range_warnings,
    single_task_warning,
    warn_stderr,
)
from ..preview.mesh_cache import start_mesh_prefetch
from ..promp import IProMP
from ..readers.synthetic import make_synthetic_dataset
from ..robot import Robot, gripper_kinematics, load_robot
from ..robot.objects import ObjectTable, load_objects
from ..robot.recordings import read_recordings
from ..safety import CheckContext, CheckSuite
from .config import PipelineConfig
from .human_fit import check_human_fit, model_registration
from .model_cache import fit_cached


@dataclass
class Session:
    """Everything a command needs after the set-up, built by :func:`prepare_session`.

    Attributes:
        cfg: The pipeline definition.
        robot: The loaded robot.
        dataset: The demonstrations.
        demo: The demo whose first part is observed (held out of training).
        train: Every demo but ``demo`` (the model's training demos, unless it was loaded).
        model: The fitted model (trained, reused from the cache or loaded).
        warnings: Warnings about the model and the data (:mod:`ipromp_pin.plans.warnings`), one
            line each.
        mesh_prefetch: The process decimating the preview meshes meanwhile
            (:func:`~ipromp_pin.preview.mesh_cache.start_mesh_prefetch`), or None.
        observation: The observed first ``cfg.ratio`` of the demo's human motion (None when not cut).
        suite: The checks of every plan (:meth:`ipromp_pin.safety.CheckSuite.build`).
        context: What they know about the world for ``demo`` (:func:`check_context`; cut to what the
            planner knows at the end of the observation when there is one).
        source: The robot of the recordings and the model when ``robot`` executes it retargeted
            (its ``[placement] source``), None: ``robot`` itself.
    """

    cfg: PipelineConfig
    robot: Robot
    dataset: Dataset
    demo: Demo
    train: list[Demo]
    model: IProMP
    warnings: list[str] = field(default_factory=list)
    mesh_prefetch: mp.process.BaseProcess | None = None
    observation: Demo | None = None
    suite: CheckSuite = field(default_factory=lambda: CheckSuite([]))
    context: CheckContext = field(default_factory=CheckContext)
    source: Robot | None = None

    def observed(self) -> Demo:
        """The observation of a session prepared with ``observe=True`` (PipelineError without one)."""
        if self.observation is None:
            raise PipelineError("the session has no observation (prepared with observe=False)")
        return self.observation


class SetupChecks:
    """A command's checks of the held-out demo and the model, run by :func:`prepare_session` as soon
    as their inputs exist (these do nothing; a command overrides what it needs)."""

    def check_demo(self, demo: Demo) -> None:
        """Refuse a held-out demo the command cannot use (called before the model is trained)."""

    def check_model(self, model: IProMP, demo: Demo) -> None:
        """Refuse a model the command cannot use on ``demo`` (called before the warnings are shown)."""


def prepare_session(
    cfg: PipelineConfig,
    log: LogFn = print,
    warn: LogFn = warn_stderr,
    *,
    robot: Robot | None = None,
    checks: SetupChecks | None = None,
    prefetch_meshes: bool = False,
    observe: bool = True,
    strict_human: bool = False,
) -> Session:
    """The set-up of one command on ``cfg`` (``warn``: where warnings go; ``robot``: the loaded
    robot, loaded here when None; ``checks``: the command's own checks; ``prefetch_meshes``: decimate
    the preview meshes meanwhile when they are not cached yet; ``observe``: cut the observation;
    ``strict_human``: refuse a model whose body model is known not to fit, else warn). A tracked
    body is placed through the model's corrected registration (:mod:`.human_fit`).

    Raises:
        ModelError: the model's joints are not the robot's (e.g. a left-arm model run with
            ``--robot baxter_right``).
        HumanModelMisfit: ``strict_human`` and the model's body model does not fit its demos.
    """
    checks = checks or SetupChecks()
    robot = robot if robot is not None else load_robot(cfg.robot)
    check_assumed_human(robot)  # an assumed human inside the robot's fixed links, before any computation
    objects = load_objects(cfg.objects)
    objects.check_robot(robot)  # retreat targets the robot cannot take, before any computation
    source, ds = recordings_robot(cfg, robot, log)
    side = robot_side(ds.all_demos())
    if side == GRIPPER:  # no joints: the arm follows the demos' gripper poses, in its scene's frame
        source = scene_robot(robot)
        log(f"[data] the robot side is a gripper pose path: {robot.settings.name} follows it")
    recorded = robot if source is None else source
    early = missing_object_warnings(ds.tasks, objects)  # before training: the model learns ds.tasks
    for w in early:
        warn(w)
    if cfg.load_model is None and side == ROBOT:  # before training: not recorded on this robot
        check_recorded_joints(
            ds, recorded, "the built-in synthetic demos" if cfg.dataset is None else str(cfg.dataset)
        )
    if cfg.objects is not None:
        objects.check_tasks(ds.tasks)
    demo = choose_demo(ds, cfg, log)
    checks.check_demo(demo)
    context = check_context(cfg, demo, robot, objects)  # a skeleton the map does not cover: before training
    prefetch = start_mesh_prefetch(robot) if prefetch_meshes else None
    train = [d for d in ds.all_demos() if d is not demo]
    model = get_model(cfg, ds, demo, log, recorded if side == ROBOT else None, train=train, side=side)
    check_model_joints(model, recorded)
    checks.check_model(model, demo)
    model_source = str(cfg.load_model or "model")
    misfit = check_human_fit(model, model_source, strict_human, warn)
    warnings = model_warnings(cfg, ds, demo, model) + ([] if misfit is None else [misfit])
    for w in warnings[: len(warnings) - (misfit is not None)]:
        warn(w)
    later = [w for w in missing_object_warnings(model.tasks_, objects) if w not in early]  # a loaded model's
    for w in later:
        warn(w)
    warnings = early + warnings + later
    session = Session(cfg, robot, ds, demo, train, model, warnings, prefetch, source=source)
    session.suite = CheckSuite.build(robot)
    session.context = context
    if session.context.human is not None:
        corrected = registered(session.context.human, model_registration(model, model_source))
        session.context = session.context.replace(human=corrected)
    if observe:
        session.observation = observation = observe_window(session, warn)
        human = session.context.human
        if human is not None:  # the planner knows the human up to the end of the observation
            session.context = session.context.replace(human=human.until(float(observation.t[-1])))
        window = f"{cfg.ratio:.0%}" if cfg.until_s is None else f"{cfg.until_s:g} s"
        log(
            f"[observe] {demo.task}/{demo.name}: first {window} "
            f"({observation.t[-1]:.2f} s, {observation.n_samples} samples) of {', '.join(cfg.observe)}"
        )
    return session


def recorded_human(session: Session) -> HumanMotion | None:
    """The session's demo's tracked body as recorded (None: no skeleton), through the model's
    corrected registration (:mod:`.human_fit`): what the scores judge after the fact."""
    human = HumanMotion.from_demo(session.demo, session.robot.settings.human)
    if human is None:
        return None
    return registered(human, model_registration(session.model, str(session.cfg.load_model or "model")))


def recordings_robot(cfg: PipelineConfig, robot: Robot, log: LogFn = print) -> tuple[Robot | None, Dataset]:
    """The robot the demos are recorded on when it is not ``robot`` (its ``[placement] source``: the
    model is retargeted; None: ``robot`` itself) and the demos read with its joints. A placed arm's
    own recordings (a dataset with its joints, e.g. ``synth --robot panda``) are its own."""
    placement = robot.settings.placement
    if placement is None:
        return None, load_data(cfg, log, robot)
    if cfg.dataset is not None:
        try:
            own = load_data(cfg, lambda _msg: None, robot)
            if robot_side(own.all_demos()) == GRIPPER:  # no joints: in the scene of the placement's source
                log(f"[data] {cfg.dataset}: {len(own.all_demos())} demos of gripper poses")
                return load_robot(placement.source), own
            log(f"[data] {cfg.dataset}: {len(own.all_demos())} demos recorded on {robot.settings.name}")
            return None, own
        except (PipelineError, DataError):
            pass  # not recorded on this arm: on the robot it is placed beside
    source = load_robot(placement.source)
    return source, load_data(cfg, log, source)


def observe_window(session: Session, warn: LogFn = warn_stderr) -> Demo:
    """The observed part of the session's demo: its first ``[observation] ratio``, or its samples of
    the first ``until_s`` seconds (all of it, with a warning in the session's, when the demo ends
    before)."""
    cfg, demo = session.cfg, session.demo
    observation = cfg.window.cut(demo, cfg.observe, float(session.model.duration_nominal_s_))
    length = float(demo.t[-1] - demo.t[0])
    if cfg.until_s is not None and length < cfg.until_s:
        note = (
            f"{demo.task}/{demo.name} ends at {length:.2f} s, before the observed window's end "
            f"({cfg.until_s:g} s): planned from all of it"
        )
        warn(note)
        session.warnings.append(note)
    return observation


def check_context(
    cfg: PipelineConfig, demo: Demo, robot: Robot | None = None, objects: ObjectTable | None = None
) -> CheckContext:
    """What the timed-motion checks (:mod:`ipromp_pin.safety`) know about the world when the robot
    plans for ``demo``'s human (``cfg``: the pipeline's settings of that world; ``robot``: whose
    ``[human]`` settings shape the body, loaded from ``cfg`` when None; ``objects``: the task file
    already read, else ``cfg.objects`` is read: the payload is the recognised task's object).

    The human is the demo's tracked skeleton (:meth:`~ipromp_pin.human.HumanMotion.from_demo`), as
    recorded over the whole demo (callers cut it to what the planner knows with ``until``); a demo
    without a skeleton gets the settings' assumed standing human (its handing hand following the
    demo's ``hand_position`` when there is one), which the reports call "assumed human"."""
    robot = robot if robot is not None else load_robot(cfg.robot)
    settings = robot.settings.human
    human = HumanMotion.from_demo(demo, settings)
    if human is None:
        human = HumanMotion.assumed_human(settings, demo.t, demo.extras.get("hand_position"))
    table = objects if objects is not None else load_objects(cfg.objects)
    return CheckContext(task=None, human=human, objects=table)


def check_outputs(cfg: PipelineConfig) -> None:
    """Refuse, before any computation, output paths that cannot be written (a file where the output
    folder should be, a read-only folder, a folder where the model file should be)."""
    atomic.check_output_dir(cfg.out_dir)
    if cfg.save_model is not None:
        atomic.check_output_file(cfg.save_model, "model file")


def robot_data_hint(robot: Robot) -> str:
    """What a robot whose joints the demos do not record needs (one clause)."""
    return (
        f"robot '{robot.settings.name}' needs demonstrations recorded with its own joints "
        f"({', '.join(robot.settings.recorded_arm_joints)}); the built-in synthetic demos and the shipped "
        "recordings are Baxter's left arm (use --robot baxter_left, or a dataset recorded on this robot)"
    )


def check_recorded_joints(ds: Dataset, robot: Robot, what: str) -> None:
    """Refuse, before training, demos whose robot group does not record the robot's arm joints."""
    want = tuple(robot.settings.recorded_arm_joints)
    for d in ds.all_demos():
        have = tuple(d.channel_names.get(ROBOT, ()))
        if have != want:
            raise PipelineError(
                f"{what}: the demos record joints {', '.join(have) or '(none)'}: {robot_data_hint(robot)}"
            )


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
    try:
        ds = read_recordings(cfg.dataset, robot, format=cfg.format, frames=frames, rate_hz=cfg.rate_hz)
    except DataError as exc:
        if exc.field in robot.settings.recorded_arm_joints and exc.problem.startswith("unknown joint name"):
            raise PipelineError(f"{exc}: {robot_data_hint(robot)}") from None
        raise
    log(f"[data] {len(ds.all_demos())} demos of tasks {', '.join(ds.tasks)}")
    return ds


def choose_demo(ds: Dataset, cfg: PipelineConfig, log: LogFn | None = None) -> Demo:
    """The demo to observe (raises :class:`PipelineError` for an unknown task or index). The
    pipeline file's task names a task of the file's dataset: with another dataset given on the
    command line (``--dataset``) and no ``--task``, a task it lacks gives way to the first task
    (``log`` says so)."""
    task = cfg.task or ds.tasks[0]
    if task not in ds.demos and "dataset" in cfg.options and "task" not in cfg.options:
        if log is not None:
            log(
                f"[data] the pipeline's task '{task}' is not in {cfg.dataset}: observing its first task, "
                f"'{ds.tasks[0]}' (--task to choose)"
            )
        task = ds.tasks[0]
    if task not in ds.demos:
        raise PipelineError(
            f"{cfg.where('task')}: unknown task '{task}'{did_you_mean(task, ds.tasks)} "
            f"({', '.join(ds.tasks)})"
        )
    demos = ds.demos[task]
    if not -len(demos) <= cfg.demo < len(demos):
        raise PipelineError(
            f"{cfg.where('demo')}: index {cfg.demo} out of range for {len(demos)} demos of task '{task}' "
            f"(0 to {len(demos) - 1}, or -{len(demos)} to -1 from the end)"
        )
    demo = demos[cfg.demo]
    for group in cfg.observe:
        if group not in demo.groups:
            known = sorted(g for g in demo.groups if g != ROBOT)
            raise PipelineError(
                f"{cfg.where('observe')}: channel group '{group}' not in the data"
                f"{did_you_mean(group, known)} (has: {', '.join(known)})"
            )
    return demo


def get_model(
    cfg: PipelineConfig,
    ds: Dataset,
    held_out: Demo,
    log: LogFn = print,
    robot: Robot | None = None,
    *,
    train: list[Demo] | None = None,
    side: str = ROBOT,
) -> IProMP:
    """Load the saved model, or train one on ``train`` (default: every demo but ``held_out``), with
    the ``robot``'s forward kinematics when given, so that its settings are chosen for the hand-over
    position error (``side``: the robot group, joints or a gripper pose path)."""
    if cfg.load_model is not None:
        log(f"[model] loading {cfg.load_model}")
        model = IProMP.load(cfg.load_model)
        missing = [g for g in cfg.observe if g not in model.observe_]
        if missing:
            raise PipelineError(
                f"{cfg.load_model}: model does not observe {missing} (observes {model.observe_})"
            )
        return model
    if train is None:
        train = [d for d in ds.all_demos() if d is not held_out]
    t0 = time.perf_counter()
    fk, fk_rot = (None, None) if robot is None else gripper_kinematics(robot)
    what = f"{len(train)} demos ({', '.join(cfg.observe)} + {side})"
    fresh = IProMP(observe=cfg.observe, robot_group=side)
    human = None if robot is None else robot.settings.human  # the body's forecast, calibrated
    if cfg.model_cache:
        model, cached = fit_cached(fresh, train, fk, log=log, fk_rot=fk_rot, human=human)
    else:
        model, cached = fresh.fit(train, fk=fk, fk_rot=fk_rot), None
        model = model if human is None else with_forecast(model, train, human)
    if cached is not None:
        log(f"[model] reused the model an earlier run trained on {what}: {cached} (--retrain: train again)")
    else:
        log(f"[model] trained on {what}, {time.perf_counter() - t0:.2f} s")
    if model.human_forecast_ is not None:
        log(f"[model] {forecast_summary(forecast_of(model))}")
    if cfg.save_model is not None:
        model.save(cfg.save_model)  # atomic: an earlier file is replaced only by a complete one
        log(f"[model] saved {cfg.save_model}")
    return model


def model_warnings(cfg: PipelineConfig, ds: Dataset, demo: Demo, model: IProMP) -> list[str]:
    """Warnings about the model: a loaded one that does not match the data or was trained on ``demo``,
    a single-task one, or a ``demo`` far outside the training data."""
    observed = range_warnings(model, demo)
    if cfg.load_model is not None:
        return loaded_model_warnings(model, ds, demo, str(cfg.load_model)) + observed
    single = single_task_warning(model)
    return ([] if single is None else [single]) + observed


def plan_session(session: Session, log: LogFn = print) -> HandoverPlan:
    """The hand-over planned from the session's observation (:func:`ipromp_pin.plans.plan`: what
    ``run`` and ``preview`` plan, with the session's checks and objects; the human as the
    observation shows it), with its retreat when ``[robot] retreat`` is on, scored against the
    session's recorded demo."""
    cfg, ctx = session.cfg, session.context
    planned = plan(
        session.model,
        session.observed(),
        session.robot,
        objects=ctx.objects,
        suite=session.suite,
        control_rate_hz=cfg.control_rate_hz,
        retreat=cfg.retreat,
        log=log,
    )
    return planned.scored(session.demo)


@dataclass
class ReplayChecks(SetupChecks):
    """The replay's checks in the set-up: the demo holds the observed and robot groups and a start
    window of at least 2 samples that ends within it; it holds every group the model observes.

    Attributes:
        observe: The observed groups of the pipeline.
        settings: The closed loop's settings (their start rule).
        start_s: When the robot starts by the rule's time, in [s] (set by :meth:`check_demo` when
            the rule does not need the model, else by :meth:`check_model`).
    """

    observe: tuple[str, ...] | list[str]
    settings: ClosedLoopSettings
    start_s: float = 0.0

    def check_demo(self, demo: Demo) -> None:
        """Refuse a demo without the observed and robot groups or with a start window under 2 samples
        (before training, when the start rule does not depend on the model)."""
        demo.require(list(self.observe))
        robot_side([demo])  # joints or a gripper pose path: where the robot starts
        if self.settings.start_ratio is not None or self.settings.start_after_s is not None:
            self.start_s = start_time(demo, self.settings, math.nan)

    def check_model(self, model: IProMP, demo: Demo) -> None:
        """Refuse a demo without every group the model observes or too short for the start rule."""
        demo.require(list(model.observe_))
        self.start_s = start_time(demo, self.settings, float(model.duration_nominal_s_))


def training_label(cfg: PipelineConfig) -> str:
    """Where the demonstrated limits come from, as the limit profile's ``source`` names it."""
    label = "the built-in synthetic demos" if cfg.dataset is None else Path(str(cfg.dataset)).name
    if cfg.load_model is not None:  # its training demos are unknown: every demo but the replayed one
        label += " (every demo but the replayed one; the loaded model's training set is unknown)"
    return label


def prime_checks(suite: CheckSuite, train: list[Demo], log: LogFn) -> None:
    """Prepare the checks for motions near the demonstrated ones (the self-collision certifier's
    distances near the training motions, computed offline and reused by every re-plan)."""
    t0 = time.perf_counter()
    suite.prime([d.groups[ROBOT] for d in train])
    log(f"[limits] checks primed on {len(train)} training motions ({time.perf_counter() - t0:.1f} s)")


@dataclass
class ReplaySetup:
    """What a replay runs with, set up as ``ipromp-pin replay`` does (:func:`prepare_replay`).

    Attributes:
        session: The pipeline's data, the held-out demo, the model and its training demos, the checks
            (primed on the training motions) and their context.
        profile: The limit profile.
    """

    session: Session
    profile: LimitProfile

    def replay(
        self,
        settings: ClosedLoopSettings,
        suite: CheckSuite | None = None,
        context: CheckContext | None = None,
    ) -> ClosedLoopResult:
        """The closed loop of the held-out demo at its recorded timing, with the session's checks and
        context (or those given: what ``ipromp-pin replay`` runs and ``benchmarks/closed_loop.py``
        times)."""
        s = self.session
        return replay_demo(
            s.model,
            s.robot,
            s.demo,
            self.profile,
            settings,
            s.suite if suite is None else suite,
            s.context if context is None else context,
            source=s.source,
        )

    def scored(self, settings: ClosedLoopSettings) -> tuple[ClosedLoopScore, ClosedLoopResult]:
        """:meth:`replay` scored against the recording (:func:`~ipromp_pin.evaluation.scoring.replay_scored`:
        the torques with the true task's object; with a tracked skeleton the human checks judged
        against the recorded human and the arrival without them), as ``evaluate --closed-loop`` scores
        every trial."""
        s = self.session
        recorded = recorded_human(s)

        def replay(suite: CheckSuite, context: CheckContext) -> ClosedLoopResult:
            return self.replay(settings, suite, context)

        return replay_scored(replay, s.demo, s.robot, s.suite, s.context, recorded, source=s.source)


def prepare_replay(
    cfg: PipelineConfig,
    settings: ClosedLoopSettings,
    limits: str,
    log: LogFn = print,
    warn: LogFn = warn_stderr,
    strict_human: bool = False,
) -> ReplaySetup:
    """Everything before the closed loop: outputs and limits checked, the session prepared (the demo
    held out, the model trained or loaded), the limit profile chosen, the certifier primed
    (``benchmarks/closed_loop.py`` times the replays of this set-up)."""
    check_outputs(cfg)
    robot = load_robot(cfg.robot)
    from_file = check_profile_choice(limits, robot, cfg.source)
    checks = ReplayChecks(cfg.observe, settings)
    session = prepare_session(
        cfg, log, warn, robot=robot, checks=checks, observe=False, strict_human=strict_human
    )
    demo, train = session.demo, session.train
    source = session.source
    poses = predicts_gripper(session.model)  # the demos' robot side is a gripper pose path: no joints
    if source is not None and from_file is None and limits == "demonstrated":
        limits = "conservative"  # the demonstrated peaks are the recorded robot's joints, not this arm's
        why = (
            "is derived from recorded joints, which the demos (a gripper pose path) do not have"
            if poses
            else f"is derived from {source.settings.name}'s recorded joints, which robot "
            f"'{robot.settings.name}' does not have"
        )
        log(f"[limits] the demonstrated profile {why}: its conservative profile instead")
    profile = choose_limit_profile(from_file or limits, robot, train, training_label(cfg))
    log(f"[limits] {profile.name}: {profile.source}")
    if source is None:
        prime_checks(session.suite, train, log)
    else:
        origin = f"gripper poses ({source.settings.name}'s frame)" if poses else source.settings.name
        log(
            f"[retarget] {origin} -> {robot.settings.name}: every re-plan retargeted through "
            "the gripper (its checks not primed on the training motions, which are not this arm's joints)"
        )
    log(
        f"[replay] {demo.task}/{demo.name}: {demo.duration_s:.2f} s at its recorded timing; the robot starts "
        f"{settings.start_text(float(session.model.duration_nominal_s_))} (its sample at "
        f"{checks.start_s:.2f} s), re-plans at "
        f"{settings.replan_rate_hz:g} Hz, control at {settings.control_rate_hz:g} Hz"
    )
    return ReplaySetup(session, profile)
