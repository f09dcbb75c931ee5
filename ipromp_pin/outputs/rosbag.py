"""A run's outputs as a ROS bag: rosbag2 with MCAP storage (ROS 2), optionally a ROS 1 ``.bag``.

The messages are built from the message definitions that ``rosbags`` ships (ROS 2 Humble store for
rosbag2, Noetic for ROS 1) and serialised by it (CDR / ROS 1 wire format), so ``ros2 bag play``,
``ros2 bag info``, Foxglove Studio and PlotJuggler read the bag as any recorded one.

Topics (names of human groups are made ROS-safe by :func:`human_topic`); the message of an observed
group or extra is the one of its channel-group specification
(:func:`ipromp_pin.signals.groups.group_spec`):

* ``/ipromp_pin/checks``, ``std_msgs/msg/String``: ``passed``, or ``checks FAILED (...)`` for a
  trajectory written because of ``--allow-failing-checks``, whose three robot topics below are then
  under ``/ipromp_pin/failed_checks/`` instead of ``/ipromp_pin/`` (a controller listening on the
  normal topics never receives it; rosbag2 custom data ``ipromp_pin.checks`` says the same);
* ``/ipromp_pin/planned_trajectory``, ``trajectory_msgs/msg/JointTrajectory``: the timed,
  jerk-limited trajectory (one message, at the plan time);
* ``/ipromp_pin/joint_states``, ``sensor_msgs/msg/JointState``: the robot's planned joint states
  along it, one per control period (then along the retreat, when there is one);
* ``/ipromp_pin/retreat_trajectory``, ``trajectory_msgs/msg/JointTrajectory``: the retreat after the
  hand-over (:mod:`ipromp_pin.planning.retreat`; one message, stamped at the hand-over), when planned;
* ``/ipromp_pin/handover_pose``, ``geometry_msgs/msg/PoseStamped``: the predicted hand-over pose of
  the end-effector, in the base frame;
* ``/ipromp_pin/human/orientation``, ``geometry_msgs/msg/QuaternionStamped``: the observed forearm
  orientation (when its 4 channels are named ``qw, qx, qy, qz`` or ``w, x, y, z``);
* ``/ipromp_pin/human/<frame>``, ``geometry_msgs/msg/PointStamped``: an observed tracked frame
  (a 3-channel group whose name starts with ``/``, e.g. ``/left_hand_1``) in [m], base frame;
* ``/ipromp_pin/human/hand_position``, ``geometry_msgs/msg/PointStamped``: the human hand in [m],
  base frame (when the observation has the extra ``hand_position``);
* ``/ipromp_pin/human/<group>``, ``std_msgs/msg/Float64MultiArray``: any other observed group, e.g.
  ``emg`` (one value per channel, in the group's channel order), or a group registered with its own
  message type.

Time: the human's motion starts at ``start_time_ns`` (default 0); a human sample at ``t`` [s] of the
observation is stamped ``start + t``; the plan is published at the end of the observation
(``start + observed_until_s``: the trajectory's ``header.stamp``, the hand-over pose's stamp), and
the joint state of trajectory sample ``k`` is stamped ``plan time + t_s[k]``; the retreat's message
is stamped at the hand-over (plan time + the trajectory's duration) and its joint states from there
(its first sample, the hand-over itself, is not repeated). The bag's record
time of every message is its stamp (``Float64MultiArray`` has no header: its record time is its
stamp). Missing samples (a tracker that lost the hand) are not written. The metadata's custom data
``ipromp_pin.channels`` (rosbag2) lists the channel names of every array topic as JSON.
"""

from __future__ import annotations

import functools
import json
import re
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np

from ..data import Demo
from ..exceptions import DataError
from ..motion.trajectory import Trajectory
from ..signals.groups import FLOAT64_MULTI_ARRAY as FLOAT64_MULTI_ARRAY  # message types, re-exported
from ..signals.groups import POINT_STAMPED as POINT_STAMPED
from ..signals.groups import QUATERNION_STAMPED as QUATERNION_STAMPED
from ..signals.groups import group_spec, registered_groups

