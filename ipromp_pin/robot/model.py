"""The Pinocchio robot built from a settings file: kinematic + collision models, arm indices, limits.

:func:`build_robot` builds the kinematic model (~3 ms) and, unless asked not to, the collision
model (~50 ms) with the SRDF's disabled pairs removed, checking the settings against the model.
:func:`load_robot` builds a robot once per settings file and caches it in this module's
dictionary ``_ROBOT_CACHE`` (module-level state, keyed by the resolved settings path, the
file's modification time and size, so a re-calibrated file is reloaded, and a digest of the settings'
values, so a changed copy of a file's settings is its own robot; :func:`clear_robot_cache`
empties it; ``cache=False`` bypasses it). Visual meshes (~2 s) are never loaded by the checks;
previews call :func:`load_visual_model`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from xml.etree import ElementTree

import coal
import numpy as np
import pinocchio as pin

from ..exceptions import RobotError
from .settings import RobotSettings, load_robot_settings, settings_error


@dataclass
class Robot:
    """A loaded robot: Pinocchio kinematic + collision models and the arm's indices and limits.

    The ``data``/``collision_data`` work buffers are shared by every user of the cached robot (not
    thread-safe: use one robot per thread, e.g. via ``load_robot(..., cache=False)``).

    Attributes:
        settings: The validated settings.
        model: Kinematic model (with the added end-effector frame).
        data: Its work data.
        collision_model: Collision geometries with the SRDF-disabled pairs removed (``None`` for a
            kinematics-only robot, ``build_robot(settings, collision=False)``).
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
        n_pairs_srdf_removed: Pairs the SRDF (and ``[checks] disabled_pairs``) disabled.
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

    def __reduce__(self) -> tuple:
        """Pickled as its settings (Pinocchio's work data cannot be pickled): the receiving process
        (a Dask worker of ``evaluate --cluster``) rebuilds the models from the settings' files."""
        return (rebuilt_robot, (self.settings, self.collision_model is not None))

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Arm joint names in kinematic order."""
        return self.settings.arm_joints

    @property
    def n_joints(self) -> int:
        """Number of arm joints."""
        return len(self.settings.arm_joints)

    @property
    def base_frame(self) -> str:
        """Name of the model's root link (the base frame of poses and positions), e.g. ``base``."""
        return next(f.name for f in self.model.frames if f.type == pin.FrameType.BODY)

    def recorded_joint_limits(self) -> dict[str, tuple[float, float]]:
        """Recorded joint name (as the recordings name it) -> URDF (lower, upper) limits in [rad] of
        the arm's joints: what readers check recorded angles against."""
        inverse = {model: rec for rec, model in self.settings.recorded_names.items()}
        return {
            inverse[j]: (float(lo), float(hi))
            for j, lo, hi in zip(self.joint_names, self.lower_rad, self.upper_rad, strict=True)
        }

    def full_configuration(self, q_arm: np.ndarray) -> np.ndarray:
        """Full model configuration(s) (..., nq) from arm joint angles (..., n_joints) in [rad]."""
        q_arm = np.asarray(q_arm, dtype=float)
        if q_arm.shape[-1] != self.n_joints:
            raise ValueError(f"expected {self.n_joints} arm joints in the last axis, got shape {q_arm.shape}")
        q = np.broadcast_to(self.q_neutral, q_arm.shape[:-1] + (self.model.nq,)).copy()
        q[..., self.arm_q_index] = q_arm
        return q

    def collision(self) -> tuple[pin.GeometryModel, pin.GeometryData]:
        """The collision model and its data.

        Raises:
            RobotError: a kinematics-only robot (``build_robot(settings, collision=False)``).
        """
        if self.collision_model is None or self.collision_data is None:
            raise settings_error(self.settings.path, None, "robot built without its collision model")
        return self.collision_model, self.collision_data

    def pair_names(self, pair_id: int) -> tuple[str, str]:
        """Geometry names of collision pair ``pair_id``."""
        cmodel, _ = self.collision()
        cp = cmodel.collisionPairs[int(pair_id)]
        g = cmodel.geometryObjects
        return g[cp.first].name, g[cp.second].name

    def pair_links(self, pair_id: int) -> tuple[str, str]:
        """Link (parent frame) names of collision pair ``pair_id``."""
        cmodel, _ = self.collision()
        cp = cmodel.collisionPairs[int(pair_id)]
        g = cmodel.geometryObjects
        return (
            self.model.frames[g[cp.first].parentFrame].name,
            self.model.frames[g[cp.second].parentFrame].name,
        )


