"""Tests of ipromp_pin.synthetic: realistic hand-over demos with known ground truth."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin import synthetic
from ipromp_pin.data import ROBOT
from ipromp_pin.exceptions import DataError
from ipromp_pin.readers import BAXTER_LEFT_JOINTS
from ipromp_pin.synthetic import make_synthetic_dataset, true_alpha


@pytest.fixture(scope="module")
def ds():
    return make_synthetic_dataset()


def test_shape_names_and_determinism(ds):
    assert ds.tasks == ["rod", "wrench", "tape"]
    assert all(len(v) == 20 for v in ds.demos.values())
    d = ds.demos["rod"][0]
    assert d.channel_names["orientation"] == ("qw", "qx", "qy", "qz")
    assert d.channel_names["emg"] == tuple(f"emg{i}" for i in range(8))
    assert d.channel_names[ROBOT] == BAXTER_LEFT_JOINTS
    assert d.extras["hand_position"].shape == (d.n_samples, 3)
    assert np.allclose(np.diff(d.t), 0.02) and d.t[0] == 0.0
    again = make_synthetic_dataset()
    other = make_synthetic_dataset(seed=1)
    for a, b in zip(ds.all_demos(), again.all_demos(), strict=True):
        for g in a.groups:
            np.testing.assert_array_equal(a.groups[g], b.groups[g])
    assert not np.allclose(ds.demos["rod"][0].groups["emg"][:5], other.demos["rod"][0].groups["emg"][:5])
    five = make_synthetic_dataset(n_tasks=5, n_demos=2, rate_hz=100.0)
    assert len(five.tasks) == 5 and np.allclose(np.diff(five.demos["task4"][0].t), 0.01)


def test_durations_and_ground_truth_alpha(ds):
    durations = np.array([d.duration_s for d in ds.all_demos()])
    assert durations.min() >= 2.5 - 0.02 and durations.max() <= 4.2 + 0.02
    assert durations.std() > 0.3  # really random
    for d in ds.all_demos():
        assert true_alpha(d) == pytest.approx(d.duration_s / synthetic.NOMINAL_DURATION_S)
        assert d.duration_s == pytest.approx(d.t[-1])
        # Signals are functions of the phase: the robot stops moving near the end of every demo.
        assert np.abs(d.groups[ROBOT][-1] - d.groups[ROBOT][int(0.92 * d.n_samples)]).max() < 1e-6
    assert synthetic.nominal_duration_s == synthetic.NOMINAL_DURATION_S


def test_robot_is_feasible_smooth_and_task_specific(ds):
    lo, hi = synthetic.BAXTER_LEFT_LIMITS_RAD.T
    ends = {}
    for task, demos in ds.demos.items():
        ends[task] = np.array([d.groups[ROBOT][-1] for d in demos])
        for d in demos:
            q = d.groups[ROBOT]
            assert np.all(q > lo) and np.all(q < hi)
            qd = np.diff(q, axis=0) / d.dt
            assert np.abs(qd).max() < 1.5  # Baxter's shoulder/elbow velocity limit [rad/s]
            qdd = np.diff(qd, axis=0) / d.dt
            assert np.abs(qdd).max() < 5.0
            np.testing.assert_allclose(q[0], synthetic.START_Q_RAD, atol=0.03)
            np.testing.assert_allclose(np.abs(qd[:2]).max(), 0.0, atol=0.05)  # starts at rest
    for k, task in enumerate(ds.tasks):
        np.testing.assert_allclose(np.median(ends[task], axis=0), synthetic.HANDOVER_Q_RAD[k], atol=0.15)
    # Hand-over poses differ between tasks more than within (e.g. the last wrist joint).
    assert abs(np.median(ends["rod"][:, 6]) - np.median(ends["wrench"][:, 6])) > 0.3


def test_motion_barely_separates_tasks_but_emg_does(ds):
    def at_phase(task, group, phase=0.1):
        return np.array([d.groups[group][int(phase * (d.n_samples - 1))] for d in ds.demos[task]])

    def separation(group):
        a, b = at_phase("rod", group), at_phase("tape", group)
        spread = 0.5 * (a.std(axis=0) + b.std(axis=0))
        return np.max(np.abs(a.mean(axis=0) - b.mean(axis=0)) / spread)

    assert separation("orientation") < 1.5
    assert separation("emg") > 3.0
    for d in ds.all_demos():
        np.testing.assert_allclose(np.linalg.norm(d.groups["orientation"], axis=1), 1.0, atol=1e-9)
        assert np.all(d.groups["emg"] > 0)


def test_hand_ends_at_the_robot_handover_point(ds):
    for k, task in enumerate(ds.tasks):
        for d in ds.demos[task]:
            hand = d.extras["hand_position"]
            assert np.linalg.norm(hand[-1] - synthetic.HANDOVER_POINT_M[k]) < 0.2
            assert np.linalg.norm(hand[0] - synthetic.HANDOVER_POINT_M[k]) > 0.4


def test_noise_free_demos_follow_the_nominal_path():
    clean = make_synthetic_dataset(n_tasks=2, n_demos=3, noise=0.0)
    a, b = clean.demos["rod"][:2]
    np.testing.assert_allclose(a.groups[ROBOT][-1], b.groups[ROBOT][-1])
    np.testing.assert_allclose(a.groups["orientation"][-1], b.groups["orientation"][-1], atol=1e-9)


@pytest.mark.parametrize(
    ("kw", "field"),
    [
        ({"n_tasks": 0}, "n_tasks"),
        ({"n_demos": 1}, "n_demos"),
        ({"rate_hz": 0.0}, "rate_hz"),
        ({"noise": -1}, "noise"),
    ],
)
def test_bad_arguments(kw, field):
    with pytest.raises(DataError, match=field):
        make_synthetic_dataset(**kw)
