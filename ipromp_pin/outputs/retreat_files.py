"""The retreat (the segment after the hand-over) in the trajectory files: ``retreat.csv`` and the
``retreat`` member of ``trajectory.json``.

``retreat.csv`` has the columns of ``trajectory.csv`` (:mod:`ipromp_pin.outputs.trajectory_files`;
read it with :func:`~ipromp_pin.outputs.trajectory_files.read_trajectory_csv`), its first sample the
approach's last (the hand-over). In ``trajectory.json`` the approach stays the envelope's
``message`` (existing readers read it unchanged); the retreat is a second ``JointTrajectory`` beside
it::

    {"format": "ipromp_pin.trajectory", "version": 3, ...,
     "retreat": {"start_s": 7.85, "dwell_s": 0.5, "target": "start", "message": {JointTrajectory}},
     "message": {JointTrajectory of the approach}}

Every time is on the human's clock, as the approach's: ``start_s`` [s] is when the retreat starts
(the hand-over) and its ``time_from_start`` (and ``retreat.csv``'s ``time_s``) run on from there.
:func:`read_retreat_json` reads it back.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from ..exceptions import DataError
from ..motion.trajectory import Trajectory
from .trajectory_files import TRAJECTORY_FORMAT, trajectory_from_ros, trajectory_to_ros

RETREAT_KEY = "retreat"
"""The member of ``trajectory.json``'s envelope holding the retreat."""

RETREAT_CSV = "retreat.csv"
"""The file of the retreat's samples beside ``trajectory.csv``."""


@dataclass(frozen=True)
class RetreatSegment:
    """The retreat as the files hold it.

    Attributes:
        trajectory: Its samples (times on the human's clock, from the hand-over).
        start_s: When it starts [s] on the human's clock (the hand-over: the approach's last sample).
        dwell_s: Its first part, holding still at the hand-over [s].
        target: The kind of its target (``start``, ``joints``, ``position``).
    """

    trajectory: Trajectory
    start_s: float
    dwell_s: float
    target: str

    def member(self, frame_id: str = "", ros: int = 2) -> dict:
        """The ``retreat`` member of ``trajectory.json`` (its message with ROS ``ros`` field names)."""
        return {
            "start_s": float(self.start_s),
            "dwell_s": float(self.dwell_s),
            "target": self.target,
            "message": trajectory_to_ros(self.trajectory, frame_id, ros=ros),
        }


def read_retreat_json(path: str | Path) -> Trajectory | None:
    """The retreat of a ``trajectory.json`` (None: the file has none, e.g. ``run --no-retreat``).

    Raises:
        DataError: unreadable file, not an ipromp_pin trajectory, a malformed ``retreat`` member.
    """
    path = Path(path)
    try:
        with open(path, encoding="utf-8") as fh:
            doc = json.load(fh)
    except (OSError, json.JSONDecodeError) as exc:
        raise DataError(path, None, f"cannot read JSON: {exc}") from exc
    if not isinstance(doc, dict) or doc.get("format") != TRAJECTORY_FORMAT:
        raise DataError(path, "format", "not an ipromp_pin trajectory")
    member = doc.get(RETREAT_KEY)
    if member is None:
        return None
    if not isinstance(member, dict) or "message" not in member:
        raise DataError(path, RETREAT_KEY, "must be an object with a 'message' JointTrajectory")
    return trajectory_from_ros(member["message"], path)
