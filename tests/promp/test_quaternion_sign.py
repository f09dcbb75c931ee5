"""q and -q are one rotation: observations are compared after the sign convention the model fixes
(the training data's hemisphere), in predict, the stream and a run on read files alike (issue 24,
item 5)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers_cli import run_tiny

from ipromp_pin.outputs.trajectory_files import read_trajectory_csv
from ipromp_pin.promp import IProMP
from ipromp_pin.readers import load_dataset
from ipromp_pin.readers.native import write_demo

FLIPS = {
    "every sample": lambda n: np.ones(n, dtype=bool),
    "every other sample": lambda n: np.arange(n) % 2 == 1,
    "the second half": lambda n: np.arange(n) >= n // 2,
    "one sample": lambda n: np.arange(n) == n // 3,
}


@pytest.fixture(scope="module")
def model_and_obs(tiny):
    ds = load_dataset(tiny[0])
    return IProMP.load(tiny[1]), ds.demos[ds.tasks[0]][0].head(0.5, ["orientation", "emg"])


def _flipped(obs, which):
    q = obs.groups["orientation"]
    flip = FLIPS[which](q.shape[0])
    return dataclasses.replace(obs, groups={**obs.groups, "orientation": np.where(flip[:, None], -q, q)})


@pytest.mark.parametrize("which", list(FLIPS))
def test_predict_is_the_same_for_q_and_minus_q(model_and_obs, which):
    model, obs = model_and_obs
    a, b = model.predict(obs), model.predict(_flipped(obs, which))
    np.testing.assert_allclose(b.posterior, a.posterior, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.q_mean, a.q_mean, rtol=0, atol=1e-12)


@pytest.mark.parametrize("which", list(FLIPS))
def test_the_stream_is_the_same_for_q_and_minus_q(model_and_obs, which):
    model, obs = model_and_obs
    results = []
    for o in (obs, _flipped(obs, which)):
        stream = model.stream()
        for i in range(o.n_samples):
            last = stream.update(float(o.t[i]), {g: o.groups[g][i] for g in ("orientation", "emg")})
        results.append(last)
    np.testing.assert_allclose(results[1].posterior, results[0].posterior, rtol=0, atol=1e-12)
    np.testing.assert_allclose(results[1].alpha, results[0].alpha, rtol=0, atol=1e-12)


def test_a_run_on_a_recording_of_the_other_sign_plans_the_same_motion(tiny, tmp_path):
    ds, model = tiny
    flipped = tmp_path / "ds"
    data = load_dataset(ds)
    for d in data.all_demos():
        if d is data.demos[data.tasks[0]][0]:  # the observed demo, recorded with the other sign
            d = dataclasses.replace(d, groups={**d.groups, "orientation": -d.groups["orientation"]})
        write_demo(d, flipped / d.task / f"{d.name}.npz")
    assert run_tiny(tiny, tmp_path / "a") == 0
    assert run_tiny((flipped, model), tmp_path / "b") == 0
    a, b = (
        read_trajectory_csv(tmp_path / "a" / "trajectory.csv"),
        read_trajectory_csv(tmp_path / "b" / "trajectory.csv"),
    )
    np.testing.assert_allclose(b.q, a.q, rtol=0, atol=1e-9)
