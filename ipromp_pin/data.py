"""Demonstrations: named, time-aligned channel groups of one recorded interaction.

A :class:`Demo` is what every reader produces and what models consume. All its
channel groups share one uniform time base ``t`` (in [s], starting at 0 at the
start of the motion), so a partial observation is simply the first rows.

Channel groups:

* human groups, e.g. ``"orientation"`` (Myo quaternion, 4 dims), ``"emg"``
  (8 Myo channels) or a tracked skeleton frame such as ``"/left_hand_1"``
  (position x, y, z in [m]);
* the robot group :data:`ROBOT` (joint angles in [rad], in the robot settings'
  kinematic order), or instead the gripper group :data:`GRIPPER` (the robot side as a
  gripper pose path: position x, y, z in [m] in the scene frame and a unit quaternion
  qx, qy, qz, qw; :data:`GRIPPER_CHANNELS`).

Samples known to be missing (a skeleton tracker that lost the hand) are NaN in
``groups`` and flagged in ``missing``; any other NaN is an error.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from .exceptions import DataError, ObservationError
from .fields import Range, did_you_mean

ROBOT = "robot"
"""Name of the channel group holding the robot's joint angles in [rad]."""

GRIPPER = "gripper"
"""Name of the channel group holding the robot side as a gripper pose path (no joints): a
human-human recording (the giver's hand or the object plays the robot) or another robot's."""

GRIPPER_CHANNELS = ("x", "y", "z", "qx", "qy", "qz", "qw")
"""The gripper group's channels: position [m] in the scene frame (the base frame of the robot the
arms' ``[placement]`` refer to: Baxter's for the shipped data), then a unit quaternion, scalar last."""


def _numeric_values(source: str, name: str, values: object) -> np.ndarray:
    """A channel group's values as floats, or DataError: booleans, strings and ragged rows are no
    measurements."""
    try:
        raw = np.asarray(values) if not isinstance(values, str) else np.asarray([values])
    except ValueError:  # rows of different lengths
        raise DataError(source, name, "values must be a (T, D) array; its rows differ in length") from None
    if raw.dtype == bool:
        raise DataError(source, name, "values are booleans (True/False), not measurements")
    if raw.dtype.kind == "O":
        try:
            return raw.astype(float)
        except (TypeError, ValueError):
            pass
    if raw.dtype.kind not in "iuf":
        raise DataError(source, name, f"values must be a numeric (T, D) array, got {raw.dtype.name} values")
    return raw.astype(float)


