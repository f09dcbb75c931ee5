"""Time parameterisation (toppra) and jerk-limited smoothing (ruckig) of a predicted joint path.

Pipeline of :func:`time_path` for a path ``q`` (M, n_joints) in [rad]:

1. **Clean** (:func:`prepare_path`): reject NaN/inf, too few points, zero length and points outside
   the position limits (:class:`~ipromp_pin.exceptions.InfeasibleError`); drop near-duplicate
   points, resample at uniform joint-space arc length (``spacing_rad``) and optionally smooth with
   a Gaussian of ``smooth_rad`` of arc length (end points kept). toppra returns ``None`` on
   stationary or repeated samples and noise of a few mrad stretches its duration several-fold,
   hence this step. The path ``c(s)`` is a not-a-knot cubic spline over arc length ``s`` in [rad]
   (a natural spline made toppra crawl over the last interval of some real paths: 280 s instead of 7 s).
2. **Time-optimal profile** (toppra 0.6, ``seidel`` solver, the only one that works in the PyPI
   install): the largest path velocity ``sdot(s)`` at the grid points under the joint velocity and
   acceleration limits times ``toppra_headroom``; between grid points the path acceleration is
   constant (the semantics of ``ParametrizeConstAccel``, which respects the acceleration limit;
   ``ParametrizeSpline`` overshoots it by up to 25 %).
3. **Jerk-limited path timing** (ruckig, one degree of freedom: the path coordinate ``s``): a
   ruckig instance tracks the toppra profile ``s_ref(t)`` online at the control rate (target = the
   reference state ``lookahead_s`` ahead, the end at rest as the final target). Because the motion
   is ``q(t) = c(s(t))`` it stays on the path by construction. (Tracking the reference in joint
   space with a 7-DoF ruckig leaves the path by tens of mrad where the toppra reference's
   acceleration switches: the time-synchronised catch-up manoeuvres cut corners.)
4. **Limit enforcement**: joint velocity ``c' sdot``, acceleration ``c'' sdot^2 + c' sddot`` and jerk
   ``c''' sdot^3 + 3 c'' sdot sddot + c' sdddot`` are evaluated exactly at every sample; if any
   exceeds its limit the trajectory is slowed uniformly by ``k = max(r_v, sqrt(r_a), cbrt(r_j))``
   (velocities scale by 1/k, accelerations 1/k^2, jerks 1/k^3), which makes every ratio <= 1.
5. **Start state**: when the robot is not at rest at the path start, a 7-DoF ruckig state-to-state
   segment first brings it from its current position/velocity/acceleration to rest at the path
   start (jerk-limited); the path then follows.

Ruckig is only ever asked for state-to-state trajectories: intermediate waypoints are never passed
(the community build would try to reach a cloud service over the network for them).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import toppra
import toppra.algorithm as algo
import toppra.constraint as constraint
from ruckig import InputParameter, OutputParameter, Result, Ruckig, RuckigError
from scipy.interpolate import CubicSpline
from scipy.ndimage import gaussian_filter1d

from ..exceptions import InfeasibleError
from .trajectory import JointLimits, Trajectory

_TOL = 1e-9

MAX_TRAJECTORY_SAMPLES = 1_000_000
"""Largest number of samples :func:`time_path` produces (10 000 s at 100 Hz; hand-overs last seconds).
A path that the limits would stretch beyond it is refused before anything is allocated."""


@dataclass
class TimingReport:
    """Verification of a :class:`Trajectory` against its limits and path.

    Attributes:
        duration_s: Trajectory duration in [s].
        toppra_duration_s: Duration of the time-optimal (jerk-unlimited) toppra profile in [s].
        n_samples: Number of samples.
        rate_hz: Control rate in [Hz].
        n_path_points: Path points after cleaning.
        max_position_violation_rad: Largest excursion beyond the position limits (0 if none) in [rad].
        velocity_ratio: max |qd| / velocity limit over samples and joints.
        acceleration_ratio: max |qdd| / acceleration limit.
        jerk_ratio: max |jerk| / jerk limit, the jerk between samples being (qdd[k+1] - qdd[k]) / dt.
        path_deviation_rad: Largest joint-space distance from a sample to the input path
            (piecewise linear through the original points) in [rad].
        final_error_rad: max |q[-1] - path end| in [rad].
        final_velocity_rad_s: max |qd[-1]| in [rad/s].
        time_scale: Uniform slow-down factor applied to meet the limits (1 = none).
        timings_ms: Time per stage in [ms].
        tolerance: Relative tolerance used by :attr:`passed` on the ratios.
    """

    duration_s: float
    toppra_duration_s: float
    n_samples: int
    rate_hz: float
    n_path_points: int
    max_position_violation_rad: float
    velocity_ratio: float
    acceleration_ratio: float
    jerk_ratio: float
    path_deviation_rad: float
    final_error_rad: float
    final_velocity_rad_s: float
    time_scale: float = 1.0
    timings_ms: dict[str, float] = field(default_factory=dict)
    tolerance: float = 1e-6

    @property
    def passed(self) -> bool:
        """Whether every limit holds at every sample and the trajectory ends at rest at the path end."""
        lim = 1.0 + self.tolerance
        return (
            self.max_position_violation_rad <= 1e-9
            and self.velocity_ratio <= lim
            and self.acceleration_ratio <= lim
            and self.jerk_ratio <= lim
            and self.final_error_rad <= 1e-6
            and self.final_velocity_rad_s <= 1e-6
        )

    def to_dict(self) -> dict:
        """JSON-serialisable form."""
        out = {k: v for k, v in self.__dict__.items() if k != "timings_ms"}
        out = {k: (float(v) if isinstance(v, float | np.floating) else v) for k, v in out.items()}
        out["passed"] = self.passed
        out["timings_ms"] = {k: round(float(v), 3) for k, v in self.timings_ms.items()}
        return out

    def to_text(self) -> str:
        """Human-readable summary."""
        return "\n".join(
            [
                f"Timing: {'OK' if self.passed else 'LIMITS VIOLATED'}; duration {self.duration_s:.2f} s "
                f"(time-optimal {self.toppra_duration_s:.2f} s), {self.n_samples} samples at "
                f"{self.rate_hz:g} Hz",
                f"  max ratio to limit: velocity {self.velocity_ratio:.3f}, acceleration "
                f"{self.acceleration_ratio:.3f}, jerk {self.jerk_ratio:.3f}; position excess "
                f"{self.max_position_violation_rad:.2e} rad",
                f"  path deviation max {self.path_deviation_rad * 1e3:.2f} mrad; final error "
                f"{self.final_error_rad:.1e} rad",
            ]
        )


# --------------------------------------------------------------------------------------------------
# Path cleaning
# --------------------------------------------------------------------------------------------------


def _check_path_input(q: np.ndarray, limits: JointLimits) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    n = limits.n_joints
    if q.ndim != 2 or q.shape[1] != n:
        raise InfeasibleError(f"path: expected shape (M, {n}), got {q.shape}")
    if q.shape[0] < 2:
        raise InfeasibleError(f"path: needs at least 2 points, got {q.shape[0]}")
    if not np.all(np.isfinite(q)):
        row = int(np.nonzero(~np.all(np.isfinite(q), axis=1))[0][0])
        raise InfeasibleError(f"path: NaN or inf joint angles (first at point {row})")
    below = q < limits.lower_rad - _TOL
    above = q > limits.upper_rad + _TOL
    if below.any() or above.any():
        i, j = np.argwhere(below | above)[0]
        raise InfeasibleError(
            f"path: point {i} has {limits.joint_names[j]} = {q[i, j]:.4f} rad outside its limits "
            f"[{limits.lower_rad[j]:.4f}, {limits.upper_rad[j]:.4f}] "
            f"({int((below | above).sum())} violations)"
        )
    return q


def prepare_path(
    q: np.ndarray, limits: JointLimits, *, spacing_rad: float = 0.02, smooth_rad: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Clean a joint path and resample it at uniform arc length.

    Args:
        q: Path points (M, n_joints) in [rad].
        limits: Joint limits (the path must lie within the position limits).
        spacing_rad: Arc-length spacing of the resampled points in [rad] (joint-space Euclidean).
        smooth_rad: Standard deviation in [rad] of arc length of a Gaussian smoothing (0: none).

    Returns:
        ``s`` (K,) arc length in [rad] from 0, and the points (K, n_joints) in [rad].

    Raises:
        InfeasibleError: NaN/inf, fewer than 2 points, outside the position limits, zero length.
    """
    q = _check_path_input(q, limits)
    step = np.linalg.norm(np.diff(q, axis=0), axis=1)
    keep = np.concatenate([[True], step > 1e-9])
    q = q[keep]
    s = np.concatenate([[0.0], np.cumsum(step[keep[1:]])])
    length = float(s[-1])
    if length < 1e-6:
        raise InfeasibleError(f"path: zero length ({length:.1e} rad): start and hand-over coincide")
    k = max(4, int(math.ceil(length / spacing_rad)) + 1)
    su = np.linspace(0.0, length, k)
    qu = np.column_stack([np.interp(su, s, q[:, j]) for j in range(q.shape[1])])
    if smooth_rad > 0:
        sigma = smooth_rad / (su[1] - su[0])
        pad = min(k - 1, int(4 * sigma) + 1)
        # odd reflection about the end points keeps them fixed and the ends' direction
        ext = np.vstack([2 * qu[0] - qu[pad:0:-1], qu, 2 * qu[-1] - qu[-2 : -pad - 2 : -1]])
        qs = gaussian_filter1d(ext, sigma, axis=0, mode="nearest")[pad : pad + k]
        qs[0], qs[-1] = qu[0], qu[-1]
        step = np.linalg.norm(np.diff(qs, axis=0), axis=1)
        s = np.concatenate([[0.0], np.cumsum(step)])
        su = np.linspace(0.0, s[-1], k)
        qu = np.column_stack([np.interp(su, s, qs[:, j]) for j in range(qs.shape[1])])
        qu = np.clip(qu, limits.lower_rad, limits.upper_rad)
    return su, qu