if TYPE_CHECKING:
    from rosbags.typesys.store import MsgType  # the message classes' protocol (typing only)

TOPIC_PREFIX = "/ipromp_pin"
TOPIC_TRAJECTORY = f"{TOPIC_PREFIX}/planned_trajectory"
TOPIC_JOINT_STATES = f"{TOPIC_PREFIX}/joint_states"
TOPIC_HANDOVER_POSE = f"{TOPIC_PREFIX}/handover_pose"
TOPIC_RETREAT = f"{TOPIC_PREFIX}/retreat_trajectory"
TOPIC_HUMAN = f"{TOPIC_PREFIX}/human"
TOPIC_CHECKS = f"{TOPIC_PREFIX}/checks"
FAILED_PREFIX = f"{TOPIC_PREFIX}/failed_checks"
"""Prefix of the robot's topics in a bag whose trajectory failed its checks (written only with
``--allow-failing-checks``): ``/ipromp_pin/failed_checks/planned_trajectory`` and so on, so that a
controller subscribed to the normal topics never receives it."""

BAG_FILE_STEM = "rosbag"
"""The committed rosbag2 folder's MCAP file is ``rosbag.mcap`` (a plain, visible name)."""

JOINT_TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"
JOINT_STATE = "sensor_msgs/msg/JointState"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
STRING = "std_msgs/msg/String"

ROSBAG2_VERSION: Literal[8, 9] = 8
"""rosbag2 metadata version written (8: read by ROS 2 Humble and later)."""


@dataclass(frozen=True)
class BagContent:
    """What goes into the bag.

    Attributes:
        trajectory: The timed trajectory (joint names, positions [rad], velocities [rad/s], ...; times
            on the human's clock: t = 0 at the start of the human's motion).
        plan_time_s: When the plan is published, in [s] from the start of the human's motion (the
            end of the observation).
        handover_pose: (7,) the predicted hand-over pose: position x, y, z [m] and quaternion x, y,
            z, w, in ``base_frame``.
        base_frame: The robot's base frame (``frame_id`` of the pose and of positions).
        observation: The observed human channels (times in [s] from the start of the motion), or None.
        start_time_ns: Stamp of the start of the human's motion in [ns].
        failures: None when the trajectory passed its checks, else the failed checks: the robot's
            topics then go under :data:`FAILED_PREFIX` and a ``std_msgs/String`` on
            :data:`TOPIC_CHECKS` (and the rosbag2 custom data ``ipromp_pin.checks``) says so.
        retreat: The segment after the hand-over (times on the human's clock), or None.
    """

    trajectory: Trajectory
    plan_time_s: float
    handover_pose: np.ndarray
    base_frame: str = "base"
    observation: Demo | None = None
    start_time_ns: int = 0
    failures: tuple[str, ...] | None = None
    retreat: Trajectory | None = None


def robot_topic(topic: str, content: BagContent) -> str:
    """The topic a robot message of ``content`` goes on: ``topic``, or under :data:`FAILED_PREFIX`
    when the trajectory failed its checks."""
    if content.failures is None:
        return topic
    return FAILED_PREFIX + topic[len(TOPIC_PREFIX) :]


def checks_text(content: BagContent) -> str:
    """The ``/ipromp_pin/checks`` message: whether the trajectory passed and what failed."""
    if content.failures is None:
        return "passed"
    return f"checks FAILED ({', '.join(content.failures)}); written because of --allow-failing-checks"


@dataclass(frozen=True)
class BagMessage:
    """One message: its topic, type, stamp in [ns] and the ``rosbags`` message object."""

    topic: str
    msgtype: str
    stamp_ns: int
    msg: object


def human_topic(group: str) -> str:
    """The topic of an observed group or extra (characters outside ``[A-Za-z0-9_]`` become ``_``)."""
    name = re.sub(r"[^A-Za-z0-9_]", "_", group.strip("/")) or "group"
    if name[0].isdigit():
        name = "g" + name
    return f"{TOPIC_HUMAN}/{name}"


