"""The robot side as a gripper pose path: the ``gripper`` channel group.

A demonstration without robot joints (a human-human recording, where the giver's hand or the object
plays the robot, or another robot's whose joints are not wanted) gives the robot side as the
gripper's pose path: position x, y, z in [m] in the scene frame (the base frame of the robot the
arms' ``[placement]`` refer to: Baxter's for the shipped data) and a unit quaternion qx, qy, qz, qw
(scalar last, as ROS's ``geometry_msgs/Pose``), the channels
:data:`~ipromp_pin.data.GRIPPER_CHANNELS`.

The model fits a Gaussian over the basis weights of these 7 channels. q and -q are the same
rotation, so the quaternion's sign is made consistent before the weights are fitted: sign-continuous
along each demo (:func:`gripper_values`) and, across demos, every demo in the hemisphere of one
reference quaternion (:func:`aligned_gripper`, the reference the chordal mean of the training
demos' quaternions, :func:`quaternion_reference`). Within that hemisphere the components are a
smooth chart of the rotations near the reference: their mean, renormalised, is the chordal mean of
the rotations, and the ProMP's conditioning and sampling stay linear-Gaussian. The output's
quaternion is renormalised where it becomes a pose (:func:`gripper_rotations`).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..data import GRIPPER_CHANNELS
from ..exceptions import DataError
from .checks import GRIPPER_QUATERNION_TOLERANCE, POSITION_BOUND_M, GroupCheck, check_norms
from .preprocess import quaternion_continuity

POSITION = slice(0, 3)
"""The position channels (x, y, z [m]) of a gripper group in canonical order."""

QUATERNION = slice(3, 7)
"""The quaternion channels (qx, qy, qz, qw) of a gripper group in canonical order."""


def check_gripper(source: object, field: str, values: np.ndarray, names: Sequence[str]) -> None:
    """Refuse a gripper group (N, 7) that is not a pose path: other channels than
    :data:`~ipromp_pin.data.GRIPPER_CHANNELS` (a position-only path named as such), NaN or inf, a
    position beyond :data:`~ipromp_pin.signals.checks.POSITION_BOUND_M` or a quaternion whose norm is
    not 1 within :data:`~ipromp_pin.signals.checks.GRIPPER_QUATERNION_TOLERANCE`."""
    have = [str(n) for n in names]
    want = list(GRIPPER_CHANNELS)
    if sorted(have) != sorted(want) or len(set(have)) != len(have):
        missing = [c for c in want if c not in have]
        unknown = [c for c in have if c not in want]
        what = f"it has {', '.join(have) or 'no channel'}"
        if missing and set(missing) >= {"qx", "qy", "qz", "qw"}:
            what += " (no orientation: the arm's inverse kinematics follows the full pose, not a position)"
        elif unknown:
            what += f" (unknown: {', '.join(unknown)})"
        raise DataError(
            source,
            field,
            f"a gripper group needs the channels {', '.join(want)} (position [m], unit quaternion scalar "
            f"last); {what}",
        )
    v = np.asarray(values, dtype=float)
    bad = ~np.isfinite(v)
    if np.any(bad):
        rows, cols = np.nonzero(bad)
        raise DataError(
            source, f"{field}/{have[cols[0]]}", f"{rows.size} NaN or inf values (first in sample {rows[0]})"
        )
    v = v[:, [have.index(c) for c in want]]
    check_norms(source, f"{field}/position", v[:, POSITION], 0.0, POSITION_BOUND_M, "m")
    tol = GRIPPER_QUATERNION_TOLERANCE
    check_norms(source, f"{field}/quaternion", v[:, QUATERNION], 1.0 - tol, 1.0 + tol, "")


@dataclass(frozen=True)
class GripperPoseCheck(GroupCheck):
    """The plausibility check of a gripper group (:func:`check_gripper`)."""

    def check(
        self,
        source: object,
        field: str,
        values: np.ndarray,
        channel_names: Sequence[str],
        joint_limits: Mapping[str, tuple[float, float]] | None = None,
    ) -> None:  # noqa: D102
        check_gripper(source, field, values, channel_names)


def gripper_values(source: object, field: str, values: np.ndarray, names: Sequence[str]) -> np.ndarray:
    """A gripper group (N, 7) checked (:func:`check_gripper`), in the canonical channel order, its
    quaternion normalised and sign-continuous along the path."""
    check_gripper(source, field, values, names)
    v = np.asarray(values, dtype=float)[:, [list(names).index(c) for c in GRIPPER_CHANNELS]]
    return np.hstack([v[:, POSITION], quaternion_continuity(v[:, QUATERNION])])


def quaternion_reference(quaternions: Iterable[np.ndarray]) -> np.ndarray:
    """The chordal mean (4,) of quaternions (each (N, 4), either sign): the principal eigenvector of
    the sum of their outer products (sign-blind), its largest component made positive (deterministic).
    """
    m = np.zeros((4, 4))
    for q in quaternions:
        q = np.asarray(q, dtype=float)
        m += q.T @ q
    _, vec = np.linalg.eigh(m)
    ref = vec[:, -1]
    return ref if ref[np.argmax(np.abs(ref))] > 0 else -ref


def aligned_gripper(values: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """A sign-continuous gripper path (N, 7) turned into the hemisphere of ``reference`` (4,): its
    quaternion negated as a whole when it lies, on average, on the other side."""
    v = np.array(values, dtype=float)
    if float(np.mean(v[:, QUATERNION] @ np.asarray(reference, dtype=float))) < 0.0:
        v[:, QUATERNION] *= -1.0
    return v


def gripper_positions(values: np.ndarray) -> np.ndarray:
    """Gripper positions (n, 3) [m] of gripper values (n, 7) (the model's forward kinematics)."""
    return np.asarray(values, dtype=float)[..., POSITION]


def gripper_rotations(values: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) of gripper values (n, 7), their quaternions renormalised."""
    q = np.asarray(values, dtype=float)[..., QUATERNION]
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(norm < 1e-9):
        raise DataError(None, "gripper", "a predicted quaternion has zero norm: no orientation")
    x, y, z, w = np.moveaxis(q / norm, -1, 0)
    rot = np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
            np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
            np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
        ],
        axis=-2,
    )
    return rot


def pose_values(positions: np.ndarray, quaternions_xyzw: np.ndarray) -> np.ndarray:
    """Gripper values (n, 7) of positions (n, 3) [m] and quaternions (n, 4) (x, y, z, w),
    sign-continuous."""
    return np.hstack([np.asarray(positions, dtype=float), quaternion_continuity(quaternions_xyzw)])
