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

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline

from ..exceptions import InfeasibleError
from .path import (
    MAX_TRAJECTORY_SAMPLES,
    TOLERANCE_RAD,
    check_path_input,
    check_sample_budget,
    path_deviation,
    prepare_path,
)
from .toppra_profile import TorqueLimit, sample_profile, toppra_profile
from .tracking import ruckig_to_rest, track_1d
from .trajectory import JointLimits, Trajectory

CAP_RAMP = 0.25
"""Into and out of a part of the path whose velocity is capped (``sd_cap`` of :func:`time_path`),
the path velocity changes with at most this fraction of the largest path acceleration of the uncapped
profile: the jerk-limited tracking of the profile (step 3) overshoots, and may even reverse, after an
abrupt deceleration to a lower speed."""

__all__ = ["TimingReport", "TorqueLimit", "time_path", "verify_trajectory"]


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
        path_s: Per sample (N,), the path coordinate (arc length in [rad] of the cleaned path; NaN
            while blending in from a start off the path), when :func:`time_path` made the trajectory;
            not part of :meth:`to_dict`.
        path_sd: Per sample (N,), the path velocity in [rad/s] (NaN likewise).
        profile_sd: Per sample (N,), the velocity [rad/s] the timed (toppra) profile has at the
            sample's path coordinate: what the jerk-limited tracking follows (it lags behind and
            catches up faster where the profile slows down); NaN likewise.
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
    path_s: np.ndarray | None = field(default=None, repr=False, compare=False)
    path_sd: np.ndarray | None = field(default=None, repr=False, compare=False)
    profile_sd: np.ndarray | None = field(default=None, repr=False, compare=False)

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
        skip = ("timings_ms", "path_s", "path_sd", "profile_sd")
        out = {k: v for k, v in self.__dict__.items() if k not in skip}
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
    start_s: float = 0.0,
    sd_cap: Callable[[np.ndarray], np.ndarray] | None = None,
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
        smooth_rad: Gaussian smoothing of the path in [rad] of arc length (0: none): it removes the
            tight turns and the noise that make toppra crawl, at the cost of a small path deviation.
        toppra_headroom: Fraction of the velocity and acceleration limits given to toppra; the rest
            is headroom for the jerk-limited tracking.
        lookahead_s: How far ahead of the current time the 1-D ruckig target is taken, in [s].
        torque: Joint-torque limits toppra respects too (:class:`TorqueLimit`; ``None``: none).
        start_s: Time of the first sample in [s] on the human's clock (the robot starts then).
        sd_cap: The largest path velocity at path coordinates: grid (G,) in [rad] -> (G,) in [rad/s]
            (``inf``: none), a local slow-down (:class:`~.toppra_profile.PathVelocityCap`), entered
            and left gently (:data:`CAP_RAMP`).

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
    q_in = check_path_input(q_path, limits)
    check_sample_budget(q_in, limits, rate_hz)
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
    t_grid, sd, sdd = _capped_profile(spline, s_grid, head, torque, toppra_headroom, sd_cap)
    t2 = time.perf_counter()
    timings["toppra_ms"] = (t2 - t1) * 1e3

    s_t, v_t, a_t, j_t = _track_profile(
        spline, s_grid, t_grid, sd, sdd, limits, rate_hz, toppra_headroom, lookahead_s
    )
    t3 = time.perf_counter()
    timings["ruckig_ms"] = (t3 - t2) * 1e3

    q, qd, qdd, qddd, k, path_s, path_sd = _meet_limits(spline, s_t, v_t, a_t, j_t, length, limits, dt)
    q[-1], qd[-1], qdd[-1] = pts[-1], 0.0, 0.0
    q = np.clip(q, limits.lower_rad, limits.upper_rad)

    q_ref_path = q_in
    if not (np.allclose(q_start, pts[0], atol=1e-9) and not qd_start.any() and not qdd_start.any()):
        blend = ruckig_to_rest(q_start, qd_start, qdd_start, pts[0], limits, dt)
        q, qd, qdd, qddd = (np.vstack([b, x[1:]]) for b, x in zip(blend, (q, qd, qdd, qddd), strict=True))
        off = np.full(blend[0].shape[0] - 1, np.nan)  # blending in: not on the path yet
        path_s, path_sd = np.concatenate([off, path_s]), np.concatenate([off, path_sd])
        q_ref_path = np.vstack([q_start[None], q_in])
    traj = Trajectory(start_s + np.arange(q.shape[0]) * dt, q, qd, qdd, tuple(limits.joint_names), qddd)
    t4 = time.perf_counter()
    timings["sampling_ms"] = (t4 - t3) * 1e3
    report = verify_trajectory(
        traj, limits, q_ref_path, toppra_duration_s=float(t_grid[-1]), n_path_points=int(pts.shape[0]),
        time_scale=k, rate_hz=float(rate_hz),
    )  # fmt: skip
    timings["verify_ms"] = (time.perf_counter() - t4) * 1e3
    timings["total_ms"] = (time.perf_counter() - t0) * 1e3
    report.timings_ms = timings
    report.path_s, report.path_sd = path_s, path_sd
    report.profile_sd = np.interp(path_s, s_grid, sd)  # NaN stays NaN
    return traj, report


