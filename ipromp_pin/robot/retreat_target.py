"""Where the arm goes after the hand-over: a task's ``retreat`` entry in the task file (objects.toml).

One inline table per task, beside the object's fields (:mod:`ipromp_pin.robot.objects`)::

    [aluminum_hold]
    mass_kg = 0.42
    holder = "robot_receives"
    retreat = { to = "start" }                       # back to the robot's start configuration
    # retreat = { joints_rad = [0.0, -0.5, ...] }    # a joint configuration, one angle [rad] per arm joint
    # retreat = { position_m = [0.6, 0.3, 0.2] }     # a gripper position [m] in the base frame (IK, the
    #                                                # hand-over orientation kept)
    # any of them with dwell_s = 0.5: the time [s] the arm holds still at the hand-over before leaving

Exactly one of ``to = "start"``, ``joints_rad``, ``position_m``. :func:`parse_retreat` checks what the
file alone can tell (keys, types, finite values, a position at most :data:`MAX_RETREAT_DISTANCE_M`
from the base frame's origin, a dwell in [0, :data:`MAX_DWELL_S`] s); :func:`check_retreat_robot`
what needs the robot (the number of joints, the joint limits less the settings' margin). Both raise
a :class:`~ipromp_pin.exceptions.RobotError` naming the file, the field and the problem, before
anything is computed. :mod:`ipromp_pin.planning.retreat` plans the motion.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..fields import unknown
from .model import Robot
from .ranges import PLAUSIBLE_RANGES
from .settings import settings_error

RETREAT_KINDS = ("start", "joints", "position")
"""``start``: the robot's configuration at the start of its approach; ``joints``: a configured joint
configuration; ``position``: a configured gripper position, reached by inverse kinematics."""

DEFAULT_DWELL_S = 0.5
"""Default time [s] the arm holds still at the hand-over before it retreats (the gripper closes on, or
lets go of, the object meanwhile)."""

MAX_DWELL_S = PLAUSIBLE_RANGES["<task>.retreat.dwell_s"].hi
"""Longest dwell [s] accepted."""

MAX_RETREAT_DISTANCE_M = PLAUSIBLE_RANGES["<task>.retreat.position_m"].hi
"""Largest distance [m] of a retreat position from the base frame's origin (Baxter reaches ~1.2 m)."""

_KEYS = ("to", "joints_rad", "position_m", "dwell_s")


