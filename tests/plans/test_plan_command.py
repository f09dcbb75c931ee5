"""``ipromp-pin plan MODEL RECORDING... --out DIR``: recordings without a task label, one or many,
planned with a trained model (ipromp_pin.plans.batch): one sub-folder each and a summary, a
recording that cannot be read reported without stopping the batch, the exit status saying what
happened, the same outputs whatever the number of worker processes, and nothing of a recording
after its observed window reaching the plan."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from ipromp_pin.app import main
from ipromp_pin.data import Demo
from ipromp_pin.outputs.trajectory_files import read_trajectory_csv
from ipromp_pin.readers import native
from ipromp_pin.schemas import load_schema

HEAVY = """
[{task}]
mass_kg = 1.7
com_m = [0.9, 0.0, 0.0]
holder = "robot_receives"
retreat = {{ joints_rad = [-1.25, 0.65, 1.72, 1.51, 1.57, 1.42, 1.49], dwell_s = 0.2 }}
"""
"""A held object too heavy for the arm's retreat (1.7 kg, 0.9 m out)."""


@pytest.fixture(scope="module")
def recordings(tmp_path_factory) -> list[Path]:
    """Four synthetic recordings the tiny model was not trained on (other seed), in a folder each."""
    root = tmp_path_factory.mktemp("recordings")
    assert main(["synth", str(root), "--tasks", "2", "--demos", "2", "--seed", "11"]) == 0
    return sorted(root.glob("*/*.npz"))


def _plan(tiny, out: Path, *paths: object, extra: tuple[str, ...] = ()) -> int:
    return main(["plan", str(tiny[1]), *map(str, paths), "--out", str(out), "--no-rosbag", *extra])


def _timeless(doc: object) -> object:
    """``doc`` without its wall-clock timings (``stage_ms``, ``timings_ms``, ``*_ms``)."""
    if isinstance(doc, dict):
        return {k: _timeless(v) for k, v in doc.items() if not k.endswith("_ms") and k != "cycle_ms"}
    if isinstance(doc, list):
        return [_timeless(v) for v in doc]
    return doc


def test_a_batch_plans_each_recording_into_its_folder_and_lists_them(tiny, recordings, tmp_path, capsys):
    out = tmp_path / "out"
    assert _plan(tiny, out, *recordings) == 0
    lines = capsys.readouterr().out.splitlines()
    progress = [ln for ln in lines if re.match(r"\[\d+/4\] ", ln)]  # one line per recording, also in logs
    assert [ln.split("]")[0] for ln in progress] == ["[1/4", "[2/4", "[3/4", "[4/4"]
    summary = json.loads((out / "summary.json").read_text())
    jsonschema.Draft202012Validator(load_schema("plan_summary")).validate(summary)
    assert summary["counts"] == {"passed": 4, "failed": 0, "unreadable": 0}
    rows = summary["recordings"]
    assert [r["recording"] for r in rows] == [str(p) for p in recordings]
    for r, path in zip(rows, recordings, strict=True):
        folder = Path(r["out_dir"])
        assert folder.parent == out and folder.name == path.stem
        report = json.loads((folder / "report.json").read_text())
        jsonschema.Draft202012Validator(load_schema("report")).validate(report)
        assert report["observation"]["task"] == ""  # no label read: the task is recognised
        assert r["task"] == report["recognised_task"] == path.parent.name  # synthetic: easy
        assert r["posterior"] == report["posterior"][r["task"]]
        assert r["arrival"] == report["arrival"] and report["passed"]
        assert report["scores"] is not None  # a whole recording: scored against its end
        assert r["handover_error_cm"] == report["scores"]["handover_error_cm"]
        t_s = read_trajectory_csv(folder / "trajectory.csv").t_s
        assert (
            t_s[0]
            == pytest.approx(r["observed_until_s"])
            == pytest.approx(report["arrival"]["robot_start_s"])
        )
    with (out / "summary.csv").open() as fh:
        table = list(csv.DictReader(fh))
    assert [row["recording"] for row in table] == [str(p) for p in recordings]
    assert all(row["status"] == "passed" and row["error"] == "" for row in table)
    assert float(table[0]["delay_s"]) == pytest.approx(rows[0]["arrival"]["delay_s"])


def test_unreadable_recordings_are_listed_and_the_rest_planned(tiny, recordings, tmp_path, capsys):
    out = tmp_path / "out"
    no_emg = tmp_path / "no_emg.npz"
    demo = native.read_demo(recordings[0], "")
    native.write_demo(_without(demo, "emg"), no_emg)
    garbage = tmp_path / "garbage.bag"
    garbage.write_bytes(b"not a bag")
    code = _plan(tiny, out, recordings[0], tmp_path / "missing.npz", no_emg, garbage)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 3 and all(ln.startswith("ipromp-pin plan: error: ") for ln in err)
    assert "missing.npz" in err[0] and "lacks emg" in err[1] and "garbage.bag" in err[2]
    summary = json.loads((out / "summary.json").read_text())
    assert [r["status"] for r in summary["recordings"]] == [
        "passed",
        "unreadable",
        "unreadable",
        "unreadable",
    ]
    assert summary["recordings"][1]["out_dir"] is None and summary["recordings"][1]["files"] == {}
    assert sorted(p.name for p in out.iterdir()) == [recordings[0].stem, "summary.csv", "summary.json"]


