"""Compiled (numba) kernels of the phase likelihood: small Cholesky factorisations fused per candidate.

The equations are those of :mod:`ipromp_pin.phase`; these kernels only remove the
per-call overhead of batched numpy / LAPACK on many tiny matrices (20 x 20 and smaller).
Compilation happens on the first call (lazily: importing :mod:`ipromp_pin` does not
import numba) and is cached on disk (``cache=True``); every kernel has one signature
(float64 / int64 C-contiguous arrays).
"""

from __future__ import annotations

import numpy as np
from numba import njit

_JIT = {"cache": True, "nogil": True, "fastmath": False, "error_model": "numpy"}
LOG_2PI = float(np.log(2.0 * np.pi))


@njit(**_JIT)
def chol_inplace(a: np.ndarray, n: int) -> float:
    """Lower Cholesky factor of ``a[:n, :n]`` in place (lower triangle) -> log-determinant (NaN if not SPD)."""
    logdet = 0.0
    for j in range(n):
        s = a[j, j]
        for k in range(j):
            s -= a[j, k] * a[j, k]
        if not s > 0.0:
            return np.nan
        d = np.sqrt(s)
        a[j, j] = d
        logdet += np.log(d)
        inv = 1.0 / d
        for i in range(j + 1, n):
            s = a[i, j]
            for k in range(j):
                s -= a[i, k] * a[j, k]
            a[i, j] = s * inv
    return 2.0 * logdet


@njit(**_JIT)
def x_inverse(gram: np.ndarray, ke: int, nu: float, xinv: np.ndarray, linv: np.ndarray) -> np.ndarray:
    """``X^-1`` (into ``xinv`` (ke, ke, U)), ``L^-1`` (into ``linv`` (ke, ke, U), lower) and ``log|X|`` (U,)
    of ``X = nu I + gram[:, :ke, :ke]`` (``gram`` (U, >=ke, >=ke)); candidate index innermost, so that
    every step is a vector operation over candidates."""
    n_u = gram.shape[0]
    lx = np.empty((ke, ke, n_u))
    for u in range(n_u):
        for i in range(ke):
            for j in range(i + 1):
                lx[i, j, u] = gram[u, i, j]
            lx[i, i, u] += nu
    logdet = np.zeros(n_u)
    ok = chol_soa(lx, ke, logdet)
    if not ok:
        logdet[:] = np.nan
        return logdet
    for j in range(ke):
        for u in range(n_u):
            linv[j, j, u] = 1.0 / lx[j, j, u]
        for i in range(j):
            linv[i, j, :] = 0.0
        for i in range(j + 1, ke):
            li = linv[i, j]
            li[:] = 0.0
            for k in range(j, i):
                lik = lx[i, k]
                lkj = linv[k, j]
                for u in range(n_u):
                    li[u] -= lik[u] * lkj[u]
            lii = lx[i, i]
            for u in range(n_u):
                li[u] /= lii[u]
    for i in range(ke):
        for j in range(i + 1):
            xi = xinv[i, j]
            xi[:] = 0.0
            for k in range(i, ke):
                lki = linv[k, i]
                lkj = linv[k, j]
                for u in range(n_u):
                    xi[u] += lki[u] * lkj[u]
            xinv[j, i, :] = xi
    return logdet


@njit(**_JIT)
def chol_soa(a: np.ndarray, n: int, logdet: np.ndarray) -> bool:
    """Lower Cholesky factors in place of a batch ``a`` (n, n, B) (batch innermost, lower triangle used);
    adds the log-determinants to ``logdet`` (B,). Returns False if a matrix is not numerically SPD."""
    nb = a.shape[2]
    for j in range(n):
        ajj = a[j, j]
        for k in range(j):
            ajk = a[j, k]
            for b in range(nb):
                ajj[b] -= ajk[b] * ajk[b]
        for b in range(nb):
            if not ajj[b] > 0.0:
                return False
            ajj[b] = np.sqrt(ajj[b])
            logdet[b] += 2.0 * np.log(ajj[b])
        for i in range(j + 1, n):
            aij = a[i, j]
            for k in range(j):
                aik = a[i, k]
                ajk = a[j, k]
                for b in range(nb):
                    aij[b] -= aik[b] * ajk[b]
            for b in range(nb):
                aij[b] /= ajj[b]
    return True


