"""Writing rosbag2 recordings for the reader's tests: the recordings' raw messages (their original
header stamps and receive times) as ROS 2 messages, written with ``rosbags``' writer.

The Myo driver's and Baxter's own message types are ROS 2 versions of the ROS 1 definitions (the same
fields; ``std_msgs/Header`` without ``seq``), registered in ROS 2 Humble's type store: the writer
stores their definitions in the bag (MCAP schemas; SQLite's ``message_definitions`` table), as
``ros2 bag record`` does from ROS 2 Iron on.
"""

from __future__ import annotations

import csv
import functools
import sqlite3
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

EMG_STATE = "myo_driver/msg/emgState"
IMU_STATE = "myo_driver/msg/imuState"
ENDPOINT_STATE = "baxter_core_msgs/msg/EndpointState"
JOINT_STATE = "sensor_msgs/msg/JointState"
IMU = "sensor_msgs/msg/Imu"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
FLOAT32_ARRAY = "std_msgs/msg/Float32MultiArray"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
POINT_STAMPED = "geometry_msgs/msg/PointStamped"
QUATERNION_STAMPED = "geometry_msgs/msg/QuaternionStamped"

DEFINITIONS = {
    EMG_STATE: "std_msgs/Header header\n" + "".join(f"uint32 ch{i}\n" for i in range(8)),
    IMU_STATE: "std_msgs/Header header\n"
    + "".join(f"int64 {f}\n" for f in ("quat0", "quat1", "quat2", "quat3", "acc0", "acc1", "acc2")),
    ENDPOINT_STATE: "std_msgs/Header header\ngeometry_msgs/Pose pose\ngeometry_msgs/Twist twist\n"
    "geometry_msgs/Wrench wrench\n",
}
"""ROS 2 definitions of the recordings' custom types (the ROS 1 fields)."""

Record = tuple[str, str, int, Any]
"""A message to write: topic, message type, record time [ns], message object."""


