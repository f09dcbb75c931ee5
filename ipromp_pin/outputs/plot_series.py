"""The numbers of the motion figures, computed apart from their drawing (no matplotlib here).

:func:`motion_series` gives a timed motion's positions, velocities, accelerations and jerks beside
the limits the checks hold them to (``joint_limits``: the position limits less the settings'
margin; ``speed_limits``: the context's limits or the robot's own, the jerk as the difference of
consecutive accelerations over the control period, as that check computes it).
:func:`separation_series` gives, per control sample, the robot-human separation the human checks
judge: ``human_clearance``'s measure (the smallest distance to the body outside the hand, at its
nominal position), the distance to the hand, the smallest protective separation distance S_p of any
pair and ``contact_speed``'s per-sample measure (the largest approach speed / v_max within S_p), from
the analysis the checks' numbers are held to
(:meth:`~ipromp_pin.human.separation.SeparationAnalyser.analyse`), so that over the judged samples
the smallest clearance is the report's ``min_separation_m`` and the largest ratio its
``max_speed_ratio``. Every time is on the human's clock (t = 0 at the start of the human's motion),
as in the reports.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..exceptions import DataError
from ..human import HumanMotion
from ..human.separation import HAND_REGION, SeparationAnalyser
from ..motion.trajectory import JointLimits, Trajectory
from ..robot import Robot
from .human_preview import held_until, human_label, judged_human

__all__ = ["MotionSeries", "SeparationSeries", "motion_series", "separation_series"]


@dataclass(frozen=True)
class MotionSeries:
    """A timed motion beside its limits (N samples, J joints; times on the human's clock).

    Attributes:
        t_s: Sample times (N,) [s].
        q: Positions (N, J) [rad].
        qd: Velocities (N, J) [rad/s].
        qdd: Accelerations (N, J) [rad/s^2].
        jerk: Jerks (N, J) [rad/s^3]: the difference of consecutive accelerations over the control
            period (``speed_limits``' measure; the first sample's is 0).
        segment: (N,) index of the segment each sample belongs to (0: the approach, 1: the retreat).
        limits: The limits the checks used (positions with the settings' margin).
        position_bounds: Position limits without the margin (lower (J,), upper (J,)) [rad], the
            URDF's (None: not known).
        joint_names: (J,) joint names.
    """

    t_s: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    jerk: np.ndarray
    segment: np.ndarray
    limits: JointLimits
    position_bounds: tuple[np.ndarray, np.ndarray] | None
    joint_names: tuple[str, ...]

    def ratios(self) -> np.ndarray:
        """The largest |velocity|, |acceleration| and |jerk| over their limits (3,)."""
        lim = self.limits
        return np.array(
            [
                float(np.max(np.abs(x) / bound))
                for x, bound in (
                    (self.qd, lim.velocity_rad_s),
                    (self.qdd, lim.acceleration_rad_s2),
                    (self.jerk, lim.jerk_rad_s3),
                )
            ]
        )


def _check_jerk(motion: Trajectory) -> np.ndarray:
    """(N, J) the jerk ``speed_limits`` measures: consecutive accelerations' difference over the
    control period (0 at the first sample)."""
    jerk = np.zeros_like(motion.qdd)
    if motion.n_samples > 1:
        jerk[1:] = np.diff(motion.qdd, axis=0) / motion.dt_s
    return jerk


def motion_series(
    segments: Sequence[Trajectory], limits: JointLimits, robot: Robot | None = None
) -> MotionSeries:
    """The samples of ``segments`` (the approach, then the retreat if any, on the human's clock) beside
    ``limits`` (what ``speed_limits`` and ``joint_limits`` used); ``robot``: its URDF position limits
    are kept too (the positions' limits before the margin)."""
    parts = [s for s in segments if s.n_samples > 0]
    if not parts:
        raise DataError("plots", "segments", "no motion samples to draw")
    jerk = [_check_jerk(s) for s in parts]
    bounds = None if robot is None else (np.asarray(robot.lower_rad), np.asarray(robot.upper_rad))
    return MotionSeries(
        t_s=np.concatenate([s.t_s for s in parts]),
        q=np.vstack([s.q for s in parts]),
        qd=np.vstack([s.qd for s in parts]),
        qdd=np.vstack([s.qdd for s in parts]),
        jerk=np.vstack(jerk),
        segment=np.concatenate([np.full(s.n_samples, k) for k, s in enumerate(parts)]),
        limits=limits,
        position_bounds=bounds,
        joint_names=tuple(parts[0].joint_names),
    )


@dataclass(frozen=True)
class SeparationSeries:
    """The robot-human separation per control sample (N samples; times on the human's clock).

    Attributes:
        t_s: Sample times (N,) [s].
        body_m: ``human_clearance``'s measure (N,) [m]: the smallest distance to the body outside the
            hand at its nominal position (inf: no such part).
        hand_m: The smallest distance (N,) [m] to the hand at its nominal position (NaN: no hand).
        protective_m: The smallest S_p (N,) [m] of any robot-body pair (NaN: none finite).
        speed_ratio: ``contact_speed``'s per-sample measure (N,): the largest approach speed / v_max
            within S_p (0: no approach within S_p).
        planning_limit_ratio: ``1 - speed_margin``: the ratio the plans are held to.
        judged: (N,) the samples of the motion the checks judged (False: the robot held at rest
            after it while the human still moves).
        human: What the human is (tracked as observed until when, recorded or assumed).
    """

    t_s: np.ndarray
    body_m: np.ndarray
    hand_m: np.ndarray
    protective_m: np.ndarray
    speed_ratio: np.ndarray
    planning_limit_ratio: float
    judged: np.ndarray
    human: str

    @property
    def min_separation_m(self) -> float:
        """The smallest ``body_m`` over the judged samples [m] (the report's ``min_separation_m``)."""
        return float(np.min(self.body_m[self.judged]))

    @property
    def max_speed_ratio(self) -> float:
        """The largest ``speed_ratio`` over the judged samples (the report's ``max_speed_ratio``)."""
        return float(np.max(self.speed_ratio[self.judged]))


def separation_series(
    robot: Robot, motion: Trajectory, human: HumanMotion | None, dt_s: float = 0.01
) -> SeparationSeries:
    """The separation of ``motion`` (the motion the checks judged, on the human's clock) from
    ``human`` (the human they judged; None: the robot settings' assumed human, as the checks take
    it), the robot held at rest after its motion until the human's last sample (``dt_s``: the
    control period [s] of a motion of one sample)."""
    who = judged_human(robot, human)
    end = float(motion.t_s[-1])
    shown = held_until(motion, float(who.t_s[-1]), dt_s)
    sep = SeparationAnalyser(robot).analyse(shown.t_s, shown.q, shown.qd, who)
    nominal = sep.nominal_distance_m().min(axis=1)  # (N, P): each part's closest capsule
    hand = np.array([r == HAND_REGION for r in sep.regions])
    n = sep.t_s.size
    sp = sep.protective_m.reshape(n, -1)
    finite = np.isfinite(sp)
    sp_min = np.where(finite.any(axis=1), np.where(finite, sp, np.inf).min(axis=1), np.nan)
    return SeparationSeries(
        t_s=sep.t_s,
        body_m=sep.clearance_m(HAND_REGION),
        hand_m=nominal[:, hand].min(axis=1) if hand.any() else np.full(n, np.nan),
        protective_m=sp_min,
        speed_ratio=np.maximum(sep.max_ratio, 0.0),
        planning_limit_ratio=1.0 - robot.settings.human.speed_margin,
        judged=sep.t_s <= end + 1e-9,
        human=human_label(who),
    )
