"""The replay's reports: ``replans.json``, ``report.json``, ``report.txt`` and the console summary.

:func:`replans_json` lists every re-plan of the closed loop; :func:`report_dict` is the replay's
``report.json`` (schema ``ipromp_pin/schemas/replay_report.schema.json``, fields in
``docs/closed_loop.md``), :func:`report_text` its ``report.txt`` and :func:`summary_lines` the
end-of-replay lines. :func:`replay_failures` says whether the commanded trajectory may be executed.
"""

from __future__ import annotations

import json

import numpy as np

from ..data import Demo
from ..evaluation.scoring import ARRIVAL_TOLERANCE_M, ClosedLoopScore
from ..human import HumanMotion
from ..motion.trajectory import Trajectory
from ..planning.closed_loop import ClosedLoopResult
from ..promp import IProMP
from ..robot.objects import ObjectTable
from ..safety import HUMAN_CHECKS, CheckContext, CheckReport, CheckSuite
from ..safety.speed_limits import TOLERANCE as LIMIT_TOLERANCE

REPLAY_FORMAT = "ipromp_pin.replay"
"""Value of the replay ``report.json``'s ``format`` field."""

REPLAY_VERSION = 1
"""Value of the replay ``report.json``'s ``version`` field."""


def _round(x: object) -> object:
    """``x`` with every float rounded to 6 decimals (in dicts, lists and tuples too)."""
    if isinstance(x, float | np.floating):
        return round(float(x), 6)
    if isinstance(x, dict):
        return _round_dict(x)
    if isinstance(x, list | tuple):
        return [_round(v) for v in x]
    return x


def _round_dict(x: dict) -> dict:
    """The dict ``x`` with every float rounded to 6 decimals (see :func:`_round`)."""
    return {k: _round(v) for k, v in x.items()}


def finite_or_none(x: float) -> float | None:
    """``x``, or None when it is NaN or infinite (JSON has no NaN)."""
    return float(x) if np.isfinite(x) else None


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
        "robot": result.robot,
        "source_robot": result.source_robot or None,
        "settings": result.settings.to_dict(),
        "limit_profile": result.profile.to_dict(),
        "start_s": result.start_s,
        "start_reason": result.start_reason,
        "stopped": result.stopped,
        "unknown_events": [e.to_dict() for e in result.unknown_events],
        "replans": rows,
    }


def unknown_task_dict(result: ClosedLoopResult) -> dict:
    """The replay report's ``unknown_task``: when the observation turned unknown after the start and
    the robot stopped, held and retreated (times [s] on the report's clock, the human's motion's start
    at 0; :mod:`~ipromp_pin.planning.unknown_stop`)."""
    hold = next((e.t_s for e in result.unknown_events if e.kind == "hold"), None)
    return {
        "require_known": result.settings.require_known,
        "hold_s": result.settings.unknown_hold_s,
        "stop_s": result.first_event_s("unknown"),
        "hold_start_s": hold,
        "retreat_s": result.first_event_s("retreat"),
        "events": [e.to_dict() for e in result.unknown_events],
    }


def unknown_lines(result: ClosedLoopResult) -> list[str]:
    """One line per stop-hold-retreat event (none when the observation stayed known after the start)."""
    words = {
        "unknown": "turned unknown, stopping",
        "hold": "held at rest",
        "resume": "resumed",
        "retreat": "retreated",
    }
    return [f"Unknown task: {words[e.kind]} at {e.t_s:.2f} s: {e.detail}" for e in result.unknown_events]


def retarget_summary(result: ClosedLoopResult) -> dict | None:
    """The replay report's ``retarget``: how the re-plans' references came from the model's robot
    through the gripper (None: the arm's own model). Residuals are the largest over the committed
    re-plans, times over every retargeted one."""
    if not result.source_robot:
        return None
    moved = [r for r in result.replans if r.retarget is not None]
    kept = [r.retarget for r in moved if r.committed and r.retarget is not None]
    ms = np.array([r.retarget["ms"] for r in moved if r.retarget is not None])

    def largest(key: str) -> float | None:
        return max(float(d[key]) for d in kept) if kept else None

    return {
        "source_robot": result.source_robot,
        "retargeted_replans": len(moved),
        "unreachable_replans": sum(r.reason.startswith("unreachable") for r in result.replans),
        "ik_residual_mm": largest("ik_residual_mm"),
        "ik_residual_deg": largest("ik_residual_deg"),
        "max_path_residual_mm": largest("max_path_residual_mm"),
        "ms": {
            "median": float(np.median(ms)) if ms.size else None,
            "max": float(ms.max()) if ms.size else None,
        },
    }


