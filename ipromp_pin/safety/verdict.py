"""What a check says about a motion (:class:`Verdict`), and the verdicts of one motion together
(:class:`CheckReport`).

A verdict is the check's status (``pass``, ``fail``, ``skip``), one line of reason with the deciding
numbers, the typed measures behind them (a frozen dataclass per check, :class:`Measures`), whether
it counts toward the plan's verdict, and, for a failure that a slower motion would fix, the uniform
slow-down it asks for. Times in the measures (``t_s``) are on the motion's clock (the human's: t = 0
at the start of the human's motion) and point at a sample of the motion checked.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

Status = Literal["pass", "fail", "skip"]
"""A check's status: ``skip`` when it could not be made (its input unknown), which is not a pass."""


@dataclass(frozen=True)
class Measures:
    """The numbers behind a verdict; each check declares its own fields (a frozen dataclass)."""

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable form (arrays as lists, non-finite floats as None)."""
        return {f.name: jsonable(getattr(self, f.name)) for f in dataclasses.fields(self)}


@dataclass(frozen=True)
class NoMeasures(Measures):
    """The measures of a check that measured nothing (skipped)."""


def jsonable(v: object) -> object:
    """``v`` as JSON takes it: arrays and tuples as lists, numpy scalars as Python numbers,
    non-finite floats as None."""
    if isinstance(v, np.ndarray):
        return [jsonable(x) for x in v.tolist()]
    if isinstance(v, list | tuple):
        return [jsonable(x) for x in v]
    if isinstance(v, dict):
        return {k: jsonable(x) for k, x in v.items()}
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


@dataclass(frozen=True)
class Verdict:
    """One check's verdict on one motion.

    Attributes:
        name: The check's name (``report.json``'s ``checks`` key).
        status: ``"pass"``, ``"fail"`` or ``"skip"``.
        reason: One line with the deciding numbers.
        measures: The check's typed measures.
        required: Whether a failure fails the plan (else the check is advisory).
        slowdown: For a failure that a uniform slow-down ``k >= 1`` of the motion would fix
            (velocities / k, accelerations / k^2): that ``k``; None otherwise.
        fits_at: The check's first-order estimate of the uniform slow-down at which the motion would
            just pass (with the margin of :attr:`slowdown`), failing or passing: below 1 when the
            motion passes with room (that much faster would still pass); None when the check does
            not estimate it. Not part of the report: a planner's next timing may start from it
            (:func:`~.retime.next_guess`).
        local_slowdown: For a failure that slowing the motion only where it fails would fix: per
            sample of the motion (N,), the slow-down that sample needs (1 where it needs none; the
            velocities there / k); None otherwise. Not part of the report: the re-time loop slows
            the path there only (:func:`~.retime.retime_until_safe`).
    """

    name: str
    status: Status
    reason: str
    measures: Measures = NoMeasures()
    required: bool = True
    slowdown: float | None = None
    fits_at: float | None = None
    local_slowdown: np.ndarray | None = field(default=None, compare=False, repr=False)

    @property
    def passed(self) -> bool:
        """True unless the check failed (a skipped check does not fail the plan)."""
        return self.status != "fail"

    @property
    def blocks(self) -> bool:
        """Whether this verdict fails the plan (a required check that failed)."""
        return self.required and self.status == "fail"

    def to_dict(self) -> dict[str, Any]:
        """The check's entry in a report: status, required, reason, the measures, and the slow-down
        it asks for (only when it asks for one)."""
        out: dict[str, Any] = {"status": self.status, "required": self.required, "reason": self.reason}
        out.update(self.measures.to_dict())
        if self.slowdown is not None:
            out["slowdown"] = jsonable(float(self.slowdown))
        return out


@dataclass
class CheckReport:
    """The verdicts on one motion, in the suite's order.

    Attributes:
        verdicts: The verdicts.
    """

    verdicts: list[Verdict]

    def __iter__(self) -> Iterator[Verdict]:
        return iter(self.verdicts)

    def __getitem__(self, name: str) -> Verdict:
        for v in self.verdicts:
            if v.name == name:
                return v
        raise KeyError(name)

    def get(self, name: str) -> Verdict | None:
        """The verdict of check ``name``, or None when it was not run."""
        return next((v for v in self.verdicts if v.name == name), None)

    @property
    def passed(self) -> bool:
        """Whether every required check passed (skipped ones do not fail it)."""
        return not any(v.blocks for v in self.verdicts)

    @property
    def failures(self) -> list[str]:
        """Names of the required checks that failed."""
        return [v.name for v in self.verdicts if v.blocks]

    def to_dict(self) -> dict[str, dict[str, Any]]:
        """Check name -> its entry (:meth:`Verdict.to_dict`)."""
        return {v.name: v.to_dict() for v in self.verdicts}

    def lines(self, prefix: str = "") -> list[str]:
        """One line per verdict: ``[STATUS] name: reason`` (advisory checks marked)."""
        out = []
        for v in self.verdicts:
            tag = v.status.upper() + ("" if v.required else " (advisory)")
            out.append(f"  [{tag:>15}] {prefix}{v.name}: {v.reason}")
        return out

    def refusal(self) -> str:
        """Why the motion is refused: the failing required checks' names and reasons ("" if none)."""
        return "; ".join(f"{v.name}: {v.reason}" for v in self.verdicts if v.blocks)


def needed_slowdown(verdicts: Sequence[Verdict], max_slowdown: float) -> float | None:
    """The slow-down ``k >= 1`` that the failing required checks ask for together.

    Returns:
        1.0 when no required check failed; the largest requested ``k`` when every failing required
        check asked for one (finite and at most ``max_slowdown``); None when a failing check cannot
        be fixed by slowing down.
    """
    k = 1.0
    for v in verdicts:
        if not v.blocks:
            continue
        hint = v.slowdown
        if hint is None or not math.isfinite(float(hint)) or float(hint) > max_slowdown:
            return None
        k = max(k, float(hint))
    return k


def needed_local_slowdown(verdicts: Sequence[Verdict], n_samples: int) -> np.ndarray | None:
    """The slow-down per sample (N,) that the failing required checks ask for together (the
    largest per sample), when every one of them asks for a local one
    (:attr:`Verdict.local_slowdown`, one value per sample of the motion); None otherwise (none
    failed, or one asks for a uniform slow-down only or none at all)."""
    need: np.ndarray | None = None
    for v in verdicts:
        if not v.blocks:
            continue
        local = v.local_slowdown
        if local is None or local.shape != (n_samples,) or not np.all(np.isfinite(local)):
            return None
        need = local.copy() if need is None else np.maximum(need, local)
    return need
