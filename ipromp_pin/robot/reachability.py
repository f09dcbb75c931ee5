"""Where to place an arm in the scene of another robot's recordings: how many of the recorded
hand-over poses it reaches at a base placement, and a search for the placement that reaches the most.

The hand-over poses are the source robot's gripper poses (its ``ee`` frame, forward kinematics) at
the last joint sample of every demo, in the source's base frame (the scene frame). An arm's
placement reaches a pose when :class:`~ipromp_pin.robot.arm_transfer.PoseSolver` (the inverse
kinematics of the retargeting, from its deterministic seeds) ends within
:data:`~ipromp_pin.robot.arm_transfer.TOL_M` and :data:`~ipromp_pin.robot.arm_transfer.TOL_RAD`.

:func:`search_placement` scores base positions and yaws of a grid (:class:`PlacementGrid`) on a
subset of the poses by (fraction reached, median joint-limit margin of the solutions), refines the
best around it with halved steps, then measures the best candidates and the arm's own placement on
every pose and suggests the best of them: the suggestion never reaches fewer poses than the arm's
own placement. :func:`write_placement` stores a placement in a copy of the arm's settings file.
Used by ``ipromp-pin place`` and ``benchmarks/placement.py`` (the study behind the shipped arms'
default placements, ``docs/other_arms.md``).
"""

from __future__ import annotations

import dataclasses
import itertools
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from .. import atomic
from ..data import GRIPPER, ROBOT, Demo
from ..exceptions import DataError, RobotError
from ..signals.gripper import gripper_positions, gripper_rotations
from .arm_transfer import TOL_M, TOL_RAD, PoseSolver, gripper_poses
from .model import Robot, build_robot, placement_pose
from .settings import ROBOTS_DIR, Placement, RobotSettings, load_robot_settings, settings_error


@dataclass(frozen=True)
class PlacementGrid:
    """Candidate base placements: every combination of the positions [m] (in the source robot's
    base frame) and yaws [deg]; roll and pitch are kept from the arm's own placement."""

    x_m: tuple[float, ...]
    y_m: tuple[float, ...]
    z_m: tuple[float, ...]
    yaw_deg: tuple[float, ...] = (0.0,)

    def candidates(self) -> list[tuple[float, float, float, float]]:
        """(x, y, z, yaw) of every grid point."""
        return list(itertools.product(self.x_m, self.y_m, self.z_m, self.yaw_deg))

    def steps(self) -> tuple[float, float, float, float]:
        """The grid's spacing per axis (0 for an axis with one value)."""

        def step(v: tuple[float, ...]) -> float:
            return float(np.min(np.diff(sorted(v)))) if len(v) > 1 else 0.0

        return step(self.x_m), step(self.y_m), step(self.z_m), step(self.yaw_deg)


DEFAULT_GRID = PlacementGrid(
    x_m=(0.0, 0.25, 0.5),
    y_m=(-0.3, -0.1, 0.1, 0.3, 0.5),
    z_m=(-0.3, -0.1, 0.1),
    yaw_deg=(-45.0, 0.0, 45.0),
)
"""The region searched in Baxter's base frame (the frame of every shipped recording): behind the
recorded hand-overs (which lie beyond x = 0.55 m, Baxter's workspace box) and short of the assumed
human (torso at x = 1.27 m), from beside Baxter's right arm to beyond its left one, the base from
0.3 m below to 0.1 m above Baxter's base frame (table heights), turned at most 45 deg from facing
the human; refined twice around the best point with halved steps."""

REFINEMENTS = 2
"""Times the search refines around its best point, each time with half the previous steps."""

SUBSET_SIZE = 20
"""Poses (evenly spread over the dataset's) every candidate is scored on; the finalists are measured
on every pose."""

FINALISTS = 3
"""Best candidates of the subset measured on every pose, with the arm's own placement."""


