"""The human body and its separation from the robot, as a preview shows them: plain arrays, validated.

- :class:`BodyTrack`: the body's capsules (segment ends and radius per body part) at the samples of
  a recording, on the human's clock: drawn as capsules moving with the recording;
- :class:`SeparationTrack`: per control sample of the robot's motion, the checks' measure of the
  separation (``human_clearance``'s: the smallest distance to the body outside the hand), its robot
  and body points, and the separation state (:data:`SEPARATION_STATES`, ``contact_speed``'s): drawn
  as a line between the two points coloured by the state, the value in the panel, and the state
  along the time slider; the panel states the report's figures (:class:`~.reported.ReportedFigure`,
  the verdicts') beside it.

Both come from the human checks' numbers for the human they judged
(:mod:`ipromp_pin.outputs.preview_content` fills them in), so that the preview does not depend on the
body model or the checks. Positions in [m] in the robot's
base frame; times in [s] on the human's clock (0 at the start of the human's motion), like
:class:`~ipromp_pin.motion.trajectory.Trajectory`. Bad input raises :class:`~ipromp_pin.exceptions.DataError`
naming the field (source ``"preview"``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..exceptions import DataError
from .reported import ReportedFigure, checked_figures

__all__ = ["SEPARATION_STATES", "BodyTrack", "SeparationTrack"]

SEPARATION_STATES = ("free", "within_sp", "speed_limited", "violation")
"""States of a control sample, from the safest: ``free`` (farther than the protective separation
distance ``S_p``), ``within_sp`` (closer than ``S_p``, approaching well below the body region's
contact-speed limit), ``speed_limited`` (closer than ``S_p``, approaching near the limit: the robot's
speed is what the limit allows), ``violation`` (closer than ``S_p`` and faster than the limit). The
human checks decide them (:meth:`ipromp_pin.human.separation.Separation.state`)."""


def _array(value: Any, name: str, shape: tuple[int | None, ...]) -> np.ndarray:
    """Finite float array of ``shape`` (None: any size) -> the array, else a DataError naming ``name``."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise DataError("preview", name, f"not a numeric array ({exc})") from exc
    if arr.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, arr.shape, strict=True)):
        want = "x".join("?" if s is None else str(s) for s in shape)
        raise DataError("preview", name, f"expected shape ({want}), got {arr.shape}")
    if arr.size == 0:
        raise DataError("preview", name, "is empty")
    if not np.all(np.isfinite(arr)):
        raise DataError("preview", name, "contains NaN or infinite values")
    return arr


def _optional_values(value: Any, name: str, n: int) -> np.ndarray:
    """(n,) values >= 0, NaN where unknown (never infinite)."""
    try:
        raw = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise DataError("preview", name, f"not a numeric array ({exc})") from exc
    arr = _array(np.where(np.isnan(raw), 0.0, raw), name, (n,))  # the shape, no infinite value
    if np.any(arr < 0.0):
        raise DataError("preview", name, "values must be >= 0")
    return np.where(np.isnan(raw), np.nan, arr)


def _times(value: Any, name: str) -> np.ndarray:
    t = _array(value, name, (None,))
    if t.size >= 2 and np.any(np.diff(t) <= 0.0):
        raise DataError("preview", name, "times must be strictly increasing")
    return t


