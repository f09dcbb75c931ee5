"""What a fitted model checks in an observation before it recognises and predicts.

An observation given through the Python API passes the same plausibility checks as a recording a
reader produced (:meth:`~ipromp_pin.signals.groups.ChannelGroup.check_values`: a quaternion of norm
0, 0.1 or 100, an EMG sample out of the device's range are refused with a
:class:`~ipromp_pin.exceptions.DataError`), and an observed group that lies far outside the
model's training data (other units, another sensor, another quaternion order) gives a
:class:`ObservationWarning`: it is still recognised, often at posterior 1, so the caller must hear it.
"""

from __future__ import annotations

import warnings

import numpy as np

from ..data import Demo
from ..signals.groups import group_spec
from .fitted import FittedModel

RANGE_WARNING_SD = 4.0
"""An observed group is far outside the training data when the median over its samples of the
root-mean-square of its scaled channels (training data: mean 0, standard deviation 1 per channel)
exceeds this. Basis: the synthetic demos' groups lie at 0.4-2.0; EMG scaled by 0.1 reaches 5.8, by
0.001 9.6, a quaternion of the other sign 28."""


class ObservationWarning(UserWarning):
    """An observation the model can process but should not be trusted on (far from its training data)."""


def group_distance_sd(fitted: FittedModel, group: str, values: np.ndarray) -> float:
    """How far the raw values (n, D_g) of an observed group lie from the training data: the median
    over the samples of the RMS of its scaled channels, in standard deviations (NaN samples ignored)."""
    lo, hi = fitted.layout.slices[group]
    with np.errstate(all="ignore"):
        z = fitted.scaler.transform(np.asarray(values, dtype=float), slice(lo, hi))
    seen = np.isfinite(z).any(axis=1)  # samples with at least one channel (occluded ones have none)
    if not seen.any():
        return 0.0
    rms = np.sqrt(np.nanmean(z[seen] ** 2, axis=1))
    rms = rms[np.isfinite(rms)]
    return float(np.median(rms)) if rms.size else 0.0


def range_warnings(fitted: FittedModel, observation: Demo) -> list[str]:
    """A message per observed group of ``observation`` that lies far outside the training data
    (:data:`RANGE_WARNING_SD`), naming the group and how far out it is."""
    out = []
    for g in fitted.layout.observe:
        if g not in observation.groups:
            continue
        d = group_distance_sd(fitted, g, observation.groups[g])
        if d > RANGE_WARNING_SD:
            out.append(
                f"the observed '{g}' lies {d:.1f} standard deviations from the model's training data "
                f"(median over its samples; the training data lie within about 2): in other units, from "
                "another sensor or of another sign? The recognition and prediction are then unreliable"
            )
    return out


def check_observation(fitted: FittedModel, observation: Demo) -> None:
    """Refuse implausible values of the observed groups (:class:`~ipromp_pin.exceptions.DataError`
    naming the group) and warn (:class:`ObservationWarning`) about groups far from the training data."""
    for g in fitted.layout.observe:
        if g in observation.groups:
            values = observation.groups[g]
            group_spec(g).check_values(observation.source, g, values, observation.channel_names[g])
    for message in range_warnings(fitted, observation):
        warnings.warn(f"{observation.source}: {message}", ObservationWarning, stacklevel=4)
