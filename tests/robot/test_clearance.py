"""Certified self-collision clearance: the per-pair bound is sound, free paths certify, collisions fail."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import load_robot
from ipromp_pin.robot.clearance import ClearanceCertifier, pair_weights
from ipromp_pin.robot.collision import in_collision


@pytest.fixture(scope="module")
def robot():
    return load_robot("baxter_left")


def _distances(robot, q: np.ndarray) -> np.ndarray:
    """Distance of every active pair at arm configuration q (brute force)."""
    model, data, cmodel, cdata = robot.model, robot.data, robot.collision_model, robot.collision_data
    pin.forwardKinematics(model, data, robot.full_configuration(q))
    pin.updateGeometryPlacements(model, data, cmodel, cdata)
    return np.array([pin.computeDistance(cmodel, cdata, int(k)).min_distance for k in robot.active_pair_ids])


def test_pair_bound_is_sound(robot):
    """d_p(q') >= d_p(q) - sum_k w_pk |q'_k - q_k| for random nearby configurations."""
    w = pair_weights(robot)
    assert w.shape == (robot.active_pair_ids.size, robot.n_joints)
    assert np.all(w >= 0) and np.all(w.sum(axis=1) > 0)  # every active pair is moved by some arm joint
    rng = np.random.default_rng(0)
    q0 = make_synthetic_dataset(n_tasks=1, n_demos=2, seed=0).all_demos()[0].groups["robot"]
    worst = np.inf
    for _ in range(6):
        a = q0[rng.integers(q0.shape[0])]
        b = np.clip(a + rng.normal(0, 0.15, a.size), robot.lower_rad, robot.upper_rad)
        da, db = _distances(robot, a), _distances(robot, b)
        bound = da - w @ np.abs(b - a)
        worst = min(worst, float(np.min(db - bound)))
    assert worst >= -1e-6


def test_free_motion_is_certified_and_reused(robot):
    demo = make_synthetic_dataset(n_tasks=1, n_demos=2, seed=1).all_demos()[0]
    q = demo.groups["robot"]
    cert = ClearanceCertifier(robot)
    first = cert.certify(q)
    assert first.certified and not first.collision and first.n_distances > 0
    # the reported closest distance is a real distance near the path
    dense = np.array([_distances(robot, x).min() for x in q[::10]])
    assert first.min_distance_m == pytest.approx(dense.min(), abs=0.02)
    again = cert.certify(q + 1e-4)  # nearly the same path: the cached balls certify it
    assert again.certified and again.n_distances < first.n_distances / 10


def test_a_motion_through_a_collision_is_refused(robot):
    rng = np.random.default_rng(2)
    lo, hi = robot.lower_rad + 0.01, robot.upper_rad - 0.01
    samples = rng.uniform(lo, hi, (400, robot.n_joints))
    hits = in_collision(robot, samples)
    free = samples[~hits][0]
    bad = samples[hits][0]
    path = np.linspace(free, bad, 60)
    result = ClearanceCertifier(robot).certify(path)
    assert not result.certified


def test_the_kept_pair_labels_are_the_robots(robot):
    cert = ClearanceCertifier(robot)
    for pid in [int(k) for k in robot.active_pair_ids[:5]] * 2:  # the second time from the kept ones
        assert cert.pair_labels(pid) == (robot.pair_names(pid), robot.pair_links(pid))
    demo = make_synthetic_dataset(n_tasks=1, n_demos=2, seed=1).all_demos()[0]
    result = cert.certify(demo.groups["robot"])
    pid = next(int(k) for k in robot.active_pair_ids if robot.pair_names(int(k)) == result.pair)
    assert result.links == robot.pair_links(pid)


def test_in_collision_equals_every_active_pair_tested(robot):
    """The broad phase only skips pairs that cannot touch: the same answer as testing every active
    pair, on random configurations of which many collide."""
    rng = np.random.default_rng(7)
    samples = rng.uniform(robot.lower_rad, robot.upper_rad, (600, robot.n_joints))
    model, data, cmodel, cdata = robot.model, robot.data, robot.collision_model, robot.collision_data
    brute = np.array(
        [
            pin.computeCollisions(model, data, cmodel, cdata, row, True)
            for row in robot.full_configuration(samples)
        ]
    )
    assert 50 < brute.sum() < 550  # both answers are exercised
    np.testing.assert_array_equal(in_collision(robot, samples), brute)
    assert not in_collision(robot, samples[~brute][:1])[0] and in_collision(robot, samples[brute][:1])[0]
