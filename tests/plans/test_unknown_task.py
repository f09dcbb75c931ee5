"""The robot acts only on a known task: ``run`` and ``plan`` refuse an observation that matches none
of the model's tasks with exit status 3 and one line, write no trajectory under the usual names, and
say so in report.json and the summary."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import pytest

from ipromp_pin.app import main
from ipromp_pin.schemas import load_schema

PIPELINE = Path(__file__).resolve().parents[2] / "pipelines" / "baxter_handover.toml"


@pytest.fixture(scope="module")
def other_tasks(tmp_path_factory) -> Path:
    """Synthetic recordings of three tasks, one of which (tape) the tiny model (rod, wrench) never learned."""
    root = tmp_path_factory.mktemp("three_tasks")
    assert main(["synth", str(root), "--tasks", "3", "--demos", "2", "--seed", "11"]) == 0
    return root


def test_plan_refuses_an_unknown_task_with_exit_3(tiny, other_tasks, tmp_path, capsys):
    out = tmp_path / "out"
    paths = [str(p) for p in sorted(other_tasks.glob("*/*_000.npz"))]
    assert main(["plan", str(tiny[1]), *paths, "--out", str(out), "--no-rosbag"]) == 3
    err = capsys.readouterr().err.splitlines()
    tape = [ln for ln in err if "tape_000" in ln]
    assert len(tape) == 1 and "the observation matches none of the 2 tasks: p = " in tape[0]
    doc = json.loads((out / "summary.json").read_text())
    jsonschema.validate(doc, load_schema("plan_summary"))
    rows = {Path(r["recording"]).parent.name: r for r in doc["recordings"]}
    assert rows["tape"]["known"] is False and rows["tape"]["status"] == "failed"
    assert rows["tape"]["failures"][0] == "unknown_task" and rows["tape"]["novelty_p_value"] <= 0.05
    assert rows["rod"]["known"] is True and rows["rod"]["novelty_p_value"] > 0.05
    folder = Path(rows["tape"]["out_dir"])
    report = json.loads((folder / "report.json").read_text())
    jsonschema.validate(report, load_schema("report"))
    assert report["known"] is False and not report["passed"]
    assert not (folder / "trajectory.csv").exists() and not (folder / "trajectory.json").exists()
    header = (out / "summary.csv").read_text().splitlines()[0].split(",")
    assert "known" in header and "novelty_p_value" in header


def test_run_refuses_an_unknown_task_with_exit_3(tiny, other_tasks, tmp_path, capsys):
    out = tmp_path / "out"
    args = ["run", str(PIPELINE), "--model", str(tiny[1]), "--dataset", str(other_tasks), "--task", "tape"]
    assert main([*args, "--out", str(out), "--no-preview", "--no-rosbag"]) == 3
    err = [ln for ln in capsys.readouterr().err.splitlines() if "error:" in ln]  # (and a tasks warning)
    assert len(err) == 1 and "the observation matches none of the 2 tasks: p = " in err[0]
    report = json.loads((out / "report.json").read_text())
    assert report["known"] is False and report["unknown_reason"] in err[0]
    assert not (out / "trajectory.csv").exists()
    # marked as failing when asked for
    assert main([*args, "--out", str(out), "--no-preview", "--no-rosbag", "--allow-failing-checks"]) == 3
    assert (out / "trajectory.csv").exists()