def _ns(t_s: float) -> int:
    return int(round(float(t_s) * 1e9))


@functools.lru_cache(maxsize=2)
def _builder(ros1: bool) -> _Builder:
    return _Builder(ros1)


class _Builder:
    """Message objects of one ``rosbags`` typestore (ROS 2, or ROS 1 with ``seq`` in headers)."""

    def __init__(self, ros1: bool) -> None:
        from rosbags.typesys import Stores, get_typestore  # deferred: ~0.3 s to import

        self.ros1 = ros1
        self.store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
        self.t = self.store.types

    def time(self, ns: int) -> MsgType:
        return self.t["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    def duration(self, ns: int) -> MsgType:
        return self.t["builtin_interfaces/msg/Duration"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    def header(self, ns: int, frame_id: str) -> MsgType:
        h = self.t["std_msgs/msg/Header"]
        if self.ros1:
            return h(seq=0, stamp=self.time(ns), frame_id=frame_id)
        return h(stamp=self.time(ns), frame_id=frame_id)

    def joint_trajectory(self, traj: Trajectory, ns: int) -> MsgType:
        point = self.t["trajectory_msgs/msg/JointTrajectoryPoint"]
        empty = np.zeros(0)
        points = [
            point(
                positions=np.asarray(traj.q[k], dtype=np.float64),
                velocities=np.asarray(traj.qd[k], dtype=np.float64),
                accelerations=np.asarray(traj.qdd[k], dtype=np.float64),
                effort=empty if traj.effort_nm is None else np.asarray(traj.effort_nm[k], dtype=np.float64),
                time_from_start=self.duration(_ns(traj.t_s[k])),
            )
            for k in range(traj.n_samples)
        ]
        return self.t[JOINT_TRAJECTORY](
            header=self.header(ns, ""), joint_names=list(traj.joint_names), points=points
        )

    def joint_state(
        self, ns: int, names: list[str], q: np.ndarray, qd: np.ndarray, effort: np.ndarray | None = None
    ) -> MsgType:
        return self.t[JOINT_STATE](
            header=self.header(ns, ""),
            name=names,
            position=np.asarray(q, dtype=np.float64),
            velocity=np.asarray(qd, dtype=np.float64),
            effort=np.zeros(0) if effort is None else np.asarray(effort, dtype=np.float64),
        )

    def point(self, xyz: np.ndarray) -> MsgType:
        return self.t["geometry_msgs/msg/Point"](x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2]))

    def quaternion(self, xyzw: np.ndarray) -> MsgType:
        x, y, z, w = (float(v) for v in xyzw)
        return self.t["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)

    def pose_stamped(self, ns: int, frame: str, pose: np.ndarray) -> MsgType:
        p = self.t["geometry_msgs/msg/Pose"](
            position=self.point(pose[:3]), orientation=self.quaternion(pose[3:])
        )
        return self.t[POSE_STAMPED](header=self.header(ns, frame), pose=p)


def _sample_messages(
    b: _Builder,
    topic: str,
    label: str,
    values: np.ndarray,
    names: tuple[str, ...],
    rows: np.ndarray,
    stamps: list[int],
    base_frame: str,
) -> list[BagMessage]:
    """One message per sample ``rows`` of a group or extra, of its specification's message type."""
    m = group_spec(label).ros_message_for(names)
    if m is None:
        return []
    frame = base_frame if m.in_base_frame else ""
    build, msgtype, types, header = m.build, m.msgtype, b.t, b.header if m.stamped else None
    out = []
    for i in rows.tolist():
        ns = stamps[i]
        msg = build(types, None if header is None else header(ns, frame), label, values[i], names)
        out.append(BagMessage(topic, msgtype, ns, msg))
    return out


def _human_messages(b: _Builder, obs: Demo, start_ns: int, base_frame: str) -> Iterator[BagMessage]:
    stamps = [start_ns + _ns(t) for t in obs.t]
    for group, values in obs.groups.items():
        names = tuple(obs.channel_names[group])
        ok = ~obs.missing.get(group, np.zeros(obs.n_samples, dtype=bool)) & np.all(
            np.isfinite(values), axis=1
        )
        yield from _sample_messages(
            b, human_topic(group), group, values, names, np.flatnonzero(ok), stamps, base_frame
        )
    for spec in registered_groups():
        v = obs.extras.get(spec.name) if spec.extra else None
        if v is None or v.ndim != 2 or not spec.fits(v.shape[1]):
            continue
        rows = np.flatnonzero(np.all(np.isfinite(v), axis=1))
        yield from _sample_messages(
            b, human_topic(spec.name), spec.name, v, spec.channels, rows, stamps, base_frame
        )


def bag_messages(content: BagContent, ros1: bool = False) -> list[BagMessage]:
    """Every message of ``content``, sorted by stamp (stable: plan messages before the states)."""
    b = _builder(ros1)
    traj = content.trajectory
    pose = np.asarray(content.handover_pose, dtype=float)
    if pose.shape != (7,) or not np.all(np.isfinite(pose)):
        raise DataError(None, "handover_pose", f"expected 7 finite values, got shape {pose.shape}")
    start = int(content.start_time_ns)
    plan_ns = start + _ns(content.plan_time_s)
    out: list[BagMessage] = []
    if content.observation is not None:
        out.extend(_human_messages(b, content.observation, start, content.base_frame))
    out.append(BagMessage(TOPIC_CHECKS, STRING, start, b.t[STRING](data=checks_text(content))))
    topics = [robot_topic(t, content) for t in (TOPIC_TRAJECTORY, TOPIC_HANDOVER_POSE, TOPIC_JOINT_STATES)]
    # every time on the human's clock: the messages' header stamp is the start of the human's motion,
    # their points' times from it, the joint states stamped at their sample's time
    out.append(BagMessage(topics[0], JOINT_TRAJECTORY, plan_ns, b.joint_trajectory(traj, start)))
    out.append(
        BagMessage(topics[1], POSE_STAMPED, plan_ns, b.pose_stamped(plan_ns, content.base_frame, pose))
    )
    out.extend(_joint_states(b, topics[2], traj, start))
    if content.retreat is not None:
        ho_ns = start + _ns(traj.t_s[-1])
        topic = robot_topic(TOPIC_RETREAT, content)
        out.append(BagMessage(topic, JOINT_TRAJECTORY, ho_ns, b.joint_trajectory(content.retreat, start)))
        out.extend(_joint_states(b, topics[2], content.retreat, start, first=1))
    out.sort(key=lambda m: m.stamp_ns)
    return out


def _joint_states(
    b: _Builder, topic: str, traj: Trajectory, start_ns: int, first: int = 0
) -> list[BagMessage]:
    """The joint states of ``traj``'s samples from ``first`` on, sample ``k`` stamped ``start + t_s[k]``."""
    names = list(traj.joint_names)
    effort = traj.effort_nm
    out = []
    for k in range(first, traj.n_samples):
        ns = start_ns + _ns(traj.t_s[k])
        tau = None if effort is None else effort[k]
        out.append(BagMessage(topic, JOINT_STATE, ns, b.joint_state(ns, names, traj.q[k], traj.qd[k], tau)))
    return out


def _channels(content: BagContent) -> dict[str, list[str]]:
    """Array topic -> channel names (what a ``Float64MultiArray``'s values are)."""
    obs = content.observation
    if obs is None:
        return {}
    return {human_topic(g): list(obs.channel_names[g]) for g in obs.groups}


def is_our_bag_folder(folder: Path) -> bool:
    """Whether ``folder`` is a rosbag2 folder as ipromp_pin writes it: ``metadata.yaml`` and the
    ``.mcap`` files it lists, nothing else (an empty folder counts too)."""
    if not folder.is_dir() or folder.is_symlink():
        return False
    entries = list(folder.iterdir())
    if not entries:
        return True
    meta = folder / "metadata.yaml"
    if not meta.is_file() or meta.stat().st_size > 1_000_000:
        return False
    listed = meta.read_text(encoding="utf-8", errors="replace")
    return all(
        p.name == "metadata.yaml" or (p.is_file() and p.suffix == ".mcap" and p.name in listed)
        for p in entries
    )


def is_our_ros1_bag(path: Path) -> bool:
    """Whether ``path`` is a ROS 1 bag file (it starts with ``#ROSBAG V2.0``)."""
    if not path.is_file() or path.is_symlink():
        return False
    with open(path, "rb") as fh:
        return fh.read(13) == b"#ROSBAG V2.0\n"


def check_bag_paths(out_dir: Path, rosbag_name: str = "rosbag", ros1_name: str = "run.bag") -> None:
    """Refuse, before any computation, an output folder whose ``rosbag`` or ``run.bag`` is not a bag
    ipromp_pin wrote (a user's own file or folder there would be replaced or removed at the commit).

    Raises:
        DataError: naming the path and what to do.
    """
    for path, ours in ((out_dir / rosbag_name, is_our_bag_folder), (out_dir / ros1_name, is_our_ros1_bag)):
        if (path.exists() or path.is_symlink()) and not ours(path):
            raise DataError(
                path,
                None,
                "exists and is not a bag written by ipromp_pin (it would be replaced); move it away or "
                "choose another output folder",
            )


def _clear(path: Path, is_ours: bool) -> None:
    if not path.exists():
        return
    if not is_ours:
        raise DataError(
            path, None, "exists and is not a bag written by ipromp_pin; choose another output folder"
        )
    if path.is_dir():
        shutil.rmtree(path)
    else:
        path.unlink()


def write_rosbag2(content: BagContent, folder: str | Path, stem: str = BAG_FILE_STEM) -> Path:
    """Write ``content`` as a rosbag2 folder with MCAP storage: ``metadata.yaml`` beside
    ``<stem>.mcap`` (default ``rosbag.mcap``, whatever the folder is called: a staged folder's
    temporary name never ends up in the bag).

    A folder of that name that holds a bag (:func:`is_our_bag_folder`) is replaced; any other
    existing path raises :class:`~ipromp_pin.exceptions.DataError`.

    Returns:
        The bag folder.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer

    folder = Path(folder)
    _clear(folder, is_our_bag_folder(folder))
    messages = bag_messages(content)
    b = _builder(False)
    folder.mkdir(parents=True)
    inner = folder / stem  # the writer names the MCAP file after its folder
    with Writer(inner, version=ROSBAG2_VERSION, storage_plugin=StoragePlugin.MCAP) as writer:
        writer.set_custom_data("ipromp_pin.channels", json.dumps(_channels(content)))
        checks = {"passed": content.failures is None, "failures": list(content.failures or [])}
        writer.set_custom_data("ipromp_pin.checks", json.dumps(checks))
        conns = {}
        for m in messages:
            if m.topic not in conns:
                conns[m.topic] = writer.add_connection(m.topic, m.msgtype, typestore=b.store)
            writer.write(conns[m.topic], m.stamp_ns, b.store.serialize_cdr(m.msg, m.msgtype))
    for p in inner.iterdir():
        p.replace(folder / p.name)
    inner.rmdir()
    return folder


def write_ros1_bag(content: BagContent, path: str | Path) -> Path:
    """Write the same messages as :func:`write_rosbag2` into a ROS 1 ``.bag`` file (Noetic types).

    An existing ``.bag`` file at ``path`` is replaced.
    """
    from rosbags.rosbag1 import Writer

    path = Path(path)
    _clear(path, path.is_file() and path.suffix == ".bag")
    messages = bag_messages(content, ros1=True)
    b = _builder(True)
    with Writer(path) as writer:
        conns = {}
        for m in messages:
            if m.topic not in conns:
                conns[m.topic] = writer.add_connection(m.topic, m.msgtype, typestore=b.store)
            writer.write(conns[m.topic], m.stamp_ns, b.store.serialize_ros1(m.msg, m.msgtype))
    return path
