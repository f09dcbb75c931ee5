"""The evaluation's protocol runner: scorers and baselines plug in by one registration, workers get
their state from the pool initializer, and the evaluate command's typed request."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ipromp_pin.data import Dataset
from ipromp_pin.evaluation import jobs as jobs_module
from ipromp_pin.evaluation.cells import Cell
from ipromp_pin.evaluation.config import EvaluationConfig
from ipromp_pin.evaluation.protocol import run_protocol
from ipromp_pin.evaluation.scorers import Scorer, TrialResult
from ipromp_pin.evaluation.splits import iter_splits, split_paper, split_random
from ipromp_pin.exceptions import DataError
from ipromp_pin.readers.synthetic import make_synthetic_dataset


@pytest.fixture(scope="module")
def synthetic() -> Dataset:
    return make_synthetic_dataset(n_tasks=3, n_demos=8, seed=3)


class MajorityScorer(Scorer):
    """Always predicts the task with the most training demos (the first on ties)."""

    def fit(self, train, observe):
        names = [d.task for d in train]
        self.task_ = max(dict.fromkeys(names), key=names.count)
        return self

    def score(self, test, window, split=0):
        nan = float("nan")
        return [  # the observed fraction of each demo as its "hand-over error"
            TrialResult(
                d.task,
                d.name,
                self.task_,
                float(d.task == self.task_),
                *[nan] * 4,
                window.fraction(d),
                nan,
                0.0,
            )
            for d in test
        ]

    def fit_facts(self):
        return {"coupled": "majority"}


def test_a_new_scorer_plugs_into_the_one_runner(synthetic):
    cfg = EvaluationConfig(
        protocol="splits", observe=[["emg"]], grid=[(5, 0.2), (4, 0.5)], n_test=2, n_splits=3
    )
    cells = run_protocol(synthetic, cfg, MajorityScorer())
    assert len(cells) == 2 * 3 and all(isinstance(c, Cell) for c in cells)
    for c in cells:
        assert c.n_splits == 3 and c.n_test == 6 and c.coupled_groups == {"majority": 3}
        assert c.accuracy == (1.0 if c.task == synthetic.tasks[0] else 0.0)
        if c.accuracy:
            assert c.handover_error_cm == c.obs_ratio  # the median of what the scorer returned


def test_workers_get_their_state_from_the_pool_initializer(synthetic):
    cfg = EvaluationConfig(protocol="splits", observe=[["emg"]], grid=[(5, 0.2)], n_test=2, n_splits=4)
    serial = run_protocol(synthetic, cfg, MajorityScorer(), jobs=1)
    parallel = run_protocol(synthetic, cfg, MajorityScorer(), jobs=2)
    assert serial == parallel
    assert jobs_module.installed_worker() is None  # nothing set in the parent process

    class WhereScorer(MajorityScorer):
        def fit_facts(self):
            worker = jobs_module.installed_worker()
            return {"coupled": "initializer" if worker is not None and worker.scorer is self else "serial"}

    for jobs, where in ((1, "serial"), (2, "initializer")):
        [cell, *_] = run_protocol(synthetic, cfg, WhereScorer(), jobs=jobs)
        assert cell.coupled_groups == {where: 4}


def test_splitters_draw_the_random_splits_in_the_protocol_order(synthetic):
    cfg = EvaluationConfig(protocol="splits", grid=[(4, 0.2), (5, 0.2)], n_test=2, n_splits=2, seed=7)
    rng = np.random.default_rng(7)
    seen = []
    for rep, n_train, indices in iter_splits(synthetic, cfg):
        seen.append((rep, n_train))
        train, test = split_random(synthetic, n_train, 2, rng)  # the same draws, in the same order
        assert [d.name for d in train] == [
            synthetic.demos[t][i].name for t, (tr, _) in indices.items() for i in tr
        ]
        assert [d.name for d in test] == [
            synthetic.demos[t][i].name for t, (_, te) in indices.items() for i in te
        ]
    assert seen == [(0, 5), (0, 4), (1, 5), (1, 4)]
    paper = EvaluationConfig(protocol="paper", grid=[(5, 0.2)], n_test=2)
    [(_, _, indices)] = list(iter_splits(synthetic, paper))
    train, _ = split_paper(synthetic, 5, 2)
    assert len(train) == 15 and all(tr == [0, 1, 2, 3, 4] for tr, _ in indices.values())
    with pytest.raises(DataError, match="unknown protocol 'kfold'"):
        list(iter_splits(synthetic, EvaluationConfig(protocol="kfold")))


def test_a_new_baseline_plugs_in_by_one_registration(synthetic):
    pytest.importorskip("sklearn")
    from sklearn.dummy import DummyRegressor
    from sklearn.naive_bayes import GaussianNB

    from ipromp_pin.evaluation.baselines import CLASSIFIERS, REGRESSORS
    from ipromp_pin.evaluation.tables import to_markdown

    cfg = EvaluationConfig(protocol="paper", observe=[["orientation", "emg"]], grid=[(5, 0.2)], n_test=2)
    cfg.baselines = True
    CLASSIFIERS.register("naive_bayes", lambda y: GaussianNB())
    REGRESSORS.register("mean", lambda n: DummyRegressor())
    try:
        with pytest.raises(ValueError, match="already registered"):
            CLASSIFIERS.register("lda", lambda y: GaussianNB())
        from ipromp_pin.evaluation.evaluate import evaluate

        cells = evaluate(synthetic, cfg, robot="baxter_left")
        md = to_markdown(cells)
    finally:
        CLASSIFIERS.unregister("naive_bayes")
        REGRESSORS.unregister("mean")
    assert list(CLASSIFIERS) == ["logistic_regression", "lda"] and list(REGRESSORS) == ["ridge", "knn"]
    for c in cells:
        assert 0.0 <= c.baselines["naive_bayes"]["accuracy"] <= 1.0
        assert c.baselines["naive_bayes"]["log_loss"] is not None
        if c.accuracy > 0:
            assert c.baselines["mean"]["handover_error_cm"] >= 0.0
    assert "logistic_regression / lda / naive_bayes" in md and "ridge / knn / mean" in md


def _write_dataset(folder: Path) -> Path:
    from ipromp_pin.readers.native import write_demo

    ds = make_synthetic_dataset(n_tasks=2, n_demos=6, seed=5)
    for task, demos in ds.demos.items():
        for d in demos:
            write_demo(d, folder / task / f"{d.name}.npz")
    return folder


def test_the_evaluate_request_runs_the_closed_loop_with_the_baselines(tmp_path):
    pytest.importorskip("sklearn")
    from ipromp_pin.evaluation.run import EvaluateRequest, grid_from, run_evaluate

    data = _write_dataset(tmp_path / "data")
    out = tmp_path / "cl.json"
    lines: list[str] = []
    request = EvaluateRequest(
        dataset=data,
        observe=[["orientation", "emg"]],
        grid=grid_from("full", [4], [0.2]),
        protocols=["splits"],
        n_test=1,
        n_splits=1,
        baselines=True,
        closed_loop=True,
        json=out,
        command="ipromp-pin evaluate test",
        log=lines.append,
    )
    cells = run_evaluate(request)
    doc = json.loads(out.read_text())
    assert len(doc["cells"]) == len(cells) == 2
    for c in doc["cells"]:
        assert c["closed_loop_handover_error_cm"] is not None and len(c["closed_loop_trials"]) == 1
        assert {"logistic_regression", "lda"} <= set(c["baselines"])
    assert doc["meta"]["closed_loop"]["start_ratio"] == "obs_ratio of each ratio cell"
    assert any(line.startswith("### Closed loop, protocol `splits`") for line in lines)
    assert out.with_suffix(".md").read_text().startswith("### Closed loop")
    too_big = EvaluateRequest(dataset=data, grid=[(6, 0.2)], protocols=["splits"], log=lines.append)
    with pytest.raises(DataError, match="has 6 demos"):
        run_evaluate(too_big)


def test_the_evaluate_command_compiles_the_kernels_once_before_forking(monkeypatch):
    from ipromp_pin.evaluation.run import compile_kernels_once
    from ipromp_pin.promp import compiled, warmup
    from ipromp_pin.promp.compiled import use_kernels

    calls, messages = [], []
    monkeypatch.setattr(compiled, "compiled_kernels_cached", lambda *a: False)
    monkeypatch.setattr(compiled, "kernels_cached", lambda *a: False)
    monkeypatch.setattr(warmup, "compile_kernels", lambda: calls.append(1) or 1.0)
    monkeypatch.setitem(compiled._state, "modules", {})  # as in a new process
    monkeypatch.setitem(compiled._state, "announced", set())
    compiled.set_announcer(messages.append)
    try:
        with use_kernels("numba"):
            compile_kernels_once()
        with use_kernels("numpy"):  # nothing to compile
            compile_kernels_once()
    finally:
        compiled.set_announcer(None)
    assert calls == [1] and len(messages) == 1 and "compiling the inference kernels" in messages[0]
