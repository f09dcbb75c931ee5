"""Time parameterisation (toppra) and jerk-limited smoothing (ruckig) (ipromp_pin.motion.timing);
absurd limits refused before allocating."""

from __future__ import annotations

import dataclasses
import socket

import numpy as np
import pytest

from ipromp_pin.exceptions import InfeasibleError
from ipromp_pin.motion.path import MAX_TRAJECTORY_SAMPLES, path_deviation, prepare_path
from ipromp_pin.motion.timing import time_path, verify_trajectory
from ipromp_pin.motion.tracking import reachable_target
from ipromp_pin.motion.trajectory import JointLimits
from ipromp_pin.robot import load_robot

Q_START = np.array([-0.839, -0.969, 0.377, 1.262, -0.204, 1.189, 1.661])
Q_HANDOVER = np.array([-1.5, -0.498, 0.38, 0.64, -0.49, 0.946, 1.274])


@pytest.fixture(scope="module")
def limits():
    return JointLimits.from_robot(load_robot("baxter_left"))


def _curved_path(m=100, noise=0.0, seed=0):
    """A smooth curved hand-over-like path (a detour through a third pose)."""
    s = np.linspace(0, 1, m)[:, None]
    mid = np.array([-1.2, -0.5, 0.9, 1.4, -0.3, 1.3, 1.5])
    q = (1 - s) ** 2 * Q_START + 2 * s * (1 - s) * mid + s**2 * Q_HANDOVER
    return q + np.random.default_rng(seed).normal(0, noise, q.shape)


def _assert_within_limits(traj, limits, tol=1e-6):
    assert np.all(traj.q >= limits.lower_rad - 1e-12) and np.all(traj.q <= limits.upper_rad + 1e-12)
    assert np.max(np.abs(traj.qd) / limits.velocity_rad_s) <= 1 + tol
    assert np.max(np.abs(traj.qdd) / limits.acceleration_rad_s2) <= 1 + tol
    jerk = np.diff(traj.qdd, axis=0) / np.diff(traj.t_s)[:, None]
    assert np.max(np.abs(jerk) / limits.jerk_rad_s3) <= 1 + tol


@pytest.mark.parametrize("noise", [0.0, 0.003])
def test_trajectory_respects_all_limits_at_every_sample(limits, noise):
    q = _curved_path(noise=noise)
    traj, rep = time_path(q, limits, rate_hz=100.0)
    _assert_within_limits(traj, limits)
    assert rep.passed, rep.to_text()
    np.testing.assert_allclose(np.diff(traj.t_s), 0.01, atol=1e-12)
    np.testing.assert_allclose(traj.q[0], q[0], atol=1e-12)
    np.testing.assert_allclose(traj.q[-1], q[-1], atol=1e-9)  # ends at the hand-over
    assert np.all(traj.qd[-1] == 0) and np.all(traj.qd[0] == 0)  # rest to rest
    assert rep.path_deviation_rad < 0.02  # reported, bounded by the smoothing
    # noise of a few mrad must not stretch the duration several-fold
    _, clean = time_path(_curved_path(), limits)
    assert rep.duration_s < 2.5 * clean.duration_s
    d = rep.to_dict()
    assert d["passed"] and d["velocity_ratio"] == rep.velocity_ratio


def test_straight_path_is_followed_exactly(limits):
    q = np.linspace(Q_START, Q_HANDOVER, 50)
    traj, rep = time_path(q, limits, smooth_rad=0.0)
    assert rep.path_deviation_rad < 1e-6  # the motion is c(s(t)): on the path by construction
    assert rep.passed


def test_other_control_rate_and_moving_start_state(limits):
    q = _curved_path()
    qd0 = np.array([0.2, -0.1, 0.0, 0.1, 0.0, 0.0, 0.05])
    traj, rep = time_path(q, limits, rate_hz=250.0, start_q=q[0] + 0.02, start_qd=qd0)
    np.testing.assert_allclose(np.diff(traj.t_s), 0.004, atol=1e-12)
    np.testing.assert_allclose(traj.q[0], q[0] + 0.02)
    np.testing.assert_allclose(traj.qd[0], qd0)
    _assert_within_limits(traj, limits)
    assert rep.passed


def test_duplicate_and_stationary_points_are_cleaned(limits):
    q = _curved_path(60)
    q = np.vstack([np.repeat(q[:1], 10, axis=0), q, np.repeat(q[-1:], 10, axis=0)])
    s, pts = prepare_path(q, limits)
    assert np.all(np.diff(s) > 0)
    traj, rep = time_path(q, limits)
    assert rep.passed


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda q: np.repeat(q[:1], 20, axis=0), "zero length"),
        (lambda q: q[:1], "at least 2"),
        (lambda q: np.where(np.arange(len(q))[:, None] == 7, np.nan, q), "NaN"),
        (lambda q: q + np.array([0, 0, 0, -3.0, 0, 0, 0]), "left_e1.*outside its limits"),
        (lambda q: q[:, :6], "shape"),
    ],
)
def test_infeasible_paths_raise(limits, make, message):
    with pytest.raises(InfeasibleError, match=message):
        time_path(make(_curved_path()), limits)


def test_infeasible_start_state_raises(limits):
    q = _curved_path()
    with pytest.raises(InfeasibleError, match="velocity"):
        time_path(q, limits, start_qd=np.full(7, 10.0))
    with pytest.raises(InfeasibleError, match="start state.*outside"):
        time_path(q, limits, start_q=np.full(7, 3.0))
    with pytest.raises(InfeasibleError, match="NaN"):
        time_path(q, limits, start_qdd=np.full(7, np.nan))


