"""Outputs a ROS user reads as they are: trajectory.json in ROS 2 / ROS 1 form, rosbag2 (MCAP) and ROS 1 bags.

The messages are checked against the message definitions rosbags ships, and the bags are read
back with rosbags' own readers: types, stamps and values.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Nodetype

from ipromp_pin.exceptions import DataError
from ipromp_pin.motion.timing import JointLimits, Trajectory, time_path
from ipromp_pin.outputs.rosbag import (
    TOPIC_CHECKS,
    TOPIC_HANDOVER_POSE,
    TOPIC_JOINT_STATES,
    TOPIC_TRAJECTORY,
    BagContent,
    human_topic,
    write_ros1_bag,
    write_rosbag2,
)
from ipromp_pin.outputs.trajectory_files import read_trajectory_json, trajectory_to_ros, write_trajectory_json
from ipromp_pin.readers.synthetic import make_synthetic_dataset
from ipromp_pin.robot import load_robot

ROS2 = get_typestore(Stores.ROS2_HUMBLE)
ROS1 = get_typestore(Stores.ROS1_NOETIC)


def build_message(store, msgtype: str, value: dict, time_keys: tuple[str, str] = ("sec", "nanosec")):
    """A rosbags message object from a dictionary, strictly: an unknown or missing key raises, as
    ``Message(**d)`` or ``set_message_fields`` do. ``time_keys`` are the dictionary's names of a
    time's seconds and nanoseconds (ROS 1: ``secs``, ``nsecs``)."""
    fields = store.fielddefs[msgtype][1]
    names = [n for n, _ in fields]
    if msgtype in ("builtin_interfaces/msg/Time", "builtin_interfaces/msg/Duration"):
        value = (
            {"sec": value[time_keys[0]], "nanosec": value[time_keys[1]]}
            if set(value) == set(time_keys)
            else value
        )
    if set(value) != set(names):
        raise TypeError(f"{msgtype}: keys {sorted(value)} != fields {sorted(names)}")
    kwargs = {}
    for name, (node, spec) in fields:
        v = value[name]
        if node == Nodetype.NAME:
            kwargs[name] = build_message(store, spec, v, time_keys)
        elif node == Nodetype.SEQUENCE and spec[0][0] == Nodetype.NAME:
            kwargs[name] = [build_message(store, spec[0][1], x, time_keys) for x in v]
        elif node == Nodetype.SEQUENCE and spec[0][1][0] == "float64":
            kwargs[name] = np.asarray(v, dtype=np.float64)
        else:
            kwargs[name] = v
    return store.types[msgtype](**kwargs)


@pytest.fixture(scope="module")
def traj() -> Trajectory:
    limits = JointLimits.from_robot(load_robot("baxter_left"))
    a = np.array([-0.839, -0.969, 0.377, 1.262, -0.204, 1.189, 1.661])
    b = np.array([-1.5, -0.498, 0.38, 0.64, -0.49, 0.946, 1.274])
    q = a + np.linspace(0, 1, 40)[:, None] * (b - a)
    return time_path(q, limits, rate_hz=100.0)[0]


@pytest.fixture(scope="module")
def content(traj) -> BagContent:
    demo = make_synthetic_dataset(n_tasks=1, n_demos=2, seed=3).demos["rod"][0]
    obs = demo.head(0.2, groups=["orientation", "emg", "acc"])
    pose = np.array([0.8, -0.3, 0.2, 0.0, 0.6, 0.0, 0.8])
    plan_s = float(obs.t[-1])  # the robot starts when the observation ends, on the human's clock
    return BagContent(
        traj.shifted(plan_s), plan_s, pose, "base", obs, start_time_ns=1_700_000_000_000_000_000
    )


def test_trajectory_json_is_a_ros2_message_by_default(traj, tmp_path):
    path = write_trajectory_json(traj, tmp_path / "t.json")
    doc = json.loads(path.read_text())
    assert doc["ros"] == 2 and doc["type"] == "trajectory_msgs/msg/JointTrajectory"
    msg = doc["message"]
    assert "seq" not in msg["header"] and set(msg["header"]["stamp"]) == {"sec", "nanosec"}
    # the message builds a ROS 2 JointTrajectory as it is, and serialises
    built = build_message(ROS2, doc["type"], msg)
    back = ROS2.deserialize_cdr(ROS2.serialize_cdr(built, doc["type"]), doc["type"])
    last = back.points[-1]
    assert last.time_from_start.sec + last.time_from_start.nanosec * 1e-9 == pytest.approx(
        traj.t_s[-1], abs=1e-9
    )
    np.testing.assert_array_equal(last.positions, traj.q[-1])
    # the ROS 1 spelling does not
    with pytest.raises(TypeError, match="keys"):
        build_message(ROS2, doc["type"], trajectory_to_ros(traj, ros=1))
    got = read_trajectory_json(path)
    np.testing.assert_allclose(got.t_s, traj.t_s, atol=1e-9, rtol=0)
    np.testing.assert_array_equal(got.qd, traj.qd)


