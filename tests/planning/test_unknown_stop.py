"""The closed loop's stop, hold and retreat when the observation turns unknown after the robot started."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ipromp_pin.data import ROBOT
from ipromp_pin.exceptions import PipelineError
from ipromp_pin.motion.limits import demonstrated_profile
from ipromp_pin.motion.retarget import stop_motion
from ipromp_pin.motion.trajectory import JointLimits, MotionState
from ipromp_pin.planning.closed_loop import ClosedLoopPlanner, ClosedLoopSettings, demo_samples
from ipromp_pin.robot import ee_positions, load_robot
from ipromp_pin.safety import CheckSuite

OBSERVE = ["orientation", "emg"]


@pytest.fixture(scope="module")
def setup(synthetic_closed_loop):
    """A model of three synthetic Baxter hand-over tasks, a held-out demo of each, the motion's checks."""
    model, robot, train, test = synthetic_closed_loop
    suite = CheckSuite.build(robot, ["speed_limits", "joint_limits", "workspace", "self_collision"])
    return model, robot, demonstrated_profile(robot, train), test, suite


def noisy_after(demo, fraction, scale=3.0, seed=0):
    """The demo's observed samples, those from ``fraction`` of it on buried in noise (a motion the
    model never learned)."""
    rng = np.random.default_rng(seed)
    samples = demo_samples(demo, OBSERVE)
    for s in samples[int(fraction * len(samples)) :]:
        for g in OBSERVE:
            if s[g] is not None:
                s[g] = s[g] + scale * rng.standard_normal(s[g].shape)
    return samples


class UnknownBetween:
    """The model's stream, its re-plans' observations read as unknown from ``t0`` to ``t1`` [s]
    (the observed time): a recognition that flips, with everything else the real one's."""

    def __init__(self, stream, t0, t1):
        self.stream, self.t0, self.t1 = stream, t0, t1

    def __getattr__(self, name):
        return getattr(self.stream, name)

    def __enter__(self):
        self.stream.__enter__()
        return self

    def __exit__(self, *exc):
        return self.stream.__exit__(*exc)

    def predict(self, *args, **kwargs):
        pred = self.stream.predict(*args, **kwargs)
        if self.t0 <= pred.observed_until_s < self.t1:
            pred = dataclasses.replace(pred, known=False, unknown_reason="unknown in the test's window")
        return pred


def replay(setup, samples, settings=None, window=None):
    model, robot, profile, test, suite = setup
    demo = test[0]
    planner = ClosedLoopPlanner(model, robot, profile, demo.groups[ROBOT][0], 0.3, settings, suite)
    if window is not None:
        planner._stream = UnknownBetween(planner._stream, *window)
    for t, sample in zip(demo.t - demo.t[0], samples, strict=True):
        planner.step(float(t), sample)
    return planner.finish()


def assert_within_limits(traj, limits, q_end=None):
    """The written trajectory re-evaluated from its samples: continuous positions, velocities,
    accelerations and jerks (differences between samples) within the limits."""
    dt = traj.dt_s
    tol = 1e-6
    assert np.all(np.abs(traj.qd) <= limits.velocity_rad_s * (1 + tol))
    assert np.all(np.abs(traj.qdd) <= limits.acceleration_rad_s2 * (1 + tol))
    assert np.all(np.abs(np.diff(traj.qdd, axis=0)) / dt <= limits.jerk_rad_s3 * (1 + tol))
    # positions integrate the velocities (no jump between plans): trapezoid within 2 % of a step
    step = np.abs(np.diff(traj.q, axis=0))
    trap = np.abs(0.5 * (traj.qd[1:] + traj.qd[:-1]) * dt)
    assert np.all(np.abs(step - trap) <= 0.02 * limits.velocity_rad_s * dt + 1e-9)
    assert np.all(traj.q >= limits.lower_rad - 1e-9) and np.all(traj.q <= limits.upper_rad + 1e-9)
    assert not traj.qd[-1].any() and not traj.qdd[-1].any()
    if q_end is not None:
        np.testing.assert_allclose(traj.q[-1], q_end, atol=1e-9)


