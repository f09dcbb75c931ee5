"""Model selection on training demos: noise ratio, temperature, coupling, conditioning noise, head rows.

Both are chosen by leave-one-out cross-validation on the training demos only: every held-out demo
(at most :data:`CV_MAX_FOLDS` in all, spread evenly over tasks and demos) is in turn removed from its
task's model (the pooled covariance target and phase priors are refitted without it), and its first
10 % and 20 % (:data:`CV_RATIOS`) are observed.

Noise ratio and temperature (:func:`choose_noise`). The observation noise of dim ``d`` is
``r_d = nu delta_d`` and the posteriors use the likelihood to the power ``tau``; the score of a
candidate (``nu``, ``tau``) (:data:`NOISE_GRID` x :data:`TEMPERATURE_GRID`) is the mean log
posterior of the held-out demo's true task plus the mean log posterior density of its true phase
(each observation's score clipped at -100). A too-small ``nu`` makes the phase estimate
overconfident (worse than the prior alone); a too-large one ignores the observation. It is chosen on
the fully coupled model. The same held-out demos, observed at :data:`HEAD_RATIOS`, are the training
rows of the recognition head (:func:`fit_recognition_head`, :mod:`~ipromp_pin.promp.head`).

Coupling (:func:`choose_coupling`). Not every observed group need inform the robot: on the hand-over
data the forearm EMG amplitudes differ strongly between repetitions of a task (which is what tells
the tasks apart) but say nothing about where the robot should go, and with 10-20 demos and hundreds
of weights their sample cross-covariance with the robot is mostly noise that the conditioning turns
into prediction error. The model therefore has two independent blocks of dims: the *coupled*
observed groups with the robot, and the remaining observed groups (still modelled, with their
correlations, for recognition and phase), each with its own Ledoit-Wolf shrinkage. The candidates
are the non-empty subsets of the observed groups (:func:`coupling_candidates`); each held-out demo's
task weights are conditioned on its observation (at 10-80 %, :data:`CONDITION_CV_RATIOS`) at its true
phase with every candidate conditioning noise ratio ``nu_c`` (:data:`NOISE_GRID`; each candidate at
its best), and the score is the RMSE in [rad] of the predicted robot trajectory over the unobserved
phases, or with the robot's forward kinematics the hand-over position error in [m]. With 10-20 demos
per task these
scores are noisy, so the one-standard-error rule picks the candidate with the fewest coupled dims
among those whose mean squared error exceeds the best one's by at most :data:`COUPLING_SE` standard
errors of their paired difference. The empty set (the prediction is the prior) is not a candidate:
the conditioning is the point of the model, and on small training sets its CV error ties with the
best coupling's; it can be chosen explicitly (``coupling=[]``).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from itertools import combinations

import numpy as np

from ..data import Demo
from ..exceptions import ModelError, ObservationError
from .distribution import shrink_covariances
from .head import RecognitionHead, fit_head
from .head_features import head_features, observed_fraction
from .likelihood import InferenceEngine
from .noise_path import part_spectrum, robot_paths, robot_prior
from .observation import ObservationEncoder, ObservationPart
from .posterior import PhasePriors, recognise_from_loglik, recognition_terms
from .training import PhaseSettings, TrainingSet, coupling_blocks, task_models
from .window import WindowSummary

NOISE_GRID = (0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0)
"""Candidate noise ratios ``nu`` for ``noise="auto"``."""

TEMPERATURE_GRID = (1.0, 0.5, 0.3, 0.2, 0.1, 0.05, 0.03, 0.02, 0.01)
"""Candidate likelihood temperatures ``tau`` for ``temperature="auto"`` (chosen jointly with ``nu``)."""

CV_RATIOS = (0.1, 0.2)
"""Observed fractions of the held-out demo used by the cross-validations."""

CONDITION_CV_RATIOS = (0.1, 0.2, 0.4, 0.6, 0.8)
"""Observed fractions of the held-out demo at which the robot's prediction is cross-validated (the
coupling and the conditioning noise ratio): the robot is predicted all along the human's motion."""

HEAD_RATIOS = (0.1, 0.2, 0.4, 0.6, 0.8)
"""Observed fractions of the held-out demos on which the recognition head is fitted (it recognises the
task all along the human's motion)."""

