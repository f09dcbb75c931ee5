"""The time-optimal path velocity (toppra) under joint velocity, acceleration and torque limits.

Step 2 of :func:`~ipromp_pin.motion.timing.time_path`: toppra 0.6 (``seidel`` solver, the only one
that works in the PyPI install) gives the largest path velocity ``sdot(s)`` at the grid points;
between grid points the path acceleration is constant (the semantics of ``ParametrizeConstAccel``,
which respects the acceleration limit; ``ParametrizeSpline`` overshoots it by up to 25 %).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import toppra
import toppra.algorithm as algo
import toppra.constraint as constraint
from scipy.interpolate import CubicSpline

from ..exceptions import InfeasibleError
from .trajectory import JointLimits


@dataclass(frozen=True)
class TorqueLimit:
    """Joint-torque limits for :func:`time_path` (toppra's ``JointTorqueConstraint``, given
    ``toppra_headroom`` of the room gravity leaves). The jerk-limited tracking may exceed them slightly
    where it catches up: the joint-torque check (:mod:`ipromp_pin.safety.joint_torques`) verifies the
    samples.

    Attributes:
        inverse_dynamics: ``(q, qd, qdd) -> tau``: joint torques (n_joints,) in [N m] of one sample
            ((n_joints,) each in [rad], [rad/s], [rad/s^2]), e.g.
            :meth:`ipromp_pin.robot.dynamics.ArmDynamics.inverse_dynamics` (payload included).
        limit_nm: Largest |torque| per joint (n_joints,) in [N m] (the effort limits less a margin).
    """

    inverse_dynamics: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]
    limit_nm: np.ndarray

    def headroom_constraint(self, headroom: float) -> constraint.JointTorqueConstraint:
        """toppra's constraint with the velocity/acceleration-dependent torque ``tau - g`` given only
        ``headroom`` of the room the gravity torque ``g`` leaves (as the velocity and acceleration
        limits are scaled for the jerk-limited tracking)."""
        zero = np.zeros(self.limit_nm.size)
        inv = self.inverse_dynamics

        def scaled(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
            g = inv(q, zero, zero)
            return g + (inv(q, qd, qdd) - g) / headroom

        lim = np.asarray(self.limit_nm, dtype=float)
        return constraint.JointTorqueConstraint(scaled, np.column_stack([-lim, lim]), zero)


class PathVelocityCap(constraint.JointVelocityConstraintVarying):
    """An upper bound on the path velocity ``sdot`` per grid point (a local slow-down: the joint
    velocities, hence every Cartesian speed along the path, scale with ``sdot``).

    Args:
        cap: Largest ``sdot`` (G,) at the grid points it will be used with (``inf``: none).
        n_joints: The path's joint count.
    """

    def __init__(self, cap: np.ndarray, n_joints: int) -> None:
        ones = np.column_stack([-np.ones(n_joints), np.ones(n_joints)])
        super().__init__(lambda _s: ones)
        self._cap = np.asarray(cap, dtype=float)

    def compute_constraint_params(self, path: object, gridpoints: np.ndarray) -> tuple:
        if self._cap.shape != (len(gridpoints),):
            n = len(gridpoints)
            raise ValueError(f"path velocity cap has {self._cap.size} values for {n} grid points")
        upper = np.where(np.isfinite(self._cap), np.maximum(self._cap, 0.0) ** 2, 1e12)
        return None, None, None, None, None, None, np.column_stack([np.zeros(upper.size), upper])


def toppra_profile(
    spline: CubicSpline,
    s_grid: np.ndarray,
    limits: JointLimits,
    torque: TorqueLimit | None = None,
    headroom: float = 1.0,
    sd_cap: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time-optimal path velocity at grid points under joint velocity/acceleration limits (toppra).

    Args:
        spline: Path ``c(s)`` (arc length ``s`` in [rad]) -> joint angles.
        s_grid: Grid points (G,) in [rad], from 0 to the path length.
        limits: Limits (use headroom-scaled ones).
        torque: Joint-torque limits too (``None``: none).
        headroom: The fraction of the torque limits' dynamic room given to toppra.
        sd_cap: Largest path velocity (G,) at the grid points (``inf``: none; None: no cap).

    Returns:
        ``t`` (G,) in [s], ``sdot`` (G,) and ``sddot`` (G-1,) (constant path acceleration per interval).

    Raises:
        InfeasibleError: toppra found no parameterisation.
    """
    logging.getLogger("toppra").setLevel(logging.ERROR)
    # the same spline as ``spline`` (same knots, same end conditions)
    path = toppra.SplineInterpolator(s_grid, spline(s_grid), bc_type="not-a-knot")
    v = limits.velocity_rad_s
    a = limits.acceleration_rad_s2
    cons = [
        constraint.JointVelocityConstraint(np.column_stack([-v, v])),
        constraint.JointAccelerationConstraint(np.column_stack([-a, a])),
    ]
    if torque is not None:
        cons.append(torque.headroom_constraint(headroom))
    if sd_cap is not None:
        cons.append(PathVelocityCap(sd_cap, v.size))
    instance = algo.TOPPRA(cons, path, gridpoints=s_grid, solver_wrapper="seidel")
    instance.compute_parameterization(0.0, 0.0)
    data = instance.problem_data
    if data.return_code != algo.ParameterizationReturnCode.Ok or data.sd_vec is None:
        raise InfeasibleError(f"toppra could not time-parameterise the path (return code {data.return_code})")
    sd = np.sqrt(np.maximum(np.asarray(data.sd_vec, dtype=float) ** 2, 0.0))
    sd[0] = sd[-1] = 0.0
    if sd.size >= 4:
        # toppra 0.6.10 (seidel) sometimes leaves a near-zero path velocity at the grid point next to
        # an end (seen on real paths: a 130 s final interval). Replace it by the largest value that
        # stops/starts within the end interval under the limits, capped by its neighbour; the
        # exact limit enforcement of :func:`time_path` absorbs any remaining excess.
        for i, j, nb in ((-2, -1, -3), (1, 0, 2)):
            d = abs(s_grid[j] - s_grid[i])
            c1 = np.abs(spline(s_grid[i], 1))
            c2 = spline(s_grid[i], 2)
            sign = -1.0 if i < 0 else 1.0
            denom = np.abs(c2 + sign * spline(s_grid[i], 1) / (2 * d))
            x_acc = np.min(limits.acceleration_rad_s2 / np.maximum(denom, 1e-12))
            x_vel = np.min((limits.velocity_rad_s / np.maximum(c1, 1e-12)) ** 2)
            x_fix = min(x_acc, x_vel, sd[nb] ** 2)
            if sd_cap is not None and math.isfinite(sd_cap[i]):
                x_fix = min(x_fix, float(sd_cap[i]) ** 2)
            if sd[i] ** 2 < 0.1 * x_fix:
                sd[i] = math.sqrt(x_fix)
    ds = np.diff(s_grid)
    dt = 2.0 * ds / np.maximum(sd[:-1] + sd[1:], 1e-12)
    sdd = (sd[1:] ** 2 - sd[:-1] ** 2) / (2.0 * ds)
    t = np.concatenate([[0.0], np.cumsum(dt)])
    return t, sd, sdd


def sample_profile(
    t_grid: np.ndarray, s_grid: np.ndarray, sd: np.ndarray, sdd: np.ndarray, t: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Path position, velocity and acceleration of a constant-acceleration-per-interval profile at times t."""
    t = np.clip(t, 0.0, t_grid[-1])
    i = np.clip(np.searchsorted(t_grid, t, side="right") - 1, 0, sdd.size - 1)
    tau = t - t_grid[i]
    s = s_grid[i] + sd[i] * tau + 0.5 * sdd[i] * tau**2
    v = sd[i] + sdd[i] * tau
    a = sdd[i].copy()
    at_end = t >= t_grid[-1]
    s[at_end], v[at_end], a[at_end] = s_grid[-1], 0.0, 0.0
    return np.minimum(s, s_grid[-1]), np.maximum(v, 0.0), a
