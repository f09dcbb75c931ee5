"""Closed-loop hand-over: the robot starts moving early and re-plans, jerk-limited, as the human moves.

:class:`ClosedLoopPlanner` receives the human's samples one by one (:meth:`~ClosedLoopPlanner.step`)
and runs a simulated control loop at ``control_rate_hz`` (no waiting):

* every sample goes into the model's streaming estimator (:meth:`~ipromp_pin.promp.IProMP.stream`);
* from ``start_s`` on (the start rule's time: :meth:`ClosedLoopSettings.start_after`, or earlier
  once a task is recognised with the settings' ``start_confidence``), at ``replan_rate_hz`` the
  task, phase and conditioned robot trajectory are re-estimated
  (:meth:`~ipromp_pin.promp.streaming.StreamingEstimator.predict`; with
  ``settings.handover_estimates`` also conditioned on the model's hand-over estimates, the hand-over
  regression and the orientation estimate, by the one-shot plan's predictor: with the model's own
  conditioning noise each re-plan's prediction is then :meth:`IProMP.predict
  <ipromp_pin.promp.IProMP.predict>` of the same samples) and the commanded motion is
  re-targeted with ruckig from the commanded position, velocity and acceleration at the next
  control tick (:mod:`ipromp_pin.motion.retarget`): it follows the predicted robot trajectory on the
  human's predicted timeline, slowed only where the limits demand;
* the remaining motion of every re-plan is checked before it is committed, by the run's checks
  (:class:`~ipromp_pin.safety.CheckSuite`: the velocity, acceleration and jerk against the
  :class:`~ipromp_pin.motion.limits.LimitProfile`, joint limits, workspace, self-collision, the
  human as observed until then, the arm's torques), re-targeted slower while they ask for it by the
  one loop of every planner (:func:`~ipromp_pin.safety.retime.retime_until_safe`, with the re-target
  as its timer: :func:`~.timers.retarget_timer`); after a re-plan that checked its unslowed motion
  and had to slow it down, the next one starts from the slow-down that turned out to be needed
  (:func:`~ipromp_pin.safety.retime.next_guess`, or where it was slowed locally: re-plans are 50 ms
  apart, and the human rarely changes the needed slow-down much in between); the delay it costs is
  recorded. A re-plan that
  fails is not committed: the robot keeps the last safe plan and the :class:`Replan` record says
  why. A change of recognised task is handled the same way.
* on an arm placed beside the model's robot (a :class:`~.transfer.ReplanTransfer`), each re-plan's
  predicted reference motion becomes the executing arm's through the gripper before it is
  re-targeted and checked on that arm; a re-plan whose hand-over pose the arm cannot reach is refused
  like any other (``unreachable``: the robot keeps its last committed plan).
* with ``require_known``, a re-plan whose observation is unknown after a committed motion stops the
  robot (jerk-limited), holds it at rest for ``unknown_hold_s`` and, if the observation is still
  unknown then, retreats it to its rest configuration; a known re-plan during the stop or the hold
  resumes re-targeting (:mod:`.unknown_stop`).

Before its first committed plan the robot rests at its start configuration. :meth:`finish` plays
the last committed plan to its end and returns the commanded trajectory with every re-plan.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field

import numpy as np

from ..data import DEFAULT_WINDOW_FRACTION, WINDOW_RANGE_S, Demo
from ..exceptions import IPrompPinError, ObservationError, PipelineError
from ..motion.limits import LimitProfile
from ..motion.retarget import HEADROOM, SETTLE_S, ReferenceMotion, Retargeter, RetargetReport
from ..motion.time_warp import TimeWarp
from ..motion.trajectory import MotionState, Trajectory
from ..promp import IProMP, Prediction, Predictor, Recognition
from ..robot import Robot
from ..safety import CheckContext, CheckSuite, Verdict, next_guess
from ..safety.self_collision import SelfCollisionMeasures
from ..safety.speed_limits import SpeedLimitMeasures
from ..safety.workspace import WorkspaceMeasures
from .human_forecast import forecast_of, replan_context
from .timers import CountedTimer, retarget_timer
from .transfer import ReplanTransfer, predicts_gripper, start_motions
from .unknown_stop import UNKNOWN_HOLD_RANGE_S, UNKNOWN_HOLD_S, Segment, StopEvent, UnknownStop

CONDITION_NOISE = 0.3
"""Observation-noise ratio ``nu`` with which the closed loop conditions the robot trajectory (the
task and phase are recognised with the model's own ``nu``). ``fit`` chooses its ``nu`` (30-100 on the
real data) for recognition and phase early in the motion; the closed loop's hand-over is predicted
from most of the motion, where a tighter noise conditions the robot more on what was observed.
Chosen by cross-validation of the closed loop on training demos (``benchmarks/closed_loop_cv.py
--study noise``, ``docs/closed_loop.md``)."""


def conditioning_predictor(model: IProMP, noise: float | None) -> Predictor:
    """The predictor whose conditioner the closed loop uses: the model's own (``noise`` None) or one
    that conditions the robot's weights with the noise ratio ``noise`` (its ``condition_noise_ratio``;
    the same fitted model otherwise: recognition and phase keep the model's own;
    :meth:`Predictor.with_condition_noise <ipromp_pin.promp.predictor.Predictor.with_condition_noise>`)."""
    return model.predictor_.with_condition_noise(noise)


START_FRACTION = DEFAULT_WINDOW_FRACTION
"""The start rule's default: the robot starts this fraction of the model's nominal duration (the mean
length of its training demos) after the motion's start, a time it knows before the motion starts (as
``plan``'s default observation window)."""


