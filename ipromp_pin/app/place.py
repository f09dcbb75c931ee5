"""``ipromp-pin place [DATASET] --robot NAME``: suggest a base placement for an arm placed in the
scene of another robot's recordings, from the dataset's hand-over poses.

The search is :func:`ipromp_pin.robot.reachability.search_placement`; this module reads the
dataset (the built-in synthetic demos without one), prints the suggestion and optionally writes it
to a user settings file (never the shipped one).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ..exceptions import RobotError

if TYPE_CHECKING:
    from ..robot.reachability import PlacementSearch


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``place`` command to ``subparsers``."""
    p = subparsers.add_parser(
        "place",
        help="suggest where an arm stands in the recordings' scene: the base placement that reaches the "
        "dataset's hand-over poses",
    )
    p.add_argument(
        "dataset",
        type=Path,
        nargs="?",
        help="dataset folder recorded on the arm's placement source, e.g. Baxter (default: the built-in "
        "synthetic demos)",
    )
    p.add_argument("--format", help="dataset format: auto, chen2017, multimodal, bag, native")
    p.add_argument(
        "--robot",
        required=True,
        help="the arm: a shipped name (panda, ur5, xarm7, kinova_jaco2) or a settings file with a "
        "[placement]",
    )
    p.add_argument(
        "--write",
        type=Path,
        metavar="FILE",
        help="write a copy of the arm's settings with the suggested [placement] to FILE (a file of yours: "
        "the shipped settings are never changed); use it with --robot FILE",
    )
    p.set_defaults(func=main)


@dataclass(frozen=True)
class PlaceOutcome:
    """What ``place`` found: the search, the poses' origin and the file written (if any)."""

    search: PlacementSearch
    poses_from: str
    seconds: float
    written: Path | None


def main(args: argparse.Namespace) -> int:
    """Search, print and optionally write the suggested placement."""
    words = [
        "ipromp-pin",
        "place",
        *([str(args.dataset)] if args.dataset else []),
        "--robot",
        str(args.robot),
    ]
    words += ["--format", args.format] if args.format else []
    words += ["--write", str(args.write)] if args.write else []
    outcome = run_place(
        args.robot, args.dataset, fmt=args.format, write_to=args.write, command=" ".join(words)
    )
    for line in outcome_lines(outcome, args.robot):
        print(line)
    return 0


def run_place(
    robot: str | Path,
    dataset: str | Path | None = None,
    *,
    fmt: str | None = None,
    write_to: str | Path | None = None,
    command: str | None = None,
) -> PlaceOutcome:
    """The suggested placement of arm ``robot`` for the hand-over poses of ``dataset`` (recorded on
    the arm's placement source; ``None``: the built-in synthetic demos), written to ``write_to``.

    Raises:
        RobotError: unknown robot, an arm without ``[placement]``, a shipped file as ``write_to``.
        DataError: an unreadable or empty dataset.
    """
    from ..readers.synthetic import make_synthetic_dataset
    from ..robot.model import load_robot
    from ..robot.reachability import handover_poses, search_placement, write_placement
    from ..robot.recordings import read_recordings
    from ..robot.settings import load_robot_settings

    settings = load_robot_settings(robot)
    if settings.placement is None:
        raise RobotError(
            f"{settings.path}: field 'placement': robot '{settings.name}' has no [placement]: it is not "
            "placed in another robot's recordings' scene (place suggests one for panda, ur5, xarm7, "
            "kinova_jaco2)"
        )
    source = load_robot(settings.placement.source)
    if dataset is None:
        demos, poses_from = make_synthetic_dataset().all_demos(), "the built-in synthetic demos"
    else:
        demos, poses_from = read_recordings(dataset, source, format=fmt or "auto").all_demos(), str(dataset)
    poses = handover_poses(source, demos)
    t0 = time.perf_counter()
    found = search_placement(settings, poses)
    seconds = time.perf_counter() - t0
    written = None
    if write_to is not None:
        cmd = command if command is not None else " ".join(["ipromp-pin", *sys.argv[1:]])
        note = [
            f"Suggested by `{cmd}`:",
            f"{found.at_suggested.n_reached} of {found.at_suggested.n_poses} hand-over poses of "
            f"{poses_from} reached (docs/other_arms.md).",
        ]
        written = write_placement(settings, found.suggested, write_to, note)
    return PlaceOutcome(found, poses_from, seconds, written)


def outcome_lines(outcome: PlaceOutcome, robot: str | Path) -> list[str]:
    """The report of ``place``: the poses, both placements' reach, the suggested table, the file."""
    from ..robot.reachability import placement_toml

    f = outcome.search

    def where(p: object) -> str:
        xyz = ", ".join(f"{v:.3f}" for v in p.xyz_m)  # type: ignore[attr-defined]
        return f"({xyz}) m, yaw {p.rpy_deg[2]:.1f} deg"  # type: ignore[attr-defined]

    lines = [
        f"{f.at_current.n_poses} hand-over poses of {outcome.poses_from} (robot '{f.current.source}''s "
        f"gripper at each demo's end), {f.n_candidates} placements scored on {f.n_subset} of them in "
        f"{outcome.seconds:.1f} s",
        f"current placement {where(f.current)}: {f.at_current.summary()}",
        f"suggested placement {where(f.suggested)}: {f.at_suggested.summary()}",
        "",
        placement_toml(f.suggested).rstrip("\n"),
    ]
    if outcome.written is not None:
        lines += ["", f"written to {outcome.written}; use it with --robot {outcome.written}"]
    return lines
