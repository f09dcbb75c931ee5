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
from ..signals.checks import EMG_RAW_RANGE, POSITION_BOUND_M, check_joint_angles, check_norms, check_range
from ..signals.groups import EMG
from ..signals.groups import SKELETON_FRAME as FRAME
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

FILE_NAME = "multiModal_states.csv"
JUMP_THRESHOLD_M = 0.25
"""A tracked position farther than this from the median of its neighbours is a jump (missing), in [m]."""
JUMP_WINDOW = 5
"""Number of valid samples (centred) whose median a tracked position is compared with."""
HAND_FRAMES = ("/left_hand_1", "/right_hand_1")
SKELETON_EXTRA = "skeleton:"
"""Prefix of the extras holding every tracked skeleton frame (``"skeleton:/head_1"`` ...): positions
(T, 3) [m], NaN where the frame is not listed, all-zero or a jump (the body model of
:mod:`ipromp_pin.human.body` reads them; they are not modelled)."""
GRIPPER_FRAMES = ("left_gripper", "/left_gripper")
"""Tracked frames at the robot's end-point (the tf of Baxter's left gripper), used to choose the
handing hand when the end-point stream was not recorded."""
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


def _frame_positions(table: CsvTable, prefixes: list[str], frame: str) -> np.ndarray | None:
    """Positions (N, 3) of ``frame`` with NaN where it is not listed or its translation is (0, 0, 0)
    (the publishing bug's all-zero transform, also when its rotation is not zero); None if never listed."""
    n = len(table)
    pos = np.full((n, 3), np.nan)
    found = False
    for p in prefixes:
        ids = table.text(p + "child_frame_id")
        rows = [i for i, s in enumerate(ids) if s.strip() == frame]
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


def flag_jumps(
    pos: np.ndarray, threshold_m: float = JUMP_THRESHOLD_M, window: int = JUMP_WINDOW
) -> np.ndarray:
    """Mask (N,) of tracked positions (N, 3) farther than ``threshold_m`` from the median of the
    ``window`` valid samples centred on them (isolated spikes); NaN rows are not flagged."""
    valid = np.flatnonzero(np.all(np.isfinite(pos), axis=1))
    out = np.zeros(pos.shape[0], dtype=bool)
    if valid.size < 3:
        return out
    v = pos[valid]
    h = window // 2
    padded = np.concatenate([np.repeat(v[:1], h, 0), v, np.repeat(v[-1:], h, 0)])
    windows = np.stack([padded[i : i + v.shape[0]] for i in range(window)], axis=0)
    med = np.median(windows, axis=0)
    out[valid] = np.linalg.norm(v - med, axis=1) > threshold_m
    return out


def _fill_gaps(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    ok = np.all(np.isfinite(x), axis=1)
    if ok.all() or ok.sum() < 2:
        return x
    return np.stack([np.interp(t, t[ok], x[ok, j]) for j in range(x.shape[1])], axis=1)


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


def _frame_streams(
    table: CsvTable, frames: list[str], t: np.ndarray, reserved: set[str], with_gripper: bool
) -> dict[str, Stream]:
    """Streams ``"frame:<f>"`` of the requested frames, the hand frames and (``with_gripper``) the
    gripper frames, on the skeleton's time base ``t`` [s]; jumps and untracked samples missing."""
    path = table.path
    for f in frames:
        if f in reserved:
            raise DataError(path, f, "frame name clashes with a channel group name")
    prefixes = _find_transforms(table)
    out = {}
    gripper = list(GRIPPER_FRAMES) if with_gripper else []
    skeleton = _skeleton_frames(table, prefixes)
    for f in dict.fromkeys(frames + list(HAND_FRAMES) + gripper + skeleton):
        p = _frame_positions(table, prefixes, f)
        if p is not None:
            check_norms(path, f, p, 0.0, POSITION_BOUND_M, "m", what="row")
        if p is None:
            if f in frames:
                available = sorted({s for pr in prefixes for s in table.text(pr + "child_frame_id") if s})
                raise DataError(path, f, f"frame never tracked (child_frame_ids: {', '.join(available)})")
            continue
        p[flag_jumps(p)] = np.nan
        if np.sum(np.all(np.isfinite(p), axis=1)) < 2:
            if f in frames:
                raise DataError(path, f, "fewer than 2 valid samples of the frame")
            continue
        out["frame:" + f] = Stream(t, p, FRAME.channels, FRAME.raw_kind, str(path), allow_missing=True)
    return out


def _skeleton_frames(table: CsvTable, prefixes: list[str]) -> list[str]:
    """The tracked skeleton frames of the file (``child_frame_id`` starting with ``/``, not the gripper)."""
    ids = {s.strip() for p in prefixes for s in table.text(p + "child_frame_id")}
    return sorted(f for f in ids if f.startswith("/") and f not in GRIPPER_FRAMES)


def _hand_position(
    t: np.ndarray,
    values: dict[str, np.ndarray],
    reference: np.ndarray | None,
) -> np.ndarray | None:
    """The hand frame that ends closest to ``reference`` (T, 3) [m], gaps filled; None without one."""
    best, best_d = None, np.inf
    for f in HAND_FRAMES:
        v = values.get("frame:" + f)
        if v is None or reference is None:
            continue
        tail = slice(int(0.8 * t.size), None)
        d = np.linalg.norm(v[tail] - reference[tail], axis=1)
        d = float(np.nanmedian(d)) if np.any(np.isfinite(d)) else np.inf
        if d < best_d:
            best, best_d = v, d
    if best is not None and np.sum(np.all(np.isfinite(best), axis=1)) >= 2:
        return _fill_gaps(t, best)
    return None


def _gripper_reference(
    t: np.ndarray,
    values: dict[str, np.ndarray],
    extras: dict[str, np.ndarray],
    end_effector: Callable[[np.ndarray], np.ndarray] | None,
) -> np.ndarray | None:
    """Where the robot's gripper is (T, 3) [m]: the end-point, else a tracked gripper frame, else the
    forward kinematics ``end_effector`` of the joints; None without any."""
    if "endpoint_pose" in extras:
        return extras["endpoint_pose"][:, :3]
    for f in GRIPPER_FRAMES:
        v = values.get("frame:" + f)
        if v is not None and np.any(np.all(np.isfinite(v[int(0.8 * t.size) :]), axis=1)):
            return v
    if end_effector is not None:
        return np.asarray(end_effector(values[ROBOT]), dtype=float).reshape(t.size, 3)
    return None


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
    reserved = set(streams) | {"hand_position"}
    streams.update(_frame_streams(table, frames, sk_t, reserved, "endpoint_position" not in streams))

    t, values, _ = align_streams(streams, rate_hz, src)
    groups, names = myo_groups(values, rate_hz, emg_cutoff_hz)
    missing = {}
    for f in frames:
        v = values["frame:" + f]
        groups[f] = v
        names[f] = FRAME.channels
        m = ~np.all(np.isfinite(v), axis=1)
        if m.all():
            raise DataError(path, f, "frame missing over the whole demo")
        v[m] = np.nan
        if m.any():
            missing[f] = m
    groups[ROBOT] = values[ROBOT]
    names[ROBOT] = tuple(robot_joints)
    extras = endpoint_extras(values)
    for name, v in values.items():
        if name.startswith("frame:/") and name[len("frame:") :] not in GRIPPER_FRAMES:
            extras[SKELETON_EXTRA + name[len("frame:") :]] = v
    hand = _hand_position(t, values, _gripper_reference(t, values, extras, end_effector))
    if hand is not None:
        extras["hand_position"] = hand
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
