"""Gripper orientations: the geodesic angle between rotations and their chordal L2 mean.

* :func:`geodesic_deg`: the angle of ``R_a^T R_b`` in [deg] (the smallest rotation from one to the other);
* :func:`chordal_mean`: the rotation closest (Frobenius norm) to the arithmetic mean of rotation matrices,
  i.e. the mean projected back to SO(3) by an SVD (the chordal L2 mean; Hartley et al., "Rotation
  averaging", IJCV 2013, section 5.1).
"""

from __future__ import annotations

import numpy as np


def geodesic_deg(rot_a: np.ndarray, rot_b: np.ndarray) -> np.ndarray:
    """Angles (...,) in [deg] between rotation matrices ``rot_a`` and ``rot_b`` (..., 3, 3)."""
    rel = np.einsum("...ji,...jk->...ik", np.asarray(rot_a, float), np.asarray(rot_b, float))
    cos = (np.trace(rel, axis1=-2, axis2=-1) - 1.0) / 2.0
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def chordal_mean(rotations: np.ndarray) -> np.ndarray:
    """The chordal L2 mean (3, 3) of rotation matrices (n, 3, 3), n >= 1.

    Raises:
        ValueError: no rotation given.
    """
    rots = np.asarray(rotations, dtype=float).reshape(-1, 3, 3)
    if rots.shape[0] == 0:
        raise ValueError("chordal_mean needs at least one rotation")
    u, _, vt = np.linalg.svd(rots.mean(axis=0))
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt
