"""Pieces shared by the readers: joint names, CSV access, the recorded streams and the demo assembly.

The chen2017 CSV export, the original ROS bags and rosbag2 recordings hold the same four message
streams (rosbag2 recordings may add tracked frames); their readers parse them into
:class:`RawRecording` and build the demo with :func:`assemble_recording`, so the formats give the
same :class:`Demo`. The multimodal reader bundles the same Myo and Baxter streams: every reader
builds them with :func:`recorded_streams` and the demo's Myo groups with :func:`myo_groups`; channel
names and interpolation kinds come from the channel-group specifications (:mod:`ipromp_pin.signals.groups`).
"""

from __future__ import annotations

import csv
import datetime
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..data import ROBOT, Demo
from ..exceptions import DataError
from ..signals.checks import (
    ACCELERATION_MAX_G,
    EMG_RAW_RANGE,
    GRIPPER_HINT,
    POSITION_BOUND_M,
    UNIT_QUATERNION_TOLERANCE,
    check_joint_angles,
    check_norms,
    check_range,
    pose_like,
)
from ..signals.groups import ACC, EMG, ORIENTATION, ROBOT_GROUP, SKELETON_FRAME
from ..signals.preprocess import (
    DEFAULT_EMG_CUTOFF_HZ,
    Stream,
    align_streams,
    emg_envelope,
    estimate_clock_offset,
    quaternion_continuity,
)
from .tracked import FrameTrack, TrackedTopic, frame_extras, frame_groups, frame_streams

BAXTER_LEFT_JOINTS: tuple[str, ...] = (
    "left_s0",
    "left_s1",
    "left_e0",
    "left_e1",
    "left_w0",
    "left_w1",
    "left_w2",
)
"""Baxter's left-arm joints in the URDF's kinematic order (the default robot group)."""

ORIENTATION_CHANNELS = ORIENTATION.channels
EMG_CHANNELS = EMG.channels
ACC_CHANNELS = ACC.channels

MYO_ORIENTATION_SCALE = 16384.0
"""Myo firmware quaternion scaling (myohw.h: MYOHW_ORIENTATION_SCALE), raw units per 1."""
MYO_ACCELEROMETER_SCALE = 2048.0
"""Myo firmware accelerometer scaling (myohw.h: MYOHW_ACCELEROMETER_SCALE), raw units per g."""

TIMEZONE_STEP_S = 900.0
"""Receive times written as local wall-clock text differ from header stamps (epoch, UTC) by
the time-zone offset, a multiple of 15 min; it is rounded away before the clock offsets are
estimated, so clock offsets must be below 7.5 min."""


