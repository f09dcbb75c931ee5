"""Feasibility checks of a predicted joint path ``q`` (M, n_joints) in [rad], and :func:`check_path`.

* ``joint_limits``: every sample inside [lower + margin, upper - margin] (URDF limits, settings margin);
* ``self_collision``: minimum collision distance along the path (:mod:`ipromp_pin.robot.collision`);
* ``workspace``: the hand-over position (FK of the last sample) inside the settings' workspace;
* ``hand_distance``: gripper-hand distance at the hand-over, when the human hand position is known;
* ``uncertainty`` (advisory, not part of ``passed``): hand-over configurations drawn from the
  prediction (samples, or the mean +/- 2 sigma per joint) checked for limits and collisions, and
  the spread of their hand-over positions.
"""

from __future__ import annotations

import time

import numpy as np

from .collision import check_self_collision, in_collision
from .kinematics import as_joint_path, ee_positions, frame_placements, rotations_to_quat_xyzw
from .model import Robot
from .report import CheckResult, FeasibilityReport


def check_joint_limits(
    robot: Robot, q: np.ndarray, margin_rad: float | np.ndarray | None = None, t_s: np.ndarray | None = None
) -> CheckResult:
    """Joint-limit check with margins for a path (M, n_joints) in [rad].

    ``values``: ``min_slack_rad`` (smallest distance to a margin-shrunk limit; negative = violated),
    ``joint``, ``sample``, ``n_violations`` (samples x joints), ``margin_rad``.
    """
    q = as_joint_path(robot, q)
    margin = (
        robot.settings.position_margin_rad
        if margin_rad is None
        else np.broadcast_to(margin_rad, (q.shape[1],))
    )
    lo = robot.lower_rad + margin
    hi = robot.upper_rad - margin
    slack = np.minimum(q - lo, hi - q)
    i, j = np.unravel_index(int(np.argmin(slack)), slack.shape)
    s = float(slack[i, j])
    n_bad = int(np.count_nonzero(slack < 0))
    name = robot.joint_names[j]
    at = f"sample {i}" if t_s is None else f"t={float(t_s[i]):.2f} s"
    side = "lower" if q[i, j] - lo[j] <= hi[j] - q[i, j] else "upper"
    values = {
        "min_slack_rad": s,
        "joint": name,
        "sample": int(i),
        "side": side,
        "n_violations": n_bad,
        "margin_rad": [float(m) for m in np.atleast_1d(margin)],
    }
    if s < 0:
        reason = (
            f"{name} = {q[i, j]:.4f} rad at {at} is {-s:.4f} rad beyond its {side} limit "
            f"(with margin: [{lo[j]:.4f}, {hi[j]:.4f}]); {n_bad} violations"
        )
        return CheckResult("joint_limits", "fail", reason, values)
    return CheckResult(
        "joint_limits", "pass", f"smallest slack {s:.4f} rad ({name}, {side} limit, {at})", values
    )


def check_workspace(robot: Robot, position_m: np.ndarray) -> CheckResult:
    """Hand-over position (3,) in [m] inside the settings' workspace.

    ``values``: ``position_m``, ``distance_outside_m`` (negative = depth inside), ``workspace``.
    """
    p = np.asarray(position_m, dtype=float)
    ws = robot.settings.workspace
    d = ws.distance_outside(p)
    values = {"position_m": p.tolist(), "distance_outside_m": d, "workspace": ws.to_dict()}
    pos = f"({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m"
    if d > 0:
        return CheckResult(
            "workspace", "fail", f"hand-over position {pos} is {d * 1e3:.0f} mm outside", values
        )
    return CheckResult(
        "workspace", "pass", f"hand-over position {pos} inside ({-d * 1e3:.0f} mm deep)", values
    )


def check_hand_distance(
    robot: Robot,
    position_m: np.ndarray,
    hand_position_m: np.ndarray | None,
    max_distance_m: float | None = None,
) -> CheckResult:
    """Gripper-hand distance at the hand-over (skipped when the hand position is unknown or NaN)."""
    limit = robot.settings.max_hand_distance_m if max_distance_m is None else float(max_distance_m)
    if hand_position_m is None or not np.all(np.isfinite(hand_position_m)):
        return CheckResult(
            "hand_distance", "skip", "human hand position unknown", {"max_distance_m": limit}, required=False
        )
    h = np.asarray(hand_position_m, dtype=float).reshape(3)
    d = float(np.linalg.norm(np.asarray(position_m, dtype=float) - h))
    values = {"distance_m": d, "max_distance_m": limit, "hand_position_m": h.tolist()}
    if d > limit:
        reason = f"gripper is {d * 1e3:.0f} mm from the hand (max {limit * 1e3:.0f} mm)"
        return CheckResult("hand_distance", "fail", reason, values)
    return CheckResult("hand_distance", "pass", f"gripper-hand distance {d * 1e3:.0f} mm", values)