def test_trajectory_json_in_ros1_form_on_request_and_old_files_still_read(traj, tmp_path):
    path = write_trajectory_json(traj, tmp_path / "t1.json", ros=1)
    doc = json.loads(path.read_text())
    assert doc["ros"] == 1 and doc["type"] == "trajectory_msgs/JointTrajectory"
    msg = doc["message"]
    assert msg["header"]["seq"] == 0 and set(msg["points"][0]["time_from_start"]) == {"secs", "nsecs"}
    build_message(ROS1, "trajectory_msgs/msg/JointTrajectory", msg, time_keys=("secs", "nsecs"))
    np.testing.assert_array_equal(read_trajectory_json(path).q, traj.q)
    # a version-1 file: the bare ROS 1 message, no envelope
    old = tmp_path / "old.json"
    old.write_text(json.dumps(msg))
    np.testing.assert_array_equal(read_trajectory_json(old).q, traj.q)
    # a bare ROS 2 message reads too
    bare2 = tmp_path / "bare2.json"
    bare2.write_text(json.dumps(trajectory_to_ros(traj)))
    np.testing.assert_allclose(read_trajectory_json(bare2).t_s, traj.t_s, atol=1e-9, rtol=0)
    with pytest.raises(DataError, match="ros"):
        write_trajectory_json(traj, tmp_path / "x.json", ros=3)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({**doc, "format": "other"}))
    with pytest.raises(DataError, match="format"):
        read_trajectory_json(bad)


def _read_rosbag2(folder):
    from rosbags.rosbag2 import Reader

    out: dict[str, list] = {}
    with Reader(folder) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        for conn, stamp, raw in reader.messages():
            out.setdefault(conn.topic, []).append((stamp, ROS2.deserialize_cdr(raw, conn.msgtype)))
    return types, out


