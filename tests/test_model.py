"""Per-task model pieces: scaling, shrinkage covariance, phase candidates."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.basis import GaussianBasis
from ipromp_pin.exceptions import ModelError
from ipromp_pin.model import ChannelScaler, alpha_candidates, alpha_prior, shrink_covariance


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
    lam = cov.shrinkage
    expected = (1 - lam) * s + lam * np.diag(np.repeat(tau, k))
    f = cov.factor.reshape(d * k, -1)
    dense = f @ f.T + np.diag(np.repeat(cov.diag, k))
    assert 0.0 < lam < 1.0
    assert cov.factor.shape[2] <= n - 1
    assert np.allclose(dense, expected, atol=1e-5 * np.abs(expected).max())
    assert np.linalg.eigvalsh(dense).min() > 0.0


def test_shrinkage_decreases_with_more_demos() -> None:
    rng = np.random.default_rng(2)
    few = shrink_covariance(_weights(rng, 8)).shrinkage
    many = shrink_covariance(_weights(rng, 400)).shrinkage
    assert many < few


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
    from ipromp_pin.model import TaskModel

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
