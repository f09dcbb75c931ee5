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
from .observation import ObservationPart

RANGE_WARNING_SD = 4.0
"""An observed group is far outside the training data when the median over its samples of the
root-mean-square of its scaled channels (training data: mean 0, standard deviation 1 per channel)
exceeds this. Basis: the synthetic demos' groups lie at 0.4-2.0; EMG scaled by 0.1 reaches 5.8, by
0.001 9.6, a quaternion of the other sign 28."""


class ObservationWarning(UserWarning):
    """An observation the model can process but should not be trusted on (far from its training data)."""


def row_rms(z: np.ndarray) -> np.ndarray:
    """The RMS of each sample's (row's) finite scaled channel values ``z`` (n, D_g), in standard
    deviations; samples with no finite channel (occluded) are left out."""
    finite = np.isfinite(z)
    if finite.all():  # the encoder's parts: every sample has every channel of the part
        return np.sqrt(np.einsum("ij,ij->i", z, z) / z.shape[1])
    z = z[finite.any(axis=1)]
    with np.errstate(all="ignore"):
        rms = np.sqrt(np.nanmean(z**2, axis=1))
    return rms[np.isfinite(rms)]


def median_rms(rows: list[np.ndarray]) -> float:
    """The median of the samples' RMS values (:func:`row_rms` of each block of ``rows``), 0 if none."""
    rms = np.concatenate([np.empty(0), *(row_rms(z) for z in rows if z.size)])
    return float(np.median(rms)) if rms.size else 0.0


def group_distance_sd(fitted: FittedModel, group: str, values: np.ndarray) -> float:
    """How far the raw values (n, D_g) of an observed group lie from the training data
    (:func:`median_rms` of its scaled channels)."""
    lo, hi = fitted.layout.slices[group]
    with np.errstate(all="ignore"):
        return median_rms([fitted.scaler.transform(np.asarray(values, dtype=float), slice(lo, hi))])


def range_message(group: str, distance_sd: float) -> str:
    """The warning for an observed group ``distance_sd`` standard deviations from the training data."""
    return (
        f"the observed '{group}' lies {distance_sd:.1f} standard deviations from the model's training "
        "data (median over its samples; the training data lie within about 2): in other units, from "
        "another sensor or of another sign? The recognition and prediction are then unreliable"
    )


def range_warnings(fitted: FittedModel, observation: Demo) -> list[str]:
    """A message per observed group of ``observation`` (raw values) that lies far outside the
    training data (:data:`RANGE_WARNING_SD`), naming the group and how far out it is."""
    out = []
    for g in fitted.layout.observe:
        if g in observation.groups:
            d = group_distance_sd(fitted, g, observation.groups[g])
            if d > RANGE_WARNING_SD:
                out.append(range_message(g, d))
    return out


def check_observation(fitted: FittedModel, observation: Demo, parts: list[ObservationPart]) -> None:
    """Refuse implausible values of the observed groups (:class:`~ipromp_pin.exceptions.DataError`
    naming the group) and warn (:class:`ObservationWarning`) about groups far from the training data,
    measured on ``parts``, the observation as the encoder scaled it (quaternion signs aligned: q and
    -q are one rotation)."""
    for g in fitted.layout.observe:
        if g in observation.groups:
            values = observation.groups[g]
            group_spec(g).check_values(observation.source, g, values, observation.channel_names[g])
    for g in fitted.layout.observe:
        lo, hi = fitted.layout.slices[g]
        d = median_rms([p.y[:, (p.dims >= lo) & (p.dims < hi)] for p in parts])
        if d > RANGE_WARNING_SD:
            warnings.warn(f"{observation.source}: {range_message(g, d)}", ObservationWarning, stacklevel=4)
