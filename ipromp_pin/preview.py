"""3-D preview of a recognised hand-over: Baxter playing its predicted trajectory next to the human.

The preview is a `meshcat <https://github.com/meshcat-dev/meshcat-python>`_ scene built with
Pinocchio's :class:`pinocchio.visualize.MeshcatVisualizer`:

- the robot's visual meshes (decimated with ``fast_simplification`` so that an offline page stays
  small), playing the time-parameterised arm trajectory in real time as a meshcat animation (the
  viewer's "Open Controls > Animations" folder has play / pause / reset and a time scrubber);
- the human hand path (observed part green, the rest grey), an animated hand marker when the hand
  times are known, and the hand-over point (gold sphere);
- the predicted end-effector path (blue tube) with its uncertainty (translucent tube of radius
  2 sigma, and thin sampled paths), and the recorded robot path (purple) when it is known;
- the recognised task on a text plane above the robot, and an HTML panel with the posterior of
  every task, the observation window and the feasibility checks; failing parts are coloured on
  the robot (a link in collision red, a joint near its limit orange).

Two outputs:

- :func:`write_html` writes ONE self-contained HTML file (viewer script, meshes and panel inline,
  no network, no server);
- :class:`LivePreview` serves the same scene on ``127.0.0.1`` only (the web server of
  ``meshcat.Visualizer()`` listens on every interface, so this module runs its own tornado
  server and never starts meshcat's) and can be updated while a streaming recognition progresses.

Everything the preview shows comes in a :class:`PreviewContent`: plain arrays plus the Pinocchio
model handles, so that this module does not depend on the recognition or planning internals.
All positions are in [m] in the robot's base frame, times in [s] from the start of the motion.
"""

from __future__ import annotations

import asyncio
import base64
import dataclasses
import ipaddress
import json
import threading
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import meshcat
import meshcat.animation
import meshcat.geometry as mg
import numpy as np
import pinocchio as pin
import umsgpack
from pinocchio.visualize import MeshcatVisualizer

from .exceptions import DataError

__all__ = [
    "DEFAULT_MAX_TRIANGLES",
    "FeasibilityCheck",
    "LivePreview",
    "PreviewContent",
    "overlay_state",
    "render_html",
    "serve_preview",
    "count_triangles",
    "simplify_visual_model",
    "write_html",
]

_SOURCE = "preview"

#: Default triangle budget of the robot's visual meshes (Baxter: a 3.7 MB offline page).
DEFAULT_MAX_TRIANGLES = 100_000

# Colours (0xRRGGBB) of the scene elements; the HTML legend uses the same values.
COLOR_HAND_OBSERVED = 0x2CA02C
COLOR_HAND_REST = 0x9E9E9E
COLOR_HANDOVER = 0xFFB000
COLOR_EE_MEAN = 0x1F77B4
COLOR_EE_BAND = 0x6BAED6
COLOR_EE_TRUTH = 0x9467BD
COLOR_COLLISION = (1.0, 0.0, 0.0, 1.0)
COLOR_NEAR_LIMIT = (1.0, 0.55, 0.0, 1.0)

# Scene paths (under meshcat's root "/meshcat").
_ROBOT_NODE = "robot"
_HUMAN_NODES = ("human/observed", "human/rest", "human/hand", "human/handover")
_PREDICTION_NODES = ("prediction/mean", "prediction/band", "prediction/samples", "prediction/truth")
_LABEL_NODE = "labels/task"

_VIEWER_JS_PATH = Path(meshcat.__file__).resolve().parent / "viewer" / "dist" / "main.min.js"

# Explicit module-level cache of meshes, keyed by (mesh file, scale, triangles, target triangles or
# None for the original):
# decimating Baxter's ~400k visual triangles takes a few seconds, and a live preview or a batch of
# offline previews reuses the same meshes.  Cleared with ``_SIMPLIFIED_MESHES.clear()``.
_SIMPLIFIED_MESHES: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}


class FeasibilityCheck(NamedTuple):
    """One line of the feasibility panel.

    Attributes:
        name: Check name, e.g. ``"joint limits"``.
        passed: Whether the check passed.
        detail: Short detail, e.g. ``"left_e1 within 0.02 rad of its limit"``.
    """

    name: str
    passed: bool
    detail: str = ""


def _err(field_name: str | None, problem: str) -> DataError:
    return DataError(_SOURCE, field_name, problem)


