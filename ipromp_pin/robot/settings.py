"""Robot settings files (``robots/*.toml``): reading and validating them, no Pinocchio model yet.

A settings file names the URDF/SRDF (from the example-robot-data package or relative to the file),
the arm's joints in kinematic order, the recorded-to-model joint name mapping, the end-effector
frame and its calibrated tool offset, the limits, the configuration at which every non-arm joint is
held and the hand-over workspace. Adding an arm or a robot needs a new settings file, not new code.
The schema is described in ``robots/README.md``; the checks that need the model (joint and frame
names, URDF limits, held configuration) are made when it is built (:mod:`ipromp_pin.robot.model`).

A bare name such as ``"baxter_left"`` is looked up among the shipped settings files
(:data:`ROBOTS_DIR`).
"""

from __future__ import annotations

import importlib.metadata
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..exceptions import RobotError
from ..shipped import ROBOTS_DIR
from .human_settings import HumanSettings, read_human_settings

__all__ = [
    "EE_FRAME",
    "DemoLimitRecipe",
    "ROBOTS_DIR",
    "RobotSettings",
    "Workspace",
    "find_robot_data_dir",
    "load_robot_settings",
    "resolve_settings_path",
    "settings_error",
]

EE_FRAME = "ee"
"""Default name of the end-effector frame added to the model (parent frame * tool offset)."""

_SCHEMA_VERSION = 1

PLAUSIBLE_RANGES: dict[str, tuple[float, float]] = {
    "limits.position_margin_rad": (0.0, 0.5),
    "limits.velocity_rad_s": (1e-3, 100.0),
    "limits.acceleration_rad_s2": (1e-3, 1e4),
    "limits.jerk_rad_s3": (1e-2, 1e6),
    "checks.min_clearance_m": (0.0, 1.0),
    "checks.collision_max_step_rad": (1e-3, 1.0),
    "checks.max_hand_distance_m": (1e-3, 10.0),
    "calibration offsets [m]": (0.0, 1.0),
    "workspace [m]": (-10.0, 10.0),
    "fixed_joints [rad or m]": (-10.0, 10.0),
}
"""Ranges, in the units of each field, outside which a settings value is refused before anything
is computed: the limits of real arms lie well inside them (Baxter: 1.5-4 rad/s, 1 rad/s^2), and
values outside make the planner allocate absurd amounts (a velocity limit of 1e-9 rad/s: a
trajectory of 1e9 s, or a collision step of 1e-12 rad: 1e12 checked samples) or make every check
meaningless. Calibration offsets are corrections of millimetres, positions are within the tracking
range of the hand (bounds: each coordinate)."""


def settings_error(source: object, field_name: str | None, problem: str) -> RobotError:
    """The error for a bad settings file or model: ``"<source>: field '<field_name>': <problem>"``."""
    where = str(source)
    if field_name:
        where += f": field '{field_name}'"
    return RobotError(f"{where}: {problem}")


@dataclass(frozen=True)
class DemoLimitRecipe:
    """How a limit profile is derived from demonstrations (``[limits.demonstrated]``; used by
    :func:`ipromp_pin.motion.limits.demonstrated_profile`).

    Attributes:
        percentile: Percentile, in (0, 100], of the per-demo peak |velocity|, |acceleration| and
            |jerk| taken as the limit.
        window_s: Savitzky-Golay differentiation window in [s] (polynomial order 4).
    """

    percentile: float = 90.0
    window_s: float = 0.34


