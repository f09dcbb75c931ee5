"""ISO/TS 15066:2016 limits: the protective separation distance and the contact-speed limit.

The ISO/TS's content is now part of ISO 10218-2:2025; the clause and table numbers here are the
ISO/TS's, where the values were read (their place in ISO 10218-2:2025 is not verified:
``docs/safety.md``, *The standards and their editions*).

* Speed and separation monitoring (clause 5.5.4, formula (1)): the protective separation distance
  ``S_p = S_h + S_r + S_s + C + Z_d + Z_r``, with ``S_h = v_h (T_r + T_s)`` the human's motion while
  the robot reacts and stops (``v_h`` = 1.6 m/s, ISO 13855's K, unless measured), ``S_r = v_r T_r`` the
  robot's motion during its reaction time, ``S_s = v_r T_s / 2`` its stopping distance at a constant
  deceleration, ``C`` the intrusion distance and ``Z_d``, ``Z_r`` the position uncertainties of the
  human and the robot (:func:`protective_distance_m`).
* Power and force limiting (clause 5.5.5, Annex A.3): a transient contact transfers the kinetic
  energy ``E = mu v^2 / 2`` of the relative motion into the body region's spring ``E = F^2 / (2 k)``,
  so the contact force stays at most ``F_max`` when ``v <= v_max = F_max / sqrt(mu k)``, ``mu`` the
  reduced mass ``1 / mu = 1 / m_H + 1 / m_R`` of the body region and of the robot
  (:func:`max_contact_speed_m_s`). The robot's effective mass at a contact point in a direction ``u``
  is ``m_R = 1 / (u^T J M^-1 J^T u)`` (``J``: the point's linear Jacobian, ``M``: the arm's
  joint-space inertia matrix from Pinocchio's CRBA, solved by Cholesky; :func:`effective_mass_kg`).

The values of the body regions (Table A.2 forces, Table A.3 spring constants and effective masses)
are in :data:`ipromp_pin.robot.human_settings.REGION_LIMITS`; the sources are in ``docs/safety.md``.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from ..robot import Robot
from ..robot.human_settings import HumanSettings, RegionLimit
from .kernels import human_kernels


def protective_distance_m(robot_speed_m_s: np.ndarray | float, settings: HumanSettings) -> np.ndarray:
    """S_p in [m] for the robot's speed toward the human ``v_r`` [m/s] (negative: moving away, taken
    as 0), clause 5.5.4 with the settings' ``v_h``, ``T_r``, ``T_s``, ``C``, ``Z_d``, ``Z_r``."""
    v_r = np.maximum(np.asarray(robot_speed_m_s, dtype=float), 0.0)
    t_r, t_s = settings.reaction_time_s, settings.stopping_time_s
    s_h = settings.speed_m_s * (t_r + t_s)
    return s_h + v_r * t_r + v_r * t_s / 2.0 + constant_distance_m(settings)


def constant_distance_m(settings: HumanSettings) -> float:
    """The part of S_p that does not depend on the robot's speed, ``C + Z_d + Z_r`` [m]."""
    return settings.intrusion_m + settings.human_uncertainty_m + settings.robot_uncertainty_m


def reduced_mass_kg(human_kg: np.ndarray | float, robot_kg: np.ndarray | float) -> np.ndarray:
    """The two-body reduced mass ``mu = (1/m_H + 1/m_R)^-1`` in [kg]."""
    m_h = np.asarray(human_kg, dtype=float)
    m_r = np.asarray(robot_kg, dtype=float)
    return 1.0 / (1.0 / m_h + 1.0 / m_r)


def region_force_n(limit: RegionLimit, contact: str = "transient") -> float:
    """The permissible force [N] of a body region for a ``"transient"`` or ``"quasi_static"`` contact."""
    return limit.force_n * (limit.transient_factor if contact == "transient" else 1.0)


def max_contact_speed_m_s(
    limit: RegionLimit, robot_kg: np.ndarray | float, contact: str = "transient"
) -> np.ndarray:
    """``v_max = F_max / sqrt(mu k)`` in [m/s] for a body region and the robot's effective mass(es)
    [kg] (Annex A.3.2, formula (A.6) with the energy of (A.3))."""
    mu = reduced_mass_kg(limit.mass_kg, robot_kg)
    return region_force_n(limit, contact) / np.sqrt(mu * limit.spring_n_m)