# --------------------------------------------------------------------------------------------------
# toppra profile
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TorqueLimit:
    """Joint-torque limits for :func:`time_path` (toppra's ``JointTorqueConstraint``, given
    ``toppra_headroom`` of the room gravity leaves). The jerk-limited tracking may exceed them slightly
    where it catches up: the joint-torque check (:mod:`ipromp_pin.checks.joint_torques`) verifies the
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


def toppra_profile(
    spline: CubicSpline,
    s_grid: np.ndarray,
    limits: JointLimits,
    torque: TorqueLimit | None = None,
    headroom: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time-optimal path velocity at grid points under joint velocity/acceleration limits (toppra).

    Args:
        spline: Path ``c(s)`` (arc length ``s`` in [rad]) -> joint angles.
        s_grid: Grid points (G,) in [rad], from 0 to the path length.
        limits: Limits (use headroom-scaled ones).
        torque: Joint-torque limits too (``None``: none).
        headroom: The fraction of the torque limits' dynamic room given to toppra.

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
            if sd[i] ** 2 < 0.1 * x_fix:
                sd[i] = math.sqrt(x_fix)
    ds = np.diff(s_grid)
    dt = 2.0 * ds / np.maximum(sd[:-1] + sd[1:], 1e-12)
    sdd = (sd[1:] ** 2 - sd[:-1] ** 2) / (2.0 * ds)
    t = np.concatenate([[0.0], np.cumsum(dt)])
    return t, sd, sdd


def _sample_profile(
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


# --------------------------------------------------------------------------------------------------
# ruckig stages
# --------------------------------------------------------------------------------------------------


def _update(otg: Ruckig, inp: InputParameter, out: OutputParameter) -> Result:
    """One ruckig cycle. ruckig 0.19.4 can fail on exact boundary cases of its profiles (e.g. a
    displacement of exactly 2 a^3 / j^2); retry once with limits lowered by 1e-6 (still within)."""
    try:
        return otg.update(inp, out)
    except RuckigError as exc:
        v, a, j = list(inp.max_velocity), list(inp.max_acceleration), list(inp.max_jerk)
        inp.max_velocity = [x * (1 - 1e-6) for x in v]
        inp.max_acceleration = [x * (1 - 1e-6) for x in a]
        inp.max_jerk = [x * (1 - 1e-6) for x in j]
        try:
            return otg.update(inp, out)
        except RuckigError:
            raise InfeasibleError(f"ruckig failed: {str(exc).splitlines()[0]}") from exc
        finally:
            inp.max_velocity, inp.max_acceleration, inp.max_jerk = v, a, j


def reachable_target(v: float, a: float, v_max: float, a_max: float, j_max: float) -> tuple[float, float]:
    """Clamp a 1-D target state (path velocity, acceleration) to one ruckig accepts.

    A target state with velocity ``v`` and acceleration ``a`` passes through ``v + a^2 / (2 j_max)``
    (after it when accelerating, before it when decelerating); ruckig rejects targets where that
    exceeds ``v_max``. Decelerating targets are also kept from passing below zero velocity. Targets are kept
    within 97 % of ``v_max``: a tracked state on the exact boundary (v + a^2 / 2j = v_max) is
    rejected by ruckig as the *current* state of the next cycle. The uniform slow-down in
    :func:`time_path` enforces the joint limits exactly afterwards.
    """
    v_cap = 0.97 * v_max
    v = min(max(float(v), 0.0), v_cap)
    a = min(max(float(a), -a_max), a_max)
    a_cap = 0.999 * math.sqrt(2.0 * j_max * max(v_cap - v, 0.0))
    if a > 0.0:
        a = min(a, a_cap)
    elif a < 0.0:
        a = max(a, -a_cap, -0.999 * math.sqrt(2.0 * j_max * v))
    return v, a


def _ruckig_track_1d(
    ref_s: np.ndarray,
    ref_v: np.ndarray,
    ref_a: np.ndarray,
    length: float,
    dt: float,
    v_max: float,
    a_max: float,
    j_max: float,
    lookahead: int,
    max_steps: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Track a path-coordinate reference with a 1-DoF ruckig (state-to-state updates only)."""
    otg = Ruckig(1, dt)
    inp = InputParameter(1)
    out = OutputParameter(1)
    inp.max_velocity = [v_max]
    inp.max_acceleration = [a_max]
    inp.max_jerk = [j_max]
    inp.current_position = [0.0]
    inp.current_velocity = [0.0]
    inp.current_acceleration = [0.0]
    n_ref = ref_s.size
    s, v, a, j = [0.0], [0.0], [0.0], [0.0]
    k = 0
    while True:
        k += 1
        i = min(k + lookahead, n_ref - 1)
        inp.target_position = [ref_s[i]]
        v_t, a_t = reachable_target(ref_v[i], ref_a[i], v_max, a_max, j_max)
        inp.target_velocity = [v_t]
        inp.target_acceleration = [a_t]
        result = _update(otg, inp, out)
        if result not in (Result.Working, Result.Finished):
            raise InfeasibleError(f"ruckig failed while timing the path: {result}")
        s.append(out.new_position[0])
        v.append(out.new_velocity[0])
        a.append(out.new_acceleration[0])
        j.append(out.new_jerk[0])
        out.pass_to_input(inp)
        if i == n_ref - 1 and result == Result.Finished:
            break
        if k > max_steps:
            raise InfeasibleError("ruckig did not reach the path end (tracking diverged)")
    return np.array(s), np.array(v), np.array(a), np.array(j)


