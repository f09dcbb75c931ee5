"""How close a closed-loop run came to the recorded human, and how fast it approached the body.

The planner checks every re-plan against the human *as observed then* (the body held and growing
at the human speed after the last sample it received). What happened is judged afterwards against
the *recorded* human motion (:meth:`~ipromp_pin.human.HumanMotion.from_demo` of the replayed demo,
every sample known): the human checks (:data:`HUMAN_CHECKS`) are run on the final commanded
trajectory (:meth:`~ipromp_pin.checks.TimedMotion.from_trajectory`, on the human's clock from 0, the
clock of the replay), and their numbers become the measures of :class:`HumanMeasures`:

* ``min_separation_m``: the smallest distance in [m] between the robot and the body outside the
  hand region (the hand meets the gripper at the hand-over and is judged by its contact limits);
* ``protective_distance_time_s``: how long in [s] the robot was closer than the protective
  separation distance ``S_p`` (ISO/TS 15066 clause 5.5.4);
* ``contact_speed_violations``: control samples inside ``S_p`` whose approach speed toward the
  body exceeds the body region's contact-speed limit (clause 5.5.5, Annex A);
* ``max_speed_ratio``: the largest approach speed over its limit inside ``S_p``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

from ..checks import CheckContext, MotionCheck, TimedMotion, run_checks
from ..human import HumanMotion
from ..motion.trajectory import Trajectory

HUMAN_CHECKS = ("human_clearance", "contact_speed")
"""The timed-motion checks of the human (:mod:`ipromp_pin.checks`), by name."""


@dataclass(frozen=True)
class HumanMeasures:
    """What the human checks measured of a commanded motion against a human motion (module docstring).

    Attributes:
        min_separation_m: Smallest robot-body distance outside the hand region, [m].
        protective_distance_time_s: Time closer than ``S_p``, [s].
        contact_speed_violations: Control samples inside ``S_p`` faster than the contact-speed limit.
        max_speed_ratio: Largest approach speed over its limit inside ``S_p`` (None: never inside).
        link: Robot link of the closest pair.
        body_part: Body part of the closest pair.
        t_s: When the closest pair was closest, [s] on the human's clock.
        passed: Whether every human check passed.
        assumed: Whether the human was the assumed one (no skeleton).
    """

    min_separation_m: float | None
    protective_distance_time_s: float | None
    contact_speed_violations: int | None
    max_speed_ratio: float | None
    link: str
    body_part: str
    t_s: float | None
    passed: bool
    assumed: bool

    def to_dict(self) -> dict:
        """JSON-serialisable form."""
        return asdict(self)


def _number(values: dict[str, Any], key: str) -> float | None:
    v = values.get(key)
    if v is None:
        return None
    x = float(v)
    return x if math.isfinite(x) else None


def human_measures(
    trajectory: Trajectory, human: HumanMotion, checks: Sequence[MotionCheck]
) -> HumanMeasures:
    """Run the human ``checks`` on ``trajectory`` (times from 0 on the human's clock) against ``human``
    (every sample known) -> the :class:`HumanMeasures` (None where no check reported a number)."""
    results = run_checks(checks, TimedMotion.from_trajectory(trajectory), CheckContext(human=human))
    values: dict[str, Any] = {}
    for r in results:
        values.update({k: v for k, v in r.values.items() if k not in values})
    violations = values.get("n_speed_violations")
    return HumanMeasures(
        min_separation_m=_number(values, "min_separation_m"),
        protective_distance_time_s=_number(values, "time_within_sp_s"),
        contact_speed_violations=None if violations is None else int(violations),
        max_speed_ratio=_number(values, "max_speed_ratio"),
        link=str(values.get("link", "")),
        body_part=str(values.get("body_part", "")),
        t_s=_number(values, "t_s"),
        passed=all(r.passed for r in results),
        assumed=bool(human.assumed),
    )
