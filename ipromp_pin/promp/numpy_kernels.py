"""The inference kernels in plain numpy: what a process runs while the numba kernels are not compiled.

Same functions, arguments and results as the numba kernels of fitting and prediction
(:mod:`ipromp_pin.promp._kernels`; the equations are those of :mod:`ipromp_pin.promp.likelihood` and
:mod:`ipromp_pin.promp.conditioning`), written as batched numpy / LAPACK operations instead of
fused loops: the same arithmetic up to the order of summation, so results agree to rounding (the
tests hold both to 1e-9 of each other and of the textbook reference). Slower per call than the
compiled kernels on large problems, but with nothing to compile or load, which is what matters for
a short run on a fresh install (:func:`ipromp_pin.promp.compiled.kernels` chooses).

The streaming kernels (``stream_sample``, ``sherman_morrison``, ``stream_group``, ``add_sample``)
have no numpy version: asking this module for one returns the compiled kernel (compiling it if
needed).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_triangular

from .head_features import head_features, interpolation
from .sample_bounds import MAX_LOG_SCALED_MAGNITUDE, MAX_SCALED_MAGNITUDE

LOG_2PI = float(np.log(2.0 * np.pi))

P_FROM_W = 0
""":func:`part_terms` forms ``P`` from the scaled factors (no ``Z`` tensor)."""
P_FROM_Z = 1
""":func:`part_terms` forms ``P`` with one product with the ``Z`` tensor per task."""
P_BY_CALLER = 2
""":func:`part_terms` leaves ``P`` to the caller (one product for all tasks, :func:`add_fused_p`)."""

_STREAMING = ("stream_sample", "sherman_morrison", "stream_group", "add_sample")


def __getattr__(name: str):
    """The compiled streaming kernels (no numpy version of them)."""
    if name in _STREAMING:
        from . import _kernels  # deferred: numba is heavy and only streaming needs it here

        return getattr(_kernels, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _running_basis(
    z: np.ndarray, centres: np.ndarray, width: float, step: np.ndarray, n_k: int
) -> np.ndarray:
    """Basis values (n_k, ...) at phases ``z`` (...) by the running product of ``basis_rows``."""
    inv_h2 = 1.0 / (width * width)
    spacing = centres[1] - centres[0]
    d0 = z - centres[0]
    first = np.exp(-0.5 * inv_h2 * d0 * d0)
    q = np.exp(z * (spacing * inv_h2))
    factors = np.empty((n_k, *np.shape(z)))
    factors[0] = first
    if n_k > 1:
        factors[1:] = q[None] * step[: n_k - 1].reshape((-1,) + (1,) * np.ndim(z))
    return np.cumprod(factors, axis=0)  # left to right: the kernel's order of products


def _exact_basis(z: np.ndarray, centres: np.ndarray, width: float, n_k: int) -> np.ndarray:
    d = (z[None] - centres[:n_k].reshape((-1,) + (1,) * np.ndim(z))) / width
    return np.exp(-0.5 * d * d)


def basis_rows(z: np.ndarray, centres: np.ndarray, width: float, step: np.ndarray) -> np.ndarray:
    """Gaussian basis values (K, U) at phases ``z`` (U,) (as the compiled ``basis_rows``)."""
    z = np.asarray(z, dtype=float)
    n_k = centres.shape[0]
    out = _running_basis(z, centres, width, step, n_k)
    d0 = z - centres[0]
    far = 0.5 * d0 * d0 / (width * width) > 650.0
    if np.any(far):
        out[:, far] = _exact_basis(z[far], centres, width, n_k)
    return out


def part_stats(t, inv_dur, centres, width, step, pair_step, overlap, ke, y):
    """``B^T B`` (ke, ke, U), ``B^T y`` (ke, U, D_m) and ``y^T y`` (D_m,) (see the compiled kernel)."""
    n = t.shape[0]
    inv_h2 = 1.0 / (width * width)
    z = t[:, None] * inv_dur[None, :]  # (n, U)
    far = float(np.max(np.abs(z - centres[0]))) ** 2 * inv_h2
    exact = ke < 3 or 0.5 * far > 650.0
    hankel = not exact and far <= 650.0
    if exact:
        b = _exact_basis(z, centres, width, ke)  # (ke, n, U)
    else:
        b = _running_basis(z, centres, width, step, ke)
    if hankel:
        spacing = centres[1] - centres[0]
        q = np.exp(z * (spacing * inv_h2))
        ns = 2 * ke - 1
        factors = np.empty((ns, *z.shape))
        factors[0] = b[0] * b[0]
        factors[1:] = q[None] * pair_step[: ns - 1, None, None]
        sums = np.cumprod(factors, axis=0).sum(axis=1)  # (ns, U)
        k, m = np.indices((ke, ke))
        gram = overlap[np.abs(k - m)][:, :, None] * sums[k + m]
    else:
        gram = np.einsum("knu,mnu->kmu", b, b)
    bn = np.ascontiguousarray(b.transpose(1, 0, 2)).reshape(n, -1)  # (n, ke U)
    proj = (bn.T @ y).reshape(ke, -1, y.shape[1])
    return np.ascontiguousarray(gram), proj, np.sum(y * y, axis=0)


def _lower_full(gram: np.ndarray, ke: int) -> np.ndarray:
    """(U, ke, ke) symmetric matrices from the lower triangles of ``gram[:ke, :ke]`` (ke', ke', U)."""
    g = np.moveaxis(gram[:ke, :ke], 2, 0)
    low = np.tril(g)
    return low + np.swapaxes(np.tril(g, -1), 1, 2)


def _chol(a: np.ndarray) -> np.ndarray | None:
    """Batched lower Cholesky factors, or None when a matrix is not numerically positive definite."""
    try:
        return np.linalg.cholesky(a)
    except np.linalg.LinAlgError:
        return None


def x_inverse(gram, ke, nu, xinv, linv, coef):
    """``X^-1`` and ``L^-1`` (into ``xinv``, ``linv`` (ke, ke, U)), ``log|X|`` (U,) and the packed
    ``I - nu X^-1`` (into ``coef`` (U, ke(ke+1)/2)) of ``X = nu I + gram`` (see the compiled kernel)."""
    n_u = gram.shape[2]
    x = _lower_full(gram, ke) + nu * np.eye(ke)
    low = _chol(x)
    if low is None:
        return np.full(n_u, np.nan)
    logdet = 2.0 * np.sum(np.log(np.diagonal(low, axis1=1, axis2=2)), axis=1)
    li = np.tril(np.linalg.inv(low))  # (U, ke, ke)
    xi = np.swapaxes(li, 1, 2) @ li  # X^-1 = L^-T L^-1
    linv[...] = np.moveaxis(li, 0, 2)
    xinv[...] = np.moveaxis(xi, 0, 2)
    ll, kk = _packed_upper(ke)
    coef[...] = (kk == ll).astype(float)[None, :] - nu * xi[:, kk, ll]
    return logdet


def _packed_upper(n: int) -> tuple[np.ndarray, np.ndarray]:
    """(l, k) of the packed upper triangle, ordered by ``l`` then ``k <= l``."""
    ll = np.concatenate([np.full(i + 1, i) for i in range(n)]).astype(np.int64)
    kk = np.concatenate([np.arange(i + 1) for i in range(n)]).astype(np.int64)
    return ll, kk


def part_terms(
    xinv, linv, logdet, coef, proj, sq, cols, n_obs, ke, nu, starts, n_c, mu_k, mu_rows, inv_delta, mu2,
    log_delta, w_k, w_1, z, unpack, p_mode, lane0, total, a, pq,
):  # fmt: skip
    """Add one observation part's terms to ``total``, ``a`` and packed ``P`` (see the compiled kernel)."""
    n_u = xinv.shape[2]
    dm = cols.shape[0]
    r = a.shape[0]
    m = ke * (ke + 1) // 2
    kd = ke * dm
    const = n_obs * dm * LOG_2PI + dm * (n_obs - ke) * np.log(nu)
    xm = (mu_rows[:, :ke] @ xinv.reshape(ke, ke * n_u)).reshape(-1, dm, ke, n_u)  # (T, D_m, ke, U)
    pt = np.ascontiguousarray(proj[:ke][:, :, cols].transpose(0, 2, 1))  # (ke, D_m, U)
    xp = np.einsum("kju,jdu->kdu", xinv, pt)
    for t in range(starts.shape[0]):
        u0 = int(starts[t])
        off = lane0 + t * n_c
        window = slice(u0, u0 + n_c)
        wd = inv_delta[t]
        base = (np.dot(sq[cols], wd) + nu * mu2[t, ke]) / nu + const + n_obs * log_delta[t]
        mkd = mu_k[t, :ke]  # (ke, D_m)
        xh = xp[:, :, window] + nu * xm[t].transpose(1, 0, 2)[:, :, window]  # (ke, D_m, C)
        quad = np.einsum("kdc,kdc,d->c", pt[:, :, window] + nu * mkd[:, :, None], xh, wd)
        xb = (xh - mkd[:, :, None]).reshape(kd, n_c)
        total[off : off + n_c] += base - quad / nu + dm * logdet[window]
        a[:, off : off + n_c] += w_k[t, :kd].T @ xb
        if p_mode == P_FROM_Z:
            pq[:, off : off + n_c] += (coef[window] @ z[t, :m]).T
    if p_mode == P_FROM_W:
        iu, ju = np.triu_indices(r)
        rows = unpack[iu, ju]
        for t in range(starts.shape[0]):
            u0 = int(starts[t])
            off = lane0 + t * n_c
            wt = w_1[t, :kd]
            s = wt.T @ wt
            v = np.einsum("kjc,jdi->ckdi", linv[:, :, u0 : u0 + n_c], wt.reshape(ke, dm, r))
            vv = np.einsum("ckdi,ckdl->cil", v, v)
            pq[rows, off : off + n_c] += s[iu, ju][:, None] - nu * vv[:, iu, ju].T