@dataclass(frozen=True)
class RetreatTarget:
    """A validated retreat entry.

    Attributes:
        kind: One of :data:`RETREAT_KINDS`.
        joints_rad: The configured joint configuration (n_joints,) in [rad] (``kind == "joints"``).
        position_m: The configured gripper position (3,) in [m], base frame (``kind == "position"``).
        dwell_s: Time [s] holding still at the hand-over before leaving.
        field: The entry's field in the task file (``"<task>.retreat"``), for messages.
        path: The task file, for messages.
    """

    kind: str
    joints_rad: np.ndarray | None = None
    position_m: np.ndarray | None = None
    dwell_s: float = DEFAULT_DWELL_S
    field: str = "retreat"
    path: Path = Path("objects.toml")

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable form (reports)."""
        return {
            "to": self.kind,
            "joints_rad": None if self.joints_rad is None else [float(v) for v in self.joints_rad],
            "position_m": None if self.position_m is None else [float(v) for v in self.position_m],
            "dwell_s": self.dwell_s,
        }

    def error(self, key: str | None, problem: str) -> Exception:
        """The one-line error about this entry (``key``: its sub-field, e.g. ``"position_m"``)."""
        return settings_error(self.path, self.field if key is None else f"{self.field}.{key}", problem)


def _numbers(value: object, path: Path, name: str, length: int | None = None) -> np.ndarray:
    if not isinstance(value, list) or (length is not None and len(value) != length):
        want = "a list of numbers" if length is None else f"a list of {length} numbers"
        raise settings_error(path, name, f"must be {want}, got {value!r}")
    out = []
    for v in value:
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise settings_error(path, name, f"must hold numbers, got {v!r}")
        if not math.isfinite(float(v)):
            raise settings_error(path, name, f"must be finite, got {v}")
        out.append(float(v))
    return np.array(out)


def _dwell(value: object, path: Path, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(float(value)):
        raise settings_error(path, name, f"must be a finite number of seconds, got {value!r}")
    rng = PLAUSIBLE_RANGES["<task>.retreat.dwell_s"]
    if not rng.contains(float(value)):
        raise settings_error(path, name, f"must be in {rng.text()} ({rng.source}), got {value}")
    return float(value)


def parse_retreat(value: object, path: Path, field: str) -> RetreatTarget:
    """The retreat entry ``value`` of the task file ``path`` (``field``: ``"<task>.retreat"``).

    Raises:
        RobotError: not a table, an unknown key, none or several targets, ``to`` other than
            ``"start"``, non-numbers or non-finite values, a position of the wrong length or more than
            :data:`MAX_RETREAT_DISTANCE_M` from the base, a dwell outside [0, :data:`MAX_DWELL_S`] s.
    """
    if not isinstance(value, dict):
        raise settings_error(
            path,
            field,
            'must be a table: { to = "start" }, { joints_rad = [...] } or { position_m = [x, y, z] }',
        )
    for key in value:
        if key not in _KEYS:
            raise settings_error(path, f"{field}.{key}", unknown(key, _KEYS))
    given = [k for k in ("to", "joints_rad", "position_m") if k in value]
    if len(given) != 1:
        raise settings_error(
            path, field, f"give exactly one of to, joints_rad, position_m (got {', '.join(given) or 'none'})"
        )
    dwell = _dwell(value.get("dwell_s", DEFAULT_DWELL_S), path, f"{field}.dwell_s")
    if given[0] == "to":
        if value["to"] != "start":
            raise settings_error(path, f"{field}.to", f'must be "start", got {value["to"]!r}')
        return RetreatTarget("start", dwell_s=dwell, field=field, path=path)
    if given[0] == "joints_rad":
        q = _numbers(value["joints_rad"], path, f"{field}.joints_rad")
        return RetreatTarget("joints", joints_rad=q, dwell_s=dwell, field=field, path=path)
    p = _numbers(value["position_m"], path, f"{field}.position_m", 3)
    if np.linalg.norm(p) > MAX_RETREAT_DISTANCE_M:
        raise settings_error(
            path,
            f"{field}.position_m",
            f"{np.linalg.norm(p):.3f} m from the base frame's origin (at most {MAX_RETREAT_DISTANCE_M:g} m: "
            f"{PLAUSIBLE_RANGES['<task>.retreat.position_m'].source})",
        )
    return RetreatTarget("position", position_m=p, dwell_s=dwell, field=field, path=path)


def check_retreat_robot(target: RetreatTarget, robot: Robot) -> None:
    """Refuse a joint target that does not fit ``robot``: the wrong number of angles, or an angle
    outside its joint limits less the settings' position margin (where every planned path must stay).

    Raises:
        RobotError: naming the file, the field, the joint and its limits.
    """
    if target.joints_rad is None:
        return
    q = target.joints_rad
    if q.size != robot.n_joints:
        raise target.error(
            "joints_rad",
            f"has {q.size} angles, robot '{robot.settings.name}' has {robot.n_joints} arm joints",
        )
    lo = robot.lower_rad + robot.settings.position_margin_rad
    hi = robot.upper_rad - robot.settings.position_margin_rad
    bad = np.flatnonzero((q < lo) | (q > hi))
    if bad.size:
        j = int(bad[0])
        raise target.error(
            "joints_rad",
            f"{robot.joint_names[j]} = {q[j]:.4f} rad outside its limits less the margin "
            f"[{lo[j]:.4f}, {hi[j]:.4f}] rad",
        )