@dataclass(frozen=True)
class Reach:
    """How many hand-over poses an arm reaches at one placement.

    Attributes:
        n_poses: Poses tried.
        n_reached: Poses reached within 1 mm and 0.5 deg.
        median_margin: Median, over the reached poses, of the solution's smallest distance to a joint
            limit as a fraction of the joint's range (0 when none is reached).
        max_residual_mm: Largest position residual [mm] where reached.
        max_residual_deg: Largest orientation residual [deg] where reached.
        worst_miss_mm: Largest position residual [mm] of the poses not reached (0 when all are).
    """

    n_poses: int
    n_reached: int
    median_margin: float
    max_residual_mm: float
    max_residual_deg: float
    worst_miss_mm: float

    @property
    def fraction(self) -> float:
        """Fraction of the poses reached."""
        return self.n_reached / self.n_poses if self.n_poses else 0.0

    def key(self) -> tuple[float, float]:
        """The ranking of placements: the fraction reached, then the median limit margin."""
        return self.fraction, self.median_margin

    def summary(self) -> str:
        """One clause, e.g. ``60/60 (100.0 %) reached, median limit margin 0.221, ...``."""
        text = (
            f"{self.n_reached}/{self.n_poses} ({self.fraction:.1%}) reached, median joint-limit margin "
            f"{self.median_margin:.3f} of the range"
        )
        if self.n_reached:
            text += f", largest residual {self.max_residual_mm:.3f} mm / {self.max_residual_deg:.3f} deg"
        if self.n_reached < self.n_poses:
            text += f"; the farthest missed pose stays {self.worst_miss_mm:.1f} mm away"
        return text


@dataclass(frozen=True)
class PlacementSearch:
    """The result of :func:`search_placement`.

    Attributes:
        suggested: The suggested placement.
        at_suggested: Its reach on every pose.
        current: The arm's own placement (its settings' ``[placement]``).
        at_current: Its reach on every pose.
        n_candidates: Placements scored (on the subset).
        n_subset: Poses of the subset the candidates were scored on.
    """

    suggested: Placement
    at_suggested: Reach
    current: Placement
    at_current: Reach
    n_candidates: int
    n_subset: int


def handover_poses(source: Robot, demos: Sequence[Demo]) -> list[pin.SE3]:
    """The source robot's gripper poses (N,) in its base frame at the last sample of each demo (of
    demos without joints: their gripper pose path's last pose).

    Raises:
        DataError: no demos, or a demo whose robot group is not ``source``'s arm joints.
    """
    if not demos:
        raise DataError(None, "dataset", "no demos: no hand-over poses to reach")
    if all(ROBOT not in d.groups and GRIPPER in d.groups for d in demos):
        last = np.array([d.groups[GRIPPER][-1] for d in demos])
        return [pin.SE3(r, p) for p, r in zip(gripper_positions(last), gripper_rotations(last), strict=True)]
    n = source.n_joints
    for d in demos:
        q = d.groups.get(ROBOT)
        if q is None or q.ndim != 2 or q.shape[1] != n or len(q) == 0:
            shape = None if q is None else q.shape
            raise DataError(
                d.name, ROBOT, f"expected {n} joints of '{source.settings.name}', got shape {shape}"
            )
    return gripper_poses(source, np.array([d.groups[ROBOT][-1] for d in demos]))


def with_pose(placement: Placement, x: float, y: float, z: float, yaw_deg: float) -> Placement:
    """``placement`` moved to base position (x, y, z) [m] and yaw [deg] (roll and pitch kept)."""
    rpy = np.array([placement.rpy_deg[0], placement.rpy_deg[1], yaw_deg], dtype=float)
    return Placement(placement.source, np.array([x, y, z], dtype=float), rpy)


