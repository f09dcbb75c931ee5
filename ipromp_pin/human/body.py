"""The human body as capsules and spheres between tracked skeleton frames, over time.

A :class:`BodyPart` is a capsule between two tracked frames (or a sphere about one) with a radius
from published anthropometric data (``docs/safety.md``; ``[human.radii_m]`` overrides) and the
ISO/TS 15066 body region it belongs to. :class:`HumanMotion` places every part at any time ``t`` [s]
on the human's clock (0 at the start of the demo, the clock of every
:class:`~ipromp_pin.motion.trajectory.Trajectory`) in the robot base frame:

* tracked frames (``demo.extras["skeleton:<frame>"]``, or a modelled group ``demo.groups[<frame>]``)
  are linearly interpolated between reliable samples; a frame that is occluded or all-zero (NaN in
  the demo) is never dropped: across a gap between reliable samples ``t_a`` and ``t_b`` the part lies
  within ``2 v min(t - t_a, t_b - t)`` of the interpolated position, after the last reliable sample it
  is held and may have moved ``v (t - t_a)`` (``v``: the human speed of the settings), and its
  capsule's radius grows by that much (capped at ``max_inflation_m``);
* :meth:`HumanMotion.until` gives the human as known at ``t_obs`` (what a planner knows then): the
  samples after ``t_obs`` are unknown, so every frame is held at its last reliable position before
  ``t_obs`` and grows at the human speed (the same arrays, no copy);
* :meth:`HumanMotion.with_forecast` places the handing arm after ``t_obs`` where the model predicts
  it, where that is a tighter bound than holding it (:mod:`ipromp_pin.human.forecast`);
* :meth:`HumanMotion.assumed` is a default standing human placed by the settings, for recordings
  without a skeleton (``assumed = True``; reports say "assumed human").
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np

from ..data import Demo
from ..exceptions import DataError
from ..fields import unknown
from ..robot.human_settings import HumanSettings
from ..robot.ranges import BODY_PART_RADII_M as RADII
from .forecast import BodyForecast
from .skeleton import plausible_positions

SKELETON_PREFIX = "skeleton:"
"""Prefix of the demo extras holding a tracked skeleton frame's positions (T, 3) [m], NaN where
the frame was not reliably tracked (see :mod:`ipromp_pin.readers.multimodal`)."""


@dataclass(frozen=True)
class BodyPart:
    """One body part: a capsule from frame ``a`` to frame ``b`` (a sphere about ``a`` when ``b`` is
    None) of radius ``radius_m`` [m], in ISO/TS 15066 body region ``region``. A frame written
    ``"/f1+/f2"`` is the midpoint of two frames. ``trim_b_m`` [m] shortens the axis at ``b`` (a
    forearm ends where the hand's sphere begins: the hand-over contact is the hand's)."""

    name: str
    a: str
    b: str | None
    radius_m: float
    region: str
    trim_b_m: float = 0.0


BODY_PARTS: tuple[BodyPart, ...] = (
    BodyPart("head", "/head_1", None, RADII["head"], "face"),
    BodyPart("neck", "/neck_1", "/head_1", RADII["neck"], "neck"),
    BodyPart("shoulders", "/left_shoulder_1", "/right_shoulder_1", RADII["shoulders"], "back_shoulders"),
    BodyPart("chest", "/neck_1", "/torso_1", RADII["chest"], "chest"),
    BodyPart("abdomen", "/torso_1", "/left_hip_1+/right_hip_1", RADII["abdomen"], "abdomen"),
    BodyPart("pelvis", "/left_hip_1", "/right_hip_1", RADII["pelvis"], "pelvis"),
    BodyPart("left_upper_arm", "/left_shoulder_1", "/left_elbow_1", RADII["left_upper_arm"], "upper_arm"),
    BodyPart("right_upper_arm", "/right_shoulder_1", "/right_elbow_1", RADII["right_upper_arm"], "upper_arm"),
    BodyPart("left_forearm", "/left_elbow_1", "/left_hand_1", RADII["left_forearm"], "lower_arm", 0.155),
    BodyPart("right_forearm", "/right_elbow_1", "/right_hand_1", RADII["right_forearm"], "lower_arm", 0.155),
    BodyPart("left_hand", "/left_hand_1", None, RADII["left_hand"], "hand"),
    BodyPart("right_hand", "/right_hand_1", None, RADII["right_hand"], "hand"),
    BodyPart("left_thigh", "/left_hip_1", "/left_knee_1", RADII["left_thigh"], "thigh"),
    BodyPart("right_thigh", "/right_hip_1", "/right_knee_1", RADII["right_thigh"], "thigh"),
)
"""The default body: frames of the skeleton tracker of handover_20171128 (OpenNI names, whose
``/left_*`` frames are the tracker's mirrored labels), radii about the 95th-percentile adult male
(:data:`~ipromp_pin.robot.ranges.BODY_PART_RADII_M`; ``docs/safety.md``: half of head length, neck,
chest breadth, hip depth, biceps, forearm and thigh circumferences / 2 pi, half of hand length)."""

ASSUMED_POSE_M: dict[str, tuple[float, float, float]] = {
    "/head_1": (0.04, 0.0, 0.35),
    "/neck_1": (0.02, 0.0, 0.17),
    "/torso_1": (0.0, 0.0, 0.0),
    "/left_shoulder_1": (0.02, 0.125, 0.17),
    "/right_shoulder_1": (0.02, -0.125, 0.17),
    "/left_elbow_1": (0.18, 0.29, 0.21),
    "/right_elbow_1": (0.02, -0.11, -0.03),
    "/left_hand_1": (0.37, 0.39, 0.28),
    "/right_hand_1": (0.03, -0.14, -0.26),
    "/left_hip_1": (-0.02, 0.08, -0.175),
    "/right_hip_1": (-0.02, -0.08, -0.175),
    "/left_knee_1": (0.0, 0.08, -0.52),
    "/right_knee_1": (0.0, -0.08, -0.52),
}
"""The assumed human's frames relative to its torso, (forward, toward the ``/left_*`` side, up) in
[m]: the median pose of the tracked partner of handover_20171128 (every third demo, measured), the
handing arm (``/left_*``) reaching toward the robot."""


def _frame_list(parts: tuple[BodyPart, ...]) -> list[str]:
    names: list[str] = []
    for p in parts:
        for end in (p.a, p.b):
            if end is not None:
                names.extend(f for f in end.split("+") if f not in names)
    return names


@dataclass(frozen=True)
class HumanMotion:
    """Body capsules over time in the robot base frame (see the module docstring).

    Attributes:
        t_s: Sample times (T,) in [s] on the human's clock.
        frames: Tracked frame names (F,).
        positions_m: Frame positions (T, F, 3) in [m], NaN where not reliably tracked.
        parts: The body parts (P,).
        radius_m: Radii (P,) in [m] before any inflation.
        speed_m_s: Human speed in [m/s] at which an unseen frame may move.
        max_inflation_m: Cap in [m] of that growth.
        assumed: Whether the human is the assumed default (no tracked skeleton).
        static: Whether each frame (F,) is known for all time (the assumed human's standing pose).
        horizon_s: Samples after this time [s] are unknown (:meth:`until`); ``inf``: all known.
        source: Where the motion comes from (a demo's source, or "assumed human").
        forecast: The handing arm as predicted after the horizon (:meth:`with_forecast`), or None.
    """

    t_s: np.ndarray
    frames: tuple[str, ...]
    positions_m: np.ndarray
    parts: tuple[BodyPart, ...]
    radius_m: np.ndarray
    speed_m_s: float
    max_inflation_m: float
    assumed: bool = False
    static: np.ndarray | None = None
    horizon_s: float = math.inf
    source: str = ""
    forecast: BodyForecast | None = None

    @property
    def part_names(self) -> np.ndarray:
        """Body part names (P,)."""
        return np.array([p.name for p in self.parts])

    @property
    def regions(self) -> np.ndarray:
        """ISO/TS 15066 body region of each part (P,)."""
        return np.array([p.region for p in self.parts])

    @property
    def n_parts(self) -> int:
        """Number of body parts P."""
        return len(self.parts)

    @property
    def label(self) -> str:
        """``"assumed"``, ``"tracked"`` or ``"predicted"`` (tracked until the horizon, then frames
        placed by the model's prediction: :meth:`with_forecast`), as reports say it."""
        if self.assumed:
            return "assumed"
        return "tracked" if self.forecast is None else "predicted"

    # ----------------------------------------------------------------- construction
    @staticmethod
    def body_frames(parts: tuple[BodyPart, ...] = BODY_PARTS) -> tuple[str, ...]:
        """The skeleton frames (body model names) the parts are placed by, once each."""
        return tuple(_frame_list(parts))

    @classmethod
    def from_demo(
        cls,
        demo: Demo,
        settings: HumanSettings | None = None,
        parts: tuple[BodyPart, ...] = BODY_PARTS,
    ) -> HumanMotion | None:
        """The tracked human of ``demo`` (None when the demo has no tracked skeleton), its joints read
        through the settings' skeleton map (:attr:`HumanSettings.skeleton`). Frames at exactly
        (0, 0, 0) and samples of impossible segment lengths are missing samples
        (:func:`~ipromp_pin.human.skeleton.plausible_positions`).

        Raises:
            DataError: a demo with a tracked skeleton that lacks frames of the map (naming them: never
                the assumed human instead), a body frame that is never reliably tracked, or an
                impossible skeleton (a part's median length outside its anthropometric range).
        """
        settings = settings if settings is not None else HumanSettings()
        frames = _frame_list(parts)
        tracked = _mapped_frames(demo, frames, settings)
        if tracked is None:
            return None
        raw = np.stack([tracked[f] for f in frames], axis=1)  # (T, F, 3)
        pos = plausible_positions(raw, frames, parts, demo.source)
        for j, f in enumerate(frames):
            if not np.any(np.all(np.isfinite(pos[:, j]), axis=1)):
                raise DataError(demo.source, f, "skeleton frame of the body model never reliably tracked")
        return cls(
            demo.t.copy(),
            tuple(frames),
            pos,
            tuple(parts),
            _radii(parts, settings),
            settings.speed_m_s,
            settings.max_inflation_m,
            source=demo.source,
        )

    @classmethod
    def assumed_human(
        cls,
        settings: HumanSettings | None = None,
        t_s: np.ndarray | None = None,
        hand_m: np.ndarray | None = None,
        parts: tuple[BodyPart, ...] = BODY_PARTS,
    ) -> HumanMotion:
        """The assumed standing human (:data:`ASSUMED_POSE_M`) at the settings' placement.

        Args:
            settings: The human settings (placement, radii, speed).
            t_s: Sample times (T,) [s] (default: one sample at 0: a human standing still).
            hand_m: The handing hand's path (T, 3) [m] when known (e.g. a synthetic demo's
                ``hand_position``): ``/left_hand_1`` follows it, the rest stands still.
        """
        settings = settings if settings is not None else HumanSettings()
        t = np.zeros(1) if t_s is None else np.asarray(t_s, dtype=float)
        frames = _frame_list(parts)
        yaw = math.radians(settings.placement.facing_deg)
        fwd = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        side = np.array([math.sin(yaw), -math.cos(yaw), 0.0])  # the /left_* side (mirrored labels)
        up = np.array([0.0, 0.0, 1.0])
        origin = np.asarray(settings.placement.torso_m, dtype=float)
        pos = np.empty((t.size, len(frames), 3))
        static = np.ones(len(frames), dtype=bool)
        for j, f in enumerate(frames):
            off = ASSUMED_POSE_M.get(f)
            if off is None:
                raise DataError("assumed human", f, "frame has no assumed position")
            pos[:, j] = origin + off[0] * fwd + off[1] * side + off[2] * up
        if hand_m is not None and "/left_hand_1" in frames:
            hand = np.asarray(hand_m, dtype=float)
            if hand.shape != (t.size, 3):
                raise DataError("assumed human", "hand_m", f"shape {hand.shape} != ({t.size}, 3)")
            j = frames.index("/left_hand_1")
            pos[:, j] = hand
            static[j] = False
            if "/left_elbow_1" in frames and "/left_shoulder_1" in frames:
                # the elbow half-way between the shoulder and the hand, 5 cm lower (a reaching arm)
                e, sh = frames.index("/left_elbow_1"), frames.index("/left_shoulder_1")
                pos[:, e] = (pos[:, sh] + hand) / 2.0 - 0.05 * up
                static[e] = False
        return cls(
            t,
            tuple(frames),
            pos,
            tuple(parts),
            _radii(parts, settings),
            settings.speed_m_s,
            settings.max_inflation_m,
            assumed=True,
            static=static,
            source="assumed human",
        )

    def until(self, t_obs_s: float) -> HumanMotion:
        """The human as known at ``t_obs_s`` [s]: later samples unknown (held, growing at the human
        speed). Shares the arrays of ``self``."""
        seen = copy.copy(self)  # shallow: the arrays and their indices are shared
        object.__setattr__(seen, "horizon_s", float(min(t_obs_s, self.horizon_s)))
        object.__setattr__(seen, "forecast", None)  # a forecast belongs to its horizon
        return seen

    def with_forecast(self, forecast: BodyForecast | None) -> HumanMotion:
        """This human (as known at its horizon) with ``forecast`` placing its frames after the horizon
        where the forecast's radius is below the held growth (:mod:`~ipromp_pin.human.forecast`).
        Shares the arrays of ``self``."""
        out = copy.copy(self)
        object.__setattr__(out, "forecast", forecast)
        return out

    def last_seen(self, frames: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
        """Where each of ``frames`` was last reliably seen at or before the horizon, (F, 3) [m], and
        when (F,) [s]; NaN for a frame this body does not track, a static one, or one never seen."""
        pos = np.full((len(frames), 3), np.nan)
        when = np.full(len(frames), np.nan)
        held = self.held_frames()
        if held is None:
            return pos, when
        for j, f in enumerate(frames):
            if f in self.frames:
                k = self.frames.index(f)
                if np.isfinite(held[1][k]) and np.all(np.isfinite(held[0][k])):
                    pos[j], when[j] = held[0][k], held[1][k]
        return pos, when

    # ----------------------------------------------------------------- queries
    def __post_init__(self) -> None:
        object.__setattr__(self, "_index", _valid_index(self.t_s, self.positions_m))
        object.__setattr__(self, "_parts", _part_matrices(self.parts, self.frames))

    def frames_at(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Frame positions (N, F, 3) [m] and their uncertainty radii (N, F) [m] at times (N,) [s];
        with a :attr:`forecast`, its frames after the horizon where it is the tighter bound."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        held = _late_frames(self, t)
        out, grow = held if held is not None else self._recorded_frames_at(t)
        late = t > self.horizon_s
        if self.forecast is not None and np.any(late):
            apply_forecast(self.forecast, self.frames, self.speed_m_s, t, late, out, grow)
        return out, grow

    def _recorded_frames_at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`frames_at` without the forecast: interpolated, bridged or held and grown."""
        prev_i, next_i = self._index  # type: ignore[attr-defined]
        ts, pos = self.t_s, self.positions_m
        n_t = ts.size
        i = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, n_t - 1)
        i_h = max(int(np.searchsorted(ts, self.horizon_s, side="right")) - 1, 0)
        late = t > self.horizon_s
        a = prev_i[np.minimum(i, i_h)]  # (N, F): last reliable sample at or before t (and the horizon)
        b = next_i[np.minimum(i + 1, n_t - 1)]  # first reliable sample after t
        b = np.where(late[:, None] | (b > i_h), -1, b)
        b = np.where(ts[np.maximum(b, 0)] < t[:, None], -1, b)
        has_a, has_b = a >= 0, b >= 0
        if not np.all(has_a | has_b):  # nothing known before the horizon: the first sample, grown fully
            first = next_i[0]
            a = np.where(has_a | has_b, a, first[None, :])
            has_a = a >= 0
        cols = np.arange(len(self.frames))[None, :]
        ta = ts[np.maximum(a, 0)]
        tb = ts[np.maximum(b, 0)]
        pa = pos[np.maximum(a, 0), cols]
        pb = pos[np.maximum(b, 0), cols]
        both = has_a & has_b
        span = np.where(both & (tb > ta), tb - ta, 1.0)
        w = np.where(both, (t[:, None] - ta) / span, 0.0)
        # blend only where both ends are known: an unknown end indexes sample 0, which may be NaN
        blend = pa + (pb - pa) * w[..., None]
        out = np.where(both[..., None], blend, np.where(has_a[..., None], pa, pb))
        v = self.speed_m_s
        dt = float(ts[1] - ts[0]) if n_t > 1 else 0.0
        gap = both & (tb - ta > 1.5 * dt)
        grow = np.where(gap, 2.0 * v * np.minimum(t[:, None] - ta, tb - t[:, None]), 0.0)
        grow = np.where(has_a & ~has_b, v * (t[:, None] - ta), grow)
        grow = np.where(~has_a & has_b, v * (tb - t[:, None]), grow)
        if self.static is not None:
            out[:, self.static] = pos[0, self.static]
            grow[:, self.static] = 0.0
        return out, np.minimum(np.maximum(grow, 0.0), self.max_inflation_m)

    def held_frames(self) -> tuple[np.ndarray, np.ndarray] | None:
        """At every time at or after :attr:`horizon_s` each frame is held where it was last seen:
        its position (F, 3) [m] and the time (F,) [s] it was seen (``inf`` for a static frame,
        which never grows); None without a finite horizon. :meth:`frames_at` of such times is
        this position with the growth ``min(max(v (t - t_f), 0), max_inflation_m)``."""
        if not math.isfinite(self.horizon_s):
            return None
        prev_i, next_i = self._index  # type: ignore[attr-defined]
        ts, pos = self.t_s, self.positions_m
        i_h = max(int(np.searchsorted(ts, self.horizon_s, side="right")) - 1, 0)
        a = prev_i[i_h]
        a = np.where(a >= 0, a, next_i[0])  # nothing known before the horizon: the first sample
        cols = np.arange(len(self.frames))
        held = pos[np.maximum(a, 0), cols]
        seen = ts[np.maximum(a, 0)].astype(float)
        if self.static is not None:
            held[self.static] = pos[0, self.static]
            seen[self.static] = math.inf
        return held, seen

    def _held_parts(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """The time-independent part of :meth:`_held_capsules`: the held ends ``a``, ``b`` (P, 3) [m],
        whether each part grows (P,) and the time (P,) [s] it was first seen; None when the held
        frames do not apply (no finite horizon, a non-finite held position). Kept per object for
        its horizon (the checks of one re-plan place the same human at several motions)."""
        cached = self.__dict__.get("_held_cache")
        if cached is not None and cached[0] == self.horizon_s:
            return cached[1]
        parts = self._held_parts_now()
        object.__setattr__(self, "_held_cache", (self.horizon_s, parts))
        return parts

    def _held_parts_now(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """:meth:`_held_parts`, computed."""
        held = self.held_frames()
        if held is None:
            return None
        pos, seen = held
        if not np.all(np.isfinite(pos)):
            return None  # the general path places (and reports) it
        wa, wb, ma, mb, trim = self._parts  # type: ignore[attr-defined]
        a, b = wa @ pos, wb @ pos  # (P, 3): each end is one frame or the midpoint of two (exact)
        if np.any(trim > 0):
            axis = b - a
            length = np.linalg.norm(axis, axis=1, keepdims=True)
            keep = np.maximum(length - trim[:, None], 0.0) / np.maximum(length, 1e-12)
            b = np.where(trim[:, None] > 0, a + axis * keep, b)
        # a part grows as its frame seen first (rounding is monotone: the same number as the largest
        # growth of its frames); a part of static frames only does not grow
        member = np.maximum(ma, mb) > 0  # (P, F)
        first = np.min(np.where(member, seen[None, :], np.inf), axis=1)  # (P,); inf: static frames only
        moving = np.isfinite(first)
        for arr in (a, b, moving, first):
            arr.flags.writeable = False
        return a, b, moving, first

    def _held_capsules(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """:meth:`capsules` at times (N,) that are all at or after the horizon: the same numbers
        from the held frames (the ends computed once per object, :meth:`_held_parts`), or None when
        that does not apply."""
        if t.size == 0 or not math.isfinite(self.horizon_s) or not np.all(t >= self.horizon_s):
            return None
        if self.forecast is not None:
            return None
        parts = self._held_parts()
        if parts is None:
            return None
        a, b, moving, first = parts
        grow = self.speed_m_s * (t[:, None] - np.where(moving, first, 0.0)[None, :])
        g = np.where(moving[None, :], np.minimum(np.maximum(grow, 0.0), self.max_inflation_m), 0.0)
        n = t.size
        return (
            np.ascontiguousarray(np.broadcast_to(a, (n, *a.shape))),
            np.ascontiguousarray(np.broadcast_to(b, (n, *b.shape))),
            self.radius_m[None, :] + g,
        )

    def capsules(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Capsule end points ``a`` and ``b`` (N, P, 3) [m] and radii (N, P) [m] (inflation included)
        at times (N,) [s]; a sphere has ``a == b``. Times at or after the horizon (a planner's
        remaining motion) take the held frames (:meth:`held_frames`): the same numbers, faster."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        fast = self._held_capsules(t)
        if fast is not None:
            return fast
        pos, grow = self.frames_at(t)
        wa, wb, ma, mb, trim = self._parts  # type: ignore[attr-defined]
        n, nf = pos.shape[0], pos.shape[1]
        flat = pos.transpose(1, 0, 2).reshape(nf, 3 * n)  # (F, N*3): one matrix product per end
        a = (wa @ flat).reshape(-1, n, 3).transpose(1, 0, 2)
        b = (wb @ flat).reshape(-1, n, 3).transpose(1, 0, 2)
        if np.any(trim > 0):
            axis = b - a
            length = np.linalg.norm(axis, axis=2, keepdims=True)
            keep = np.maximum(length - trim[None, :, None], 0.0) / np.maximum(length, 1e-12)
            b = np.where(trim[None, :, None] > 0, a + axis * keep, b)
        g = np.max(grow[:, None, :] * np.maximum(ma, mb), axis=2)  # the part's most uncertain frame
        return a, b, self.radius_m[None, :] + g

    def capsules_at(self, t_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Capsule end points ``a``, ``b`` (P, 3) [m] and radii (P,) [m] at time ``t_s`` [s]."""
        a, b, r = self.capsules(np.array([float(t_s)]))
        return a[0], b[0], r[0]


def _late_frames(human: HumanMotion, t: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``human``'s frame positions (N, F, 3) [m] and growths (N, F) [m] without the forecast at times
    (N,) all at or after its horizon, from the held frames (:meth:`HumanMotion.held_frames`: the
    numbers of the per-sample path without its indexing), or None when that does not apply."""
    if t.size == 0 or not math.isfinite(human.horizon_s) or not np.all(t >= human.horizon_s):
        return None
    held = human.held_frames()
    if held is None or not np.all(np.isfinite(held[0])):
        return None
    pos, seen = held
    grow = human.speed_m_s * (t[:, None] - seen[None, :])  # a static frame (seen inf) grows by 0
    out = np.repeat(pos[None, :, :], t.size, axis=0)
    return out, np.minimum(np.maximum(grow, 0.0), human.max_inflation_m)


def apply_forecast(
    fc: BodyForecast,
    frames: tuple[str, ...],
    speed_m_s: float,
    t: np.ndarray,
    late: np.ndarray,
    out: np.ndarray,
    grow: np.ndarray,
) -> None:
    """The frames (of ``frames``) that ``fc`` places take, at the times ``t`` (N,) [s] after the
    horizon (``late`` (N,)), its position and radius where that radius is below the held growth (in
    place on the positions ``out`` (N, F, 3) [m] and growths ``grow`` (N, F) [m])."""
    pos, radius = fc.at(t[late], speed_m_s)
    rows = np.flatnonzero(late)
    cols = np.array([frames.index(f) for f in fc.frames], dtype=np.int64)
    r, c = np.nonzero(radius < grow[np.ix_(rows, cols)])  # (late sample, forecast frame) pairs
    out[rows[r], cols[c]] = pos[r, c]
    grow[rows[r], cols[c]] = radius[r, c]


def _mapped_frames(demo: Demo, frames: list[str], settings: HumanSettings) -> dict[str, np.ndarray] | None:
    """Body frame -> its positions (T, 3) [m] in ``demo`` through the settings' skeleton map (the mean
    of the recording's frames it maps to; a frame the map does not name is read as itself); None when
    the demo has no tracked skeleton at all.

    Raises:
        DataError: the demo has a tracked skeleton but not every frame the map names, listing them.
    """
    mapped = settings.skeleton.body_frames()
    sources = {f: mapped.get(f, (f,)) for f in frames}
    found = {name: _demo_frame(demo, name) for names in sources.values() for name in names}
    present = {name: v for name, v in found.items() if v is not None}
    lacking = [name for name in found if name not in present]
    if not lacking:
        return {f: _mean([present[n] for n in names]) for f, names in sources.items()}
    has = recorded_skeleton_frames(demo)
    if len(lacking) == len(found) and not has:
        return None
    shown_has = ", ".join(has[:12]) + (f" and {len(has) - 12} more" if len(has) > 12 else "")
    raise DataError(
        demo.source,
        "skeleton",
        f"the tracked skeleton lacks the frames {', '.join(lacking)} of skeleton map "
        f"'{settings.skeleton.name}' (it has {shown_has or 'none of them'}); name its frames in the robot "
        "settings' [human] skeleton or [human.skeleton_map] (docs/your_data.md)",
    )


def _mean(arrays: list[np.ndarray]) -> np.ndarray:
    """The mean (T, 3) of a joint's frames (one frame: itself, unchanged); NaN where any is NaN."""
    return arrays[0] if len(arrays) == 1 else np.mean(np.stack(arrays), axis=0)


def recorded_skeleton_frames(demo: Demo) -> list[str]:
    """The tracked skeleton frames ``demo`` holds (its ``skeleton:<frame>`` extras, then its groups
    that are frames, ``/<name>``), once each, in order."""
    names = [k[len(SKELETON_PREFIX) :] for k in demo.extras if k.startswith(SKELETON_PREFIX)]
    names += [g for g in demo.groups if g.startswith("/")]
    return list(dict.fromkeys(names))


def _demo_frame(demo: Demo, frame: str) -> np.ndarray | None:
    """Positions (T, 3) of a skeleton frame in ``demo`` (extras, else a modelled group), or None."""
    v = demo.extras.get(SKELETON_PREFIX + frame)
    if v is None:
        v = demo.groups.get(frame)
    return None if v is None else np.asarray(v, dtype=float)


def _radii(parts: tuple[BodyPart, ...], settings: HumanSettings) -> np.ndarray:
    names = [p.name for p in parts]
    for part in settings.radii_m:
        if part not in names:
            raise DataError(
                settings.source or "human settings",
                f"human.radii_m.{part}",
                unknown(part, names, "body part"),
            )
    return np.array([settings.radii_m.get(p.name, p.radius_m) for p in parts])


def _valid_index(t: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per sample and frame (T, F): the index of the last reliable sample at or before it and of
    the first at or after it (-1: none)."""
    ok = np.all(np.isfinite(pos), axis=2)
    idx = np.arange(t.size)[:, None]
    prev = np.maximum.accumulate(np.where(ok, idx, -1), axis=0)
    big = t.size
    nxt = np.minimum.accumulate(np.where(ok, idx, big)[::-1], axis=0)[::-1]
    return prev, np.where(nxt == big, -1, nxt)


def _part_matrices(
    parts: tuple[BodyPart, ...], frames: tuple[str, ...]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Weights (P, F) averaging the frames of each part's ends ``a`` and ``b``, the same as masks,
    and the trims (P,) [m]."""
    idx = {f: j for j, f in enumerate(frames)}
    wa = np.zeros((len(parts), len(frames)))
    wb = np.zeros_like(wa)
    for k, part in enumerate(parts):
        ja = [idx[f] for f in part.a.split("+")]
        jb = ja if part.b is None else [idx[f] for f in part.b.split("+")]
        wa[k, ja] = 1.0 / len(ja)
        wb[k, jb] = 1.0 / len(jb)
    trim = np.array([p.trim_b_m for p in parts])
    return wa, wb, (wa > 0).astype(float), (wb > 0).astype(float), trim
