"""Jerk-limited re-targeting (ruckig) from the robot's current state onto a predicted trajectory's timeline.

A re-plan at time ``t_c`` [s] (a control tick) starts from the robot's commanded state
(``q``, ``qd``, ``qdd``) and a :class:`ReferenceMotion` ``r(t)``: the predicted robot trajectory on
the human's predicted timeline, ``t`` in [0, D] from the start of the human's motion, the hand-over
at ``D``. :func:`retarget` builds the remaining commanded motion in three pieces:

1. **blend**: a 7-DoF ruckig state-to-state trajectory from the current state to the reference's
   state at ``t_c + h`` (``h``: the blend horizon), in at least ``h`` (ruckig's minimum duration),
   time-synchronised. When the limits make it longer, the target is moved to the later reference
   time it reaches (a few iterations), so the robot catches up as fast as the limits allow;
2. **follow**: the reference itself on its own timeline up to ``D - settle``, slowed uniformly by the
   factor ``k >= 1`` that keeps its velocity, acceleration and jerk within ``headroom`` of the
   limits (``k = 1`` when they already hold: then the hand-over happens when the human gets there),
   and further only where the checks ask by a :class:`~.time_warp.TimeWarp` of its timeline;
3. **settle**: ruckig from the reference's state at ``D - settle`` to rest at ``r(D)``, in at least
   the (slowed) time the reference takes for that last part.

The pieces meet with equal position, velocity and acceleration, so the acceleration is continuous
and the jerk between two control samples (the difference of their accelerations over the period)
is bounded by the pieces' jerks. The plan is sampled at the control rate; :func:`limit_ratios`
measures it against the limits (position limits and collisions are the caller's checks).
Ruckig is only asked for state-to-state trajectories (no intermediate waypoints).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from ruckig import ControlInterface, InputParameter, Result, Ruckig, RuckigError
from ruckig import Trajectory as RuckigTrajectory

from ..exceptions import InfeasibleError
from .ruckig_sampling import sample_trajectory
from .time_warp import TimeWarp
from .trajectory import JointLimits, MotionState, Trajectory

HEADROOM = 0.95
"""Fraction of the velocity, acceleration and jerk limits the followed reference may use; the rest
absorbs the difference between the reference's values on the control grid and between samples."""

SETTLE_S = 0.2
"""The last part of the reference, in [s], replaced by a ruckig settle to rest at the hand-over:
the Gaussian basis fits the demonstrations' slopes up to the ends of the phase range, which gives the
predicted mean's third derivative spurious peaks in its last few percent (e.g. 128 rad/s^3 at the
end against at most 46 rad/s^3 inside, on a ``chen2017_handover`` prediction); following them would
slow the whole motion down."""

CATCH_UP_ITERATIONS = 4
"""Re-targets of the blend to a later reference time when the limits make it longer than ``h``."""


