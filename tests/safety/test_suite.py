"""The check interface and the one re-time-until-safe loop (ipromp_pin.safety): a verdict joins the
plan's report, a check that asks for a slower motion gets it (the one-shot re-timing, the closed loop's
slower re-target, by the same loop), one that slowing cannot fix fails the plan, path checks are not
run again on a re-timing of the same path, and a check that does not apply gives no verdict."""

from __future__ import annotations

import numpy as np
import pytest
from helpers_checks import RegionSpeedBound, SpeedBound

from ipromp_pin.exceptions import PipelineError
from ipromp_pin.motion.limits import demonstrated_profile
from ipromp_pin.motion.trajectory import Trajectory
from ipromp_pin.planning.closed_loop import ClosedLoopSettings, replay_demo
from ipromp_pin.planning.one_shot import plan
from ipromp_pin.promp import IProMP
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import load_robot
from ipromp_pin.safety import (
    CHECKS,
    MAX_SLOWDOWN,
    MAX_SLOWDOWN_ROUNDS,
    SLOWDOWN_STEP,
    Check,
    CheckContext,
    CheckSuite,
    Timed,
    Verdict,
    needed_slowdown,
    next_guess,
)
from ipromp_pin.safety.retime import retime_until_safe

OBSERVE = ["orientation", "emg"]


class PathCount(Check):
    """A toy path check that counts its runs and never fails."""

    name = "path_count"
    depends_on = "path"

    def __init__(self, robot) -> None:
        super().__init__(robot)
        self.runs = 0

    def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
        self.runs += 1
        return Verdict(self.name, "pass", f"run {self.runs}")


class NotAfter(PathCount):
    """A toy check that does not apply after the hand-over."""

    name = "not_after"

    def applies(self, context: CheckContext) -> bool:
        return not context.after_handover


@pytest.fixture(scope="module")
def setup():
    ds = make_synthetic_dataset(n_tasks=2, n_demos=6, seed=5)
    train = [d for demos in ds.demos.values() for d in demos[:-1]]
    test = [demos[-1] for demos in ds.demos.values()]
    return IProMP(observe=OBSERVE).fit(train), load_robot("baxter_left"), train, test


def test_needed_slowdown_combines_the_failing_required_checks():
    ok = Verdict("a", "pass", "", slowdown=9.0)
    slow2 = Verdict("b", "fail", "", slowdown=2.0)
    slow3 = Verdict("c", "fail", "", slowdown=3.0)
    advisory = Verdict("d", "fail", "", required=False)
    assert needed_slowdown([ok, advisory], MAX_SLOWDOWN) == 1.0
    assert needed_slowdown([ok, slow2, slow3, advisory], MAX_SLOWDOWN) == 3.0
    assert needed_slowdown([slow2, Verdict("e", "fail", "")], MAX_SLOWDOWN) is None
    assert needed_slowdown([Verdict("f", "fail", "", slowdown=MAX_SLOWDOWN * 1.01)], MAX_SLOWDOWN) is None
    assert needed_slowdown([Verdict("g", "fail", "", slowdown=float("nan"))], MAX_SLOWDOWN) is None


def test_the_suite_builds_the_registered_checks_and_names_an_unknown_one():
    robot = load_robot("baxter_left")
    assert [type(c) for c in CheckSuite.build(robot).checks] == list(CHECKS)
    assert CheckSuite.build(robot, exclude=["uncertainty"]).names == [
        c.name for c in CHECKS if c.name != "uncertainty"
    ]
    with pytest.raises(PipelineError, match="did you mean 'contact_speed'"):
        CheckSuite.build(robot, ["contact_sped"])
    human = CheckSuite.build(robot, ["human_clearance", "contact_speed"])
    assert human.checks[0].summariser is human.checks[1].summariser  # one separation for both


def test_one_shot_plan_runs_the_checks_on_the_timed_motion_from_the_observation_end(setup):
    model, robot, _, test = setup
    obs = test[0].head(0.3, groups=OBSERVE)
    base = plan(model, robot, obs, CheckSuite([]))
    check = SpeedBound(robot)
    result = plan(model, robot, obs, CheckSuite([check]), CheckContext())
    assert result.checks["speed_bound"].status == "pass" and result.passed
    motion = check.seen[0]
    t_end = float(obs.t[-1] - obs.t[0])
    assert motion.t_s[0] == pytest.approx(t_end) and result.start_s == pytest.approx(t_end)
    assert result.trajectory.start_s == pytest.approx(t_end)  # the human's clock
    np.testing.assert_array_equal(motion.q, base.trajectory.q)
    assert check.contexts[0].task == result.prediction.task
    assert check.contexts[0].handover_s == pytest.approx(result.prediction.duration_s)
    assert result.slowdown == 1.0 and result.slowdown_delay_s == 0.0 and not result.slowdown_local