@dataclass(frozen=True)
class ClosedLoopSettings:
    """Settings of the closed loop. The defaults of the start, re-plan rate, blend horizon, freeze
    phase and conditioning noise were chosen by cross-validation on training demos
    (``docs/closed_loop.md``); the settle window and the headroom are technical margins
    (:mod:`ipromp_pin.motion.retarget`).

    When the robot starts is a rule it can apply online: ``start_after_s`` seconds after the motion's
    start (by default :data:`START_FRACTION` of the model's nominal duration), or earlier once a task
    is recognised with posterior ``start_confidence``. Offline, ``start_ratio`` starts it after a
    fraction of the recorded motion's own length instead (the paper's protocol: that length is known
    only once the motion is over).

    Attributes:
        start_ratio: Offline only: start after this fraction of the demo's own length, in (0, 1)
            (None: the online rule).
        start_after_s: Start this long after the motion's start, in [s] (None: :data:`START_FRACTION`
            of the model's nominal duration); not with ``start_ratio``.
        start_confidence: Also start as soon as a task's posterior reaches this, in (0, 1] (None: by
            time alone).
        replan_rate_hz: Re-plan rate in [Hz] (> 0, at most the control rate).
        control_rate_hz: Control rate in [Hz] of the commanded trajectory.
        blend_s: Blend horizon in [s]: a re-plan joins the predicted trajectory this much later.
        settle_s: The last part of the predicted trajectory, in [s], replaced by a ruckig settle.
        headroom: Fraction of the limits the followed prediction may use.
        freeze_phase: Re-planning stops once the human's motion is this far through its predicted
            duration (observed time / predicted hand-over time); the robot then completes its last
            plan. 1: re-plan while samples arrive.
        condition_noise: Noise ratio with which the robot trajectory is conditioned (None: the
            model's own).
        handover_estimates: Whether each re-plan also applies the model's hand-over estimates (the
            hand-over regression and the orientation estimate), as :meth:`IProMP.predict
            <ipromp_pin.promp.IProMP.predict>` and the one-shot plan do. Off by default: measured
            against the closed loop without them (``docs/closed_loop.md``), they made the arrival
            later.
        require_known: The robot acts only on a known task: it does not start while the observation
            matches none of the model's tasks (its novelty p-value at most the model's ``alpha``, or no
            task explains it), and once started, a re-plan whose observation is unknown is not
            committed: the robot stops, holds and then retreats (:mod:`.unknown_stop`). False: act on
            the most probable task whatever its novelty.
        unknown_hold_s: With ``require_known``: how long the robot holds at rest after stopping on an
            unknown observation before it retreats, in [s] (:data:`~.unknown_stop.UNKNOWN_HOLD_S`).
    """

    start_ratio: float | None = None
    start_after_s: float | None = None
    start_confidence: float | None = None
    replan_rate_hz: float = 20.0
    control_rate_hz: float = 100.0
    blend_s: float = 0.2
    settle_s: float = SETTLE_S
    headroom: float = HEADROOM
    freeze_phase: float = 0.9
    condition_noise: float | None = CONDITION_NOISE
    handover_estimates: bool = False
    require_known: bool = True
    unknown_hold_s: float = UNKNOWN_HOLD_S

    def validate(self, source: str = "closed loop") -> ClosedLoopSettings:
        """Check the values; raise :class:`PipelineError` naming ``source`` and the field."""

        def bad(name: str, problem: str) -> PipelineError:
            return PipelineError(f"{source}: field '{name}': {problem}")

        r = self.start_ratio
        if r is not None and not (isinstance(r, int | float) and math.isfinite(r) and 0.0 < r < 1.0):
            raise bad("start_ratio", f"must be in (0, 1), got {r}")
        a = self.start_after_s
        if a is not None and not (isinstance(a, int | float) and WINDOW_RANGE_S.contains(a)):
            raise bad("start_after_s", f"must be a time in {WINDOW_RANGE_S.text()}, got {a}")
        if r is not None and a is not None:
            raise bad("start_after_s", "give start_ratio (offline) or start_after_s, not both")
        p = self.start_confidence
        if p is not None and not (isinstance(p, int | float) and math.isfinite(p) and 0.0 < p <= 1.0):
            raise bad("start_confidence", f"must be a posterior in (0, 1], got {p}")
        c = self.control_rate_hz
        if not (math.isfinite(c) and c > 0):
            raise bad("control_rate_hz", f"must be a positive rate, got {c}")
        p = self.replan_rate_hz
        if not (math.isfinite(p) and p > 0):
            raise bad("replan_rate_hz", f"must be a positive rate, got {p}")
        if p > c:
            raise bad("replan_rate_hz", f"{p:g} Hz is faster than the control rate {c:g} Hz")
        for name, v in (("blend_s", self.blend_s), ("settle_s", self.settle_s)):
            if not (math.isfinite(v) and v >= 0) or (name == "blend_s" and v == 0):
                raise bad(name, f"must be {'positive' if name == 'blend_s' else '>= 0'} and finite, got {v}")
        if not (math.isfinite(self.headroom) and 0 < self.headroom <= 1):
            raise bad("headroom", f"must be in (0, 1], got {self.headroom}")
        if not (math.isfinite(self.freeze_phase) and 0 < self.freeze_phase <= 1):
            raise bad("freeze_phase", f"must be in (0, 1], got {self.freeze_phase}")
        nu = self.condition_noise
        if nu is not None and not (isinstance(nu, int | float) and math.isfinite(nu) and nu > 0):
            raise bad("condition_noise", f"must be a positive number (or the model's own), got {nu}")
        for name in ("handover_estimates", "require_known"):
            if not isinstance(getattr(self, name), bool):
                raise bad(name, f"must be true or false, got {getattr(self, name)!r}")
        h = self.unknown_hold_s
        if not (isinstance(h, int | float) and not isinstance(h, bool) and UNKNOWN_HOLD_RANGE_S.contains(h)):
            raise bad(
                "unknown_hold_s", UNKNOWN_HOLD_RANGE_S.problem(h) if isinstance(h, int | float) else f"{h!r}"
            )
        return self

    def to_dict(self) -> dict:
        """JSON-serialisable form."""
        return asdict(self)

    def start_after(self, nominal_s: float) -> float | None:
        """The start rule's time in [s] from the motion's start for a model of nominal duration
        ``nominal_s`` [s] (None with ``start_ratio``: it depends on the recording's length)."""
        if self.start_ratio is not None:
            return None
        return self.start_after_s if self.start_after_s is not None else START_FRACTION * float(nominal_s)

    def start_text(self, nominal_s: float) -> str:
        """The start rule in words, e.g. ``after 0.64 s (20% of the model's nominal 3.20 s)``."""
        if self.start_ratio is not None:
            text = f"after {self.start_ratio:.0%} of the recording (offline)"
        elif self.start_after_s is not None:
            text = f"after {self.start_after_s:g} s"
        else:
            nominal = f"{START_FRACTION:.0%} of the model's nominal {nominal_s:.2f} s"
            text = f"after {START_FRACTION * nominal_s:.2f} s ({nominal})"
        if self.start_confidence is not None:
            text += f" or once a task's posterior reaches {self.start_confidence:g}"
        return text


