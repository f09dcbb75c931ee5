"""A task added to a fitted model from a few demos, without re-fitting the tasks it already knows.

:func:`add_task` fits the new task's weight distribution and phase prior with the model's own channel
layout, scaling, basis and nominal duration, and appends it to the model. What is kept and what is
new, and why:

* **kept** — the scaling, the basis and ``T_norm`` (the new demos are encoded as the fitted ones
  were); the noise ratio ``nu``, the temperature ``tau``, the coupled groups and ``nu_c`` (chosen by
  cross-validations over the fitted tasks' demos, which the model does not hold; re-choosing them
  would also change the fitted tasks' predictions); every fitted task's distribution, and the shared
  covariance diagonal and shrinkage intensities the new task's covariance is built with
  (:func:`~ipromp_pin.promp.distribution.added_task_covariance`), so the fitted tasks predict exactly
  as before;
* **phase candidates** — the new task's on the fitted tasks' lattice when its support fits in their
  number of candidates; otherwise every task's candidates are rebuilt from the (unchanged) phase
  priors on a lattice that holds the new support too (the fitted tasks' phase estimates then move
  by at most a lattice step);
* **recognition head** — kept for the fitted tasks only: the generative posterior decides between
  the fitted tasks and the added ones, the head shares the fitted tasks' part among them
  (:meth:`~ipromp_pin.promp.predictor.Predictor.recognition_from_loglik`). A head over every task
  needs held-out rows of the fitted tasks, i.e. their demos: a full refit;
* **hand-over regression and orientation estimate** — not used for an added task (they are fitted
  on leave-one-out rows of every task); its robot prediction is the conditioned ProMP alone;
* **novelty detector** — the new task gets its own Gaussians on its demos' windows with the fitted
  feature set and shrinkage, and its rows join the conformal calibration
  (:func:`~ipromp_pin.promp.novelty.with_added_task`); with fewer than
  :data:`~ipromp_pin.promp.novelty.MIN_TASK_ROWS` demos the model has no novelty detector after the
  addition (every observation some task explains is known), which :func:`add_task` warns about;
* **task prior** — uniform over every task when the fit's was; a model fitted with an explicit
  ``task_prior`` needs the new task's prior (``task_prior`` argument).
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Mapping, Sequence

import numpy as np

from ..data import Demo
from ..exceptions import DataError
from .distribution import (
    ShrinkageCache,
    ShrunkCovariance,
    TaskModel,
    added_task_covariance,
    alpha_candidates,
    alpha_prior,
    candidate_lattice,
    lattice_candidates,
    phase_support,
)
from .fitted import FittedModel
from .gripper_side import added_demos
from .novelty import NoveltyRow, with_added_task
from .predictor import Predictor
from .provenance import demo_digest, demo_record
from .training import check_distinct, coupling_blocks, demo_weights, log_task_prior
from .window import WindowSummary

__all__ = ["ADDED_POOLING_GRID", "NoveltyDroppedWarning", "add_task", "choose_pooling"]

ADDED_POOLING_GRID = (0.0, 0.5, 1.0)
"""Candidate weights of the covariance pooled over every task in an added task's covariance."""

CV_FRACTIONS = (0.2,)
"""Observed fractions of a held-out demo in the added task's leave-one-out choice of its pooling."""


class NoveltyDroppedWarning(UserWarning):
    """The model lost its novelty detector when a task was added from too few demos."""