def _ruckig_to_rest(
    q0: np.ndarray, qd0: np.ndarray, qdd0: np.ndarray, q1: np.ndarray, limits: JointLimits, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """7-DoF ruckig state-to-state segment from the current state to rest at ``q1`` (sampled at dt)."""
    n = limits.n_joints
    otg = Ruckig(n, dt)
    inp = InputParameter(n)
    out = OutputParameter(n)
    inp.max_velocity = limits.velocity_rad_s
    inp.max_acceleration = limits.acceleration_rad_s2
    inp.max_jerk = limits.jerk_rad_s3
    inp.current_position = q0
    inp.current_velocity = qd0
    inp.current_acceleration = qdd0
    inp.target_position = q1
    inp.target_velocity = np.zeros(n)
    inp.target_acceleration = np.zeros(n)
    qs, vs, acs = [q0], [qd0], [qdd0]
    for _ in range(100000):
        result = _update(otg, inp, out)
        if result not in (Result.Working, Result.Finished):
            raise InfeasibleError(f"ruckig cannot bring the start state to the path start: {result}")
        qs.append(np.array(out.new_position))
        vs.append(np.array(out.new_velocity))
        acs.append(np.array(out.new_acceleration))
        out.pass_to_input(inp)
        if result == Result.Finished:
            break
    q, qd, qdd = np.array(qs), np.array(vs), np.array(acs)
    qddd = np.zeros_like(qdd)
    qddd[1:] = np.diff(qdd, axis=0) / dt
    return q, qd, qdd, qddd


# --------------------------------------------------------------------------------------------------
# Verification
# --------------------------------------------------------------------------------------------------


def path_deviation(q: np.ndarray, path: np.ndarray) -> np.ndarray:
    """Distance (N,) in [rad] from each sample of ``q`` (N, n) to the piecewise-linear ``path`` (M, n)."""
    q = np.asarray(q, dtype=float)
    path = np.asarray(path, dtype=float)
    if path.shape[0] == 1:
        return np.linalg.norm(q - path[0], axis=1)
    a = path[:-1]
    ab = path[1:] - a
    l2 = np.maximum(np.sum(ab**2, axis=1), 1e-300)
    best = np.full(q.shape[0], np.inf)
    for m in range(a.shape[0]):
        u = np.clip((q - a[m]) @ ab[m] / l2[m], 0.0, 1.0)
        d = np.sum((q - a[m] - u[:, None] * ab[m]) ** 2, axis=1)
        np.minimum(best, d, out=best)
    out = np.sqrt(best)
    return out


def path_times(traj: Trajectory, q_path: np.ndarray) -> np.ndarray:
    """Time (M,) in [s] on ``traj`` at which it passes each point of the path ``q_path`` (M, n) it
    was timed from (:func:`time_path` with the robot at rest at the path start).

    The trajectory follows the cleaned path, so a point is matched by its fraction of the path's
    joint-space arc length: point ``i`` is passed when the trajectory has covered the same fraction
    of its own arc length (the first time it does). Converts times or sample indices of the
    prediction (the human's time base) to the trajectory's time base.
    """
    q_path = np.asarray(q_path, dtype=float)
    s_path = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(q_path, axis=0), axis=1))])
    s_traj = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(traj.q, axis=0), axis=1))])
    if s_path[-1] <= 0.0 or s_traj[-1] <= 0.0:
        return np.full(q_path.shape[0], float(traj.t_s[0]))
    f_path = s_path / s_path[-1]
    f_traj = s_traj / s_traj[-1]
    k = np.clip(np.searchsorted(f_traj, f_path, side="left"), 1, f_traj.size - 1)
    f0, f1 = f_traj[k - 1], f_traj[k]
    w = np.where(f1 > f0, (f_path - f0) / np.where(f1 > f0, f1 - f0, 1.0), 1.0)
    w = np.clip(w, 0.0, 1.0)
    return traj.t_s[k - 1] + w * (traj.t_s[k] - traj.t_s[k - 1])


