"""Training's building blocks that save time or memory give the same numbers as the plain versions:
the L-BFGS driver of the recognition head, the panel-wise ``Z`` tensors, the ridge fit's residuals."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from ipromp_pin.promp.handover import fit_ridge
from ipromp_pin.promp.latent_blocks import LatentBlock
from ipromp_pin.promp.lbfgs import minimize_lbfgs


def _logistic(seed: int):
    """A small weighted multinomial logistic loss with an L2 penalty (value, gradient)."""
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(60, 5))
    y = rng.integers(0, 3, size=60)
    onehot = np.eye(3)[y]

    def loss(theta: np.ndarray) -> tuple[float, np.ndarray]:
        w, b = theta[:15].reshape(3, 5), theta[15:]
        z = x @ w.T + b
        z = z - z.max(axis=1, keepdims=True)
        logp = z - np.log(np.exp(z).sum(axis=1, keepdims=True))
        r = (np.exp(logp) - onehot) / 60.0
        grad = np.concatenate([(r.T @ x + 0.01 * w).ravel(), r.sum(axis=0)])
        return -float(np.sum(onehot * logp)) / 60.0 + 0.005 * float(np.sum(w * w)), grad

    return loss


@pytest.mark.parametrize("max_iter", [500, 3])
@pytest.mark.parametrize("seed", [0, 1])
def test_lbfgs_driver_takes_scipys_iterates(seed: int, max_iter: int) -> None:
    loss = _logistic(seed)
    x0 = np.full(18, 0.1)
    ours = minimize_lbfgs(loss, x0, max_iter=max_iter)
    ref = minimize(loss, x0, jac=True, method="L-BFGS-B", options={"maxiter": max_iter}).x
    assert np.array_equal(ours, ref)  # the same numbers, not only close
    assert np.array_equal(x0, np.full(18, 0.1))  # the start is not changed


def _dense_z(w: np.ndarray) -> np.ndarray:
    """``Z`` (T, K(K+1)/2, r(r+1)/2) from its definition: sum_d W_dka W_dlb + (k != l) W_dla W_dkb."""
    _, _, k, r = w.shape
    ia, ib = np.triu_indices(r)
    rows = [(kk, ll) for ll in range(k) for kk in range(ll + 1)]
    z = np.zeros((w.shape[0], len(rows), ia.size))
    for n, (kk, ll) in enumerate(rows):
        z[:, n] = np.einsum("tda,tdb->tab", w[:, :, kk], w[:, :, ll])[:, ia, ib]
        if kk != ll:
            z[:, n] += np.einsum("tda,tdb->tab", w[:, :, ll], w[:, :, kk])[:, ia, ib]
    return z


@pytest.mark.parametrize("shape", [(2, 4, 9, 3), (3, 5, 7, 1), (1, 2, 4, 2)])
def test_panel_z_tensor_matches_its_definition(shape: tuple[int, int, int, int]) -> None:
    """Panels of several basis functions (a last partial one; rank 1 one at a time) fill every row."""
    rng = np.random.default_rng(3)
    block = LatentBlock.__new__(LatentBlock)  # only the factors matter here
    block.w, block._z = rng.normal(size=shape), {}
    n_task, n_dim, k, r = shape
    ref = _dense_z(block.w)
    local = np.arange(n_dim)
    assert np.allclose(block.z_tensor(local), ref, rtol=1e-13, atol=1e-13)
    assert np.allclose(block.z_tensor(local, n_basis=3), _dense_z(block.w[:, :, :3]), rtol=1e-13, atol=1e-13)
    out = np.full((n_task, k * (k + 1) // 2, r * (r + 1) // 2), np.nan)
    assert block.z_tensor(local, out=out) is out and np.allclose(out, ref, rtol=1e-13, atol=1e-13)


def test_ridge_fit_does_not_keep_every_penalty_residuals() -> None:
    rng = np.random.default_rng(4)
    fit = fit_ridge(rng.normal(size=(12, 4)), rng.normal(size=(12, 3)))
    assert fit.residuals.shape == (12, 3) and fit.residuals.base is None
