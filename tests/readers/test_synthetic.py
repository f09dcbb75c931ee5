"""Tests of ipromp_pin.readers.synthetic: realistic hand-over demos with known ground truth."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ipromp_pin.data import ROBOT
from ipromp_pin.exceptions import DataError
from ipromp_pin.readers import BAXTER_LEFT_JOINTS, synthetic
from ipromp_pin.readers.synthetic import handover_offset, make_synthetic_dataset, true_alpha


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
    low, high = synthetic.DURATION_RANGE_S
    assert durations.min() >= low - 0.02 and durations.max() <= high + 0.02
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
    # Hand-over poses differ between tasks more than within, in some joint (as in handover_20171128,
    # where the three tasks' hand-overs lie a few centimetres apart).
    for a, b in (("rod", "wrench"), ("rod", "tape"), ("wrench", "tape")):
        spread = 0.5 * (ends[a].std(axis=0) + ends[b].std(axis=0))
        assert (np.abs(np.median(ends[a], axis=0) - np.median(ends[b], axis=0)) / spread).max() > 0.8


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
            hand, offset = d.extras["hand_position"], handover_offset(d)
            np.testing.assert_array_equal(d.extras["handover_offset"], np.tile(offset, (d.n_samples, 1)))
            target = synthetic.HANDOVER_POINT_M[k] + offset + synthetic.HAND_FROM_GRIPPER_M
            assert np.linalg.norm(hand[-1] - target) < 0.05
            assert np.linalg.norm(hand[0] - synthetic.HANDOVER_POINT_M[k]) > 0.4


def test_handover_offset_has_the_real_spread_and_moves_the_gripper(ds):
    from ipromp_pin.robot import ee_positions, load_robot

    offsets = np.array([handover_offset(d) for d in ds.all_demos()])
    np.testing.assert_allclose(offsets.std(axis=0), synthetic.HANDOVER_OFFSET_STD_M, rtol=0.35)
    # the robot's gripper goes (to first order) where the human's hand goes
    robot = load_robot("baxter_left")
    err = []
    for k, task in enumerate(ds.tasks):
        nominal = ee_positions(robot, synthetic.HANDOVER_Q_RAD[k][None])[0]
        for d in ds.demos[task]:
            err.append(
                np.linalg.norm(ee_positions(robot, d.groups[ROBOT][-1:])[0] - nominal - handover_offset(d))
            )
    assert np.median(err) < 0.02 and np.quantile(err, 0.9) < 0.06
    h, n = synthetic.offset_maps(
        synthetic.HANDOVER_JACOBIAN_M_PER_RAD[0], synthetic.HANDOVER_REGRESSION_RAD_PER_M[0]
    )
    np.testing.assert_allclose(synthetic.HANDOVER_JACOBIAN_M_PER_RAD[0] @ h, np.eye(3), atol=1e-9)
    np.testing.assert_allclose(synthetic.HANDOVER_JACOBIAN_M_PER_RAD[0] @ n, 0.0, atol=1e-9)
    with pytest.raises(DataError, match="handover_offset"):
        handover_offset(dataclasses.replace(d, extras={}))


def _conditioning_errors(coupling: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Final-configuration errors [rad] (conditioned, prior) on held-out demos, and recognition accuracy."""
    from ipromp_pin.promp import IProMP

    # 15 training demos per task; 25 held out per task (the median over 5 varies by +-0.15 between seeds)
    data = make_synthetic_dataset(n_demos=40, seed=0, coupling=coupling)
    train = [d for demos in data.demos.values() for d in demos[:15]]
    test = [d for demos in data.demos.values() for d in demos[15:]]
    model = IProMP(observe=["orientation", "emg"], noise=10.0).fit(train)
    cond, prior, hits = [], [], []
    for d in test:
        p = model.predict(d.head(0.2, groups=["orientation", "emg"]))
        cond.append(np.linalg.norm(p.q_mean[-1] - d.groups[ROBOT][-1]))
        prior.append(np.linalg.norm(p.q_prior_mean[-1] - d.groups[ROBOT][-1]))
        hits.append(p.task == d.task)
    return np.array(cond), np.array(prior), float(np.mean(hits))


def test_robot_follows_the_human_so_conditioning_beats_the_prior():
    # the first 20 % of the human's motion reveals the hand-over offset, which moves the robot
    # (measured ratio of the medians 0.66-0.75 over seeds 0-7; 0.95-1.07 without coupling)
    cond, prior, accuracy = _conditioning_errors(coupling=1.0)
    assert accuracy >= 0.9
    assert np.median(cond) < 0.8 * np.median(prior)
    # control: a robot that ignores the offset leaves nothing to learn beyond the task
    cond, prior, accuracy = _conditioning_errors(coupling=0.0)
    assert accuracy >= 0.9
    assert np.median(cond) > 0.85 * np.median(prior)


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
        ({"coupling": -0.5}, "coupling"),
    ],
)
def test_bad_arguments(kw, field):
    with pytest.raises(DataError, match=field):
        make_synthetic_dataset(**kw)
