"""Textbook reference implementation of the inference, beside the fast one, for tests and benchmarks.

:func:`direct_loglik` is the marginal likelihood ``N(y; Phi mu, Phi Sigma Phi^T + R)`` with a dense
block-diagonal observation matrix ``Phi`` and one dense Cholesky factorisation per candidate;
:func:`direct_predict` the whole recognition and prediction with it and dense Gaussian conditioning;
:func:`refine_peak` the continuous MAP phase in plain Python (the compiled ``phase_posterior``
kernel does the same arithmetic). They read only the public fitted state and are hundreds of times
slower than :class:`~ipromp_pin.promp.predictor.Predictor`, which the tests check against them.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from ..data import Demo
from .basis import GaussianBasis
from .distribution import TaskModel
from .fitted import FittedModel
from .head_features import LOG_POSTERIOR_CLIP
from .likelihood import LOG_2PI
from .observation import ObservationPart
from .posterior import (
    REFINE_NODES,
    REFINE_STEPS,
    REFINE_WEIGHTS,
    Prediction,
    finish_recognition,
    with_task_posterior,
)
from .predictor import Predictor


def parabola_vertex(x0: float, x1: float, x2: float, y0: float, y1: float, y2: float) -> float:
    """Vertex of the parabola through three points with ``y1`` the largest, kept in ``[x0, x2]``
    (``x1`` when the points are not concave)."""
    denom = (x0 - x1) * (x0 - x2) * (x1 - x2)
    ca = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / denom
    cb = (x2 * x2 * (y0 - y1) + x1 * x1 * (y2 - y0) + x0 * x0 * (y1 - y2)) / denom
    if not ca < 0.0:
        return float(x1)
    return float(min(max(-cb / (2.0 * ca), x0), x2))


def refine_peak(grid: np.ndarray, logpost: np.ndarray) -> float:
    """Continuous maximum of a log posterior sampled on a uniform ``grid``.

    The log posterior is a smooth function of the phase; around the best candidate ``i`` it is
    interpolated on the two neighbouring intervals at ``REFINE_STEPS`` points per spacing, each
    interval by the degree-5 polynomial through the 6 candidates around it (error ``O(h^6)`` for a
    spacing ``h``), and the best fine point is refined by a parabola through it and its two fine
    neighbours. Where the stencil would leave the grid or meet an impossible candidate the parabola
    goes through the candidates ``i - 1, i, i + 1`` instead; at the grid's edge (or next to an
    impossible candidate) the best candidate itself is returned.
    """
    i = int(np.argmax(logpost))
    n = grid.size
    if i == 0 or i == n - 1 or not np.all(np.isfinite(logpost[i - 1 : i + 2])):
        return float(grid[i])
    if i < 3 or i > n - 4 or not np.all(np.isfinite(logpost[i - 3 : i + 4])):
        return parabola_vertex(*grid[i - 1 : i + 2], *logpost[i - 1 : i + 2])
    steps = REFINE_STEPS
    fine = np.empty(2 * steps + 1)
    for half in range(2):
        left = i - 1 + half  # interval [left, left + 1]
        for j in range(steps):
            v = 0.0
            for q in range(REFINE_NODES.size):
                v += REFINE_WEIGHTS[j, q] * logpost[left + REFINE_NODES[q]]
            fine[half * steps + j] = v
    fine[2 * steps] = logpost[i + 1]
    h = (grid[i + 1] - grid[i - 1]) / (2 * steps)
    j = int(np.argmax(fine))
    if j == 0 or j == 2 * steps:
        return float(grid[i - 1] + j * h)
    x0 = grid[i - 1] + (j - 1) * h
    return parabola_vertex(x0, x0 + h, x0 + 2.0 * h, fine[j - 1], fine[j], fine[j + 1])


def dense_observation_matrix(
    basis: GaussianBasis, parts: list[ObservationPart], alpha: float, t_norm: float, n_dims: int, k: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Dense observation matrix (n_y, n_dims * K), the stacked values (n_y,) and their dims (n_y,)."""
    rows, ys, dims_of_rows = [], [], []
    for part in parts:
        phi = basis(part.t / (alpha * t_norm))
        for j, d in enumerate(part.dims):
            blk = np.zeros((phi.shape[0], n_dims * k))
            blk[:, d * k : (d + 1) * k] = phi
            rows.append(blk)
            ys.append(part.y[:, j])
            dims_of_rows.append(np.full(phi.shape[0], d))
    return np.concatenate(rows), np.concatenate(ys), np.concatenate(dims_of_rows)


