"""``human_clearance``: the robot keeps clear of the human's body outside the hand.

At every sample the distance between every robot collision geometry (enclosed in capsules) and every
body part (:class:`~ipromp_pin.human.HumanMotion`, tracked or assumed) is computed
(:mod:`ipromp_pin.human.separation`). The check fails where the robot touches a body part outside
the hand region at its nominal position (tracked, interpolated across an occlusion, or held since
the last observation; distance at most ``[human] min_separation_m``): a contact there is never
intended, and going slower does not remove it. How far unseen parts could have moved counts toward
the protective separation distance and the contact-speed limits (``contact_speed``), not here; the
hand, where the hand-over happens, is judged by ``contact_speed`` too. The time the robot spends
closer than the protective separation distance S_p (ISO/TS 15066:2016 clause 5.5.4, now in
ISO 10218-2:2025) is reported.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..motion.trajectory import Trajectory
from .context import CheckContext
from .separation import SeparationCheck
from .verdict import Measures, Verdict


@dataclass(frozen=True)
class ClearanceMeasures(Measures):
    """Attributes:
    min_separation_m: Smallest robot-body distance outside the hand [m].
    link: The robot link of it.
    body_part: The body part of it.
    t_s: When [s].
    protective_distance_m: The smallest S_p of any pair then [m] (None: none finite).
    time_within_sp_s: Time closer than S_p to some part [s].
    min_required_m: The distance at or below which the body counts as touched [m].
    human: ``"tracked"``, ``"predicted"`` or ``"assumed"`` (:attr:`~ipromp_pin.human.body.HumanMotion.label`).
    """

    min_separation_m: float
    link: str
    body_part: str
    t_s: float
    protective_distance_m: float | None
    time_within_sp_s: float
    min_required_m: float
    human: str


class HumanClearance(SeparationCheck):
    """The robot stays clear of the body outside the hand region (see the module docstring)."""

    name = "human_clearance"
    measures_type = ClearanceMeasures

    def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
        sep = self.summary(motion, context)
        li, pi = sep.clearance_pair
        limit = self.robot.settings.human.min_separation_m
        m = ClearanceMeasures(
            min_separation_m=sep.clearance_m,
            link=sep.links[li],
            body_part=sep.parts[pi],
            t_s=float(sep.t_s[sep.clearance_sample]),
            protective_distance_m=sep.clearance_protective_m,
            time_within_sp_s=sep.time_within_sp_s,
            min_required_m=limit,
            human=sep.human,
        )
        where = f"{m.link} - {m.body_part} at t={m.t_s:.2f} s"
        who = "assumed human" if sep.human == "assumed" else "tracked human"
        d = m.min_separation_m
        if d <= limit:
            reason = f"robot touches the {who}'s body: {d * 1e3:.0f} mm <= {limit * 1e3:.0f} mm ({where})"
            return Verdict(self.name, "fail", reason, m)
        reason = (
            f"closest to the {who}'s body (hand excluded) {d * 1e3:.0f} mm ({where}); "
            f"within S_p for {m.time_within_sp_s:.2f} s"
        )
        return Verdict(self.name, "pass", reason, m)