CV_MAX_FOLDS = 45
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
    encoder: ObservationEncoder,
    demo: Demo,
    ratios: Sequence[float] = CV_RATIOS,
    cache: dict | None = None,
) -> list[tuple[float, list[ObservationPart], float]]:
    """(observed ratio, encoded parts, last sample time in [s]) of the first ``ratios`` of a
    held-out training demo (ratios the demo is too short for are left out). With ``cache`` (the
    training set's :attr:`~ipromp_pin.promp.training.TrainingSet.encoded`, for encoders of its
    layout and scaling), each (demo, ratio) is encoded once for every cross-validation."""
    out = []
    for ratio in ratios:
        key = (id(demo), float(ratio))
        hit = None if cache is None else cache.get(key)
        if hit is not None and hit[0] is demo:
            if hit[1] is not None:
                out.append((ratio, *hit[1]))
            continue
        try:
            obs = demo.head(ratio, encoder.layout.observe)
        except ObservationError:
            if cache is not None:
                cache[key] = (demo, None)
            continue
        parts, t_last = encoder.encode(obs, check_length=False)
        if cache is not None:
            cache[key] = (demo, (parts, t_last))
        out.append((ratio, parts, t_last))
    return out


def _without(values: Mapping[str, np.ndarray], task: str, keep: np.ndarray) -> dict[str, np.ndarray]:
    """``values`` with the rows of ``task`` restricted to ``keep``."""
    return {**values, task: values[task][keep]}


@dataclass(frozen=True)
class NoiseChoice:
    """What :func:`choose_noise` chose.

    Attributes:
        nu: The noise ratio (1.0 when no demo could be held out).
        temperature: The likelihood temperature ``tau``.
        scores: Candidate ``nu`` -> CV score (at its best ``tau``).
        rows: The held-out observations (at :data:`HEAD_RATIOS`), for the recognition head.
    """

    nu: float
    temperature: float
    scores: dict[float, float]
    rows: list[HeldOutRow] = field(default_factory=list)