def _as_array(value: Any, field_name: str, ndim: int, last: int | None = None) -> np.ndarray:
    """Finite float array with ``ndim`` dimensions (and last dimension ``last``)."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise _err(field_name, f"not a numeric array ({exc})") from exc
    if arr.ndim != ndim:
        raise _err(field_name, f"expected {ndim} dimensions, got shape {arr.shape}")
    if last is not None and arr.shape[-1] != last:
        raise _err(field_name, f"expected last dimension {last}, got shape {arr.shape}")
    if arr.size == 0:
        raise _err(field_name, "is empty")
    if not np.all(np.isfinite(arr)):
        raise _err(field_name, "contains NaN or infinite values")
    return arr


def _optional(value: Any, field_name: str, ndim: int, last: int | None = None) -> np.ndarray | None:
    return None if value is None else _as_array(value, field_name, ndim, last)


@dataclass
class PreviewContent:
    """Everything one preview shows (built by the pipeline from the model and planner outputs).

    Attributes:
        model: Pinocchio model of the whole robot.
        visual_model: Visual geometry (meshes) of the robot; ``None`` draws ``collision_model``.
        t_s: (N,) trajectory time in [s], strictly increasing, starting at the motion start.
        q: (N, J) arm joint positions in [rad] at ``t_s``.
        joint_names: (J,) model joint names of the columns of ``q``.
        q_full: (nq,) full configuration giving the other joints' fixed values (``None``: neutral).
        collision_model: Collision geometry (used when ``visual_model`` is ``None``).
        ee_mean: (M, 3) predicted end-effector path in [m] (mean).
        ee_samples: (S, M, 3) end-effector paths of trajectories sampled from the prediction.
        ee_std: (M, 3) per-point standard deviation of the end-effector path in [m]; computed
            from ``ee_samples`` when only those are given.
        ee_truth: (G, 3) recorded robot end-effector path (ground truth of a known demo).
        hand_path: (H, 3) human hand path in [m] in the robot base frame.
        hand_t_s: (H,) times of ``hand_path`` in [s] (animates a hand marker, splits the path
            at ``observed_until_s``).
        hand_observed_index: Number of ``hand_path`` points that were observed (overrides the
            split computed from ``hand_t_s`` and ``observed_until_s``).
        observed_until_s: End of the observed window in [s] from the motion start.
        handover_point: (3,) hand-over point in [m].
        task: Recognised task name.
        tasks: (K,) names of all tasks.
        posterior: (K,) posterior probability of every task (sums to 1).
        feasibility: Feasibility results as :class:`FeasibilityCheck` or ``(name, passed, detail)``.
        collision_links: Links (frame or geometry names) found in collision: drawn red.
        near_limit_joints: Joints near a limit: the link they move is drawn orange.
        title: Title of the page / panel.
    """

    model: pin.Model
    visual_model: pin.GeometryModel | None
    t_s: np.ndarray
    q: np.ndarray
    joint_names: Sequence[str]
    q_full: np.ndarray | None = None
    collision_model: pin.GeometryModel | None = None
    ee_mean: np.ndarray | None = None
    ee_samples: np.ndarray | None = None
    ee_std: np.ndarray | None = None
    ee_truth: np.ndarray | None = None
    hand_path: np.ndarray | None = None
    hand_t_s: np.ndarray | None = None
    hand_observed_index: int | None = None
    observed_until_s: float | None = None
    handover_point: np.ndarray | None = None
    task: str = ""
    tasks: Sequence[str] = ()
    posterior: np.ndarray | None = None
    feasibility: Sequence[FeasibilityCheck | tuple] = ()
    collision_links: Sequence[str] = ()
    near_limit_joints: Sequence[str] = ()
    title: str = "ipromp_pin preview"
    _q_index: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.model, pin.Model):
            raise _err("model", f"expected a pinocchio.Model, got {type(self.model).__name__}")
        if self.visual_model is None and self.collision_model is None:
            raise _err("visual_model", "neither a visual nor a collision model was given")
        self.t_s = _as_array(self.t_s, "t_s", 1)
        if self.t_s.size >= 2 and np.any(np.diff(self.t_s) <= 0.0):
            raise _err("t_s", "times must be strictly increasing")
        self.joint_names = tuple(str(n) for n in self.joint_names)
        self.q = _as_array(self.q, "q", 2, len(self.joint_names))
        if self.q.shape[0] != self.t_s.size:
            raise _err("q", f"has {self.q.shape[0]} rows but t_s has {self.t_s.size} samples")
        index = []
        for name in self.joint_names:
            if not self.model.existJointName(name):
                raise _err("joint_names", f"joint '{name}' is not in the robot model")
            joint = self.model.joints[self.model.getJointId(name)]
            if joint.nq != 1:
                raise _err(
                    "joint_names", f"joint '{name}' has {joint.nq} configuration variables, expected 1"
                )
            index.append(joint.idx_q)
        self._q_index = np.asarray(index, dtype=int)
        if self.q_full is None:
            self.q_full = pin.neutral(self.model)
        self.q_full = _as_array(self.q_full, "q_full", 1)
        if self.q_full.size != self.model.nq:
            raise _err("q_full", f"expected {self.model.nq} values (model.nq), got {self.q_full.size}")

        self.ee_mean = _optional(self.ee_mean, "ee_mean", 2, 3)
        self.ee_samples = _optional(self.ee_samples, "ee_samples", 3, 3)
        self.ee_std = _optional(self.ee_std, "ee_std", 2, 3)
        if self.ee_samples is not None:
            if self.ee_mean is None:
                self.ee_mean = self.ee_samples.mean(axis=0)
            if self.ee_samples.shape[1] != self.ee_mean.shape[0]:
                raise _err(
                    "ee_samples",
                    f"paths have {self.ee_samples.shape[1]} points, ee_mean has {self.ee_mean.shape[0]}",
                )
            if self.ee_std is None and self.ee_samples.shape[0] >= 2:
                self.ee_std = self.ee_samples.std(axis=0, ddof=1)
        if self.ee_std is not None:
            if self.ee_mean is None:
                raise _err("ee_std", "given without ee_mean")
            if self.ee_std.shape != self.ee_mean.shape:
                raise _err("ee_std", f"shape {self.ee_std.shape} differs from ee_mean {self.ee_mean.shape}")
            if np.any(self.ee_std < 0.0):
                raise _err("ee_std", "standard deviations must be >= 0")
        self.ee_truth = _optional(self.ee_truth, "ee_truth", 2, 3)

        self.hand_path = _optional(self.hand_path, "hand_path", 2, 3)
        self.hand_t_s = _optional(self.hand_t_s, "hand_t_s", 1)
        if self.hand_t_s is not None:
            if self.hand_path is None:
                raise _err("hand_t_s", "given without hand_path")
            if self.hand_t_s.size != self.hand_path.shape[0]:
                raise _err(
                    "hand_t_s", f"has {self.hand_t_s.size} samples, hand_path has {self.hand_path.shape[0]}"
                )
            if self.hand_t_s.size >= 2 and np.any(np.diff(self.hand_t_s) <= 0.0):
                raise _err("hand_t_s", "times must be strictly increasing")
        if self.hand_observed_index is not None:
            if self.hand_path is None:
                raise _err("hand_observed_index", "given without hand_path")
            idx = int(self.hand_observed_index)
            if not 0 <= idx <= self.hand_path.shape[0]:
                raise _err("hand_observed_index", f"{idx} outside [0, {self.hand_path.shape[0]}]")
            self.hand_observed_index = idx
        if self.observed_until_s is not None:
            self.observed_until_s = float(self.observed_until_s)
            if not np.isfinite(self.observed_until_s) or self.observed_until_s < 0.0:
                raise _err("observed_until_s", f"must be a finite time >= 0, got {self.observed_until_s}")
        self.handover_point = _optional(self.handover_point, "handover_point", 1, 3)

        self.tasks = tuple(str(t) for t in self.tasks)
        self.task = str(self.task)
        if self.posterior is not None:
            self.posterior = _as_array(self.posterior, "posterior", 1)
            if self.posterior.size != len(self.tasks):
                raise _err("posterior", f"has {self.posterior.size} values for {len(self.tasks)} tasks")
            if np.any(self.posterior < 0.0) or abs(float(self.posterior.sum()) - 1.0) > 1e-6:
                raise _err("posterior", "must be probabilities >= 0 summing to 1")
        if self.task and self.tasks and self.task not in self.tasks:
            raise _err("task", f"'{self.task}' is not one of the tasks {list(self.tasks)}")
        checks = []
        for item in self.feasibility:
            if not isinstance(item, (tuple, list)) or not 2 <= len(item) <= 3:
                raise _err("feasibility", f"expected (name, passed, detail), got {item!r}")
            checks.append(
                FeasibilityCheck(str(item[0]), bool(item[1]), str(item[2]) if len(item) > 2 else "")
            )
        self.feasibility = tuple(checks)
        self.collision_links = tuple(str(n) for n in self.collision_links)
        for name in self.collision_links:
            self.link_frame(name)
        self.near_limit_joints = tuple(str(n) for n in self.near_limit_joints)
        for name in self.near_limit_joints:
            if not self.model.existJointName(name):
                raise _err("near_limit_joints", f"joint '{name}' is not in the robot model")

    def link_frame(self, name: str) -> int:
        """Frame id of a link given by its frame name or by a geometry object's name."""
        if self.model.existFrame(name):
            return self.model.getFrameId(name)
        for geometry in (self.collision_model, self.visual_model):
            if geometry is not None and geometry.existGeometryName(name):
                return geometry.geometryObjects[geometry.getGeometryId(name)].parentFrame
        raise _err("collision_links", f"'{name}' is neither a frame nor a geometry of the robot")

    @property
    def duration_s(self) -> float:
        """Duration of the robot trajectory in [s]."""
        return float(self.t_s[-1])

    def configurations(self, t_s: np.ndarray) -> np.ndarray:
        """Full configurations (len(t_s), nq) at times ``t_s`` [s], arm joints linearly interpolated."""
        qs = np.repeat(self.q_full[None, :], len(t_s), axis=0)
        for j, iq in enumerate(self._q_index):
            qs[:, iq] = np.interp(t_s, self.t_s, self.q[:, j])
        return qs

    def hand_observed_count(self) -> int | None:
        """Number of observed ``hand_path`` points, ``None`` when unknown."""
        if self.hand_path is None:
            return None
        if self.hand_observed_index is not None:
            return self.hand_observed_index
        if self.hand_t_s is not None and self.observed_until_s is not None:
            return int(np.searchsorted(self.hand_t_s, self.observed_until_s, side="right"))
        return None

    def replace(self, **changes: Any) -> PreviewContent:
        """Copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


# ----------------------------------------------------------------------------------------------
# Robot geometry


def _triangles(geometry: Any) -> tuple[np.ndarray, np.ndarray]:
    vertices = np.asarray(geometry.vertices(), dtype=float)
    faces = np.empty((geometry.num_tris, 3), dtype=np.int64)
    for k in range(geometry.num_tris):
        tri = geometry.tri_indices(k)
        faces[k] = (tri[0], tri[1], tri[2])
    return vertices, faces


def _bvh(vertices: np.ndarray, faces: np.ndarray) -> Any:
    import coal

    bvh = coal.BVHModelOBBRSS()
    bvh.beginModel(len(faces), len(vertices))
    bvh.addVertices(np.ascontiguousarray(vertices, dtype=float))
    bvh.addTriangles(np.ascontiguousarray(faces, dtype=np.int64))
    bvh.endModel()
    return bvh


def _decimated(obj: pin.GeometryObject, target: int) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of a mesh object, scale baked in, decimated to about ``target`` triangles."""
    import fast_simplification

    scale = np.asarray(obj.meshScale, dtype=float)
    source = (obj.meshPath, tuple(scale), obj.geometry.num_tris)
    if source + (None,) not in _SIMPLIFIED_MESHES:
        vertices, faces = _triangles(obj.geometry)
        _SIMPLIFIED_MESHES[source + (None,)] = (vertices * scale, faces)
    key = source + (target,)
    if key not in _SIMPLIFIED_MESHES:
        vertices, faces = _SIMPLIFIED_MESHES[source + (None,)]
        if target < len(faces):
            vertices, faces = fast_simplification.simplify(
                vertices.astype(np.float32), faces.astype(np.int32), target_count=target
            )
        _SIMPLIFIED_MESHES[key] = (np.asarray(vertices, dtype=float), np.asarray(faces, dtype=np.int64))
    return _SIMPLIFIED_MESHES[key]