def speed_bound_any_robot_m_s(limit: RegionLimit, contact: str = "transient") -> float:
    """The contact-speed limit for an infinitely heavy robot (``mu = m_H``), in [m/s]: a lower bound
    of :func:`max_contact_speed_m_s` for every robot mass."""
    return region_force_n(limit, contact) / math.sqrt(limit.mass_kg * limit.spring_n_m)


def arm_mass_matrix(robot: Robot, q_arm: np.ndarray, data: pin.Data | None = None) -> np.ndarray:
    """The arm's joint-space inertia matrix (n_joints, n_joints) in [kg m^2] at arm angles ``q_arm``
    [rad] (Pinocchio's CRBA on the full model, restricted to the arm: the other joints are held)."""
    data = data if data is not None else robot.model.createData()
    m = pin.crba(robot.model, data, robot.full_configuration(np.asarray(q_arm, dtype=float)))
    m = np.triu(m) + np.triu(m, 1).T
    v = robot.arm_v_index
    return m[np.ix_(v, v)]


def arm_model(robot: Robot) -> pin.Model:
    """The arm alone: ``robot``'s model with every other joint locked at its held value (Pinocchio's
    ``buildReducedModel``), so that its CRBA gives the arm's inertia (n_joints, n_joints) directly."""
    arm = {int(j) for j in robot.arm_joint_ids}
    lock = [j for j in range(1, robot.model.njoints) if j not in arm]
    return pin.buildReducedModel(robot.model, lock, robot.q_neutral)


class ArmInertia:
    """The arm's joint-space inertia at many configurations: its reduced model (:func:`arm_model`),
    a Pinocchio ``Data`` for its CRBA and, when the model is a serial chain of revolute joints, the
    parameters of the compiled CRBA (:func:`chain_parameters`), built once.

    Args:
        robot: The loaded robot.
        model: The arm's reduced model (built here when None).

    Attributes:
        model: The arm's reduced model.
        data: Its ``Data`` (CRBA overwrites what it fills).
        chain: Its chain parameters, or None (then only Pinocchio's CRBA runs).
    """

    def __init__(self, robot: Robot, model: pin.Model | None = None) -> None:
        self.model = model if model is not None else arm_model(robot)
        self.data = self.model.createData()
        self.chain = chain_parameters(self.model)
        self._lower = np.tril_indices(self.model.nv, -1)  # the strict lower triangle CRBA leaves

    def mass_matrices(self, q_arm: np.ndarray, compiled: bool = False) -> np.ndarray:
        """The inertia (S, n_joints, n_joints) [kg m^2] at every row of ``q_arm`` (S, n_joints)
        [rad]: Pinocchio's CRBA; ``compiled``: with the compiled human kernels and a chain, the
        compiled CRBA of the chain instead (equal to Pinocchio's to rounding, 1e-14, not to the bit:
        for bounds, see :mod:`.separation_summary`)."""
        q = np.atleast_2d(np.asarray(q_arm, dtype=float))
        kernels = human_kernels()
        if compiled and self.chain is not None and hasattr(kernels, "chain_mass_matrices"):
            return kernels.chain_mass_matrices(np.ascontiguousarray(q), *self.chain)
        model, data, lower = self.model, self.data, self._lower
        out = np.empty((q.shape[0], model.nv, model.nv))
        for i, row in enumerate(q):
            out[i] = pin.crba(model, data, row)  # the upper triangle is filled
        out[:, lower[0], lower[1]] = out[:, lower[1], lower[0]]
        return out


def arm_mass_matrices(
    robot: Robot, q_arm: np.ndarray, model: pin.Model | None = None, compiled: bool = False
) -> np.ndarray:
    """:func:`arm_mass_matrix` at every row of ``q_arm`` (S, n_joints) -> (S, n_joints, n_joints)
    (``model``: the arm's reduced model, :func:`arm_model`, built here when None; ``compiled``: see
    :meth:`ArmInertia.mass_matrices`, which a caller of many calls should hold instead)."""
    return ArmInertia(robot, model).mass_matrices(q_arm, compiled)