def direct_loglik(
    basis: GaussianBasis,
    task: TaskModel,
    parts: list[ObservationPart],
    alpha: float,
    t_norm: float,
    nu: float,
    sigma: np.ndarray | None = None,
) -> float:
    """Textbook log N(y; Phi mu, Phi Sigma Phi^T + R) with a dense Cholesky.

    Args:
        basis, task, parts: Model basis, task model and observation parts (scaled).
        alpha: Phase candidate.
        t_norm: Nominal duration in [s].
        nu: Noise ratio (``R = nu * delta_d`` per observed dim).
        sigma: Dense weight covariance of the task (computed when None).
    """
    n_dims, k = task.mean.shape
    t_last = max(float(p.t[-1]) for p in parts)
    if t_last > alpha * t_norm * (1.0 + 1e-12):
        return -np.inf
    phi, y, dd = dense_observation_matrix(basis, parts, alpha, t_norm, n_dims, k)
    sigma = task.covariance() if sigma is None else sigma
    cov = phi @ sigma @ phi.T + np.diag(nu * task.diag[dd])
    c, low = cho_factor(cov, lower=True)
    e = y - phi @ task.mean.reshape(-1)
    sol = cho_solve((c, low), e)
    return float(-0.5 * (y.size * LOG_2PI + 2.0 * np.sum(np.log(np.diag(c))) + e @ sol))


def direct_window(parts: list[ObservationPart], n_obs: int) -> np.ndarray:
    """Per observed dim the first, mean and last valid scaled value of the parts, sample by sample
    ((3 n_obs,): the firsts, then the means, then the lasts; zeros where a dim has no sample)."""
    samples: list[list[tuple[float, float]]] = [[] for _ in range(n_obs)]
    for part in parts:
        for j, d in enumerate(part.dims):
            samples[int(d)] += [(float(t), float(v)) for t, v in zip(part.t, part.y[:, j], strict=True)]
    window = np.zeros(3 * n_obs)
    for d, rows in enumerate(samples):
        if rows:
            rows.sort()
            window[d] = rows[0][1]
            window[n_obs + d] = sum(v for _, v in rows) / len(rows)
            window[2 * n_obs + d] = rows[-1][1]
    return window