def add_fused_p(pz, starts, u0, n_c, col0, npk, lane0, pq):
    """Add one block's packed ``P`` of every (task, candidate) pair from ``pz`` (see the compiled kernel)."""
    for t in range(starts.shape[0]):
        c0 = col0 + t * npk
        r0 = int(starts[t]) - u0
        off = lane0 + t * n_c
        pq[:, off : off + n_c] += pz[r0 : r0 + n_c, c0 : c0 + npk].T


def finish_soa(pq, a, total, unpack, alphas, t_norm, t_last, loglik, add, n_blocks):
    """Log likelihood (into ``loglik`` (T, C)) from ``Q = I + P``, ``a`` and the other terms (see the
    compiled kernel). Returns False when a ``Q`` was not numerically positive definite."""
    r, n_p = a.shape
    n_t, n_c = alphas.shape
    if r:
        q = np.moveaxis(pq[unpack], 2, 0) + np.eye(r)  # (P', r, r)
        low = _chol(q)
        if low is None:
            return False
        logdet = 2.0 * np.sum(np.log(np.diagonal(low, axis1=1, axis2=2)), axis=1)
        v = np.linalg.solve(low, a.T[:, :, None])[:, :, 0]
        vv = np.sum(v * v, axis=1)
    else:
        logdet = vv = np.zeros(n_p)
    stride = n_p // n_blocks
    p = np.arange(n_t * n_c)
    lanes = p[None, :] + stride * np.arange(n_blocks)[:, None]
    value = np.sum(-0.5 * (total[lanes] + logdet[lanes] - vv[lanes]), axis=0).reshape(n_t, n_c)
    value[t_last > alphas * t_norm * (1.0 + 1e-12)] = -np.inf
    if add:
        loglik += value
    else:
        loglik[...] = value
    return True


