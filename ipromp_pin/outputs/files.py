"""The table of every file a command writes into its output folder.

One row per file: its name in the output folder, its key in the report's ``files`` (kept from
earlier versions), whether a robot executes it (trajectory-carrying: written only when the checks
pass, or marked as failing when the user allows failing checks) and which commands write it. A new
output of a command is one row here; the command's :class:`~ipromp_pin.atomic.OutputSet` then
manages it (an earlier run's copy that a later run does not write is removed).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

RUN = "run"
"""Command name of ``ipromp-pin run``."""

REPLAY = "replay"
"""Command name of ``ipromp-pin replay``."""

PLAN = "plan"
"""Command name of ``ipromp-pin plan`` (its files in each recording's folder)."""

T = TypeVar("T")


@dataclass(frozen=True)
class OutputFile:
    """One output file (or folder).

    Attributes:
        name: Its name in the output folder.
        key: Its key in the report's ``files``.
        trajectory: Whether a robot executes (or replays) it.
        commands: The commands that write it (:data:`RUN`, :data:`REPLAY`).
    """

    name: str
    key: str
    trajectory: bool
    commands: frozenset[str]


def _row(name: str, key: str, trajectory: bool, *commands: str) -> OutputFile:
    return OutputFile(name, key, trajectory, frozenset(commands))


OUTPUT_FILES: tuple[OutputFile, ...] = (
    _row("trajectory.csv", "trajectory_csv", True, RUN, REPLAY, PLAN),
    _row("trajectory.json", "trajectory_json", True, RUN, REPLAY, PLAN),
    _row("retreat.csv", "retreat_csv", True, RUN, PLAN),
    _row("rosbag", "rosbag", True, RUN, REPLAY, PLAN),
    _row("run.bag", "ros1_bag", True, RUN, PLAN),
    _row("replans.json", "replans", False, REPLAY),
    _row("report.json", "report", False, RUN, REPLAY, PLAN),
    _row("report.txt", "report_text", False, RUN, REPLAY, PLAN),
    _row("limits.toml", "limits", False, REPLAY),
    _row("preview.html", "preview", False, RUN, REPLAY, PLAN),
    _row("prediction.png", "plot_prediction", False, RUN),
    _row("phase_posterior.png", "plot_phase", False, RUN),
    _row("distributions.png", "plot_distributions", False, RUN),
    _row("torques.png", "plot_torques", False, RUN),
    _row("motion.png", "plot_motion", False, RUN, REPLAY),
    _row("separation.png", "plot_separation", False, RUN, REPLAY),
)
"""Every output file of the commands, in the order the reports list them."""

FILE_KEYS: dict[str, str] = {f.name: f.key for f in OUTPUT_FILES}
"""File name -> key of the report's ``files``."""


def trajectory_outputs(command: str | None = None) -> tuple[str, ...]:
    """The names of the files a robot executes (of ``command``, or of any), in table order."""
    return tuple(f.name for f in OUTPUT_FILES if f.trajectory and (command is None or command in f.commands))


ALL_OUTPUTS: tuple[str, ...] = tuple(f.name for f in OUTPUT_FILES)
"""Every file any command writes into an output folder. Each command's output set manages them all
(:class:`~ipromp_pin.atomic.OutputSet`): after a command the folder holds its files only, whatever
wrote there before (a replay into a run's folder removes the run's retreat and bags)."""


def keyed(files: Mapping[str, T]) -> dict[str, T]:
    """File name -> value (e.g. its path) as report key -> value, in table order (names outside the
    table keep their name as key and come last)."""
    known = [f.name for f in OUTPUT_FILES if f.name in files]
    rest = [n for n in files if n not in FILE_KEYS]
    return {FILE_KEYS.get(n, n): files[n] for n in [*known, *rest]}


def report_listing(paths: Mapping[str, Path]) -> dict[str, str]:
    """The report's ``files``: report key -> path as text, in table order."""
    return {k: str(v) for k, v in keyed(paths).items()}
