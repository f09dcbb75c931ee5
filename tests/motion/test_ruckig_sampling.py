"""The vectorised sampling of ruckig trajectories gives ruckig's own ``at_time`` states, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from ruckig import InputParameter, Ruckig, RuckigError, Trajectory

from ipromp_pin.motion.ruckig_sampling import VECTOR_FROM, sample_trajectory

N_DOF = 7


def _at_time(traj: Trajectory, times: np.ndarray) -> list[np.ndarray]:
    out = [traj.at_time(float(t)) for t in times]
    return [np.array([o[i] for o in out]).reshape(len(out), -1) for i in range(3)]


def _random_trajectories(n: int, seed: int) -> list[Trajectory]:
    """State-to-state trajectories as the re-target asks for, and harder ones: start states beyond
    the limits (brake pre-profiles), moving targets, minimum durations."""
    rng = np.random.default_rng(seed)
    otg, inp = Ruckig(N_DOF), InputParameter(N_DOF)
    inp.max_velocity = rng.uniform(0.8, 2.0, N_DOF)
    inp.max_acceleration = rng.uniform(1.5, 4.0, N_DOF)
    inp.max_jerk = rng.uniform(5.0, 30.0, N_DOF)
    out = []
    for i in range(n):
        inp.current_position = rng.normal(size=N_DOF)
        inp.current_velocity = rng.normal(size=N_DOF) * (2.5 if i % 4 == 0 else 0.4)
        inp.current_acceleration = rng.normal(size=N_DOF) * (5.0 if i % 5 == 0 else 0.8)
        inp.target_position = rng.normal(size=N_DOF)
        inp.target_velocity = rng.normal(size=N_DOF) * 0.3 * (i % 2)
        inp.target_acceleration = rng.normal(size=N_DOF) * 0.2 * (i % 3 == 1)
        inp.minimum_duration = float(rng.uniform(0.5, 4.0)) if i % 3 == 0 else None
        traj = Trajectory(N_DOF)
        try:
            otg.calculate(inp, traj)
        except RuckigError:  # an infeasible random target (ruckig raises): draw the next
            continue
        out.append(traj)
    return out


def test_equals_at_time_bit_for_bit() -> None:
    trajs = _random_trajectories(300, seed=3)
    n_brake = sum(any(p.brake.duration > 0 for p in t.profiles[0]) for t in trajs)
    assert len(trajs) > 250 and n_brake > 30  # the brake pre-profiles are exercised
    for traj in trajs:
        # the control grid past the end (held with constant acceleration), and the exact end
        times = np.append(np.arange(0.0, traj.duration + 0.05, 0.005), traj.duration)
        got = sample_trajectory(traj, times)
        for want, have in zip(_at_time(traj, times), got, strict=True):
            assert have.shape == (times.size, N_DOF)
            np.testing.assert_array_equal(have, want)


def test_segment_boundaries_and_brake_ends() -> None:
    """Times exactly at the cumulative segment ends and at the brake's end (the upper bound's ties)."""
    for traj in _random_trajectories(40, seed=4):
        times = [0.0, traj.duration]
        for p in traj.profiles[0]:
            times += list(p.brake.duration + np.cumsum(p.t)) + [p.brake.duration, p.brake.t[0]]
        grid = np.linspace(0.0, traj.duration, VECTOR_FROM)  # enough times for the numpy pass
        times_arr = np.clip(np.concatenate([times, grid]), 0.0, None)
        for want, have in zip(_at_time(traj, times_arr), sample_trajectory(traj, times_arr), strict=True):
            np.testing.assert_array_equal(have, want)


def test_no_times() -> None:
    traj = _random_trajectories(1, seed=5)[0]
    q, qd, qdd = sample_trajectory(traj, np.array([]))
    assert q.size == qd.size == qdd.size == 0


@pytest.mark.parametrize("t", [0.0, 0.37])
def test_single_time(t: float) -> None:
    traj = _random_trajectories(2, seed=6)[-1]
    for want, have in zip(_at_time(traj, np.array([t])), sample_trajectory(traj, np.array([t])), strict=True):
        np.testing.assert_array_equal(have, want)


def test_few_and_many_times_take_their_paths_and_agree(monkeypatch: pytest.MonkeyPatch) -> None:
    """Below VECTOR_FROM times the states come from at_time, from it on from the numpy pass: the
    same states either way."""
    import ipromp_pin.motion.ruckig_sampling as rs

    traj = _random_trajectories(3, seed=8)[-1]
    times = np.linspace(0.0, traj.duration, rs.VECTOR_FROM + 5)
    calls: list[int] = []
    monkeypatch.setattr(rs, "_at_time_loop", lambda tr, t: calls.append(t.size) or _at_time(tr, t))
    many = sample_trajectory(traj, times)
    few = sample_trajectory(traj, times[: rs.VECTOR_FROM - 1])
    assert calls == [rs.VECTOR_FROM - 1]  # only the short request went through at_time
    for a, b in zip(many, few, strict=True):
        np.testing.assert_array_equal(a[: rs.VECTOR_FROM - 1], b)