@functools.lru_cache(maxsize=1)
def store():
    """ROS 2 Humble's type store with the custom types registered."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    s = get_typestore(Stores.ROS2_HUMBLE)
    types: dict = {}
    for name, text in DEFINITIONS.items():
        types.update(get_types_from_msg(text, name))
    s.register(types)
    return s


def T(name: str):
    """The message class ``name`` of :func:`store`."""
    return store().types[name]


def header(stamp_ns: int, frame_id: str = "") -> Any:
    stamp = T("builtin_interfaces/msg/Time")(sec=int(stamp_ns) // 10**9, nanosec=int(stamp_ns) % 10**9)
    return T("std_msgs/msg/Header")(stamp=stamp, frame_id=frame_id)


def vector3(v: Sequence[float]) -> Any:
    return T("geometry_msgs/msg/Vector3")(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def quaternion(xyzw: Sequence[float]) -> Any:
    x, y, z, w = (float(c) for c in xyzw)
    return T("geometry_msgs/msg/Quaternion")(x=x, y=y, z=z, w=w)


def pose(p: Sequence[float]) -> Any:
    point = T("geometry_msgs/msg/Point")(x=float(p[0]), y=float(p[1]), z=float(p[2]))
    return T("geometry_msgs/msg/Pose")(position=point, orientation=quaternion(p[3:7]))


def emg_state(stamp_ns: int, ch: Sequence[float]) -> Any:
    return T(EMG_STATE)(header=header(stamp_ns), **{f"ch{i}": int(ch[i]) for i in range(8)})


def imu_state(stamp_ns: int, v: Sequence[float]) -> Any:
    names = ("quat0", "quat1", "quat2", "quat3", "acc0", "acc1", "acc2")
    return T(IMU_STATE)(header=header(stamp_ns), **{n: int(x) for n, x in zip(names, v, strict=True)})


def imu(stamp_ns: int, q_wxyz: Sequence[float], acc: Sequence[float], frame_id: str = "") -> Any:
    w, x, y, z = q_wxyz
    return T(IMU)(
        header=header(stamp_ns, frame_id),
        orientation=quaternion([x, y, z, w]),
        orientation_covariance=np.zeros(9),
        angular_velocity=vector3([0.0, 0.0, 0.0]),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=vector3(acc),
        linear_acceleration_covariance=np.zeros(9),
    )


def joint_state(
    stamp_ns: int, names: Sequence[str], position: Sequence[float], velocity=(), effort=()
) -> Any:
    return T(JOINT_STATE)(
        header=header(stamp_ns),
        name=list(names),
        position=np.asarray(position, dtype=np.float64),
        velocity=np.asarray(velocity, dtype=np.float64),
        effort=np.asarray(effort, dtype=np.float64),
    )


def endpoint_state(stamp_ns: int, p: Sequence[float], frame_id: str = "") -> Any:
    zero = vector3([0.0, 0.0, 0.0])
    return T(ENDPOINT_STATE)(
        header=header(stamp_ns, frame_id),
        pose=pose(p),
        twist=T("geometry_msgs/msg/Twist")(linear=zero, angular=zero),
        wrench=T("geometry_msgs/msg/Wrench")(force=zero, torque=zero),
    )


def transform(stamp_ns: int, parent: str, child: str, v: Sequence[float]) -> Any:
    tf = T("geometry_msgs/msg/Transform")(translation=vector3(v[:3]), rotation=quaternion(v[3:7]))
    return T("geometry_msgs/msg/TransformStamped")(
        header=header(stamp_ns, parent), child_frame_id=child, transform=tf
    )


def tf_message(transforms: Iterable[Any]) -> Any:
    return T(TF_MESSAGE)(transforms=list(transforms))


def float32_array(values: Sequence[float]) -> Any:
    dim = T("std_msgs/msg/MultiArrayDimension")(label="emg", size=len(values), stride=len(values))
    layout = T("std_msgs/msg/MultiArrayLayout")(dim=[dim], data_offset=0)
    return T(FLOAT32_ARRAY)(layout=layout, data=np.asarray(values, dtype=np.float32))


def write_rosbag2(path: Path, records: Iterable[Record], storage: str = "mcap") -> Path:
    """Write ``records`` into a rosbag2 folder ``path`` (``storage``: ``"mcap"`` or ``"sqlite3"``)."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    s = store()
    with Writer(path, version=8, storage_plugin=plugin) as writer:
        conns: dict[tuple[str, str], Any] = {}
        for topic, msgtype, record_ns, msg in sorted(records, key=lambda r: r[2]):
            key = (topic, msgtype)
            if key not in conns:
                conns[key] = writer.add_connection(topic, msgtype, typestore=s)
            writer.write(conns[key], int(record_ns), s.serialize_cdr(msg, msgtype))
    return path


def drop_definitions(db3: Path) -> None:
    """Remove the message definitions from an SQLite rosbag2 file (as ROS 2 Humble writes it)."""
    with sqlite3.connect(db3) as con:
        con.execute("DELETE FROM message_definitions")


# ------------------------------------------------------------------------------- the recordings
def chen2017_records(bag: Path) -> list[Record]:
    """The four chen2017 topics of a ROS 1 bag as ROS 2 messages: each message with its header stamp
    and record time (the recording PC's receive time) as recorded."""
    from rosbags.rosbag1 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    out: list[Record] = []
    with Reader(bag) as reader:
        ros1 = get_typestore(Stores.EMPTY)
        types: dict = {}
        for c in reader.connections:
            types.update(get_types_from_msg(c.msgdef.data, c.msgtype))
        ros1.register(types)
        for c, record_ns, raw in reader.messages():
            m = ros1.deserialize_ros1(raw, c.msgtype)
            ns = m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
            if c.topic == "/myo_raw_emg_pub":
                msg = emg_state(ns, [getattr(m, f"ch{i}") for i in range(8)])
                out.append((c.topic, EMG_STATE, record_ns, msg))
            elif c.topic == "/myo_raw_imu_pub":
                fields = ("quat0", "quat1", "quat2", "quat3", "acc0", "acc1", "acc2")
                out.append((c.topic, IMU_STATE, record_ns, imu_state(ns, [getattr(m, f) for f in fields])))
            elif c.topic == "/robot/joint_states":
                msg = joint_state(ns, m.name, m.position, m.velocity, m.effort)
                out.append((c.topic, JOINT_STATE, record_ns, msg))
            elif c.topic == "/robot/limb/left/endpoint_state":
                p, o = m.pose.position, m.pose.orientation
                msg = endpoint_state(ns, [p.x, p.y, p.z, o.x, o.y, o.z, o.w], m.header.frame_id)
                out.append((c.topic, ENDPOINT_STATE, record_ns, msg))
    return out