class ReachTest:
    """Reach of one arm at any base placement, with the arm's model built once: placing the arm at
    ``P`` instead of its built placement ``P0`` is the same as asking its built model for the pose
    ``P0 P^-1 T`` instead of ``T``.

    A pose farther from the first arm joint than the chain's length (the sum of the distances from
    joint to joint to the ``ee`` frame, a bound of the arm's reach) is missed without inverse
    kinematics.
    """

    def __init__(self, settings: RobotSettings) -> None:
        if settings.placement is None:
            raise settings_error(
                settings.path,
                "placement",
                "missing: the arm is not placed in another robot's recordings' scene",
            )
        self.settings = settings
        self.arm = build_robot(settings, collision=False)
        self.solver = PoseSolver(self.arm)
        self.built = placement_pose(settings)
        m = self.arm.model
        first = int(self.arm.arm_joint_ids[0])
        frame = m.frames[self.arm.ee_frame_id]
        length, j = float(np.linalg.norm(frame.placement.translation)), frame.parentJoint
        while j != first:
            length += float(np.linalg.norm(m.jointPlacements[j].translation))
            j = m.parents[j]
        self.chain_length_m = length
        # the first arm joint's origin in the arm's own base frame (fixed: nothing moves it)
        origin = pin.SE3.Identity()
        j = first
        while j != 0:
            origin = m.jointPlacements[j] * origin
            j = m.parents[j]
        self.shoulder_base = self.built.inverse() * origin  # in the unplaced base frame

    def shoulder(self, placement: Placement) -> np.ndarray:
        """The first arm joint's origin (3,) in the scene [m] with the arm at ``placement``."""
        base = placement_pose(dataclasses.replace(self.settings, placement=placement))
        return (base * self.shoulder_base).translation

    def promise(self, poses: Sequence[pin.SE3], placement: Placement) -> tuple[int, float]:
        """A cheap ranking of placements to try first (smaller is more promising): the poses beyond
        the chain's length, then how far the median pose distance is from 0.55 of that length."""
        d = np.linalg.norm(np.array([p.translation for p in poses]) - self.shoulder(placement), axis=1)
        return int(np.sum(d > self.chain_length_m)), abs(float(np.median(d)) / self.chain_length_m - 0.55)

    def reach(
        self,
        poses: Sequence[pin.SE3],
        placement: Placement | None = None,
        max_misses: int | None = None,
        chained: bool = False,
    ) -> Reach | None:
        """The reach over ``poses`` (scene frame) at ``placement`` (default: the settings' own);
        ``None`` as soon as more than ``max_misses`` poses are missed (a bound: the placement cannot
        beat one that missed fewer). ``chained``: each pose's inverse kinematics first tries the
        previous pose's solution as its seed (faster on similar poses; the retargeting itself starts
        from its fixed seeds, which the default measures)."""
        base = (
            self.built
            if placement is None
            else placement_pose(dataclasses.replace(self.settings, placement=placement))
        )
        to_built = self.built * base.inverse()
        shoulder = (base * self.shoulder_base).translation
        margins: list[float] = []
        res_mm = res_deg = miss_mm = 0.0
        misses = 0
        seed = None
        for pose in poses:
            far = float(np.linalg.norm(pose.translation - shoulder)) - self.chain_length_m
            if far > TOL_M:
                ep = far
            else:
                target = to_built * pose
                q, ep, er, _ = self.solver.first_pose(target.rotation, target.translation, seed)
                if ep <= TOL_M and er <= TOL_RAD:
                    seed = q if chained else None
                    margins.append(self.solver.margin(q))
                    res_mm, res_deg = max(res_mm, ep * 1e3), max(res_deg, float(np.degrees(er)))
                    continue
            misses += 1
            miss_mm = max(miss_mm, ep * 1e3)
            if max_misses is not None and misses > max_misses:
                return None
        margin = float(np.median(margins)) if margins else 0.0
        return Reach(len(poses), len(margins), margin, res_mm, res_deg, miss_mm)


def _refined(
    point: tuple[float, ...], steps: tuple[float, ...], grid: PlacementGrid
) -> list[tuple[float, float, float, float]]:
    """The neighbours of ``point`` (x, y, z, yaw) at +-``steps`` within the grid's bounds."""
    bounds = [(min(v), max(v)) for v in (grid.x_m, grid.y_m, grid.z_m, grid.yaw_deg)]
    axes = [
        sorted({float(np.clip(p + d, lo, hi)) for d in (-s, 0.0, s)})
        for p, s, (lo, hi) in zip(point, steps, bounds, strict=True)
    ]
    return [c for c in itertools.product(*axes) if c != tuple(point)]  # type: ignore[misc]


