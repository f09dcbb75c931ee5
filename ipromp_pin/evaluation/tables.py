"""Tables of evaluation cells: Markdown (recognition accuracy, motion prediction, the baselines, the
closed loop), the JSON document, and writing both (atomically)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path

import numpy as np

from .. import atomic
from .arm_tables import arm_markdown, plans_markdown
from .baselines import CLASSIFIERS, REGRESSORS
from .cells import Cell, ClosedLoopCell, median
from .config import observe_key


def overall_key(cell: Cell) -> str:
    """The :func:`overall` entry of a cell: ``protocol:observed`` for a cell observing a fraction of
    each test demo (the paper's windows), ``protocol/kind:observed`` for the other windows (e.g.
    ``paper/train_fraction:orientation+emg``)."""
    kind = "" if cell.window_kind == "ratio" else f"/{cell.window_kind}"
    return f"{cell.protocol}{kind}:{observe_key(cell.observe)}"


def overall(cells: Sequence[Cell]) -> dict[str, dict[str, float]]:
    """Mean accuracy per (protocol, window kind, observed set), with the paper's mean where known."""
    out: dict[str, dict[str, float]] = {}
    for c in cells:
        key = overall_key(c)
        empty = {
            "cells": 0,
            "accuracy_sum": 0.0,
            "paper_sum": 0.0,
            "paper_cells": 0,
            "ours_on_paper_sum": 0.0,
        }
        o = out.setdefault(key, empty)
        o["cells"] += 1
        o["accuracy_sum"] += c.accuracy
        if c.paper_accuracy is not None:
            o["paper_sum"] += c.paper_accuracy
            o["ours_on_paper_sum"] += c.accuracy
            o["paper_cells"] += 1
    result = {}
    for key, o in out.items():
        result[key] = {"mean_accuracy": o["accuracy_sum"] / o["cells"], "cells": o["cells"]}
        if o["paper_cells"]:  # like with like: our mean over exactly the cells the paper reports
            result[key]["paper_cells"] = o["paper_cells"]
            result[key]["mean_accuracy_on_paper_cells"] = o["ours_on_paper_sum"] / o["paper_cells"]
            result[key]["paper_mean_accuracy"] = o["paper_sum"] / o["paper_cells"]
            result[key]["cells_below_paper"] = sum(
                1
                for c in cells
                if overall_key(c) == key
                and c.paper_accuracy is not None
                and c.accuracy < c.paper_accuracy - 1e-9
            )
    return result


def paper_comparison(o: dict) -> str:
    """Our mean accuracy on the cells the paper reports beside the paper's mean on them (an entry of
    :func:`overall` that has ``paper_mean_accuracy``): the same cells, never a grid mean against it."""
    n = o["paper_cells"]
    return (
        f"on the {n} cell{'s' if n != 1 else ''} the paper reports: {o['mean_accuracy_on_paper_cells']:.3f} "
        f"(paper {o['paper_mean_accuracy']:.3f})"
    )


def format_number(x: float | None, digits: int = 2) -> str:
    """``x`` with ``digits`` decimals for a table, ``-`` when it is missing or not finite."""
    return "-" if x is None or not np.isfinite(x) else f"{x:.{digits}f}"


_fmt = format_number


SECONDS_TITLE = ", windows in seconds"
"""What the headings of the tables of cells observed through windows in seconds add."""

SECONDS_NOTE = (
    "Each test demo observed for its first seconds: `S s` for S seconds, `F of train` for F x the "
    "training demos' mean length (the model's nominal duration, a time known before the motion starts)."
)
"""The line under the first heading of those tables."""


def window_column(cells: Sequence[Cell]) -> str:
    """The name of a table's window column: ``obs ratio`` for cells observing a fraction of each test
    demo (the paper's windows), ``window`` otherwise."""
    return "obs ratio" if all(c.window_kind == "ratio" for c in cells) else "window"


def to_markdown(cells: Sequence[Cell]) -> str:
    """The accuracy table (and prediction errors) as Markdown: per protocol, the cells observing a
    fraction of each test demo, then those observing windows in seconds, then both side by side
    (:func:`window_comparison_markdown`); first the plans on the executing arm, when planned
    (:func:`~.arm_tables.plans_markdown`)."""
    lines: list[str] = plans_markdown(cells)
    for protocol in dict.fromkeys(c.protocol for c in cells):
        pc = [c for c in cells if c.protocol == protocol]
        fractions = [c for c in pc if c.window_kind == "ratio"]
        seconds = [c for c in pc if c.window_kind != "ratio"]
        if fractions:
            lines += protocol_markdown(fractions)
        if seconds:
            lines += protocol_markdown(seconds, SECONDS_TITLE, couplings=not fractions)
        lines += window_comparison_markdown(pc)
    return "\n".join(lines)


