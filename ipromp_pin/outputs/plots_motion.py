"""Figures of the robot's timed motion: the joints against their limits (:func:`plot_joint_motion`)
and the robot-human separation over time (:func:`plot_separation`).

Like :mod:`.plots`, every function takes plain arrays (their numbers: :mod:`.plot_series`), writes
one PNG and returns its path; mismatched shapes raise :class:`~ipromp_pin.exceptions.DataError`
naming the argument. Every time is on the human's clock (t = 0 at the start of the human's motion).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes

from .plot_canvas import as_array, dim_names, legend_entries, mark_times, new_figure, plot_error, save_png

__all__ = ["plot_joint_motion", "plot_separation"]


def _rows(value: Any, name: str, n: int, j: int) -> np.ndarray:
    """An (n, j) array, else DataError naming ``name``."""
    arr = as_array(value, name, 2)
    if arr.shape != (n, j):
        raise plot_error(name, f"shape {arr.shape}, expected {(n, j)}")
    return arr


def _per_joint(value: Any, name: str, j: int, positive: bool = True) -> np.ndarray:
    """A (j,) array of limits, else DataError naming ``name``."""
    arr = as_array(value, name, 1)
    if arr.shape != (j,) or not np.all(np.isfinite(arr)) or (positive and np.any(arr <= 0)):
        raise plot_error(name, f"expected {j} finite limits{' > 0' if positive else ''}, got {arr.tolist()}")
    return arr


def plot_joint_motion(
    t_s: np.ndarray,
    values: Sequence[np.ndarray],
    limits: Sequence[np.ndarray],
    path: str | Path,
    *,
    position_bounds: tuple[np.ndarray, np.ndarray] | None = None,
    segment: np.ndarray | None = None,
    joint_names: Sequence[str] | None = None,
    events: Sequence[tuple[float, str]] = (),
    ticks_s: np.ndarray | None = None,
    segment_labels: Sequence[str] = ("approach", "retreat"),
    title: str = "",
    figsize: tuple[float, float] = (20.0, 10.0),
    dpi: int = 90,
) -> Path:
    """A timed joint motion against its limits: one row per quantity (position, velocity,
    acceleration and, when given, jerk), one column per joint.

    Args:
        t_s: (N,) sample times in [s].
        values: ``(q, qd, qdd)`` or ``(q, qd, qdd, jerk)``, each (N, J), in [rad], [rad/s], [rad/s^2],
            [rad/s^3].
        limits: ``(lower, upper, velocity, acceleration[, jerk])``, each (J,): the position limits the
            ``joint_limits`` check uses (with its margin; red dashed) and the magnitude limits of
            ``speed_limits`` (drawn at +- the limit).
        path: PNG file to write.
        position_bounds: (lower, upper), each (J,), the URDF position limits (red solid), when known.
        segment: (N,) segment of every sample (0: approach, 1: retreat, drawn in another colour).
        segment_labels: The legend's name of each segment.
        joint_names: (J,) joint names (column titles).
        events: (t [s], label) marked with a vertical line in every panel.
        ticks_s: Times [s] marked with short ticks at the bottom of every panel (the re-plans).
    """
    t_s = as_array(t_s, "t_s", 1)
    n = t_s.size
    if len(values) not in (3, 4) or len(limits) != len(values) + 1:
        raise plot_error("values", f"expected 3 or 4 quantities with one more limit array, got {len(values)}")
    first = as_array(values[0], "values[0]", 2)
    j = first.shape[1]
    series = [_rows(v, f"values[{k}]", n, j) for k, v in enumerate(values)]
    lower = _per_joint(limits[0], "limits[0]", j, positive=False)
    upper = _per_joint(limits[1], "limits[1]", j, positive=False)
    bounds = [_per_joint(b, f"limits[{k + 2}]", j) for k, b in enumerate(limits[2:])]
    seg = np.zeros(n, dtype=int) if segment is None else np.asarray(segment, dtype=int).reshape(-1)
    if seg.size != n:
        raise plot_error("segment", f"has {seg.size} values for {n} times")
    names = dim_names(joint_names, j, "joint_names", "joint ")
    rows = (("position", "rad"), ("velocity", "rad/s"), ("acceleration", "rad/s^2"), ("jerk", "rad/s^3"))
    fig = new_figure(figsize)
    grid = fig.subplots(len(series), j, squeeze=False, sharex=True)
    ticks = None if ticks_s is None else np.asarray(ticks_s, dtype=float)
    for r, (x, (quantity, unit)) in enumerate(zip(series, rows, strict=False)):
        for c in range(j):
            ax = grid[r, c]
            _segments(ax, t_s, x[:, c], seg, segment_labels if (r, c) == (0, 0) else ())
            if r == 0:
                _position_limits(ax, x[:, c], lower[c], upper[c], position_bounds, c)
                ax.set_title(names[c], fontsize=9)
            else:
                lim = bounds[r - 1][c]
                ax.axhline(lim, color="C3", lw=1.0, ls="--", label="limit" if (r, c) == (1, 0) else None)
                ax.axhline(-lim, color="C3", lw=1.0, ls="--")
                share = float(np.max(np.abs(x[:, c]))) / lim
                ax.text(0.02, 0.98, f"peak {share:.0%}", transform=ax.transAxes, va="top", fontsize=6)
            mark_times(ax, events, ticks, (r, c) == (0, 0))
            ax.tick_params(labelsize=6)
            if c == 0:
                ax.set_ylabel(f"{quantity} [{unit}]", fontsize=8)
            if r == len(series) - 1:
                ax.set_xlabel("time [s]", fontsize=8)
    fig.legend(*legend_entries(grid[0, 0], grid[1, 0]), loc="outside lower center", ncol=8, fontsize=8)
    if title:
        fig.suptitle(title)
    return save_png(fig, path, dpi)


def _segments(ax: Axes, t_s: np.ndarray, x: np.ndarray, seg: np.ndarray, labels: Sequence[str]) -> None:
    """``x`` (N,) over ``t_s`` (N,), each segment of ``seg`` in its colour (named ``labels[k]``; none
    when ``labels`` is empty)."""
    for k in np.unique(seg):
        on = seg == k
        label = labels[int(k)] if int(k) < len(labels) else None
        ax.plot(t_s[on], x[on], color=f"C{int(k)}", lw=1.2, label=label)


def _position_limits(
    ax: Axes,
    x: np.ndarray,
    lower: float,
    upper: float,
    bounds: tuple[np.ndarray, np.ndarray] | None,
    c: int,
) -> None:
    """Joint ``c``'s position limits: with the check's margin (dashed), the URDF's (solid, ``bounds``)
    and the smallest slack of ``x`` (N,) [rad] to the dashed ones."""
    ax.axhline(lower, color="C3", lw=1.0, ls="--", label="limit (with margin)" if c == 0 else None)
    ax.axhline(upper, color="C3", lw=1.0, ls="--")
    if bounds is not None:
        ax.axhline(float(bounds[0][c]), color="C3", lw=1.0, label="URDF limit" if c == 0 else None)
        ax.axhline(float(bounds[1][c]), color="C3", lw=1.0)
    slack = min(float(np.min(x - lower)), float(np.min(upper - x)))
    ax.text(0.02, 0.98, f"slack {slack:.3f} rad", transform=ax.transAxes, va="top", fontsize=6)


def plot_separation(
    t_s: np.ndarray,
    body_m: np.ndarray,
    protective_m: np.ndarray,
    speed_ratio: np.ndarray,
    path: str | Path,
    *,
    hand_m: np.ndarray | None = None,
    planning_limit_ratio: float = 1.0,
    judged: np.ndarray | None = None,
    events: Sequence[tuple[float, str]] = (),
    ticks_s: np.ndarray | None = None,
    title: str = "",
    figsize: tuple[float, float] = (11.0, 7.0),
    dpi: int = 100,
) -> Path:
    """The robot-human separation over time: the closest distances with the protective separation
    distance S_p (top), the contact-speed ratio against its limits (bottom).

    Args:
        t_s: (N,) sample times in [s].
        body_m: (N,) smallest distance [m] to the body outside the hand (``human_clearance``).
        protective_m: (N,) smallest S_p [m] of any robot-body pair (NaN: none).
        speed_ratio: (N,) largest approach speed / v_max within S_p (``contact_speed``), >= 0.
        path: PNG file to write.
        hand_m: (N,) smallest distance [m] to the hand.
        planning_limit_ratio: The ratio the plans are held to (``1 - speed_margin``), in (0, 1].
        judged: (N,) the samples the checks judged (the others, the robot at rest while the human
            still moves, drawn faint).
        events: (t [s], label) marked with a vertical line.
        ticks_s: Times [s] marked with short ticks (the re-plans).
    """
    t_s = as_array(t_s, "t_s", 1)
    n = t_s.size
    series = {}
    for name, value in (("body_m", body_m), ("protective_m", protective_m), ("speed_ratio", speed_ratio)):
        arr = as_array(value, name, 1)
        if arr.size != n:
            raise plot_error(name, f"has {arr.size} values for {n} times")
        series[name] = arr
    hand = None if hand_m is None else as_array(hand_m, "hand_m", 1)
    if hand is not None and hand.size != n:
        raise plot_error("hand_m", f"has {hand.size} values for {n} times")
    if not 0.0 < planning_limit_ratio <= 1.0:
        raise plot_error("planning_limit_ratio", f"must be in (0, 1], got {planning_limit_ratio}")
    if np.any(series["speed_ratio"] < 0):
        raise plot_error("speed_ratio", "ratios must be >= 0")
    mask = np.ones(n, dtype=bool) if judged is None else np.asarray(judged, dtype=bool).reshape(-1)
    if mask.size != n or not mask.any():
        raise plot_error("judged", f"expected {n} flags with at least one judged sample")
    fig = new_figure(figsize)
    top, bottom = fig.subplots(2, 1, sharex=True)
    curves = [("body outside the hand", series["body_m"], "C0"), ("S_p (smallest of any pair)",
              series["protective_m"], "C3")]  # fmt: skip
    if hand is not None:
        curves.insert(1, ("hand", hand, "C1"))
    for ax, items in ((top, curves), (bottom, [("approach speed / v_max", series["speed_ratio"], "C0")])):
        for label, y, colour in items:
            ax.plot(t_s[mask], y[mask], color=colour, lw=1.5, label=label,
                    ls="--" if colour == "C3" else "-")  # fmt: skip
            if not mask.all():
                ax.plot(t_s[~mask], y[~mask], color=colour, lw=1.0, alpha=0.35)
    i = int(np.flatnonzero(mask)[np.argmin(series["body_m"][mask])])
    top.plot(t_s[i], series["body_m"][i], "o", color="C0", mfc="none",
             label=f"closest {series['body_m'][i] * 1e3:.0f} mm at {t_s[i]:.2f} s")  # fmt: skip
    k = int(np.flatnonzero(mask)[np.argmax(series["speed_ratio"][mask])])
    bottom.plot(t_s[k], series["speed_ratio"][k], "o", color="C0", mfc="none",
                label=f"largest {series['speed_ratio'][k]:.2f} at {t_s[k]:.2f} s")  # fmt: skip
    bottom.axhline(planning_limit_ratio, color="C3", ls="--", lw=1.0,
                   label=f"planning limit {planning_limit_ratio:.2f} (1 - speed margin)")  # fmt: skip
    bottom.axhline(1.0, color="C3", lw=1.2, label="contact-speed limit v_max")
    for ax in (top, bottom):
        mark_times(ax, events, None if ticks_s is None else np.asarray(ticks_s, float), ax is top)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    top.set_ylabel("distance [m]")
    top.set_ylim(bottom=0.0)
    bottom.set_ylabel("approach speed / v_max (within S_p)")
    bottom.set_ylim(0.0, 1.1 * max(1.0, float(series["speed_ratio"].max())))
    bottom.set_xlabel("time [s] (t = 0 at the start of the human's motion)")
    if not mask.all():
        top.set_title("faint: the robot at rest after its motion while the human still moves", fontsize=8)
    if title:
        fig.suptitle(title)
    return save_png(fig, path, dpi)
