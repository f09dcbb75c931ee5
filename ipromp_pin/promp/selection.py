"""Model selection on training demos: the observation-noise ratio and the groups coupled to the robot.

Both are chosen by leave-one-out cross-validation on the training demos only: every held-out demo
(at most :data:`CV_MAX_FOLDS` in all, spread evenly over tasks and demos) is in turn removed from its
task's model (the pooled covariance target and phase priors are refitted without it), and its first
10 % and 20 % (:data:`CV_RATIOS`) are observed.

Noise ratio (:func:`choose_noise`). The observation noise of dim ``d`` is ``r_d = nu delta_d``; the
score of a candidate ``nu`` (:data:`NOISE_GRID`) is the mean log posterior of the held-out demo's true
task plus the mean log posterior density of its true phase (each observation's score clipped at
-100). A too-small ``nu`` makes the phase estimate overconfident (worse than the prior alone); a
too-large one ignores the observation. It is chosen on the fully coupled model.

Coupling (:func:`choose_coupling`). Not every observed group need inform the robot: on the hand-over
data the forearm EMG amplitudes differ strongly between repetitions of a task (which is what tells
the tasks apart) but say nothing about where the robot should go, and with 10-20 demos and hundreds
of weights their sample cross-covariance with the robot is mostly noise that the conditioning turns
into prediction error. The model therefore has two independent blocks of dims: the *coupled*
observed groups with the robot, and the remaining observed groups (still modelled, with their
correlations, for recognition and phase), each with its own Ledoit-Wolf shrinkage. The candidates
are the non-empty subsets of the observed groups (:func:`coupling_candidates`); each held-out demo's
task weights are conditioned on its observation at its true phase, and the score is the RMSE in
[rad] of the predicted robot trajectory over the unobserved phases. With 10-20 demos per task these
scores are noisy, so the one-standard-error rule picks the candidate with the fewest coupled dims
among those whose mean squared error exceeds the best one's by at most :data:`COUPLING_SE` standard
errors of their paired difference. The empty set (the prediction is the prior) is not a candidate:
the conditioning is the point of the model, and on small training sets its CV error ties with the
best coupling's; it can be chosen explicitly (``coupling=[]``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from itertools import combinations

import numpy as np

from ..data import Demo
from ..exceptions import ModelError, ObservationError
from .conditioning import robot_posterior_mean
from .distribution import shrink_covariances
from .likelihood import InferenceEngine
from .observation import ObservationEncoder, ObservationPart
from .posterior import PhasePriors, recognise_from_loglik
from .training import PhaseSettings, TrainingSet, coupling_blocks, task_models

NOISE_GRID = (0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0)
"""Candidate noise ratios ``nu`` for ``noise="auto"``."""

CV_RATIOS = (0.1, 0.2)
"""Observed fractions of the held-out demo used by the cross-validations."""

CV_MAX_FOLDS = 30
"""Largest number of held-out demos of the cross-validations (spread evenly over tasks and demos)."""

CV_PHASES = 50
"""Phases of the unobserved part of the motion at which the coupling cross-validation compares the
robot's predicted and true trajectories."""

COUPLING_SE = 1.0
"""Candidates within this many standard errors of the best CV error count as equally good (the one with
the fewest coupled dims is chosen)."""

COUPLING_MAX_GROUPS = 4
"""Up to this many observed groups, ``coupling="auto"`` tries every subset of them."""


