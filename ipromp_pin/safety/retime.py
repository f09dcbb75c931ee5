"""The one re-time-until-safe loop of every planner (the one-shot plan, the retreat, every re-plan).

A planner gives a :data:`Timer`: a function from a requested slow-down to the motion timed that much
slower (the one-shot plan and the retreat re-time their path with toppra under limits scaled by
``k``, ``k^2``, ``k^3``; the closed loop re-targets its prediction followed ``k`` times slower). The
loop times the motion, runs the checks, and while the failing required checks all ask for a slower
motion, times it again ``k`` times slower than the last (times :data:`SLOWDOWN_STEP`, a margin over
the checks' first-order estimates), at most :data:`MAX_SLOWDOWN_ROUNDS` times and
:data:`MAX_SLOWDOWN` in all. The first motion that passes is committed; when none does, the last
(slowest) motion tried is returned with its verdicts, refused: it says how far slowing went and what
still fails.

A :class:`LocalTimer` (every planner's: the one-shot plan's and the retreat's cap their path
velocity, the closed loop warps its reference's timeline) is first slowed only where the checks ask:
when every failing required check says which samples need how much slow-down
(:attr:`~.verdict.Verdict.local_slowdown`, e.g. ``contact_speed`` where the arm approaches a body part
too fast), the motion is slowed there and nowhere else, at most :data:`MAX_LOCAL_SLOWDOWN` times at
any sample and :data:`MAX_SLOWDOWN` times longer in all, again at most :data:`MAX_SLOWDOWN_ROUNDS`
times (each adding its slow-downs to the last); the first motion that passes is committed, its
slow-down the ratio of the durations. When none does, the uniform slow-downs
above start again from the unslowed motion, so that slowing locally never refuses a motion the
uniform slow-down would pass.

A planner that plans the same motion again and again (the closed loop, every 50 ms) may pass a
``guess``: the slow-down its last committed motion turned out to need (:func:`next_guess`). The first
(unslowed) motion is still timed, as the base the slow-downs are counted from (its samples are not
made: :class:`Timed`), but the first motion checked is the one timed ``guess`` times slower; the loop
goes on from there as from any other timing. A guess below what the motion needs costs the rounds
the loop would take anyway; one above it commits a motion slower than needed. A guessed plan gives
no guess for the next one (:func:`next_guess`): that one checks its unslowed motion first, so that a
motion slowed for the human is sped up again at most one plan later when it no longer needs to be
slowed (the checks' first-order estimates of how much faster would still pass,
:attr:`~.verdict.Verdict.fits_at`, do not see it: a re-target slowed down takes another path than the
unslowed one), and guesses do not build on guesses.

A timing of the same path (the timer says so, :attr:`Timed.path`) keeps the verdicts of the checks
that depend on the path only (:attr:`~.base.Check.depends_on`) for the decision; the committed motion
is then checked by them once more, so that every verdict's numbers and times are those of the motion
that is committed.

A :class:`GuessingTimer` (the closed loop's) may instead guess where its motion needs slowing (where
the last re-plan was slowed locally): that motion is checked first and slowed further locally from
there; a guessed plan again gives no guess for the next.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from ..exceptions import InfeasibleError
from ..motion.trajectory import Trajectory
from .context import CheckContext
from .verdict import CheckReport, Verdict, needed_local_slowdown, needed_slowdown

MAX_SLOWDOWN = 4.0
"""The largest slow-down a motion is given before it is refused (4x the duration)."""

MAX_LOCAL_SLOWDOWN = 2.0 * MAX_SLOWDOWN
"""The largest slow-down a motion slowed only where the checks ask is given at any one sample (the
whole motion still takes at most :data:`MAX_SLOWDOWN` times as long)."""

MAX_SLOWDOWN_ROUNDS = 3
"""How many times a motion is slowed again while its slower version still fails a check that asks
for a slower motion (a check's factor is a first-order estimate: a slower motion meets the moving
human at other times and places)."""

SLOWDOWN_STEP = 1.05
"""Each slower timing asks for 5 % more slow-down than the failing checks estimated."""


class Timed:
    """A motion as a timer made it.

    Args:
        motion: The motion (times on the human's clock), or a function that makes it: a timer whose
            samples cost time gives one, and the loop samples only the motions it checks (the
            unslowed motion of a plan that starts from a guess is only the base of the slow-downs).
        report: The timing's own report (e.g. a toppra timing's verification, a re-target's arrival).
        scale: The slow-down the motion has in the timer's own units (its first motion's scale is the
            base the slow-downs are counted from).
        path: The geometric path the motion follows, the same object for every timing of it (None: the
            timer does not promise one).
    """

    __slots__ = ("_make", "_motion", "path", "report", "scale")

    def __init__(
        self,
        motion: Trajectory | Callable[[], Trajectory],
        report: object,
        scale: float = 1.0,
        path: object | None = None,
    ) -> None:
        self._motion: Trajectory | None = motion if isinstance(motion, Trajectory) else None
        self._make: Callable[[], Trajectory] | None = None if isinstance(motion, Trajectory) else motion
        self.report = report
        self.scale = scale
        self.path = path

    @property
    def motion(self) -> Trajectory:
        """The motion (made on first use when the timer gave a function)."""
        if self._motion is None:
            assert self._make is not None
            self._motion, self._make = self._make(), None
        return self._motion


Timer = Callable[[float], Timed]
"""A requested slow-down scale (1.0 first, then larger) -> the motion timed so.