@dataclass(frozen=True)
class Workspace:
    """Region of the base frame in which a hand-over position must lie.

    Attributes:
        shape: ``"box"`` or ``"sphere"``.
        min_m: Box lower corner (3,) in [m] (box only).
        max_m: Box upper corner (3,) in [m] (box only).
        center_m: Sphere centre (3,) in [m] (sphere only).
        radius_m: Sphere radius in [m] (sphere only).
    """

    shape: str
    min_m: np.ndarray | None = None
    max_m: np.ndarray | None = None
    center_m: np.ndarray | None = None
    radius_m: float | None = None

    def contains(self, p: np.ndarray) -> bool:
        """Whether position ``p`` (3,) in [m] lies inside."""
        return self.distance_outside(p) <= 0.0

    def distance_outside(self, p: np.ndarray) -> float:
        """Distance in [m] from ``p`` (3,) to the region; negative inside (depth below the surface)."""
        p = np.asarray(p, dtype=float)
        if self.shape == "sphere":
            center, radius = self._sphere()
            return float(np.linalg.norm(p - center) - radius)
        lo, hi = self._box()
        below = lo - p
        above = p - hi
        outside = np.maximum(np.maximum(below, above), 0.0)
        if np.any(outside > 0):
            return float(np.linalg.norm(outside))
        return float(np.max(np.maximum(below, above)))

    def to_dict(self) -> dict:
        """JSON-serialisable description."""
        if self.shape == "sphere":
            center, radius = self._sphere()
            return {"shape": "sphere", "center_m": center.tolist(), "radius_m": radius}
        lo, hi = self._box()
        return {"shape": "box", "min_m": lo.tolist(), "max_m": hi.tolist()}

    def _sphere(self) -> tuple[np.ndarray, float]:
        if self.center_m is None or self.radius_m is None:
            raise ValueError("a sphere workspace needs center_m and radius_m")
        return self.center_m, self.radius_m

    def _box(self) -> tuple[np.ndarray, np.ndarray]:
        if self.min_m is None or self.max_m is None:
            raise ValueError("a box workspace needs min_m and max_m")
        return self.min_m, self.max_m


@dataclass(frozen=True)
class RobotSettings:
    """Validated content of a robot settings file (see ``robots/README.md``).

    Attributes:
        name: Robot/arm name, e.g. ``"baxter_left"``.
        path: Resolved settings file path.
        urdf_path: Resolved URDF path.
        srdf_path: Resolved SRDF path, or ``None`` (no disabled collision pairs).
        package_dirs: Folders searched for ``package://`` mesh URIs.
        arm_joints: The arm's model joint names in kinematic order (n_joints,).
        recorded_names: Recorded joint name -> model joint name.
        ee_parent_frame: Model frame the tool offset is expressed in, e.g. ``"left_gripper"``.
        ee_frame: Name of the added end-effector frame (parent frame * offset).
        tool_offset_m: Tool offset (3,) in [m] in the parent frame's axes.
        mount_offset_m: Translation (3,) in [m] of the arm's mount (the placement of its first joint),
            in the frame of that joint's parent (Baxter: the base frame). Each Baxter has its own
            arm-mount origins in its on-robot URDF; this corrects the generic URDF's.
        calibration_info: Calibration provenance (fit, command, date, residuals), as in the file.
        position_margin_rad: Joint-limit margin(s) (n_joints,) in [rad].
        velocity_override_rad_s: Optional velocity limits (n_joints,) in [rad/s] that replace the URDF's.
        acceleration_rad_s2: Acceleration limits (n_joints,) in [rad/s^2].
        jerk_rad_s3: Jerk limits (n_joints,) in [rad/s^3].
        demonstrated_limits: How the ``demonstrated`` limit profile is derived from training demos.
        fixed_joints: Non-arm model joint name -> held value in [rad] or [m].
        workspace: Hand-over workspace.
        min_clearance_m: Required minimum self-collision clearance in [m].
        collision_max_step_rad: Largest joint step between collision-checked path samples in [rad].
        max_hand_distance_m: Largest gripper-hand distance at the hand-over in [m].
        human: The ``[human]`` / ``[iso15066]`` tables (:mod:`.human_settings`).
    """

    name: str
    path: Path
    urdf_path: Path
    srdf_path: Path | None
    package_dirs: tuple[str, ...]
    arm_joints: tuple[str, ...]
    recorded_names: dict[str, str]
    ee_parent_frame: str
    ee_frame: str
    tool_offset_m: np.ndarray
    mount_offset_m: np.ndarray
    calibration_info: dict
    position_margin_rad: np.ndarray
    velocity_override_rad_s: np.ndarray | None
    acceleration_rad_s2: np.ndarray
    jerk_rad_s3: np.ndarray
    demonstrated_limits: DemoLimitRecipe
    fixed_joints: dict[str, float]
    workspace: Workspace
    min_clearance_m: float
    collision_max_step_rad: float
    max_hand_distance_m: float
    human: HumanSettings = field(default_factory=HumanSettings)

    @property
    def n_joints(self) -> int:
        """Number of arm joints."""
        return len(self.arm_joints)

    @property
    def recorded_arm_joints(self) -> tuple[str, ...]:
        """The arm's joints as the recordings name them, in kinematic order (what readers ask for)."""
        inverse = {model: rec for rec, model in self.recorded_names.items()}
        return tuple(inverse[j] for j in self.arm_joints)


