"""Trajectory files: CSV with named columns and JSON holding a ROS ``JointTrajectory`` message.

CSV: header ``time_s``, then ``q.<joint>`` for every joint, ``qd.<joint>``, ``qdd.<joint>``; one row per
sample; numbers written with 17 significant digits so they read back exactly.

JSON: the message with the field names of ROS 2 ``trajectory_msgs/msg/JointTrajectory`` (default)
or of ROS 1 ``trajectory_msgs/JointTrajectory`` (``ros=1``), inside a small envelope that says
which::

    {"format": "ipromp_pin.trajectory", "version": 3, "ros": 2,
     "type": "trajectory_msgs/msg/JointTrajectory",
     "clock": {"t0": "start of the human's motion", "robot_start_s": 0.64},
     "message": {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""},
                 "joint_names": [...],
                 "points": [{"positions": [...], "velocities": [...], "accelerations": [...],
                             "effort": [], "time_from_start": {"sec": 1, "nanosec": 250000000}}, ...]}}

Every time is on the human's clock: ``time_from_start`` counts from the start of the human's
motion (the header's stamp is 0: "now" for a controller that receives it then), so the first point,
the robot at rest, comes at ``clock.robot_start_s``, when the observation ended and the robot starts.
A controller that receives it only then subtracts ``robot_start_s``. ``trajectory.csv``'s ``time_s``
is on the same clock.

ROS 1 form: ``"ros": 1``, ``"type": "trajectory_msgs/JointTrajectory"``, a header with ``seq`` and
times as ``{"secs": .., "nsecs": ..}``. ``message`` is exactly the message (no other keys), so
``rosidl_runtime_py.set_message_fields(JointTrajectory(), doc["message"])`` (ROS 2) or
``rospy_message_converter`` (ROS 1) builds it. The readers accept both forms, with or without the
envelope (files of version 1 were the bare ROS 1 message). Times are split into integer seconds
and nanoseconds, so they round to 1 ns on reading.

Files are written atomically (:mod:`ipromp_pin.atomic`): a temporary file in the same folder,
renamed into place when complete. The ``*_text`` functions give the content, for callers that
stage several files together (:class:`ipromp_pin.atomic.OutputSet`).

Marked files. A trajectory whose checks failed is written only when the user asks for it
(``ipromp-pin run --allow-failing-checks``), and then marked: the CSV starts with a comment line
``# ipromp_pin: ...`` (which :func:`read_trajectory_csv` skips) and the JSON's envelope has an
``"ipromp_pin_checks"`` object (``{"passed": false, "failures": [...]}``) beside ``message``.
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

import numpy as np

from .. import atomic
from ..exceptions import DataError
from ..motion.trajectory import Trajectory


def _check(traj: Trajectory) -> None:
    n = len(traj.joint_names)
    for name in ("q", "qd", "qdd"):
        v = getattr(traj, name)
        if v.shape != (traj.t_s.size, n):
            raise DataError(
                None, name, f"shape {v.shape} does not match {traj.t_s.size} samples x {n} joints"
            )
        if not np.all(np.isfinite(v)):
            raise DataError(None, name, "NaN or inf values")
    if not np.all(np.isfinite(traj.t_s)) or np.any(np.diff(traj.t_s) <= 0):
        raise DataError(None, "time_s", "times must be finite and strictly increasing")


def trajectory_csv_text(traj: Trajectory, comment: str | None = None) -> str:
    """The CSV content of ``traj`` (see :func:`write_trajectory_csv`); ``comment`` (one line) is
    written first as ``# <comment>``."""
    _check(traj)
    names = list(traj.joint_names)
    header = ["time_s"] + [f"{p}.{j}" for p in ("q", "qd", "qdd") for j in names]
    data = np.column_stack([traj.t_s, traj.q, traj.qd, traj.qdd])
    buf = io.StringIO()
    if comment is not None:
        buf.write("# " + " ".join(comment.splitlines()) + "\n")
    # %.17g round-trips every float64 exactly
    np.savetxt(buf, data, fmt="%.17g", delimiter=",", header=",".join(header), comments="")
    return buf.getvalue()


def write_trajectory_csv(traj: Trajectory, path: str | Path, comment: str | None = None) -> Path:
    """Write ``traj`` as CSV (columns ``time_s``, ``q.<joint>``..., ``qd.<joint>``..., ``qdd.<joint>``...),
    atomically; ``comment`` (one line) is written first as ``# <comment>``."""
    return atomic.write_text(path, trajectory_csv_text(traj, comment))