_ROBOT_CACHE: dict[tuple, Robot] = {}
"""Loaded robots keyed by (resolved settings path, mtime_ns, size, settings digest); see
:func:`load_robot`."""

ROBOT_CACHE_SIZE = 8
"""Most robots kept in the cache (the least recently used is dropped)."""


def settings_digest(settings: RobotSettings) -> str:
    """A SHA-1 hex digest of every value of ``settings`` (arrays at full precision), for the robot
    cache's key: equal settings give equal digests, a changed value another one."""

    def encode(value: object) -> object:
        if isinstance(value, np.ndarray):
            return [value.dtype.str, list(value.shape), value.ravel().tolist()]
        if isinstance(value, np.generic):
            return value.item()
        return repr(value)

    text = json.dumps(dataclasses.asdict(settings), sort_keys=True, default=encode)
    return hashlib.sha1(text.encode()).hexdigest()


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
    if not isinstance(settings, RobotSettings):
        settings = load_robot_settings(settings)
    key = None
    if cache:  # by the file and the settings' values (a changed copy of a file's settings is another robot)
        st = settings.path.stat()
        digest = settings_digest(settings)
        key = (str(settings.path), st.st_mtime_ns, st.st_size, digest)
        robot = _ROBOT_CACHE.pop(key, None)
        if robot is not None:
            _ROBOT_CACHE[key] = robot  # the most recently used last: the least recently used goes first
            return robot
    robot = build_robot(settings)
    if key is not None:
        stale = [k for k in _ROBOT_CACHE if k[0] == key[0] and k[1:3] != key[1:3]]
        for k in stale[:] + list(_ROBOT_CACHE)[: max(len(_ROBOT_CACHE) - ROBOT_CACHE_SIZE + 1, 0)]:
            _ROBOT_CACHE.pop(k, None)
        _ROBOT_CACHE[key] = robot
    return robot


def rebuilt_robot(settings: RobotSettings, collision: bool = True) -> Robot:
    """The robot of ``settings`` (with its collision model: :func:`load_robot`, cached), e.g. an
    unpickled :class:`Robot`."""
    return load_robot(settings) if collision else build_robot(settings, collision=False)


CONTINUOUS_RANGE_RAD = 2.0 * math.pi
"""A continuous URDF joint is modelled as a revolute joint within +-this [rad]: two full turns of
travel. Pinocchio models a continuous joint with two configuration values (cos, sin: nq = 2, nv =
1), which a joint-angle vector (one value per arm joint) cannot hold; a plan's motion between two
configurations never needs more than a turn, and +-2 pi is what the URDFs of the continuous arms
shipped here write in their (otherwise ignored) ``<limit>`` (Kinova's j2s6s200: joints 1, 4 and 6,
which turn endlessly on the hardware; kinova-ros ``kinova_description``)."""


def bounded_continuous_joints(urdf_text: str) -> str | None:
    """``urdf_text`` with every continuous joint made revolute within +-:data:`CONTINUOUS_RANGE_RAD`
    (its effort and velocity limits kept), or ``None`` when it has no continuous joint."""
    root = ElementTree.fromstring(urdf_text)
    continuous = [j for j in root.iter("joint") if j.get("type") == "continuous"]
    if not continuous:
        return None
    for joint in continuous:
        joint.set("type", "revolute")
        limit = joint.find("limit")
        if limit is None:
            limit = ElementTree.SubElement(joint, "limit")
        limit.set("lower", repr(-CONTINUOUS_RANGE_RAD))
        limit.set("upper", repr(CONTINUOUS_RANGE_RAD))
    return ElementTree.tostring(root, encoding="unicode")


