"""The assumed human against the robot's fixed links: a robot settings file whose assumed human
(``[human.assumed]``) intersects the robot where it does not move is refused.

The fixed links are the collision geometries of the robot's collision model (the one of the
self-collision check) that the planned arm does not move: Baxter's pedestal, torso, head, sonar ring
and the other arm at its held configuration (``[fixed_joints]``). Each is taken as its convex hull
(a mesh is only its triangles: a body wholly inside the pedestal would be at a positive distance from
them), a sphere, cylinder or box as itself. The body is the assumed human's capsules
(:meth:`~ipromp_pin.human.HumanMotion.assumed_human`: its standing pose at the placement, the
settings' radii, no inflation). Distances are coal's (GJK/EPA: negative when the two overlap, by the
penetration depth). The planned arm is not checked here: it moves, and the human checks of every
plan judge it.

:func:`check_assumed_human` raises; :func:`assumed_human_overlaps` lists what intersects.
"""

from __future__ import annotations

from dataclasses import dataclass

import coal
import numpy as np
import pinocchio as pin

from ..robot import Robot
from ..robot.settings import settings_error
from .body import HumanMotion

_HULLS: dict[tuple[str, str], object] = {}
"""(URDF path, geometry name) -> the convex hull of a mesh geometry, built once."""


@dataclass(frozen=True)
class Overlap:
    """A body part of the assumed human inside a fixed link of the robot.

    Attributes:
        part: Body part name (e.g. ``chest``).
        link: The robot's link (frame) of the geometry (e.g. ``pedestal``).
        geometry: The collision geometry's name.
        depth_m: Penetration depth in [m] (> 0).
    """

    part: str
    link: str
    geometry: str
    depth_m: float


def _convex(robot: Robot, obj: pin.GeometryObject) -> object:
    """The geometry itself (a primitive) or its convex hull (a mesh), built once per robot file."""
    geom = obj.geometry
    if not hasattr(geom, "buildConvexHull"):
        return geom
    key = (str(robot.settings.urdf_path), obj.name)
    if key not in _HULLS:
        copy = geom.clone()
        copy.buildConvexHull(False, "Qt")
        _HULLS[key] = copy.convex
    return _HULLS[key]


def _fixed_geometries(robot: Robot) -> list[tuple[pin.GeometryObject, pin.SE3]]:
    """The collision geometries the arm does not move, with their placements at the held configuration."""
    model = robot.model
    cmodel, _ = robot.collision()
    data = model.createData()
    gdata = pin.GeometryData(cmodel)
    pin.updateGeometryPlacements(model, data, cmodel, gdata, robot.q_neutral)
    arm = {int(j) for j in robot.arm_joint_ids}
    out = []
    for k, obj in enumerate(cmodel.geometryObjects):
        if arm.isdisjoint(int(s) for s in model.supports[obj.parentJoint]):
            out.append((obj, gdata.oMg[k]))
    return out


def _capsule(a: np.ndarray, b: np.ndarray, radius: float) -> tuple[object, coal.Transform3s]:
    """A coal capsule (or sphere) from ``a`` to ``b`` (3,) [m] of ``radius`` [m], and its placement."""
    axis = b - a
    length = float(np.linalg.norm(axis))
    if length < 1e-9:
        return coal.Sphere(radius), coal.Transform3s(np.eye(3), a)
    z = axis / length
    rot = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), z).matrix()
    return coal.Capsule(radius, length / 2.0), coal.Transform3s(rot, (a + b) / 2.0)


def assumed_human_overlaps(robot: Robot) -> list[Overlap]:
    """Every (body part, fixed geometry) pair of ``robot`` and its settings' assumed human that
    intersects, deepest first."""
    human = HumanMotion.assumed_human(robot.settings.human)
    a, b, r = human.capsules_at(0.0)
    parts = [_capsule(a[k], b[k], float(r[k])) for k in range(human.n_parts)]
    request = coal.DistanceRequest()
    found = []
    for obj, placement in _fixed_geometries(robot):
        shape = _convex(robot, obj)
        where = coal.Transform3s(placement.rotation, placement.translation)
        for k, (capsule, at) in enumerate(parts):
            result = coal.DistanceResult()
            d = coal.distance(shape, where, capsule, at, request, result)
            if d < 0.0:
                link = robot.model.frames[obj.parentFrame].name
                found.append(Overlap(str(human.part_names[k]), link, obj.name, -float(d)))
    return sorted(found, key=lambda o: -o.depth_m)


def check_assumed_human(robot: Robot) -> None:
    """Refuse ``robot``'s settings when their assumed human intersects a fixed link of the robot.

    Raises:
        RobotError: ``FILE: field 'human.assumed.torso_m': ...`` naming every intersecting pair
            (body part in link, depth), deepest first.
    """
    overlaps = assumed_human_overlaps(robot)
    if not overlaps:
        return
    placement = robot.settings.human.placement
    pairs = ", ".join(f"{o.part} in {o.link} ({o.depth_m * 100:.1f} cm deep)" for o in overlaps)
    torso = ", ".join(f"{v:g}" for v in placement.torso_m)
    raise settings_error(
        robot.settings.path,
        "human.assumed.torso_m",
        f"the assumed human (torso at [{torso}] m, facing {placement.facing_deg:g} deg) intersects the "
        f"robot's fixed links: {pairs}; place it clear of the robot",
    )
