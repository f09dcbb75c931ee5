"""Physical limits of recorded values and the check objects of channel groups.

A value can be finite and still impossible: a joint angle of 100 rad, a quaternion of norm 3, an
EMG sample of 1e300. The limits below (units in the names, sources in each constant's docstring)
and the check functions are the primitives; a :class:`GroupCheck` binds them to one channel group
(:mod:`ipromp_pin.signals.groups` gives each group its check). Every check raises
:class:`~ipromp_pin.exceptions.DataError` naming the file, the channel, the value and the limit.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..exceptions import DataError

JOINT_LIMIT_MARGIN_RAD = 0.1
"""Recorded joint angles may exceed the robot's URDF limits by this much, in [rad]. The real
recordings stay within 1 mrad of them (largest excursion 0.99 mrad, handover_20171128; chen2017
stays 36 mrad inside); 0.1 rad (5.7 deg) leaves room for encoder offsets and still refuses angles
in degrees or multiples of 2 pi."""

GENERIC_JOINT_BOUND_RAD = 2.0 * math.pi + JOINT_LIMIT_MARGIN_RAD
"""Largest joint angle magnitude in [rad] when the robot's limits are not given: one turn (a
revolute joint's range rarely exceeds it; Baxter's largest is +-3.06 rad) plus the margin."""

UNIT_QUATERNION_TOLERANCE = 0.1
"""Largest deviation of an orientation quaternion's norm from 1 (after the device's scaling).
The Myo's quaternions are unit to about 1e-4 (16384 raw units per 1, myohw.h); 0.1 refuses a
wrong scaling or a corrupt sample, the reader then normalises the rest."""

EMG_RAW_RANGE = (0.0, 65535.0)
"""Range of a raw EMG sample: the Myo driver that recorded the datasets (myo_raw) unpacks each
channel as an unsigned 16-bit integer (the ROS message stores uint32). Measured: 18-986."""

EMG_ENVELOPE_RANGE = (-0.1 * 65535.0, 65535.0)
"""Range of an EMG envelope (the rectified, low-pass filtered raw signal of
:func:`~ipromp_pin.signals.preprocess.emg_envelope`): the raw range, with room below 0 for the 2nd-order
filter's undershoot (at most about 4 % of a step)."""

ACCELERATION_MAX_G = 16.0
"""Largest acceleration magnitude in [g]: the Myo accelerometer's full scale (+-16 g; 2048 raw
units per g, myohw.h). Measured on the real recordings: at most 1.22 g."""

POSITION_BOUND_M = 10.0
"""Largest distance in [m] of a tracked position or of the robot's end-point from the robot's base
frame. Skeleton trackers see up to about 5 m, Baxter reaches 1.2 m; measured at most 1.28 m."""


GRIPPER_QUATERNION_TOLERANCE = 0.01
"""Largest deviation of a gripper pose's quaternion norm from 1. A pose exported with 4 significant
digits or more is unit to about 1e-4; 0.01 refuses a corrupt sample or a quaternion whose fields are
not one quaternion's (the reader then normalises the rest exactly)."""

POSE_CHANNELS = frozenset({"x", "y", "z", "qx", "qy", "qz", "qw"})
"""Channel names of a pose (the gripper group's): never joint names."""

GRIPPER_HINT = (
    "a robot side given as a gripper pose path goes in a 'gripper' group: position x, y, z [m] in the "
    "scene frame and a unit quaternion qx, qy, qz, qw (docs/your_data.md)"
)
"""What a robot side given as poses needs (the end of a one-line error)."""


def pose_like(names: Sequence[str]) -> list[str]:
    """The names among ``names`` that are a pose's channels (x, y, z, qx ... qw), not joints."""
    return [n for n in names if n.lower() in POSE_CHANNELS]


def _first_bad(mask: np.ndarray) -> tuple[int, int]:
    rows, cols = np.nonzero(mask.reshape(mask.shape[0], -1))
    return int(rows[0]), int(cols[0])


def check_range(
    source: object,
    field: str,
    values: np.ndarray,
    low: float,
    high: float,
    unit: str,
    channel_names: Sequence[str] | None = None,
    what: str = "sample",
) -> None:
    """Raise :class:`DataError` when a finite value of ``values`` (N, D) lies outside ``[low, high]``.

    The message names the channel, the first bad value, where it is, and how many values are bad.
    NaN values are ignored (missing samples are checked elsewhere).
    """
    v = np.asarray(values, dtype=float)
    with np.errstate(invalid="ignore"):
        bad = (v < low) | (v > high)
    if not np.any(bad):
        return
    row, col = _first_bad(bad)
    name = field if channel_names is None else f"{field}/{channel_names[col]}"
    value = v.reshape(v.shape[0], -1)[row, col]
    raise DataError(
        source,
        name,
        f"implausible value {value:.6g} {unit} in {what} {row} (physical range [{low:g}, {high:g}] {unit}; "
        f"{int(bad.sum())} such values)",
    )


def check_norms(
    source: object, field: str, values: np.ndarray, low: float, high: float, unit: str, what: str = "sample"
) -> None:
    """Raise :class:`DataError` when the norm of a finite row of ``values`` (N, D) is outside [low, high]."""
    v = np.asarray(values, dtype=float)
    with np.errstate(invalid="ignore"):
        big = np.abs(v) > high  # a component beyond the bound: its norm is too (and may overflow)
    if np.any(big):
        row, col = _first_bad(big)
        raise DataError(
            source,
            field,
            f"implausible component {v[row, col]:.6g} {unit} in {what} {row} (the norm must be in "
            f"[{low:g}, {high:g}] {unit}; {int(np.any(big, axis=1).sum())} such {what}s)",
        )
    norm = np.linalg.norm(v, axis=1)
    with np.errstate(invalid="ignore"):
        bad = (norm < low) | (norm > high)
    if not np.any(bad):
        return
    row = int(np.flatnonzero(bad)[0])
    raise DataError(
        source,
        field,
        f"implausible norm {norm[row]:.6g} {unit} in {what} {row} (must be in [{low:g}, {high:g}] {unit}; "
        f"{int(bad.sum())} such {what}s)",
    )


def check_joint_angles(
    source: object,
    field: str,
    q: np.ndarray,
    names: Sequence[str],
    joint_limits: Mapping[str, tuple[float, float]] | None = None,
    what: str = "sample",
) -> None:
    """Joint angles (N, J) in [rad] inside the limits widened by :data:`JOINT_LIMIT_MARGIN_RAD`.

    Args:
        source: File for the message.
        field: Field name for the message (e.g. ``"robot"``).
        q: Joint angles (N, J) in [rad].
        names: The J joint names (as recorded).
        joint_limits: Joint name -> (lower, upper) in [rad] (the robot's URDF limits); joints not
            listed (or all, when None) must lie within :data:`GENERIC_JOINT_BOUND_RAD`.
    """
    posed = pose_like(names)
    if posed:  # never a position or a quaternion labelled as joint angles in [rad]
        raise DataError(
            source,
            field,
            f"channels {', '.join(posed)} are a pose, not joint angles in [rad]: " + GRIPPER_HINT,
        )
    q = np.asarray(q, dtype=float)
    m = JOINT_LIMIT_MARGIN_RAD
    lo = np.full(len(names), -GENERIC_JOINT_BOUND_RAD)
    hi = np.full(len(names), GENERIC_JOINT_BOUND_RAD)
    for j, n in enumerate(names):
        if joint_limits is not None and n in joint_limits:
            lo[j], hi[j] = joint_limits[n][0] - m, joint_limits[n][1] + m
    with np.errstate(invalid="ignore"):
        bad = (q < lo) | (q > hi)
    if not np.any(bad):
        return
    row, col = _first_bad(bad)
    raise DataError(
        source,
        f"{field}/{names[col]}",
        f"implausible joint angle {q[row, col]:.6g} rad in {what} {row} (the joint's limits with a "
        f"{m:g} rad margin are [{lo[col]:.4g}, {hi[col]:.4g}] rad; {int(bad.sum())} such values; "
        "angles in degrees?)",
    )


def check_emg_activity(source: object, field: str, emg: np.ndarray) -> None:
    """Raise :class:`DataError` when every EMG channel is constant over the whole demo (e.g. all
    zero: the armband sent no signal)."""
    v = np.asarray(emg, dtype=float)
    if v.shape[0] < 2:
        return
    span = np.nanmax(v, axis=0) - np.nanmin(v, axis=0)
    if np.all(span == 0):
        raise DataError(
            source,
            field,
            f"every EMG channel is constant over the demo (value {v[0, 0]:g}): the armband sent no signal",
        )


GENERIC_MAGNITUDE_BOUND = 1e12
"""Largest magnitude of a value of a channel group without a specification (any unit): no sensor
of a hand-over reports 1e12 in its unit, a corrupt sample (1e300) does."""


JointLimitMap = Mapping[str, tuple[float, float]]
"""Recorded joint name -> (lower, upper) limits in [rad] (the robot's URDF limits)."""