def _without(demo: Demo, group: str) -> Demo:
    return Demo(
        demo.task,
        demo.name,
        demo.source,
        demo.t,
        {g: v for g, v in demo.groups.items() if g != group},
        {g: v for g, v in demo.channel_names.items() if g != group},
        {g: v for g, v in demo.missing.items() if g != group},
        demo.extras,
    )


def test_failing_checks_exit_3_and_write_no_trajectory(tiny, recordings, tmp_path, capsys):
    objects = tmp_path / "objects.toml"
    objects.write_text(HEAVY.format(task="rod") + HEAVY.format(task="wrench"))
    out = tmp_path / "out"
    assert _plan(tiny, out, *recordings[:2], extra=("--objects", str(objects))) == 3
    assert "2 of 2 recordings failed their checks" in capsys.readouterr().err
    rows = json.loads((out / "summary.json").read_text())["recordings"]
    assert all(r["status"] == "failed" and "retreat.joint_torques" in r["failures"] for r in rows)
    folder = Path(rows[0]["out_dir"])
    assert (folder / "report.json").exists() and not (folder / "trajectory.csv").exists()


def test_the_window_in_seconds_and_a_recording_shorter_than_it(tiny, recordings, tmp_path):
    out = tmp_path / "out"
    assert _plan(tiny, out, recordings[0], extra=("--until-s", "0.5")) == 0
    [row] = json.loads((out / "summary.json").read_text())["recordings"]
    assert row["observed_until_s"] == pytest.approx(0.5, abs=0.02)
    assert _plan(tiny, out, recordings[0], extra=("--until-s", "60")) == 0
    [row] = json.loads((out / "summary.json").read_text())["recordings"]
    assert any(
        "before the observed window's end (60.00 s): planned from all of it" in w for w in row["warnings"]
    )
    assert row["handover_error_cm"] is None  # nothing left to score against


def test_the_outputs_do_not_depend_on_the_worker_processes(tiny, recordings, tmp_path):
    one, two = tmp_path / "one", tmp_path / "two"
    assert _plan(tiny, one, *recordings) == 0
    assert _plan(tiny, two, *recordings, extra=("--jobs", "2")) == 0
    a = json.loads((one / "summary.json").read_text())
    b = json.loads((two / "summary.json").read_text())
    assert _timeless(a) == _timeless(_renamed(b, two, one))
    for path in recordings:
        ra = json.loads((one / path.stem / "report.json").read_text())
        rb = json.loads((two / path.stem / "report.json").read_text())
        assert _timeless(ra) == _timeless(_renamed(rb, two, one))
        assert (one / path.stem / "trajectory.csv").read_bytes() == (
            two / path.stem / "trajectory.csv"
        ).read_bytes()


def _renamed(doc: object, old: Path, new: Path) -> object:
    return json.loads(json.dumps(doc).replace(str(old), str(new)))


def test_nothing_after_the_window_reaches_the_plan(tiny, recordings, tmp_path):
    """The same first 0.6 s followed by another recording's motion, or by nothing: every check's
    verdict, the trajectory and the recognition are the same."""
    a = native.read_demo(recordings[0], "")
    b = native.read_demo(recordings[3], "")
    n = int(np.searchsorted(a.t, 0.6 + 1e-9, side="right"))
    files = {
        "original": recordings[0],
        "spliced": native.write_demo(_spliced(a, n, b), tmp_path / "spliced.npz"),
        "cut": native.write_demo(a.slice(n + 1), tmp_path / "cut.npz"),
    }
    reports, trajectories = {}, {}
    for name, path in files.items():
        out = tmp_path / name
        assert _plan(tiny, out, path, extra=("--until-s", "0.6", "--no-score", "--no-retreat")) == 0
        folder = next(p for p in out.iterdir() if p.is_dir())
        report = _timeless(json.loads((folder / "report.json").read_text()))
        del report["observation"], report["files"]
        reports[name] = report
        trajectories[name] = (folder / "trajectory.csv").read_bytes()
    assert reports["spliced"] == reports["original"] == reports["cut"]
    assert trajectories["spliced"] == trajectories["original"] == trajectories["cut"]


def _spliced(a: Demo, n: int, b: Demo) -> Demo:
    """``a``'s first ``n`` samples, then ``b``'s samples after its own first ``n`` (on ``a``'s grid)."""
    m = n + b.n_samples - n
    dt = a.t[1] - a.t[0]

    def join(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.concatenate([x[:n], y[n:]])

    return Demo(
        "",
        "spliced",
        "spliced",
        a.t[0] + dt * np.arange(m),
        {g: join(a.groups[g], b.groups[g]) for g in a.groups},
        a.channel_names,
        {g: join(a.missing[g], b.missing[g]) for g in a.missing if g in b.missing},
        {k: join(a.extras[k], b.extras[k]) for k in a.extras if k in b.extras},
    )
