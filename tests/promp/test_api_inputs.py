"""Hostile inputs through the Python API: what ``run`` refuses or warns about, ``predict`` refuses or
warns about too; malformed groups, a duplicated training demo and a malformed goal are one-line
errors, never tracebacks from numpy or Pinocchio nor silently moved predictions."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ipromp_pin.data import Demo
from ipromp_pin.exceptions import DataError, InfeasibleError, ModelError
from ipromp_pin.promp import IProMP
from ipromp_pin.promp.inputs import ObservationWarning
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot.inverse_kinematics import target_placement

OBSERVE = ["orientation", "emg"]


@pytest.fixture(scope="module")
def setup():
    data = make_synthetic_dataset(n_demos=5, seed=3)
    train = [d for task in data.tasks for d in data.demos[task][:-1]]
    model = IProMP(observe=OBSERVE, head=False, handover=False, noise=10.0).fit(train)
    observation = data.demos[data.tasks[0]][-1].head(0.3, groups=model.observe_)
    return model, train, observation


def changed(observation: Demo, group: str, values: object) -> Demo:
    return dataclasses.replace(observation, groups={**observation.groups, group: values})


def test_a_plain_observation_gives_no_warning(setup, recwarn):
    model, _, observation = setup
    model.predict(observation)
    assert not [w for w in recwarn if issubclass(w.category, ObservationWarning)]


@pytest.mark.parametrize(
    ("group", "change"),
    [("emg", lambda v: v / 1000.0), ("orientation", lambda v: np.roll(v, -1, axis=1))],  # units; xyzw
)
def test_an_observation_far_from_the_training_data_warns(setup, group, change):
    model, _, observation = setup
    with pytest.warns(ObservationWarning, match=f"the observed '{group}' lies [\\d.]+ standard deviations"):
        model.predict(changed(observation, group, change(observation.groups[group])))


@pytest.mark.parametrize("scale", [0.0, 0.1, 100.0])
def test_non_unit_quaternions_are_refused(setup, scale):
    model, _, observation = setup
    bad = changed(observation, "orientation", observation.groups["orientation"] * scale)
    with pytest.raises(DataError, match="field 'orientation': implausible"):
        model.predict(bad)


@pytest.mark.parametrize(
    ("values", "problem"),
    [
        ("abc", "must be a numeric"),
        ([[1.0, 2.0], [3.0]], "rows differ in length"),
        (np.array([True, False]), "booleans"),
    ],
)
def test_malformed_groups_are_one_line_errors(values, problem):
    with pytest.raises(DataError, match=f"field 'emg': .*{problem}"):
        Demo("t", "n", "src", np.array([0.0, 1.0]), {"emg": values}, {"emg": ("a",)})


def test_boolean_emg_in_an_observation_is_refused(setup):
    model, _, observation = setup
    with pytest.raises(DataError, match="booleans"):
        model.predict(changed(observation, "emg", observation.groups["emg"] > 50.0))


def test_none_in_a_batch_is_named(setup):
    model, _, observation = setup
    with pytest.raises(ModelError, match="NoneType"):
        model.predict([observation, None])


def test_a_demo_given_twice_is_refused_naming_it(setup):
    _, train, _ = setup
    with pytest.raises(DataError, match=f"holds one recording twice \\('{train[0].name}'"):
        IProMP(observe=OBSERVE, head=False, handover=False, noise=10.0).fit([*train, train[0]])


@pytest.mark.parametrize(
    ("quat", "problem"),
    [([0.0, 0.0, 1.0], "4 values"), ([np.nan, 0.0, 0.0, 1.0], "NaN"), ([0.0, 0.0, 0.0, 0.0], "zero")],
)
def test_a_malformed_goal_quaternion_is_named(quat, problem):
    with pytest.raises(InfeasibleError, match=f"goal orientation: .*{problem}"):
        target_placement(np.array([0.8, 0.2, 0.3]), np.array(quat))