def add_task(
    fitted: FittedModel,
    demos: Sequence[Demo],
    params: Mapping,
    task_prior: Mapping[str, float] | None = None,
) -> FittedModel:
    """``fitted`` with one more task, learned from ``demos`` (see the module docstring).

    Args:
        fitted: The fitted model.
        demos: The new task's demos (at least 2, all of one task that the model does not know), with
            the model's observed groups and its robot group.
        params: The estimator's parameters (``IProMP.get_params()``: ``n_alpha``, ``alpha_width``,
            ``pooling``, ``task_prior``).
        task_prior: Task -> prior probability over every task (needed when the fit had one).

    Raises:
        DataError: the demos are not one new task's, or lack a modelled group.
    """
    task = _check_demos(fitted, demos)
    if params.get("task_prior") is not None and task_prior is None:
        raise DataError(
            None, "task_prior", f"the model was fitted with a task prior: give the prior of '{task}'"
        )
    layout = fitted.layout
    given = list(demos)
    demos = [layout.aligned(d) for d in added_demos(fitted, given)]
    weights = np.stack([demo_weights(layout, fitted.basis, fitted.scaler, d)[0] for d in demos])
    alphas = np.array([d.t[-1] - d.t[0] for d in demos]) / fitted.duration_nominal_s
    settings = (int(params["n_alpha"]), float(params["alpha_width"]))
    pooling = choose_pooling(fitted, demos, weights, alphas, settings)[0]
    grown = _grown(fitted, task, weights, alphas, pooling, settings, task_prior)
    records = None if fitted.trained_on is None else (*fitted.trained_on, *map(demo_record, given))
    grown = dataclasses.replace(grown, trained_on=records)
    if fitted.novelty is not None:
        rows = _novelty_rows(grown, demos, fitted.novelty.ratios)
        novelty = with_added_task(fitted.novelty, rows, fitted.duration_nominal_s)
        if novelty is None:
            warnings.warn(
                f"task '{task}' was added from {len(demos)} demos, too few to model it for the open-set "
                "recognition: the model has no novelty detector now (every observation some task "
                "explains is known)",
                NoveltyDroppedWarning,
                stacklevel=3,
            )
        grown = dataclasses.replace(grown, novelty=novelty)
    return grown


def _grown(
    fitted: FittedModel,
    task: str,
    weights: np.ndarray,
    alphas: np.ndarray,
    pooling: float,
    settings: tuple[int, float],
    task_prior: Mapping[str, float] | None = None,
) -> FittedModel:
    """``fitted`` with the task ``task`` of demos' weights (N, D, K) and phases (N,), its covariance
    pooled with weight ``pooling``, without a novelty detector."""
    cov = _added_covariance(fitted, weights, pooling)
    models = _with_candidates(fitted, alpha_prior(alphas), *settings, task, cov, weights, alphas)
    tasks = (*fitted.tasks, task)
    return dataclasses.replace(
        fitted,
        tasks=tasks,
        models=models,
        task_log_prior=log_task_prior(tasks, task_prior),
        added_tasks=(*fitted.added_tasks, task),
        novelty=None,
    )


def _added_covariance(
    fitted: FittedModel, weights: np.ndarray, pooling: float, cache: ShrinkageCache | None = None
) -> ShrunkCovariance:
    """The covariance of a task of weights (N, D, K) added to ``fitted`` with ``pooling``
    (:func:`~ipromp_pin.promp.distribution.added_task_covariance`: the fitted tasks' diagonal and
    intensities, their coupling blocks)."""
    first = fitted.models[fitted.tasks[0]]
    fitted_weights = [m.train_weights for m in fitted.task_models()]
    blocks = coupling_blocks(fitted.layout, fitted.coupled_groups)
    return added_task_covariance(fitted_weights, weights, pooling, blocks, first.diag, first.shrinkage, cache)


def choose_pooling(
    fitted: FittedModel,
    demos: list[Demo],
    weights: np.ndarray,
    alphas: np.ndarray,
    settings: tuple[int, float],
) -> tuple[float, dict[float, float]]:
    """The new task's covariance pooling among :data:`ADDED_POOLING_GRID`, by leave-one-out on its
    demos: the largest mean log evidence per observed second of a held-out demo's first
    :data:`CV_FRACTIONS` under the task learned from the others (with fewer than 3 demos: 1, the
    pooled covariance, as one demo left gives no spread). Returns the choice and every candidate's
    score."""
    if len(demos) < 3:
        return 1.0, {}
    observe = fitted.layout.observe
    cache = ShrinkageCache([m.train_weights for m in fitted.task_models()])  # the fitted tasks' statistics
    scores = {}
    for pooling in ADDED_POOLING_GRID:
        total = []
        for i, d in enumerate(demos):
            keep = np.arange(len(demos)) != i
            cov = _added_covariance(fitted, weights[keep], pooling, cache)
            prior = alpha_prior(alphas[keep])
            cands = alpha_candidates([prior], *settings)[0]
            alone = TaskModel.from_estimate("held-out", cov, prior, cands, weights[keep], alphas[keep])
            one = dataclasses.replace(
                fitted, tasks=("held-out",), models={"held-out": alone}, task_log_prior=np.zeros(1),
                head=None, handover=None, orientation=None, novelty=None, added_tasks=(),
            )  # fmt: skip
            predictor = Predictor(one, 2)  # the held-out task alone: its evidence
            for ratio in CV_FRACTIONS:
                parts, t_last = predictor.encode(d.head(ratio, observe))
                evidence = float(predictor.recognise(parts, t_last).log_evidence[0])
                total.append(evidence / max(t_last, 1e-9))
        scores[pooling] = float(np.mean(total))
    return max(scores, key=lambda b: (scores[b], -b)), scores