def test_a_motion_turned_unknown_stops_holds_and_retreats_to_rest(setup):
    model, robot, profile, test, _ = setup
    demo = test[0]
    known = replay(setup, demo_samples(demo, OBSERVE))
    assert known.unknown_events == [] and known.n_committed > 0  # a known motion is not stopped
    result = replay(setup, noisy_after(demo, 0.4))
    kinds = [e.kind for e in result.unknown_events]
    assert kinds == ["unknown", "hold", "retreat"]
    unknown_s, hold_s, retreat_s = (e.t_s for e in result.unknown_events)
    first_unknown = next(r for r in result.replans if not r.known)
    assert unknown_s == pytest.approx(first_unknown.t_s) and first_unknown.committed
    assert first_unknown.action == "stop" and 0.0 < unknown_s < hold_s
    assert retreat_s >= hold_s + result.settings.unknown_hold_s - 1e-9  # held at least the hold
    assert retreat_s < hold_s + result.settings.unknown_hold_s + 1.0 / result.settings.replan_rate_hz + 1e-9
    assert [r.action for r in result.replans if r.committed and r.action] == ["stop", "retreat"]
    assert "retreating" in result.stopped
    # the robot ends at rest where it waited, every limit kept throughout (the written samples)
    traj = result.trajectory
    assert_within_limits(traj, profile.limits, demo.groups[ROBOT][0])
    # from the unknown re-plan on it approaches the hand-over it aimed at by at most its stopping
    # distance, and never again once it holds
    aim = np.asarray(
        next(
            r for r in reversed(result.replans[: first_unknown.index]) if r.committed
        ).predicted_handover_position_m
    )
    gripper = ee_positions(robot, traj.q)
    d = np.linalg.norm(gripper - aim, axis=1)
    i_unknown, i_hold, i_retreat = (int(round(t / traj.dt_s)) for t in (unknown_s, hold_s, retreat_s))
    assert np.all(np.linalg.norm(gripper[i_hold : i_retreat + 1] - gripper[i_hold], axis=1) < 1e-9)  # still
    assert np.all(np.diff(d[i_hold:]) >= -1e-4)  # holding, then moving away
    assert d[i_hold] > d[-1] - np.linalg.norm(gripper[-1] - gripper[i_hold]) - 1e-9
    travelled = np.sum(np.linalg.norm(np.diff(gripper[i_unknown : i_hold + 1], axis=0), axis=1))
    # it stops short of the hand-over its last plan went to (and came to rest at: the old behaviour)
    assert d[i_unknown:].min() > 0.05 and d[i_unknown] - d[i_unknown:].min() <= travelled + 1e-9
    without = replay(setup, noisy_after(demo, 0.4), ClosedLoopSettings(require_known=False))
    # the same replay up to the unknown re-plan
    np.testing.assert_array_equal(traj.q[: i_unknown + 1], without.trajectory.q[: i_unknown + 1])


def test_known_again_during_the_hold_resumes_re_targeting(setup):
    _, _, profile, test, _ = setup
    demo = test[0]
    settings = ClosedLoopSettings(unknown_hold_s=1.0)
    result = replay(setup, demo_samples(demo, OBSERVE), settings, window=(1.2, 1.5))
    kinds = [e.kind for e in result.unknown_events]
    assert kinds[0] == "unknown" and "resume" in kinds and "retreat" not in kinds
    resume = next(e.t_s for e in result.unknown_events if e.kind == "resume")
    assert resume >= result.unknown_events[0].t_s
    after = [r for r in result.replans if r.t_s >= resume - 1e-9 and r.committed]
    assert after and after[0].action == "" and after[0].known  # a re-target toward the hand-over
    assert_within_limits(result.trajectory, profile.limits)
    assert result.trajectory.end_s > resume and not result.stopped.startswith("re-planning stopped at t=1")


def test_samples_ending_during_the_hold_still_retreat(setup):
    _, _, profile, test, _ = setup
    demo = test[0]
    end = float(demo.t[-1] - demo.t[0])
    settings = ClosedLoopSettings(unknown_hold_s=5.0, freeze_phase=1.0)
    result = replay(setup, demo_samples(demo, OBSERVE), settings, window=(end - 0.5, end + 1.0))
    kinds = [e.kind for e in result.unknown_events]
    assert kinds == ["unknown", "hold", "retreat"]
    hold, retreat = result.unknown_events[1].t_s, result.unknown_events[2].t_s
    assert retreat == pytest.approx(hold + 5.0, abs=0.011) and retreat > end  # planned by finish()
    assert result.replans[-1].action == "retreat" and result.replans[-1].committed
    assert_within_limits(result.trajectory, profile.limits, demo.groups[ROBOT][0])


def test_ignore_keeps_the_last_plan(setup):
    demo = setup[3][0]
    result = replay(setup, demo_samples(demo, OBSERVE), ClosedLoopSettings(require_known=False), (1.2, 9.0))
    assert result.unknown_events == [] and not any(r.action for r in result.replans)
    assert all(r.committed or r.reason for r in result.replans)


def test_the_stop_is_jerk_limited_and_comes_to_rest():
    robot = load_robot("baxter_left")
    limits = JointLimits.from_robot(robot)
    v = 0.8 * limits.velocity_rad_s * np.linspace(-1, 1, 7)
    state = MotionState(1.0, np.zeros(7), v, 0.5 * limits.acceleration_rad_s2)
    stop = stop_motion(state, limits, 0.01, hold_s=0.5)
    assert stop.start_s == 1.0 and np.array_equal(stop.qd[0], v)
    rest = int(np.argmax(~np.any(stop.qd != 0, axis=1)))
    assert stop.n_samples - 1 - rest == 50  # then held 0.5 s at rest where it stopped
    assert np.all(stop.q[rest:] == stop.q[rest])
    assert np.all(np.abs(stop.qdd) <= limits.acceleration_rad_s2)
    assert np.all(np.abs(np.diff(stop.qdd, axis=0)) / 0.01 <= limits.jerk_rad_s3)
    assert np.all(np.abs(stop.qd) <= limits.velocity_rad_s)


@pytest.mark.parametrize("hold", [-0.1, 11.0, float("nan")])
def test_an_implausible_hold_is_refused_naming_the_field(hold):
    with pytest.raises(PipelineError, match="field 'unknown_hold_s': implausible value"):
        ClosedLoopSettings(unknown_hold_s=hold).validate()