@dataclass
class Replan:
    """One re-plan of the closed loop.

    Attributes:
        index: Re-plan number (from 0).
        t_s: Control tick at which the new plan would take over, in [s] from the motion start.
        observed_until_s: Time of the last human sample used, in [s].
        n_observed: Human samples received.
        task: Recognised task.
        posterior: Task -> posterior probability.
        known: Whether the observation was recognised as one of the model's tasks.
        novelty_p_value: The observation's conformal novelty p-value (None: no novelty detector).
        predicted_handover_s: Predicted hand-over time (end of the human's motion) in [s].
        predicted_handover_position_m: Gripper position (3,) at the predicted hand-over in [m].
        planned_arrival_s: When the planned motion comes to rest, in [s] (None if no plan was made).
        lateness_s: ``planned_arrival_s - predicted_handover_s`` in [s] (how late the limits make it).
        time_scale: Slow-down of the followed prediction (1: on the human's timeline).
        committed: Whether the plan was committed.
        reason: Why it was refused (empty when committed).
        limit_ratios: Largest |v|, |a|, |jerk| over their limits in the plan (3,).
        min_distance_m: Closest computed self-collision distance near the plan, in [m].
        checks: Timed-motion check name -> its status, reason and values (:mod:`ipromp_pin.safety`),
            for the last plan checked.
        slowdown: Extra slow-down ``k >= 1`` that the timed-motion checks asked for (1: none; slowed
            only where they asked: how many times longer the plan takes).
        slowdown_local: Whether the plan was slowed only where the checks asked (its reference's
            timeline warped there, :mod:`~ipromp_pin.motion.time_warp`), not as a whole.
        slowdown_delay_s: How much later the slowed plan arrives than the plan without it, in [s].
        cycle_ms: Wall time of the cycle in [ms]: stream update of the latest sample, conditioning,
            re-target, checks.
        stage_ms: Wall time per stage in [ms].
        retarget: How the reference came from the model's robot through the gripper
            (:meth:`~.transfer.ReplanRetarget.to_dict`; None: the model predicts this arm's joints).
        action: What the plan does: ``""`` a re-target toward the hand-over, ``stop`` or ``retreat``
            on an unknown observation (:mod:`.unknown_stop`).
    """

    index: int
    t_s: float
    observed_until_s: float
    n_observed: int
    task: str = ""
    posterior: dict[str, float] = field(default_factory=dict)
    known: bool = True
    novelty_p_value: float | None = None
    predicted_handover_s: float | None = None
    predicted_handover_position_m: list[float] | None = None
    planned_arrival_s: float | None = None
    lateness_s: float | None = None
    time_scale: float | None = None
    committed: bool = False
    reason: str = ""
    limit_ratios: list[float] | None = None
    min_distance_m: float | None = None
    checks: dict[str, dict] = field(default_factory=dict)
    slowdown: float = 1.0
    slowdown_local: bool = False
    slowdown_delay_s: float = 0.0
    cycle_ms: float = 0.0
    stage_ms: dict[str, float] = field(default_factory=dict)
    retarget: dict | None = None
    action: str = ""

    def to_dict(self) -> dict:
        """JSON-serialisable form (rounded)."""
        out = asdict(self)
        for k, v in out.items():
            if isinstance(v, float):
                out[k] = round(v, 6)
        out["stage_ms"] = {k: round(v, 4) for k, v in self.stage_ms.items()}
        out["cycle_ms"] = round(self.cycle_ms, 4)
        return out