def find_robot_data_dir(package: str = "example-robot-data") -> Path:
    """Data folder of an installed robot-description package (its cmeel ``share`` folder).

    Raises:
        RobotError: the package is not installed or ships no data folder.
    """
    try:
        dist = importlib.metadata.distribution(package)
    except importlib.metadata.PackageNotFoundError as exc:
        raise RobotError(f"robot description package '{package}' is not installed") from exc
    share = Path(str(dist.locate_file("cmeel.prefix/share")))
    if not share.is_dir():
        raise RobotError(f"package '{package}' has no data folder at {share}")
    return share


def resolve_settings_path(path_or_name: str | Path) -> Path:
    """Resolve a settings file path, or a bare name (``"baxter_left"``) in :data:`ROBOTS_DIR`."""
    p = Path(path_or_name)
    if p.is_file():
        return p.resolve()
    if p.suffix == "" and len(p.parts) == 1:
        candidate = ROBOTS_DIR / f"{p.name}.toml"
        if candidate.is_file():
            return candidate.resolve()
    known = ", ".join(sorted(f.stem for f in ROBOTS_DIR.glob("*.toml"))) if ROBOTS_DIR.is_dir() else ""
    raise RobotError(f"{path_or_name}: robot settings file not found (known robots: {known or 'none'})")


def _table(doc: dict, key: str, source: Path, required: bool = True) -> dict:
    value = doc.get(key)
    if value is None:
        if required:
            raise settings_error(source, key, "missing table")
        return {}
    if not isinstance(value, dict):
        raise settings_error(source, key, "must be a table")
    return value


def _get(table: dict, key: str, source: Path, prefix: str, kind: type | tuple, default: Any = ...) -> Any:
    """``table[key]``, which must be of type ``kind`` (an int is accepted as a float), or ``default``
    when absent (``...``: the key is required)."""
    if key not in table:
        if default is ...:
            raise settings_error(source, f"{prefix}.{key}", "missing")
        return default
    value = table[key]
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not isinstance(value, kind) or isinstance(value, bool) and kind is not bool:
        raise settings_error(source, f"{prefix}.{key}", f"must be of type {getattr(kind, '__name__', kind)}")
    return value


def _in_range(arr: np.ndarray, source: Path, name: str, key: str | None = None) -> np.ndarray:
    lo, hi = PLAUSIBLE_RANGES[key or name]
    bad = (arr < lo) | (arr > hi)
    if np.any(bad):
        raise settings_error(
            source,
            name,
            f"implausible value {arr[bad][0]:g} (plausible range [{lo:g}, {hi:g}]; values: {arr.tolist()})",
        )
    return arr


