"""Robot description: settings files (``robots/*.toml``) and the Pinocchio models they describe.

A settings file names the URDF/SRDF (from the example-robot-data package or relative to the file),
the arm's joints in kinematic order, the recorded-to-model joint name mapping, the end-effector
frame and its calibrated tool offset, the limits, the configuration at which every non-arm joint is
held and the hand-over workspace. Adding an arm or a robot needs a new settings file, not new code.
The schema is described in ``robots/README.md``.

:func:`load_robot` builds the kinematic model (~3 ms) and the collision model (~50 ms) once per
settings file and caches the result in the module-level dictionary ``_ROBOT_CACHE`` (keyed by the
resolved settings path and the file's modification time and size, so a re-calibrated file is
reloaded; :func:`clear_robot_cache` empties it). Visual meshes (~2 s) are never loaded by the
checks; previews call :func:`load_visual_model`.
"""

from __future__ import annotations

import importlib.metadata
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from .exceptions import RobotError

ROBOTS_DIR = Path(__file__).resolve().parents[1] / "robots"
"""Folder of the project's robot settings files (``robots/`` beside the package)."""

EE_FRAME = "ee"
"""Default name of the end-effector frame added to the model (parent frame * tool offset)."""

_SCHEMA_VERSION = 1


def _err(source: object, field_name: str | None, problem: str) -> RobotError:
    where = str(source)
    if field_name:
        where += f": field '{field_name}'"
    return RobotError(f"{where}: {problem}")


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
            return float(np.linalg.norm(p - self.center_m) - self.radius_m)
        below = self.min_m - p
        above = p - self.max_m
        outside = np.maximum(np.maximum(below, above), 0.0)
        if np.any(outside > 0):
            return float(np.linalg.norm(outside))
        return float(np.max(np.maximum(below, above)))

    def to_dict(self) -> dict:
        """JSON-serialisable description."""
        if self.shape == "sphere":
            return {"shape": "sphere", "center_m": self.center_m.tolist(), "radius_m": self.radius_m}
        return {"shape": "box", "min_m": self.min_m.tolist(), "max_m": self.max_m.tolist()}


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
        fixed_joints: Non-arm model joint name -> held value in [rad] or [m].
        workspace: Hand-over workspace.
        min_clearance_m: Required minimum self-collision clearance in [m].
        collision_max_step_rad: Largest joint step between collision-checked path samples in [rad].
        max_hand_distance_m: Largest gripper-hand distance at the hand-over in [m].
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
    fixed_joints: dict[str, float]
    workspace: Workspace
    min_clearance_m: float
    collision_max_step_rad: float
    max_hand_distance_m: float

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
            raise _err(source, key, "missing table")
        return {}
    if not isinstance(value, dict):
        raise _err(source, key, "must be a table")
    return value


def _get(
    table: dict, key: str, source: Path, prefix: str, kind: type | tuple, default: object = ...
) -> object:
    if key not in table:
        if default is ...:
            raise _err(source, f"{prefix}.{key}", "missing")
        return default
    value = table[key]
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not isinstance(value, kind) or isinstance(value, bool) and kind is not bool:
        raise _err(source, f"{prefix}.{key}", f"must be of type {getattr(kind, '__name__', kind)}")
    return value


def _positive_vector(value: object, n: int, source: Path, name: str, allow_zero: bool = False) -> np.ndarray:
    if isinstance(value, int | float) and not isinstance(value, bool):
        value = [value] * n
    if not isinstance(value, list) or len(value) != n:
        raise _err(source, name, f"must be a number or a list of {n} numbers")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise _err(source, name, "must contain numbers only") from exc
    if not np.all(np.isfinite(arr)):
        raise _err(source, name, f"must be finite, got {arr.tolist()}")
    bad = arr < 0 if allow_zero else arr <= 0
    if np.any(bad):
        which = "negative" if allow_zero else "zero or negative"
        raise _err(source, name, f"{which} value {arr[bad][0]} (values: {arr.tolist()})")
    return arr