@dataclass
class ClosedLoopResult:
    """What a closed-loop run commanded.

    Attributes:
        trajectory: The commanded trajectory at the control rate, from the motion start (t = 0)
            until it comes to rest (``qddd``: jerk between samples).
        replans: Every re-plan, committed or refused.
        profile: The limit profile used.
        settings: The closed-loop settings.
        start_s: When the robot was allowed to start, in [s] (its first re-plan; the start rule's time
            when it never started).
        stopped: Why re-planning stopped before the human's last sample, or why the robot never
            started (an unknown task, ``require_known``; empty if neither).
        plans: The committed plans, in the order of the committed re-plans.
        start_reason: What started the robot and when (empty: it never started).
        start_rule: The start rule in words (:meth:`ClosedLoopSettings.start_text`).
        robot: The executing arm's name.
        source_robot: The model's robot when the arm executed it retargeted through the gripper
            (empty: the arm's own model).
        unknown_events: When the observation turned unknown after the start, the robot held, resumed
            or retreated (:class:`~.unknown_stop.StopEvent`, in time order).
        tool: The executing arm's ``[tool]``, the gripper its URDF lacks (``Tool.to_dict``; None: none).
    """

    trajectory: Trajectory
    replans: list[Replan]
    profile: LimitProfile
    settings: ClosedLoopSettings
    start_s: float
    stopped: str = ""
    plans: list[Trajectory] = field(default_factory=list)
    start_reason: str = ""
    start_rule: str = ""
    robot: str = ""
    source_robot: str = ""
    unknown_events: list[StopEvent] = field(default_factory=list)
    tool: dict | None = None

    def first_event_s(self, kind: str) -> float | None:
        """The time [s] of the first :attr:`unknown_events` of ``kind`` (None: none)."""
        return next((e.t_s for e in self.unknown_events if e.kind == kind), None)

    @property
    def n_refused(self) -> int:
        """Re-plans that were not committed."""
        return sum(not r.committed for r in self.replans)

    @property
    def n_committed(self) -> int:
        """Re-plans that were committed."""
        return sum(r.committed for r in self.replans)

    @property
    def arrival_s(self) -> float:
        """When the commanded motion comes to rest (its last sample), in [s]."""
        return float(self.trajectory.t_s[-1])


