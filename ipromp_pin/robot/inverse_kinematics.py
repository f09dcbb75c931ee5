"""Inverse kinematics of the arm's end-effector frame: damped least squares from a seed configuration.

Each iteration linearises the end-effector error with Pinocchio's frame Jacobian (arm joints only;
every other joint at its settings value) and takes the damped least-squares step
``dq = J^T (J J^T + lambda^2 I)^-1 e`` (a Cholesky solve), then clips the arm to its position
limits shrunk by the settings' margin. For a position-only target the error is the position
difference in the base frame; for a full pose it is ``log6`` of the remaining transform, in the
end-effector frame, with the Jacobian of ``log6``. A redundant arm (Baxter has 7 joints) stays close
to the seed, so seeding with a predicted configuration gives the solution nearest to the prediction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.linalg import cho_factor, cho_solve

from ..exceptions import InfeasibleError
from .model import Robot


@dataclass(frozen=True)
class IKResult:
    """Outcome of :func:`solve_ik`.

    Attributes:
        q: (n_joints,) arm joint angles in [rad] (the last iterate when not converged).
        position_error_m: Remaining end-effector position error in [m].
        rotation_error_rad: Remaining orientation error in [rad] (0 for a position-only target).
        iterations: Iterations taken.
        converged: Whether both errors are within the tolerances.
    """

    q: np.ndarray
    position_error_m: float
    rotation_error_rad: float
    iterations: int
    converged: bool


def target_placement(position_m: np.ndarray, quat_xyzw: np.ndarray | None) -> pin.SE3:
    """The target pose (identity rotation when ``quat_xyzw`` is None)."""
    p = np.asarray(position_m, dtype=float).ravel()
    if p.size != 3 or not np.all(np.isfinite(p)):
        raise InfeasibleError(f"goal position: give 3 finite values x, y, z in [m], got {p.tolist()}")
    if quat_xyzw is None:
        return pin.SE3(np.eye(3), p)
    quat = np.asarray(quat_xyzw, dtype=float).ravel()
    if quat.size != 4:
        raise InfeasibleError(f"goal orientation: give a quaternion of 4 values x, y, z, w, got {quat.size}")
    if not np.all(np.isfinite(quat)):
        raise InfeasibleError(f"goal orientation: the quaternion has NaN or infinite values: {quat.tolist()}")
    x, y, z, w = (float(v) for v in quat)
    norm = np.sqrt(x * x + y * y + z * z + w * w)
    if not norm > 0:
        raise InfeasibleError("goal orientation: the quaternion is zero")
    return pin.SE3(pin.Quaternion(w / norm, x / norm, y / norm, z / norm).matrix(), p)


def solve_ik(
    robot: Robot,
    position_m: np.ndarray,
    quat_xyzw: np.ndarray | None = None,
    q_seed: np.ndarray | None = None,
    *,
    tol_m: float = 1e-4,
    tol_rad: float = 1e-3,
    damping: float = 1e-3,
    max_iter: int = 300,
) -> IKResult:
    """Arm joint angles that put the end-effector frame at a position (and orientation) in the base frame.

    Args:
        robot: Loaded robot.
        position_m: (3,) target position in [m], base frame.
        quat_xyzw: (4,) target orientation, quaternion x, y, z, w (None: position only).
        q_seed: (n_joints,) start configuration in [rad] (default: the middle of the limits).
        tol_m, tol_rad: Convergence tolerances on the position [m] and orientation [rad] errors.
        damping: ``lambda`` of the damped least-squares step.
        max_iter: Iteration limit.
    """
    target = target_placement(position_m, quat_xyzw)
    if not np.all(np.isfinite(target.translation)):
        raise InfeasibleError("goal position: NaN or inf")
    lo = robot.lower_rad + robot.settings.position_margin_rad
    hi = robot.upper_rad - robot.settings.position_margin_rad
    q = 0.5 * (lo + hi) if q_seed is None else np.clip(np.asarray(q_seed, dtype=float).reshape(-1), lo, hi)
    model, data, fid, cols = robot.model, robot.data, robot.ee_frame_id, robot.arm_v_index
    full_pose = quat_xyzw is not None
    err_p = err_r = np.inf
    iterations = 0
    while iterations < max_iter:
        iterations += 1
        full = robot.full_configuration(q)
        pin.forwardKinematics(model, data, full)
        current = pin.updateFramePlacement(model, data, fid)
        if full_pose:
            rest = current.actInv(target)
            e = pin.log6(rest).vector
            jac = (
                pin.Jlog6(rest.inverse())
                @ pin.computeFrameJacobian(model, data, full, fid, pin.LOCAL)[:, cols]
            )
            err_p = float(np.linalg.norm(target.translation - current.translation))
            err_r = float(np.linalg.norm(e[3:]))
        else:
            e = target.translation - current.translation
            jac = pin.computeFrameJacobian(model, data, full, fid, pin.LOCAL_WORLD_ALIGNED)[:3, cols]
            err_p, err_r = float(np.linalg.norm(e)), 0.0
        if err_p <= tol_m and err_r <= tol_rad:
            break
        # the error after a small step dq is e - jac dq, to first order
        step = jac.T @ cho_solve(cho_factor(jac @ jac.T + damping**2 * np.eye(jac.shape[0])), e)
        q = np.clip(q + step, lo, hi)
    converged = err_p <= tol_m and err_r <= tol_rad
    return IKResult(q, err_p, err_r, iterations, bool(converged))
