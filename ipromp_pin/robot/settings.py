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
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..exceptions import RobotError
from ..fields import Range, Table, field_errors
from ..inputs import MAX_DOCUMENT_BYTES, check_regular, load_toml
from ..shipped import ROBOTS_DIR
from .human_settings import HUMAN_KEYS, ISO15066_KEYS, HumanSettings, read_human_settings
from .ranges import PLAUSIBLE_RANGES

__all__ = [
    "EE_FRAME",
    "PLAUSIBLE_RANGES",
    "TABLES",
    "DemoLimitRecipe",
    "Placement",
    "ROBOTS_DIR",
    "RobotSettings",
    "Tool",
    "Workspace",
    "find_robot_data_dir",
    "load_robot_settings",
    "resolve_settings_path",
    "settings_error",
]

EE_FRAME = "ee"
"""Default name of the end-effector frame added to the model (parent frame * tool offset)."""

_SCHEMA_VERSION = 1

TABLES: dict[str, tuple[str, ...] | None] = {
    "schema_version": None,
    "name": None,
    "description": ("package", "urdf", "srdf"),
    "arm": ("joints", "recorded_names"),
    "end_effector": ("parent_frame", "frame", "rpy_deg"),
    "tool": ("name", "length_m", "radius_m", "mass_kg", "source"),
    "calibration": (
        "fit",
        "tool_offset_m",
        "mount_offset_m",
        "calibrated_by",
        "calibrated_on",
        "residual_median_mm_before",
        "residual_median_mm_after",
    ),
    "limits": (
        "position_margin_rad",
        "velocity_rad_s",
        "acceleration_rad_s2",
        "jerk_rad_s3",
        "effort_margin",
        "demonstrated",
    ),
    "fixed_joints": None,
    "placement": ("source", "xyz_m", "rpy_deg"),
    "workspace": ("shape", "min_m", "max_m", "center_m", "radius_m"),
    "checks": ("min_clearance_m", "collision_max_step_rad", "disabled_pairs"),
    "springs": None,
    "human": HUMAN_KEYS,
    "iso15066": ISO15066_KEYS,
}
"""The top-level keys of a settings file and the keys of each table (None: a value, or a table whose
keys are names checked elsewhere: joints, recorded names). Anything else is refused, naming the
known key it resembles."""


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
class Placement:
    """Where an arm stands in the scene of another robot's recordings (``[placement]``): its base
    pose in the base frame of the ``source`` robot, whose recorded demonstrations (and the models
    trained on them) it executes through the gripper (:mod:`ipromp_pin.robot.arm_transfer`).

    The arm's model is built already placed: its world frame is the source robot's base frame, so
    the workspace, the assumed human and every check's positions are in that frame.

    Attributes:
        source: Settings name (or path) of the robot whose base frame this is, e.g. ``"baxter_left"``.
        xyz_m: (3,) base position in [m].
        rpy_deg: (3,) base orientation, roll, pitch, yaw in [deg] (rotation ``Rz(yaw) Ry(pitch) Rx(roll)``).
    """

    source: str
    xyz_m: np.ndarray
    rpy_deg: np.ndarray