class ReferenceMotion:
    """A predicted joint trajectory with exact derivatives: ``q_j(t) = sum_k phi_k(t / D) w_jk s_j + o_j``
    for ``t`` in [0, D] (Gaussian basis ``phi_k(z) = exp(-(z - c_k)^2 / (2 h^2))``); held at
    ``q(D)`` after ``D`` and at ``q(0)`` before 0.

    Args:
        weights: (J, K) basis weights (scaled units).
        centres: (K,) basis centres in phase units.
        width: Basis width ``h`` in phase units.
        scale: (J,) scaling to [rad] (``q = scaled * scale + offset``).
        offset: (J,) offset in [rad].
        duration_s: ``D`` in [s] (the predicted hand-over time, from the start of the motion).
    """

    def __init__(
        self,
        weights: np.ndarray,
        centres: np.ndarray,
        width: float,
        scale: np.ndarray,
        offset: np.ndarray,
        duration_s: float,
    ) -> None:
        self.weights = np.asarray(weights, dtype=float)
        self.centres = np.asarray(centres, dtype=float)
        self.width = float(width)
        self.scale = np.asarray(scale, dtype=float)
        self.offset = np.asarray(offset, dtype=float)
        self.duration_s = float(duration_s)
        if not (self.duration_s > 0 and math.isfinite(self.duration_s)):
            raise InfeasibleError(f"reference motion: duration must be positive, got {duration_s}")
        self._ws = np.ascontiguousarray((self.weights * self.scale[:, None]).T)  # (K, J), in [rad]

    @classmethod
    def from_prediction(
        cls, prediction, centres: np.ndarray | None = None, width: float | None = None
    ) -> ReferenceMotion:
        """The conditioned mean of a :class:`~ipromp_pin.promp.Prediction` (its ``robot_weights``)
        with the basis ``centres`` and ``width`` (default: the basis the prediction's robot weights
        carry, the model's ``IProMP.basis_``)."""
        w = prediction.robot_weights
        if w is None:
            raise InfeasibleError("reference motion: the prediction holds no robot weights")
        if centres is None or width is None:
            if w.basis is None:
                raise InfeasibleError("reference motion: the prediction's robot weights hold no basis")
            centres = w.basis.centres if centres is None else centres
            width = w.basis.width if width is None else width
        return cls(w.mean, centres, width, w.scale, w.offset, prediction.duration_s)

    def evaluate(
        self, t_s: np.ndarray, order: int = 3
    ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, np.ndarray | None]:
        """Position [rad], velocity [rad/s], acceleration [rad/s^2] and jerk [rad/s^3], each
        (len(t_s), J), at times ``t_s`` [s] (derivatives 0 outside [0, D]); derivatives above
        ``order`` are None."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        d = self.duration_s
        inv_h2 = 1.0 / (self.width * self.width)
        diff = np.clip(t, 0.0, d)[:, None] * (1.0 / d) - self.centres  # (n, K)
        phi = np.exp(diff * diff * (-0.5 * inv_h2))
        m0 = phi @ self._ws
        q = m0 + self.offset
        qd = qdd = qddd = None
        if order >= 1:
            u = diff * inv_h2
            up = u * phi
            m1 = up @ self._ws
            qd = m1 * (-1.0 / d)
            if order >= 2:
                u2p = u * up
                m2 = u2p @ self._ws
                qdd = (m2 - inv_h2 * m0) * (1.0 / d**2)
                if order >= 3:
                    m3 = (u * u2p) @ self._ws
                    qddd = (3.0 * inv_h2 * m1 - m3) * (1.0 / d**3)
        if t.size and (t.min() < 0.0 or t.max() > d):
            outside = ((t < 0.0) | (t > d))[:, None]
            qd, qdd, qddd = (None if x is None else np.where(outside, 0.0, x) for x in (qd, qdd, qddd))
        return q, qd, qdd, qddd

    def at(self, t_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration (J,) each at one time ``t_s`` [s]: :meth:`evaluate` of
        ``[t_s]`` to the bit (the same operations on the same shapes), without its handling of many
        times (a re-target asks for a few single times)."""
        d = self.duration_s
        inv_h2 = 1.0 / (self.width * self.width)
        diff = min(max(float(t_s), 0.0), d) * (1.0 / d) - self.centres[None, :]  # (1, K)
        phi = np.exp(diff * diff * (-0.5 * inv_h2))
        m0 = phi @ self._ws
        u = diff * inv_h2
        up = u * phi
        m1 = up @ self._ws
        m2 = (u * up) @ self._ws
        q = (m0 + self.offset)[0]
        if not 0.0 <= t_s <= d:
            zero = np.zeros_like(q)
            return q, zero, zero.copy()
        return q, (m1 * (-1.0 / d))[0], ((m2 - inv_h2 * m0) * (1.0 / d**2))[0]

    def end(self) -> np.ndarray:
        """The hand-over configuration ``q(D)`` (J,) in [rad] (kept: a re-target asks for it again)."""
        q_end = self.__dict__.get("_end")
        if q_end is None:
            q_end = self._end = self.evaluate(np.array([self.duration_s]), order=0)[0][0]
        return q_end.copy()


@dataclass(frozen=True)
class RetargetReport:
    """How a re-targeted motion (:meth:`Retargeter.plan`) meets its reference.

    Attributes:
        arrival_s: Time in [s] at which the motion comes to rest at the hand-over configuration.
        target_s: The reference's hand-over time ``D`` in [s].
        time_scale: Slow-down factor ``k`` of the followed reference (1: on the human's timeline).
        blend_s: Duration of the blend in [s].
    """

    arrival_s: float
    target_s: float
    time_scale: float = 1.0
    blend_s: float = 0.0

    @property
    def lateness_s(self) -> float:
        """How much later than the reference's hand-over time the motion comes to rest, in [s]."""
        return self.arrival_s - self.target_s


