"""Fitting the hand-over regression and choosing how much to trust it, on the training demos only.

The regressions (:mod:`~ipromp_pin.promp.handover`) are fitted per task and observed fraction on
every training demo of the task. Their trust factor ``s`` is chosen by cross-validation of the
hand-over on the held-out demos of the noise cross-validation (:mod:`~ipromp_pin.promp.selection`),
each observed at :data:`~ipromp_pin.promp.handover.RATIOS`, as online: its task's phase is the
leave-one-out model's MAP estimate (the recognition rows of :func:`~ipromp_pin.promp.selection.
choose_noise`), the robot is conditioned with the chosen coupling and conditioning noise ratio on the
leave-one-out covariance, and the regression is refitted without the held-out demo (its penalty and
residuals by leave-one-out among the others), interpolated at the estimated observed fraction. The
score of every candidate (each of :data:`~ipromp_pin.promp.handover.TRUST_GRID`, and "off") is the
mean hand-over position error in [m] (with the robot's forward kinematics; else the RMS error of the
final joint angles in [rad]); the best one is chosen ("off": the model has no regression).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .distribution import shrink_covariances
from .handover import RATIOS, TRUST_GRID, HandoverRegression, RidgeFit, fit_ridge, readouts, window_features
from .head import WindowSummary, interpolation
from .noise_path import part_spectrum, robot_path
from .observation import ObservationEncoder
from .posterior import recognise_from_loglik
from .selection import HeldOutRow, cv_observations, held_out
from .training import PhaseSettings, TrainingSet, coupling_blocks


@dataclass(frozen=True)
class HandoverChoice:
    """What :func:`choose_handover` chose.

    Attributes:
        regression: The hand-over regression (None: "off", or nothing to regress on).
        scores: Candidate trust factor -> CV error (mean hand-over position error in [m], or final
            joint RMS error in [rad] without forward kinematics); ``inf`` is "off".
    """

    regression: HandoverRegression | None
    scores: dict[float, float]


def final_configurations(training: TrainingSet) -> dict[str, np.ndarray]:
    """Task -> (N, J) the final joint angles in [rad] of its demos' basis fits (phase 1)."""
    rs = training.layout.robot_slice
    phi = training.basis(np.array([1.0]))[0]
    scale, offset = training.scaler.scale[rs], training.scaler.offset[rs]
    return {t: (w[:, rs] @ phi) * scale + offset for t, w in training.weights.items()}


def _features(training: TrainingSet, dims: np.ndarray) -> dict[str, np.ndarray]:
    """Task -> (R, N, 2 F) the regression features of every demo at every fraction of
    :data:`RATIOS` (NaN where the demo is too short for the fraction)."""
    encoder = ObservationEncoder(training.layout, training.scaler, np.inf)
    n_obs = training.layout.n_obs_dims
    out = {}
    for task, demos in training.demos.items():
        x = np.full((len(RATIOS), len(demos), 2 * dims.size), np.nan)
        for i, demo in enumerate(demos):
            for ratio, parts, _ in cv_observations(encoder, demo, RATIOS):
                window = WindowSummary.from_parts(parts, n_obs).values
                x[RATIOS.index(ratio), i] = window_features(window, dims)
        out[task] = x
    return out


def _fit(x: np.ndarray, y: np.ndarray, drop: int | None = None) -> RidgeFit | None:
    """The ridge of targets ``y`` (N, M) on features ``x`` (N, F) over the demos with features, without
    demo ``drop`` (None when fewer than 2 remain)."""
    keep = ~np.isnan(x[:, 0])
    if drop is not None:
        keep[drop] = False
    if keep.sum() < 2:
        return None
    return fit_ridge(x[keep], y[keep])


def choose_handover(
    training: TrainingSet,
    settings: PhaseSettings,
    coupled: Sequence[str],
    nu_condition: float,
    rows: list[HeldOutRow],
    temperature: float,
    fk: Callable[[np.ndarray], np.ndarray] | None = None,
) -> HandoverChoice:
    """Fit the hand-over regressions on the coupled groups' window features and choose their trust
    factor by cross-validation (see the module docstring).

    Args:
        training: The training set.
        settings: Phase and covariance settings.
        coupled: The observed groups coupled to the robot (the features are theirs).
        nu_condition: The conditioning noise ratio of the robot's weights.
        rows: The held-out observations of :func:`~ipromp_pin.promp.selection.choose_noise` (their
            log likelihood at the chosen noise ratio).
        temperature: The chosen likelihood temperature.
        fk: The robot's forward kinematics (joint angles (n, J) in [rad] -> positions (n, 3) in [m]).
    """
    layout = training.layout
    dims = layout.dims(list(coupled))
    if dims.size == 0:
        return HandoverChoice(None, {})
    tasks = training.tasks
    q_end = final_configurations(training)
    readout = readouts(np.stack([q_end[t].mean(axis=0) for t in tasks]), fk)
    targets = {t: q_end[t] @ readout[k].T for k, t in enumerate(tasks)}
    feats = _features(training, dims)
    fits = {(r, t): _fit(feats[t][r], targets[t]) for r in range(len(RATIOS)) for t in tasks}
    if any(f is None for f in fits.values()):
        return HandoverChoice(None, {})
    scores = _cross_validate(training, settings, coupled, nu_condition, rows, temperature, fk, feats, fits)
    n_ratio, n_task = len(RATIOS), len(tasks)
    m = readout.shape[1]
    coef = np.stack([np.stack([fits[(r, t)].coef for t in tasks]) for r in range(n_ratio)])
    intercept = np.stack([np.stack([fits[(r, t)].intercept for t in tasks]) for r in range(n_ratio)])
    cov = np.stack([_pooled([fits[(r, t)].residuals for t in tasks]) for r in range(n_ratio)])
    trust = min(scores, key=scores.get) if scores else np.inf
    if not np.isfinite(trust):
        return HandoverChoice(None, scores)
    regression = HandoverRegression(
        ratios=np.asarray(RATIOS, dtype=float),
        dims=np.asarray(dims, dtype=np.int64),
        readout=readout,
        coef=coef.reshape(n_ratio, n_task, m, -1),
        intercept=intercept,
        residual_cov=cov,
        trust=float(trust),
    )
    return HandoverChoice(regression, scores)


