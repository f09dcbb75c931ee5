"""Trajectory files: CSV with named columns and JSON shaped like ROS ``trajectory_msgs/JointTrajectory``.

CSV: header ``time_s``, then ``q.<joint>`` for every joint, ``qd.<joint>``, ``qdd.<joint>``; one row per
sample; numbers written with 17 significant digits so they read back exactly.

JSON (ROS JointTrajectory field names)::

    {"header": {"seq": 0, "stamp": {"secs": 0, "nsecs": 0}, "frame_id": ""},
     "joint_names": [...],
     "points": [{"positions": [...], "velocities": [...], "accelerations": [...], "effort": [],
                 "time_from_start": {"secs": 1, "nsecs": 250000000}}, ...]}

Times are split into integer seconds and nanoseconds, so they round to 1 ns on reading.

Files are written atomically (:mod:`ipromp_pin.atomic`): a temporary file in the same folder,
renamed into place when complete. The ``*_text`` functions give the content, for callers that
stage several files together (:class:`ipromp_pin.atomic.OutputSet`).

Marked files. A trajectory whose checks failed is written only when the user asks for it
(``ipromp-pin run --allow-failing-checks``), and then marked: the CSV starts with a comment line
``# ipromp_pin: ...`` (which :func:`read_trajectory_csv` skips) and the JSON has a top-level
``"ipromp_pin_checks"`` object (``{"passed": false, "failures": [...]}``), ignored by readers of
JointTrajectory fields.
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

import numpy as np

from . import atomic
from .exceptions import DataError
from .timing import Trajectory


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


def _duration(t: float) -> dict[str, int]:
    ns = int(round(t * 1e9))
    return {"secs": ns // 1_000_000_000, "nsecs": ns % 1_000_000_000}


def trajectory_to_ros(traj: Trajectory, frame_id: str = "", stamp_s: float = 0.0) -> dict:
    """A ``trajectory_msgs/JointTrajectory``-shaped dictionary of ``traj``."""
    _check(traj)
    return {
        "header": {"seq": 0, "stamp": _duration(stamp_s), "frame_id": frame_id},
        "joint_names": list(traj.joint_names),
        "points": [
            {
                "positions": traj.q[k].tolist(),
                "velocities": traj.qd[k].tolist(),
                "accelerations": traj.qdd[k].tolist(),
                "effort": [],
                "time_from_start": _duration(float(traj.t_s[k])),
            }
            for k in range(traj.t_s.size)
        ],
    }


def trajectory_json_text(traj: Trajectory, frame_id: str = "", extra: dict | None = None) -> str:
    """The ROS JointTrajectory-shaped JSON of ``traj`` (see :func:`write_trajectory_json`); ``extra``
    adds top-level fields (e.g. the ``"ipromp_pin_checks"`` mark)."""
    _check(traj)
    head = json.dumps(
        {
            "header": {"seq": 0, "stamp": _duration(0.0), "frame_id": frame_id},
            "joint_names": list(traj.joint_names),
            **(extra or {}),
        }
    )[:-1]
    # one point per line, formatted directly (repr round-trips float64; faster than json.dump)
    lines = []
    for k in range(traj.t_s.size):
        t = _duration(float(traj.t_s[k]))
        lines.append(
            '{"positions": ['
            + ", ".join(map(repr, traj.q[k].tolist()))
            + '], "velocities": ['
            + ", ".join(map(repr, traj.qd[k].tolist()))
            + '], "accelerations": ['
            + ", ".join(map(repr, traj.qdd[k].tolist()))
            + f'], "effort": [], "time_from_start": {{"secs": {t["secs"]}, "nsecs": {t["nsecs"]}}}}}'
        )
    body = ",\n".join(lines)
    return f'{head}, "points": [\n{body}\n]}}\n'


def write_trajectory_json(
    traj: Trajectory, path: str | Path, frame_id: str = "", extra: dict | None = None
) -> Path:
    """Write ``traj`` as ROS JointTrajectory-shaped JSON, atomically (``extra``: top-level fields)."""
    return atomic.write_text(path, trajectory_json_text(traj, frame_id, extra))


def trajectory_from_ros(msg: dict, source: object = None) -> Trajectory:
    """Inverse of :func:`trajectory_to_ros`.

    Raises:
        DataError: missing fields or inconsistent lengths.
    """
    try:
        names = [str(n) for n in msg["joint_names"]]
        points = msg["points"]
        t = [p["time_from_start"]["secs"] + p["time_from_start"]["nsecs"] * 1e-9 for p in points]
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
    """Read a JSON file written by :func:`write_trajectory_json`."""
    path = Path(path)
    try:
        with open(path, encoding="utf-8") as fh:
            msg = json.load(fh)
    except (OSError, json.JSONDecodeError) as exc:
        raise DataError(path, None, f"cannot read JSON: {exc}") from exc
    return trajectory_from_ros(msg, path)