Raises :class:`~ipromp_pin.exceptions.InfeasibleError` when it cannot time the motion."""


@runtime_checkable
class LocalTimer(Protocol):
    """A timer that can also slow its motion only where the checks ask for it."""

    def __call__(self, k: float) -> Timed: ...

    def locally(self, timed: Timed, need: np.ndarray) -> Timed:
        """The motion of ``timed`` (one this timer made) slowed by ``need`` (N,) >= 1 at each of
        its samples (1: as fast as before), and where every earlier call asked; raises
        :class:`~ipromp_pin.exceptions.InfeasibleError` when it cannot."""
        ...


@runtime_checkable
class GuessingTimer(Protocol):
    """A :class:`LocalTimer` that may know where its motion will need slowing (e.g. where the last
    similar motion was slowed locally)."""

    def __call__(self, k: float) -> Timed: ...

    def locally(self, timed: Timed, need: np.ndarray) -> Timed: ...

    def guessed(self) -> Timed | None:
        """The motion slowed where the timer expects it (None: no such guess); further
        :meth:`locally` calls add to that slow-down."""
        ...


class Runs(Protocol):
    """What the loop needs of a suite: its checks' names by dependency, and running them."""

    def run(
        self,
        motion: Trajectory,
        context: CheckContext,
        *,
        reuse: Sequence[Verdict] = (),
        stop_early: bool = False,
    ) -> list[Verdict]: ...

    def path_checks(self) -> set[str]: ...


@dataclass(frozen=True)
class Retimed:
    """The outcome of :func:`retime_until_safe`.

    Attributes:
        timed: The committed motion (the last one tried when none passed).
        verdicts: Its verdicts.
        first: The first (unslowed) motion.
        slowdown: Its slow-down over the first (1: none).
        rounds: Motions checked.
        guessed: Whether the first motion checked was a guess (not the unslowed one).
        local: Whether the motion was slowed only where the checks asked for it (``slowdown`` is
            then its duration over the first's).
    """

    timed: Timed
    verdicts: list[Verdict]
    first: Timed
    slowdown: float = 1.0
    rounds: int = 1
    guessed: bool = False
    local: bool = False

    @property
    def motion(self) -> Trajectory:
        """The committed motion."""
        return self.timed.motion

    @property
    def report(self) -> CheckReport:
        """The verdicts as a report."""
        return CheckReport(list(self.verdicts))

    @property
    def passed(self) -> bool:
        """Whether every required check passed."""
        return not any(v.blocks for v in self.verdicts)

    @property
    def delay_s(self) -> float:
        """How much later the committed motion ends than the first, in [s]."""
        return self.timed.motion.end_s - self.first.motion.end_s


def next_guess(retimed: Retimed) -> float | None:
    """The slow-down to start the next timing of a similar motion from (``guess`` of
    :func:`retime_until_safe`): the committed slow-down times the largest slow-down at which the
    checks estimate the committed motion would just pass (:attr:`~.verdict.Verdict.fits_at`, below 1
    when it passed with room), times :data:`SLOWDOWN_STEP` as for a requested slow-down. None (start
    unslowed) when the motion was not slowed, was slowed only locally (the next is slowed locally
    again), was refused, started from a guess itself (see the module docstring), or no check
    estimates it."""
    if retimed.guessed or retimed.local or not retimed.passed or retimed.slowdown <= 1.0:
        return None
    fits = [float(v.fits_at) for v in retimed.verdicts if v.fits_at is not None and v.required]
    if not fits or not all(math.isfinite(f) for f in fits):
        return None
    return retimed.slowdown * max(fits) * SLOWDOWN_STEP


def retime_until_safe(
    suite: Runs,
    timer: Timer,
    context: CheckContext,
    *,
    stop_early: bool = False,
    guess: float | None = None,
) -> Retimed:
    """Time, check, and time slower while the failing checks ask for it (see the module docstring).

    Args:
        suite: The checks.
        timer: The planner's timer (a :class:`LocalTimer` is slowed only where the checks ask first).
        context: What the checks know.
        stop_early: Stop checking a motion at its first failure that no slow-down fixes (the closed
            loop: a refused re-plan needs no further verdicts).
        guess: Check first the motion timed this much slower than the first (when above 1; at most
            :data:`MAX_SLOWDOWN`), e.g. :func:`next_guess` of the previous plan.

    Raises:
        InfeasibleError: the timer cannot time the first motion.
    """
    first = timer(1.0)
    base = first.scale
    cur, requested, guessed, local_guess = first, 1.0, False, None
    if guess is not None and math.isfinite(guess) and guess > 1.0:
        try:
            requested = base * min(float(guess), MAX_SLOWDOWN)
            cur, guessed = timer(requested), True
        except InfeasibleError:
            cur, requested = first, 1.0
    elif isinstance(timer, GuessingTimer):
        local_guess = timer.guessed()
        cur, guessed = (first, False) if local_guess is None else (local_guess, True)
    verdicts = suite.run(cur.motion, context, stop_early=stop_early)
    if isinstance(timer, LocalTimer) and (not guessed or local_guess is not None):
        local = _slow_locally(suite, timer, context, first, (cur, verdicts), stop_early)
        if local is not None:
            return local
    if local_guess is not None:  # the uniform slow-downs count from the unslowed motion, checked now
        cur, guessed = first, False
        verdicts = suite.run(first.motion, context, stop_early=stop_early)
    return _slow_uniformly(suite, timer, context, first, (cur, requested), verdicts, guessed, stop_early)


