"""The JSON Schema of the checks' entries in the reports, derived from the checks themselves.

Each check declares the type of its measures (:attr:`~.base.Check.measures_type`, a frozen dataclass
whose docstring's ``Attributes:`` section describes every field, with its unit); the entry of a
check in ``report.json`` (:meth:`~.verdict.Verdict.to_dict`) is its status, whether it is required,
its reason, its measures and, when it asks for one, the slow-down. :func:`checks_schema` writes that
down as JSON Schema, which is what the shipped ``report.schema.json`` holds (a test compares them),
so that a new check or a new measure cannot be written without its schema.
"""

from __future__ import annotations

import dataclasses
import re
import sys
import types
import typing
from collections.abc import Iterable
from typing import Any

from .base import Check

BASE_FIELDS: dict[str, dict[str, Any]] = {
    "status": {"enum": ["pass", "fail", "skip"], "description": "pass, fail or skip (not made)"},
    "required": {"type": "boolean", "description": "whether a failure fails the plan"},
    "reason": {"type": "string", "description": "one line with the deciding numbers"},
    "slowdown": {
        "type": ["number", "null"],
        "description": "the uniform slow-down that would pass (failures)",
    },
}
"""The fields every check's entry has (``slowdown`` only when it asks for one)."""


def _json_type(annotation: object) -> dict[str, Any]:
    """The JSON Schema of a measure's type annotation (floats may be null: non-finite values are)."""
    origin = typing.get_origin(annotation)
    if origin in (types.UnionType, typing.Union):
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        inner = _json_type(args[0]) if len(args) == 1 else {}
        kind = inner.get("type", [])
        kinds = kind if isinstance(kind, list) else [kind]
        return {**inner, "type": [*kinds, "null"] if "null" not in kinds else kinds}
    if origin in (list, tuple):
        (item,) = typing.get_args(annotation)[:1] or (Any,)
        return {"type": "array", "items": _json_type(item)} if item is not Any else {"type": "array"}
    if origin is dict or annotation is dict:
        return {"type": "object"}
    table = {float: ["number", "null"], int: "integer", str: "string", bool: "boolean"}
    return {"type": table[annotation]} if annotation in table else {}


def _descriptions(cls: type) -> dict[str, str]:
    """Field -> its description in the class docstring's ``Attributes:`` section."""
    doc = cls.__doc__ or ""
    body = doc.split("Attributes:", 1)[1] if "Attributes:" in doc else ""
    out: dict[str, str] = {}
    for m in re.finditer(r"^\s*(\w+): (.*(?:\n(?!\s*\w+: ).*)*)", body, flags=re.MULTILINE):
        out[m.group(1)] = " ".join(m.group(2).split())
    return out


def verdict_schema(check: type[Check]) -> dict[str, Any]:
    """The JSON Schema of ``check``'s entry in a report."""
    measures = check.measures_type
    hints = typing.get_type_hints(measures)
    described = _descriptions(measures)
    props: dict[str, Any] = {k: dict(v) for k, v in BASE_FIELDS.items() if k != "slowdown"}
    for f in dataclasses.fields(measures):
        props[f.name] = _json_type(hints[f.name])
        if f.name in described:
            props[f.name]["description"] = described[f.name]
    props["slowdown"] = dict(BASE_FIELDS["slowdown"])
    module_doc = sys.modules[check.__module__].__doc__ or ""
    return {
        "type": "object",
        "description": " ".join(module_doc.split("\n\n")[0].split()),
        "properties": props,
        "required": ["status", "required", "reason"],
        "additionalProperties": False,
    }


def checks_schema(checks: Iterable[type[Check]]) -> dict[str, Any]:
    """The JSON Schema of a report's ``checks`` object: one optional entry per check."""
    return {
        "type": "object",
        "properties": {c.name: verdict_schema(c) for c in checks},
        "additionalProperties": False,
    }