@njit(**_JIT)
def part_terms(
    gram: np.ndarray,
    proj: np.ndarray,
    sq: np.ndarray,
    n_obs: int,
    ke: int,
    nu: float,
    tasks: np.ndarray,
    index: np.ndarray,
    mu_k: np.ndarray,
    inv_delta: np.ndarray,
    mu2: np.ndarray,
    log_delta: np.ndarray,
    w_k: np.ndarray,
    w_1: np.ndarray,
    z: np.ndarray,
    pk: np.ndarray,
    pl: np.ndarray,
    unpack: np.ndarray,
    use_z: bool,
    total: np.ndarray,
    a: np.ndarray,
    pq: np.ndarray,
) -> bool:
    """Add one observation part's terms to ``total`` (T', C), ``a`` (T', r, C) and packed ``P`` (T', r(r+1)/2, C).

    Args:
        gram, proj, sq: Part statistics ``B^T B`` (U, >=ke, >=ke), ``B^T y`` (U, >=ke, D_m), ``y^T y`` (D_m,).
        n_obs, ke, nu: Number of samples, active basis functions, noise ratio.
        tasks, index: (T',) task indices and (T', C) unique-candidate index of every pair.
        mu_k, inv_delta, mu2, log_delta, w_k: Model arrays of the part's dims (see ``InferenceEngine._dims``).
        w_1: (T, K D_m, r) ``W_d`` rows ordered (basis, dim) (only used without ``Z``).
        z, pk, pl: Packed ``Z`` tensors (T, K(K+1)/2, r(r+1)/2) and their basis pairs (only with ``use_z``).
        unpack: (r, r) index of ``(i, j)`` in the packed layout.

    Returns:
        False when a matrix ``X`` was not numerically positive definite.
    """
    n_u = gram.shape[0]
    dm = proj.shape[2]
    r = a.shape[1]
    n_t, n_c = index.shape
    xinv = np.empty((ke, ke, n_u))
    linv = np.empty((ke, ke, n_u))
    logdet = x_inverse(gram, ke, nu, xinv, linv)
    if not np.isfinite(logdet[0]):
        return False
    m = ke * (ke + 1) // 2
    kd = ke * dm
    const = n_obs * dm * LOG_2PI + dm * (n_obs - ke) * np.log(nu)
    h = np.empty((ke, dm, n_c))
    xg = np.empty((ke, ke, n_c))
    xb = np.empty((kd, n_c))
    coef = np.empty((m, n_c))
    quad = np.empty(n_c)
    for ti in range(n_t):
        t = tasks[ti]
        sqd = 0.0
        for d in range(dm):
            sqd += sq[d] * inv_delta[t, d]
        base = (sqd + nu * mu2[t, ke]) / nu + const + n_obs * log_delta[t]
        for c in range(n_c):
            u = index[ti, c]
            for k in range(ke):
                for d in range(dm):
                    h[k, d, c] = proj[u, k, d] + nu * mu_k[t, k, d]
                for j in range(ke):
                    xg[k, j, c] = xinv[k, j, u]
        quad[:] = 0.0
        for k in range(ke):
            for d in range(dm):
                acc = xb[k * dm + d]
                acc[:] = 0.0
                for j in range(ke):
                    xkj = xg[k, j]
                    hjd = h[j, d]
                    for c in range(n_c):
                        acc[c] += xkj[c] * hjd[c]
                hkd = h[k, d]
                wd = inv_delta[t, d]
                mkd = mu_k[t, k, d]
                for c in range(n_c):
                    quad[c] += hkd[c] * acc[c] * wd
                    acc[c] -= mkd
        for c in range(n_c):
            total[ti, c] += base - quad[c] / nu + dm * logdet[index[ti, c]]
        a[ti] += np.dot(np.ascontiguousarray(w_k[t, :kd].T), xb)
        if use_z:
            for q in range(m):
                diag = 1.0 if pk[q] == pl[q] else 0.0
                xq = xg[pk[q], pl[q]]
                cq = coef[q]
                for c in range(n_c):
                    cq[c] = diag - nu * xq[c]
            pq[ti] += np.dot(np.ascontiguousarray(z[t, :m].T), coef)
    if not use_z:
        v = np.empty((kd, r))
        for ti in range(n_t):
            t = tasks[ti]
            wt = np.ascontiguousarray(w_1[t, :kd])
            s = np.dot(wt.T, wt)
            for c in range(n_c):
                u = index[ti, c]
                for k in range(ke):
                    for d in range(dm):
                        for p in range(r):
                            v[k * dm + d, p] = 0.0
                        for j in range(k + 1):
                            x = linv[k, j, u]
                            for p in range(r):
                                v[k * dm + d, p] += x * wt[j * dm + d, p]
                vv = np.dot(v.T, v)
                for i in range(r):
                    for j in range(i, r):
                        pq[ti, unpack[i, j], c] += s[i, j] - nu * vv[i, j]
    return True


@njit(**_JIT)
def finish_terms(
    pq: np.ndarray,
    a: np.ndarray,
    total: np.ndarray,
    unpack: np.ndarray,
    alphas: np.ndarray,
    t_norm: float,
    t_last: float,
    loglik: np.ndarray,
) -> bool:
    """Log likelihood (into ``loglik`` (T', C)) from ``Q = I + P`` (packed (T', r(r+1)/2, C)), ``a`` (T', r, C)
    and the other terms ``total`` (T', C).

    ``log|Q|`` and ``a^T Q^-1 a`` come from one Cholesky factorisation of ``Q`` per pair
    (vectorised over candidates); candidates shorter than the observation get ``-inf``.
    Returns False when a ``Q`` was not numerically positive definite.
    """
    n_t, r, n_c = a.shape
    lq = np.empty((r, r, n_c))
    v = np.empty((r, n_c))
    logdet = np.empty(n_c)
    for t in range(n_t):
        for i in range(r):
            for j in range(i + 1):
                lq[i, j] = pq[t, unpack[i, j]]
            lq[i, i] += 1.0
        logdet[:] = 0.0
        if not chol_soa(lq, r, logdet):
            return False
        vv = np.zeros(n_c)
        for i in range(r):
            vi = v[i]
            vi[:] = a[t, i]
            for k in range(i):
                lik = lq[i, k]
                vk = v[k]
                for c in range(n_c):
                    vi[c] -= lik[c] * vk[c]
            lii = lq[i, i]
            for c in range(n_c):
                vi[c] /= lii[c]
                vv[c] += vi[c] * vi[c]
        for c in range(n_c):
            if t_last > alphas[t, c] * t_norm * (1.0 + 1e-12):
                loglik[t, c] = -np.inf
            else:
                loglik[t, c] = -0.5 * (total[t, c] + logdet[c] - vv[c])
    return True