def _vector3(value: object, source: Path, name: str) -> np.ndarray:
    if not isinstance(value, list) or len(value) != 3:
        raise _err(source, name, "must be a list of 3 numbers")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise _err(source, name, "must contain numbers only") from exc
    if not np.all(np.isfinite(arr)):
        raise _err(source, name, f"must be finite, got {arr.tolist()}")
    return arr


def load_robot_settings(path_or_name: str | Path) -> RobotSettings:
    """Read and validate a robot settings file (file-level checks; model checks are in :func:`load_robot`).

    Args:
        path_or_name: Path of a ``.toml`` settings file, or the name of one in ``robots/``.

    Raises:
        RobotError: unreadable file, missing or malformed field, infeasible limits; the message
            names the file, the field and the problem.
    """
    path = resolve_settings_path(path_or_name)
    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise _err(path, None, f"not valid TOML: {exc}") from exc
    version = doc.get("schema_version", _SCHEMA_VERSION)
    if version != _SCHEMA_VERSION:
        raise _err(
            path, "schema_version", f"unsupported version {version} (this code reads {_SCHEMA_VERSION})"
        )
    name = _get(doc, "name", path, "", str, path.stem)

    desc = _table(doc, "description", path)
    package = _get(desc, "package", path, "description", str, "")
    base = find_robot_data_dir(package) if package else path.parent
    urdf_rel = _get(desc, "urdf", path, "description", str)
    if Path(urdf_rel).is_absolute():
        raise _err(path, "description.urdf", "must be a relative path (no absolute paths in settings)")
    urdf_path = (base / urdf_rel).resolve()
    if not urdf_path.is_file():
        raise _err(path, "description.urdf", f"file not found: {urdf_path}")
    srdf_rel = _get(desc, "srdf", path, "description", str, "")
    srdf_path = None
    if srdf_rel:
        if Path(srdf_rel).is_absolute():
            raise _err(path, "description.srdf", "must be a relative path (no absolute paths in settings)")
        srdf_path = (base / srdf_rel).resolve()
        if not srdf_path.is_file():
            raise _err(path, "description.srdf", f"file not found: {srdf_path}")

    arm = _table(doc, "arm", path)
    joints = _get(arm, "joints", path, "arm", list)
    if not joints or not all(isinstance(j, str) and j for j in joints):
        raise _err(path, "arm.joints", "must be a non-empty list of joint names")
    if len(set(joints)) != len(joints):
        raise _err(path, "arm.joints", f"joint listed twice in {joints}")
    n = len(joints)
    recorded = _get(arm, "recorded_names", path, "arm", dict, {j: j for j in joints})
    for rec, mod in recorded.items():
        if not isinstance(mod, str) or mod not in joints:
            raise _err(path, f"arm.recorded_names.{rec}", f"maps to '{mod}', which is not one of arm.joints")
    missing = [j for j in joints if j not in recorded.values()]
    if missing:
        raise _err(path, "arm.recorded_names", f"no recorded name maps to {missing}")

    ee = _table(doc, "end_effector", path)
    parent_frame = _get(ee, "parent_frame", path, "end_effector", str)
    ee_frame = _get(ee, "frame", path, "end_effector", str, EE_FRAME)

    calib = _table(doc, "calibration", path, required=False)
    offset = _vector3(calib.get("tool_offset_m", [0.0, 0.0, 0.0]), path, "calibration.tool_offset_m")
    mount = _vector3(calib.get("mount_offset_m", [0.0, 0.0, 0.0]), path, "calibration.mount_offset_m")
    calib_info = {k: v for k, v in calib.items() if k not in ("tool_offset_m", "mount_offset_m")}

    limits = _table(doc, "limits", path)
    margin = _positive_vector(
        limits.get("position_margin_rad", 0.0), n, path, "limits.position_margin_rad", allow_zero=True
    )
    vel = None
    if "velocity_rad_s" in limits:
        vel = _positive_vector(limits["velocity_rad_s"], n, path, "limits.velocity_rad_s")
    if "acceleration_rad_s2" not in limits:
        raise _err(path, "limits.acceleration_rad_s2", "missing (the URDF has no acceleration limits)")
    acc = _positive_vector(limits["acceleration_rad_s2"], n, path, "limits.acceleration_rad_s2")
    if "jerk_rad_s3" not in limits:
        raise _err(path, "limits.jerk_rad_s3", "missing (the URDF has no jerk limits)")
    jerk = _positive_vector(limits["jerk_rad_s3"], n, path, "limits.jerk_rad_s3")

    fixed_raw = _table(doc, "fixed_joints", path, required=False)
    fixed: dict[str, float] = {}
    for k, v in fixed_raw.items():
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise _err(path, f"fixed_joints.{k}", f"must be a finite number, got {v!r}")
        if k in joints:
            raise _err(path, f"fixed_joints.{k}", "is an arm joint; only non-arm joints can be fixed")
        fixed[k] = float(v)

    ws = _table(doc, "workspace", path)
    shape = _get(ws, "shape", path, "workspace", str, "box")
    if shape == "box":
        lo = _vector3(ws.get("min_m"), path, "workspace.min_m")
        hi = _vector3(ws.get("max_m"), path, "workspace.max_m")
        if np.any(lo >= hi):
            raise _err(path, "workspace", f"min_m {lo.tolist()} must be below max_m {hi.tolist()}")
        workspace = Workspace("box", min_m=lo, max_m=hi)
    elif shape == "sphere":
        c = _vector3(ws.get("center_m"), path, "workspace.center_m")
        r = _get(ws, "radius_m", path, "workspace", float)
        if not (math.isfinite(r) and r > 0):
            raise _err(path, "workspace.radius_m", f"must be positive and finite, got {r}")
        workspace = Workspace("sphere", center_m=c, radius_m=float(r))
    else:
        raise _err(path, "workspace.shape", f"must be 'box' or 'sphere', got '{shape}'")

    checks = _table(doc, "checks", path, required=False)
    clearance = _get(checks, "min_clearance_m", path, "checks", float, 0.0)
    step = _get(checks, "collision_max_step_rad", path, "checks", float, 0.05)
    hand = _get(checks, "max_hand_distance_m", path, "checks", float, 0.25)
    for key, value, lo_ok in (
        ("min_clearance_m", clearance, True),
        ("collision_max_step_rad", step, False),
        ("max_hand_distance_m", hand, False),
    ):
        if not math.isfinite(value) or value < 0 or (value == 0 and not lo_ok):
            raise _err(path, f"checks.{key}", f"must be {'>= 0' if lo_ok else '> 0'} and finite, got {value}")

    share = find_robot_data_dir(package) if package else path.parent
    return RobotSettings(
        name=name,
        path=path,
        urdf_path=urdf_path,
        srdf_path=srdf_path,
        package_dirs=(str(share),),
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
        fixed_joints=fixed,
        workspace=workspace,
        min_clearance_m=float(clearance),
        collision_max_step_rad=float(step),
        max_hand_distance_m=float(hand),
    )


