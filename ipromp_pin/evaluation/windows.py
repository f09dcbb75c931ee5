"""The observation windows of an evaluation's cells: how much of each test demo the model sees.

Three kinds (:class:`Window`):

* ``ratio``: the first ``value`` (a fraction in (0, 1]) of each test demo's own length: the paper's
  protocol. That length is known only once the motion is over, so a robot cannot use it online, and
  the window's length itself tells a long task from a short one;
* ``seconds``: the first ``value`` [s] of each test demo, whatever its length;
* ``train_fraction``: the first ``value`` x the fit's nominal duration [s], the mean length of its
  training demos (the model's ``T_norm``, :attr:`~ipromp_pin.promp.IProMP.duration_nominal_s_`):
  a window in seconds a robot knows before the test motion starts, the counterpart of the paper's
  10 % / 20 % cells (and the default window of ``ipromp-pin plan``,
  :class:`~ipromp_pin.data.ObservationWindow`).

A cell's window becomes concrete per model fit (:class:`FitWindow`: a ``train_fraction`` needs the
fit's training demos); the cut is :class:`~ipromp_pin.data.ObservationWindow`'s, as ``plan`` and
``run`` cut.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..data import WINDOW_RANGE_S, Demo, ObservationWindow
from ..exceptions import DataError
from ..fields import Range

WINDOW_KINDS = ("ratio", "seconds", "train_fraction")
"""The kinds of observation window of an evaluation cell."""

FRACTION_RANGE = Range(0.0, 1.0, "", "a fraction of a motion's length", lo_open=True)
"""Plausible values of a ``ratio`` or ``train_fraction`` window."""


@dataclass(frozen=True)
class Window:
    """An evaluation cell's observation window (see the module docstring).

    Attributes:
        kind: ``"ratio"``, ``"seconds"`` or ``"train_fraction"``.
        value: The fraction in (0, 1] (``ratio``, ``train_fraction``) or the seconds in (0, 600]
            (``seconds``).

    Raises:
        DataError: an unknown kind or a value outside its range (one line naming ``window``).
    """

    kind: str
    value: float

    def __post_init__(self) -> None:
        if self.kind not in WINDOW_KINDS:
            raise DataError(None, "window", f"unknown kind '{self.kind}' (known: {', '.join(WINDOW_KINDS)})")
        value = float(self.value)
        span = WINDOW_RANGE_S if self.kind == "seconds" else FRACTION_RANGE
        if not span.contains(value):
            raise DataError(None, "window", f"a {self.kind} window must be in {span.text()}, got {value}")
        object.__setattr__(self, "value", value)

    @classmethod
    def of(cls, window: float | Window) -> Window:
        """``window`` itself, or a ``ratio`` window for a bare fraction (the grid's ``obs_ratio``)."""
        return window if isinstance(window, Window) else cls("ratio", float(window))

    @property
    def is_ratio(self) -> bool:
        """Whether the window is a fraction of each test demo's own length (the paper's protocol)."""
        return self.kind == "ratio"

    def label(self) -> str:
        """The window in a table: ``0.2`` (ratio), ``0.6 s``, ``0.2 of train``."""
        if self.kind == "ratio":
            return f"{self.value:g}"
        return f"{self.value:g} s" if self.kind == "seconds" else f"{self.value:g} of train"

    def for_fit(self, nominal_s: float) -> FitWindow:
        """The window of a fit whose training demos last ``nominal_s`` [s] on average."""
        return FitWindow(self, float(nominal_s))

    def to_dict(self, seconds: float | None = None) -> dict[str, Any]:
        """The JSON form: ``{"kind", "value", "seconds"}`` (``seconds``: the window's end [s], None for
        a ratio window, whose end depends on each test demo)."""
        end = self.value if self.kind == "seconds" else seconds
        return {"kind": self.kind, "value": self.value, "seconds": None if self.is_ratio else end}


@dataclass(frozen=True)
class FitWindow:
    """A cell's window for one model fit.

    Attributes:
        window: The cell's window.
        nominal_s: The fit's nominal duration [s] (the mean length of its training demos; NaN when
            unknown, which only a ``train_fraction`` window needs).
    """

    window: Window
    nominal_s: float = math.nan

    @classmethod
    def of(cls, window: float | Window | FitWindow) -> FitWindow:
        """``window`` itself, or the fit window of a :class:`Window` or a bare ratio."""
        return window if isinstance(window, FitWindow) else cls(Window.of(window))

    @property
    def end_s(self) -> float | None:
        """The window's end [s] from each test demo's start (None for a ratio window)."""
        w = self.window
        if w.kind == "ratio":
            return None
        if w.kind == "seconds":
            return w.value
        if not (math.isfinite(self.nominal_s) and self.nominal_s > 0.0):
            raise DataError(None, "window", "a train_fraction window needs the fit's nominal duration")
        return w.value * self.nominal_s

    def observation(self) -> ObservationWindow:
        """The window as ``plan`` and ``run`` cut it (:class:`~ipromp_pin.data.ObservationWindow`)."""
        if self.window.is_ratio:
            return ObservationWindow(ratio=self.window.value)
        return ObservationWindow(until_s=self.end_s)

    def cut(self, demo: Demo, groups: Sequence[str] | None = None) -> Demo:
        """The observed part of ``demo`` (restricted to ``groups``): its first ``ratio``, or its
        samples of the window's first seconds (all of it when the window reaches past its end)."""
        return self.observation().cut(demo, groups, self.nominal_s)

    def fraction(self, demo: Demo) -> float:
        """The observed fraction of ``demo``'s length, in (0, 1], for the scores over its unobserved
        part (known after the fact: the scores use the whole recording)."""
        if self.window.is_ratio:
            return self.window.value
        end = self.end_s
        assert end is not None and demo.duration_s is not None
        return float(min(1.0, end / demo.duration_s)) if demo.duration_s > 0 else 1.0


def nominal_duration_s(train: Sequence[Demo]) -> float:
    """The nominal duration [s] of a fit on ``train``: the mean length of the training demos, as
    :class:`~ipromp_pin.promp.IProMP` computes its ``T_norm``."""
    return float(np.mean([d.t[-1] - d.t[0] for d in train]))


def check_windows(demos: Sequence[Demo], windows: Sequence[Window]) -> None:
    """Refuse, before any fit, a window that leaves fewer than 2 samples of a demo (the
    :class:`~ipromp_pin.exceptions.ObservationError` names the demo and the window). A
    ``train_fraction`` window is checked at its shortest: the fraction of the shortest demo."""
    if not demos:
        return
    shortest = min(d.t[-1] - d.t[0] for d in demos)
    for window in dict.fromkeys(windows):
        fit = window.for_fit(shortest)
        for demo in demos:
            fit.cut(demo)