def simplify_visual_model(
    visual_model: pin.GeometryModel, max_triangles: int = DEFAULT_MAX_TRIANGLES
) -> pin.GeometryModel:
    """Copy of ``visual_model`` whose meshes have at most about ``max_triangles`` triangles in total.

    Meshes are decimated with quadric edge collapse (``fast_simplification``) by a common ratio;
    meshes that cannot be reduced that far (many small parts) keep more triangles, and the ratio
    of the others is lowered to stay within the budget (a few passes). Primitives (boxes,
    cylinders, spheres) are kept as they are. Mesh scales are baked into the vertices and mesh file
    references dropped, so that meshcat receives the decimated triangles instead of the original
    files. Colours are the description's ``meshColor``.
    """
    import coal

    if max_triangles < 100:
        raise _err("max_triangles", f"must be >= 100, got {max_triangles}")
    meshes = [g for g in visual_model.geometryObjects if isinstance(g.geometry, coal.BVHModelBase)]
    total = sum(g.geometry.num_tris for g in meshes)
    ratio = min(1.0, max_triangles / total) if total else 1.0
    targets: dict[str, int] = {}
    for _ in range(4):
        targets = {g.name: max(12, int(g.geometry.num_tris * ratio)) for g in meshes}
        reached = sum(len(_decimated(g, targets[g.name])[1]) for g in meshes)
        if reached <= 1.05 * max_triangles or ratio * total < 12 * len(meshes):
            break
        ratio *= max_triangles / reached
    result = pin.GeometryModel()
    for obj in visual_model.geometryObjects:
        new = pin.GeometryObject(obj)
        if obj.name in targets:
            new.geometry = _bvh(*_decimated(obj, targets[obj.name]))
            new.meshPath = ""
            new.meshScale = np.ones(3)
        result.addGeometryObject(new)
    return result


def count_triangles(geometry_model: pin.GeometryModel) -> int:
    """Total number of mesh triangles of a geometry model (primitives not counted)."""
    import coal

    return sum(
        g.geometry.num_tris
        for g in geometry_model.geometryObjects
        if isinstance(g.geometry, coal.BVHModelBase)
    )


def _highlight(content: PreviewContent, geometry_model: pin.GeometryModel) -> dict[str, tuple]:
    """Colour override per geometry object name: collision links red, near-limit joints orange."""
    model = content.model
    colors: dict[str, tuple] = {}
    by_frame: dict[int, list[str]] = {}
    by_joint: dict[int, list[str]] = {}
    for obj in geometry_model.geometryObjects:
        by_frame.setdefault(obj.parentFrame, []).append(obj.name)
        by_joint.setdefault(obj.parentJoint, []).append(obj.name)
    for name in content.near_limit_joints:
        for geom in by_joint.get(model.getJointId(name), []):
            colors[geom] = COLOR_NEAR_LIMIT
    for name in content.collision_links:
        frame_id = content.link_frame(name)
        geoms = by_frame.get(frame_id) or by_joint.get(model.frames[frame_id].parentJoint, [])
        for geom in geoms:
            colors[geom] = COLOR_COLLISION
    return colors


# ----------------------------------------------------------------------------------------------
# Scene primitives