@dataclass(frozen=True)
class Demo:
    """One demonstration (or a partial observation of one).

    Attributes:
        task: Task name (the dataset's sub-folder name).
        name: Demo identifier, e.g. the recording's start stamp.
        source: File or folder the demo was read from (for error messages).
        t: Sample times in [s] from the start of the motion, shape (T,),
            strictly increasing and uniformly spaced.
        groups: Channel group name -> values, shape (T, D_group).
        channel_names: Channel group name -> names of its D_group channels.
        missing: Channel group name -> boolean mask (T,) of samples known to be
            missing (their values are NaN). Groups absent here have none.
        extras: Other time-aligned signals that are not modelled, e.g.
            ``"endpoint_pose"`` (T, 7): the robot's own end-point report,
            position x, y, z in [m] and quaternion x, y, z, w, in the robot
            base frame.
        duration_s: Full duration of the demonstration in [s]. For a partial
            observation made with :meth:`head` this stays the full duration
            (which a model must not use: it is unknown online).
    """

    task: str
    name: str
    source: str
    t: np.ndarray
    groups: dict[str, np.ndarray]
    channel_names: dict[str, tuple[str, ...]]
    missing: dict[str, np.ndarray] = field(default_factory=dict)
    extras: dict[str, np.ndarray] = field(default_factory=dict)
    duration_s: float | None = None

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=float)
        object.__setattr__(self, "t", t)
        if t.ndim != 1:
            raise DataError(self.source, "t", f"time stamps must be 1-D, got shape {t.shape}")
        if t.size < 2:
            raise DataError(self.source, "t", f"a stream needs at least 2 samples, got {t.size}")
        if not np.all(np.isfinite(t)):
            raise DataError(self.source, "t", "time stamps contain NaN or inf")
        if np.any(np.diff(t) <= 0):
            raise DataError(self.source, "t", "time stamps are not strictly increasing")
        if not self.groups:
            raise DataError(self.source, None, "demo has no channel groups")
        groups = {}
        for name, values in self.groups.items():
            v = _numeric_values(self.source, name, values)
            if v.ndim == 1:
                v = v[:, None]
            if v.ndim != 2 or v.shape[0] != t.size:
                raise DataError(
                    self.source, name, f"values of shape {v.shape} do not match {t.size} time stamps"
                )
            if v.shape[1] == 0:
                raise DataError(self.source, name, "channel group has no channels")
            names = self.channel_names.get(name)
            if names is None or len(names) != v.shape[1]:
                raise DataError(self.source, name, "channel names missing or of the wrong length")
            mask = self.missing.get(name)
            bad = ~np.isfinite(v)
            if mask is not None:
                mask = np.asarray(mask, dtype=bool)
                if mask.shape != (t.size,):
                    raise DataError(self.source, name, "missing-sample mask has the wrong shape")
                bad = bad & ~mask[:, None]
            if np.any(bad):
                rows, cols = np.nonzero(bad)
                raise DataError(
                    self.source,
                    f"{name}/{names[cols[0]]}",
                    f"{rows.size} NaN or inf values (first at t={t[rows[0]]:.3f} s)",
                )
            if mask is not None and np.all(mask):
                raise DataError(self.source, name, "every sample of the channel group is missing")
            groups[name] = v
        object.__setattr__(self, "groups", groups)
        if self.duration_s is None:
            object.__setattr__(self, "duration_s", float(t[-1] - t[0]))

    @property
    def n_samples(self) -> int:
        """Number of samples T."""
        return int(self.t.size)

    @property
    def dt(self) -> float:
        """Sampling period in [s]."""
        return float(np.median(np.diff(self.t)))

    def dims(self, group: str) -> int:
        """Number of channels of ``group``."""
        return int(self.groups[group].shape[1])

    def require(self, groups: Iterable[str]) -> None:
        """Raise :class:`DataError` naming the first of ``groups`` this demo lacks."""
        for g in groups:
            if g not in self.groups:
                hint = did_you_mean(g, self.groups)
                raise DataError(
                    self.source, g, f"channel group not in demo{hint} (has: {', '.join(sorted(self.groups))})"
                )

    def select(self, groups: Iterable[str]) -> Demo:
        """Return a demo restricted to ``groups`` (extras are kept)."""
        groups = list(groups)
        self.require(groups)
        return Demo(
            task=self.task,
            name=self.name,
            source=self.source,
            t=self.t,
            groups={g: self.groups[g] for g in groups},
            channel_names={g: self.channel_names[g] for g in groups},
            missing={g: self.missing[g] for g in groups if g in self.missing},
            extras=dict(self.extras),
            duration_s=self.duration_s,
        )

    def with_channel_order(self, order: Mapping[str, Iterable[str]]) -> Demo:
        """The demo with the channels of some groups rearranged by name (channels are matched by
        name, never by position).

        Args:
            order: Group -> the wanted channel names (a permutation of the group's names).

        Raises:
            DataError: a group's channels are not the wanted ones (naming both lists).
        """
        groups, names = dict(self.groups), dict(self.channel_names)
        changed = False
        for g, wanted in order.items():
            wanted = tuple(wanted)
            have = tuple(self.channel_names[g])
            if have == wanted:
                continue
            if sorted(have) != sorted(wanted) or len(set(have)) != len(have):
                raise DataError(self.source, g, f"channels {list(have)} are not the expected {list(wanted)}")
            idx = [have.index(c) for c in wanted]
            groups[g] = self.groups[g][:, idx]
            names[g] = wanted
            changed = True
        if not changed:
            return self
        return Demo(
            task=self.task,
            name=self.name,
            source=self.source,
            t=self.t,
            groups=groups,
            channel_names=names,
            missing=dict(self.missing),
            extras=dict(self.extras),
            duration_s=self.duration_s,
        )

    def head(self, ratio: float, groups: Iterable[str] | None = None) -> Demo:
        """First ``ratio`` of the demo in time: what is observed online.

        Args:
            ratio: Observed fraction of the duration, in (0, 1].
            groups: Groups to keep (default: all).

        Returns:
            A partial demo whose ``duration_s`` is still the full duration.
        """
        ratio = float(ratio)
        if not (0.0 < ratio <= 1.0) or not np.isfinite(ratio):
            raise ObservationError(self.source, "obs_ratio", f"must be in (0, 1], got {ratio}")
        t_end = self.t[0] + ratio * (self.t[-1] - self.t[0])
        n = int(np.searchsorted(self.t, t_end + 1e-9, side="right"))
        if n < 2:
            raise ObservationError(
                self.source,
                "obs_ratio",
                f"observing {ratio:.0%} of a {self.duration_s:.2f} s demo leaves fewer than 2 samples",
            )
        return self.slice(n, groups)

    def until(self, t_s: float, groups: Iterable[str] | None = None) -> Demo:
        """The samples of the first ``t_s`` [s] from the demo's start: what is observed online after
        ``t_s`` seconds, whatever the demo's length (:meth:`head` cuts a fraction of it, which needs
        the whole recording's length).

        Raises:
            ObservationError: ``t_s`` is not positive and finite, or leaves fewer than 2 samples.
        """
        t_s = float(t_s)
        if not (np.isfinite(t_s) and t_s > 0.0):
            raise ObservationError(self.source, "until_s", f"must be a positive time in [s], got {t_s}")
        n = int(np.searchsorted(self.t, self.t[0] + t_s + 1e-9, side="right"))
        if n < 2:
            raise ObservationError(
                self.source, "until_s", f"the first {t_s:g} s of the recording hold fewer than 2 samples"
            )
        return self.slice(n, groups)

    def slice(self, n: int, groups: Iterable[str] | None = None) -> Demo:
        """First ``n`` samples of the demo (restricted to ``groups``)."""
        keep = list(self.groups) if groups is None else list(groups)
        self.require(keep)
        return Demo(
            task=self.task,
            name=self.name,
            source=self.source,
            t=self.t[:n],
            groups={g: self.groups[g][:n] for g in keep},
            channel_names={g: self.channel_names[g] for g in keep},
            missing={g: self.missing[g][:n] for g in keep if g in self.missing},
            extras={k: v[:n] for k, v in self.extras.items()},
            duration_s=self.duration_s,
        )


