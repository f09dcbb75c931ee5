"""The cross-validations' leave-one-out covariances: the shared per-task statistics
(:class:`~ipromp_pin.promp.distribution.ShrinkageCache`) give the same estimates as refitting every
task without the held-out demo, and the fitted model's cross-validation choices do not depend on them."""

from __future__ import annotations

import numpy as np
import pytest

from ipromp_pin.promp.distribution import ShrinkageCache, shrink_covariances


def _weights(rng: np.random.Generator, n: int, d: int = 4, k: int = 5) -> np.ndarray:
    mix = rng.normal(size=(3, d * k))
    return (rng.normal(size=(n, 3)) @ mix + 0.3 * rng.normal(size=(n, d * k))).reshape(n, d, k)


def _covariance_arrays(cov) -> list[np.ndarray]:
    # the factor is compared through F F^T (an SVD's columns are defined up to sign)
    f = cov.factor.reshape(-1, cov.factor.shape[2])
    return [cov.mean, cov.diag, cov.shrinkage, f @ f.T]


@pytest.mark.parametrize("pooling", [0.0, 0.4])
def test_cached_leave_one_out_equals_the_refit(pooling: float) -> None:
    rng = np.random.default_rng(3)
    weights = [_weights(rng, n) for n in (6, 5, 7)]
    blocks = [np.array([0, 2]), np.array([1, 3])]
    cache = ShrinkageCache(weights)
    for task in range(len(weights)):
        for i in range(weights[task].shape[0]):
            keep = np.arange(weights[task].shape[0]) != i
            loo = [w[keep] if t == task else w for t, w in enumerate(weights)]
            # refit: fresh copies, so that nothing can come from the cache
            refit = shrink_covariances([w.copy() for w in loo], pooling, blocks)
            fast = shrink_covariances(loo, pooling, blocks, cache=cache)
            for a, b in zip(refit, fast, strict=True):
                for x, y in zip(_covariance_arrays(a), _covariance_arrays(b), strict=True):
                    np.testing.assert_allclose(y, x, rtol=1e-12, atol=1e-14)
    # the full estimate is unchanged by the cache too, and the LOO one differs from it
    full = shrink_covariances(weights, pooling, blocks, cache=cache)
    plain = shrink_covariances([w.copy() for w in weights], pooling, blocks)
    for a, b in zip(plain, full, strict=True):
        np.testing.assert_array_equal(a.diag, b.diag)
    assert not np.allclose(full[-1].mean, shrink_covariances(loo, pooling, blocks)[-1].mean)


def test_cache_ignores_arrays_it_was_not_given() -> None:
    rng = np.random.default_rng(4)
    w = _weights(rng, 6)
    cache = ShrinkageCache([w])
    dims = np.arange(4)
    assert cache.stats(w, dims) is cache.stats(w, dims)
    assert cache.stats(w.copy(), dims) is None


@pytest.mark.parametrize("pooling", [0.0, 0.4])
def test_factor_blocks_keep_the_chosen_blocks_columns(pooling: float) -> None:
    """``factor_blocks``: the chosen blocks' factor columns and every diagonal are those of the full
    estimate (the same numbers), the other blocks get no columns."""
    rng = np.random.default_rng(5)
    weights = [_weights(rng, n) for n in (6, 5, 7)]
    blocks = [np.array([1, 3]), np.array([0, 2])]
    full = shrink_covariances(weights, pooling, blocks, [1])[0]
    part = shrink_covariances(weights, pooling, blocks, [1], factor_blocks=[0])[0]
    cols = np.flatnonzero(np.any(full.factor[blocks[0]] != 0.0, axis=(0, 1)))
    np.testing.assert_array_equal(part.factor, full.factor[:, :, cols])
    for name in ("mean", "diag", "shrinkage"):
        np.testing.assert_array_equal(getattr(part, name), getattr(full, name))