def _vertex(x0: float, x1: float, x2: float, y0: float, y1: float, y2: float) -> float:
    """Vertex of the parabola through three points, kept in ``[x0, x2]`` (``x1`` if not concave)."""
    denom = (x0 - x1) * (x0 - x2) * (x1 - x2)
    ca = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / denom
    cb = (x2 * x2 * (y0 - y1) + x1 * x1 * (y2 - y0) + x0 * x0 * (y1 - y2)) / denom
    if not ca < 0.0:
        return float(x1)
    return float(min(max(-cb / (2.0 * ca), x0), x2))


def phase_posterior(loglik, log_prior, grids, weights, nodes):
    """Log evidence (T,), normalised log phase posterior (T, C) and MAP phases (T,) (see the
    compiled kernel: the same refinement around the best candidate)."""
    n_t, n_c = loglik.shape
    steps = weights.shape[0]
    lp_all = loglik + log_prior
    evidence = np.empty(n_t)
    alpha = np.empty(n_t)
    for t in range(n_t):
        lp = lp_all[t]
        i = int(np.argmax(lp))
        top = lp[i]
        ev = top + np.log(np.sum(np.exp(lp - top))) if np.isfinite(top) else top
        evidence[t] = ev
        g = grids[t]
        if i == 0 or i == n_c - 1 or not np.all(np.isfinite(lp[i - 1 : i + 2])):
            alpha[t] = g[i]
        elif i < 3 or i > n_c - 4 or not np.all(np.isfinite(lp[i - 3 : i + 4])):
            alpha[t] = _vertex(g[i - 1], g[i], g[i + 1], lp[i - 1], lp[i], lp[i + 1])
        else:
            fine = np.empty(2 * steps + 1)
            for half in range(2):
                left = i - 1 + half
                fine[half * steps : (half + 1) * steps] = weights @ lp[left + nodes]
            fine[2 * steps] = lp[i + 1]
            h = (g[i + 1] - g[i - 1]) / (2 * steps)
            jb = int(np.argmax(fine))
            if jb == 0 or jb == 2 * steps:
                alpha[t] = g[i - 1] + jb * h
            else:
                x0 = g[i - 1] + (jb - 1) * h
                alpha[t] = _vertex(x0, x0 + h, x0 + 2.0 * h, fine[jb - 1], fine[jb], fine[jb + 1])
        if np.isfinite(ev):
            lp_all[t] = lp - ev
    return evidence, lp_all, alpha


