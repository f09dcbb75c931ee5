"""``train --add-task DIR --model M --out M2``: new tasks added to a trained model (issue 35, item 5)."""

from __future__ import annotations

import shutil

import pytest
from helpers_cli import one_error_line

from ipromp_pin.app import main
from ipromp_pin.promp import IProMP


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """A synthetic dataset of 3 tasks split into a training dataset (2 tasks) and a new-task folder,
    and a model trained on the first."""
    root = tmp_path_factory.mktemp("add")
    assert main(["synth", str(root / "all"), "--tasks", "3", "--demos", "4"]) == 0
    tasks = sorted(p.name for p in (root / "all").iterdir() if p.is_dir())
    for t in tasks[:2]:
        shutil.copytree(root / "all" / t, root / "train" / t)
    shutil.copytree(root / "all" / tasks[2], root / "new" / tasks[2])
    assert main(["train", str(root / "train"), "--out", str(root / "m.npz")]) == 0
    return root, tasks


def test_a_new_task_is_added_and_the_model_saved(folders, capsys):
    root, tasks = folders
    capsys.readouterr()
    out = root / "m2.npz"
    assert (
        main(["train", "--add-task", str(root / "new"), "--model", str(root / "m.npz"), "--out", str(out)])
        == 0
    )
    text = capsys.readouterr().out
    assert f"added task {tasks[2]} from 4 demos" in text
    model = IProMP.load(out)
    assert model.tasks_ == tasks and model.fitted_.added_tasks == (tasks[2],)
    before = IProMP.load(root / "m.npz")
    assert before.tasks_ == tasks[:2]  # the trained model itself is untouched


@pytest.mark.parametrize(
    ("extra", "field", "problem"),
    [
        (["--add-task", "NEW"], "add-task", "give both --add-task DIR and --model MODEL"),
        (["--add-task", "TRAIN", "--model", "M"], "task", "already has a task"),
        (["DATASET", "--add-task", "NEW", "--model", "M"], "dataset", "with --add-task"),
    ],
)
def test_bad_add_task_commands_are_refused_in_one_line(folders, capsys, tmp_path, extra, field, problem):
    root, _ = folders
    names = {"NEW": root / "new", "TRAIN": root / "train", "M": root / "m.npz", "DATASET": root / "train"}
    out = tmp_path / "m2.npz"
    out.write_bytes(b"earlier output")
    args = ["train", *[str(names.get(a, a)) for a in extra], "--out", str(out)]
    assert main(args) == 2
    line = one_error_line(capsys.readouterr().err)
    assert f"field '{field}'" in line and problem in line
    assert out.read_bytes() == b"earlier output"
