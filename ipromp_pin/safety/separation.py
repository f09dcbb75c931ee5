"""The base of the checks judged on the robot-body separation (``human_clearance``, ``contact_speed``).

A :class:`SeparationCheck` holds a :class:`~ipromp_pin.human.separation_summary.SeparationSummariser`
over a :class:`~ipromp_pin.human.separation.SeparationAnalyser`: the checks that
:meth:`~.suite.CheckSuite.build` builds together share one, so the separation of a motion is
computed once for both. Without a human in the context they judge the robot settings' assumed
standing human, and say so.
"""

from __future__ import annotations

from ..human import HumanMotion
from ..human.separation import Separation, SeparationAnalyser
from ..human.separation_summary import SeparationSummariser, SeparationSummary
from ..motion.trajectory import Trajectory
from ..robot import Robot
from .base import Check
from .context import CheckContext


class SeparationCheck(Check):
    """A check of the robot-body separation.

    Args:
        robot: The loaded robot.
        summariser: The summariser (shared by the checks built together; default: one of this check's
            own, with the robot's human settings).
    """

    depends_on = "timing"

    def __init__(self, robot: Robot, summariser: SeparationSummariser | None = None) -> None:
        super().__init__(robot)
        self.summariser = (
            summariser if summariser is not None else SeparationSummariser(SeparationAnalyser(robot))
        )
        self._assumed: HumanMotion | None = None  # built on first use, then the same (immutable) body

    @property
    def analyser(self) -> SeparationAnalyser:
        """The separation analyser."""
        return self.summariser.analyser

    def human(self, context: CheckContext) -> HumanMotion:
        """The context's human, or the robot settings' assumed human when the context has none."""
        if context.human is not None:
            return context.human
        if self._assumed is None:
            self._assumed = HumanMotion.assumed_human(self.robot.settings.human)
        return self._assumed

    def separation(self, motion: Trajectory, context: CheckContext) -> Separation:
        """The robot-body separation along ``motion``, every pair's numbers."""
        return self.analyser.analyse(motion.t_s, motion.q, motion.qd, self.human(context))

    def summary(self, motion: Trajectory, context: CheckContext) -> SeparationSummary:
        """What the separation checks judge of the robot-body separation along ``motion``."""
        return self.summariser.summary(motion.t_s, motion.q, motion.qd, self.human(context))
