"""Reference baselines of the evaluation (scikit-learn on window features) and `evaluate --baselines`."""

from __future__ import annotations

import builtins
import json

import numpy as np
import pytest
from helpers_model import random_dataset, split

from ipromp_pin.app import main
from ipromp_pin.evaluation.baselines import (
    CLASSIFIERS,
    REGRESSORS,
    MissingDependencyError,
    WindowBaselines,
    phase_trajectory,
    require_sklearn,
    window_features,
)
from ipromp_pin.evaluation.evaluate import EvaluationConfig, evaluate, to_json, to_markdown
from ipromp_pin.readers.synthetic import make_synthetic_dataset

pytest.importorskip("sklearn")


def test_window_features_skip_missing_samples():
    ds = random_dataset(3, missing_group="a")
    demo = next(d for d in ds.all_demos() if d.missing["a"][:20].any())
    window = demo.head(0.5, ["a", "b"])
    f = window_features(window, ["a", "b"])
    valid = ~window.missing["a"]
    assert f.shape == (10,)
    assert np.allclose(f[:2], window.groups["a"][valid].mean(axis=0))
    assert np.allclose(f[5:7], window.groups["a"][valid][-1])
    assert np.allclose(f[7:], window.groups["b"][-1])


def test_phase_trajectory_spans_the_unobserved_part():
    demo = random_dataset(4).all_demos()[0]
    q = phase_trajectory(demo, 0.3)
    assert q.shape == (50, 3)
    assert np.allclose(q[-1], demo.groups["robot"][-1]) and not np.allclose(q[0], demo.groups["robot"][0])


def test_baselines_recognise_separable_tasks_and_predict_the_robot():
    train, test = split(random_dataset(5, n_demos=16), 12)
    fk = lambda q: np.asarray(q)[:, :3] * 0.1  # noqa: E731 (a linear stand-in for the kinematics)
    base = WindowBaselines(["a", "b"], 0.3, fk).fit(train.all_demos())
    demos = [d for ds in test.values() for d in ds]
    scored = base.score(demos)
    assert set(scored[0]) == set(CLASSIFIERS) | set(REGRESSORS)
    for name in CLASSIFIERS:
        acc = np.mean([s[name].predicted == d.task for s, d in zip(scored, demos, strict=True)])
        assert acc >= 0.75, name  # the tasks' mean curves differ: far above chance (1/3)
        assert all(0.0 <= s[name].posterior <= 1.0 and 0.0 <= s[name].brier <= 2.0 for s in scored)
    for name in REGRESSORS:
        errs = [s[name].handover_error_cm for s in scored]
        assert all(np.isfinite(e) and e >= 0.0 for e in errs)
        assert all(s[name].predicted == d.task for s, d in zip(scored, demos, strict=True))
    assert base.classifiers_["logistic_regression"].C_ is not None  # chosen by its own CV


def test_evaluate_with_baselines_reports_them_beside_the_model():
    ds = make_synthetic_dataset(n_tasks=3, n_demos=13, seed=3)
    cfg = EvaluationConfig(
        protocol="splits", observe=[["orientation", "emg"]], grid=[(10, 0.2)], n_test=3, n_splits=2
    )
    cfg.baselines = True
    cells = evaluate(ds, cfg, robot="baxter_left")
    for c in cells:
        assert set(c.baselines) == set(CLASSIFIERS) | set(REGRESSORS)
        for name in CLASSIFIERS:
            assert 0.0 <= c.baselines[name]["accuracy"] <= 1.0 and c.baselines[name]["accuracy_std"] >= 0.0
        for name in REGRESSORS:
            assert c.baselines[name]["handover_error_cm"] >= 0.0
        assert c.log_loss is not None and c.log_loss >= 0.0 and 0.0 <= c.brier <= 2.0
        # the expected calibration error beside them, for us and every classifier
        assert c.ece is not None and 0.0 <= c.ece <= 1.0
        assert all(0.0 <= c.baselines[name]["ece"] <= 1.0 for name in CLASSIFIERS)
    doc = json.loads(json.dumps(to_json(cells)))
    assert "logistic_regression" in doc["cells"][0]["baselines"]
    md = to_markdown(cells)
    assert "| ECE: ipromp_pin / logistic_regression" in md
    assert "ipromp_pin and the baselines" in md and "| 10 | 0.2 | orientation+emg |" in md


def test_baselines_without_scikit_learn_is_a_one_line_error(tmp_path, capsys, monkeypatch):
    real_import = builtins.__import__

    def no_sklearn(name, *args, **kwargs):
        if name == "sklearn" or name.startswith("sklearn."):
            raise ImportError("No module named 'sklearn'")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_sklearn)
    with pytest.raises(MissingDependencyError, match="scikit-learn"):
        require_sklearn()
    code = main(["evaluate", str(tmp_path), "--baselines"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "scikit-learn" in err[0]
