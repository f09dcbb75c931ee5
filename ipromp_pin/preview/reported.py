"""A figure of the report as a preview panel states it: :class:`ReportedFigure`.

A panel that shows what a check measured (the separation panel: ``human_clearance``,
``contact_speed``; the torque panel: ``joint_torques``) states the check's figure as the report gives
it: read from the check's verdict (:mod:`ipromp_pin.outputs.preview_content` fills them in), never
computed again by the page. Its per-sample track is labelled as what it is and agrees with the
figure at the figure's sample. Plain values, so that the preview does not depend on the checks.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from ..exceptions import DataError

__all__ = ["ReportedFigure", "checked_figures"]


@dataclass(frozen=True)
class ReportedFigure:
    """One check's figure, as the report gives it.

    Attributes:
        check: The check as the report and the page's check list name it, e.g. ``"human_clearance"``
            or ``"retreat joint_torques"``.
        value: The figure: e.g. the smallest clearance [m], the largest contact-speed ratio, the peak
            torque usage (a ratio).
        t_s: When, in [s] on the human's clock (a sample of the motion checked).
        text: The verdict's one line (the report's ``reason``).
        where: What it is measured between, e.g. ``(link, body part)`` or ``(joint,)``.
    """

    check: str
    value: float
    t_s: float
    text: str
    where: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not self.check:
            raise DataError("preview", "reported.check", "a reported figure needs its check's name")
        for name in ("value", "t_s"):
            v = getattr(self, name)
            if not isinstance(v, int | float) or not math.isfinite(float(v)):
                raise DataError(
                    "preview", f"reported.{name}", f"{self.check}: must be a finite number, got {v!r}"
                )
        object.__setattr__(self, "where", tuple(str(w) for w in self.where))

    def to_dict(self) -> dict[str, Any]:
        """The panel's JSON form."""
        return {
            "check": self.check,
            "value": float(self.value),
            "t_s": float(self.t_s),
            "text": self.text,
            "where": list(self.where),
        }


def checked_figures(figures: Iterable[object], name: str) -> tuple[ReportedFigure, ...]:
    """``figures`` as a tuple, each checked to be a :class:`ReportedFigure` (else a DataError naming
    the field ``name``)."""
    out = []
    for f in figures:
        if not isinstance(f, ReportedFigure):
            raise DataError("preview", name, f"expected ReportedFigure items, got {type(f).__name__}")
        out.append(f)
    return tuple(out)