def verify_trajectory(
    traj: Trajectory,
    limits: JointLimits,
    path: np.ndarray,
    *,
    toppra_duration_s: float = float("nan"),
    n_path_points: int = 0,
    time_scale: float = 1.0,
    timings_ms: dict[str, float] | None = None,
    rate_hz: float | None = None,
) -> TimingReport:
    """Check a trajectory against limits at every sample and measure its deviation from ``path``.

    The jerk is the finite difference of consecutive accelerations (what a controller replaying the
    samples sees). ``rate_hz`` is the control rate reported in [Hz] (default: the reciprocal of
    the median sample spacing, to 9 significant digits).
    """
    q, qd, qdd = traj.q, traj.qd, traj.qdd
    path = np.asarray(path, dtype=float)
    excess = np.maximum(np.maximum(limits.lower_rad - q, q - limits.upper_rad), 0.0)
    dt = np.diff(traj.t_s)
    jerk = np.diff(qdd, axis=0) / dt[:, None] if dt.size else np.zeros_like(qdd)
    if rate_hz is not None:
        rate = float(rate_hz)
    else:
        rate = float(f"{1.0 / np.median(dt):.9g}") if dt.size else float("nan")
    return TimingReport(
        duration_s=traj.duration_s,
        toppra_duration_s=float(toppra_duration_s),
        n_samples=traj.n_samples,
        rate_hz=rate,
        n_path_points=int(n_path_points),
        max_position_violation_rad=float(excess.max()),
        velocity_ratio=float(np.max(np.abs(qd) / limits.velocity_rad_s)),
        acceleration_ratio=float(np.max(np.abs(qdd) / limits.acceleration_rad_s2)),
        jerk_ratio=float(np.max(np.abs(jerk) / limits.jerk_rad_s3)),
        path_deviation_rad=float(np.max(path_deviation(q, path))),
        final_error_rad=float(np.max(np.abs(q[-1] - path[-1]))),
        final_velocity_rad_s=float(np.max(np.abs(qd[-1]))),
        time_scale=float(time_scale),
        timings_ms=dict(timings_ms or {}),
    )