RUCKIG_MARGIN = 1e-6
"""Relative margin below the limits given to ruckig: its time-optimal segments reach their limits
exactly, so the sampled values would otherwise exceed them by rounding (1e-13)."""


class _Ruckig:
    """A reusable 7-DoF ruckig calculator for state-to-state trajectories."""

    def __init__(self, limits: JointLimits) -> None:
        n = limits.n_joints
        self.otg = Ruckig(n)
        self.inp = InputParameter(n)
        keep = 1.0 - RUCKIG_MARGIN
        self.inp.max_velocity = limits.velocity_rad_s * keep
        self.inp.max_acceleration = limits.acceleration_rad_s2 * keep
        self.inp.max_jerk = limits.jerk_rad_s3 * keep

    def __call__(
        self, start: tuple[np.ndarray, ...], target: tuple[np.ndarray, ...], min_duration: float | None
    ) -> RuckigTrajectory:
        inp = self.inp
        inp.current_position, inp.current_velocity, inp.current_acceleration = start
        inp.target_position, inp.target_velocity, inp.target_acceleration = target
        inp.minimum_duration = None if min_duration is None or min_duration <= 0 else float(min_duration)
        traj = RuckigTrajectory(len(start[0]))
        try:
            result = self.otg.calculate(inp, traj)
        except RuckigError as exc:
            raise InfeasibleError("ruckig: " + " ".join(str(exc).split())) from exc
        if result not in (Result.Working, Result.Finished):
            raise InfeasibleError(f"ruckig: no trajectory to the target ({result})")
        return traj


