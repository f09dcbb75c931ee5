"""A batch's summary: ``summary.json`` (schema ``plan_summary.schema.json``) and ``summary.csv``, one
line per recording (:class:`~.batch.PlannedRecording`), written together beside the recordings'
sub-folders; a failed write leaves an earlier summary as it was."""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

from .. import atomic
from .batch import STATUSES, PlannedRecording

SUMMARY_FORMAT = "ipromp_pin.plan_summary"
"""Value of ``summary.json``'s ``format`` field."""

SUMMARY_VERSION = 1
"""Value of ``summary.json``'s ``version`` field."""

SUMMARY_FILES = ("summary.json", "summary.csv")
"""The files of a summary."""

CSV_COLUMNS = (
    "recording",
    "status",
    "task",
    "posterior",
    "known",
    "novelty_p_value",
    "failures",
    "observed_until_s",
    "human_s",
    "robot_start_s",
    "robot_s",
    "delay_s",
    "slowdown",
    "handover_error_cm",
    "out_dir",
    "report",
    "trajectory_csv",
    "error",
)
"""The columns of ``summary.csv`` (lists joined by ``;``, a missing value empty)."""


def counts(rows: Sequence[PlannedRecording]) -> dict[str, int]:
    """Status -> how many recordings have it."""
    return {s: sum(r.status == s for r in rows) for s in STATUSES}


def summary_dict(rows: Sequence[PlannedRecording], about: dict[str, Any]) -> dict[str, Any]:
    """``summary.json``: ``about`` (the model, the robot, the window) and one entry per recording."""
    entries = []
    for r in rows:
        entry = asdict(r)
        del entry["index"]
        entries.append(entry)
    return {
        "format": SUMMARY_FORMAT,
        "version": SUMMARY_VERSION,
        **about,
        "counts": counts(rows),
        "recordings": entries,
    }


def _cell(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, list):
        return ";".join(str(v) for v in value)
    if isinstance(value, float):
        return repr(value)
    return str(value)


def summary_csv(rows: Sequence[PlannedRecording]) -> str:
    """``summary.csv``: a header of :data:`CSV_COLUMNS`, one row per recording."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for r in rows:
        flat: dict[str, object] = {**asdict(r), **(r.arrival or {})}
        flat["report"] = r.files.get("report")
        flat["trajectory_csv"] = r.files.get("trajectory_csv")
        writer.writerow([_cell(flat.get(c)) for c in CSV_COLUMNS])
    return buf.getvalue()


def write_summary(out_dir: Path, rows: Sequence[PlannedRecording], about: dict[str, Any]) -> dict[str, Path]:
    """Write ``summary.json`` and ``summary.csv`` into ``out_dir`` together; returns their paths."""
    doc = summary_dict(rows, about)
    with atomic.OutputSet(out_dir) as out:
        out.write_text("summary.json", json.dumps(doc, indent=1, allow_nan=False) + "\n")
        out.write_text("summary.csv", summary_csv(rows))
        return out.commit()
