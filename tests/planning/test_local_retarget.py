"""The closed loop's re-target slowed only where the checks ask: a warped timeline of the reference."""

from __future__ import annotations

import numpy as np
import pytest
from helpers_checks import RegionSpeedBound

from ipromp_pin.data import ROBOT
from ipromp_pin.motion.limits import conservative_profile, demonstrated_profile
from ipromp_pin.motion.retarget import ReferenceMotion, Retargeter
from ipromp_pin.motion.time_warp import SMOOTH_S, SPREAD_S, TimeWarp
from ipromp_pin.motion.trajectory import MotionState, Trajectory
from ipromp_pin.outputs.replay_report import slowed_text
from ipromp_pin.planning.closed_loop import ClosedLoopSettings, replay_demo
from ipromp_pin.planning.timers import retarget_timer
from ipromp_pin.safety import CheckContext, CheckSuite, next_guess
from ipromp_pin.safety.retime import retime_until_safe
from ipromp_pin.safety.speed_limits import limit_ratios

OBSERVE = ["orientation", "emg"]
DT = 0.01


def test_a_time_warp_slows_where_asked_and_nowhere_else():
    plain = TimeWarp(4.0)
    assert not plain.active and np.all(plain.factor(np.linspace(0, 4, 9)) == 1.0)
    assert plain.span_s(0.5, 2.5, 1.5) == pytest.approx(3.0)
    np.testing.assert_allclose(plain.reference_times(np.array([0.0, 1.5]), 0.5, 1.5), [0.5, 1.5])
    warp = plain.asking(np.array([2.0]), np.array([3.0]))
    assert warp.active
    assert warp.factor(2.0) >= 0.97 * 3.0  # kept where asked, through the smoothing
    far = SPREAD_S + 5 * SMOOTH_S
    assert warp.factor(2.0 - far) < 1.001 and warp.factor(2.0 + far) < 1.001
    # smooth: no step in g, so no step in the follower's acceleration
    assert np.max(np.abs(np.diff(warp.g))) < 0.1
    # the times it maps are the inverse of the spans it takes
    span = warp.span_s(0.5, 3.0, 1.2)
    assert span > 1.2 * 2.5 + 2 * SPREAD_S  # the stretch around 2 s takes longer
    assert warp.reference_times(np.array([span]), 0.5, 1.2)[0] == pytest.approx(3.0, abs=1e-9)
    # asked factors only grow, and a second ask at the same place multiplies the slow-down there
    again = warp.asking(np.array([2.0]), np.array([0.5]))
    np.testing.assert_array_equal(again.g, warp.g)
    more = warp.asking(np.array([2.0]), np.array([1.5]))
    assert more.factor(2.0) >= 0.97 * 4.5
    assert plain.asking(np.array([1.0]), np.array([1.0]), catch_up=2.0).catch_up == 2.0


@pytest.fixture(scope="module")
def follow(synthetic_closed_loop):
    """A reference, loose limits, and a state at rest at its start 0.5 s in."""
    model, robot, _, test = synthetic_closed_loop
    pred = model.predict(test[1].head(0.5, groups=OBSERVE))
    ref = ReferenceMotion.from_prediction(pred, model.basis_.centres, model.basis_.width)
    limits = conservative_profile(robot).limits.scaled(4.0, 20.0, 200.0)
    state = MotionState.at_rest(0.5, test[1].groups[ROBOT][0])
    return ref, limits, state


def test_an_inactive_warp_follows_the_reference_as_without_one(follow):
    ref, limits, state = follow
    retargeter = Retargeter(limits, DT, 0.2)
    plain = retargeter.planned(state, ref).sample()
    warped = retargeter.planned(state, ref, warp=TimeWarp(ref.duration_s)).sample()
    np.testing.assert_allclose(warped.q, plain.q, atol=1e-9)
    np.testing.assert_allclose(warped.qd, plain.qd, atol=1e-9)
    np.testing.assert_allclose(warped.qdd, plain.qdd, atol=1e-7)


