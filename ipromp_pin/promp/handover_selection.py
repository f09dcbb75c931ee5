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
final joint angles in [rad]); the best one is chosen ("off": the model has no regression). The
regression's features are the window of the groups coupled to the robot or of every observed group
(when they differ), chosen by the same cross-validation; the robot's leave-one-out conditioning is
computed once for all candidates.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from .distribution import shrink_covariances
from .handover import (
    RATIOS,
    TRUST_GRID,
    HandoverRegression,
    KnnFit,
    RidgeFit,
    fit_knn,
    fit_ridge,
    neighbour_arrays,
    readouts,
)
from .handover_orientation import FKRot, OrientationEstimate, conditioned
from .head_features import interpolation
from .noise_path import RobotPrior, part_spectrum, robot_paths, robot_prior
from .observation import ObservationEncoder
from .orientation_selection import FinalRow, choose_orientation
from .selection import HeldOutRow, cv_observations, held_out
from .training import PhaseSettings, TrainingSet, coupling_blocks
from .window import WindowSummary, window_features


@dataclass(frozen=True)
class HandoverChoice:
    """What :func:`choose_handover` chose.

    Attributes:
        regression: The hand-over regression (None: "off", or nothing to regress on).
        scores: Candidate trust factor -> CV error (mean hand-over position error in [m], or final
            joint RMS error in [rad] without forward kinematics); ``inf`` is "off".
        orientation: The hand-over orientation estimate (None: none;
            :mod:`~ipromp_pin.promp.orientation_selection`); ``orientation_scores`` its trust
            factors' CV errors in [deg].
    """

    regression: HandoverRegression | None
    scores: dict[float, float]
    orientation: OrientationEstimate | None = None
    orientation_scores: dict[float, float] = field(default_factory=dict)


def final_configurations(training: TrainingSet) -> dict[str, np.ndarray]:
    """Task -> (N, J) the final joint angles in [rad] of its demos: the last sample with every joint
    (what the hand-over is measured against; the basis fit at phase 1 for a demo without one)."""
    rs = training.layout.robot_slice
    phi = training.basis(np.array([1.0]))[0]
    scale, offset = training.scaler.scale[rs], training.scaler.offset[rs]
    robot = training.layout.robot_group
    out = {}
    for t, w in training.weights.items():
        q = (w[:, rs] @ phi) * scale + offset
        for i, demo in enumerate(training.demos[t]):
            values = np.asarray(demo.groups[robot], dtype=float)
            rows = np.flatnonzero(np.all(np.isfinite(values), axis=1))
            if rows.size:
                q[i] = values[rows[-1]]
        out[t] = q
    return out


def readout_targets(
    q_end: dict[str, np.ndarray],
    readout: np.ndarray,
    tasks: Sequence[str],
    fk: Callable[[np.ndarray], np.ndarray] | None,
) -> dict[str, np.ndarray]:
    """Task -> (N, M) the regression's targets: with the forward kinematics the gripper positions
    ``p_i`` [m] in the read-out's linearisation at the task's mean final configuration ``q_bar``,
    ``A q_bar + p_i - fk(q_bar)`` (so that ``A q(T)`` equal to the target puts the linearised gripper
    at ``p_i``); without it the final joint angles [rad]."""
    out = {}
    for k, t in enumerate(tasks):
        if fk is None:
            out[t] = q_end[t] @ readout[k].T
            continue
        q_bar = q_end[t].mean(axis=0)
        p = np.asarray(fk(np.vstack([q_bar[None], q_end[t]])), dtype=float)
        out[t] = (readout[k] @ q_bar - p[0])[None] + p[1:]
    return out


def _features(training: TrainingSet, dims: np.ndarray) -> dict[str, np.ndarray]:
    """Task -> (R, N, 2 F) the regression features of every demo at every fraction of
    :data:`RATIOS` (NaN where the demo is too short for the fraction)."""
    encoder = ObservationEncoder(training.layout, training.scaler, np.inf)
    n_obs = training.layout.n_obs_dims
    out = {}
    for task, demos in training.demos.items():
        x = np.full((len(RATIOS), len(demos), 2 * dims.size), np.nan)
        for i, demo in enumerate(demos):
            for ratio, parts, _ in cv_observations(encoder, demo, RATIOS, training.encoded):
                window = WindowSummary.from_parts(parts, n_obs).values
                x[RATIOS.index(ratio), i] = window_features(window, dims)
        out[task] = x
    return out


def _fit(
    x: np.ndarray, y: np.ndarray, drop: int | None = None, knn: bool = False
) -> RidgeFit | KnnFit | None:
    """The ridge (or k-nearest-neighbour) regression of targets ``y`` (N, M) on features ``x`` (N, F)
    over the demos with features, without demo ``drop`` (None when fewer than 2 remain)."""
    keep = ~np.isnan(x[:, 0])
    if drop is not None:
        keep[drop] = False
    if keep.sum() < 2:
        return None
    return fit_knn(x[keep], y[keep]) if knn else fit_ridge(x[keep], y[keep])


