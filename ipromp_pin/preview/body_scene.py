"""Drawing the human body and its separation from the robot into a meshcat scene.

- every body part of a :class:`~ipromp_pin.preview.body.BodyTrack` is a capsule: a unit cylinder
  and two unit spheres scaled and placed per frame (meshcat's cylinder axis is its local y), moving
  with the recording;
- the closest robot-body pair of a :class:`~ipromp_pin.preview.body.SeparationTrack` is a thin rod
  from the robot's closest point to the body's, one node per separation state (the node of the
  sample's state is the one shown), so that its colour says the state;
- :func:`separation_panel` is the HTML panel's data: the report's figures as the verdicts give them,
  and the per-sample distance, state and pair on the animation's time base, read by
  ``static/separation.js`` (the figures, the value at the current time and the states along the
  time slider).

The scene's animation gets every frame's body and rod from :func:`body_tracks`.
"""

from __future__ import annotations

import meshcat
import meshcat.animation as ma
import meshcat.geometry as mg
import numpy as np

from .body import SEPARATION_STATES, BodyTrack, SeparationTrack
from .tracks import put_property, put_transforms, translations

__all__ = [
    "BODY_NODE",
    "CLOSEST_NODE",
    "COLOR_BODY",
    "COLOR_BODY_ASSUMED",
    "SEPARATION_COLORS",
    "body_tracks",
    "capsule_transforms",
    "draw_body",
    "separation_panel",
]

COLOR_BODY = 0xD9A27E
"""Colour of the tracked body's capsules."""
COLOR_BODY_ASSUMED = 0x9FB0C4
"""Colour of an assumed (not recorded) body's capsules."""
SEPARATION_COLORS = {
    "free": 0x2CA02C,
    "within_sp": 0xE6C200,
    "speed_limited": 0xFF7F0E,
    "violation": 0xD62728,
}
"""Colour of the closest-pair rod and of the time strip per separation state."""

BODY_NODE = "human/body"
CLOSEST_NODE = "human/closest"
_ROD_RADIUS_M = 0.008
_BODY_OPACITY = 0.35
_MIN_LENGTH_M = 1e-6


def _segment(a: np.ndarray, b: np.ndarray, radius: float) -> tuple[np.ndarray, list[float]]:
    """Placement (4, 4) without scale and scale (x, y, z) of a unit cylinder (axis y, height 1,
    radius 1) spanning ``a`` to ``b`` (3,) [m] with ``radius`` [m] (:func:`_segments` of one)."""
    T, scale = _segments(np.asarray(a, dtype=float)[None], np.asarray(b, dtype=float)[None], radius)
    return T[0], scale[0].tolist()


def capsule_transforms(
    a: np.ndarray, b: np.ndarray, radius: float
) -> dict[str, tuple[np.ndarray, list[float]]]:
    """The placements and scales of one capsule's nodes ``cyl``, ``a`` and ``b`` (unit geometries)."""
    out = {"cyl": _segment(a, b, radius)}
    for end, p in (("a", a), ("b", b)):
        T = np.eye(4)
        T[:3, 3] = p
        out[end] = (T, [radius, radius, radius])
    return out


def _scaled(T: np.ndarray, scale: list[float]) -> np.ndarray:
    S = T.copy()
    S[:3, :3] = T[:3, :3] * np.asarray(scale)[None, :]
    return S


def _material(color: int, opacity: float) -> mg.MeshLambertMaterial:
    return mg.MeshLambertMaterial(color=color, opacity=opacity, transparent=opacity < 1.0)


def _closest_at(separation: SeparationTrack, t_s: float) -> int:
    """Index of the control sample in force at ``t_s`` [s] (the last one at or before it)."""
    return int(np.clip(np.searchsorted(separation.t_s, t_s + 1e-9) - 1, 0, separation.t_s.size - 1))


def draw_body(
    viewer: meshcat.Visualizer, body: BodyTrack | None, separation: SeparationTrack | None, t_s: float
) -> None:
    """(Re)draw the body's capsules and the closest-pair rods, posed at the human's time ``t_s`` [s]."""
    viewer[BODY_NODE].delete()
    viewer[CLOSEST_NODE].delete()
    if body is not None:
        material = _material(COLOR_BODY_ASSUMED if body.assumed else COLOR_BODY, _BODY_OPACITY)
        for k in range(body.n_parts):
            node = viewer[f"{BODY_NODE}/{k}"]
            node["cyl"].set_object(mg.Cylinder(1.0, 1.0), material)
            node["a"].set_object(mg.Sphere(1.0), material)
            node["b"].set_object(mg.Sphere(1.0), material)
    if separation is not None:
        for state in SEPARATION_STATES:
            viewer[f"{CLOSEST_NODE}/{state}"].set_object(
                mg.Cylinder(1.0, 1.0), _material(SEPARATION_COLORS[state], 1.0)
            )
    _pose_static(viewer, body, separation, t_s)


def _pose_static(
    viewer: meshcat.Visualizer, body: BodyTrack | None, separation: SeparationTrack | None, t_s: float
) -> None:
    if body is not None:
        a, b, r = (x[0] for x in body.at(np.array([t_s])))
        for k in range(body.n_parts):
            for end, (T, scale) in capsule_transforms(a[k], b[k], float(r[k])).items():
                viewer[f"{BODY_NODE}/{k}/{end}"].set_transform(_scaled(T, scale))
    if separation is not None:
        i = _closest_at(separation, t_s)
        T, scale = _segment(separation.robot_point_m[i], separation.body_point_m[i], _ROD_RADIUS_M)
        for state in SEPARATION_STATES:
            node = viewer[f"{CLOSEST_NODE}/{state}"]
            node.set_transform(_scaled(T, scale))
            node.set_property("visible", state == separation.state[i])