def test_the_re_target_is_slowed_only_where_asked_within_its_limits(follow):
    ref, limits, state = follow
    timer = retarget_timer(Retargeter(limits, DT, 0.2), state, ref)
    first = timer(1.0)
    motion = first.motion
    planned = timer._made[id(first.report)][0]
    which, tau = planned.followed(motion.t_s)
    assert set(np.unique(which)) == {0, 1, 2}
    lo, hi = np.nanquantile(tau, [0.45, 0.55])
    asked = (which == 1) & (tau >= lo) & (tau <= hi)
    slowed = timer.locally(first, np.where(asked, 3.0, 1.0))
    out = slowed.motion
    # within the limits, continuous, from the same state to the same hand-over
    assert np.all(limit_ratios(out, limits)[0] <= 1.0 + 1e-6)
    np.testing.assert_allclose(out.q[0], state.q)
    np.testing.assert_allclose(out.q[-1], motion.q[-1], atol=1e-12)
    # the same motion until the slow-down starts
    before = motion.t_s < motion.t_s[asked][0] - (SPREAD_S + 4 * SMOOTH_S) * slowed.scale
    np.testing.assert_allclose(out.q[: before.sum()], motion.q[before], atol=1e-9)
    # where asked, three times slower along the same reference; later, but less than slowed uniformly
    w_which, w_tau = timer._made[id(slowed.report)][0].followed(out.t_s)
    there = (w_which == 1) & (w_tau >= lo) & (w_tau <= hi)
    for t_ref in np.linspace(lo, hi, 5):
        i, j = (
            np.argmin(np.abs(np.where(asked, tau, np.inf) - t_ref)),
            np.argmin(np.abs(np.where(there, w_tau, np.inf) - t_ref)),
        )
        assert np.abs(out.qd[j]).max() <= np.abs(motion.qd[i]).max() / 2.9 + 1e-9
    added = out.duration_s - motion.duration_s
    assert added >= 2.0 * (hi - lo) * first.scale - 0.05
    assert out.duration_s < timer(3.0).motion.duration_s - 0.5


def _replay(model, robot, train, demo, suite):
    profile = demonstrated_profile(robot, train)
    return replay_demo(model, robot, demo, profile, ClosedLoopSettings(start_ratio=0.2), suite)


def test_the_closed_loop_slows_locally_where_a_check_asks(synthetic_closed_loop):
    model, robot, train, test = synthetic_closed_loop
    demo = test[1]
    base = CheckSuite.build(robot, ["speed_limits", "joint_limits", "workspace", "self_collision"])
    free = _replay(model, robot, train, demo, base)
    q0, q1 = free.trajectory.q[0], free.trajectory.q[-1]
    probe = RegionSpeedBound(robot, np.inf, q0, q1)
    bound = 0.5 * float(np.abs(free.trajectory.qd[probe.region(free.trajectory)]).max())
    local = _replay(
        model, robot, train, demo, CheckSuite([*base.checks, RegionSpeedBound(robot, bound, q0, q1)])
    )
    only_uniform = RegionSpeedBound(robot, bound, q0, q1, local=False)
    uniform = _replay(model, robot, train, demo, CheckSuite([*base.checks, only_uniform]))
    for out in (local, uniform):
        committed = [r for r in out.replans if r.committed]
        assert committed and all(r.checks["region_speed"]["status"] == "pass" for r in committed)
        assert any(r.slowdown > 1.0 for r in committed)
        assert np.abs(out.trajectory.qd[probe.region(out.trajectory)]).max() <= bound * (1 + 1e-6)
    assert any(r.slowdown_local for r in local.replans) and not any(r.slowdown_local for r in uniform.replans)
    slowed = [r for r in local.replans if r.committed and r.slowdown != 1.0]
    n_local = sum(r.slowdown_local for r in slowed)
    assert 0 < n_local < len(slowed)  # report.txt counts both
    assert (
        slowed_text(local) == f"{len(slowed)} slowed for the checks, {n_local} of them only where they asked"
    )
    # slowed only where it is too fast, the first plan arrives sooner than slowed as a whole
    first_local = next(r for r in local.replans if r.committed)
    first_uniform = next(r for r in uniform.replans if r.committed)
    assert first_local.slowdown_local and first_local.slowdown < first_uniform.slowdown
    assert first_local.planned_arrival_s < first_uniform.planned_arrival_s - 1.0
    assert local.arrival_s > free.arrival_s


