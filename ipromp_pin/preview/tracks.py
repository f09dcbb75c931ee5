"""Animation tracks written whole, one node's frames at once.

meshcat's per-frame animation API (``animation.at_frame(viewer, k)[path].set_transform(T)``) does one
quaternion eigen-decomposition and one sorted insert per node and frame in Python; a preview's
animation has hundreds of frames of dozens of nodes. These functions put every frame's key of one
node's property at once, with the keys that API gives (the same quaternion convention, the same
frame numbers), and the animation is sent as meshcat's own (``viewer.set_animation``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import meshcat.animation as ma
import numpy as np

__all__ = ["put_property", "put_transforms", "quaternions_wxyz", "translations"]


def quaternions_wxyz(T: np.ndarray) -> np.ndarray:
    """Unit quaternions (n, 4) ``(w, x, y, z)`` of the rotations of ``T`` (n, 3+, 3+), as meshcat's
    ``transformations.quaternion_from_matrix`` gives them (the eigenvector of the largest eigenvalue
    of its symmetric 4x4 matrix, ``w >= 0``), batched."""
    M = np.asarray(T, dtype=float)
    m00, m01, m02 = M[:, 0, 0], M[:, 0, 1], M[:, 0, 2]
    m10, m11, m12 = M[:, 1, 0], M[:, 1, 1], M[:, 1, 2]
    m20, m21, m22 = M[:, 2, 0], M[:, 2, 1], M[:, 2, 2]
    K = np.zeros((M.shape[0], 4, 4))
    K[:, 0, 0] = m00 - m11 - m22
    K[:, 1, 0], K[:, 1, 1] = m01 + m10, m11 - m00 - m22
    K[:, 2, 0], K[:, 2, 1], K[:, 2, 2] = m02 + m20, m12 + m21, m22 - m00 - m11
    K[:, 3, 0], K[:, 3, 1], K[:, 3, 2], K[:, 3, 3] = m21 - m12, m02 - m20, m10 - m01, m00 + m11 + m22
    K /= 3.0
    w, V = np.linalg.eigh(K)  # the lower triangle, as meshcat's
    q = V[np.arange(M.shape[0]), :, np.argmax(w, axis=1)][:, [3, 0, 1, 2]]
    return np.where(q[:, :1] < 0.0, -q, q)


def _clip(animation: ma.Animation, path: Any) -> ma.AnimationClip:
    clip = animation.clips.get(path)
    if clip is None:
        clip = animation.clips[path] = ma.AnimationClip(fps=animation.default_framerate)
    return clip


def put_property(
    animation: ma.Animation, path: Any, prop: str, jstype: str, frames: Sequence[int], values: Sequence[Any]
) -> None:
    """Keys of ``path``'s (a meshcat ``Path``) property ``prop`` at ``frames`` (frame numbers), merged
    into the track's earlier keys in frame order (a key at a frame it has goes after it, as meshcat's
    inserts do)."""
    if len(frames) != len(values):
        raise ValueError(f"{len(frames)} frames for {len(values)} values")
    clip = _clip(animation, path)
    track = clip.tracks.get(prop)
    if track is None:
        clip.tracks[prop] = ma.AnimationTrack(prop, jstype, [int(f) for f in frames], list(values))
        return
    keys = sorted(
        [(f, 0, i, v) for i, (f, v) in enumerate(zip(track.frames, track.values, strict=True))]
        + [(int(f), 1, i, v) for i, (f, v) in enumerate(zip(frames, values, strict=True))],
        key=lambda x: (x[0], x[1], x[2]),
    )
    track.frames = [k[0] for k in keys]
    track.values = [k[3] for k in keys]


def translations(p: np.ndarray) -> np.ndarray:
    """Placements (n, 4, 4) without rotation at the positions ``p`` (n, 3) [m]."""
    T = np.tile(np.eye(4), (p.shape[0], 1, 1))
    T[:, :3, 3] = p
    return T


def put_transforms(animation: ma.Animation, path: Any, frames: Sequence[int], T: np.ndarray) -> None:
    """Position and quaternion keys of ``path`` at ``frames`` from the placements ``T`` (n, 4, 4)."""
    T = np.asarray(T, dtype=float).reshape(-1, 4, 4)
    put_property(animation, path, "position", "vector3", frames, T[:, :3, 3].tolist())
    q = quaternions_wxyz(T)
    put_property(animation, path, "quaternion", "quaternion", frames, q[:, [1, 2, 3, 0]].tolist())
