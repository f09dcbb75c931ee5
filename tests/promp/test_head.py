"""The recognition head, the likelihood temperature and the conditioning noise ratio."""

from __future__ import annotations

import numpy as np
import pytest
from helpers_model import random_dataset, split

from ipromp_pin.promp import IProMP
from ipromp_pin.promp.head import (
    HEAD_C_GRID,
    LDA,
    LDA_TEMPERATURE_GRID,
    LOGISTIC,
    fit_head,
)
from ipromp_pin.promp.head_features import LOG_POSTERIOR_CLIP, interpolation, observed_fraction
from ipromp_pin.promp.selection import NOISE_GRID, TEMPERATURE_GRID
from ipromp_pin.promp.window import WindowSummary


def test_interpolation_and_observed_fraction():
    r = [0.1, 0.2, 0.4]
    assert interpolation(r, 0.05) == (0, 0.0) and interpolation(r, 0.5) == (2, 0.0)
    i, w = interpolation(r, 0.3)
    assert i == 1 and np.isclose(w, 0.5)
    assert interpolation(r, 0.2) == (1, 0.0)
    post, alpha = np.array([0.25, 0.75]), np.array([1.0, 0.5])
    assert np.isclose(observed_fraction(post, alpha, 0.6, 3.0), 0.25 * 0.2 + 0.75 * 0.4)


def test_head_is_a_calibrated_classifier_of_its_features():
    rng = np.random.default_rng(1)
    n, n_tasks = 60, 3
    labels = np.tile(np.arange(n_tasks), n // n_tasks)
    window = rng.normal(size=(n, 6)) + 1.5 * np.eye(n_tasks, 6)[labels]
    generative = np.log(np.full((n, n_tasks), 1.0 / n_tasks))
    x = np.hstack([window, generative])
    head = fit_head(x, labels, np.arange(n), np.full(n, 0.2), n_tasks)
    assert head.ratios.tolist() == [0.2] and head.kind[0] in (LOGISTIC, LDA)
    assert head.c[0] in (HEAD_C_GRID if head.kind[0] == LOGISTIC else LDA_TEMPERATURE_GRID)
    assert head.cv_log_loss.shape == (1, len(HEAD_C_GRID) + len(LDA_TEMPERATURE_GRID))
    # the chosen candidate has the smallest cross-validated log loss of its features and rows
    chosen = (
        list(HEAD_C_GRID).index(head.c[0])
        if head.kind[0] == LOGISTIC
        else (len(HEAD_C_GRID) + list(LDA_TEMPERATURE_GRID).index(head.c[0]))
    )
    assert head.cv_log_loss[0, chosen] == head.cv_log_loss[0].min()
    # the generative log posterior is uninformative here: its weights are 0 when the window alone won
    if head.generative[0] == 0.0:
        assert np.all(head.coef[0][:, -n_tasks:] == 0.0)
    assert head.cv_log_loss.min() < np.log(n_tasks)  # better than chance in cross-validation
    post = [head.log_posterior(WindowSummary(window[i].reshape(3, 2)), generative[i], 0.2) for i in range(n)]
    assert np.allclose([np.logaddexp.reduce(p) for p in post], 0.0)
    assert np.mean([np.argmax(p) == k for p, k in zip(post, labels, strict=True)]) > 0.7
    # a task the generative model rules out stays impossible
    impossible = np.array([0.0, -np.inf, -np.inf])
    p = head.log_posterior(WindowSummary(window[1].reshape(3, 2)), impossible, 0.2)
    assert np.isneginf(p[1]) and np.isneginf(p[2]) and p[0] == 0.0
    assert LOG_POSTERIOR_CLIP < 0


@pytest.fixture(scope="module")
def fitted_with_fk():
    train, test = split(random_dataset(31, n_demos=12), 9)
    fk = lambda q: np.asarray(q)[:, :3]  # noqa: E731
    return IProMP(["a", "b"], n_basis=9).fit(train, fk=fk), test


def test_fit_chooses_temperature_head_and_conditioning_noise(fitted_with_fk):
    model, test = fitted_with_fk
    assert model.temperature_ in TEMPERATURE_GRID
    assert model.condition_noise_ratio_ in NOISE_GRID
    scores = model.condition_cv_scores_
    assert set(scores) == set(NOISE_GRID) and scores[model.condition_noise_ratio_] == min(scores.values())
    assert model.head_ is not None and model.head_.ratios.size >= 2
    rec = model.recognise(test["task0"][0].head(0.3, ["a", "b"]))
    assert np.isclose(np.logaddexp.reduce(rec.log_posterior), 0.0)
    assert rec.task == rec.tasks[int(np.argmax(rec.posterior))]


def test_generative_posterior_is_tempered(fitted_with_fk):
    model, test = fitted_with_fk
    plain = IProMP(["a", "b"], n_basis=9, noise=model.noise_ratio_, temperature=1.0, head=False)
    tempered = IProMP(["a", "b"], n_basis=9, noise=model.noise_ratio_, temperature=0.1, head=False)
    train = split(random_dataset(31, n_demos=12), 9)[0]
    plain.fit(train)
    tempered.fit(train)
    obs = test["task1"][0].head(0.3, ["a", "b"])
    a, b = plain.recognise(obs), tempered.recognise(obs)
    # log p(k | y) = log pi_k + tau log p(y | k) - const: the evidence is that of the tempered
    # likelihood, and a temperature below 1 pulls the posterior toward the prior
    assert np.max(b.posterior) <= np.max(a.posterior) + 1e-12
    engine = plain.predictor_.engine
    parts, t_last = plain.predictor_.encode(obs)
    ll = engine.log_likelihood([engine.part_stats(p) for p in parts], t_last)
    assert np.allclose(b.log_evidence, np.logaddexp.reduce(0.1 * ll + engine.log_prior, axis=1))
    assert np.allclose(a.log_evidence, np.logaddexp.reduce(ll + engine.log_prior, axis=1))


def test_parameters_are_validated():
    train = split(random_dataset(2), 6)[0]
    with pytest.raises(Exception, match="temperature"):
        IProMP(["a", "b"], temperature=1.5).fit(train)
    with pytest.raises(Exception, match="condition_noise"):
        IProMP(["a", "b"], condition_noise="often").fit(train)