def _first_rows(stamps: list[int]) -> list[int]:
    """Rows holding a bundled message for the first time (stamp not 0 and new)."""
    seen: set[int] = set()
    rows = []
    for r, s in enumerate(stamps):
        if s != 0 and s not in seen:
            seen.add(s)
            rows.append(r)
    return rows


def multimodal_records(csv_path: Path) -> list[Record]:
    """The messages bundled in a ``multiModal_states.csv`` as the separate ROS 2 topics a rosbag2
    recording of the session holds: each Myo and Baxter message once (its first row, stamp 0 rows
    are placeholders), with its header stamp and that row's receive time ``%time``; the tracked
    frames as one ``tf2_msgs/TFMessage`` per row on ``/tf_of_interest``, the listed transforms
    stamped with the row's ``field.header.stamp`` (the stamp of the message that carried them: their
    own is 0 in the CSV)."""
    with open(csv_path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    P = "field."
    receive = [int(r["%time"]) for r in rows]

    def stamps(prefix: str) -> list[int]:
        return [int(r[f"{P}{prefix}.header.stamp"]) for r in rows]

    def num(r: dict, cols: list[str]) -> list[float]:
        return [float(r[P + c]) for c in cols]

    out: list[Record] = []
    emg_s = stamps("emgStates")
    for k in _first_rows(emg_s):
        out.append(
            (
                "/myo_raw_emg_pub",
                EMG_STATE,
                receive[k],
                emg_state(emg_s[k], num(rows[k], [f"emgStates.ch{i}" for i in range(8)])),
            )
        )
    imu_s = stamps("imuStates")
    for k in _first_rows(imu_s):
        q = num(rows[k], [f"imuStates.orientation.{a}" for a in "wxyz"])
        acc = num(rows[k], [f"imuStates.linear_acceleration.{a}" for a in "xyz"])
        msg = imu(imu_s[k], q, acc, rows[k][P + "imuStates.header.frame_id"])
        out.append(("/myo_raw_imu_pub", IMU, receive[k], msg))
    ep_s = stamps("endpointStates")
    for k in _first_rows(ep_s):
        cols = [f"endpointStates.pose.position.{a}" for a in "xyz"]
        cols += [f"endpointStates.pose.orientation.{a}" for a in "xyzw"]
        msg = endpoint_state(ep_s[k], num(rows[k], cols))
        out.append(("/robot/limb/left/endpoint_state", ENDPOINT_STATE, receive[k], msg))
    js_s = stamps("jointStates")
    for k in _first_rows(js_s):
        r = rows[k]
        n = sum(1 for j in range(64) if r.get(f"{P}jointStates.name{j}"))
        names = [r[f"{P}jointStates.name{j}"] for j in range(n)]
        msg = joint_state(
            js_s[k],
            names,
            num(r, [f"jointStates.position{j}" for j in range(n)]),
            num(r, [f"jointStates.velocity{j}" for j in range(n)]),
            num(r, [f"jointStates.effort{j}" for j in range(n)]),
        )
        out.append(("/robot/joint_states", JOINT_STATE, receive[k], msg))
    bundle = [int(r[f"{P}header.stamp"]) for r in rows]
    for k, r in enumerate(rows):
        tfs = []
        for j in range(64):
            p = f"{P}tf_of_interest.transforms{j}."
            if p + "child_frame_id" not in r:
                break
            child = r[p + "child_frame_id"]
            if not child:
                continue
            cols = [f"transform.translation.{a}" for a in "xyz"] + [f"transform.rotation.{a}" for a in "xyzw"]
            tfs.append(transform(bundle[k], r[p + "header.frame_id"], child, [float(r[p + c]) for c in cols]))
        out.append(("/tf_of_interest", TF_MESSAGE, receive[k], tf_message(tfs)))
    return out


# --------------------------------------------------------------------------- a synthetic recording
BAXTER_NAMES = tuple(
    ["head_nod", "head_pan"]
    + [f"left_{j}" for j in ("e0", "e1", "s0", "s1", "w0", "w1", "w2")]
    + [f"right_{j}" for j in ("e0", "e1", "s0", "s1", "w0", "w1", "w2")]
    + ["torso_t0"]
)
"""Baxter's 17 joint-state names, alphabetical as the robot publishes them."""
ARM = ("left_s0", "left_s1", "left_e0", "left_e1", "left_w0", "left_w1", "left_w2")
Q_START = np.array([-0.84, -0.97, 0.38, 1.26, -0.20, 1.19, 1.66])
Q_END = np.array([-1.50, -0.50, 0.38, 0.64, -0.49, 0.95, 1.27])
ROBOT_CLOCK_AHEAD_S = 4.0
"""The robot stamps its messages with its own clock, this far ahead of the recording PC."""
START_NS = 1_700_000_000 * 10**9


class Synthetic:
    """A synthetic recording: every stream a known function of the true time ``tau`` [s] from the
    start, sampled at its own rate with jitter, received 1-4 ms after it was stamped.

    Streams: raw EMG (8 channels, 50 Hz, ``Float32MultiArray``: no header), the forearm orientation
    (rotation about x by ``0.5 tau`` [rad]) and gravity in the sensor frame (``sensor_msgs/Imu`` in SI
    units, 50 Hz, PC clock), Baxter's 17 joint states with the left arm moving linearly from
    :data:`Q_START` to :data:`Q_END` and one-name gripper messages between them (100 Hz and 10 Hz,
    robot clock), the end-point (``PoseStamped``, 100 Hz, robot clock) and tracked frames
    (``TFMessage``, 30 Hz, PC clock): ``/left_hand_1`` moving 0.2 m/s along x (absent from every
    7th message, all zeros in message 40), ``/right_hand_1``, ``/head_1``, ``left_gripper`` in the
    base frame and a camera frame in another parent (not read).
    """

    def __init__(self, seed: int = 0, duration_s: float = 3.0) -> None:
        self.rng = np.random.default_rng(seed)
        self.duration_s = duration_s

    def times(self, rate_hz: float) -> np.ndarray:
        """Sample times [s] of a stream at ``rate_hz`` with 10 % jitter."""
        n = int(self.duration_s * rate_hz)
        return np.arange(n) / rate_hz + self.rng.uniform(0.0, 0.1 / rate_hz, n)

    def latency(self, n: int) -> np.ndarray:
        return self.rng.uniform(0.001, 0.004, n)

    @staticmethod
    def ns(t_s: np.ndarray) -> np.ndarray:
        return START_NS + np.round(np.asarray(t_s) * 1e9).astype(np.int64)

    @staticmethod
    def angle(tau: np.ndarray) -> np.ndarray:
        return 0.5 * np.asarray(tau)

    def q(self, tau: np.ndarray) -> np.ndarray:
        return Q_START + (np.asarray(tau) / self.duration_s)[:, None] * (Q_END - Q_START)

    @staticmethod
    def hand(tau: np.ndarray) -> np.ndarray:
        tau = np.asarray(tau)
        return np.column_stack([0.3 + 0.2 * tau, 0.1 + 0 * tau, 0.2 + 0 * tau])

    def records(self) -> list[Record]:
        """Every message of the recording; also sets the raw arrays as attributes (``emg``, ``imu``,
        ``joints``, ``endpoint``, ``tf``: (header [s], receive [s], values))."""
        out: list[Record] = []
        t = self.times(50.0)
        r = t + self.latency(t.size)
        emg = self.rng.integers(5, 120, (t.size, 8)).astype(float)
        for k in range(t.size):
            out.append(("/myo_raw_emg_pub", FLOAT32_ARRAY, int(self.ns(r[k])), float32_array(emg[k])))
        self.emg = (self.ns(r) * 1e-9, self.ns(r) * 1e-9, emg)

        t = self.times(50.0)
        r = t + self.latency(t.size)
        a = self.angle(t)
        q = np.column_stack([np.cos(a / 2), np.sin(a / 2), 0 * a, 0 * a])
        acc = STANDARD_GRAVITY_MS2 * np.column_stack([0 * a, np.sin(a), np.cos(a)])
        for k in range(t.size):
            out.append(("/myo_raw_imu_pub", IMU, int(self.ns(r[k])), imu(int(self.ns(t[k])), q[k], acc[k])))
        self.imu = (self.ns(t) * 1e-9, self.ns(r) * 1e-9, np.hstack([q, acc]))

        t = self.times(100.0)
        r = t + self.latency(t.size)
        h = t + ROBOT_CLOCK_AHEAD_S
        arm = self.q(t)
        full = np.zeros((t.size, len(BAXTER_NAMES)))
        for j, name in enumerate(ARM):
            full[:, BAXTER_NAMES.index(name)] = arm[:, j]
        for k in range(t.size):
            msg = joint_state(int(self.ns(h[k])), BAXTER_NAMES, full[k])
            out.append(("/robot/joint_states", JOINT_STATE, int(self.ns(r[k])), msg))
            if k % 10 == 5:  # the gripper's one-name messages on the same topic
                grip = joint_state(int(self.ns(h[k])) + 1000, ["left_gripper"], [0.02])
                out.append(("/robot/joint_states", JOINT_STATE, int(self.ns(r[k])) + 1000, grip))
        self.joints = (self.ns(h) * 1e-9, self.ns(r) * 1e-9, arm)
        ep = np.column_stack([0.6 + 0.05 * t, 0.1 + 0 * t, 0.2 + 0 * t, 0 * t, 0 * t, 0 * t, 1 + 0 * t])
        for k in range(t.size):
            msg = T(POSE_STAMPED)(header=header(int(self.ns(h[k])), "base"), pose=pose(ep[k]))
            out.append(("/robot/limb/left/endpoint_state", POSE_STAMPED, int(self.ns(r[k])), msg))
        self.endpoint = (self.ns(h) * 1e-9, self.ns(r) * 1e-9, ep)

        t = self.times(30.0)
        r = t + self.latency(t.size)
        frames = {
            "/left_hand_1": self.hand(t),
            "/right_hand_1": self.hand(t) + [0.0, -0.4, 0.0],
            "/head_1": np.tile([0.2, -0.2, 0.6], (t.size, 1)),
            "left_gripper": np.column_stack([0.6 + 0.05 * t, 0.1 + 0 * t, 0.2 + 0 * t]),
        }
        self.tf_positions = {f: np.array(p, dtype=float) for f, p in frames.items()}
        self.tf_positions["/left_hand_1"][::7] = np.nan
        self.tf_positions["/left_hand_1"][40] = np.nan
        identity = [0.0, 0.0, 0.0, 1.0]
        for k in range(t.size):
            tfs = [transform(int(self.ns(t[k])), "world", "camera", [1.0, 0, 0, *identity])]
            for f, p in frames.items():
                if f == "/left_hand_1" and k % 7 == 0:
                    continue
                v = [0.0] * 7 if (f == "/left_hand_1" and k == 40) else [*p[k], *identity]
                tfs.append(transform(int(self.ns(t[k])), "base", f, v))
            out.append(("/tf", TF_MESSAGE, int(self.ns(r[k])), tf_message(tfs)))
        self.tf = (self.ns(t) * 1e-9, self.ns(r) * 1e-9)
        return out


STANDARD_GRAVITY_MS2 = 9.80665
