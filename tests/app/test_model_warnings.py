"""Warnings where a user is likely to be fooled: mismatched model, demo seen in training, single task."""

from __future__ import annotations

import copy
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from helpers_model import random_dataset, split

from ipromp_pin.app import main
from ipromp_pin.data import Dataset
from ipromp_pin.plans.warnings import (
    dataset_mismatch_warnings,
    held_out_warning,
    loaded_model_warnings,
    single_task_warning,
)
from ipromp_pin.promp import IProMP

PIPELINE = Path(__file__).resolve().parents[2] / "pipelines" / "baxter_handover.toml"


@pytest.fixture(scope="module")
def fitted():
    train, test = split(random_dataset(5), 6)
    return IProMP(["a", "b"], n_basis=7, noise=30.0, coupling="all").fit(train), train, test


def test_a_matching_model_and_a_held_out_demo_raise_no_warning(fitted):
    model, train, test = fitted
    full = Dataset(train.root, {t: train.demos[t] + test[t] for t in train.tasks})
    assert loaded_model_warnings(model, full, test["task1"][0], "m.npz") == []


def test_demo_in_the_training_set_is_found_by_content(fitted):
    model, train, _ = fitted
    demo = train.demos["task2"][3]
    w = held_out_warning(model, demo, "m.npz")
    assert w is not None and "task2/task2_3 was in m.npz's training set" in w
    # same content under another name and source (a moved or renamed file): still found
    moved = type(demo)(**{**demo.__dict__, "name": "renamed", "source": "/elsewhere/renamed.npz"})
    assert held_out_warning(model, moved, "m.npz") is not None
    # same name and task, different content (another seed): not the training demo
    other = random_dataset(6).demos["task2"][3]
    assert (other.task, other.name) == (demo.task, demo.name)
    assert held_out_warning(model, other, "m.npz") is None
    # a model file of format version 1 does not know its training demos: say so
    old = copy.copy(model)._set_fitted(dataclasses.replace(model.fitted_, trained_on=None))
    assert "does not record its training demos" in held_out_warning(old, other, "old.npz")


def test_model_of_other_tasks_or_channels_is_flagged(fitted):
    model, _, _ = fitted
    other = random_dataset(5, n_tasks=2, dims={"a": 2, "b": 4})  # task2 missing, group b has 4 channels
    warnings = dataset_mismatch_warnings(model, other, "m.npz")
    assert len(warnings) == 2
    assert "trained on tasks task0, task1, task2, the dataset has task0, task1" in warnings[0]
    assert "channels of group 'b' (b0, b1, b2) differ from the dataset's (b0, b1, b2, b3)" in warnings[1]
    renamed = Dataset("x", {"hold": other.demos["task0"], "give": other.demos["task1"]})
    assert "(hold, give cannot be recognised)" in dataset_mismatch_warnings(model, renamed)[0]


def test_single_task_model_is_flagged():
    ds = random_dataset(7, n_tasks=1)
    model = IProMP(["a"], n_basis=7, noise=30.0, coupling="all").fit(ds)
    assert "single task ('task0')" in single_task_warning(model)
    assert model.predict(ds.demos["task0"][0].head(0.3, ["a"])).posterior.tolist() == [1.0]


def test_cli_warns_on_stderr_in_one_line_when_the_demo_was_trained_on(tmp_path, capsys):
    model = tmp_path / "model.npz"
    common = ["run", str(PIPELINE), "--no-preview", "--no-rosbag"]
    assert main([*common, "--out", str(tmp_path / "a"), "--save-model", str(model)]) == 0
    assert "warning" not in capsys.readouterr().err
    # demo 3 of the pipeline's task was in the saved model's training set (demo -1 was held out)
    assert main([*common, "--out", str(tmp_path / "b"), "--model", str(model), "--demo", "3"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert (
        len(err) == 1
        and err[0].startswith("warning: wrench/wrench_003 was in ")
        and "Traceback" not in err[0]
    )
    report = json.loads((tmp_path / "b" / "report.json").read_text())
    assert report["warnings"] == [err[0].removeprefix("warning: ")]
    assert (tmp_path / "b" / "report.txt").read_text().startswith("Warning: wrench/wrench_003 was in")
    # the held-out demo raises no warning
    assert main([*common, "--out", str(tmp_path / "c"), "--model", str(model)]) == 0
    assert capsys.readouterr().err == ""
    assert json.loads((tmp_path / "c" / "report.json").read_text())["warnings"] == []
    np.testing.assert_equal(report["observation"]["demo"], "wrench_003")
