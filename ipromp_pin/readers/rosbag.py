"""Reader of the original chen2017 ROS1 bags, with the ``rosbags`` package (no ROS install needed).

Message types are decoded from each bag's own connection message definitions
(registered in an empty type store; stores are cached by the definitions' text,
see :func:`_typestore`), so custom types such as ``myo_driver/emgState`` need
no generated code. Topics read
(:data:`DEFAULT_TOPICS`): ``/myo_raw_emg_pub`` (``ch0..ch7``),
``/myo_raw_imu_pub`` (``quat0..3``, ``acc0..2``), ``/robot/joint_states``
(the arm's 17-name messages; the one-name gripper messages on the same topic
are dropped), ``/robot/limb/left/endpoint_state``.

The bag's record time of each message is the recording PC's receive time
(the CSV export's ``time`` column), the header stamps are the senders'; the
streams are then aligned exactly as in :mod:`.chen2017`, so a bag and its CSV
export give the same :class:`~ipromp_pin.data.Demo` (to within the CSV's
microsecond rounding of the receive time).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ..data import Demo
from ..exceptions import DataError
from ..signals.preprocess import DEFAULT_EMG_CUTOFF_HZ
from .streams import (
    BAXTER_LEFT_JOINTS,
    RawRecording,
    RawStream,
    assemble_recording,
    select_joint_messages,
)

DEFAULT_TOPICS: dict[str, str] = {
    "emg": "/myo_raw_emg_pub",
    "imu": "/myo_raw_imu_pub",
    "joints": "/robot/joint_states",
    "endpoint": "/robot/limb/left/endpoint_state",
}
"""Stream -> topic of the chen2017 bags."""


def is_bag_folder(folder: Path) -> bool:
    """Whether ``folder`` holds ``*.bag`` files."""
    return any(Path(folder).glob("*.bag"))


def list_demos(folder: Path, order: str = "config") -> list[Path]:
    """Bags of a task folder: in the order of ``csv/filename_<task>.cfg`` when present
    (``order="config"``), else by name (stamp); see :func:`.chen2017.list_demos`."""
    from .chen2017 import read_config_order

    folder = Path(folder)
    if order not in ("config", "recorded"):
        raise DataError(folder, "order", f"unknown demo order {order!r} (use 'config' or 'recorded')")
    bags = sorted(folder.glob("*.bag"))
    cfg = folder / "csv" / f"filename_{folder.name}.cfg"
    if order == "config" and cfg.is_file():
        rank = {s: i for i, s in enumerate(read_config_order(cfg))}
        bags.sort(key=lambda p: (rank.get(p.stem, len(rank)), p.name))
    return bags


@functools.lru_cache(maxsize=16)
def _typestore(definitions: tuple[tuple[str, str], ...]):
    """A type store with the given (msgtype, ROS1 message definition) pairs registered.

    Cached (module-level, at most 16 stores) by the definitions' text, so that bags of one
    recording session share their generated deserialisers; a bag with different definitions
    gets its own store.
    """
    _, _, Stores, get_types_from_msg, get_typestore = _import_rosbags()
    store = get_typestore(Stores.EMPTY)
    types = {}
    for msgtype, text in definitions:
        types.update(get_types_from_msg(text, msgtype))
    store.register(types)
    return store


def _import_rosbags():
    try:
        from rosbags.rosbag1 import Reader, ReaderError
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    except ImportError as exc:  # pragma: no cover - rosbags is a dependency
        raise DataError(None, "format", f"reading bags needs the 'rosbags' package: {exc}") from None
    return Reader, ReaderError, Stores, get_types_from_msg, get_typestore


def read_raw(
    path: Path,
    robot_joints: Sequence[str] = BAXTER_LEFT_JOINTS,
    topics: Mapping[str, str] | None = None,
) -> RawRecording:
    """The raw chen2017 streams of one bag."""
    Reader, ReaderError, *_ = _import_rosbags()
    path = Path(path)
    topics = dict(DEFAULT_TOPICS, **(topics or {}))
    if not path.is_file():
        raise DataError(path, None, "file not found")
    header: dict[str, list[float]] = {k: [] for k in topics}
    receive: dict[str, list[float]] = {k: [] for k in topics}
    values: dict[str, list] = {k: [] for k in topics}
    names: list[tuple[str, ...]] = []
    by_topic = {v: k for k, v in topics.items()}
    try:
        with Reader(path) as reader:
            conns = [c for c in reader.connections if c.topic in by_topic]
            store = _typestore(tuple(sorted({(c.msgtype, c.msgdef.data) for c in conns})))
            for c, stamp_ns, raw in reader.messages(connections=conns):
                key = by_topic[c.topic]
                msg = store.deserialize_ros1(raw, c.msgtype)
                st = msg.header.stamp
                header[key].append(st.sec + st.nanosec * 1e-9)
                receive[key].append(stamp_ns * 1e-9)
                if key == "emg":
                    values[key].append([getattr(msg, f"ch{i}") for i in range(8)])
                elif key == "imu":
                    values[key].append(
                        [
                            getattr(msg, f)
                            for f in ("quat0", "quat1", "quat2", "quat3", "acc0", "acc1", "acc2")
                        ]
                    )
                elif key == "joints":
                    names.append(tuple(msg.name))
                    values[key].append(np.asarray(msg.position, dtype=float))
                else:
                    p, o = msg.pose.position, msg.pose.orientation
                    values[key].append([p.x, p.y, p.z, o.x, o.y, o.z, o.w])
    except ReaderError as exc:
        raise DataError(path, None, f"corrupt or unreadable bag: {exc}") from None
    except (AttributeError, KeyError) as exc:
        raise DataError(path, None, f"unexpected message layout: {exc}") from None
    except Exception as exc:  # rosbags raises various errors on truncated data
        if isinstance(exc, DataError):
            raise
        raise DataError(path, None, f"cannot decode bag ({type(exc).__name__}: {exc})") from None
    for key in ("emg", "imu", "joints"):
        if not header[key]:
            raise DataError(path, topics[key], "topic missing or without messages")
    keep, cols = select_joint_messages(f"{path}:{topics['joints']}", names, robot_joints)
    idx = np.flatnonzero(keep)
    n_names = len(names[idx[0]])
    for k in idx:
        if values["joints"][k].size != n_names:
            raise DataError(
                path,
                topics["joints"],
                f"message {k}: {values['joints'][k].size} positions for {n_names} names",
            )
    jpos = np.array([values["joints"][k] for k in idx])[:, cols]

    def stream(key: str, v: ArrayLike, sel: np.ndarray | None = None) -> RawStream:
        h, r = np.asarray(header[key]), np.asarray(receive[key])
        if sel is not None:
            h, r = h[sel], r[sel]
        return RawStream(h, r, np.asarray(v, dtype=float), f"{path}:{topics[key]}")

    return RawRecording(
        emg=stream("emg", values["emg"]),
        imu=stream("imu", values["imu"]),
        joints=stream("joints", jpos, idx),
        endpoint=stream("endpoint", values["endpoint"]) if header["endpoint"] else None,
    )


def read_demo(
    path: Path,
    task: str | None = None,
    *,
    rate_hz: float = 50.0,
    robot_joints: Sequence[str] = BAXTER_LEFT_JOINTS,
    emg_cutoff_hz: float = DEFAULT_EMG_CUTOFF_HZ,
    topics: Mapping[str, str] | None = None,
) -> Demo:
    """Read one chen2017 bag as a demo.

    Args:
        path: The ``.bag`` file (named by its stamp).
        task: Task name (default: the bag's folder name).
        rate_hz: Output sampling rate in [Hz].
        robot_joints: Joint names of the robot group, in the wanted order.
        emg_cutoff_hz: EMG envelope cut-off in [Hz].
        topics: Overrides of :data:`DEFAULT_TOPICS`.
    """
    path = Path(path)
    raw = read_raw(path, robot_joints, topics)
    return assemble_recording(
        raw,
        task=task if task is not None else path.parent.name,
        name=path.stem,
        source=path,
        rate_hz=rate_hz,
        robot_joints=robot_joints,
        emg_cutoff_hz=emg_cutoff_hz,
    )
