"""Open-set recognition: the novelty score, its conformal calibration, unknown tasks and observations
no task explains."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest
from helpers_model import random_dataset

from ipromp_pin.promp import IProMP
from ipromp_pin.promp.novelty import auroc, conformal_p_values

OBSERVE = ["a", "b"]


@pytest.fixture(scope="module")
def open_set():
    """A model of three synthetic tasks and held-out demos of them and of a fourth, unseen task."""
    ds = random_dataset(3, n_tasks=4, n_demos=14)
    train = [d for t in ("task0", "task1", "task2") for d in ds.demos[t][:10]]
    model = IProMP(OBSERVE, n_basis=9, noise=10.0, temperature=1.0, coupling="all", handover=False).fit(train)
    known = [d for t in ("task0", "task1", "task2") for d in ds.demos[t][10:]]
    return model, known, ds.demos["task3"]


@pytest.mark.parametrize("alpha", [0.05, 0.1, 0.2])
def test_conformal_p_values_refuse_at_most_alpha_of_exchangeable_scores(alpha):
    # split-conformal guarantee: a score exchangeable with the calibration scores gets p <= alpha
    # with probability at most alpha (here: 400 calibration sets, one test score each)
    rng = np.random.default_rng(0)
    rejected = 0
    n_trials = 400
    for _ in range(n_trials):
        scores = rng.standard_t(3, size=60)
        rejected += int(conformal_p_values(scores[:59], scores[59:])[0] <= alpha)
    assert rejected / n_trials <= alpha + 0.03
    # and it is not vacuous: scores far above every calibration score are refused
    assert np.all(conformal_p_values(np.arange(59.0), np.array([100.0, 1e9])) <= 1 / 60)


def test_auroc_counts_ties_as_half():
    assert auroc(np.array([0.0, 1.0]), np.array([2.0, 3.0])) == 1.0
    assert auroc(np.array([2.0, 3.0]), np.array([0.0, 1.0])) == 0.0
    assert auroc(np.array([1.0]), np.array([1.0])) == 0.5


def test_known_tasks_are_known_and_an_unseen_task_is_not(open_set):
    model, known, unseen = open_set
    det = model.fitted_.novelty
    assert det is not None and det.alpha == 0.05
    # the detector's calibration rows are the held-out training rows (at every head fraction)
    assert det.calibration.size == 30 * det.ratios.size
    k = [model.predict(d.head(0.2, OBSERVE)) for d in known]
    u = [model.predict(d.head(0.2, OBSERVE)) for d in unseen]
    assert all(0.0 < p.novelty_p_value <= 1.0 for p in k + u)
    assert all(p.known == (p.novelty_p_value > 0.05) for p in k + u)
    assert all(p.task in model.tasks_ for p in u)  # the best learned task, flagged unknown
    refused = np.mean([not p.known for p in k])
    assert refused <= 0.05 + 0.15  # 12 known observations: the guarantee with sampling slack
    assert np.mean([not p.known for p in u]) >= 0.75
    assert all(
        p.unknown_reason is not None and "matches none of the 3 tasks" in p.unknown_reason
        for p in u
        if not p.known
    )
    assert auroc(np.array([p.novelty_score for p in k]), np.array([p.novelty_score for p in u])) >= 0.9


def test_impossibly_long_stream_is_unknown_not_an_error(open_set):
    # a slow human: the stream goes on past the longest motion any task allows
    model, known, _ = open_set
    demo = known[0]
    stream = model.stream()
    longest = model.fitted_.longest_s
    i, t, rec = 0, 0.0, None
    while t <= longest + 0.5:
        j = min(i, demo.t.size - 1)
        rec = stream.update(t, {g: demo.groups[g][j] for g in OBSERVE})
        if i == 5:
            assert rec is not None and rec.known
        i, t = i + 1, t + 0.1
    assert rec is not None and not rec.known and rec.observed_until_s > longest
    assert rec.unknown_reason is not None and "impossible under every task" in rec.unknown_reason
    assert np.all(np.isfinite(stream.predict().q_mean))


def test_novelty_detector_round_trips_and_older_files_load_without_one(open_set, tmp_path):
    model, known, unseen = open_set
    path = tmp_path / "m.npz"
    model.save(path)
    again = IProMP.load(path)
    obs = unseen[0].head(0.2, OBSERVE)
    a, b = model.predict(obs), again.predict(obs)
    assert again.novelty_alpha == 0.05
    assert a.novelty_score == b.novelty_score and a.novelty_p_value == b.novelty_p_value
    # a format-5 file (before the detector): loads, every observation some task explains is known
    old = tmp_path / "old.npz"
    with zipfile.ZipFile(path) as zin, zipfile.ZipFile(old, "w") as zout:
        for item in zin.infolist():
            if item.filename.startswith("novelty_"):
                continue
            data = zin.read(item.filename)
            if item.filename == "header.npy":
                header = json.loads(str(np.load(zin.open("header.npy"))[()]))
                header["format_version"] = 5
                header.pop("novelty")
                header["params"].pop("novelty_alpha")
                with zout.open("header.npy", "w") as fh:
                    np.save(fh, np.array(json.dumps(header)))
                continue
            zout.writestr(item, data)
    older = IProMP.load(old)
    assert older.fitted_.novelty is None and older.novelty_alpha is None
    p = older.predict(obs)
    assert p.known and np.isnan(p.novelty_p_value)


def test_novelty_alpha_none_fits_no_detector_and_is_validated():
    ds = random_dataset(4, n_tasks=2, n_demos=5)
    model = IProMP(
        OBSERVE, n_basis=7, noise=10.0, temperature=1.0, head=False, handover=False, novelty_alpha=None
    )
    assert model.fit(ds).fitted_.novelty is None
    with pytest.raises(Exception, match="novelty_alpha"):
        IProMP(OBSERVE, novelty_alpha=0.9).fit(ds)
