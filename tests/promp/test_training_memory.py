"""Training's building blocks that save time or memory give the same numbers as the plain versions:
the panel-wise ``Z`` tensors, the ridge fit's residuals."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.promp.handover import fit_ridge
from ipromp_pin.promp.latent_blocks import LatentBlock


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
