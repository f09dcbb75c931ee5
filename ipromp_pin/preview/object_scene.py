"""Drawing the task's object in the gripper into a meshcat scene.

The object of a :class:`~ipromp_pin.preview.torques.HeldObject` is one node (:data:`OBJECT_NODE`)
placed at its frame's pose in every animation frame (:func:`object_placements`, Pinocchio's frame
kinematics of the content's configurations), with the shape (a box, a cylinder along its axis, or a
small sphere) as its child ``shape`` placed at the object's centre in that frame; the shape is
visible only while the robot holds the object (:meth:`~ipromp_pin.preview.torques.HeldObject.held`
at the human's time).
"""

from __future__ import annotations

import meshcat
import meshcat.animation as ma
import meshcat.geometry as mg
import numpy as np
import pinocchio as pin

from .content import PreviewContent, preview_error
from .torques import HeldObject
from .tracks import put_property, put_transforms

__all__ = [
    "COLOR_OBJECT",
    "OBJECT_NODE",
    "draw_object",
    "object_tracks",
    "object_placements",
    "shape_transform",
]

OBJECT_NODE = "object/held"
"""Scene path of the held object (its shape is the child ``shape``)."""
COLOR_OBJECT = 0xB5651D
"""Colour of the held object."""


def shape_transform(obj: HeldObject) -> np.ndarray:
    """(4, 4) placement of the shape's meshcat geometry in the object's frame: at ``center_m``, a
    cylinder's axis (meshcat's local y) turned onto ``obj.axis``."""
    T = np.eye(4)
    T[:3, 3] = obj.center_m
    if obj.kind == "cylinder" and obj.axis == 0:  # y -> x: -90 deg about z
        T[:3, :3] = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    elif obj.kind == "cylinder" and obj.axis == 2:  # y -> z: +90 deg about x
        T[:3, :3] = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    return T


def _geometry(obj: HeldObject) -> mg.Geometry:
    d = obj.dims_m
    if obj.kind == "box":
        return mg.Box(list(d))
    if obj.kind == "cylinder":
        return mg.Cylinder(d[1], d[0])
    return mg.Sphere(d[0])


def object_placements(content: PreviewContent, obj: HeldObject, times_s: np.ndarray) -> np.ndarray:
    """(K, 4, 4) world poses of the object's frame at the animation's times ``times_s`` (K,) [s]."""
    model = content.model
    if not model.existFrame(obj.frame):
        raise preview_error("held_object.frame", f"frame '{obj.frame}' is not in the robot model")
    fid = model.getFrameId(obj.frame)
    data = model.createData()
    out = []
    for q in content.configurations(np.asarray(times_s, dtype=float)):
        pin.framesForwardKinematics(model, data, q)
        out.append(data.oMf[fid].homogeneous.copy())
    return np.array(out).reshape(-1, 4, 4)


def draw_object(
    viewer: meshcat.Visualizer, obj: HeldObject | None, pose: np.ndarray | None, held: bool
) -> None:
    """(Re)draw the object (``None``: remove it) at the frame pose ``pose`` (4, 4), shown if ``held``."""
    viewer[OBJECT_NODE].delete()
    if obj is None:
        return
    material = mg.MeshLambertMaterial(color=COLOR_OBJECT)
    viewer[f"{OBJECT_NODE}/shape"].set_object(_geometry(obj), material)
    viewer[f"{OBJECT_NODE}/shape"].set_transform(shape_transform(obj))
    if pose is not None:
        viewer[OBJECT_NODE].set_transform(pose)
    viewer[f"{OBJECT_NODE}/shape"].set_property("visible", bool(held))


def object_tracks(
    animation: ma.Animation, viewer: meshcat.Visualizer, poses: np.ndarray, held: np.ndarray
) -> None:
    """Pose the object in every frame of ``animation`` at its frame's poses ``poses`` (K, 4, 4); its
    visibility ``held`` (K,) set in the first frame and where it changes."""
    frames = list(range(poses.shape[0]))
    put_transforms(animation, viewer[OBJECT_NODE].path, frames, poses)
    held = np.asarray(held, dtype=bool)
    keys = [0, *(np.flatnonzero(held[1:] != held[:-1]) + 1).tolist()]
    shape = viewer[f"{OBJECT_NODE}/shape"].path
    put_property(animation, shape, "visible", "boolean", keys, [bool(held[k]) for k in keys])
