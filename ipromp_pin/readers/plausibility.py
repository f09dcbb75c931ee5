"""Plausibility checks of recorded values: what the sensors and the robot can physically report.

A value can be finite and still impossible: a joint angle of 100 rad, angles in degrees, a
quaternion of norm 3, an EMG sample of 1e300, a tracked hand 1e300 m away, an armband that sent
only zeros, a recording cut to a tenth of its task's usual length. Such values silently distort a
model (one EMG sample of 1e300 moved a learned channel scaling from 0.585 to 103.7), so every
reader checks each demo against the limits below and refuses it with a
:class:`~ipromp_pin.exceptions.DataError` naming the file, the channel, the value and the limit.

Limits (units in the names; sources in each constant's docstring):

* joint angles: inside the robot's joint limits (from its URDF, passed by the caller as
  ``joint_limits``) widened by :data:`JOINT_LIMIT_MARGIN_RAD`; without them, within
  :data:`GENERIC_JOINT_BOUND_RAD`;
* orientation quaternions: unit norm within :data:`UNIT_QUATERNION_TOLERANCE`;
* EMG: raw samples in :data:`EMG_RAW_RANGE`, envelopes in :data:`EMG_ENVELOPE_RANGE`; and not
  constant on every channel over the whole demo (an armband that sent nothing);
* accelerations: norm of each sample at most :data:`ACCELERATION_MAX_G`;
* positions (tracked frames, the robot's end-point, the human hand): within
  :data:`POSITION_BOUND_M` of the robot's base;
* durations: every demo of a task lasts between :data:`DURATION_RATIO_RANGE` times the task's
  median duration (checked by :func:`check_durations` on a whole dataset, tasks of 3 demos or more).

The checks here read :class:`~ipromp_pin.data.Demo` groups by their conventional names
(``"robot"``, ``"orientation"``, ``"emg"``, ``"acc"``, skeleton frames ``"/..."``) and the extras
``"endpoint_pose"`` and ``"hand_position"``; other groups need only be finite (the Demo checks that).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from ..data import ROBOT, Demo
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

DURATION_RATIO_RANGE = (1.0 / 3.0, 3.0)
"""A demo's duration divided by its task's median duration must lie in this range. Measured on
the 189 real demos: 0.52 to 1.53; a recording cut to a third of its task's length or shorter is
refused (a truncated file or a stopped recorder)."""

SKELETON_PREFIX = "/"
"""Channel groups whose name starts with this are tracked positions x, y, z in [m]."""


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


def check_demo(demo: Demo, joint_limits: Mapping[str, tuple[float, float]] | None = None) -> Demo:
    """Check the groups and extras of ``demo`` with conventional names against the physical limits.

    Args:
        demo: A demo as a reader produced it (EMG as an envelope).
        joint_limits: Recorded joint name -> (lower, upper) in [rad] of the robot.

    Returns:
        ``demo`` unchanged.

    Raises:
        DataError: naming the file, channel, value and limit of the first implausible value.
    """
    src = demo.source
    for g, v in demo.groups.items():
        names = demo.channel_names[g]
        if g == ROBOT:
            check_joint_angles(src, g, v, names, joint_limits)
        elif g == "orientation" and v.shape[1] == 4:
            check_norms(src, g, v, 1 - UNIT_QUATERNION_TOLERANCE, 1 + UNIT_QUATERNION_TOLERANCE, "")
        elif g == "emg":
            check_range(src, g, v, *EMG_ENVELOPE_RANGE, "", names)
            check_emg_activity(src, g, v)
        elif g == "acc" and v.shape[1] == 3:
            check_norms(src, g, v, 0.0, ACCELERATION_MAX_G, "g")
        elif g.startswith(SKELETON_PREFIX):
            check_norms(src, g, v, 0.0, POSITION_BOUND_M, "m")
    pose = demo.extras.get("endpoint_pose")
    if pose is not None and np.ndim(pose) == 2 and np.shape(pose)[1] == 7:
        check_norms(src, "extras:endpoint_pose/position", pose[:, :3], 0.0, POSITION_BOUND_M, "m")
        check_norms(
            src,
            "extras:endpoint_pose/orientation",
            pose[:, 3:],
            1 - UNIT_QUATERNION_TOLERANCE,
            1 + UNIT_QUATERNION_TOLERANCE,
            "",
        )
    hand = demo.extras.get("hand_position")
    if hand is not None and np.ndim(hand) == 2 and np.shape(hand)[1] == 3:
        check_norms(src, "extras:hand_position", hand, 0.0, POSITION_BOUND_M, "m")
    for name, v in demo.extras.items():
        a = np.asarray(v, dtype=float)
        if np.any(np.isinf(a)):
            raise DataError(src, f"extras:{name}", "infinite values")
    return demo


def check_durations(demos: Mapping[str, Iterable[Demo]]) -> None:
    """Refuse a demo whose duration is an outlier of its task (see :data:`DURATION_RATIO_RANGE`).

    Args:
        demos: Task -> its demos. Tasks with fewer than 3 demos are not checked (no median to
            compare with).

    Raises:
        DataError: naming the demo, its duration and the task's median.
    """
    lo, hi = DURATION_RATIO_RANGE
    for task, items in demos.items():
        items = list(items)
        if len(items) < 3:
            continue
        d = np.array([float(x.duration_s) for x in items])
        med = float(np.median(d))
        for x, dur in zip(items, d, strict=True):
            if not (lo * med <= dur <= hi * med):
                raise DataError(
                    x.source,
                    "duration",
                    f"the demo lasts {dur:.3g} s, {dur / med:.0%} of its task '{task}''s median {med:.3g} s "
                    f"(plausible: {lo:.0%} to {hi:.0%}; a truncated or overlong recording?)",
                )