def _parse_urdf(s: RobotSettings) -> pin.Model:
    """The kinematic model of the settings' URDF, continuous joints bounded
    (:func:`bounded_continuous_joints`: one configuration value per joint)."""
    try:
        bounded = bounded_continuous_joints(s.urdf_path.read_text(encoding="utf-8"))
        if bounded is None:
            return pin.buildModelFromUrdf(str(s.urdf_path))
        return pin.buildModelFromXML(bounded)
    except (RuntimeError, ValueError, ElementTree.ParseError, UnicodeDecodeError) as exc:
        raise settings_error(s.path, "description.urdf", f"cannot be parsed: {exc}") from exc


def _arm_indices(model: pin.Model, s: RobotSettings) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The arm's joint ids, configuration indices and velocity indices (n_joints,) each, checked to be
    1-dof joints of the model in kinematic order."""
    src = s.path
    ids = []
    for name in s.arm_joints:
        if not model.existJointName(name):
            raise settings_error(
                src, "arm.joints", f"unknown joint '{name}' (not a movable joint of {s.urdf_path.name})"
            )
        jid = model.getJointId(name)
        if model.joints[jid].nq != 1 or model.joints[jid].nv != 1:
            raise settings_error(src, "arm.joints", f"joint '{name}' is not a 1-dof joint")
        ids.append(jid)
    for a, b, ja, jb in zip(s.arm_joints[:-1], s.arm_joints[1:], ids[:-1], ids[1:], strict=True):
        if jb not in model.subtrees[ja]:
            raise settings_error(src, "arm.joints", f"not in kinematic order: '{b}' does not follow '{a}'")
    joint_ids = np.asarray(ids, dtype=int)
    q_idx = np.array([model.joints[int(j)].idx_q for j in joint_ids], dtype=int)
    v_idx = np.array([model.joints[int(j)].idx_v for j in joint_ids], dtype=int)
    return joint_ids, q_idx, v_idx


def _arm_limits(
    model: pin.Model, s: RobotSettings, q_idx: np.ndarray, v_idx: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The arm's URDF position limits (n_joints,) in [rad] and its velocity limits (n_joints,) in
    [rad/s] (the URDF's or the settings' override), checked against the settings' margins."""
    src = s.path
    lower = np.asarray(model.lowerPositionLimit, dtype=float)[q_idx]
    upper = np.asarray(model.upperPositionLimit, dtype=float)[q_idx]
    urdf_vel = np.asarray(model.velocityLimit, dtype=float)[v_idx]
    for i, name in enumerate(s.arm_joints):
        lo, hi, v = lower[i], upper[i], urdf_vel[i]
        if not (np.isfinite(lo) and np.isfinite(hi)) or lo >= hi:
            raise settings_error(s.urdf_path, f"joint {name} limit", f"invalid position limits [{lo}, {hi}]")
        if s.velocity_override_rad_s is None and not (np.isfinite(v) and 0 < v < 1e3):
            raise settings_error(
                s.urdf_path,
                f"joint {name} limit velocity",
                f"invalid velocity limit {v} (not finite and positive, or a placeholder); "
                f"set limits.velocity_rad_s in {src.name}",
            )
        if 2 * s.position_margin_rad[i] >= hi - lo:
            raise settings_error(
                src,
                "limits.position_margin_rad",
                f"margin {s.position_margin_rad[i]} leaves no range for {name}",
            )
    vel = urdf_vel if s.velocity_override_rad_s is None else s.velocity_override_rad_s
    return lower, upper, np.asarray(vel, dtype=float)


def _held_configuration(
    model: pin.Model, s: RobotSettings, q_idx: np.ndarray, lower: np.ndarray, upper: np.ndarray
) -> np.ndarray:
    """The full configuration (nq,): non-arm joints at their fixed values (checked), arm at 0 clipped
    into its limits less the margins."""
    src = s.path
    q0 = pin.neutral(model)
    q0 = np.clip(q0, model.lowerPositionLimit, model.upperPositionLimit)
    q0[q_idx] = np.clip(0.0, lower + s.position_margin_rad, upper - s.position_margin_rad)
    for name, value in s.fixed_joints.items():
        if not model.existJointName(name):
            raise settings_error(
                src, f"fixed_joints.{name}", "unknown joint (not a movable joint of the model)"
            )
        j = model.joints[model.getJointId(name)]
        if j.nq != 1:
            raise settings_error(src, f"fixed_joints.{name}", "only 1-dof joints can be fixed by value")
        lo, hi = model.lowerPositionLimit[j.idx_q], model.upperPositionLimit[j.idx_q]
        if not lo <= value <= hi:
            raise settings_error(
                src, f"fixed_joints.{name}", f"value {value} outside the joint's limits [{lo}, {hi}]"
            )
        q0[j.idx_q] = value
    return q0


