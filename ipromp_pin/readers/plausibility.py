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

Each group is checked by the check of its channel-group specification
(:func:`ipromp_pin.signals.groups.group_spec`: ``"robot"``, ``"orientation"``, ``"emg"``, ``"acc"``,
skeleton frames ``"/..."``, and the extras ``"endpoint_pose"`` and ``"hand_position"``); a group
without a specification gets the generic magnitude check
(:data:`~ipromp_pin.signals.checks.GENERIC_MAGNITUDE_BOUND`), never none. The limits and the check
primitives live in :mod:`ipromp_pin.signals.checks` (re-exported here).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

from ..data import Demo
from ..exceptions import DataError
from ..signals.checks import (
    ACCELERATION_MAX_G,
    EMG_ENVELOPE_RANGE,
    EMG_RAW_RANGE,
    GENERIC_JOINT_BOUND_RAD,
    GENERIC_MAGNITUDE_BOUND,
    JOINT_LIMIT_MARGIN_RAD,
    POSITION_BOUND_M,
    UNIT_QUATERNION_TOLERANCE,
    check_emg_activity,
    check_joint_angles,
    check_norms,
    check_range,
)
from ..signals.groups import SKELETON_PREFIX, group_spec, registered_groups
from .streams import full_duration_s

__all__ = [
    "ACCELERATION_MAX_G",
    "DURATION_RATIO_RANGE",
    "EMG_ENVELOPE_RANGE",
    "EMG_RAW_RANGE",
    "GENERIC_JOINT_BOUND_RAD",
    "GENERIC_MAGNITUDE_BOUND",
    "JOINT_LIMIT_MARGIN_RAD",
    "POSITION_BOUND_M",
    "SKELETON_PREFIX",
    "UNIT_QUATERNION_TOLERANCE",
    "check_demo",
    "check_durations",
    "check_emg_activity",
    "check_joint_angles",
    "check_norms",
    "check_range",
]

DURATION_RATIO_RANGE = (1.0 / 3.0, 3.0)
"""A demo's duration divided by its task's median duration must lie in this range. Measured on
the 189 real demos: 0.52 to 1.53; a recording cut to a third of its task's length or shorter is
refused (a truncated file or a stopped recorder)."""


def check_demo(demo: Demo, joint_limits: Mapping[str, tuple[float, float]] | None = None) -> Demo:
    """Check the groups and extras of ``demo`` against their channel-group specifications.

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
        group_spec(g).check_values(src, g, v, demo.channel_names[g], joint_limits)
    for spec in registered_groups():
        extra = demo.extras.get(spec.name) if spec.extra else None
        if extra is not None and np.ndim(extra) == 2 and spec.fits(np.shape(extra)[1]):
            spec.check(src, f"extras:{spec.name}", extra, spec.channels, joint_limits)
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
        d = np.array([full_duration_s(x) for x in items])
        med = float(np.median(d))
        for x, dur in zip(items, d, strict=True):
            if not (lo * med <= dur <= hi * med):
                raise DataError(
                    x.source,
                    "duration",
                    f"the demo lasts {dur:.3g} s, {dur / med:.0%} of its task '{task}''s median {med:.3g} s "
                    f"(plausible: {lo:.0%} to {hi:.0%}; a truncated or overlong recording?)",
                )
