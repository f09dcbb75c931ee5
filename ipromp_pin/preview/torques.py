"""The arm's joint torques and the object it holds, as a preview shows them: plain arrays, validated.

- :class:`TorqueTrack`: at the samples the joint-torque check evaluated, every joint's torque usage
  ``|tau| / effort limit`` and whether the gripper holds the task's object: drawn as one bar per
  joint at the current time (its peak over the motion marked), coloured by :func:`usage_color`, with
  the payload held and the report's peak (:class:`~.reported.ReportedFigure`, the verdict's) stated
  (``static/torques.js``);
- :class:`HeldObject`: the task's object, a box, a cylinder or (no shape given) a small sphere in the
  gripper frame, and when the robot holds it: drawn in the gripper while held
  (:mod:`~ipromp_pin.preview.object_scene`).

Both come from the joint-torque check's numbers and the task file
(:mod:`ipromp_pin.outputs.torque_preview` fills them in), so that the preview does not depend on the
dynamics or the checks. Times in [s] on the human's clock (0 at the start of the human's motion), like
:class:`~ipromp_pin.preview.body.SeparationTrack`; lengths in [m] in the gripper frame. Bad input
raises :class:`~ipromp_pin.exceptions.DataError` naming the field (source ``"preview"``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..exceptions import DataError
from .reported import ReportedFigure, checked_figures

__all__ = [
    "OBJECT_KINDS",
    "TORQUE_COLORS",
    "WARN_RATIO",
    "HeldObject",
    "TorqueTrack",
    "torque_panel",
    "usage_color",
]

WARN_RATIO = 0.7
"""Torque usage (|tau| / effort limit) from which a bar is drawn orange instead of green."""

TORQUE_COLORS = {"ok": "#2ca02c", "high": "#ff7f0e", "over": "#d62728"}
"""Bar colours: ``ok`` below :data:`WARN_RATIO`, ``high`` up to the allowed usage (1 - effort margin),
``over`` beyond it (the joint-torque check fails)."""

OBJECT_KINDS = ("box", "cylinder", "sphere")
"""Shapes of a :class:`HeldObject` (``sphere``: the task file gives no shape)."""


def usage_color(ratio: float, allowed_ratio: float) -> str:
    """The colour key of :data:`TORQUE_COLORS` of a torque usage ``ratio`` (|tau| / limit)."""
    if ratio > allowed_ratio + 1e-9:
        return "over"
    return "ok" if ratio < WARN_RATIO else "high"


def _error(name: str, problem: str) -> DataError:
    return DataError("preview", name, problem)


def _finite(value: object, name: str, ndim: int) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise _error(name, f"not a numeric array ({exc})") from exc
    if arr.ndim != ndim or arr.size == 0:
        raise _error(name, f"expected a non-empty {ndim}-d array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise _error(name, "contains NaN or infinite values")
    return arr


@dataclass
class TorqueTrack:
    """Every joint's torque usage at samples of the robot's motion.

    Attributes:
        t_s: (N,) sample times in [s] on the human's clock, non-decreasing (two samples at one time:
            the gripper before and after the object changes hands, the end of the approach and the
            start of the retreat).
        ratio: (N, J) ``|tau| / effort limit`` per sample and joint (>= 0).
        joint_names: (J,) the arm joints.
        limit_nm: (J,) the effort limits in [N m] (> 0).
        allowed_ratio: The usage the joint-torque check allows, ``1 - effort_margin``, in (0, 1].
        held: (N,) whether the gripper holds the object at each sample (all False: no object).
        payload: The object, e.g. ``"spanner_handover 0.25 kg"`` ("": the task has none).
        samples: Which samples these are, for the panel (e.g. "the 112 samples the joint_torques
            check evaluated"; "": every control sample).
        reported: The report's figures the panel states (the joint-torque verdicts).
    """

    t_s: np.ndarray
    ratio: np.ndarray
    joint_names: Sequence[str]
    limit_nm: np.ndarray
    allowed_ratio: float
    held: np.ndarray
    payload: str = ""
    samples: str = ""
    reported: Sequence[ReportedFigure] = ()

    def __post_init__(self) -> None:
        self.t_s = _finite(self.t_s, "torques.t_s", 1)
        if self.t_s.size >= 2 and np.any(np.diff(self.t_s) < 0.0):
            raise _error("torques.t_s", "times must be non-decreasing")
        self.joint_names = tuple(str(n) for n in self.joint_names)
        self.ratio = _finite(self.ratio, "torques.ratio", 2)
        if self.ratio.shape != (self.t_s.size, len(self.joint_names)):
            raise _error(
                "torques.ratio",
                f"shape {self.ratio.shape}, expected {(self.t_s.size, len(self.joint_names))}",
            )
        if np.any(self.ratio < 0.0):
            raise _error("torques.ratio", "usages must be >= 0")
        self.limit_nm = _finite(self.limit_nm, "torques.limit_nm", 1)
        if self.limit_nm.shape != (len(self.joint_names),) or np.any(self.limit_nm <= 0):
            raise _error("torques.limit_nm", f"expected {len(self.joint_names)} limits > 0")
        self.allowed_ratio = float(self.allowed_ratio)
        if not 0.0 < self.allowed_ratio <= 1.0:
            raise _error("torques.allowed_ratio", f"must be in (0, 1], got {self.allowed_ratio}")
        self.held = np.asarray(self.held, dtype=bool).reshape(-1)
        if self.held.size != self.t_s.size:
            raise _error("torques.held", f"has {self.held.size} values for {self.t_s.size} samples")
        self.payload = str(self.payload)
        self.samples = str(self.samples)
        self.reported = checked_figures(self.reported, "torques.reported")

    @property
    def peak(self) -> np.ndarray:
        """(J,) each joint's peak usage over the motion."""
        return self.ratio.max(axis=0)

    @property
    def peak_index(self) -> np.ndarray:
        """(J,) the sample of each joint's peak usage."""
        return self.ratio.argmax(axis=0)

    def payload_at(self, i: int) -> str:
        """What the gripper holds at sample ``i``: ``"holding <object>"`` or ``"empty"``."""
        return f"holding {self.payload}" if self.payload and self.held[i] else "empty"


@dataclass
class HeldObject:
    """The task's object in the gripper frame, and when the robot holds it.

    Attributes:
        name: The object's task name (labels).
        mass_kg: Its mass in [kg].
        frame: The model frame the object is attached to (the gripper frame of the dynamics).
        kind: One of :data:`OBJECT_KINDS`.
        dims_m: Box: edge lengths (x, y, z); cylinder: (radius, length); sphere: (radius,), in [m].
        center_m: (3,) its centre (the centre of mass) in the frame, in [m].
        axis: A cylinder's axis in the frame (0: x, 1: y, 2: z).
        held_from_s: From when the robot holds it, in [s] on the human's clock (None: from the start).
        held_until_s: Until when, in [s] (None: to the end).
    """

    name: str
    mass_kg: float
    frame: str
    kind: str
    dims_m: Sequence[float]
    center_m: np.ndarray
    axis: int = 2
    held_from_s: float | None = None
    held_until_s: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in OBJECT_KINDS:
            raise _error("held_object.kind", f"must be one of {', '.join(OBJECT_KINDS)}, got {self.kind!r}")
        want = {"box": 3, "cylinder": 2, "sphere": 1}[self.kind]
        dims = _finite(self.dims_m, "held_object.dims_m", 1)
        if dims.size != want or np.any(dims <= 0):
            raise _error(
                "held_object.dims_m", f"a {self.kind} needs {want} dimensions > 0, got {dims.tolist()}"
            )
        self.dims_m = tuple(float(d) for d in dims)
        self.center_m = _finite(self.center_m, "held_object.center_m", 1)
        if self.center_m.shape != (3,):
            raise _error("held_object.center_m", f"expected 3 coordinates, got {self.center_m.shape}")
        if self.axis not in (0, 1, 2):
            raise _error("held_object.axis", f"must be 0, 1 or 2, got {self.axis!r}")
        self.name, self.frame = str(self.name), str(self.frame)

    def held(self, t_s: np.ndarray) -> np.ndarray:
        """Whether the robot holds the object at the human's times ``t_s`` (K,) [s]."""
        t = np.asarray(t_s, dtype=float)
        out = np.ones(t.shape, dtype=bool)
        if self.held_from_s is not None:
            out &= t >= self.held_from_s - 1e-9
        if self.held_until_s is not None:
            out &= t <= self.held_until_s + 1e-9
        return out


def torque_panel(track: TorqueTrack) -> dict:
    """The HTML panel's torque data on the animation's clock (the human's): per
    sample the usages (rounded) and whether the object is held; per joint the peak and its time;
    the allowed usage, the colour thresholds, the payload, which samples these are and the report's
    figures; read by ``static/torques.js``."""
    peak, at = track.peak, track.peak_index
    return {
        "t_s": [round(float(t), 3) for t in track.t_s],
        "ratio": np.round(track.ratio, 3).tolist(),
        "held": [bool(h) for h in track.held],
        "joints": list(track.joint_names),
        "limit_nm": [float(v) for v in track.limit_nm],
        "peak": [round(float(p), 4) for p in peak],
        "peak_t_s": [round(float(track.t_s[i]), 3) for i in at],
        "allowed": track.allowed_ratio,
        "warn": WARN_RATIO,
        "payload": track.payload,
        "samples": track.samples,
        "reported": [f.to_dict() for f in track.reported],
        "colors": dict(TORQUE_COLORS),
    }
