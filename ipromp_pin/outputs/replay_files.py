"""What ``replay`` writes besides its trajectory and reports: the bags and the figures.

:func:`replay_bag` is the commanded trajectory as ``run``'s bags hold a plan
(:class:`~ipromp_pin.outputs.rosbag.BagContent`: the trajectory on the human's clock, published when
the robot started, the gripper's pose where the commanded motion comes to rest, the recorded human's
channels the closed loop streamed); ``replay`` stages it with its trajectory
(:func:`~ipromp_pin.outputs.staging.stage_trajectory`: only when the replay passed, or marked as
failing). :func:`stage_replay_plots` stages ``motion.png`` (the commanded motion against the limit
profile it was planned with, the re-plans marked) and, when the human checks judged it against the
recorded human, ``separation.png``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import atomic
from ..data import ROBOT, Demo
from ..human import HumanMotion
from ..planning.closed_loop import ClosedLoopResult
from ..robot import Robot, frame_placements
from ..robot.kinematics import rotations_to_quat_xyzw
from ..safety import CheckReport
from .rosbag import BagContent

__all__ = ["ReplayExtras", "replay_bag", "replay_events", "stage_replay_plots"]


@dataclass(frozen=True)
class ReplayExtras:
    """Which of the optional files ``replay`` writes.

    Attributes:
        rosbag: The rosbag2 folder ``rosbag/`` (MCAP), as ``run`` writes it.
        ros1_bag: The ROS 1 bag ``run.bag`` too.
        plots: The figures ``motion.png`` and ``separation.png``.
    """

    rosbag: bool = True
    ros1_bag: bool = False
    plots: bool = False


def replay_bag(result: ClosedLoopResult, demo: Demo, robot: Robot) -> BagContent:
    """The bags' content of a replay: the commanded trajectory (on the human's clock), published at
    the robot's start (``result.start_s``), the gripper's pose at its last sample as the hand-over
    pose, and the recorded ``demo``'s human channels (every group but the robot's)."""
    tr = result.trajectory
    pos, rot = frame_placements(robot, tr.q[-1:])
    return BagContent(
        trajectory=tr,
        plan_time_s=float(result.start_s),
        handover_pose=np.hstack([pos[0], rotations_to_quat_xyzw(rot)[0]]),
        base_frame=robot.base_frame,
        observation=demo.select([g for g in demo.groups if g != ROBOT]),
    )


def replay_events(result: ClosedLoopResult) -> tuple[list[tuple[float, str]], np.ndarray]:
    """The times a replay figure marks: (t [s], label) of the robot's start and its coming to rest,
    and the times [s] of the committed re-plans."""
    events = [(float(result.start_s), "robot starts"), (result.arrival_s, "robot at rest")]
    return events, np.array([r.t_s for r in result.replans if r.committed], dtype=float)


def stage_replay_plots(
    out: atomic.OutputSet,
    robot: Robot,
    result: ClosedLoopResult,
    judged: CheckReport,
    recorded: HumanMotion | None,
) -> dict[str, Path]:
    """Stage ``motion.png`` and, when ``judged`` holds the human checks (a recorded human,
    ``recorded``), ``separation.png`` of the replay's commanded motion; returns the staged paths by
    report key."""
    from . import plots_motion
    from .figures import motion_plot
    from .plot_series import separation_series

    events, replans = replay_events(result)
    tr = result.trajectory
    refused = f"; {result.n_refused} refused" if result.n_refused else ""
    files = {
        "plot_motion": motion_plot(
            tr,
            [],
            robot,
            result.profile.limits,
            out.stage("motion.png"),
            events,
            replans,
            title=f"the commanded trajectory against the {result.profile.name} limit profile (ticks: the "
            f"{result.n_committed} committed re-plans{refused}; t = 0 at the start of the human's motion)",
            labels=("commanded",),
        )
    }
    if recorded is not None and judged.get("human_clearance") is not None:
        sep = separation_series(robot, tr, recorded, tr.dt_s or 0.01)
        files["plot_separation"] = plots_motion.plot_separation(
            sep.t_s,
            sep.body_m,
            sep.protective_m,
            sep.speed_ratio,
            out.stage("separation.png"),
            hand_m=sep.hand_m,
            planning_limit_ratio=sep.planning_limit_ratio,
            judged=sep.judged,
            events=events,
            ticks_s=replans,
            title=f"robot-human separation of the commanded trajectory ({sep.human})",
        )
    return files
