"""Reader of rosbag2 recordings (ROS 2, MCAP or SQLite storage), with ``rosbags`` (no ROS install).

A recording is a rosbag2 folder as ``ros2 bag record`` writes it (``metadata.yaml`` beside its
``.mcap`` or ``.db3`` files), or one ``.mcap`` / ``.db3`` file on its own. A task folder of this
format holds one recording per demo (``<task>/<stamp>/metadata.yaml`` or ``<task>/<stamp>.mcap``).

Topics (:data:`DEFAULT_TOPICS`, the chen2017 bags' topics, each replaceable with ``topics=``) and
the message types read on them. A stream is decoded by its fields, so a custom type with the same
fields as one below is read as well:

* ``emg``, ``/myo_raw_emg_pub`` (required): the Myo driver's ``emgState`` (``header``,
  ``ch0..ch7``), or a ``std_msgs/msg/*MultiArray`` of 8 values (``Float32MultiArray``,
  ``Float64MultiArray``, ``Int32MultiArray`` ...), the raw EMG (the reader filters it into the
  envelope);
* ``imu``, ``/myo_raw_imu_pub`` (required): the Myo driver's ``imuState`` (``quat0..3`` with
  ``quat0`` = w, ``acc0..2``, raw integers); ``sensor_msgs/msg/Imu`` (``orientation``,
  ``linear_acceleration``) either with the Myo's raw integers, as the handover_20171128 session
  recorded them, or in SI units (a unit quaternion and [m/s^2]): told apart by the median norm of
  the quaternion (16384 or 1, each within 5 %; anything else is refused);
  ``geometry_msgs/msg/QuaternionStamped`` (the orientation only: the demo then has no ``"acc"``);
* ``joints``, ``/robot/joint_states`` (required): ``sensor_msgs/msg/JointState``, joints by name;
  messages without every requested joint (Baxter's one-name gripper messages) are dropped;
* ``endpoint``, ``/robot/limb/left/endpoint_state`` (optional): anything with a ``pose``
  (``baxter_core_msgs/msg/EndpointState``, ``geometry_msgs/msg/PoseStamped``);
* tracked frames, every topic of :data:`TF_TOPICS` present, or the one topic ``topics["tf"]``
  (optional): ``tf2_msgs/msg/TFMessage``
  or ``geometry_msgs/msg/TransformStamped``; a transform whose parent (``header.frame_id``) is the
  robot's base frame (``base_frames``) gives the position of its ``child_frame_id`` (the skeleton's
  ``/left_hand_1`` ..., Baxter's ``left_gripper``); transforms to other parents are not composed
  (a message without one to the base frame is skipped). A message is one sample of every frame: a
  frame it does not list, or lists as all zeros, is missing there (:mod:`.tracked`);
* ``frame:<name>`` keys of ``topics`` (none by default): a ``geometry_msgs/msg/PointStamped`` (or
  anything with a ``pose``) topic giving the frame ``<name>``'s position in the base frame.

Message types. Each topic's type is decoded from the definition the bag carries (MCAP files and
SQLite files of ROS 2 Iron and later store them; ``.msg`` or ``.idl``), so a custom type such as the
Myo driver's needs no generated code; a type without a definition in the bag is taken from the
``rosbags`` type store of the bag's ROS distribution (``metadata.yaml``'s ``ros_distro``; else the
newest one). A custom type neither carries is refused, naming the topic and the type.

Time. A message's header stamp is the sender's clock, its record time the recording PC's receive
time; every stream is put on the PC's clock with its estimated offset, as for the ROS 1 bags
(:func:`~ipromp_pin.readers.streams.clock_streams`). A message without a header (a
``MultiArray``), or a stream whose header stamps are all 0, is stamped with its record time; a
stream mixing stamped and zero-stamped messages is refused. The tracked frames of a topic share its
messages' stamps (those of their transforms to the base frame, or the record times when all are 0).
The streams are then aligned as for the other formats, so a recording written to rosbag2 with its
original stamps and receive times gives the same :class:`~ipromp_pin.data.Demo` as its ROS 1 bag or
CSV export (see the tests).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..data import Demo
from ..exceptions import DataError
from ..signals.preprocess import DEFAULT_EMG_CUTOFF_HZ
from .rosbag import DEFAULT_TOPICS as ROS1_TOPICS
from .streams import (
    BAXTER_LEFT_JOINTS,
    MYO_ACCELEROMETER_SCALE,
    MYO_ORIENTATION_SCALE,
    RawRecording,
    RawStream,
    assemble_recording,
    select_joint_messages,
)
from .tracked import TrackedTopic

DEFAULT_TOPICS: dict[str, str] = dict(ROS1_TOPICS)
"""Stream -> topic: those of the chen2017 bags (``emg``, ``imu``, ``joints``, ``endpoint``)."""
TF_TOPICS = ("/tf_of_interest", "/tf")
"""Topics whose transforms to the base frame give tracked frames (the first topic listing a frame wins)."""
BASE_FRAMES = ("base", "/base")
"""Names of the robot's base frame, the parent of the tracked frames' transforms (Baxter's ``base``)."""
TF_KEY = "tf"
"""The ``topics`` key naming the one TF topic to read instead of :data:`TF_TOPICS`."""
FRAME_KEY = "frame:"
"""Prefix of the ``topics`` keys naming a topic of one tracked frame (``"frame:/left_hand_1"``)."""
STORAGE_SUFFIXES = (".mcap", ".db3")
"""The storage files of a rosbag2 recording (MCAP, SQLite)."""
MAGIC = {".mcap": b"\x89MCAP0\r\n", ".db3": b"SQLite format 3\x00", ".zstd": b"\x28\xb5\x2f\xfd"}
"""The first bytes of each storage file (``.zstd``: a storage file compressed whole)."""
STANDARD_GRAVITY = 9.80665
"""[m/s^2] per g: a ``sensor_msgs/Imu`` in SI units gives its acceleration in [m/s^2]."""
SCALE_TOLERANCE = 0.05
"""Relative tolerance of the median quaternion norm (1 or the Myo's 16384) that tells the units."""

Message = tuple[int, str, Any]
"""A decoded message: record time [ns], message type, the ``rosbags`` message object."""


# ------------------------------------------------------------------------------------ discovery
def is_recording(path: Path) -> bool:
    """Whether ``path`` is a rosbag2 recording: a folder with ``metadata.yaml``, or an ``.mcap`` /
    ``.db3`` file."""
    path = Path(path)
    if path.is_dir():
        return (path / "metadata.yaml").is_file()
    return path.suffix in STORAGE_SUFFIXES and path.is_file()


def recording_path(path: Path) -> Path:
    """The recording ``path`` belongs to: a storage file inside a rosbag2 folder gives the folder (a
    recording split over several files is read as a whole)."""
    path = Path(path)
    if path.suffix in STORAGE_SUFFIXES and (path.parent / "metadata.yaml").is_file():
        return path.parent
    return path


def is_rosbag2_folder(folder: Path) -> bool:
    """Whether ``folder`` holds rosbag2 recordings (sub-folders with ``metadata.yaml``, or ``.mcap`` /
    ``.db3`` files)."""
    folder = Path(folder)
    if not folder.is_dir() or (folder / "metadata.yaml").is_file():
        return False
    return any(is_recording(p) for p in folder.iterdir() if not p.name.startswith("."))


def list_demos(folder: Path, order: str = "config") -> list[Path]:
    """The recordings of a task folder, by name (there is no cfg file in this format)."""
    folder = Path(folder)
    if order not in ("config", "recorded"):
        raise DataError(folder, "order", f"unknown demo order {order!r} (use 'config' or 'recorded')")
    return sorted(p for p in folder.iterdir() if not p.name.startswith(".") and is_recording(p))


def _storage_files(folder: Path) -> list[Path]:
    """The storage files of a rosbag2 folder (``.mcap``, ``.db3``, or either compressed ``.zstd``)."""
    return sorted(
        p
        for p in folder.iterdir()
        if p.suffix in STORAGE_SUFFIXES or (p.suffix == ".zstd" and Path(p.stem).suffix in STORAGE_SUFFIXES)
    )


def check_storage(path: Path) -> None:
    """Refuse, with a one-line error, what cannot be a rosbag2 recording: a folder without
    ``metadata.yaml`` or without storage files, an empty file, a file without its format's magic
    bytes (a truncated or foreign file)."""
    path = Path(path)
    if path.is_dir():
        if not (path / "metadata.yaml").is_file():
            raise DataError(path, "metadata.yaml", "not a rosbag2 folder (no metadata.yaml)")
        files = _storage_files(path)
        if not files:
            raise DataError(path, None, "rosbag2 folder without .mcap or .db3 storage files")
    elif not path.exists():
        raise DataError(path, None, "file not found")
    else:
        files = [path]
    for f in files:
        if f.suffix not in MAGIC:
            raise DataError(f, None, "not a rosbag2 storage file (expected .mcap, .db3 or .zstd)")
        try:
            with open(f, "rb") as fh:
                head = fh.read(len(MAGIC[f.suffix]))
        except OSError as exc:
            raise DataError(f, None, f"cannot read: {exc.strerror or exc}") from None
        if not head:
            raise DataError(f, None, "empty file")
        if head != MAGIC[f.suffix]:
            kind = {".mcap": "an MCAP file", ".db3": "an SQLite database", ".zstd": "a zstd file"}[f.suffix]
            raise DataError(f, None, f"not {kind} (its first bytes are not {MAGIC[f.suffix]!r})")


# ---------------------------------------------------------------------------------- type stores
def _import_rosbags():
    try:
        from rosbags.interfaces import MessageDefinitionFormat
        from rosbags.rosbag2 import Reader
        from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore
    except ImportError as exc:  # pragma: no cover - rosbags is a dependency
        raise DataError(None, "format", f"reading rosbag2 needs the 'rosbags' package: {exc}") from None
    return Reader, MessageDefinitionFormat, Stores, get_types_from_idl, get_types_from_msg, get_typestore


@functools.lru_cache(maxsize=4)
def _standard_store(distro: str):
    """The ``rosbags`` type store of ROS 2 distribution ``distro`` (the newest when unknown)."""
    *_, Stores, _, _, get_typestore = _import_rosbags()
    member = f"ROS2_{distro.upper()}"
    return get_typestore(Stores[member] if member in Stores.__members__ else Stores.LATEST)


def _parse_definition(msgtype: str, fmt: str, text: str) -> dict:
    """The types of one definition the bag carries (``.msg`` text with its dependencies, or ``.idl``)."""
    *_, get_types_from_idl, get_types_from_msg, _ = _import_rosbags()
    if fmt == "MSG":
        return dict(get_types_from_msg(text, msgtype))
    sep = "=" * 80 + "\n"
    types: dict = {}
    if text.startswith(f"{sep}IDL: "):
        for part in text.split(sep)[1:]:
            types.update(get_types_from_idl(part.split("\n", 1)[1]))
    else:
        types.update(get_types_from_idl(text))
    return types


@functools.lru_cache(maxsize=16)
def _typestore(definitions: tuple[tuple[str, str, str], ...], standard: tuple[str, ...], distro: str):
    """A type store with the bag's definitions ``(msgtype, format, text)`` and the ``standard``
    types (with their dependencies) from the distribution's store.

    Cached (at most 16 stores) by the definitions' text, so that recordings of one session share
    their generated deserialisers.
    """
    *_, Stores, _, get_types_from_msg, get_typestore = _import_rosbags()
    std = _standard_store(distro)
    if not definitions:
        return std
    types: dict = {}
    for msgtype in standard:
        text, _ = std.generate_msgdef(msgtype, ros_version=2)
        types.update(get_types_from_msg(text, msgtype))
    for msgtype, fmt, text in definitions:
        types.update(_parse_definition(msgtype, fmt, text))
    store = get_typestore(Stores.EMPTY)
    store.register(types)
    return store


def _store_for(path: Path, conns: list, distro: str | None):
    """The type store that decodes ``conns``; DataError naming a topic whose type is unknown."""
    _, MessageDefinitionFormat, *_ = _import_rosbags()
    defs, standard = {}, set()
    std = _standard_store(distro or "")
    for c in conns:
        if c.msgdef.format != MessageDefinitionFormat.NONE and c.msgdef.data:
            defs[c.msgtype] = (c.msgtype, c.msgdef.format.name, c.msgdef.data)
    for c in conns:
        if c.msgtype in defs:
            continue
        if c.msgtype not in std.fielddefs:
            raise DataError(
                path,
                c.topic,
                f"message type {c.msgtype} is not a standard ROS 2 type and the bag carries no definition "
                "of it (record to MCAP, or to SQLite with ROS 2 Iron or later; or publish it as a standard "
                "type, see docs/formats.md)",
            )
        standard.add(c.msgtype)
    try:
        return _typestore(tuple(sorted(defs.values())), tuple(sorted(standard)), distro or "")
    except Exception as exc:  # rosbags raises its own errors on a malformed definition
        raise DataError(
            path, None, f"cannot parse the bag's message definitions ({_one_line(exc)})"
        ) from None


# ------------------------------------------------------------------------------------- decoding
def _one_line(exc: Exception, limit: int = 300) -> str:
    """An exception's text on one line (a YAML parser's carets and line breaks folded), shortened."""
    text = " ".join(str(exc).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def read_messages(path: Path, topics: Sequence[str]) -> tuple[dict[str, list[Message]], list[str]]:
    """The decoded messages of ``topics`` in a rosbag2 recording, in record-time order per topic.

    Returns:
        ``(messages, available)``: topic -> its messages (empty when the bag lacks the topic), and
        every topic of the bag (for error messages).

    Raises:
        DataError: not a rosbag2 recording, a corrupt, truncated or unreadable one, an unknown type.
    """
    Reader, *_ = _import_rosbags()
    path = recording_path(Path(path))
    check_storage(path)
    out: dict[str, list[Message]] = {t: [] for t in topics}
    try:
        with Reader(path) as reader:
            available = sorted({c.topic for c in reader.connections})
            conns = [c for c in reader.connections if c.topic in out]
            if not conns:
                return out, available
            store = _store_for(path, conns, reader.ros_distro)
            for c, stamp_ns, raw in reader.messages(connections=conns):
                out[c.topic].append((stamp_ns, c.msgtype, store.deserialize_cdr(raw, c.msgtype)))
    except DataError:
        raise
    except PermissionError as exc:
        raise DataError(path, None, f"cannot read: {exc.strerror or exc}") from None
    except Exception as exc:  # rosbags, sqlite3, the MCAP parser and zstd raise many kinds
        raise DataError(
            path, None, f"corrupt or unreadable rosbag2 ({type(exc).__name__}: {_one_line(exc)})"
        ) from None
    return out, available


def _header_stamp(msg: Any) -> float:
    """The header stamp of ``msg`` in [s] (0 without a header)."""
    header = getattr(msg, "header", None)
    if header is None:
        return 0.0
    return header.stamp.sec + header.stamp.nanosec * 1e-9


def _stamps(source: str, header: Sequence[float], receive: np.ndarray) -> np.ndarray:
    """Header stamps of a stream [s], or its record times when none is stamped (all 0)."""
    h = np.asarray(header, dtype=float)
    zero = h == 0.0
    if np.all(zero):
        return receive.copy()
    if np.any(zero):
        raise DataError(
            source,
            "header.stamp",
            f"{int(zero.sum())} of {zero.size} messages are stamped 0 and the others are not: the stream "
            "cannot be put on one clock",
        )
    return h


def _receive(messages: Sequence[Message]) -> np.ndarray:
    return np.array([ns for ns, _, _ in messages], dtype=np.int64) * 1e-9


def _one_layout(source: str, messages: Sequence[Message], kinds: list[str], what: str) -> str:
    """The single decoding of a stream (``kinds[k]`` per message); DataError for none or several."""
    found = sorted(set(kinds))
    if "" in found:
        k = kinds.index("")
        raise DataError(source, None, f"message type {messages[k][1]} cannot be read as {what}")
    if len(found) > 1:
        types = sorted({m[1] for m in messages})
        raise DataError(source, None, f"the topic mixes message types {', '.join(types)}")
    return found[0]


def _emg_stream(source: str, messages: Sequence[Message]) -> RawStream:
    """Raw EMG (N, 8): ``ch0..ch7``, or the 8 values of a ``MultiArray``."""
    rows: list[Any] = []
    kinds = []
    for k, (_, _, msg) in enumerate(messages):
        if hasattr(msg, "ch0"):
            kinds.append("channels")
            rows.append([getattr(msg, f"ch{i}") for i in range(8)])
        elif hasattr(msg, "data") and hasattr(msg, "layout"):
            v = np.asarray(msg.data, dtype=float).ravel()
            if v.size != 8:
                raise DataError(source, "data", f"message {k}: {v.size} values, the Myo EMG has 8")
            kinds.append("array")
            rows.append(v)
        else:
            kinds.append("")
    _one_layout(source, messages, kinds, "EMG (fields ch0..ch7, or a MultiArray of 8 values)")
    receive = _receive(messages)
    header = _stamps(source, [_header_stamp(m) for _, _, m in messages], receive)
    return RawStream(header, receive, np.asarray(rows, dtype=float), source)


def _imu_layout(msg: Any) -> str:
    if hasattr(msg, "quat0"):
        return "myo"
    if hasattr(msg, "orientation") and hasattr(msg, "linear_acceleration"):
        return "imu"
    if hasattr(msg, "quaternion"):
        return "quaternion"
    return ""


def _imu_row(layout: str, msg: Any) -> list[float]:
    if layout == "myo":
        return [getattr(msg, f) for f in ("quat0", "quat1", "quat2", "quat3", "acc0", "acc1", "acc2")]
    q = msg.orientation if layout == "imu" else msg.quaternion
    row = [q.w, q.x, q.y, q.z]
    if layout == "imu":
        a = msg.linear_acceleration
        row += [a.x, a.y, a.z]
    return row


IMU_FIELDS = {
    "myo": {"orientation": ".quat0-3", "acc": ".acc0-2"},
    "imu": {"orientation": ".orientation", "acc": ".linear_acceleration"},
    "quaternion": {"orientation": ".quaternion", "acc": ""},
}
"""The IMU fields error messages name, per decoding."""


def _imu_stream(source: str, messages: Sequence[Message]) -> tuple[RawStream, tuple[float, float], str]:
    """Orientation w, x, y, z and acceleration (N, 7), or the orientation only (N, 4); the scales
    that turn them into units (1, [g]); the decoding (a key of :data:`IMU_FIELDS`)."""
    kinds = [_imu_layout(m) for _, _, m in messages]
    layout = _one_layout(source, messages, kinds, "an IMU (Myo imuState, sensor_msgs/Imu, QuaternionStamped)")
    values = np.array([_imu_row(layout, m) for _, _, m in messages], dtype=float)
    receive = _receive(messages)
    header = _stamps(source, [_header_stamp(m) for _, _, m in messages], receive)
    if layout == "myo":
        scales = (MYO_ORIENTATION_SCALE, MYO_ACCELEROMETER_SCALE)
    else:
        if layout == "imu" and all(m.orientation_covariance[0] == -1 for _, _, m in messages):
            raise DataError(
                source, "orientation", "the IMU gives no orientation (orientation_covariance[0] = -1)"
            )
        norm = float(np.median(np.linalg.norm(values[:, :4], axis=1)))
        if abs(norm - MYO_ORIENTATION_SCALE) <= SCALE_TOLERANCE * MYO_ORIENTATION_SCALE:
            scales = (MYO_ORIENTATION_SCALE, MYO_ACCELEROMETER_SCALE)
        elif abs(norm - 1.0) <= SCALE_TOLERANCE:
            scales = (1.0, STANDARD_GRAVITY)
        else:
            raise DataError(
                source,
                IMU_FIELDS[layout]["orientation"],
                f"median quaternion norm {norm:.6g}: neither a unit quaternion nor the Myo's raw integers "
                f"({MYO_ORIENTATION_SCALE:g})",
            )
    return RawStream(header, receive, values, source), scales, layout


def _joint_stream(source: str, messages: Sequence[Message], robot_joints: Sequence[str]) -> RawStream:
    """The requested joints' angles (N, J) of the messages that carry all of them."""
    if not all(hasattr(m, "name") and hasattr(m, "position") for _, _, m in messages):
        bad = next(t for _, t, m in messages if not (hasattr(m, "name") and hasattr(m, "position")))
        raise DataError(source, None, f"message type {bad} is not a joint state (fields name, position)")
    names = [tuple(m.name) for _, _, m in messages]
    keep, cols = select_joint_messages(source, names, robot_joints)
    idx = [int(k) for k in np.flatnonzero(keep)]
    n_names = len(names[idx[0]])
    rows = []
    for k in idx:
        p = np.asarray(messages[k][2].position, dtype=np.float64)
        if p.size != n_names:
            raise DataError(source, "position", f"message {k}: {p.size} positions for {n_names} names")
        rows.append(p)
    receive = _receive(messages)[idx]
    header = _stamps(source, [_header_stamp(messages[k][2]) for k in idx], receive)
    return RawStream(header, receive, np.array(rows)[:, cols], source)


def _pose_row(msg: Any) -> list[float] | None:
    """Position x, y, z and quaternion x, y, z, w of a message with a ``pose`` (None otherwise)."""
    pose = getattr(msg, "pose", None)
    if pose is None or not hasattr(pose, "position"):
        return None
    p, o = pose.position, pose.orientation
    return [p.x, p.y, p.z, o.x, o.y, o.z, o.w]


def _endpoint_stream(source: str, messages: Sequence[Message]) -> RawStream | None:
    """End-point poses (N, 7) [m, quaternion x, y, z, w], or None without messages."""
    if not messages:
        return None
    rows = [_pose_row(m) for _, _, m in messages]
    if any(r is None for r in rows):
        bad = next(t for (_, t, _), r in zip(messages, rows, strict=True) if r is None)
        raise DataError(source, None, f"message type {bad} has no pose (the end-point needs one)")
    receive = _receive(messages)
    header = _stamps(source, [_header_stamp(m) for _, _, m in messages], receive)
    return RawStream(header, receive, np.asarray(rows, dtype=float), source)


def _transforms(msg: Any) -> list | None:
    """The transforms of a ``TFMessage`` or a ``TransformStamped`` (None for another type)."""
    if hasattr(msg, "transforms"):
        return list(msg.transforms)
    if hasattr(msg, "child_frame_id") and hasattr(msg, "transform"):
        return [msg]
    return None


def _tf_topic(source: str, messages: Sequence[Message], base_frames: Sequence[str]) -> TrackedTopic | None:
    """The frames a TF topic gives relative to the base frame, one sample per message that has a
    transform to it; None when none has."""
    receive_ns: list[int] = []
    header: list[float] = []
    listed: dict[str, list[tuple[int, list[float]]]] = {}
    for ns, msgtype, msg in messages:
        transforms = _transforms(msg)
        if transforms is None:
            raise DataError(
                source, None, f"message type {msgtype} is not a TF message (TFMessage, TransformStamped)"
            )
        base = [tf for tf in transforms if tf.header.frame_id in base_frames]
        if not base:
            continue
        row = len(receive_ns)
        stamps = [_header_stamp(tf) for tf in base]
        header.append(next((s for s in stamps if s != 0.0), 0.0))
        receive_ns.append(ns)
        for tf in base:
            tr, ro = tf.transform.translation, tf.transform.rotation
            name = tf.child_frame_id.strip()
            if name:
                listed.setdefault(name, []).append((row, [tr.x, tr.y, tr.z, ro.x, ro.y, ro.z, ro.w]))
    if not receive_ns:
        return None
    n = len(receive_ns)
    positions = {}
    for frame, items in listed.items():
        pos = np.full((n, 3), np.nan)
        for row, v in items:
            if any(x != 0.0 for x in v):  # all zeros: the look-up returned nothing
                pos[row] = v[:3]
        positions[frame] = pos
    receive = np.asarray(receive_ns, dtype=np.int64) * 1e-9
    return TrackedTopic(_stamps(source, header, receive), receive, positions, source)


def _point_topic(
    source: str, frame: str, messages: Sequence[Message], base_frames: Sequence[str]
) -> TrackedTopic:
    """One frame's positions (N, 3) [m] from a ``PointStamped`` (or posed) topic in the base frame."""
    rows = []
    for k, (_, msgtype, msg) in enumerate(messages):
        point = getattr(msg, "point", None)
        pose = _pose_row(msg)
        if point is None and pose is None:
            raise DataError(
                source, None, f"message type {msgtype} has no point or pose (a tracked frame needs one)"
            )
        parent = msg.header.frame_id
        if parent not in base_frames:
            raise DataError(
                source,
                "header.frame_id",
                f"message {k}: {parent!r} is not the robot's base frame ({', '.join(base_frames)})",
            )
        rows.append([point.x, point.y, point.z] if point is not None else (pose or [])[:3])
    receive = _receive(messages)
    header = _stamps(source, [_header_stamp(m) for _, _, m in messages], receive)
    return TrackedTopic(header, receive, {frame: np.asarray(rows, dtype=float)}, source)


def _check_frames(
    path: Path,
    frames: Sequence[str],
    tracked: Sequence[TrackedTopic],
    tf_topics: Sequence[str],
    messages: Mapping[str, Sequence[Message]],
    base_frames: Sequence[str],
) -> None:
    """Refuse a requested frame that no topic gives in the base frame, naming what the TF topics hold."""
    have = {f for t in tracked for f in t.positions}
    missing = [f for f in frames if f not in have]
    if not missing:
        return
    seen: set[tuple[str, str]] = set()
    for topic in tf_topics:
        for _, _, msg in messages[topic]:
            seen.update((tf.header.frame_id, tf.child_frame_id) for tf in _transforms(msg) or [])
    if not seen:
        problem = (
            f"frame never tracked (no TF messages on {', '.join(TF_TOPICS)}; 'tf' in topics names another)"
        )
    else:
        pairs = ", ".join(f"{p or '?'}->{c}" for p, c in sorted(seen)[:12])
        problem = (
            f"frame never tracked in the base frame ({', '.join(base_frames)}; transforms are not composed); "
            f"the TF messages hold {pairs}"
        )
    raise DataError(path, missing[0], problem)


def read_raw(
    path: Path,
    robot_joints: Sequence[str] = BAXTER_LEFT_JOINTS,
    topics: Mapping[str, str] | None = None,
    base_frames: Sequence[str] = BASE_FRAMES,
    frames: Sequence[str] = (),
) -> RawRecording:
    """The raw streams of one rosbag2 recording (see the module docstring for topics and types).

    Args:
        path: The rosbag2 folder, or an ``.mcap`` / ``.db3`` file.
        robot_joints: Joint names of the robot group, in the wanted order.
        topics: Overrides of :data:`DEFAULT_TOPICS`; ``"tf"``: the one TF topic to read instead of
            :data:`TF_TOPICS`; ``"frame:<name>"``: the topic of one tracked frame.
        base_frames: Names of the robot's base frame (parent of the tracked frames).
        frames: Tracked frames that must be there (named in the error, with the transforms there are).

    Raises:
        DataError: unreadable recording, a required topic missing, a message type that cannot be
            read as its stream, mixed stamps, a tracked frame outside the base frame.
    """
    path = recording_path(Path(path))
    topics = dict(DEFAULT_TOPICS, **(topics or {}))
    tf_topics = (topics.pop(TF_KEY),) if TF_KEY in topics else TF_TOPICS
    for key in topics:
        if key not in DEFAULT_TOPICS and not key.startswith(FRAME_KEY):
            raise DataError(
                path,
                "topics",
                f"unknown stream {key!r} (use {', '.join(DEFAULT_TOPICS)}, {TF_KEY} or '{FRAME_KEY}<name>')",
            )
    wanted = list(dict.fromkeys([*topics.values(), *tf_topics]))
    messages, available = read_messages(path, wanted)
    for key in ("emg", "imu", "joints"):
        if not messages[topics[key]]:
            raise DataError(
                path,
                topics[key],
                f"topic missing or without messages (the bag's topics: {', '.join(available) or 'none'})",
            )

    def source(topic: str) -> str:
        return f"{path}:{topic}"

    emg = _emg_stream(source(topics["emg"]), messages[topics["emg"]])
    imu, scales, layout = _imu_stream(source(topics["imu"]), messages[topics["imu"]])
    tracked = []
    for key, topic in topics.items():
        if key.startswith(FRAME_KEY):
            if not messages[topic]:
                raise DataError(path, topic, "topic of a tracked frame missing or without messages")
            tracked.append(_point_topic(source(topic), key[len(FRAME_KEY) :], messages[topic], base_frames))
    for topic in tf_topics:
        tf = _tf_topic(source(topic), messages[topic], base_frames) if topic not in topics.values() else None
        if tf is not None:
            tracked.append(tf)
    _check_frames(path, frames, tracked, [t for t in tf_topics if messages[t]], messages, base_frames)
    fields = {"emg": ".ch0-7" if hasattr(messages[topics["emg"]][0][2], "ch0") else ".data"}
    fields.update(IMU_FIELDS[layout], joints=".position", endpoint=".pose")
    return RawRecording(
        emg=emg,
        imu=imu,
        joints=_joint_stream(source(topics["joints"]), messages[topics["joints"]], robot_joints),
        endpoint=_endpoint_stream(source(topics["endpoint"]), messages[topics["endpoint"]]),
        imu_scales=scales,
        tracked=tracked,
        fields=fields,
    )


def read_demo(
    path: Path,
    task: str | None = None,
    *,
    frames: Sequence[str] | None = None,
    rate_hz: float = 50.0,
    robot_joints: Sequence[str] = BAXTER_LEFT_JOINTS,
    emg_cutoff_hz: float = DEFAULT_EMG_CUTOFF_HZ,
    end_effector: Callable[[np.ndarray], np.ndarray] | None = None,
    topics: Mapping[str, str] | None = None,
    base_frames: Sequence[str] = BASE_FRAMES,
) -> Demo:
    """Read one rosbag2 recording as a demo.

    Args:
        path: The rosbag2 folder (named by its stamp), or an ``.mcap`` / ``.db3`` file.
        task: Task name (default: the name of the folder holding the recording).
        frames: Tracked frames (``child_frame_id``) to add as human position groups.
        rate_hz: Output sampling rate in [Hz].
        robot_joints: Joint names of the robot group, in the wanted order.
        emg_cutoff_hz: EMG envelope cut-off in [Hz].
        end_effector: Forward kinematics of the robot group, (T, J) [rad] -> (T, 3) [m]; chooses the
            handing hand when neither the end-point nor the gripper frame was recorded.
        topics, base_frames: See :func:`read_raw`.
    """
    path = recording_path(Path(path))
    raw = read_raw(path, robot_joints, topics, base_frames, list(frames or []))
    return assemble_recording(
        raw,
        task=task if task is not None else path.parent.name,
        name=path.name if path.is_dir() else path.stem,
        source=path,
        rate_hz=rate_hz,
        robot_joints=robot_joints,
        emg_cutoff_hz=emg_cutoff_hz,
        frames=list(frames or []),
        end_effector=end_effector,
    )
