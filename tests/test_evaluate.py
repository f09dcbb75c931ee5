"""Evaluation protocols: splits, scoring, table outputs and the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ipromp_pin.cli import main
from ipromp_pin.evaluate import EvaluationConfig, evaluate, split_paper, split_random, to_markdown
from ipromp_pin.exceptions import DataError
from ipromp_pin.synthetic import make_synthetic_dataset


@pytest.fixture(scope="module")
def synthetic():
    return make_synthetic_dataset(n_tasks=3, n_demos=16, seed=3)


def test_paper_split_takes_first_demos_in_order(synthetic):
    train, test = split_paper(synthetic, n_train=10, n_test=4)
    for task, demos in synthetic.demos.items():
        assert [d.name for d in train if d.task == task] == [d.name for d in demos[:10]]
        assert [d.name for d in test if d.task == task] == [d.name for d in demos[10:14]]
    with pytest.raises(DataError, match="needs 16 to train"):
        split_paper(synthetic, n_train=16, n_test=4)


def test_random_splits_are_disjoint_and_vary(synthetic):
    rng = np.random.default_rng(0)
    a_train, a_test = split_random(synthetic, 10, 5, rng)
    b_train, _ = split_random(synthetic, 10, 5, rng)
    assert not {id(d) for d in a_train} & {id(d) for d in a_test}
    assert len(a_train) == 30 and len(a_test) == 15
    assert [d.name for d in a_train] != [d.name for d in b_train]


def test_evaluation_recognises_synthetic_tasks_and_conditioning_helps(synthetic):
    cfg = EvaluationConfig(protocol="paper", observe=[["orientation", "emg"]], grid=[(10, 0.2)], n_test=6)
    cells = evaluate(synthetic, cfg, robot="baxter_left")
    assert len(cells) == 3
    assert all(c.n_test == 6 for c in cells)
    # EMG separates the synthetic tasks by construction
    assert np.mean([c.accuracy for c in cells]) >= 0.9
    for c in cells:
        assert 0.0 <= c.handover_error_cm < 50.0
        assert c.joint_rmse_rad is not None and c.joint_rmse_prior_rad is not None
    md = to_markdown(cells)
    assert "| 10 | 0.2 | orientation+emg |" in md


def test_evaluate_command_writes_json_and_markdown(tmp_path, capsys):
    data = tmp_path / "synthetic"
    assert main(["synth", str(data), "--demos", "13", "--seed", "5"]) == 0
    out = tmp_path / "eval.json"
    code = main(
        ["evaluate", str(data), "--protocol", "splits", "--observe", "orientation,emg", "--json", str(out)]
        + ["--grid", "full", "--n-train", "10", "--ratios", "0.2", "--splits", "2", "--n-test", "3"]
    )
    assert code == 0
    doc = json.loads(out.read_text())
    assert len(doc["cells"]) == 3
    for cell in doc["cells"]:
        for key in ("protocol", "n_train", "obs_ratio", "observe", "task", "accuracy", "accuracy_std"):
            assert key in cell
        assert cell["protocol"] == "splits" and cell["observe"] == ["orientation", "emg"]
        assert 0.0 <= cell["accuracy"] <= 1.0
        assert "handover_error_cm" in cell and "handover_error_prior_cm" in cell
    assert out.with_suffix(".md").read_text().startswith("### Recognition accuracy")
    assert "[2/2]" not in capsys.readouterr().err  # progress lines only on a terminal


def test_evaluate_command_rejects_unknown_groups(tmp_path, capsys):
    data = tmp_path / "synthetic"
    main(["synth", str(data), "--demos", "12"])
    assert main(["evaluate", str(data), "--observe", "orientation,gaze", "--n-test", "2"]) == 2
    assert "gaze" in capsys.readouterr().err


def test_train_command_sets_the_coupled_groups(tmp_path, capsys):
    from ipromp_pin.promp import IProMP

    data = tmp_path / "synth"
    main(["synth", str(data), "--tasks", "2", "--demos", "6"])
    out = tmp_path / "model.npz"
    assert main(["train", str(data), "--out", str(out), "--coupling", "emg"]) == 0
    assert "coupled to the robot: emg" in capsys.readouterr().out
    assert IProMP.load(out).coupled_groups_ == ["emg"]
    # a group that is not observed is a clear error, not a silent choice
    assert main(["train", str(data), "--out", str(out), "--coupling", "gaze"]) == 2
    assert "gaze" in capsys.readouterr().err
