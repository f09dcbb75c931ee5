"""``ipromp-pin replay``: one held-out demo replayed in the closed loop, and its files.

:func:`run_replay` reads the pipeline's data (the built-in synthetic demos by default), holds the
chosen demo out, trains the model on the others (or loads one), chooses the limit profile, and
replays the demo at its recorded timing (:func:`~ipromp_pin.handover.closed_loop.replay_demo`, simulated
clock). It writes into the output folder:

- ``trajectory.csv`` and ``trajectory.json``: the commanded trajectory at the control rate
  (:mod:`ipromp_pin.outputs.trajectory_files`, as ``run`` writes them);
- ``replans.json``: every re-plan (time, observed ratio, task posterior, predicted hand-over pose
  and time, planned arrival, committed or refused and why);
- ``report.json`` / ``report.txt``: the reached hand-over error, arrival delay, limit profile and
  its source, limit ratios, re-plan counts and cycle times;
- ``limits.toml``: the limit profile used (reusable with ``--limits limits.toml``);
- ``preview.html``: the time-scrubbing preview (:mod:`ipromp_pin.preview.timeline`).

Every input is checked before anything is computed (one-line errors naming the file and field):
the closed-loop settings, the limit profile, the demo's observed and robot groups and the length
of its start window.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import atomic
from ..data import ROBOT, Demo
from ..exceptions import IPrompPinError, PipelineError
from ..handover.closed_loop import (
    LIMIT_TOLERANCE,
    ClosedLoopResult,
    ClosedLoopSettings,
    replay_demo,
    start_time,
)
from ..handover.one_shot import LogFn, check_model_joints
from ..handover.score import ARRIVAL_TOLERANCE_M, ClosedLoopScore, score_closed_loop
from ..motion.limits import (
    PROFILE_NAMES,
    LimitProfile,
    conservative_profile,
    demonstrated_profile,
    read_limit_profile,
)
from ..outputs.trajectory_files import trajectory_csv_text, trajectory_json_text
from ..preview import PreviewContent
from ..preview.timeline import TimelineEvent, render_timeline_html
from ..promp import IProMP
from ..robot import Robot, ee_positions, load_robot
from ..robot.clearance import ClearanceCertifier
from .config import PipelineConfig
from .model_warnings import warn_stderr
from .pipeline import check_outputs, choose_demo, get_model, load_data, model_warnings, preview_visual_model

REPLAY_FORMAT = "ipromp_pin.replay"
"""Value of the replay ``report.json``'s ``format`` field."""

REPLAY_VERSION = 1

REPLAY_OUTPUTS = (
    "trajectory.csv",
    "trajectory.json",
    "replans.json",
    "report.json",
    "report.txt",
    "limits.toml",
    "preview.html",
)
"""Every file ``ipromp-pin replay`` may write into its output folder (committed together, see
:class:`ipromp_pin.atomic.OutputSet`; an earlier replay's files that this one does not write are removed)."""

TRAJECTORY_OUTPUTS = ("trajectory.csv", "trajectory.json")
"""The outputs a robot executes: written only when the replay passed (or marked, when allowed)."""

_FILE_KEYS = {
    "trajectory.csv": "trajectory_csv",
    "trajectory.json": "trajectory_json",
    "replans.json": "replans",
    "report.json": "report",
    "report.txt": "report_text",
    "limits.toml": "limits",
    "preview.html": "preview",
}


@dataclass
class ReplayOutcome:
    """The replay and what it reached.

    Attributes:
        demo: The replayed demo.
        result: The closed loop's commanded trajectory and re-plans.
        score: Hand-over error, arrival delay, limit ratios, collisions.
        files: Written files by kind.
        passed: Whether the commanded trajectory passed (:func:`replay_passed`).
    """

    demo: Demo
    result: ClosedLoopResult
    score: ClosedLoopScore
    files: dict[str, Path]
    passed: bool = True