# ----------------------------------------------------------------------------------------- CSV
class CsvTable:
    """A CSV file read as text columns (``csv`` module, no pandas).

    Attributes:
        path: The file.
        header: Column names.
        rows: Data rows (lists of strings), all of the header's length.
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        try:
            with open(self.path, newline="", encoding="utf-8-sig") as fh:
                rows = list(csv.reader(fh))
        except FileNotFoundError:
            raise DataError(self.path, None, "file not found") from None
        except (OSError, UnicodeDecodeError, csv.Error) as exc:
            raise DataError(self.path, None, f"cannot read CSV: {exc}") from None
        if not rows:
            raise DataError(self.path, None, "empty file (no header line)")
        self.header = [h.strip() for h in rows[0]]
        self.rows = rows[1:]
        while self.rows and not self.rows[-1]:
            self.rows.pop()
        n = len(self.header)
        for i, r in enumerate(self.rows):
            if len(r) != n:
                raise DataError(
                    self.path,
                    f"line {i + 2}",
                    f"has {len(r)} fields, the header has {n} (truncated or corrupt file?)",
                )
        self._index = {h: i for i, h in enumerate(self.header)}

    def __len__(self) -> int:
        return len(self.rows)

    def has(self, column: str) -> bool:
        """Whether the file has ``column``."""
        return column in self._index

    def index(self, column: str) -> int:
        """Position of ``column`` in a row."""
        i = self._index.get(column)
        if i is None:
            raise DataError(self.path, column, "missing column")
        return i

    def text(self, column: str) -> list[str]:
        """One column as strings."""
        i = self._index.get(column)
        if i is None:
            raise DataError(self.path, column, "missing column")
        return [r[i] for r in self.rows]

    def numbers(self, columns: Sequence[str]) -> np.ndarray:
        """Columns as floats, shape (N, len(columns))."""
        idx = []
        for c in columns:
            i = self._index.get(c)
            if i is None:
                raise DataError(self.path, c, "missing column")
            idx.append(i)
        try:
            return np.array([[r[i] for i in idx] for r in self.rows], dtype=float).reshape(len(self.rows), -1)
        except ValueError:
            for c, i in zip(columns, idx, strict=True):
                for k, r in enumerate(self.rows):
                    try:
                        float(r[i])
                    except ValueError:
                        raise DataError(self.path, c, f"line {k + 2}: not a number: {r[i]!r}") from None
            raise


def parse_receive_times(path: object, values: Sequence[str]) -> np.ndarray:
    """Receive times in [s]: wall-clock text ``YYYY/MM/DD/HH:MM:SS.ffffff`` (read as UTC)
    or plain numbers (seconds, or nanoseconds when above 1e12)."""
    if not values:
        return np.zeros(0)
    first = values[0].strip()
    try:
        float(first)
        numeric = True
    except ValueError:
        numeric = False
    if numeric:
        try:
            v = np.array(values, dtype=float)
        except ValueError:
            raise DataError(path, "time", "mixes numbers and text") from None
        return v * 1e-9 if np.nanmedian(v) > 1e12 else v
    days: dict[str, float] = {}
    out = np.empty(len(values))
    try:
        for k, s in enumerate(values):
            day = s[:10]
            d0 = days.get(day)
            if d0 is None:
                midnight = datetime.datetime.strptime(day, "%Y/%m/%d").replace(tzinfo=datetime.UTC)
                d0 = days[day] = midnight.timestamp()
            if s[10] != "/" or s[13] != ":" or s[16] != ":":
                raise ValueError(s)
            out[k] = d0 + int(s[11:13]) * 3600 + int(s[14:16]) * 60 + float(s[17:])
    except (ValueError, IndexError):
        raise DataError(
            path, "time", f"line {k + 2}: {values[k]!r} is not a 'YYYY/MM/DD/HH:MM:SS.ffffff' time"
        ) from None
    return out


# ------------------------------------------------------------------------------ raw plausibility
def check_raw_imu(
    source: object, orientation_field: str, acc_field: str, q: np.ndarray, acc: np.ndarray | None
) -> None:
    """IMU messages after the scaling to units: unit quaternions (N, 4), accelerations (N, 3) in [g]
    within the accelerometer's range (:mod:`.plausibility`; None: not recorded); DataError otherwise."""
    tol = UNIT_QUATERNION_TOLERANCE
    check_norms(
        source,
        orientation_field,
        q,
        1 - tol,
        1 + tol,
        f"(after the Myo scaling 1/{MYO_ORIENTATION_SCALE:g})",
        what="message",
    )
    if acc is not None:
        check_norms(source, acc_field, acc, 0.0, ACCELERATION_MAX_G, "g", what="message")


def check_raw_endpoint(source: object, field: str, pose: np.ndarray) -> None:
    """End-point messages (N, 7): position x, y, z [m] near the robot, unit quaternion x, y, z, w."""
    tol = UNIT_QUATERNION_TOLERANCE
    check_norms(source, f"{field}.position", pose[:, :3], 0.0, POSITION_BOUND_M, "m", what="message")
    check_norms(source, f"{field}.orientation", pose[:, 3:7], 1 - tol, 1 + tol, "", what="message")


def stream_received(stream: RawStream | None) -> RawStream | None:
    """``stream`` without the messages never received (header stamp 0), or None when no message was."""
    if stream is None:
        return None
    ok = stream.header_s > 0
    if not np.any(ok):
        return None
    if np.all(ok):
        return stream
    return RawStream(stream.header_s[ok], stream.receive_s[ok], stream.values[ok], stream.source)


