"""The registered timed-motion checks, in report order, and running them.

Register a check by adding its class to :data:`MOTION_CHECKS` (its module is one file in this
package, a :class:`~.base.MotionCheck` subclass).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from ..exceptions import PipelineError
from ..human.separation import SeparationAnalyser
from ..human.separation_summary import SeparationSummariser
from ..robot import CheckResult, Robot
from .base import CheckContext, MotionCheck, TimedMotion
from .contact_speed import ContactSpeed
from .human_clearance import HumanClearance
from .joint_torques import JointTorques
from .separation_base import SeparationCheck

MOTION_CHECKS: tuple[type[MotionCheck], ...] = (HumanClearance, ContactSpeed, JointTorques)
"""Every timed-motion check, in the order of the reports."""


def build_checks(robot: Robot, names: Iterable[str] | None = None) -> list[MotionCheck]:
    """The registered checks for ``robot`` (all, or those named, in registry order); the separation
    checks share one :class:`~ipromp_pin.human.separation_summary.SeparationSummariser`.

    Raises:
        PipelineError: an unknown check name.
    """
    known = {c.name: c for c in MOTION_CHECKS}
    wanted = list(known if names is None else names)
    unknown = [n for n in wanted if n not in known]
    if unknown:
        raise PipelineError(f"unknown motion check(s) {unknown}; known: {sorted(known)}")
    shared = SeparationSummariser(SeparationAnalyser(robot))  # one separation per motion for them all
    return [
        c(robot, shared) if issubclass(c, SeparationCheck) else c(robot)
        for c in MOTION_CHECKS
        if c.name in wanted
    ]


def run_checks(
    checks: Sequence[MotionCheck], motion: TimedMotion, context: CheckContext | None = None
) -> list[CheckResult]:
    """Every check of ``checks`` on ``motion``, in order."""
    ctx = context if context is not None else CheckContext()
    return [c.check(motion, ctx) for c in checks]
