"""Drawing of a :class:`~ipromp_pin.preview.content.PreviewContent` into a meshcat scene.

The scene is built with Pinocchio's :class:`pinocchio.visualize.MeshcatVisualizer` on a meshcat
viewer whose window is a :class:`~ipromp_pin.preview.recorder.SceneRecorder`:

- the robot's (decimated) visual meshes, failing links coloured (in collision red, moved by a joint
  near its limit orange), playing the arm trajectory in real time as a meshcat animation;
- the human hand path (observed part green, the rest grey), an animated hand marker and the
  hand-over point (gold);
- the human body's capsules and the closest robot-body pair (:mod:`~ipromp_pin.preview.body_scene`),
  moving with the human's motion, and the smallest distance as a label;
- the predicted end-effector path (blue tube), its uncertainty (translucent tube of radius 2 sigma,
  thin sampled paths) and the recorded robot path (purple);
- the recognised task on a text plane above the robot, the background, grid and a camera fitted to
  the scene's bounding box (:func:`camera_view`), so that any robot fills the view;
- the state of the HTML panel (:func:`overlay_state`).

Positions in [m] in the robot's base frame. One clock: the animation runs on the human's motion
(t = 0 at its start), the clock of the content's robot trajectory, hand path, body, separation and
torques; the robot rests at its first configuration until its trajectory starts.
"""

from __future__ import annotations

import warnings
from typing import Any

import coal
import meshcat
import meshcat.animation
import meshcat.geometry as mg
import numpy as np
import pinocchio as pin
from pinocchio.visualize import MeshcatVisualizer

from .body_scene import (
    COLOR_BODY,
    COLOR_BODY_ASSUMED,
    SEPARATION_COLORS,
    body_tracks,
    draw_body,
    separation_panel,
)
from .content import PreviewContent
from .meshes import simplify_visual_model, sphere_mesh, tube_mesh
from .object_scene import COLOR_OBJECT, draw_object, object_placements, object_tracks
from .recorder import SceneRecorder
from .torques import torque_panel
from .tracks import put_transforms, translations

__all__ = [
    "CAMERA_DIRECTION",
    "CAMERA_FOV_DEG",
    "COLOR_COLLISION",
    "COLOR_EE_BAND",
    "COLOR_EE_MEAN",
    "COLOR_EE_TRUTH",
    "COLOR_HANDOVER",
    "COLOR_HAND_OBSERVED",
    "COLOR_HAND_REST",
    "COLOR_NEAR_LIMIT",
    "RobotView",
    "animation_times",
    "scene_animation",
    "build_scene",
    "camera_view",
    "overlay_state",
    "scene_points",
    "update_scene",
]

# Colours (0xRRGGBB) of the scene elements; the HTML legend uses the same values. The two link
# highlights are RGBA in [0, 1] (meshcat's colour property).
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
_CLOSEST_LABEL_NODE = "labels/closest"


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


