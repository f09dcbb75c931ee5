"""The shipped JSON Schemas are valid, the files the pipeline writes validate against them, and the
documentation lists every field they allow."""

from __future__ import annotations

import copy
import json
import re
from pathlib import Path

import jsonschema
import pytest
from helpers_cli import without_uncertainty

from ipromp_pin.app import main
from ipromp_pin.app.config import load_pipeline
from ipromp_pin.app.session import prepare_session
from ipromp_pin.outputs.report import report_dict
from ipromp_pin.planning.one_shot import plan
from ipromp_pin.schemas import SCHEMA_FILES, SCHEMAS_DIR, load_schema, schema_path

ROOT = Path(__file__).resolve().parents[2]
PIPELINE = ROOT / "pipelines" / "baxter_handover.toml"
VALIDATOR = jsonschema.Draft202012Validator


def _validate(doc: dict, name: str = "report") -> None:
    VALIDATOR(load_schema(name)).validate(doc)


@pytest.mark.parametrize("name", sorted(SCHEMA_FILES))
def test_shipped_schemas_are_valid_json_schemas(name):
    schema = load_schema(name)
    VALIDATOR.check_schema(schema)
    assert schema["$schema"].endswith("/2020-12/schema")
    assert schema_path(name).parent == SCHEMAS_DIR
    # every schema file in the folder is registered
    assert {p.name for p in SCHEMAS_DIR.glob("*.schema.json")} == set(SCHEMA_FILES.values())


@pytest.fixture(scope="module")
def written_report(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("run")
    assert main(["run", str(PIPELINE), "--out", str(out), "--no-preview", "--no-rosbag", "--rate", "60"]) == 0
    return json.loads((out / "report.json").read_text())


def test_written_report_validates_and_reports_the_configured_rate(written_report):
    _validate(written_report)
    assert written_report["trajectory"]["rate_hz"] == 60.0


def test_report_with_a_skipped_check_validates(tmp_path):
    cfg = load_pipeline(PIPELINE, out_dir=tmp_path, task="tape")
    prep = prepare_session(cfg, log=lambda _m: None)
    result = without_uncertainty(
        plan(prep.model, prep.robot, prep.observed(), prep.suite, prep.context), prep.suite
    )
    doc = json.loads(json.dumps(report_dict(result, None, ["a warning"]), allow_nan=False))
    assert doc["feasibility"]["checks"]["uncertainty"]["status"] == "skip"
    assert doc["observation"] is None
    _validate(doc)
    assert doc["trajectory"]["rate_hz"] == 100.0


@pytest.mark.parametrize(
    "path, value",
    [
        (("undocumented_field",), 1),
        (("trajectory", "rate_hz"), "100"),
        (("feasibility", "checks", "joint_limits", "status"), "ok"),
        (("posterior", "rod"), 1.5),
        (("feasibility", "handover_position_m"), [0.1, 0.2]),
    ],
)
def test_schema_rejects_undocumented_or_wrong_fields(written_report, path, value):
    doc = copy.deepcopy(written_report)
    node = doc
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    with pytest.raises(jsonschema.ValidationError):
        _validate(doc)


def _documented_fields(section: str) -> set[str]:
    """Field names in the first column of the tables under the ``section`` heading of docs/formats.md."""
    text = (ROOT / "docs" / "formats.md").read_text()
    start = text.index(f"\n{section}\n")
    end = text.find("\n## ", start + 1)
    body = text[start : end if end > 0 else None]
    return set(re.findall(r"^\| `([A-Za-z_0-9]+)` \|", body, flags=re.MULTILINE))


def test_docs_list_every_field_of_the_report_schema():
    schema = load_schema("report")
    documented = _documented_fields("## Plan report")
    assert set(schema["properties"]) <= documented, set(schema["properties"]) - documented
    traj = schema["properties"]["trajectory"]["properties"]
    feas = schema["properties"]["feasibility"]["properties"]
    assert set(traj) <= documented and set(feas) <= documented
    measures = {f for c in feas["checks"]["properties"].values() for f in c["properties"]}
    named = set(re.findall(r"`([A-Za-z_0-9]+)`", _section("## Plan report")))
    assert measures <= named, measures - named


def test_docs_list_every_field_of_the_plan_summary_schema():
    schema = load_schema("plan_summary")
    documented = _documented_fields("## Plan summary")
    rows = schema["properties"]["recordings"]["items"]["properties"]
    assert set(schema["properties"]) | set(rows) <= documented, (
        set(schema["properties"]) | set(rows)
    ) - documented


def _section(heading: str) -> str:
    text = (ROOT / "docs" / "formats.md").read_text()
    start = text.index(f"\n{heading}\n")
    end = text.find("\n## ", start + 1)
    return text[start : end if end > 0 else None]


@pytest.fixture(scope="module")
def written_replay(tmp_path_factory) -> tuple[dict, dict]:
    out = tmp_path_factory.mktemp("replay")
    assert main(["replay", str(PIPELINE), "--out", str(out), "--no-preview"]) == 0
    return json.loads((out / "report.json").read_text()), json.loads((out / "replans.json").read_text())


def test_written_replay_files_validate(written_replay):
    report, replans = written_replay
    _validate(report, "replay_report")
    _validate(replans, "replans")
    assert replans["replans"] and report["replans"] == len(replans["replans"])
    bad = copy.deepcopy(replans)
    bad["replans"][0]["committed"] = "yes"
    with pytest.raises(jsonschema.ValidationError):
        _validate(bad, "replans")
    bad = copy.deepcopy(report)
    bad["surprise"] = 1
    with pytest.raises(jsonschema.ValidationError):
        _validate(bad, "replay_report")


def test_docs_list_every_field_of_the_replay_schemas():
    text = (ROOT / "docs" / "closed_loop.md").read_text()
    section = text[text.index("\n## Files\n") :]
    named = set(re.findall(r"`([A-Za-z_0-9]+)`", section))
    for name in ("replans", "replay_report"):
        schema = load_schema(name)
        fields = set(schema["properties"])
        if name == "replans":
            fields |= set(schema["properties"]["replans"]["items"]["properties"])
        assert fields <= named, (name, fields - named)
