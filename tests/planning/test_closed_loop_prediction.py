"""One prediction path: the closed loop's re-plans predict as the one-shot plan does (the hand-over
regression and the orientation estimate applied after the conditioning on the samples)."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.exceptions import PipelineError
from ipromp_pin.motion.limits import conservative_profile
from ipromp_pin.planning.closed_loop import (
    CONDITION_NOISE,
    ClosedLoopPlanner,
    ClosedLoopSettings,
    demo_samples,
    start_time,
)
from ipromp_pin.promp import IProMP
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import gripper_kinematics, load_robot
from ipromp_pin.safety import CheckSuite

OBSERVE = ["orientation", "emg"]


@pytest.fixture(scope="module")
def setup():
    """A model with a hand-over regression and an orientation estimate (fitted with the robot's
    kinematics, as the evaluation and ``train`` fit it) and held-out demos."""
    ds = make_synthetic_dataset(n_tasks=3, n_demos=10, seed=3)
    train = [d for demos in ds.demos.values() for d in demos[:-1]]
    test = [demos[-1] for demos in ds.demos.values()]
    robot = load_robot("baxter_left")
    fk, fk_rot = gripper_kinematics(robot)
    model = IProMP(observe=OBSERVE).fit(train, fk=fk, fk_rot=fk_rot)
    # both estimates kept by their cross-validation: otherwise the test below would say nothing
    assert model.handover_ is not None and model.orientation_ is not None
    suite = CheckSuite.build(robot, ["speed_limits", "joint_limits"])
    return model, robot, test, suite


def _replans(model, robot, demo, suite, noise, n_replans, estimates=True):
    """Run the closed loop on ``demo`` until ``n_replans`` re-plans -> (re-plan, its prediction) each."""
    settings = ClosedLoopSettings(condition_noise=noise, handover_estimates=estimates)
    start = start_time(demo, settings, float(model.duration_nominal_s_))
    q_start = demo.groups[model.robot_group][0]
    out = []
    with ClosedLoopPlanner(
        model, robot, conservative_profile(robot), q_start, start, settings, suite
    ) as planner:
        for t, sample in zip(demo.t - demo.t[0], demo_samples(demo, OBSERVE), strict=True):
            r = planner.step(float(t), sample)
            if r is not None:
                out.append((r, planner.prediction))
                if len(out) == n_replans:
                    break
    return out


def _same(a, b):
    assert a.task == b.task
    assert a.duration_s == pytest.approx(b.duration_s, rel=1e-9)
    assert np.allclose(a.q_mean, b.q_mean, rtol=1e-8, atol=1e-9)
    assert np.allclose(a.q_cov, b.q_cov, rtol=1e-7, atol=1e-12)


@pytest.mark.parametrize("which", [0, 1, 2])
def test_the_closed_loops_plans_are_the_one_shot_prediction_of_the_same_samples(setup, which):
    model, robot, test, suite = setup
    demo = test[which]
    replans = _replans(model, robot, demo, suite, None, 4)
    assert len(replans) == 4
    for r, pred in replans:
        observed = demo.slice(r.n_observed, OBSERVE)
        one = model.predict(observed)  # what run and plan() predict from these samples
        _same(pred, one)
    # the estimates change the prediction (without them the closed loop predicted something else)
    r, pred = replans[0]
    parts, _ = model.predictor_.encode(demo.slice(r.n_observed, OBSERVE))
    raw = model.predictor_.conditioner.condition(model.recognise(demo.slice(r.n_observed, OBSERVE)), parts)
    assert np.max(np.abs(raw.q_mean[-1] - pred.q_mean[-1])) > 1e-4


def test_with_its_own_noise_the_closed_loop_applies_the_same_estimates(setup):
    # the closed loop's conditioning noise changes the conditioning only: the estimates follow it as
    # the one-shot predictor of that noise applies them
    model, robot, test, suite = setup
    demo = test[1]
    predictor = model.predictor_.with_condition_noise(CONDITION_NOISE)
    for r, pred in _replans(model, robot, demo, suite, CONDITION_NOISE, 3):
        parts, t_last = predictor.encode(demo.slice(r.n_observed, OBSERVE))
        _same(pred, predictor.predict(parts, t_last))


def test_stream_predict_without_estimates_is_the_conditioning_alone(setup):
    model, _, test, _ = setup
    demo = test[2]
    n = demo.n_samples // 3
    observed = demo.slice(n, OBSERVE)
    with model.stream() as stream:
        for t, sample in zip(observed.t, demo_samples(observed, OBSERVE), strict=True):
            stream.update(float(t), sample)
        parts, _ = stream.parts()
        raw = model.predictor_.conditioner.condition(stream.recognition(), parts)
        bare = stream.predict(estimates=False)
        assert np.array_equal(bare.q_mean, raw.q_mean) and np.array_equal(bare.q_cov, raw.q_cov)
        _same(stream.predict(), model.predict(observed))
        _same(stream.predict(), stream.prediction())


def test_by_default_the_closed_loop_conditions_on_the_samples_alone(setup):
    # the measured better choice (docs/closed_loop.md): the estimates are a setting, off by default
    model, robot, test, suite = setup
    demo = test[0]
    assert ClosedLoopSettings().handover_estimates is False
    predictor = model.predictor_.with_condition_noise(CONDITION_NOISE)
    ((r, pred),) = _replans(model, robot, demo, suite, CONDITION_NOISE, 1, estimates=False)
    observed = demo.slice(r.n_observed, OBSERVE)
    parts, _ = predictor.encode(observed)
    _same(pred, predictor.conditioner.condition(model.recognise(observed), parts))
    with pytest.raises(PipelineError, match="handover_estimates"):
        ClosedLoopSettings(handover_estimates="yes").validate()  # type: ignore[arg-type]
