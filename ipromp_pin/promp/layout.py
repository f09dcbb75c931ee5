"""Channel layout: where every modelled channel sits among the stacked dims of a model.

A model stacks the channels of its observed human groups (in ``observe`` order) and then the
robot's joint angles into ``D`` dims; a group ``g`` occupies the dims ``slices[g] = (lo, hi)``.
Every array of the model (weights, scaling, noise) is indexed by these dims.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from ..data import Demo
from ..exceptions import DataError


@dataclass(frozen=True)
class ChannelLayout:
    """Observed groups then the robot group, each with its channel names and dim range.

    Attributes:
        observe: Observed human channel groups, in model order.
        robot_group: Name of the robot's joint-angle group (the last group).
        channel_names: Group -> its channel names (every group of :attr:`groups`).
        slices: Group -> ``(lo, hi)``, its dims ``lo .. hi - 1`` (derived).
    """

    observe: tuple[str, ...]
    robot_group: str
    channel_names: Mapping[str, tuple[str, ...]]
    slices: Mapping[str, tuple[int, int]] = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "observe", tuple(self.observe))
        names = {g: tuple(self.channel_names[g]) for g in self.groups}
        object.__setattr__(self, "channel_names", names)
        starts = np.concatenate([[0], np.cumsum([len(names[g]) for g in self.groups])])
        slices = {g: (int(starts[i]), int(starts[i + 1])) for i, g in enumerate(self.groups)}
        object.__setattr__(self, "slices", slices)

    @classmethod
    def from_demos(cls, demos: Iterable[Demo], observe: Iterable[str], robot_group: str) -> ChannelLayout:
        """The layout of demos that all hold the observed groups and the robot group with the same
        channels, in the first demo's order (others may list them in another order, see
        :meth:`aligned`; raises :class:`DataError` naming the first demo whose channels differ)."""
        observe = tuple(observe)
        groups = [*observe, robot_group]
        names: dict[str, tuple[str, ...]] = {}
        for d in demos:
            d.require(groups)
            for g in groups:
                ref = names.setdefault(g, tuple(d.channel_names[g]))
                have = tuple(d.channel_names[g])
                if have != ref and sorted(have) != sorted(ref):
                    raise DataError(
                        d.source, g, f"channels {list(have)} differ from the first demo's {list(ref)}"
                    )
        return cls(observe, robot_group, names)

    def aligned(self, demo: Demo) -> Demo:
        """``demo`` with the channels of its modelled groups in this layout's order, matched by name
        (raises :class:`DataError` when a group's channel names are not the layout's)."""
        order = {g: self.channel_names[g] for g in self.groups if g in demo.groups}
        return demo.with_channel_order(order)

    @property
    def groups(self) -> tuple[str, ...]:
        """Every modelled group: the observed ones, then the robot group."""
        return (*self.observe, self.robot_group)

    @property
    def n_dims(self) -> int:
        """Number of modelled dims ``D``."""
        return self.slices[self.robot_group][1]

    @property
    def n_obs_dims(self) -> int:
        """Number of observed dims ``D_o`` (the first dims)."""
        return self.slices[self.robot_group][0]

    @property
    def robot_slice(self) -> slice:
        """The robot's dims."""
        return slice(*self.slices[self.robot_group])

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The robot's joint names."""
        return self.channel_names[self.robot_group]

    def dims(self, groups: Iterable[str]) -> np.ndarray:
        """The dims (int64) of ``groups``, concatenated in the given order."""
        ranges = [np.arange(*self.slices[g]) for g in groups]
        return np.concatenate(ranges).astype(np.int64) if ranges else np.zeros(0, dtype=np.int64)

    def size(self, groups: Iterable[str]) -> int:
        """Number of dims of ``groups``."""
        return sum(self.slices[g][1] - self.slices[g][0] for g in groups)

    def labels(self) -> list[str]:
        """``"group/channel"`` labels of every dim (observed groups, then robot)."""
        return [f"{g}/{c}" for g in self.groups for c in self.channel_names[g]]