def test_one_shot_plan_is_re_timed_when_a_check_asks_for_a_slower_motion(setup):
    model, robot, _, test = setup
    obs = test[0].head(0.3, groups=OBSERVE)
    base = plan(model, robot, obs, CheckSuite([]))
    peak = float(np.max(np.abs(base.trajectory.qd)))
    result = plan(model, robot, obs, CheckSuite([SpeedBound(robot, 0.6 * peak)]))
    assert result.passed and result.checks["speed_bound"].status == "pass"
    assert np.max(np.abs(result.trajectory.qd)) <= 0.6 * peak
    assert result.slowdown > 1.0 / 0.6
    assert result.slowdown_delay_s == pytest.approx(result.trajectory.end_s - base.trajectory.end_s)
    assert result.slowdown_delay_s > 0.1
    # the same path: only its timing changed
    np.testing.assert_allclose(result.trajectory.q[-1], base.trajectory.q[-1], atol=1e-6)
    # a failure that slowing cannot fix fails the plan, untouched
    stuck = plan(model, robot, obs, CheckSuite([SpeedBound(robot, 0.6 * peak, fixable=False)]))
    assert not stuck.passed and stuck.checks.failures == ["speed_bound"]
    assert stuck.slowdown == 1.0 and stuck.trajectory.end_s == base.trajectory.end_s


def test_a_slowed_plan_that_still_fails_is_slowed_again_until_it_passes(setup):
    model, robot, _, test = setup
    obs = test[0].head(0.3, groups=OBSERVE)
    peak = float(np.max(np.abs(plan(model, robot, obs, CheckSuite([])).trajectory.qd)))
    check = SpeedBound(robot, 0.6 * peak, power=0.5)  # asks for the square root of what it needs
    result = plan(model, robot, obs, CheckSuite([check]))
    assert result.passed and np.max(np.abs(result.trajectory.qd)) <= 0.6 * peak
    assert result.slowdown > 1.0 / 0.6
    assert 3 <= len(check.seen) <= 1 + MAX_SLOWDOWN_ROUNDS  # the plan, then one timing per round
    # rounds are bounded: a check that asks for too little every time leaves the plan failing, and
    # the failing plan reported is the slowest one tried
    stingy = SpeedBound(robot, 0.2 * peak, power=0.05)
    failed = plan(model, robot, obs, CheckSuite([stingy]))
    assert not failed.passed and failed.slowdown > 1.0 and len(stingy.seen) == 1 + MAX_SLOWDOWN_ROUNDS
    assert np.array_equal(failed.trajectory.q, stingy.seen[-1].q)


def test_path_checks_run_once_per_path_and_again_on_the_committed_motion(setup):
    model, robot, _, test = setup
    obs = test[0].head(0.3, groups=OBSERVE)
    peak = float(np.max(np.abs(plan(model, robot, obs, CheckSuite([])).trajectory.qd)))
    counter = PathCount(robot)
    speed = SpeedBound(robot, 0.6 * peak, power=0.5)
    result = plan(model, robot, obs, CheckSuite([counter, speed]))
    assert result.passed and len(speed.seen) >= 3
    # the first timing, then the committed one (not every slower timing of the same path)
    assert counter.runs == 2
    assert result.checks["path_count"].reason == "run 2"


def test_the_loop_refuses_when_the_timer_cannot_slow_down(setup):
    _, robot, _, _ = setup
    q = np.linspace(np.zeros(7), np.full(7, 0.1), 5)
    motion = Trajectory(np.arange(5) * 0.01, q, np.ones((5, 7)), np.zeros((5, 7)), tuple(robot.joint_names))
    calls = []

    def timer(k: float) -> Timed:
        calls.append(k)
        if k > 1.0:
            from ipromp_pin.exceptions import InfeasibleError

            raise InfeasibleError("cannot")
        return Timed(motion, None, 1.0)

    out = retime_until_safe(CheckSuite([SpeedBound(robot, 0.5)]), timer, CheckContext())
    assert not out.passed and out.motion is motion and calls[0] == 1.0 and len(calls) == 2
    assert out.slowdown == 1.0


def _scaled_timer(robot, calls: list[float]):
    """A timer of a fixed joint path whose speeds are divided by the requested slow-down."""
    q = np.linspace(np.zeros(7), np.full(7, 0.1), 5)

    def timer(k: float) -> Timed:
        calls.append(k)
        qd = np.ones((5, 7)) / k
        return Timed(Trajectory(np.arange(5) * 0.01 * k, q, qd, 0 * qd, tuple(robot.joint_names)), None, k)

    return timer


