"""Validating the fields of a settings document: every key known or refused, every value of its type
and within its plausible range.

One style for every settings file the package reads (robot settings, pipeline definitions, objects
files, limit profiles): an error is one line ``FILE: field 'dotted.name': PROBLEM``; a key that is
not known names the known key it resembles (``unknown key; did you mean 'speed_margin'? (known:
...)``); a value outside its plausible range names the range and where the range comes from.
Nothing is clamped: a value is used as written or refused.

* :func:`field_errors` makes the caller's error builder (its exception class and file);
* :class:`Range`: a plausible range, its unit and its source;
* :class:`Table`: one table of a parsed TOML document, its keys checked when it is made, with typed
  getters (:meth:`Table.number`, :meth:`Table.vector`, :meth:`Table.text`, :meth:`Table.table`).
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

FieldError = Callable[[str | None, str], Exception]
"""Builds the caller's one-line error from a dotted field name (None: the file as a whole) and a problem."""

REQUIRED: Any = object()
"""Default of a getter whose key must be present."""


def field_errors(kind: Callable[[str], Exception], source: object) -> FieldError:
    """The error builder of file ``source``: ``kind("SOURCE: field 'FIELD': PROBLEM")``."""

    def make(field: str | None, problem: str) -> Exception:
        where = str(source) + (f": field '{field}'" if field else "")
        return kind(f"{where}: {problem}")

    return make


def dotted(prefix: str, key: str) -> str:
    """``prefix.key`` (``key`` alone when the prefix is empty)."""
    return f"{prefix}.{key}" if prefix else key


def did_you_mean(key: str, known: Iterable[str]) -> str:
    """``"; did you mean 'k'?"`` for the known name ``k`` closest to ``key`` (difflib ratio >= 0.6,
    case ignored), or ``""`` when none is close."""
    names = list(known)
    lower = {n.lower(): n for n in names}
    close = difflib.get_close_matches(key.lower(), list(lower), n=1, cutoff=0.6)
    return f"; did you mean '{lower[close[0]]}'?" if close else ""


def unknown(key: str, known: Iterable[str], what: str = "key") -> str:
    """The problem of an unknown ``key``: ``unknown key; did you mean 'x'? (known: a, b)``."""
    names = list(known)
    return f"unknown {what}{did_you_mean(key, names)} (known: {', '.join(names) or 'none'})"


def check_keys(
    table: Mapping[str, Any], known: Iterable[str], prefix: str, error: FieldError, what: str = "key"
) -> None:
    """Refuse the first key of ``table`` that is not ``known`` (the field ``prefix.key``)."""
    names = list(known)
    for key in table:
        if key not in names:
            raise error(dotted(prefix, key), unknown(key, names, what))


