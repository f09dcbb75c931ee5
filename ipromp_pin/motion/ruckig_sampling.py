"""A ruckig trajectory's states at many times in one call: :func:`sample_trajectory`.

``Trajectory.at_time`` of ruckig's Python module takes one time per call (about 1.8 us each, most
of it the call and the conversion of its result); a re-plan samples its ruckig pieces at every control
tick. :func:`sample_trajectory` reads the trajectory's constant-jerk profiles once and integrates
every (time, joint) pair with numpy, in the operations and order ruckig's ``at_time`` uses, so the
states are ruckig's bit for bit (``tests/motion/test_ruckig_sampling.py`` holds them to it on random
trajectories with and without brake pre-profiles, and past the end):

* a joint's brake pre-profile (``brake.duration > 0``: the start state exceeds a limit) first, in
  its two segments;
* then its seven constant-jerk segments, the segment of ``t`` being the upper bound of ``t`` in
  their cumulative durations (the eighth state, held with constant acceleration, past the last);
* from the trajectory's duration on, every joint's final state with constant acceleration.

Each segment's state is ``integrate(t, p, v, a, j) = (p + t (v + t (a/2 + t j/6)), v + t (a +
t j/2), a + t j)``, as in ruckig. Only single-section trajectories (state to state, no intermediate
waypoints: the only kind this package asks ruckig for) of at least :data:`VECTOR_FROM` times are
sampled this way; fewer times, or other trajectories, go through ``at_time``.
"""

from __future__ import annotations

import numpy as np
from ruckig import Trajectory

__all__ = ["sample_trajectory"]

_N_SEG = 7
"""Constant-jerk segments of a ruckig profile (its states: 8)."""

VECTOR_FROM = 80
"""Fewest times sampled in one numpy pass: below, ``at_time`` per time is faster (a pass costs about
100 us plus 0.3 us per time, ``at_time`` about 1.8 us per time, on this project's machine; 320 times:
186 against 600 us)."""


def _integrate(
    t: np.ndarray, p: np.ndarray, v: np.ndarray, a: np.ndarray, j: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity and acceleration after ``t`` [s] of constant jerk ``j`` from (p, v, a),
    elementwise, in ruckig's order of operations."""
    return p + t * (v + t * (a / 2 + t * j / 6)), v + t * (a + t * j / 2), a + t * j


def _at_time_loop(traj: Trajectory, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The states through ``at_time``, one time per call."""
    out = [traj.at_time(float(t)) for t in times]
    n = len(out)
    return tuple(np.array([o[i] for o in out], dtype=float).reshape(n, -1) for i in range(3))  # type: ignore[return-value]


def sample_trajectory(traj: Trajectory, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions, velocities and accelerations (len(times), n_dofs) of a ruckig trajectory at
    ``times`` (N,) [s] from its start, equal to ruckig's ``at_time`` (see the module docstring)."""
    t = np.asarray(times, dtype=float).reshape(-1)
    if t.size == 0:
        empty = np.empty((0, traj.degrees_of_freedom))
        return empty, empty.copy(), empty.copy()
    sections = traj.profiles
    if len(sections) != 1 or t.size < VECTOR_FROM:
        return _at_time_loop(traj, t)
    prof = sections[0]
    nd = len(prof)
    # per joint (rows): states p, v, a (8 each), jerks (7, and 0 for the held last state), the
    # segment durations (7) behind a 0, and the brake pre-profile's duration
    rows = np.array([[*p.p, *p.v, *p.a, *p.j, 0.0, 0.0, *p.t, p.brake.duration] for p in prof])
    states = rows[:, :32].reshape(nd, 4, 8).transpose(2, 0, 1).reshape(-1, 4)  # row k nd + d: p, v, a, j
    ends = np.zeros((_N_SEG + 1, nd))  # 0, then the cumulative durations (ruckig's t_sum)
    np.cumsum(rows[:, 33:40].T, axis=0, out=ends[1:])
    brake_s = rows[:, 40]
    cols = np.arange(nd)
    tc = t[:, None]
    td = tc - brake_s  # time into the seven segments (exact t without a brake)
    seg = np.empty(td.shape, dtype=np.intp)
    for d in range(nd):
        seg[:, d] = np.searchsorted(ends[1:, d], td[:, d], side="right")
    after = t >= traj.duration
    if after.any():
        seg[after] = _N_SEG
    flat = seg * nd + cols
    dt = td - ends.ravel()[flat]
    if after.any():
        dt[after] = tc[after] - (brake_s + ends[_N_SEG])
    start = states[flat]
    sp, sv, sa, sj = start[..., 0], start[..., 1], start[..., 2], start[..., 3]
    if (brake_s > 0).any():
        brake = np.array([[*p.brake.p, *p.brake.v, *p.brake.a, *p.brake.j, p.brake.t[0]] for p in prof]).T
        inside = (tc < brake_s) & (brake_s > 0) & ~after[:, None]
        second = (tc >= brake[8]).astype(np.intp)  # the brake's second segment
        bflat = second * nd + cols
        dt = np.where(inside, np.where(second > 0, tc - brake[8], tc), dt)
        sp, sv, sa, sj = (
            np.where(inside, brake[2 * i : 2 * i + 2].ravel()[bflat], x)
            for i, x in enumerate((sp, sv, sa, sj))
        )
    return _integrate(dt, sp, sv, sa, sj)