def _positive_vector(value: object, n: int, source: Path, name: str, allow_zero: bool = False) -> np.ndarray:
    if isinstance(value, int | float) and not isinstance(value, bool):
        value = [value] * n
    if not isinstance(value, list) or len(value) != n:
        raise settings_error(source, name, f"must be a number or a list of {n} numbers")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise settings_error(source, name, "must contain numbers only") from exc
    if not np.all(np.isfinite(arr)):
        raise settings_error(source, name, f"must be finite, got {arr.tolist()}")
    bad = arr < 0 if allow_zero else arr <= 0
    if np.any(bad):
        which = "negative" if allow_zero else "zero or negative"
        raise settings_error(source, name, f"{which} value {arr[bad][0]} (values: {arr.tolist()})")
    return _in_range(arr, source, name) if name in PLAUSIBLE_RANGES else arr


def _vector3(value: object, source: Path, name: str) -> np.ndarray:
    if not isinstance(value, list) or len(value) != 3:
        raise settings_error(source, name, "must be a list of 3 numbers")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise settings_error(source, name, "must contain numbers only") from exc
    if not np.all(np.isfinite(arr)):
        raise settings_error(source, name, f"must be finite, got {arr.tolist()}")
    return arr


def _demo_limit_recipe(limits: dict, path: Path) -> DemoLimitRecipe:
    """The optional ``[limits.demonstrated]`` table (percentile in (0, 100], window_s > 0)."""
    table = limits.get("demonstrated", {})
    if not isinstance(table, dict):
        raise settings_error(path, "limits.demonstrated", "must be a table")
    known = {"percentile", "window_s"}
    for key in table:
        if key not in known:
            raise settings_error(
                path, f"limits.demonstrated.{key}", "unknown key (known: percentile, window_s)"
            )
    default = DemoLimitRecipe()
    pct = _get(table, "percentile", path, "limits.demonstrated", float, default.percentile)
    win = _get(table, "window_s", path, "limits.demonstrated", float, default.window_s)
    if not (math.isfinite(pct) and 0 < pct <= 100):
        raise settings_error(path, "limits.demonstrated.percentile", f"must be in (0, 100], got {pct}")
    if not (math.isfinite(win) and win > 0):
        raise settings_error(path, "limits.demonstrated.window_s", f"must be positive and finite, got {win}")
    return DemoLimitRecipe(float(pct), float(win))


def _read_document(path: Path) -> dict:
    """The parsed TOML document of ``path``, its ``schema_version`` checked."""
    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise settings_error(path, None, f"not valid TOML: {exc}") from None
    except OSError as exc:
        raise settings_error(path, None, f"cannot read: {exc.strerror or exc}") from None
    version = doc.get("schema_version", _SCHEMA_VERSION)
    if version != _SCHEMA_VERSION:
        raise settings_error(
            path, "schema_version", f"unsupported version {version} (this code reads {_SCHEMA_VERSION})"
        )
    return doc


def _description_file(rel: str, key: str, base: Path, path: Path) -> Path:
    """The resolved file of ``description.<key>`` (``rel``, relative to ``base``), which must exist."""
    if Path(rel).is_absolute():
        raise settings_error(
            path, f"description.{key}", "must be a relative path (no absolute paths in settings)"
        )
    resolved = (base / rel).resolve()
    if not resolved.is_file():
        raise settings_error(path, f"description.{key}", f"file not found: {resolved}")
    return resolved


def _arm_joints(arm: dict, path: Path) -> tuple[list[str], dict[str, str]]:
    """The ``[arm]`` table: joint names in kinematic order and the recorded -> model name mapping."""
    joints = _get(arm, "joints", path, "arm", list)
    if not joints or not all(isinstance(j, str) and j for j in joints):
        raise settings_error(path, "arm.joints", "must be a non-empty list of joint names")
    if len(set(joints)) != len(joints):
        raise settings_error(path, "arm.joints", f"joint listed twice in {joints}")
    recorded = _get(arm, "recorded_names", path, "arm", dict, {j: j for j in joints})
    for rec, mod in recorded.items():
        if not isinstance(mod, str) or mod not in joints:
            raise settings_error(
                path, f"arm.recorded_names.{rec}", f"maps to '{mod}', which is not one of arm.joints"
            )
    missing = [j for j in joints if j not in recorded.values()]
    if missing:
        raise settings_error(path, "arm.recorded_names", f"no recorded name maps to {missing}")
    return joints, recorded


