"""The base of every check: :class:`Check`.

A check is built once per robot (``__init__`` stores its parameters; anything expensive, such as
collision geometry, is prepared on first use and kept on the instance) and then judges motions:
:meth:`Check.check` takes a :class:`~ipromp_pin.motion.trajectory.Trajectory` (times on the human's
clock) and a :class:`~.context.CheckContext` and returns a :class:`~.verdict.Verdict`.

A check declares what its verdict depends on (:attr:`Check.depends_on`): ``"path"`` when only the
positions the motion passes through matter (joint limits, self-collision, workspace), ``"timing"``
when the times matter too (speeds, the moving human, torques); a re-timing of the same path re-runs
only the latter (:mod:`.suite`). A check may also constrain the timing itself
(:meth:`Check.timing_constraints`: e.g. the torque limits toppra must respect) and add what it
computed to the committed motion (:meth:`Check.annotate`: e.g. the joint torques).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterable
from dataclasses import dataclass
from typing import ClassVar, Literal

import numpy as np

from ..motion.toppra_profile import TorqueLimit
from ..motion.trajectory import Trajectory
from ..robot import Robot
from .context import CheckContext
from .verdict import Measures, NoMeasures, Verdict

Dependency = Literal["path", "timing"]
"""What a verdict depends on: the positions only, or their times too."""


@dataclass(frozen=True)
class TimingConstraints:
    """What a timing must respect besides the joint limits (toppra's extra constraints).

    Attributes:
        torque: Joint-torque limits with the carried object (None: none).
    """

    torque: TorqueLimit | None = None


class Check(ABC):
    """One check of a timed motion.

    Class attributes:
        name: The check's name in reports.
        measures_type: The type of its verdicts' measures (their fields are the report's, see
            :mod:`.schema`).
        required: Whether a failure fails the plan (else advisory).
        depends_on: ``"path"`` or ``"timing"`` (see the module docstring).

    Args:
        robot: The loaded robot (stored; nothing else happens here).
    """

    name: ClassVar[str]
    measures_type: ClassVar[type[Measures]] = NoMeasures
    required: ClassVar[bool] = True
    depends_on: ClassVar[Dependency] = "timing"

    def __init__(self, robot: Robot) -> None:
        self.robot = robot

    @abstractmethod
    def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
        """Judge ``motion`` (N samples on the human's clock) knowing ``context``."""

    def applies(self, context: CheckContext) -> bool:
        """Whether this check judges motions in ``context`` (default: always); a check that does not
        apply gives no verdict (e.g. the hand-over checks on the motion after the hand-over)."""
        return True

    def timing_constraints(self, context: CheckContext) -> TimingConstraints:
        """What a timing of a motion in ``context`` must respect for this check (default: nothing)."""
        return TimingConstraints()

    def annotate(self, motion: Trajectory, context: CheckContext) -> Trajectory:
        """The committed ``motion`` with what this check computed of it (default: unchanged)."""
        return motion

    def prime(self, paths: Iterable[np.ndarray]) -> None:
        """Prepare for motions near ``paths`` (each (N, n_joints) [rad], e.g. the demonstrated motions)
        before the first one is checked (default: nothing)."""
        return None

    def reset(self) -> None:
        """Forget what earlier motions left behind (caches), so that a run does not depend on the
        runs before it (default: nothing)."""
        return None
