"""``human_clearance``: the robot keeps clear of the human's body outside the hand.

At every control sample the distance between every robot collision geometry (enclosed in capsules)
and every body part (:class:`~ipromp_pin.human.HumanMotion`, tracked or assumed) is computed
(:mod:`ipromp_pin.human.separation`). The check fails where the robot touches a body part outside
the hand region at its nominal position (tracked, interpolated across an occlusion, or held since
the last observation; distance at most ``[human] min_separation_m``, 0 m by default): a contact
there is never intended, and going slower does not remove it. The inflation of unseen parts (how far
they could have moved since) is where contact cannot be excluded: it counts toward S_p and the
contact-speed limits (``contact_speed``), not here. The hand, where the hand-over happens, is
judged by ``contact_speed`` instead. The time the robot spends closer than the protective
separation distance S_p (ISO/TS 15066 clause 5.5.4) is reported.

Without a human in the context the check uses the assumed standing human of the robot settings and
says so (``values["human"] == "assumed"``): it never passes without a human.
"""

from __future__ import annotations

from ..robot import CheckResult
from .base import CheckContext, TimedMotion
from .separation_base import SeparationCheck


class HumanClearance(SeparationCheck):
    """The robot stays clear of the body outside the hand region (see the module docstring)."""

    name = "human_clearance"

    def check(self, motion: TimedMotion, context: CheckContext) -> CheckResult:
        sep = self.summary(motion, context)
        n = sep.clearance_sample
        li, pi = sep.clearance_pair
        link, part, t, d = sep.links[li], sep.parts[pi], float(sep.t_s[n]), sep.clearance_m
        limit = self.robot.settings.human.min_separation_m
        values = {
            "min_separation_m": d,
            "link": link,
            "body_part": part,
            "t_s": t,
            "protective_distance_m": sep.clearance_protective_m,
            "time_within_sp_s": sep.time_within_sp_s,
            "min_required_m": limit,
            "human": sep.human,
        }
        where = f"{link} - {part} at t={t:.2f} s"
        who = "assumed human" if sep.human == "assumed" else "tracked human"
        if d <= limit:
            reason = f"robot touches the {who}'s body: {d * 1e3:.0f} mm <= {limit * 1e3:.0f} mm ({where})"
            return CheckResult(self.name, "fail", reason, values)
        reason = (
            f"closest to the {who}'s body (hand excluded) {d * 1e3:.0f} mm ({where}); "
            f"within S_p for {values['time_within_sp_s']:.2f} s"
        )
        return CheckResult(self.name, "pass", reason, values)
