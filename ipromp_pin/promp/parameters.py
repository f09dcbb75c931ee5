"""The estimator's parameters: their names, declared constraints and one function that checks them.

Every parameter of :class:`~ipromp_pin.promp.estimator.IProMP` has one entry in
:data:`PARAMETER_CONSTRAINTS` (as scikit-learn's ``_parameter_constraints``): a :class:`Constraint`
(what the value may be, and the words that complete "``<name> must be ...``") or None (not checked
on its own). :func:`validate_params` checks a parameter mapping against the table;
:func:`parse_params` also parses the observed groups and the coupling and does the checks that
involve two parameters. :func:`param_names` derives the names from a constructor's signature (as
scikit-learn's ``_get_param_names``).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Self, TypeGuard, cast

import numpy as np

from ..data import parse_groups
from ..exceptions import ModelError

MAX_POINTS = 100_000
"""Largest number of points of a predicted trajectory (``n_points``)."""

MAX_BLAS_THREADS = 1024
"""Largest ``blas_threads``."""


@dataclass(frozen=True)
class Constraint:
    """The values a parameter may take.

    Attributes:
        must: Completes the error message "``<name> must <must>, got <value>``".
        test: Whether a value is allowed (it may raise TypeError or ValueError on a value of a
            wrong type, as ``float(value)`` does).
    """

    must: str
    test: Callable[[object], bool]


def is_int(value: object) -> TypeGuard[int | np.integer]:
    """Whether ``value`` is an integer (``int`` or an integral NumPy integer, not a bool)."""
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def is_number(value: object) -> TypeGuard[int | float | np.integer | np.floating]:
    """Whether ``value`` is a real number (not a bool)."""
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)


def word_or_positive(must: str, *words: str) -> Constraint:
    """One of the strings ``words``, or a positive finite float."""

    def test(v: object) -> bool:
        if isinstance(v, str):
            return v in words
        return float(v) > 0 and bool(np.isfinite(float(v)))  # type: ignore[arg-type]

    return Constraint(must, test)


def integer(low: int, high: int | None = None) -> Constraint:
    """An integer ``>= low`` (and ``<= high`` when given)."""
    bound = f">= {low}" if high is None else f"in [{low}, {high}]"
    return Constraint(
        f"be an integer {bound}", lambda v: bool(is_int(v) and v >= low and (high is None or v <= high))
    )


def finite_number() -> Constraint:
    """A finite real number."""
    return Constraint("be a finite number", lambda v: is_number(v) and bool(np.isfinite(v)))


def _temperature(v: object) -> bool:
    return v == "auto" if isinstance(v, str) else 0.0 < float(v) <= 1.0  # type: ignore[arg-type]


def _task_prior(prior: object) -> bool:
    return prior is None or (
        isinstance(prior, Mapping)
        and all(isinstance(t, str) and is_number(p) and np.isfinite(p) and p >= 0 for t, p in prior.items())
    )


PARAMETER_CONSTRAINTS: dict[str, Constraint | None] = {
    "observe": None,  # parsed by parse_groups; must not hold the robot group (parse_params)
    "robot_group": None,
    "noise": word_or_positive("be 'auto' or a positive float", "auto"),
    "temperature": Constraint("be 'auto' or a float in (0, 1]", _temperature),
    "condition_noise": word_or_positive("be 'auto', 'same' or a positive float", "auto", "same"),
    "pooling": Constraint("be in [0, 1]", lambda v: 0.0 <= float(v) <= 1.0),  # type: ignore[arg-type]
    # a list must name distinct observed groups (parse_params)
    "coupling": Constraint(
        "be 'auto', 'all' or a list of observed groups",
        lambda v: not isinstance(v, str) or v in ("auto", "all"),
    ),
    "n_alpha": integer(3),
    "n_points": integer(2, MAX_POINTS),
    "n_basis": integer(2),
    "blas_threads": Constraint(
        f"be None or an integer in [1, {MAX_BLAS_THREADS}]",
        lambda v: v is None or bool(is_int(v) and 1 <= v <= MAX_BLAS_THREADS),
    ),
    "task_prior": Constraint("map task names to non-negative numbers", _task_prior),
    "ridge": finite_number(),
    "margin": finite_number(),
    "alpha_width": finite_number(),
    "width": None,
    "head": None,
    "handover": None,
    "novelty_alpha": Constraint(
        "be None or a number in (0, 0.5]",
        lambda v: (
            v is None or bool(isinstance(v, (int, float)) and not isinstance(v, bool) and 0.0 < v <= 0.5)
        ),
    ),
    "log_groups": None,
}
"""Parameter name -> its :class:`Constraint` (None: not checked on its own), in checking order."""


def validate_params(
    params: Mapping[str, object], constraints: Mapping[str, Constraint | None] = PARAMETER_CONSTRAINTS
) -> None:
    """Raise ModelError naming the first parameter of ``params`` that its constraint refuses."""
    for name, constraint in constraints.items():
        if constraint is not None and name in params and not constraint.test(params[name]):
            raise ModelError(f"{name} must {constraint.must}, got {params[name]!r}")


def parse_params(
    params: Mapping[str, object], constraints: Mapping[str, Constraint | None] = PARAMETER_CONSTRAINTS
) -> tuple[list[str], str | list[str]]:
    """Validate the estimator's parameters -> the observed groups and the coupling (parsed)."""
    # a value of a wrong type fails inside parse_groups, as before
    observe = parse_groups(cast("str | Iterable[str]", params["observe"]))
    raw = params["coupling"]
    coupling = raw if isinstance(raw, str) else list(raw)  # type: ignore[call-overload]
    robot = params["robot_group"]
    if robot in observe:
        raise ModelError(f"the robot group '{robot}' cannot be an observed group")
    validate_params(params, constraints)
    if not isinstance(coupling, str) and (
        any(g not in observe for g in coupling) or len(set(coupling)) != len(coupling)
    ):
        raise ModelError(f"coupling {coupling} must list distinct observed groups ({observe})")
    return observe, coupling


def param_names(cls: type[Any]) -> tuple[str, ...]:
    """The parameter names of ``cls.__init__`` (keyword parameters, in signature order)."""
    sig = inspect.signature(cls.__init__)
    names = []
    for p in list(sig.parameters.values())[1:]:
        if p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
            raise TypeError(f"{cls.__name__}.__init__ must not take *args or **kwargs")
        names.append(p.name)
    return tuple(names)


class ParameterMixin:
    """Parameters as scikit-learn's ``BaseEstimator`` has them: the names of ``__init__``'s
    arguments, stored unchanged by ``__init__``, read by :meth:`get_params`, set by
    :meth:`set_params`, and checked against the class's ``_parameter_constraints``."""

    _parameter_constraints: Mapping[str, Constraint | None] = {}

    @classmethod
    def _get_param_names(cls) -> tuple[str, ...]:
        """The parameter names, from the signature of ``__init__`` (scikit-learn convention)."""
        return param_names(cls)

    def get_params(self, deep: bool = True) -> dict[str, object]:
        """The constructor parameters (scikit-learn convention; ``deep`` is accepted and ignored)."""
        return {name: getattr(self, name) for name in self._get_param_names()}

    def set_params(self, **params: object) -> Self:
        """Set constructor parameters (scikit-learn convention); refit to use them."""
        names = self._get_param_names()
        for name, value in params.items():
            if name not in names:
                raise ModelError(f"unknown parameter '{name}' (parameters: {', '.join(names)})")
            setattr(self, name, value)
        return self