def _add_ee_frame(model: pin.Model, s: RobotSettings, last_joint_id: int) -> tuple[int, int]:
    """Add the end-effector frame (parent frame * tool offset, turned by ``[end_effector] rpy_deg``)
    to ``model``; its id and the parent's."""
    src = s.path
    if not model.existFrame(s.ee_parent_frame):
        raise settings_error(src, "end_effector.parent_frame", f"unknown frame '{s.ee_parent_frame}'")
    parent_id = model.getFrameId(s.ee_parent_frame)
    if model.existFrame(s.ee_frame):
        raise settings_error(src, "end_effector.frame", f"frame '{s.ee_frame}' already exists in the model")
    parent = model.frames[parent_id]
    if parent.parentJoint not in model.subtrees[last_joint_id]:
        raise settings_error(
            src, "end_effector.parent_frame", f"frame '{s.ee_parent_frame}' is not moved by the arm"
        )
    offset = _ee_offset(s, 0.0 if s.tool is None else s.tool.length_m)  # a [tool]'s far end: its centre point
    ee_id = model.addFrame(
        pin.Frame(
            s.ee_frame, parent.parentJoint, parent_id, parent.placement * offset, pin.FrameType.OP_FRAME
        )
    )
    return int(ee_id), int(parent_id)


TOOL_GEOMETRY = "tool"
"""Name of the ``[tool]`` cylinder among the collision and visual geometries."""

TOOL_COLOUR = np.array([0.25, 0.25, 0.28, 1.0])
"""RGBA of the ``[tool]`` cylinder in the preview (a dark grey gripper)."""


def _ee_offset(s: RobotSettings, along_m: float) -> pin.SE3:
    """The placement, in the end-effector parent frame, of the point ``along_m`` [m] along the ``ee``
    frame's z from its mount (the tool offset, turned by ``[end_effector] rpy_deg``)."""
    return pin.SE3(s.ee_turn, s.point_on_ee_axis_m(along_m))


def _tool_centre(model: pin.Model, s: RobotSettings) -> tuple[int, int, pin.SE3]:
    """The ``[tool]`` cylinder's joint, frame (the end-effector parent frame) and the placement of its
    centre in that joint's frame (z along the cylinder)."""
    assert s.tool is not None
    parent_id = model.getFrameId(s.ee_parent_frame)
    parent = model.frames[parent_id]
    return int(parent.parentJoint), int(parent_id), parent.placement * _ee_offset(s, 0.5 * s.tool.length_m)


def add_tool_inertia(model: pin.Model, s: RobotSettings) -> None:
    """Add the ``[tool]``'s mass (a solid cylinder) to the inertia of the joint that carries it
    (before any data of ``model`` is created; nothing without a tool or with a massless one)."""
    if s.tool is None or s.tool.mass_kg <= 0.0:
        return
    joint, _, centre = _tool_centre(model, s)
    body = pin.Inertia.FromCylinder(s.tool.mass_kg, s.tool.radius_m, s.tool.length_m)
    model.appendBodyToJoint(joint, body, centre)


