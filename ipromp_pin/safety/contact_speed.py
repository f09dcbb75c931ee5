"""``contact_speed``: inside the protective separation distance, the robot approaches every body
region no faster than its ISO/TS 15066:2016 contact-speed limit (content now in ISO 10218-2:2025).

Where a robot geometry is closer to a body part than S_p (clause 5.5.4), its closest point's speed
toward that part must be at most ``v_max = F_max / sqrt(mu k)`` of the part's body region (clause
5.5.5, Annex A; :mod:`ipromp_pin.human.iso15066`), with the robot's effective mass at that point in
that direction. The hand region, where the hand-over contact is intended, is judged by the hand's
limits like every other region.

A motion passes when every such approach stays within ``(1 - speed_margin)`` of ``v_max`` (the
settings' ``[iso15066] speed_margin``: room for the human's motion after the observation the motion
was checked against). ``n_speed_violations`` counts the samples faster than ``v_max`` itself,
``n_over_planning_limit`` those beyond the margin. A failing check asks for the uniform slow-down
``k = max(approach speed / v_max) / (1 - speed_margin)`` (times :data:`SLOWDOWN_MARGIN`): going
``k`` times slower divides every approach speed by ``k`` and shrinks S_p; it also gives the
slow-down each sample needs on its own (:attr:`Verdict.local_slowdown
<ipromp_pin.safety.verdict.Verdict.local_slowdown>`), so that a planner that can may slow the motion
only where it approaches too fast (an approach speed scales with the path velocity there). The same
``k`` of a passing motion (below 1) is its estimate of how much faster would still pass
(:attr:`Verdict.fits_at <ipromp_pin.safety.verdict.Verdict.fits_at>`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..motion.trajectory import Trajectory
from .context import CheckContext
from .separation import SeparationCheck
from .verdict import Measures, Verdict

SLOWDOWN_MARGIN = 1.02
"""Factor on the requested slow-down so that the re-timed motion passes with a little room."""


@dataclass(frozen=True)
class ContactSpeedMeasures(Measures):
    """Attributes:
    n_speed_violations: Samples inside S_p faster than a contact-speed limit.
    n_over_planning_limit: Samples inside S_p faster than ``planning_limit_ratio`` of it.
    planning_limit_ratio: ``1 - speed_margin``.
    max_speed_ratio: The largest approach speed / v_max inside S_p (0: none).
    link: The robot link of it.
    body_part: The body part of it.
    region: Its body region.
    t_s: When [s].
    approach_speed_m_s: The approach speed there [m/s].
    v_max_m_s: The contact-speed limit there [m/s] (None: no approach).
    robot_mass_kg: The robot's effective mass there [kg] (None: no approach).
    protective_distance_m: S_p there [m] (None: no approach).
    time_within_sp_s: Time closer than S_p to some part [s].
    human: ``"tracked"``, ``"predicted"`` or ``"assumed"`` (:attr:`~ipromp_pin.human.body.HumanMotion.label`).
    """

    n_speed_violations: int
    n_over_planning_limit: int
    planning_limit_ratio: float
    max_speed_ratio: float
    link: str
    body_part: str
    region: str
    t_s: float
    approach_speed_m_s: float
    v_max_m_s: float | None
    robot_mass_kg: float | None
    protective_distance_m: float | None
    time_within_sp_s: float
    human: str


class ContactSpeed(SeparationCheck):
    """Inside S_p, approach speeds within the body regions' limits (see the module docstring)."""

    name = "contact_speed"
    measures_type = ContactSpeedMeasures

    def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
        sep = self.summary(motion, context)
        allowed = 1.0 - self.robot.settings.human.speed_margin
        over = int(np.count_nonzero(sep.over(allowed)))
        li, pi = sep.ratio_pair
        worst = sep.worst_ratio
        speed = sep.approach_m_s
        m = ContactSpeedMeasures(
            n_speed_violations=int(np.count_nonzero(sep.violation)),
            n_over_planning_limit=over,
            planning_limit_ratio=allowed,
            max_speed_ratio=worst,
            link=sep.links[li],
            body_part=sep.parts[pi],
            region=sep.regions[pi],
            t_s=float(sep.t_s[sep.ratio_sample]),
            approach_speed_m_s=speed if worst > 0 else 0.0,
            v_max_m_s=speed / worst if worst > 0 else None,
            robot_mass_kg=sep.robot_mass_kg if worst > 0 else None,
            protective_distance_m=sep.protective_m if worst > 0 else None,
            time_within_sp_s=sep.time_within_sp_s,
            human=sep.human,
        )
        who = "assumed human" if sep.human == "assumed" else "tracked human"
        fits = worst / allowed * SLOWDOWN_MARGIN
        where = f"{m.link} toward the {who}'s {m.body_part} ({m.region}) at t={m.t_s:.2f} s"
        if over:
            reason = (
                f"{over} samples inside S_p faster than {allowed:.0%} of the contact-speed limit "
                f"({m.n_speed_violations} beyond the limit): {speed:.2f} m/s, limit {m.v_max_m_s:.2f} m/s "
                f"({where})"
            )
            local = np.maximum(sep.max_ratio / allowed * SLOWDOWN_MARGIN, 1.0)
            return Verdict(self.name, "fail", reason, m, slowdown=fits, fits_at=fits, local_slowdown=local)
        if worst <= 0:
            return Verdict(
                self.name, "pass", f"no approach near a contact-speed limit ({who})", m, fits_at=0.0
            )
        reason = f"at most {worst:.0%} of the contact-speed limit ({where})"
        return Verdict(self.name, "pass", reason, m, fits_at=fits)
