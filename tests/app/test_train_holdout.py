"""``train --holdout``: demos left out of training, so that ``run --model`` on them is a test
(issue 24, item 15)."""

from __future__ import annotations

import pytest
from helpers_cli import PIPELINE, one_error_line

from ipromp_pin.app import main
from ipromp_pin.promp import IProMP
from ipromp_pin.readers import load_dataset


@pytest.mark.parametrize("spec", ["by index", "by name", "negative index", "two demos"])
def test_held_out_demos_are_not_trained_on_and_run_does_not_warn(tiny, tmp_path, capsys, spec):
    ds_dir, _ = tiny
    ds = load_dataset(ds_dir)
    task, other = ds.tasks
    demo = ds.demos[task][1]
    holdout = {
        "by index": [f"{task}/1"],
        "by name": [f"{task}/{demo.name}"],
        "negative index": [f"{task}/{-len(ds.demos[task]) + 1}"],
        "two demos": [f"{task}/1", f"{other}/0"],
    }[spec]
    model_path = tmp_path / "m.npz"
    args = ["train", str(ds_dir), "--out", str(model_path)]
    for h in holdout:
        args += ["--holdout", h]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert f"held out {task}/{demo.name}" in out
    model = IProMP.load(model_path)
    names = {(r.task, r.name) for r in model.trained_on_}
    assert (task, demo.name) not in names
    assert len(names) == len(ds.all_demos()) - len(holdout)
    run = ["run", str(PIPELINE), "--dataset", str(ds_dir), "--model", str(model_path), "--task", task,
           "--demo", "1", "--out", str(tmp_path / "out"), "--no-preview", "--no-rosbag"]  # fmt: skip
    assert main(run) == 0
    assert "training set" not in capsys.readouterr().err


@pytest.mark.parametrize(
    ("holdout", "problem"),
    [("nope/0", "is not TASK/DEMO of a task"), ("rod", "is not TASK/DEMO"), ("rod/99", "has no demo '99'"),
     ("rod/x", "has no demo 'x'")],
)  # fmt: skip
def test_a_bad_holdout_is_refused_before_training(tiny, tmp_path, capsys, holdout, problem):
    assert main(["train", str(tiny[0]), "--out", str(tmp_path / "m.npz"), "--holdout", holdout]) == 2
    line = one_error_line(capsys.readouterr().err)
    assert "field 'holdout'" in line and problem in line
    assert not (tmp_path / "m.npz").exists()