def protocol_markdown(pc: Sequence[Cell], title: str = "", couplings: bool = True) -> list[str]:
    """Markdown lines of one protocol's cells of one window family (``title``: what the headings add):
    accuracy, robot motion, hand-over orientation, the baselines and (``couplings``) the coupled groups."""
    protocol = pc[0].protocol
    tasks = list(dict.fromkeys(c.task for c in pc))
    lines = [f"### Recognition accuracy, protocol `{protocol}`{title}\n"]
    if title:
        lines += [SECONDS_NOTE, ""]
    head = f"| n_train | {window_column(pc)} | observed | " + " | ".join(tasks) + " | mean |"
    lines += [head, "|" + "---|" * (4 + len(tasks))]
    rows: dict[tuple[int, str, str], list[Cell]] = {}
    for c in pc:
        rows.setdefault((c.n_train, c.window_label(), observe_key(c.observe)), []).append(c)
    for (n_train, window, key), row in rows.items():
        texts = []
        for task in tasks:
            c = next(c for c in row if c.task == task)
            s = _fmt(c.accuracy)
            if c.accuracy_std is not None:
                s += f" ± {_fmt(c.accuracy_std)}"
            if c.paper_accuracy is not None:
                s += f" (paper {_fmt(c.paper_accuracy)})"
            texts.append(s)
        mean = float(np.mean([c.accuracy for c in row]))
        lines.append(f"| {n_train} | {window} | {key} | " + " | ".join(texts) + f" | {_fmt(mean)} |")
    lines.append("")
    for key, o in overall(pc).items():
        kind = key.split(":", 1)[0].partition("/")[2]
        what = key.split(":", 1)[1] + (f", {kind} windows" if kind else "")
        s = f"- mean over cells, {what}: {o['mean_accuracy']:.3f}"
        if "paper_mean_accuracy" in o:
            s += f"; {paper_comparison(o)}; cells below it: {o['cells_below_paper']}"
        lines.append(s)
    lines.append("")
    lines.append(
        f"### Robot motion prediction, protocol `{protocol}`{title} "
        "(medians over correctly recognised trials; conditioned vs prior mean)\n"
    )
    lines.append(
        f"| n_train | {window_column(pc)} | observed | task | joint RMSE [rad] | final joint err [rad] "
        "| hand-over err [cm] | duration err [s] |"
    )
    lines.append("|---|---|---|---|---|---|---|---|")
    for c in pc:
        lines.append(
            f"| {c.n_train} | {c.window_label()} | {observe_key(c.observe)} | {c.task} "
            f"| {_fmt(c.joint_rmse_rad, 3)} vs {_fmt(c.joint_rmse_prior_rad, 3)} "
            f"| {_fmt(c.final_joint_error_rad, 3)} vs {_fmt(c.final_joint_error_prior_rad, 3)} "
            f"| {_fmt(c.handover_error_cm, 1)} vs {_fmt(c.handover_error_prior_cm, 1)} "
            f"| {_fmt(c.duration_error_s, 2)} |"
        )
    lines.append("")
    lines += orientation_markdown(pc)
    if any(c.baselines for c in pc):
        lines += baseline_markdown(pc, title)
    fits = {(c.n_train, observe_key(c.observe)): c.coupled_groups for c in pc if c.coupled_groups}
    for (n_train, key), counts in fits.items() if couplings else ():
        chosen = ", ".join(f"{g or 'none'} ({n})" for g, n in counts.items())
        lines.append(f"- observed groups coupled to the robot, n_train={n_train}, {key}: {chosen}")
    if fits and couplings:
        lines.append("")
    return lines


