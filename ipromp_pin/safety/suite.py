"""The registered checks and :class:`CheckSuite`, which runs them on a motion and re-times a motion
until it is safe.

Register a check by adding its class to :data:`CHECKS` (its module is one file in this package, a
:class:`~.base.Check` subclass); every planner (the one-shot plan, the retreat, every re-plan of the
closed loop), the reports and the scores pick it up.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Sequence

import numpy as np

from ..exceptions import PipelineError
from ..human.separation import SeparationAnalyser
from ..human.separation_summary import SeparationSummariser
from ..motion.trajectory import Trajectory
from ..robot import Robot
from .base import Check, TimingConstraints
from .contact_speed import ContactSpeed
from .context import CheckContext
from .human_clearance import HumanClearance
from .joint_limits import JointLimits
from .joint_torques import JointTorques
from .retime import Retimed, Timer, retime_until_safe
from .self_collision import SelfCollision
from .separation import SeparationCheck
from .speed_limits import SpeedLimits
from .uncertainty import Uncertainty
from .verdict import CheckReport, Verdict
from .workspace import Workspace

CHECKS: tuple[type[Check], ...] = (
    SpeedLimits,
    JointLimits,
    Workspace,
    SelfCollision,
    Uncertainty,
    HumanClearance,
    ContactSpeed,
    JointTorques,
)
"""Every check, in the order of the reports and of evaluation (cheap and decisive ones first)."""

HUMAN_CHECKS = ("human_clearance", "contact_speed")
"""The checks of the human."""


class CheckSuite:
    """Checks run together on a motion (see the module docstring).

    Args:
        checks: The checks, in the order they run and are reported.
    """

    def __init__(self, checks: Sequence[Check]) -> None:
        self.checks = list(checks)

    @classmethod
    def build(
        cls, robot: Robot, names: Iterable[str] | None = None, *, exclude: Iterable[str] = ()
    ) -> CheckSuite:
        """The registered checks for ``robot`` (all, or those named, less ``exclude``, in registry
        order); the separation checks share one summariser.

        Raises:
            PipelineError: an unknown check name (with the closest known one).
        """
        known = {c.name: c for c in CHECKS}
        wanted = list(known if names is None else names)
        for n in [*wanted, *exclude]:
            if n not in known:
                close = difflib.get_close_matches(n, list(known), n=1)
                hint = f" (did you mean '{close[0]}'?)" if close else ""
                raise PipelineError(f"unknown check '{n}'{hint}; known: {', '.join(known)}")
        skip = set(exclude)
        shared = SeparationSummariser(SeparationAnalyser(robot))
        checks: list[Check] = []
        for c in CHECKS:
            if c.name in wanted and c.name not in skip:
                checks.append(c(robot, shared) if issubclass(c, SeparationCheck) else c(robot))
        return cls(checks)

    @property
    def names(self) -> list[str]:
        """The checks' names, in order."""
        return [c.name for c in self.checks]

    def __contains__(self, name: str) -> bool:
        return any(c.name == name for c in self.checks)

    def get(self, name: str) -> Check | None:
        """The check named ``name``, or None."""
        return next((c for c in self.checks if c.name == name), None)

    def path_checks(self) -> set[str]:
        """The names of the checks that depend on the path only."""
        return {c.name for c in self.checks if c.depends_on == "path"}

    def only(self, names: Iterable[str]) -> CheckSuite:
        """The checks named ``names`` (the same instances, in this suite's order)."""
        keep = set(names)
        return CheckSuite([c for c in self.checks if c.name in keep])

    def without(self, names: Iterable[str]) -> CheckSuite:
        """The checks not named ``names`` (the same instances)."""
        drop = set(names)
        return CheckSuite([c for c in self.checks if c.name not in drop])

    def run(
        self,
        motion: Trajectory,
        context: CheckContext,
        *,
        reuse: Sequence[Verdict] = (),
        stop_early: bool = False,
    ) -> list[Verdict]:
        """Every check's verdict on ``motion``, in order.

        Args:
            motion: The motion (times on the human's clock).
            context: What the checks know.
            reuse: Verdicts taken instead of running their checks again (the caller vouches that
                they hold for ``motion``: e.g. the path checks' on another timing of the same path).
            stop_early: Stop after the first required check that fails and asks for no slow-down
                (the motion is refused whatever the rest say).

        Checks that do not apply in ``context`` (:meth:`~.base.Check.applies`) give no verdict.
        """
        known = {v.name: v for v in reuse}
        out = []
        for c in self.checks:
            if not c.applies(context):
                continue
            v = known.get(c.name)
            v = v if v is not None else c.check(motion, context)
            out.append(v)
            if stop_early and v.blocks and v.slowdown is None:
                break
        return out

    def report(self, motion: Trajectory, context: CheckContext) -> CheckReport:
        """:meth:`run` as a :class:`~.verdict.CheckReport`."""
        return CheckReport(self.run(motion, context))

    def timing_constraints(self, context: CheckContext) -> TimingConstraints:
        """What a timing in ``context`` must respect for the checks together."""
        torque = None
        for c in self.checks:
            t = c.timing_constraints(context).torque
            torque = t if t is not None else torque
        return TimingConstraints(torque)

    def annotate(self, motion: Trajectory, context: CheckContext) -> Trajectory:
        """The committed ``motion`` with what the checks computed of it (e.g. its joint torques)."""
        for c in self.checks:
            motion = c.annotate(motion, context)
        return motion

    def prime(self, paths: Sequence[np.ndarray]) -> None:
        """Prepare every check for motions near ``paths`` (:meth:`~.base.Check.prime`)."""
        for c in self.checks:
            c.prime(paths)

    def reset(self) -> None:
        """Let every check forget its caches (:meth:`~.base.Check.reset`)."""
        for c in self.checks:
            c.reset()

    def retime_until_safe(
        self,
        timer: Timer,
        context: CheckContext,
        *,
        stop_early: bool = False,
        guess: float | None = None,
    ) -> Retimed:
        """The motion ``timer`` gives, re-timed slower while its failing checks ask for it
        (:func:`~.retime.retime_until_safe`)."""
        return retime_until_safe(self, timer, context, stop_early=stop_early, guess=guess)


__all__ = ["CHECKS", "HUMAN_CHECKS", "CheckSuite"]
