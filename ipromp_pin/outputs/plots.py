"""Matplotlib figures (PNG, Agg backend) of learned models, predictions and evaluation results.

Every function takes plain arrays (the pipeline passes model outputs), writes one PNG of a fixed
pixel size (``figsize`` in inches times ``dpi``) and returns its path. Mismatched shapes raise
:class:`~ipromp_pin.exceptions.DataError` naming the argument.

The figures are :class:`matplotlib.figure.Figure` objects drawn by their own Agg canvas: no pyplot
state, no display, and the importer's matplotlib backend is left as it is (importing this module
does not select one).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .plot_canvas import as_array as _array
from .plot_canvas import dim_names as _names
from .plot_canvas import legend_entries as _legend_entries
from .plot_canvas import mark_times as _mark_times
from .plot_canvas import one_panel as _axes
from .plot_canvas import panel_grid as _panels
from .plot_canvas import plot_error as _err
from .plot_canvas import save_png as _save

__all__ = [
    "AccuracyBars",
    "accuracy_bars",
    "held_spans",
    "plot_accuracy",
    "plot_distributions",
    "plot_phase_posterior",
    "plot_prediction",
    "plot_torques",
]


def plot_distributions(
    phase: np.ndarray,
    mean: np.ndarray,
    std: np.ndarray,
    path: str | Path,
    *,
    demos: Sequence[np.ndarray] | np.ndarray | None = None,
    dim_names: Sequence[str] | None = None,
    units: Sequence[str] | None = None,
    band: tuple[np.ndarray, np.ndarray] | None = None,
    title: str = "",
    figsize: tuple[float, float] = (12.0, 8.0),
    dpi: int = 100,
) -> Path:
    """Learned distribution per dimension: centre and 2-sigma band over phase, training demos in grey.

    Args:
        phase: (P,) phase grid in [0, 1].
        mean: (P, D) mean (or centre) of every dimension on ``phase`` (original units).
        std: (P, D) standard deviation on ``phase`` (same units); the band is ``mean +- 2 std``
            unless ``band`` is given.
        path: PNG file to write.
        demos: Training demos resampled on ``phase``: (n, P, D) or a sequence of (P, D).
        dim_names: (D,) names of the dimensions (subplot titles).
        units: (D,) unit of every dimension (y-axis labels), e.g. ``"rad"``.
        band: (lower, upper), each (P, D), the 2-sigma band in original units, for dimensions whose
            spread is not symmetric in them (a channel modelled in log space:
            ``IProMP.distribution_band``); ``std`` is then not drawn.
        title: Figure title (e.g. the task name).
    """
    phase = _array(phase, "phase", 1)
    mean = _array(mean, "mean", 2)
    std = _array(std, "std", 2)
    if mean.shape[0] != phase.size:
        raise _err("mean", f"has {mean.shape[0]} rows for {phase.size} phase values")
    if std.shape != mean.shape:
        raise _err("std", f"shape {std.shape} differs from mean {mean.shape}")
    if np.any(std < 0):
        raise _err("std", "standard deviations must be >= 0")
    if band is None:
        lower, upper = mean - 2 * std, mean + 2 * std
    else:
        lower, upper = _array(band[0], "band", 2), _array(band[1], "band", 2)
        if lower.shape != mean.shape or upper.shape != mean.shape:
            raise _err("band", f"shapes {lower.shape}, {upper.shape} differ from mean {mean.shape}")
        if np.any(lower > mean + 1e-12 * np.abs(mean)) or np.any(upper < mean - 1e-12 * np.abs(mean)):
            raise _err("band", "the band must contain the centre (lower <= mean <= upper)")
    demo_list: list[np.ndarray] = []
    if demos is not None:
        for i, demo in enumerate(demos):
            demo = _array(demo, f"demos[{i}]", 2)
            if demo.shape != mean.shape:
                raise _err("demos", f"demo {i} has shape {demo.shape}, expected {mean.shape}")
            demo_list.append(demo)
    n_dims = mean.shape[1]
    names = _names(dim_names, n_dims, "dim_names", "dim ")
    unit_names = _names(units, n_dims, "units", "") if units is not None else None
    fig, axes, cols = _panels(n_dims, figsize)
    for d, ax in enumerate(axes):
        for k, demo in enumerate(demo_list):
            ax.plot(
                phase, demo[:, d], color="0.6", lw=0.7, alpha=0.6, label="training demos" if k == 0 else None
            )
        ax.fill_between(phase, lower[:, d], upper[:, d], color="C0", alpha=0.25, label="2 sigma")
        ax.plot(
            phase,
            mean[:, d],
            color="C0",
            lw=1.8,
            label="mean" if band is None else "mean (log-scaled: median)",
        )
        ax.set_title(names[d], fontsize=9)
        if unit_names is not None and unit_names[d]:
            ax.set_ylabel(unit_names[d], fontsize=8)
        ax.tick_params(labelsize=7)
        if d + cols >= n_dims:
            ax.set_xlabel("phase", fontsize=8)
    axes[0].legend(fontsize=7, loc="best")
    if title:
        fig.suptitle(title)
    return _save(fig, path, dpi)


def plot_prediction(
    t_s: np.ndarray,
    q_mean: np.ndarray,
    q_std: np.ndarray,
    path: str | Path,
    *,
    truth_t_s: np.ndarray | None = None,
    q_truth: np.ndarray | None = None,
    observed_until_s: float | None = None,
    joint_names: Sequence[str] | None = None,
    title: str = "",
    figsize: tuple[float, float] = (12.0, 8.0),
    dpi: int = 100,
) -> Path:
    """Conditioned prediction of every robot joint against the ground truth.

    Args:
        t_s: (M,) prediction times in [s] from the motion start.
        q_mean: (M, J) predicted joint positions in [rad].
        q_std: (M, J) standard deviation in [rad] (band of 2 sigma).
        path: PNG file to write.
        truth_t_s: (G,) times of the recorded trajectory in [s].
        q_truth: (G, J) recorded joint positions in [rad].
        observed_until_s: End of the observed window in [s] (shaded).
        joint_names: (J,) joint names.
    """
    t_s = _array(t_s, "t_s", 1)
    q_mean = _array(q_mean, "q_mean", 2)
    q_std = _array(q_std, "q_std", 2)
    if q_mean.shape[0] != t_s.size:
        raise _err("q_mean", f"has {q_mean.shape[0]} rows for {t_s.size} times")
    if q_std.shape != q_mean.shape:
        raise _err("q_std", f"shape {q_std.shape} differs from q_mean {q_mean.shape}")
    if (truth_t_s is None) != (q_truth is None):
        raise _err("q_truth", "truth_t_s and q_truth must be given together")
    if q_truth is not None:
        truth_t_s = _array(truth_t_s, "truth_t_s", 1)
        q_truth = _array(q_truth, "q_truth", 2)
        if q_truth.shape != (truth_t_s.size, q_mean.shape[1]):
            raise _err("q_truth", f"shape {q_truth.shape}, expected {(truth_t_s.size, q_mean.shape[1])}")
    n_joints = q_mean.shape[1]
    names = _names(joint_names, n_joints, "joint_names", "joint ")
    fig, axes, cols = _panels(n_joints, figsize)
    for j, ax in enumerate(axes):
        if observed_until_s is not None:
            ax.axvspan(0.0, observed_until_s, color="C2", alpha=0.12, label="observed")
            ax.axvline(observed_until_s, color="C2", lw=1.0)
        ax.fill_between(
            t_s,
            q_mean[:, j] - 2 * q_std[:, j],
            q_mean[:, j] + 2 * q_std[:, j],
            color="C0",
            alpha=0.25,
            label="2 sigma",
        )
        ax.plot(t_s, q_mean[:, j], color="C0", lw=1.8, label="prediction")
        if q_truth is not None and truth_t_s is not None:
            ax.plot(truth_t_s, q_truth[:, j], color="k", lw=1.2, ls="--", label="ground truth")
        ax.set_title(names[j], fontsize=9)
        ax.set_ylabel("rad", fontsize=8)
        ax.tick_params(labelsize=7)
        if j + cols >= n_joints:
            ax.set_xlabel("time [s]", fontsize=8)
    axes[0].legend(fontsize=7, loc="best")
    if title:
        fig.suptitle(title)
    return _save(fig, path, dpi)


def plot_phase_posterior(
    alphas: Mapping[str, np.ndarray] | np.ndarray,
    log_posterior: Mapping[str, np.ndarray] | np.ndarray,
    path: str | Path,
    *,
    tasks: Sequence[str] | None = None,
    true_alpha: float | None = None,
    title: str = "",
    ylabel: str = "log p(task, alpha | observation)",
    span: float | None = 60.0,
    figsize: tuple[float, float] = (8.0, 5.0),
    dpi: int = 100,
) -> Path:
    """Log posterior over the phase (time-scaling alpha) candidates of every task, on one scale.

    Args:
        alphas: (A,) candidates shared by all tasks, or {task: (A_k,)}.
        log_posterior: {task: (A_k,)} log posterior of each candidate, or a (K, A) array with the
            task names in ``tasks``: the JOINT ``log p(task, alpha | observation)`` (comparable
            across tasks; what ``ylabel`` says by default), or whatever ``ylabel`` names.
        path: PNG file to write.
        tasks: (K,) task names of the rows of an array ``log_posterior``.
        true_alpha: Ground-truth alpha of the observed demo (vertical line), when known.
        ylabel: The y-axis label: what ``log_posterior`` is.
        span: Range shown below the highest value (a task far below it is drawn at the bottom
            edge, its peak value in the legend); ``None``: everything.
    """
    if not isinstance(log_posterior, Mapping):
        table = _array(log_posterior, "log_posterior", 2)
        names = _names(tasks, table.shape[0], "tasks", "task ")
        log_posterior = dict(zip(names, table, strict=True))
    if not log_posterior:
        raise _err("log_posterior", "no task given")
    curves = []
    for task, values in log_posterior.items():
        grid = alphas.get(task) if isinstance(alphas, Mapping) else alphas
        if grid is None:
            raise _err("alphas", f"no candidates for task '{task}'")
        grid = _array(grid, f"alphas[{task}]", 1)
        values = _array(values, f"log_posterior[{task}]", 1)
        if values.size != grid.size:
            raise _err(
                "log_posterior", f"task '{task}' has {values.size} values for {grid.size} alpha candidates"
            )
        curves.append((task, grid, values))
    peaks = [float(np.max(v[np.isfinite(v)])) if np.isfinite(v).any() else -np.inf for _, _, v in curves]
    top = max(peaks)
    floor = top - span if span is not None and np.isfinite(top) else -np.inf
    fig, ax = _axes(figsize)
    for k, ((task, grid, values), peak) in enumerate(zip(curves, peaks, strict=True)):
        finite = np.isfinite(values)
        shown = np.maximum(values, floor)
        ax.plot(grid[finite], shown[finite], marker=".", color=f"C{k}", label=f"{task} (peak {peak:.1f})")
        if finite.any():
            best = int(np.flatnonzero(finite)[np.argmax(values[finite])])
            ax.plot(grid[best], shown[best], marker="o", ms=8, mfc="none", color=f"C{k}")
    if np.isfinite(floor) and min(peaks) < floor:
        ax.axhline(floor, color="0.5", lw=0.8, ls=":", label=f"values below {floor:.0f} drawn at it")
    if true_alpha is not None:
        ax.axvline(true_alpha, color="k", ls="--", lw=1.0, label="true alpha")
    ax.set_xlabel("alpha (time scaling)")
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    if title:
        ax.set_title(title)
    return _save(fig, path, dpi)


@dataclass(frozen=True)
class AccuracyBars:
    """The bars of :func:`plot_accuracy`: one group per cell, one bar per observed set.

    Attributes:
        cells: (C,) (training demos per task, observed ratio) of the groups.
        settings: (S,) the observed sets (the legend).
        mean: (S, C) accuracy averaged over the tasks (NaN: no record).
        spread: (S, C) the mean over the tasks of the accuracy's standard deviation over the random
            splits (NaN: no split, e.g. the paper's protocol): an upper bound of the standard
            deviation over the splits of the task-averaged accuracy (the standard deviation of a
            mean is at most the mean of the standard deviations).
        n_splits: The number of random splits of the records that have one (0: none).
    """

    cells: list[tuple[int, float]]
    settings: list[str]
    mean: np.ndarray
    spread: np.ndarray
    n_splits: int


def accuracy_bars(records: Sequence[Mapping[str, Any]]) -> AccuracyBars:
    """The bars of :func:`plot_accuracy` from its ``records`` (see there), checked."""
    required = ("n_train", "obs_ratio", "observe", "accuracy")
    if not records:
        raise _err("records", "no records given")
    rows = []
    splits = set()
    for i, record in enumerate(records):
        missing = [k for k in required if k not in record]
        if missing:
            raise _err("records", f"record {i} lacks {missing}")
        accuracy = float(record["accuracy"])
        if not 0.0 <= accuracy <= 1.0:
            raise _err("records", f"record {i} has accuracy {accuracy} outside [0, 1]")
        std = record.get("accuracy_std")
        std = float("nan") if std is None else float(std)
        if std < 0:
            raise _err("records", f"record {i} has accuracy_std {std} < 0")
        if record.get("n_splits"):
            splits.add(int(record["n_splits"]))
        observe = record["observe"]
        if not isinstance(observe, str):
            observe = ",".join(observe)
        protocol = record.get("protocol")
        rows.append((int(record["n_train"]), float(record["obs_ratio"]), observe, accuracy, protocol, std))
    if len({r[4] for r in rows}) > 1:  # several protocols: name them in the legend
        rows = [(n, ratio, f"{p}: {observe}", acc, p, sd) for n, ratio, observe, acc, p, sd in rows]
    cells = sorted({(r[0], r[1]) for r in rows}, key=lambda c: (-c[0], c[1]))
    settings = sorted({r[2] for r in rows}, key=lambda s: ("emg" in s, s))
    mean = np.full((len(settings), len(cells)), np.nan)
    spread = np.full_like(mean, np.nan)
    for k, setting in enumerate(settings):
        for c, (n_train, ratio) in enumerate(cells):
            chosen = [r for r in rows if (r[0], r[1], r[2]) == (n_train, ratio, setting)]
            if chosen:
                mean[k, c] = float(np.mean([r[3] for r in chosen]))
                stds = [r[5] for r in chosen if np.isfinite(r[5])]
                spread[k, c] = float(np.mean(stds)) if stds else np.nan
    return AccuracyBars(cells, settings, mean, spread, max(splits) if splits else 0)


def plot_accuracy(
    records: Sequence[Mapping[str, Any]],
    path: str | Path,
    *,
    title: str = "Task recognition accuracy",
    figsize: tuple[float, float] = (12.0, 4.5),
    dpi: int = 100,
) -> Path:
    """Recognition accuracy per cell (training-set size, observed ratio) as grouped bars, with error
    bars of the spread over the random splits where the records have one (:class:`AccuracyBars`;
    clipped to accuracies in [0, 1]).

    One bar per ``observe`` setting (e.g. ``"orientation"`` vs ``"orientation,emg"``), averaged
    over the tasks of the records; the legend beside the axes.

    Args:
        records: Rows ``{"n_train": int, "obs_ratio": float, "observe": str or list of groups,
            "task": str, "accuracy": float in [0, 1]}``, optionally ``"accuracy_std"`` (its standard
            deviation over the random splits) and ``"n_splits"`` (an optional ``"protocol"`` is named
            in the legend when the records mix several).
        path: PNG file to write.
    """
    bars = accuracy_bars(records)
    fig, ax = _axes(figsize)
    width = 0.8 / len(bars.settings)
    x = np.arange(len(bars.cells))
    for k, setting in enumerate(bars.settings):
        mean, spread = bars.mean[k], bars.spread[k]
        pos = x - 0.4 + (k + 0.5) * width
        hatch = None if "emg" in setting else "//"
        ax.bar(pos, mean, width, color=f"C{k}", hatch=hatch, edgecolor="white", label=setting)
        if np.isfinite(spread).any():
            sd = np.where(np.isfinite(spread), spread, 0.0)  # clipped to accuracies in [0, 1]
            yerr = np.vstack([np.minimum(sd, mean), np.minimum(sd, 1.0 - mean)])
            ax.errorbar(pos, mean, yerr=yerr, fmt="none", ecolor="0.15", elinewidth=1.0, capsize=3)
        for xi, value, sd in zip(pos, mean, spread, strict=True):
            if np.isfinite(value):
                top = min(value + (sd if np.isfinite(sd) else 0.0), 1.0)
                ax.annotate(f"{value:.2f}", (xi, top), textcoords="offset points", xytext=(0, 2),
                            ha="center", fontsize=7, color=f"C{k}")  # fmt: skip
    ax.set_xticks(x, [f"{n} train / task\n{ratio:.0%} observed" for n, ratio in bars.cells])
    ylabel = "accuracy (mean over tasks)"
    if bars.n_splits:
        ylabel += (
            f"\nerror bars: ± mean over tasks of the std\nover {bars.n_splits} random splits (within [0, 1])"
        )
    ax.set_ylabel(ylabel, fontsize=8)
    ax.set_ylim(0.0, 1.15)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), title="observed", title_fontsize=8)
    fig.suptitle(title)
    return _save(fig, path, dpi)


def plot_torques(
    t_s: np.ndarray,
    tau_nm: np.ndarray,
    limit_nm: np.ndarray,
    path: str | Path,
    *,
    effort_margin: float = 0.0,
    held: np.ndarray | None = None,
    joint_names: Sequence[str] | None = None,
    events: Sequence[tuple[float, str]] = (),
    title: str = "",
    figsize: tuple[float, float] = (12.0, 7.0),
    dpi: int = 100,
) -> Path:
    """Every joint's |torque| over time against its effort limit and the allowed torque.

    Args:
        t_s: (N,) sample times in [s].
        tau_nm: (N, J) joint torques in [N m] (their magnitude is drawn).
        limit_nm: (J,) effort limits in [N m] (> 0; a solid red line).
        path: PNG file to write.
        effort_margin: Fraction of the limit kept free, in [0, 1): the allowed torque
            ``(1 - effort_margin) x limit`` is a dashed line.
        held: (N,) whether the gripper holds the object (shaded from the first to the last sample of
            each run, widened by half a sample period: :func:`held_spans`).
        joint_names: (J,) joint names.
        events: (t [s], label) marked with a vertical line (e.g. the robot's start, the hand-over).
    """
    t_s = _array(t_s, "t_s", 1)
    tau = _array(tau_nm, "tau_nm", 2)
    limit = _array(limit_nm, "limit_nm", 1)
    if tau.shape[0] != t_s.size:
        raise _err("tau_nm", f"has {tau.shape[0]} rows for {t_s.size} times")
    if limit.shape != (tau.shape[1],) or np.any(limit <= 0):
        raise _err("limit_nm", f"expected {tau.shape[1]} limits > 0, got {limit.tolist()}")
    if not 0.0 <= effort_margin < 1.0:
        raise _err("effort_margin", f"must be in [0, 1), got {effort_margin}")
    mask = None if held is None else np.asarray(held, dtype=bool).reshape(-1)
    if mask is not None and mask.size != t_s.size:
        raise _err("held", f"has {mask.size} values for {t_s.size} times")
    n_joints = tau.shape[1]
    names = _names(joint_names, n_joints, "joint_names", "joint ")
    fig, axes, cols = _panels(n_joints, figsize)
    spans = [] if mask is None else held_spans(t_s, mask)
    for j, ax in enumerate(axes):
        for k, (a, b) in enumerate(spans):
            ax.axvspan(a, b, color="C2", alpha=0.22, lw=0, label="object held" if k == 0 else None)
        _mark_times(ax, events, None, j == 0)
        ax.plot(t_s, np.abs(tau[:, j]), color="C0", lw=1.5, label="|torque|")
        ax.axhline(limit[j], color="C3", lw=1.2, label="effort limit")
        ax.axhline((1.0 - effort_margin) * limit[j], color="C3", lw=1.0, ls="--", label="allowed")
        peak = float(np.abs(tau[:, j]).max())
        ax.set_title(f"{names[j]}: peak {peak / limit[j]:.0%}", fontsize=9)
        ax.set_ylabel("N m", fontsize=8)
        ax.set_ylim(0.0, 1.08 * max(limit[j], peak))
        ax.tick_params(labelsize=7)
        if j + cols >= n_joints:
            ax.set_xlabel("time [s]", fontsize=8)
    fig.legend(*_legend_entries(axes[0]), loc="outside lower center", ncol=6, fontsize=8)
    if title:
        fig.suptitle(title)
    return _save(fig, path, dpi)


def held_spans(t_s: np.ndarray, held: np.ndarray) -> list[tuple[float, float]]:
    """The time spans [s] of the runs of ``held`` (N,) at the times ``t_s`` (N,): from a run's first
    sample to its last, widened by half a sample period on each side (within the samples' range),
    so that a run of one sample is a visible span."""
    t = np.asarray(t_s, dtype=float)
    h = np.asarray(held, dtype=bool)
    if t.size == 0 or not h.any():
        return []
    half = 0.5 * float(np.median(np.diff(t))) if t.size > 1 else 0.0
    edges = np.diff(np.r_[0, h.astype(int), 0])
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    return [
        (max(float(t[a]) - half, float(t[0])), min(float(t[b]) + half, float(t[-1])))
        for a, b in zip(starts, stops, strict=True)
    ]