def test_a_locally_slowed_re_plan_gives_the_next_no_guess(synthetic_closed_loop, follow):
    ref, limits, state = follow
    _, robot, _, _ = synthetic_closed_loop
    timer = retarget_timer(Retargeter(limits, DT, 0.2), state, ref)
    motion: Trajectory = timer(1.0).motion
    check = RegionSpeedBound(robot, 0.0, motion.q[0], motion.q[-1])
    check.bound = 0.5 * float(np.abs(motion.qd[check.region(motion)]).max())
    out = retime_until_safe(CheckSuite([check]), timer, CheckContext())
    assert out.passed and out.local and out.slowdown > 1.0
    assert next_guess(out) is None  # the next re-plan is slowed locally again, from unslowed


def test_the_next_re_plan_checks_first_where_the_last_was_slowed_locally(synthetic_closed_loop, follow):
    ref, limits, state = follow
    _, robot, _, _ = synthetic_closed_loop
    retargeter = Retargeter(limits, DT, 0.2)
    motion = retarget_timer(retargeter, state, ref)(1.0).motion
    check = RegionSpeedBound(robot, 0.0, motion.q[0], motion.q[-1])
    check.bound = 0.5 * float(np.abs(motion.qd[check.region(motion)]).max())
    timer = retarget_timer(retargeter, state, ref)
    fresh = retime_until_safe(CheckSuite([check]), timer, CheckContext())
    assert fresh.local and not fresh.guessed and fresh.rounds > 1 and timer.warp is not None
    # the next re-plan (here: the same motion) guesses that warp: checked first, and it passes at once
    check.seen.clear()
    again = retime_until_safe(
        CheckSuite([check]), retarget_timer(retargeter, state, ref, timer.warp), CheckContext()
    )
    assert again.passed and again.guessed and again.local and again.rounds == 1 and len(check.seen) == 1
    np.testing.assert_allclose(again.motion.q, fresh.motion.q, atol=1e-9)
    assert again.slowdown == pytest.approx(fresh.slowdown)
    # a guess that is not needed (the check gone) is still what is checked first: the plan after a
    # guessed one checks its unslowed motion again (the closed loop keeps no warp from a guessed plan)
    free = retime_until_safe(
        CheckSuite([]), retarget_timer(retargeter, state, ref, timer.warp), CheckContext()
    )
    assert free.guessed and free.passed


def test_a_guess_too_weak_is_slowed_further_where_the_checks_ask(synthetic_closed_loop, follow):
    ref, limits, state = follow
    _, robot, _, _ = synthetic_closed_loop
    retargeter = Retargeter(limits, DT, 0.2)
    timer = retarget_timer(retargeter, state, ref)
    first = timer(1.0)
    motion = first.motion
    check = RegionSpeedBound(robot, 0.0, motion.q[0], motion.q[-1])
    check.bound = 0.4 * float(np.abs(motion.qd[check.region(motion)]).max())
    which, tau = timer._made[id(first.report)][0].followed(motion.t_s)
    inside = check.region(motion) & (which == 1)
    weak = TimeWarp(ref.duration_s).asking(tau[inside], np.full(inside.sum(), 1.2))
    out = retime_until_safe(CheckSuite([check]), retarget_timer(retargeter, state, ref, weak), CheckContext())
    assert out.passed and out.guessed and out.local and out.rounds > 1
    assert np.abs(out.motion.qd[check.region(out.motion)]).max() <= check.bound * (1 + 1e-6)


def test_a_factor_is_asked_at_its_own_time_on_any_grid():
    for duration in (4.0, 4.125, 30.005):  # grids of 0.01 s and slightly finer
        warp = TimeWarp(duration).asking(np.array([0.9 * duration]), np.array([2.0]))
        peak = warp.tau[np.argmax(warp.g)]
        assert abs(peak - 0.9 * duration) < 0.006
