"""From demonstrations to task models: layout, scaling, per-demo weights, phases, covariances.

:func:`prepare_training` does everything that does not depend on the noise ratio or on the
coupling (the channel layout, the scaling learned on every training sample, each demo's basis
weights and phase ``alpha_i = T_i / T_norm``); :func:`task_models` turns per-task weights and
phases into :class:`~ipromp_pin.promp.distribution.TaskModel` objects for a given coupling, which the
cross-validations (:mod:`ipromp_pin.promp.selection`) call again with demos left out.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from ..data import Dataset, Demo, group_by_task
from ..exceptions import DataError, ModelError
from .basis import GaussianBasis
from .distribution import (
    ChannelScaler,
    ShrinkageCache,
    TaskModel,
    alpha_candidates,
    alpha_prior,
    fit_demo_weights,
    shrink_covariances,
)
from .layout import ChannelLayout
from .provenance import demo_digest
from .validation import MAX_ORIGINAL


@dataclass(frozen=True)
class PhaseSettings:
    """How phase candidates and covariances are built (see :class:`~ipromp_pin.promp.estimator.IProMP`).

    Attributes:
        n_alpha: Minimum number of phase candidates inside every task's prior support.
        alpha_width: Candidates span ``mu +- alpha_width sigma`` of each task's phase prior.
        pooling: Weight in [0, 1] of the covariance pooled over tasks.
    """

    n_alpha: int
    alpha_width: float
    pooling: float


@dataclass(frozen=True)
class TrainingSet:
    """Training demos reduced to what the task models are built from.

    Attributes:
        demos: Task -> its demos (at least 2 each).
        layout: Channel layout of the demos.
        basis: The basis the weights are fitted with.
        scaler: Channel scaling learned on every training sample.
        tasks: Task names, in order.
        weights: Task -> (N, D, K) basis weights of its demos (scaled units).
        alphas: Task -> (N,) phases ``T_i / T_norm`` of its demos.
        duration_nominal_s: ``T_norm`` in [s], the mean duration over all demos.
        residual_var: (D,) mean per-sample residual variance of the basis fits.
        cache: The covariance statistics of ``weights`` (shared by the leave-one-out estimates of
            the cross-validations, :class:`~ipromp_pin.promp.distribution.ShrinkageCache`).
        encoded: The cross-validations' encoded demo heads (see
            :func:`~ipromp_pin.promp.selection.cv_observations`).
    """

    demos: Mapping[str, list[Demo]]
    layout: ChannelLayout
    basis: GaussianBasis
    scaler: ChannelScaler
    tasks: tuple[str, ...]
    weights: Mapping[str, np.ndarray]
    alphas: Mapping[str, np.ndarray]
    duration_nominal_s: float
    residual_var: np.ndarray
    cache: ShrinkageCache = field(default_factory=ShrinkageCache, compare=False, repr=False)
    encoded: dict = field(default_factory=dict, compare=False, repr=False)


def demos_by_task(data: Dataset | Iterable[Demo]) -> dict[str, list[Demo]]:
    """Task -> demos of a dataset or of demos grouped by ``demo.task`` (at least 2 per task)."""
    by_task = dict(data.demos) if isinstance(data, Dataset) else dict(group_by_task(data))
    if not by_task:
        raise DataError(None, "demos", "no demonstrations to fit")
    for task, demos in by_task.items():
        if len(demos) < 2:
            src = demos[0].source if demos else None
            raise DataError(src, "task", f"task '{task}' has {len(demos)} demo(s); at least 2 are needed")
    check_distinct(by_task)
    return by_task


def check_distinct(by_task: Mapping[str, list[Demo]]) -> None:
    """Refuse a degenerate training set: a task whose demos are all one recording (no variation to
    learn) or that holds one recording twice (it would count double), or two tasks that hold the
    same demos (they cannot be told apart). Demos are compared by content
    (:func:`~ipromp_pin.promp.provenance.demo_digest`)."""
    seen: dict[frozenset[str], str] = {}
    for task, demos in by_task.items():
        digests = [demo_digest(d) for d in demos]
        if len(set(digests)) == 1:
            raise DataError(
                demos[0].source,
                "task",
                f"task '{task}': its {len(demos)} demos are all the same recording (identical content); "
                "a task needs at least 2 different demos",
            )
        first: dict[str, Demo] = {}
        for d, digest in zip(demos, digests, strict=True):
            if digest in first:
                raise DataError(
                    d.source,
                    "task",
                    f"task '{task}' holds one recording twice ('{first[digest].name}' and '{d.name}' have "
                    "identical content): it would count double; drop one",
                )
            first[digest] = d
        key = frozenset(digests)
        if key in seen:
            raise DataError(
                demos[0].source,
                "task",
                f"tasks '{seen[key]}' and '{task}' hold the same demos: they cannot be told apart",
            )
        seen[key] = task


def stack_channels(layout: ChannelLayout, demo: Demo) -> np.ndarray:
    """The demo's samples of every modelled group side by side (T, D), NaN where flagged missing."""
    cols = []
    for g in layout.groups:
        v = demo.groups[g]
        if g in demo.missing:
            v = np.where(demo.missing[g][:, None], np.nan, v)
        cols.append(v)
    return np.concatenate(cols, axis=1)