# ------------------------------------------------------------------------------- chen2017 assembly
@dataclass
class RawStream:
    """Messages of one topic as recorded.

    Attributes:
        header_s: Header stamps in [s] (sender clock), shape (N,).
        receive_s: Receive times in [s] (recording PC; may include a time-zone offset), shape (N,).
        values: Message fields, shape (N, D).
        source: File it came from.
    """

    header_s: np.ndarray
    receive_s: np.ndarray
    values: np.ndarray
    source: str


CHEN2017_FIELDS: dict[str, str] = {
    "orientation": ".quat0-3",
    "acc": ".acc0-2",
    "emg": ".ch0-7",
    "joints": ".position",
    "endpoint": ".pose",
}
"""The fields of the raw streams that error messages name (here the chen2017 message fields)."""


@dataclass
class RawRecording:
    """The streams of one recording (Myo EMG, Myo IMU, arm joints, end-point, tracked frames).

    ``joints.values`` holds the requested joints in the requested order; ``imu.values`` is (N, 7),
    the orientation quaternion w, x, y, z then the acceleration x, y, z, or (N, 4) without an
    acceleration (the demo then has no ``"acc"`` group), in the units that ``imu_scales`` divides
    into units (1 and [g]; default: the Myo's raw integers); ``endpoint`` (position xyz,
    quaternion xyzw) is optional: ``None`` when it was not recorded (no file, no message, or only
    messages stamped 0). ``tracked``: topics of tracked frames (skeleton, gripper), if any.
    ``fields``: the message fields of the streams, for error messages (:data:`CHEN2017_FIELDS`).
    """

    emg: RawStream
    imu: RawStream
    joints: RawStream
    endpoint: RawStream | None = None
    clock_offsets_s: dict[str, float] = field(default_factory=dict)
    imu_scales: tuple[float, float] = (MYO_ORIENTATION_SCALE, MYO_ACCELEROMETER_SCALE)
    tracked: list[TrackedTopic] = field(default_factory=list)
    fields: dict[str, str] = field(default_factory=lambda: dict(CHEN2017_FIELDS))


def select_joint_messages(
    source: object,
    names_per_msg: Sequence[Sequence[str]],
    robot_joints: Sequence[str],
) -> tuple[np.ndarray, list[int]]:
    """Which joint-state messages carry the arm, and where its joints are.

    Messages without every requested joint (e.g. Baxter's one-name gripper
    messages on the same topic) are dropped.

    Args:
        source: File for error messages.
        names_per_msg: Joint names of each message.
        robot_joints: Requested joint names, in the wanted order.

    Returns:
        ``(keep, columns)``: boolean mask over messages, and per requested joint
        its index in the kept messages' name list (the kept messages share one list).

    Raises:
        DataError: a requested joint is in no message, or the kept messages
            list the joints in different orders.
    """
    robot_joints = list(robot_joints)
    if not robot_joints:
        raise DataError(source, "robot_joints", "no robot joint requested")
    posed = pose_like(robot_joints)
    if posed:  # never a pose labelled as joint angles in [rad]
        raise DataError(
            source, "robot_joints", f"{', '.join(posed)} are a pose's channels, not joints: {GRIPPER_HINT}"
        )
    wanted = set(robot_joints)
    keep = np.zeros(len(names_per_msg), dtype=bool)
    layout: tuple[str, ...] | None = None
    seen: set[str] = set()
    for k, names in enumerate(names_per_msg):
        seen.update(names)
        if wanted.issubset(names):
            names = tuple(names)
            if layout is None:
                layout = names
            elif names != layout:
                # Same joints in another order would need per-message mapping; not seen in practice.
                raise DataError(source, ".name", f"message {k} lists joints {names}, earlier ones {layout}")
            keep[k] = True
    if layout is None:
        missing = [j for j in robot_joints if j not in seen]
        if missing:
            raise DataError(
                source,
                missing[0],
                f"unknown joint name (the joint states have: {', '.join(sorted(seen)) or 'none'})",
            )
        raise DataError(source, ".name", f"no single message carries all of the joints {robot_joints}")
    return keep, [layout.index(j) for j in robot_joints]