def test_a_guess_checks_the_guessed_timing_first_and_the_slowdown_counts_from_the_unslowed(setup):
    _, robot, _, _ = setup
    calls: list[float] = []
    check = SpeedBound(robot, 0.5)  # needs 2x slower
    out = retime_until_safe(CheckSuite([check]), _scaled_timer(robot, calls), CheckContext(), guess=2.5)
    # the unslowed motion is timed (the base) but not checked: one round, at the guess
    assert calls == [1.0, 2.5] and len(check.seen) == 1 and out.rounds == 1
    assert out.passed and out.slowdown == 2.5 and out.first.scale == 1.0
    # a guess below what is needed: the loop goes on from the guessed timing
    calls.clear()
    low = retime_until_safe(
        CheckSuite([SpeedBound(robot, 0.5)]), _scaled_timer(robot, calls), CheckContext(), guess=1.5
    )
    assert low.passed and calls[:2] == [1.0, 1.5] and low.rounds == 2
    assert low.slowdown == pytest.approx(1.5 * (2.0 / 1.5) * SLOWDOWN_STEP)
    # no guess (or one of at most 1): the unslowed motion is checked first, as before
    calls.clear()
    plain = retime_until_safe(
        CheckSuite([SpeedBound(robot, 0.5)]), _scaled_timer(robot, calls), CheckContext(), guess=0.9
    )
    assert calls[0] == 1.0 and plain.rounds == 2 and plain.slowdown == pytest.approx(2.0 * SLOWDOWN_STEP)


def test_the_next_guess_follows_what_the_committed_motion_needed(setup):
    _, robot, _, _ = setup
    calls: list[float] = []
    # slowed from the unslowed motion: the next plan starts from what it needed (2x, with the step's
    # margin)
    out = retime_until_safe(CheckSuite([SpeedBound(robot, 0.5)]), _scaled_timer(robot, calls), CheckContext())
    assert out.slowdown == pytest.approx(2.0 * SLOWDOWN_STEP) and not out.guessed
    assert next_guess(out) == pytest.approx(2.0 * SLOWDOWN_STEP)
    # a plan that started from a guess gives none: the next one checks its unslowed motion again
    guessed = retime_until_safe(
        CheckSuite([SpeedBound(robot, 0.5)]), _scaled_timer(robot, calls), CheckContext(), guess=2.5
    )
    assert guessed.guessed and guessed.passed and next_guess(guessed) is None
    # an unslowed motion, a refused one, or no estimate: no guess
    free = retime_until_safe(
        CheckSuite([SpeedBound(robot, 3.0)]), _scaled_timer(robot, calls), CheckContext()
    )
    assert free.slowdown == 1.0 and next_guess(free) is None
    stuck = retime_until_safe(
        CheckSuite([SpeedBound(robot, 0.4, fixable=False)]),
        _scaled_timer(robot, calls),
        CheckContext(),
        guess=2.0,
    )
    assert not stuck.passed and next_guess(stuck) is None
    silent = retime_until_safe(
        CheckSuite([PathCount(robot)]), _scaled_timer(robot, calls), CheckContext(), guess=2.0
    )
    assert silent.slowdown == 2.0 and next_guess(silent) is None


def test_a_check_that_does_not_apply_gives_no_verdict(setup):
    _, robot, _, _ = setup
    q = np.zeros((3, 7))
    motion = Trajectory(np.arange(3) * 0.01, q, q, q, tuple(robot.joint_names))
    suite = CheckSuite([NotAfter(robot), PathCount(robot)])
    assert [v.name for v in suite.run(motion, CheckContext())] == ["not_after", "path_count"]
    assert [v.name for v in suite.run(motion, CheckContext(after_handover=True))] == ["path_count"]


def test_closed_loop_re_targets_slower_when_a_check_asks_and_records_the_delay(setup):
    model, robot, train, test = setup
    demo = test[1]
    profile = demonstrated_profile(robot, train)
    settings = ClosedLoopSettings(start_ratio=0.2)
    base = CheckSuite.build(robot, ["speed_limits", "joint_limits", "workspace", "self_collision"])
    free = replay_demo(model, robot, demo, profile, settings, base)
    peak = float(np.max(np.abs(free.trajectory.qd)))
    check = SpeedBound(robot, 0.7 * peak)
    slowed = replay_demo(model, robot, demo, profile, settings, CheckSuite([*base.checks, check]))
    assert np.max(np.abs(slowed.trajectory.qd)) <= 0.7 * peak + 1e-9
    committed = [r for r in slowed.replans if r.committed]
    assert committed and all(r.checks["speed_bound"]["status"] == "pass" for r in committed)
    assert any(r.slowdown > 1.0 and r.slowdown_delay_s > 0 for r in committed)
    assert slowed.arrival_s > free.arrival_s
    assert all(r.slowdown == 1.0 and "speed_bound" not in r.checks for r in free.replans)
    # a check that slowing cannot fix refuses every re-plan: the robot stays at rest
    stuck = CheckSuite([*base.checks, SpeedBound(robot, 0.0, False)])
    never = replay_demo(model, robot, demo, profile, settings, stuck)
    assert never.n_committed == 0 and not never.trajectory.qd.any()
    assert all("speed_bound" in r.reason for r in never.replans)