def window_comparison_markdown(cells: Sequence[Cell]) -> list[str]:
    """Markdown lines: every cell observing a fraction of the training demos' mean length beside the
    cell observing the same fraction of each test demo (same protocol, training size and observed
    set), each number the mean over the tasks; none when there is no such pair."""
    ratio = {(c.n_train, c.obs_ratio, observe_key(c.observe), c.task): c for c in cells if c.obs_ratio}
    pairs: dict[tuple[int, float, str], list[tuple[Cell, Cell]]] = {}
    for c in cells:
        if c.window_kind == "train_fraction":
            where = (c.n_train, float(c.window["value"]), observe_key(c.observe))
            twin = ratio.get((*where, c.task))
            if twin is not None:
                pairs.setdefault(where, []).append((twin, c))
    if not pairs:
        return []
    lines = [
        f"### The same fraction of each test demo or of the training demos' mean length, protocol "
        f"`{cells[0].protocol}` (means over tasks)\n",
        "| n_train | fraction | observed | accuracy: of the test demo / of train "
        "| hand-over err [cm]: of the test demo / of train | observed [s]: of the test demo / of train |",
        "|---|---|---|---|---|---|",
    ]

    def mean(rows: list[tuple[Cell, Cell]], i: int, name: str) -> float | None:
        return row_mean([getattr(pair[i], name) for pair in rows])

    for (n_train, value, key), rows in pairs.items():
        lines.append(
            f"| {n_train} | {value:g} | {key} "
            + "".join(
                f"| {_fmt(mean(rows, 0, name), digits)} / {_fmt(mean(rows, 1, name), digits)} "
                for name, digits in (("accuracy", 2), ("handover_error_cm", 1), ("observed_s", 2))
            )
            + "|"
        )
    return [*lines, ""]


def row_mean(values: Sequence[float | None]) -> float | None:
    vals = [v for v in values if v is not None and np.isfinite(v)]
    return float(np.mean(vals)) if vals else None


def baseline_markdown(cells: Sequence[Cell], title: str = "") -> list[str]:
    """Markdown lines: ipromp_pin beside the baselines, one row per (n_train, window, observed set),
    each number the mean over the row's tasks (of the per-task accuracy, log loss, or median error);
    ``title``: what the heading adds."""
    protocol = cells[0].protocol
    rows: dict[tuple[int, str, str], list[Cell]] = {}
    for c in cells:
        rows.setdefault((c.n_train, c.window_label(), observe_key(c.observe)), []).append(c)
    names = ["ipromp_pin", *CLASSIFIERS]
    lines = [
        f"### ipromp_pin and the baselines, protocol `{protocol}`{title} (means over tasks)\n",
        f"| n_train | {window_column(cells)} | observed | accuracy: "
        + " / ".join(names)
        + " | log loss: "
        + " / ".join(names)
        + " | ECE: "
        + " / ".join(names)
        + " | hand-over err [cm]: ipromp_pin / "
        + " / ".join(REGRESSORS)
        + " | joint RMSE [rad]: ipromp_pin / "
        + " / ".join(REGRESSORS)
        + " |",
        "|---|---|---|---|---|---|---|---|",
    ]

    def base(row: list[Cell], name: str, key: str) -> float | None:
        return row_mean([c.baselines.get(name, {}).get(key) for c in row])

    for (n_train, window, key), row in rows.items():
        acc = [row_mean([c.accuracy for c in row])] + [base(row, n, "accuracy") for n in CLASSIFIERS]
        loss = [row_mean([c.log_loss for c in row])] + [base(row, n, "log_loss") for n in CLASSIFIERS]
        ece = [row_mean([c.ece for c in row])] + [base(row, n, "ece") for n in CLASSIFIERS]
        ho = [row_mean([c.handover_error_cm for c in row])] + [
            base(row, n, "handover_error_cm") for n in REGRESSORS
        ]
        rmse = [row_mean([c.joint_rmse_rad for c in row])] + [
            base(row, n, "joint_rmse_rad") for n in REGRESSORS
        ]
        lines.append(
            f"| {n_train} | {window} | {key} | "
            + " / ".join(_fmt(v) for v in acc) + " | " + " / ".join(_fmt(v) for v in loss) + " | "
            + " / ".join(_fmt(v) for v in ece) + " | "
            + " / ".join(_fmt(v, 1) for v in ho) + " | " + " / ".join(_fmt(v, 3) for v in rmse) + " |"
        )  # fmt: skip
    lines.append("")
    return lines


def to_json(cells: Sequence[Cell], meta: dict | None = None) -> dict:
    """JSON document: ``cells`` (one record per table cell), ``overall`` and ``meta``.

    Undefined numbers (e.g. an error median over no correctly recognised trial) are ``null``.
    """
    return finite(
        {
            "format": "ipromp_pin.evaluation",
            "version": 1,
            "meta": meta or {},
            "overall": overall(cells),
            "cells": [asdict(c) for c in cells],
        }
    )