def held_out(by_task: Mapping[str, list[Demo]]) -> list[tuple[str, int]]:
    """(task, demo index) of the demos held out by the cross-validations: at most
    :data:`CV_MAX_FOLDS` in all, spread evenly over the tasks with >= 3 demos and over their demos."""
    per_task = max(1, -(-CV_MAX_FOLDS // len(by_task)))
    out = []
    for task, demos in by_task.items():
        if len(demos) < 3:
            continue
        n_held = min(per_task, len(demos))
        held = np.unique(np.linspace(0, len(demos) - 1, n_held).round().astype(int))
        out += [(task, int(i)) for i in held]
    return out


def cv_observations(
    encoder: ObservationEncoder, demo: Demo
) -> list[tuple[float, list[ObservationPart], float]]:
    """(observed ratio, encoded parts, last sample time in [s]) of the first :data:`CV_RATIOS` of a
    held-out training demo (ratios the demo is too short for are left out)."""
    out = []
    for ratio in CV_RATIOS:
        try:
            obs = demo.head(ratio, encoder.layout.observe)
        except ObservationError:
            continue
        parts, t_last = encoder.encode(obs, check_length=False)
        out.append((ratio, parts, t_last))
    return out


def _without(values: Mapping[str, np.ndarray], task: str, keep: np.ndarray) -> dict[str, np.ndarray]:
    """``values`` with the rows of ``task`` restricted to ``keep``."""
    return {**values, task: values[task][keep]}


def choose_noise(
    training: TrainingSet, settings: PhaseSettings, task_log_prior: np.ndarray
) -> tuple[float, dict[float, float]]:
    """Leave-one-out choice of the noise ratio among :data:`NOISE_GRID` (see the module docstring).

    Returns:
        The chosen ``nu`` (1.0 when no demo could be held out) and every candidate's score.
    """
    encoder = ObservationEncoder(training.layout, training.scaler, np.inf)
    scores = np.zeros(len(NOISE_GRID))
    n_eval = 0
    everything = training.layout.observe
    for task, i in held_out(training.demos):
        ki = training.tasks.index(task)
        keep = np.arange(len(training.demos[task])) != i
        models = task_models(
            training,
            _without(training.weights, task, keep),
            _without(training.alphas, task, keep),
            everything,
            settings,
        )
        ordered = [models[t] for t in training.tasks]
        m = models[task]
        engine = InferenceEngine(
            training.basis, ordered, training.layout.n_obs_dims, training.duration_nominal_s, NOISE_GRID[0]
        )
        priors = PhasePriors(
            tasks=training.tasks,
            alphas=engine.alphas,
            log_prior=engine.log_prior,
            alpha_mu=np.array([mt.alpha_mu for mt in ordered]),
            task_log_prior=task_log_prior,
            duration_nominal_s=training.duration_nominal_s,
        )
        dens_shift = np.log(m.alpha_grid[1] - m.alpha_grid[0])
        alpha_true = training.alphas[task][i]
        for _, parts, t_last in cv_observations(encoder, training.demos[task][i]):
            stats = [engine.part_stats(p) for p in parts]
            n_eval += 1
            for j, nu in enumerate(NOISE_GRID):
                loglik = engine.log_likelihood(stats, t_last, nu=nu)
                rec, logpost = recognise_from_loglik(priors, loglik, t_last)
                s = rec.log_posterior[ki]
                # log posterior density of the true phase (interpolated between candidates)
                dens = logpost[ki] - dens_shift
                s += float(np.interp(alpha_true, m.alpha_grid, dens, left=-50.0, right=-50.0))
                scores[j] += max(float(s), -100.0)
    if n_eval == 0:
        return 1.0, {}
    scores /= n_eval
    best = int(np.argmax(scores))
    return float(NOISE_GRID[best]), {float(nu): float(v) for nu, v in zip(NOISE_GRID, scores, strict=True)}


def coupling_candidates(observe: Sequence[str]) -> list[list[str]]:
    """Candidate coupled groups: every non-empty subset of the observed groups, largest first (all
    groups first); with more than :data:`COUPLING_MAX_GROUPS` groups only all, all but one, and one."""
    n = len(observe)
    sizes = range(n, 0, -1) if n <= COUPLING_MAX_GROUPS else [n, n - 1, 1]
    return [[g for g in observe if g in c] for size in sizes for c in combinations(observe, size)]


def choose_coupling(
    training: TrainingSet, settings: PhaseSettings, noise_ratio: float
) -> tuple[list[str], dict[str, float]]:
    """Leave-one-out choice of the observed groups coupled to the robot (see the module docstring).

    Returns:
        The chosen groups and, with more than one candidate, every candidate's (``"+"``-joined) CV
        RMSE of the robot prediction in [rad].
    """
    layout = training.layout
    cands = coupling_candidates(layout.observe)
    if len(cands) == 1:
        return cands[0], {}
    encoder = ObservationEncoder(layout, training.scaler, np.inf)
    rs = layout.robot_slice
    scale = training.scaler.scale[rs]
    rows = []  # per held-out observation, the mean squared error of every candidate in [rad^2]
    for task, i in held_out(training.demos):
        keep = np.arange(len(training.demos[task])) != i
        weights = [training.weights[t][keep] if t == task else training.weights[t] for t in training.tasks]
        ki = [training.tasks.index(task)]
        covs = [
            shrink_covariances(weights, settings.pooling, coupling_blocks(layout, c), ki)[0] for c in cands
        ]
        alpha = float(training.alphas[task][i])
        w_true = training.weights[task][i][rs]
        for ratio, parts, _ in cv_observations(encoder, training.demos[task][i]):
            phi = training.basis(np.linspace(ratio, 1.0, CV_PHASES))
            row = []
            for cov in covs:
                w = robot_posterior_mean(
                    training.basis, rs, training.duration_nominal_s, noise_ratio,
                    cov.mean, cov.diag, cov.factor, parts, alpha,
                )  # fmt: skip
                err = (phi @ (w - w_true).T) * scale
                row.append(float(np.mean(err * err)))
            rows.append(row)
    if not rows:
        return list(layout.observe), {}
    mse = np.array(rows)
    mean = mse.mean(axis=0)
    if not np.all(np.isfinite(mean)):
        raise ModelError(
            "the cross-validation of the coupling gave non-finite errors (implausible training data?)"
        )
    best = int(np.argmin(mean))
    # one-standard-error rule: the fewest coupled dims whose error is within one standard error
    # (of its paired difference to the best, over the same held-out observations) of the best
    diff = mse - mse[:, [best]]
    se = diff.std(axis=0, ddof=1) / np.sqrt(len(rows)) if len(rows) > 1 else np.zeros(len(cands))
    size = [layout.size(c) for c in cands]
    ok = [j for j in range(len(cands)) if mean[j] - mean[best] <= COUPLING_SE * se[j]]
    chosen = min(ok, key=lambda j: (size[j], mean[j]))
    rmse = np.sqrt(mean)
    return cands[chosen], {"+".join(c): float(v) for c, v in zip(cands, rmse, strict=True)}
