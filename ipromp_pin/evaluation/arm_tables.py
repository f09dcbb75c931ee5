"""Markdown of the plans on the executing arm (``evaluate --robot NAME``, :mod:`.arm_plans`): which
arm executed, retargeted from which robot, the reach, residuals, refusals and re-evaluation per cell."""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

from .cells import Cell, ClosedLoopCell
from .config import observe_key


def _num(x: float | None, digits: int = 2) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def _counts(counts: dict[str, int]) -> str:
    return ", ".join(f"{k} {v}" for k, v in counts.items()) or "none"


def executed_line(robot: str, source: str | None) -> str:
    """Which arm executed the plans (a Markdown heading)."""
    how = "its own model" if source is None else f"retargeted through the gripper from a model of {source}"
    return f"### Executed by {robot} ({how})\n"


def plans_markdown(cells: Sequence[Cell]) -> list[str]:
    """The one-shot plans on the executing arm, one row per cell with ``plans`` (none: no line)."""
    planned = [c for c in cells if c.plans]
    if not planned:
        return []
    first = planned[0].plans or {}
    lines = [
        executed_line(str(first["robot"]), first.get("source_robot")),
        "One-shot plans (timed, checked and re-timed as `run` plans them), scored against the recorded "
        "gripper at the demo's end in the scene frame; errors and delays are medians over the passed "
        "plans.\n",
        "| protocol | n_train | window | observed | task | plans | reached | passed | refused (by check) "
        "| hand-over err [cm] | arrival delay [s] | max IK residual [mm / deg] | passed with a violation |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    refused: Counter[str] = Counter()
    for c in planned:
        p = c.plans or {}
        refused.update(p["refused"])
        reached = f"{p['reached']}/{p['retargeted']}" if p["retargeted"] else "-"
        lines.append(
            f"| {c.protocol} | {c.n_train} | {c.window_label()} | {observe_key(c.observe)} | {c.task} "
            f"| {p['plans']} | {reached} | {p['passed']} | {_counts(p['refused'])} "
            f"| {_num(p['handover_error_cm'])} | {_num(p['arrival_delay_s'])} "
            f"| {_num(p['max_ik_residual_mm'], 3)} / {_num(p['max_ik_residual_deg'], 3)} "
            f"| {p['passed_with_violation']} |"
        )
    total = [c.plans or {} for c in planned]
    lines += [
        "",
        f"- {sum(p['plans'] for p in total)} plans: reached {sum(p['reached'] for p in total)} of "
        f"{sum(p['retargeted'] for p in total)} retargeted, passed {sum(p['passed'] for p in total)}, "
        f"refused {_counts(dict(sorted(refused.items())))}; passed with a violation "
        f"{sum(p['passed_with_violation'] for p in total)}",
        "",
    ]
    return lines


def arm_markdown(cells: Sequence[ClosedLoopCell]) -> list[str]:
    """The closed loop's re-plans on the executing arm, one row per cell with ``arm`` (none: no line)."""
    armed = [c for c in cells if c.arm]
    if not armed:
        return []
    first = armed[0].arm or {}
    lines = [
        executed_line(str(first["robot"]), first.get("source_robot")),
        "| protocol | n_train | window | observed | task | replays | unreachable start | re-plans reached "
        "| max IK residual [mm / deg] | max path residual [mm] | refused re-plans "
        "| replays with a violation |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for c in armed:
        a = c.arm or {}
        lines.append(
            f"| {c.protocol} | {c.n_train} | {c.window_label()} | {observe_key(c.observe)} | {c.task} "
            f"| {a['replays']} | {a['unreachable_start']} | {a['reached_replans']}/{a['retargeted_replans']} "
            f"| {_num(a['max_ik_residual_mm'], 3)} / {_num(a['max_ik_residual_deg'], 3)} "
            f"| {_num(a['max_path_residual_mm'], 3)} | {_counts(a['refused_replans'])} "
            f"| {a['replays_with_violation']} ({_counts(a['violations_found'])}) |"
        )
    return lines + [""]
