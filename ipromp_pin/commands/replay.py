"""``ipromp-pin replay``: one held-out demo replayed in the closed loop, and its files.

:func:`run_replay` sets up the command as ``run`` does
(:func:`~ipromp_pin.commands.setup.prepare_session`: the pipeline's data, the chosen demo held out,
the model trained on the others or loaded), chooses the limit profile, and replays the demo at its
recorded timing (:func:`~ipromp_pin.planning.closed_loop.replay_demo`, simulated clock). It writes
into the output folder:

- ``trajectory.csv`` and ``trajectory.json``: the commanded trajectory at the control rate
  (:mod:`ipromp_pin.outputs.trajectory_files`, as ``run`` writes them);
- ``replans.json``: every re-plan (time, observed ratio, task posterior, predicted hand-over pose
  and time, planned arrival, committed or refused and why);
- ``report.json`` / ``report.txt``: the reached hand-over error, arrival delay, limit profile and
  its source, limit ratios, re-plan counts and cycle times;
- ``limits.toml``: the limit profile used (reusable with ``--limits limits.toml``);
- ``preview.html``: the time-scrubbing preview (:mod:`ipromp_pin.preview.timeline`).

The files are listed in :mod:`ipromp_pin.outputs.files`, staged by :mod:`ipromp_pin.outputs.staging`
and built by :mod:`ipromp_pin.outputs.replay_report`. Every input is checked before anything is
computed (one-line errors naming the file and field): the closed-loop settings (by the caller: the
command line validates them), the limit profile, the demo's observed and robot groups and the
length of its start window.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from .. import atomic
from ..data import ROBOT, Demo
from ..evaluation.scoring import ClosedLoopScore, replay_scored
from ..human import HumanMotion
from ..motion.limits import LimitProfile, check_profile_choice, choose_limit_profile
from ..outputs.files import REPLAY, command_outputs, keyed, trajectory_outputs
from ..outputs.preview_content import replay_preview_html
from ..outputs.replay_report import (
    replans_text,
    replay_failures,
    replay_passed,
    report_dict,
    report_text,
    summary_lines,
)
from ..outputs.staging import stage_report, stage_trajectory
from ..planning.closed_loop import ClosedLoopResult, ClosedLoopSettings, replay_demo, start_time
from ..planning.one_shot import LogFn
from ..promp import IProMP
from ..robot import load_robot
from ..safety import CheckContext, CheckSuite
from .config import PipelineConfig
from .meshes import preview_visual_model
from .model_warnings import warn_stderr
from .setup import Session, SetupChecks, check_outputs, prepare_session

REPLAY_OUTPUTS = command_outputs(REPLAY)
"""Every file ``ipromp-pin replay`` may write into its output folder (:mod:`ipromp_pin.outputs.files`;
committed together, see :class:`ipromp_pin.atomic.OutputSet`; an earlier replay's files that this one
does not write are removed)."""

TRAJECTORY_OUTPUTS = trajectory_outputs(REPLAY)
"""The outputs a robot executes: written only when the replay passed (or marked, when allowed)."""


@dataclass
class ReplayOutcome:
    """The replay and what it reached.

    Attributes:
        demo: The replayed demo.
        result: The closed loop's commanded trajectory and re-plans.
        score: Hand-over error, arrival delay, limit ratios, collisions.
        files: Written files by kind.
        passed: Whether the commanded trajectory passed
            (:func:`~ipromp_pin.outputs.replay_report.replay_passed`).
    """

    demo: Demo
    result: ClosedLoopResult
    score: ClosedLoopScore
    files: dict[str, Path]
    passed: bool = True


@dataclass
class ReplayChecks(SetupChecks):
    """The replay's checks in the set-up: the demo holds the observed and robot groups and a start
    window of at least 2 samples; it holds every group the model observes.

    Attributes:
        observe: The observed groups of the pipeline.
        start_ratio: The fraction of the demo observed before the robot starts.
        start_s: When the robot starts, in [s] (set by :meth:`check_demo`).
    """

    observe: tuple[str, ...] | list[str]
    start_ratio: float
    start_s: float = 0.0

    def check_demo(self, demo: Demo) -> None:
        """Refuse a demo without the observed and robot groups or with a start window under 2 samples."""
        demo.require(list(self.observe) + [ROBOT])
        self.start_s = start_time(demo, self.start_ratio)

    def check_model(self, model: IProMP, demo: Demo) -> None:
        """Refuse a demo without every group the model observes."""
        demo.require(list(model.observe_))


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
        )

    def scored(self, settings: ClosedLoopSettings) -> tuple[ClosedLoopScore, ClosedLoopResult]:
        """:meth:`replay` scored against the recording (:func:`~ipromp_pin.evaluation.scoring.replay_scored`:
        the torques with the true task's object; with a tracked skeleton the human checks judged
        against the recorded human and the arrival without them), as ``evaluate --closed-loop`` scores
        every trial."""
        s = self.session
        recorded = HumanMotion.from_demo(s.demo, s.robot.settings.human)

        def replay(suite: CheckSuite, context: CheckContext) -> ClosedLoopResult:
            return self.replay(settings, suite, context)

        return replay_scored(replay, s.demo, s.robot, s.suite, s.context, recorded)


def prepare_replay(
    cfg: PipelineConfig,
    settings: ClosedLoopSettings,
    limits: str,
    log: LogFn = print,
    warn: LogFn = warn_stderr,
) -> ReplaySetup:
    """Everything before the closed loop: outputs and limits checked, the session prepared (the demo
    held out, the model trained or loaded), the limit profile chosen, the certifier primed
    (``benchmarks/closed_loop.py`` times the replays of this set-up)."""
    check_outputs(cfg)
    robot = load_robot(cfg.robot)
    from_file = check_profile_choice(limits, robot, cfg.source)
    checks = ReplayChecks(cfg.observe, settings.start_ratio)
    session = prepare_session(cfg, log, warn, robot=robot, checks=checks, observe=False)
    demo, train = session.demo, session.train
    profile = choose_limit_profile(from_file or limits, robot, train, training_label(cfg))
    log(f"[limits] {profile.name}: {profile.source}")
    prime_checks(session.suite, train, log)
    log(
        f"[replay] {demo.task}/{demo.name}: {demo.duration_s:.2f} s at its recorded timing; the robot starts "
        f"after {settings.start_ratio:.0%} ({checks.start_s:.2f} s), re-plans at "
        f"{settings.replan_rate_hz:g} Hz, control at {settings.control_rate_hz:g} Hz"
    )
    return ReplaySetup(session, profile)


def run_replay(
    cfg: PipelineConfig,
    settings: ClosedLoopSettings,
    limits: str = "demonstrated",
    preview: bool = True,
    log: LogFn = print,
    warn: LogFn = warn_stderr,
    *,
    allow_failing_checks: bool = False,
) -> ReplayOutcome:
    """Replay the pipeline's held-out demo in the closed loop and write the files into ``cfg.out_dir``
    together (:data:`REPLAY_OUTPUTS`): complete, or the folder's earlier files untouched.

    ``settings`` are validated by the caller (:meth:`ClosedLoopSettings.validate`; the command line
    does it). The commanded trajectory is written only when it passed (no commanded sample in
    collision, every limit ratio at most 1), unless ``allow_failing_checks`` (then marked, as ``run``
    marks its files).
    """
    t_start = time.perf_counter()
    setup = prepare_replay(cfg, settings, limits, log, warn)
    session = setup.session
    demo = session.demo
    score, result = setup.scored(settings)
    truth = CheckContext(task=demo.task, objects=session.context.objects)  # the files' torques
    result.trajectory = session.suite.annotate(result.trajectory, truth)
    with atomic.OutputSet(cfg.out_dir, managed=REPLAY_OUTPUTS) as out:
        _stage_files(out, session, result, score, allow_failing_checks, preview, log)
        files = keyed(out.commit())
    log(summary_lines(demo, result, score, time.perf_counter() - t_start))
    return ReplayOutcome(demo, result, score, files, replay_passed(score))


def _stage_files(
    out: atomic.OutputSet,
    session: Session,
    result: ClosedLoopResult,
    score: ClosedLoopScore,
    allow_failing_checks: bool,
    preview: bool,
    log: LogFn,
) -> None:
    """Stage the replay's files: the trajectory (:func:`~ipromp_pin.outputs.staging.stage_trajectory`),
    ``replans.json``, ``limits.toml``, ``preview.html`` and, last, the reports."""
    demo = session.demo
    stage_trajectory(
        out, result.trajectory, replay_failures(score), allow_failing_checks=allow_failing_checks
    )
    out.write_text("replans.json", replans_text(result, demo))
    out.write_text("limits.toml", result.profile.to_toml())
    if preview:
        t0 = time.perf_counter()
        visual = preview_visual_model(session.robot)
        ctx = session.context
        html = replay_preview_html(demo, result, score, session.robot, visual, ctx.human, ctx.objects)
        out.write_text("preview.html", html)
        log(f"[preview] {out.path('preview.html')} ({time.perf_counter() - t0:.1f} s)")
    report = report_dict(result, score, demo, session.model, session.warnings)
    stage_report(out, report, report_text(result, score, demo, session.warnings))
