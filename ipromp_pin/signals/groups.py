"""Channel-group specifications: one entry per kind of channel group, read by every step.

A :class:`ChannelGroup` says what a group's values are (unit, default channel names), how they are
resampled (interpolation kind), what values are physically plausible (a check object of
:mod:`.checks`), whether a model fits them in log space by default, and which ROS message carries
one sample in a bag. The readers, the plausibility checks (:mod:`ipromp_pin.readers.plausibility`),
the native resampling, the IProMP's ``log_groups`` default and the rosbag writer
(:mod:`ipromp_pin.outputs.rosbag`) all read it: adding a sensor group is one :func:`register_group`
call plus its reader.

Entries: ``"robot"`` (joint angles), ``"gripper"`` (the robot side as a gripper pose path),
``"orientation"`` (Myo quaternion), ``"emg"`` (Myo EMG
envelopes), ``"acc"`` (Myo accelerations), skeleton frames ``"/<frame>"`` (a name pattern: every
group whose name starts with ``/``), and the extras ``"hand_position"`` and ``"endpoint_pose"``
(time-aligned signals that are not modelled). A group without an entry gets
:func:`generic_group`: no unit, linear interpolation, a ``Float64MultiArray`` in a bag and only a
generic magnitude check (:class:`~.checks.MagnitudeCheck`), never silently unchecked.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..data import GRIPPER, GRIPPER_CHANNELS, ROBOT
from ..exceptions import DataError
from .checks import (
    ACCELERATION_MAX_G,
    EMG_ENVELOPE_RANGE,
    POSITION_BOUND_M,
    UNIT_QUATERNION_TOLERANCE,
    ActivityCheck,
    AllChecks,
    GroupCheck,
    JointAngleCheck,
    MagnitudeCheck,
    NormCheck,
    PoseCheck,
    RangeCheck,
)
from .gripper import GripperPoseCheck

INTERPOLATIONS = ("linear", "previous", "quaternion", "pose")
"""Interpolation kinds of :func:`ipromp_pin.signals.preprocess.align_streams`."""

RosTypes = Mapping[str, Any]
"""Message classes of a ``rosbags`` typestore by type name (``store.types``)."""

QUATERNION_STAMPED = "geometry_msgs/msg/QuaternionStamped"
POINT_STAMPED = "geometry_msgs/msg/PointStamped"
FLOAT64_MULTI_ARRAY = "std_msgs/msg/Float64MultiArray"


@dataclass(frozen=True)
class RosMessage:
    """How one sample of a group becomes a ROS message in a bag.

    Attributes:
        msgtype: The message type, e.g. ``"geometry_msgs/msg/PointStamped"``.
        build: ``build(types, header, label, values, channel_names)`` -> the message object, from the
            typestore's classes, a ready ``std_msgs/Header`` (stamp and frame set; None when not
            ``stamped``), the group's name, one sample (D,) and the D channel names.
        stamped: The message has a header (its stamp is the sample's time).
        in_base_frame: The header's ``frame_id`` is the robot's base frame (else ``""``).
        fits: ``fits(channel_names)``: whether this message can carry the group (e.g. a quaternion
            needs channels named w, x, y, z); when not, the sample is written as
            :data:`ARRAY_MESSAGE`.
    """

    msgtype: str
    build: Callable[[RosTypes, object, str, np.ndarray, tuple[str, ...]], object]
    stamped: bool = True
    in_base_frame: bool = False
    fits: Callable[[tuple[str, ...]], bool] = lambda names: True


def quaternion_columns(names: Sequence[str]) -> list[int] | None:
    """Column indices of x, y, z, w among quaternion channel names (``qx`` or ``x`` ...), or None."""
    cols = _quaternion_columns(tuple(names))
    return None if cols is None else list(cols)


@functools.lru_cache(maxsize=64)
def _quaternion_columns(names: tuple[str, ...]) -> tuple[int, ...] | None:
    short = [n.lower().removeprefix("q") for n in names]
    if len(short) == 4 and sorted(short) == ["w", "x", "y", "z"]:
        return tuple(short.index(c) for c in "xyzw")
    return None


def _point(types: RosTypes, xyz: np.ndarray) -> object:
    return types["geometry_msgs/msg/Point"](x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2]))


def _quaternion_stamped(types: RosTypes, header: object, label: str, v: np.ndarray, names) -> object:
    x, y, z, w = (float(c) for c in v[quaternion_columns(names)])
    q = types["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)
    return types[QUATERNION_STAMPED](header=header, quaternion=q)


def _point_stamped(types: RosTypes, header: object, label: str, v: np.ndarray, names) -> object:
    return types[POINT_STAMPED](header=header, point=_point(types, v))


def _array(types: RosTypes, header: object, label: str, v: np.ndarray, names) -> object:
    dim = types["std_msgs/msg/MultiArrayDimension"](label=label, size=v.size, stride=v.size)
    layout = types["std_msgs/msg/MultiArrayLayout"](dim=[dim], data_offset=0)
    return types[FLOAT64_MULTI_ARRAY](layout=layout, data=np.ascontiguousarray(v, dtype=np.float64))


ARRAY_MESSAGE = RosMessage(FLOAT64_MULTI_ARRAY, _array, stamped=False)
"""Any group: ``std_msgs/msg/Float64MultiArray`` (no header; one value per channel)."""
QUATERNION_MESSAGE = RosMessage(
    QUATERNION_STAMPED, _quaternion_stamped, fits=lambda names: quaternion_columns(names) is not None
)
"""A 4-channel orientation named w, x, y, z (or qw ...): ``geometry_msgs/msg/QuaternionStamped``."""
POINT_MESSAGE = RosMessage(POINT_STAMPED, _point_stamped, in_base_frame=True, fits=lambda n: len(n) == 3)
"""A position x, y, z in [m] in the base frame: ``geometry_msgs/msg/PointStamped``."""


@dataclass(frozen=True)
class ChannelGroup:
    """Specification of one kind of channel group.

    Attributes:
        name: The group's name (``"emg"``), or with ``prefix`` a name pattern: every group whose
            name starts with it (``"/"``: the skeleton frames ``"/<frame>"``).
        unit: Unit of the values (``"m"``, ``"rad"``, ...; ``""`` when unknown).
        interpolation: How the demo's values are resampled (one of :data:`INTERPOLATIONS`).
        check: The plausibility check of the demo's values (:mod:`.checks`).
        log_space: Whether an IProMP models the group in log space by default (EMG envelopes).
        ros_message: The ROS message of one sample in a bag (None: not written).
        channels: Default channel names (empty when they depend on the recording, e.g. the robot's
            joints).
        n_channels: The channel count the quaternion interpolation and the check need (None: any);
            a group of another count is resampled linearly and checked generically.
        raw_interpolation: How the reader resamples the raw stream before its processing (the raw
            EMG is held, then turned into an envelope); None: ``interpolation``.
        prefix: ``name`` is a prefix pattern.
        extra: An extra of :class:`~ipromp_pin.data.Demo` (time-aligned, not modelled), not a group.
    """

    name: str
    unit: str = ""
    interpolation: str = "linear"
    check: GroupCheck = field(default_factory=MagnitudeCheck)
    log_space: bool = False
    ros_message: RosMessage | None = ARRAY_MESSAGE
    channels: tuple[str, ...] = ()
    n_channels: int | None = None
    raw_interpolation: str | None = None
    prefix: bool = False
    extra: bool = False

    def __post_init__(self) -> None:
        for key in ("interpolation", "raw_interpolation"):
            kind = getattr(self, key)
            if kind is not None and kind not in INTERPOLATIONS:
                raise DataError(self.name, key, f"unknown interpolation {kind!r} (use {INTERPOLATIONS})")
        if not self.name:
            raise DataError(None, "name", "a channel group needs a name")

    def matches(self, group: str) -> bool:
        """Whether the group named ``group`` is of this kind."""
        return group.startswith(self.name) if self.prefix else group == self.name

    def fits(self, n_channels: int) -> bool:
        """Whether a group of ``n_channels`` channels has the shape this specification needs."""
        return self.n_channels is None or self.n_channels == n_channels

    def interpolation_kind(self, n_channels: int) -> str:
        """Interpolation of a demo's group of ``n_channels`` channels."""
        return self.interpolation if self.fits(n_channels) else "linear"

    @property
    def raw_kind(self) -> str:
        """Interpolation of the raw stream a reader resamples."""
        return self.raw_interpolation or self.interpolation

    def check_values(
        self,
        source: object,
        field: str,
        values: np.ndarray,
        channel_names: Sequence[str],
        joint_limits: Mapping[str, tuple[float, float]] | None = None,
    ) -> None:
        """Check values (N, D) against this specification (the generic check when of another shape)."""
        v = np.asarray(values)
        check = self.check if v.ndim == 2 and self.fits(v.shape[1]) else MagnitudeCheck()
        check(source, field, v, channel_names, joint_limits)

    def ros_message_for(self, channel_names: Sequence[str]) -> RosMessage | None:
        """The message carrying a sample of a group with these channels (None: not written)."""
        m = self.ros_message
        if m is None:
            return None
        return m if m.fits(tuple(channel_names)) else ARRAY_MESSAGE


_EXACT: dict[str, ChannelGroup] = {}
_PATTERNS: dict[str, ChannelGroup] = {}


def register_group(spec: ChannelGroup, *, replace: bool = False) -> ChannelGroup:
    """Add a channel-group specification (a new sensor group: one call plus its reader).

    Raises:
        DataError: a specification of that name exists and ``replace`` is False.
    """
    table = _PATTERNS if spec.prefix else _EXACT
    if spec.name in table and not replace:
        raise DataError(None, spec.name, "a channel group of this name is already registered")
    table[spec.name] = spec
    return spec


def unregister_group(name: str) -> None:
    """Remove the specification registered under ``name`` (exact name or pattern); no-op if none."""
    _EXACT.pop(name, None)
    _PATTERNS.pop(name, None)


def generic_group(name: str) -> ChannelGroup:
    """The specification of a group nobody registered (see the module docstring)."""
    return ChannelGroup(name)


def is_registered(name: str) -> bool:
    """Whether ``name`` has a specification (exact, or by a pattern)."""
    return name in _EXACT or any(p.matches(name) for p in _PATTERNS.values())


def group_spec(name: str) -> ChannelGroup:
    """The specification of the group (or extra) ``name``: its exact entry, else the longest matching
    pattern, else :func:`generic_group`."""
    spec = _EXACT.get(name)
    if spec is not None:
        return spec
    hits = [p for p in _PATTERNS.values() if p.matches(name)]
    if hits:
        return max(hits, key=lambda p: len(p.name))
    return generic_group(name)


def registered_groups() -> Iterator[ChannelGroup]:
    """Every registered specification, exact names first, in registration order."""
    yield from _EXACT.values()
    yield from _PATTERNS.values()


def default_log_groups() -> tuple[str, ...]:
    """Registered groups modelled in log space by default (``("emg",)`` with the built-in entries)."""
    return tuple(s.name for s in _EXACT.values() if s.log_space and not s.extra)


def group_unit(group: str) -> str:
    """Unit of a channel group's values (``"m"`` for a skeleton frame, ``""`` if unknown)."""
    return group_spec(group).unit


class _Units(Mapping[str, str]):
    """Group name -> unit of the exactly named registered groups (read live from the registry)."""

    def __getitem__(self, key: str) -> str:
        spec = _EXACT.get(key)
        if spec is None or spec.extra:
            raise KeyError(key)
        return spec.unit

    def __iter__(self) -> Iterator[str]:
        return (k for k, s in _EXACT.items() if not s.extra)

    def __len__(self) -> int:
        return sum(1 for s in _EXACT.values() if not s.extra)


GROUP_UNITS: Mapping[str, str] = _Units()
"""Unit of the values of each registered channel group (skeleton frames ``"/..."`` are in [m])."""

SKELETON_PREFIX = "/"
"""Channel groups whose name starts with this are tracked positions x, y, z in [m]."""

_QUATERNION_NORM = NormCheck(1 - UNIT_QUATERNION_TOLERANCE, 1 + UNIT_QUATERNION_TOLERANCE, "")
_POSITION = NormCheck(0.0, POSITION_BOUND_M, "m")

ROBOT_GROUP = register_group(ChannelGroup(ROBOT, "rad", check=JointAngleCheck()))
GRIPPER_GROUP = register_group(
    ChannelGroup(
        GRIPPER,
        "m, unitless",
        interpolation="pose",
        check=GripperPoseCheck(),
        channels=GRIPPER_CHANNELS,
        n_channels=None,
    )
)
"""The robot side as a gripper pose path (:mod:`.gripper`): every shape is checked as a pose."""
ORIENTATION = register_group(
    ChannelGroup(
        "orientation",
        "unitless",
        interpolation="quaternion",
        check=_QUATERNION_NORM,
        ros_message=QUATERNION_MESSAGE,
        channels=("qw", "qx", "qy", "qz"),
        n_channels=4,
    )
)
EMG = register_group(
    ChannelGroup(
        "emg",
        "Myo EMG units",
        check=AllChecks((RangeCheck(*EMG_ENVELOPE_RANGE, ""), ActivityCheck())),
        log_space=True,
        channels=tuple(f"emg{i}" for i in range(8)),
        raw_interpolation="previous",
    )
)
ACC = register_group(
    ChannelGroup(
        "acc", "g", check=NormCheck(0.0, ACCELERATION_MAX_G, "g"), channels=("ax", "ay", "az"), n_channels=3
    )
)
SKELETON_FRAME = register_group(
    ChannelGroup(
        SKELETON_PREFIX,
        "m",
        check=_POSITION,
        ros_message=POINT_MESSAGE,
        channels=("x", "y", "z"),
        prefix=True,
    )
)
ENDPOINT_POSE = register_group(
    ChannelGroup(
        "endpoint_pose",
        "m",
        check=PoseCheck(),
        ros_message=None,
        channels=("x", "y", "z", "qx", "qy", "qz", "qw"),
        n_channels=7,
        extra=True,
    )
)
HAND_POSITION = register_group(
    ChannelGroup(
        "hand_position",
        "m",
        check=_POSITION,
        ros_message=POINT_MESSAGE,
        channels=("x", "y", "z"),
        n_channels=3,
        extra=True,
    )
)

DEFAULT_LOG_GROUPS: tuple[str, ...] = default_log_groups()
"""The IProMP's default ``log_groups``: the built-in groups with ``log_space`` (``("emg",)``). A group
registered later with ``log_space`` is named in ``log_groups`` by its user (the default is fixed at
import, so a model's parameters do not change with what else was registered)."""