def _pooled(residuals: list[np.ndarray]) -> np.ndarray:
    """The second moment (M, M) of the leave-one-out residuals of every task (a small ridge keeps it
    positive definite)."""
    e = np.concatenate(residuals)
    cov = e.T @ e / e.shape[0]
    return cov + 1e-9 * max(float(np.trace(cov)) / cov.shape[0], 1e-12) * np.eye(cov.shape[0])


def _cross_validate(
    training: TrainingSet,
    settings: PhaseSettings,
    coupled: Sequence[str],
    nu_condition: float,
    rows: list[HeldOutRow],
    temperature: float,
    fk: Callable[[np.ndarray], np.ndarray] | None,
    feats: dict[str, np.ndarray],
    fits: dict[tuple[int, str], RidgeFit],
) -> dict[float, float]:
    """Candidate trust factor -> CV error (``inf``: off); empty when no row could be scored."""
    layout = training.layout
    tasks = training.tasks
    rs = layout.robot_slice
    scale, offset = training.scaler.scale[rs], training.scaler.offset[rs]
    phi_end = training.basis(np.array([1.0]))[0]
    q_end = final_configurations(training)
    readout = readouts(np.stack([q_end[t].mean(axis=0) for t in tasks]), fk)
    encoder = ObservationEncoder(layout, training.scaler, np.inf)
    folds = held_out(training.demos)
    blocks = coupling_blocks(layout, coupled)
    covs: dict[int, object] = {}
    nested: dict[tuple[int, int], RidgeFit | None] = {}
    configs, truths = [], []
    for row in rows:
        task, i = folds[row.demo]
        k = tasks.index(task)
        rec, _ = recognise_from_loglik(row.priors, temperature * row.loglik, row.t_last)
        alpha = float(rec.alpha[k])
        if not np.isfinite(alpha) or alpha <= 0.0:
            continue
        fraction = row.t_last / (alpha * training.duration_nominal_s)
        if row.demo not in covs:
            keep = np.arange(len(training.demos[task])) != i
            weights = [training.weights[t][keep] if t == task else training.weights[t] for t in tasks]
            covs[row.demo] = shrink_covariances(weights, settings.pooling, blocks, [k])[0]
        cov = covs[row.demo]
        obs = cv_observations(encoder, training.demos[task][i], [row.ratio])
        if not obs:
            continue
        _, parts, _ = obs[0]
        spectrum = part_spectrum(training.basis, parts, alpha * training.duration_nominal_s)
        path = robot_path(spectrum, parts, rs, [nu_condition], cov.mean, cov.diag, cov.factor)
        mean = (path.mean[0] @ phi_end) * scale + offset  # (J,) [rad]
        s_cov = path.readout_cov(phi_end)[0] * scale[:, None] * scale[None, :]
        # the regression without the held-out demo, interpolated at the estimated fraction
        j, w = interpolation(list(RATIOS), fraction)
        x = window_features(row.window, layout.dims(list(coupled)))
        pred, noise = np.zeros(readout.shape[1]), np.zeros((readout.shape[1],) * 2)
        ok = True
        for level, weight in ((j, 1.0 - w), (j + 1, w)):
            if weight <= 0.0:
                continue
            key = (level, row.demo)
            if key not in nested:
                nested[key] = _fit(feats[task][level], q_end[task] @ readout[k].T, drop=i)
            fit = nested[key]
            if fit is None:
                ok = False
                break
            pred += weight * (fit.coef @ x + fit.intercept)
            others = [fits[(level, t)].residuals for t in tasks if t != task]
            noise += weight * _pooled([*others, fit.residuals])
        if not ok:
            continue
        a = readout[k]
        gain_base = s_cov @ a.T  # (J, M)
        innov = pred - a @ mean
        outs = [mean]
        for trust in TRUST_GRID:
            outs.append(mean + gain_base @ np.linalg.solve(a @ gain_base + trust * noise, innov))
        configs.append(np.stack(outs))
        truths.append(q_end[task][i])
    if not configs:
        return {}
    q = np.stack(configs)  # (n, 1 + len(TRUST_GRID), J)
    truth = np.stack(truths)
    if fk is not None:
        n, c, nj = q.shape
        pos = np.asarray(fk(np.concatenate([truth, q.reshape(-1, nj)])), dtype=float)
        err = np.linalg.norm(pos[n:].reshape(n, c, -1) - pos[:n, None], axis=2)
    else:
        err = np.sqrt(np.mean((q - truth[:, None]) ** 2, axis=2))
    mean_err = err.mean(axis=0)
    return {
        np.inf: float(mean_err[0]),
        **{t: float(v) for t, v in zip(TRUST_GRID, mean_err[1:], strict=True)},
    }
