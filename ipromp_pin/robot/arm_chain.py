"""An arm as a serial chain of revolute joints, for the compiled inverse and forward kinematics of its
``ee`` frame (:mod:`ipromp_pin.robot.ik_kernels`), which are the kernel set ``"ik"`` of the package's
one kernel switch (:mod:`ipromp_pin.promp.compiled`, which registers the set by name).

:func:`arm_chain` reads the chain from the Pinocchio model once per robot: each arm joint's frame in
the previous one's at zero angle (the first in the scene frame, so the ``[placement]`` is in it; every
other joint held at its settings value), its axis, and the ``ee`` frame in the last joint's frame. It
checks the chain against Pinocchio's forward kinematics at a few configurations and gives None for an
arm that is not such a chain (a prismatic or multi-valued joint, a branch): Pinocchio's solver then
runs. The set's "numpy" version is that Pinocchio solver (:class:`~ipromp_pin.robot.arm_transfer
.PoseSolver`, the reference the compiled one is tested against): :func:`ik_kernels` gives the compiled
module when the backend is ``"numba"`` (or ``"auto"`` found it compiled) and None otherwise, or when
numba cannot be imported or fails to compile the kernels (then once per process, announced).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from types import ModuleType
from typing import Any

import numpy as np
import pinocchio as pin

from .kinematics import as_joint_path, frame_placements
from .model import Robot

__all__ = [
    "ArmChain",
    "arm_chain",
    "chain_placements",
    "ik_kernels",
    "ik_kernels_cached",
    "kernel_failed",
    "run_compiled",
]

CHECK_TOL = 1e-9
"""Largest difference [m], [rad] between the chain's and Pinocchio's ``ee`` pose at which the chain is
used."""

_chains: dict[int, tuple[weakref.ref, ArmChain | None]] = {}
_failed: dict[str, str] = {}


@dataclass(frozen=True)
class ArmChain:
    """An arm's serial chain of revolute joints up to its ``ee`` frame.

    Attributes:
        x0: (n, 4, 4) each joint's frame in the previous joint's at zero angle (the first: in the
            model's world frame, the scene frame of a placed arm).
        axis: (n, 3) each joint's unit axis in its own frame.
        ee: (4, 4) the ``ee`` frame in the last joint's frame.
    """

    x0: np.ndarray
    axis: np.ndarray
    ee: np.ndarray


def arm_chain(robot: Robot) -> ArmChain | None:
    """``robot``'s chain (read once per robot), None when the arm is not a serial revolute chain."""
    key = id(robot)
    cached = _chains.get(key)
    if cached is not None and cached[0]() is robot:
        return cached[1]
    chain = _read_chain(robot)
    _chains[key] = (weakref.ref(robot), chain)
    return chain


def _read_chain(robot: Robot) -> ArmChain | None:
    model = robot.model
    data = model.createData()
    arm = [int(j) for j in robot.arm_joint_ids]
    for k, j in enumerate(arm):
        joint = model.joints[j]
        if joint.nq != 1 or joint.nv != 1 or not joint.shortname().startswith("JointModelR"):
            return None  # prismatic or multi-valued (e.g. an unbounded continuous joint)
        if k and arm[k - 1] not in [int(s) for s in model.supports[j]]:
            return None  # not one chain
    frame = model.frames[robot.ee_frame_id]
    if arm[-1] not in [int(s) for s in model.supports[frame.parentJoint]]:
        return None
    full = robot.full_configuration(np.zeros(robot.n_joints))
    pin.forwardKinematics(model, data, full)
    x0 = np.empty((len(arm), 4, 4))
    axes = np.empty((len(arm), 3))
    prev = pin.SE3.Identity()
    for k, j in enumerate(arm):
        x0[k] = (prev.inverse() * data.oMi[j]).homogeneous
        prev = data.oMi[j]
        axes[k] = pin.computeJointJacobian(model, data, full, j)[3:, model.joints[j].idx_v]
    ee = (prev.inverse() * pin.updateFramePlacement(model, data, robot.ee_frame_id)).homogeneous
    chain = ArmChain(np.ascontiguousarray(x0), np.ascontiguousarray(axes), np.ascontiguousarray(ee))
    return chain if _matches(robot, chain) else None


def _matches(robot: Robot, chain: ArmChain) -> bool:
    """Whether the chain's ``ee`` pose is Pinocchio's at the limits' middle and two fixed random
    configurations (numpy forward kinematics: no compile needed)."""
    rng = np.random.default_rng(0)
    lo, hi = robot.lower_rad, robot.upper_rad
    for q in (0.5 * (lo + hi), rng.uniform(lo, hi), rng.uniform(lo, hi)):
        full = robot.full_configuration(q)
        pin.forwardKinematics(robot.model, robot.data, full)
        ref = pin.updateFramePlacement(robot.model, robot.data, robot.ee_frame_id)
        mine = np.eye(4)
        for k in range(q.size):
            mine = mine @ chain.x0[k]
            mine[:3, :3] = mine[:3, :3] @ pin.exp3(chain.axis[k] * q[k])
        mine = mine @ chain.ee
        if not (
            np.allclose(mine[:3, 3], ref.translation, rtol=0.0, atol=CHECK_TOL)
            and np.allclose(mine[:3, :3], ref.rotation, rtol=0.0, atol=CHECK_TOL)
        ):
            return False
    return True


def ik_kernels() -> ModuleType | None:
    """The compiled kernels when the switch chooses them for set ``"ik"`` (None: Pinocchio's solver,
    also when numba is missing or failed to compile them in this process)."""
    if _failed:
        return None
    from ..promp import compiled  # deferred: importing the robot package does not import the model's

    if compiled.active_backend(compiled.IK) != "numba":
        return None
    try:
        return compiled.kernels(compiled.IK)
    except ImportError as exc:  # numba missing or broken: the reference solver for this process
        kernel_failed(exc)
        return None


def kernel_failed(exc: BaseException) -> None:
    """Record that the compiled kernels failed (``exc``): Pinocchio's solver from now on, announced
    once through the switch's announcer."""
    from ..promp import compiled

    if not _failed:
        _failed["why"] = f"{type(exc).__name__}: {exc}".splitlines()[0]
        compiled.announce(
            f"[kernels] the inverse-kinematics kernels failed ({_failed['why']}): retargeting uses "
            "Pinocchio's solver in this process"
        )


def ik_kernels_cached() -> bool:
    """Whether numba's on-disk cache holds machine code of every kernel of the set ``"ik"``."""
    from ..promp import compiled

    return compiled.kernels_cached(compiled.IK)


def run_compiled(name: str, *args: Any) -> Any:
    """Kernel ``name`` of the compiled set called with ``args``; None when the set is not in use or
    numba fails to compile it (recorded: the reference solver for the rest of the process)."""
    module = ik_kernels()
    if module is None:
        return None
    try:
        return getattr(module, name)(*args)
    except Exception as exc:
        from numba.core.errors import NumbaError

        if not isinstance(exc, NumbaError):
            raise
        kernel_failed(exc)
        return None


def chain_placements(robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~ipromp_pin.robot.kinematics.frame_placements` of the ``ee`` frame along ``q`` (M, n)
    [rad] (positions (M, 3) [m], rotations (M, 3, 3)), compiled when the chain and the kernels are."""
    chain = arm_chain(robot)
    if chain is not None:
        path = np.ascontiguousarray(as_joint_path(robot, q))
        out = run_compiled("chain_fk", path, chain.x0, chain.axis, chain.ee)
        if out is not None:
            return out
    return frame_placements(robot, q)
