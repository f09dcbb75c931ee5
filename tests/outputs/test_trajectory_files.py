"""Trajectory CSV and ROS JointTrajectory JSON (ipromp_pin.outputs.trajectory_files)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from ipromp_pin.exceptions import DataError
from ipromp_pin.motion.timing import JointLimits, Trajectory, time_path
from ipromp_pin.outputs.trajectory_files import (
    read_trajectory_csv,
    read_trajectory_json,
    write_trajectory_csv,
    write_trajectory_json,
)
from ipromp_pin.robot import load_robot


@pytest.fixture(scope="module")
def traj() -> Trajectory:
    limits = JointLimits.from_robot(load_robot("baxter_left"))
    a = np.array([-0.839, -0.969, 0.377, 1.262, -0.204, 1.189, 1.661])
    b = np.array([-1.5, -0.498, 0.38, 0.64, -0.49, 0.946, 1.274])
    q = a + np.linspace(0, 1, 40)[:, None] * (b - a)
    return time_path(q, limits, rate_hz=100.0)[0]


def test_csv_round_trip_is_exact(traj, tmp_path):
    path = write_trajectory_csv(traj, tmp_path / "traj.csv")
    with open(path) as fh:
        header = next(csv.reader(fh))
    assert header[0] == "time_s" and header[1] == "q.left_s0" and header[8] == "qd.left_s0"
    assert header[-1] == "qdd.left_w2" and len(header) == 1 + 3 * 7
    back = read_trajectory_csv(path)
    assert back.joint_names == traj.joint_names
    for name in ("t_s", "q", "qd", "qdd"):
        np.testing.assert_array_equal(getattr(back, name), getattr(traj, name))


def test_json_is_ros_joint_trajectory_and_round_trips(traj, tmp_path):
    path = write_trajectory_json(traj, tmp_path / "traj.json")
    doc = json.loads(path.read_text())
    assert set(doc) == {"format", "version", "ros", "type", "message"}
    msg = doc["message"]
    assert set(msg) == {"header", "joint_names", "points"}
    assert msg["joint_names"] == list(traj.joint_names)
    p = msg["points"][-1]
    assert set(p) >= {"positions", "velocities", "accelerations", "time_from_start"}
    t = p["time_from_start"]
    assert isinstance(t["sec"], int) and 0 <= t["nanosec"] < 1_000_000_000
    assert t["sec"] + t["nanosec"] * 1e-9 == pytest.approx(traj.t_s[-1], abs=1e-9)
    back = read_trajectory_json(path)
    np.testing.assert_allclose(back.t_s, traj.t_s, atol=1e-9, rtol=0)
    for name in ("q", "qd", "qdd"):
        np.testing.assert_array_equal(getattr(back, name), getattr(traj, name))


def test_bad_files_fail_clearly(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,q.a,qd.b,qdd.a\n0,1,2,3\n")
    with pytest.raises(DataError, match="same joints"):
        read_trajectory_csv(bad)
    bad.write_text("time,q.a\n")
    with pytest.raises(DataError, match="time_s"):
        read_trajectory_csv(bad)
    bad_json = tmp_path / "bad.json"
    bad_json.write_text(json.dumps({"joint_names": ["a"], "points": [{"positions": [0.0]}]}))
    with pytest.raises(DataError, match="time_from_start"):
        read_trajectory_json(bad_json)
    with pytest.raises(DataError, match="NaN"):
        write_trajectory_csv(
            Trajectory(np.arange(2.0), np.full((2, 1), np.nan), np.zeros((2, 1)), np.zeros((2, 1)), ("a",)),
            tmp_path / "x.csv",
        )
