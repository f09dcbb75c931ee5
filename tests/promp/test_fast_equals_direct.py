"""The fast inference equals the textbook equations (dense Phi, full covariance, Cholesky)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers_model import random_dataset, split

from ipromp_pin.promp import IProMP, direct_predict
from ipromp_pin.promp.compiled import use_kernels

CASES = [
    # seed, missing group, Z tensors (False: per-candidate solve route), noise ratio, observed ratio,
    # groups coupled to the robot (the others form an independent block of dims)
    (31, None, True, 0.3, 0.25, "all"),
    (32, "a", True, 3.0, 0.3, ["b"]),
    (33, None, False, 1.0, 0.2, ["a"]),
    (34, "b", False, 0.1, 0.15, "all"),
    (36, None, True, 1.0, 0.2, []),  # robot independent of the human: its latent dims stay at the prior
]


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(a - b)) / max(float(np.max(np.abs(b))), 1e-300))


@pytest.mark.parametrize("backend", ["numba", "numpy"])
@pytest.mark.parametrize(("seed", "missing", "use_z", "noise", "ratio", "coupling"), CASES)
def test_fast_prediction_equals_direct(seed, missing, use_z, noise, ratio, coupling, backend) -> None:
    with use_kernels(backend):  # the compiled kernels and their numpy version
        _check_fast_equals_direct(seed, missing, use_z, noise, ratio, coupling)


def _check_fast_equals_direct(seed, missing, use_z, noise, ratio, coupling) -> None:
    rng = np.random.default_rng(seed)
    train, test = split(random_dataset(seed, n_demos=9, missing_group=missing), 7)
    n_basis = int(rng.integers(6, 10))
    model = IProMP(["a", "b"], n_basis=n_basis, n_alpha=50, noise=noise, coupling=coupling).fit(train)
    model.predictor_.engine.use_z = use_z
    assert len(model.predictor_.engine.blocks) == (1 if coupling in ("all", []) else 2)
    for task in ("task0", "task2"):
        obs = test[task][int(rng.integers(0, 2))].head(ratio, model.observe)
        fast, ref = model.predict(obs), direct_predict(model.predictor_, obs)
        assert fast.task == ref.task
        assert np.allclose(fast.log_posterior, ref.log_posterior, rtol=1e-8, atol=1e-8)
        assert _rel(fast.posterior, ref.posterior) < 1e-8
        assert _rel(fast.log_evidence, ref.log_evidence) < 1e-8
        assert _rel(fast.alpha, ref.alpha) < 1e-8
        assert _rel(fast.q_mean, ref.q_mean) < 1e-8
        assert _rel(fast.q_cov, ref.q_cov) < 1e-8
        for g in model.observe:
            assert _rel(fast.human_mean[g], ref.human_mean[g]) < 1e-8


def test_close_tasks_give_a_spread_posterior_that_still_matches() -> None:
    # two tasks drawn from the same distribution: the posterior is not saturated, so its equality
    # is a real check of the likelihood values, not only of their ranking
    from ipromp_pin.data import Dataset

    demos = random_dataset(35, n_tasks=1, n_demos=15).demos["task0"]
    relabel = [type(d)(**{**vars(d), "task": "x" if i < 7 else "y"}) for i, d in enumerate(demos[:14])]
    train = Dataset("two-of-one", {"x": relabel[:7], "y": relabel[7:]})
    model = IProMP(["a", "b"], n_basis=7, n_alpha=50, noise=3.0).fit(train)
    for ratio in (0.2, 0.5):
        obs = demos[14].head(ratio, model.observe)
        fast, ref = model.predict(obs), direct_predict(model.predictor_, obs)
        assert 0.01 < fast.posterior.max() < 0.99
        assert _rel(fast.posterior, ref.posterior) < 1e-8
        assert _rel(fast.alpha, ref.alpha) < 1e-8
        assert _rel(fast.q_cov, ref.q_cov) < 1e-8