def shown(value: object, limit: int = 80) -> str:
    """``repr(value)``, cut to ``limit`` characters (a message stays one short line)."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def is_number(value: object) -> bool:
    """Whether ``value`` is an int or a float (a bool is not a number)."""
    return isinstance(value, int | float) and not isinstance(value, bool)


@dataclass(frozen=True)
class Range:
    """A plausible range of a settings value, in its unit, and where the range comes from.

    Attributes:
        lo: Lower bound.
        hi: Upper bound.
        unit: Unit of the value (``""``: a pure number).
        source: Where the bounds come from (a standard's clause or table, a measurement, a reason).
        lo_open: The lower bound itself is excluded.
        hi_open: The upper bound itself is excluded.
    """

    lo: float
    hi: float
    unit: str
    source: str
    lo_open: bool = False
    hi_open: bool = False

    def contains(self, value: float) -> bool:
        """Whether ``value`` lies in the range (NaN never does)."""
        above = value > self.lo if self.lo_open else value >= self.lo
        below = value < self.hi if self.hi_open else value <= self.hi
        return bool(above and below)

    def text(self) -> str:
        """The range as written in messages and docs, e.g. ``[0.01, 2] s`` or ``(0, 100]``."""
        body = f"{'(' if self.lo_open else '['}{self.lo:g}, {self.hi:g}{')' if self.hi_open else ']'}"
        return f"{body} {self.unit}" if self.unit else body

    def narrowed(self, lo: float | None = None, hi: float | None = None) -> Range:
        """The same range with other bounds (e.g. one body region's own limit), same source."""
        return Range(
            self.lo if lo is None else lo, self.hi if hi is None else hi, self.unit, self.source,
            self.lo_open, self.hi_open,
        )  # fmt: skip

    def problem(self, value: float) -> str:
        """The problem of a ``value`` outside the range."""
        unit = f" {self.unit}" if self.unit else ""
        return f"implausible value {value:g}{unit} (plausible range {self.text()}: {self.source})"

    def check(self, values: np.ndarray | float, field: str, error: FieldError) -> None:
        """Refuse the first of ``values`` outside the range."""
        arr = np.atleast_1d(np.asarray(values, dtype=float))
        for v in arr.ravel():
            if not self.contains(float(v)):
                raise error(field, self.problem(float(v)))


class Table:
    """One table of a settings document, its keys checked when it is made.

    Args:
        value: The parsed table (anything else is refused as "must be a table").
        prefix: Its dotted name (``""`` for the document).
        error: The error builder (:func:`field_errors`).
        known: Its known keys (None: any key, e.g. a table of names).
        what: What its keys are called in messages (``key``, ``table``, ``section``).
    """

    def __init__(
        self,
        value: object,
        prefix: str,
        error: FieldError,
        known: Iterable[str] | None = None,
        what: str = "key",
    ) -> None:
        if not isinstance(value, dict):
            raise error(prefix or None, f"must be a table, got {shown(value)}")
        self.data: dict[str, Any] = value
        self.prefix = prefix
        self.error_fn = error
        if known is not None:
            check_keys(value, known, prefix, error, what)

    def __contains__(self, key: str) -> bool:
        return key in self.data

    def keys(self) -> list[str]:
        """The table's keys, in file order."""
        return list(self.data)

    def field(self, key: str) -> str:
        """The dotted name of ``key`` in this table."""
        return dotted(self.prefix, key)

    def error(self, key: str | None, problem: str) -> Exception:
        """The one-line error about ``key`` of this table (None: the table itself)."""
        return self.error_fn((self.prefix or None) if key is None else self.field(key), problem)

    def raw(self, key: str, default: Any = REQUIRED) -> Any:
        """The value of ``key`` as parsed, or ``default`` when absent (:data:`REQUIRED`: refused)."""
        if key not in self.data:
            if default is REQUIRED:
                raise self.error(key, "missing")
            return default
        return self.data[key]

    def table(
        self, key: str, known: Iterable[str] | None = None, required: bool = False, what: str = "key"
    ) -> Table:
        """Sub-table ``key`` (an empty one when absent and not ``required``)."""
        value = self.raw(key, REQUIRED if required else {})
        return Table(value, self.field(key), self.error_fn, known, what)

    def number(self, key: str, rng: Range | None = None, default: Any = REQUIRED) -> float:
        """``key`` as a finite float within ``rng`` (an int is accepted), or ``default`` when absent."""
        if key not in self.data and default is not REQUIRED:
            return default
        value = self.raw(key)
        if not is_number(value):
            raise self.error(key, f"must be a number, got {shown(value)}")
        out = float(value)
        if not math.isfinite(out):
            raise self.error(key, f"must be finite, got {out}")
        if rng is not None:
            rng.check(out, self.field(key), self.error_fn)
        return out

    def vector(
        self,
        key: str,
        n: int,
        rng: Range | None = None,
        default: Any = REQUIRED,
        scalar: bool = False,
    ) -> np.ndarray:
        """``key`` as ``n`` finite floats (n,) within ``rng`` (``scalar``: one number stands for all),
        or ``default`` (as an array) when absent."""
        if key not in self.data and default is not REQUIRED:
            return np.array(default, dtype=float)
        return numbers(self.raw(key), n, self.field(key), self.error_fn, rng, scalar)

    def text(self, key: str, default: Any = REQUIRED, choices: Iterable[str] | None = None) -> str:
        """``key`` as a string (one of ``choices`` when given), or ``default`` when absent."""
        if key not in self.data and default is not REQUIRED:
            return default
        value = self.raw(key)
        if not isinstance(value, str):
            raise self.error(key, f"must be a string, got {shown(value)}")
        if choices is not None:
            allowed = list(choices)
            if value not in allowed:
                raise self.error(
                    key, f"must be one of {', '.join(repr(c) for c in allowed)}, got {shown(value)}"
                    + did_you_mean(value, allowed).replace(";", ",", 1)
                )  # fmt: skip
        return value


def numbers(
    value: object,
    n: int | None,
    field: str,
    error: FieldError,
    rng: Range | None = None,
    scalar: bool = False,
) -> np.ndarray:
    """``value`` as finite floats (n,) (``n`` None: any length) within ``rng``; ``scalar``: one number
    stands for all ``n``."""
    if scalar and is_number(value) and n is not None:
        value = [value] * n
    if not isinstance(value, list) or (n is not None and len(value) != n):
        want = "a list of numbers" if n is None else f"a list of {n} numbers"
        raise error(field, f"must be {'a number or ' if scalar else ''}{want}, got {shown(value)}")
    if not all(is_number(v) for v in value):
        raise error(field, f"must contain numbers only, got {shown(value)}")
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise error(field, f"must be finite, got {shown(arr.tolist())}")
    if rng is not None:
        rng.check(arr, field, error)
    return arr


def float_array(
    value: Any, field: str, ndim: int, error: FieldError, last: int | None = None, finite: bool = True
) -> np.ndarray:
    """``value`` as a non-empty float array with ``ndim`` dimensions (and last dimension ``last``),
    every value finite unless ``finite`` is False; else ``error(field, problem)``."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise error(field, f"not a numeric array ({exc})") from exc
    if arr.ndim != ndim:
        raise error(field, f"expected {ndim} dimensions, got shape {arr.shape}")
    if last is not None and arr.shape[-1] != last:
        raise error(field, f"expected last dimension {last}, got shape {arr.shape}")
    if arr.size == 0:
        raise error(field, "is empty")
    if finite and not np.all(np.isfinite(arr)):
        raise error(field, "contains NaN or infinite values")
    return arr