def clock_streams(raw: RawRecording, robot_joints: Sequence[str]) -> tuple[dict[str, Stream], float]:
    """The streams of ``raw`` (EMG, IMU, joints, end-point) on the recording PC's clock, checked.

    Each stream's clock offset (header stamp vs receive time, after removing a whole-quarter-hour
    time-zone difference) is estimated and removed (stored in ``raw.clock_offsets_s``); the raw EMG,
    the IMU after its scaling, the joint angles and the end-point poses are checked against their
    physical limits.

    Returns:
        The streams to align (:func:`recorded_streams`) and the time-zone difference in [s].
    """
    raw.endpoint = stream_received(raw.endpoint)
    streams = {"emg": raw.emg, "imu": raw.imu, "robot": raw.joints}
    if raw.endpoint is not None:
        streams["endpoint"] = raw.endpoint
    for key, s in streams.items():
        if s.header_s.size == 0:
            raise DataError(s.source, key, "stream is empty")
    # Time-zone part of (header - receive): shared by all streams, a multiple of 15 min.
    medians = [float(np.median(s.header_s - s.receive_s)) for s in streams.values()]
    tz = TIMEZONE_STEP_S * np.round(np.median(medians) / TIMEZONE_STEP_S)
    offsets = {k: estimate_clock_offset(s.header_s, s.receive_s + tz) for k, s in streams.items()}
    raw.clock_offsets_s.update(offsets)

    imu, (q_scale, acc_scale), fields = raw.imu.values, raw.imu_scales, raw.fields
    q_raw = imu[:, :4] / q_scale
    acc = imu[:, 4:7] / acc_scale if imu.shape[1] >= 7 else None
    check_raw_imu(raw.imu.source, fields["orientation"], fields["acc"], q_raw, acc)
    check_range(
        raw.emg.source, fields["emg"], raw.emg.values, *EMG_RAW_RANGE, "", EMG_CHANNELS, what="message"
    )
    check_joint_angles(raw.joints.source, fields["joints"], raw.joints.values, robot_joints, what="message")
    if raw.endpoint is not None:
        check_raw_endpoint(raw.endpoint.source, fields["endpoint"], raw.endpoint.values)
    on_pc = {k: s.header_s - offsets[k] for k, s in streams.items()}
    sources = {k: s.source for k, s in streams.items()}
    ep = None if raw.endpoint is None else raw.endpoint.values
    streams_out = recorded_streams(
        on_pc, raw.emg.values, q_raw, acc, raw.joints.values, robot_joints, ep, sources
    )
    return streams_out, float(tz)


def assemble_recording(
    raw: RawRecording,
    *,
    task: str,
    name: str,
    source: object,
    rate_hz: float,
    robot_joints: Sequence[str],
    emg_cutoff_hz: float = DEFAULT_EMG_CUTOFF_HZ,
    frames: Sequence[str] = (),
    end_effector: Callable[[np.ndarray], np.ndarray] | None = None,
) -> Demo:
    """Build a :class:`Demo` from the raw streams of a recording.

    The streams are put on the recording PC's clock (:func:`clock_streams`; tracked frames with
    their topic's offset); the demo spans the streams' overlap on a uniform grid at ``rate_hz``. The
    EMG is sample-and-hold resampled then turned into a causal envelope; quaternions are made
    unit-norm and sign-continuous. With tracked frames: the requested ``frames`` as groups, the
    skeleton and the hand as extras (:mod:`.tracked`; ``end_effector`` as there).

    Raises:
        DataError: implausible or unsynchronised streams, a requested frame that was not tracked.
    """
    aligned_in, tz = clock_streams(raw, robot_joints)
    frames = list(frames)
    if raw.tracked:
        tracks: dict[str, FrameTrack] = {}
        for topic in raw.tracked:
            t_pc = topic.header_s - estimate_clock_offset(topic.header_s, topic.receive_s + tz)
            for f, pos in topic.positions.items():
                tracks.setdefault(f, FrameTrack(t_pc, pos))
        with_gripper = "endpoint_position" not in aligned_in
        reserved = set(aligned_in) | {"hand_position"}
        aligned_in.update(frame_streams(source, tracks, frames, reserved, with_gripper, sorted(tracks)))
    elif frames:
        raise DataError(source, frames[0], "frame never tracked (the recording has no tracked frames)")
    t, values, _ = align_streams(aligned_in, rate_hz, source)
    groups, names = myo_groups(values, rate_hz, emg_cutoff_hz)
    missing: dict[str, np.ndarray] = {}
    if raw.tracked:
        frame_values, frame_names, missing = frame_groups(source, values, frames)
        groups.update(frame_values)
        names.update(frame_names)
    groups[ROBOT] = values[ROBOT]
    names[ROBOT] = tuple(robot_joints)
    extras = endpoint_extras(values)
    if raw.tracked:
        frame_extras(t, values, extras, end_effector)
    return Demo(
        task=task,
        name=name,
        source=str(source),
        t=t,
        groups=groups,
        channel_names=names,
        missing=missing,
        extras=extras,
    )


