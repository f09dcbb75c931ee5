"""A stream refuses a sample time that cannot be right at the sample that is wrong, and stays usable
(issue 24, item 6): a bool or text time, a stamp far after the previous sample, boolean values."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers_model import random_dataset

from ipromp_pin.exceptions import ObservationError
from ipromp_pin.promp import IProMP
from ipromp_pin.promp.streaming import MAX_GAP_FRACTION

GROUPS = ("a", "emg")


@pytest.fixture(scope="module")
def streaming_model():
    ds = random_dataset(9, n_tasks=2, n_demos=5, dims={"a": 2, "emg": 3})
    for demos in ds.demos.values():
        for k, d in enumerate(demos):
            demos[k] = dataclasses.replace(d, groups={**d.groups, "emg": np.exp(d.groups["emg"])})
    model = IProMP(list(GROUPS), n_basis=9, noise=10.0, log_groups=["emg"]).fit(ds)
    return model, ds.demos["task1"][0].head(0.5, list(GROUPS))


def _sample(obs, i):
    return {g: obs.groups[g][i] for g in GROUPS}


def _reference(model, obs):
    stream = model.stream()
    for i in range(obs.n_samples):
        last = stream.update(float(obs.t[i]), _sample(obs, i))
    return last


def _feed_with(model, obs, bad_t, bad_sample=None, at=4):
    """Feed ``obs``, with one wrong call before sample ``at``; the wrong call must be refused."""
    stream = model.stream()
    for i in range(obs.n_samples):
        if i == at:
            with pytest.raises(ObservationError, match="stream") as exc:
                stream.update(bad_t(obs, i), bad_sample or _sample(obs, i))
            assert "\n" not in str(exc.value)
        last = stream.update(float(obs.t[i]), _sample(obs, i))
    assert stream.n_samples == obs.n_samples
    return last, exc


def _duration(model) -> float:
    return model.fitted_.duration_nominal_s


@pytest.mark.parametrize("bad", [True, False, np.True_, "0.1", b"0.1"])
def test_a_bool_or_text_sample_time_is_refused(streaming_model, bad):
    model, obs = streaming_model
    last, exc = _feed_with(model, obs, lambda o, i: bad)
    assert "field 't'" in str(exc.value) or "t:" in str(exc.value)
    expected = _reference(model, obs)
    np.testing.assert_allclose(last.posterior, expected.posterior, rtol=0, atol=1e-12)


@pytest.mark.parametrize("late", ["just over the gap", "2 s", "most of the longest motion"])
def test_a_sample_stamped_far_too_late_is_refused_and_the_stream_goes_on(streaming_model, late):
    model, obs = streaming_model
    gap = MAX_GAP_FRACTION * _duration(model)

    def stamp(o, i):
        prev = float(o.t[i - 1])
        if late == "just over the gap":
            return prev + gap * 1.01
        if late == "2 s":
            return prev + max(2.0, gap * 1.01)
        return prev + 0.9 * model.fitted_.longest_s

    last, exc = _feed_with(model, obs, stamp)
    assert "after the previous sample" in str(exc.value) and "refused" in str(exc.value)
    expected = _reference(model, obs)
    np.testing.assert_allclose(last.posterior, expected.posterior, rtol=0, atol=1e-12)
    np.testing.assert_allclose(last.alpha, expected.alpha, rtol=0, atol=1e-12)


def test_a_gap_below_the_bound_is_a_valid_stream(streaming_model):
    model, obs = streaming_model
    stream = model.stream()
    for i in range(4):
        stream.update(float(obs.t[i]), _sample(obs, i))
    t = float(obs.t[3]) + 0.9 * MAX_GAP_FRACTION * _duration(model)
    assert stream.update(t, _sample(obs, 4)) is not None and stream.n_samples == 5


@pytest.mark.parametrize("group", GROUPS)
def test_boolean_sample_values_are_refused(streaming_model, group):
    model, obs = streaming_model
    sample = _sample(obs, 4)
    sample[group] = np.ones(sample[group].size, dtype=bool)
    last, exc = _feed_with(model, obs, lambda o, i: float(o.t[i]), bad_sample=sample)
    assert "booleans" in str(exc.value) and group in str(exc.value)