@dataclass(frozen=True)
class Tool:
    """A gripper mounted on the arm's flange that its URDF does not describe (``[tool]``): a solid
    cylinder along the ``ee`` frame's z axis from the end-effector parent frame (turned and offset as
    ``[end_effector]`` and ``[calibration]`` say) to the tool centre point, which becomes the ``ee``
    frame. Its volume joins the collision geometry (self-collision, the human checks) and its mass
    the last link's inertia (the joint torques); the preview draws it.

    Attributes:
        name: What it is, e.g. ``"Robotiq 2F-85"``.
        length_m: Flange to tool centre point along z [m].
        radius_m: Radius [m] of the cylinder that holds the gripper with its fingers open.
        mass_kg: Mass [kg], spread evenly over the cylinder.
        source: Where the numbers come from.
    """

    name: str
    length_m: float
    radius_m: float
    mass_kg: float
    source: str

    def to_dict(self) -> dict:
        """JSON-serialisable form (the reports' ``tool``)."""
        return asdict(self)


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
        ee_frame: Name of the added end-effector frame (parent frame * offset, turned by ``ee_rpy_deg``).
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
        effort_margin: Fraction of the URDF's effort limits kept free by the joint-torque check, in
            [0, 0.5] (``[limits] effort_margin``; default 0.1: torques up to 90 % of the limits).
        spring_torque_nm: Arm joint name -> ``(c0, c1)``: a spring (Baxter's shoulder counterbalance)
            adds ``c0 + c1 * q`` [N m] (``q`` in [rad]) to that joint, so the motor delivers the rest
            (``[springs]``; default none).
        human: The ``[human]`` / ``[iso15066]`` tables (:mod:`.human_settings`).
        placement: The arm's base pose in another robot's scene (``[placement]``), None: the arm is
            the robot of its recordings (its base frame is the scene's).
        ee_rpy_deg: (3,) orientation of the end-effector frame in the parent frame's axes, roll, pitch,
            yaw in [deg] (``Rz Ry Rx``; ``[end_effector] rpy_deg``, default none): a gripper whose URDF
            frame does not point z out of the gripper gets one that does.
        disabled_pairs: Link pairs whose collisions are not checked, besides the SRDF's disabled
            pairs (``[checks] disabled_pairs``; for a description whose SRDF disables none).
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
    effort_margin: float = 0.1
    spring_torque_nm: dict[str, tuple[float, float]] = field(default_factory=dict)
    human: HumanSettings = field(default_factory=HumanSettings)
    placement: Placement | None = None
    ee_rpy_deg: np.ndarray = field(default_factory=lambda: np.zeros(3))
    disabled_pairs: tuple[tuple[str, str], ...] = ()
    tool: Tool | None = None

    @property
    def n_joints(self) -> int:
        """Number of arm joints."""
        return len(self.arm_joints)

    @property
    def ee_turn(self) -> np.ndarray:
        """The ``ee`` frame's rotation (3, 3) in the end-effector parent frame (``[end_effector]
        rpy_deg``: roll, pitch, yaw about the fixed x, y, z axes)."""
        return Rotation.from_euler("xyz", np.radians(self.ee_rpy_deg)).as_matrix()

    def point_on_ee_axis_m(self, along_m: float) -> np.ndarray:
        """The point (3,) [m], in the end-effector parent frame's axes, ``along_m`` [m] along the
        ``ee`` frame's z axis from its mount (the tool offset)."""
        return np.asarray(self.tool_offset_m, dtype=float) + self.ee_turn @ np.array([0.0, 0.0, along_m])

    @property
    def gripper_point_m(self) -> np.ndarray:
        """Where the gripper holds an object (3,) [m] in the end-effector parent frame's axes: the
        tool offset, plus the tool's length along the turned z axis when a ``[tool]`` is mounted."""
        return self.point_on_ee_axis_m(0.0 if self.tool is None else self.tool.length_m)

    @property
    def tool_record(self) -> dict | None:
        """The ``[tool]`` as the reports give it (:meth:`Tool.to_dict`; None: none)."""
        return None if self.tool is None else self.tool.to_dict()

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
    if p.exists():  # a folder, a FIFO, a device: refused by name, never read
        check_regular(
            p, "robot settings", lambda problem: settings_error(p, None, problem), MAX_DOCUMENT_BYTES
        )
    if p.suffix == "" and len(p.parts) == 1:
        candidate = ROBOTS_DIR / f"{p.name}.toml"
        if candidate.is_file():
            return candidate.resolve()
    known = ", ".join(sorted(f.stem for f in ROBOTS_DIR.glob("*.toml"))) if ROBOTS_DIR.is_dir() else ""
    raise RobotError(f"{path_or_name}: robot settings file not found (known robots: {known or 'none'})")


def _range(name: str) -> Range:
    return PLAUSIBLE_RANGES[name]


def _positive_vector(
    table: Table, key: str, n: int, default: object = ..., allow_zero: bool = False
) -> np.ndarray:
    """``table[key]``: a number or ``n`` numbers (n,), positive (``allow_zero``: >= 0), in their range."""
    if key not in table:
        if default is ...:
            raise table.error(key, "missing")
        return np.full(n, float(default))  # type: ignore[arg-type]
    arr = table.vector(key, n, scalar=True)
    bad = arr < 0 if allow_zero else arr <= 0
    if np.any(bad):
        which = "negative" if allow_zero else "zero or negative"
        raise table.error(key, f"{which} value {arr[bad][0]} (values: {arr.tolist()})")
    _range(table.field(key)).check(arr, table.field(key), table.error_fn)
    return arr


def _demo_limit_recipe(limits: Table) -> DemoLimitRecipe:
    """The optional ``[limits.demonstrated]`` table (percentile in (0, 100], window_s in (0, 5] s)."""
    table = limits.table("demonstrated", ("percentile", "window_s"))
    d = DemoLimitRecipe()
    pct = table.number("percentile", _range("limits.demonstrated.percentile"), d.percentile)
    win = table.number("window_s", _range("limits.demonstrated.window_s"), d.window_s)
    return DemoLimitRecipe(pct, win)


def _read_document(path: Path) -> Table:
    """The parsed TOML document of ``path``, its top-level keys known and ``schema_version`` checked."""
    try:
        doc = load_toml(path, "robot settings", lambda problem: settings_error(path, None, problem))
    except OSError as exc:
        raise settings_error(path, None, f"cannot read: {exc.strerror or exc}") from None
    table = Table(doc, "", field_errors(RobotError, path), TABLES, what="key or table")
    version = doc.get("schema_version", _SCHEMA_VERSION)
    if not isinstance(version, int) or isinstance(version, bool):
        raise settings_error(
            path,
            "schema_version",
            f"must be the integer {_SCHEMA_VERSION}, got {version!r} ({type(version).__name__})",
        )
    if version != _SCHEMA_VERSION:
        raise settings_error(
            path, "schema_version", f"unsupported version {version} (this code reads {_SCHEMA_VERSION})"
        )
    return table


RETIRED_KEYS = {
    "checks.max_hand_distance_m": "is no longer read: the gripper-hand distance at the hand-over "
    "needs the hand's future position, so it is a score against a recording (report.json "
    "scores.hand_distance_m), not a check; remove the key",
}
"""Keys that earlier versions read, each refused with what became of it."""


def _sub(doc: Table, key: str, required: bool = True) -> Table:
    """Table ``key`` of the document with its known keys (:data:`TABLES`); a retired key is refused
    with what became of it (:data:`RETIRED_KEYS`)."""
    raw = doc.data.get(key)
    for name in raw if isinstance(raw, dict) else ():
        problem = RETIRED_KEYS.get(f"{key}.{name}")
        if problem is not None:
            raise doc.error(f"{key}.{name}", problem)
    return doc.table(key, TABLES[key], required=required)


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


def _arm_joints(arm: Table) -> tuple[list[str], dict[str, str]]:
    """The ``[arm]`` table: joint names in kinematic order and the recorded -> model name mapping."""
    joints = arm.raw("joints")
    if not isinstance(joints, list) or not joints or not all(isinstance(j, str) and j for j in joints):
        raise arm.error("joints", "must be a non-empty list of joint names")
    if len(set(joints)) != len(joints):
        raise arm.error("joints", f"joint listed twice in {joints}")
    recorded = arm.table("recorded_names").data if "recorded_names" in arm else {j: j for j in joints}
    for rec, mod in recorded.items():
        if not isinstance(mod, str) or mod not in joints:
            raise arm.error(f"recorded_names.{rec}", f"maps to '{mod}', which is not one of arm.joints")
    missing = [j for j in joints if j not in recorded.values()]
    if missing:
        raise arm.error("recorded_names", f"no recorded name maps to {missing}")
    return joints, recorded


def _calibration(calib: Table) -> tuple[np.ndarray, np.ndarray, dict]:
    """The optional ``[calibration]`` table: tool offset (3,) and mount offset (3,) in [m], provenance."""
    offsets = [
        calib.vector(key, 3, _range(calib.field(key)), [0.0, 0.0, 0.0])
        for key in ("tool_offset_m", "mount_offset_m")
    ]
    calib_info = {k: v for k, v in calib.data.items() if k not in ("tool_offset_m", "mount_offset_m")}
    return offsets[0], offsets[1], calib_info


def _joint_limits(limits: Table, n: int) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, np.ndarray]:
    """The ``[limits]`` vectors (n,): position margin [rad], velocity override [rad/s] or ``None``,
    acceleration [rad/s^2] and jerk [rad/s^3]."""
    margin = _positive_vector(limits, "position_margin_rad", n, 0.0, allow_zero=True)
    vel = _positive_vector(limits, "velocity_rad_s", n) if "velocity_rad_s" in limits else None
    if "acceleration_rad_s2" not in limits:
        raise limits.error("acceleration_rad_s2", "missing (the URDF has no acceleration limits)")
    acc = _positive_vector(limits, "acceleration_rad_s2", n)
    if "jerk_rad_s3" not in limits:
        raise limits.error("jerk_rad_s3", "missing (the URDF has no jerk limits)")
    jerk = _positive_vector(limits, "jerk_rad_s3", n)
    return margin, vel, acc, jerk


def _springs(table: Table, joints: list[str]) -> dict[str, tuple[float, float]]:
    """The optional ``[springs]`` table: arm joint -> [c0 N m, c1 N m/rad] within their range."""
    out: dict[str, tuple[float, float]] = {}
    for name in table.keys():
        if name not in joints:
            raise table.error(name, f"not an arm joint ({', '.join(joints)})")
        c = table.vector(name, 2, _range("springs.<joint>"))
        out[name] = (float(c[0]), float(c[1]))
    return out


def _fixed_joints(table: Table, joints: list[str]) -> dict[str, float]:
    """The optional ``[fixed_joints]`` table: non-arm joint name -> held value in [rad] or [m]."""
    fixed: dict[str, float] = {}
    for k in table.keys():
        if k in joints:
            raise table.error(k, "is an arm joint; only non-arm joints can be fixed")
        fixed[k] = table.number(k, _range("fixed_joints.<joint>"))
    return fixed


def _workspace(ws: Table) -> Workspace:
    """The ``[workspace]`` table: a box (``min_m``, ``max_m``) or a sphere (``center_m``, ``radius_m``)."""
    shape = ws.text("shape", "box", ("box", "sphere"))
    keys = ("shape", "min_m", "max_m") if shape == "box" else ("shape", "center_m", "radius_m")
    Table(ws.data, ws.prefix, ws.error_fn, keys)  # a sphere's keys in a box are typos, and vice versa
    if shape == "box":
        lo, hi = (ws.vector(k, 3, _range(ws.field(k))) for k in ("min_m", "max_m"))
        if np.any(lo >= hi):
            raise ws.error(None, f"min_m {lo.tolist()} must be below max_m {hi.tolist()}")
        return Workspace("box", min_m=lo, max_m=hi)
    centre = ws.vector("center_m", 3, _range("workspace.center_m"))
    return Workspace("sphere", center_m=centre, radius_m=ws.number("radius_m", _range("workspace.radius_m")))


def _placement(table: Table, path: Path) -> Placement | None:
    """The optional ``[placement]`` table: the source robot and the base pose in its base frame."""
    if not table.data:
        return None
    source = table.text("source")
    if not source or Path(source).stem == path.stem:
        raise table.error("source", f"must name another robot's settings, got '{source}'")
    xyz = table.vector("xyz_m", 3, _range("placement.xyz_m"))
    rpy = table.vector("rpy_deg", 3, _range("placement.rpy_deg"), [0.0, 0.0, 0.0])
    return Placement(source, xyz, rpy)


def _tool(table: Table) -> Tool | None:
    """The optional ``[tool]`` table: a gripper the URDF does not describe (every key required)."""
    if not table.data:
        return None
    numbers = (table.number(k, _range(f"tool.{k}")) for k in ("length_m", "radius_m", "mass_kg"))
    length, radius, mass = numbers
    name, source = table.text("name"), table.text("source")
    if not name or not source:
        raise table.error("name" if not name else "source", "must not be empty")
    return Tool(name, length, radius, mass, source)


def _check_thresholds(checks: Table) -> tuple[float, float]:
    """The optional ``[checks]`` table: min clearance [m], collision step [rad]."""
    defaults = {"min_clearance_m": 0.0, "collision_max_step_rad": 0.05}
    clearance, step = (checks.number(k, _range(checks.field(k)), d) for k, d in defaults.items())
    return clearance, step


def _disabled_pairs(checks: Table) -> tuple[tuple[str, str], ...]:
    """``[checks] disabled_pairs``: link pairs (two different link names each, no pair twice) whose
    collisions are not checked, besides the SRDF's (the links are checked against the model)."""
    raw = checks.raw("disabled_pairs", [])
    form = "must be a list of [link, link] pairs of two different link names"
    if not isinstance(raw, list):
        raise checks.error("disabled_pairs", form)
    pairs: list[tuple[str, str]] = []
    for item in raw:
        if not (isinstance(item, list) and len(item) == 2 and all(isinstance(n, str) and n for n in item)):
            raise checks.error("disabled_pairs", f"{form}, got {item!r}")
        if item[0] == item[1] or tuple(sorted(item)) in {tuple(sorted(p)) for p in pairs}:
            raise checks.error("disabled_pairs", f"{form}: {item!r} is a link with itself or listed twice")
        pairs.append((item[0], item[1]))
    return tuple(pairs)


def load_robot_settings(path_or_name: str | Path) -> RobotSettings:
    """Read and validate a robot settings file (file-level checks; model checks are in :func:`load_robot`).

    Args:
        path_or_name: Path of a ``.toml`` settings file, or the name of one in ``robots/``.

    Raises:
        RobotError: unreadable file, an unknown table or key (naming the known one it resembles), a
            missing or malformed field, a value outside its plausible range (naming the range and
            its source, :data:`PLAUSIBLE_RANGES`), infeasible limits; the message names the file, the
            field and the problem.
    """
    path = resolve_settings_path(path_or_name)
    doc = _read_document(path)
    name = doc.text("name", path.stem)

    desc = _sub(doc, "description")
    package = desc.text("package", "")
    base = find_robot_data_dir(package) if package else path.parent
    urdf_path = _description_file(desc.text("urdf"), "urdf", base, path)
    srdf_rel = desc.text("srdf", "")
    srdf_path = _description_file(srdf_rel, "srdf", base, path) if srdf_rel else None

    joints, recorded = _arm_joints(_sub(doc, "arm"))

    ee = _sub(doc, "end_effector")
    parent_frame = ee.text("parent_frame")
    ee_frame = ee.text("frame", EE_FRAME)
    ee_rpy = ee.vector("rpy_deg", 3, _range("end_effector.rpy_deg"), [0.0, 0.0, 0.0])

    offset, mount, calib_info = _calibration(_sub(doc, "calibration", required=False))

    limits = _sub(doc, "limits")
    margin, vel, acc, jerk = _joint_limits(limits, len(joints))
    checks = _sub(doc, "checks", required=False)
    clearance, step = _check_thresholds(checks)

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
        ee_rpy_deg=ee_rpy,
        disabled_pairs=_disabled_pairs(checks),
        tool_offset_m=offset,
        mount_offset_m=mount,
        calibration_info=calib_info,
        position_margin_rad=margin,
        velocity_override_rad_s=vel,
        acceleration_rad_s2=acc,
        jerk_rad_s3=jerk,
        demonstrated_limits=_demo_limit_recipe(limits),
        fixed_joints=_fixed_joints(_sub(doc, "fixed_joints", required=False), joints),
        workspace=_workspace(_sub(doc, "workspace")),
        min_clearance_m=clearance,
        collision_max_step_rad=step,
        effort_margin=limits.number("effort_margin", _range("limits.effort_margin"), 0.1),
        spring_torque_nm=_springs(_sub(doc, "springs", required=False), joints),
        human=read_human_settings(doc, path),
        placement=_placement(_sub(doc, "placement", required=False), path),
        tool=_tool(_sub(doc, "tool", required=False)),
    )