@dataclass(frozen=True)
class HeldOutRow:
    """One held-out observation of the noise cross-validation.

    Attributes:
        task: Index of the true task.
        demo: Index of the held-out demo among all held-out demos.
        window: (3 D_o,) its window summary (:class:`~ipromp_pin.promp.window.WindowSummary`).
        ratio: Its observed fraction.
        loglik: The log likelihood (T, C) of the leave-one-out model at the chosen ``nu``.
        priors: The leave-one-out model's phase priors.
        t_last: Time of the last observed sample in [s].
        recognitions: Likelihood temperature -> what :meth:`recognised` returned (its cache).
    """

    task: int
    demo: int
    window: np.ndarray
    ratio: float
    loglik: np.ndarray
    priors: PhasePriors
    t_last: float
    recognitions: dict[float, tuple[np.ndarray, np.ndarray, np.ndarray]] = field(
        default_factory=dict, repr=False, compare=False
    )

    def recognised(self, temperature: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The generative task log posterior, posterior and MAP phases (T,) each of the row at the
        likelihood temperature ``temperature`` (:func:`~ipromp_pin.promp.posterior.recognise_from_loglik`;
        cached: the head and the hand-over regression both read them)."""
        out = self.recognitions.get(temperature)
        if out is None:
            rec, _ = recognise_from_loglik(self.priors, temperature * self.loglik, self.t_last)
            if math.isinf(rec.novelty_score):  # no task explains the row (see explained_rows)
                raise ObservationError(None, "t", rec.unknown_reason or "no task explains it")
            out = self.recognitions[temperature] = (rec.log_posterior, rec.posterior, rec.alpha)
        return out


class UnexplainedRowsWarning(UserWarning):
    """Training went on without held-out rows that no leave-one-out model explains."""


def explained_rows(
    rows: list[HeldOutRow], temperature: float, by_task: Mapping[str, list[Demo]]
) -> list[HeldOutRow]:
    """The held-out rows that some task's leave-one-out model explains at ``temperature``.

    A row no remaining demo's phase range explains (its held-out demo is much longer than every
    other demo of the training set) tells the head and the hand-over estimate nothing; it is left
    out, and an :class:`UnexplainedRowsWarning` says how many and of which demos (``by_task``: the
    training demos the rows were held out of)."""
    kept, dropped = [], []
    for r in rows:
        try:
            r.recognised(temperature)
        except ObservationError:
            dropped.append(r)
            continue
        kept.append(r)
    if dropped:
        folds = held_out(by_task)
        names = sorted(
            {f"{folds[r.demo][0]}/{by_task[folds[r.demo][0]][folds[r.demo][1]].name}" for r in dropped}
        )
        warnings.warn(
            f"{len(dropped)} of the {len(rows)} held-out observations of the recognition head's "
            f"cross-validation (of {', '.join(names)}) are longer than any other demo of the training "
            "set allows; they were left out of the head and the hand-over estimate (is that demo much "
            "slower than the others?)",
            UnexplainedRowsWarning,
            stacklevel=2,
        )
    return kept


def fit_recognition_head(rows: list[HeldOutRow], temperature: float, n_tasks: int) -> RecognitionHead:
    """The recognition head (:func:`~ipromp_pin.promp.head.fit_head`) fitted on the held-out rows with
    the generative posterior at the chosen noise ratio and temperature."""
    feats, fractions = [], []
    for r in rows:
        log_posterior, posterior, alpha = r.recognised(temperature)
        feats.append(head_features(r.window, log_posterior))
        fractions.append(observed_fraction(posterior, alpha, r.t_last, r.priors.duration_nominal_s))
    labels = np.array([r.task for r in rows])
    groups = np.array([r.demo for r in rows])
    ratios = np.array([r.ratio for r in rows])
    return fit_head(np.array(feats), labels, groups, ratios, n_tasks, np.array(fractions))


@dataclass
class _Fold:
    """One held-out demo of :func:`choose_noise`: its leave-one-out task models and observations."""

    task: int
    held: tuple[str, int]  # (task, demo index) of the held-out demo
    priors: PhasePriors
    observations: list  # (ratio, parts, t_last, window summary (3 D_o,))
    logliks: dict  # (observation index, nu) -> log likelihood (T, C)


def _fold_models(training: TrainingSet, settings: PhaseSettings, task: str, i: int) -> list:
    """The task models (in task order) without demo ``i`` of ``task``, all observed groups coupled
    (only the task that lost a demo is re-estimated: ``training.cache``)."""
    keep = np.arange(len(training.demos[task])) != i
    models = task_models(
        training,
        _without(training.weights, task, keep),
        _without(training.alphas, task, keep),
        training.layout.observe,
        settings,
    )
    return [models[t] for t in training.tasks]


def _fold_engine(training: TrainingSet, models: list, nu: float) -> InferenceEngine:
    return InferenceEngine(
        training.basis, models, training.layout.n_obs_dims, training.duration_nominal_s, nu
    )


def _true_task_posterior(
    priors: PhasePriors, loglik: np.ndarray, t_last: float, task: int
) -> tuple[float, np.ndarray]:
    """The log posterior of task ``task`` and its log phase posterior (C,) from the log likelihood
    (T, C): the numbers of :func:`~ipromp_pin.promp.posterior.recognise_from_loglik` (the same compiled
    kernel) without building the recognition (the noise CV scores thousands of them); an observation
    impossible under every task raises its error."""
    _, logpost, _, _, log_post, _, best = recognition_terms(priors, loglik)
    if not math.isfinite(float(log_post[best])):
        raise ObservationError(
            None, "t", f"a held-out observation of {t_last:.2f} s is impossible under every task"
        )
    return float(log_post[task]), logpost[task]


def choose_noise(
    training: TrainingSet,
    settings: PhaseSettings,
    task_log_prior: np.ndarray,
    noise_grid: Sequence[float] = NOISE_GRID,
    temperature_grid: Sequence[float] = TEMPERATURE_GRID,
) -> NoiseChoice:
    """Leave-one-out choice of the noise ratio and of the likelihood temperature (see the module
    docstring) among ``noise_grid`` x ``temperature_grid`` (a one-element grid fixes a value).

    Two passes over the held-out demos: the first scores every candidate on the observations at
    :data:`CV_RATIOS` (few active basis functions: cheap); the second computes the log likelihood
    of the recognition head's rows (:data:`HEAD_RATIOS`) at the chosen ``nu`` only (in the first pass
    already when ``nu`` is given). A fold's models are not kept between the passes (they would hold
    every fold's factors at once): the second pass re-estimates them."""
    encoder = ObservationEncoder(training.layout, training.scaler, np.inf)
    scores = np.zeros((len(noise_grid), len(temperature_grid)))
    n_eval = 0
    folds: list[_Fold] = []
    for task, i in held_out(training.demos):
        ki = training.tasks.index(task)
        ordered = _fold_models(training, settings, task, i)
        m = ordered[ki]
        engine = _fold_engine(training, ordered, noise_grid[0])
        priors = PhasePriors(
            tasks=training.tasks,
            alphas=engine.alphas,
            log_prior=engine.log_prior,
            alpha_mu=np.array([mt.alpha_mu for mt in ordered]),
            task_log_prior=task_log_prior,
            duration_nominal_s=training.duration_nominal_s,
        )
        fold = _Fold(ki, (task, i), priors, [], {})
        folds.append(fold)
        dens_shift = np.log(m.alpha_grid[1] - m.alpha_grid[0])
        alpha_true = training.alphas[task][i]
        scored = []
        for ratio, parts, t_last in cv_observations(
            encoder, training.demos[task][i], HEAD_RATIOS, training.encoded
        ):
            summary = WindowSummary.from_parts(parts, training.layout.n_obs_dims).vector()
            fold.observations.append((ratio, parts, t_last, summary))
            if ratio in CV_RATIOS or len(noise_grid) == 1:
                scored.append((len(fold.observations) - 1, [engine.part_stats(p) for p in parts], t_last))
        engine.reserve_z([st for _, stats, _ in scored for st in stats])
        for n_obs, stats, t_last in scored:
            for j, nu in enumerate(noise_grid):
                loglik = engine.log_likelihood(stats, t_last, nu=nu)
                fold.logliks[(n_obs, j)] = loglik
            if fold.observations[n_obs][0] not in CV_RATIOS:
                continue
            n_eval += 1
            for j in range(len(noise_grid)):
                loglik = fold.logliks[(n_obs, j)]
                for k, tau in enumerate(temperature_grid):
                    s, logpost_true = _true_task_posterior(priors, tau * loglik, t_last, ki)
                    # log posterior density of the true phase (interpolated between candidates)
                    dens = logpost_true - dens_shift
                    s += float(np.interp(alpha_true, m.alpha_grid, dens, left=-50.0, right=-50.0))
                    scores[j, k] += max(float(s), -100.0)
        del engine, ordered, m, scored  # not alive while the next fold's are built (memory)
    if n_eval == 0:
        j, k, best = 0, 0, None
        nu = float(noise_grid[0]) if len(noise_grid) == 1 else 1.0
    else:
        scores /= n_eval
        j, k = (int(v) for v in np.unravel_index(int(np.argmax(scores)), scores.shape))
        best = scores.max(axis=1)
        nu = float(noise_grid[j])
    rows: list[HeldOutRow] = []
    for n_demo, fold in enumerate(folds):
        todo = [n for n in range(len(fold.observations)) if (n, j) not in fold.logliks]
        if todo:
            fold_engine = _fold_engine(training, _fold_models(training, settings, *fold.held), nu)
            todo_stats = {n: [fold_engine.part_stats(p) for p in fold.observations[n][1]] for n in todo}
            fold_engine.reserve_z([st for sts in todo_stats.values() for st in sts])
            for n in todo:
                t_obs = fold.observations[n][2]
                fold.logliks[(n, j)] = fold_engine.log_likelihood(todo_stats[n], t_obs, nu=nu)
            del fold_engine, todo_stats  # not alive while the next fold's are built (memory)
        for n_obs, (ratio, _, t_last, summary) in enumerate(fold.observations):
            loglik = fold.logliks[(n_obs, j)]
            rows.append(HeldOutRow(fold.task, n_demo, summary, ratio, loglik, fold.priors, t_last))
        fold.logliks.clear()
    if best is None:
        return NoiseChoice(nu, float(temperature_grid[0]), {}, rows)
    return NoiseChoice(
        nu,
        float(temperature_grid[k]),
        {float(v): float(b) for v, b in zip(noise_grid, best, strict=True)},
        rows,
    )