# --------------------------------------------------------------------------------------------------
# Main entry point
# --------------------------------------------------------------------------------------------------


def time_path(
    q_path: np.ndarray,
    limits: JointLimits,
    *,
    rate_hz: float = 100.0,
    start_q: np.ndarray | None = None,
    start_qd: np.ndarray | None = None,
    start_qdd: np.ndarray | None = None,
    spacing_rad: float = 0.02,
    smooth_rad: float = 0.05,
    toppra_headroom: float = 0.5,
    lookahead_s: float = 0.0,
    torque: TorqueLimit | None = None,
) -> tuple[Trajectory, TimingReport]:
    """Turn a predicted joint path into a jerk-limited trajectory sampled at ``rate_hz``.

    Args:
        q_path: Path points (M, n_joints) in [rad]; the last one is the hand-over (reached at rest).
        limits: Joint limits (e.g. :meth:`JointLimits.from_robot`).
        rate_hz: Control rate in [Hz] of the output samples.
        start_q: Robot's current position (n_joints,) in [rad] (default: the path start).
        start_qd: Current velocity (n_joints,) in [rad/s] (default: 0).
        start_qdd: Current acceleration (n_joints,) in [rad/s^2] (default: 0).
        spacing_rad: Arc-length spacing of the cleaned path in [rad].
        smooth_rad: Gaussian smoothing of the path in [rad] of arc length (0: none); it removes the
            tight turns and the noise that make toppra crawl (3 mrad of noise: 1.8x the noise-free
            duration instead of 3.8x without smoothing), at the cost of a path deviation of ~1 cm
            at the hand (median ~10-15 mrad on the real demonstrations' paths).
        toppra_headroom: Fraction of the velocity and acceleration limits given to toppra; the rest
            is headroom for the jerk-limited tracking.
        lookahead_s: How far ahead of the current time the 1-D ruckig target is taken, in [s].
        torque: Joint-torque limits toppra respects too (:class:`TorqueLimit`; ``None``: none).

    Returns:
        The trajectory and its verification report.

    Raises:
        InfeasibleError: bad path (NaN, < 2 points, zero length, outside the position limits), start
            state outside the limits, or no parameterisation found.
    """
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    _check_rate_headroom(rate_hz, toppra_headroom)
    dt = 1.0 / rate_hz
    n = limits.n_joints
    q_in = _check_path_input(q_path, limits)
    _check_sample_budget(q_in, limits, rate_hz)
    q_start = q_in[0] if start_q is None else np.asarray(start_q, dtype=float).reshape(-1)
    qd_start = np.zeros(n) if start_qd is None else np.asarray(start_qd, dtype=float).reshape(-1)
    qdd_start = np.zeros(n) if start_qdd is None else np.asarray(start_qdd, dtype=float).reshape(-1)
    _check_start(q_start, qd_start, qdd_start, limits)

    s_grid, pts = prepare_path(q_in, limits, spacing_rad=spacing_rad, smooth_rad=smooth_rad)
    length = float(s_grid[-1])
    spline = CubicSpline(s_grid, pts, bc_type="not-a-knot")
    t1 = time.perf_counter()
    timings["clean_ms"] = (t1 - t0) * 1e3

    head = limits.scaled(toppra_headroom, toppra_headroom)
    t_grid, sd, sdd = toppra_profile(spline, s_grid, head, torque, toppra_headroom)
    t2 = time.perf_counter()
    timings["toppra_ms"] = (t2 - t1) * 1e3

    s_t, v_t, a_t, j_t = _track_profile(
        spline, s_grid, t_grid, sd, sdd, limits, rate_hz, toppra_headroom, lookahead_s
    )
    t3 = time.perf_counter()
    timings["ruckig_ms"] = (t3 - t2) * 1e3

    q, qd, qdd, qddd, k = _meet_limits(spline, s_t, v_t, a_t, j_t, length, limits, dt)
    q[-1], qd[-1], qdd[-1] = pts[-1], 0.0, 0.0
    q = np.clip(q, limits.lower_rad, limits.upper_rad)

    if not (np.allclose(q_start, pts[0], atol=1e-9) and not qd_start.any() and not qdd_start.any()):
        pq, pqd, pqdd, pqddd = _ruckig_to_rest(q_start, qd_start, qdd_start, pts[0], limits, dt)
        q = np.vstack([pq, q[1:]])
        qd = np.vstack([pqd, qd[1:]])
        qdd = np.vstack([pqdd, qdd[1:]])
        qddd = np.vstack([pqddd, qddd[1:]])
        q_ref_path = np.vstack([q_start[None], q_in])
    else:
        q_ref_path = q_in
    traj = Trajectory(np.arange(q.shape[0]) * dt, q, qd, qdd, tuple(limits.joint_names), qddd)
    t4 = time.perf_counter()
    timings["sampling_ms"] = (t4 - t3) * 1e3
    report = verify_trajectory(
        traj,
        limits,
        q_ref_path,
        toppra_duration_s=float(t_grid[-1]),
        n_path_points=int(pts.shape[0]),
        time_scale=k,
        timings_ms=timings,
        rate_hz=float(rate_hz),
    )
    timings["verify_ms"] = (time.perf_counter() - t4) * 1e3
    timings["total_ms"] = (time.perf_counter() - t0) * 1e3
    report.timings_ms = timings
    return traj, report