def _calibration(calib: dict, path: Path) -> tuple[np.ndarray, np.ndarray, dict]:
    """The optional ``[calibration]`` table: tool offset (3,) and mount offset (3,) in [m], provenance."""
    offset = _vector3(calib.get("tool_offset_m", [0.0, 0.0, 0.0]), path, "calibration.tool_offset_m")
    mount = _vector3(calib.get("mount_offset_m", [0.0, 0.0, 0.0]), path, "calibration.mount_offset_m")
    for key, v in (("calibration.tool_offset_m", offset), ("calibration.mount_offset_m", mount)):
        _in_range(np.abs(v), path, key, "calibration offsets [m]")
    calib_info = {k: v for k, v in calib.items() if k not in ("tool_offset_m", "mount_offset_m")}
    return offset, mount, calib_info


def _joint_limits(
    limits: dict, n: int, path: Path
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, np.ndarray]:
    """The ``[limits]`` vectors (n,): position margin [rad], velocity override [rad/s] or ``None``,
    acceleration [rad/s^2] and jerk [rad/s^3]."""
    margin = _positive_vector(
        limits.get("position_margin_rad", 0.0), n, path, "limits.position_margin_rad", allow_zero=True
    )
    vel = None
    if "velocity_rad_s" in limits:
        vel = _positive_vector(limits["velocity_rad_s"], n, path, "limits.velocity_rad_s")
    if "acceleration_rad_s2" not in limits:
        raise settings_error(
            path, "limits.acceleration_rad_s2", "missing (the URDF has no acceleration limits)"
        )
    acc = _positive_vector(limits["acceleration_rad_s2"], n, path, "limits.acceleration_rad_s2")
    if "jerk_rad_s3" not in limits:
        raise settings_error(path, "limits.jerk_rad_s3", "missing (the URDF has no jerk limits)")
    jerk = _positive_vector(limits["jerk_rad_s3"], n, path, "limits.jerk_rad_s3")
    return margin, vel, acc, jerk


def _fixed_joints(fixed_raw: dict, joints: list[str], path: Path) -> dict[str, float]:
    """The optional ``[fixed_joints]`` table: non-arm joint name -> held value in [rad] or [m]."""
    fixed: dict[str, float] = {}
    for k, v in fixed_raw.items():
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise settings_error(path, f"fixed_joints.{k}", f"must be a finite number, got {v!r}")
        if k in joints:
            raise settings_error(
                path, f"fixed_joints.{k}", "is an arm joint; only non-arm joints can be fixed"
            )
        fixed[k] = float(
            _in_range(np.array([float(v)]), path, f"fixed_joints.{k}", "fixed_joints [rad or m]")[0]
        )
    return fixed


def _workspace(ws: dict, path: Path) -> Workspace:
    """The ``[workspace]`` table: a box (``min_m``, ``max_m``) or a sphere (``center_m``, ``radius_m``)."""
    shape = _get(ws, "shape", path, "workspace", str, "box")
    if shape == "box":
        lo = _in_range(
            _vector3(ws.get("min_m"), path, "workspace.min_m"), path, "workspace.min_m", "workspace [m]"
        )
        hi = _in_range(
            _vector3(ws.get("max_m"), path, "workspace.max_m"), path, "workspace.max_m", "workspace [m]"
        )
        if np.any(lo >= hi):
            raise settings_error(path, "workspace", f"min_m {lo.tolist()} must be below max_m {hi.tolist()}")
        return Workspace("box", min_m=lo, max_m=hi)
    if shape == "sphere":
        c = _vector3(ws.get("center_m"), path, "workspace.center_m")
        _in_range(c, path, "workspace.center_m", "workspace [m]")
        r = _get(ws, "radius_m", path, "workspace", float)
        if not (math.isfinite(r) and 0 < r <= PLAUSIBLE_RANGES["workspace [m]"][1]):
            raise settings_error(path, "workspace.radius_m", f"must be in (0, 10] m, got {r}")
        return Workspace("sphere", center_m=c, radius_m=float(r))
    raise settings_error(path, "workspace.shape", f"must be 'box' or 'sphere', got '{shape}'")


