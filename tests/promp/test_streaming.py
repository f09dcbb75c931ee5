"""Streaming observations (IProMP.stream): a rejected or malformed sample leaves the stream as it was."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers_model import random_dataset

from ipromp_pin.exceptions import ObservationError
from ipromp_pin.promp import IProMP


@pytest.fixture(scope="module")
def streaming_model():
    ds = random_dataset(9, n_tasks=2, n_demos=5, dims={"a": 2, "emg": 3})
    for demos in ds.demos.values():  # EMG-like channels: positive, modelled in log space
        for k, d in enumerate(demos):
            demos[k] = dataclasses.replace(d, groups={**d.groups, "emg": np.exp(d.groups["emg"])})
    model = IProMP(["a", "emg"], n_basis=9, noise=10.0, log_groups=["emg"]).fit(ds)
    obs = ds.demos["task1"][0].head(0.4, ["a", "emg"])
    return model, obs


def _feed(stream, obs, i):
    return stream.update(float(obs.t[i]), {g: obs.groups[g][i] for g in ("a", "emg")})


BAD_SAMPLES = [
    ("a", 1e200),
    ("a", -1e200),
    ("a", 1e308),
    ("a", np.inf),
    ("a", np.nan),
    ("a", 1e30),
    ("emg", 1e200),
    ("emg", 1e300),
    ("emg", -1e200),
    ("emg", 1e30),
    ("emg", np.inf),
    ("a", "abc"),
    ("emg", None),  # a whole group given as a wrong type below
]


@pytest.mark.parametrize(("group", "value"), BAD_SAMPLES)
def test_rejected_stream_sample_leaves_the_stream_as_it_was(streaming_model, group, value):
    model, obs = streaming_model
    reference = model.stream()
    for i in range(obs.n_samples):
        expected = _feed(reference, obs, i)
    stream = model.stream()
    for i in range(obs.n_samples):
        if i == 4:
            sample = {
                g: obs.groups[g][i].astype(object if isinstance(value, str) else float) for g in ("a", "emg")
            }
            if value is None:
                sample[group] = {"not": "numbers"}
            else:
                sample[group][1] = value
            with pytest.raises(ObservationError, match=group):
                stream.update(float(obs.t[i]) - 1e-4, sample)
        result = _feed(stream, obs, i)
    assert stream.n_samples == obs.n_samples
    np.testing.assert_allclose(result.posterior, expected.posterior, rtol=0, atol=1e-12)
    np.testing.assert_allclose(result.alpha, expected.alpha, rtol=0, atol=1e-12)


@pytest.mark.parametrize("bad", [("t", "abc"), ("t", None), ("sample", None), ("sample", [1, 2])])
def test_malformed_stream_calls_are_refused(streaming_model, bad):
    model, obs = streaming_model
    stream = model.stream()
    t, sample = 0.0, {g: obs.groups[g][0] for g in ("a", "emg")}
    if bad[0] == "t":
        t = bad[1]
    else:
        sample = bad[1]
    with pytest.raises(ObservationError):
        stream.update(t, sample)
    assert stream.n_samples == 0


@pytest.mark.parametrize("gaps", [(), (1, 4, 5)])
def test_stream_parts_are_the_encoded_observation(streaming_model, gaps):
    # the closed loop conditions on the stream's own scaled samples (parts()): the same parts as
    # encoding the stream's observation again, and the same predictions
    model, obs = streaming_model
    stream = model.stream()
    for i in range(obs.n_samples):
        sample = {g: obs.groups[g][i] for g in ("a", "emg")}
        if i in gaps:
            sample["emg"] = None
        stream.update(float(obs.t[i]), sample)
    parts, t_last = stream.parts()
    encoded, t_enc = model.predictor_.encode(stream.observation())
    assert t_last == t_enc and len(parts) == len(encoded) == (2 if gaps else 1)
    for p, e in zip(parts, encoded, strict=True):
        assert np.array_equal(p.dims, e.dims) and np.array_equal(p.t, e.t)
        assert np.allclose(p.y, e.y, rtol=1e-13, atol=1e-13)
        assert gaps or not p.y.flags.writeable  # without gaps: views of the stream's buffers
    one = model.predict(stream.observation())
    assert np.allclose(stream.prediction().q_mean, one.q_mean, rtol=1e-10, atol=1e-10)
    rec = stream.recognition()
    direct = model.predictor_.conditioner.condition(rec, encoded)
    assert np.allclose(stream.predict(estimates=False).q_cov, direct.q_cov, rtol=1e-10, atol=1e-12)
    # with the model's hand-over estimates (as the closed loop predicts): the one-shot prediction
    assert np.allclose(stream.predict().q_cov, one.q_cov, rtol=1e-8, atol=1e-12)
    assert np.allclose(stream.predict().q_mean, one.q_mean, rtol=1e-10, atol=1e-10)