def _slow_uniformly(
    suite: Runs,
    timer: Timer,
    context: CheckContext,
    first: Timed,
    start: tuple[Timed, float],
    verdicts: list[Verdict],
    guessed: bool,
    stop_early: bool,
) -> Retimed:
    """The uniform slow-downs of :func:`retime_until_safe` from ``start`` (the motion checked first,
    its verdicts ``verdicts``, and the scale it was asked for)."""
    base = first.scale
    cur, requested = start
    path_names = suite.path_checks()
    cur_v, rounds, reused = verdicts, 1, False
    while rounds <= MAX_SLOWDOWN_ROUNDS:
        k = needed_slowdown(cur_v, MAX_SLOWDOWN)
        if k is None or k <= 1.0 or cur.scale >= base * MAX_SLOWDOWN:
            break
        requested = min(cur.scale * k * SLOWDOWN_STEP, base * MAX_SLOWDOWN)
        try:
            nxt = timer(requested)
        except InfeasibleError:
            break
        rounds += 1
        cur_v, reused = _check_next(suite, context, (cur, cur_v), nxt, path_names, stop_early)
        cur = nxt
    if reused:
        cur_v = _recheck_path(suite, context, cur, cur_v, path_names, stop_early)
    return Retimed(cur, cur_v, first, 1.0 if cur is first else requested / base, rounds, guessed)


def _slow_locally(
    suite: Runs,
    timer: LocalTimer,
    context: CheckContext,
    first: Timed,
    start: tuple[Timed, list[Verdict]],
    stop_early: bool,
) -> Retimed | None:
    """Slow ``start`` (``first`` or the timer's own guess, with its verdicts) only where its failing
    checks ask for it, at most :data:`MAX_SLOWDOWN_ROUNDS` times; the first motion that passes, or
    None when none does (or a failing check asks for no local slow-down: the uniform slow-down
    decides then)."""
    (cur, cur_v), reused = start, False
    guessed = cur is not first
    path_names = suite.path_checks()
    for rounds in range(1, MAX_SLOWDOWN_ROUNDS + 2):
        if not any(v.blocks for v in cur_v):
            if reused:
                cur_v = _recheck_path(suite, context, cur, cur_v, path_names, stop_early)
            slowdown = cur.motion.duration_s / first.motion.duration_s
            return Retimed(cur, cur_v, first, slowdown, rounds, guessed, local=cur is not first)
        if rounds > MAX_SLOWDOWN_ROUNDS:
            return None
        need = needed_local_slowdown(cur_v, cur.motion.n_samples)
        if need is None or float(need.max()) > MAX_LOCAL_SLOWDOWN:
            return None
        try:
            nxt = timer.locally(cur, np.where(need > 1.0, need * SLOWDOWN_STEP, 1.0))
        except InfeasibleError:
            return None
        if nxt.motion.duration_s > first.motion.duration_s * MAX_SLOWDOWN:
            return None
        cur_v, reused = _check_next(suite, context, (cur, cur_v), nxt, path_names, stop_early)
        cur = nxt
    return None


def _check_next(
    suite: Runs,
    context: CheckContext,
    last: tuple[Timed, list[Verdict]],
    nxt: Timed,
    path_names: set[str],
    stop_early: bool,
) -> tuple[list[Verdict], bool]:
    """The verdicts on ``nxt``, keeping those of the path-only checks of ``last`` (a motion and its
    verdicts) for the decision when ``nxt`` follows the same path; and whether any were kept."""
    cur, cur_v = last
    same = nxt.path is not None and nxt.path is cur.path
    keep = [v for v in cur_v if v.name in path_names] if same else []
    return suite.run(nxt.motion, context, reuse=keep, stop_early=stop_early), bool(keep)


def _recheck_path(
    suite: Runs,
    context: CheckContext,
    timed: Timed,
    verdicts: list[Verdict],
    path_names: set[str],
    stop_early: bool,
) -> list[Verdict]:
    """The path checks run once more on the returned motion (their numbers and times its own), its
    timing checks' ``verdicts`` kept."""
    timing = [v for v in verdicts if v.name not in path_names]
    return suite.run(timed.motion, context, reuse=timing, stop_early=stop_early)