class Retargeter:
    """Builds re-targeted motions under one set of limits (:func:`retarget` for one call).

    Args:
        limits: Velocity, acceleration and jerk limits (positions are checked by the caller).
        dt_s: Control period in [s].
        blend_s: Blend horizon ``h`` in [s].
        headroom: Fraction of the limits the followed reference may use.
        settle_s: The last part of the reference, in [s], that is not followed: ruckig settles from
            the reference's state there to rest at the hand-over configuration, arriving no earlier
            than the reference does.
    """

    def __init__(
        self,
        limits: JointLimits,
        dt_s: float,
        blend_s: float,
        headroom: float = HEADROOM,
        settle_s: float = SETTLE_S,
    ) -> None:
        if not (dt_s > 0 and math.isfinite(dt_s)):
            raise InfeasibleError(f"control period must be positive, got {dt_s}")
        if not (blend_s > 0 and math.isfinite(blend_s)):
            raise InfeasibleError(f"blend horizon must be positive, got {blend_s}")
        if not 0 < headroom <= 1:
            raise InfeasibleError(f"headroom must be in (0, 1], got {headroom}")
        self.limits = limits
        self.dt_s = float(dt_s)
        self.blend_s = float(blend_s)
        self.headroom = float(headroom)
        if not (settle_s >= 0 and math.isfinite(settle_s)):
            raise InfeasibleError(f"settle window must be >= 0, got {settle_s}")
        self.settle_s = float(settle_s)
        self._ruckig = _Ruckig(limits)
        self._scale_cache: tuple[ReferenceMotion, tuple[float, ...], float] | None = None

    def time_scale(self, qd: np.ndarray, qdd: np.ndarray, qddd: np.ndarray) -> float:
        """Smallest uniform slow-down ``k >= 1`` keeping derivatives (n, J) within headroom of the limits."""
        lim = self.limits
        h = self.headroom
        rv = float(np.max(np.abs(qd) / lim.velocity_rad_s)) / h if qd.size else 0.0
        ra = float(np.max(np.abs(qdd) / lim.acceleration_rad_s2)) / h if qdd.size else 0.0
        rj = float(np.max(np.abs(qddd) / lim.jerk_rad_s3)) / h if qddd.size else 0.0
        return max(1.0, rv, math.sqrt(ra), rj ** (1.0 / 3.0))

    def reachable_scale(self, v: np.ndarray, a: np.ndarray, k: float) -> float:
        """The smallest slow-down ``>= k`` that makes the state (``v / k``, ``a / k^2``) (J,) a valid
        ruckig target: a state with acceleration ``a`` passes through the velocity ``|v| + a^2 / 2j``
        (before it when decelerating, after it when accelerating), which must stay below the limit."""
        lim = self.limits
        cap = 0.98 * lim.velocity_rad_s
        for _ in range(200):
            if np.all(np.abs(v) / k + (a / k**2) ** 2 / (2.0 * lim.jerk_rad_s3) <= cap):
                return k
            k *= 1.02
        return k

    def _reference_scale(self, reference: ReferenceMotion, t_c: float, d_follow: float) -> float:
        """:meth:`time_scale` of the followed reference on the control grid from ``t_c + h`` to
        ``d_follow`` [s]; kept for the next call with the same reference and start (the slower
        re-targets of one re-plan follow the same reference from the same tick)."""
        key = (t_c, d_follow, self.blend_s, self.dt_s)
        hit = self._scale_cache
        if hit is not None and hit[0] is reference and hit[1] == key:
            return hit[2]
        grid = np.append(np.arange(t_c + self.blend_s, d_follow, self.dt_s), d_follow)
        _, v, a, j = reference.evaluate(grid)
        assert v is not None and a is not None and j is not None  # order 3: every derivative
        k = self.time_scale(v, a, j)
        self._scale_cache = (reference, key, k)
        return k

    def plan(
        self, state: MotionState, reference: ReferenceMotion, min_scale: float = 1.0
    ) -> tuple[Trajectory, RetargetReport]:
        """The remaining motion from ``state`` (at a control tick) onto ``reference``'s timeline: its
        samples at the control rate from ``state.t_s`` (the start state first, at rest at the end)
        and how it meets the reference.

        ``min_scale``: the followed reference goes at least this many times slower (``k >= 1``; a check
        that asks for a slower motion, :mod:`ipromp_pin.safety.retime`).

        Raises:
            InfeasibleError: ruckig finds no trajectory, or the sampled plan exceeds a limit.
        """
        planned = self.planned(state, reference, min_scale)
        return planned.sample(), planned.report

    def planned(
        self,
        state: MotionState,
        reference: ReferenceMotion,
        min_scale: float = 1.0,
        warp: TimeWarp | None = None,
    ) -> Planned:
        """:meth:`plan` up to its samples: the pieces and the report, the samples made on demand
        (:meth:`Planned.sample`; a caller that needs only the report saves their cost). ``warp``:
        the followed reference slowed further where it asks, and the catch-up with it
        (:mod:`.time_warp`)."""
        h = self.blend_s
        t_c = float(state.t_s)
        d_end = reference.duration_s
        start = (state.q, state.qd, state.qdd)
        q_end = reference.end()
        # (kind, t_begin, t_end, data): data a ruckig trajectory, or (tau0, k, warp) of a followed piece
        pieces: list[tuple[str, float, float, Any]] = []
        k = 1.0
        zeros = np.zeros_like(q_end)
        d_follow = d_end - self.settle_s
        slower = float(min_scale) * (1.0 if warp is None else warp.catch_up)
        if t_c + h >= d_follow:
            blend = self._ruckig(start, (q_end, zeros, zeros), d_end - t_c)
            if slower > 1.0:  # the last blend, stretched: ruckig's time-optimal profile k times longer
                blend = self._ruckig(start, (q_end, zeros, zeros), blend.duration * slower)
                k = float(min_scale)
            pieces.append(("ruckig", t_c, t_c + blend.duration, blend))
            blend_s = blend.duration
        else:
            k = max(self._reference_scale(reference, t_c, d_follow), float(min_scale))
            target_t = t_c + h
            k_follow = k
            for _ in range(CATCH_UP_ITERATIONS):
                tau0 = target_t
                q0, v0, a0 = reference.at(tau0)
                k = self.reachable_scale(v0, a0, k_follow)
                # a slowed plan (min_scale > 1) catches up min_scale times slower too: the catch-up is
                # part of the motion the checks asked to slow down
                window = (tau0 - t_c) * slower
                blend = self._ruckig(start, _followed_state(q0, v0, a0, tau0, k, warp), window)
                if blend.duration <= window + 1e-9 or tau0 >= d_follow:
                    break
                target_t = min(t_c + blend.duration, d_follow)
            blend_s = blend.duration
            t_b = t_c + blend.duration
            span = k * (d_follow - tau0) if warp is None else warp.span_s(tau0, d_follow, k)
            t_f = t_b + span
            pieces.append(("ruckig", t_c, t_b, blend))
            pieces.append(("follow", t_b, t_f, (tau0, k, warp)))
            q_f, v_f, a_f = reference.at(d_follow)
            g_end = 1.0 if warp is None else float(warp.factor(d_follow))
            settle = self._ruckig(
                _followed_state(q_f, v_f, a_f, d_follow, k, warp),
                (q_end, zeros, zeros),
                k * g_end * self.settle_s,
            )
            pieces.append(("ruckig", t_f, t_f + settle.duration, settle))
        arrival = pieces[-1][2]
        report = RetargetReport(float(arrival), d_end, float(k), float(blend_s))
        return Planned(state, reference, q_end, pieces, report, self.dt_s, self.limits.joint_names)