def _capped_profile(
    spline: CubicSpline,
    s_grid: np.ndarray,
    head: JointLimits,
    torque: TorqueLimit | None,
    headroom: float,
    sd_cap: Callable[[np.ndarray], np.ndarray] | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Step 2 of :func:`time_path`: the time-optimal profile, under the path velocity cap where it
    binds (entered and left gently: :func:`ramped_cap`)."""
    t_grid, sd, sdd = toppra_profile(spline, s_grid, head, torque, headroom)
    if sd_cap is not None:
        cap = np.asarray(sd_cap(s_grid), dtype=float)
        if np.any(cap < sd):
            cap = ramped_cap(s_grid, cap, CAP_RAMP * float(np.abs(sdd).max()))
            t_grid, sd, sdd = toppra_profile(spline, s_grid, head, torque, headroom, cap)
    return t_grid, sd, sdd


def ramped_cap(s_grid: np.ndarray, cap: np.ndarray, accel: float) -> np.ndarray:
    """Path velocity caps (G,) [rad/s] at the grid points (G,) [rad] lowered so that they change at
    most as fast as a path acceleration ``accel`` [rad/s^2] allows (``sdot^2`` by ``2 accel ds``)
    between grid points: into and out of a capped part of the path the profile changes gently."""
    x = np.asarray(cap, dtype=float) ** 2
    step = 2.0 * accel * np.diff(s_grid)
    for g in range(1, x.size):
        x[g] = min(x[g], x[g - 1] + step[g - 1])
    for g in range(x.size - 2, -1, -1):
        x[g] = min(x[g], x[g + 1] + step[g])
    return np.sqrt(x)


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
    ref_s, ref_v, ref_a = sample_profile(t_grid, s_grid, sd, sdd, np.arange(n_ref) * dt)
    d1 = np.abs(spline(s_grid, 1)).max(axis=0)  # max |c'_j| over the path
    v_max = float(np.min(limits.velocity_rad_s / np.maximum(d1, 1e-9)))
    a_max = float(max(np.abs(sdd).max(), 1e-6)) / toppra_headroom
    j_max = float(np.min(limits.jerk_rad_s3 / np.maximum(d1, 1e-9)))
    v_max = max(v_max, float(sd.max()) * 1.0001)
    s_t, v_t, a_t, j_t = track_1d(
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
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float, np.ndarray, np.ndarray]:
    """Step 4 of :func:`time_path`: joint derivatives along the path of the tracked path coordinate
    (``s_t`` etc., (N,) each, sampled every ``dt`` [s], on a path of ``length`` [rad]), then the
    uniform slow-down that meets every limit (the jerk is checked as a controller replaying the
    samples sees it: differences of accelerations).

    Returns:
        Joint position, velocity, acceleration and jerk (N', n_joints) each, the slow-down factor, and
        the path coordinate [rad] and velocity [rad/s] (N',) each.
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
    return q, qd, qdd, qddd, k, s_q, v_q


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
    bad = (q < limits.lower_rad - TOLERANCE_RAD) | (q > limits.upper_rad + TOLERANCE_RAD)
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