@dataclass
class BodyTrack:
    """The human body's capsules over a recording (a sphere is a capsule with ``a == b``).

    Attributes:
        t_s: (T,) sample times in [s] on the human's clock, strictly increasing.
        a_m: (T, P, 3) first end of every body part's segment in [m].
        b_m: (T, P, 3) second end in [m].
        radius_m: (T, P) capsule radius in [m] (> 0).
        part_names: (P,) body part names.
        assumed: Whether the body is an assumed standing human (no skeleton recorded).
        label: What the body is, for the legend (e.g. "tracked human as observed until 0.64 s, then
            held"; "": from ``assumed``).
    """

    t_s: np.ndarray
    a_m: np.ndarray
    b_m: np.ndarray
    radius_m: np.ndarray
    part_names: Sequence[str]
    assumed: bool = False
    label: str = ""

    def __post_init__(self) -> None:
        self.t_s = _times(self.t_s, "body.t_s")
        self.part_names = tuple(str(n) for n in self.part_names)
        n_t, n_p = self.t_s.size, len(self.part_names)
        if n_p == 0:
            raise DataError("preview", "body.part_names", "no body part")
        self.a_m = _array(self.a_m, "body.a_m", (n_t, n_p, 3))
        self.b_m = _array(self.b_m, "body.b_m", (n_t, n_p, 3))
        self.radius_m = _array(self.radius_m, "body.radius_m", (n_t, n_p))
        if np.any(self.radius_m <= 0.0):
            raise DataError("preview", "body.radius_m", "radii must be > 0")
        self.assumed = bool(self.assumed)
        self.label = str(self.label)

    @property
    def n_parts(self) -> int:
        """Number of body parts P."""
        return len(self.part_names)

    def at(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Capsules at times ``t_s`` (K,) [s], linearly interpolated (held beyond the ends) ->
        ``(a (K, P, 3), b (K, P, 3), radius (K, P))`` in [m]."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        if self.t_s.size == 1:
            k = np.zeros(t.size, dtype=int)
            return self.a_m[k], self.b_m[k], self.radius_m[k]
        idx = np.clip(np.searchsorted(self.t_s, t, side="right") - 1, 0, self.t_s.size - 2)
        w = np.clip((t - self.t_s[idx]) / (self.t_s[idx + 1] - self.t_s[idx]), 0.0, 1.0)

        def lerp(x: np.ndarray) -> np.ndarray:
            ww = w.reshape((-1,) + (1,) * (x.ndim - 1))
            return (1.0 - ww) * x[idx] + ww * x[idx + 1]

        return lerp(self.a_m), lerp(self.b_m), lerp(self.radius_m)


@dataclass
class SeparationTrack:
    """The robot-body separation at every control sample of the robot's motion.

    Attributes:
        t_s: (N,) sample times in [s] on the human's clock, strictly increasing.
        distance_m: (N,) the distance in [m] that ``measure`` names (0 in contact): the checks'
            per-sample measure, whose smallest value over a judged motion is the report's.
        robot_point_m: (N, 3) the robot's point of that distance in [m].
        body_point_m: (N, 3) the body's point of that distance in [m].
        state: (N,) one of :data:`SEPARATION_STATES` per sample.
        link: (N,) the robot link of that pair (or empty).
        body_part: (N,) the body part of that pair (or empty).
        protective_distance_m: (N,) a protective separation distance ``S_p`` in [m] at the sample, if
            known (NaN: not computed at that sample).
        speed_ratio: (N,) approach speed over the body region's contact-speed limit, if known (NaN:
            not computed).
        source: What the separation is judged against, e.g. ``"recorded human"``, ``"assumed human"``.
        measure: What ``distance_m`` is, for the panel ("": the smallest robot-body distance).
        judged: (N,) whether the sample is one of a motion the checks judged (False: e.g. the robot
            at rest after its motion while the human still moves); None: every sample.
        reported: The report's figures the panel states (the checks' verdicts), each at a judged
            sample.
    """

    t_s: np.ndarray
    distance_m: np.ndarray
    robot_point_m: np.ndarray
    body_point_m: np.ndarray
    state: Sequence[str]
    link: Sequence[str] = ()
    body_part: Sequence[str] = ()
    protective_distance_m: np.ndarray | None = None
    speed_ratio: np.ndarray | None = None
    source: str = ""
    measure: str = ""
    judged: np.ndarray | None = None
    reported: Sequence[ReportedFigure] = ()

    def __post_init__(self) -> None:
        self.t_s = _times(self.t_s, "separation.t_s")
        n = self.t_s.size
        self.distance_m = _array(self.distance_m, "separation.distance_m", (n,))
        if np.any(self.distance_m < 0.0):
            raise DataError("preview", "separation.distance_m", "distances must be >= 0")
        self.robot_point_m = _array(self.robot_point_m, "separation.robot_point_m", (n, 3))
        self.body_point_m = _array(self.body_point_m, "separation.body_point_m", (n, 3))
        self.state = tuple(str(s) for s in self.state)
        bad = sorted(set(self.state) - set(SEPARATION_STATES))
        if len(self.state) != n or bad:
            problem = f"unknown state(s) {bad}" if bad else f"has {len(self.state)} states for {n} samples"
            raise DataError("preview", "separation.state", f"{problem}; states: {list(SEPARATION_STATES)}")
        for name in ("link", "body_part"):
            names = tuple(str(s) for s in getattr(self, name))
            if names and len(names) != n:
                raise DataError("preview", f"separation.{name}", f"has {len(names)} names for {n} samples")
            setattr(self, name, names or ("",) * n)
        if self.protective_distance_m is not None:
            self.protective_distance_m = _optional_values(
                self.protective_distance_m, "separation.protective_distance_m", n
            )
        if self.speed_ratio is not None:
            self.speed_ratio = _optional_values(self.speed_ratio, "separation.speed_ratio", n)
        self.source = str(self.source)
        self.measure = str(self.measure)
        judged = np.ones(n, dtype=bool) if self.judged is None else np.asarray(self.judged)
        if judged.shape != (n,) or judged.dtype != bool:
            raise DataError("preview", "separation.judged", f"expected {n} booleans, got {judged!r:.60}")
        self.judged = judged
        self.reported = checked_figures(self.reported, "separation.reported")

    @property
    def closest(self) -> int:
        """Index of the sample of the smallest distance among the judged samples (among all when
        none is judged)."""
        assert self.judged is not None  # set by __post_init__
        d = np.where(self.judged, self.distance_m, np.inf) if self.judged.any() else self.distance_m
        return int(np.argmin(d))

    def state_counts(self) -> dict[str, int]:
        """Number of samples in each state of :data:`SEPARATION_STATES`."""
        return {s: sum(x == s for x in self.state) for s in SEPARATION_STATES}
