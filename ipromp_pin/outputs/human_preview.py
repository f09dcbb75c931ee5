"""What the previews show of the human: the body's capsules and the robot-body separation.

:func:`human_tracks` turns a :class:`~ipromp_pin.human.HumanMotion` and a timed robot motion into
the preview's plain arrays (:class:`~ipromp_pin.preview.body.BodyTrack`,
:class:`~ipromp_pin.preview.body.SeparationTrack`): the capsules at the human's samples, and per
control sample the closest robot-body pair (every body part, the hand included: it is where the
hand-over happens), its distance, ``S_p`` and approach-speed ratio of that pair, and the separation
state the human checks decide (:meth:`~ipromp_pin.human.separation.Separation.state`).

Which human: the recorded one when the demo has a tracked skeleton (what actually happened), else
the one the checks were given (the assumed human), labelled so on the page.
"""

from __future__ import annotations

import numpy as np

from ..data import Demo
from ..human import HumanMotion
from ..human.separation import Separation, SeparationAnalyser
from ..motion.trajectory import Trajectory
from ..preview.body import SEPARATION_STATES, BodyTrack, SeparationTrack
from ..robot import Robot


def shown_human(robot: Robot, demo: Demo | None, fallback: HumanMotion | None) -> HumanMotion | None:
    """The human a preview draws: the demo's recorded one (a tracked skeleton, shaped by the robot's
    ``[human]`` settings), else ``fallback``."""
    recorded = HumanMotion.from_demo(demo, robot.settings.human) if demo is not None else None
    return recorded if recorded is not None else fallback


def body_track(human: HumanMotion) -> BodyTrack:
    """The capsules of ``human`` at its samples (a human standing still: its one sample)."""
    a, b, r = human.capsules(human.t_s)
    return BodyTrack(human.t_s, a, b, r, [str(n) for n in human.part_names], human.assumed)


def separation_track(sep: Separation, source: str) -> SeparationTrack:
    """The preview's per-sample separation of an analysed motion (closest pair over every part)."""
    n = sep.t_s.size
    flat = sep.distance_m.reshape(n, -1).argmin(axis=1)
    li, pi = np.unravel_index(flat, sep.distance_m.shape[1:])
    rows = np.arange(n)
    ratio = sep.speed_ratio.reshape(n, -1).max(axis=1)
    return SeparationTrack(
        t_s=sep.t_s,
        distance_m=np.maximum(sep.distance_m[rows, li, pi], 0.0),
        robot_point_m=sep.closest_robot_m,
        body_point_m=sep.closest_body_m,
        state=[SEPARATION_STATES[int(s)] for s in sep.state()],
        link=[sep.links[i] for i in li],
        body_part=[sep.parts[i] for i in pi],
        protective_distance_m=sep.protective_m[rows, li, pi],
        speed_ratio=np.maximum(ratio, 0.0),
        source=source,
    )


def held_until(motion: Trajectory, t_end_s: float, dt_s: float) -> Trajectory:
    """``motion`` followed by its last pose at rest until ``t_end_s`` [s] (every ``dt_s`` [s], its own
    control period if it has one): the robot waits while the human still moves."""
    dt = motion.dt_s if motion.dt_s > 0 else dt_s
    n_extra = int(np.floor((t_end_s - motion.t_s[-1]) / dt + 1e-9))
    if n_extra <= 0:
        return motion
    t = np.r_[motion.t_s, motion.t_s[-1] + dt * np.arange(1, n_extra + 1)]
    q = np.vstack([motion.q, np.repeat(motion.q[-1:], n_extra, axis=0)])
    zeros = np.zeros((n_extra, motion.q.shape[1]))
    return Trajectory(t, q, np.vstack([motion.qd, zeros]), np.vstack([motion.qdd, zeros]), motion.joint_names)


def human_tracks(
    robot: Robot, motion: Trajectory, human: HumanMotion | None, dt_s: float = 0.01
) -> tuple[BodyTrack | None, SeparationTrack | None]:
    """The body and the separation of ``motion`` (on the human's clock) from ``human`` (None: none),
    the robot held at rest after its motion until the human's last sample (``dt_s``: the control
    period [s] of a motion of one sample)."""
    if human is None:
        return None, None
    motion = held_until(motion, float(human.t_s[-1]), dt_s)
    sep = SeparationAnalyser(robot).analyse(motion.t_s, motion.q, motion.qd, human)
    source = "assumed human" if human.assumed else "recorded human"
    return body_track(human), separation_track(sep, source)
