"""Reader of ``multiModal_states.csv`` recordings (handover_20171128: skeleton + Myo + Baxter).

Layout: ``<task>/csv/<stamp>/multiModal_states.csv``, one synchronised message
stream (~50 Hz, ``rostopic echo -p`` style, ``field.`` prefixes) bundling the
latest Myo EMG (``emgStates.ch0..7``), Myo IMU (``imuStates``), Baxter left
end-point (``endpointStates``), joint states (``jointStates.name0..16`` /
``position0..16``) and the tracked frames ``tf_of_interest.transformsK``.

Time base. ``%time`` is the recording PC's receive time and
``field.header.stamp`` the synchroniser's stamp (PC clock). Each bundled
message keeps its own header stamp: a stale message is repeated in
consecutive rows with the same stamp (only its first row is used), and the
robot's messages carry the robot's clock. So every sub-stream is put on its own
stamps, mapped onto the PC clock with the offset estimated against ``%time``
(:func:`~ipromp_pin.signals.preprocess.estimate_clock_offset`; about +0.02-0.05 s for
the robot in this session, ~0 for the Myo). The tracked frames have no stamps
(header stamp 0) and use ``field.header.stamp``. Then all streams are resampled
onto a uniform ``rate_hz`` grid spanning their overlap, ``t`` from 0.

Tracked frames. Which ``transformsK`` holds which frame is read from its
``child_frame_id`` per row (rows may list fewer frames). A requested frame
(``frames=["/left_hand_1"]``) becomes a group of positions x, y, z [m] in the
``frame_id`` frame (``/base``, Baxter's base frame). Samples are missing (NaN in
the group, True in ``Demo.missing``) where the frame is not listed, its
translation is (0, 0, 0) (the recorders' publishing bug leaves transforms at all zeros; a
translation of zeros with a rotation is no position either), or it jumps: more than
:data:`JUMP_THRESHOLD_M` from the component-wise median of the
:data:`JUMP_WINDOW` valid samples centred on it (an isolated spike of at most 2
samples; the tracker's genuine catch-up steps after a stall, up to ~0.4 m
between rows in these recordings, persist and are kept). A grid sample is
missing when a neighbouring source sample is.

Groups: ``"emg"`` (envelope, as for chen2017), ``"orientation"`` (``imuStates
.orientation`` raw Myo ints / 16384, here the fields are labelled correctly:
w = ``orientation.w``, checked against the accelerometer's gravity direction,
|cos| = 0.999), ``"acc"`` ([g]), the requested frames, ``"robot"``.
Extras: ``"endpoint_pose"`` (T, 7) and ``"hand_position"`` (T, 3): the human hand
frame (``/left_hand_1`` or ``/right_hand_1``, whichever ends closer to the robot's
end-point; in this session always ``/left_hand_1``), gaps linearly filled
(extras are for previews).
``"skeleton:<frame>"`` (T, 3) for every tracked skeleton frame of the file (NaN where missing, as
for a group): the human body of the safety checks (:mod:`ipromp_pin.human.body`).

Optional streams. The robot's end-point (``endpointStates``) is not modelled: it serves the
calibration and the choice of the handing hand. In sessions where it was never recorded (every
``endpointStates.header.stamp`` is 0) the demo loads without ``"endpoint_pose"``; the hand is then
chosen against the tracked gripper frame (:data:`GRIPPER_FRAMES`, the same position as the
end-point: 1.3 mm apart in this session), or else against the forward kinematics of the recorded
joints when the caller passes ``end_effector``; without either, the demo has no
``"hand_position"``. The tracked frames are optional as well (only requested ones must be there).
The EMG, IMU and joint streams are required.

Plausibility. Raw EMG samples, accelerations, end-point positions and quaternions are checked
against the physical limits of :mod:`.plausibility` (as are the resampled demo's joint angles and
tracked positions, by :func:`ipromp_pin.readers.read_demo`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..data import ROBOT, Demo
from ..exceptions import DataError
from ..signals.checks import EMG_RAW_RANGE, check_joint_angles, check_range
from ..signals.groups import EMG
from ..signals.preprocess import DEFAULT_EMG_CUTOFF_HZ, Stream, align_streams, estimate_clock_offset
from .streams import (
    BAXTER_LEFT_JOINTS,
    MYO_ACCELEROMETER_SCALE,
    MYO_ORIENTATION_SCALE,
    CsvTable,
    check_raw_endpoint,
    check_raw_imu,
    endpoint_extras,
    myo_groups,
    recorded_streams,
    select_joint_messages,
)
from .tracked import (
    GRIPPER_FRAMES,
    HAND_FRAMES,
    JUMP_THRESHOLD_M,
    JUMP_WINDOW,
    SKELETON_EXTRA,
    FrameTrack,
    flag_jumps,
    frame_extras,
    frame_groups,
    frame_streams,
    is_skeleton_frame,
    needed_frames,
)

__all__ = [  # the tracked-frame names live in .tracked since the rosbag2 reader shares them
    "FILE_NAME",
    "GRIPPER_FRAMES",
    "HAND_FRAMES",
    "JUMP_THRESHOLD_M",
    "JUMP_WINDOW",
    "SKELETON_EXTRA",
    "flag_jumps",
    "is_multimodal_folder",
    "list_demos",
    "read_demo",
]

FILE_NAME = "multiModal_states.csv"
N_TRANSFORMS_MAX = 64

P = "field."


def is_multimodal_folder(folder: Path) -> bool:
    """Whether ``folder`` holds ``csv/<stamp>/multiModal_states.csv`` demos."""
    csv_dir = Path(folder) / "csv"
    return csv_dir.is_dir() and any(csv_dir.glob(f"*/{FILE_NAME}"))


def list_demos(folder: Path, order: str = "config") -> list[Path]:
    """The demo files of a task folder, by stamp (there is no cfg file in this format)."""
    if order not in ("config", "recorded"):
        raise DataError(folder, "order", f"unknown demo order {order!r} (use 'config' or 'recorded')")
    return sorted((Path(folder) / "csv").glob(f"*/{FILE_NAME}"))


def _stamps(table: CsvTable, column: str) -> np.ndarray:
    """Header stamps in [s] (ROS ``rostopic -p`` writes nanoseconds)."""
    v = table.numbers([column])[:, 0]
    return v * 1e-9


def _optional_sub_stream(
    table: CsvTable, stamp_column: str, columns: Sequence[str], receive: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(header stamps, receive times, values) of a bundled message, without never-received rows;
    None when no message of the stream was received."""
    header = _stamps(table, stamp_column)
    ok = header > 0
    if not np.any(ok):
        return None
    values = table.numbers(columns)
    return header[ok], receive[ok], values[ok]


