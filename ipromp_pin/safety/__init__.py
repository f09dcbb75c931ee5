"""Safety: every check of a timed motion behind one interface, and the one re-time-until-safe loop.

- :mod:`.base`: :class:`~.base.Check` (``check(motion, context) -> Verdict``, what it depends on,
  the timing constraints it imposes, what it adds to the committed motion);
- :mod:`.verdict`: :class:`~.verdict.Verdict` (status, reason, typed measures, the slow-down asked
  for) and :class:`~.verdict.CheckReport`;
- :mod:`.context`: :class:`~.context.CheckContext`, what the checks know at plan time;
- one file per check: :mod:`.speed_limits`, :mod:`.joint_limits`, :mod:`.workspace`,
  :mod:`.self_collision`, :mod:`.uncertainty` (advisory),
  :mod:`.human_clearance`, :mod:`.contact_speed` (on the shared :mod:`.separation` base) and
  :mod:`.joint_torques`;
- :mod:`.suite`: the registry (:data:`~.suite.CHECKS`) and :class:`~.suite.CheckSuite`;
- :mod:`.retime`: the loop that re-times a motion slower while its failing checks ask for it.

A new check is one file here plus one line in :data:`~.suite.CHECKS`.
"""

from .base import Check, TimingConstraints
from .context import CheckContext
from .retime import (
    MAX_LOCAL_SLOWDOWN,
    MAX_SLOWDOWN,
    MAX_SLOWDOWN_ROUNDS,
    SLOWDOWN_STEP,
    Retimed,
    Timed,
    Timer,
    next_guess,
)
from .suite import CHECKS, HUMAN_CHECKS, CheckSuite
from .verdict import CheckReport, Measures, Verdict, needed_slowdown

__all__ = [
    "CHECKS",
    "HUMAN_CHECKS",
    "MAX_LOCAL_SLOWDOWN",
    "MAX_SLOWDOWN",
    "MAX_SLOWDOWN_ROUNDS",
    "SLOWDOWN_STEP",
    "Check",
    "CheckContext",
    "CheckReport",
    "CheckSuite",
    "Measures",
    "Retimed",
    "Timed",
    "Timer",
    "TimingConstraints",
    "Verdict",
    "needed_slowdown",
    "next_guess",
]
