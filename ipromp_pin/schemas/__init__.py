"""JSON Schemas (draft 2020-12) of the JSON files ipromp_pin writes, shipped with the package.

============================  ============================  ==================================
file                          schema                        written by
============================  ============================  ==================================
``report.json``               ``report.schema.json``        ``ipromp-pin run``, ``plan``
``summary.json``              ``plan_summary.schema.json``  ``ipromp-pin plan``
``replans.json``              ``replans.schema.json``       ``ipromp-pin replay``
replay ``report.json``        ``replay_report.schema.json`` ``ipromp-pin replay``
============================  ============================  ==================================

The schemas are strict (``additionalProperties: false`` where the fields are documented), so a
field added to a file without being added to its schema and to ``docs/formats.md`` fails the tests
(``tests/outputs/test_schemas.py`` validates files written by ``run`` and ``replay``). Use them with
any JSON Schema validator, e.g. ``jsonschema.validate(doc, load_schema("report"))``.
"""

from __future__ import annotations

import json
from pathlib import Path

SCHEMAS_DIR = Path(__file__).resolve().parent
"""Folder of the shipped ``*.schema.json`` files."""

SCHEMA_FILES = {
    "report": "report.schema.json",
    "replans": "replans.schema.json",
    "replay_report": "replay_report.schema.json",
    "plan_summary": "plan_summary.schema.json",
}
"""Schema name -> file in :data:`SCHEMAS_DIR`."""


def schema_path(name: str) -> Path:
    """The file of the schema ``name`` (a key of :data:`SCHEMA_FILES`)."""
    if name not in SCHEMA_FILES:
        raise KeyError(f"unknown schema {name!r} (schemas: {', '.join(SCHEMA_FILES)})")
    return SCHEMAS_DIR / SCHEMA_FILES[name]


def load_schema(name: str) -> dict:
    """The JSON Schema ``name`` as a dictionary."""
    return json.loads(schema_path(name).read_text(encoding="utf-8"))