def _choose_kinds(
    feats: dict[str, np.ndarray], targets: dict[str, np.ndarray], tasks: Sequence[str]
) -> tuple[dict[tuple[int, str], RidgeFit | KnnFit], list[bool]] | None:
    """Per fraction of :data:`RATIOS`, the ridge or the k-nearest-neighbour regressions of every task,
    whichever has the smaller leave-one-out squared error summed over the tasks -> (fits (ratio index,
    task) -> fit, kinds (R,) True where k-nearest-neighbour), or None when a fit is missing."""
    fits: dict[tuple[int, str], RidgeFit | KnnFit] = {}
    kinds: list[bool] = []
    for r in range(len(RATIOS)):
        ridge_or_none = {t: _fit(feats[t][r], targets[t]) for t in tasks}
        knn_or_none = {t: _fit(feats[t][r], targets[t], knn=True) for t in tasks}
        ridge = {t: f for t, f in ridge_or_none.items() if f is not None}
        knn = {t: f for t, f in knn_or_none.items() if f is not None}
        if len(ridge) < len(ridge_or_none) or len(knn) < len(knn_or_none):
            return None
        sse_r = sum(float(np.sum(f.residuals**2)) for f in ridge.values())
        sse_k = sum(float(np.sum(f.residuals**2)) for f in knn.values())
        use_knn = sse_k < sse_r
        kinds.append(use_knn)
        for t in tasks:
            fits[(r, t)] = knn[t] if use_knn else ridge[t]
    return fits, kinds


def choose_handover(
    training: TrainingSet,
    settings: PhaseSettings,
    coupled: Sequence[str],
    nu_condition: float,
    rows: list[HeldOutRow],
    temperature: float,
    fk: Callable[[np.ndarray], np.ndarray] | None = None,
    fk_rot: FKRot | None = None,
) -> HandoverChoice:
    """Fit the hand-over regressions and choose their features (the coupled groups' window or every
    observed group's) and trust factor by cross-validation (see the module docstring).

    Args:
        training: The training set.
        settings: Phase and covariance settings.
        coupled: The observed groups coupled to the robot (the robot is conditioned on them).
        nu_condition: The conditioning noise ratio of the robot's weights.
        rows: The held-out observations of :func:`~ipromp_pin.promp.selection.choose_noise` (their
            log likelihood at the chosen noise ratio).
        temperature: The chosen likelihood temperature.
        fk: The robot's forward kinematics (joint angles (n, J) in [rad] -> positions (n, 3) in [m]).
        fk_rot: The gripper's rotations (joint angles -> rotation matrices (n, 3, 3)); with ``fk``,
            the orientation estimate is fitted and its trust chosen on the same held-out rows, with
            the chosen regression applied (:func:`~ipromp_pin.promp.orientation_selection.
            choose_orientation`).

    Returns:
        The chosen regression (None: "off") and the CV errors of the trust factors with the chosen
        features; the orientation estimate and its CV errors.
    """
    layout = training.layout
    if not layout.dims(list(coupled)).size:  # the robot is independent of the human: nothing to fuse
        return HandoverChoice(None, {})
    tasks = training.tasks
    q_end = final_configurations(training)
    readout = readouts(np.stack([q_end[t].mean(axis=0) for t in tasks]), fk)
    targets = readout_targets(q_end, readout, tasks, fk)
    candidates: list[
        tuple[np.ndarray, dict[str, np.ndarray], dict[tuple[int, str], RidgeFit | KnnFit], list[bool]]
    ] = []
    for groups in (list(coupled), list(layout.observe)):
        dims = layout.dims(groups)
        if dims.size == 0 or any(np.array_equal(dims, c[0]) for c in candidates):
            continue
        feats = _features(training, dims)
        chosen = _choose_kinds(feats, targets, tasks)
        if chosen is not None:
            candidates.append((dims, feats, *chosen))
    if not candidates:
        return HandoverChoice(None, {})
    held = _held_out_predictions(training, settings, coupled, nu_condition, rows, temperature)
    best = None
    for dims, feats, fits, kinds in candidates:
        nested: dict[tuple[int, str, int], Refit | None] = {}
        scores = _cross_validate(
            training, held, readout, fk, dims, feats, fits, kinds, q_end, targets, nested
        )
        if scores and (best is None or min(scores.values()) < min(best[4].values())):
            best = (dims, feats, fits, kinds, scores, nested)
    if best is None:
        return HandoverChoice(None, {})
    dims, feats, fits, kinds, scores, nested = best
    trust = min(scores, key=lambda v: scores[v])
    orientation, orientation_scores = None, {}
    if fk is not None and fk_rot is not None:
        final = _final_rows(training, held, readout, dims, feats, fits, kinds, targets, trust, nested)
        picked = choose_orientation(final, q_end, tasks, fk, fk_rot)
        orientation, orientation_scores = picked.estimate, picked.scores
    if not np.isfinite(trust):
        return HandoverChoice(None, scores, orientation, orientation_scores)
    n_ratio, n_task = len(RATIOS), len(tasks)
    m = readout.shape[1]
    n_feat = 2 * dims.size
    coef = np.stack(
        [
            np.stack([getattr(fits[(r, t)], "coef", np.zeros((m, n_feat))) for t in tasks])
            for r in range(n_ratio)
        ]
    )
    intercept = np.stack(
        [np.stack([getattr(fits[(r, t)], "intercept", np.zeros(m)) for t in tasks]) for r in range(n_ratio)]
    )
    cov = np.stack([_pooled([fits[(r, t)].residuals for t in tasks]) for r in range(n_ratio)])
    extra = (
        neighbour_arrays([[fits[(r, t)] for t in tasks] for r in range(n_ratio)], m, n_feat)
        if any(kinds)
        else {}
    )
    regression = HandoverRegression(
        ratios=np.asarray(RATIOS, dtype=float),
        dims=np.asarray(dims, dtype=np.int64),
        readout=readout,
        coef=coef.reshape(n_ratio, n_task, m, -1),
        intercept=intercept,
        residual_cov=cov,
        trust=float(trust),
        **extra,
    )
    return HandoverChoice(regression, scores, orientation, orientation_scores)