def direct_handover(
    fm: FittedModel, parts: list[ObservationPart], task: int, fraction: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The hand-over regression's evidence written out: the read-out ``A`` (M, J), the prediction
    ``y`` (M,) of the features (window mean and last value of its dims) of the regressions at the two
    fractions around ``fraction`` interpolated linearly, and its noise covariance ``s R`` (M, M)."""
    ho = fm.handover
    assert ho is not None, "the model has no hand-over regression"
    window: np.ndarray = direct_window(parts, fm.layout.n_obs_dims).reshape(3, -1)
    x = np.concatenate([window[1, ho.dims], window[2, ho.dims]])
    r = ho.ratios
    if fraction <= r[0]:
        i, w = 0, 0.0
    elif fraction >= r[-1]:
        i, w = r.size - 1, 0.0
    else:
        i = max(k for k in range(r.size - 1) if r[k] <= fraction)
        w = (fraction - r[i]) / (r[i + 1] - r[i])
    y = ho.coef[i, task] @ x + ho.intercept[i, task]
    cov = ho.residual_cov[i]
    if w > 0.0:
        y = (1.0 - w) * y + w * (ho.coef[i + 1, task] @ x + ho.intercept[i + 1, task])
        cov = (1.0 - w) * cov + w * ho.residual_cov[i + 1]
    return ho.readout[task], y, ho.trust * cov


def direct_head(
    fm: FittedModel, parts: list[ObservationPart], generative: np.ndarray, fraction: float
) -> np.ndarray:
    """The recognition head's log task posterior written out: per observed dim the first, mean and
    last valid scaled value (sample by sample), the clipped generative log posterior, standardised,
    the linear logits of the regressions at the two observed fractions around ``fraction`` (the
    expected observed fraction under the generative posterior) interpolated linearly, and their
    log-softmax."""
    window = direct_window(parts, fm.layout.n_obs_dims)
    x = np.concatenate([window, np.maximum(generative, LOG_POSTERIOR_CLIP)])
    head = fm.head
    assert head is not None, "the model has no recognition head"
    logits = [
        head.coef[i] @ ((x - head.feature_mean[i]) / head.feature_scale[i]) + head.intercept[i]
        for i in range(head.ratios.size)
    ]
    s = fraction
    r = head.ratios
    if s <= r[0]:
        z = logits[0]
    elif s >= r[-1]:
        z = logits[-1]
    else:
        i = max(k for k in range(r.size - 1) if r[k] <= s)
        w = (s - r[i]) / (r[i + 1] - r[i])
        z = (1.0 - w) * logits[i] + w * logits[i + 1]
    z = np.where(np.isfinite(generative), z, -np.inf)
    return z - np.logaddexp.reduce(z)


def direct_predict(predictor: Predictor, observation: Demo) -> Prediction:
    """Reference recognition and prediction by the textbook equations (slow; tests and benchmarks)."""
    fm = predictor.fitted
    parts, t_last = predictor.encode(observation)
    nu = fm.noise_ratio
    tn = fm.duration_nominal_s
    grids = np.stack([fm.models[t].alpha_grid for t in fm.tasks])
    logpost = np.empty_like(grids)
    evidence = np.empty(len(fm.tasks))
    alpha = np.empty(len(fm.tasks))
    for i, task in enumerate(fm.tasks):
        m = fm.models[task]
        sigma = m.covariance()
        ll = np.array([direct_loglik(fm.basis, m, parts, a, tn, nu, sigma) for a in m.alpha_grid])
        lp = fm.temperature * ll + m.alpha_log_prior
        evidence[i] = np.logaddexp.reduce(lp)
        logpost[i] = lp - evidence[i]
        alpha[i] = refine_peak(m.alpha_grid, lp)
    rec = finish_recognition(predictor.priors, evidence, alpha, logpost, t_last)
    n_fit = fm.n_fit_tasks  # the head and the hand-over estimates know the fitted tasks only
    fitted_mass = float(np.logaddexp.reduce(rec.log_posterior[:n_fit]))
    if fm.head is not None and n_fit == len(fm.tasks):
        fraction = sum(p * t_last / (a * tn) for p, a in zip(rec.posterior, rec.alpha, strict=True))
        post = direct_head(fm, parts, rec.log_posterior, float(fraction))
        rec = with_task_posterior(rec, post, predictor.priors)
    elif fm.head is not None and np.isfinite(fitted_mass):
        # the fitted tasks' part of the generative posterior, shared among them by the head
        gen = rec.log_posterior[:n_fit] - fitted_mass
        fraction = sum(np.exp(g) * t_last / (a * tn) for g, a in zip(gen, rec.alpha[:n_fit], strict=True))
        post = np.concatenate(
            [fitted_mass + direct_head(fm, parts, gen, float(fraction)), rec.log_posterior[n_fit:]]
        )
        rec = with_task_posterior(rec, post, predictor.priors)
    m = fm.models[rec.task]
    a_best = float(rec.alpha[fm.tasks.index(rec.task)])
    n_dims, k = m.mean.shape
    phi, y, dd = dense_observation_matrix(fm.basis, parts, a_best, tn, n_dims, k)
    sigma = m.covariance()
    cov = phi @ sigma @ phi.T + np.diag(fm.nu_condition * m.diag[dd])  # the conditioning's noise
    c = cho_factor(cov, lower=True)
    gain_t = cho_solve(c, phi @ sigma)  # C^-1 Phi Sigma, (n_y, p)
    w_mean = m.mean.reshape(-1) + gain_t.T @ (y - phi @ m.mean.reshape(-1))
    w_cov = sigma - (phi @ sigma).T @ gain_t
    rs = fm.layout.robot_slice
    nj = rs.stop - rs.start
    sel = slice(rs.start * k, rs.stop * k)
    scale = fm.scaler.scale[rs]
    wr = w_mean.reshape(n_dims, k)  # the human's estimates do not use the hand-over regression
    estimates = fm.tasks.index(rec.task) < n_fit
    if fm.handover is not None and estimates:  # y = A q(T) + e, q(T) = scale * (phi(1) w_robot) + offset
        task_index = fm.tasks.index(rec.task)
        readout, values, noise = direct_handover(fm, parts, task_index, t_last / (a_best * tn))
        phi_end = fm.basis(np.array([1.0]))[0]
        h = np.zeros((readout.shape[0], n_dims * k))
        h[:, sel] = np.kron(readout * scale[None, :], phi_end[None, :])
        q_end = w_mean[sel].reshape(nj, k) @ phi_end * scale + fm.scaler.offset[rs]
        s_cov = h @ w_cov @ h.T + noise
        c = cho_factor(s_cov, lower=True)
        gain_t = cho_solve(c, h @ w_cov)  # (M, p)
        w_mean = w_mean + gain_t.T @ (values - readout @ q_end)
        w_cov = w_cov - (h @ w_cov).T @ gain_t
    if (
        fm.orientation is not None and estimates
    ):  # the orientation observed where it is uncorrelated with the position
        o = fm.orientation
        task_index = fm.tasks.index(rec.task)
        phi_end = fm.basis(np.array([1.0]))[0]
        e = np.zeros((nj, n_dims * k))
        e[:, sel] = np.kron(np.diag(scale), phi_end[None, :])  # q(T) = e w + offset
        q_end = e @ w_mean + fm.scaler.offset[rs]
        s_end = e @ w_cov @ e.T
        pos, rot = o.position_readout[task_index], o.rotation_readout[task_index]
        b = cho_solve(cho_factor(pos @ s_end @ pos.T, lower=True), pos @ s_end @ rot.T).T
        h = (rot - b @ pos) @ e
        values = o.target[task_index] - b @ pos @ q_end
        s_cov = h @ w_cov @ h.T + o.trust * o.noise_cov[task_index]
        c = cho_factor(s_cov, lower=True)
        gain_t = cho_solve(c, h @ w_cov)
        w_mean = w_mean + gain_t.T @ (values - (rot - b @ pos) @ q_end)
        w_cov = w_cov - (h @ w_cov).T @ gain_t
    z = np.linspace(0.0, 1.0, predictor.conditioner.n_points)
    b = fm.basis(z)
    big = np.zeros((z.size * nj, nj * k))
    for j in range(nj):
        big[j::nj, j * k : (j + 1) * k] = b
    q_mean = (big @ w_mean[sel]).reshape(z.size, nj)
    q_cov = np.stack(
        [big[i * nj : (i + 1) * nj] @ w_cov[sel, sel] @ big[i * nj : (i + 1) * nj].T for i in range(z.size)]
    )
    # the prediction's other fields from the fast assembly; its trajectories replaced by the dense ones
    pred = predictor.conditioner.prediction(rec, m.factor, m, a_best, wr, np.eye(m.rank), "all")
    pred.q_mean = fm.scaler.inverse(q_mean, rs)
    pred.q_cov = q_cov * scale[None, :, None] * scale[None, None, :]
    return pred
