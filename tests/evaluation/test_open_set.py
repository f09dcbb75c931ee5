"""The open-set protocol: leave one task out, score known and left-out test demos, beside baselines."""

from __future__ import annotations

import functools
import json

import pytest

from ipromp_pin.app import main
from ipromp_pin.evaluation import open_set
from ipromp_pin.evaluation.config import EvaluationConfig
from ipromp_pin.evaluation.open_set import OPEN_SET_BASELINES, evaluate_open_set
from ipromp_pin.promp import IProMP
from ipromp_pin.readers.synthetic import make_synthetic_dataset

FAST = {"n_basis": 7, "noise": 10.0, "temperature": 1.0, "coupling": "all", "head": False}


@pytest.fixture(scope="module")
def synthetic():
    return make_synthetic_dataset(n_tasks=3, n_demos=9, seed=3)


def _config(baselines: bool) -> EvaluationConfig:
    return EvaluationConfig(
        protocol="open-set", observe=[["orientation", "emg"]], grid=[(6, 0.2)], n_test=3, n_splits=1,
        model_params=FAST, baselines=baselines,
    )  # fmt: skip


def test_open_set_cells_have_the_fields(synthetic):
    pytest.importorskip("sklearn")
    cells = evaluate_open_set(synthetic, _config(True), alpha=0.1, jobs=1)
    assert [c.unknown_task for c in cells] == synthetic.tasks
    for c in cells:
        assert c.alpha == 0.1 and c.n_known == 6 and c.n_unknown == 3 and c.n_splits == 1
        for value in (c.false_reject_rate, c.false_accept_rate, c.auroc, c.accepted_accuracy):
            assert 0.0 <= value <= 1.0
        assert set(c.baselines) == set(OPEN_SET_BASELINES)
        for b in c.baselines.values():
            assert set(b) == {"false_reject_rate", "false_accept_rate", "auroc"}
        # the rates are those of the trials: the left-out task's demos are the unknown ones
        known = [t for t in c.trials if not t["unknown"]]
        assert {t["task"] for t in c.trials if t["unknown"]} == {c.unknown_task}
        assert c.false_reject_rate == sum(not t["known"] for t in known) / len(known)
        assert all(t["known"] == (t["p_value"] > 0.1) for t in c.trials)


def test_open_set_gives_the_same_cells_with_jobs(synthetic):
    serial = evaluate_open_set(synthetic, _config(False), alpha=0.1, jobs=1)
    parallel = evaluate_open_set(synthetic, _config(False), alpha=0.1, jobs=2)
    assert [c.trials for c in parallel] == [c.trials for c in serial]


def test_open_set_needs_three_tasks():
    two = make_synthetic_dataset(n_tasks=2, n_demos=8, seed=1)
    cfg = EvaluationConfig(protocol="open-set", observe=[["orientation"]], grid=[(5, 0.2)], n_splits=1)
    with pytest.raises(Exception, match="3\\+ tasks"):
        evaluate_open_set(two, cfg)


def test_evaluate_command_writes_the_open_set_table(tmp_path, monkeypatch):
    monkeypatch.setattr(open_set, "IProMP", functools.partial(IProMP, **FAST))  # small fits (jobs=1)
    data = tmp_path / "synthetic"
    assert main(["synth", str(data), "--demos", "9", "--seed", "5"]) == 0
    out = tmp_path / "open.json"
    args = [
        "evaluate",
        str(data),
        "--protocol",
        "open-set",
        "--observe",
        "orientation,emg",
        "--json",
        str(out),
    ]
    args += ["--grid", "full", "--n-train", "6", "--ratios", "0.2", "--splits", "1", "--n-test", "2"]
    assert main([*args, "--alpha", "0.1"]) == 0
    doc = json.loads(out.read_text())
    assert len(doc["cells"]) == 3
    for cell in doc["cells"]:
        for key in (
            "alpha",
            "false_reject_rate",
            "false_accept_rate",
            "auroc",
            "accepted_accuracy",
            "baselines",
        ):
            assert key in cell
        assert cell["protocol"] == "open-set" and cell["alpha"] == 0.1
    assert out.with_suffix(".md").read_text().startswith("### Open-set recognition")
    with pytest.raises(SystemExit):
        main([*args, "--alpha", "0.9"])
