"""The robot's moving collision geometry as capsules, placed and moved along a joint motion.

Every geometry of the robot's collision model (the one of the self-collision check,
:meth:`~ipromp_pin.robot.Robot.collision`) that the arm moves is enclosed, once per robot, in a
capsule fixed to its arm joint's frame: a cylinder or capsule by itself (same axis and radius), a
sphere by itself, a box by a capsule along its longest axis whose radius is the half-diagonal of the
other two, any other geometry by the capsule of its local bounding box. Each capsule contains its
geometry, so a distance to it never over-states the distance to the robot.

:func:`arm_kinematics` is the arm's forward kinematics for many samples at once (numpy, no loop over
samples): the origin and axis of every arm joint (N, n_joints, 3) and each capsule's end points. The
velocity of a point ``x`` carried by arm joint ``k`` is the arm's point Jacobian times ``qd``,
``v(x) = sum_{i<=k} qd_i z_i x (x - o_i)`` (:func:`point_velocities`); it equals Pinocchio's
``getFrameJacobian`` at that point times ``qd`` (tests/human/test_robot_capsules.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..robot import Robot
from .kernels import human_kernels


@dataclass(frozen=True)
class RobotCapsules:
    """Capsules enclosing the robot's moving collision geometries.

    Attributes:
        names: Geometry names (L,).
        links: Their links (parent frame names) (L,).
        anchor: Index (L,) of the arm joint (0..n_joints-1) that carries each capsule.
        a_local: First end point (L, 3) [m] in the anchor joint's frame.
        b_local: Second end point (L, 3) [m] in the anchor joint's frame.
        radius_m: Radii (L,) [m].
        base: Placement (4, 4) of the first arm joint's parent frame at zero arm angles... as the
            constant transforms below: ``x0`` (n_joints, 4, 4) from the previous arm joint's frame
            (the world for the first) to arm joint ``k``'s frame at zero angle.
        axis_local: Joint axes (n_joints, 3) in their own frames.
    """

    names: tuple[str, ...]
    links: tuple[str, ...]
    anchor: np.ndarray
    a_local: np.ndarray
    b_local: np.ndarray
    radius_m: np.ndarray
    x0: np.ndarray
    axis_local: np.ndarray

    @property
    def n_capsules(self) -> int:
        """Number of capsules L."""
        return int(self.radius_m.size)


def _geometry_capsule(obj: pin.GeometryObject) -> tuple[np.ndarray, np.ndarray, float]:
    """End points (3,), (3,) in the geometry's own frame and radius of a capsule enclosing it."""
    geom = obj.geometry
    kind = type(geom).__name__
    if kind in ("Cylinder", "Capsule"):
        h = float(geom.halfLength)
        return np.array([0.0, 0.0, -h]), np.array([0.0, 0.0, h]), float(geom.radius)
    if kind == "Sphere":
        return np.zeros(3), np.zeros(3), float(geom.radius)
    if kind == "Box":
        half = np.asarray(geom.halfSide, dtype=float)
        centre = np.zeros(3)
    else:
        geom.computeLocalAABB()
        lo = np.asarray(geom.aabb_local.min_, dtype=float)
        hi = np.asarray(geom.aabb_local.max_, dtype=float)
        half, centre = (hi - lo) / 2.0, (hi + lo) / 2.0
    k = int(np.argmax(half))
    other = np.delete(half, k)
    axis = np.zeros(3)
    axis[k] = half[k]
    return centre - axis, centre + axis, float(np.linalg.norm(other))


def fit_robot_capsules(robot: Robot) -> RobotCapsules:
    """The capsules of ``robot``'s collision geometries that the arm moves (see the module docstring)."""
    model = robot.model
    cmodel, _ = robot.collision()
    data = model.createData()
    q0 = robot.full_configuration(np.zeros(robot.n_joints))
    pin.forwardKinematics(model, data, q0)
    arm = [int(j) for j in robot.arm_joint_ids]
    x0 = np.empty((len(arm), 4, 4))
    prev = pin.SE3.Identity()
    axes = np.empty((len(arm), 3))
    for k, j in enumerate(arm):
        x0[k] = (prev.inverse() * data.oMi[j]).homogeneous
        prev = data.oMi[j]
        jac = pin.computeJointJacobian(model, data, q0, j)  # in joint j's own frame
        axes[k] = jac[3:, model.joints[j].idx_v]
    names, links, anchor, a_loc, b_loc, radius = [], [], [], [], [], []
    for obj in cmodel.geometryObjects:
        support = [int(s) for s in model.supports[obj.parentJoint]]
        carried = [k for k, j in enumerate(arm) if j in support]
        if not carried:
            continue  # not moved by the arm
        k = carried[-1]
        a, b, r = _geometry_capsule(obj)
        # geometry frame -> anchor joint frame (joints between them are held at their values)
        to_anchor = data.oMi[arm[k]].inverse() * data.oMi[obj.parentJoint] * obj.placement
        names.append(obj.name)
        links.append(model.frames[obj.parentFrame].name)
        anchor.append(k)
        a_loc.append(to_anchor.act(a))
        b_loc.append(to_anchor.act(b))
        radius.append(r)
    return RobotCapsules(
        tuple(names),
        tuple(links),
        np.asarray(anchor, dtype=int),
        np.asarray(a_loc),
        np.asarray(b_loc),
        np.asarray(radius),
        x0,
        axes,
    )


def arm_kinematics(
    caps: RobotCapsules, q: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Joint origins and world axes (N, n_joints, 3) and capsule end points (N, L, 3) [m] along
    arm joint angles ``q`` (N, n_joints) [rad] (the robot's held joints at their settings values)."""
    q = np.ascontiguousarray(np.atleast_2d(np.asarray(q, dtype=float)))
    return human_kernels().arm_frames(q, caps.x0, caps.axis_local, caps.anchor, caps.a_local, caps.b_local)


def point_velocities(
    origins: np.ndarray, axes: np.ndarray, qd: np.ndarray, points: np.ndarray, anchor: np.ndarray
) -> np.ndarray:
    """Velocities (M, 3) [m/s] of points (M, 3) carried by arm joints ``anchor`` (M,), at samples
    whose joint origins / axes (M, n_joints, 3) and velocities ``qd`` (M, n_joints) [rad/s] are given."""
    nj = origins.shape[1]
    upto = np.arange(nj)[None, :] <= anchor[:, None]  # (M, n_joints)
    lever = points[:, None, :] - origins  # (M, n_joints, 3)
    cols = np.cross(axes, lever) * upto[..., None]
    return np.einsum("mkj,mk->mj", cols, qd)


def point_jacobians(
    origins: np.ndarray, axes: np.ndarray, points: np.ndarray, anchor: np.ndarray
) -> np.ndarray:
    """Linear Jacobians (M, 3, n_joints) [m/rad] of points (M, 3) carried by arm joints ``anchor``."""
    nj = origins.shape[1]
    upto = np.arange(nj)[None, :] <= anchor[:, None]
    cols = np.cross(axes, points[:, None, :] - origins) * upto[..., None]  # (M, n_joints, 3)
    return np.transpose(cols, (0, 2, 1))