WINDOW_RANGE_S = Range(
    0.0,
    600.0,
    "s",
    "a hand-over motion lasts seconds (2-6 s in the shipped recordings); 10 minutes is far beyond any",
    lo_open=True,
)
"""Plausible observation windows in seconds (``--until-s``, ``[observation] until_s``, ``evaluate
--window-s``)."""

DEFAULT_WINDOW_FRACTION = 0.2
"""The observation window when none is given: this fraction of the model's nominal duration (the
mean length of its training demos), a time a robot knows before the motion starts."""


@dataclass(frozen=True)
class ObservationWindow:
    """How much of a recording is observed: its first ``until_s`` seconds; or, offline only, its first
    ``ratio`` of its own length (the paper's protocol: that length is known once the motion is over);
    or, with neither, the first ``nominal_fraction`` of the model's nominal duration.

    Attributes:
        until_s: Seconds from the recording's start [s] (None: not by time).
        ratio: Fraction of the recording's duration in (0, 1] (None: not by fraction).
        nominal_fraction: The fraction of the nominal duration when neither is given.
    """

    until_s: float | None = None
    ratio: float | None = None
    nominal_fraction: float = DEFAULT_WINDOW_FRACTION

    def end_s(self, nominal_s: float) -> float | None:
        """The window's end [s] from the start (None for a ``ratio`` window: it depends on the
        recording); ``nominal_s``: the model's nominal duration [s]."""
        if self.ratio is not None:
            return None
        return self.until_s if self.until_s is not None else self.nominal_fraction * float(nominal_s)

    def cut(self, demo: Demo, groups: Iterable[str] | None, nominal_s: float) -> Demo:
        """The observed part of ``demo`` (restricted to ``groups``); all of it when the window reaches
        past its end."""
        if self.ratio is not None:
            return demo.head(self.ratio, groups)
        end = self.end_s(nominal_s)
        assert end is not None
        return demo.until(end, groups)

    def text(self, nominal_s: float) -> str:
        """The window in words, e.g. ``first 0.64 s (20% of the model's nominal 3.20 s)``."""
        if self.ratio is not None:
            return f"first {self.ratio:.0%} of each recording"
        if self.until_s is not None:
            return f"first {self.until_s:.2f} s"
        return (
            f"first {self.nominal_fraction * nominal_s:.2f} s ({self.nominal_fraction:.0%} of the model's "
            f"nominal {nominal_s:.2f} s)"
        )


