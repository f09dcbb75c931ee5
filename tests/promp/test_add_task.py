"""A task added to a fitted model from a few demos: the fitted tasks unchanged, the new one recognised
and predicted, saved and loaded, the fast inference equal to the reference, bad demos refused."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from helpers_model import random_dataset

from ipromp_pin.exceptions import DataError
from ipromp_pin.promp import IProMP, direct_predict
from ipromp_pin.promp.distribution import added_task_covariance, shrink_covariances
from ipromp_pin.promp.new_task import NoveltyDroppedWarning

OBSERVE = ["a", "b"]
FITTED = ("task0", "task1", "task2")


@pytest.fixture(scope="module")
def data():
    ds = random_dataset(41, n_tasks=4, n_demos=14)
    train = [d for t in FITTED for d in ds.demos[t][:10]]
    return ds, train


def _model(train, **kw) -> IProMP:
    params = {"n_basis": 8, "noise": 3.0, "temperature": 1.0, "coupling": "all", **kw}
    return IProMP(OBSERVE, **params).fit(train)


def test_fitted_tasks_predict_as_before_and_the_new_one_is_recognised(data) -> None:
    ds, train = data
    model = _model(train, head=False, handover=False)
    before = [model.predict(d.head(0.3, OBSERVE)) for t in FITTED for d in ds.demos[t][10:]]
    model.add_task(ds.demos["task3"][:8])
    assert model.tasks_ == [*FITTED, "task3"]
    assert model.fitted_.added_tasks == ("task3",)
    after = [model.predict(d.head(0.3, OBSERVE)) for t in FITTED for d in ds.demos[t][10:]]
    for b, a in zip(before, after, strict=True):
        # the fitted tasks' evidence, phases and the prediction of the recognised task are unchanged
        # (equal up to the rounding of batched sums over one more task)
        np.testing.assert_allclose(a.log_evidence[:3], b.log_evidence, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(a.alpha[:3], b.alpha, rtol=1e-12, atol=1e-12)
        assert a.task == b.task
        np.testing.assert_allclose(a.q_mean, b.q_mean, rtol=0, atol=1e-12)
    new = [model.recognise(d.head(0.3, OBSERVE)).task for d in ds.demos["task3"][8:]]
    assert new == ["task3"] * len(new)


def test_added_task_with_a_head_is_recognised_and_matches_the_reference(data) -> None:
    ds, train = data
    model = _model(train, head=True, handover=False)
    model.add_task(ds.demos["task3"][:8])
    for task in ("task1", "task3"):
        for d in ds.demos[task][10:12]:
            obs = d.head(0.35, OBSERVE)
            fast, ref = model.predict(obs), direct_predict(model.predictor_, obs)
            assert fast.task == ref.task == task
            np.testing.assert_allclose(fast.log_posterior, ref.log_posterior, rtol=1e-8, atol=1e-8)
            np.testing.assert_allclose(fast.q_mean, ref.q_mean, rtol=1e-8, atol=1e-10)


def test_the_added_covariance_of_a_fitted_task_is_its_own() -> None:
    # a task's covariance built as if it were added to the others equals the joint estimate's
    rng = np.random.default_rng(5)
    weights = [rng.normal(size=(n, 5, 4)) * rng.uniform(0.5, 2.0, (1, 5, 1)) for n in (7, 9, 6)]
    blocks = [np.arange(3), np.arange(3, 5)]
    for pooling in (0.0, 0.3):
        ref = shrink_covariances(weights, pooling, blocks)[2]
        got = added_task_covariance(weights[:2], weights[2], pooling, blocks, ref.diag, ref.shrinkage)
        f_ref = ref.factor.reshape(-1, ref.factor.shape[2])
        f_got = got.factor.reshape(-1, got.factor.shape[2])
        np.testing.assert_allclose(f_got @ f_got.T, f_ref @ f_ref.T, rtol=1e-9, atol=1e-12)
        np.testing.assert_array_equal(got.mean, ref.mean)
        np.testing.assert_array_equal(got.diag, ref.diag)


def test_a_model_with_an_added_task_saves_and_loads_with_the_same_predictions(data, tmp_path) -> None:
    ds, train = data
    model = _model(train, head=True, handover=False, novelty_alpha=0.1)
    model.add_task(ds.demos["task3"][:8])
    path = tmp_path / "grown.npz"
    model.save(path)
    loaded = IProMP.load(path)
    assert loaded.fitted_.added_tasks == ("task3",)
    for d in (ds.demos["task3"][9], ds.demos["task0"][11]):
        a, b = model.predict(d.head(0.3, OBSERVE)), loaded.predict(d.head(0.3, OBSERVE))
        np.testing.assert_array_equal(a.log_posterior, b.log_posterior)
        np.testing.assert_array_equal(a.q_mean, b.q_mean)
        assert a.novelty_p_value == b.novelty_p_value


def test_the_novelty_detector_learns_the_added_task(data) -> None:
    ds, train = data
    model = _model(train, head=True, handover=False, novelty_alpha=0.05)
    held_out = [d.head(0.3, OBSERVE) for d in ds.demos["task3"][8:]]
    before = [model.predict(o) for o in held_out]
    assert not any(p.known for p in before)  # unseen: refused
    n_cal = model.fitted_.novelty.calibration.size
    model.add_task(ds.demos["task3"][:8])
    novelty = model.fitted_.novelty
    assert novelty.mean.shape[0] == 4
    assert novelty.calibration.size == n_cal + 8 * novelty.ratios.size
    after = [model.predict(o) for o in held_out]
    assert all(p.task == "task3" for p in after)
    # as many accepted as a full refit with the same demos accepts (this synthetic task is hard for
    # the window features: the refit refuses some of them too)
    refit = _model(train + ds.demos["task3"][:8], head=True, handover=False, novelty_alpha=0.05)
    n_refit = sum(p.known for p in refit.predict(held_out))
    assert sum(p.known for p in after) >= max(n_refit - 1, 1)


def test_too_few_demos_for_the_novelty_detector_are_said(data) -> None:
    ds, train = data
    model = _model(train, head=False, handover=False, novelty_alpha=0.05)
    with pytest.warns(NoveltyDroppedWarning, match="too few"):
        model.add_task(ds.demos["task3"][:2])
    assert model.fitted_.novelty is None


def test_bad_demos_are_refused_with_the_reason(data) -> None:
    ds, train = data
    model = _model(train, head=False, handover=False)
    with pytest.raises(DataError, match="already has a task 'task1'"):
        model.add_task(ds.demos["task1"][10:])
    with pytest.raises(DataError, match="at least 2 demos"):
        model.add_task(ds.demos["task3"][:1])
    with pytest.raises(DataError, match="training demos"):
        relabelled = [type(d)(**{**vars(d), "task": "again"}) for d in ds.demos["task0"][:3]]
        model.add_task(relabelled)
    with pytest.raises(DataError, match="several tasks"):
        model.add_task([ds.demos["task3"][0], ds.demos["task0"][12]])
    lacking = [type(d)(**{**vars(d), "groups": {k: v for k, v in d.groups.items() if k != "b"}})
               for d in ds.demos["task3"][:3]]  # fmt: skip
    with pytest.raises(DataError, match="lacks the model's group"):
        model.add_task(lacking)
    assert model.tasks_ == list(FITTED)  # nothing was added
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model.add_task(ds.demos["task3"][:4])
    assert model.tasks_ == [*FITTED, "task3"]