def replay_checks(
    trajectory: Trajectory,
    suite: CheckSuite,
    task: str,
    objects: ObjectTable | None,
    human: HumanMotion | None,
) -> CheckReport:
    """The commanded motion (on the human's clock) judged after the fact, as the replay's score
    judges it (:func:`~ipromp_pin.evaluation.scoring.replay_scored`, the same checks on the same
    inputs): ``suite``'s joint-torque check with the object of the TRUE ``task`` in ``objects``, and
    with ``human`` (the recorded human, every sample known; None: no tracked skeleton) its human
    checks against it. The report's ``checks``, and what the preview's check list and panels show."""
    verdicts = []
    torques = suite.only(["joint_torques"])
    if torques.checks:
        verdicts += torques.run(trajectory, CheckContext(task=task, objects=objects))
    humans = suite.only(HUMAN_CHECKS)
    if human is not None and humans.checks:
        verdicts += humans.run(trajectory, CheckContext(human=human))
    return CheckReport(verdicts)


def report_dict(
    result: ClosedLoopResult,
    score: ClosedLoopScore,
    demo: Demo,
    model: IProMP | None = None,
    warnings: list[str] | None = None,
    checks: CheckReport | None = None,
) -> dict:
    """The machine-readable replay report (JSON-serialisable; its schema:
    ``ipromp_pin/schemas/replay_report.schema.json``); ``checks``: the commanded motion's verdicts
    judged after the fact (:func:`replay_checks`; None: none)."""
    cycles = np.array([r.cycle_ms for r in result.replans]) if result.replans else np.zeros(0)
    reasons: dict[str, int] = {}
    for r in result.replans:
        if not r.committed:
            key = r.reason.split(":")[0]
            reasons[key] = reasons.get(key, 0) + 1
    committed = [r for r in result.replans if r.committed and not r.action]  # toward a hand-over
    last = committed[-1] if committed else None
    return _round_dict(
        {
            "format": REPLAY_FORMAT,
            "version": REPLAY_VERSION,
            "demo": {"task": demo.task, "name": demo.name, "source": demo.source},
            "robot": result.robot,
            "tool": result.tool,
            "retarget": retarget_summary(result),
            "warnings": list(warnings or []),
            "passed": replay_passed(score),
            "failures": replay_failures(score) or [],
            "failure_reason": failure_reason(result, score),
            "model": None
            if model is None
            else {"observe": list(model.observe_), "noise_ratio": float(model.noise_ratio_)},
            "settings": result.settings.to_dict(),
            "limit_profile": result.profile.to_dict(),
            "start_s": result.start_s,
            "start_reason": result.start_reason,
            "handover_error_cm": score.handover_error_cm,
            "handover_orientation_error_deg": finite_or_none(score.handover_orientation_error_deg),
            "peak_torque_ratio": finite_or_none(score.peak_torque_ratio),
            "human_min_separation_m": score.human_min_separation_m,
            "protective_distance_time_s": score.protective_distance_time_s,
            "contact_speed_violations": score.contact_speed_violations,
            "arrival_delay_without_human_s": score.arrival_delay_without_human_s,
            "checks": {} if checks is None else checks.to_dict(),
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
            "unknown_task": unknown_task_dict(result),
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
    result: ClosedLoopResult,
    score: ClosedLoopScore,
    demo: Demo,
    warnings: list[str] | None = None,
    checks: CheckReport | None = None,
) -> str:
    """The human-readable replay report (``checks``: the commanded motion's verdicts judged after the
    fact, one line each)."""
    p = result.profile
    s = result.settings
    lines = [f"Warning: {w}" for w in warnings or []]
    lines += [
        f"Replayed: {demo.task}/{demo.name} ({demo.source}), {score.handover_time_s:.2f} s",
        f"Closed loop: start {result.start_rule}: started {result.start_reason or 'never'}; re-plan "
        f"{s.replan_rate_hz:g} Hz, control {s.control_rate_hz:g} Hz, blend {s.blend_s:g} s, "
        f"freeze phase {s.freeze_phase:g}",
        f"Limit profile: {p.name} ({p.source})",
        *retarget_lines(result),
        f"Re-plans: {score.replans} ({result.n_committed} committed, {score.refused_replans} refused; "
        f"{slowed_text(result)}); final task {score.final_task or '(none)'}",
        f"Hand-over error at the recorded hand-over time: {score.handover_error_cm:.2f} cm; where the motion "
        f"comes to rest: {score.final_error_cm:.2f} cm; gripper orientation error at the hand-over "
        f"{score.handover_orientation_error_deg:.1f} deg; peak joint torque "
        f"{score.peak_torque_ratio:.0%} of the effort limits",
        f"Arrival: {score.arrival_s:.2f} s (recorded robot {score.recorded_arrival_s:.2f} s): delay "
        f"{score.arrival_delay_s:+.2f} s; at rest at {score.rest_s:.2f} s",
        "Limits: max ratio velocity {:.3f}, acceleration {:.3f}, jerk {:.3f}; position excess {:.1e} rad; "
        "collisions {}".format(*score.limit_ratios, score.position_excess_rad, score.collisions),
    ]
    if checks is not None and checks.verdicts:
        lines += ["The commanded motion judged after the fact (times on the human's clock):", *checks.lines()]
    if not replay_passed(score):
        lines.append(f"FAILED: {failure_reason(result, score)}")
    if result.stopped:
        lines.append(f"Re-planning stopped: {result.stopped}")
    lines += unknown_lines(result)
    refused = [r for r in result.replans if not r.committed]
    for r in refused[:10]:
        lines.append(f"  refused at {r.t_s:.2f} s: {r.reason}")
    if len(refused) > 10:
        lines.append(f"  ... {len(refused) - 10} more refused re-plans in replans.json")
    return "\n".join(lines)


def slowed_text(result: ClosedLoopResult) -> str:
    """How many committed re-plans the checks slowed, and how many of them only where they asked."""
    slowed = [r for r in result.replans if r.committed and r.slowdown != 1.0]
    local = sum(1 for r in slowed if r.slowdown_local)
    return f"{len(slowed)} slowed for the checks, {local} of them only where they asked"


def retarget_lines(result: ClosedLoopResult) -> list[str]:
    """Which arm executed a retargeted replay and how closely it followed (no line for the arm's own
    model)."""
    d = retarget_summary(result)
    if d is None:
        return []
    if d["ik_residual_mm"] is None:
        close = "no re-plan committed"
    else:
        close = (
            f"hand-over residual at most {d['ik_residual_mm']:.3f} mm / {d['ik_residual_deg']:.3f} deg, path "
            f"at most {d['max_path_residual_mm']:.3f} mm"
        )
    median = d["ms"]["median"]
    cost = "" if median is None else f"; retargeting {median:.2f} ms per re-plan (median)"
    return [
        f"Executed by {result.robot}, every re-plan retargeted through the gripper from a model of "
        f"{d['source_robot']}: {close}; {d['unreachable_replans']} re-plans refused as unreachable{cost}"
    ]


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
            *unknown_lines(result),
            f"Re-plan cycle median {np.median(cycles):.2f} ms" if cycles else "No re-plan",
            f"Total {elapsed_s:.1f} s",
        ]
    )