def _sub_stream(
    table: CsvTable, stamp_column: str, columns: Sequence[str], receive: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """As :func:`_optional_sub_stream`, for a stream that must have been received (else DataError)."""
    stream = _optional_sub_stream(table, stamp_column, columns, receive)
    if stream is None:
        raise DataError(table.path, stamp_column, "no message of this stream was received (all stamps 0)")
    return stream


def _find_transforms(table: CsvTable) -> list[str]:
    prefixes = []
    for k in range(N_TRANSFORMS_MAX):
        p = f"{P}tf_of_interest.transforms{k}."
        if table.has(p + "child_frame_id"):
            prefixes.append(p)
    return prefixes


def _frame_rows(table: CsvTable, prefixes: list[str]) -> dict[str, dict[str, list[int]]]:
    """Per transform prefix: frame id -> the rows that list it there."""
    out: dict[str, dict[str, list[int]]] = {}
    for p in prefixes:
        rows: dict[str, list[int]] = {}
        for i, s in enumerate(table.text(p + "child_frame_id")):
            rows.setdefault(s.strip(), []).append(i)
        out[p] = rows
    return out


def _frame_positions(
    table: CsvTable, listed: dict[str, dict[str, list[int]]], frame: str
) -> np.ndarray | None:
    """Positions (N, 3) of ``frame`` with NaN where it is not listed or its translation is (0, 0, 0)
    (the publishing bug's all-zero transform, also when its rotation is not zero); None if never
    listed. ``listed``: :func:`_frame_rows`."""
    n = len(table)
    pos = np.full((n, 3), np.nan)
    found = False
    for p, frames in listed.items():
        rows = frames.get(frame)
        if not rows:
            continue
        found = True
        cols = [p + f"transform.translation.{a}" for a in "xyz"] + [
            p + f"transform.rotation.{a}" for a in "xyzw"
        ]
        idx = [table.index(c) for c in cols]
        try:
            v = np.array([[table.rows[r][i] for i in idx] for r in rows], dtype=float)
        except ValueError:
            raise DataError(table.path, p + "transform", f"non-numeric value for frame {frame!r}") from None
        # no position at the base frame's origin, whatever the rotation
        zero = np.all(v[:, :3] == 0.0, axis=1)
        v[zero] = np.nan
        pos[rows] = v[:, :3]
    return pos if found else None


def _joint_stream(
    table: CsvTable, receive: np.ndarray, robot_joints: Sequence[str]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(header stamps, receive times, angles (N, J) of ``robot_joints``) of the joint-state messages
    that carry the arm (joints found by name, per row)."""
    path = table.path
    name_cols = []
    k = 0
    while table.has(f"{P}jointStates.name{k}"):
        name_cols.append(f"{P}jointStates.name{k}")
        k += 1
    if not name_cols:
        raise DataError(path, P + "jointStates.name0", "missing column")
    name_text = [table.text(c) for c in name_cols]
    names_per_row = [tuple(n[r] for n in name_text if n[r]) for r in range(len(table))]
    keep, cols = select_joint_messages(path, names_per_row, robot_joints)
    pos_cols = [f"{P}jointStates.position{k}" for k in range(len(name_cols))]
    layout_len = len(names_per_row[int(np.flatnonzero(keep)[0])])
    jpos = table.numbers(pos_cols[:layout_len])
    j_h_all = _stamps(table, P + "jointStates.header.stamp")
    keep &= j_h_all > 0
    j_h, j_r, jpos = j_h_all[keep], receive[keep], jpos[keep][:, cols]
    check_joint_angles(path, P + "jointStates.position", jpos, robot_joints, what="message")
    return j_h, j_r, jpos


def _message_streams(table: CsvTable, receive: np.ndarray, robot_joints: Sequence[str]) -> dict[str, Stream]:
    """The bundled Myo, joint and (when recorded) end-point streams on the PC's clock, checked."""
    path = table.path
    emg_h, emg_r, emg = _sub_stream(
        table, P + "emgStates.header.stamp", [f"{P}emgStates.ch{i}" for i in range(8)], receive
    )
    imu_cols = [f"{P}imuStates.orientation.{a}" for a in "wxyz"]
    imu_cols += [f"{P}imuStates.linear_acceleration.{a}" for a in "xyz"]
    imu_h, imu_r, imu = _sub_stream(table, P + "imuStates.header.stamp", imu_cols, receive)
    ep_cols = [f"{P}endpointStates.pose.position.{a}" for a in "xyz"]
    ep_cols += [f"{P}endpointStates.pose.orientation.{a}" for a in "xyzw"]
    endpoint = _optional_sub_stream(table, P + "endpointStates.header.stamp", ep_cols, receive)
    check_range(path, P + "emgStates", emg, *EMG_RAW_RANGE, "", EMG.channels, what="message")
    j_h, j_r, jpos = _joint_stream(table, receive, robot_joints)

    # Orientation and acceleration sanity (raw Myo ints), end-point positions and quaternions.
    q = imu[:, :4] / MYO_ORIENTATION_SCALE
    acc = imu[:, 4:7] / MYO_ACCELEROMETER_SCALE
    check_raw_imu(path, P + "imuStates.orientation", P + "imuStates.linear_acceleration", q, acc)
    if endpoint is not None:
        check_raw_endpoint(path, P + "endpointStates.pose", endpoint[2])

    def on_pc(h: np.ndarray, r: np.ndarray) -> np.ndarray:
        return h - estimate_clock_offset(h, r)

    t = {"emg": on_pc(emg_h, emg_r), "imu": on_pc(imu_h, imu_r), "robot": on_pc(j_h, j_r)}
    if endpoint is not None:
        t["endpoint"] = on_pc(endpoint[0], endpoint[1])
    src = str(path)
    sources = dict.fromkeys(("emg", "imu", "robot", "endpoint"), src)
    ep = None if endpoint is None else endpoint[2]
    return recorded_streams(t, emg, q, acc, jpos, robot_joints, ep, sources)


def _frame_tracks(
    table: CsvTable, prefixes: list[str], frames: list[str], t: np.ndarray, with_gripper: bool
) -> dict[str, FrameTrack]:
    """The tracks of the frames :func:`.tracked.frame_streams` reads (the requested frames, the hand
    frames, with ``with_gripper`` the gripper frames, every skeleton frame) that the file lists, on the
    skeleton's time base ``t`` [s]."""
    tracks = {}
    listed = _frame_rows(table, prefixes)
    skeleton = sorted({f for rows in listed.values() for f in rows if is_skeleton_frame(f)})
    for f in needed_frames(frames, skeleton, with_gripper):
        p = _frame_positions(table, listed, f)
        if p is not None:
            tracks[f] = FrameTrack(t, p)
    return tracks


def read_demo(
    path: Path,
    task: str | None = None,
    *,
    frames: Sequence[str] | None = None,
    rate_hz: float = 50.0,
    robot_joints: Sequence[str] = BAXTER_LEFT_JOINTS,
    emg_cutoff_hz: float = DEFAULT_EMG_CUTOFF_HZ,
    end_effector: Callable[[np.ndarray], np.ndarray] | None = None,
) -> Demo:
    """Read one ``multiModal_states.csv`` demo.

    Args:
        path: The CSV file or its folder ``<task>/csv/<stamp>``.
        task: Task name (default: the task folder's name).
        frames: Tracked frames (``child_frame_id``) to add as human position groups.
        rate_hz: Output sampling rate in [Hz].
        robot_joints: Joint names of the robot group, in the wanted order.
        emg_cutoff_hz: EMG envelope cut-off in [Hz].
        end_effector: Forward kinematics of the robot group, (T, J) [rad] -> (T, 3) [m]; chooses the
            handing hand when neither the end-point nor the gripper frame was recorded.
    """
    path = Path(path)
    if path.is_dir():
        path = path / FILE_NAME
    table = CsvTable(path)
    if len(table) < 2:
        raise DataError(path, None, f"a demo needs at least 2 messages, got {len(table)}")
    src = str(path)
    receive = _stamps(table, "%time")
    pc_stamp = _stamps(table, P + "header.stamp")
    streams = _message_streams(table, receive, robot_joints)
    sk_t = pc_stamp - estimate_clock_offset(pc_stamp, receive)
    frames = list(frames or [])
    with_gripper = "endpoint_position" not in streams
    prefixes = _find_transforms(table)
    available = sorted({s for pr in prefixes for s in table.text(pr + "child_frame_id") if s})
    tracks = _frame_tracks(table, prefixes, frames, sk_t, with_gripper)
    reserved = set(streams) | {"hand_position"}
    streams.update(frame_streams(path, tracks, frames, reserved, with_gripper, available))

    t, values, _ = align_streams(streams, rate_hz, src)
    groups, names = myo_groups(values, rate_hz, emg_cutoff_hz)
    frame_values, frame_names, missing = frame_groups(path, values, frames)
    groups.update(frame_values)
    names.update(frame_names)
    groups[ROBOT] = values[ROBOT]
    names[ROBOT] = tuple(robot_joints)
    extras = endpoint_extras(values)
    frame_extras(t, values, extras, end_effector)
    return Demo(
        task=task if task is not None else path.parent.parent.parent.name,
        name=path.parent.name,
        source=src,
        t=t,
        groups=groups,
        channel_names=names,
        missing=missing,
        extras=extras,
    )
