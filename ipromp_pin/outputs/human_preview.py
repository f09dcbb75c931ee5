"""What the previews show of the human: the body the checks judged and the separation they measured.

:func:`human_tracks` turns the human the checks judged (:class:`~ipromp_pin.human.HumanMotion`:
``run``'s as observed until the end of the observation, then held; the replay report's recorded
one) and the timed robot motion they judged into the preview's plain arrays
(:class:`~ipromp_pin.preview.body.BodyTrack`, :class:`~ipromp_pin.preview.body.SeparationTrack`):
the body's nominal capsules at the human's samples, and per control sample ``human_clearance``'s
measure (the smallest distance to the body outside the hand, at its nominal position) with its pair
and points, the smallest ``S_p`` of any pair and the largest approach-speed ratio (``contact_speed``'s
per-sample measure), and the separation state the human checks decide
(:meth:`~ipromp_pin.human.separation.Separation.state`). The analysis is the one the checks' numbers
are held to (:class:`~ipromp_pin.human.separation.SeparationAnalyser`), so that the curve's smallest
value over a judged motion is the report's, at the report's sample, with the same pair; the panel
states the report's figures themselves (:func:`separation_figures`, read from the verdicts).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np

from ..human import HumanMotion
from ..human.separation import HAND_REGION, Separation, SeparationAnalyser
from ..motion.trajectory import Trajectory
from ..preview.body import SEPARATION_STATES, BodyTrack, SeparationTrack
from ..preview.reported import ReportedFigure
from ..robot import Robot
from ..safety import Verdict
from ..safety.contact_speed import ContactSpeedMeasures
from ..safety.human_clearance import ClearanceMeasures

CLEARANCE_MEASURE = (
    "human_clearance's measure: the smallest distance to the body outside the hand (hand excluded), "
    "at its nominal position"
)
"""What the separation track's per-sample distance is (the panel names it)."""


def judged_human(robot: Robot, human: HumanMotion | None) -> HumanMotion:
    """The human the separation checks judge with ``human`` in their context: ``human``, else the
    robot settings' assumed standing human (as :meth:`~ipromp_pin.safety.separation.SeparationCheck.human`
    takes a context without one)."""
    return human if human is not None else HumanMotion.assumed_human(robot.settings.human)


def human_label(human: HumanMotion) -> str:
    """How the page names ``human``: tracked (as observed until when) or assumed."""
    if human.assumed:
        return "assumed human (no tracked skeleton)"
    if math.isfinite(human.horizon_s) and human.forecast is not None:
        n = len(human.forecast.frames)
        return (
            f"tracked human as observed until {human.horizon_s:.2f} s, then {n} of its {len(human.frames)} "
            "frames placed as the model predicts them, the others held where last seen"
        )
    if math.isfinite(human.horizon_s):
        return f"tracked human as observed until {human.horizon_s:.2f} s, then held where last seen"
    return "recorded human (tracked skeleton, every sample)"


def body_track(human: HumanMotion, label: str = "") -> BodyTrack:
    """The nominal capsules of ``human`` (its radii without the uncertainty inflation, the body
    ``human_clearance`` measures to) at its samples (a human standing still: its one sample)."""
    a, b, r = human.capsules(human.t_s)
    radius = np.broadcast_to(np.asarray(human.radius_m, dtype=float), r.shape)
    names = [str(n) for n in human.part_names]
    return BodyTrack(human.t_s, a, b, radius, names, human.assumed, label or human_label(human))


def separation_track(
    sep: Separation,
    source: str,
    judged: np.ndarray | None = None,
    reported: Sequence[ReportedFigure] = (),
) -> SeparationTrack:
    """The preview's per-sample separation of an analysed motion: ``human_clearance``'s measure and
    pair, the smallest ``S_p`` of any pair, the largest contact-speed ratio, the state; ``judged``
    (N,) marks the samples of a judged motion."""
    d, li, pi = sep.clearance_pairs(HAND_REGION)
    if not np.all(np.isfinite(d)):  # no part outside the hand: the closest pair of every part
        n = sep.t_s.size
        d = sep.min_distance_m
        li, pi = np.unravel_index(sep.distance_m.reshape(n, -1).argmin(axis=1), sep.distance_m.shape[1:])
    n = sep.t_s.size
    sp = sep.protective_m.reshape(n, -1)
    sp = np.where(np.isfinite(sp), sp, np.nan)
    has = ~np.all(np.isnan(sp), axis=1)
    sp_min = np.full(n, np.nan)
    sp_min[has] = np.nanmin(sp[has], axis=1)
    return SeparationTrack(
        t_s=sep.t_s,
        distance_m=np.maximum(d, 0.0),
        robot_point_m=sep.clearance_robot_m,
        body_point_m=sep.clearance_body_m,
        state=[SEPARATION_STATES[int(s)] for s in sep.state()],
        link=[sep.links[i] for i in li],
        body_part=[sep.parts[i] for i in pi],
        protective_distance_m=sp_min,
        speed_ratio=np.maximum(sep.max_ratio, 0.0),
        source=source,
        measure=CLEARANCE_MEASURE,
        judged=judged,
        reported=reported,
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


def separation_figures(verdicts: Iterable[Verdict], prefix: str = "") -> list[ReportedFigure]:
    """The report's figures of the human checks among ``verdicts`` (``prefix``: how the check list
    names them, e.g. ``"retreat "``): ``human_clearance``'s smallest clearance and
    ``contact_speed``'s largest speed ratio, each with its time, pair and the verdict's reason."""
    out = []
    for v in verdicts:
        m = v.measures
        if isinstance(m, ClearanceMeasures) and math.isfinite(m.min_separation_m):
            out.append(
                ReportedFigure(prefix + v.name, m.min_separation_m, m.t_s, v.reason, (m.link, m.body_part))
            )
        elif isinstance(m, ContactSpeedMeasures):
            out.append(
                ReportedFigure(prefix + v.name, m.max_speed_ratio, m.t_s, v.reason, (m.link, m.body_part))
            )
    return out


def human_tracks(
    robot: Robot,
    motion: Trajectory,
    human: HumanMotion | None,
    dt_s: float = 0.01,
    reported: Sequence[ReportedFigure] = (),
    source: str = "",
) -> tuple[BodyTrack | None, SeparationTrack | None]:
    """The body and the separation of ``motion`` (on the human's clock: the motion the checks judged)
    from ``human`` (the human they judged; None: none), the robot held at rest after its motion until
    the human's last sample (those samples marked not judged; ``dt_s``: the control period [s] of a
    motion of one sample); ``reported``: the report's figures the panel states; ``source``: what the
    panel calls the human ("": :func:`human_label`)."""
    if human is None:
        return None, None
    end = float(motion.t_s[-1])
    shown = held_until(motion, float(human.t_s[-1]), dt_s)
    sep = SeparationAnalyser(robot).analyse(shown.t_s, shown.q, shown.qd, human)
    judged = shown.t_s <= end + 1e-9
    label = source or human_label(human)
    return body_track(human, label), separation_track(sep, label, judged, reported)