def _check_thresholds(checks: dict, path: Path) -> tuple[float, float, float]:
    """The optional ``[checks]`` table: min clearance [m], collision step [rad], hand distance [m]."""
    clearance = _get(checks, "min_clearance_m", path, "checks", float, 0.0)
    step = _get(checks, "collision_max_step_rad", path, "checks", float, 0.05)
    hand = _get(checks, "max_hand_distance_m", path, "checks", float, 0.25)
    for key, value, lo_ok in (
        ("min_clearance_m", clearance, True),
        ("collision_max_step_rad", step, False),
        ("max_hand_distance_m", hand, False),
    ):
        if not math.isfinite(value) or value < 0 or (value == 0 and not lo_ok):
            raise settings_error(
                path, f"checks.{key}", f"must be {'>= 0' if lo_ok else '> 0'} and finite, got {value}"
            )
        _in_range(np.array([value]), path, f"checks.{key}")
    return float(clearance), float(step), float(hand)


def load_robot_settings(path_or_name: str | Path) -> RobotSettings:
    """Read and validate a robot settings file (file-level checks; model checks are in :func:`load_robot`).

    Args:
        path_or_name: Path of a ``.toml`` settings file, or the name of one in ``robots/``.

    Raises:
        RobotError: unreadable file, missing or malformed field, infeasible limits; the message
            names the file, the field and the problem.
    """
    path = resolve_settings_path(path_or_name)
    doc = _read_document(path)
    name = _get(doc, "name", path, "", str, path.stem)

    desc = _table(doc, "description", path)
    package = _get(desc, "package", path, "description", str, "")
    base = find_robot_data_dir(package) if package else path.parent
    urdf_path = _description_file(_get(desc, "urdf", path, "description", str), "urdf", base, path)
    srdf_rel = _get(desc, "srdf", path, "description", str, "")
    srdf_path = _description_file(srdf_rel, "srdf", base, path) if srdf_rel else None

    joints, recorded = _arm_joints(_table(doc, "arm", path), path)

    ee = _table(doc, "end_effector", path)
    parent_frame = _get(ee, "parent_frame", path, "end_effector", str)
    ee_frame = _get(ee, "frame", path, "end_effector", str, EE_FRAME)

    offset, mount, calib_info = _calibration(_table(doc, "calibration", path, required=False), path)

    limits = _table(doc, "limits", path)
    margin, vel, acc, jerk = _joint_limits(limits, len(joints), path)
    demo_limits = _demo_limit_recipe(limits, path)

    fixed = _fixed_joints(_table(doc, "fixed_joints", path, required=False), joints, path)
    workspace = _workspace(_table(doc, "workspace", path), path)
    clearance, step, hand = _check_thresholds(_table(doc, "checks", path, required=False), path)

    return RobotSettings(
        name=name,
        path=path,
        urdf_path=urdf_path,
        srdf_path=srdf_path,
        package_dirs=(str(base),),
        arm_joints=tuple(joints),
        recorded_names=dict(recorded),
        ee_parent_frame=parent_frame,
        ee_frame=ee_frame,
        tool_offset_m=offset,
        mount_offset_m=mount,
        calibration_info=calib_info,
        position_margin_rad=margin,
        velocity_override_rad_s=vel,
        acceleration_rad_s2=acc,
        jerk_rad_s3=jerk,
        demonstrated_limits=demo_limits,
        fixed_joints=fixed,
        workspace=workspace,
        min_clearance_m=clearance,
        collision_max_step_rad=step,
        max_hand_distance_m=hand,
        human=read_human_settings(doc, path),
    )