def task_posterior(log_prior, evidence):
    """Normalised log task posterior (T,), the posterior (T,) and the most probable task (see the
    compiled kernel)."""
    joint = log_prior + evidence
    best = int(np.argmax(joint))
    top = joint[best]
    total = top + np.log(np.sum(np.exp(joint - top))) if np.isfinite(top) else top
    if not np.isfinite(total):
        nan = np.full(joint.shape[0], np.nan)
        return nan, nan.copy(), best
    log_post = joint - total
    return log_post, np.exp(log_post), best


def recognition(loglik, log_prior, grids, weights, nodes, task_log_prior):
    """:func:`phase_posterior` then :func:`task_posterior` (see the compiled kernel)."""
    evidence, logpost, alpha = phase_posterior(loglik, log_prior, grids, weights, nodes)
    finite = bool(np.all(np.isfinite(evidence)))
    log_post, post, best = task_posterior(task_log_prior, evidence)
    return evidence, logpost, alpha, finite, log_post, post, best


def head_posterior(values, generative, posterior, alpha, t_scale, ratios, w, b, clip):
    """Task posterior of the recognition head: log posterior (T,), posterior (T,), most probable task
    (see the compiled kernel)."""
    x = head_features(values, generative, clip)
    i, wt = interpolation(ratios, t_scale * np.dot(posterior, 1.0 / alpha))
    z = w[i] @ x + b[i]
    if wt > 0.0:
        z = (1.0 - wt) * z + wt * (w[i + 1] @ x + b[i + 1])
    finite = np.isfinite(generative)
    if not finite.all():
        z = np.where(finite, z, -np.inf)
    z = z - z.max()
    log_post = z - np.log(np.sum(np.exp(z)))
    return log_post, np.exp(log_post), int(np.argmax(log_post))


def scale_samples(raw, log_idx, log_c, offset, scale, out):
    """Scaled values (into ``out`` (n, D)) of raw samples; whether every raw value is finite and every
    scaled one within the bounds of :mod:`ipromp_pin.promp.sample_bounds` (see the compiled kernel)."""
    finite = bool(np.all(np.isfinite(raw)))
    vals = np.array(raw, dtype=float, copy=True)
    with np.errstate(all="ignore"):
        if log_idx.size:
            finite = finite and bool(np.all(vals[:, log_idx] >= -MAX_SCALED_MAGNITUDE * log_c))
            vals[:, log_idx] = np.log(np.maximum(vals[:, log_idx], 0.0) + log_c)
        out[...] = (vals - offset) / scale
        finite = finite and bool(np.all(np.abs(out) <= MAX_SCALED_MAGNITUDE))
        if log_idx.size:
            finite = finite and bool(np.all(np.abs(out[:, log_idx]) <= MAX_LOG_SCALED_MAGNITUDE))
    return finite


def channel_values(phi, w, scale, offset, log_idx, log_shift):
    """Trajectories (M, D) in original units of weights ``w`` (D, K) (see the compiled kernel)."""
    out = (phi @ w.T) * scale + offset
    if log_idx.size:
        out[:, log_idx] = np.exp(out[:, log_idx]) - log_shift[log_idx]
    return out


def prediction_cov(low, phi_f, phi2, diag, scale):
    """Covariance (M, J, J) of the predicted joints (see the compiled kernel)."""
    r, n_j, n_m = phi_f.shape
    s = solve_triangular(low, phi_f.reshape(r, n_j * n_m), lower=True).reshape(r, n_j, n_m)
    cov = np.einsum("kim,kjm->mij", s, s)
    idx = np.arange(n_j)
    cov[:, idx, idx] += phi2[:, None] * diag[None, :]
    return cov * (scale[:, None] * scale[None, :])