def test_a_check_that_asks_locally_slows_the_motion_only_where_it_fails(setup):
    model, robot, _, test = setup
    obs = test[0].head(0.3, groups=OBSERVE)
    base = plan(model, robot, obs, CheckSuite([]))
    q0, q1 = base.trajectory.q[0], base.trajectory.q[-1]
    probe = RegionSpeedBound(robot, np.inf, q0, q1)
    inside = probe.region(base.trajectory)
    peak_in = float(np.abs(base.trajectory.qd[inside]).max())
    local = plan(model, robot, obs, CheckSuite([RegionSpeedBound(robot, 0.6 * peak_in, q0, q1)]))
    only_uniform = RegionSpeedBound(robot, 0.6 * peak_in, q0, q1, local=False)
    uniform = plan(model, robot, obs, CheckSuite([only_uniform]))
    assert local.passed and uniform.passed
    assert local.slowdown_local and not uniform.slowdown_local
    motion = local.trajectory
    assert np.abs(motion.qd[probe.region(motion)]).max() <= 0.6 * peak_in
    # the same path, in less time than the uniform slow-down: only the region was slowed
    np.testing.assert_allclose(motion.q[-1], base.trajectory.q[-1], atol=1e-6)
    assert base.trajectory.duration_s < motion.duration_s < uniform.trajectory.duration_s - 0.1
    assert local.slowdown == pytest.approx(motion.duration_s / base.trajectory.duration_s)
    assert local.slowdown_delay_s == pytest.approx(motion.end_s - base.trajectory.end_s)
    outside = ~probe.region(motion) & (np.linalg.norm(motion.q - q0, axis=1) < 0.2 * np.linalg.norm(q1 - q0))
    before = np.linalg.norm(base.trajectory.q - q0, axis=1) < 0.2 * np.linalg.norm(q1 - q0)
    # before the region the motion is as fast as unslowed (not slowed uniformly)
    assert np.abs(motion.qd[outside]).max() >= 0.95 * np.abs(base.trajectory.qd[before]).max()


def _region_plan(setup):
    """The unslowed one-shot plan of the first test demo, the toy region's ends and the peak joint
    speed in it [rad/s]: (model, robot, observation, plan, q0, q1, peak)."""
    model, robot, _, test = setup
    obs = test[0].head(0.3, groups=OBSERVE)
    base = plan(model, robot, obs, CheckSuite([]))
    q0, q1 = base.trajectory.q[0], base.trajectory.q[-1]
    inside = RegionSpeedBound(robot, np.inf, q0, q1).region(base.trajectory)
    return model, robot, obs, base, q0, q1, float(np.abs(base.trajectory.qd[inside]).max())


def test_a_local_slowdown_that_does_not_pass_falls_back_to_the_uniform_one(setup):
    model, robot, obs, base, q0, q1, peak = _region_plan(setup)
    bound = 0.5 * peak
    stingy = RegionSpeedBound(robot, bound, q0, q1, stingy=0.05)  # asks locally for far too little
    result = plan(model, robot, obs, CheckSuite([stingy]))
    assert result.passed and not result.slowdown_local and result.slowdown > 1.0
    # the local rounds were tried first: the unslowed motion, MAX_SLOWDOWN_ROUNDS local timings, then
    # the uniform ones
    assert len(stingy.seen) > 1 + MAX_SLOWDOWN_ROUNDS


def test_a_stretch_may_be_slowed_beyond_the_uniform_cap_while_the_whole_stays_within_it(setup):
    model, robot, obs, _, q0, q1, peak = _region_plan(setup)
    bound = peak / (1.25 * MAX_SLOWDOWN)
    local = plan(model, robot, obs, CheckSuite([RegionSpeedBound(robot, bound, q0, q1)]))
    assert local.passed and local.slowdown_local
    assert local.slowdown < MAX_SLOWDOWN
    assert (
        np.abs(local.trajectory.qd[RegionSpeedBound(robot, bound, q0, q1).region(local.trajectory)]).max()
        <= bound
    )
    # slowed as a whole, the same stretch would need more than the cap: refused
    uniform = plan(model, robot, obs, CheckSuite([RegionSpeedBound(robot, bound, q0, q1, local=False)]))
    assert not uniform.passed