def test_bad_limits_raise():
    with pytest.raises(InfeasibleError, match="positive"):
        JointLimits(np.zeros(2) - 1, np.ones(2), np.ones(2), np.array([1.0, 0.0]), np.ones(2), ("a", "b"))
    with pytest.raises(InfeasibleError, match="lower limit"):
        JointLimits(np.ones(2), np.zeros(2), np.ones(2), np.ones(2), np.ones(2), ("a", "b"))


def test_verification_catches_violations(limits):
    traj, _ = time_path(_curved_path(), limits)
    traj.qd = traj.qd * 10.0
    rep = verify_trajectory(traj, limits, _curved_path())
    assert rep.velocity_ratio > 1 and not rep.passed
    assert path_deviation(np.array([[0.0, 1.0]]), np.array([[0.0, 0.0], [1.0, 0.0]]))[0] == pytest.approx(1.0)


def test_no_network_access_during_smoothing(limits, monkeypatch):
    """ruckig's community build tries a cloud service for intermediate waypoints; we never ask for
    them, and nothing in timing may open a socket."""
    attempts = []

    def refuse(*args, **kwargs):
        attempts.append(args)
        raise OSError("network access attempted")

    monkeypatch.setattr(socket, "socket", refuse)
    monkeypatch.setattr(socket, "create_connection", refuse)
    monkeypatch.setattr(socket, "getaddrinfo", refuse)
    traj, rep = time_path(_curved_path(noise=0.002), limits, start_qd=np.full(7, 0.05))
    assert rep.passed and not attempts


def test_reachable_target_never_implies_exceeding_the_velocity_limit():

    rng = np.random.default_rng(0)
    for _ in range(2000):
        v_max, a_max, j_max = rng.uniform(0.2, 2.0), rng.uniform(0.5, 3.0), rng.uniform(1.0, 20.0)
        v, a = reachable_target(rng.uniform(-0.5, 3.0), rng.uniform(-4, 4), v_max, a_max, j_max)
        assert 0.0 <= v <= v_max and abs(a) <= a_max
        assert v + a * a / (2 * j_max) <= v_max  # both when accelerating and decelerating
        if a < 0:
            assert v - a * a / (2 * j_max) >= 0.0


def test_predicted_paths_of_a_model_are_all_timed_within_limits():
    """Regression: smooth predicted paths once made ruckig reject a target state (velocity overshoot)."""
    from ipromp_pin.promp import IProMP
    from ipromp_pin.readers.synthetic import make_synthetic_dataset

    ds = make_synthetic_dataset(n_demos=12, seed=1)
    demos = ds.all_demos()
    model = IProMP(observe=["orientation", "emg"], noise=10.0).fit(demos[::2])
    robot = load_robot("baxter_left")
    limits = JointLimits.from_robot(robot)
    for demo in demos[1::2]:
        prediction = model.predict(demo.head(0.2, groups=["orientation", "emg"]))
        _, report = time_path(prediction.q_mean, limits)
        assert report.passed, report.to_text()


def test_absurd_limits_are_refused_before_allocating():
    names = tuple(f"j{i}" for i in range(3))
    limits = JointLimits(
        lower_rad=np.full(3, -3.0),
        upper_rad=np.full(3, 3.0),
        velocity_rad_s=np.full(3, 1e-9),
        acceleration_rad_s2=np.ones(3),
        jerk_rad_s3=np.full(3, 10.0),
        joint_names=names,
    )
    path = np.linspace([0.0, 0.0, 0.0], [1.0, -1.0, 0.5], 50)
    with pytest.raises(InfeasibleError, match=f"at least 1e\\+09 s .*more than {MAX_TRAJECTORY_SAMPLES}"):
        time_path(path, limits, rate_hz=100.0)
    slow = dataclasses.replace(limits, velocity_rad_s=np.full(3, 1.0), acceleration_rad_s2=np.full(3, 1e-12))
    with pytest.raises(InfeasibleError, match="acceleration 1e-12"):
        time_path(path, slow, rate_hz=100.0)


def test_a_path_velocity_cap_slows_only_that_part_of_the_path(limits):
    q = _curved_path()
    free, rep_free = time_path(q, limits)
    assert rep_free.path_s is not None and rep_free.path_sd is not None
    assert rep_free.path_s.shape == (free.n_samples,) and np.all(np.diff(rep_free.path_s) >= -1e-3)
    assert "path_s" not in rep_free.to_dict() and "path_sd" not in rep_free.to_dict()
    length = float(rep_free.path_s[-1])
    lo, hi, cap = 0.4 * length, 0.6 * length, 0.5 * float(rep_free.path_sd.max())

    def sd_cap(grid: np.ndarray) -> np.ndarray:
        return np.where((grid >= lo) & (grid <= hi), cap, np.inf)

    traj, rep = time_path(q, limits, sd_cap=sd_cap)
    _assert_within_limits(traj, limits)
    assert rep.passed and free.duration_s < traj.duration_s
    inside = (rep.path_s > lo + 0.02 * length) & (rep.path_s < hi - 0.02 * length)
    assert inside.any() and np.all(rep.path_sd[inside] <= cap * 1.02)
    # the joint velocities follow the path velocity: q' = c'(s) sdot
    np.testing.assert_allclose(traj.q[-1], q[-1], atol=1e-9)
    # a cap nowhere on the path changes nothing
    same, _ = time_path(q, limits, sd_cap=lambda grid: np.full(grid.size, np.inf))
    np.testing.assert_allclose(same.q, free.q, atol=1e-9)
