"""``contact_speed``: inside the protective separation distance, the robot approaches every body
region no faster than its ISO/TS 15066 contact-speed limit.

Where a robot geometry is closer to a body part than S_p (clause 5.5.4), its closest point's speed
toward that part must be at most ``v_max = F_max / sqrt(mu k)`` of the part's body region (clause
5.5.5, Annex A; :mod:`ipromp_pin.human.iso15066`), with the robot's effective mass at that point in
that direction. The hand region, where the hand-over contact is intended, is judged by the hand's
limits like every other region.

A plan passes when every such approach stays within ``(1 - speed_margin) v_max`` (the settings'
``[iso15066] speed_margin``: room for the human's motion after the observation the plan was checked
against). ``n_speed_violations`` counts the samples faster than ``v_max`` itself (what the
evaluation reports against the recorded human), ``n_over_planning_limit`` those beyond the margin.
A failing check asks for the uniform slow-down ``k = max(approach speed / v_max) / (1 -
speed_margin)`` (``values["slowdown"]``): going ``k`` times slower divides every approach speed by
``k`` and shrinks S_p, so the plan is re-timed instead of refused.
"""

from __future__ import annotations

import numpy as np

from ..robot import CheckResult
from .base import CheckContext, TimedMotion
from .separation_base import SeparationCheck

SLOWDOWN_MARGIN = 1.02
"""Factor on the requested slow-down so that the re-timed motion passes with a little room."""


class ContactSpeed(SeparationCheck):
    """Inside S_p, approach speeds within the body regions' limits (see the module docstring)."""

    name = "contact_speed"

    def check(self, motion: TimedMotion, context: CheckContext) -> CheckResult:
        sep = self.summary(motion, context)
        allowed = 1.0 - self.robot.settings.human.speed_margin
        violations = int(np.count_nonzero(sep.violation))
        over = int(np.count_nonzero(sep.over(allowed)))
        n = sep.ratio_sample
        li, pi = sep.ratio_pair
        worst = sep.worst_ratio
        speed = sep.approach_m_s
        values: dict = {
            "n_speed_violations": violations,
            "n_over_planning_limit": over,
            "planning_limit_ratio": allowed,
            "max_speed_ratio": worst,
            "link": sep.links[li],
            "body_part": sep.parts[pi],
            "region": sep.regions[pi],
            "t_s": float(sep.t_s[n]),
            "approach_speed_m_s": speed if worst > 0 else 0.0,
            "v_max_m_s": speed / worst if worst > 0 else None,
            "robot_mass_kg": sep.robot_mass_kg if worst > 0 else None,
            "protective_distance_m": sep.protective_m if worst > 0 else None,
            "time_within_sp_s": sep.time_within_sp_s,
            "human": sep.human,
        }
        who = "assumed human" if sep.human == "assumed" else "tracked human"
        where = (
            f"{sep.links[li]} toward the {who}'s {sep.parts[pi]} ({sep.regions[pi]}) at t={sep.t_s[n]:.2f} s"
        )
        if over:
            values["slowdown"] = worst / allowed * SLOWDOWN_MARGIN
            reason = (
                f"{over} samples inside S_p faster than {allowed:.0%} of the contact-speed limit "
                f"({violations} beyond the limit): {speed:.2f} m/s, limit {values['v_max_m_s']:.2f} m/s "
                f"({where})"
            )
            return CheckResult(self.name, "fail", reason, values)
        if worst <= 0:
            return CheckResult(self.name, "pass", f"no approach near a contact-speed limit ({who})", values)
        reason = f"at most {worst:.0%} of the contact-speed limit ({where})"
        return CheckResult(self.name, "pass", reason, values)