def replay_passed(score: ClosedLoopScore) -> bool:
    """Whether the commanded trajectory did what it is for and is safe to execute: at least one re-plan
    was committed (else the robot never moved towards a hand-over), no commanded sample in collision
    and every velocity, acceleration and jerk within the limit profile at every control sample."""
    return replay_failures(score) is None


def replay_failures(score: ClosedLoopScore) -> list[str] | None:
    """None when the commanded trajectory passed (:func:`replay_passed`), else what failed:
    ``no_committed_replan``, ``collisions`` and/or ``limits``."""
    failed = [
        name
        for name, bad in (
            ("no_committed_replan", score.replans - score.refused_replans <= 0),
            ("collisions", score.collisions > 0),
            ("limits", score.max_limit_ratio > 1.0 + LIMIT_TOLERANCE),
        )
        if bad
    ]
    return failed or None


def failure_reason(result: ClosedLoopResult, score: ClosedLoopScore) -> str:
    """Why the replay did not pass, in one line ("" when it passed): every failed check, and for a
    replay without a committed re-plan, why its re-plans were refused (counts by reason)."""
    parts = []
    for name in replay_failures(score) or []:
        if name == "no_committed_replan":
            counts: dict[str, int] = {}
            for r in result.replans:
                counts[r.reason.split(":")[0]] = counts.get(r.reason.split(":")[0], 0) + 1
            why = ", ".join(f"{k} {v}" for k, v in counts.items()) or "no re-plan was made"
            first = next((r.reason for r in result.replans if r.reason), "")
            parts.append(
                f"no re-plan was committed ({score.refused_replans} refused: {why}"
                + (f"; first: {first}" if first else "")
                + "), the robot never moved towards the hand-over"
            )
        elif name == "collisions":
            parts.append(f"{score.collisions} commanded samples in collision")
        else:
            parts.append(f"max limit ratio {score.max_limit_ratio:.3f} above 1")
    return "; ".join(parts)


def replans_text(result: ClosedLoopResult, demo: Demo) -> str:
    """The content of ``replans.json`` (:func:`replans_json`, floats rounded to 6 decimals)."""
    return json.dumps(_round(replans_json(result, demo)), indent=1, allow_nan=False)