def check_limits_choice(limits: str, robot: Robot, source: str) -> LimitProfile | None:
    """Validate ``--limits`` before any computation: a built-in name (None) or a profile file (read)."""
    if limits in PROFILE_NAMES:
        return None
    if not Path(limits).suffix and not Path(limits).exists():
        raise PipelineError(
            f"{source}: field 'limits': unknown limit profile '{limits}' "
            f"(use {' or '.join(PROFILE_NAMES)}, or a profile file)"
        )
    return read_limit_profile(limits, robot)


def choose_profile(
    limits: str, robot: Robot, train: list[Demo], label: str, from_file: LimitProfile | None
) -> LimitProfile:
    """The limit profile: the settings' conservative one, the one derived from ``train``, or a file's."""
    if from_file is not None:
        return from_file
    if limits == "conservative":
        return conservative_profile(robot)
    return demonstrated_profile(robot, train, robot.settings.demonstrated_limits, label)


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

    The commanded trajectory is written only when it passed (no commanded sample in collision, every
    limit ratio at most 1), unless ``allow_failing_checks`` (then marked, as ``run`` marks its files).
    """
    t_start = time.perf_counter()
    settings = settings.validate(f"{cfg.source}: closed loop")
    check_outputs(cfg)
    robot = load_robot(cfg.robot)
    from_file = check_limits_choice(limits, robot, cfg.source)
    ds = load_data(cfg, log, robot)
    demo = choose_demo(ds, cfg)
    demo.require(list(cfg.observe) + [ROBOT])
    start_s = start_time(demo, settings.start_ratio)
    model = get_model(cfg, ds, demo, log, robot)
    check_model_joints(model, robot)
    demo.require(list(model.observe_))
    warnings = model_warnings(cfg, ds, demo, model)
    for w in warnings:
        warn(w)
    train = [d for d in ds.all_demos() if d is not demo]
    label = "the built-in synthetic demos" if cfg.dataset is None else Path(str(cfg.dataset)).name
    if cfg.load_model is not None:  # its training demos are unknown: every demo but the replayed one
        label += " (every demo but the replayed one; the loaded model's training set is unknown)"
    profile = choose_profile(limits, robot, train, label, from_file)
    log(f"[limits] {profile.name}: {profile.source}")
    certifier = ClearanceCertifier(robot)
    t0 = time.perf_counter()
    for d in train:  # offline: distances near the demonstrated motions, reused by every re-plan
        certifier.certify(d.groups[ROBOT])
    primed = time.perf_counter() - t0
    log(f"[limits] collision certifier primed on {len(train)} training motions ({primed:.1f} s)")
    log(
        f"[replay] {demo.task}/{demo.name}: {demo.duration_s:.2f} s at its recorded timing; the robot starts "
        f"after {settings.start_ratio:.0%} ({start_s:.2f} s), re-plans at {settings.replan_rate_hz:g} Hz, "
        f"control at {settings.control_rate_hz:g} Hz"
    )
    result = replay_demo(model, robot, demo, profile, settings, certifier)
    score = score_closed_loop(result, demo, robot)
    with atomic.OutputSet(cfg.out_dir, managed=REPLAY_OUTPUTS) as out:
        write_trajectory = replay_passed(score) or allow_failing_checks
        names = [n for n in REPLAY_OUTPUTS if write_trajectory or n not in TRAJECTORY_OUTPUTS]
        if not preview:
            names.remove("preview.html")
        report = report_dict(result, score, demo, model, warnings)
        report["files"] = {_FILE_KEYS[n]: str(out.path(n)) for n in names}
        stage_replay(out, demo, result, score, report, allow_failing_checks=allow_failing_checks)
        if preview:
            t0 = time.perf_counter()
            html = replay_preview_html(demo, result, score, robot, preview_visual_model(robot))
            out.write_text("preview.html", html)
            log(f"[preview] {out.path('preview.html')} ({time.perf_counter() - t0:.1f} s)")
        files = out.commit()
    log(summary_lines(demo, result, score, time.perf_counter() - t_start))
    return ReplayOutcome(
        demo, result, score, {_FILE_KEYS[n]: p for n, p in files.items()}, replay_passed(score)
    )


def _round(x: object) -> object:
    if isinstance(x, float | np.floating):
        return round(float(x), 6)
    if isinstance(x, dict):
        return {k: _round(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_round(v) for v in x]
    return x


def replans_json(result: ClosedLoopResult, demo: Demo) -> dict:
    """``replans.json``: settings, limit profile and one record per re-plan."""
    duration = float(demo.t[-1] - demo.t[0])
    rows = []
    for r in result.replans:
        d = r.to_dict()
        d["observed_ratio"] = round(r.observed_until_s / duration, 4) if duration > 0 else None
        rows.append(d)
    return {
        "format": "ipromp_pin.replans",
        "version": 1,
        "demo": {"task": demo.task, "name": demo.name, "source": demo.source, "duration_s": duration},
        "settings": result.settings.to_dict(),
        "limit_profile": result.profile.to_dict(),
        "start_s": result.start_s,
        "stopped": result.stopped,
        "replans": rows,
    }


def report_dict(
    result: ClosedLoopResult,
    score: ClosedLoopScore,
    demo: Demo,
    model: IProMP | None = None,
    warnings: list[str] | None = None,
) -> dict:
    """The machine-readable replay report (JSON-serialisable; its schema:
    ``ipromp_pin/schemas/replay_report.schema.json``)."""
    cycles = np.array([r.cycle_ms for r in result.replans]) if result.replans else np.zeros(0)
    reasons: dict[str, int] = {}
    for r in result.replans:
        if not r.committed:
            key = r.reason.split(":")[0]
            reasons[key] = reasons.get(key, 0) + 1
    committed = [r for r in result.replans if r.committed]
    last = committed[-1] if committed else None
    return _round(
        {
            "format": REPLAY_FORMAT,
            "version": REPLAY_VERSION,
            "demo": {"task": demo.task, "name": demo.name, "source": demo.source},
            "warnings": list(warnings or []),
            "passed": replay_passed(score),
            "model": None
            if model is None
            else {"observe": list(model.observe_), "noise_ratio": float(model.noise_ratio_)},
            "settings": result.settings.to_dict(),
            "limit_profile": result.profile.to_dict(),
            "start_s": result.start_s,
            "handover_error_cm": score.handover_error_cm,
            "final_error_cm": score.final_error_cm,
            "arrival_delay_s": score.arrival_delay_s,
            "arrival_s": score.arrival_s,
            "recorded_arrival_s": score.recorded_arrival_s,
            "arrival_tolerance_m": ARRIVAL_TOLERANCE_M,
            "handover_time_s": score.handover_time_s,
            "rest_s": score.rest_s,
            "limit_ratios": dict(zip(("velocity", "acceleration", "jerk"), score.limit_ratios, strict=True)),
            "max_limit_ratio": score.max_limit_ratio,
            "position_excess_rad": score.position_excess_rad,
            "collisions": score.collisions,
            "replans": score.replans,
            "committed_replans": result.n_committed,
            "refused_replans": score.refused_replans,
            "refusals": reasons,
            "stopped": result.stopped,
            "final_task": score.final_task,
            "final_posterior": last.posterior if last else {},
            "predicted_handover_s": last.predicted_handover_s if last else None,
            "cycle_ms": {
                "median": float(np.median(cycles)) if cycles.size else None,
                "p95": float(np.percentile(cycles, 95)) if cycles.size else None,
                "max": float(cycles.max()) if cycles.size else None,
            },
        }
    )


def report_text(
    result: ClosedLoopResult, score: ClosedLoopScore, demo: Demo, warnings: list[str] | None = None
) -> str:
    """The human-readable replay report."""
    p = result.profile
    s = result.settings
    lines = [f"Warning: {w}" for w in warnings or []]
    lines += [
        f"Replayed: {demo.task}/{demo.name} ({demo.source}), {score.handover_time_s:.2f} s",
        f"Closed loop: start after {s.start_ratio:.0%} ({result.start_s:.2f} s), re-plan "
        f"{s.replan_rate_hz:g} Hz, control {s.control_rate_hz:g} Hz, blend {s.blend_s:g} s, "
        f"freeze phase {s.freeze_phase:g}",
        f"Limit profile: {p.name} ({p.source})",
        f"Re-plans: {score.replans} ({result.n_committed} committed, {score.refused_replans} refused); "
        f"final task {score.final_task or '(none)'}",
        f"Hand-over error at the recorded hand-over time: {score.handover_error_cm:.2f} cm; where the motion "
        f"comes to rest: {score.final_error_cm:.2f} cm",
        f"Arrival: {score.arrival_s:.2f} s (recorded robot {score.recorded_arrival_s:.2f} s): delay "
        f"{score.arrival_delay_s:+.2f} s; at rest at {score.rest_s:.2f} s",
        "Limits: max ratio velocity {:.3f}, acceleration {:.3f}, jerk {:.3f}; position excess {:.1e} rad; "
        "collisions {}".format(*score.limit_ratios, score.position_excess_rad, score.collisions),
    ]
    if result.stopped:
        lines.append(f"Re-planning stopped: {result.stopped}")
    refused = [r for r in result.replans if not r.committed]
    for r in refused[:10]:
        lines.append(f"  refused at {r.t_s:.2f} s: {r.reason}")
    if len(refused) > 10:
        lines.append(f"  ... {len(refused) - 10} more refused re-plans in replans.json")
    return "\n".join(lines)


def summary_lines(demo: Demo, result: ClosedLoopResult, score: ClosedLoopScore, elapsed_s: float) -> str:
    """End-of-run lines on the console."""
    cycles = [r.cycle_ms for r in result.replans]
    return "\n".join(
        [
            "",
            f"Replayed {demo.task}/{demo.name}: final task {score.final_task or '(none)'}; "
            f"{score.replans} re-plans, {score.refused_replans} refused",
            f"Hand-over error {score.handover_error_cm:.2f} cm at the recorded hand-over time; arrival delay "
            f"{score.arrival_delay_s:+.2f} s ({result.profile.name} limits, max ratio "
            f"{score.max_limit_ratio:.3f}); collisions {score.collisions}",
            f"Re-plan cycle median {np.median(cycles):.2f} ms" if cycles else "No re-plan",
            f"Total {elapsed_s:.1f} s",
        ]
    )


def replay_passed(score: ClosedLoopScore) -> bool:
    """Whether the commanded trajectory is safe to execute: no commanded sample in collision and every
    velocity, acceleration and jerk within the limit profile at every control sample."""
    return score.collisions == 0 and score.max_limit_ratio <= 1.0 + LIMIT_TOLERANCE


def stage_replay(
    out: atomic.OutputSet,
    demo: Demo,
    result: ClosedLoopResult,
    score: ClosedLoopScore,
    report: dict,
    *,
    allow_failing_checks: bool = False,
) -> None:
    """Stage the trajectory files (when :func:`replay_passed`, or marked with
    ``allow_failing_checks``), ``replans.json``, ``limits.toml`` and the reports in ``out``."""
    if replay_passed(score) or allow_failing_checks:
        comment, extra = None, None
        if not replay_passed(score):
            failures = [
                name
                for name, bad in (
                    ("collisions", score.collisions > 0),
                    ("limits", score.max_limit_ratio > 1.0 + LIMIT_TOLERANCE),
                )
                if bad
            ]
            comment = (
                f"ipromp_pin: checks FAILED ({', '.join(failures)}); "
                "written because of --allow-failing-checks"
            )
            extra = {"ipromp_pin_checks": {"passed": False, "failures": failures}}
        out.write_text("trajectory.csv", trajectory_csv_text(result.trajectory, comment))
        out.write_text("trajectory.json", trajectory_json_text(result.trajectory, extra=extra))
    out.write_text("replans.json", json.dumps(_round(replans_json(result, demo)), indent=1, allow_nan=False))
    out.write_text("limits.toml", result.profile.to_toml())
    out.write_text("report.json", json.dumps(report, indent=1, allow_nan=False))
    out.write_text("report.txt", report_text(result, score, demo, report.get("warnings", [])) + "\n")


def replay_preview_html(
    demo: Demo, result: ClosedLoopResult, score: ClosedLoopScore, robot: Robot, visual_model: object
) -> str:
    """The time-scrubbing ``preview.html`` of a replay (one self-contained page)."""
    traj = result.trajectory
    tasks = list(result.replans[0].posterior) if result.replans else []
    committed = [r for r in result.replans if r.committed]
    hand = hand_t = None
    if "hand_position" in demo.extras:
        hp = demo.extras["hand_position"]
        ok = np.all(np.isfinite(hp), axis=1)
        if ok.sum() >= 2:
            hand, hand_t = hp[ok], (demo.t - demo.t[0])[ok]
    plans = iter(result.plans)
    events = []
    for r in result.replans:
        path_m = None
        if r.committed:
            q = next(plans).q
            path_m = ee_positions(robot, q[:: max(1, q.shape[0] // 40)])
        events.append(
            TimelineEvent(
                t_s=r.t_s,
                observed_until_s=r.observed_until_s,
                task=r.task,
                posterior=[r.posterior[t] for t in tasks] if r.posterior else [],
                predicted_handover_s=r.predicted_handover_s,
                handover_point=None
                if r.predicted_handover_position_m is None
                else np.asarray(r.predicted_handover_position_m),
                planned_path=path_m if path_m is not None and path_m.shape[0] >= 2 else None,
                arrival_s=r.planned_arrival_s,
                committed=r.committed,
                reason=r.reason,
            )
        )
    final = committed[-1] if committed else None
    content = PreviewContent(
        model=robot.model,
        visual_model=visual_model,
        collision_model=robot.collision_model,
        t_s=traj.t_s,
        q=traj.q,
        joint_names=robot.joint_names,
        q_full=robot.full_configuration(traj.q[0]),
        ee_mean=ee_positions(robot, traj.q[:: max(1, traj.n_samples // 200)]),
        ee_truth=ee_positions(robot, demo.groups[ROBOT]),
        hand_path=hand,
        hand_t_s=hand_t,
        task=final.task if final else "",
        tasks=tasks,
        posterior=np.array([final.posterior[t] for t in tasks]) if final else None,
        feasibility=[
            (
                "re-plans",
                score.refused_replans == 0,
                f"{result.n_committed} committed, {score.refused_replans} refused",
            ),
            (
                "limits",
                score.max_limit_ratio <= 1 + 1e-6,
                f"max ratio {score.max_limit_ratio:.3f} ({result.profile.name})",
            ),
            ("collisions", score.collisions == 0, f"{score.collisions} commanded samples in contact"),
        ],
        title=f"ipromp_pin replay: {demo.task}/{demo.name}",
    )
    summary = [
        f"Hand-over error {score.handover_error_cm:.1f} cm at the recorded hand-over time "
        f"({score.handover_time_s:.2f} s); {score.final_error_cm:.1f} cm at rest",
        f"Arrival {score.arrival_s:.2f} s vs recorded {score.recorded_arrival_s:.2f} s "
        f"(delay {score.arrival_delay_s:+.2f} s); {result.profile.name} limits",
        "Blue: commanded gripper path; cyan: the latest plan; purple: recorded robot; green: hand observed.",
    ]
    return render_timeline_html(content, events, motion_s=score.handover_time_s, summary=summary)


def replay_error(exc: IPrompPinError) -> str:
    """The one-line message of a replay error."""
    return str(exc).splitlines()[0]
