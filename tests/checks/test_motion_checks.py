"""The timed-motion checks' base (ipromp_pin.checks): a check's result joins the one-shot report, a
check that asks for a slower motion gets it (one-shot re-timing, closed-loop slower re-targeting), and
one that slowing cannot fix fails the plan."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.checks import (
    MAX_SLOWDOWN,
    MAX_SLOWDOWN_ROUNDS,
    MOTION_CHECKS,
    CheckContext,
    MotionCheck,
    TimedMotion,
    build_checks,
    needed_slowdown,
)
from ipromp_pin.exceptions import PipelineError
from ipromp_pin.handover.closed_loop import ClosedLoopSettings, replay_demo
from ipromp_pin.handover.one_shot import plan
from ipromp_pin.motion.limits import demonstrated_profile
from ipromp_pin.promp import IProMP
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import CheckResult, load_robot

OBSERVE = ["orientation", "emg"]


class SpeedBound(MotionCheck):
    """A toy check: every joint speed at most ``bound`` [rad/s]; asks for the slow-down that gives it."""

    name = "speed_bound"

    def __init__(self, robot, bound: float = np.inf, fixable: bool = True, power: float = 1.0) -> None:
        super().__init__(robot)
        self.bound = bound
        self.fixable = fixable
        self.power = power  # < 1: asks for less slow-down than it needs (a first-order estimate)
        self.seen: list[TimedMotion] = []
        self.contexts: list[CheckContext] = []

    def check(self, motion: TimedMotion, context: CheckContext) -> CheckResult:
        self.seen.append(motion)
        self.contexts.append(context)
        peak = float(np.max(np.abs(motion.qd)))
        values = {"peak_rad_s": peak}
        if peak <= self.bound:
            return CheckResult(self.name, "pass", f"peak {peak:.3f} rad/s", values)
        if self.fixable:
            values["slowdown"] = (peak / self.bound) ** self.power
        return CheckResult(self.name, "fail", f"peak {peak:.3f} rad/s > {self.bound}", values)


@pytest.fixture(scope="module")
def setup():
    ds = make_synthetic_dataset(n_tasks=2, n_demos=6, seed=5)
    train = [d for demos in ds.demos.values() for d in demos[:-1]]
    test = [demos[-1] for demos in ds.demos.values()]
    return IProMP(observe=OBSERVE).fit(train), load_robot("baxter_left"), train, test


def test_needed_slowdown_combines_the_failing_required_checks():
    ok = CheckResult("a", "pass", "", {"slowdown": 9.0})
    slow2 = CheckResult("b", "fail", "", {"slowdown": 2.0})
    slow3 = CheckResult("c", "fail", "", {"slowdown": 3.0})
    advisory = CheckResult("d", "fail", "", {}, required=False)
    assert needed_slowdown([ok, advisory]) == 1.0
    assert needed_slowdown([ok, slow2, slow3, advisory]) == 3.0
    assert needed_slowdown([slow2, CheckResult("e", "fail", "", {})]) is None
    assert needed_slowdown([CheckResult("f", "fail", "", {"slowdown": MAX_SLOWDOWN * 1.01})]) is None
    assert needed_slowdown([CheckResult("g", "fail", "", {"slowdown": float("nan")})]) is None


def test_build_checks_names_an_unknown_check():
    robot = load_robot("baxter_left")
    assert [type(c) for c in build_checks(robot)] == list(MOTION_CHECKS)
    with pytest.raises(PipelineError, match="unknown motion check"):
        build_checks(robot, ["no_such_check"])


def test_one_shot_plan_runs_the_checks_on_the_timed_motion_from_the_observation_end(setup):
    model, robot, _, test = setup
    obs = test[0].head(0.3, groups=OBSERVE)
    base = plan(model, robot, obs)
    check = SpeedBound(robot)
    result = plan(model, robot, obs, checks=[check], context=CheckContext())
    assert result.report["speed_bound"].status == "pass" and result.passed
    motion = check.seen[0]
    t_end = float(obs.t[-1] - obs.t[0])
    assert motion.t_s[0] == pytest.approx(t_end) and result.start_s == pytest.approx(t_end)
    np.testing.assert_array_equal(motion.q, base.trajectory.q)
    assert check.contexts[0].task == result.prediction.task
    assert check.contexts[0].handover_s == pytest.approx(t_end + base.trajectory.t_s[-1])
    assert result.slowdown == 1.0 and result.slowdown_delay_s == 0.0


def test_one_shot_plan_is_re_timed_when_a_check_asks_for_a_slower_motion(setup):
    model, robot, _, test = setup
    obs = test[0].head(0.3, groups=OBSERVE)
    base = plan(model, robot, obs)
    peak = float(np.max(np.abs(base.trajectory.qd)))
    result = plan(model, robot, obs, checks=[SpeedBound(robot, 0.6 * peak)])
    assert result.passed and result.report["speed_bound"].status == "pass"
    assert np.max(np.abs(result.trajectory.qd)) <= 0.6 * peak
    assert result.slowdown > 1.0 / 0.6
    assert result.slowdown_delay_s == pytest.approx(result.trajectory.t_s[-1] - base.trajectory.t_s[-1])
    assert result.slowdown_delay_s > 0.1
    # the same path: only its timing changed
    np.testing.assert_allclose(result.trajectory.q[-1], base.trajectory.q[-1], atol=1e-6)
    # a failure that slowing cannot fix fails the plan, untouched
    stuck = plan(model, robot, obs, checks=[SpeedBound(robot, 0.6 * peak, fixable=False)])
    assert not stuck.passed and stuck.report.failures == ["speed_bound"]
    assert stuck.slowdown == 1.0 and stuck.trajectory.t_s[-1] == base.trajectory.t_s[-1]


def test_a_slowed_plan_that_still_fails_is_slowed_again_until_it_passes(setup):
    model, robot, _, test = setup
    obs = test[0].head(0.3, groups=OBSERVE)
    peak = float(np.max(np.abs(plan(model, robot, obs).trajectory.qd)))
    check = SpeedBound(robot, 0.6 * peak, power=0.5)  # asks for the square root of what it needs
    result = plan(model, robot, obs, checks=[check])
    assert result.passed and np.max(np.abs(result.trajectory.qd)) <= 0.6 * peak
    assert result.slowdown > 1.0 / 0.6
    assert 3 <= len(check.seen) <= 2 + MAX_SLOWDOWN_ROUNDS  # the plan, then one timing per round
    # rounds are bounded: a check that asks for too little every time leaves the plan failing
    stingy = SpeedBound(robot, 0.2 * peak, power=0.05)
    failed = plan(model, robot, obs, checks=[stingy])
    assert not failed.passed and failed.slowdown == 1.0 and len(stingy.seen) == 2 + MAX_SLOWDOWN_ROUNDS


def test_closed_loop_re_targets_slower_when_a_check_asks_and_records_the_delay(setup):
    model, robot, train, test = setup
    demo = test[1]
    profile = demonstrated_profile(robot, train)
    settings = ClosedLoopSettings(start_ratio=0.2)
    free = replay_demo(model, robot, demo, profile, settings)
    peak = float(np.max(np.abs(free.trajectory.qd)))
    check = SpeedBound(robot, 0.7 * peak)
    slowed = replay_demo(model, robot, demo, profile, settings, checks=[check])
    assert np.max(np.abs(slowed.trajectory.qd)) <= 0.7 * peak + 1e-9
    committed = [r for r in slowed.replans if r.committed]
    assert committed and all(r.checks["speed_bound"]["status"] == "pass" for r in committed)
    assert any(r.slowdown > 1.0 and r.slowdown_delay_s > 0 for r in committed)
    assert slowed.arrival_s > free.arrival_s
    assert all(r.slowdown == 1.0 and r.checks == {} for r in free.replans)
    # a check that slowing cannot fix refuses every re-plan: the robot stays at rest
    never = replay_demo(model, robot, demo, profile, settings, checks=[SpeedBound(robot, 0.0, False)])
    assert never.n_committed == 0 and not never.trajectory.qd.any()
    assert all("speed_bound" in r.reason for r in never.replans)