def recorded_streams(
    t: dict[str, np.ndarray],
    emg: np.ndarray,
    orientation: np.ndarray,
    acc: np.ndarray | None,
    joints: np.ndarray,
    robot_joints: Sequence[str],
    endpoint: np.ndarray | None,
    sources: dict[str, str],
) -> dict[str, Stream]:
    """The streams a reader aligns: raw EMG, Myo orientation and acceleration, the robot's joints
    and the optional end-point, with the interpolation kinds of their channel groups.

    Args:
        t: Stream (``"emg"``, ``"imu"``, ``"robot"``, ``"endpoint"``) -> its times on the
            recording PC's clock in [s], shape (N_stream,).
        emg: Raw EMG samples (N_emg, 8).
        orientation: Unit quaternions w, x, y, z (N_imu, 4) (made sign-continuous here).
        acc: Accelerations (N_imu, 3) in [g], or None (not recorded: no ``"acc"`` stream).
        joints: Joint angles (N_robot, J) in [rad] of ``robot_joints``.
        endpoint: End-point poses (N_endpoint, 7), position [m] and quaternion x, y, z, w, or None.
        sources: Stream -> file it came from.
    """
    out = {
        "emg": Stream(t["emg"], emg, EMG.channels, EMG.raw_kind, sources["emg"]),
        "orientation": Stream(
            t["imu"],
            quaternion_continuity(orientation),
            ORIENTATION.channels,
            ORIENTATION.raw_kind,
            sources["imu"],
        ),
    }
    if acc is not None:
        out["acc"] = Stream(t["imu"], acc, ACC.channels, ACC.raw_kind, sources["imu"])
    out[ROBOT] = Stream(t["robot"], joints, tuple(robot_joints), ROBOT_GROUP.raw_kind, sources["robot"])
    if endpoint is not None:
        ep_t, src = t["endpoint"], sources["endpoint"]
        out["endpoint_position"] = Stream(
            ep_t, endpoint[:, :3], SKELETON_FRAME.channels, SKELETON_FRAME.raw_kind, src
        )
        out["endpoint_orientation"] = Stream(
            ep_t, endpoint[:, 3:7], ("qx", "qy", "qz", "qw"), ORIENTATION.raw_kind, src
        )
    return out


def myo_groups(
    values: dict[str, np.ndarray], rate_hz: float, emg_cutoff_hz: float
) -> tuple[dict[str, np.ndarray], dict[str, tuple[str, ...]]]:
    """The demo's Myo groups from the aligned streams: ``"orientation"``, ``"emg"`` (the causal
    envelope of the held raw EMG, cut-off ``emg_cutoff_hz`` [Hz]) and ``"acc"`` (when recorded),
    with their channel names."""
    groups = {
        "orientation": values["orientation"],
        "emg": emg_envelope(values["emg"], 1.0 / rate_hz, emg_cutoff_hz),
    }
    names = {"orientation": ORIENTATION.channels, "emg": EMG.channels}
    if "acc" in values:
        groups["acc"] = values["acc"]
        names["acc"] = ACC.channels
    return groups, names


def endpoint_extras(values: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``{"endpoint_pose": (T, 7)}`` from the aligned end-point streams, or ``{}`` without them."""
    if "endpoint_position" not in values:
        return {}
    return {"endpoint_pose": np.hstack([values["endpoint_position"], values["endpoint_orientation"]])}


def full_duration_s(demo: Demo) -> float:
    """The demo's full duration in [s] (``Demo`` sets it when built; DataError if it is missing)."""
    if demo.duration_s is None:
        raise DataError(demo.source, "duration_s", "the demo has no duration")
    return float(demo.duration_s)
