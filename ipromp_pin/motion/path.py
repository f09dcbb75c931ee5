"""The geometric path a timing follows: a predicted joint path checked, cleaned and resampled, and
where a timed motion passes its points.

:func:`prepare_path` is step 1 of :func:`~ipromp_pin.motion.timing.time_path`: reject NaN/inf, too few
points, zero length and points outside the position limits
(:class:`~ipromp_pin.exceptions.InfeasibleError`); drop near-duplicate points, resample at uniform
joint-space arc length and optionally smooth with a Gaussian over arc length (end points kept).
toppra returns ``None`` on stationary or repeated samples and noise of a few mrad stretches its
duration several-fold, hence this step.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..exceptions import InfeasibleError
from .trajectory import JointLimits

TOLERANCE_RAD = 1e-9
"""How far a path point may lie outside the position limits before it is refused, in [rad]."""

MAX_TRAJECTORY_SAMPLES = 1_000_000
"""Largest number of samples :func:`~ipromp_pin.motion.timing.time_path` produces (10 000 s at 100 Hz;
hand-overs last seconds). A path that the limits would stretch beyond it is refused before anything
is allocated."""


def check_path_input(q: np.ndarray, limits: JointLimits) -> np.ndarray:
    """The path ``q`` (M, n_joints) [rad] as a float array, refused (:class:`InfeasibleError`) when it
    has the wrong shape, fewer than 2 points, NaN/inf or a point outside the position limits."""
    q = np.asarray(q, dtype=float)
    n = limits.n_joints
    if q.ndim != 2 or q.shape[1] != n:
        raise InfeasibleError(f"path: expected shape (M, {n}), got {q.shape}")
    if q.shape[0] < 2:
        raise InfeasibleError(f"path: needs at least 2 points, got {q.shape[0]}")
    if not np.all(np.isfinite(q)):
        row = int(np.nonzero(~np.all(np.isfinite(q), axis=1))[0][0])
        raise InfeasibleError(f"path: NaN or inf joint angles (first at point {row})")
    below = q < limits.lower_rad - TOLERANCE_RAD
    above = q > limits.upper_rad + TOLERANCE_RAD
    if below.any() or above.any():
        i, j = np.argwhere(below | above)[0]
        raise InfeasibleError(
            f"path: point {i} has {limits.joint_names[j]} = {q[i, j]:.4f} rad outside its limits "
            f"[{limits.lower_rad[j]:.4f}, {limits.upper_rad[j]:.4f}] "
            f"({int((below | above).sum())} violations)"
        )
    return q


def prepare_path(
    q: np.ndarray, limits: JointLimits, *, spacing_rad: float = 0.02, smooth_rad: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Clean a joint path and resample it at uniform arc length.

    Args:
        q: Path points (M, n_joints) in [rad].
        limits: Joint limits (the path must lie within the position limits).
        spacing_rad: Arc-length spacing of the resampled points in [rad] (joint-space Euclidean).
        smooth_rad: Standard deviation in [rad] of arc length of a Gaussian smoothing (0: none).

    Returns:
        ``s`` (K,) arc length in [rad] from 0, and the points (K, n_joints) in [rad].

    Raises:
        InfeasibleError: NaN/inf, fewer than 2 points, outside the position limits, zero length.
    """
    q = check_path_input(q, limits)
    step = np.linalg.norm(np.diff(q, axis=0), axis=1)
    keep = np.concatenate([[True], step > 1e-9])
    q = q[keep]
    s = np.concatenate([[0.0], np.cumsum(step[keep[1:]])])
    length = float(s[-1])
    if length < 1e-6:
        raise InfeasibleError(f"path: zero length ({length:.1e} rad): start and hand-over coincide")
    k = max(4, int(math.ceil(length / spacing_rad)) + 1)
    su = np.linspace(0.0, length, k)
    qu = np.column_stack([np.interp(su, s, q[:, j]) for j in range(q.shape[1])])
    if smooth_rad > 0:
        sigma = smooth_rad / (su[1] - su[0])
        pad = min(k - 1, int(4 * sigma) + 1)
        # odd reflection about the end points keeps them fixed and the ends' direction
        ext = np.vstack([2 * qu[0] - qu[pad:0:-1], qu, 2 * qu[-1] - qu[-2 : -pad - 2 : -1]])
        qs = gaussian_filter1d(ext, sigma, axis=0, mode="nearest")[pad : pad + k]
        qs[0], qs[-1] = qu[0], qu[-1]
        step = np.linalg.norm(np.diff(qs, axis=0), axis=1)
        s = np.concatenate([[0.0], np.cumsum(step)])
        su = np.linspace(0.0, s[-1], k)
        qu = np.column_stack([np.interp(su, s, qs[:, j]) for j in range(qs.shape[1])])
        qu = np.clip(qu, limits.lower_rad, limits.upper_rad)
    return su, qu


def check_sample_budget(q: np.ndarray, limits: JointLimits, rate_hz: float) -> None:
    """Refuse a path whose duration under ``limits`` is certain to exceed :data:`MAX_TRAJECTORY_SAMPLES`
    samples at ``rate_hz``, from lower bounds that cost nothing: each joint must travel its total
    variation at most at its velocity limit, and reach its farthest point from the start (from rest)
    at most at its acceleration and jerk limits."""
    travel = np.sum(np.abs(np.diff(q, axis=0)), axis=0)
    reach = np.max(np.abs(q - q[0]), axis=0)
    with np.errstate(over="ignore"):
        bound = np.max(
            np.stack(
                [
                    travel / limits.velocity_rad_s,
                    np.sqrt(2.0 * reach / limits.acceleration_rad_s2),
                    np.cbrt(6.0 * reach / limits.jerk_rad_s3),
                ]
            ),
            axis=0,
        )
    j = int(np.argmax(bound))
    if not bound[j] * rate_hz <= MAX_TRAJECTORY_SAMPLES:
        raise InfeasibleError(
            f"the path would take at least {bound[j]:.3g} s ({limits.joint_names[j]}: velocity limit "
            f"{limits.velocity_rad_s[j]:g} rad/s, acceleration {limits.acceleration_rad_s2[j]:g} rad/s^2, "
            f"jerk {limits.jerk_rad_s3[j]:g} rad/s^3): more than {MAX_TRAJECTORY_SAMPLES} samples at "
            f"{rate_hz:g} Hz"
        )


def path_deviation(q: np.ndarray, path: np.ndarray) -> np.ndarray:
    """Distance (N,) in [rad] from each sample of ``q`` (N, n) to the piecewise-linear ``path`` (M, n)."""
    q = np.asarray(q, dtype=float)
    path = np.asarray(path, dtype=float)
    if path.shape[0] == 1:
        return np.linalg.norm(q - path[0], axis=1)
    a = path[:-1]
    ab = path[1:] - a
    l2 = np.maximum(np.sum(ab**2, axis=1), 1e-300)
    best = np.full(q.shape[0], np.inf)
    for m in range(a.shape[0]):
        u = np.clip((q - a[m]) @ ab[m] / l2[m], 0.0, 1.0)
        d = np.sum((q - a[m] - u[:, None] * ab[m]) ** 2, axis=1)
        np.minimum(best, d, out=best)
    out = np.sqrt(best)
    return out