def chain_parameters(model: pin.Model) -> tuple[np.ndarray, ...] | None:
    """A reduced arm model as a serial chain of revolute joints for the compiled CRBA
    (:func:`~ipromp_pin.human.separation_kernels.chain_mass_matrices`): each joint's placement
    (n, 4, 4) in its parent's frame, its axis (n, 3) in its own frame, its body's mass (n,) [kg],
    centre of mass (n, 3) [m] and inertia about it (n, 3, 3) [kg m^2]; None when the model is not
    such a chain (then Pinocchio's CRBA runs)."""
    n = model.njoints - 1
    axes = {"JointModelRX": (1.0, 0.0, 0.0), "JointModelRY": (0.0, 1.0, 0.0), "JointModelRZ": (0.0, 0.0, 1.0)}
    kinds = [model.joints[j].shortname() for j in range(1, model.njoints)]
    chain: tuple[np.ndarray, ...] | None = None
    if (
        model.nq == n
        and model.nv == n
        and all(k in axes for k in kinds)
        and all(int(model.parents[j]) == j - 1 for j in range(1, model.njoints))
    ):
        chain = (
            np.array([model.jointPlacements[j].homogeneous for j in range(1, n + 1)]),
            np.array([axes[k] for k in kinds]),
            np.array([model.inertias[j].mass for j in range(1, n + 1)]),
            np.array([np.asarray(model.inertias[j].lever) for j in range(1, n + 1)]),
            np.array([np.asarray(model.inertias[j].inertia) for j in range(1, n + 1)]),
        )
    return chain


def effective_mass_kg(
    mass_matrix: np.ndarray, jacobian: np.ndarray, direction: np.ndarray, payload_mass_kg: float = 0.0
) -> float:
    """The robot's effective mass [kg] at a point in a direction: ``1 / (u^T J M^-1 J^T u)``.

    Args:
        mass_matrix: The arm's joint-space inertia (n, n) [kg m^2] (SPD).
        jacobian: The point's linear Jacobian (3, n) [m/rad].
        direction: The direction ``u`` (3,) (normalised here).
        payload_mass_kg: Hook for a held object: a point mass at the contact point adds exactly its
            mass to the effective mass there (Sherman-Morrison); a rigidly held object elsewhere
            belongs in the model's inertia instead.
    """
    u = np.asarray(direction, dtype=float)
    u = u / np.linalg.norm(u)
    w = np.asarray(jacobian, dtype=float).T @ u
    lower = np.linalg.cholesky(np.asarray(mass_matrix, dtype=float))
    y = forward_substitution(lower, w[:, None])[:, 0]
    inv = float(y @ y)
    return (math.inf if inv <= 0.0 else 1.0 / inv) + float(payload_mass_kg)


def point_effective_mass_kg(
    robot: Robot,
    q_arm: np.ndarray,
    joint: int,
    point_m: np.ndarray,
    direction: np.ndarray,
    payload_mass_kg: float = 0.0,
) -> float:
    """:func:`effective_mass_kg` at ``point_m`` (3,) [m, base frame] carried by the model joint id
    ``joint``, from Pinocchio's joint Jacobian (``LOCAL_WORLD_ALIGNED``) and CRBA."""
    model, data = robot.model, robot.model.createData()
    q = robot.full_configuration(np.asarray(q_arm, dtype=float))
    pin.computeJointJacobians(model, data, q)
    pin.forwardKinematics(model, data, q)
    jac = pin.getJointJacobian(model, data, int(joint), pin.LOCAL_WORLD_ALIGNED)
    lever = np.asarray(point_m, dtype=float) - data.oMi[int(joint)].translation
    lin = jac[:3] - np.cross(lever, jac[3:].T).T  # v_p = v_o + w x (p - o)
    return effective_mass_kg(
        arm_mass_matrix(robot, q_arm, data), lin[:, robot.arm_v_index], direction, payload_mass_kg
    )


def forward_substitution(lower: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``y`` with ``L y = rhs`` for a lower-triangular ``L`` (n, n) and ``rhs`` (n, K): the half of a
    Cholesky solve the effective mass needs (``u^T J M^-1 J^T u = |L^-1 J^T u|^2``), vectorised over
    the K columns."""
    y = np.empty_like(rhs, dtype=float)
    for i in range(lower.shape[0]):
        y[i] = (rhs[i] - lower[i, :i] @ y[:i]) / lower[i, i]
    return y
