"""The canvas of the figures (:mod:`.plots`, :mod:`.plots_motion`): Agg figures without pyplot, the
argument checks that raise :class:`~ipromp_pin.exceptions.DataError` naming the argument, atomic PNG
saving and the time marks and legends the figures share."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .. import atomic
from ..exceptions import DataError
from ..fields import float_array

SOURCE = "plots"
"""The source the figures' input errors name."""


def plot_error(field_name: str | None, problem: str) -> DataError:
    return DataError(SOURCE, field_name, problem)


def as_array(value: Any, name: str, ndim: int) -> np.ndarray:
    """``value`` as a non-empty float array of ``ndim`` dimensions (NaN allowed: a gap in a curve)."""
    return float_array(value, name, ndim, plot_error, finite=False)


def dim_names(names: Sequence[str] | None, n: int, name: str, prefix: str) -> list[str]:
    if names is None:
        return [f"{prefix}{i}" for i in range(n)]
    names = [str(x) for x in names]
    if len(names) != n:
        raise plot_error(name, f"has {len(names)} names for {n} dimensions")
    return names


def new_figure(figsize: tuple[float, float]) -> Figure:
    """An empty figure of ``figsize`` in inches with a constrained layout, drawn by an Agg canvas."""
    fig = Figure(figsize=figsize, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def one_panel(figsize: tuple[float, float]) -> tuple[Figure, Axes]:
    """A figure with one panel."""
    fig = new_figure(figsize)
    return fig, fig.subplots()


def panel_grid(n: int, figsize: tuple[float, float], max_cols: int = 4) -> tuple[Figure, list[Axes], int]:
    """A figure with ``n`` panels on a grid of at most ``max_cols`` columns (unused cells hidden).

    Returns:
        The figure, its ``n`` axes and the number of columns (panel ``i`` has none below it when
        ``i + cols >= n``).
    """
    cols = min(n, max_cols)
    rows = int(np.ceil(n / cols))
    fig = new_figure(figsize)
    grid = fig.subplots(rows, cols, squeeze=False)
    for ax in grid.flat[n:]:
        ax.set_visible(False)
    return fig, list(grid.flat[:n]), cols


def save_png(fig: Figure, path: str | Path, dpi: int) -> Path:
    """Save ``fig`` as PNG, atomically (a temporary file renamed into place)."""
    path = Path(path)
    with atomic.replacing(path) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi)
    return path


def mark_times(ax: Axes, events: Sequence[tuple[float, str]], ticks: np.ndarray | None, first: bool) -> None:
    """Labelled vertical lines at ``events`` ((t [s], label)) and short grey ticks at the bottom of the
    panel at ``ticks`` [s] (e.g. the re-plan times; labelled in the first panel)."""
    for k, (t, label) in enumerate(events):
        ax.axvline(t, color=f"C{k + 4}", lw=1.0, ls="-.", label=label if first else None)
    if ticks is not None and ticks.size:
        ax.vlines(ticks, 0.0, 0.06, transform=ax.get_xaxis_transform(), color="0.35", lw=0.6,
                  label="re-plans" if first else "_nolegend_")  # fmt: skip


def legend_entries(*axes: Axes) -> tuple[list, list[str]]:
    """The labelled artists of ``axes``, each label once."""
    handles, labels = [], []
    for ax in axes:
        for h, label in zip(*ax.get_legend_handles_labels(), strict=True):
            if label not in labels:
                handles.append(h)
                labels.append(label)
    return handles, labels