@dataclass
class Robot:
    """A loaded robot: Pinocchio kinematic + collision models and the arm's indices and limits.

    The ``data``/``collision_data`` work buffers are shared by every user of the cached robot (not
    thread-safe: use one robot per thread, e.g. via ``load_robot(..., cache=False)``).

    Attributes:
        settings: The validated settings.
        model: Kinematic model (with the added end-effector frame).
        data: Its work data.
        collision_model: Collision geometries with the SRDF-disabled pairs removed (``None`` only
            for the kinematics-only robots used internally by the calibration).
        collision_data: Its work data (only pairs whose distance the arm can change are active).
        arm_joint_ids: Model joint ids of the arm joints (n_joints,).
        arm_q_index: Indices of the arm joints in the model configuration vector (n_joints,).
        arm_v_index: Indices of the arm joints in the model velocity vector (n_joints,).
        ee_frame_id: Id of the end-effector frame (parent frame * tool offset).
        ee_parent_frame_id: Id of the parent frame (e.g. ``left_gripper``).
        q_neutral: Full configuration (nq,) with non-arm joints at their fixed values, arm at 0 clipped.
        lower_rad: Arm position lower limits (n_joints,) from the URDF in [rad].
        upper_rad: Arm position upper limits (n_joints,) in [rad].
        velocity_rad_s: Arm velocity limits (n_joints,) in [rad/s] (URDF or settings override).
        n_pairs_total: Collision pairs before removing the SRDF's disabled pairs.
        n_pairs_srdf_removed: Pairs the SRDF disabled.
        active_pair_ids: Indices (into ``collision_model.collisionPairs``) of pairs whose distance
            can change when the arm moves.
        static_min_distance_m: Smallest distance among the other (static) pairs at ``q_neutral``.
    """

    settings: RobotSettings
    model: pin.Model
    data: pin.Data
    collision_model: pin.GeometryModel | None
    collision_data: pin.GeometryData | None
    arm_joint_ids: np.ndarray
    arm_q_index: np.ndarray
    arm_v_index: np.ndarray
    ee_frame_id: int
    ee_parent_frame_id: int
    q_neutral: np.ndarray
    lower_rad: np.ndarray
    upper_rad: np.ndarray
    velocity_rad_s: np.ndarray
    n_pairs_total: int = 0
    n_pairs_srdf_removed: int = 0
    active_pair_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    static_min_distance_m: float = math.inf

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Arm joint names in kinematic order."""
        return self.settings.arm_joints

    @property
    def n_joints(self) -> int:
        """Number of arm joints."""
        return len(self.settings.arm_joints)

    def full_configuration(self, q_arm: np.ndarray) -> np.ndarray:
        """Full model configuration(s) (..., nq) from arm joint angles (..., n_joints) in [rad]."""
        q_arm = np.asarray(q_arm, dtype=float)
        if q_arm.shape[-1] != self.n_joints:
            raise ValueError(f"expected {self.n_joints} arm joints in the last axis, got shape {q_arm.shape}")
        q = np.broadcast_to(self.q_neutral, q_arm.shape[:-1] + (self.model.nq,)).copy()
        q[..., self.arm_q_index] = q_arm
        return q

    def pair_names(self, pair_id: int) -> tuple[str, str]:
        """Geometry names of collision pair ``pair_id``."""
        cp = self.collision_model.collisionPairs[int(pair_id)]
        g = self.collision_model.geometryObjects
        return g[cp.first].name, g[cp.second].name

    def pair_links(self, pair_id: int) -> tuple[str, str]:
        """Link (parent frame) names of collision pair ``pair_id``."""
        cp = self.collision_model.collisionPairs[int(pair_id)]
        g = self.collision_model.geometryObjects
        return (
            self.model.frames[g[cp.first].parentFrame].name,
            self.model.frames[g[cp.second].parentFrame].name,
        )


_ROBOT_CACHE: dict[tuple, Robot] = {}
"""Loaded robots keyed by (resolved settings path, mtime_ns, size); see :func:`load_robot`."""


def clear_robot_cache() -> None:
    """Forget every cached robot (the next :func:`load_robot` rebuilds the models)."""
    _ROBOT_CACHE.clear()


def load_robot(settings: RobotSettings | str | Path, *, cache: bool = True) -> Robot:
    """Load the kinematic and collision models described by ``settings`` (cached, no visual meshes).

    Args:
        settings: Validated settings, or a settings path / robot name (read with
            :func:`load_robot_settings`).
        cache: Reuse (and store) the robot loaded from the same settings file.

    Raises:
        RobotError: unknown joint or frame names, non-revolute or out-of-order arm joints, invalid
            URDF limits, fixed joint values outside their limits, a held configuration in collision.
    """
    key = None
    if cache:
        path = settings.path if isinstance(settings, RobotSettings) else resolve_settings_path(settings)
        st = path.stat()
        key = (str(path), st.st_mtime_ns, st.st_size)
        robot = _ROBOT_CACHE.get(key)
        if robot is not None:
            return robot
    if not isinstance(settings, RobotSettings):
        settings = load_robot_settings(settings)
    robot = _build_robot(settings)
    if key is not None:
        for k in [k for k in _ROBOT_CACHE if k[0] == key[0]]:
            del _ROBOT_CACHE[k]
        _ROBOT_CACHE[key] = robot
    return robot


def _build_robot(s: RobotSettings, collision: bool = True) -> Robot:
    src = s.path
    try:
        model = pin.buildModelFromUrdf(str(s.urdf_path))
    except (RuntimeError, ValueError) as exc:
        raise _err(src, "description.urdf", f"cannot be parsed: {exc}") from exc

    joint_ids = []
    for name in s.arm_joints:
        if not model.existJointName(name):
            raise _err(
                src, "arm.joints", f"unknown joint '{name}' (not a movable joint of {s.urdf_path.name})"
            )
        jid = model.getJointId(name)
        if model.joints[jid].nq != 1 or model.joints[jid].nv != 1:
            raise _err(src, "arm.joints", f"joint '{name}' is not a 1-dof joint")
        joint_ids.append(jid)
    for a, b, ja, jb in zip(s.arm_joints[:-1], s.arm_joints[1:], joint_ids[:-1], joint_ids[1:], strict=True):
        if jb not in model.subtrees[ja]:
            raise _err(src, "arm.joints", f"not in kinematic order: '{b}' does not follow '{a}'")
    joint_ids = np.asarray(joint_ids, dtype=int)
    q_idx = np.array([model.joints[int(j)].idx_q for j in joint_ids], dtype=int)
    v_idx = np.array([model.joints[int(j)].idx_v for j in joint_ids], dtype=int)

    lower = np.asarray(model.lowerPositionLimit, dtype=float)[q_idx]
    upper = np.asarray(model.upperPositionLimit, dtype=float)[q_idx]
    urdf_vel = np.asarray(model.velocityLimit, dtype=float)[v_idx]
    for i, name in enumerate(s.arm_joints):
        lo, hi, v = lower[i], upper[i], urdf_vel[i]
        if not (np.isfinite(lo) and np.isfinite(hi)) or lo >= hi:
            raise _err(s.urdf_path, f"joint {name} limit", f"invalid position limits [{lo}, {hi}]")
        if s.velocity_override_rad_s is None and not (np.isfinite(v) and 0 < v < 1e3):
            raise _err(
                s.urdf_path,
                f"joint {name} limit velocity",
                f"invalid velocity limit {v} (not finite and positive, or a placeholder); "
                f"set limits.velocity_rad_s in {src.name}",
            )
        if 2 * s.position_margin_rad[i] >= hi - lo:
            raise _err(
                src,
                "limits.position_margin_rad",
                f"margin {s.position_margin_rad[i]} leaves no range for {name}",
            )
    vel = urdf_vel if s.velocity_override_rad_s is None else s.velocity_override_rad_s

    q0 = pin.neutral(model)
    q0 = np.clip(q0, model.lowerPositionLimit, model.upperPositionLimit)
    q0[q_idx] = np.clip(0.0, lower + s.position_margin_rad, upper - s.position_margin_rad)
    for name, value in s.fixed_joints.items():
        if not model.existJointName(name):
            raise _err(src, f"fixed_joints.{name}", "unknown joint (not a movable joint of the model)")
        j = model.joints[model.getJointId(name)]
        if j.nq != 1:
            raise _err(src, f"fixed_joints.{name}", "only 1-dof joints can be fixed by value")
        lo, hi = model.lowerPositionLimit[j.idx_q], model.upperPositionLimit[j.idx_q]
        if not lo <= value <= hi:
            raise _err(src, f"fixed_joints.{name}", f"value {value} outside the joint's limits [{lo}, {hi}]")
        q0[j.idx_q] = value

    if not model.existFrame(s.ee_parent_frame):
        raise _err(src, "end_effector.parent_frame", f"unknown frame '{s.ee_parent_frame}'")
    parent_id = model.getFrameId(s.ee_parent_frame)
    if model.existFrame(s.ee_frame):
        raise _err(src, "end_effector.frame", f"frame '{s.ee_frame}' already exists in the model")
    parent = model.frames[parent_id]
    if parent.parentJoint not in model.subtrees[int(joint_ids[-1])]:
        raise _err(src, "end_effector.parent_frame", f"frame '{s.ee_parent_frame}' is not moved by the arm")
    offset = pin.SE3(np.eye(3), s.tool_offset_m)
    ee_id = model.addFrame(
        pin.Frame(
            s.ee_frame, parent.parentJoint, parent_id, parent.placement * offset, pin.FrameType.OP_FRAME
        )
    )
    root = int(joint_ids[0])
    model.jointPlacements[root] = pin.SE3(np.eye(3), s.mount_offset_m) * model.jointPlacements[root]
    data = model.createData()
    kinematic = dict(
        settings=s,
        model=model,
        data=data,
        arm_joint_ids=joint_ids,
        arm_q_index=q_idx,
        arm_v_index=v_idx,
        ee_frame_id=int(ee_id),
        ee_parent_frame_id=int(parent_id),
        q_neutral=q0,
        lower_rad=lower,
        upper_rad=upper,
        velocity_rad_s=np.asarray(vel, dtype=float),
    )
    if not collision:
        return Robot(collision_model=None, collision_data=None, **kinematic)

    try:
        cmodel = pin.buildGeomFromUrdf(
            model, str(s.urdf_path), pin.COLLISION, package_dirs=list(s.package_dirs)
        )
    except (RuntimeError, ValueError) as exc:
        raise _err(src, "description.urdf", f"collision geometry cannot be loaded: {exc}") from exc
    cmodel.addAllCollisionPairs()
    n_total = len(cmodel.collisionPairs)
    if s.srdf_path is not None:
        try:
            pin.removeCollisionPairs(model, cmodel, str(s.srdf_path))
        except (RuntimeError, ValueError) as exc:
            raise _err(src, "description.srdf", f"cannot be applied: {exc}") from exc
    n_removed = n_total - len(cmodel.collisionPairs)
    cdata = pin.GeometryData(cmodel)

    # A pair's distance can change only if an arm joint lies between its two geometries: each
    # geometry gets the number of arm joints among its parent joint's ancestors ("segment"), and
    # pairs on the same segment (e.g. gripper fingers vs hand, torso vs other arm) are static.
    segment = np.zeros(model.njoints, dtype=int)
    for jid in joint_ids:
        segment[list(model.subtrees[int(jid)])] += 1
    geom_segment = np.array([segment[g.parentJoint] for g in cmodel.geometryObjects], dtype=int)
    active, static = [], []
    for k, cp in enumerate(cmodel.collisionPairs):
        (active if geom_segment[cp.first] != geom_segment[cp.second] else static).append(k)
    robot = Robot(
        collision_model=cmodel,
        collision_data=cdata,
        **kinematic,
        n_pairs_total=n_total,
        n_pairs_srdf_removed=n_removed,
        active_pair_ids=np.asarray(active, dtype=int),
    )
    # Static pairs (neither geometry moves with the arm) are checked once, here.
    if static:
        pin.updateGeometryPlacements(model, data, cmodel, cdata, q0)
        dists = [(pin.computeDistance(cmodel, cdata, k).min_distance, k) for k in static]
        dmin, kmin = min(dists)
        robot.static_min_distance_m = float(dmin)
        if dmin <= s.min_clearance_m:
            a, b = robot.pair_names(kmin)
            raise _err(
                src, "fixed_joints", f"held configuration is in self-collision: {a} - {b} ({dmin:.4f} m)"
            )
    for k in static:
        cdata.deactivateCollisionPair(k)
    return robot


def load_visual_model(robot: Robot) -> pin.GeometryModel:
    """Visual geometry (meshes) of ``robot``, for previews only (slow: ~2 s; never used by the checks)."""
    s = robot.settings
    try:
        return pin.buildGeomFromUrdf(
            robot.model, str(s.urdf_path), pin.VISUAL, package_dirs=list(s.package_dirs)
        )
    except (RuntimeError, ValueError) as exc:
        raise _err(s.path, "description.urdf", f"visual geometry cannot be loaded: {exc}") from exc


def map_recorded_joints(settings: RobotSettings, names: list[str] | tuple[str, ...]) -> np.ndarray:
    """Column index, in a recording with joint ``names``, of each arm joint (in kinematic order).

    Raises:
        RobotError: an arm joint has no recorded column.
    """
    index = {settings.recorded_names.get(n): i for i, n in enumerate(names) if n in settings.recorded_names}
    missing = [j for j in settings.arm_joints if j not in index]
    if missing:
        raise RobotError(f"{settings.path}: recorded joints {list(names)} lack arm joints {missing}")
    return np.array([index[j] for j in settings.arm_joints], dtype=int)