@dataclass
class Dataset:
    """Demonstrations of several tasks.

    Attributes:
        root: Folder the dataset was read from (or a description).
        demos: Task name -> its demos, in the recorded (or configured) order.
    """

    root: str
    demos: dict[str, list[Demo]]

    @property
    def tasks(self) -> list[str]:
        """Task names, in a stable order."""
        return list(self.demos)

    def all_demos(self) -> list[Demo]:
        """All demos of all tasks, task by task."""
        return [d for task in self.demos for d in self.demos[task]]

    def groups(self) -> list[str]:
        """Channel groups present in every demo."""
        common: set[str] | None = None
        for d in self.all_demos():
            common = set(d.groups) if common is None else common & set(d.groups)
        return sorted(common or ())


def parse_groups(text: str | Iterable[str]) -> list[str]:
    """Parse a comma-separated list of channel groups (``"orientation,emg"``)."""
    items = text.split(",") if isinstance(text, str) else list(text)
    groups = [g.strip() for g in items if g and g.strip()]
    if not groups:
        raise DataError(None, "observe", "no channel group given")
    if len(set(groups)) != len(groups):
        raise DataError(None, "observe", f"channel group listed twice in {groups}")
    return groups


def robot_side(demos: Iterable[Demo]) -> str:
    """The robot group of demos: :data:`ROBOT` when every demo records joints, else :data:`GRIPPER`
    when every one records a gripper pose path.

    Raises:
        DataError: naming the first demo that has neither (or the other one).
    """
    demos = list(demos)
    for side in (ROBOT, GRIPPER):
        if demos and all(side in d.groups for d in demos):
            return side
    first = next((d for d in demos if ROBOT in d.groups or GRIPPER in d.groups), None)
    want = ROBOT if first is None or ROBOT in first.groups else GRIPPER
    lacking = next((d for d in demos if want not in d.groups), demos[0] if demos else None)
    raise DataError(
        None if lacking is None else lacking.source,
        want,
        f"no '{want}' group: every demo needs the robot side, as joint angles ('{ROBOT}') or as a gripper "
        f"pose path ('{GRIPPER}'), the same in every demo",
    )


def skeleton_frames(groups: Iterable[str]) -> list[str]:
    """The tracked skeleton frames (``"/left_hand_1"`` ...) among channel group names, once each, in order."""
    return list(dict.fromkeys(g for g in groups if g.startswith("/")))


def group_by_task(demos: Iterable[Demo]) -> Mapping[str, list[Demo]]:
    """Group demos by task, keeping the first-seen task order."""
    out: dict[str, list[Demo]] = {}
    for d in demos:
        out.setdefault(d.task, []).append(d)
    return out