def _stamp(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def test_rosbag2_mcap_reads_back_with_types_stamps_and_values(content, tmp_path):
    folder = write_rosbag2(content, tmp_path / "rosbag")
    files = sorted(p.name for p in folder.iterdir())
    assert files == ["metadata.yaml", "rosbag.mcap"]
    assert "storage_identifier: mcap" in (folder / "metadata.yaml").read_text()
    types, msgs = _read_rosbag2(folder)
    assert types == {
        TOPIC_CHECKS: "std_msgs/msg/String",
        TOPIC_TRAJECTORY: "trajectory_msgs/msg/JointTrajectory",
        TOPIC_JOINT_STATES: "sensor_msgs/msg/JointState",
        TOPIC_HANDOVER_POSE: "geometry_msgs/msg/PoseStamped",
        human_topic("orientation"): "geometry_msgs/msg/QuaternionStamped",
        human_topic("emg"): "std_msgs/msg/Float64MultiArray",
        human_topic("acc"): "std_msgs/msg/Float64MultiArray",
        human_topic("hand_position"): "geometry_msgs/msg/PointStamped",
    }
    traj, obs, start = content.trajectory, content.observation, content.start_time_ns
    plan_ns = start + round(content.plan_time_s * 1e9)
    # the trajectory: one message at the plan time, every point on the human's clock (its header
    # stamped at the start of the human's motion, its first point when the robot starts)
    [(stamp, jt)] = msgs[TOPIC_TRAJECTORY]
    assert stamp == plan_ns and _stamp(jt) == start
    first = jt.points[0].time_from_start
    assert first.sec * 1_000_000_000 + first.nanosec == plan_ns - start
    assert list(jt.joint_names) == list(traj.joint_names) and len(jt.points) == traj.n_samples
    np.testing.assert_array_equal(np.array([p.accelerations for p in jt.points]), traj.qdd)
    # joint states at the control rate along it
    states = msgs[TOPIC_JOINT_STATES]
    assert len(states) == traj.n_samples
    stamps = np.array([s for s, _ in states])
    assert np.array_equal(stamps, [_stamp(m) for _, m in states])
    np.testing.assert_array_equal(np.diff(stamps), np.full(traj.n_samples - 1, 10_000_000))  # 100 Hz
    assert stamps[0] == plan_ns
    np.testing.assert_array_equal(np.array([m.position for _, m in states]), traj.q)
    np.testing.assert_array_equal(np.array([m.velocity for _, m in states]), traj.qd)
    assert list(states[0][1].name) == list(traj.joint_names)
    # the predicted hand-over pose, in the base frame
    [(stamp, pose)] = msgs[TOPIC_HANDOVER_POSE]
    assert stamp == plan_ns and pose.header.frame_id == "base"
    p, o = pose.pose.position, pose.pose.orientation
    np.testing.assert_array_equal([p.x, p.y, p.z, o.x, o.y, o.z, o.w], content.handover_pose)
    # the observed human channels, one message per sample, stamped from the start of the motion
    quats = msgs[human_topic("orientation")]
    assert [s for s, _ in quats] == [start + round(t * 1e9) for t in obs.t]
    q = quats[5][1].quaternion
    qw, qx, qy, qz = obs.groups["orientation"][5]
    assert (q.x, q.y, q.z, q.w) == (qx, qy, qz, qw)
    emg = msgs[human_topic("emg")]
    assert len(emg) == obs.n_samples
    np.testing.assert_array_equal(np.array([m.data for _, m in emg]), obs.groups["emg"])
    assert emg[0][1].layout.dim[0].size == 8
    hand = msgs[human_topic("hand_position")]
    pt = hand[-1][1].point
    np.testing.assert_array_equal([pt.x, pt.y, pt.z], obs.extras["hand_position"][-1])
    # channel names of the array topics are in the metadata
    meta = (folder / "metadata.yaml").read_text()
    assert "ipromp_pin.channels" in meta and "emg7" in meta
    # writing again replaces the bag; a folder that is not a bag is left alone
    write_rosbag2(content, folder)
    other = tmp_path / "notabag"
    other.mkdir()
    (other / "keep.txt").write_text("mine")
    with pytest.raises(DataError, match="not a bag"):
        write_rosbag2(content, other)
    assert (other / "keep.txt").read_text() == "mine"


def test_ros1_bag_has_the_same_messages(content, tmp_path):
    from rosbags.rosbag1 import Reader

    path = write_ros1_bag(content, tmp_path / "run.bag")
    _, ros2_msgs = _read_rosbag2(write_rosbag2(content, tmp_path / "rosbag"))
    got: dict[str, list] = {}
    with Reader(path) as reader:
        for conn, stamp, raw in reader.messages():
            got.setdefault(conn.topic, []).append((stamp, ROS1.deserialize_ros1(raw, conn.msgtype)))
    assert {t: len(v) for t, v in got.items()} == {t: len(v) for t, v in ros2_msgs.items()}
    js1 = got[TOPIC_JOINT_STATES]
    js2 = ros2_msgs[TOPIC_JOINT_STATES]
    assert [s for s, _ in js1] == [s for s, _ in js2]
    np.testing.assert_array_equal(js1[7][1].position, js2[7][1].position)
    assert hasattr(js1[0][1].header, "seq")


def test_run_writes_the_bags_and_the_requested_ros_form(tmp_path):
    from ipromp_pin.app import main
    from ipromp_pin.outputs.trajectory_files import read_trajectory_csv

    pipeline = "baxter_handover"
    out = tmp_path / "out"
    assert main(["run", pipeline, "--out", str(out), "--no-preview", "--ros", "1", "--ros1-bag"]) == 0
    doc = json.loads((out / "trajectory.json").read_text())
    assert doc["ros"] == 1 and "secs" in doc["message"]["points"][0]["time_from_start"]
    assert "secs" in doc["retreat"]["message"]["points"][0]["time_from_start"]  # the retreat in the same form
    traj = read_trajectory_csv(out / "trajectory.csv")
    types, msgs = _read_rosbag2(out / "rosbag")
    # the approach's joint states, then the retreat's (the shipped tasks retreat; its first sample is the
    # approach's last, not repeated)
    retreat = read_trajectory_csv(out / "retreat.csv")
    assert len(msgs[TOPIC_JOINT_STATES]) == traj.n_samples + retreat.n_samples - 1 and len(types) >= 6
    positions = np.array([m.position for _, m in msgs[TOPIC_JOINT_STATES]])
    np.testing.assert_array_equal(positions[: traj.n_samples], traj.q)
    np.testing.assert_array_equal(positions[traj.n_samples :], retreat.q[1:])
    report = json.loads((out / "report.json").read_text())
    [(_, pose)] = msgs[TOPIC_HANDOVER_POSE]
    p = pose.pose.position
    np.testing.assert_array_equal([p.x, p.y, p.z], report["feasibility"]["handover_position_m"])
    assert (out / "run.bag").stat().st_size > 0
    bare = tmp_path / "bare"
    assert main(["run", pipeline, "--out", str(bare), "--no-preview", "--no-rosbag"]) == 0
    assert not (bare / "rosbag").exists() and not (bare / "run.bag").exists()
    assert json.loads((bare / "trajectory.json").read_text())["ros"] == 2