def _pooled(residuals: list[np.ndarray]) -> np.ndarray:
    """The second moment (M, M) of the leave-one-out residuals of every task (a small ridge keeps it
    positive definite)."""
    e = np.concatenate(residuals)
    cov = e.T @ e / e.shape[0]
    return cov + 1e-9 * max(float(np.trace(cov)) / cov.shape[0], 1e-12) * np.eye(cov.shape[0])


Refit = tuple[RidgeFit | KnnFit, np.ndarray]
"""A leave-one-out refit of a regression and its pooled residual second moment (M, M) (the other
tasks' residuals with the refit's)."""


@dataclass(frozen=True)
class _HeldOutPrediction:
    """The leave-one-out robot prediction of one held-out row: its demo (task, index), the window
    (3 D_o,), the estimated observed fraction, the conditioned final configuration's mean (J,) in
    [rad] and covariance (J, J) in [rad^2]."""

    task: str
    index: int
    window: np.ndarray
    fraction: float
    mean: np.ndarray
    cov: np.ndarray


def _held_out_predictions(
    training: TrainingSet,
    settings: PhaseSettings,
    coupled: Sequence[str],
    nu_condition: float,
    rows: list[HeldOutRow],
    temperature: float,
) -> list[_HeldOutPrediction]:
    """The robot conditioned as online on every held-out row (its task's MAP phase under the
    leave-one-out model, the chosen coupling and conditioning noise ratio, the leave-one-out
    covariance); rows without a phase or observation are left out."""
    layout = training.layout
    tasks = training.tasks
    rs = layout.robot_slice
    scale, offset = training.scaler.scale[rs], training.scaler.offset[rs]
    phi_end = training.basis(np.array([1.0]))[0]
    encoder = ObservationEncoder(layout, training.scaler, np.inf)
    folds = held_out(training.demos)
    blocks = coupling_blocks(layout, coupled)
    prior: RobotPrior | None = None  # the leave-one-out distribution of the current demo
    cov_demo = -1
    out = []
    for row in rows:
        task, i = folds[row.demo]
        k = tasks.index(task)
        alpha = float(row.recognised(temperature)[2][k])
        if not np.isfinite(alpha) or alpha <= 0.0:
            continue
        fraction = row.t_last / (alpha * training.duration_nominal_s)
        if prior is None or row.demo != cov_demo:  # the rows of a demo are consecutive
            keep = np.arange(len(training.demos[task])) != i
            weights = [training.weights[t][keep] if t == task else training.weights[t] for t in tasks]
            # the robot's block first: the others' factors are not needed
            cov = shrink_covariances(weights, settings.pooling, blocks, [k], training.cache, [0])[0]
            prior = robot_prior(cov.mean, cov.diag, cov.factor, rs)
            cov_demo = row.demo
        obs = cv_observations(encoder, training.demos[task][i], [row.ratio], training.encoded)
        if not obs:
            continue
        _, parts, _ = obs[0]
        spectrum = part_spectrum(training.basis, parts, alpha * training.duration_nominal_s)
        path = robot_paths(spectrum, parts, [nu_condition], [prior])[0]
        mean = (path.mean[0] @ phi_end) * scale + offset  # (J,) [rad]
        s_cov = path.readout_cov(phi_end)[0] * scale[:, None] * scale[None, :]
        out.append(_HeldOutPrediction(task, i, np.asarray(row.window, dtype=float), fraction, mean, s_cov))
    return out