class GroupCheck:
    """The plausibility check of one channel group's values (N, D); subclasses fill :meth:`check`."""

    def check(
        self,
        source: object,
        field: str,
        values: np.ndarray,
        channel_names: Sequence[str],
        joint_limits: JointLimitMap | None = None,
    ) -> None:
        """Raise :class:`DataError` naming ``source`` and ``field`` when a value is implausible."""
        raise NotImplementedError

    def __call__(
        self,
        source: object,
        field: str,
        values: np.ndarray,
        channel_names: Sequence[str],
        joint_limits: Mapping[str, tuple[float, float]] | None = None,
    ) -> None:
        self.check(source, field, values, channel_names, joint_limits)


@dataclass(frozen=True)
class RangeCheck(GroupCheck):
    """Every value in ``[low, high]`` (in ``unit``); the message names the channel."""

    low: float
    high: float
    unit: str = ""

    def check(
        self,
        source: object,
        field: str,
        values: np.ndarray,
        channel_names: Sequence[str],
        joint_limits: JointLimitMap | None = None,
    ) -> None:  # noqa: D102
        check_range(source, field, values, self.low, self.high, self.unit, channel_names)


@dataclass(frozen=True)
class NormCheck(GroupCheck):
    """The norm of every sample (row) in ``[low, high]`` (in ``unit``)."""

    low: float
    high: float
    unit: str = ""

    def check(
        self,
        source: object,
        field: str,
        values: np.ndarray,
        channel_names: Sequence[str],
        joint_limits: JointLimitMap | None = None,
    ) -> None:  # noqa: D102
        check_norms(source, field, values, self.low, self.high, self.unit)


@dataclass(frozen=True)
class JointAngleCheck(GroupCheck):
    """Joint angles in [rad] inside the robot's limits (``joint_limits``) widened by the margin."""

    def check(
        self,
        source: object,
        field: str,
        values: np.ndarray,
        channel_names: Sequence[str],
        joint_limits: JointLimitMap | None = None,
    ) -> None:  # noqa: D102
        check_joint_angles(source, field, values, channel_names, joint_limits)


@dataclass(frozen=True)
class ActivityCheck(GroupCheck):
    """Not every channel constant over the demo (an EMG armband that sent nothing)."""

    def check(
        self,
        source: object,
        field: str,
        values: np.ndarray,
        channel_names: Sequence[str],
        joint_limits: JointLimitMap | None = None,
    ) -> None:  # noqa: D102
        check_emg_activity(source, field, values)


@dataclass(frozen=True)
class PoseCheck(GroupCheck):
    """Poses (N, 7): position x, y, z within ``position_bound_m`` [m], then a unit quaternion."""

    position_bound_m: float = POSITION_BOUND_M
    tolerance: float = UNIT_QUATERNION_TOLERANCE

    def check(
        self,
        source: object,
        field: str,
        values: np.ndarray,
        channel_names: Sequence[str],
        joint_limits: JointLimitMap | None = None,
    ) -> None:  # noqa: D102
        v = np.asarray(values, dtype=float)
        check_norms(source, f"{field}/position", v[:, :3], 0.0, self.position_bound_m, "m")
        check_norms(source, f"{field}/orientation", v[:, 3:], 1 - self.tolerance, 1 + self.tolerance, "")


@dataclass(frozen=True)
class MagnitudeCheck(GroupCheck):
    """Generic check of a group without a specification: every value within ``bound`` (any unit)."""

    bound: float = GENERIC_MAGNITUDE_BOUND

    def check(
        self,
        source: object,
        field: str,
        values: np.ndarray,
        channel_names: Sequence[str],
        joint_limits: JointLimitMap | None = None,
    ) -> None:  # noqa: D102
        v = np.asarray(values, dtype=float).reshape(np.shape(values)[0], -1)
        with np.errstate(invalid="ignore"):
            bad = np.abs(v) > self.bound
        if not np.any(bad):
            return
        rows, cols = np.nonzero(bad)
        raise DataError(
            source,
            f"{field}/{channel_names[cols[0]]}",
            f"implausible value {v[rows[0], cols[0]]:.6g} in sample {rows[0]} (the group has no "
            f"channel-group specification: only |value| <= {self.bound:g} is checked; "
            f"{int(bad.sum())} such values)",
        )


@dataclass(frozen=True)
class AllChecks(GroupCheck):
    """Several checks, in order (the first failing one raises)."""

    checks: tuple[GroupCheck, ...]

    def check(
        self,
        source: object,
        field: str,
        values: np.ndarray,
        channel_names: Sequence[str],
        joint_limits: JointLimitMap | None = None,
    ) -> None:  # noqa: D102
        for c in self.checks:
            c.check(source, field, values, channel_names, joint_limits)
