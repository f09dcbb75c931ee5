"""One-shot evaluation cells: ``peak_torque_ratio`` of the one-shot plans with the true task's object,
only when objects are in use (the cells are otherwise as before)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ipromp_pin.evaluation.evaluate import EvaluationConfig, evaluate
from ipromp_pin.evaluation.scorers.one_shot import predict_window
from ipromp_pin.evaluation.scoring import one_shot_peak_torque_ratio, peak_torque_ratio
from ipromp_pin.motion.timing import time_path
from ipromp_pin.motion.trajectory import JointLimits
from ipromp_pin.promp import IProMP
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import load_robot
from ipromp_pin.robot.objects import TaskObject, load_objects
from ipromp_pin.safety import CheckContext, CheckSuite


@pytest.fixture(scope="module")
def synthetic():
    return make_synthetic_dataset(n_tasks=2, n_demos=8, seed=4)


def test_one_shot_cells_get_the_peak_torque_ratio_only_with_objects(synthetic):
    cfg = EvaluationConfig(protocol="paper", observe=[["orientation", "emg"]], grid=[(5, 0.3)], n_test=3)
    plain = evaluate(synthetic, cfg, robot="baxter_left")
    with_objects = evaluate(synthetic, cfg, robot="baxter_left", objects=load_objects())
    assert all(c.peak_torque_ratio is None for c in plain)
    assert all("peak_torque_ratio" not in t for c in plain for t in c.trials)
    for a, b in zip(plain, with_objects, strict=True):
        assert b.peak_torque_ratio is not None and 0.05 < b.peak_torque_ratio < 2.0
        peaks = [t["peak_torque_ratio"] for t in b.trials]
        assert b.peak_torque_ratio == pytest.approx(max(peaks))
        # everything else is the same cell
        strip = [{k: v for k, v in t.items() if k != "peak_torque_ratio"} for t in b.trials]
        assert strip == a.trials
        assert dataclasses.replace(b, peak_torque_ratio=None, trials=a.trials) == a


def test_the_one_shot_peak_is_the_checks_on_the_timed_plan_with_the_true_object(synthetic):
    robot = load_robot("baxter_left")
    objects = load_objects()
    train = [d for demos in synthetic.demos.values() for d in demos[:5]]
    demo = synthetic.demos["rod"][6]
    model = IProMP(observe=["orientation", "emg"]).fit(train)
    prediction = predict_window(model, demo, 0.3, ["orientation", "emg"])
    suite = CheckSuite.build(robot, ["joint_torques"])
    check = suite.get("joint_torques")
    got = one_shot_peak_torque_ratio(suite, robot, prediction, "rod", objects)
    # timed as run times it first: under the recognised task's torque limits, from the observation's end
    torque = suite.timing_constraints(CheckContext(task=prediction.task, objects=objects)).torque
    limits = JointLimits.from_robot(robot)
    trajectory, _ = time_path(prediction.q_mean, limits, torque=torque, start_s=prediction.observed_until_s)
    expected = check.check(trajectory, CheckContext(task="rod", objects=objects)).measures.peak_torque_ratio
    assert got == pytest.approx(expected)
    assert got == pytest.approx(peak_torque_ratio(suite, trajectory.shifted(-1.0), "rod", objects))
    # a heavier true object: a higher peak (the rod is received: it joins at the hand-over, at rest)
    heavy = TaskObject("rod", 3.0, np.array([0.0, 0.0, 0.05]), np.eye(3) * 1e-3, "robot_receives")
    table = dataclasses.replace(objects, objects={**objects.objects, "rod": heavy})
    assert peak_torque_ratio(suite, trajectory, "rod", table) > got + 0.02