def _check_rate_headroom(rate_hz: float, toppra_headroom: float) -> None:
    """Refuse a non-positive control rate or a toppra headroom outside (0, 1]."""
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise InfeasibleError(f"rate_hz must be positive, got {rate_hz}")
    if not 0 < toppra_headroom <= 1:
        raise InfeasibleError(f"toppra_headroom must be in (0, 1], got {toppra_headroom}")


def _track_profile(
    spline: CubicSpline,
    s_grid: np.ndarray,
    t_grid: np.ndarray,
    sd: np.ndarray,
    sdd: np.ndarray,
    limits: JointLimits,
    rate_hz: float,
    toppra_headroom: float,
    lookahead_s: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Step 3 of :func:`time_path`: the toppra profile (grid ``t_grid`` (G,) in [s], ``sd`` (G,),
    ``sdd`` (G-1,)) sampled at the control rate and tracked by a 1-D ruckig on the path coordinate.

    Returns:
        Path position ``s`` in [rad] (clipped to the path length), velocity, acceleration and jerk,
        each (N,), at the control rate.
    """
    dt = 1.0 / rate_hz
    length = float(s_grid[-1])
    if not t_grid[-1] * rate_hz <= MAX_TRAJECTORY_SAMPLES:
        raise InfeasibleError(
            f"the time-optimal trajectory lasts {t_grid[-1]:.3g} s: more than {MAX_TRAJECTORY_SAMPLES} "
            f"samples at {rate_hz:g} Hz (are the velocity and acceleration limits plausible?)"
        )
    n_ref = int(math.ceil(t_grid[-1] / dt)) + 1
    ref_s, ref_v, ref_a = _sample_profile(t_grid, s_grid, sd, sdd, np.arange(n_ref) * dt)
    d1 = np.abs(spline(s_grid, 1)).max(axis=0)  # max |c'_j| over the path
    v_max = float(np.min(limits.velocity_rad_s / np.maximum(d1, 1e-9)))
    a_max = float(max(np.abs(sdd).max(), 1e-6)) / toppra_headroom
    j_max = float(np.min(limits.jerk_rad_s3 / np.maximum(d1, 1e-9)))
    v_max = max(v_max, float(sd.max()) * 1.0001)
    s_t, v_t, a_t, j_t = _ruckig_track_1d(
        ref_s, ref_v, ref_a, length, dt, v_max, a_max, j_max, int(round(lookahead_s / dt)), 20 * n_ref + 10000
    )
    return np.clip(s_t, 0.0, length), v_t, a_t, j_t


def _meet_limits(
    spline: CubicSpline,
    s_t: np.ndarray,
    v_t: np.ndarray,
    a_t: np.ndarray,
    j_t: np.ndarray,
    length: float,
    limits: JointLimits,
    dt: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """Step 4 of :func:`time_path`: joint derivatives along the path of the tracked path coordinate
    (``s_t`` etc., (N,) each, sampled every ``dt`` [s], on a path of ``length`` [rad]), then the
    uniform slow-down that meets every limit (the jerk is checked as a controller replaying the
    samples sees it: differences of accelerations).

    Returns:
        Joint position, velocity, acceleration and jerk (N', n_joints) each, and the slow-down factor.
    """
    t_old = np.arange(s_t.size) * dt
    k = 1.0
    for _ in range(6):
        if k == 1.0:
            s_q, v_q, a_q, j_q = s_t, v_t, a_t, j_t
        else:
            n_new = int(math.ceil(t_old[-1] * k / dt)) + 1
            t_query = np.minimum(np.arange(n_new) * dt / k, t_old[-1])
            s_q = np.clip(_hermite_quintic(t_old, s_t, v_t, a_t, t_query), 0.0, length)
            v_q = np.interp(t_query, t_old, v_t) / k
            a_q = np.interp(t_query, t_old, a_t) / k**2
            j_q = np.interp(t_query, t_old, j_t) / k**3
            v_q[-1] = a_q[-1] = 0.0
            s_q[-1] = length
        q, qd, qdd, qddd = _joint_states(spline, s_q, v_q, a_q, j_q)
        jerk_fd = np.diff(qdd, axis=0) / dt
        r_v = np.max(np.abs(qd) / limits.velocity_rad_s)
        r_a = np.max(np.abs(qdd) / limits.acceleration_rad_s2)
        r_j = np.max(np.abs(jerk_fd) / limits.jerk_rad_s3) if jerk_fd.size else 0.0
        factor = max(r_v, math.sqrt(r_a), r_j ** (1.0 / 3.0))
        if factor <= 1.0:
            break
        k *= factor * (1.0 + (1e-3 if k == 1.0 else 1e-2))
    else:
        raise InfeasibleError(f"could not meet the limits by slowing down (last factor {factor:.3f})")
    return q, qd, qdd, qddd, k


def _check_sample_budget(q: np.ndarray, limits: JointLimits, rate_hz: float) -> None:
    """Refuse a path whose duration under ``limits`` is certain to exceed :data:`MAX_TRAJECTORY_SAMPLES`
    samples at ``rate_hz``, from lower bounds that cost nothing: each joint must travel its total
    variation at most at its velocity limit, and reach its farthest point from the start (from rest)
    at most at its acceleration and jerk limits."""
    travel = np.sum(np.abs(np.diff(q, axis=0)), axis=0)
    reach = np.max(np.abs(q - q[0]), axis=0)
    with np.errstate(over="ignore"):
        bound = np.max(
            np.stack(
                [
                    travel / limits.velocity_rad_s,
                    np.sqrt(2.0 * reach / limits.acceleration_rad_s2),
                    np.cbrt(6.0 * reach / limits.jerk_rad_s3),
                ]
            ),
            axis=0,
        )
    j = int(np.argmax(bound))
    if not bound[j] * rate_hz <= MAX_TRAJECTORY_SAMPLES:
        raise InfeasibleError(
            f"the path would take at least {bound[j]:.3g} s ({limits.joint_names[j]}: velocity limit "
            f"{limits.velocity_rad_s[j]:g} rad/s, acceleration {limits.acceleration_rad_s2[j]:g} rad/s^2, "
            f"jerk {limits.jerk_rad_s3[j]:g} rad/s^3): more than {MAX_TRAJECTORY_SAMPLES} samples at "
            f"{rate_hz:g} Hz"
        )


def _joint_states(
    spline: CubicSpline, s: np.ndarray, v: np.ndarray, a: np.ndarray, j: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Joint position, velocity, acceleration and jerk of ``q(t) = c(s(t))`` (chain rule)."""
    c1, c2, c3 = spline(s, 1), spline(s, 2), spline(s, 3)
    q = spline(s)
    qd = c1 * v[:, None]
    qdd = c2 * (v**2)[:, None] + c1 * a[:, None]
    qddd = c3 * (v**3)[:, None] + 3 * c2 * (v * a)[:, None] + c1 * j[:, None]
    return q, qd, qdd, qddd


def _hermite_quintic(
    t: np.ndarray, s: np.ndarray, v: np.ndarray, a: np.ndarray, tq: np.ndarray
) -> np.ndarray:
    """Quintic Hermite interpolation of s(t) with known first and second derivatives."""
    i = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, t.size - 2)
    h = t[i + 1] - t[i]
    u = (tq - t[i]) / h
    u2, u3 = u * u, u * u * u
    h00 = 1 - 10 * u3 + 15 * u2 * u2 - 6 * u3 * u2
    h10 = u - 6 * u3 + 8 * u2 * u2 - 3 * u3 * u2
    h20 = 0.5 * u2 - 1.5 * u3 + 1.5 * u2 * u2 - 0.5 * u3 * u2
    h01 = 10 * u3 - 15 * u2 * u2 + 6 * u3 * u2
    h11 = -4 * u3 + 7 * u2 * u2 - 3 * u3 * u2
    h21 = 0.5 * u3 - u2 * u2 + 0.5 * u3 * u2
    return (
        h00 * s[i]
        + h10 * h * v[i]
        + h20 * h * h * a[i]
        + h01 * s[i + 1]
        + h11 * h * v[i + 1]
        + h21 * h * h * a[i + 1]
    )


def _check_start(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, limits: JointLimits) -> None:
    n = limits.n_joints
    for name, v in (("start_q", q), ("start_qd", qd), ("start_qdd", qdd)):
        if v.shape != (n,):
            raise InfeasibleError(f"{name}: expected shape ({n},), got {v.shape}")
        if not np.all(np.isfinite(v)):
            raise InfeasibleError(f"{name}: NaN or inf values {v.tolist()}")
    bad = (q < limits.lower_rad - _TOL) | (q > limits.upper_rad + _TOL)
    if bad.any():
        j = int(np.argmax(bad))
        raise InfeasibleError(
            f"start state: {limits.joint_names[j]} = {q[j]:.4f} rad outside its limits "
            f"[{limits.lower_rad[j]:.4f}, {limits.upper_rad[j]:.4f}]"
        )
    for name, v, lim in (
        ("velocity", qd, limits.velocity_rad_s),
        ("acceleration", qdd, limits.acceleration_rad_s2),
    ):
        over = np.abs(v) > lim * (1 + 1e-9)
        if over.any():
            j = int(np.argmax(over))
            raise InfeasibleError(
                f"start state: {limits.joint_names[j]} {name} {v[j]:.4f} exceeds its limit {lim[j]:.4f}"
            )
