"""Evaluation protocols: splits, scoring, table outputs and the command line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ipromp_pin.app import main
from ipromp_pin.evaluation.evaluate import (
    EvaluationConfig,
    check_dataset_size,
    evaluate,
    split_paper,
    split_random,
    to_markdown,
)
from ipromp_pin.exceptions import DataError
from ipromp_pin.readers.synthetic import make_synthetic_dataset


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


def test_evaluate_command_writes_json_and_markdown(tmp_path, capsys, monkeypatch):
    from ipromp_pin.outputs import plots

    drawn = []
    original = plots.accuracy_bars
    monkeypatch.setattr(plots, "accuracy_bars", lambda records: drawn.append(original(records)) or drawn[-1])
    data = tmp_path / "synthetic"
    assert main(["synth", str(data), "--demos", "13", "--seed", "5"]) == 0
    out = tmp_path / "eval.json"
    code = main(
        ["evaluate", str(data), "--protocol", "splits", "--observe", "orientation,emg", "--json", str(out)]
        + ["--grid", "full", "--n-train", "10", "--ratios", "0.2", "--splits", "2", "--n-test", "3"]
        + ["--plots", str(tmp_path / "figures")]
    )
    assert code == 0
    doc = json.loads(out.read_text())
    # the accuracy figure's error bars: the mean over the tasks of each cell's std over the 2 splits
    assert (tmp_path / "figures" / "accuracy.png").stat().st_size > 5000
    (bars,) = drawn
    assert bars.n_splits == 2
    ratio_cells = [c for c in doc["cells"] if c["window"]["kind"] == "ratio"]
    assert bars.spread[0, 0] == pytest.approx(np.mean([c["accuracy_std"] for c in ratio_cells]))
    # by default each cell of the grid and its counterpart in seconds: the same fraction of the
    # training demos' mean length
    assert len(doc["cells"]) == 6
    assert [c["window"]["kind"] for c in doc["cells"]] == ["ratio"] * 3 + ["train_fraction"] * 3
    for cell in doc["cells"]:
        for key in ("protocol", "n_train", "obs_ratio", "observe", "task", "accuracy", "accuracy_std"):
            assert key in cell
        assert cell["protocol"] == "splits" and cell["observe"] == ["orientation", "emg"]
        assert cell["window"]["value"] == 0.2
        assert 0.0 <= cell["accuracy"] <= 1.0
        assert "handover_error_cm" in cell and "handover_error_prior_cm" in cell
        # the one-shot plans' peak joint torque with the true task's (shipped) object
        assert 0.05 < cell["peak_torque_ratio"] < 2.0
    md = out.with_suffix(".md").read_text()
    assert md.startswith("### Recognition accuracy")
    peak = max(cell["peak_torque_ratio"] for cell in doc["cells"])
    assert f"- peak joint torque ratio at most {peak:.3f}" in md
    err = capsys.readouterr().err  # without a terminal, progress as plain lines (logs), no \r
    assert "[2/2]" in err and "\r" not in err


def test_evaluate_command_rejects_unknown_groups(tmp_path, capsys):
    data = tmp_path / "synthetic"
    main(["synth", str(data), "--demos", "12"])
    small = ["--protocol", "splits", "--grid", "full", "--n-train", "5", "--n-test", "2"]
    assert main(["evaluate", str(data), "--observe", "orientation,gaze", *small]) == 2
    assert "gaze" in capsys.readouterr().err


def test_evaluate_command_says_up_front_when_the_dataset_is_too_small(tmp_path, capsys, monkeypatch):
    import ipromp_pin.readers as readers

    data = tmp_path / "synthetic"
    main(["synth", str(data), "--demos", "12"])
    capsys.readouterr()

    def no_reading(*args, **kwargs):
        raise AssertionError("the dataset was read before its size was checked")

    monkeypatch.setattr(readers, "load_dataset", no_reading)
    assert main(["evaluate", str(data)]) == 2  # paper protocol: cells train on up to 20 demos per task
    out = capsys.readouterr()
    lines = out.err.strip().splitlines()
    assert len(lines) == 1 and not out.out
    assert "has 12 demos" in lines[0] and "need 21 per task" in lines[0]
    assert "--protocol splits" in lines[0] and "--n-train 5 10" in lines[0]
    # the splits protocol is held to the same need; the suggested cells pass the check
    assert main(["evaluate", str(data), "--protocol", "splits", "--grid", "full", "--n-train", "20"]) == 2
    assert "need 21 per task" in capsys.readouterr().err
    counts = {"rod": 12, "wrench": 12, "tape": 12}
    check_dataset_size(counts, EvaluationConfig(protocol="splits", grid=[(5, 0.2), (10, 0.2)]))
    with pytest.raises(DataError, match="task 'tape' has 11 demos"):
        check_dataset_size({**counts, "tape": 11}, EvaluationConfig(grid=[(11, 0.2)]))


def test_evaluate_help_documents_the_protocols_and_spares_a_core(capsys, monkeypatch):
    from ipromp_pin.app import evaluate as cli_evaluate

    monkeypatch.setattr(cli_evaluate.os, "sched_getaffinity", lambda pid: set(range(4)), raising=False)
    assert cli_evaluate.default_jobs() == 3
    monkeypatch.setattr(cli_evaluate.os, "sched_getaffinity", lambda pid: {0}, raising=False)
    assert cli_evaluate.default_jobs() == 1
    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "paper: the paper's experiment" in text and "splits: every cell over --splits random" in text
    assert "every core but one" in text


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
