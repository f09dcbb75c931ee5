"""Plausible tracked skeletons: what a recording's frames must look like before they become a body.

* A frame at exactly (0, 0, 0) is a missing sample, never a position: the recorders' publishing bug
  leaves a transform at all zeros when the look-up returned nothing (the datasets' README), and a
  person cannot stand at the robot's base frame origin, inside the robot.
* Each capsule part between two frames has a length within its anthropometric range
  (:data:`SEGMENT_RANGES`, from :data:`ipromp_pin.robot.ranges.PLAUSIBLE_RANGES`). A skeleton whose
  median length of a part (over the samples where both ends are tracked) lies outside is impossible:
  the demo is refused, naming the part, the range and its source. Single samples outside (a tracker
  glitch: an elbow collapsed onto the shoulder for a frame) become missing samples of the part's
  frames, bridged and inflated at the human speed like an occlusion (:mod:`.body`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

from ..exceptions import DataError
from ..fields import Range
from ..robot.ranges import SEGMENT_FRACTIONS, segment_range

SEGMENT_RANGES: dict[str, Range] = {part: segment_range(part) for part in SEGMENT_FRACTIONS}
"""Body part -> plausible length [m] between its two tracked frames (the parts of
:data:`ipromp_pin.human.BODY_PARTS` that are capsules; spheres have no length)."""


class _Part(Protocol):
    """A body part: its name and the frames of its ends (:class:`~ipromp_pin.human.BodyPart`)."""

    @property
    def name(self) -> str: ...

    @property
    def a(self) -> str: ...

    @property
    def b(self) -> str | None: ...


def zeros_as_missing(positions: np.ndarray) -> np.ndarray:
    """A copy of positions (..., 3) [m] with every point at exactly (0, 0, 0) set to NaN."""
    out = np.array(positions, dtype=float)
    out[np.all(out == 0.0, axis=-1)] = np.nan
    return out


def _end(pos: np.ndarray, index: dict[str, int], end: str) -> np.ndarray:
    """Positions (T, 3) of a part's end: one frame, or the midpoint of ``"/f1+/f2"``."""
    return np.mean([pos[:, index[f]] for f in end.split("+")], axis=0)


def plausible_positions(
    positions: np.ndarray, frames: Sequence[str], parts: Sequence[_Part], source: str
) -> np.ndarray:
    """Frame positions (T, F, 3) [m] with zeros and implausible samples missing (NaN); see the module
    docstring.

    Raises:
        DataError: a part whose median length is outside its range, naming ``source``, the part, the
            range and its source.
    """
    clean = zeros_as_missing(positions)
    out = clean.copy()
    index = {f: j for j, f in enumerate(frames)}
    for part in parts:
        rng = SEGMENT_RANGES.get(part.name)
        if rng is None or part.b is None:
            continue
        with np.errstate(invalid="ignore"):
            length = np.linalg.norm(_end(clean, index, part.a) - _end(clean, index, part.b), axis=1)
        seen = np.isfinite(length)
        if not seen.any():
            continue  # never both tracked: the body model reports the frame
        median = float(np.median(length[seen]))
        if not rng.contains(median):
            raise DataError(
                source,
                part.name,
                f"impossible tracked skeleton: {part.a} to {part.b} {rng.problem(median)} (median over "
                f"{int(seen.sum())} samples)",
            )
        bad = seen & ~((length >= rng.lo) & (length <= rng.hi))
        if bad.any():
            cols = [index[f] for end in (part.a, part.b) for f in end.split("+")]
            out[np.ix_(np.flatnonzero(bad), np.array(cols))] = np.nan
    return out
