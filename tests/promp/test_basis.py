"""Gaussian basis: conditioning, fast evaluation, weight fit."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.exceptions import ModelError
from ipromp_pin.promp.basis import GaussianBasis


@pytest.mark.parametrize("n_basis", [31, 61])
def test_gram_condition_number_is_modest(n_basis: int) -> None:
    cond = GaussianBasis(n_basis).condition_number()
    # the paper authors' basis had ~1e9; ours is ~2.2e3 (see the module docstring)
    assert cond < 5e3


def test_wide_basis_is_ill_conditioned() -> None:
    # the check above can fail: a width of 1.5 spacings is as bad as the paper's basis
    assert GaussianBasis(31, width=1.5 / 30).condition_number() > 1e8


@pytest.mark.parametrize("n_basis", [11, 31, 61])
def test_prefix_values_equal_direct_formula(n_basis: int) -> None:
    basis = GaussianBasis(n_basis)
    z = np.random.default_rng(0).uniform(0.0, 0.45, (7, 13))
    direct = basis(z)[..., :n_basis]
    fast = np.moveaxis(basis.values_prefix_t(z, n_basis), 0, -1)
    assert np.max(np.abs(fast - direct)) < 1e-12


def test_fit_weights_reproduces_smooth_signal() -> None:
    basis = GaussianBasis(31)
    z = np.linspace(0.0, 1.0, 150)
    y = np.stack([np.sin(2 * np.pi * z), z**2], axis=1)
    w = basis.fit_weights(z, y)
    assert w.shape == (2, 31)
    assert np.max(np.abs(basis(z) @ w.T - y)) < 3e-3


def test_margin_lets_the_fit_follow_the_ends() -> None:
    z = np.linspace(0.0, 1.0, 400)
    y = z[:, None] ** 2
    errors = []
    for margin in (0.0, 1.0):
        basis = GaussianBasis(31, margin=margin)
        errors.append(np.max(np.abs(basis(z) @ basis.fit_weights(z, y).T - y)))
    assert errors[1] < 0.1 * errors[0]


def test_support_count_drops_only_negligible_functions() -> None:
    basis = GaussianBasis(31)
    z = np.linspace(0.0, 0.2, 50)
    ke = basis.support_count(0.2)
    assert ke < 31
    assert np.max(basis(z)[:, ke:]) < 1e-11
    assert np.max(basis(z)[:, ke - 1]) > 1e-11 or ke == 1


@pytest.mark.parametrize(
    "kwargs", [{"n_basis": 1}, {"n_basis": 31, "width": -1.0}, {"n_basis": 5, "ridge": -1}]
)
def test_bad_parameters_raise(kwargs: dict) -> None:
    with pytest.raises(ModelError):
        GaussianBasis(**kwargs)


def test_support_limit_matches_support_count() -> None:
    basis = GaussianBasis(31)
    zs = np.linspace(0.0, 1.0, 2001)
    for n_first in (3, 10, 20, 30, 31):
        limit = basis.support_limit(n_first)
        counts = np.array([basis.support_count(z) for z in zs])
        assert np.all((counts <= n_first) == (zs < limit))


def test_gram_factors_give_the_gram_matrix() -> None:
    basis = GaussianBasis(21)
    z = np.random.default_rng(3).uniform(0.0, 0.4, 37)
    b = basis(z)
    pair_step, overlap = basis.gram_factors()
    inv_h2 = 1.0 / basis.width**2
    psi = np.empty((2 * basis.n_basis - 1, z.size))
    psi[0] = np.exp(-((z - basis.centres[0]) ** 2) * inv_h2)
    q = np.exp(z * basis.spacing * inv_h2)
    for s in range(1, psi.shape[0]):
        psi[s] = psi[s - 1] * q * pair_step[s - 1]
    sums = psi.sum(axis=1)
    k = np.arange(basis.n_basis)
    gram = overlap[np.abs(k[:, None] - k[None, :])] * sums[k[:, None] + k[None, :]]
    np.testing.assert_allclose(gram, b.T @ b, rtol=1e-12, atol=1e-300)