def check_uncertainty(
    robot: Robot,
    q_end: np.ndarray,
    *,
    q_samples: np.ndarray | None = None,
    q_std: np.ndarray | None = None,
    max_samples: int = 16,
) -> CheckResult:
    """Advisory check of the hand-over's uncertainty.

    Args:
        robot: Loaded robot.
        q_end: Predicted hand-over configuration (n_joints,) in [rad].
        q_samples: Sampled trajectories (n, M, n_joints) or hand-over configurations (n, n_joints);
            at most ``max_samples`` are checked (their last point).
        q_std: Standard deviation (n_joints,) in [rad] at the hand-over; used when no samples are
            given: the 2 * n_joints configurations mean +/- 2 sigma (one joint at a time).

    ``values``: ``n_configs``, ``n_outside_limits`` (hard URDF limits), ``n_in_collision`` (contact
    test, no distances: it is the cheap part of the budget), ``position_spread_mm`` (max distance of a
    hand-over position from the mean's).
    """
    q_end = np.asarray(q_end, dtype=float).reshape(-1)
    if q_samples is not None:
        s = np.asarray(q_samples, dtype=float)
        ends = s[:, -1, :] if s.ndim == 3 else s.reshape(-1, robot.n_joints)
        ends = ends[:max_samples]
        kind = f"{ends.shape[0]} sampled hand-overs"
    elif q_std is not None:
        sd = np.broadcast_to(np.asarray(q_std, dtype=float).reshape(-1), q_end.shape)
        ends = np.vstack([q_end + 2 * np.diag(sd), q_end - 2 * np.diag(sd)])
        kind = "mean +/- 2 sigma per joint"
    else:
        return CheckResult("uncertainty", "skip", "no uncertainty given", {}, required=False)
    ends = as_joint_path(robot, ends, "q_samples")
    outside = np.any((ends < robot.lower_rad) | (ends > robot.upper_rad), axis=1)
    colliding = in_collision(robot, ends)  # contact test only (~0.1 ms each), no distances
    p_mean = ee_positions(robot, q_end)[0]
    spread = float(np.max(np.linalg.norm(ee_positions(robot, ends) - p_mean, axis=1)))
    values = {
        "n_configs": int(ends.shape[0]),
        "kind": kind,
        "n_outside_limits": int(outside.sum()),
        "n_in_collision": int(colliding.sum()),
        "position_spread_mm": spread * 1e3,
    }
    status = "fail" if outside.any() or colliding.any() else "pass"
    reason = (
        f"{kind}: {int(outside.sum())} outside joint limits, {int(colliding.sum())} in collision, "
        f"hand-over spread {spread * 1e3:.0f} mm"
    )
    return CheckResult("uncertainty", status, reason, values, required=False)


def check_path(
    robot: Robot,
    q: np.ndarray,
    *,
    t_s: np.ndarray | None = None,
    q_samples: np.ndarray | None = None,
    q_std: np.ndarray | None = None,
    hand_position_m: np.ndarray | None = None,
) -> FeasibilityReport:
    """Run every feasibility check on a predicted joint path.

    Args:
        robot: Loaded robot (:func:`ipromp_pin.robot.load_robot`).
        q: Predicted arm joint path (M, n_joints) in [rad]; the last sample is the hand-over.
        t_s: Optional sample times (M,) in [s], named in the messages
            (:func:`~ipromp_pin.handover.one_shot.plan` passes the times at which the timed trajectory
            passes the samples).
        q_samples: Optional sampled trajectories (n, M, n_joints) (advisory uncertainty check).
        q_std: Optional hand-over standard deviation (n_joints,) in [rad] (used without samples).
        hand_position_m: Optional human hand position (3,) in [m] in the base frame at the hand-over.

    Raises:
        InfeasibleError: ``q`` has the wrong shape or contains NaN/inf.
    """
    q = as_joint_path(robot, q)
    timings = {}
    t0 = time.perf_counter()
    pos, rot = frame_placements(robot, q)
    handover = np.hstack([pos[-1], rotations_to_quat_xyzw(rot[-1:])[0]])
    t1 = time.perf_counter()
    checks = [check_joint_limits(robot, q, t_s=t_s)]
    t2 = time.perf_counter()
    checks.append(check_self_collision(robot, q, t_s=t_s))
    t3 = time.perf_counter()
    checks.append(check_workspace(robot, pos[-1]))
    checks.append(check_hand_distance(robot, pos[-1], hand_position_m))
    checks.append(check_uncertainty(robot, q[-1], q_samples=q_samples, q_std=q_std))
    t4 = time.perf_counter()
    timings = {
        "fk": (t1 - t0) * 1e3,
        "joint_limits": (t2 - t1) * 1e3,
        "self_collision": (t3 - t2) * 1e3,
        "other": (t4 - t3) * 1e3,
    }
    return FeasibilityReport(robot.settings.name, checks, handover, pos, timings)
