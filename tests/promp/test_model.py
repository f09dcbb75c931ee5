"""Per-task model pieces: scaling, shrinkage covariance, phase candidates."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.exceptions import ModelError
from ipromp_pin.promp.basis import GaussianBasis
from ipromp_pin.promp.distribution import (
    ChannelScaler,
    alpha_candidates,
    alpha_prior,
    shrink_covariance,
    shrink_covariances,
)


def test_scaler_round_trip_and_constant_channel() -> None:
    rng = np.random.default_rng(0)
    x = np.column_stack([rng.normal(5.0, 3.0, 100), np.full(100, 2.0)])
    sc = ChannelScaler.fit(x)
    y = sc.transform(x)
    assert np.allclose(y[:, 0].std(), 1.0) and np.allclose(y[:, 0].mean(), 0.0)
    assert sc.scale[1] == 1.0
    assert np.allclose(sc.inverse(y), x)


def _weights(rng: np.random.Generator, n: int, d: int = 4, k: int = 6) -> np.ndarray:
    mix = rng.normal(size=(3, d * k))  # true covariance: rank 3 + small diagonal
    return (rng.normal(size=(n, 3)) @ mix + 0.3 * rng.normal(size=(n, d * k))).reshape(n, d, k)


def test_shrinkage_is_spd_and_matches_its_formula() -> None:
    rng = np.random.default_rng(1)
    w = _weights(rng, 10)
    cov = shrink_covariance(w)
    n, d, k = w.shape
    xc = (w - w.mean(axis=0)).reshape(n, d * k)
    s = xc.T @ xc / n
    tau = np.array([np.trace(s[i * k : (i + 1) * k, i * k : (i + 1) * k]) / k for i in range(d)])
    assert cov.shrinkage.shape == (d,) and np.all(cov.shrinkage == cov.shrinkage[0])
    lam = cov.shrinkage[0]
    expected = (1 - lam) * s + lam * np.diag(np.repeat(tau, k))
    f = cov.factor.reshape(d * k, -1)
    dense = f @ f.T + np.diag(np.repeat(cov.diag, k))
    assert 0.0 < lam < 1.0
    assert cov.factor.shape[2] <= n - 1
    assert np.allclose(dense, expected, atol=1e-5 * np.abs(expected).max())
    assert np.linalg.eigvalsh(dense).min() > 0.0


def test_shrinkage_decreases_with_more_demos() -> None:
    rng = np.random.default_rng(2)
    few = shrink_covariance(_weights(rng, 8)).shrinkage[0]
    many = shrink_covariance(_weights(rng, 400)).shrinkage[0]
    assert many < few


def _dense(cov) -> np.ndarray:
    d, k, _ = cov.factor.shape
    f = cov.factor.reshape(d * k, -1)
    return f @ f.T + np.diag(np.repeat(cov.diag, k))


def test_blocks_are_independent_and_each_shrunk_on_its_own() -> None:
    rng = np.random.default_rng(5)
    weights = [_weights(rng, n, d=5, k=4) for n in (7, 9)]
    blocks = [np.array([0, 3, 4]), np.array([1, 2])]
    covs = shrink_covariances(weights, blocks=blocks)
    for t, cov in enumerate(covs):
        dense = _dense(cov).reshape(5, 4, 5, 4)
        assert np.linalg.eigvalsh(_dense(cov)).min() > 0.0
        assert cov.factor.shape[2] <= 2 * (weights[t].shape[0] - 1)
        # no covariance between the blocks
        assert np.all(dense[np.ix_(blocks[0], range(4), blocks[1], range(4))] == 0.0)
        for b in blocks:
            # each block equals the estimate made from its dims alone (own intensity and target)
            alone = shrink_covariances([w[:, b] for w in weights])[t]
            assert np.allclose(dense[np.ix_(b, range(4), b, range(4))].reshape(b.size * 4, -1), _dense(alone))
            assert np.all(cov.shrinkage[b] == alone.shrinkage[0])
            assert np.array_equal(cov.diag[b], alone.diag)
    assert covs[0].shrinkage[0] != covs[0].shrinkage[1]
    # only some tasks: the same estimates (the pooled target and intensity still use every task)
    (only,) = shrink_covariances(weights, blocks=blocks, tasks=[1])
    assert np.allclose(_dense(only), _dense(covs[1])) and np.array_equal(only.mean, covs[1].mean)


@pytest.mark.parametrize("blocks", [[np.array([0, 1])], [np.array([0, 1, 2]), np.array([2, 3, 4])]])
def test_blocks_must_partition_the_dims(blocks) -> None:
    rng = np.random.default_rng(6)
    with pytest.raises(ModelError, match="partition"):
        shrink_covariances([_weights(rng, 6, d=5, k=3)], blocks=blocks)


def test_shrinkage_needs_two_demos() -> None:
    with pytest.raises(ModelError):
        shrink_covariance(np.zeros((1, 2, 3)))


def test_alpha_candidates_share_a_lattice_and_cover_every_support() -> None:
    rng = np.random.default_rng(3)
    priors = [alpha_prior(rng.normal(mu, 0.1, 15)) for mu in (0.9, 1.0, 1.2)]
    cands = alpha_candidates(priors, 50, 3.0)
    spacing = cands[0][0][1] - cands[0][0][0]
    for (mu, sd), (grid, logw) in zip(priors, cands, strict=True):
        inside = (grid >= mu - 3 * sd - 1e-12) & (grid <= mu + 3 * sd + 1e-12)
        assert inside.sum() >= 50
        assert grid[0] <= mu - 3 * sd + spacing and grid[-1] >= mu + 3 * sd - spacing
        assert np.isclose(np.logaddexp.reduce(logw), 0.0)
    # shared candidates are bitwise equal, so the engine computes them once
    common = np.intersect1d(cands[0][0], cands[1][0])
    assert common.size > 10


def test_distribution_matches_dense_covariance() -> None:
    from ipromp_pin.promp.distribution import TaskModel

    rng = np.random.default_rng(4)
    w = _weights(rng, 9, d=3, k=6)
    cov = shrink_covariance(w)
    m = TaskModel(
        "t", cov.mean, cov.diag, cov.factor, cov.shrinkage, 1.0, 0.1, np.ones(3), np.zeros(3), w, np.ones(9)
    )
    basis = GaussianBasis(6)
    phi = basis(np.linspace(0, 1, 5))
    mean, std = m.distribution(phi)
    dense = m.covariance()
    for j in range(3):
        block = dense[j * 6 : (j + 1) * 6, j * 6 : (j + 1) * 6]
        assert np.allclose(std[:, j] ** 2, np.einsum("nk,kl,nl->n", phi, block, phi))
        assert np.allclose(mean[:, j], phi @ cov.mean[j])