def demo_weights(
    layout: ChannelLayout, basis: GaussianBasis, scaler: ChannelScaler, demo: Demo
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Basis weights (D, K) of one demo (scaled units), their residual sums of squares (D,) and the
    number of samples each was fitted on (D,)."""
    w = np.zeros((layout.n_dims, basis.n_basis))
    rss = np.zeros(layout.n_dims)
    cnt = np.zeros(layout.n_dims)
    for g in layout.groups:
        lo, hi = layout.slices[g]
        valid = ~demo.missing[g] if g in demo.missing else None
        y = scaler.transform(demo.groups[g], slice(lo, hi))
        w[lo:hi], rss[lo:hi] = fit_demo_weights(basis, demo.t, y, valid, demo.source, g)
        cnt[lo:hi] = demo.n_samples if valid is None else int(np.sum(valid))
    return w, rss, cnt


def prepare_training(
    by_task: Mapping[str, list[Demo]],
    observe: Iterable[str],
    robot_group: str,
    basis: GaussianBasis,
    log_groups: Iterable[str],
) -> TrainingSet:
    """Layout, scaling, weights and phases of the training demos (see :class:`TrainingSet`).

    Args:
        by_task: Task -> demos (:func:`demos_by_task`).
        observe: Observed human groups.
        robot_group: The robot's joint-angle group.
        basis: The basis of every channel.
        log_groups: Observed groups modelled in log space (others and the robot: linear).
    """
    layout = ChannelLayout.from_demos([d for demos in by_task.values() for d in demos], observe, robot_group)
    by_task = {task: [layout.aligned(d) for d in demos] for task, demos in by_task.items()}
    all_demos = [d for demos in by_task.values() for d in demos]
    log_dims = np.zeros(layout.n_dims, dtype=bool)
    for g in log_groups:
        if g in layout.slices and g != robot_group:
            log_dims[slice(*layout.slices[g])] = True
    stacked = [stack_channels(layout, d) for d in all_demos]
    with np.errstate(over="ignore", invalid="ignore"):
        scaler = ChannelScaler.fit(np.concatenate(stacked), log_dims)
    _check_scaling(layout, scaler, all_demos, stacked)
    durations = {task: np.array([d.t[-1] - d.t[0] for d in demos]) for task, demos in by_task.items()}
    t_norm = float(np.mean(np.concatenate(list(durations.values()))))
    weights = {}
    rss = np.zeros(layout.n_dims)
    count = np.zeros(layout.n_dims)
    for task, demos in by_task.items():
        ws = []
        for d in demos:
            w, res, cnt = demo_weights(layout, basis, scaler, d)
            ws.append(w)
            rss += res
            count += cnt
        weights[task] = np.stack(ws)
    return TrainingSet(
        demos=by_task,
        layout=layout,
        basis=basis,
        scaler=scaler,
        tasks=tuple(by_task),
        weights=weights,
        alphas={task: durations[task] / t_norm for task in by_task},
        duration_nominal_s=t_norm,
        residual_var=rss / np.maximum(count, 1),
        cache=ShrinkageCache(list(weights.values())),
    )


def _check_scaling(
    layout: ChannelLayout, scaler: ChannelScaler, demos: list[Demo], stacked: list[np.ndarray]
) -> None:
    """Refuse training data whose channel scaling is not finite or implausibly large (a finite but
    absurd value such as 1e300 in some demo), naming the demo that holds the most extreme value."""
    with np.errstate(invalid="ignore"):
        bad = ~(np.isfinite(scaler.offset) & np.isfinite(scaler.scale))
        bad |= (np.abs(scaler.offset) > MAX_ORIGINAL) | (scaler.scale > MAX_ORIGINAL)
    if not bad.any():
        return
    d = int(np.flatnonzero(bad)[0])
    with np.errstate(invalid="ignore"):
        extreme = [float(np.nanmax(np.abs(x[:, d]))) for x in stacked]
    k = int(np.nanargmax(extreme))
    raise DataError(
        demos[k].source,
        layout.labels()[d],
        f"implausible training value {extreme[k]:.6g} (the channel's scaling would be "
        f"{scaler.scale[d]:.3g}; check the readers' plausibility limits)",
    )


def coupling_blocks(layout: ChannelLayout, coupled: Iterable[str]) -> list[np.ndarray]:
    """Independent blocks of dims: the coupled groups with the robot, and the other observed groups."""
    coupled = list(coupled)
    rest = [g for g in layout.observe if g not in coupled]
    blocks = [[*coupled, layout.robot_group]] + ([rest] if rest else [])
    return [layout.dims(b) for b in blocks]


def task_models(
    training: TrainingSet,
    weights: Mapping[str, np.ndarray],
    alphas: Mapping[str, np.ndarray],
    coupled: Iterable[str],
    settings: PhaseSettings,
) -> dict[str, TaskModel]:
    """Task models from per-task weights (N, D, K) and phases (N,): phase priors and candidates,
    and the Ledoit-Wolf covariances with ``coupled`` groups in the robot's block."""
    tasks = training.tasks
    priors = [alpha_prior(alphas[t]) for t in tasks]
    cands = alpha_candidates(priors, settings.n_alpha, settings.alpha_width)
    blocks = coupling_blocks(training.layout, coupled)
    covs = shrink_covariances([weights[t] for t in tasks], settings.pooling, blocks, cache=training.cache)
    models = {}
    for task, prior, cand, cov in zip(tasks, priors, cands, covs, strict=True):
        models[task] = TaskModel.from_estimate(task, cov, prior, cand, weights[task], alphas[task])
    return models


def log_task_prior(tasks: tuple[str, ...], task_prior: Mapping[str, float] | None) -> np.ndarray:
    """(K,) log prior of the tasks: uniform, or from ``task_prior`` (task -> p, normalised)."""
    if task_prior is None:
        return np.full(len(tasks), -np.log(len(tasks)))
    unknown = set(task_prior) - set(tasks)
    if unknown:
        raise ModelError(f"task_prior names unknown tasks {sorted(unknown)} (tasks: {list(tasks)})")
    p = np.array([float(task_prior.get(t, 0.0)) for t in tasks])
    if np.any(p < 0) or not np.any(p > 0) or not np.all(np.isfinite(p)):
        raise ModelError(f"task_prior must be non-negative with a positive sum, got {dict(task_prior)}")
    with np.errstate(divide="ignore"):
        return np.log(p / p.sum())
