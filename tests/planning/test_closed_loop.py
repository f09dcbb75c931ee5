"""The closed loop: reference motion, jerk-limited re-targeting, the planner and its checks."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.data import ROBOT
from ipromp_pin.evaluation.scoring import arrival_time, score_closed_loop
from ipromp_pin.exceptions import ObservationError, PipelineError
from ipromp_pin.motion.limits import LimitProfile, conservative_profile, demonstrated_profile
from ipromp_pin.motion.retarget import ReferenceMotion, Retargeter
from ipromp_pin.motion.trajectory import MotionState, Trajectory
from ipromp_pin.planning.closed_loop import (
    ClosedLoopPlanner,
    ClosedLoopSettings,
    conditioning_predictor,
    demo_samples,
    replay_demo,
    start_time,
)
from ipromp_pin.promp import IProMP
from ipromp_pin.robot import ee_positions
from ipromp_pin.safety import CheckContext, CheckSuite, Verdict
from ipromp_pin.safety.self_collision import SelfCollision
from ipromp_pin.safety.speed_limits import limit_ratios as motion_limit_ratios

OBSERVE = ["orientation", "emg"]


@pytest.fixture(scope="module")
def setup(synthetic_closed_loop):
    """A model trained on synthetic Baxter hand-overs (all but the last demo of each task)."""
    return synthetic_closed_loop


@pytest.fixture(scope="module")
def certifier(setup):
    """The motion's own checks (limits, workspace, self-collision), shared by the tests' replays."""
    return CheckSuite.build(setup[1], ["speed_limits", "joint_limits", "workspace", "self_collision"])


def limit_ratios(qd, qdd, dt, limits):
    n = qd.shape[0]
    return motion_limit_ratios(Trajectory(np.arange(n) * dt, np.zeros_like(qd), qd, qdd, ()), limits)[0]


def _reference(model, demo, ratio=0.5):
    pred = model.predict(demo.head(ratio, groups=OBSERVE))
    return pred, ReferenceMotion.from_prediction(pred, model.basis_.centres, model.basis_.width)


def test_reference_motion_is_the_prediction_with_exact_derivatives(setup):
    model, _, _, test = setup
    pred, ref = _reference(model, test[0])
    q, qd, qdd, qddd = ref.evaluate(pred.t)
    np.testing.assert_allclose(q, pred.q_mean, atol=1e-12)
    t = np.linspace(0.3, pred.duration_s - 0.3, 7)
    h = 1e-5
    for k, (lo, hi, d) in enumerate(((0, 0, 1), (1, 1, 2), (2, 2, 3))):
        fd = (ref.evaluate(t + h)[lo] - ref.evaluate(t - h)[hi]) / (2 * h)
        exact = ref.evaluate(t)[d]
        tol = 1e-5 * (1 + np.abs(exact).max())
        np.testing.assert_allclose(fd, exact, atol=tol, err_msg=f"derivative {k + 1}")
    # held at the ends, at rest
    q_after, qd_after, _, _ = ref.evaluate(np.array([pred.duration_s + 1.0]))
    np.testing.assert_allclose(q_after[0], pred.q_mean[-1], atol=1e-12)
    assert not qd_after.any()
    # one time at a time (what a re-target asks for): the same numbers to the bit, inside, at the
    # ends and outside
    for t1 in (*t, 0.0, pred.duration_s, -0.5, pred.duration_s + 1.0):
        many = ref.evaluate(np.array([t1]), order=2)
        for x, y in zip(ref.at(float(t1)), many[:3], strict=True):
            assert np.array_equal(x, y[0])
    assert np.array_equal(ref.end(), ref.evaluate(np.array([pred.duration_s]), order=0)[0][0])


def _check_plan(plan, state, limits, dt):
    # starts exactly at the current state, ends at rest, within every limit at every sample
    np.testing.assert_allclose(plan.q[0], state.q)
    np.testing.assert_allclose(plan.qd[0], state.qd)
    np.testing.assert_allclose(plan.qdd[0], state.qdd)
    assert not plan.qd[-1].any() and not plan.qdd[-1].any()
    assert np.all(limit_ratios(plan.qd, plan.qdd, dt, limits) <= 1 + 1e-6)
    # positions consistent with the velocities (no jump between samples)
    vel_fd = np.diff(plan.q, axis=0) / dt
    assert np.max(np.abs(vel_fd) / limits.velocity_rad_s) <= 1.0 + 1e-6


def test_retarget_follows_the_prediction_on_time_when_the_limits_allow(setup):
    model, robot, _, test = setup
    pred, ref = _reference(model, test[1])
    limits = conservative_profile(robot).limits.scaled(4.0, 20.0, 200.0)
    dt = 0.01
    t_c = 1.0
    q0, v0, a0, _ = ref.evaluate(np.array([t_c]))
    state = MotionState(t_c, q0[0], v0[0], a0[0])  # on the reference
    plan, report = Retargeter(limits, dt, 0.2).plan(state, ref)
    _check_plan(plan, state, limits, dt)
    assert report.time_scale == 1.0
    assert abs(report.arrival_s - ref.duration_s) < 2 * dt  # rests when the human gets there
    # between the blend and the settle it is the prediction itself, on the human's timeline
    mid = (plan.t_s > t_c + 0.3) & (plan.t_s < ref.duration_s - 0.3)
    np.testing.assert_allclose(plan.q[mid], ref.evaluate(plan.t_s[mid])[0], atol=1e-9)
    np.testing.assert_allclose(plan.q[-1], ref.end(), atol=1e-12)


def test_retarget_is_late_only_as_much_as_the_limits_demand(setup):
    model, robot, _, test = setup
    pred, ref = _reference(model, test[1])
    dt = 0.01
    state = MotionState.at_rest(0.5, test[1].groups[ROBOT][0])
    tight = conservative_profile(robot).limits.scaled(1.0, 0.5, 0.5)
    loose = conservative_profile(robot).limits.scaled(4.0, 20.0, 200.0)
    late, late_r = Retargeter(tight, dt, 0.2).plan(state, ref)
    fast, fast_r = Retargeter(loose, dt, 0.2).plan(state, ref)
    _check_plan(late, state, tight, dt)
    _check_plan(fast, state, loose, dt)
    assert late_r.time_scale > 1.0 and late_r.lateness_s > 0.3
    assert late_r.lateness_s > fast_r.lateness_s
    assert fast_r.lateness_s < 0.1
    np.testing.assert_allclose(late.q[-1], fast.q[-1], atol=1e-12)  # same hand-over, later


def test_settings_are_validated_naming_the_field():
    for kwargs, field in (
        ({"start_ratio": 0.0}, "start_ratio"),
        ({"start_ratio": 1.0}, "start_ratio"),
        ({"replan_rate_hz": 0.0}, "replan_rate_hz"),
        ({"replan_rate_hz": 200.0}, "replan_rate_hz"),
        ({"blend_s": float("nan")}, "blend_s"),
        ({"freeze_phase": 0.0}, "freeze_phase"),
        ({"start_after_s": 0.0}, "start_after_s"),
        ({"start_after_s": 1e4}, "start_after_s"),
        ({"start_ratio": 0.2, "start_after_s": 0.5}, "start_after_s"),
        ({"start_confidence": 0.0}, "start_confidence"),
        ({"start_confidence": 1.5}, "start_confidence"),
    ):
        with pytest.raises(PipelineError, match=f"somewhere: field '{field}'"):
            ClosedLoopSettings(**kwargs).validate("somewhere")


def test_the_start_rule_is_a_time_whatever_the_recordings_length(setup):
    model, _, _, test = setup
    demo = test[0]
    dt = float(demo.t[1] - demo.t[0])
    nominal = float(model.duration_nominal_s_)
    shorter = demo.slice(int(0.7 * demo.n_samples))  # the same motion, recorded for less time
    rule = ClosedLoopSettings()  # by default: a fraction of the model's nominal duration
    t_rule = start_time(demo, rule, nominal)
    assert t_rule == start_time(shorter, rule, nominal)
    assert 0.2 * nominal - dt < t_rule <= 0.2 * nominal  # its last sample observed by then
    assert (
        rule.start_text(nominal)
        == f"after {0.2 * nominal:.2f} s (20% of the model's nominal {nominal:.2f} s)"
    )
    # the paper's fraction of the recording moves with the recording's length
    paper = ClosedLoopSettings(start_ratio=0.2)
    assert start_time(demo, paper, nominal) != start_time(shorter, paper, nominal)
    assert start_time(demo, ClosedLoopSettings(start_after_s=0.5), nominal) == pytest.approx(0.5, abs=dt)
    with pytest.raises(ObservationError, match="start_after_s.*after the demo's end"):
        start_time(demo, ClosedLoopSettings(start_after_s=100.0), nominal)


def _first_replan(model, robot, demo, settings, certifier):
    """The planner and its first re-plan on ``demo`` (replayed at its recorded timing)."""
    profile = demonstrated_profile(robot, [demo])
    start = start_time(demo, settings, float(model.duration_nominal_s_))
    with ClosedLoopPlanner(
        model, robot, profile, demo.groups[ROBOT][0], start, settings, certifier
    ) as planner:
        for t, sample in zip(demo.t - demo.t[0], demo_samples(demo, OBSERVE), strict=True):
            replan = planner.step(float(t), sample)
            if replan is not None:
                return planner, start, replan
    raise AssertionError("no re-plan")


def test_the_robot_starts_earlier_once_a_task_is_recognised_with_the_set_confidence(setup, certifier):
    model, robot, _, test = setup
    demo = test[1]
    planner, start, first = _first_replan(model, robot, demo, ClosedLoopSettings(), certifier)
    assert start - 1e-9 <= first.observed_until_s < start + 0.05
    assert planner.start_s == first.observed_until_s and "the start rule's time" in planner.start_reason
    # recognised with posterior 0.9 before the rule's time: the robot starts then
    planner, _, early = _first_replan(model, robot, demo, ClosedLoopSettings(start_confidence=0.9), certifier)
    assert early.observed_until_s < start and max(early.posterior.values()) >= 0.9
    assert planner.start_s == early.observed_until_s
    assert f"{early.task} recognised with posterior" in planner.start_reason


def test_replay_starts_late_stays_within_limits_and_reaches_the_handover(setup, certifier):
    model, robot, train, test = setup
    demo = test[2]
    profile = demonstrated_profile(robot, train)
    settings = ClosedLoopSettings(start_ratio=0.2)
    result = replay_demo(model, robot, demo, profile, settings, certifier)
    traj = result.trajectory
    start = result.start_s
    assert 0.15 * demo.duration_s < start <= 0.21 * demo.duration_s
    # at rest at the recorded start configuration until the start
    before = traj.t_s < start - 1e-9
    assert before.any() and np.abs(traj.q[before] - demo.groups[ROBOT][0]).max() < 1e-12
    assert not traj.qd[before].any()
    # every control sample within the profile's limits, continuous acceleration, at rest at the end
    assert np.all(limit_ratios(traj.qd, traj.qdd, traj.t_s[1] - traj.t_s[0], profile.limits) <= 1 + 1e-6)
    assert not traj.qd[-1].any()
    assert result.replans and result.n_refused == 0
    assert all(r.task == demo.task for r in result.replans[-5:])
    score = score_closed_loop(result, demo, robot)
    assert score.collisions == 0 and score.max_limit_ratio <= 1 + 1e-6
    # it comes to rest where the model, given what the last re-plan had observed, predicts the hand-over:
    # task and phase recognised with the model's noise ratio, the robot conditioned with condition_noise
    last = result.replans[-1]
    observed = demo.slice(last.n_observed, OBSERVE)
    parts, _ = model.predictor_.encode(observed)
    conditioner = conditioning_predictor(model, settings.condition_noise).conditioner
    q_end = conditioner.condition(model.recognise(observed), parts).q_mean[-1]
    np.testing.assert_allclose(traj.q[-1], q_end, atol=1e-9)
    # another conditioning noise ratio (the recognition unchanged) ends elsewhere: the setting is used
    other = conditioning_predictor(model, 10.0 * settings.condition_noise).conditioner
    q_other = other.condition(model.recognise(observed), parts).q_mean[-1]
    assert np.abs(q_other - q_end).max() > 1e-4
    assert score.handover_error_cm < 10.0
    # re-plans come at the re-plan rate
    dt = np.diff([r.t_s for r in result.replans])
    assert np.median(dt) == pytest.approx(1.0 / settings.replan_rate_hz, abs=0.011)


def test_a_refused_replan_keeps_the_last_safe_plan(setup, certifier):
    model, robot, train, test = setup
    demo = test[0]
    profile = demonstrated_profile(robot, train)
    start = float(demo.head(0.2).t[-1])
    real = certifier.get("self_collision")

    class RefuseAfterFive(SelfCollision):
        calls = 0

        def check(self, motion: Trajectory, context: CheckContext) -> Verdict:
            RefuseAfterFive.calls += 1
            v = real.check(motion, context)
            return (
                v if RefuseAfterFive.calls <= 5 else Verdict(self.name, "fail", "not certified", v.measures)
            )

    suite = CheckSuite(
        [c if c.name != "self_collision" else RefuseAfterFive(robot) for c in certifier.checks]
    )
    planner = ClosedLoopPlanner(model, robot, profile, demo.groups[ROBOT][0], start, None, suite)
    for t, sample in zip(demo.t, demo_samples(demo, OBSERVE), strict=True):
        planner.step(float(t), sample)
    result = planner.finish()
    committed = [r for r in result.replans if r.committed]
    refused = [r for r in result.replans if not r.committed]
    assert len(committed) == 5 and refused
    assert all(r.reason.startswith("self_collision") for r in refused)
    # after the fifth re-plan the commanded motion is exactly that plan, to its end
    last = result.plans[-1]
    k0 = int(round(committed[-1].t_s / planner.dt_s))
    np.testing.assert_allclose(result.trajectory.q[k0:], last.q, atol=1e-12)
    assert result.arrival_s == pytest.approx(last.t_s[-1])


def test_a_change_of_task_is_followed_smoothly(setup, certifier):
    model, robot, train, test = setup
    a, b = test[0], test[1]
    assert a.task != b.task
    # the human starts like demo a and continues like demo b (same clock)
    n = min(a.n_samples, b.n_samples)
    cut = int(0.45 * n)
    samples = demo_samples(a, OBSERVE)[:cut] + demo_samples(b, OBSERVE)[cut:n]
    profile = demonstrated_profile(robot, train)
    start = float(a.t[cut // 2])
    # a stitched motion is none of the learned ones: followed only when the robot may act on it
    settings = ClosedLoopSettings(require_known=False)
    planner = ClosedLoopPlanner(model, robot, profile, a.groups[ROBOT][0], start, settings, certifier)
    for t, sample in zip(a.t[:n], samples, strict=True):
        planner.step(float(t), sample)
    result = planner.finish()
    tasks = [r.task for r in result.replans if r.committed]
    assert tasks[0] == a.task and tasks[-1] == b.task
    traj = result.trajectory
    assert np.all(limit_ratios(traj.qd, traj.qdd, planner.dt_s, profile.limits) <= 1 + 1e-6)
    # it ends at the new task's hand-over, at rest
    end = ee_positions(robot, np.stack([traj.q[-1], result.plans[-1].q[-1]]))
    assert np.linalg.norm(end[0] - end[1]) < 1e-9


def test_arrival_time_is_when_the_gripper_stays_near_its_end():
    t = np.linspace(0.0, 2.0, 201)
    p = np.zeros((201, 3))
    p[:, 0] = np.minimum(t, 1.0) * 0.5  # moves 0.5 m in 1 s, then rests
    assert arrival_time(t, p, 0.01) == pytest.approx(0.98, abs=0.011)
    p[150, 0] = 0.3  # leaves again at 1.5 s
    assert arrival_time(t, p, 0.01) == pytest.approx(1.51, abs=0.011)


def test_tighter_limits_make_the_robot_late_and_the_report_says_so(setup, certifier):
    model, robot, train, test = setup
    demo = test[1]
    conservative = conservative_profile(robot)
    loose = LimitProfile("loose", conservative.limits.scaled(2.0, 10.0, 50.0), "test")
    out = {}
    for profile in (conservative, loose):
        result = replay_demo(model, robot, demo, profile, ClosedLoopSettings(), certifier)
        score = score_closed_loop(result, demo, robot, check_collisions=False)
        assert score.max_limit_ratio <= 1 + 1e-6
        out[profile.name] = (result.replans[0], score)
    first_c, score_c = out["conservative"]
    first_l, score_l = out["loose"]
    # the first re-plan starts from rest behind the human: the tight limits make it late, and say by how much
    assert first_c.lateness_s > 0.1
    assert first_c.planned_arrival_s == pytest.approx(first_c.predicted_handover_s + first_c.lateness_s)
    assert first_l.lateness_s < first_c.lateness_s


def test_stream_predict_is_the_conditioning_of_the_streams_recognition_on_its_samples(setup):
    model, _, _, test = setup
    demo = test[0]
    n = demo.n_samples // 2
    for gap in (False, True):
        observed = demo.slice(n, OBSERVE)
        if gap:  # a lost EMG frame: the stream falls back to the encoded observation's parts
            observed.missing["emg"] = np.arange(n) == n // 3
        with model.stream() as stream:
            for t, sample in zip(observed.t, demo_samples(observed, OBSERVE), strict=True):
                stream.update(float(t), sample)
            parts, t_last = model.predictor_.encode(stream.observation())
            got_parts, got_t = stream.parts()
            assert got_t == t_last and len(got_parts) == len(parts)
            for a, b in zip(got_parts, parts, strict=True):
                assert np.array_equal(a.t, b.t) and np.array_equal(a.dims, b.dims)
                assert np.array_equal(a.y, b.y)
            for noise in (None, 0.3, 3.0):
                predictor = conditioning_predictor(model, noise)
                ref = predictor.conditioner.condition(stream.recognition(), parts)
                # then the model's hand-over estimates, as the one-shot prediction applies them
                ref = predictor.with_estimates(ref, stream.window(), t_last)
                pred = stream.predict(condition_noise=noise)
                assert pred.task == ref.task and np.array_equal(pred.q_mean, ref.q_mean)
                assert np.array_equal(pred.q_cov, ref.q_cov)
            # the conditioning predictor of a noise ratio is built once and kept
            assert conditioning_predictor(model, 0.3) is conditioning_predictor(model, 0.3)
            assert conditioning_predictor(model, None) is model.predictor_


def test_reference_motion_reads_the_basis_from_the_prediction(setup):
    model, _, _, test = setup
    pred, ref = _reference(model, test[1])
    alone = ReferenceMotion.from_prediction(pred)
    t = np.linspace(0.0, pred.duration_s, 11)
    for a, b in zip(alone.evaluate(t), ref.evaluate(t), strict=True):
        assert np.array_equal(a, b)


def test_the_planner_is_a_context_manager_that_opens_and_closes_its_stream(setup, certifier):
    model, robot, train, test = setup
    demo = test[1]
    profile = demonstrated_profile(robot, train)
    start = float(demo.head(0.2).t[-1])
    samples = demo_samples(demo, OBSERVE)
    with ClosedLoopPlanner(model, robot, profile, demo.groups[ROBOT][0], start, None, certifier) as planner:
        assert planner._stream._held is not None  # the stream is open (BLAS threads limited)
        for t, sample in zip(demo.t - demo.t[0], samples, strict=True):
            planner.step(float(t), sample)
    assert planner._stream._held is None
    with pytest.raises(PipelineError, match="after finish"):
        planner.step(float(demo.t[-1]) + 1.0, samples[-1])
    result = planner.finish()
    # the same as without the context manager, and as replay_demo
    other = ClosedLoopPlanner(model, robot, profile, demo.groups[ROBOT][0], start, None, certifier)
    for t, sample in zip(demo.t - demo.t[0], samples, strict=True):
        other.step(float(t), sample)
    again = other.finish()
    assert np.array_equal(result.trajectory.q, again.trajectory.q)
    replayed = replay_demo(model, robot, demo, profile, ClosedLoopSettings(start_ratio=0.2), certifier)
    assert np.array_equal(result.trajectory.q, replayed.trajectory.q)


def test_every_replan_records_whether_the_task_is_known(setup, certifier):
    # a model of two of the three tasks sees the third: its re-plans say unknown, with the p-value;
    # the same demo with its task learned reads as known at the end
    model, robot, train, test = setup
    demo = test[2]
    two = IProMP(observe=OBSERVE).fit([d for d in train if d.task != demo.task])
    profile = demonstrated_profile(robot, train)
    settings = ClosedLoopSettings(start_ratio=0.2, require_known=False)  # re-plans although unknown
    result = replay_demo(two, robot, demo, profile, settings, certifier)
    assert result.replans and not any(r.known for r in result.replans)
    assert all(r.novelty_p_value is not None and r.novelty_p_value <= 0.05 for r in result.replans)
    known = replay_demo(model, robot, demo, profile, settings, certifier)
    assert known.replans[-1].known and known.replans[-1].novelty_p_value > 0.05


def test_the_robot_acts_only_on_a_known_task(setup, certifier):
    # a model without the last task: that task's demo is unknown. The robot never starts (and says
    # when the observation became unknown); with require_known=False it acts on the nearest task
    model, robot, train, test = setup
    unknown = test[2]
    small = IProMP(observe=OBSERVE).fit([d for d in train if d.task != unknown.task])
    profile = demonstrated_profile(robot, train)
    results = {}
    for require in (True, False):
        settings = ClosedLoopSettings(require_known=require)
        planner = ClosedLoopPlanner(small, robot, profile, unknown.groups[ROBOT][0], 0.3, settings, certifier)
        for t, sample in zip(unknown.t, demo_samples(unknown, OBSERVE), strict=True):
            planner.step(float(t), sample)
        results[require] = planner.finish()
    held, acted = results[True], results[False]
    assert not any(r.committed for r in held.replans)
    assert held.start_reason == "" and held.stopped.startswith("never started: unknown task from ")
    np.testing.assert_allclose(held.trajectory.q, unknown.groups[ROBOT][0][None, :], atol=1e-12)
    assert any(r.committed for r in acted.replans) and not any(r.known for r in acted.replans)
    # a known task's replay is not held
    known = test[0]
    planner = ClosedLoopPlanner(model, robot, profile, known.groups[ROBOT][0], 0.3, None, certifier)
    for t, sample in zip(known.t, demo_samples(known, OBSERVE), strict=True):
        planner.step(float(t), sample)
    assert planner.finish().n_committed > 0