def add_tool_geometry(model: pin.Model, geometry: pin.GeometryModel, s: RobotSettings, pairs: bool) -> None:
    """Add the ``[tool]`` cylinder to ``geometry`` (collision or visual); ``pairs``: also pair it with
    every geometry except those its own link and the link before it carry (in contact by design)."""
    if s.tool is None:
        return
    joint, frame, centre = _tool_centre(model, s)
    shape = coal.Cylinder(s.tool.radius_m, s.tool.length_m)
    obj = pin.GeometryObject(TOOL_GEOMETRY, joint, frame, centre, shape)
    obj.meshColor = TOOL_COLOUR
    obj.overrideMaterial = True
    tool_id = geometry.addGeometryObject(obj)
    if not pairs:
        return
    adjacent = {joint, int(model.parents[joint])}
    for k, other in enumerate(geometry.geometryObjects):
        if k != tool_id and int(other.parentJoint) not in adjacent:
            geometry.addCollisionPair(pin.CollisionPair(k, tool_id))


def placement_pose(s: RobotSettings) -> pin.SE3:
    """The arm's base pose in the scene (``[placement]``; identity without one)."""
    if s.placement is None:
        return pin.SE3.Identity()
    rot = pin.rpy.rpyToMatrix(*np.radians(s.placement.rpy_deg))
    return pin.SE3(rot, np.asarray(s.placement.xyz_m, dtype=float))


def _place(model: pin.Model, s: RobotSettings) -> None:
    """Put the whole model at its ``[placement]``: every joint and frame fixed to the world is moved,
    so the world frame of the model (and of its geometries, built from it) is the scene's."""
    if s.placement is None:
        return
    pose = placement_pose(s)
    for j in range(1, model.njoints):
        if model.parents[j] == 0:
            model.jointPlacements[j] = pose * model.jointPlacements[j]
    for i in range(1, len(model.frames)):
        frame = model.frames[i]
        if frame.parentJoint == 0:
            frame.placement = pose * frame.placement
            model.frames[i] = frame


def _collision_model(model: pin.Model, s: RobotSettings) -> tuple[pin.GeometryModel, int, int]:
    """The collision model with the SRDF's disabled pairs removed, the number of pairs before and the
    number the SRDF removed."""
    src = s.path
    try:
        cmodel = pin.buildGeomFromUrdf(
            model, str(s.urdf_path), pin.COLLISION, package_dirs=list(s.package_dirs)
        )
    except (RuntimeError, ValueError) as exc:
        raise settings_error(src, "description.urdf", f"collision geometry cannot be loaded: {exc}") from exc
    cmodel.addAllCollisionPairs()
    n_total = len(cmodel.collisionPairs)
    if s.srdf_path is not None:
        try:
            pin.removeCollisionPairs(model, cmodel, str(s.srdf_path))
        except (RuntimeError, ValueError) as exc:
            raise settings_error(src, "description.srdf", f"cannot be applied: {exc}") from exc
    _remove_listed_pairs(model, cmodel, s)
    n_removed = n_total - len(cmodel.collisionPairs)
    add_tool_geometry(model, cmodel, s, pairs=True)  # its pairs are kept: the total counts them
    return cmodel, n_removed + len(cmodel.collisionPairs), n_removed


def _remove_listed_pairs(model: pin.Model, cmodel: pin.GeometryModel, s: RobotSettings) -> None:
    """Remove the collision pairs between the links of ``[checks] disabled_pairs`` (names checked)."""
    if not s.disabled_pairs:
        return
    for a, b in s.disabled_pairs:
        for name in (a, b):
            if not model.existFrame(name):
                raise settings_error(s.path, "checks.disabled_pairs", f"unknown link '{name}'")
    listed = {frozenset(p) for p in s.disabled_pairs}
    g = cmodel.geometryObjects
    for cp in list(cmodel.collisionPairs):
        links = frozenset(model.frames[g[k].parentFrame].name for k in (cp.first, cp.second))
        if links in listed:
            cmodel.removeCollisionPair(cp)


def _split_pairs(
    model: pin.Model, cmodel: pin.GeometryModel, joint_ids: np.ndarray
) -> tuple[list[int], list[int]]:
    """Indices of the collision pairs whose distance the arm can change (active) and of the others."""
    # A pair's distance can change only if an arm joint lies between its two geometries: each
    # geometry gets the number of arm joints among its parent joint's ancestors ("segment"), and
    # pairs on the same segment (e.g. gripper fingers vs hand, torso vs other arm) are static.
    segment = np.zeros(model.njoints, dtype=int)
    for jid in joint_ids:
        segment[list(model.subtrees[int(jid)])] += 1
    geom_segment = np.array([segment[g.parentJoint] for g in cmodel.geometryObjects], dtype=int)
    active: list[int] = []
    static: list[int] = []
    for k, cp in enumerate(cmodel.collisionPairs):
        (active if geom_segment[cp.first] != geom_segment[cp.second] else static).append(k)
    return active, static