def _loo_observation(
    h: _HeldOutPrediction,
    tasks: Sequence[str],
    dims: np.ndarray,
    feats: dict[str, np.ndarray],
    fits: dict[tuple[int, str], RidgeFit | KnnFit],
    kinds: list[bool],
    targets: dict[str, np.ndarray],
    nested: dict[tuple[int, str, int], Refit | None],
) -> tuple[np.ndarray, np.ndarray] | None:
    """The regression's prediction (M,) and noise covariance (M, M) for held-out row ``h``: refitted
    without its demo (``nested`` caches the refits), interpolated at its estimated fraction; None when
    a refit has too few demos."""
    j, w = interpolation(list(RATIOS), h.fraction)
    x = window_features(h.window, dims)
    m = next(iter(targets.values())).shape[1]
    pred, noise = np.zeros(m), np.zeros((m, m))
    for level, weight in ((j, 1.0 - w), (j + 1, w)):
        if weight <= 0.0:
            continue
        key = (level, h.task, h.index)
        if key not in nested:
            fit = _fit(feats[h.task][level], targets[h.task], drop=h.index, knn=kinds[level])
            others = [fits[(level, t)].residuals for t in tasks if t != h.task]
            nested[key] = None if fit is None else (fit, _pooled([*others, fit.residuals]))
        refit = nested[key]
        if refit is None:
            return None
        pred += weight * refit[0].predict(x)
        noise += weight * refit[1]
    return pred, noise


def _final_rows(
    training: TrainingSet,
    held: list[_HeldOutPrediction],
    readout: np.ndarray,
    dims: np.ndarray,
    feats: dict[str, np.ndarray],
    fits: dict[tuple[int, str], RidgeFit | KnnFit],
    kinds: list[bool],
    targets: dict[str, np.ndarray],
    trust: float,
    nested: dict[tuple[int, str, int], Refit | None],
) -> list[FinalRow]:
    """The held-out final configurations as online with the chosen regression (trust ``trust``;
    ``inf``: off) applied by exact conditioning, its leave-one-out refits taken from ``nested`` (the
    cross-validation's); rows whose regression cannot be refitted are left out."""
    tasks = training.tasks
    out = []
    for h in held:
        if not np.isfinite(trust):
            out.append(FinalRow(h.task, h.index, h.mean, h.cov))
            continue
        obs = _loo_observation(h, tasks, dims, feats, fits, kinds, targets, nested)
        if obs is None:
            continue
        pred, noise = obs
        a = readout[tasks.index(h.task)]
        mean, cov = conditioned(a, pred, trust * noise, h.mean, h.cov)
        out.append(FinalRow(h.task, h.index, mean, cov))
    return out


def _cross_validate(
    training: TrainingSet,
    held: list[_HeldOutPrediction],
    readout: np.ndarray,
    fk: Callable[[np.ndarray], np.ndarray] | None,
    dims: np.ndarray,
    feats: dict[str, np.ndarray],
    fits: dict[tuple[int, str], RidgeFit | KnnFit],
    kinds: list[bool],
    q_end: dict[str, np.ndarray],
    targets: dict[str, np.ndarray],
    nested: dict[tuple[int, str, int], Refit | None],
) -> dict[float, float]:
    """Candidate trust factor -> CV error (``inf``: off) of the regression on the features of
    ``dims`` (final configurations ``q_end``, regression targets ``targets``; ``nested`` caches the
    leave-one-out refits, for :func:`_final_rows` to reuse); empty when no row could be scored."""
    tasks = training.tasks
    trusts = np.asarray(TRUST_GRID, dtype=float)
    configs, truths = [], []
    for h in held:
        k = tasks.index(h.task)
        obs = _loo_observation(h, tasks, dims, feats, fits, kinds, targets, nested)
        if obs is None:
            continue
        pred, noise = obs
        a = readout[k]
        gain_base = h.cov @ a.T  # (J, M)
        innov = pred - a @ h.mean
        # every trust factor's innovation covariance (n_trust, M, M) solved in one call
        gains = np.linalg.solve(a @ gain_base + trusts[:, None, None] * noise, innov[None, :, None])
        configs.append(np.concatenate([h.mean[None], h.mean + (gain_base @ gains)[:, :, 0]]))
        truths.append(q_end[h.task][h.index])
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
    scores = {np.inf: float(mean_err[0])}
    scores.update({t: float(v) for t, v in zip(TRUST_GRID, mean_err[1:], strict=True)})
    return scores
