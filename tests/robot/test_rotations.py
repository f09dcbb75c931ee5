"""Geodesic angle and chordal mean of rotations (robot/rotations.py), and the orientation fields of an
evaluation trial (the prediction's and the mean-orientation baseline's hand-over orientation errors)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from ipromp_pin.evaluation.scorers.one_shot import OneShotScorer
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import ee_positions, frame_placements, load_robot
from ipromp_pin.robot.rotations import chordal_mean, geodesic_deg


def rot(axis, angle_deg: float) -> np.ndarray:
    return pin.exp3(np.asarray(axis, float) / np.linalg.norm(axis) * np.radians(angle_deg))


def test_geodesic_angle_of_a_known_rotation():
    base = rot([1, 2, 3], 40.0)
    assert geodesic_deg(base, base @ rot([0, 0, 1], 25.0)) == pytest.approx(25.0)
    assert geodesic_deg(base, base @ rot([1, -1, 0], 179.0)) == pytest.approx(179.0, abs=1e-6)
    stacked = geodesic_deg(np.stack([base, base]), np.stack([base, base @ rot([0, 1, 0], 10.0)]))
    np.testing.assert_allclose(stacked, [0.0, 10.0], atol=1e-6)


def test_chordal_mean_of_symmetric_rotations_is_the_middle_one():
    mid = rot([0.3, -1, 0.5], 70.0)
    rots = np.stack(
        [mid @ rot([0, 0, 1], a) for a in (-20.0, 20.0)] + [mid @ rot([1, 0, 0], a) for a in (-5.0, 5.0)]
    )
    mean = chordal_mean(rots)
    assert geodesic_deg(mean, mid) == pytest.approx(0.0, abs=1e-6)
    np.testing.assert_allclose(mean @ mean.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(mean) == pytest.approx(1.0)


def test_trials_carry_the_orientation_error_and_its_baseline():
    robot = load_robot("baxter_left")
    ds = make_synthetic_dataset(n_tasks=2, n_demos=6, seed=3)
    train = [d for demos in ds.demos.values() for d in demos[:-1]]
    test = [demos[-1] for demos in ds.demos.values()]
    scorer = OneShotScorer(
        {"head": False, "handover": False, "coupling": "all"},
        lambda q: ee_positions(robot, q),
        lambda q: frame_placements(robot, q)[1],
    ).fit(train, ["orientation", "emg"])
    trials = scorer.score(test, 0.4)
    for t, d in zip(trials, test, strict=True):
        r_true = frame_placements(robot, d.groups["robot"][-1])[1][0]
        expected = geodesic_deg(scorer.mean_rot_[d.task], r_true)
        assert t.handover_orientation_baseline_deg == pytest.approx(float(expected))
        assert 0.0 <= t.handover_orientation_error_deg < 90.0
    assert set(scorer.mean_rot_) == set(ds.tasks)
