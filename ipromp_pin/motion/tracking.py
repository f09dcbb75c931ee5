"""The ruckig stages of a timing: a 1-D jerk-limited tracker of a path-coordinate profile, and a
state-to-state segment that brings a moving arm to rest.

Ruckig is only ever asked for state-to-state trajectories: intermediate waypoints are never passed
(the community build would try to reach a cloud service over the network for them).
"""

from __future__ import annotations

import math

import numpy as np
from ruckig import InputParameter, OutputParameter, Result, Ruckig, RuckigError

from ..exceptions import InfeasibleError
from .trajectory import JointLimits


def ruckig_update(otg: Ruckig, inp: InputParameter, out: OutputParameter) -> Result:
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


def track_1d(
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
        result = ruckig_update(otg, inp, out)
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


def ruckig_to_rest(
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
        result = ruckig_update(otg, inp, out)
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