def _segments(a: np.ndarray, b: np.ndarray, radius: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Placements (n, 4, 4) without scale and scales (n, 3) of unit cylinders (axis y, height 1,
    radius 1) spanning ``a`` to ``b`` (n, 3) [m] with ``radius`` [m] (scalar or (n,)): the axis a
    rotation whose y column is the unit direction (the identity for a segment shorter than
    ``_MIN_LENGTH_M``)."""
    d = b - a
    length = np.linalg.norm(d, axis=1)
    long = length > _MIN_LENGTH_M
    y = np.where(long[:, None], d / np.where(long, length, 1.0)[:, None], [0.0, 1.0, 0.0])
    helper = np.where((np.abs(y[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    x = np.cross(y, helper)
    x /= np.linalg.norm(x, axis=1)[:, None]
    T = np.tile(np.eye(4), (a.shape[0], 1, 1))
    T[:, :3, :3] = np.where(long[:, None, None], np.stack([x, y, np.cross(x, y)], axis=-1), np.eye(3))
    T[:, :3, 3] = (a + b) / 2.0
    r = np.broadcast_to(np.asarray(radius, dtype=float), length.shape)
    return T, np.stack([r, np.maximum(length, _MIN_LENGTH_M), r], axis=1)


def body_tracks(
    animation: ma.Animation,
    viewer: meshcat.Visualizer,
    body: BodyTrack | None,
    separation: SeparationTrack | None,
    times_s: np.ndarray,
) -> None:
    """Pose the body's capsules and the closest-pair rod in every frame of ``animation`` (frame ``k``
    at the human's time ``times_s[k]`` [s]): each capsule's nodes placed and scaled per frame; the rod
    of the sample's separation state placed where that state is in force, shown and hidden where it
    changes (every rod's visibility set in the first frame)."""
    n = times_s.size
    frames = list(range(n))
    if body is not None:
        a, b, r = body.at(times_s)
        for k in range(body.n_parts):
            T, scale = _segments(a[:, k], b[:, k], r[:, k])
            ends = np.repeat(r[:, k, None], 3, axis=1).tolist()
            for name, placement, size in (
                ("cyl", T, scale.tolist()),
                ("a", translations(a[:, k]), ends),
                ("b", translations(b[:, k]), ends),
            ):
                path = viewer[f"{BODY_NODE}/{k}/{name}"].path
                put_transforms(animation, path, frames, placement)
                put_property(animation, path, "scale", "vector3", frames, size)
    if separation is None:
        return
    idx = np.clip(np.searchsorted(separation.t_s, times_s + 1e-9) - 1, 0, separation.t_s.size - 1)
    T, scale = _segments(separation.robot_point_m[idx], separation.body_point_m[idx], _ROD_RADIUS_M)
    state = np.asarray(separation.state, dtype=object)[idx]
    changed = np.flatnonzero(state[1:] != state[:-1]) + 1
    for s in SEPARATION_STATES:
        path = viewer[f"{CLOSEST_NODE}/{s}"].path
        visible = [(0, bool(state[0] == s))]
        visible += [(int(k), bool(state[k] == s)) for k in changed if s in (state[k], state[k - 1])]
        put_property(animation, path, "visible", "boolean", [f for f, _ in visible], [v for _, v in visible])
        at = np.flatnonzero(state == s)
        if at.size:
            put_transforms(animation, path, at.tolist(), T[at])
            put_property(animation, path, "scale", "vector3", at.tolist(), scale[at].tolist())


def separation_panel(separation: SeparationTrack, body: BodyTrack | None = None) -> dict:
    """The HTML panel's separation data on the animation's clock (the human's):
    per sample time, distance [m] (what ``measure`` says), state, pair, ``S_p`` [m], speed ratio
    (rounded) and whether a check judged it; the samples per state; the report's figures (the
    verdicts', stated as they are) and what the separation is judged against; read by
    ``static/separation.js``."""
    sp = separation.protective_distance_m
    ratio = separation.speed_ratio
    judged = separation.judged if separation.judged is not None else np.ones(separation.t_s.size, bool)

    def rounded(x: np.ndarray | None, digits: int = 4) -> list[float | None] | None:
        return None if x is None else [round(float(v), digits) if np.isfinite(v) else None for v in x]

    return {
        "t_s": rounded(separation.t_s, 3),
        "distance_m": rounded(separation.distance_m),
        "state": list(separation.state),
        "link": list(separation.link),
        "body_part": list(separation.body_part),
        "protective_distance_m": rounded(sp),
        "speed_ratio": rounded(ratio, 3),
        "judged": [bool(j) for j in judged],
        "measure": separation.measure or "smallest robot-body distance",
        "reported": [f.to_dict() for f in separation.reported],
        "counts": separation.state_counts(),
        "source": separation.source or ("assumed human" if body is not None and body.assumed else ""),
        "colors": {s: f"#{c:06x}" for s, c in SEPARATION_COLORS.items()},
    }
