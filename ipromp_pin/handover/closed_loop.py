"""Closed-loop hand-over: the robot starts moving early and re-plans, jerk-limited, as the human moves.

:class:`ClosedLoopPlanner` receives the human's samples one by one (:meth:`~ClosedLoopPlanner.step`)
and runs a simulated control loop at ``control_rate_hz`` (no waiting):

* every sample goes into the model's streaming estimator (:meth:`~ipromp_pin.promp.IProMP.stream`);
* from ``start_s`` on (the replay's start ratio of the human's motion), at ``replan_rate_hz`` the
  task, phase and conditioned robot trajectory are re-estimated and the commanded motion is
  re-targeted with ruckig from the commanded position, velocity and acceleration at the next
  control tick (:mod:`ipromp_pin.motion.retarget`): it follows the predicted robot trajectory on the
  human's predicted timeline, slowed only where the limits demand;
* the remaining motion of every re-plan is checked before it is committed: velocity,
  acceleration and jerk at every control sample against the :class:`~ipromp_pin.motion.limits.LimitProfile`,
  joint limits with the settings' margin, the hand-over position inside the workspace, and
  self-collision certified between samples (:class:`~ipromp_pin.robot.clearance.ClearanceCertifier`),
  then the timed-motion checks (:mod:`ipromp_pin.checks`: the human, the arm's torques, ...) with the
  planner's :class:`~ipromp_pin.checks.CheckContext`. When a failing check says a slower motion would
  pass, the re-plan follows the prediction that much slower (at most
  :data:`~ipromp_pin.checks.MAX_SLOWDOWN` times) and is checked again; the delay it costs is recorded.
  A re-plan that fails is not committed: the robot keeps the last safe plan and the
  :class:`Replan` record says why. A change of recognised task is handled the same way.

Before its first committed plan the robot rests at its start configuration. :meth:`finish` plays
the last committed plan to its end and returns the commanded trajectory with every re-plan.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from ..checks import (
    MAX_SLOWDOWN,
    MAX_SLOWDOWN_ROUNDS,
    CheckContext,
    MotionCheck,
    TimedMotion,
    needed_slowdown,
    run_checks,
)
from ..data import Demo
from ..exceptions import IPrompPinError, ObservationError, PipelineError
from ..motion.limits import LimitProfile
from ..motion.retarget import (
    HEADROOM,
    SETTLE_S,
    MotionPlan,
    MotionState,
    ReferenceMotion,
    Retargeter,
    hold_plan,
    limit_ratios,
)
from ..motion.trajectory import Trajectory
from ..promp import IProMP, Predictor
from ..robot import CheckResult, Robot, check_joint_limits, check_workspace, ee_positions
from ..robot.clearance import ClearanceCertifier

LIMIT_TOLERANCE = 1e-6
"""Relative tolerance of the velocity, acceleration and jerk checks of a re-plan."""


SLOWDOWN_STEP = 1.05
"""Each slower re-target asks for 5 % more slow-down than the failing checks estimated."""

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


@dataclass(frozen=True)
class ClosedLoopSettings:
    """Settings of the closed loop. The defaults of the start ratio, re-plan rate, blend horizon,
    freeze phase and conditioning noise were chosen by cross-validation on training demos
    (``docs/closed_loop.md``); the settle window and the headroom are technical margins
    (:mod:`ipromp_pin.motion.retarget`).

    Attributes:
        start_ratio: Fraction of the human's motion observed before the robot starts, in (0, 1).
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
    """

    start_ratio: float = 0.2
    replan_rate_hz: float = 20.0
    control_rate_hz: float = 100.0
    blend_s: float = 0.2
    settle_s: float = SETTLE_S
    headroom: float = HEADROOM
    freeze_phase: float = 0.9
    condition_noise: float | None = CONDITION_NOISE

    def validate(self, source: str = "closed loop") -> ClosedLoopSettings:
        """Check the values; raise :class:`PipelineError` naming ``source`` and the field."""

        def bad(name: str, problem: str) -> PipelineError:
            return PipelineError(f"{source}: field '{name}': {problem}")

        r = self.start_ratio
        if not (isinstance(r, int | float) and math.isfinite(r) and 0.0 < r < 1.0):
            raise bad("start_ratio", f"must be in (0, 1), got {r}")
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
        return self

    def to_dict(self) -> dict:
        """JSON-serialisable form."""
        return asdict(self)


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
        predicted_handover_s: Predicted hand-over time (end of the human's motion) in [s].
        predicted_handover_position_m: Gripper position (3,) at the predicted hand-over in [m].
        planned_arrival_s: When the planned motion comes to rest, in [s] (None if no plan was made).
        lateness_s: ``planned_arrival_s - predicted_handover_s`` in [s] (how late the limits make it).
        time_scale: Slow-down of the followed prediction (1: on the human's timeline).
        committed: Whether the plan was committed.
        reason: Why it was refused (empty when committed).
        limit_ratios: Largest |v|, |a|, |jerk| over their limits in the plan (3,).
        min_distance_m: Closest computed self-collision distance near the plan, in [m].
        checks: Timed-motion check name -> its status, reason and values (:mod:`ipromp_pin.checks`),
            for the last plan checked.
        slowdown: Extra slow-down ``k >= 1`` that the timed-motion checks asked for (1: none).
        slowdown_delay_s: How much later the slowed plan arrives than the plan without it, in [s].
        cycle_ms: Wall time of the cycle in [ms]: stream update of the latest sample, conditioning,
            re-target, checks.
        stage_ms: Wall time per stage in [ms].
    """

    index: int
    t_s: float
    observed_until_s: float
    n_observed: int
    task: str = ""
    posterior: dict[str, float] = field(default_factory=dict)
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
    slowdown_delay_s: float = 0.0
    cycle_ms: float = 0.0
    stage_ms: dict[str, float] = field(default_factory=dict)

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
        start_s: When the robot was allowed to start, in [s].
        stopped: Why re-planning stopped before the human's last sample (empty if it did not).
        plans: The committed plans, in the order of the committed re-plans.
    """

    trajectory: Trajectory
    replans: list[Replan]
    profile: LimitProfile
    settings: ClosedLoopSettings
    start_s: float
    stopped: str = ""
    plans: list[MotionPlan] = field(default_factory=list)

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
            is at the first sample at or after it).
        settings: Closed-loop settings (validated here).
        certifier: Self-collision certifier to use (default: a new one; reuse one across runs of the
            same robot to keep its cache of computed distances).
        conditioner: The predictor whose conditioner conditions the robot trajectory (default: the
            stream's predictor for ``settings.condition_noise``,
            :meth:`~ipromp_pin.promp.streaming.StreamingEstimator.predict`).
        checks: Timed-motion checks run on every re-plan's remaining motion (default: none;
            :func:`ipromp_pin.checks.build_checks` gives the registered ones).
        context: What the checks know about the world (the human, the object, ...).
    """

    def __init__(
        self,
        model: IProMP,
        robot: Robot,
        profile: LimitProfile,
        q_start: np.ndarray,
        start_s: float,
        settings: ClosedLoopSettings | None = None,
        certifier: ClearanceCertifier | None = None,
        conditioner: Predictor | None = None,
        checks: Sequence[MotionCheck] = (),
        context: CheckContext | None = None,
    ) -> None:
        self.settings = (settings or ClosedLoopSettings()).validate()
        self.model = model
        self.robot = robot
        self.profile = profile
        self.start_s = float(start_s)
        self.dt_s = 1.0 / self.settings.control_rate_hz
        self.certifier = certifier if certifier is not None else ClearanceCertifier(robot)
        s = self.settings
        self.retargeter = Retargeter(profile.limits, self.dt_s, s.blend_s, s.headroom, s.settle_s)
        self._conditioner = conditioner
        self.checks = list(checks)
        self.context = context if context is not None else CheckContext()
        self._stream = model.stream()
        self._open = False
        self._plans: list[tuple[int, MotionPlan]] = [
            (0, hold_plan(MotionState.at_rest(0.0, q_start), self.dt_s))
        ]
        self.replans: list[Replan] = []
        self._next_replan = self.start_s
        self._stopped = ""
        self._finished = False
        self._pose_cache: tuple[bytes, np.ndarray, CheckResult] | None = None

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
        if rec is None or t_s < self.start_s - 1e-9 or t_s < self._next_replan - 1e-9:
            return None
        freeze = self.settings.freeze_phase
        if freeze < 1.0 and len(self._plans) > 1 and t_s >= freeze * rec.duration_s:
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

    def _replan(self, t_s: float, update_s: float) -> Replan:
        tick = self._tick(t_s)
        state = self.state_at(tick)
        stream = self._stream
        ms: dict[str, float] = {"stream_update": update_s * 1e3}
        r = Replan(len(self.replans), tick * self.dt_s, float(t_s), stream.n_samples)
        t0 = time.perf_counter()
        try:
            pred = stream.predict(self.settings.condition_noise, self._conditioner)
            reference = ReferenceMotion.from_prediction(pred)
        except IPrompPinError as exc:
            r.reason = f"prediction failed: {exc}"
            return r
        t1 = time.perf_counter()
        ms["condition"] = (t1 - t0) * 1e3
        r.task = pred.task
        r.posterior = {k: float(v) for k, v in zip(pred.tasks, pred.posterior, strict=True)}
        r.predicted_handover_s = float(pred.duration_s)
        context = replace(self.context, task=pred.task, handover_s=float(pred.duration_s))
        plan = self._plan_checked(state, reference, r, ms, context)
        r.stage_ms = ms
        if plan is not None and not r.reason:
            r.committed = True
            self._plans.append((tick, plan))
        return r

    def _plan_checked(
        self,
        state: MotionState,
        reference: ReferenceMotion,
        r: Replan,
        ms: dict[str, float],
        context: CheckContext,
    ) -> MotionPlan | None:
        """Re-target, check, and re-target slower while a failing check asks for it -> the last plan
        (``r.reason`` empty if it passed) or None when re-targeting failed."""
        plan: MotionPlan | None = None
        scale, first_arrival, k0 = 1.0, None, 1.0
        t_start = time.perf_counter()
        t_checks = 0.0
        if context.human is not None:  # the human as observed up to this re-plan, for every round
            context = replace(context, human=context.human.until(r.observed_until_s))
        for _ in range(MAX_SLOWDOWN_ROUNDS + 1):
            try:
                plan = self.retargeter.plan(state, reference, min_scale=scale)
            except IPrompPinError as exc:
                r.reason = f"re-target failed: {exc}"
                break
            t0 = time.perf_counter()
            if first_arrival is None:
                first_arrival, k0 = plan.arrival_s, plan.time_scale
            r.planned_arrival_s = plan.arrival_s
            r.lateness_s = plan.lateness_s
            r.time_scale = plan.time_scale
            r.slowdown_delay_s = float(plan.arrival_s - first_arrival)
            r.reason, k = self._check(plan, r, context)
            t_checks += time.perf_counter() - t0
            if not r.reason or k is None or k <= 1.0 or plan.time_scale >= k0 * MAX_SLOWDOWN:
                break
            scale = min(plan.time_scale * k * SLOWDOWN_STEP, k0 * MAX_SLOWDOWN)
            r.slowdown = scale / k0
        ms["checks"] = t_checks * 1e3
        ms["retarget"] = (time.perf_counter() - t_start - t_checks) * 1e3
        return plan if r.planned_arrival_s is not None else None

    def _handover_pose(self, q_end: np.ndarray) -> tuple[np.ndarray, CheckResult]:
        """The gripper position (3,) [m] at a plan's end configuration (n_joints,) [rad] and its
        workspace check; kept for the next call with the same configuration (the slower re-targets
        of a re-plan end where it does)."""
        key = np.asarray(q_end, dtype=float).tobytes()
        if self._pose_cache is None or self._pose_cache[0] != key:
            end = ee_positions(self.robot, q_end)[0]
            self._pose_cache = (key, end, check_workspace(self.robot, end))
        return self._pose_cache[1], self._pose_cache[2]

    def _check(self, plan: MotionPlan, r: Replan, context: CheckContext) -> tuple[str, float | None]:
        """Check a plan's remaining motion against ``context`` (its human as observed up to the
        re-plan) -> the reason to refuse it ("" if it passes) and the slow-down the failing
        timed-motion checks ask for (None: slowing would not help)."""
        ratios = limit_ratios(plan.qd, plan.qdd, self.dt_s, self.profile.limits)
        r.limit_ratios = [float(x) for x in ratios]
        if np.any(ratios > 1.0 + LIMIT_TOLERANCE):
            names = ("velocity", "acceleration", "jerk")
            i = int(np.argmax(ratios))
            return f"{names[i]} limit exceeded ({ratios[i]:.3f} of the limit)", None
        end, ws = self._handover_pose(plan.q[-1])
        r.predicted_handover_position_m = [float(x) for x in end]
        lim = check_joint_limits(self.robot, plan.q, t_s=plan.t_s)
        if not lim.passed:
            return f"joint_limits: {lim.reason}", None
        if not ws.passed:
            return f"workspace: {ws.reason}", None
        clearance = self.certifier.certify(plan.q)
        r.min_distance_m = clearance.min_distance_m
        if not clearance.certified:
            return f"self_collision: {clearance.to_check().reason}", None
        if not self.checks:
            return "", None
        results = run_checks(self.checks, TimedMotion.from_plan(plan), context)
        r.checks = {c.name: {"status": c.status, "reason": c.reason, **c.values} for c in results}
        failed = [c for c in results if c.required and not c.passed]
        if not failed:
            return "", None
        return "; ".join(f"{c.name}: {c.reason}" for c in failed), needed_slowdown(results)

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
            traj, self.replans, self.profile, self.settings, self.start_s, self._stopped, plans
        )