def search_placement(
    settings: RobotSettings,
    poses: Sequence[pin.SE3],
    grid: PlacementGrid = DEFAULT_GRID,
    *,
    subset_size: int = SUBSET_SIZE,
    refinements: int = REFINEMENTS,
) -> PlacementSearch:
    """The base placement of the arm of ``settings`` that reaches the most of ``poses`` (then with
    the largest median limit margin), searched as the module docstring says.

    Args:
        settings: A placed arm's settings (its ``[placement]`` gives the source and roll, pitch).
        poses: Hand-over poses (N,) in the source's base frame (:func:`handover_poses`).
        grid: The candidate positions [m] and yaws [deg] (refined within their bounds).
        subset_size: Candidates are scored on this many poses, evenly spread over ``poses``.
        refinements: Refinements around the best point, each with halved steps.

    Raises:
        RobotError: the arm has no ``[placement]``.
    """
    test = ReachTest(settings)
    current = settings.placement
    assert current is not None
    pick = np.unique(np.linspace(0, len(poses) - 1, min(subset_size, len(poses))).round().astype(int))
    subset = [poses[i] for i in pick]
    scored: dict[tuple[float, ...], Reach] = {}
    best_misses: int | None = None

    def score(points: list[tuple[float, float, float, float]]) -> None:
        nonlocal best_misses
        for p in points:
            key = tuple(round(v, 6) for v in p)
            if key in scored:
                continue
            r = test.reach(subset, with_pose(current, *p), best_misses, chained=True)
            if r is not None:
                scored[key] = r
                missed = r.n_poses - r.n_reached
                best_misses = missed if best_misses is None else min(best_misses, missed)

    # the arm's own placement, then the grid's most promising points first: an early good placement
    # bounds how many poses the others may miss before they are dropped
    own = (*(float(v) for v in current.xyz_m), float(current.rpy_deg[2]))
    score([own])  # type: ignore[list-item]
    score(sorted(grid.candidates(), key=lambda p: test.promise(subset, with_pose(current, *p))))
    own_key = tuple(round(v, 6) for v in own)
    if own_key not in {tuple(round(v, 6) for v in p) for p in grid.candidates()}:
        scored.pop(own_key, None)  # suggested only from the region (or kept below, as the current one)
    steps = grid.steps()
    for _ in range(refinements):
        steps = tuple(s / 2 for s in steps)  # type: ignore[assignment]
        best = max(scored, key=lambda k: scored[k].key())
        score(_refined(best, steps, grid))
    at_current = test.reach(poses)
    assert at_current is not None
    chosen, at_chosen = current, at_current
    for k in sorted(scored, key=lambda k: scored[k].key(), reverse=True)[:FINALISTS]:
        moved = with_pose(current, *k)
        r = test.reach(poses, moved)
        if r is not None and r.key() > at_chosen.key():
            chosen, at_chosen = moved, r
    return PlacementSearch(chosen, at_chosen, current, at_current, len(scored), len(subset))


def placement_toml(placement: Placement, comments: Sequence[str] = ()) -> str:
    """The ``[placement]`` table of ``placement`` (TOML text, comment lines first)."""
    lines = ["[placement]", *(f"# {c}" for c in comments)]
    lines.append(f'source = "{placement.source}"')
    lines.append("xyz_m = [" + ", ".join(f"{v:.3f}" for v in placement.xyz_m) + "]")
    lines.append("rpy_deg = [" + ", ".join(f"{v:.1f}" for v in placement.rpy_deg) + "]")
    return "\n".join(lines) + "\n"


def write_placement(
    settings: RobotSettings, placement: Placement, out_path: str | Path, comments: Sequence[str] = ()
) -> Path:
    """Write a copy of the settings file of ``settings`` with its ``[placement]`` table replaced by
    ``placement`` to ``out_path`` (atomically; read back before it replaces anything).

    Raises:
        RobotError: ``out_path`` is a settings file the package ships, or the written file does not
            read back with the placement.
    """
    path = Path(out_path)
    if path.resolve().parent == ROBOTS_DIR.resolve():
        raise RobotError(
            f"{path}: field 'placement': a shipped settings file is never changed; write to a file of yours"
        )
    text = settings.path.read_text(encoding="utf-8")
    table = placement_toml(placement, comments)
    m = re.search(r"^\[placement\][ \t]*\n", text, flags=re.M)
    if m is None:
        text = text.rstrip("\n") + "\n\n" + table
    else:
        nxt = re.search(r"^\[", text[m.end() :], flags=re.M)
        end = m.end() + nxt.start() if nxt else len(text)
        text = text[: m.start()] + table + ("\n" if nxt else "") + text[end:]
    with atomic.replacing(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
        back = load_robot_settings(tmp).placement
        if back is None or not (
            np.allclose(back.xyz_m, placement.xyz_m, atol=5e-4)
            and np.allclose(back.rpy_deg, placement.rpy_deg, atol=0.05)
        ):
            raise RobotError(
                f"{path}: field 'placement': the written placement did not read back (file unchanged)"
            )
    return path
