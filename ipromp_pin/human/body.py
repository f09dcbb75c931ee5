"""The human body as capsules and spheres between tracked skeleton frames, over time.

A :class:`BodyPart` is a capsule between two tracked frames (or a sphere about one) with a radius
from published anthropometric data (``docs/safety.md``; ``[human.radii_m]`` overrides) and the
ISO/TS 15066 body region it belongs to. :class:`HumanMotion` places every part at any time ``t`` [s]
on the human's clock (0 at the start of the demo, the clock of :class:`~ipromp_pin.checks.TimedMotion`)
in the robot base frame:

* tracked frames (``demo.extras["skeleton:<frame>"]``, or a modelled group ``demo.groups[<frame>]``)
  are linearly interpolated between reliable samples; a frame that is occluded or all-zero (NaN in
  the demo) is never dropped: across a gap between reliable samples ``t_a`` and ``t_b`` the part lies
  within ``2 v min(t - t_a, t_b - t)`` of the interpolated position, after the last reliable sample it
  is held and may have moved ``v (t - t_a)`` (``v``: the human speed of the settings), and its
  capsule's radius grows by that much (capped at ``max_inflation_m``);
* :meth:`HumanMotion.until` gives the human as known at ``t_obs`` (what a planner knows then): the
  samples after ``t_obs`` are unknown, so every frame is held at its last reliable position before
  ``t_obs`` and grows at the human speed (the same arrays, no copy);
* :meth:`HumanMotion.assumed` is a default standing human placed by the settings, for recordings
  without a skeleton (``assumed = True``; reports say "assumed human").
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..data import Demo
from ..exceptions import DataError
from ..robot.human_settings import HumanSettings

SKELETON_PREFIX = "skeleton:"
"""Prefix of the demo extras holding a tracked skeleton frame's positions (T, 3) [m], NaN where
the frame was not reliably tracked (see :mod:`ipromp_pin.readers.multimodal`)."""


@dataclass(frozen=True)
class BodyPart:
    """One body part: a capsule from frame ``a`` to frame ``b`` (a sphere about ``a`` when ``b`` is
    None) of radius ``radius_m`` [m], in ISO/TS 15066 body region ``region``. A frame written
    ``"/f1+/f2"`` is the midpoint of two frames."""

    name: str
    a: str
    b: str | None
    radius_m: float
    region: str


BODY_PARTS: tuple[BodyPart, ...] = (
    BodyPart("head", "/head_1", None, 0.11, "face"),
    BodyPart("neck", "/neck_1", "/head_1", 0.07, "neck"),
    BodyPart("shoulders", "/left_shoulder_1", "/right_shoulder_1", 0.08, "back_shoulders"),
    BodyPart("chest", "/neck_1", "/torso_1", 0.17, "chest"),
    BodyPart("abdomen", "/torso_1", "/left_hip_1+/right_hip_1", 0.16, "abdomen"),
    BodyPart("pelvis", "/left_hip_1", "/right_hip_1", 0.14, "pelvis"),
    BodyPart("left_upper_arm", "/left_shoulder_1", "/left_elbow_1", 0.065, "upper_arm"),
    BodyPart("right_upper_arm", "/right_shoulder_1", "/right_elbow_1", 0.065, "upper_arm"),
    BodyPart("left_forearm", "/left_elbow_1", "/left_hand_1", 0.055, "lower_arm"),
    BodyPart("right_forearm", "/right_elbow_1", "/right_hand_1", 0.055, "lower_arm"),
    BodyPart("left_hand", "/left_hand_1", None, 0.10, "hand"),
    BodyPart("right_hand", "/right_hand_1", None, 0.10, "hand"),
    BodyPart("left_thigh", "/left_hip_1", "/left_knee_1", 0.10, "thigh"),
    BodyPart("right_thigh", "/right_hip_1", "/right_knee_1", 0.10, "thigh"),
)
"""The default body: frames of the skeleton tracker of handover_20171128 (OpenNI names, whose
``/left_*`` frames are the tracker's mirrored labels), radii about the 95th-percentile adult male
(``docs/safety.md``: half of head length, neck, chest breadth, hip depth, biceps, forearm and thigh
circumferences / 2 pi, half of hand length)."""

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
        """``"assumed"`` or ``"tracked"``, as reports say it."""
        return "assumed" if self.assumed else "tracked"

    # ----------------------------------------------------------------- construction
    @classmethod
    def from_demo(
        cls,
        demo: Demo,
        settings: HumanSettings | None = None,
        parts: tuple[BodyPart, ...] = BODY_PARTS,
    ) -> HumanMotion | None:
        """The tracked human of ``demo`` (None when the demo has no tracked skeleton).

        Raises:
            DataError: a body frame that is never reliably tracked in a demo that has a skeleton.
        """
        settings = settings if settings is not None else HumanSettings()
        frames = _frame_list(parts)
        found = {f: _demo_frame(demo, f) for f in frames}
        if all(v is None for v in found.values()):
            return None
        pos = np.full((demo.n_samples, len(frames), 3), np.nan)
        for j, f in enumerate(frames):
            v = found[f]
            if v is None or not np.any(np.all(np.isfinite(v), axis=1)):
                raise DataError(demo.source, f, "skeleton frame of the body model never reliably tracked")
            pos[:, j] = v
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
        return dataclasses.replace(self, horizon_s=float(min(t_obs_s, self.horizon_s)))

    # ----------------------------------------------------------------- queries
    def frames_at(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Frame positions (N, F, 3) [m] and their uncertainty radii (N, F) [m] at times (N,) [s]."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        out = np.empty((t.size, len(self.frames), 3))
        grow = np.zeros((t.size, len(self.frames)))
        known = self.t_s <= self.horizon_s
        if not np.any(known):
            known = np.zeros_like(known)
            known[0] = True
        dt = float(np.median(np.diff(self.t_s))) if self.t_s.size > 1 else 0.0
        for j in range(len(self.frames)):
            p = self.positions_m[:, j]
            ok = known & np.all(np.isfinite(p), axis=1)
            if self.static is not None and self.static[j]:
                out[:, j] = p[0]
                continue
            tv, pv = self.t_s[ok], p[ok]
            out[:, j], grow[:, j] = _frame_at(t, tv, pv, self.speed_m_s, dt)
        return out, np.minimum(grow, self.max_inflation_m)

    def capsules(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Capsule end points ``a`` and ``b`` (N, P, 3) [m] and radii (N, P) [m] (inflation included)
        at times (N,) [s]; a sphere has ``a == b``."""
        pos, grow = self.frames_at(t_s)
        idx = {f: j for j, f in enumerate(self.frames)}
        n = pos.shape[0]
        a = np.empty((n, self.n_parts, 3))
        b = np.empty((n, self.n_parts, 3))
        r = np.empty((n, self.n_parts))
        for k, part in enumerate(self.parts):
            ja = [idx[f] for f in part.a.split("+")]
            jb = ja if part.b is None else [idx[f] for f in part.b.split("+")]
            a[:, k] = pos[:, ja].mean(axis=1)
            b[:, k] = pos[:, jb].mean(axis=1)
            r[:, k] = self.radius_m[k] + np.maximum(grow[:, ja].max(axis=1), grow[:, jb].max(axis=1))
        return a, b, r

    def capsules_at(self, t_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Capsule end points ``a``, ``b`` (P, 3) [m] and radii (P,) [m] at time ``t_s`` [s]."""
        a, b, r = self.capsules(np.array([float(t_s)]))
        return a[0], b[0], r[0]


def _demo_frame(demo: Demo, frame: str) -> np.ndarray | None:
    """Positions (T, 3) of a skeleton frame in ``demo`` (extras, else a modelled group), or None."""
    v = demo.extras.get(SKELETON_PREFIX + frame)
    if v is None:
        v = demo.groups.get(frame)
    return None if v is None else np.asarray(v, dtype=float)


def _radii(parts: tuple[BodyPart, ...], settings: HumanSettings) -> np.ndarray:
    unknown = sorted(set(settings.radii_m) - {p.name for p in parts})
    if unknown:
        raise DataError("human settings", "human.radii_m", f"unknown body part(s) {unknown}")
    return np.array([settings.radii_m.get(p.name, p.radius_m) for p in parts])


def _frame_at(
    t: np.ndarray, tv: np.ndarray, pv: np.ndarray, speed: float, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 3) and uncertainty radii (N,) at times ``t`` of a frame reliably seen at times
    ``tv`` (K,) at positions ``pv`` (K, 3) (see the module docstring)."""
    k = np.searchsorted(tv, t, side="right")  # tv[k-1] <= t < tv[k]
    before = k == 0
    after = k == tv.size
    lo = np.clip(k - 1, 0, tv.size - 1)
    hi = np.clip(k, 0, tv.size - 1)
    ta, tb = tv[lo], tv[hi]
    span = np.where(hi > lo, tb - ta, 1.0)
    w = np.where(hi > lo, (t - ta) / span, 0.0)[:, None]
    pos = pv[lo] * (1.0 - w) + pv[hi] * w
    gap = (hi > lo) & (tb - ta > 1.5 * dt)
    grow = np.where(gap, 2.0 * speed * np.minimum(t - ta, tb - t), 0.0)
    grow = np.where(after, speed * (t - tv[-1]), grow)
    grow = np.where(before, speed * (tv[0] - t), grow)
    pos[before] = pv[0]
    pos[after] = pv[-1]
    return pos, np.maximum(grow, 0.0)
