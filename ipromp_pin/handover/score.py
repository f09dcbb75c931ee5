"""How well a closed-loop run did against the recorded demo: where and when the robot got there.

* **hand-over error**: distance in [cm] between the commanded gripper position at the recorded
  hand-over time (the demo's end, where the evaluation takes the hand-over point) and the recorded
  gripper position then;
* **final error**: the same where the commanded motion comes to rest;
* **arrival delay**: commanded arrival minus the recorded robot's arrival, in [s]. A gripper
  *arrives* at the first time after which it stays within :data:`ARRIVAL_TOLERANCE_M` of where it
  ends (its final resting position, resp. the recorded one at the demo's end). The recorded robot
  still creeps at 2-6 cm/s when a demo ends and arrives 0.3-0.9 s before it (``chen2017_handover``
  10th-90th percentiles with 1 cm), so the same rule is applied to both;
* **limit ratio**: the largest |velocity|, |acceleration| or |jerk| (difference of consecutive
  accelerations over the control period) over its limit at any control sample;
* **collisions**: commanded control samples in contact (Pinocchio/coal contact test of every
  sample, independent of the certification the planner did before committing);
* **the human** (recordings with a skeleton, filled in by the closed-loop evaluation): the
  separation and contact-speed measures against the recorded human motion
  (:mod:`~ipromp_pin.handover.human_score`) and the arrival delay of the same replay without the
  human checks.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..data import ROBOT, Demo
from ..motion.retarget import limit_ratios
from ..robot import Robot, ee_positions, frame_placements
from ..robot.collision import in_collision
from ..robot.rotations import geodesic_deg
from .closed_loop import ClosedLoopResult

ARRIVAL_TOLERANCE_M = 0.01
"""A gripper has arrived once it stays within this distance [m] of its final position."""


def arrival_time(t_s: np.ndarray, positions_m: np.ndarray, tolerance_m: float = ARRIVAL_TOLERANCE_M) -> float:
    """First time in [s] after which ``positions_m`` (N, 3) stay within ``tolerance_m`` of the last one."""
    far = np.linalg.norm(positions_m - positions_m[-1], axis=1) > tolerance_m
    idx = np.flatnonzero(far)
    return float(t_s[0] if idx.size == 0 else t_s[min(idx[-1] + 1, t_s.size - 1)])


@dataclass
class ClosedLoopScore:
    """The measures of one closed-loop run against its recorded demo (see the module docstring).

    Attributes:
        handover_error_cm: Commanded vs recorded gripper position at the recorded hand-over time, [cm].
        final_error_cm: Commanded resting vs recorded hand-over gripper position, [cm].
        arrival_delay_s: Commanded minus recorded arrival, [s].
        arrival_s: Commanded arrival, [s] from the motion start.
        recorded_arrival_s: Recorded robot's arrival, [s].
        handover_time_s: Recorded hand-over time (the demo's end), [s].
        rest_s: When the commanded motion comes to rest, [s].
        max_limit_ratio: Largest of ``limit_ratios``.
        limit_ratios: Largest |v|, |a|, |jerk| over their limits at any control sample (3,).
        position_excess_rad: Largest excursion beyond the margin-shrunk position limits, [rad].
        collisions: Commanded control samples in contact.
        replans: Re-plans made.
        refused_replans: Re-plans not committed.
        final_task: Task of the last committed re-plan ("" if none).
        handover_orientation_error_deg: Geodesic angle between the commanded and the recorded gripper
            rotations at the recorded hand-over time, in [deg].
        peak_torque_ratio: Largest |joint torque| / effort limit of the commanded motion (the task's
            object included while held), when the caller computed it (NaN otherwise).
        human_min_separation_m: Smallest robot-body distance outside the hand region against the
            recorded human, [m] (None: no skeleton, or not measured).
        protective_distance_time_s: Time closer than the protective separation distance, [s].
        contact_speed_violations: Control samples inside it faster than the contact-speed limit.
        arrival_delay_without_human_s: ``arrival_delay_s`` of the same replay without the human
            checks, [s].
    """

    handover_error_cm: float
    final_error_cm: float
    arrival_delay_s: float
    arrival_s: float
    recorded_arrival_s: float
    handover_time_s: float
    rest_s: float
    max_limit_ratio: float
    limit_ratios: list[float]
    position_excess_rad: float
    collisions: int
    replans: int
    refused_replans: int
    final_task: str
    handover_orientation_error_deg: float = float("nan")
    peak_torque_ratio: float = float("nan")
    human_min_separation_m: float | None = None
    protective_distance_time_s: float | None = None
    contact_speed_violations: int | None = None
    arrival_delay_without_human_s: float | None = None

    def to_dict(self) -> dict:
        """JSON-serialisable form."""
        return asdict(self)


def handover_orientation_error_deg(robot: Robot, q_commanded: np.ndarray, q_recorded: np.ndarray) -> float:
    """Geodesic angle in [deg] between the gripper rotations (forward kinematics) of a commanded and a
    recorded arm configuration (n_joints,) in [rad], e.g. at the hand-over."""
    rot = frame_placements(robot, np.stack([q_commanded, q_recorded]))[1]
    return float(geodesic_deg(rot[0], rot[1]))


def score_closed_loop(
    result: ClosedLoopResult,
    demo: Demo,
    robot: Robot,
    tolerance_m: float = ARRIVAL_TOLERANCE_M,
    check_collisions: bool = True,
) -> ClosedLoopScore:
    """Measure a closed-loop run against the recorded demo it replayed."""
    traj = result.trajectory
    t_demo = demo.t - demo.t[0]
    truth = demo.groups[ROBOT]
    t_end = float(t_demo[-1])
    q_at = np.array([np.interp(t_end, traj.t_s, traj.q[:, j]) for j in range(traj.q.shape[1])])
    p_cmd = ee_positions(robot, traj.q)
    p_true = ee_positions(robot, truth)
    p_at, p_rest = ee_positions(robot, np.stack([q_at, traj.q[-1]]))
    arrival = arrival_time(traj.t_s, p_cmd, tolerance_m)
    recorded = arrival_time(t_demo, p_true, tolerance_m)
    lim = result.profile.limits
    ratios = limit_ratios(traj.qd, traj.qdd, 1.0 / result.settings.control_rate_hz, lim)
    excess = float(np.max(np.maximum(np.maximum(lim.lower_rad - traj.q, traj.q - lim.upper_rad), 0.0)))
    collisions = int(np.count_nonzero(in_collision(robot, traj.q))) if check_collisions else 0
    committed = [r for r in result.replans if r.committed]
    return ClosedLoopScore(
        handover_error_cm=float(np.linalg.norm(p_at - p_true[-1]) * 100.0),
        final_error_cm=float(np.linalg.norm(p_rest - p_true[-1]) * 100.0),
        arrival_delay_s=arrival - recorded,
        arrival_s=arrival,
        recorded_arrival_s=recorded,
        handover_time_s=t_end,
        rest_s=result.arrival_s,
        max_limit_ratio=float(ratios.max()),
        limit_ratios=[float(x) for x in ratios],
        position_excess_rad=excess,
        collisions=collisions,
        replans=len(result.replans),
        refused_replans=result.n_refused,
        final_task=committed[-1].task if committed else "",
        handover_orientation_error_deg=handover_orientation_error_deg(robot, q_at, truth[-1]),
    )