def _tube(points: np.ndarray, radius: float | np.ndarray, sides: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Closed tube mesh (vertices (V,3), faces (F,3)) around a polyline (M,3), radius scalar or (M,)."""
    pts = np.asarray(points, dtype=float)
    radii = np.broadcast_to(np.asarray(radius, dtype=float), (len(pts),))
    keep = np.ones(len(pts), dtype=bool)
    keep[1:] = np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-9
    pts, radii = pts[keep], radii[keep]
    if len(pts) < 2:
        return _sphere_mesh(pts[0], float(radii[0]))
    tangents = np.gradient(pts, axis=0)
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    # Parallel transport of a normal along the path (no twist).
    normals = np.empty_like(pts)
    axis = np.eye(3)[int(np.argmin(np.abs(tangents[0])))]
    normal = np.cross(tangents[0], axis)
    normal /= np.linalg.norm(normal)
    for i, tangent in enumerate(tangents):
        projected = normal - np.dot(normal, tangent) * tangent
        norm = np.linalg.norm(projected)
        if norm < 1e-6:
            projected = np.cross(tangent, np.eye(3)[int(np.argmin(np.abs(tangent)))])
            norm = np.linalg.norm(projected)
        normal = projected / norm
        normals[i] = normal
    binormals = np.cross(tangents, normals)
    angles = 2.0 * np.pi * np.arange(sides) / sides
    ring = (
        pts[:, None, :]
        + radii[:, None, None]
        * (
            np.cos(angles)[None, :, None] * normals[:, None, :]
            + np.sin(angles)[None, :, None] * binormals[:, None, :]
        )
    ).reshape(-1, 3)
    m = len(pts)
    i, k = np.meshgrid(np.arange(m - 1), np.arange(sides), indexing="ij")
    a = i * sides + k
    b = i * sides + (k + 1) % sides
    c = a + sides
    d = b + sides
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    start, end = len(ring), len(ring) + 1
    k = np.arange(sides)
    caps = np.concatenate(
        [
            np.stack([np.full(sides, start), (k + 1) % sides, k], -1),
            np.stack([np.full(sides, end), (m - 1) * sides + k, (m - 1) * sides + (k + 1) % sides], -1),
        ]
    )
    vertices = np.vstack([ring, pts[0], pts[-1]])
    return vertices, np.vstack([faces, caps])


def _sphere_mesh(center: np.ndarray, radius: float, n: int = 12) -> tuple[np.ndarray, np.ndarray]:
    theta = np.linspace(0.0, np.pi, n + 1)[1:-1]
    phi = 2.0 * np.pi * np.arange(2 * n) / (2 * n)
    ring = np.stack(
        [
            np.outer(np.sin(theta), np.cos(phi)),
            np.outer(np.sin(theta), np.sin(phi)),
            np.outer(np.cos(theta), phi * 0),
        ],
        -1,
    ).reshape(-1, 3)
    vertices = np.vstack([ring, [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]) * radius + np.asarray(center, dtype=float)
    rows, cols = len(theta), len(phi)
    i, k = np.meshgrid(np.arange(rows - 1), np.arange(cols), indexing="ij")
    a = i * cols + k
    b = i * cols + (k + 1) % cols
    faces = [
        np.stack([a, b, b + cols], -1).reshape(-1, 3),
        np.stack([a, b + cols, a + cols], -1).reshape(-1, 3),
    ]
    top, bottom = len(ring), len(ring) + 1
    k = np.arange(cols)
    faces.append(np.stack([np.full(cols, top), (k + 1) % cols, k], -1))
    last = (rows - 1) * cols
    faces.append(np.stack([np.full(cols, bottom), last + k, last + (k + 1) % cols], -1))
    return vertices, np.vstack(faces)


def _material(color: int, opacity: float = 1.0) -> mg.MeshPhongMaterial:
    return mg.MeshPhongMaterial(color=color, opacity=opacity, transparent=opacity < 1.0)


def _set_mesh(
    node: meshcat.Visualizer, mesh: tuple[np.ndarray, np.ndarray], color: int, opacity: float = 1.0
) -> None:
    node.set_object(mg.TriangularMeshGeometry(mesh[0], mesh[1]), _material(color, opacity))


class _PlaneGeometry(mg.Geometry):
    """three.js PlaneGeometry (in the XY plane, facing +z, with texture coordinates)."""

    def __init__(self, width: float, height: float) -> None:
        super().__init__()
        self.width = width
        self.height = height

    def lower(self, object_data: Any) -> dict[str, Any]:
        return {
            "uuid": self.uuid,
            "type": "PlaneGeometry",
            "width": self.width,
            "height": self.height,
            "widthSegments": 1,
            "heightSegments": 1,
        }


def _text_plane(text: str) -> mg.Mesh:
    """Square plane showing ``text`` on meshcat's canvas texture (one line, 256 px canvas)."""
    texture = mg.GenericTexture({"type": "_text", "text": text, "font_size": 44, "font_face": "sans-serif"})
    material = mg.MeshBasicMaterial(map=texture, transparent=True)
    return mg.Mesh(_PlaneGeometry(1.0, 1.0), material)


def _plane_facing_x(position: np.ndarray, size: float) -> np.ndarray:
    """Transform putting an XY plane upright, readable from the front (+x) of the robot."""
    T = np.eye(4)
    T[:3, :3] = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]) * size
    T[:3, 3] = position
    return T


# ----------------------------------------------------------------------------------------------
# Scene building