class RobotView:
    """Pinocchio MeshcatVisualizer of the (decimated) robot inside a meshcat scene.

    Built once per robot (decimating the meshes is the slow part) and reused by every redraw.

    Attributes:
        geometry: Decimated copy of the content's visual (or collision) model.
        visualizer: Pinocchio visualizer drawing ``geometry`` (its viewer is set by :meth:`load`).
    """

    def __init__(self, content: PreviewContent, max_triangles: int) -> None:
        """Decimate ``content``'s visual (else collision) model to about ``max_triangles`` triangles."""
        source = content.visual_model if content.visual_model is not None else content.collision_model
        self.geometry = simplify_visual_model(source, max_triangles)
        self.visualizer = MeshcatVisualizer(content.model, None, self.geometry)
        self._painted: dict[str, tuple] = {}
        self._local_boxes: list[np.ndarray] | None = None

    def load(self, viewer: meshcat.Visualizer, content: PreviewContent) -> None:
        """Send the robot meshes (description colours), paint failing links, show the start pose."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            self.visualizer.initViewer(viewer=viewer)
            self.visualizer.loadViewerModel(rootNodeName=_ROBOT_NODE)
        self._painted = {}
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
        """(4, 4) world placement of every geometry object at full configuration ``q`` (nq,)."""
        viz = self.visualizer
        pin.forwardKinematics(viz.model, viz.data, q)
        pin.updateGeometryPlacements(viz.model, viz.data, self.geometry, viz.visual_data)
        return [viz.visual_data.oMg[i].homogeneous.copy() for i in range(self.geometry.ngeoms)]

    def floor_height(self, q: np.ndarray) -> float:
        """Lowest vertex height in [m] of the robot at configuration ``q``."""
        low = np.inf
        for obj, T in zip(self.geometry.geometryObjects, self.placements(q), strict=True):
            if isinstance(obj.geometry, coal.BVHModelBase):
                v = np.asarray(obj.geometry.vertices())
                low = min(low, float((v @ T[:3, :3].T + T[:3, 3])[:, 2].min()))
        return low if np.isfinite(low) else 0.0

    def corners(self, qs: np.ndarray) -> np.ndarray:
        """(n, 3) world corners in [m] of every geometry's bounding box at the configurations ``qs``
        (k, nq): the robot's extent along a motion (primitives count by their origin)."""
        if self._local_boxes is None:
            boxes = []
            for obj in self.geometry.geometryObjects:
                if isinstance(obj.geometry, coal.BVHModelBase) and obj.geometry.num_vertices:
                    v = np.asarray(obj.geometry.vertices())
                    lo, hi = v.min(axis=0), v.max(axis=0)
                    boxes.append(np.array([[(hi if b else lo)[i] for i, b in enumerate(c)] for c in _CUBE]))
                else:
                    boxes.append(np.zeros((1, 3)))
            self._local_boxes = boxes
        out = []
        for q in np.atleast_2d(qs):
            for box, T in zip(self._local_boxes, self.placements(q), strict=True):
                out.append(box @ T[:3, :3].T + T[:3, 3])
        return np.vstack(out)


_CUBE = [(i & 1, (i >> 1) & 1, (i >> 2) & 1) for i in range(8)]

#: Vertical field of view of meshcat's default camera in [deg] (three.js PerspectiveCamera(75, ...)).
CAMERA_FOV_DEG = 75.0
#: Direction from the scene's centre to the camera, in the robot's base frame: in front of the robot
#: (+x), to its left (+y) and above (+z).
CAMERA_DIRECTION = np.array([2.0, 1.2, 0.8]) / np.linalg.norm([2.0, 1.2, 0.8])
#: The camera direction when the human body is drawn (it stands in front of the robot, +x): from the
#: robot's left side (+y), a little in front and above, the human and the robot side by side.
CAMERA_DIRECTION_BODY = np.array([0.8, -2.0, 0.9]) / np.linalg.norm([0.8, -2.0, 0.9])