def condition_block(
    t_cat, n_off, y_cat, y_off, y_width, pos_cat, dims_cat, p_off, ke_p, inv_dur, centres, width, step, mean,
    diag, factor, nu, w_post, lq,
):  # fmt: skip
    """Condition one independent latent block of a task on every observation part at one phase (see
    the compiled kernel). Returns False when ``X`` or ``Q`` is not numerically positive definite."""
    n_parts = n_off.shape[0] - 1
    n_dims, n_k, r = factor.shape
    q = np.eye(r)
    a = np.zeros(r)
    saved = []
    for p in range(n_parts):
        n0, n1 = int(n_off[p]), int(n_off[p + 1])
        ke = int(ke_p[p])
        d0, d1 = int(p_off[p]), int(p_off[p + 1])
        dims = dims_cat[d0:d1]
        bt = basis_rows(t_cat[n0:n1] * inv_dur, centres, width, step)[:ke]  # (ke, n)
        values = y_cat[y_off[p] : y_off[p] + (n1 - n0) * y_width[p]].reshape(n1 - n0, int(y_width[p]))
        ys = values[:, pos_cat[d0:d1]]
        sd = np.sqrt(diag[dims])
        wf = (factor[dims, :ke, :] / sd[:, None, None]).transpose(1, 0, 2)  # (ke, D_m, r)
        gram = bt @ bt.T
        b = bt @ ys - gram @ mean[dims, :ke].T  # (ke, D_m)
        try:
            factor_x = cho_factor(gram + nu * np.eye(ke), lower=True)
        except np.linalg.LinAlgError:
            return False
        if not np.all(np.isfinite(factor_x[0])):
            return False
        wk = wf.reshape(ke * len(dims), r)
        rhs = np.concatenate([wf.reshape(ke, -1), b / sd], axis=1)
        sol = cho_solve(factor_x, rhs)
        xw = sol[:, : len(dims) * r].reshape(ke * len(dims), r)
        xb = sol[:, len(dims) * r :].reshape(ke * len(dims))
        q += wk.T @ (wk - nu * xw)
        a += wk.T @ xb
        saved.append((dims, ke, factor_x, gram, b))
    f_eta = np.zeros((n_dims, n_k))
    if r > 0:
        low = _chol(q[None])
        if low is None:
            return False
        lq[...] = low[0]
        m_eta = cho_solve((low[0], True), a)
        f_eta = (factor.reshape(n_dims * n_k, r) @ m_eta).reshape(n_dims, n_k)
        w_post += f_eta
    for dims, ke, factor_x, gram, b in saved:
        rhs = b - gram @ f_eta[dims, :ke].T
        w_post[dims, :ke] += cho_solve(factor_x, rhs).T
    return True


def readout_update(
    mean, sd, factor, base, extra, extra_u, extra_s, phi, phi_f, scale, offset, row, readout, values, cov
):
    """``_kernels.readout_update`` (the read-out update of the robot weights) with numpy / LAPACK."""
    nj, k, r = factor.shape
    jk = nj * k
    n_u = jk + r
    b0 = n_u - base.shape[0]
    m = readout.shape[0]
    n_m = phi.shape[0]
    fail = (False, np.zeros((m, n_u)), np.zeros((nj, k)), np.zeros((n_m, nj)), np.zeros((n_m, nj, nj)))
    lc = _chol(cov)
    if lc is None:
        return fail
    a_w = solve_triangular(lc, readout * scale[None, :], lower=True, check_finite=False)
    v = np.empty((m, n_u))
    v[:, :jk] = ((a_w * sd[None, :])[:, :, None] * row[None, None, :]).reshape(m, jk)
    v[:, jk:] = a_w @ (row @ factor)
    predicted = readout @ (mean @ row * scale + offset)
    resid = solve_triangular(lc, values - predicted, lower=True, check_finite=False)
    u = v.T.copy()
    if base.shape[0]:
        u[b0:] = cho_solve((base, True), u[b0:], check_finite=False)
    if extra.shape[0]:
        u -= extra_u @ cho_solve((extra_s, True), extra @ u, check_finite=False)
    ls = _chol(np.eye(m) + v @ u)
    if ls is None:
        return fail
    du = u @ cho_solve((ls, True), resid, check_finite=False)
    dw = du[:jk].reshape(nj, k) * sd[:, None] + factor @ du[jk:]
    u_w = (u[:jk].reshape(nj, k, m) * sd[:, None, None]).transpose(1, 0, 2).reshape(k, nj * m)
    cross = (phi @ u_w).reshape(n_m, nj, m)
    if r:
        cross += (u[jk:].T @ phi_f.reshape(r, nj * n_m)).reshape(m, nj, n_m).transpose(2, 1, 0)
    cross *= scale[None, :, None]
    d = solve_triangular(ls, cross.reshape(-1, m).T, lower=True, check_finite=False).T.reshape(cross.shape)
    return True, v, dw, (phi @ dw.T) * scale, np.matmul(d, d.transpose(0, 2, 1))
