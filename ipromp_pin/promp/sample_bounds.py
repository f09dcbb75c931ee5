"""Plausibility bounds of a scaled observed value: beyond them a sample cannot come from the model's sensors.

Both kernel implementations (``scale_samples`` of :mod:`ipromp_pin.promp._kernels` and
:mod:`ipromp_pin.promp.numpy_kernels`) and :class:`~ipromp_pin.promp.observation.ObservationEncoder`
refuse such samples like NaN: a stream then continues as if the sample had never arrived.
"""

from __future__ import annotations

MAX_SCALED_MAGNITUDE = 1e4
"""Largest magnitude of a scaled observed value (``(f(y) - offset) / scale``: standard deviations of
the channel's training samples from their mean). Beyond it a sample cannot come from the sensors the
model was trained on, and its square would swamp (or overflow) the running sums of squares, so
the ``scale_samples`` kernels report it like a NaN."""

MAX_LOG_SCALED_MAGNITUDE = 30.0
"""The same bound for channels modelled in log space (EMG envelopes), whose logarithm compresses
absurd values (an envelope of 1e300 is only about 1000 standard deviations of log-EMG away): 30
standard deviations of the training data's logarithm is a factor of about e^20 beyond anything
recorded. Negative values, which the logarithm's clamp ``max(y, 0)`` hides, are refused below
``-MAX_SCALED_MAGNITUDE`` times the channel's shift ``c``."""
