"""The run's report: what was recognised, predicted and checked, as JSON, as text and as a summary.

:func:`report_dict` is ``report.json`` (its fields are listed in ``docs/formats.md``),
:func:`report_text` is ``report.txt`` and :func:`summary_text` the end-of-run lines on the console.
"""

from __future__ import annotations

import math
from pathlib import Path

from ..data import Demo
from ..evaluation.scoring import RecordedScores
from ..planning.one_shot import PlanResult
from ..planning.retreat import RetreatResult
from ..promp import Prediction
from ..safety.joint_torques import TorqueMeasures

REPORT_FORMAT = "ipromp_pin.report"
"""Value of ``report.json``'s ``format`` field."""

REPORT_VERSION = 2
"""Value of ``report.json``'s ``version`` field."""


def arrival(result: PlanResult) -> dict[str, float | bool]:
    """When the human and the robot reach the hand-over, in [s] from the start of the human's motion:
    ``human_s`` the predicted end of the human's motion (the model's hand-over time), ``robot_start_s``
    when the robot starts (the end of the observation, when the plan is published: the bags' stamp),
    ``robot_s`` when it comes to rest at the hand-over (start + trajectory duration) and ``delay_s``
    = robot minus human (positive: the robot arrives after the human, who waits); ``slowdown``,
    ``slowdown_local`` and ``slowdown_delay_s`` how much of that the checks' slow-down made."""
    p = result.prediction
    robot = result.trajectory.end_s
    return {
        "human_s": float(p.duration_s),
        "robot_start_s": result.trajectory.start_s,
        "robot_s": robot,
        "delay_s": robot - float(p.duration_s),
        "slowdown": float(result.slowdown),
        "slowdown_local": bool(result.slowdown_local),
        "slowdown_delay_s": float(result.slowdown_delay_s),
    }


def arrival_line(result: PlanResult) -> str:
    """The arrival in one line (:func:`arrival`), for ``report.txt``, the summary and the preview."""
    a = arrival(result)
    when = "after" if a["delay_s"] >= 0 else "before"
    return (
        f"Arrival (from the start of the human's motion): human {a['human_s']:.2f} s (predicted), robot "
        f"{a['robot_s']:.2f} s (starts at {a['robot_start_s']:.2f} s, at rest at the hand-over): "
        f"{abs(a['delay_s']):.2f} s {when} the human"
    )


def orientation_line(error_deg: float) -> str:
    """The hand-over orientation error line of the reports and the preview panel ([deg])."""
    return f"Gripper orientation at the hand-over: {error_deg:.1f} deg from the recorded one"


def report_dict(
    result: PlanResult,
    observation: Demo | None = None,
    warnings: list[str] | None = None,
    retreat: RetreatResult | None = None,
    scores: RecordedScores | None = None,
) -> dict:
    """The machine-readable report of a planned hand-over (JSON-serialisable; schema:
    ``ipromp_pin/schemas/report.schema.json``); ``retreat``: the segment after the hand-over (its
    section; its failures fail ``passed``); ``scores``: the plan measured against the whole
    recording, when it has its future (``run`` on a dataset's demo, ``plan`` of a recorded demo).
    Every time is on the human's clock (t = 0 at the start of the human's motion)."""
    p = result.prediction
    torques = next((v.measures for v in result.checks if isinstance(v.measures, TorqueMeasures)), None)
    return {
        "format": REPORT_FORMAT,
        "version": REPORT_VERSION,
        "clock": "t = 0 at the start of the human's motion",
        "recognised_task": p.task,
        "posterior": {t: float(v) for t, v in zip(p.tasks, p.posterior, strict=True)},
        "known": bool(p.known),
        "novelty_p_value": None if not math.isfinite(p.novelty_p_value) else float(p.novelty_p_value),
        "unknown_reason": p.unknown_reason,
        "alpha": {t: float(v) for t, v in zip(p.tasks, p.alpha, strict=True)},
        "predicted_duration_s": float(p.duration_s),
        "observed_until_s": float(p.observed_until_s),
        "arrival": arrival(result),
        "observation": None
        if observation is None
        else {"task": observation.task, "demo": observation.name, "source": observation.source},
        "feasibility": feasibility_dict(result),
        "trajectory": result.timing_report.to_dict(),
        "passed": result.passed and (retreat is None or retreat.passed),
        "retreat": None if retreat is None else retreat.to_dict(),
        "stage_ms": {k: round(v, 3) for k, v in result.stage_ms.items()},
        "warnings": list(warnings or []),
        "scores": None if scores is None else scores.to_dict(),
        "peak_torque_ratio": None if torques is None else torques.peak_torque_ratio,
        "retarget": None if result.retarget is None else result.retarget.to_dict(),
    }


def retarget_lines(result: PlanResult) -> list[str]:
    """Which arm executed a retargeted plan and how closely it follows the model's gripper path (no
    line when the model predicts the executing arm's own joints)."""
    r = result.retarget
    if r is None:
        return []
    d = r.to_dict()
    origin = (
        f"a model of gripper poses (in {d['source_robot']}'s frame)"
        if d["source_path"] == "gripper_pose"
        else f"a model of {d['source_robot']}"
    )
    line = (
        f"Executed by {result.robot}, retargeted through the gripper from {origin}: "
        f"hand-over residual {d['ik_residual_mm']:.3f} mm / {d['ik_residual_deg']:.3f} deg, "
        f"path at most {d['max_path_residual_mm']:.3f} mm"
    )
    return [line]


