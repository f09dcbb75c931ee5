"""Closest points between line segments, vectorised: the distance between capsules.

A capsule is a segment ``[a, b]`` with a radius; the distance between two capsules is the distance
between their segments minus both radii (a sphere is a segment with ``a == b``).
"""

from __future__ import annotations

import numpy as np

_EPS = 1e-12


def segment_closest_points(
    p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest points of segments ``[p1, q1]`` and ``[p2, q2]`` (broadcast arrays (..., 3) [m]).

    Returns:
        ``(c1, c2, dist)``: the closest point on each segment (..., 3) and their distance (...,).
    """
    d1 = q1 - p1
    d2 = q2 - p2
    r = p1 - p2
    a = np.einsum("...i,...i->...", d1, d1)
    e = np.einsum("...i,...i->...", d2, d2)
    f = np.einsum("...i,...i->...", d2, r)
    c = np.einsum("...i,...i->...", d1, r)
    b = np.einsum("...i,...i->...", d1, d2)
    denom = a * e - b * b
    safe_a = np.where(a > _EPS, a, 1.0)
    safe_e = np.where(e > _EPS, e, 1.0)
    # s on segment 1 for the infinite lines (0 when parallel), then t, then re-clamp s.
    s = np.where(
        denom > _EPS * np.maximum(a * e, _EPS), (b * f - c * e) / np.where(denom > 0, denom, 1.0), 0.0
    )
    s = np.clip(s, 0.0, 1.0)
    t = (b * s + f) / safe_e
    t_clamped = np.clip(t, 0.0, 1.0)
    s = np.where(t != t_clamped, np.clip((b * t_clamped - c) / safe_a, 0.0, 1.0), s)
    t = t_clamped
    # degenerate segments (points)
    point1 = a <= _EPS
    point2 = e <= _EPS
    s = np.where(point1, 0.0, s)
    t = np.where(point1 & ~point2, np.clip(f / safe_e, 0.0, 1.0), t)
    s = np.where(point2 & ~point1, np.clip(-c / safe_a, 0.0, 1.0), s)
    t = np.where(point2, 0.0, t)
    c1 = p1 + d1 * s[..., None]
    c2 = p2 + d2 * t[..., None]
    return c1, c2, np.linalg.norm(c1 - c2, axis=-1)