def demo_samples(demo: Demo, groups: list[str]) -> list[dict[str, np.ndarray | None]]:
    """The demo's human samples as the planner receives them: group -> values, None where missing."""
    out = []
    for i in range(demo.n_samples):
        out.append(
            {g: None if (g in demo.missing and demo.missing[g][i]) else demo.groups[g][i] for g in groups}
        )
    return out


def start_time(demo: Demo, start_ratio: float) -> float:
    """Time in [s] of the last sample of the first ``start_ratio`` of ``demo`` (when the robot starts).

    Raises:
        ObservationError: the start window holds fewer than 2 samples.
    """
    try:
        return float(demo.head(start_ratio).t[-1])
    except ObservationError:
        raise ObservationError(
            demo.source,
            "start_ratio",
            f"the start window ({start_ratio:.0%} of a {demo.t[-1] - demo.t[0]:.2f} s demo of "
            f"{demo.n_samples} samples) holds fewer than 2 samples",
        ) from None


def replay_demo(
    model: IProMP,
    robot: Robot,
    demo: Demo,
    profile: LimitProfile,
    settings: ClosedLoopSettings | None = None,
    certifier: ClearanceCertifier | None = None,
    conditioner: Predictor | None = None,
    checks: Sequence[MotionCheck] = (),
    context: CheckContext | None = None,
) -> ClosedLoopResult:
    """Run the closed loop on a recorded demo at its recorded timing (simulated clock, no waiting).

    The robot starts at rest at the demo's first recorded configuration; the human's observed groups
    (``model.observe_``) arrive sample by sample. ``checks`` and ``context``: the timed-motion checks
    of every re-plan (:class:`ClosedLoopPlanner`).

    Raises:
        DataError: the demo lacks an observed group or the robot group.
        ObservationError: the start window holds fewer than 2 samples.
    """
    settings = (settings or ClosedLoopSettings()).validate()
    groups = list(model.observe_)
    demo.require(groups + [model.robot_group])
    start = start_time(demo, settings.start_ratio)
    q_start = demo.groups[model.robot_group][0]
    with ClosedLoopPlanner(
        model, robot, profile, q_start, start, settings, certifier, conditioner, checks, context
    ) as planner:
        for t, sample in zip(demo.t - demo.t[0], demo_samples(demo, groups), strict=True):
            planner.step(float(t), sample)
    return planner.finish()