def camera_view(
    points: np.ndarray, fov_deg: float = CAMERA_FOV_DEG, direction: np.ndarray = CAMERA_DIRECTION
) -> tuple[np.ndarray, np.ndarray]:
    """Where to look from so that ``points`` (n, 3) [m] fill the view: the centre of their bounding box
    (3,) and the camera position (3,) relative to it, both in the robot's base frame [m].

    The camera is along ``direction`` (a unit vector, :data:`CAMERA_DIRECTION`), at the distance from
    which the bounding box's circumscribed sphere (radius ``R``) spans the vertical field of view
    ``fov_deg`` seen from its centre: ``R / tan(fov / 2)`` (the box's corners, which the sphere
    over-covers, stay in view).
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 0.05)
    distance = radius / np.tan(np.radians(fov_deg) / 2.0)
    return (lo + hi) / 2.0, direction * distance


def scene_points(content: PreviewContent, robot: RobotView, n_poses: int = 5) -> np.ndarray:
    """(n, 3) points in [m] the view must hold: the robot's bounding boxes at ``n_poses`` times of its
    trajectory, the hand path, the predicted and recorded gripper paths and the hand-over point."""
    qs = content.configurations(np.linspace(0.0, content.duration_s, n_poses))
    parts = [robot.corners(qs)]
    for extra in (content.hand_path, content.ee_mean, content.ee_truth, content.handover_point):
        if extra is not None:
            parts.append(np.atleast_2d(extra))
    if content.body is not None:  # the body at the animation's start
        a, b, _ = content.body.at(np.array([0.0]))
        parts += [a[0], b[0]]
    return np.vstack(parts)


def animation_times(end_s: float, fps: float) -> tuple[np.ndarray, float]:
    """The frame times (n,) [s] of an animation from 0 to ``end_s`` [s] at about ``fps`` frames/s, and
    the frame rate that puts its last frame exactly at ``end_s`` (meshcat's frame k is at k / rate):
    the animation's time never runs past the page's last time."""
    n_frames = max(2, int(np.ceil(end_s * fps - 1e-9)) + 1)
    if end_s <= 0.0:
        return np.arange(n_frames) / fps, fps
    return np.linspace(0.0, end_s, n_frames), (n_frames - 1) / end_s


def _animate(viewer: meshcat.Visualizer, robot: RobotView, content: PreviewContent, fps: float) -> None:
    """Meshcat animation of the scene in real time at about ``fps`` frames/s (:func:`scene_animation`),
    from 0 to the page's last time (:attr:`PreviewContent.end_s`)."""
    times, rate = animation_times(content.end_s, fps)
    viewer.set_animation(scene_animation(viewer, robot, content, times, rate), play=True, repetitions=1)


def scene_animation(
    viewer: meshcat.Visualizer, robot: RobotView, content: PreviewContent, times: np.ndarray, rate: float
) -> meshcat.animation.Animation:
    """The animation of the robot's moving links, the hand marker, the body, the closest-pair rod and
    the held object, frame ``k`` at the human's time ``times[k]`` [s] (one clock: the content's
    ``t_s``, ``hand_t_s``, body, separation and torque tracks are the human's), ``rate`` frames/s.
    Every node's frames are put at once (:mod:`.tracks`)."""
    frames = list(range(times.size))
    placements = np.array([robot.placements(q) for q in content.configurations(times)])  # (K, nodes, 4, 4)
    names = [
        robot.visualizer.getViewerNodeName(o, pin.GeometryType.VISUAL) for o in robot.geometry.geometryObjects
    ]
    still = np.isclose(placements, placements[:1], rtol=1e-5, atol=1e-9).all(axis=(0, 2, 3))
    animation = meshcat.animation.Animation(default_framerate=rate)
    for i in np.flatnonzero(~still):
        put_transforms(animation, viewer[names[i]].path, frames, placements[:, i])
    if content.hand_path is not None and content.hand_t_s is not None:
        hand = np.stack([np.interp(times, content.hand_t_s, content.hand_path[:, d]) for d in range(3)], -1)
        put_transforms(animation, viewer["human/hand"].path, frames, translations(hand))
    body_tracks(animation, viewer, content.body, content.separation, times)
    obj = content.held_object
    if obj is not None:
        object_tracks(animation, viewer, object_placements(content, obj, times), obj.held(times))
    return animation


def _draw_human(viewer: meshcat.Visualizer, content: PreviewContent) -> None:
    for name in _HUMAN_NODES:
        viewer[name].delete()
    if content.hand_path is not None:
        path = content.hand_path
        n_obs = content.hand_observed_count()
        if n_obs is None:
            _set_mesh(viewer["human/rest"], tube_mesh(path, 0.006), COLOR_HAND_REST, 0.8)
        else:
            if n_obs >= 1:
                _set_mesh(viewer["human/observed"], tube_mesh(path[:n_obs], 0.009), COLOR_HAND_OBSERVED)
            if n_obs < len(path):
                rest = path[max(0, n_obs - 1) :]
                _set_mesh(viewer["human/rest"], tube_mesh(rest, 0.006), COLOR_HAND_REST, 0.8)
        if content.hand_t_s is not None:
            _set_mesh(viewer["human/hand"], sphere_mesh(np.zeros(3), 0.03), COLOR_HAND_OBSERVED, 0.9)
            T = np.eye(4)
            T[:3, 3] = [np.interp(0.0, content.hand_t_s, path[:, d]) for d in range(3)]
            viewer["human/hand"].set_transform(T)
    if content.handover_point is not None:
        _set_mesh(viewer["human/handover"], sphere_mesh(content.handover_point, 0.035), COLOR_HANDOVER)
    draw_body(viewer, content.body, content.separation, 0.0)
    _draw_closest_label(viewer, content)


def _draw_closest_label(viewer: meshcat.Visualizer, content: PreviewContent) -> None:
    """The report's smallest clearance (the first reported figure of the separation, e.g. the
    approach's ``human_clearance``) as text beside its pair at its sample; without one, the smallest
    per-sample distance, marked as not in the report."""
    node = viewer[_CLOSEST_LABEL_NODE]
    node.delete()
    sep = content.separation
    if sep is None:
        return
    figure = sep.reported[0] if sep.reported else None
    if figure is not None:
        i = int(np.argmin(np.abs(sep.t_s - figure.t_s)))
        text = f"{figure.value * 1e3:.0f} mm ({figure.check})"
    else:
        i = sep.closest
        text = f"{sep.distance_m[i] * 1e3:.0f} mm (not in the report)"
    position = (sep.robot_point_m[i] + sep.body_point_m[i]) / 2.0 + np.array([0.0, 0.0, 0.08])
    node.set_object(_text_plane(text))
    node.set_transform(_plane_facing_x(position, 0.22))


def _draw_prediction(viewer: meshcat.Visualizer, content: PreviewContent) -> None:
    for name in _PREDICTION_NODES:
        viewer[name].delete()
    if content.ee_mean is not None:
        _set_mesh(viewer["prediction/mean"], tube_mesh(content.ee_mean, 0.006), COLOR_EE_MEAN)
        if content.ee_std is not None:
            # Radius: 2 sigma of the root-mean-square per-axis standard deviation.
            radius = 2.0 * np.sqrt(np.mean(content.ee_std**2, axis=1))
            _set_mesh(
                viewer["prediction/band"],
                tube_mesh(content.ee_mean, np.maximum(radius, 0.007), 16),
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
        _set_mesh(viewer["prediction/truth"], tube_mesh(content.ee_truth, 0.005), COLOR_EE_TRUTH)


def _task_label(content: PreviewContent) -> str:
    if not content.task:
        return "task: (none)"
    if content.posterior is not None and content.task in content.tasks:
        p = float(content.posterior[content.tasks.index(content.task)])
        return f"{content.label_prefix}{content.task} ({p:.2f})"
    return content.label_prefix + content.task


def _draw_label(viewer: meshcat.Visualizer, content: PreviewContent, robot: RobotView) -> None:
    """The task label on a plane above the robot (at its start pose), sized to the robot."""
    corners = robot.corners(content.configurations(np.array([0.0])))
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    size = float(np.clip(0.33 * np.max(hi - lo), 0.2, 1.0))
    position = np.array([hi[0] - 0.25 * (hi[0] - lo[0]), (lo[1] + hi[1]) / 2.0, hi[2] + 0.1 * size])
    node = viewer[_LABEL_NODE]
    node.set_object(_text_plane(_task_label(content)))
    node.set_transform(_plane_facing_x(position, size))


def _setup_view(
    viewer: meshcat.Visualizer, floor_z: float, points: np.ndarray, direction: np.ndarray = CAMERA_DIRECTION
) -> None:
    """Background, floor grid and a camera fitted to the scene ``points`` (n, 3) [m].

    meshcat's orbit controls turn around the world origin, so the scene (everything under
    ``/meshcat``) is moved to put the centre of its bounding box there, and the camera is placed
    by :func:`camera_view` (in three.js coordinates, x, z, -y).
    """
    viewer["/Background"].set_property("top_color", [0.97, 0.97, 0.98])
    viewer["/Background"].set_property("bottom_color", [0.78, 0.80, 0.84])
    center, eye = camera_view(points, direction=direction)
    shift = np.eye(4)
    shift[:3, 3] = -center
    viewer["/meshcat"].set_transform(shift)
    # The grid on the floor under the robot; hidden by default (software WebGL draws its lines
    # badly), "Open Controls > Grid" shows it.
    T = np.eye(4)
    T[:3, 3] = [-center[0], -center[1], floor_z - center[2]]
    viewer["/Grid"].set_transform(T)
    viewer["/Grid"].set_property("visible", False)
    viewer["/Axes"].set_property("visible", False)
    viewer["/Cameras/default/rotated/<object>"].set_property("position", [eye[0], eye[2], -eye[1]])


def overlay_state(content: PreviewContent) -> dict[str, Any]:
    """JSON-serialisable state of the HTML panel (task, posterior, observation, feasibility, legend)."""
    posterior = [] if content.posterior is None else [float(p) for p in content.posterior]
    observed = None
    if content.observed_until_s is not None:
        # Of the HUMAN's motion (its recorded or predicted duration), never of the robot trajectory.
        observed = {
            "until_s": content.observed_until_s,
            "human_duration_s": content.human_duration_s,
            "source": content.human_duration_source,
            "fraction": content.observed_fraction(),
        }
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
    legend += _body_legend(content)
    if content.held_object is not None:
        o = content.held_object
        legend.append(
            {"label": f"{o.name} ({o.mass_kg:g} kg), drawn while held", "color": f"#{COLOR_OBJECT:06x}"}
        )
    return {
        "title": content.title,
        "task": content.task,
        "tasks": list(content.tasks),
        "posterior": posterior,
        "observed": observed,
        "robot_duration_s": content.duration_s,
        "end_s": content.end_s,
        "timebase": content.timebase,
        "notes": [str(n) for n in content.notes],
        "feasibility": [
            {
                "name": c.name,
                "passed": c.passed,
                "status": c.status,
                "required": c.required,
                "detail": c.detail,
            }
            for c in content.checks
        ],
        "collision_links": list(content.collision_links),
        "near_limit_joints": list(content.near_limit_joints),
        "legend": legend,
        "separation": None
        if content.separation is None
        else separation_panel(content.separation, content.body),
        "torques": None if content.torques is None else torque_panel(content.torques),
    }


def _body_legend(content: PreviewContent) -> list[dict[str, str]]:
    """Legend lines of the body's capsules and of the closest-pair rod's states."""
    out = []
    if content.body is not None:
        assumed = content.body.assumed
        color = COLOR_BODY_ASSUMED if assumed else COLOR_BODY
        label = "human body (assumed, no skeleton)" if assumed else "human body (tracked)"
        if content.body.label:
            label = f"human body: {content.body.label}"
        out.append({"label": label, "color": f"#{color:06x}"})
    if content.separation is not None:
        names = {"within_sp": "within S_p", "speed_limited": "speed-limited"}
        out += [
            {"label": f"closest robot-body pair: {names.get(s, s)}", "color": f"#{c:06x}"}
            for s, c in SEPARATION_COLORS.items()
        ]
    return out


def _new_viewer(window: SceneRecorder) -> meshcat.Visualizer:
    return meshcat.Visualizer(window=window)


def build_scene(window: SceneRecorder, content: PreviewContent, *, robot: RobotView, fps: float) -> None:
    """Draw the whole scene of ``content`` into ``window``: robot, view, human, prediction, label,
    animation at ``fps`` frames/s, and the HTML panel's state."""
    viewer = _new_viewer(window)
    robot.load(viewer, content)
    _setup_view(
        viewer,
        robot.floor_height(content.configurations(np.array([0.0]))[0]),
        scene_points(content, robot),
        CAMERA_DIRECTION if content.body is None else CAMERA_DIRECTION_BODY,
    )
    _draw_human(viewer, content)
    _draw_prediction(viewer, content)
    _draw_label(viewer, content, robot)
    _draw_object(viewer, content)
    _animate(viewer, robot, content, fps)
    window.set_overlay(overlay_state(content))


def _draw_object(viewer: meshcat.Visualizer, content: PreviewContent) -> None:
    """The held object at the animation's start (its pose and visibility then follow the animation)."""
    obj = content.held_object
    pose = None if obj is None else object_placements(content, obj, np.array([0.0]))[0]
    held = obj is not None and bool(obj.held(np.array([0.0]))[0])
    draw_object(viewer, obj, pose, held)


def update_scene(
    window: SceneRecorder,
    content: PreviewContent,
    *,
    robot: RobotView,
    fps: float,
    human: bool = False,
    prediction: bool = False,
    label: bool = False,
    animation: bool = False,
    paint: bool = False,
) -> None:
    """Redraw only some parts of the scene of ``content`` in ``window``, then the HTML panel's state.

    Args:
        window: Recorder holding the scene (built by :func:`build_scene`).
        content: Content to show.
        robot: Robot view the scene was built with.
        fps: Frames per second of the animation.
        human: Redraw the hand path, hand marker, hand-over point, body and closest-pair rod.
        prediction: Redraw the predicted, sampled and recorded end-effector paths.
        label: Redraw the task label.
        animation: Recompute the animation (robot and hand marker).
        paint: Recolour the robot's failing links (colour properties only).
    """
    viewer = _new_viewer(window)
    if paint:
        robot.paint(viewer, content)
    if human:
        _draw_human(viewer, content)
    if prediction:
        _draw_prediction(viewer, content)
    if label:
        _draw_label(viewer, content, robot)
    if animation:
        _draw_object(viewer, content)
        _animate(viewer, robot, content, fps)
    window.set_overlay(overlay_state(content))