class ClosedLoopPlanner:
    """Runs the closed loop on a stream of human samples (see the module docstring).

    Used as a context manager (``with ClosedLoopPlanner(...) as planner:``), it opens the model's
    streaming estimator on entry (BLAS threads limited once for the whole loop) and closes it on exit;
    without one, the stream is opened on the first :meth:`step` and closed by :meth:`close` or
    :meth:`finish`.

    Args:
        model: A fitted model.
        robot: The loaded robot.
        profile: Velocity, acceleration and jerk limits (and position limits with margin).
        q_start: The robot's configuration (n_joints,) in [rad] at the motion start (at rest).
        start_s: Time in [s] from the motion start at which the robot may start (its first re-plan
            is at the first sample at or after it, or earlier at the first sample whose task
            posterior reaches ``settings.start_confidence``).
        settings: Closed-loop settings (validated here).
        suite: The checks of every re-plan's remaining motion (default: every registered check,
            :meth:`~ipromp_pin.safety.CheckSuite.build`; reuse one across runs of the same robot to
            keep its self-collision certifier's computed distances).
        context: What the checks know about the world (the human, the object, ...); each re-plan
            adds the recognised task, the predicted hand-over time, the limit profile and cuts the
            human to what was observed until then.
        conditioner: The predictor that conditions the robot trajectory and applies the hand-over
            estimates (default: the stream's predictor for ``settings.condition_noise``,
            :meth:`~ipromp_pin.promp.streaming.StreamingEstimator.predict`).
        transfer: The retargeting of each re-plan's reference to ``robot`` when the model predicts
            another robot's joints (None: ``robot``'s own; ``q_start`` is ``robot``'s either way).

    Attributes:
        prediction: The prediction of the latest re-plan (None before the first).
    """

    def __init__(
        self,
        model: IProMP,
        robot: Robot,
        profile: LimitProfile,
        q_start: np.ndarray,
        start_s: float,
        settings: ClosedLoopSettings | None = None,
        suite: CheckSuite | None = None,
        context: CheckContext | None = None,
        conditioner: Predictor | None = None,
        transfer: ReplanTransfer | None = None,
    ) -> None:
        self.settings = (settings or ClosedLoopSettings()).validate()
        self.transfer = transfer
        self.model, self.forecast = model, forecast_of(model, robot.settings.human)
        self.robot = robot
        self.profile = profile
        self.start_s = float(start_s)
        self.dt_s = 1.0 / self.settings.control_rate_hz
        self.suite = suite if suite is not None else CheckSuite.build(robot)
        s = self.settings
        self.retargeter = Retargeter(profile.limits, self.dt_s, s.blend_s, s.headroom, s.settle_s)
        self._conditioner = conditioner
        self.context = (context if context is not None else CheckContext()).replace(limits=profile.limits)
        self._stream = model.stream()
        self._open = False
        self._plans: list[tuple[int, Trajectory]] = [
            (0, Trajectory.at_rest(0.0, q_start, tuple(robot.joint_names)))
        ]
        self.replans: list[Replan] = []
        self._next_replan = self.start_s
        self._started = False
        self.start_reason = ""
        self._waiting = ""  # why the robot has not started although the start rule's time has come
        self._unknown_since = ""
        self.start_rule = self.settings.start_text(float(model.duration_nominal_s_))
        self.prediction: Prediction | None = None  # that of the latest re-plan
        self._guess: float | None = None
        self._warp_guess: TimeWarp | None = None  # where the last re-plan was slowed locally
        self._stopped = ""
        self._finished = False
        self._unknown = UnknownStop(self.suite, profile.limits, q_start, s.unknown_hold_s, self.dt_s)
        self._task = ""  # that of the last committed re-plan

    def __enter__(self) -> ClosedLoopPlanner:
        self._open_stream()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _open_stream(self) -> None:
        """Open the streaming estimator (limits the BLAS threads until :meth:`close`)."""
        if not self._open and not self._finished:
            self._stream.__enter__()
            self._open = True

    # ------------------------------------------------------------------ loop
    def _tick(self, t_s: float) -> int:
        """The control tick at or after ``t_s`` (a sample at a tick's time is at that tick)."""
        x = t_s / self.dt_s
        k = round(x)
        return int(k) if abs(x - k) < 1e-6 else int(math.ceil(x))

    def state_at(self, tick: int) -> MotionState:
        """The commanded state at control tick ``tick`` (of the plan in force then)."""
        k0, plan = next((k, p) for k, p in reversed(self._plans) if k <= tick)
        st = plan.state(tick - k0)
        return MotionState(tick * self.dt_s, st.q, st.qd, st.qdd)

    def step(self, t_s: float, sample: Mapping[str, np.ndarray | None]) -> Replan | None:
        """Receive one human sample (time in [s] from the motion start; observed group -> values,
        None for a missing group) and re-plan when one is due; returns the re-plan, if any."""
        if self._finished:
            raise PipelineError("closed loop: step() after finish()")
        t0 = time.perf_counter()
        if self._stopped:
            return None
        if not self._open:
            self._open_stream()
        try:
            rec = self._stream.update(t_s, sample)
        except IPrompPinError as exc:
            self._stopped = f"stream stopped at t={t_s:.3f} s: {exc}"
            return None
        t1 = time.perf_counter()
        if rec is None or not self._may_start(t_s, rec) or t_s < self._next_replan - 1e-9:
            return None
        freeze = self.settings.freeze_phase
        stopping = self._unknown.hold_end_s() is not None  # frozen only once it retreats or resumes
        if freeze < 1.0 and len(self._plans) > 1 and not stopping and t_s >= freeze * rec.duration_s:
            self._stopped = (
                f"re-planning stopped at t={t_s:.3f} s: {t_s / rec.duration_s:.0%} of the predicted "
                f"motion observed (freeze_phase {self.settings.freeze_phase:g})"
            )
            return None
        period = 1.0 / self.settings.replan_rate_hz
        while self._next_replan <= t_s + 1e-9:
            self._next_replan += period
        replan = self._replan(t_s, t1 - t0)
        replan.cycle_ms = (time.perf_counter() - t0) * 1e3
        self.replans.append(replan)
        return replan

    def _may_start(self, t_s: float, rec: Recognition) -> bool:
        """Whether the robot has started by ``t_s``: the start rule's time is reached, or the task
        posterior reaches ``start_confidence`` (the start is then at ``t_s``)."""
        if self._started:
            return True
        if self.settings.require_known and not rec.known:
            if not self._unknown_since:
                self._unknown_since = f"{t_s:.2f} s"
            self.start_reason = ""
            self._waiting = f"never started: unknown task from {self._unknown_since} ({rec.unknown_reason})"
            return False
        self._unknown_since = ""
        confidence = self.settings.start_confidence
        best = int(np.argmax(rec.posterior))
        if t_s >= self.start_s - 1e-9:
            self.start_reason = f"at {t_s:.2f} s, the start rule's time"
        elif confidence is not None and rec.posterior[best] >= confidence:
            self.start_reason = (
                f"at {t_s:.2f} s, {rec.tasks[best]} recognised with posterior {rec.posterior[best]:.3f} >= "
                f"{confidence:g}"
            )
        else:
            return False
        self._started = True
        self._waiting = ""
        self.start_s = self._next_replan = t_s
        return True

    def _replan(self, t_s: float, update_s: float) -> Replan:
        tick = self._tick(t_s)
        state = self.state_at(tick)
        stream = self._stream
        ms: dict[str, float] = {"stream_update": update_s * 1e3}
        r = Replan(len(self.replans), tick * self.dt_s, float(t_s), stream.n_samples)
        t0 = time.perf_counter()
        try:
            s = self.settings
            pred = stream.predict(s.condition_noise, self._conditioner, s.handover_estimates)
            reference = ReferenceMotion.from_prediction(pred)
        except IPrompPinError as exc:
            r.reason = f"prediction failed: {exc}"
            return r
        t1 = time.perf_counter()
        ms["condition"] = (t1 - t0) * 1e3
        self.prediction = pred
        r.task = pred.task
        r.posterior = {k: float(v) for k, v in zip(pred.tasks, pred.posterior, strict=True)}
        r.known = bool(pred.known)
        r.novelty_p_value = None if math.isnan(pred.novelty_p_value) else float(pred.novelty_p_value)
        r.predicted_handover_s = float(pred.duration_s)
        if self.settings.require_known and not pred.known:
            r.reason = f"not re-targeted: unknown task ({pred.unknown_reason})"
            r.stage_ms = ms
            if len(self._plans) > 1:  # it moved: stop, hold, retreat
                self._unknown_segment(r, tick, state, pred.unknown_reason or "")
            return r
        if self.transfer is not None:  # the model's robot's reference -> this arm's, through the gripper
            # not moved yet after a refused re-plan (that was not restarted): from where its gripper is
            last = self.replans[-1] if self.replans else None
            refused = last is not None and not last.committed and not (last.retarget or {}).get("restarted")
            restart = len(self._plans) == 1 and refused
            moved, how = self.transfer.reference(reference, state.q, float(state.t_s), restart)
            ms["arm_transfer"] = how.ms
            r.retarget = how.to_dict()
            if moved is None:  # refused as any failed re-plan: never a shifted hand-over
                r.reason = f"unreachable: {self.transfer.why_not_reached(how)}"
                r.stage_ms = ms
                return r
            reference = moved
        context = replan_context(self.context, pred, r.observed_until_s, self.forecast)
        plan = self._plan_checked(state, reference, r, ms, context)
        r.stage_ms = ms
        if plan is not None and not r.reason:
            r.committed = True
            self._plans.append((tick, plan))
            self._task = pred.task
            self._unknown.resumed(tick * self.dt_s)
        return r

    def _unknown_segment(self, r: Replan, tick: int, state: MotionState, why: str) -> None:
        """Commit the stop or the retreat due at ``tick`` (:meth:`UnknownStop.due`) into ``r``, an
        unknown re-plan at the commanded ``state``, when its checks pass."""
        action = self._unknown.due(tick * self.dt_s)
        if not action:
            return
        t0 = time.perf_counter()
        context = self.context.replace(task=self._task or None, handover_s=None)
        if context.human is not None:
            context = context.replace(human=context.human.until(r.observed_until_s))
        segment = self._unknown.segment(action, state, context)
        r.stage_ms[action] = (time.perf_counter() - t0) * 1e3
        record_segment(r, segment)
        motion = segment.motion
        if motion is None:
            r.reason = f"{r.reason}; {segment.reason}"
            return
        r.committed, r.reason = True, ""
        self._plans.append((tick, motion))
        self._unknown.committed(segment, tick * self.dt_s, why)
        if action == "retreat":
            self._stopped = (
                f"re-planning stopped at t={r.t_s:.3f} s: retreating, the task still unknown ({why})"
            )

    def _plan_checked(
        self,
        state: MotionState,
        reference: ReferenceMotion,
        r: Replan,
        ms: dict[str, float],
        context: CheckContext,
    ) -> Trajectory | None:
        """Re-target, check, and re-target slower while the failing checks ask for it -> the committed
        plan (``r.reason`` empty), the refused one (``r.reason`` says why) or None when re-targeting
        failed."""
        t0 = time.perf_counter()
        retarget = retarget_timer(self.retargeter, state, reference, self._warp_guess)
        timer = CountedTimer(retarget)  # the rest of the loop's time: the checks
        try:
            retimed = self.suite.retime_until_safe(timer, context, stop_early=True, guess=self._guess)
        except IPrompPinError as exc:
            r.reason = f"re-target failed: {exc}"
            self._guess = self._warp_guess = None
            return None
        finally:
            ms["retarget"] = timer.spent_s * 1e3
            ms["checks"] = (time.perf_counter() - t0 - timer.spent_s) * 1e3
        report = retimed.timed.report
        first = retimed.first.report
        assert isinstance(report, RetargetReport) and isinstance(first, RetargetReport)
        r.planned_arrival_s = report.arrival_s
        r.lateness_s = report.lateness_s
        r.time_scale = report.time_scale
        r.slowdown, r.slowdown_local = retimed.slowdown, retimed.local
        r.slowdown_delay_s = float(report.arrival_s - first.arrival_s)
        record_verdicts(r, retimed.verdicts)
        r.reason = retimed.report.refusal()
        self._guess = next_guess(retimed)
        # slowed locally from its unslowed motion: the next re-plan checks first that slow-down
        fresh = retimed.local and retimed.passed and not retimed.guessed
        self._warp_guess = retarget.warp if fresh else None
        return retimed.motion

    def close(self) -> None:
        """Stop receiving samples (releases the streaming estimator's BLAS thread limit)."""
        if not self._finished:
            if self._open:
                self._stream.__exit__(None, None, None)
                self._open = False
            self._finished = True

    def finish(self) -> ClosedLoopResult:
        """Stop receiving samples and return the commanded trajectory until it comes to rest."""
        self.close()
        last_unknown = bool(self.replans) and not self.replans[-1].known
        end = self._unknown.hold_end_s()
        if self.settings.require_known and last_unknown and end is not None:  # samples ended in the hold
            observed = self.replans[-1].observed_until_s
            r = Replan(len(self.replans), 0.0, observed, self._stream.n_samples, known=False)
            tick = max(self._tick(end), self._plans[-1][0] + 1, self._tick(self.replans[-1].t_s) + 1)
            r.t_s = tick * self.dt_s
            r.reason = "not re-targeted: the human's samples ended while the robot held"
            self._unknown_segment(r, tick, self.state_at(tick), "the last observation was unknown")
            self.replans.append(r)
        k_last, last = self._plans[-1]
        n = k_last + last.n_samples
        nj = last.q.shape[1]
        q = np.empty((n, nj))
        qd = np.empty((n, nj))
        qdd = np.empty((n, nj))
        bounds = [k for k, _ in self._plans[1:]] + [n]
        for (k0, plan), k1 in zip(self._plans, bounds, strict=True):
            idx = np.arange(k0, k1) - k0
            inside = idx < plan.n_samples
            j = np.minimum(idx, plan.n_samples - 1)
            q[k0:k1] = plan.q[j]
            qd[k0:k1] = np.where(inside[:, None], plan.qd[j], 0.0)
            qdd[k0:k1] = np.where(inside[:, None], plan.qdd[j], 0.0)
        t = np.arange(n) * self.dt_s
        qddd = np.zeros_like(qdd)
        if n > 1:
            qddd[1:] = np.diff(qdd, axis=0) / self.dt_s
        traj = Trajectory(t, q, qd, qdd, tuple(self.robot.joint_names), qddd)
        plans = [p for _, p in self._plans[1:]]
        return ClosedLoopResult(
            traj,
            self.replans,
            self.profile,
            self.settings,
            self.start_s,
            self._stopped or self._waiting,
            plans,
            self.start_reason,
            self.start_rule,
            self.robot.settings.name,
            "" if self.transfer is None else self.transfer.source.settings.name,
            list(self._unknown.events),
            self.robot.settings.tool_record,
        )