class _RobotView:
    """Pinocchio MeshcatVisualizer of the (decimated) robot inside a meshcat scene."""

    def __init__(self, content: PreviewContent, max_triangles: int) -> None:
        source = content.visual_model if content.visual_model is not None else content.collision_model
        self.geometry = simplify_visual_model(source, max_triangles)
        self.visualizer = MeshcatVisualizer(content.model, None, self.geometry)

    def load(self, viewer: meshcat.Visualizer, content: PreviewContent) -> None:
        """Send the robot meshes (description colours), paint failing links, show the start pose."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            self.visualizer.initViewer(viewer=viewer)
            self.visualizer.loadViewerModel(rootNodeName=_ROBOT_NODE)
        self._painted: dict[str, tuple] = {}
        self.paint(viewer, content)
        self.visualizer.display(content.configurations(np.array([0.0]))[0])

    def paint(self, viewer: meshcat.Visualizer, content: PreviewContent) -> None:
        """Colour links in collision red and links moved by a joint near its limit orange.

        Only the colour property of the affected nodes is sent (no mesh is sent again), which keeps
        live updates small.
        """
        colors = _highlight(content, self.geometry)
        for obj in self.geometry.geometryObjects:
            color = colors.get(obj.name)
            if color is None and obj.name not in self._painted:
                continue
            if color is None:
                color = tuple(float(c) for c in obj.meshColor)
            if self._painted.get(obj.name) == color:
                continue
            node = viewer[self.visualizer.getViewerNodeName(obj, pin.GeometryType.VISUAL)]
            node.set_property("color", list(color))
            self._painted[obj.name] = color

    def placements(self, q: np.ndarray) -> list[np.ndarray]:
        viz = self.visualizer
        pin.forwardKinematics(viz.model, viz.data, q)
        pin.updateGeometryPlacements(viz.model, viz.data, self.geometry, viz.visual_data)
        return [viz.visual_data.oMg[i].homogeneous.copy() for i in range(self.geometry.ngeoms)]

    def floor_height(self, q: np.ndarray) -> float:
        """Lowest vertex height in [m] of the robot at configuration ``q``."""
        import coal

        low = np.inf
        for obj, T in zip(self.geometry.geometryObjects, self.placements(q), strict=True):
            if isinstance(obj.geometry, coal.BVHModelBase):
                v = np.asarray(obj.geometry.vertices())
                low = min(low, float((v @ T[:3, :3].T + T[:3, 3])[:, 2].min()))
        return low if np.isfinite(low) else 0.0


def _animate(viewer: meshcat.Visualizer, robot: _RobotView, content: PreviewContent, fps: float) -> None:
    """Meshcat animation of the robot (and of the hand marker) in real time at ``fps`` frames/s."""
    duration = content.duration_s
    if content.hand_t_s is not None:
        duration = max(duration, float(content.hand_t_s[-1]))
    n_frames = max(2, int(np.ceil(duration * fps)) + 1)
    times = np.arange(n_frames) / fps
    qs = content.configurations(times)
    frames = [robot.placements(q) for q in qs]
    names = [
        robot.visualizer.getViewerNodeName(o, pin.GeometryType.VISUAL) for o in robot.geometry.geometryObjects
    ]
    moving = [
        i for i in range(len(names)) if any(not np.allclose(f[i], frames[0][i], atol=1e-9) for f in frames)
    ]
    animation = meshcat.animation.Animation(default_framerate=fps)
    hand = None
    if content.hand_path is not None and content.hand_t_s is not None:
        hand = np.stack([np.interp(times, content.hand_t_s, content.hand_path[:, d]) for d in range(3)], -1)
    for k in range(n_frames):
        with animation.at_frame(viewer, k) as frame:
            for i in moving:
                frame[names[i]].set_transform(frames[k][i])
            if hand is not None:
                T = np.eye(4)
                T[:3, 3] = hand[k]
                frame["human/hand"].set_transform(T)
    viewer.set_animation(animation, play=True, repetitions=1)


def _draw_human(viewer: meshcat.Visualizer, content: PreviewContent) -> None:
    for name in _HUMAN_NODES:
        viewer[name].delete()
    if content.hand_path is not None:
        path = content.hand_path
        n_obs = content.hand_observed_count()
        if n_obs is None:
            _set_mesh(viewer["human/rest"], _tube(path, 0.006), COLOR_HAND_REST, 0.8)
        else:
            if n_obs >= 1:
                _set_mesh(viewer["human/observed"], _tube(path[:n_obs], 0.009), COLOR_HAND_OBSERVED)
            if n_obs < len(path):
                rest = path[max(0, n_obs - 1) :]
                _set_mesh(viewer["human/rest"], _tube(rest, 0.006), COLOR_HAND_REST, 0.8)
        if content.hand_t_s is not None:
            _set_mesh(viewer["human/hand"], _sphere_mesh(np.zeros(3), 0.03), COLOR_HAND_OBSERVED, 0.9)
            T = np.eye(4)
            T[:3, 3] = path[0]
            viewer["human/hand"].set_transform(T)
    if content.handover_point is not None:
        _set_mesh(viewer["human/handover"], _sphere_mesh(content.handover_point, 0.035), COLOR_HANDOVER)


def _draw_prediction(viewer: meshcat.Visualizer, content: PreviewContent) -> None:
    for name in _PREDICTION_NODES:
        viewer[name].delete()
    if content.ee_mean is not None:
        _set_mesh(viewer["prediction/mean"], _tube(content.ee_mean, 0.006), COLOR_EE_MEAN)
        if content.ee_std is not None:
            # Radius: 2 sigma of the root-mean-square per-axis standard deviation.
            radius = 2.0 * np.sqrt(np.mean(content.ee_std**2, axis=1))
            _set_mesh(
                viewer["prediction/band"],
                _tube(content.ee_mean, np.maximum(radius, 0.007), 16),
                COLOR_EE_BAND,
                0.25,
            )
        if content.ee_samples is not None:
            samples = content.ee_samples[:30]
            # One LineSegments object: consecutive point pairs of every sampled path.
            segments = np.concatenate([np.stack([s[:-1], s[1:]], 1).reshape(-1, 3) for s in samples])
            material = mg.LineBasicMaterial(color=COLOR_EE_MEAN, opacity=0.35, transparent=True)
            viewer["prediction/samples"].set_object(mg.LineSegments(mg.PointsGeometry(segments.T), material))
    if content.ee_truth is not None:
        _set_mesh(viewer["prediction/truth"], _tube(content.ee_truth, 0.005), COLOR_EE_TRUTH)


def _task_label(content: PreviewContent) -> str:
    if not content.task:
        return "task: (none)"
    if content.posterior is not None and content.task in content.tasks:
        p = float(content.posterior[content.tasks.index(content.task)])
        return f"{content.task} ({p:.2f})"
    return content.task


def _draw_label(viewer: meshcat.Visualizer, content: PreviewContent) -> None:
    node = viewer[_LABEL_NODE]
    node.set_object(_text_plane(_task_label(content)))
    node.set_transform(_plane_facing_x(np.array([0.35, 0.0, 0.95]), 0.6))


def _setup_view(viewer: meshcat.Visualizer, floor_z: float) -> None:
    viewer["/Background"].set_property("top_color", [0.97, 0.97, 0.98])
    viewer["/Background"].set_property("bottom_color", [0.78, 0.80, 0.84])
    # The grid on the floor under the pedestal; hidden by default (software WebGL draws its lines
    # badly), "Open Controls > Grid" shows it.
    T = np.eye(4)
    T[2, 3] = floor_z
    viewer["/Grid"].set_transform(T)
    viewer["/Grid"].set_property("visible", False)
    viewer["/Axes"].set_property("visible", False)
    # Camera in three.js coordinates (x, z, -y): in front of Baxter, to its left, above.
    viewer["/Cameras/default/rotated/<object>"].set_property("position", [2.0, 0.8, -1.2])


def overlay_state(content: PreviewContent) -> dict[str, Any]:
    """JSON-serialisable state of the HTML panel (task, posterior, observation, feasibility, legend)."""
    posterior = [] if content.posterior is None else [float(p) for p in content.posterior]
    observed = None
    if content.observed_until_s is not None:
        observed = {"until_s": content.observed_until_s, "duration_s": content.duration_s}
    legend = []
    if content.hand_path is not None:
        legend.append({"label": "hand path (observed)", "color": f"#{COLOR_HAND_OBSERVED:06x}"})
        legend.append({"label": "hand path (not yet observed)", "color": f"#{COLOR_HAND_REST:06x}"})
    if content.handover_point is not None:
        legend.append({"label": "hand-over point", "color": f"#{COLOR_HANDOVER:06x}"})
    if content.ee_mean is not None:
        legend.append({"label": "predicted gripper path", "color": f"#{COLOR_EE_MEAN:06x}"})
    if content.ee_std is not None:
        legend.append({"label": "uncertainty (2 sigma)", "color": f"#{COLOR_EE_BAND:06x}"})
    if content.ee_truth is not None:
        legend.append({"label": "recorded robot path", "color": f"#{COLOR_EE_TRUTH:06x}"})
    return {
        "title": content.title,
        "task": content.task,
        "tasks": list(content.tasks),
        "posterior": posterior,
        "observed": observed,
        "feasibility": [
            {"name": c.name, "passed": c.passed, "detail": c.detail} for c in content.feasibility
        ],
        "collision_links": list(content.collision_links),
        "near_limit_joints": list(content.near_limit_joints),
        "legend": legend,
    }


# ----------------------------------------------------------------------------------------------
# Scene recording (a meshcat "window" that keeps the scene like meshcat's server does)


class _Node(dict):
    __slots__ = ("object", "transform", "properties", "animation")

    def __init__(self) -> None:
        super().__init__()
        self.object: bytes | None = None
        self.transform: bytes | None = None
        self.properties: dict[str, bytes] = {}
        self.animation: bytes | None = None


def _walk(node: _Node):
    yield node
    for child in node.values():
        yield from _walk(child)


class _SceneWindow:
    """Stand-in for meshcat's ``ViewerWindow``: keeps the scene tree and forwards new commands.

    ``send`` is what ``meshcat.Visualizer`` calls for every command. The tree mirrors what
    meshcat's ZMQ server keeps, so that :meth:`commands` replays the whole scene.
    """

    def __init__(self) -> None:
        self.root = _Node()
        self.overlay: bytes | None = None
        self.lock = threading.RLock()
        self.listener = None  # callable(bytes) receiving every new command, or None

    def _find(self, path: list[str]) -> _Node:
        node = self.root
        for part in path:
            node = node.setdefault(part, _Node())
        return node

    def send(self, command: Any) -> None:
        data = command.lower()
        kind = data["type"]
        packed = umsgpack.packb(data)
        path = [p for p in str(data.get("path", "")).split("/") if p]
        with self.lock:
            if kind == "set_object":
                node = self._find(path)
                node.object = packed
                node.properties = {}
            elif kind == "set_transform":
                self._find(path).transform = packed
            elif kind == "set_property":
                # Keep the latest value of every property (a live preview re-sends them).
                self._find(path).properties[data["property"]] = packed
            elif kind == "set_animation":
                self.root.animation = packed
            elif kind == "delete":
                if path:
                    parent = self._find(path[:-1])
                    parent.pop(path[-1], None)
                else:
                    self.root = _Node()
            else:
                raise ValueError(f"unsupported meshcat command {kind!r}")
            if self.listener is not None:
                self.listener(packed)

    def set_overlay(self, state: dict[str, Any]) -> None:
        packed = umsgpack.packb({"type": "ipromp_overlay", "state": state})
        with self.lock:
            self.overlay = packed
            if self.listener is not None:
                self.listener(packed)

    def commands(self) -> list[bytes]:
        """Every command needed to rebuild the current scene, in order."""
        with self.lock:
            out: list[bytes] = []
            for node in _walk(self.root):
                if node.object is not None:
                    out.append(node.object)
                out.extend(node.properties.values())
                if node.transform is not None:
                    out.append(node.transform)
            if self.root.animation is not None:
                out.append(self.root.animation)
            if self.overlay is not None:
                out.append(self.overlay)
            return out

    def get_image(self) -> None:  # pinocchio checks that the viewer can capture images
        raise NotImplementedError("image capture is not available in a preview")


def _new_viewer(window: _SceneWindow) -> meshcat.Visualizer:
    return meshcat.Visualizer(window=window)


def _build(
    window: _SceneWindow, content: PreviewContent, *, robot: _RobotView, fps: float, with_robot: bool = True
) -> None:
    viewer = _new_viewer(window)
    if with_robot:
        robot.load(viewer, content)
        _setup_view(viewer, robot.floor_height(content.configurations(np.array([0.0]))[0]))
    _draw_human(viewer, content)
    _draw_prediction(viewer, content)
    _draw_label(viewer, content)
    _animate(viewer, robot, content, fps)
    window.set_overlay(overlay_state(content))


# ----------------------------------------------------------------------------------------------
# HTML page

_PAGE_CSS = """
body { margin: 0; font-family: "DejaVu Sans", Arial, sans-serif; }
#meshcat-pane { width: 100vw; height: 100vh; overflow: hidden; }
#ipromp-overlay { position: absolute; top: 8px; left: 8px; max-width: 360px; padding: 8px 12px;
  background: rgba(255,255,255,0.88); border-radius: 6px; font-size: 13px; color: #222;
  box-shadow: 0 1px 4px rgba(0,0,0,0.25); }
