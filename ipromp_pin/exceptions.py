"""Exceptions raised by ipromp_pin.

Every error a user can trigger with bad input derives from :class:`IPrompPinError`
and says *where* (file, field) and *what* went wrong, so that nothing silently
produces numbers.
"""

from __future__ import annotations


class IPrompPinError(Exception):
    """Base class of all ipromp_pin errors."""


class DataError(IPrompPinError, ValueError):
    """Bad or unreadable demonstration data.

    Attributes:
        source: File (or folder) the problem was found in, or ``None``.
        field: Column, channel group or key concerned, or ``None``.
        problem: Human-readable description of the problem.
    """

    def __init__(self, source: object | None, field: str | None, problem: str) -> None:
        self.source = None if source is None else str(source)
        self.field = field
        self.problem = problem
        where = []
        if self.source is not None:
            where.append(self.source)
        if field is not None:
            where.append(f"field '{field}'")
        prefix = ": ".join(where)
        super().__init__(f"{prefix}: {problem}" if prefix else problem)


class ObservationError(DataError):
    """An observation does not fit the model (dimensions, groups, ratio, length)."""


class ModelError(IPrompPinError):
    """A model cannot be fitted or used as asked."""


class NotFittedError(ModelError):
    """A model method that needs a fitted model was called before ``fit``."""


class ModelFileError(ModelError):
    """A model file is corrupt, truncated, of an unknown format or a newer version."""


class RobotError(IPrompPinError):
    """Bad robot settings or description (unknown joint, missing frame, bad limits)."""


class InfeasibleError(IPrompPinError):
    """A path or start state cannot be turned into a trajectory within the limits."""


class UnreachableError(InfeasibleError):
    """The executing arm cannot reach the predicted hand-over pose (a plan retargeted to another arm):
    refused, never a shifted hand-over (exit status 3 on the command line, as a failed check)."""


class PipelineError(IPrompPinError):
    """A pipeline definition file is invalid."""


class OutputError(IPrompPinError):
    """An output file or folder cannot be written (a file where a folder is needed, a read-only
    folder, a full disk); earlier files are left as they were."""