def record_segment(r: Replan, segment: Segment) -> None:
    """Fill ``r``'s action, check fields, arrival and slow-down from a stop or retreat segment."""
    r.action = segment.action
    if segment.retimed is not None:
        record_verdicts(r, segment.retimed.verdicts)
        r.planned_arrival_s = segment.retimed.motion.end_s
        r.slowdown = segment.retimed.slowdown


def record_verdicts(r: Replan, verdicts: list[Verdict]) -> None:
    """Fill ``r``'s check fields from the verdicts of its plan: every verdict, the limit ratios, the
    self-collision distance and the predicted hand-over position (those the checks reached)."""
    r.checks = {v.name: v.to_dict() for v in verdicts}
    for v in verdicts:
        m = v.measures
        if isinstance(m, SpeedLimitMeasures):
            r.limit_ratios = list(m.limit_ratios)
        elif isinstance(m, WorkspaceMeasures):
            r.predicted_handover_position_m = list(m.position_m)
        elif isinstance(m, SelfCollisionMeasures):
            r.min_distance_m = float(m.min_distance_m)


def demo_samples(demo: Demo, groups: list[str]) -> list[dict[str, np.ndarray | None]]:
    """The demo's human samples as the planner receives them: group -> values, None where missing."""
    return [
        {g: None if (g in demo.missing and demo.missing[g][i]) else demo.groups[g][i] for g in groups}
        for i in range(demo.n_samples)
    ]