def _check_static_pairs(robot: Robot, static: list[int]) -> None:
    """Check the static pairs once at the held configuration (their smallest distance is stored in
    ``robot.static_min_distance_m``), then deactivate them."""
    model, data = robot.model, robot.data
    cmodel, cdata = robot.collision()
    s = robot.settings
    # Static pairs (neither geometry moves with the arm) are checked once, here.
    if static:
        pin.updateGeometryPlacements(model, data, cmodel, cdata, robot.q_neutral)
        dists = [(pin.computeDistance(cmodel, cdata, k).min_distance, k) for k in static]
        dmin, kmin = min(dists)
        robot.static_min_distance_m = float(dmin)
        if dmin <= s.min_clearance_m:
            a, b = robot.pair_names(kmin)
            raise settings_error(
                s.path, "fixed_joints", f"held configuration is in self-collision: {a} - {b} ({dmin:.4f} m)"
            )
    for k in static:
        cdata.deactivateCollisionPair(k)


def build_robot(s: RobotSettings, collision: bool = True) -> Robot:
    """Build the robot described by validated settings (not cached; see :func:`load_robot`).

    Args:
        s: Validated settings (:func:`load_robot_settings`).
        collision: Also build the collision model (~50 ms) and check the held configuration;
            ``False`` gives a kinematics-only robot (~3 ms, ``collision_model`` is ``None``).

    Raises:
        RobotError: as :func:`load_robot`.
    """
    model = _parse_urdf(s)
    joint_ids, q_idx, v_idx = _arm_indices(model, s)
    lower, upper, vel = _arm_limits(model, s, q_idx, v_idx)
    q0 = _held_configuration(model, s, q_idx, lower, upper)
    ee_id, parent_id = _add_ee_frame(model, s, int(joint_ids[-1]))
    root = int(joint_ids[0])
    model.jointPlacements[root] = pin.SE3(np.eye(3), s.mount_offset_m) * model.jointPlacements[root]
    _place(model, s)
    add_tool_inertia(model, s)
    data = model.createData()
    kinematic = dict(
        settings=s,
        model=model,
        data=data,
        arm_joint_ids=joint_ids,
        arm_q_index=q_idx,
        arm_v_index=v_idx,
        ee_frame_id=ee_id,
        ee_parent_frame_id=parent_id,
        q_neutral=q0,
        lower_rad=lower,
        upper_rad=upper,
        velocity_rad_s=vel,
    )
    if not collision:
        return Robot(collision_model=None, collision_data=None, **kinematic)

    cmodel, n_total, n_removed = _collision_model(model, s)
    cdata = pin.GeometryData(cmodel)
    active, static = _split_pairs(model, cmodel, joint_ids)
    robot = Robot(
        collision_model=cmodel,
        collision_data=cdata,
        **kinematic,
        n_pairs_total=n_total,
        n_pairs_srdf_removed=n_removed,
        active_pair_ids=np.asarray(active, dtype=int),
    )
    _check_static_pairs(robot, static)
    return robot


def load_visual_model(robot: Robot, tool: bool = True) -> pin.GeometryModel:
    """Visual geometry (meshes) of ``robot``, for previews only (slow: ~2 s; never used by the checks);
    ``tool``: with the ``[tool]`` cylinder (False: the URDF's alone)."""
    s = robot.settings
    try:
        visual = pin.buildGeomFromUrdf(
            robot.model, str(s.urdf_path), pin.VISUAL, package_dirs=list(s.package_dirs)
        )
    except (RuntimeError, ValueError) as exc:
        raise settings_error(s.path, "description.urdf", f"visual geometry cannot be loaded: {exc}") from exc
    if tool:
        add_tool_geometry(robot.model, visual, s, pairs=False)
    return visual


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
