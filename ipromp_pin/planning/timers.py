"""The planners' timers (:data:`~ipromp_pin.safety.retime.Timer`): a requested slow-down -> the
motion timed that much slower, for the one re-time-until-safe loop of :mod:`ipromp_pin.safety`.

- :class:`PathTimer`: a joint path timed with toppra and ruckig (:func:`~ipromp_pin.motion.timing.time_path`)
  under the joint limits scaled by ``1/k``, ``1/k^2``, ``1/k^3`` and the checks' torque limits (the
  one-shot plan, the retreat), or slowed only where the checks ask (its path velocity capped there);
  every timing follows the same geometric path;
- :func:`retarget_timer`: the closed loop's re-target from the commanded state onto the predicted
  motion followed at least ``k`` times slower (:meth:`~ipromp_pin.motion.retarget.Retargeter.plan`),
  or slowed only where the checks ask (its timeline warped there, :mod:`~ipromp_pin.motion.time_warp`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import numpy as np
from scipy.ndimage import maximum_filter1d

from ..exceptions import InfeasibleError
from ..motion.retarget import Planned, ReferenceMotion, Retargeter
from ..motion.time_warp import TimeWarp
from ..motion.timing import TorqueLimit, time_path
from ..motion.trajectory import JointLimits, MotionState, Trajectory
from ..safety import Timed, Timer, TimingConstraints

LogFn = Callable[[str], None]
"""Where progress messages go (one line each)."""


LOCAL_SPREAD_SAMPLES = 3
"""A local slow-down asked for at a sample is applied this many samples either side too (the
jerk-limited tracking lags the timed profile where it slows down)."""


class PathTimer:
    """A timer of the joint path ``path`` (M, n_joints) [rad] from rest to rest, its first sample at
    ``start_s`` [s] on the human's clock, at ``rate_hz`` [Hz]; a
    :class:`~ipromp_pin.safety.retime.LocalTimer`: :meth:`locally` slows it only where asked.

    When toppra finds no profile under the torque limits (gravity alone exceeds them somewhere on the
    path: slowing down cannot help), the first timing is made without them and says so (``what``:
    the log line's tag); the joint-torque check then fails the motion.
    """

    def __init__(
        self,
        path: np.ndarray,
        limits: JointLimits,
        constraints: TimingConstraints,
        rate_hz: float,
        start_s: float,
        say: LogFn,
        what: str = "timing",
    ) -> None:
        self.path, self.limits, self.rate_hz, self.start_s = path, limits, rate_hz, start_s
        self.say, self.what = say, what
        self._torque = constraints.torque
        self._caps: list[tuple[np.ndarray, np.ndarray]] = []  # (path coordinates [rad], sdot caps [rad/s])

    def __call__(self, k: float) -> Timed:
        """The path timed under the joint limits scaled by ``1/k``, ``1/k^2``, ``1/k^3``."""
        scaled = self.limits if k == 1.0 else self.limits.scaled(1.0 / k, 1.0 / k**2, 1.0 / k**3)
        if self._torque is not None:
            try:
                return self._timed(scaled, k, None, self._torque)
            except InfeasibleError as exc:
                if k != 1.0:
                    raise
                self.say(f"[{self.what}] not timeable under the torque limits ({exc}): timed without them")
                self._torque = None
        return self._timed(scaled, k, None, None)

    def locally(self, timed: Timed, need: np.ndarray) -> Timed:
        """The path timed under the joint limits with its path velocity capped where ``timed`` (a
        timing of this timer) needs slowing: ``need`` (N,) per sample of it, at most its path velocity
        there (or its timed profile's, the lower) over ``need`` (spread :data:`LOCAL_SPREAD_SAMPLES`
        either side), and every cap an earlier call set."""
        report = timed.report
        s = getattr(report, "path_s", None)
        actual = getattr(report, "path_sd", None)
        profile = getattr(report, "profile_sd", None)
        if s is None or actual is None or profile is None or s.shape != need.shape:
            raise InfeasibleError("the motion has no path coordinates to slow it locally")
        # the profile the tracking follows, lowered: where the tracking catches up after a slow-down
        # it runs faster than the profile, and a cap above the profile would change nothing
        sd = np.fmin(actual, profile)
        spread = maximum_filter1d(np.asarray(need, dtype=float), 2 * LOCAL_SPREAD_SAMPLES + 1)
        where = (spread > 1.0) & np.isfinite(s) & (sd > 0.0)
        if not where.any():
            raise InfeasibleError("no sample asks for a slow-down")
        self._caps.append((s[where], sd[where] / spread[where]))
        return self._timed(self.limits, timed.scale, self._cap_at, self._torque)

    def _cap_at(self, grid: np.ndarray) -> np.ndarray:
        """The path velocity caps at the grid points (G,) [rad]: each cap binds the grid points either
        side of its path coordinate."""
        out = np.full(grid.size, np.inf)
        for s, cap in self._caps:
            i = np.searchsorted(grid, s)
            np.minimum.at(out, np.clip(i - 1, 0, grid.size - 1), cap)
            np.minimum.at(out, np.clip(i, 0, grid.size - 1), cap)
        return out

    def _timed(
        self,
        limits: JointLimits,
        k: float,
        sd_cap: Callable[[np.ndarray], np.ndarray] | None,
        torque: TorqueLimit | None,
    ) -> Timed:
        motion, report = time_path(
            self.path, limits, rate_hz=self.rate_hz, torque=torque, start_s=self.start_s, sd_cap=sd_cap
        )
        return Timed(motion, report, k, self.path)


def fixed_timer(motion: Trajectory, why: str) -> Timer:
    """The timer of a motion that is never slowed: ``motion`` itself; a slower one is refused with
    ``why`` (:class:`~ipromp_pin.exceptions.InfeasibleError`)."""

    def timer(k: float) -> Timed:
        if k != 1.0:
            raise InfeasibleError(why)
        return Timed(motion, None, 1.0, None)

    return timer


class RetargetTimer:
    """The closed loop's timer (:func:`retarget_timer`), a :class:`~ipromp_pin.safety.retime.LocalTimer`:
    :meth:`locally` slows the followed reference only where the checks ask (a
    :class:`~ipromp_pin.motion.time_warp.TimeWarp` of its timeline), the catch-up to it as a whole.
    The asked factors add up over the calls of one re-plan."""

    def __init__(
        self,
        retargeter: Retargeter,
        state: MotionState,
        reference: ReferenceMotion,
        guess: TimeWarp | None = None,
    ) -> None:
        self.retargeter, self.state, self.reference = retargeter, state, reference
        self._made: dict[int, tuple[Planned, float]] = {}  # id(report) -> (planned, the k asked)
        self._guess = guess.over(reference.duration_s) if guess is not None and guess.active else None
        self._warp: TimeWarp | None = None

    @property
    def warp(self) -> TimeWarp | None:
        """The warp of the last locally slowed motion (None: none was)."""
        return self._warp

    def __call__(self, k: float) -> Timed:
        """The remaining motion with the reference followed at least ``k`` times slower."""
        return self._timed(self.retargeter.planned(self.state, self.reference, min_scale=k), k)

    def guessed(self) -> Timed | None:
        """The remaining motion slowed where the last re-plan was slowed locally (``guess``, at the
        same reference times), or None without a guess; :meth:`locally` adds to it."""
        if self._guess is None:
            return None
        self._warp = self._guess
        return self._timed(self.retargeter.planned(self.state, self.reference, 1.0, self._guess), 1.0)

    def locally(self, timed: Timed, need: np.ndarray) -> Timed:
        """``timed`` (one this timer made) slowed by ``need`` (N,) >= 1 per sample where it follows
        the reference, its catch-up by the largest ``need`` there, its settle to rest by the largest
        there (at the reference's end), and where earlier calls asked."""
        made = self._made.get(id(timed.report))
        if made is None:
            raise InfeasibleError("the motion was not re-targeted by this timer")
        planned, k = made
        which, tau = planned.followed(timed.motion.t_s)
        need = np.asarray(need, dtype=float)
        if need.shape != which.shape:
            raise InfeasibleError(f"{need.size} slow-downs for a motion of {which.size} samples")
        slow = need > 1.0
        if not slow.any():
            raise InfeasibleError("no sample asks for a slow-down")
        if not np.any(which == 1):
            raise InfeasibleError("the motion follows no reference to slow locally")
        follow = slow & (which == 1)
        settle = slow & (which == 2)
        taus, factors = tau[follow], need[follow]
        if settle.any():
            d_follow = self.reference.duration_s - self.retargeter.settle_s
            taus, factors = np.append(taus, d_follow), np.append(factors, need[settle].max())
        catch_up = float(need[slow & (which == 0)].max(initial=1.0))
        warp = self._warp if self._warp is not None else TimeWarp(self.reference.duration_s)
        self._warp = warp.asking(taus, factors, catch_up)
        return self._timed(self.retargeter.planned(self.state, self.reference, k, self._warp), k)

    def _timed(self, planned: Planned, k: float) -> Timed:
        self._made[id(planned.report)] = (planned, k)
        return Timed(planned.sample, planned.report, planned.report.time_scale, None)


class CountedTimer:
    """``timer`` (a :class:`~ipromp_pin.safety.retime.LocalTimer` when it has ``locally``), adding
    the time its timings and their samples take to :attr:`spent_s` [s]."""

    def __init__(self, timer: Timer) -> None:
        self.timer = timer
        self.spent_s = 0.0

    def __call__(self, k: float) -> Timed:
        with self._counting():
            got = self.timer(k)
        return self._counted(got)

    def locally(self, timed: Timed, need: np.ndarray) -> Timed:
        local = getattr(self.timer, "locally", None)
        if local is None:
            raise InfeasibleError("the timer slows its motion only as a whole")
        with self._counting():
            got = local(timed, need)
        return self._counted(got)

    def guessed(self) -> Timed | None:
        guess = getattr(self.timer, "guessed", None)
        if guess is None:
            return None
        with self._counting():
            got = guess()
        return None if got is None else self._counted(got)

    @contextmanager
    def _counting(self) -> Iterator[None]:
        """Adds the time the block takes to :attr:`spent_s`, also when it raises."""
        t = time.perf_counter()
        try:
            yield
        finally:
            self.spent_s += time.perf_counter() - t

    def _counted(self, got: Timed) -> Timed:
        """``got`` whose samples, made when first used, count too."""

        def sample() -> Trajectory:
            with self._counting():
                return got.motion

        return Timed(sample, got.report, got.scale, got.path)


def retarget_timer(
    retargeter: Retargeter, state: MotionState, reference: ReferenceMotion, guess: TimeWarp | None = None
) -> RetargetTimer:
    """A timer of the remaining motion from ``state`` (the commanded state at a control tick) onto
    ``reference``'s timeline; its scale is the followed reference's slow-down
    (:attr:`~ipromp_pin.motion.retarget.RetargetReport.time_scale`). The path is not the same for
    every slow-down (the blend to the reference changes with it). A motion is sampled when it is
    first used (:meth:`~ipromp_pin.motion.retarget.Planned.sample`); :meth:`RetargetTimer.locally`
    slows it only where the checks ask, :meth:`RetargetTimer.guessed` where ``guess`` (the last
    re-plan's warp) did."""
    return RetargetTimer(retargeter, state, reference, guess)