def start_time(demo: Demo, settings: ClosedLoopSettings, nominal_s: float) -> float:
    """When the robot starts replaying ``demo`` by the start rule, in [s] from its start: the last
    sample of its first ``start_ratio`` (offline), else the rule's time
    (:meth:`ClosedLoopSettings.start_after` of a model of nominal duration ``nominal_s`` [s]); the
    ``start_confidence`` may start it earlier (:class:`ClosedLoopPlanner`).

    Raises:
        ObservationError: the start window holds fewer than 2 samples, or ends after the demo.
    """
    length = float(demo.t[-1] - demo.t[0])
    ratio = settings.start_ratio
    after = settings.start_after(nominal_s)
    name = "start_ratio" if ratio is not None else "start_after_s"
    window = f"{ratio:.0%} of" if ratio is not None else f"{after:.2f} s of"
    if after is not None and after > length:
        problem = f"the robot would start at {after:.2f} s, after the demo's end ({length:.2f} s)"
        raise ObservationError(demo.source, name, problem)
    try:
        cut = demo.head(ratio) if ratio is not None else demo.until(after or 0.0)
    except ObservationError:
        raise ObservationError(
            demo.source,
            name,
            f"the start window ({window} a {length:.2f} s demo of {demo.n_samples} samples) holds fewer "
            "than 2 samples",
        ) from None
    return float(cut.t[-1] - demo.t[0])


