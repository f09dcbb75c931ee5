"""Compiled (numba) kernels of the phase likelihood: small Cholesky factorisations fused per candidate.

The equations are those of :mod:`ipromp_pin.promp.likelihood`; these kernels only remove the
per-call overhead of batched numpy / LAPACK on many tiny matrices (20 x 20 and smaller).
Compilation happens on the first call (lazily: importing :mod:`ipromp_pin` does not
import numba) and is cached on disk (``cache=True``); every kernel has one signature
(float64 / int64 C-contiguous arrays).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .sample_bounds import MAX_LOG_SCALED_MAGNITUDE, MAX_SCALED_MAGNITUDE

_JIT = {"cache": True, "nogil": True, "fastmath": False, "error_model": "numpy"}
_JIT_FMA = {**_JIT, "fastmath": {"contract"}}  # fused multiply-add only (no reassociation)

LOG_2PI = float(np.log(2.0 * np.pi))

P_FROM_W = 0
""":func:`part_terms` forms ``P`` from the scaled factors (no ``Z`` tensor)."""
P_FROM_Z = 1
""":func:`part_terms` forms ``P`` with one product with the ``Z`` tensor per task."""
P_BY_CALLER = 2
""":func:`part_terms` leaves ``P`` to the caller (one product for all tasks, :func:`add_fused_p`)."""


@njit(**_JIT)
def chol_inplace(a: np.ndarray, n: int) -> float:
    """Cholesky factor of ``a[:n, :n]`` in place (lower triangle) -> log-determinant (NaN if not SPD)."""
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
def part_stats(
    t: np.ndarray,
    inv_dur: np.ndarray,
    centres: np.ndarray,
    width: float,
    step: np.ndarray,
    pair_step: np.ndarray,
    overlap: np.ndarray,
    ke: int,
    y: np.ndarray,
):
    """``B^T B`` (ke, ke, U), ``B^T y`` (ke, U, D_m) and ``y^T y`` (D_m,) of the first ``ke`` Gaussian
    basis functions at the phases ``z = t inv_dur`` of samples at times ``t`` (n,) in [s] for the
    candidates ``inv_dur`` (U,) in [1/s]; ``y`` (n, D_m).

    The basis values come from the running product of
    :meth:`ipromp_pin.promp.basis.GaussianBasis.values_prefix_t` (same operations):
    ``phi_0 = exp(-(z - c_0)^2 / (2 h^2))``, ``phi_k = phi_{k-1} (q step_{k-1})`` with
    ``q = exp(z Delta / h^2)``, and ``B^T B`` from the 2 ke - 1 sums of
    :meth:`~ipromp_pin.promp.basis.GaussianBasis.gram_factors` (``psi_0 = phi_0^2``,
    ``psi_s = psi_{s-1} (q pair_step_{s-1})``). Where ``phi_0^2`` could underflow the Gram sums are
    products of the basis values, and where ``phi_0`` could underflow (or ``ke < 3``) the basis
    values are exact exponentials (as ``GaussianBasis.__call__``).
    """
    n = t.shape[0]
    n_u = inv_dur.shape[0]
    dm = y.shape[1]
    inv_h2 = 1.0 / (width * width)
    spacing = centres[1] - centres[0]
    c0 = centres[0]
    far = 0.0
    for j in range(n):
        for u in range(n_u):
            far = max(far, abs(t[j] * inv_dur[u] - c0))
    far = far * far * inv_h2
    exact = ke < 3 or 0.5 * far > 650.0
    hankel = not exact and far <= 650.0
    ns = 2 * ke - 1
    sums = np.zeros((ns, n_u))
    bn = np.empty((n, ke, n_u))  # basis values, sample-major: B^T y is one matrix product
    psi = np.empty(n_u)
    qj = np.empty(n_u)
    gram = np.zeros((ke, ke, n_u))
    inv_w = 1.0 / width
    for j in range(n):
        b = bn[j]
        if exact:
            for k in range(ke):
                for u in range(n_u):
                    d = (t[j] * inv_dur[u] - centres[k]) * inv_w
                    b[k, u] = np.exp(-0.5 * d * d)
        else:
            for u in range(n_u):
                z = t[j] * inv_dur[u]
                d0 = z - c0
                b[0, u] = np.exp(-0.5 * inv_h2 * d0 * d0)
                qj[u] = np.exp(z * (spacing * inv_h2))
            for k in range(1, ke):
                f = step[k - 1]
                for u in range(n_u):
                    b[k, u] = b[k - 1, u] * (qj[u] * f)
        if hankel:
            s0 = sums[0]
            for u in range(n_u):
                psi[u] = b[0, u] * b[0, u]
                s0[u] += psi[u]
            for s in range(1, ns):
                f = pair_step[s - 1]
                ss = sums[s]
                for u in range(n_u):
                    psi[u] *= qj[u] * f
                    ss[u] += psi[u]
        else:
            for k in range(ke):
                for m in range(k + 1):
                    g = gram[k, m]
                    for u in range(n_u):
                        g[u] += b[k, u] * b[m, u]
    for k in range(ke):
        for m in range(k + 1):
            g = gram[k, m]
            if hankel:
                o = overlap[k - m]
                sk = sums[k + m]
                for u in range(n_u):
                    g[u] = o * sk[u]
            gram[m, k] = g
    proj = np.dot(bn.reshape(n, ke * n_u).T, y).reshape(ke, n_u, dm)
    sq = np.zeros(dm)
    for j in range(n):
        for d in range(dm):
            sq[d] += y[j, d] * y[j, d]
    return gram, proj, sq


@njit(**_JIT)
def x_inverse(
    gram: np.ndarray, ke: int, nu: float, xinv: np.ndarray, linv: np.ndarray, coef: np.ndarray
) -> np.ndarray:
    """``X^-1`` (into ``xinv`` (ke, ke, U)), ``L^-1`` (into ``linv`` (ke, ke, U), lower) and ``log|X|`` (U,)
    of ``X = nu I + gram[:ke, :ke]`` (``gram`` (>=ke, >=ke, U)); candidate index innermost, so that
    every step is a vector operation over candidates. Also ``coef`` (U, ke(ke+1)/2), the packed upper
    triangle of ``I - nu X^-1`` (columns ``(k, l)``, ``k <= l``, ordered by ``l`` then ``k``), the
    coefficients of the ``Z`` product of :func:`part_terms`."""
    n_k, n_u = gram.shape[1], gram.shape[2]
    entry = np.empty((ke, ke), dtype=np.int64)  # row of gram's entry (i, j) once flattened
    for i in range(ke):
        for j in range(ke):
            entry[i, j] = i * n_k + j
    lx = np.empty((ke * (ke + 1) // 2, n_u))  # factor of X in packed lower rows
    logdet = np.zeros(n_u)
    if not chol_packed(gram.reshape(-1, n_u), entry, nu, lx, ke, logdet):
        logdet[:] = np.nan
        return logdet
    for j in range(ke):
        rj = j * (j + 1) // 2
        for u in range(n_u):
            linv[j, j, u] = 1.0 / lx[rj + j, u]
    for j in range(ke):
        for i in range(j):
            linv[i, j, :] = 0.0
        for i in range(j + 1, ke):
            ri = i * (i + 1) // 2
            li = linv[i, j]
            li[:] = 0.0
            for k in range(j, i):
                lik = lx[ri + k]
                lkj = linv[k, j]
                for u in range(n_u):
                    li[u] -= lik[u] * lkj[u]
            rii = linv[i, i]
            for u in range(n_u):
                li[u] *= rii[u]
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
    q = 0
    for ll in range(ke):
        for kk in range(ll + 1):
            diag = 1.0 if kk == ll else 0.0
            xq = xinv[kk, ll]
            for u in range(n_u):
                coef[u, q] = diag - nu * xq[u]
            q += 1
    return logdet


@njit(**_JIT)
def chol_packed(
    src: np.ndarray, entry: np.ndarray, shift: float, a: np.ndarray, n: int, logdet: np.ndarray
) -> bool:
    """Lower Cholesky factors of a batch of ``n x n`` matrices ``shift I + S`` (batch innermost), written
    as packed lower rows into ``a`` (n(n+1)/2, B): entry ``(i, j <= i)`` at row ``i (i + 1) / 2 + j``.
    ``S[i, j]`` is row ``entry[i, j]`` of ``src`` (M, B) (only ``j <= i`` is read), so a packed or a
    square source is read where each entry is first needed, without a copy. Adds the
    log-determinants to ``logdet`` (B,); returns False if a matrix is not numerically SPD.

    Every entry is accumulated in a contiguous buffer over the batch, four products per pass over
    it (in the order of the plain loop: same rounding), and divided by the diagonal through its
    reciprocal (one division per column and matrix)."""
    nb = a.shape[1]
    prod = np.ones(nb)
    inv = np.empty(nb)
    acc = np.empty(nb)
    for j in range(n):
        rj = j * (j + 1) // 2
        for i in range(j, n):  # the diagonal entry first, then the column below it
            ri = i * (i + 1) // 2
            row = src[entry[i, j]]
            if i == j:
                for b in range(nb):
                    acc[b] = row[b] + shift
            else:
                for b in range(nb):
                    acc[b] = row[b]
            k = 0
            while k + 4 <= j:  # four terms per pass over the batch (same order of operations)
                for b in range(nb):
                    acc[b] = (
                        ((acc[b] - a[ri + k, b] * a[rj + k, b]) - a[ri + k + 1, b] * a[rj + k + 1, b])
                        - a[ri + k + 2, b] * a[rj + k + 2, b]
                    ) - a[ri + k + 3, b] * a[rj + k + 3, b]
                k += 4
            for kk in range(k, j):
                for b in range(nb):
                    acc[b] -= a[ri + kk, b] * a[rj + kk, b]
            if i > j:
                for b in range(nb):
                    a[ri + j, b] = acc[b] * inv[b]
                continue
            for b in range(nb):
                if not acc[b] > 0.0:
                    return False
            for b in range(nb):
                d = np.sqrt(acc[b])
                a[rj + j, b] = d
                prod[b] *= d
                inv[b] = 1.0 / d
            if j % 8 == 7 or j == n - 1:  # one log per 8 factors (bounded diagonals: no overflow)
                for b in range(nb):
                    logdet[b] += 2.0 * np.log(prod[b])
                    prod[b] = 1.0
    return True


@njit(**_JIT)
def part_terms(
    xinv: np.ndarray,
    linv: np.ndarray,
    logdet: np.ndarray,
    coef: np.ndarray,
    proj: np.ndarray,
    sq: np.ndarray,
    cols: np.ndarray,
    n_obs: int,
    ke: int,
    nu: float,
    starts: np.ndarray,
    n_c: int,
    mu_k: np.ndarray,
    mu_rows: np.ndarray,
    inv_delta: np.ndarray,
    mu2: np.ndarray,
    log_delta: np.ndarray,
    w_k: np.ndarray,
    w_1: np.ndarray,
    z: np.ndarray,
    unpack: np.ndarray,
    p_mode: int,
    lane0: int,
    total: np.ndarray,
    a: np.ndarray,
    pq: np.ndarray,
) -> None:
    """Add one observation part's terms to ``total`` (P',), ``a`` (r, P') and packed ``P`` (r(r+1)/2, P'),
    in the lanes from ``lane0``.

    The P = T C (task, candidate) pairs are ordered task-major; task t's candidates are the unique
    candidates ``starts[t] .. starts[t] + C - 1`` (consecutive points of the common lattice).
    With ``h_d = B^T y_d + nu mu_d``: ``X^-1 h_d = X^-1 B^T y_d + nu X^-1 mu_d``, the first product
    once per unique candidate (shared by the tasks), the second for every task and candidate in
    one matrix product; ``P`` of all candidates is one product with ``Z`` per task.

    Args:
        xinv, linv, logdet, coef: ``X^-1``, ``L^-1`` (ke, ke, U), ``log|X|`` (U,) and the packed
            ``I - nu X^-1`` (U, ke(ke+1)/2) (:func:`x_inverse`).
        proj, sq: Part statistics ``B^T y`` (>=ke, U, D') and ``y^T y`` (D',) of the part's dims.
        cols: (D_m,) the columns of ``proj`` and ``sq`` of the block's dims.
        n_obs, ke, nu: Number of samples, active basis functions, noise ratio.
        starts, n_c: (T,) first unique candidate of every task; candidates per task C.
        mu_k, mu_rows, inv_delta, mu2, log_delta, w_k: Model arrays of the part's dims
            (see ``InferenceEngine._dims``).
        w_1: (T, K D_m, r) ``W_d`` rows ordered (basis, dim) (only used without ``Z``).
        z: Packed ``Z`` tensors (T, K(K+1)/2, r(r+1)/2), rows ordered as ``coef``'s columns (only with
            ``p_mode`` :data:`P_FROM_Z`).
        unpack: (r, r) index of ``(i, j)`` in the packed layout.
        p_mode: How ``P`` is added: :data:`P_FROM_W` (from ``w_1``), :data:`P_FROM_Z` (one product with
            ``z`` per task) or :data:`P_BY_CALLER` (not here: :func:`add_fused_p`).

    """
    n_u = xinv.shape[2]
    dm = cols.shape[0]
    r = a.shape[0]
    n_t = starts.shape[0]
    m = ke * (ke + 1) // 2
    kd = ke * dm
    const = n_obs * dm * LOG_2PI + dm * (n_obs - ke) * np.log(nu)
    # X^-1 mu_t of every task and unique candidate: rows (t, d), columns (k, u)
    xm = np.dot(np.ascontiguousarray(mu_rows[:, :ke]), xinv.reshape(ke, ke * n_u))
    # X^-1 B^T y per unique candidate: (k, d, u)
    pt = np.empty((ke, dm, n_u))
    for j in range(ke):
        for u in range(n_u):
            for d in range(dm):
                pt[j, d, u] = proj[j, u, cols[d]]
    xp = np.zeros((ke, dm, n_u))
    for k in range(ke):
        for j in range(ke):
            xkj = xinv[k, j]
            for d in range(dm):
                row = xp[k, d]
                pjd = pt[j, d]
                for u in range(n_u):
                    row[u] += xkj[u] * pjd[u]
    xb = np.empty((kd, n_c))
    quad = np.empty(n_c)
    for t in range(n_t):
        u0 = starts[t]
        off = lane0 + t * n_c
        sqd = 0.0
        for d in range(dm):
            sqd += sq[cols[d]] * inv_delta[t, d]
        base = (sqd + nu * mu2[t, ke]) / nu + const + n_obs * log_delta[t]
        quad[:] = 0.0
        for k in range(ke):
            for d in range(dm):
                row = xb[k * dm + d]
                xpr = xp[k, d]
                xmr = xm[t * dm + d]
                pr = pt[k, d]
                mkd = mu_k[t, k, d]
                nm = nu * mkd
                wd = inv_delta[t, d]
                xo = k * n_u + u0
                for c in range(n_c):
                    xh = xpr[u0 + c] + nu * xmr[xo + c]
                    quad[c] += (pr[u0 + c] + nm) * xh * wd
                    row[c] = xh - mkd
        for c in range(n_c):
            total[off + c] += base - quad[c] / nu + dm * logdet[u0 + c]
        a[:, off : off + n_c] += np.dot(w_k[t, :kd].T, xb)
        if p_mode == P_FROM_Z:
            pz = np.dot(coef[u0 : u0 + n_c], z[t, :m])  # (C, npk)
            for c in range(n_c):
                pzc = pz[c]
                for q in range(pz.shape[1]):
                    pq[q, off + c] += pzc[q]
    if p_mode == P_FROM_W:
        v = np.empty((kd, r))
        for t in range(n_t):
            wt = np.ascontiguousarray(w_1[t, :kd])
            s = np.dot(wt.T, wt)
            for c in range(n_c):
                u = starts[t] + c
                p = lane0 + t * n_c + c
                for k in range(ke):
                    for d in range(dm):
                        for i in range(r):
                            v[k * dm + d, i] = 0.0
                        for j in range(k + 1):
                            x = linv[k, j, u]
                            for i in range(r):
                                v[k * dm + d, i] += x * wt[j * dm + d, i]
                vv = np.dot(v.T, v)
                for i in range(r):
                    for j in range(i, r):
                        pq[unpack[i, j], p] += s[i, j] - nu * vv[i, j]


@njit(**_JIT)
def add_fused_p(
    pz: np.ndarray, starts: np.ndarray, u0: int, n_c: int, col0: int, npk: int, lane0: int, pq: np.ndarray
) -> None:
    """Add one block's packed ``P`` of every (task, candidate) pair from a product of the coefficients
    of consecutive unique candidates (rows ``u - u0``) with the ``Z`` tensors of several tasks and
    blocks side by side: ``pz`` (U', sum T r(r+1)/2), the block's task ``t`` in the columns
    ``col0 + t npk .. col0 + (t + 1) npk``, added to the lanes from ``lane0`` of ``pq`` (npk, P')
    (see :func:`part_terms`)."""
    for t in range(starts.shape[0]):
        c0 = col0 + t * npk
        r0 = starts[t] - u0
        off = lane0 + t * n_c
        for c in range(n_c):  # contiguous reads of pz (twice as fast as contiguous writes of pq here)
            src = pz[r0 + c, c0 : c0 + npk]
            for q in range(npk):
                pq[q, off + c] += src[q]


@njit(**_JIT)
def cholesky(a: np.ndarray) -> np.ndarray:
    """Lower Cholesky factor (n, n) of an SPD matrix ``a`` (upper triangle zero; NaN-filled if not SPD)."""
    n = a.shape[0]
    low = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1):
            low[i, j] = a[i, j]
    if not np.isfinite(chol_inplace(low, n)):
        low[:, :] = np.nan
    return low


@njit(**_JIT)
def tri_solve(low: np.ndarray, b: np.ndarray, transpose: bool) -> np.ndarray:
    """Solve ``L x = b`` (``L^T x = b`` with ``transpose``); ``L`` (n, n) lower triangular, ``b`` (n, m)."""
    n, m = b.shape
    x = b.copy()
    if not transpose:
        for i in range(n):
            xi = x[i]
            for k in range(i):
                lik = low[i, k]
                xk = x[k]
                for j in range(m):
                    xi[j] -= lik * xk[j]
            inv = 1.0 / low[i, i]
            for j in range(m):
                xi[j] *= inv
    else:
        for i in range(n - 1, -1, -1):
            xi = x[i]
            for k in range(i + 1, n):
                lki = low[k, i]
                xk = x[k]
                for j in range(m):
                    xi[j] -= lki * xk[j]
            inv = 1.0 / low[i, i]
            for j in range(m):
                xi[j] *= inv
    return x


@njit(**_JIT)
def cho_solve(low: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve ``L L^T x = b`` for the lower Cholesky factor ``L`` (n, n) and ``b`` (n, m)."""
    return tri_solve(low, tri_solve(low, b, False), True)


@njit(**_JIT)
def condition_part(
    bt: np.ndarray,
    y: np.ndarray,
    mean: np.ndarray,
    wf: np.ndarray,
    sd: np.ndarray,
    nu: float,
    q: np.ndarray,
    a: np.ndarray,
    lx: np.ndarray,
    gram: np.ndarray,
    b: np.ndarray,
) -> bool:
    """Add one observation part's terms of the conditioning at one phase (see :func:`condition_block`).

    Args:
        bt: (ke, n) basis values of the part's samples; y: (n, D_m) scaled values.
        mean: (D_m, K) prior mean weights of the part's dims; wf: (ke, D_m r) ``F_d / sqrt(delta_d)``
            rows k; sd: (D_m,) ``sqrt(delta_d)``; nu: noise ratio.
        q, a: (r, r) ``Q`` and (r,) ``a``, updated in place.
        lx, gram, b: Outputs (ke, ke) Cholesky factor of ``X = nu I + B^T B``, ``B^T B`` and
            (ke, D_m) ``b = B^T (y - B mu)``.

    Returns:
        False when ``X`` is not numerically positive definite.
    """
    ke, n = bt.shape
    dm = y.shape[1]
    r = q.shape[0]
    gram[:, :] = np.dot(bt, bt.T)
    by = np.dot(bt, y)
    for k in range(ke):
        for d in range(dm):
            s = by[k, d]
            for j in range(ke):
                s -= gram[k, j] * mean[d, j]
            b[k, d] = s
    for i in range(ke):
        for j in range(i + 1):
            lx[i, j] = gram[i, j]
        for j in range(i + 1, ke):
            lx[i, j] = 0.0
        lx[i, i] += nu
    if not np.isfinite(chol_inplace(lx, ke)):
        return False
    ncol = dm * r
    rhs = np.empty((ke, ncol + dm))
    for k in range(ke):
        for c in range(ncol):
            rhs[k, c] = wf[k, c]
        for d in range(dm):
            rhs[k, ncol + d] = b[k, d] / sd[d]
    sol = cho_solve(lx, rhs)
    wk = wf.reshape(ke * dm, r)
    xw = np.ascontiguousarray(sol[:, :ncol]).reshape(ke * dm, r)
    xb = np.ascontiguousarray(sol[:, ncol:]).reshape(ke * dm)
    q += np.dot(wk.T, wk - nu * xw)
    a += np.dot(wk.T, xb)
    return True


@njit(**_JIT)
def condition_block(
    t_cat: np.ndarray,
    n_off: np.ndarray,
    y_cat: np.ndarray,
    y_off: np.ndarray,
    y_width: np.ndarray,
    pos_cat: np.ndarray,
    dims_cat: np.ndarray,
    p_off: np.ndarray,
    ke_p: np.ndarray,
    inv_dur: float,
    centres: np.ndarray,
    width: float,
    step: np.ndarray,
    mean: np.ndarray,
    diag: np.ndarray,
    factor: np.ndarray,
    nu: float,
    w_post: np.ndarray,
    lq: np.ndarray,
) -> bool:
    """Condition one independent latent block of a task on every observation part at one phase.

    The conditioning of :mod:`ipromp_pin.promp.conditioning` for one block in one call (``P``, ``a``,
    ``Q`` as in :mod:`ipromp_pin.promp.likelihood`): per part, :func:`condition_part`
    (its basis rows from :func:`basis_rows`); then the latent posterior ``N(Q^-1 a, Q^-1)``
    (:func:`latent_posterior`), ``w_post += F Q^-1 a`` and, per part, the observed dims' correction
    ``X^-1 (b_d - G F_d eta)``.

    Args:
        t_cat, n_off: Sample times in [s] of the parts, concatenated; part p is ``n_off[p]:n_off[p+1]``.
        y_cat, y_off, y_width: Scaled values of the parts, each flattened row-major (n_p, y_width[p])
            from ``y_off[p]``.
        pos_cat, dims_cat, p_off: Per part (``p_off[p]:p_off[p+1]``), the columns of its values that
            belong to the block and their model dims.
        ke_p: (P,) active basis functions per part.
        inv_dur: ``1 / (alpha T_norm)`` in [1/s]; centres, width, step: the basis (see :func:`basis_rows`).
        mean, diag, factor: (D, K) mean weights, (D,) diagonal variances and (D, K, r) the block's
            factor columns of the task (all dims).
        nu: Noise ratio.
        w_post: (D, K) weights, updated in place.
        lq: (r, r) output, the lower Cholesky factor of ``Q``.

    Returns:
        False when ``X`` or ``Q`` is not numerically positive definite.
    """
    n_parts = n_off.shape[0] - 1
    n_dims, n_k, r = factor.shape
    q = np.eye(r)
    a = np.zeros(r)
    kmax = 1
    dmax = 1
    for p in range(n_parts):
        kmax = max(kmax, ke_p[p])
        dmax = max(dmax, p_off[p + 1] - p_off[p])
    lxs = np.zeros((n_parts, kmax, kmax))
    grams = np.zeros((n_parts, kmax, kmax))
    bbs = np.zeros((n_parts, kmax, dmax))
    for p in range(n_parts):
        n0 = n_off[p]
        n = n_off[p + 1] - n0
        ke = ke_p[p]
        d0 = p_off[p]
        dm = p_off[p + 1] - d0
        bt = np.ascontiguousarray(basis_rows(t_cat[n0 : n0 + n] * inv_dur, centres, width, step)[:ke])
        ys = np.empty((n, dm))
        yw = y_width[p]
        for j in range(n):
            row = y_off[p] + j * yw
            for d in range(dm):
                ys[j, d] = y_cat[row + pos_cat[d0 + d]]
        md = np.empty((dm, n_k))
        sd = np.empty(dm)
        wf = np.empty((ke, dm * r))
        for d in range(dm):
            dd = dims_cat[d0 + d]
            md[d] = mean[dd]
            sd[d] = np.sqrt(diag[dd])
            for k in range(ke):
                for i in range(r):
                    wf[k, d * r + i] = factor[dd, k, i] / sd[d]
        lx = np.empty((ke, ke))
        gram = np.empty((ke, ke))
        bb = np.empty((ke, dm))
        if not condition_part(bt, ys, md, wf, sd, nu, q, a, lx, gram, bb):
            return False
        lxs[p, :ke, :ke] = lx
        grams[p, :ke, :ke] = gram
        bbs[p, :ke, :dm] = bb
    f_eta = np.zeros((n_dims, n_k))
    if r > 0:
        low, f_eta = latent_posterior(q, a, factor)
        if not np.isfinite(low[0, 0]):
            return False
        lq[:, :] = low
        w_post += f_eta
    for p in range(n_parts):
        ke = ke_p[p]
        d0 = p_off[p]
        dm = p_off[p + 1] - d0
        gram = grams[p, :ke, :ke]
        rhs = np.empty((ke, dm))
        for k in range(ke):
            for d in range(dm):
                s = bbs[p, k, d]
                dd = dims_cat[d0 + d]
                for j in range(ke):
                    s -= gram[k, j] * f_eta[dd, j]
                rhs[k, d] = s
        sol = cho_solve(np.ascontiguousarray(lxs[p, :ke, :ke]), rhs)
        for d in range(dm):
            dd = dims_cat[d0 + d]
            for k in range(ke):
                w_post[dd, k] += sol[k, d]
    return True


@njit(**_JIT)
def channel_values(
    phi: np.ndarray,
    w: np.ndarray,
    scale: np.ndarray,
    offset: np.ndarray,
    log_idx: np.ndarray,
    log_shift: np.ndarray,
) -> np.ndarray:
    """Trajectories (M, D) in original units of weights ``w`` (D, K) at basis values ``phi`` (M, K):
    ``phi w^T`` scaled back by ``scale`` and ``offset`` (D,), then ``exp(.) - log_shift`` on the
    log-scaled channels ``log_idx`` (see ``ChannelScaler.inverse``)."""
    out = np.dot(phi, w.T)
    n_m, n_d = out.shape
    for m in range(n_m):
        for d in range(n_d):
            out[m, d] = out[m, d] * scale[d] + offset[d]
        for i in range(log_idx.shape[0]):
            d = log_idx[i]
            out[m, d] = np.exp(out[m, d]) - log_shift[d]
    return out


@njit(**_JIT)
def latent_posterior(q: np.ndarray, a: np.ndarray, factor: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cholesky factor (r, r) of ``Q`` (NaN if not SPD) and ``F Q^-1 a`` (D, K) for ``factor`` (D, K, r)."""
    r = q.shape[0]
    lq = cholesky(q)
    d, k, _ = factor.shape
    if not np.isfinite(lq[0, 0]):
        return lq, np.zeros((d, k))
    m_eta = cho_solve(lq, a.reshape(r, 1)).reshape(r)
    return lq, np.dot(factor.reshape(d * k, r), m_eta).reshape(d, k)


@njit(**_JIT)
def prediction_cov(
    low: np.ndarray, phi_f: np.ndarray, phi2: np.ndarray, diag: np.ndarray, scale: np.ndarray
) -> np.ndarray:
    """Covariance (M, J, J) of the predicted joints: ``S^T S + phi2 diag`` with ``S = L^-1 phi_f``,
    times the channel scales.

    Args:
        low: (r, r) lower Cholesky factor of ``Q``.
        phi_f: (r, J, M) ``phi(z_m)^T F_j`` of the robot dims.
        phi2: (M,) ``|phi(z_m)|^2``; diag: (J,) diagonal weight variances; scale: (J,) channel scales.
    """
    r, n_j, n_m = phi_f.shape
    s = tri_solve(low, phi_f.reshape(r, n_j * n_m), False).reshape(r, n_j, n_m)
    acc = np.zeros((n_j, n_j, n_m))
    for k in range(r):
        for i in range(n_j):
            si = s[k, i]
            for j in range(i + 1):
                sj = s[k, j]
                aij = acc[i, j]
                for m in range(n_m):
                    aij[m] += si[m] * sj[m]
    cov = np.empty((n_m, n_j, n_j))
    for i in range(n_j):
        for j in range(i + 1):
            f = scale[i] * scale[j]
            aij = acc[i, j]
            for m in range(n_m):
                v = aij[m]
                if i == j:
                    v += phi2[m] * diag[i]
                v *= f
                cov[m, i, j] = v
                cov[m, j, i] = v
    return cov


@njit(**_JIT)
def _vertex(x0: float, x1: float, x2: float, y0: float, y1: float, y2: float) -> float:
    """:func:`ipromp_pin.promp.reference.parabola_vertex` (same arithmetic)."""
    denom = (x0 - x1) * (x0 - x2) * (x1 - x2)
    ca = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / denom
    cb = (x2 * x2 * (y0 - y1) + x1 * x1 * (y2 - y0) + x0 * x0 * (y1 - y2)) / denom
    if not ca < 0.0:
        return x1
    return min(max(-cb / (2.0 * ca), x0), x2)


@njit(**_JIT)
def phase_posterior(
    loglik: np.ndarray, log_prior: np.ndarray, grids: np.ndarray, weights: np.ndarray, nodes: np.ndarray
):
    """Per task: log evidence (T,), normalised log phase posterior (T, C) and continuous MAP phase (T,).

    ``lp = loglik + log_prior``; the evidence is the log-sum-exp of ``lp`` over candidates (rows
    without a possible candidate keep ``lp`` and get ``-inf``); the MAP phase is refined as in
    :func:`ipromp_pin.promp.reference.refine_peak` (same arithmetic; ``weights`` (S, 6) and ``nodes`` (6,) are
    its interpolation weights and stencil).
    """
    n_t, n_c = loglik.shape
    steps = weights.shape[0]
    n_w = nodes.shape[0]
    evidence = np.empty(n_t)
    logpost = np.empty((n_t, n_c))
    alpha = np.empty(n_t)
    fine = np.empty(2 * steps + 1)
    for t in range(n_t):
        lp = logpost[t]
        best = 0
        for c in range(n_c):
            lp[c] = loglik[t, c] + log_prior[t, c]
            if lp[c] > lp[best]:
                best = c
        top = lp[best]
        if np.isfinite(top):
            s = 0.0
            for c in range(n_c):
                s += np.exp(lp[c] - top)
            ev = top + np.log(s)
        else:
            ev = top
        evidence[t] = ev
        g = grids[t]
        i = best
        if (
            i == 0
            or i == n_c - 1
            or not (np.isfinite(lp[i - 1]) and np.isfinite(lp[i]) and np.isfinite(lp[i + 1]))
        ):
            alpha[t] = g[i]
        else:
            inner = i >= 3 and i <= n_c - 4
            if inner:
                for c in range(i - 3, i + 4):
                    if not np.isfinite(lp[c]):
                        inner = False
            if not inner:
                alpha[t] = _vertex(g[i - 1], g[i], g[i + 1], lp[i - 1], lp[i], lp[i + 1])
            else:
                for half in range(2):
                    left = i - 1 + half
                    for j in range(steps):
                        v = 0.0
                        for q in range(n_w):
                            v += weights[j, q] * lp[left + nodes[q]]
                        fine[half * steps + j] = v
                fine[2 * steps] = lp[i + 1]
                h = (g[i + 1] - g[i - 1]) / (2 * steps)
                jb = 0
                for j in range(2 * steps + 1):
                    if fine[j] > fine[jb]:
                        jb = j
                if jb == 0 or jb == 2 * steps:
                    alpha[t] = g[i - 1] + jb * h
                else:
                    x0 = g[i - 1] + (jb - 1) * h
                    alpha[t] = _vertex(x0, x0 + h, x0 + 2.0 * h, fine[jb - 1], fine[jb], fine[jb + 1])
        if np.isfinite(ev):
            for c in range(n_c):
                lp[c] -= ev
    return evidence, logpost, alpha


@njit(**_JIT)
def task_posterior(log_prior: np.ndarray, evidence: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Normalised log task posterior (T,), the posterior (T,) and the most probable task from the
    log task prior and the log evidence (T,); the first two are NaN when every task is impossible."""
    n_t = evidence.shape[0]
    joint = log_prior + evidence
    best = 0
    for t in range(n_t):
        if joint[t] > joint[best]:
            best = t
    top = joint[best]
    total = top
    if np.isfinite(top):
        s = 0.0
        for t in range(n_t):
            s += np.exp(joint[t] - top)
        total = top + np.log(s)
    if not np.isfinite(total):
        nan = np.full(n_t, np.nan)
        return nan, nan.copy(), best
    log_post = joint - total
    return log_post, np.exp(log_post), best


@njit(**_JIT)
def recognition(
    loglik: np.ndarray,
    log_prior: np.ndarray,
    grids: np.ndarray,
    weights: np.ndarray,
    nodes: np.ndarray,
    task_log_prior: np.ndarray,
):
    """:func:`phase_posterior` then :func:`task_posterior` in one call: log evidence (T,), log phase
    posterior (T, C), MAP phases (T,), whether every evidence is finite, log task posterior (T,), task
    posterior (T,), best task."""
    evidence, logpost, alpha = phase_posterior(loglik, log_prior, grids, weights, nodes)
    finite = True
    for t in range(evidence.shape[0]):
        finite = finite and np.isfinite(evidence[t])
    log_post, post, best = task_posterior(task_log_prior, evidence)
    return evidence, logpost, alpha, finite, log_post, post, best


@njit(**_JIT)
def head_posterior(
    values: np.ndarray,
    generative: np.ndarray,
    posterior: np.ndarray,
    alpha: np.ndarray,
    t_scale: float,
    ratios: np.ndarray,
    w: np.ndarray,
    b: np.ndarray,
    clip: float,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Task posterior of the recognition head (:class:`ipromp_pin.promp.head.RecognitionHead`): the
    normalised log posterior (T,), the posterior (T,) and the most probable task.

    Features ``x`` = the window ``values`` (3 D_o,) then the generative log posterior ``generative``
    (T,) clipped below at ``clip``; logits ``w[i] x + b[i]`` (``w`` (R, T, F), ``b`` (R, T))
    interpolated linearly between the ratios ``ratios`` (R,) around the observed fraction
    ``t_scale sum_t posterior_t / alpha_t`` (:func:`ipromp_pin.promp.head_features.observed_fraction`: the
    generative posterior (T,), MAP phases (T,) and ``t_last / T_norm``), constant outside them;
    tasks with a non-finite generative log posterior stay impossible."""
    n_r = ratios.shape[0]
    n_t = generative.shape[0]
    fraction = 0.0
    for t in range(posterior.shape[0]):
        fraction += posterior[t] * (1.0 / alpha[t])
    fraction = t_scale * fraction
    i = 0
    wt = 0.0
    if fraction > ratios[0]:
        while i + 1 < n_r and ratios[i + 1] <= fraction:
            i += 1
        if i + 1 < n_r:
            wt = (fraction - ratios[i]) / (ratios[i + 1] - ratios[i])
    z = np.empty(n_t)
    for t in range(n_t):
        z[t] = _head_logit(w[i, t], b[i, t], values, generative, clip)
        if wt > 0.0:
            z[t] = (1.0 - wt) * z[t] + wt * _head_logit(w[i + 1, t], b[i + 1, t], values, generative, clip)
        if not np.isfinite(generative[t]):
            z[t] = -np.inf
    top = z.max()
    s = 0.0
    for t in range(n_t):
        z[t] -= top
        s += np.exp(z[t])
    log_post = z - np.log(s)
    best = 0
    for t in range(n_t):
        if log_post[t] > log_post[best]:
            best = t
    return log_post, np.exp(log_post), best


@njit(**_JIT)
def _head_logit(w: np.ndarray, b: float, values: np.ndarray, generative: np.ndarray, clip: float) -> float:
    """One task's logit ``w x + b`` of :func:`head_posterior` (``w`` (F,))."""
    n_v = values.shape[0]
    acc = 0.0
    for f in range(n_v):
        acc += w[f] * values[f]
    for t in range(generative.shape[0]):
        acc += w[n_v + t] * max(generative[t], clip)
    return acc + b


@njit(**_JIT)
def add_sample(gram: np.ndarray, proj: np.ndarray, phi: np.ndarray, y: np.ndarray) -> None:
    """Add one sample to running statistics: ``gram`` (K, K, U) ``+= phi phi^T`` (lower triangle only:
    :func:`x_inverse` reads no other entry) and ``proj`` (K, U, D) ``+= phi y^T`` for basis values
    ``phi`` (K, U) and scaled values ``y`` (D,); an empty ``gram`` (K, 0, U) or ``proj`` (K, U, 0) is
    left out."""
    n_k, n_u = phi.shape
    for k in range(gram.shape[0]):
        pk = phi[k]
        for m in range(min(k + 1, gram.shape[1])):
            pm = phi[m]
            g = gram[k, m]
            for u in range(n_u):
                g[u] += pk[u] * pm[u]
    for k in range(proj.shape[0]):
        for u in range(n_u):
            p = phi[k, u]
            for d in range(proj.shape[2]):
                proj[k, u, d] += p * y[d]


@njit(**_JIT)
def scale_samples(
    raw: np.ndarray,
    log_idx: np.ndarray,
    log_c: np.ndarray,
    offset: np.ndarray,
    scale: np.ndarray,
    out: np.ndarray,
) -> bool:
    """Scaled values (into ``out`` (n, D)) of raw samples ``raw`` (n, D), as ``ChannelScaler.transform``:
    ``log(max(y, 0) + c)`` on the dims ``log_idx`` with shifts ``log_c``, then ``(y - offset) / scale``
    (D,). Returns whether every raw value is finite and every scaled one at most
    :data:`MAX_SCALED_MAGNITUDE` (:data:`MAX_LOG_SCALED_MAGNITUDE` for log dims) in magnitude."""
    n, n_d = raw.shape
    finite = True
    for j in range(n):
        rj = raw[j]
        oj = out[j]
        for d in range(n_d):
            v = rj[d]
            finite = finite and np.isfinite(v)
            oj[d] = v
        for i in range(log_idx.shape[0]):
            d = log_idx[i]
            finite = finite and oj[d] >= -MAX_SCALED_MAGNITUDE * log_c[i]  # (a log is blind below 0)
            oj[d] = np.log(max(oj[d], 0.0) + log_c[i])
        for d in range(n_d):
            oj[d] = (oj[d] - offset[d]) / scale[d]
            finite = finite and abs(oj[d]) <= MAX_SCALED_MAGNITUDE
        for i in range(log_idx.shape[0]):
            finite = finite and abs(oj[log_idx[i]]) <= MAX_LOG_SCALED_MAGNITUDE
    return finite


@njit(**_JIT)
def stream_sample(
    t_s: float,
    inv_dur: np.ndarray,
    centres: np.ndarray,
    width: float,
    step: np.ndarray,
    y: np.ndarray,
    log_idx: np.ndarray,
    log_c: np.ndarray,
    offset: np.ndarray,
    scale: np.ndarray,
    gram: np.ndarray,
    proj: np.ndarray,
    sq: np.ndarray,
    window: np.ndarray,
    w_sum: np.ndarray,
    w_count: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, bool]:
    """Add one sample with every observed dim to the running statistics of a stream.

    Scales the raw values ``y`` (D,) as ``ChannelScaler.transform`` (``log(max(y, 0) + c)`` on the
    dims ``log_idx`` with shifts ``log_c``, then ``(y - offset) / scale``), computes the basis values
    (K, U) at the phases ``t_s inv_dur`` (:func:`basis_rows`), adds the sample to ``gram``
    (K, K, U), ``proj`` (K, U, D) and ``sq`` (D,) (:func:`add_sample`) and to the window summary
    ``window`` (3, D) (rows: first, mean and last value) with its running sums ``w_sum`` and counts
    ``w_count`` (D,). Returns the basis values, the scaled values and whether every raw value is
    finite and plausible (:func:`scale_samples`; if not, the statistics are left unchanged).
    """
    ys: np.ndarray = np.empty((1, y.shape[0]))
    if not scale_samples(y.reshape(1, -1), log_idx, log_c, offset, scale, ys):
        return np.empty((0, 0)), ys.reshape(-1), False
    ys = ys.reshape(-1)
    for d in range(ys.shape[0]):
        v = ys[d]
        sq[d] += v * v
        if w_count[d] == 0.0:
            window[0, d] = v
        w_sum[d] += v
        w_count[d] += 1.0
        window[1, d] = w_sum[d] / w_count[d]
        window[2, d] = v
    phi = basis_rows(t_s * inv_dur, centres, width, step)
    add_sample(gram, proj, phi, ys)
    return phi, ys, True


@njit(**_JIT_FMA)
def sherman_morrison(
    xinv: np.ndarray, logdet: np.ndarray, phi: np.ndarray
) -> tuple[np.ndarray, np.ndarray, bool]:
    """Add one sample with basis values ``phi`` (K, U) to ``X = nu I + B^T B`` of every unique candidate:
    with ``g = X^-1 phi`` and ``s = 1 + phi^T g``, ``X^-1 -= g g^T / s`` and ``log|X| += log s``
    (``xinv`` (ke, ke, U) and ``logdet`` (U,) updated in place, unless some ``s <= 0``, i.e. ``X``
    lost positive definiteness). Returns ``g`` (ke, U), ``s`` (U,) and whether every ``s > 0``."""
    ke = xinv.shape[0]
    n_u = xinv.shape[2]
    g = np.zeros((ke, n_u))
    for k in range(ke):
        gk = g[k]
        for j in range(ke):
            xkj = xinv[k, j]
            pj = phi[j]
            for u in range(n_u):
                gk[u] += xkj[u] * pj[u]
    s = np.ones(n_u)
    for k in range(ke):
        gk = g[k]
        pk = phi[k]
        for u in range(n_u):
            s[u] += pk[u] * gk[u]
    for u in range(n_u):
        if not s[u] > 0.0:
            return g, s, False
    gs = np.empty((ke, n_u))  # g / s
    for u in range(n_u):
        logdet[u] += np.log(s[u])
    for k in range(ke):
        for u in range(n_u):
            gs[k, u] = g[k, u] / s[u]
    for k in range(ke):
        gk = gs[k]
        for j in range(k + 1):
            xkj = xinv[k, j]
            gj = g[j]
            for u in range(n_u):
                xkj[u] -= gk[u] * gj[u]
        for j in range(k):
            xinv[j, k] = xinv[k, j]
    return g, s, True


@njit(**_JIT)
def finish_soa(
    pq: np.ndarray,
    a: np.ndarray,
    total: np.ndarray,
    unpack: np.ndarray,
    alphas: np.ndarray,
    t_norm: float,
    t_last: float,
    loglik: np.ndarray,
    add: bool,
    n_blocks: int,
) -> bool:
    """Log likelihood (into ``loglik`` (T, C), added to it with ``add``) from ``Q = I + P`` (packed
    ``pq`` (r(r+1)/2, P')), ``a`` (r, P') and the other terms ``total`` (P',), pairs (task,
    candidate) task-major and innermost; ``n_blocks`` independent blocks of equal rank side by side
    (lanes ``b P' / n_blocks + p``), whose log likelihoods add up.

    ``log|Q|`` and ``a^T Q^-1 a`` come from one Cholesky factorisation of ``Q`` per pair
    (vectorised over pairs); candidates shorter than the observation get ``-inf``. ``P' >= T C``:
    lanes beyond ``T C`` are padding (zeros, so ``Q = I``) that keeps the pair loops in whole
    vector widths. Returns False when a ``Q`` was not numerically positive definite.
    """
    r, n_p = a.shape
    n_c = alphas.shape[1]
    # Cholesky factor of Q, rows packed one after the other: entry (i, j <= i) at row i (i + 1) / 2 + j
    lq = np.empty((r * (r + 1) // 2, n_p))
    logdet = np.zeros(n_p)
    if not chol_packed(pq, unpack, 1.0, lq, r, logdet):
        return False
    v = np.empty((r, n_p))
    vv = np.zeros(n_p)
    for i in range(r):
        ri = i * (i + 1) // 2
        vi = v[i]
        vi[:] = a[i]
        for k in range(i):
            lik = lq[ri + k]
            vk = v[k]
            for c in range(n_p):
                vi[c] -= lik[c] * vk[c]
        lii = lq[ri + i]
        for c in range(n_p):
            vi[c] /= lii[c]
            vv[c] += vi[c] * vi[c]
    stride = n_p // n_blocks  # lanes per block
    for p in range(alphas.shape[0] * n_c):
        t = p // n_c
        c = p - t * n_c
        if t_last > alphas[t, c] * t_norm * (1.0 + 1e-12):
            loglik[t, c] = -np.inf
            continue
        pair = 0.0
        for b in range(n_blocks):
            lane = b * stride + p
            pair += -0.5 * (total[lane] + logdet[lane] - vv[lane])
        if add:
            loglik[t, c] += pair
        else:
            loglik[t, c] = pair
    return True


@njit(**_JIT_FMA)
def stream_group(
    g: np.ndarray,
    s: np.ndarray,
    y: np.ndarray,
    proj: np.ndarray,
    w_t: np.ndarray,
    dims: np.ndarray,
    dim_off: np.ndarray,
    col_off: np.ndarray,
    nu: float,
    starts: np.ndarray,
    n_c: int,
    inv_delta: np.ndarray,
    log_delta: np.ndarray,
    ia: np.ndarray,
    ib: np.ndarray,
    total: np.ndarray,
    a: np.ndarray,
    pq: np.ndarray,
    unpack: np.ndarray,
    alphas: np.ndarray,
    t_norm: float,
    t_last: float,
    loglik: np.ndarray,
    add: bool,
    finish: bool,
) -> bool:
    """Add one sample (the dims ``dims`` of one observation part, same active basis functions) to the
    terms of one lane group's blocks (:func:`part_terms`, block ``b`` in the lanes from ``b P'``),
    after :func:`sherman_morrison` of the part's ``X``, and with ``finish`` return their log
    likelihood as :func:`finish_soa` (into ``loglik``, added to it with ``add``; False when a ``Q`` is
    not numerically positive definite; without ``finish`` the terms are only updated, True).

    Per pair, with ``h_d = B^T y_d + nu mu_d`` (after the sample, ``proj`` already updated) and
    ``c_d = y_d - g^T h_d / s``: ``X^-1 h_d += c_d g``,
    ``h_d^T X^-1 h_d += 2 y_d g^T h_d - (s - 1) y_d^2 - (g^T h_d)^2 / s``, ``a += sum_d c_d W_d^T g /
    sqrt(delta_d)`` and ``P += nu / s sum_d (W_d^T g)(W_d^T g)^T``. ``W_d^T g`` and ``nu mu_d^T g``
    of every block, task, dim and unique candidate are one matrix product; the updates of ``a`` and
    ``P`` then run over all (task, candidate) pairs at once.

    Args:
        g, s: (ke, U) ``X^-1 phi`` (before the update) and (U,) ``1 + phi^T g``.
        y: (D,) the sample's scaled values (all observed dims).
        proj: (K, U, D) ``B^T y`` of all observed dims, including the new sample.
        w_t: (M, ke) the first ``ke`` basis rows of block ``b``'s ``W_d`` in the rows
            ``col_off[b] .. col_off[b + 1]`` ordered (latent, dim, task), then of ``nu mu_d`` of the
            dims ``dims`` from row ``col_off[-1]`` ordered (dim, task).
        dims, dim_off: (D_g,) the observed dims of the group's blocks, block ``b``'s at
            ``dim_off[b] .. dim_off[b + 1]``.
        col_off: (n_blocks + 1,) see ``w_t``.
        starts, n_c: (T,) first unique candidate of every task; candidates per task C.
        inv_delta, log_delta: (T, D_g) ``1 / delta_d`` of the dims ``dims``; (n_blocks, T)
            ``sum_d log delta_d`` of each block.
        ia, ib: Row and column of each packed entry of ``P``.
        total, a, pq: (B P',), (r, B P') and packed ``P`` (r(r+1)/2, B P'), pairs ordered (task,
            candidate), innermost; updated in place.
        unpack, alphas, t_norm, t_last, loglik, add: As :func:`finish_soa`.
        finish: Whether to factorise ``Q`` and write the log likelihood (the last part to receive
            the sample; the parts before it only add their terms).
    """
    ke = g.shape[0]
    n_u = g.shape[1]
    n_b = dim_off.shape[0] - 1
    dg = dims.shape[0]
    n_t = starts.shape[0]
    r = a.shape[0]
    npk = ia.shape[0]
    n_p = n_t * n_c
    stride = total.shape[0] // n_b
    # g^T B^T y_d per unique candidate (shared by the tasks): (U, D_g)
    gp = np.zeros((n_u, dg))
    for k in range(ke):
        for u in range(n_u):
            gku = g[k, u]
            for d in range(dg):
                gp[u, d] += gku * proj[k, u, dims[d]]
    # W_d^T g and nu mu_d^T g of every block, (latent, dim, task) and unique candidate: (M, U)
    wg = np.dot(w_t, g)
    mu0 = col_off[n_b]
    same = n_u == n_c
    for t in range(n_t):
        same = same and starts[t] == 0
    log_s = np.log(s)
    inv_s = 1.0 / s
    f = np.empty(n_p)
    for t in range(n_t):
        for c in range(n_c):
            f[t * n_c + c] = nu * inv_s[starts[t] + c]
    for b in range(n_b):
        d0 = dim_off[b]
        dm = dim_off[b + 1] - d0
        lane0 = b * stride
        c0 = col_off[b]
        if same:  # every task has every unique candidate: rows (latent, dim, task) are ordered by pair
            v = wg[c0 : c0 + r * dm * n_t].reshape(r, dm, n_p)
        else:  # W_d^T g per pair
            v = np.empty((r, dm, n_p))
            for i in range(r):
                for d in range(dm):
                    for t in range(n_t):
                        row = c0 + (i * dm + d) * n_t + t
                        u0 = starts[t]
                        for c in range(n_c):
                            v[i, d, t * n_c + c] = wg[row, u0 + c]
        ch = np.empty((dm, n_p))  # c_d / sqrt(delta_d) per pair
        step = dm * (LOG_2PI + np.log(nu))
        for t in range(n_t):
            u0 = starts[t]
            off = lane0 + t * n_c
            base = step + log_delta[b, t]
            for c in range(n_c):
                total[off + c] += base + dm * log_s[u0 + c]
            for d in range(dm):
                yd = y[dims[d0 + d]]
                wd = inv_delta[t, d0 + d]
                sdi = np.sqrt(wd)
                gpd = gp[:, d0 + d]
                gmu = wg[mu0 + (d0 + d) * n_t + t]
                chd = ch[d, t * n_c : (t + 1) * n_c]
                for c in range(n_c):
                    u = u0 + c
                    gh = gpd[u] + gmu[u]  # g^T h_d = g^T B^T y_d + nu g^T mu_d
                    ghs = gh * inv_s[u]
                    dq = 2.0 * yd * gh - (s[u] - 1.0) * yd * yd - gh * ghs
                    total[off + c] += wd * (yd * yd - dq) / nu
                    chd[c] = (yd - ghs) * sdi
        fv = np.empty((r, dm, n_p))  # f v, formed in the same pass over v as the update of a
        for i in range(r):
            ai = a[i, lane0 : lane0 + n_p]
            for d in range(dm):
                vid = v[i, d]
                chd = ch[d]
                fvid = fv[i, d]
                for p in range(n_p):
                    ai[p] += chd[p] * vid[p]
                    fvid[p] = f[p] * vid[p]
        for q in range(npk):
            row = pq[q, lane0 : lane0 + n_p]
            fi = fv[ia[q]]
            vj = v[ib[q]]
            d = 0
            while d + 4 <= dm:  # four dims per pass over the pairs (same order of operations)
                f0, f1, f2, f3 = fi[d], fi[d + 1], fi[d + 2], fi[d + 3]
                v0, v1, v2, v3 = vj[d], vj[d + 1], vj[d + 2], vj[d + 3]
                for p in range(n_p):
                    row[p] = (((row[p] + f0[p] * v0[p]) + f1[p] * v1[p]) + f2[p] * v2[p]) + f3[p] * v3[p]
                d += 4
            for dd in range(d, dm):
                fid = fi[dd]
                vjd = vj[dd]
                for p in range(n_p):
                    row[p] += fid[p] * vjd[p]
    if not finish:
        return True
    return finish_soa(pq, a, total, unpack, alphas, t_norm, t_last, loglik, add, n_b)


@njit(**_JIT)
def basis_rows(z: np.ndarray, centres: np.ndarray, width: float, step: np.ndarray) -> np.ndarray:
    """Gaussian basis values (K, U) at phases ``z`` (U,): the running product of
    :meth:`ipromp_pin.promp.basis.GaussianBasis.values_prefix_t` (``step`` (K-1,) its step factors),
    one basis function at a time over all phases; exact exponentials for a phase where ``phi_0``
    could underflow."""
    n_k = centres.shape[0]
    n_u = z.shape[0]
    inv_h2 = 1.0 / (width * width)
    spacing = centres[1] - centres[0]
    out = np.empty((n_k, n_u))
    q = np.empty(n_u)
    exact = False
    for u in range(n_u):
        d0 = z[u] - centres[0]
        exact = exact or 0.5 * d0 * d0 * inv_h2 > 650.0
        out[0, u] = np.exp(-0.5 * inv_h2 * d0 * d0)
        q[u] = np.exp(z[u] * (spacing * inv_h2))
    for k in range(1, n_k):
        sk = step[k - 1]
        prev = out[k - 1]
        row = out[k]
        for u in range(n_u):
            row[u] = prev[u] * (q[u] * sk)
    if exact:
        for u in range(n_u):
            d0 = z[u] - centres[0]
            if 0.5 * d0 * d0 * inv_h2 > 650.0:
                for k in range(n_k):
                    d = (z[u] - centres[k]) / width
                    out[k, u] = np.exp(-0.5 * d * d)
    return out


@njit(**_JIT)
def readout_update(
    mean: np.ndarray,
    sd: np.ndarray,
    factor: np.ndarray,
    base: np.ndarray,
    extra: np.ndarray,
    extra_u: np.ndarray,
    extra_s: np.ndarray,
    phi: np.ndarray,
    phi_f: np.ndarray,
    scale: np.ndarray,
    offset: np.ndarray,
    row: np.ndarray,
    readout: np.ndarray,
    values: np.ndarray,
    cov: np.ndarray,
) -> tuple[bool, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Condition the robot weights ``w = mean + sd xi + factor eta`` (latent precision ``Lambda``) on
    ``values = readout q(z) + e``, ``e ~ N(0, cov)`` (see
    :meth:`ipromp_pin.promp.weight_posterior.RobotWeightPosterior.readout_update`).

    ``Lambda = blockdiag(I, L L^T) + E^T E``: ``base`` (n_b, n_b) the lower factor ``L`` of its last
    ``n_b`` latent coordinates (``Q``'s, or the whole precision after via-points), pending rows ``E``
    ``extra`` (m_e, n_u) with ``U = blockdiag(I, L L^T)^-1 E^T`` ``extra_u`` (n_u, m_e) and the lower
    factor ``extra_s`` of ``I + E U`` (Woodbury identity). ``mean`` (J, K), ``sd`` (J,), ``factor``
    (J, K, r), ``phi`` (M, K) and ``phi_f`` (r, J, M) the basis at the prediction's phases and times
    the factor, ``scale``, ``offset`` (J,), ``row`` (K,), ``readout`` (m, J), ``values`` (m,), ``cov``
    (m, m).

    Returns whether ``cov`` and the update were numerically positive definite, the whitened rows
    ``V`` (m, n_u), the change of the weights' mean (J, K), of the mean joint angles (M, J) and the
    decrease of their covariance (M, J, J)."""
    nj, k, r = factor.shape
    jk = nj * k
    n_u = jk + r
    b0 = n_u - base.shape[0]
    m = readout.shape[0]
    n_m = phi.shape[0]
    v = np.zeros((m, n_u))
    dw = np.zeros((nj, k))
    d_mean = np.zeros((n_m, nj))
    d_cov = np.zeros((n_m, nj, nj))
    lc = cholesky(cov)
    if not np.isfinite(lc[0, 0]):
        return False, v, dw, d_mean, d_cov
    a_s = np.empty((m, nj))
    for i in range(m):
        for j in range(nj):
            a_s[i, j] = readout[i, j] * scale[j]
    a_w = tri_solve(lc, a_s, False)  # whitened read-out of the scaled joints (m, J)
    fr = np.zeros((nj, r))  # the factor's rows at ``row``
    for j in range(nj):
        for kk in range(k):
            rk = row[kk]
            for q in range(r):
                fr[j, q] += rk * factor[j, kk, q]
    for i in range(m):
        for j in range(nj):
            c = a_w[i, j] * sd[j]
            for kk in range(k):
                v[i, j * k + kk] = c * row[kk]
        for q in range(r):
            acc = 0.0
            for j in range(nj):
                acc += a_w[i, j] * fr[j, q]
            v[i, jk + q] = acc
    res = np.empty((m, 1))
    q_end = np.empty(nj)
    for j in range(nj):
        acc = 0.0
        for kk in range(k):
            acc += mean[j, kk] * row[kk]
        q_end[j] = acc * scale[j] + offset[j]
    for i in range(m):
        acc = 0.0
        for j in range(nj):
            acc += readout[i, j] * q_end[j]
        res[i, 0] = values[i] - acc
    resid = tri_solve(lc, res, False)
    u = np.ascontiguousarray(v.T)  # Lambda^-1 V^T (n_u, m)
    if base.shape[0]:
        u[b0:] = cho_solve(base, u[b0:])
    if extra.shape[0]:
        u -= np.dot(extra_u, cho_solve(extra_s, np.dot(extra, u)))
    s = np.dot(v, u)
    for i in range(m):
        s[i, i] += 1.0
    ls = cholesky(s)
    if not np.isfinite(ls[0, 0]):
        return False, v, dw, d_mean, d_cov
    du = np.dot(u, cho_solve(ls, resid))  # (n_u, 1)
    for j in range(nj):
        for kk in range(k):
            acc = du[j * k + kk, 0] * sd[j]
            for q in range(r):
                acc += factor[j, kk, q] * du[jk + q, 0]
            dw[j, kk] = acc
    for p in range(n_m):
        for j in range(nj):
            acc = 0.0
            for kk in range(k):
                acc += phi[p, kk] * dw[j, kk]
            d_mean[p, j] = acc * scale[j]
    # cross-covariance of the trajectory's joints with the whitened read-outs, (M, J m) and (J M, m)
    u_w = np.empty((k, nj * m))
    for j in range(nj):
        for kk in range(k):
            for i in range(m):
                u_w[kk, j * m + i] = sd[j] * u[j * k + kk, i]
    cross = np.dot(phi, u_w)
    if r:
        cross_f = np.dot(np.ascontiguousarray(phi_f.reshape(r, nj * n_m).T), np.ascontiguousarray(u[jk:]))
    else:
        cross_f = np.zeros((nj * n_m, m))
    dp = np.empty((nj, m))
    for p in range(n_m):
        for j in range(nj):
            for i in range(m):  # forward substitution with the factor of S
                acc = (cross[p, j * m + i] + cross_f[j * n_m + p, i]) * scale[j]
                for ll in range(i):
                    acc -= ls[i, ll] * dp[j, ll]
                dp[j, i] = acc / ls[i, i]
        for a in range(nj):
            for b in range(a + 1):
                acc = 0.0
                for i in range(m):
                    acc += dp[a, i] * dp[b, i]
                d_cov[p, a, b] = acc
                d_cov[p, b, a] = acc
    return True, v, dw, d_mean, d_cov
