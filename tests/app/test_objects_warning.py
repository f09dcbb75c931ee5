"""A task the data has but the objects file lacks (issue of 2026-12-04, round 3): no payload and no
retreat for it, said in one warning line at the start of ``run`` / ``replay`` (before training) and
in the report's ``warnings``, not only inside a check's reason."""

from __future__ import annotations

import json

from helpers_cli import PIPELINE

from ipromp_pin.app import main
from ipromp_pin.app.config import load_pipeline
from ipromp_pin.app.session import prepare_session


def _objects(tmp_path):
    f = tmp_path / "objects.toml"
    f.write_text("[rod]\nmass_kg = 0.42\nholder = 'robot_receives'\n")
    return f


def test_a_task_without_an_object_is_warned_before_training(tmp_path, tiny):
    ds, _ = tiny
    objects = _objects(tmp_path)
    cfg = load_pipeline(PIPELINE, dataset=ds, objects=objects, model_cache=False)
    events: list[str] = []
    session = prepare_session(
        cfg, log=lambda m: events.append("log " + m), warn=lambda m: events.append("warn " + m)
    )
    lines = [e for e in events if "wrench" in e and "objects.toml" in e]
    assert len(lines) == 1 and lines[0].startswith("warn "), events
    assert "no payload and no retreat" in lines[0]
    first_model_line = next(i for i, e in enumerate(events) if e.startswith("log [model]"))
    assert events.index(lines[0]) < first_model_line
    assert sum("wrench" in w for w in session.warnings) == 1
    assert not any("'rod'" in w for w in session.warnings)


def test_run_and_replay_report_it(tmp_path, tiny, capsys):
    ds, model = tiny
    objects = _objects(tmp_path)
    common = ["--dataset", str(ds), "--model", str(model), "--objects", str(objects), "--no-preview"]
    for command in ("run", "replay"):
        out = tmp_path / command
        code = main([command, str(PIPELINE), *common, "--out", str(out)])
        assert code in (0, 3)
        err = capsys.readouterr().err
        assert sum("warning:" in ln and "'wrench'" in ln for ln in err.splitlines()) == 1, err
        report = json.loads((out / "report.json").read_text())
        assert any("'wrench'" in w and str(objects) in w for w in report["warnings"]), report["warnings"]


def test_the_shipped_objects_cover_the_synthetic_tasks_without_a_warning(tmp_path, tiny):
    ds, _ = tiny
    cfg = load_pipeline(PIPELINE, dataset=ds, model_cache=False)
    warnings: list[str] = []
    prepare_session(cfg, log=lambda m: None, warn=warnings.append)
    assert not any("no payload" in w for w in warnings)
