"""A planned or commanded joint trajectory re-evaluated independently of the planner's checks.

The arm's URDF is read as it is through Pinocchio (not the package's robot model,
:mod:`ipromp_pin.robot.model`): a continuous joint is Pinocchio's (cos, sin) joint without position
limits (only checked to be finite), the arm is not placed (its base frame is the URDF's; gravity is
turned into it by the settings' ``[placement] rpy_deg``). From that model:

* **limits**: positions beyond the URDF's position limits [rad], |velocity| over its velocity limits;
* **torques**: inverse dynamics (RNEA) from finite-difference accelerations, minus the settings'
  springs (Baxter's shoulder counterbalance, which the URDF lacks), with the true task's object as a
  point mass at the gripper point (the ``ee`` parent frame plus the tool offset) held during the
  whole motion (the conservative choice: the checks hold it only before or after the hand-over),
  over the URDF's effort limits;
* **self-collision**: the URDF's collision geometry, the SRDF's disabled pairs and the settings'
  ``[checks] disabled_pairs`` removed.

What the planner's checks measure with the whole recording (the human against the recorded human:
:func:`~ipromp_pin.evaluation.scoring.human_measures`) is not repeated here. The tests that
re-evaluate ``run``'s and ``replay``'s written trajectories use the same class.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..robot import add_tool_geometry, add_tool_inertia, load_robot_settings

TORQUE_FRACTION = 0.9
"""Largest |joint torque| / URDF effort limit a plan may need (issue 37's 90 %)."""

GRAVITY_M_S2 = 9.81
"""Gravity [m/s^2] along the scene's -z."""


@dataclass(frozen=True)
class Findings:
    """What the independent re-evaluation found on one trajectory.

    Attributes:
        position_excess_rad: Largest excursion beyond the URDF's position limits [rad] (0: within).
        velocity_ratio: Largest |velocity| / URDF velocity limit.
        torque_ratio: Largest |torque| / URDF effort limit (object held throughout).
        self_collisions: Checked samples in self-collision.
    """

    position_excess_rad: float
    velocity_ratio: float
    torque_ratio: float
    self_collisions: int

    def violations(self) -> list[str]:
        """The names of what is violated: ``limits``, ``torques`` (over :data:`TORQUE_FRACTION`),
        ``self_collision``."""
        out = []
        if self.position_excess_rad > 1e-9 or self.velocity_ratio > 1.0 + 1e-9:
            out.append("limits")
        if self.torque_ratio > TORQUE_FRACTION:
            out.append("torques")
        if self.self_collisions:
            out.append("self_collision")
        return out

    def to_dict(self) -> dict:
        """JSON-serialisable form (rounded)."""
        return {k: round(v, 6) if isinstance(v, float) else v for k, v in asdict(self).items()}


class UrdfArm:
    """A robot settings' URDF model (not the package's robot model) and its arm joints' indices.

    Args:
        name: Robot settings name or file (:func:`~ipromp_pin.robot.load_robot_settings`).
    """

    def __init__(self, name: str | Path) -> None:
        self.settings = s = load_robot_settings(name)
        self.model = pin.buildModelFromUrdf(str(s.urdf_path))
        add_tool_inertia(self.model, s)  # a [tool] the URDF lacks: its mass and volume
        self.names = list(s.arm_joints)
        joints = [self.model.joints[self.model.getJointId(n)] for n in self.names]
        self.idx_q = [j.idx_q for j in joints]
        self.idx_v = [j.idx_v for j in joints]
        self.continuous = [j.nq == 2 for j in joints]  # (cos, sin) joints: no position limits
        if s.placement is not None:  # gravity in the arm's (unplaced) base frame
            turn = pin.rpy.rpyToMatrix(*np.radians(s.placement.rpy_deg))
            self.model.gravity.linear = turn.T @ np.array([0.0, 0.0, -GRAVITY_M_S2])
        self.parent = self.model.getFrameId(s.ee_parent_frame)
        self.offset = s.gripper_point_m  # where the payload is held, in the parent frame's axes
        self._geometry: tuple[pin.GeometryModel, pin.GeometryData] | None = None

    def limit_excess(self, q: np.ndarray, qd: np.ndarray) -> tuple[float, float]:
        """Largest excursion [rad] of ``q`` (N, J) beyond the URDF's position limits (continuous
        joints: infinite when not finite, else 0) and largest |``qd``| / velocity limit."""
        m = self.model
        excess = 0.0 if np.all(np.isfinite(q)) else math.inf
        for k, (iq, cont) in enumerate(zip(self.idx_q, self.continuous, strict=True)):
            if not cont:
                lo, hi = m.lowerPositionLimit[iq], m.upperPositionLimit[iq]
                excess = max(excess, float(np.max(np.maximum(lo - q[:, k], q[:, k] - hi))), 0.0)
        ratio = float(np.max(np.abs(qd) / np.asarray(m.velocityLimit)[self.idx_v]))
        return excess, ratio

    def full(self, q: np.ndarray) -> np.ndarray:
        """Full configurations (N, nq): the arm's joints ``q`` (N, J), the settings' fixed joints."""
        m = self.model
        full = np.tile(pin.neutral(m), (len(q), 1))
        for k, (iq, cont) in enumerate(zip(self.idx_q, self.continuous, strict=True)):
            if cont:
                full[:, iq], full[:, iq + 1] = np.cos(q[:, k]), np.sin(q[:, k])
            else:
                full[:, iq] = q[:, k]
        for name, value in self.settings.fixed_joints.items():
            full[:, m.joints[m.getJointId(name)].idx_q] = value
        return full

    def torque_ratios(
        self, t: np.ndarray, q: np.ndarray, qd: np.ndarray, payload_kg: float = 0.0, step: int = 5
    ) -> np.ndarray:
        """Per joint the largest |torque| / URDF effort limit at every ``step``-th sample (and the
        last) of times ``t`` (N,) [s], positions ``q`` and velocities ``qd`` (N, J): RNEA from
        finite-difference accelerations, minus the settings' springs, with a point mass
        ``payload_kg`` [kg] at the gripper point."""
        model, data = self.model, self.model.createData()
        full = self.full(q)
        qdd = np.gradient(qd, t, axis=0) if len(t) > 1 else np.zeros_like(qd)
        effort = np.asarray(model.effortLimit)[self.idx_v]
        springs = self.settings.spring_torque_nm
        coef = np.array([springs.get(n, (0.0, 0.0)) for n in self.names]).reshape(-1, 2)
        peak = np.zeros(len(self.names))
        for k in sorted(set(range(0, len(t), step)) | {len(t) - 1}):
            v, a = np.zeros(model.nv), np.zeros(model.nv)
            v[self.idx_v], a[self.idx_v] = qd[k], qdd[k]
            tau = pin.rnea(model, data, full[k], v, a)[self.idx_v].copy()
            if payload_kg > 0.0:
                tau += self._payload_torque(data, full[k], v, a, payload_kg)
            tau -= coef[:, 0] + coef[:, 1] * q[k]
            peak = np.maximum(peak, np.abs(tau) / effort)
        return peak

    def _payload_torque(
        self, data: pin.Data, full: np.ndarray, v: np.ndarray, a: np.ndarray, mass_kg: float
    ) -> np.ndarray:
        """Joint torques (J,) [N m] holding a point mass at the gripper point (after :func:`pin.rnea`
        at ``full``, ``v``, ``a``): J^T m (acceleration - gravity), in the world frame."""
        model = self.model
        pin.forwardKinematics(model, data, full, v, a)
        pin.updateFramePlacements(model, data)
        frame = data.oMf[self.parent]
        point = frame.translation + frame.rotation @ self.offset
        jac = pin.computeFrameJacobian(model, data, full, self.parent, pin.LOCAL_WORLD_ALIGNED)
        lever = point - frame.translation
        lin = jac[:3] - np.cross(lever, jac[3:].T).T  # the point's linear Jacobian
        acc = pin.getFrameClassicalAcceleration(model, data, self.parent, pin.LOCAL_WORLD_ALIGNED)
        omega = pin.getFrameVelocity(model, data, self.parent, pin.LOCAL_WORLD_ALIGNED).angular
        alpha = acc.angular
        a_point = acc.linear + np.cross(alpha, lever) + np.cross(omega, np.cross(omega, lever))
        force = mass_kg * (a_point - np.asarray(model.gravity.linear))
        return (lin.T @ force)[self.idx_v]

    def self_collisions(self, q: np.ndarray, step: int = 3) -> int:
        """Configurations among every ``step``-th of ``q`` (N, J) (and the last) in contact of the
        URDF's collision geometry (the SRDF's disabled pairs and the settings' ``disabled_pairs``
        removed)."""
        return self.collisions_full(self.full(q), step)

    def collisions_full(self, full: np.ndarray, step: int = 3) -> int:
        """:meth:`self_collisions` of full configurations ``full`` (N, nq) (:meth:`full`)."""
        geom, gdata = self.geometry()
        m = self.model
        data = m.createData()
        rows = sorted(set(range(0, len(full), step)) | {len(full) - 1})
        return sum(bool(pin.computeCollisions(m, data, geom, gdata, full[k], True)) for k in rows)

    def geometry(self) -> tuple[pin.GeometryModel, pin.GeometryData]:
        """The URDF's collision geometry with its checked pairs (built on first use)."""
        if self._geometry is None:
            s, m = self.settings, self.model
            dirs = [str(d) for d in s.package_dirs]
            geom = pin.buildGeomFromUrdf(m, str(s.urdf_path), pin.COLLISION, package_dirs=dirs)
            geom.addAllCollisionPairs()
            if s.srdf_path is not None:
                pin.removeCollisionPairs(m, geom, str(s.srdf_path))
            add_tool_geometry(m, geom, s, pairs=True)
            listed = {frozenset(p) for p in s.disabled_pairs}
            g = geom.geometryObjects
            for cp in list(geom.collisionPairs):
                if frozenset(m.frames[g[k].parentFrame].name for k in (cp.first, cp.second)) in listed:
                    geom.removeCollisionPair(cp)
            self._geometry = (geom, pin.GeometryData(geom))
        return self._geometry

    def judge(self, t: np.ndarray, q: np.ndarray, qd: np.ndarray, payload_kg: float = 0.0) -> Findings:
        """Every finding on the trajectory of times ``t`` (N,) [s], positions ``q`` (N, J) [rad] and
        velocities ``qd`` (N, J) [rad/s] (see the module docstring)."""
        excess, ratio = self.limit_excess(q, qd)
        torques = self.torque_ratios(t, q, qd, payload_kg)
        return Findings(excess, ratio, float(torques.max()), self.self_collisions(q))