def _check_demos(fitted: FittedModel, demos: Sequence[Demo]) -> str:
    """The new task's name, after checking that ``demos`` are at least 2 distinct demos of one task the
    model does not know, with every modelled group, none of them a training demo."""
    demos = list(demos)
    if len(demos) < 2:
        raise DataError(demos[0].source if demos else None, "task", "a new task needs at least 2 demos")
    names = {d.task for d in demos}
    if len(names) != 1:
        raise DataError(
            demos[0].source, "task", f"the demos are of several tasks {sorted(names)}; add one at a time"
        )
    task = names.pop()
    if not task:
        raise DataError(demos[0].source, "task", "the demos have no task name")
    if task in fitted.tasks:
        raise DataError(demos[0].source, "task", f"the model already has a task '{task}'")
    for d in demos:
        lacking = [g for g in fitted.layout.groups if g not in d.groups]
        if lacking:
            raise DataError(d.source, "groups", f"lacks the model's group(s) {lacking}")
    check_distinct({task: demos})
    known = {r.sha256 for r in fitted.trained_on or ()}
    for d in demos:
        if demo_digest(d) in known:
            raise DataError(d.source, "task", f"'{d.name}' is one of the model's training demos")
    return task


def _with_candidates(
    fitted: FittedModel,
    prior: tuple[float, float],
    n_alpha: int,
    width: float,
    task: str,
    cov: ShrunkCovariance,
    weights: np.ndarray,
    alphas: np.ndarray,
) -> dict[str, TaskModel]:
    """Every task's model with the new one: its phase candidates on the fitted lattice when they fit,
    else every task's candidates rebuilt from the phase priors (see the module docstring)."""
    old = fitted.task_models()
    priors = [(m.alpha_mu, m.alpha_sigma) for m in old]
    origin, spacing, n_cand = candidate_lattice(priors, n_alpha, width)
    models = {m.task: m for m in old}
    on_lattice = all(
        np.array_equal(m.alpha_grid, lattice_candidates(origin, spacing, n_cand, p, width)[0])
        for m, p in zip(old, priors, strict=True)
    )
    lo, hi = phase_support(prior, width)
    if on_lattice and lo >= origin and np.ceil((hi - lo) / spacing - 1e-9) + 2 <= n_cand:
        new_cands = lattice_candidates(origin, spacing, n_cand, prior, width)
    else:
        cands = alpha_candidates([*priors, prior], n_alpha, width)
        for m, (grid, logw) in zip(old, cands, strict=False):
            models[m.task] = dataclasses.replace(m, alpha_grid=grid, alpha_log_prior=logw)
        new_cands = cands[-1]
    models[task] = TaskModel.from_estimate(task, cov, prior, new_cands, weights, alphas)
    return models


def _novelty_rows(grown: FittedModel, demos: list[Demo], ratios: np.ndarray) -> list[NoveltyRow]:
    """The new task's rows for the novelty detector: each demo observed at every fraction ``ratios``
    of the detector, with the MAP phases of the grown model's tasks (without a novelty detector)."""
    predictor = Predictor(grown, 2)
    observe = grown.layout.observe
    rows = []
    for i, d in enumerate(demos):
        for ratio in (float(r) for r in np.asarray(ratios, float).reshape(-1)):
            parts, t_last = predictor.encode(d.head(ratio, observe))
            window = WindowSummary.from_parts(parts, grown.layout.n_obs_dims)
            rec = predictor.recognise(parts, t_last, window)
            rows.append(NoveltyRow(len(grown.tasks) - 1, i, window.vector(), ratio, rec.alpha, t_last))
    return rows