#ipromp-overlay h1 { font-size: 15px; margin: 0 0 6px 0; }
#ipromp-task { font-size: 16px; margin-bottom: 6px; }
#ipromp-posterior { border-collapse: collapse; width: 100%; margin-bottom: 6px; }
#ipromp-posterior td { padding: 1px 4px; white-space: nowrap; }
#ipromp-posterior tr.winner td { font-weight: bold; }
.ipromp-bar { display: inline-block; height: 9px; background: #1f77b4; }
#ipromp-feasibility { list-style: none; padding: 0; margin: 4px 0; }
#ipromp-feasibility li.pass::before { content: "\\2714  "; color: #2ca02c; }
#ipromp-feasibility li.fail::before { content: "\\2718  "; color: #d62728; }
#ipromp-feasibility li.fail { color: #d62728; }
.ipromp-swatch { display: inline-block; width: 10px; height: 10px; margin-right: 4px; }
#ipromp-legend div, #ipromp-hint { font-size: 11px; color: #444; }
"""

_OVERLAY_JS = r"""
function iprompEl(tag, attrs, text) {
  const e = document.createElement(tag);
  for (const k in (attrs || {})) e.setAttribute(k, attrs[k]);
  if (text !== undefined) e.textContent = text;
  return e;
}
function iprompRender(s) {
  const root = document.getElementById("ipromp-overlay");
  root.replaceChildren();
  root.appendChild(iprompEl("h1", {id: "ipromp-title"}, s.title));
  const task = iprompEl("div", {id: "ipromp-task"}, "Recognised task: ");
  task.appendChild(iprompEl("b", {id: "ipromp-task-name"}, s.task || "(none)"));
  root.appendChild(task);
  if (s.tasks.length) {
    const table = iprompEl("table", {id: "ipromp-posterior"});
    s.tasks.forEach((name, i) => {
      const p = s.posterior.length ? s.posterior[i] : NaN;
      const row = iprompEl("tr", {"data-task": name, "class": name === s.task ? "winner" : ""});
      row.appendChild(iprompEl("td", {}, name));
      const bar = iprompEl("td");
      const fill = iprompEl("span", {"class": "ipromp-bar"});
      fill.style.width = (isNaN(p) ? 0 : Math.round(120 * p)) + "px";
      bar.appendChild(fill);
      row.appendChild(bar);
      row.appendChild(iprompEl("td", {"class": "ipromp-p"}, isNaN(p) ? "?" : p.toFixed(3)));
      table.appendChild(row);
    });
    root.appendChild(table);
  }
  if (s.observed) {
    const pct = s.observed.duration_s > 0 ? Math.round(100 * s.observed.until_s / s.observed.duration_s) : 0;
    root.appendChild(iprompEl("div", {id: "ipromp-observed"},
      "Observed: " + s.observed.until_s.toFixed(2) + " s of " + s.observed.duration_s.toFixed(2) +
      " s (" + pct + " %)"));
  }
  if (s.feasibility.length) {
    const list = iprompEl("ul", {id: "ipromp-feasibility"});
    for (const c of s.feasibility) {
      list.appendChild(iprompEl("li", {"class": c.passed ? "pass" : "fail"},
        c.name + (c.detail ? ": " + c.detail : "")));
    }
    root.appendChild(list);
  }
  if (s.collision_links.length) {
    root.appendChild(iprompEl("div", {}, "In collision (red): " + s.collision_links.join(", ")));
  }
  if (s.near_limit_joints.length) {
    root.appendChild(iprompEl("div", {}, "Near a joint limit (orange): " + s.near_limit_joints.join(", ")));
  }
  const legend = iprompEl("div", {id: "ipromp-legend"});
  for (const item of s.legend) {
    const row = iprompEl("div");
    const sw = iprompEl("span", {"class": "ipromp-swatch"});
    sw.style.background = item.color;
    row.appendChild(sw);
    row.appendChild(document.createTextNode(item.label));
    legend.appendChild(row);
  }
  root.appendChild(legend);
  root.appendChild(iprompEl("div", {id: "ipromp-hint"}, "Play / pause / scrub: Open Controls > Animations"));
}
(function () {
  const original = viewer.handle_command.bind(viewer);
  viewer.handle_command = function (cmd) {
    if (cmd && cmd.type === "ipromp_overlay") { iprompRender(cmd.state); viewer.set_dirty(); return; }
    if (cmd && cmd.type === "ipromp_synced") { window.iprompSynced = cmd.count; return; }
    original(cmd);
  };
})();
"""

_STATIC_LOADER_JS = r"""
(function () {
  const commands = JSON.parse(document.getElementById("ipromp-scene").textContent);
  for (const c of commands) {
    const bin = atob(c);
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    viewer.handle_command_bytearray(bytes);
  }
  window.iprompReady = commands.length;
})();
"""

_LIVE_CONNECT_JS = r"""
viewer.connect((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws");
"""


def _viewer_js() -> str:
    source = _VIEWER_JS_PATH.read_text(encoding="utf-8")
    return source.replace("</script", "<\\/script")


def _page(title: str, body_js: str, data_script: str = "") -> str:
    import html

    return (
        '<!DOCTYPE html>\n<html>\n<head>\n<meta charset="utf-8">\n'
        f"<title>{html.escape(title)}</title>\n<style>{_PAGE_CSS}</style>\n</head>\n<body>\n"
        '<div id="meshcat-pane"></div>\n<div id="ipromp-overlay"></div>\n'
        f"{data_script}"
        f"<script>\n{_viewer_js()}\n</script>\n"
        '<script>\nvar viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));\n'
        f"{_OVERLAY_JS}\n{body_js}\n</script>\n</body>\n</html>\n"
    )


def render_html(
    content: PreviewContent, *, max_triangles: int = DEFAULT_MAX_TRIANGLES, fps: float = 30.0
) -> str:
    """Self-contained HTML page (viewer script, scene and panel inline; no network) of ``content``."""
    if fps <= 0:
        raise _err("fps", f"must be > 0, got {fps}")
    window = _SceneWindow()
    _build(window, content, robot=_RobotView(content, max_triangles), fps=fps)
    encoded = [base64.b64encode(c).decode("ascii") for c in window.commands()]
    data = f'<script type="application/json" id="ipromp-scene">{json.dumps(encoded)}</script>\n'
    return _page(content.title, _STATIC_LOADER_JS, data)


def write_html(
    content: PreviewContent,
    path: str | Path,
    *,
    max_triangles: int = DEFAULT_MAX_TRIANGLES,
    fps: float = 30.0,
) -> Path:
    """Write the offline preview of ``content`` as ONE self-contained HTML file; returns its path.

    The page needs no server and no network: open it in any browser with WebGL. With the default
    ``max_triangles`` Baxter's page is about 3.7 MB (1.4 MB gzipped).
    """
    path = Path(path)
    text = render_html(content, max_triangles=max_triangles, fps=fps)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


# ----------------------------------------------------------------------------------------------
# Live server (127.0.0.1 only)


def _check_loopback(host: str) -> str:
    name = "127.0.0.1" if host == "localhost" else host
    try:
        address = ipaddress.ip_address(name)
    except ValueError as exc:
        raise _err("host", f"'{host}' is not an IP address") from exc
    if not address.is_loopback:
        raise _err("host", f"the live preview only listens on a loopback address, not '{host}'")
    return str(address)


class LivePreview:
    """Preview served on the loopback interface, updatable while a recognition streams.

    Example::

        with LivePreview(content, port=7000) as live:
            print(live.url)
            live.update_posterior(posterior, task="handover_cup")

    Attributes:
        url: Address of the page, ``http://127.0.0.1:<port>/``.
        port: Port the server listens on.
        content: Content currently shown.
    """

    def __init__(
        self,
        content: PreviewContent,
        *,
        host: str = "127.0.0.1",
        port: int = 7000,
        max_triangles: int = DEFAULT_MAX_TRIANGLES,
        fps: float = 30.0,
        port_attempts: int = 50,
    ) -> None:
        self.host = _check_loopback(host)
        self.content = content
        self.fps = float(fps)
        self._window = _SceneWindow()
        self._robot = _RobotView(content, max_triangles)
        _build(self._window, content, robot=self._robot, fps=self.fps)
        self._clients: set = set()
        self._loop = None
        self._server = None
        self._thread: threading.Thread | None = None
        self._sockets = self._bind(port, port_attempts)
        self.port = int(self._sockets[0].getsockname()[1])
        self.url = (
            f"http://{self.host}:{self.port}/"
            if ":" not in self.host
            else f"http://[{self.host}]:{self.port}/"
        )
        self._start()

    # -- server ---------------------------------------------------------------------------------
    def _bind(self, port: int, attempts: int) -> list:
        import tornado.netutil

        if port == 0:
            return tornado.netutil.bind_sockets(0, address=self.host)
        last: OSError | None = None
        for candidate in range(port, port + max(1, attempts)):
            try:
                return tornado.netutil.bind_sockets(candidate, address=self.host)
            except OSError as exc:
                last = exc
        raise _err("port", f"no free port in [{port}, {port + attempts}) on {self.host}: {last}")

    def _start(self) -> None:
        import tornado.httpserver
        import tornado.ioloop
        import tornado.web
        import tornado.websocket

        preview = self
        page = _page(self.content.title, _LIVE_CONNECT_JS).encode("utf-8")

        class PageHandler(tornado.web.RequestHandler):
            def get(self) -> None:
                self.set_header("Content-Type", "text/html; charset=utf-8")
                self.set_header("Cache-Control", "no-store")
                self.write(page)

        class NoIconHandler(tornado.web.RequestHandler):
            def get(self) -> None:
                self.set_status(204)

        class SocketHandler(tornado.websocket.WebSocketHandler):
            def open(self) -> None:
                preview._on_open(self)

            def on_close(self) -> None:
                preview._clients.discard(self)

            def on_message(self, message: Any) -> None:  # the viewer only sends image captures
                pass

        ready = threading.Event()

        def run() -> None:
            asyncio.set_event_loop(asyncio.new_event_loop())
            self._loop = tornado.ioloop.IOLoop.current()
            app = tornado.web.Application(
                [(r"/", PageHandler), (r"/favicon.ico", NoIconHandler), (r"/ws", SocketHandler)]
            )
            self._server = tornado.httpserver.HTTPServer(app)
            self._server.add_sockets(self._sockets)
            ready.set()
            self._loop.start()
            self._loop.close(all_fds=True)

        self._thread = threading.Thread(target=run, name=f"ipromp-preview-{self.port}", daemon=True)
        self._thread.start()
        ready.wait()
        self._window.listener = self._forward

    def _on_open(self, socket: Any) -> None:
        with self._window.lock:
            commands = self._window.commands()
            self._clients.add(socket)
        for data in commands:
            socket.write_message(data, binary=True)
        socket.write_message(umsgpack.packb({"type": "ipromp_synced", "count": len(commands)}), binary=True)

    def _forward(self, data: bytes) -> None:
        if self._loop is not None:
            self._loop.add_callback(self._broadcast, data)

    def _broadcast(self, data: bytes) -> None:
        import tornado.websocket

        for socket in list(self._clients):
            try:
                socket.write_message(data, binary=True)
            except tornado.websocket.WebSocketClosedError:
                self._clients.discard(socket)

    @property
    def running(self) -> bool:
        """Whether the server thread is running."""
        return self._thread is not None and self._thread.is_alive()

    @property
    def n_clients(self) -> int:
        """Number of connected browser pages."""
        return len(self._clients)

    def close(self, timeout_s: float = 5.0) -> None:
        """Stop the server, close every connection and the listening socket (idempotent)."""
        if self._thread is None:
            return
        loop, server = self._loop, self._server
        self._window.listener = None

        def stop() -> None:
            for socket in list(self._clients):
                socket.close()
            self._clients.clear()
            server.stop()
            loop.stop()

        loop.add_callback(stop)
        self._thread.join(timeout_s)
        self._thread = None

    def __enter__(self) -> LivePreview:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- updates --------------------------------------------------------------------------------
    def show(self, content: PreviewContent) -> None:
        """Show new content (same robot model): redraws everything but the robot meshes' geometry."""
        self.content = content
        _build(self._window, content, robot=self._robot, fps=self.fps)

    def _redraw(
        self,
        content: PreviewContent,
        *,
        human: bool = False,
        prediction: bool = False,
        label: bool = False,
        animation: bool = False,
        paint: bool = False,
    ) -> None:
        self.content = content
        viewer = _new_viewer(self._window)
        if paint:
            self._robot.paint(viewer, content)
        if human:
            _draw_human(viewer, content)
        if prediction:
            _draw_prediction(viewer, content)
        if label:
            _draw_label(viewer, content)
        if animation:
            _animate(viewer, self._robot, content, self.fps)
        self._window.set_overlay(overlay_state(content))

    def update_posterior(
        self, posterior: np.ndarray, *, task: str | None = None, tasks: Sequence[str] | None = None
    ) -> None:
        """New task posterior (K,); ``task`` defaults to the most probable one."""
        tasks = tuple(self.content.tasks if tasks is None else tasks)
        posterior = _as_array(posterior, "posterior", 1)
        if task is None and len(tasks) == posterior.size:
            task = tasks[int(np.argmax(posterior))]
        content = self.content.replace(posterior=posterior, tasks=tasks, task=task or "")
        self._redraw(content, label=True)

    def update_observation(
        self,
        observed_until_s: float,
        *,
        hand_path: np.ndarray | None = None,
        hand_t_s: np.ndarray | None = None,
        hand_observed_index: int | None = None,
    ) -> None:
        """New end of the observed window in [s] (and optionally a new/extended hand path)."""
        changes: dict[str, Any] = {
            "observed_until_s": observed_until_s,
            "hand_observed_index": hand_observed_index,
        }
        if hand_path is not None:
            changes.update(hand_path=hand_path, hand_t_s=hand_t_s)
        self._redraw(self.content.replace(**changes), human=True, animation=hand_path is not None)

    def update_prediction(
        self,
        t_s: np.ndarray,
        q: np.ndarray,
        *,
        ee_mean: np.ndarray | None = None,
        ee_samples: np.ndarray | None = None,
        ee_std: np.ndarray | None = None,
        handover_point: np.ndarray | None = None,
    ) -> None:
        """New predicted robot trajectory (N,) [s], (N, J) [rad] and end-effector path (M, 3) [m]."""
        content = self.content.replace(
            t_s=t_s,
            q=q,
            ee_mean=ee_mean,
            ee_samples=ee_samples,
            ee_std=ee_std,
            handover_point=self.content.handover_point if handover_point is None else handover_point,
        )
        self._redraw(content, prediction=True, animation=True, human=True)

    def update_feasibility(
        self,
        feasibility: Sequence[FeasibilityCheck | tuple],
        *,
        collision_links: Sequence[str] = (),
        near_limit_joints: Sequence[str] = (),
    ) -> None:
        """New feasibility results; recolours the robot's failing links."""
        content = self.content.replace(
            feasibility=feasibility, collision_links=collision_links, near_limit_joints=near_limit_joints
        )
        self._redraw(content, paint=True)


def serve_preview(
    content: PreviewContent,
    *,
    port: int = 7000,
    max_triangles: int = DEFAULT_MAX_TRIANGLES,
    duration_s: float | None = None,
    print_fn: Any = print,
) -> None:
    """Serve ``content`` on 127.0.0.1 and print the URL; blocks until Ctrl-C (or ``duration_s``)."""
    import time

    with LivePreview(content, port=port, max_triangles=max_triangles) as live:
        print_fn(f"Preview at {live.url} (Ctrl-C to stop)")
        try:
            if duration_s is None:
                while True:
                    time.sleep(1.0)
            else:
                time.sleep(duration_s)
        except KeyboardInterrupt:
            pass