def replay_demo(
    model: IProMP,
    robot: Robot,
    demo: Demo,
    profile: LimitProfile,
    settings: ClosedLoopSettings | None = None,
    suite: CheckSuite | None = None,
    context: CheckContext | None = None,
    conditioner: Predictor | None = None,
    source: Robot | None = None,
) -> ClosedLoopResult:
    """Run the closed loop on a recorded demo at its recorded timing (simulated clock, no waiting).

    The robot starts at rest at the demo's first recorded configuration; the human's observed groups
    (``model.observe_``) arrive sample by sample. ``suite`` and ``context``: the checks of every
    re-plan and what they know (:class:`ClosedLoopPlanner`). ``source``: the robot the demo and the
    model are recorded on when ``robot`` is placed beside it (every re-plan retargeted through the
    gripper, :class:`~.transfer.ReplanTransfer`; ``robot`` starts where its gripper meets the recorded
    start's).

    Raises:
        DataError: the demo lacks an observed group or the robot group.
        ObservationError: the start window holds fewer than 2 samples or ends after the demo.
        UnreachableError: ``robot`` cannot reach the recorded start pose.
    """
    settings = (settings or ClosedLoopSettings()).validate()
    groups = list(model.observe_)
    demo.require(groups + [model.robot_group])
    start = start_time(demo, settings, float(model.duration_nominal_s_))
    q_start = demo.groups[model.robot_group][0]
    poses = predicts_gripper(model)  # gripper poses: always followed by inverse kinematics
    source = robot if source is None and poses else source
    transfer = None if source is None else ReplanTransfer(source, robot, from_poses=poses)
    if transfer is not None:  # its start configuration chosen for the tasks' motions, the human in view
        q_start = transfer.start(q_start, start_motions(model, suite, context))
    with ClosedLoopPlanner(
        model, robot, profile, q_start, start, settings, suite, context, conditioner, transfer
    ) as planner:
        for t, sample in zip(demo.t - demo.t[0], demo_samples(demo, groups), strict=True):
            planner.step(float(t), sample)
    return planner.finish()