def read_trajectory_csv(path: str | Path) -> Trajectory:
    """Read a CSV written by :func:`write_trajectory_csv`.

    Raises:
        DataError: missing/unknown columns, non-numeric values, inconsistent joints.
    """
    path = Path(path)
    try:
        with open(path, newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise DataError(path, None, f"cannot read: {exc}") from exc
    while rows and rows[0][:1] and rows[0][0].startswith("#"):
        rows.pop(0)  # comment lines (a marked file)
    if not rows or rows[0][:1] != ["time_s"]:
        raise DataError(path, "time_s", "first column must be 'time_s'")
    header = rows[0]
    groups: dict[str, list[str]] = {"q": [], "qd": [], "qdd": []}
    for col in header[1:]:
        prefix, _, joint = col.partition(".")
        if prefix not in groups or not joint:
            raise DataError(path, col, "unknown column (expected q.<joint>, qd.<joint>, qdd.<joint>)")
        groups[prefix].append(joint)
    names = groups["q"]
    if not names or groups["qd"] != names or groups["qdd"] != names:
        raise DataError(path, None, "q., qd. and qdd. columns must name the same joints in the same order")
    try:
        data = np.array([[float(x) for x in r] for r in rows[1:] if r], dtype=float)
    except ValueError as exc:
        raise DataError(path, None, f"non-numeric value: {exc}") from exc
    if data.ndim != 2 or data.shape[0] == 0 or data.shape[1] != len(header):
        raise DataError(path, None, "no rows, or rows of the wrong length")
    n = len(names)
    traj = Trajectory(
        data[:, 0], data[:, 1 : 1 + n], data[:, 1 + n : 1 + 2 * n], data[:, 1 + 2 * n :], tuple(names)
    )
    try:
        _check(traj)
    except DataError as exc:
        raise DataError(path, exc.field, exc.problem) from exc
    return traj


TRAJECTORY_FORMAT = "ipromp_pin.trajectory"
"""Value of ``trajectory.json``'s ``format`` field."""

TRAJECTORY_VERSION = 3
"""Value of ``trajectory.json``'s ``version`` field (1: the bare ROS 1 message, no envelope)."""

ROS_TYPES = {1: "trajectory_msgs/JointTrajectory", 2: "trajectory_msgs/msg/JointTrajectory"}
"""The message type named in the envelope, per ROS version."""

_TIME_KEYS = {1: ("secs", "nsecs"), 2: ("sec", "nanosec")}


def _check_ros(ros: int) -> int:
    if ros not in ROS_TYPES:
        raise DataError(None, "ros", f"ROS version must be 1 or 2, got {ros!r}")
    return int(ros)


def _duration(t: float, ros: int = 2) -> dict[str, int]:
    ns = int(round(t * 1e9))
    sec, nsec = _TIME_KEYS[ros]
    return {sec: ns // 1_000_000_000, nsec: ns % 1_000_000_000}


def _header(frame_id: str, stamp_s: float, ros: int) -> dict:
    if ros == 1:
        return {"seq": 0, "stamp": _duration(stamp_s, 1), "frame_id": frame_id}
    return {"stamp": _duration(stamp_s, 2), "frame_id": frame_id}


def trajectory_to_ros(traj: Trajectory, frame_id: str = "", stamp_s: float = 0.0, ros: int = 2) -> dict:
    """A ``JointTrajectory`` message of ``traj`` as a dictionary with ROS 2 (default) or ROS 1 field names.

    Args:
        traj: The trajectory.
        frame_id: ``header.frame_id``.
        stamp_s: ``header.stamp`` in [s].
        ros: 2 (``sec``/``nanosec``, no ``seq``) or 1 (``secs``/``nsecs``, ``seq``).
    """
    ros = _check_ros(ros)
    _check(traj)
    return {
        "header": _header(frame_id, stamp_s, ros),
        "joint_names": list(traj.joint_names),
        "points": [
            {
                "positions": traj.q[k].tolist(),
                "velocities": traj.qd[k].tolist(),
                "accelerations": traj.qdd[k].tolist(),
                "effort": [] if traj.effort_nm is None else traj.effort_nm[k].tolist(),
                "time_from_start": _duration(float(traj.t_s[k]), ros),
            }
            for k in range(traj.t_s.size)
        ],
    }


def trajectory_json_text(
    traj: Trajectory, frame_id: str = "", ros: int = 2, extra: dict | None = None
) -> str:
    """The JSON content of ``traj`` (see :func:`write_trajectory_json`): a ``JointTrajectory`` message in
    its envelope; ``extra`` adds envelope fields (e.g. the ``"ipromp_pin_checks"`` mark)."""
    ros = _check_ros(ros)
    _check(traj)
    envelope = json.dumps(
        {
            "format": TRAJECTORY_FORMAT,
            "version": TRAJECTORY_VERSION,
            "ros": ros,
            "type": ROS_TYPES[ros],
            **(extra or {}),
        }
    )[:-1]
    head = json.dumps({"header": _header(frame_id, 0.0, ros), "joint_names": list(traj.joint_names)})[:-1]
    sec, nsec = _TIME_KEYS[ros]
    # one point per line, formatted directly (repr round-trips float64; faster than json.dump)
    lines = []
    effort = traj.effort_nm
    for k in range(traj.t_s.size):
        t = _duration(float(traj.t_s[k]), ros)
        tau = "" if effort is None else ", ".join(map(repr, effort[k].tolist()))
        lines.append(
            '{"positions": ['
            + ", ".join(map(repr, traj.q[k].tolist()))
            + '], "velocities": ['
            + ", ".join(map(repr, traj.qd[k].tolist()))
            + '], "accelerations": ['
            + ", ".join(map(repr, traj.qdd[k].tolist()))
            + f'], "effort": [{tau}], "time_from_start": {{"{sec}": {t[sec]}, "{nsec}": {t[nsec]}}}}}'
        )
    body = ",\n".join(lines)
    return f'{envelope},\n "message": {head}, "points": [\n{body}\n]}}}}\n'


def write_trajectory_json(
    traj: Trajectory, path: str | Path, frame_id: str = "", ros: int = 2, extra: dict | None = None
) -> Path:
    """Write ``traj`` as a ``JointTrajectory`` message in its envelope (ROS 2 field names by default),
    atomically (``extra``: envelope fields)."""
    return atomic.write_text(path, trajectory_json_text(traj, frame_id, ros, extra))


def _seconds(d: dict) -> float:
    """Seconds of a ROS 2 (``sec``/``nanosec``) or ROS 1 (``secs``/``nsecs``) time dictionary."""
    if "sec" in d:
        return d["sec"] + d["nanosec"] * 1e-9
    return d["secs"] + d["nsecs"] * 1e-9


def trajectory_from_ros(msg: dict, source: object = None) -> Trajectory:
    """Inverse of :func:`trajectory_to_ros` (either ROS version's field names).

    Raises:
        DataError: missing fields or inconsistent lengths.
    """
    try:
        names = [str(n) for n in msg["joint_names"]]
        points = msg["points"]
        t = [_seconds(p["time_from_start"]) for p in points]
        q = [p["positions"] for p in points]
        qd = [p.get("velocities") or [math.nan] * len(names) for p in points]
        qdd = [p.get("accelerations") or [math.nan] * len(names) for p in points]
    except (KeyError, TypeError) as exc:
        raise DataError(source, str(exc), "missing or malformed JointTrajectory field") from exc
    if not points:
        raise DataError(source, "points", "no trajectory points")
    try:
        arrays = [np.asarray(v, dtype=float) for v in (t, q, qd, qdd)]
    except ValueError as exc:
        raise DataError(source, "points", f"inconsistent point lengths: {exc}") from exc
    for name, a in zip(("positions", "velocities", "accelerations"), arrays[1:], strict=True):
        if a.ndim != 2 or a.shape[1] != len(names):
            raise DataError(source, name, f"every point needs {len(names)} values")
    traj = Trajectory(arrays[0], arrays[1], arrays[2], arrays[3], tuple(names))
    try:
        _check(traj)
    except DataError as exc:
        raise DataError(source, exc.field, exc.problem) from exc
    return traj


def read_trajectory_json(path: str | Path) -> Trajectory:
    """Read a JSON file written by :func:`write_trajectory_json`: the envelope (ROS 1 or 2 message
    inside) or a bare ``JointTrajectory`` message with either ROS version's field names."""
    path = Path(path)
    try:
        with open(path, encoding="utf-8") as fh:
            doc = json.load(fh)
    except (OSError, json.JSONDecodeError) as exc:
        raise DataError(path, None, f"cannot read JSON: {exc}") from exc
    if isinstance(doc, dict) and "message" in doc:
        if doc.get("format") != TRAJECTORY_FORMAT:
            raise DataError(path, "format", f"not an ipromp_pin trajectory (format {doc.get('format')!r})")
        if not isinstance(doc.get("version"), int) or doc["version"] > TRAJECTORY_VERSION:
            raise DataError(path, "version", f"unsupported version {doc.get('version')!r}")
        doc = doc["message"]
    return trajectory_from_ros(doc, path)
