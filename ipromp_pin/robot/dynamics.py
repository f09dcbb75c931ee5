"""Inverse dynamics of the arm along a timed motion (Pinocchio RNEA), with an object in the gripper.

:class:`ArmDynamics` reduces the robot's model to its arm joints (every other joint locked at its held
value, which leaves the arm's torques unchanged: the other bodies are not moved by the arm) and, for a
payload (:class:`~ipromp_pin.robot.objects.TaskObject`), adds the object's inertia to the body of the
gripper frame's joint. Torques of many samples are computed in one call of Pinocchio's
``rneaInParallel`` (one thread; ~3 us per sample for Baxter's arm instead of ~7 us per ``pin.rnea``
call from Python), or a loop of ``pin.rnea`` where that is not built in.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .model import Robot
from .objects import TaskObject

GRAVITY_M_S2 = 9.81
"""The gravity of Pinocchio's models [m/s^2] (along -z of the base frame)."""


def payload_key(payload: TaskObject) -> tuple:
    """What identifies a payload's dynamics: mass, centre of mass and inertia (not the object's id,
    which Python reuses once an object is freed)."""
    return (
        float(payload.mass_kg),
        *np.asarray(payload.com_m, float).tolist(),
        *payload.inertia_kg_m2.ravel().tolist(),
    )


class ArmDynamics:
    """Joint torques of the arm of ``robot``, with or without an object in the gripper.

    The torques are what the motors deliver: Pinocchio's RNEA minus the torque of the joints' springs
    (``[springs]`` of the robot settings: Baxter's shoulder s1 counterbalance, which the URDF lacks).

    Args:
        robot: The loaded robot.
        springs: Subtract the settings' spring torques (False: the plain RNEA torques).

    Attributes:
        model_: The arm-only Pinocchio model (n_joints degrees of freedom).
        effort_limit_nm: The URDF's effort limits of the arm joints (n_joints,) in [N m].
    """

    def __init__(self, robot: Robot, springs: bool = True) -> None:
        self.robot = robot
        self.springs = springs
        full = robot.model
        arm = {int(j) for j in robot.arm_joint_ids}
        locked = [j for j in range(1, full.njoints) if j not in arm]
        self.model_ = pin.buildReducedModel(full, locked, robot.q_neutral) if locked else pin.Model(full)
        names = [self.model_.names[j] for j in range(1, self.model_.njoints)]
        if tuple(names) != robot.joint_names:
            raise ValueError(f"reduced model joints {names} differ from the arm's {robot.joint_names}")
        self.effort_limit_nm = np.asarray(self.model_.effortLimit, dtype=float).copy()
        frame = self.model_.frames[self.model_.getFrameId(robot.settings.ee_parent_frame)]
        self.gripper_joint_ = int(frame.parentJoint)
        # where the gripper holds the object: the tool centre point of a [tool], else the frame itself
        self.gripper_placement_ = frame.placement * pin.SE3(np.eye(3), robot.settings.gripper_point_m)
        coef = robot.settings.spring_torque_nm if springs else {}
        self.spring_ = np.array([coef.get(n, (0.0, 0.0)) for n in robot.joint_names]).reshape(-1, 2)
        self._models: dict[tuple, tuple[pin.Model, pin.Data, object]] = {}

    def payload_model(self, payload: TaskObject | None) -> pin.Model:
        """The arm model with ``payload`` attached to the gripper frame (``None``: the bare arm)."""
        return self._entry(payload)[0]

    def _entry(self, payload: TaskObject | None) -> tuple[pin.Model, pin.Data, object]:
        key: tuple = () if payload is None else payload_key(payload)
        if key not in self._models:
            model = pin.Model(self.model_)
            if payload is not None and payload.mass_kg > 0:
                body = pin.Inertia(
                    float(payload.mass_kg), np.asarray(payload.com_m, float), payload.inertia_kg_m2
                )
                j = self.gripper_joint_
                model.inertias[j] = model.inertias[j] + self.gripper_placement_.act(body)
            pool = pin.ModelPool(model, 1) if hasattr(pin, "rneaInParallel") else None
            self._models[key] = (model, model.createData(), pool)
        return self._models[key]

    def torques(
        self,
        q: np.ndarray,
        qd: np.ndarray | None = None,
        qdd: np.ndarray | None = None,
        payload: TaskObject | None = None,
        held: np.ndarray | None = None,
    ) -> np.ndarray:
        """Joint torques (N, n_joints) in [N m] that realise the motion (RNEA).

        Args:
            q: Positions (N, n_joints) in [rad].
            qd: Velocities (N, n_joints) in [rad/s] (``None``: at rest).
            qdd: Accelerations (N, n_joints) in [rad/s^2] (``None``: zero; with ``qd`` None too, the
                gravity torques).
            payload: The object in the gripper, or ``None``.
            held: (N,) bool, the samples at which the gripper holds ``payload`` (``None``: all).
        """
        q = np.atleast_2d(np.asarray(q, dtype=float))
        qd = np.zeros_like(q) if qd is None else np.atleast_2d(np.asarray(qd, dtype=float))
        qdd = np.zeros_like(q) if qdd is None else np.atleast_2d(np.asarray(qdd, dtype=float))
        if payload is None or payload.mass_kg <= 0:
            return self._rnea(None, q, qd, qdd)
        mask = np.ones(q.shape[0], dtype=bool) if held is None else np.asarray(held, dtype=bool)
        out = np.empty_like(q)
        if mask.any():
            out[mask] = self._rnea(payload, q[mask], qd[mask], qdd[mask])
        if (~mask).any():
            out[~mask] = self._rnea(None, q[~mask], qd[~mask], qdd[~mask])
        return out

    def inverse_dynamics(self, payload: TaskObject | None = None):
        """A function ``(q, qd, qdd) -> tau`` of one sample ((n_joints,) each, [rad], [rad/s],
        [rad/s^2] -> [N m]), e.g. for toppra's ``JointTorqueConstraint``."""
        model, data, _ = self._entry(payload)

        c0, c1 = self.spring_[:, 0], self.spring_[:, 1]

        def inv_dyn(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
            return np.array(pin.rnea(model, data, q, qd, qdd)) - (c0 + c1 * q)

        return inv_dyn

    def spring_torques(self, q: np.ndarray) -> np.ndarray:
        """The springs' torques (N, n_joints) in [N m] at positions ``q`` (N, n_joints) [rad]."""
        return self.spring_[:, 0] + self.spring_[:, 1] * np.atleast_2d(q)

    def _rnea(self, payload: TaskObject | None, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        return self._plain_rnea(payload, q, qd, qdd) - self.spring_torques(q)

    def _plain_rnea(
        self, payload: TaskObject | None, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray
    ) -> np.ndarray:
        model, data, pool = self._entry(payload)
        n = q.shape[0]
        if pool is not None and n > 1:
            tau = np.zeros((model.nv, n), order="F")
            pin.rneaInParallel(
                1, pool, np.asfortranarray(q.T), np.asfortranarray(qd.T), np.asfortranarray(qdd.T), tau
            )
            return tau.T.copy()
        return np.array([pin.rnea(model, data, q[i], qd[i], qdd[i]) for i in range(n)]).reshape(n, model.nv)