def feasibility_dict(result: PlanResult) -> dict:
    """``report.json``'s ``feasibility`` section: the verdicts on the committed trajectory (times on
    the human's clock), the hand-over pose, the stages' times."""
    pose = result.handover_pose
    return {
        "robot": result.robot,
        "tool": result.tool,
        "passed": result.checks.passed,
        "failures": result.checks.failures,
        "handover_position_m": [float(x) for x in pose[:3]],
        "handover_quat_xyzw": [float(x) for x in pose[3:]],
        "checks": result.checks.to_dict(),
        "timings_ms": {k: round(float(v), 3) for k, v in result.stage_ms.items()},
    }


def _with_tool(tool: dict | None) -> str:
    """`` with <the tool> (<length> m, <mass> kg)`` for a robot with a ``[tool]``, else nothing."""
    if tool is None:
        return ""
    return f" with {tool['name']} ({tool['length_m']:.3f} m, {tool['mass_kg']:.2f} kg)"


def checks_text(result: PlanResult) -> str:
    """The verdicts as ``report.txt`` lists them: the verdict line, the hand-over position, one line
    per check."""
    p = result.handover_pose
    verdict = "PASSED" if result.checks.passed else "FAILED: " + ", ".join(result.checks.failures)
    lines = [
        f"Feasibility ({result.robot}{_with_tool(result.tool)}): {verdict}",
        f"  hand-over position [m]: ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f})",
    ]
    return "\n".join(lines + result.checks.lines())


def scores_lines(scores: RecordedScores) -> list[str]:
    """The scores against the recording, a line each (for ``report.txt`` and the preview)."""
    lines = []
    if scores.handover_error_cm is not None:
        lines.append(
            f"Against the recording ({scores.recorded_duration_s:.2f} s): gripper "
            f"{scores.handover_error_cm:.1f} cm from the recorded robot's hand-over position"
        )
    if scores.handover_orientation_error_deg is not None:
        lines.append(orientation_line(scores.handover_orientation_error_deg))
    if scores.hand_distance_m is not None:
        lines.append(
            f"Gripper at rest {scores.hand_distance_m * 1e3:.0f} mm from the recorded hand's last position"
        )
    return lines


def report_text(
    result: PlanResult,
    observation: Demo | None = None,
    warnings: list[str] | None = None,
    retreat: RetreatResult | None = None,
    scores: RecordedScores | None = None,
) -> str:
    """The human-readable report: warnings, recognition, the arrival, the scores against the
    recording (when scored), the checks and the trajectory's verification."""
    p = result.prediction
    lines = [f"Warning: {w}" for w in warnings or []]
    if observation is not None:
        lines.append(
            f"Observed: {observation.task or '(no task label)'}/{observation.name} ({observation.source})"
        )
    lines.append(
        f"Recognised task: {p.task}; posterior "
        + ", ".join(f"{t} {v:.3f}" for t, v in zip(p.tasks, p.posterior, strict=True))
    )
    lines.append(known_line(p))
    lines.append(
        f"Predicted duration of the human's motion: {p.duration_s:.2f} s "
        f"(observed {p.observed_until_s:.2f} s)"
    )
    lines.append(arrival_line(result))
    lines += retarget_lines(result)
    if scores is not None:
        lines += scores_lines(scores)
    lines.append(
        f"Every time is on the human's motion (t = 0 at its start); the robot moves from "
        f"{result.trajectory.start_s:.2f} s to {result.trajectory.end_s:.2f} s"
    )
    lines.append(checks_text(result))
    lines.append(result.timing_report.to_text())
    if retreat is not None:
        lines.append(retreat.to_text())
    return "\n".join(lines)


def summary_text(
    result: PlanResult, files: dict[str, Path], elapsed_s: float, retreat: RetreatResult | None = None
) -> str:
    """Short end-of-run summary: task, hand-over pose, checks, trajectory, files, total time in [s]."""
    p = result.prediction
    pose = result.handover_pose
    post = ", ".join(f"{t} {v:.3f}" for t, v in zip(p.tasks, p.posterior, strict=True))
    checks = ", ".join(f"{v.name} {v.status}" for v in result.checks)
    tr = result.trajectory
    lines = [
        "",
        f"Recognised task: {p.task}   posterior: {post}",
        known_line(p),
        f"Hand-over pose: position ({pose[0]:.3f}, {pose[1]:.3f}, {pose[2]:.3f}) m, "
        f"quaternion xyzw ({pose[3]:.3f}, {pose[4]:.3f}, {pose[5]:.3f}, {pose[6]:.3f})",
        f"Checks: {'PASS' if result.checks.passed else 'FAIL'} ({checks})",
        *retarget_lines(result),
        arrival_line(result),
        f"Trajectory: {tr.duration_s:.2f} s, {tr.n_samples} samples; online stages "
        + ", ".join(f"{k} {v:.1f} ms" for k, v in result.stage_ms.items()),
        *([] if retreat is None else [retreat.to_text().splitlines()[0]]),
        "Files: " + ", ".join(str(f) for f in files.values()),
        f"Total {elapsed_s:.1f} s",
    ]
    return "\n".join(lines)


def known_line(p: Prediction) -> str:
    """Whether the observation is one of the model's tasks, in one line."""
    if not p.known:
        return f"UNKNOWN TASK: {p.unknown_reason}; the robot does not act on it"
    if math.isnan(p.novelty_p_value):
        return "Known task: the model has no novelty detector (trained before ipromp_pin had one)"
    return f"Known task: novelty p = {p.novelty_p_value:.3f}"