def finite(x):
    """``x`` with NaN and inf floats replaced by ``None`` (strict JSON) and numpy scalars made plain."""
    if isinstance(x, dict):
        return {k: finite(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [finite(v) for v in x]
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not np.isfinite(x):
        return None
    return x


def write_results(cells: Sequence[Cell], json_path: Path | None, md_path: Path | None, meta: dict) -> None:
    """Write the JSON and Markdown results (each atomically: a temporary file renamed into place)."""
    if json_path is not None:
        atomic.write_text(json_path, json.dumps(to_json(cells, meta), indent=1, allow_nan=False))
    if md_path is not None:
        atomic.write_text(md_path, to_markdown(cells))


def orientation_markdown(cells: Sequence[Cell]) -> list[str]:
    """The hand-over orientation table (prediction vs the mean training orientation of the true task),
    as Markdown lines; none when no cell has the orientation (no robot kinematics)."""
    rows = [c for c in cells if c.handover_orientation_error_deg is not None]
    if not rows:
        return []
    lines = [
        f"| n_train | {window_column(rows)} | observed | task | hand-over orientation err [deg] "
        "| mean-orientation baseline [deg] |",
        "|---|---|---|---|---|---|",
    ]
    for c in rows:
        lines.append(
            f"| {c.n_train} | {c.window_label()} | {observe_key(c.observe)} | {c.task} "
            f"| {_fmt(c.handover_orientation_error_deg, 1)} "
            f"| {_fmt(c.handover_orientation_baseline_deg, 1)} |"
        )
    below = sum(
        1
        for c in rows
        if c.handover_orientation_error_deg is not None
        and c.handover_orientation_baseline_deg is not None
        and c.handover_orientation_error_deg < c.handover_orientation_baseline_deg
    )
    out = [*lines, "", f"- hand-over orientation below the baseline in {below} of {len(rows)} cells"]
    peaks = [c.peak_torque_ratio for c in cells if c.peak_torque_ratio is not None]
    if peaks:  # objects in use: the plans' peak |joint torque| / effort limit, true task's object
        out.append(f"- peak joint torque ratio at most {_fmt(max(peaks), 3)} (over the cells' trials)")
    return [*out, ""]


START_KINDS = {
    "ratio": "robot starting after a fraction of each test demo",
    "seconds": "robot starting by the online rule",
    "train_fraction": "robot starting by the online rule",
}
"""How the robot starts in a closed-loop cell of each window kind (the summary lines' groups)."""


def closed_loop_markdown(cells: Sequence[ClosedLoopCell]) -> str:
    """The closed-loop table (one row per cell) and its medians over cells, as Markdown; first the
    re-plans on the executing arm, when measured (:func:`~.arm_tables.arm_markdown`)."""
    lines = arm_markdown(cells)
    for protocol in dict.fromkeys(c.protocol for c in cells):
        pc = [c for c in cells if c.protocol == protocol]
        profile = ", ".join(dict.fromkeys(c.limit_profile for c in pc))
        lines.append(f"### Closed loop, protocol `{protocol}` (limit profile: {profile})\n")
        lines.append(
            "| n_train | window | observed | task | hand-over err [cm] closed loop | one-shot "
            "| robot start [s] | final err [cm] | arrival delay [s] | max limit ratio | refused / re-plans "
            "| collisions |"
        )
        lines.append("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for c in pc:
            lines.append(
                f"| {c.n_train} | {c.window_label()} | {observe_key(c.observe)} | {c.task} "
                f"| {_fmt(c.closed_loop_handover_error_cm)} | {_fmt(c.one_shot_handover_error_cm)} "
                f"| {_fmt(c.robot_start_s)} "
                f"| {_fmt(c.closed_loop_final_error_cm)} | {_fmt(c.arrival_delay_s)} "
                f"| {_fmt(c.max_limit_ratio, 3)} | {c.refused_replans} / {c.replans} | {c.collisions} |"
            )
        lines.append("")
        groups = {(observe_key(c.observe), START_KINDS[c.window_kind]) for c in pc}
        for key, start in sorted(groups, key=lambda g: (g[0], g[1] != START_KINDS["ratio"])):
            kc = [c for c in pc if observe_key(c.observe) == key and START_KINDS[c.window_kind] == start]
            below = sum(
                1
                for c in kc
                if c.closed_loop_handover_error_cm is not None
                and c.one_shot_handover_error_cm is not None
                and c.closed_loop_handover_error_cm < c.one_shot_handover_error_cm
            )
            lines.append(
                f"- {key}, {start}, median over {len(kc)} cells: hand-over error "
                f"{_fmt(median([c.closed_loop_handover_error_cm for c in kc]))} cm closed loop vs "
                f"{_fmt(median([c.one_shot_handover_error_cm for c in kc]))} cm one-shot (closed loop "
                f"below one-shot in {below} of {len(kc)} cells); final error "
                f"{_fmt(median([c.closed_loop_final_error_cm for c in kc]))} cm; arrival delay "
                f"{_fmt(median([c.arrival_delay_s for c in kc]))} s; max limit ratio "
                f"{_fmt(max((c.max_limit_ratio or 0.0) for c in kc), 3)}; collisions "
                f"{sum(c.collisions for c in kc)}; refused re-plans {sum(c.refused_replans for c in kc)} "
                f"of {sum(c.replans for c in kc)}; replays never started {sum(c.never_started for c in kc)}, "
                f"stopped on an unknown task {sum(c.stopped_unknown for c in kc)} (retreated "
                f"{sum(c.retreated for c in kc)}); "
                "hand-over orientation error "
                f"{_fmt(median([c.closed_loop_handover_orientation_error_deg for c in kc]), 1)} deg "
                "closed loop "
                f"vs {_fmt(median([c.handover_orientation_baseline_deg for c in kc]), 1)} deg baseline; peak "
                f"torque ratio {_fmt(max((c.peak_torque_ratio or 0.0) for c in kc), 3)}"
            )
        lines.append("")
        lines += human_markdown(pc)
    return "\n".join(lines)


NO_HUMAN_LINE = (
    "no replay above was checked against a human: the test demos have no tracked skeleton (or the "
    "human checks were off). `replay` and `run` check such a demo against the assumed human "
    "(`[human.assumed]` of the robot settings), which slows the robot where it passes the assumed "
    "face; these figures do not include that (`evaluate --arm-scores`, or `--robot` with a placed "
    "arm, replays with it)"
)
"""The closed-loop Markdown's line for cells replayed without the human checks."""


def human_markdown(cells: Sequence[ClosedLoopCell]) -> list[str]:
    """Markdown lines of the human measures (against the recorded human) of the cells that have
    them, one row per cell, with the arrival delay with and without the human checks; when no cell
    has them and none was replayed on an arm judged against the assumed human (``--robot``), one
    line saying that these replays ran without any human checks."""
    hc = [c for c in cells if c.arrival_delay_without_human_s is not None]
    if not hc:
        if any(c.arm is not None for c in cells):
            return []
        return [
            f"- {NO_HUMAN_LINE}",
            "",
        ]
    lines = [
        f"### The human in the closed loop, protocol `{hc[0].protocol}` (judged against the recorded "
        "human motion)\n",
        "| n_train | window | observed | task | min separation [m] (outside the hand) "
        "| time within S_p [s] | contact-speed violations | arrival delay [s] with / without the human |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for c in hc:
        violations = "-" if c.contact_speed_violations is None else str(c.contact_speed_violations)
        lines.append(
            f"| {c.n_train} | {c.window_label()} | {observe_key(c.observe)} | {c.task} "
            f"| {_fmt(c.human_min_separation_m, 3)} | {_fmt(c.protective_distance_time_s)} | {violations} "
            f"| {_fmt(c.arrival_delay_s)} / {_fmt(c.arrival_delay_without_human_s)} |"
        )
    total = sum(c.contact_speed_violations or 0 for c in hc)
    seps = [c.human_min_separation_m for c in hc if c.human_min_separation_m is not None]
    extra = [
        c.arrival_delay_s - c.arrival_delay_without_human_s
        for c in hc
        if c.arrival_delay_s is not None and c.arrival_delay_without_human_s is not None
    ]
    lines += [
        "",
        f"- over {len(hc)} cells: contact-speed violations {total}; smallest separation "
        f"{_fmt(min(seps) if seps else None, 3)} m; median extra arrival delay of the human checks "
        f"{_fmt(median(extra))} s",
        "",
    ]
    return lines


def write_closed_loop_results(
    cells: Sequence[ClosedLoopCell], json_path: Path | None, md_path: Path | None, meta: dict
) -> None:
    """Write the JSON (the evaluation format, cells with the closed-loop fields) and the Markdown
    (the closed-loop table, then the usual recognition and prediction tables), each atomically."""
    if json_path is not None:
        atomic.write_text(json_path, json.dumps(to_json(cells, meta), indent=1, allow_nan=False))
    if md_path is not None:
        atomic.write_text(md_path, closed_loop_markdown(cells) + "\n" + to_markdown(cells))