def coupling_candidates(observe: Sequence[str]) -> list[list[str]]:
    """Candidate coupled groups: every non-empty subset of the observed groups, largest first (all
    groups first); with more than :data:`COUPLING_MAX_GROUPS` groups only all, all but one, and one."""
    n = len(observe)
    sizes = range(n, 0, -1) if n <= COUPLING_MAX_GROUPS else [n, n - 1, 1]
    return [[g for g in observe if g in c] for size in sizes for c in combinations(observe, size)]


@dataclass(frozen=True)
class CouplingChoice:
    """What :func:`choose_coupling` chose.

    Attributes:
        groups: The observed groups coupled to the robot.
        scores: With more than one candidate, every candidate's (``"+"``-joined) CV RMSE of the robot
            prediction in [rad] (at its best conditioning noise ratio).
        nu_condition: The conditioning noise ratio ``nu_c`` (the given one when not chosen).
        nu_scores: Candidate ``nu_c`` -> CV RMSE in [rad] with the chosen groups (empty when given).
    """

    groups: list[str]
    scores: dict[str, float]
    nu_condition: float
    nu_scores: dict[float, float]


def choose_coupling(
    training: TrainingSet,
    settings: PhaseSettings,
    noise_ratio: float | None,
    candidates: list[list[str]] | None = None,
    fk: Callable[[np.ndarray], np.ndarray] | None = None,
) -> CouplingChoice:
    """Leave-one-out choice of the observed groups coupled to the robot and of the conditioning noise
    ratio (see the module docstring).

    Args:
        training: The training set.
        settings: Phase and covariance settings.
        noise_ratio: The conditioning noise ratio ``nu_c``, or None to choose it among
            :data:`NOISE_GRID` (jointly with the groups).
        candidates: The candidate coupled groups (default :func:`coupling_candidates`).
        fk: The robot's forward kinematics, joint angles (n, J) in [rad] -> hand-over (gripper)
            positions (n, 3) in [m]: when given, the score is the hand-over position error at the end
            of the motion (what a hand-over needs: joint errors in the arm's null space do not count)
            instead of the joint RMSE over the unobserved phases.
    """
    layout = training.layout
    cands = coupling_candidates(layout.observe) if candidates is None else candidates
    nus = NOISE_GRID if noise_ratio is None else (float(noise_ratio),)
    if len(cands) == 1 and len(nus) == 1:
        return CouplingChoice(list(cands[0]), {}, nus[0], {})
    encoder = ObservationEncoder(layout, training.scaler, np.inf)
    rs = layout.robot_slice
    scale = training.scaler.scale[rs]
    offset = training.scaler.offset[rs]
    # the basis at the unobserved phases of each observed fraction (K values at CV_PHASES phases)
    phis = {r: training.basis(np.linspace(r, 1.0, CV_PHASES)) for r in CONDITION_CV_RATIOS}
    rows = []  # per held-out observation, the MSE of every (candidate, nu_c) in [rad^2]
    ends = []  # with fk: per held-out observation, the final robot configurations in [rad]
    for task, i in held_out(training.demos):
        keep = np.arange(len(training.demos[task])) != i
        weights = [training.weights[t][keep] if t == task else training.weights[t] for t in training.tasks]
        ki = [training.tasks.index(task)]
        blocks = [coupling_blocks(layout, c) for c in cands]  # the robot's block first: only its factor
        covs = [shrink_covariances(weights, settings.pooling, b, ki, training.cache, [0])[0] for b in blocks]
        priors = [robot_prior(c.mean, c.diag, c.factor, rs) for c in covs]
        del covs  # only the factor columns that load on the robot are kept (memory)
        alpha = float(training.alphas[task][i])
        w_true = training.weights[task][i][rs]
        for ratio, parts, _ in cv_observations(
            encoder, training.demos[task][i], CONDITION_CV_RATIOS, training.encoded
        ):
            phi = phis[ratio]
            spectrum = part_spectrum(training.basis, parts, alpha * training.duration_nominal_s)
            # (candidates, nu_c, J, K) conditioned robot weights
            ws = np.stack([path.mean for path in robot_paths(spectrum, parts, nus, priors)])
            if fk is None:  # mean squared joint error over the unobserved phases [rad^2]
                errs = ((ws - w_true) @ phi.T) * scale[:, None]  # (candidates, nu_c, J, phases)
                rows.append(np.mean(errs * errs, axis=(2, 3)).ravel())
            else:  # final configurations, the true one first
                ends.append(
                    np.concatenate([(phi[-1] @ w_true.T)[None], (ws @ phi[-1]).reshape(-1, scale.size)])
                )
    if fk is not None and ends:  # squared hand-over position errors [m^2]
        n_conf = ends[0].shape[0]
        p_end = fk(np.concatenate(ends) * scale + offset).reshape(len(ends), n_conf, -1)
        rows = list(np.sum((p_end[:, 1:] - p_end[:, :1]) ** 2, axis=2))
    if not rows:
        return CouplingChoice(list(layout.observe), {}, 1.0 if noise_ratio is None else nus[0], {})
    per_nu = np.array(rows).reshape(len(rows), len(cands), len(nus))
    # every candidate at its best nu_c
    best_nu = per_nu.mean(axis=0).argmin(axis=1)
    mse = per_nu[:, np.arange(len(cands)), best_nu]
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
    scores = {"+".join(c): float(v) for c, v in zip(cands, rmse, strict=True)} if len(cands) > 1 else {}
    nu_rmse = np.sqrt(per_nu[:, chosen, :].mean(axis=0))
    nu_scores = {float(nu): float(v) for nu, v in zip(nus, nu_rmse, strict=True)}
    if noise_ratio is not None:
        nu_scores = {}
    return CouplingChoice(list(cands[chosen]), scores, float(nus[best_nu[chosen]]), nu_scores)