class Planned:
    """A re-targeted motion (:meth:`Retargeter.planned`) before its samples: its report, and its
    samples at the control rate made on demand (:meth:`sample`, once).

    Attributes:
        report: How the motion meets its reference.
    """

    def __init__(
        self,
        state: MotionState,
        reference: ReferenceMotion,
        q_end: np.ndarray,
        pieces: list[tuple[str, float, float, Any]],
        report: RetargetReport,
        dt_s: float,
        joint_names: tuple[str, ...],
    ) -> None:
        self.report = report
        self._args = (state, reference, q_end, pieces, dt_s, joint_names)
        self._motion: Trajectory | None = None

    def sample(self) -> Trajectory:
        """The motion's samples at the control rate from the start state's time (the start state
        first, at rest at the hand-over configuration at the end)."""
        if self._motion is None:
            self._motion = _sample_pieces(*self._args)
        return self._motion

    def followed(self, times_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """At times ``times_s`` (n,) [s] of the motion: which piece moves it (0: the catch-up,
        1: the followed reference, 2: the settle to rest) and the reference time [s] it follows
        there (NaN outside the followed piece)."""
        t = np.asarray(times_s, dtype=float)
        which = np.zeros(t.size, dtype=int)
        tau = np.full(t.size, np.nan)
        pieces = self._args[3]
        if len(pieces) < 3:  # one blend to rest: nothing followed
            return which, tau
        _, t_b, t_f, data = pieces[1]
        inside = (t >= t_b) & (t < t_f)
        which[inside] = 1
        which[t >= t_f] = 2
        tau[inside] = followed_times(data, t[inside] - t_b)
        return which, tau


def _sample_pieces(
    state: MotionState,
    reference: ReferenceMotion,
    q_end: np.ndarray,
    pieces: list[tuple[str, float, float, Any]],
    dt: float,
    joint_names: tuple[str, ...],
) -> Trajectory:
    """The samples of a re-targeted motion's pieces (:meth:`Retargeter.planned`) every ``dt`` [s]."""
    t_c = float(state.t_s)
    arrival = pieces[-1][2]
    n = int(math.ceil((arrival - t_c) / dt - 1e-9)) + 1
    times = t_c + dt * np.arange(n)
    nj = q_end.size
    q = np.empty((n, nj))
    qd = np.empty((n, nj))
    qdd = np.empty((n, nj))
    for kind, t0, t1, data in pieces:
        i0 = max(0, int(math.ceil((t0 - t_c) / dt - 1e-9)))
        i1 = min(n, int(math.ceil((t1 - t_c) / dt - 1e-9)))
        if i1 <= i0:
            continue
        sel = slice(i0, i1)
        if kind == "ruckig":
            q[sel], qd[sel], qdd[sel] = sample_trajectory(data, times[sel] - t0)
        elif data[2] is None:  # the uniform follower, as before warps: the same operations, to the bit
            tau0_, k_, _ = data
            tq, tv, ta, _ = reference.evaluate(tau0_ + (times[sel] - t0) / k_, order=2)
            assert tv is not None and ta is not None
            q[sel], qd[sel], qdd[sel] = tq, tv / k_, ta / k_**2
        else:
            tau = followed_times(data, times[sel] - t0)
            tq, tv, ta, _ = reference.evaluate(tau, order=2)
            assert tv is not None and ta is not None
            rate, accel = data[2].rates(tau, data[1])
            q[sel], qd[sel], qdd[sel] = tq, tv * rate[:, None], ta * (rate**2)[:, None] + tv * accel[:, None]
    q[-1], qd[-1], qdd[-1] = q_end, 0.0, 0.0
    q[0], qd[0], qdd[0] = state.q, state.qd, state.qdd
    return Trajectory(times, q, qd, qdd, joint_names)


def followed_times(follow: tuple[float, float, TimeWarp | None], elapsed_s: np.ndarray) -> np.ndarray:
    """The reference times (n,) [s] a follow piece ``(tau0, k, warp)`` reaches ``elapsed_s`` (n,) [s]
    after it starts."""
    tau0, k, warp = follow
    if warp is None:
        return tau0 + np.asarray(elapsed_s, dtype=float) / k
    return warp.reference_times(elapsed_s, tau0, k)


def _followed_state(
    q: np.ndarray, v: np.ndarray, a: np.ndarray, tau: float, k: float, warp: TimeWarp | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The follower's state (J,) each where it passes reference time ``tau`` [s], the reference's
    state there being ``q``, ``v``, ``a``: ``(q, v tau', a tau'^2 + v tau'')``."""
    if warp is None:
        return q, v / k, a / k**2
    rate, accel = (float(x[0]) for x in warp.rates(np.array([tau]), k))
    return q, v * rate, a * rate**2 + v * accel


def retarget(
    state: MotionState,
    reference: ReferenceMotion,
    limits: JointLimits,
    dt_s: float,
    blend_s: float,
    headroom: float = HEADROOM,
    settle_s: float = SETTLE_S,
) -> tuple[Trajectory, RetargetReport]:
    """The remaining motion from ``state`` onto ``reference``'s timeline (see the module docstring)."""
    return Retargeter(limits, dt_s, blend_s, headroom, settle_s).plan(state, reference)


def stop_motion(state: MotionState, limits: JointLimits, dt_s: float, hold_s: float = 0.0) -> Trajectory:
    """The quickest jerk-limited stop from ``state`` (a control tick's commanded state): ruckig's
    velocity interface brings every joint's velocity and acceleration to zero together, within the
    velocity, acceleration and jerk ``limits`` (less :data:`RUCKIG_MARGIN`), wherever the joints then
    are; then at rest there for ``hold_s`` [s]. Sampled every ``dt_s`` [s] from ``state.t_s`` (the
    start state first, at rest at the end).

    Raises:
        InfeasibleError: ruckig finds no stop.
    """
    n = limits.n_joints
    otg = Ruckig(n)
    inp = InputParameter(n)
    keep = 1.0 - RUCKIG_MARGIN
    inp.control_interface = ControlInterface.Velocity
    inp.max_velocity = limits.velocity_rad_s * keep
    inp.max_acceleration = limits.acceleration_rad_s2 * keep
    inp.max_jerk = limits.jerk_rad_s3 * keep
    inp.current_position, inp.current_velocity, inp.current_acceleration = state.q, state.qd, state.qdd
    inp.target_velocity = np.zeros(n)
    inp.target_acceleration = np.zeros(n)
    traj = RuckigTrajectory(n)
    try:
        result = otg.calculate(inp, traj)
    except RuckigError as exc:
        raise InfeasibleError("ruckig stop: " + " ".join(str(exc).split())) from exc
    if result not in (Result.Working, Result.Finished):
        raise InfeasibleError(f"ruckig stop: no trajectory to rest ({result})")
    n_stop = int(math.ceil(traj.duration / dt_s - 1e-9))
    n_hold = int(round(max(hold_s, 0.0) / dt_s))
    t = dt_s * np.arange(n_stop + n_hold + 1)
    q, qd, qdd = sample_trajectory(traj, np.minimum(t, traj.duration))
    qd[n_stop:], qdd[n_stop:] = 0.0, 0.0  # at rest from the stop's end (ruckig's end state, to the bit)
    q[n_stop:] = q[n_stop]
    q[0], qd[0], qdd[0] = state.q, state.qd, state.qdd
    return Trajectory(float(state.t_s) + t, q, qd, qdd, limits.joint_names)
