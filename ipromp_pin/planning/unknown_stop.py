"""The closed loop's answer to an observation that turns unknown after the robot started: stop, hold,
then retreat.

With ``require_known`` (:class:`~.closed_loop.ClosedLoopSettings`) the robot does not start while
the observation matches none of the model's tasks. Once it has started, a re-plan whose observation
is unknown no longer leaves it on its last committed plan (toward the hand-over of the task it last
knew): :class:`UnknownStop` makes the motion segments that replace it, each checked by the run's
checks through the one re-time-until-safe loop
(:meth:`~ipromp_pin.safety.CheckSuite.retime_until_safe`) as any re-plan:

1. **stop**: at the first unknown re-plan after a committed motion, the quickest jerk-limited stop
   from the commanded state (:func:`~ipromp_pin.motion.retarget.stop_motion`: ruckig's velocity
   interface, within the run's velocity, acceleration and jerk limits), then at rest where it
   stopped;
2. **hold**: at rest for ``unknown_hold_s``; a re-plan whose observation is known again re-targets
   from the commanded state as any re-plan (re-targeting resumes);
3. **retreat**: at the first re-plan at or after the hold's end whose observation is still unknown,
   the straight joint-space line from the held configuration to the robot's rest configuration (its
   configuration before the first committed plan: where it waited, away from the human), timed with
   toppra and ruckig from rest to rest (:func:`~.retreat.retreat_timer`, the one-shot plan's
   retreat timer, without a dwell). The retreat is final: the closed loop re-plans no more. When
   the human's samples end during the hold, the retreat is planned at the hold's end
   (:meth:`~.closed_loop.ClosedLoopPlanner.finish`).

A stop is checked at its own timing only (a slower stop travels further toward the human); a refused
stop or retreat is not committed (the robot keeps its last committed motion and the next re-plan
tries again). The checks that judge a hand-over pose (``workspace``, ``uncertainty``) do not judge
the stop and the retreat: neither ends at a hand-over. The torques are checked with the object the
robot carries before a hand-over of the task it last committed to.

Times are on the human's clock (t = 0 at the start of the human's motion), as every re-plan's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import IPrompPinError
from ..fields import Range
from ..motion.retarget import stop_motion
from ..motion.trajectory import JointLimits, MotionState, Trajectory
from ..safety import CheckContext, CheckSuite, Retimed
from .retreat import retreat_timer, straight_path
from .timers import fixed_timer

UNKNOWN_HOLD_S = 0.5
"""Default of ``unknown_hold_s``: how long the robot holds at rest after stopping on an unknown
observation before it retreats, in [s]. Ten re-plans at the default 20 Hz: a known task's observation
that reads as unknown for a few re-plans (its novelty p-value near the model's ``alpha``) is known
again within it and the hand-over goes on; a motion the model never learned stays unknown and the
robot withdraws."""

UNKNOWN_HOLD_RANGE_S = Range(
    0.0,
    10.0,
    "s",
    "0: retreat as soon as the robot is at rest; a hand-over motion lasts 2-6 s in the shipped "
    "recordings, a hold longer than 10 s outlasts any",
)
"""Plausible range of ``unknown_hold_s``."""

NOT_AT_HANDOVER = ("workspace", "uncertainty")
"""The checks that judge a motion's end as a hand-over pose; the stop and the retreat end elsewhere."""


@dataclass(frozen=True)
class StopEvent:
    """One step of the stop-hold-retreat, on the human's clock.

    Attributes:
        kind: ``unknown`` (a re-plan's observation turned unknown while the robot moved toward a
            hand-over), ``hold`` (the committed stop comes to rest: the hold starts), ``resume`` (a known
            re-plan was committed during the stop or the hold), ``retreat`` (the committed retreat
            starts).
        t_s: When, in [s] from the start of the human's motion (``unknown``: the re-plan's tick, the
            stop takes over there).
        detail: What happened, in words.
    """

    kind: str
    t_s: float
    detail: str

    def to_dict(self) -> dict:
        """JSON-serialisable form."""
        return {"kind": self.kind, "t_s": round(float(self.t_s), 6), "detail": self.detail}


@dataclass
class Segment:
    """A stop or retreat made by :class:`UnknownStop`, checked.

    Attributes:
        action: ``stop`` or ``retreat``.
        retimed: The checked motion and its verdicts (None when it could not be made).
        reason: Why it is refused (empty: it may be committed).
    """

    action: str
    retimed: Retimed | None
    reason: str = ""

    @property
    def motion(self) -> Trajectory | None:
        """The motion to commit (None when refused)."""
        return None if self.reason or self.retimed is None else self.retimed.motion


class UnknownStop:
    """The stop-hold-retreat state of one closed loop (see the module docstring).

    Args:
        suite: The run's checks (those of every re-plan).
        limits: The run's limit profile's joint limits.
        q_rest: The rest configuration (n_joints,) [rad] the retreat goes to.
        hold_s: How long the robot holds at rest before it retreats, in [s].
        dt_s: Control period in [s].
    """

    def __init__(
        self, suite: CheckSuite, limits: JointLimits, q_rest: np.ndarray, hold_s: float, dt_s: float
    ) -> None:
        self.suite = suite.without(NOT_AT_HANDOVER)
        self.limits = limits
        self.q_rest = np.asarray(q_rest, dtype=float).copy()
        self.hold_s = float(hold_s)
        self.dt_s = float(dt_s)
        self.events: list[StopEvent] = []
        self.rest_s: float | None = None  # when the committed stop comes to rest (None: not stopped)
        self.retreated = False

    @property
    def stopped(self) -> bool:
        """Whether a committed stop (or the retreat after it) is what the robot executes."""
        return self.rest_s is not None

    def hold_end_s(self) -> float | None:
        """When the hold ends and the robot may retreat, in [s] (None: not holding)."""
        return None if self.rest_s is None or self.retreated else self.rest_s + self.hold_s

    def due(self, t_s: float) -> str:
        """What an unknown re-plan at the tick ``t_s`` [s] makes: ``stop`` (the robot still moves toward
        a hand-over), ``retreat`` (the hold is over) or ``""`` (holding, or already retreating)."""
        if self.retreated:
            return ""
        if self.rest_s is None:
            return "stop"
        end = self.hold_end_s()
        return "retreat" if end is not None and t_s >= end - 1e-9 else ""

    def segment(self, action: str, state: MotionState, context: CheckContext) -> Segment:
        """The ``stop`` or ``retreat`` from ``state`` (a control tick's commanded state), checked in
        ``context`` (the re-plan's: the human as observed until then, the task last committed to)."""
        try:
            if action == "stop":
                stop = stop_motion(state, self.limits, self.dt_s, self.hold_s)
                timer = fixed_timer(stop, "a slower stop travels further: not slowed")
            else:
                timer = retreat_timer(
                    straight_path(state.q, self.q_rest),
                    state.q,
                    self.limits,
                    self.suite,
                    context,
                    0.0,
                    1.0 / self.dt_s,
                    float(state.t_s),
                    lambda _msg: None,
                )
            retimed = self.suite.retime_until_safe(timer, context, stop_early=True)
        except IPrompPinError as exc:
            return Segment(action, None, f"{action} failed: {exc}")
        refusal = retimed.report.refusal()
        return Segment(action, retimed, f"{action} refused: {refusal}" if refusal else "")

    def committed(self, segment: Segment, t_s: float, why: str) -> None:
        """Record ``segment`` as committed at the tick ``t_s`` [s] (``why``: the unknown reason)."""
        motion = segment.motion
        assert motion is not None, "only a passed segment is committed"
        if segment.action == "stop":
            self.rest_s = float(motion.end_s) - self.hold_s
            self.events.append(StopEvent("unknown", t_s, f"unknown task ({why})"))
            self.events.append(
                StopEvent("hold", self.rest_s, f"at rest, holding for {self.hold_s:g} s before retreating")
            )
        else:
            self.retreated = True
            self.events.append(
                StopEvent(
                    "retreat",
                    t_s,
                    f"retreating to the rest configuration, at rest at {motion.end_s:.2f} s: still unknown "
                    f"({why})",
                )
            )

    def resumed(self, t_s: float) -> None:
        """A known re-plan was committed at the tick ``t_s`` [s] during the stop or the hold."""
        if self.rest_s is not None and not self.retreated:
            if t_s < self.rest_s - 1e-9 and self.events and self.events[-1].kind == "hold":
                self.events.pop()  # resumed while stopping: it never came to rest
            self.events.append(StopEvent("resume", t_s, "known again: re-targeting resumed"))
            self.rest_s = None
